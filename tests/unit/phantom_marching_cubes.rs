//! Tests of `src/phantom/marching_cubes.rs`.

use destair::mesh::Topology;
use destair::phantom::marching_cubes::*;
use destair::phantom::volume::LabelVolume;

#[test]
fn every_configuration_chains_into_closed_loops_without_face_diagonals() {
    for config in 0..=255u8 {
        let segments = face_segments(config);
        let mut starts = [0; 12];
        let mut ends = [0; 12];
        for &(a, b) in &segments {
            starts[a] += 1;
            ends[b] += 1;
        }
        assert_eq!(starts, ends, "config {config:08b}");
        assert!(starts.iter().all(|&s| s <= 1), "config {config:08b}");
        // Every edge with a sign change is a vertex of some triangle.
        let used: u16 = case_table()[config as usize]
            .iter()
            .flatten()
            .fold(0, |m, &e| m | 1 << e);
        let changed: u16 = (0..12)
            .filter(|&e| starts[e] == 1)
            .fold(0, |m, e| m | 1 << e);
        assert_eq!(used, changed, "config {config:08b}");
        for t in &case_table()[config as usize] {
            for k in 0..3 {
                let (p, q) = (t[k] as usize, t[(k + 1) % 3] as usize);
                let polygon_edge = segments.contains(&(p, q));
                let shares = edge_faces(p) & edge_faces(q) != 0;
                assert!(
                    polygon_edge || !shares,
                    "config {config:08b}: diagonal in a face"
                );
            }
        }
    }
}

#[test]
fn single_voxel_is_an_octahedron_pointing_outward() {
    let mut v = LabelVolume::new([3, 3, 3], [1.0, 2.0, 3.0], [0.0; 3]);
    let i = v.index(1, 1, 1);
    v.labels[i] = 1;
    let m = extract_surface(&v, 1, BorderEnds::Capped);
    assert_eq!((m.n_vertices(), m.n_triangles()), (6, 8));
    let t = Topology::build(&m);
    assert!(t.is_closed_oriented_manifold());
    assert_eq!(t.euler_characteristic(), 2);
    // Octahedron with half-diagonals 0.5, 1.0, 1.5 mm: volume = 4/3 * a * b * c.
    let vol = destair::mesh::geometry::signed_volume(&m);
    assert!((vol - 4.0 / 3.0 * 0.5 * 1.0 * 1.5).abs() < 1e-9, "{vol}");
}
