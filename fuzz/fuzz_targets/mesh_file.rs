//! Any bytes as a mesh file: decoding must answer with a mesh or an error, never panic; a
//! mesh that decodes goes through what `smooth` (with the smoother the first byte picks) and
//! the guard do to it, and its PLY encoding must decode to the same mesh, bit for bit.
#![no_main]
use destair::io::{decode_mesh, ReadOptions};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&which, bytes)) = data.split_first() else {
        return;
    };
    let extension = ["ply", "stl", "obj", "txt"][which as usize % 4];
    let options = ReadOptions {
        keep_vertex_properties: which & 4 != 0,
        ..Default::default()
    };
    let Ok(loaded) = decode_mesh(bytes, Some(extension), &options) else {
        return;
    };
    let mesh = &loaded.mesh;
    if mesh.n_triangles() > 20_000 {
        return;
    }
    let encoded = destair::io::ply::write::encode_ply(mesh, &loaded.meta, &[]).unwrap();
    let back = decode_mesh(&encoded, Some("ply"), &ReadOptions::default()).unwrap();
    assert_eq!(back.mesh.triangles(), mesh.triangles());
    let bits = |m: &destair::Mesh| -> Vec<[u32; 3]> {
        m.positions().iter().map(|p| p.map(f32::to_bits)).collect()
    };
    assert_eq!(bits(&back.mesh), bits(mesh));

    let topology = destair::Topology::build(mesh);
    let params = destair::weights::context::ContextParams::default();
    let context = destair::weights::context::context_weights(mesh, &topology, &params, &[]);
    // The voxel size as `smooth` finds it (1 mm where the mesh does not tell), and the
    // smoother the first byte's high bits pick.
    let voxel = destair::analysis::voxel_size::voxel_size(mesh, &topology)
        .spacing()
        .map_or([1.0; 3], |s| s.map(|x| x as f32));
    use destair::smooth::MethodKind::*;
    let kinds = [Hc, Laplace, Taubin, Mcf, Npc, CellSize, CellEdge, Diamond];
    let method = kinds[(which >> 3) as usize % 8].build(&Default::default(), voxel);
    let fixed = destair::smooth::boundary_vertices(&topology);
    let (smoothed, _) =
        destair::smooth::smooth(mesh, &topology, &method, 5, &context.weights, &fixed);
    let _ = destair::smooth::check_result(mesh.positions(), &smoothed, 2.0, (1.0, "mm"), None);
    let _ = destair::spatial::intersect::self_intersections(mesh);
    if let Ok(after) = destair::Mesh::new(smoothed, mesh.triangles().to_vec()) {
        let _ = destair::metrics::hausdorff_distance(mesh, &after);
        let _ = destair::spatial::intersect::mesh_intersections(mesh, &after);
    }
});
