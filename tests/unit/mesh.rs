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
