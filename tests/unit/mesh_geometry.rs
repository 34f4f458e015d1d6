//! Tests of `src/mesh/geometry.rs`.

use destair::mesh::geometry::*;
use destair::mesh::{Mesh, Topology};

/// Unit cube, outward-oriented, 12 triangles.
pub(crate) fn cube() -> Mesh {
    crate::cuboid([0.0; 3], [1.0; 3])
}

#[test]
fn cube_area_volume_normals() {
    let m = cube();
    let topo = Topology::build(&m);
    assert!(topo.is_closed_oriented_manifold());
    assert_eq!(area(&m), 6.0);
    assert!((signed_volume(&m) - 1.0).abs() < 1e-12);
    let fnorm = face_normals(&m);
    assert_eq!(fnorm[0], [0.0, 0.0, -1.0]);
    assert_eq!(fnorm[2], [0.0, 0.0, 1.0]);
    let vn = vertex_normals(&m, &topo);
    // Corner 7 = (1,1,1): normal points along the diagonal.
    let s = 1.0 / 3f32.sqrt();
    for c in vn[7] {
        assert!(c > 0.0 && (c - s).abs() < 0.2);
    }
    let b = bounding_box(&m).unwrap();
    assert_eq!(b.extent(), [1.0, 1.0, 1.0]);
}

#[test]
fn face_and_vertex_normals_are_bit_for_bit_the_separate_ones() {
    let mut rng = fastrand::Rng::with_seed(7);
    // Random triangles over 60 random vertices, some without area (a repeated corner).
    let positions: Vec<[f32; 3]> = (0..60)
        .map(|_| [rng.f32() * 9.0, rng.f32() * 9.0, rng.f32() * 9.0])
        .collect();
    let triangles: Vec<[u32; 3]> = (0..200)
        .map(|i| {
            let a = rng.u32(0..60);
            let b = if i % 17 == 0 { a } else { rng.u32(0..60) };
            [a, b, rng.u32(0..60)]
        })
        .collect();
    let m = Mesh::new(positions, triangles).unwrap();
    let topo = Topology::build(&m);
    let (faces, vertices) = face_and_vertex_normals(&m, &topo);
    let bits = |v: &[[f32; 3]]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&faces), bits(&face_normals(&m)));
    assert_eq!(bits(&vertices), bits(&vertex_normals(&m, &topo)));
}

#[test]
fn volume_is_translation_invariant_for_closed_meshes() {
    let m = cube();
    let (mut p, t) = m.into_parts();
    for q in &mut p {
        q[0] += 1000.0;
        q[2] -= 250.0;
    }
    let moved = Mesh::new(p, t).unwrap();
    assert!((signed_volume(&moved) - 1.0).abs() < 1e-9);
}
