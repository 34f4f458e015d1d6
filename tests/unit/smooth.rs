//! Tests of `src/smooth/mod.rs`.

use destair::mesh::Topology;
use destair::smooth::*;
use destair::weights::VertexWeights;

/// Renumbering a scattered mesh changes no bit of any result.
#[test]
fn a_renumbered_run_gives_the_bits_of_a_run_in_file_order() {
    let case = destair::phantom::big_case(120_000, &Default::default());
    let grid_mesh = &case.meshes[0].1;
    let mesh = destair::bench::shuffled(grid_mesh, 5);
    let topology = Topology::build(&mesh);
    let (offsets, neighbors) = topology.neighbor_csr();
    assert!(mesh.n_vertices() > 50_000);
    assert!(destair::mesh::order::is_scattered(offsets, neighbors));
    let n = mesh.n_vertices();
    let weights = VertexWeights::new((0..n).map(|v| (v % 5) as f32 / 4.0).collect(), n).unwrap();
    let fixed: Vec<bool> = (0..mesh.n_vertices()).map(|v| v % 11 == 0).collect();
    let voxel = case.info.spacing_mm.map(|x| x as f32);
    // Curvature flow always runs in the mesh's own numbering.
    let methods = destair::bench::every_method(voxel);
    for method in methods
        .into_iter()
        .filter(|m| !matches!(m, Method::Mcf { .. }))
    {
        let (renumbered, stats) = smooth(&mesh, &topology, &method, 4, &weights, &fixed);
        let (scale, axes) = step_scales(&mesh, &topology, &method, &weights, &fixed);
        let (direct, iterations, last, _) = run_method(
            &mesh,
            &topology,
            &method,
            mesh.positions(),
            (offsets, neighbors, None),
            &scale,
            axes.as_deref(),
            4,
        );
        assert_ne!(direct, mesh.positions(), "{method:?} moved nothing");
        assert!(renumbered == direct, "{method:?}");
        assert_eq!((stats.iterations, stats.last_max_step), (iterations, last));
    }
}

#[test]
fn check_result_names_the_vertex_as_the_file_numbers_it() {
    let original = vec![[0.0f32; 3]; 4];
    let mut smoothed = original.clone();
    smoothed[1] = [5.0, 0.0, 0.0];
    let unit = (1.0, "voxel diagonals");
    let plain = destair::smooth::check_result(&original, &smoothed, 2.0, unit, None).unwrap_err();
    assert!(plain.contains("vertex 1 by 5 mm"), "{plain}");
    // Worked vertex 1 is the file's vertex 3.
    let r = destair::mesh::order::Renumbering::from_old(vec![2, 3, 0, 1]);
    let named =
        destair::smooth::check_result(&original, &smoothed, 2.0, unit, Some(&r)).unwrap_err();
    assert!(named.contains("vertex 3 by 5 mm"), "{named}");
    smoothed[1] = [f32::NAN, 0.0, 0.0];
    let named =
        destair::smooth::check_result(&original, &smoothed, 2.0, unit, Some(&r)).unwrap_err();
    assert!(named.contains("vertex 3 has a non-finite"), "{named}");
}
