//! Tests of `src/mesh/topology.rs`.

use destair::mesh::topology::*;
use destair::mesh::Mesh;

fn mesh(p: &[[f32; 3]], t: &[[u32; 3]]) -> Mesh {
    Mesh::new(p.to_vec(), t.to_vec()).unwrap()
}

fn tetrahedron() -> Mesh {
    mesh(
        &[[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.]],
        &[[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]],
    )
}

#[test]
fn tetrahedron_is_closed_manifold() {
    let t = Topology::build(&tetrahedron());
    assert_eq!(t.edges().len(), 6);
    assert!(t.edge_n_faces().iter().all(|&c| c == 2));
    assert!(t.is_closed_oriented_manifold());
    assert_eq!(t.euler_characteristic(), 2);
    assert_eq!(t.n_components(), 1);
    assert_eq!(t.neighbors(0), &[1, 2, 3]);
    assert_eq!(t.vertex_faces(3), &[1, 2, 3]);
}

#[test]
fn single_triangle_has_one_boundary_loop_in_face_order() {
    let t = Topology::build(&mesh(
        &[[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]],
        &[[0, 1, 2]],
    ));
    assert_eq!(
        t.boundary_loops(),
        &[BoundaryLoop {
            vertices: vec![0, 1, 2],
            closed: true
        }]
    );
    assert_eq!(t.euler_characteristic(), 1);
}

#[test]
fn flipped_triangle_is_inconsistent() {
    let m = mesh(
        &[[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.]],
        &[[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 2, 3]],
    );
    let t = Topology::build(&m);
    assert_eq!(t.inconsistent_edges().len(), 3);
    assert!(!t.is_closed_oriented_manifold());
}

#[test]
fn three_faces_on_an_edge_are_non_manifold() {
    let m = mesh(
        &[
            [0., 0., 0.],
            [1., 0., 0.],
            [0., 1., 0.],
            [0., -1., 0.],
            [0., 0., 1.],
        ],
        &[[0, 1, 2], [1, 0, 3], [0, 1, 4]],
    );
    let t = Topology::build(&m);
    assert_eq!(t.non_manifold_edges(), &[0]);
    assert_eq!(t.edges()[0], [0, 1]);
}

#[test]
fn bowtie_vertex_and_unreferenced_and_degenerate() {
    let m = mesh(
        &[
            [0., 0., 0.],
            [1., 0., 0.],
            [1., 1., 0.],
            [-1., 0., 0.],
            [-1., -1., 0.],
            [9., 9., 9.],
        ],
        &[[0, 1, 2], [0, 3, 4], [1, 1, 2]],
    );
    let t = Topology::build(&m);
    assert_eq!(t.non_manifold_vertices(), &[0]);
    assert_eq!(t.unreferenced_vertices(), &[5]);
    assert_eq!(t.degenerate_triangles(), &[2]);
    assert_eq!(t.n_components(), 1);
    assert_eq!(t.vertex_component()[5], u32::MAX);
    // The two fans share vertex 0, so their rims form one chain through it.
    let n_loop_vertices: usize = t.boundary_loops().iter().map(|l| l.vertices.len()).sum();
    assert_eq!(n_loop_vertices, 6);
}

#[test]
fn two_separate_triangles_are_two_components() {
    let m = mesh(
        &[
            [0., 0., 0.],
            [1., 0., 0.],
            [0., 1., 0.],
            [5., 0., 0.],
            [6., 0., 0.],
            [5., 1., 0.],
        ],
        &[[3, 4, 5], [0, 1, 2]],
    );
    let t = Topology::build(&m);
    assert_eq!(t.n_components(), 2);
    assert_eq!(t.vertex_component(), &[0, 0, 0, 1, 1, 1]);
    assert_eq!(t.boundary_loops().len(), 2);
}

#[test]
fn empty_mesh() {
    let t = Topology::build(&Mesh::default());
    assert_eq!(t.edges().len(), 0);
    assert_eq!(t.euler_characteristic(), 0);
}
