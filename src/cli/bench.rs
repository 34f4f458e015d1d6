//! `destair bench`: throughput of the stages on generated meshes.

use std::path::PathBuf;

#[derive(clap::Subcommand)]
pub enum Args {
    /// Stack axis, staircase weights, caps, and exact distance queries per second.
    Context {
        /// Approximate number of triangles of the `big` phantom (and of query points).
        #[arg(long, default_value_t = 1_000_000)]
        triangles: usize,
        /// Permute vertex numbering and face order (worst-case memory locality; the queries
        /// follow the faces).
        #[arg(long)]
        shuffle: bool,
        #[arg(long, default_value_t = 3)]
        repeat: usize,
        #[arg(long)]
        json: bool,
    },
    /// Every smoother (seconds per run, vertex updates per second) and the Hausdorff metric.
    Smooth {
        /// Approximate number of triangles of the `big` phantom.
        #[arg(long, default_value_t = 1_000_000)]
        triangles: usize,
        #[arg(long, default_value_t = 20)]
        iterations: usize,
        /// Runs per measurement; the best is reported.
        #[arg(long, default_value_t = 3)]
        repeat: usize,
        #[arg(long)]
        json: bool,
    },
    /// A 512 x 512 x 300 u8 label map with 12 touching labels at 0.8 x 0.8 x 1.5 mm: reading
    /// it (.nii.gz and .nii) and extracting every label's surface.
    #[command(alias = "labelmap")]
    Extract {
        /// Folder for the temporary files (default: the system temp folder).
        #[arg(long)]
        dir: Option<PathBuf>,
        /// Keep the label maps written there (destair-bench.nii.gz, .nii), e.g. to run other
        /// tools or `destair extract` on the same volume.
        #[arg(long)]
        keep: bool,
        /// Runs per measurement; the best is reported (and the median of the extraction).
        #[arg(long, default_value_t = 5)]
        repeat: usize,
        #[arg(long)]
        json: bool,
    },
    /// PLY read+validate, write and topology build on a generated closed mesh.
    Io {
        /// Approximate number of triangles.
        #[arg(long, default_value_t = 5_000_000)]
        triangles: usize,
        /// Folder for the temporary PLY file (default: the system temp folder).
        #[arg(long)]
        dir: Option<PathBuf>,
        /// Mesh to run on: the `big` phantom (marching-cubes blob) or a regular torus.
        #[arg(long, value_enum, default_value_t = MeshArg::Phantom)]
        mesh: MeshArg,
        /// Permute vertex numbering and face order (worst-case memory locality).
        #[arg(long)]
        shuffle: bool,
        /// Runs per measurement; the best is reported.
        #[arg(long, default_value_t = 5)]
        repeat: usize,
        /// Print the results as JSON.
        #[arg(long)]
        json: bool,
    },
}

#[derive(Clone, Copy, clap::ValueEnum)]
pub enum MeshArg {
    Phantom,
    Torus,
}

pub fn exec(args: Args) -> anyhow::Result<()> {
    match args {
        Args::Context {
            triangles,
            shuffle,
            repeat,
            json,
        } => {
            let r = destair::bench::context(triangles, shuffle, repeat);
            if json {
                println!("{}", serde_json::to_string_pretty(&r)?);
                return Ok(());
            }
            println!(
                "bench context: {} vertices, {} triangles{}, {} threads, best of {repeat}",
                r.n_vertices,
                r.n_triangles,
                if r.shuffled {
                    " (shuffled numbering and face order)"
                } else {
                    ""
                },
                r.threads
            );
            println!("  topology           {:.4} s", r.topology_s);
            println!("  stack axis         {:.4} s", r.stack_axis_s);
            println!("  staircase weights  {:.4} s", r.staircase_weights_s);
            println!("  caps               {:.4} s", r.caps_s);
            println!(
                "  all of the context {:.4} s  (as smooth and inspect --context run it)",
                r.context_weights_s
            );
            println!(
                "  triangle index     {:.4} s  (cells and hierarchy)",
                r.tree_build_s
            );
            println!(
                "  {} exact queries  {:.4} s  ({:.2} M queries/s), 1.5 mm off the surface",
                r.n_queries,
                r.queries_s,
                r.queries_per_s / 1e6
            );
            println!(
                "  {} exact queries  {:.4} s  ({:.2} M queries/s), {:.1} mm away on average",
                r.n_queries,
                r.far_queries_s,
                r.far_queries_per_s / 1e6,
                r.far_mean_distance_mm
            );
        }
        Args::Smooth {
            triangles,
            iterations,
            repeat,
            json,
        } => {
            let r = destair::bench::smooth(triangles, iterations, repeat);
            if json {
                println!("{}", serde_json::to_string_pretty(&r)?);
                return Ok(());
            }
            println!(
                "bench smooth: {} vertices, {} triangles, {} iterations, {} threads, best of {repeat}",
                r.n_vertices, r.n_triangles, r.iterations, r.threads
            );
            for t in &r.smoothers {
                println!(
                    "  {:<10} {:.4} s  {:.1} M vertex-updates/s",
                    t.method,
                    t.seconds,
                    t.vertex_updates_per_s / 1e6
                );
            }
            println!("  laplace by vertex numbering:");
            for t in &r.numberings {
                println!(
                    "    {:<9} {:.4} s (passes {:.4} s){}  largest difference {:.1e} mm",
                    t.numbering,
                    t.seconds,
                    t.passes_seconds,
                    match t.renumbering_seconds {
                        Some(r) => format!(
                            " (scattered: run in scanline order; renumbering after reading and back before writing {r:.4} s besides)"
                        ),
                        None => String::new(),
                    },
                    t.max_difference_mm
                );
            }
            println!(
                "    bound     {:.4} s  (arrays streamed once per iteration at {:.1} GB/s copy bandwidth)",
                r.laplace_bound_s, r.copy_gb_per_s
            );
            println!(
                "    compute   {:.4} s  (the kernel in cache: {:.0} M updates/s on one thread, over a {} k triangle blob, times {} threads); phantom passes on one thread {:.4} s",
                r.laplace_compute_bound_s,
                r.in_cache_updates_per_s / 1e6,
                destair::bench::IN_CACHE_TRIANGLES / 1000,
                r.threads,
                r.passes_one_thread_s
            );
            println!(
                "  hausdorff  {:.4} s  ({:.2} M point-to-surface queries/s, indexes included)",
                r.hausdorff_s,
                r.hausdorff_queries_per_s / 1e6
            );
            println!(
                "  self-intersections of the smoothed copy  {:.4} s  ({} pairs; the guard's check)",
                r.self_intersections_s, r.self_intersections
            );
        }
        Args::Extract {
            dir,
            keep,
            repeat,
            json,
        } => {
            let dir = dir.unwrap_or_else(std::env::temp_dir);
            let r = destair::bench::labelmap(&dir, repeat, keep)?;
            if json {
                println!("{}", serde_json::to_string_pretty(&r)?);
                return Ok(());
            }
            println!(
                "bench extract: {} x {} x {} u8 voxels, {} labels, {} threads, best of {repeat}",
                r.dims[0], r.dims[1], r.dims[2], r.n_labels, r.threads
            );
            println!(
                "  read .nii.gz ({:.1} MB)  {:.4} s",
                r.gz_bytes as f64 / 1e6,
                r.read_nii_gz_s
            );
            println!("  read .nii (mapped)     {:.4} s", r.read_nii_s);
            println!(
                "  extract all labels     {:.4} s  (median {:.4} s; {} interface triangles)",
                r.extract_s, r.extract_median_s, r.n_interface_triangles
            );
            println!("    interfaces           {:.4} s", r.interfaces_s);
            println!("    label surfaces       {:.4} s", r.assemble_s);
            println!(
                "  constrained surfaces   {:.4} s  (median {:.4} s; default settings)",
                r.constrained_s, r.constrained_median_s
            );
            println!(
                "  count surfaces         {:.4} s  ({} surface triangles, for the memory budget)",
                r.count_s, r.n_surface_triangles
            );
        }
        Args::Io {
            triangles,
            dir,
            mesh,
            shuffle,
            repeat,
            json,
        } => {
            let dir = dir.unwrap_or_else(std::env::temp_dir);
            let kind = match mesh {
                MeshArg::Phantom => destair::bench::BenchMesh::Phantom,
                MeshArg::Torus => destair::bench::BenchMesh::Torus,
            };
            // Whole smooth processes of this very executable.
            let exe = std::env::current_exe()?;
            let r = destair::bench::io(&dir, triangles, kind, shuffle, repeat, Some(&exe))?;
            if json {
                println!("{}", serde_json::to_string_pretty(&r)?);
                return Ok(());
            }
            println!(
                "bench io: {:?} mesh, {} vertices, {} triangles{}, binary PLY {:.1} MB, {} threads, best of {repeat}",
                r.mesh,
                r.n_vertices,
                r.n_triangles,
                if r.shuffled { " (shuffled numbering and face order)" } else { "" },
                r.file_bytes as f64 / 1e6,
                r.threads
            );
            println!(
                "  read+validate (mmap)  {:.4} s  {:.0} MB/s",
                r.read_mmap_s, r.read_mmap_mb_per_s
            );
            println!("  read+validate (read)  {:.4} s", r.read_plain_s);
            println!(
                "  write (atomic)        {:.4} s  {:.0} MB/s",
                r.write_s, r.write_mb_per_s
            );
            println!("  topology build        {:.4} s", r.topology_s);
            if let Some(p) = &r.smooth_process {
                println!(
                    "  smooth, whole process (Laplace 20): {:.4} s plain (--staircase false --caps smooth), {:.4} s with the default context",
                    p.plain_s, p.context_s
                );
            }
            println!(
                "  STL ({:.1} MB) write  {:.4} s, read+weld {:.4} s",
                r.stl_file_bytes as f64 / 1e6,
                r.stl_write_s,
                r.stl_read_s
            );
        }
    }
    Ok(())
}
