//! Tests of `src/mesh/order.rs`.

use destair::mesh::order::*;
use destair::mesh::Mesh;

#[test]
fn spread_puts_two_zero_bits_after_each_bit() {
    assert_eq!(spread(0b1), 0b1);
    assert_eq!(spread(0b11), 0b1001);
    assert_eq!(spread(0b101), 0b1_000_001);
    // Bit 20 goes to bit 60; higher bits are dropped.
    assert_eq!(spread(1 << 20), 1 << 60);
    assert_eq!(spread(1 << 21), 0);
}

#[test]
fn reordering_keeps_every_face_and_follows_the_curve() {
    // A 2 x 2 grid of quads written in a scattered vertex order.
    let positions = vec![
        [2.0, 2.0, 0.0],
        [0.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [2.0, 0.0, 0.0],
        [0.0, 2.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [2.0, 1.0, 0.0],
        [1.0, 2.0, 0.0],
    ];
    let at = |x: f32, y: f32| {
        positions
            .iter()
            .position(|p| p[0] == x && p[1] == y)
            .unwrap() as u32
    };
    let mut triangles = Vec::new();
    for (x, y) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
        triangles.push([at(x, y), at(x + 1.0, y), at(x + 1.0, y + 1.0)]);
        triangles.push([at(x, y), at(x + 1.0, y + 1.0), at(x, y + 1.0)]);
    }
    let mesh = Mesh::new(positions.clone(), triangles.clone()).unwrap();
    let (ordered, face_order) = locality_ordered(&mesh);
    // Z-order over the 3 x 3 grid: (0,0) (1,0) (0,1) (1,1) first.
    let q = ordered.positions();
    assert_eq!(
        &q[..4],
        &[
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.0]
        ]
    );
    // Every new face is the old face it says it was, corner for corner.
    let mut seen = vec![false; triangles.len()];
    for (t, &f) in ordered.triangles().iter().zip(&face_order) {
        let old = triangles[f as usize].map(|v| positions[v as usize]);
        assert_eq!(t.map(|v| q[v as usize]), old);
        seen[f as usize] = true;
    }
    assert!(seen.iter().all(|&s| s));
    // Faces come in order of their smallest vertex.
    let firsts: Vec<u32> = ordered
        .triangles()
        .iter()
        .map(|t| *t.iter().min().unwrap())
        .collect();
    assert!(firsts.windows(2).all(|w| w[0] <= w[1]));
}

#[test]
fn scanline_renumbers_a_scattered_torus_and_keeps_every_neighbour_list() {
    let torus = destair::bench::torus(300, 200);
    let t = destair::mesh::Topology::build(&torus);
    assert!(!is_scattered(t.neighbor_csr().0, t.neighbor_csr().1));
    let mesh = destair::bench::shuffled(&torus, 9);
    let topology = destair::mesh::Topology::build(&mesh);
    let (offsets, neighbors) = topology.neighbor_csr();
    assert!(is_scattered(offsets, neighbors));
    let r = scanline(mesh.positions(), offsets, neighbors);
    // A permutation, and `new` is its inverse.
    let mut seen = vec![false; mesh.n_vertices()];
    for (i, &v) in r.old.iter().enumerate() {
        assert!(!seen[v as usize]);
        seen[v as usize] = true;
        assert_eq!(r.new[v as usize], i as u32);
    }
    assert_eq!(r.old.len(), mesh.n_vertices());
    // The adjacency in the new numbering is no longer scattered.
    let (mut o2, mut n2) = (vec![0u32], Vec::new());
    for &v in &r.old {
        let list = &neighbors[offsets[v as usize] as usize..offsets[v as usize + 1] as usize];
        n2.extend(list.iter().map(|&w| r.new[w as usize]));
        o2.push(n2.len() as u32);
    }
    assert!(!is_scattered(&o2, &n2));
    // Gathering then scattering gives the values back.
    let values: Vec<u32> = (0..mesh.n_vertices() as u32).map(|v| v * 7).collect();
    assert_eq!(r.scatter(&r.gather(&values)), values);
}

#[test]
fn working_numbering_is_read_from_the_faces_and_restores_to_the_bit() {
    let torus = destair::bench::torus(300, 200);
    assert!(!faces_scattered(torus.triangles()));
    assert!(working_numbering(&torus).is_none());
    for seed in [1, 9] {
        let mesh = destair::bench::shuffled(&torus, seed);
        let topology = destair::mesh::Topology::build(&mesh);
        let (offsets, neighbors) = topology.neighbor_csr();
        // The faces tell what the adjacency tells.
        assert_eq!(
            faces_scattered(mesh.triangles()),
            is_scattered(offsets, neighbors)
        );
        let r = working_numbering(&mesh).expect("a shuffled torus is scattered");
        let worked = r.mesh(&mesh);
        assert!(!faces_scattered(worked.triangles()));
        // Same faces in the same order, each vertex where it was.
        for (t, u) in mesh.triangles().iter().zip(worked.triangles()) {
            for k in 0..3 {
                assert_eq!(r.old[u[k] as usize], t[k]);
                assert_eq!(
                    worked.positions()[u[k] as usize],
                    mesh.positions()[t[k] as usize]
                );
            }
        }
        let back = r.restore(&worked);
        assert_eq!(back.positions(), mesh.positions());
        assert_eq!(back.triangles(), mesh.triangles());
    }
    // Degenerate inputs do not panic.
    assert!(working_numbering(&Mesh::default()).is_none());
}
