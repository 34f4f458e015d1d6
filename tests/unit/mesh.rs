//! Tests of `src/mesh/mod.rs`.

use destair::mesh::*;

#[test]
fn rejects_bad_index_and_nan() {
    let p = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    assert!(Mesh::new(p.clone(), vec![[0, 1, 2]]).is_ok());
    assert_eq!(
        Mesh::new(p.clone(), vec![[0, 1, 2], [0, 1, 3]]),
        Err(MeshError::IndexOutOfRange {
            triangle: 1,
            index: 3,
            n_vertices: 3
        })
    );
    let mut q = p;
    q[1][2] = f32::NAN;
    assert!(matches!(
        Mesh::new(q, vec![]),
        Err(MeshError::NonFinite { vertex: 1, .. })
    ));
}

#[test]
fn coordinates_beyond_ten_kilometres_are_not_a_mesh() {
    let at = |x: f32| vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, x, 0.0]];
    for x in [1e7, -1e7, 9.99e6] {
        assert!(Mesh::new(at(x), vec![[0, 1, 2]]).is_ok(), "{x}");
    }
    for x in [1.0000001e7, -2e7, f32::MAX, f32::INFINITY] {
        let err = Mesh::new(at(x), vec![[0, 1, 2]]).unwrap_err();
        assert!(matches!(err, MeshError::NonFinite { vertex: 2, .. }), "{x}");
        assert!(err.to_string().contains("within +-1e7 mm"), "{err}");
    }
    assert!(is_valid_coordinate(MAX_COORDINATE_MM) && !is_valid_coordinate(f32::NAN));
}

/// Copies of a mesh share its faces: moving one copy's vertices or taking it apart leaves the
/// other as it was.
#[test]
fn copies_keep_their_own_positions_and_faces() {
    let p = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    let t = vec![[0, 1, 2], [0, 3, 1]];
    let original = Mesh::new(p.clone(), t.clone()).unwrap();
    let mut copy = original.clone();
    copy.positions_mut()[3] = [5.0, 5.0, 5.0];
    assert_eq!(original.positions(), &p[..]);
    assert_eq!(copy.triangles(), &t[..]);
    let (q, u) = copy.into_parts();
    assert_eq!((q[3], u), ([5.0, 5.0, 5.0], t.clone()));
    assert_eq!(original.into_parts(), (p, t));
}
