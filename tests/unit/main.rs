//! Tests of single modules through the library's public API.

mod analysis_voxel_size;
mod extract_kernel;
mod extract_noise;
mod guard;
mod io_atomic;
mod io_identity;
mod io_mapped;
mod io_ply_header;
mod io_text;
mod io_vtp;
mod io_weld;
mod job_config;
mod job_discover;
mod job_index_page;
mod job_lock;
mod job_outputs;
mod job_paths;
mod job_plan;
mod job_settings;
mod mesh;
mod mesh_face_neighbours;
mod mesh_geometry;
mod mesh_manifold;
mod mesh_order;
mod mesh_topology;
mod mesh_umbrella;
mod metrics_distance;
mod metrics_normal_curvature;
mod metrics_quality;
mod parallel;
mod phantom_gaussian;
mod phantom_marching_cubes;
mod phantom_volume;
mod render;
mod render_colour;
mod render_sheet;
mod render_text;
mod report_html;
mod report_html_markdown;
mod report_html_svg;
mod report_pictures;
mod smooth;
mod smooth_constraints;
mod smooth_mcf;
mod spatial;
mod spatial_bvh;
mod spatial_cells;
mod spatial_intersect;
mod units;
mod volume;
mod volume_components;
mod volume_grid;
mod weights;
mod weights_distance;
mod weights_staircase;

use destair::mesh::Mesh;

/// An axis-aligned box from `lo` to `hi` (mm) as a closed, outward-oriented mesh of 12
/// triangles; corner i is at x = hi if i & 1, y = hi if i & 2, z = hi if i & 4.
pub fn cuboid(lo: [f32; 3], hi: [f32; 3]) -> Mesh {
    let p: Vec<[f32; 3]> = (0..8)
        .map(|i| std::array::from_fn(|k| if i & (1 << k) == 0 { lo[k] } else { hi[k] }))
        .collect();
    let quads = [
        [0, 2, 3, 1], // z = lo, normal -z
        [4, 5, 7, 6], // z = hi
        [0, 1, 5, 4], // y = lo
        [2, 6, 7, 3], // y = hi
        [0, 4, 6, 2], // x = lo
        [1, 3, 7, 5], // x = hi
    ];
    let t = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    Mesh::new(p, t).expect("a valid box")
}
