//! `destair bench`: measured throughput of destair's stages on generated meshes.
//!
//! Timings are the best of several runs (warm page cache), the usual way to report
//! throughput that is not disturbed by other work on the machine.

use crate::io::ply::write_ply;
use crate::io::stl::write_stl;
use crate::io::{read_mesh, MeshMeta, ReadMode, ReadOptions};
use crate::mesh::{Mesh, Topology};
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// The same mesh with its vertices renumbered and its faces listed in an order given by seeded
/// permutations: a file in no order at all, without the memory locality marching-cubes output
/// has; the worst case.
pub fn shuffled(mesh: &Mesh, seed: u64) -> Mesh {
    let renamed = renumbered(mesh, &permutation(mesh.n_vertices(), seed));
    relisted(
        &renamed,
        &permutation(mesh.n_triangles(), seed.wrapping_add(1)),
    )
}

/// The mesh with its faces listed in another order: face i is the mesh's face `order[i]`
/// (`order` a permutation of its faces).
pub fn relisted(mesh: &Mesh, order: &[u32]) -> Mesh {
    let tris = mesh.triangles();
    let triangles = order.iter().map(|&f| tris[f as usize]).collect();
    Mesh::from_checked_parts(mesh.positions().to_vec(), triangles)
}

/// A seeded random permutation of 0..n.
pub fn permutation(n: usize, seed: u64) -> Vec<u32> {
    let mut order: Vec<u32> = (0..n as u32).collect();
    fastrand::Rng::with_seed(seed).shuffle(&mut order);
    order
}

/// The mesh with vertex `old[i]` numbered i (`old` a permutation of its vertices); the faces keep
/// their order.
pub fn renumbered(mesh: &Mesh, old: &[u32]) -> Mesh {
    crate::mesh::order::Renumbering::from_old(old.to_vec()).mesh(mesh)
}

/// A closed torus of `rings` x `segments` quads split into triangles (2 x rings x segments
/// triangles), radii 60 and 20 mm.
pub fn torus(rings: usize, segments: usize) -> Mesh {
    let n = rings * segments;
    let mut positions = vec![[0.0f32; 3]; n];
    for i in 0..rings {
        let u = i as f32 / rings as f32 * std::f32::consts::TAU;
        for j in 0..segments {
            let v = j as f32 / segments as f32 * std::f32::consts::TAU;
            let r = 60.0 + 20.0 * v.cos();
            positions[i * segments + j] = [r * u.cos(), r * u.sin(), 20.0 * v.sin()];
        }
    }
    let id = |i: usize, j: usize| ((i % rings) * segments + (j % segments)) as u32;
    let mut triangles = Vec::with_capacity(2 * n);
    for i in 0..rings {
        for j in 0..segments {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    Mesh::from_checked_parts(positions, triangles)
}

/// The `big` phantom's mesh of about `triangles` triangles and its grid spacing (mm).
fn big_mesh(triangles: usize) -> (Mesh, [f64; 3]) {
    let case = crate::phantom::big_case(triangles as u64, &Default::default());
    let spacing = case.info.spacing_mm;
    let mesh = case
        .meshes
        .into_iter()
        .next()
        .map(|(_, m)| m)
        .unwrap_or_default();
    (mesh, spacing)
}

/// Seconds of the best run of `f` over `repeat` runs.
pub fn best_of<T>(repeat: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut last = None;
    for _ in 0..repeat.max(1) {
        let t = Instant::now();
        let out = f();
        best = best.min(t.elapsed().as_secs_f64());
        last = Some(out);
    }
    (best, last.expect("repeat.max(1) runs at least once"))
}

/// Results of `destair bench io`.
#[derive(Debug, Serialize)]
pub struct IoBench {
    pub mesh: BenchMesh,
    pub n_vertices: usize,
    pub n_triangles: usize,
    pub shuffled: bool,
    pub file_bytes: u64,
    pub threads: usize,
    pub write_s: f64,
    pub read_mmap_s: f64,
    pub read_plain_s: f64,
    pub topology_s: f64,
    pub stl_file_bytes: u64,
    pub stl_write_s: f64,
    pub stl_read_s: f64,
    pub write_mb_per_s: f64,
    pub read_mmap_mb_per_s: f64,
    /// Whole `smooth` processes on the file (start to exit, reading and writing included),
    /// when an executable was given.
    pub smooth_process: Option<SmoothProcess>,
}

/// Seconds of whole `destair smooth` processes on the benchmark file, Laplace 20 iterations
/// (best run): as users run it, page faults and process exit included.
#[derive(Debug, Serialize)]
pub struct SmoothProcess {
    /// `--staircase false --caps smooth`: the smoother alone (no context analysis).
    pub plain_s: f64,
    /// Default settings: staircase weights and caps preserved (the context analysis).
    pub context_s: f64,
}

/// Which generated mesh a benchmark runs on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BenchMesh {
    /// A closed torus grid (generated instantly; perfectly regular).
    Torus,
    /// The `big` phantom: a marching-cubes blob with staircases, like real input.
    Phantom,
}

/// Generates a mesh of about `triangles` triangles, writes it as binary PLY in `dir`, then
/// times write, read+validate (mmap and plain read) and topology build, whole `smooth`
/// processes of `destair` (the executable, when given), then STL write and read.
pub fn io(
    dir: &Path,
    triangles: usize,
    kind: BenchMesh,
    shuffle: bool,
    repeat: usize,
    destair: Option<&Path>,
) -> anyhow::Result<IoBench> {
    let mesh = match kind {
        BenchMesh::Torus => {
            // Rings about 2.5 x segments keeps the quads near square on a 60/20 mm torus.
            let segments = ((triangles as f64 / 5.0).sqrt().round() as usize).max(3);
            let rings = (triangles / 2).div_ceil(segments).max(3);
            torus(rings, segments)
        }
        BenchMesh::Phantom => {
            let case = crate::phantom::big_case(triangles as u64, &Default::default());
            case.meshes
                .into_iter()
                .next()
                .map(|(_, m)| m)
                .unwrap_or_default()
        }
    };
    let mesh = if shuffle { shuffled(&mesh, 7) } else { mesh };
    let path = dir.join("bench-io.ply");
    let meta = MeshMeta::default();
    let (write_s, written) = best_of(repeat, || write_ply(&path, &mesh, &meta, &[]));
    written?;
    let file_bytes = std::fs::metadata(&path)?.len();
    let read = |mode| {
        let options = ReadOptions {
            mode,
            ..Default::default()
        };
        best_of(repeat, || read_mesh(&path, &options))
    };
    let (read_mmap_s, loaded) = read(ReadMode::Mmap);
    let loaded = loaded?;
    anyhow::ensure!(
        loaded.mesh == mesh,
        "bench: mesh read back differs from mesh written"
    );
    let (read_plain_s, _) = read(ReadMode::Read);
    let (topology_s, topology) = best_of(repeat, || Topology::build(&mesh));
    anyhow::ensure!(
        topology.is_closed_oriented_manifold(),
        "bench mesh is not a closed manifold"
    );
    let smooth_process = match destair {
        Some(exe) => Some(smooth_processes(exe, &path, repeat)?),
        None => None,
    };
    std::fs::remove_file(&path)?;
    let stl = dir.join("bench-io.stl");
    let (stl_write_s, written) = best_of(repeat, || write_stl(&stl, &mesh, &meta));
    written?;
    let stl_file_bytes = std::fs::metadata(&stl)?.len();
    let (stl_read_s, loaded) = best_of(repeat, || read_mesh(&stl, &ReadOptions::default()));
    anyhow::ensure!(loaded?.mesh.n_triangles() == mesh.n_triangles());
    std::fs::remove_file(&stl)?;
    let mb = file_bytes as f64 / 1e6;
    Ok(IoBench {
        mesh: kind,
        n_vertices: mesh.n_vertices(),
        n_triangles: mesh.n_triangles(),
        shuffled: shuffle,
        file_bytes,
        threads: rayon::current_num_threads(),
        write_s,
        read_mmap_s,
        read_plain_s,
        topology_s,
        stl_file_bytes,
        stl_write_s,
        stl_read_s,
        write_mb_per_s: mb / write_s,
        read_mmap_mb_per_s: mb / read_mmap_s,
        smooth_process,
    })
}

/// Times `exe smooth` on `input` as a child process (same thread count as this one), plain and
/// with the default context; the output goes beside the input and is removed.
fn smooth_processes(exe: &Path, input: &Path, repeat: usize) -> anyhow::Result<SmoothProcess> {
    let output = input.with_file_name("bench-io-smoothed.ply");
    let threads = rayon::current_num_threads().to_string();
    // Every run is checked; a failed one reports the child's error output.
    let run = |extra: &[&str]| -> anyhow::Result<f64> {
        let mut best = f64::INFINITY;
        for _ in 0..repeat.max(1) {
            let started = Instant::now();
            let out = std::process::Command::new(exe)
                .arg("smooth")
                .arg(input)
                .arg("-o")
                .arg(&output)
                .args(["--method", "laplace", "--iterations", "20"])
                .args(["--threads", &threads])
                .args(extra)
                .output()?;
            best = best.min(started.elapsed().as_secs_f64());
            if !out.status.success() {
                let _ = std::fs::remove_file(&output);
                anyhow::bail!(
                    "bench: {} smooth failed ({}): {}",
                    exe.display(),
                    out.status,
                    String::from_utf8_lossy(&out.stderr).trim()
                );
            }
        }
        Ok(best)
    };
    let plain_s = run(&["--staircase", "false", "--caps", "smooth"])?;
    let context_s = run(&[])?;
    std::fs::remove_file(&output)?;
    Ok(SmoothProcess { plain_s, context_s })
}

/// One smoother's timing in `destair bench smooth`.
#[derive(Debug, Serialize)]
pub struct SmoothTiming {
    pub method: &'static str,
    /// Seconds for the given number of iterations (best run).
    pub seconds: f64,
    /// Vertices times iterations per second (a Taubin iteration is a lambda and a mu pass).
    pub vertex_updates_per_s: f64,
}

/// Results of `destair bench smooth`.
#[derive(Debug, Serialize)]
pub struct SmoothBench {
    pub n_vertices: usize,
    pub n_triangles: usize,
    pub iterations: usize,
    pub threads: usize,
    pub smoothers: Vec<SmoothTiming>,
    /// Laplace on the same surface in other vertex numberings, the file order the kernels get.
    pub numberings: Vec<NumberingTiming>,
    /// Copy bandwidth of this machine (GB/s, bytes read plus bytes written), and the time Laplace
    /// needs at that rate to stream its arrays once per iteration (s): the memory-bandwidth bound.
    pub copy_gb_per_s: f64,
    pub laplace_bound_s: f64,
    /// The phantom numbering's passes alone on one thread (s): against its `passes_seconds`,
    /// how the kernel scales with threads (a kernel twice as fast on two threads is limited
    /// by each core, not by the memory they share).
    pub passes_one_thread_s: f64,
    /// Vertex updates per second of the same kernel on one thread over a blob of
    /// [`IN_CACHE_TRIANGLES`] triangles, whose arrays stay in cache: the core's own limit.
    pub in_cache_updates_per_s: f64,
    /// The time Laplace needs at that rate on every thread (s): the compute bound, which
    /// binds where it is above the memory-bandwidth bound.
    pub laplace_compute_bound_s: f64,
    /// Symmetric Hausdorff distance between the phantom and its Laplace-smoothed version,
    /// including building both indexes (seconds).
    pub hausdorff_s: f64,
    /// Point-to-surface queries per second within that measurement.
    pub hausdorff_queries_per_s: f64,
    /// The exact self-intersection search over the Laplace-smoothed version, as the guard runs
    /// it on every smoothed structure (s), and the pairs it found.
    pub self_intersections_s: f64,
    pub self_intersections: usize,
}

/// Laplace's time on one vertex numbering of the bench mesh.
#[derive(Debug, Serialize)]
pub struct NumberingTiming {
    /// `phantom` (the marching cubes' own), `scanline` (rows of cells, as VTK's flying edges
    /// writes them) or `shuffled` (seeded permutations of the vertices and of the faces: a
    /// worst case).
    pub numbering: &'static str,
    /// Seconds for the iterations in the numbering the commands work in (best run).
    pub seconds: f64,
    /// Of `seconds`, the passes alone (best run): the kernel, without making the step scales,
    /// the neighbour rows and the working copies, or unpadding the result.
    pub passes_seconds: f64,
    /// Whether the numbering is scattered, so that `smooth` and cohort runs renumber the mesh
    /// to scanline order once after reading, and the iterations ran in that order.
    pub renumbered: bool,
    /// For a scattered numbering, the seconds the commands spend on that renumbering and on
    /// putting the result back in the file's numbering before writing (best run; not part of
    /// `seconds`).
    pub renumbering_seconds: Option<f64>,
    /// Largest difference from the phantom numbering's result, vertex for vertex (mm).
    pub max_difference_mm: f32,
}

/// Seconds of `iterations` Laplace passes (lambda 0.5, weight 1) over `mesh` in its own
/// numbering (best of `repeat`), with everything the passes read made beforehand.
fn laplace_passes(mesh: &Mesh, topology: &Topology, iterations: usize, repeat: usize) -> f64 {
    use crate::mesh::umbrella::{
        copied, padded, umbrella_pass, written_before_read, NeighbourLists,
    };
    let (offsets, neighbors) = topology.neighbor_csr();
    let rows = NeighbourLists::new(offsets, neighbors, None);
    let scale = vec![1.0f32; mesh.n_vertices()];
    let start = padded(mesh.positions());
    // The working copies as the smoothers make them.
    let (mut a, mut b) = (copied(&start), written_before_read(&start));
    best_of(repeat, || {
        a.copy_from_slice(&start);
        for _ in 0..iterations {
            umbrella_pass(&a, &mut b, &rows, &scale, 0.5, None);
            std::mem::swap(&mut a, &mut b);
        }
    })
    .0
}

/// Triangles of the blob whose Laplace passes run with every array in cache (about 10 k
/// vertices: 0.7 MB of positions, rows and scales, within a core's L2 cache on common
/// machines: 1 MB on the one the issues were measured on).
pub const IN_CACHE_TRIANGLES: usize = 20_000;

/// `f` on a pool of one thread (on the current pool if one cannot be started).
fn on_one_thread<T: Send>(f: impl FnOnce() -> T + Send) -> T {
    match rayon::ThreadPoolBuilder::new().num_threads(1).build() {
        Ok(pool) => pool.install(f),
        Err(_) => f(),
    }
}

/// Best copy bandwidth over a 256 MB buffer in GB/s, counting bytes read and written.
pub fn copy_bandwidth(repeat: usize) -> f64 {
    use rayon::prelude::*;
    let n = 32 << 20;
    let src: Vec<u64> = (0..n as u64).into_par_iter().collect();
    let mut dst = vec![0u64; n];
    let (s, _) = best_of(repeat.max(3), || {
        dst.par_chunks_mut(1 << 16)
            .zip(src.par_chunks(1 << 16))
            .for_each(|(d, s)| d.copy_from_slice(s));
    });
    (2 * 8 * n) as f64 / s / 1e9
}

/// Every smoother with the bench's parameters; threshold 0 never stops a relaxation early, so
/// each runs all its iterations.
pub fn every_method(voxel: [f32; 3]) -> [crate::smooth::Method; 8] {
    use crate::smooth::Method;
    [
        Method::Laplace { lambda: 0.5 },
        Method::Taubin {
            lambda: 0.5,
            mu: -0.53,
        },
        Method::Hc {
            lambda: 0.5,
            alpha: 0.0,
            beta: 0.5,
        },
        Method::Mcf { lambda: 0.5 },
        Method::Npc { lambda: 0.5, voxel },
        Method::CellSize {
            lambda: 1.0,
            voxel,
            threshold: 0.0,
        },
        Method::CellEdge {
            lambda: 1.0,
            voxel,
            threshold: 0.0,
        },
        Method::Diamond {
            lambda: 1.0,
            voxel,
            threshold: 0.0,
        },
    ]
}

/// Times every smoother for `iterations` iterations on the `big` phantom of about
/// `triangles` triangles (relaxations run the full count, without stopping early), then the
/// Hausdorff distance between the phantom and its smoothed version.
pub fn smooth(triangles: usize, iterations: usize, repeat: usize) -> SmoothBench {
    use crate::smooth::{smooth, Method};
    use crate::weights::VertexWeights;
    let (mesh, spacing) = big_mesh(triangles);
    let topology = Topology::build(&mesh);
    let weights = VertexWeights::uniform(mesh.n_vertices());
    let fixed = vec![false; mesh.n_vertices()];
    let voxel = spacing.map(|x| x as f32);
    let methods = every_method(voxel);
    let mut smoothed = mesh.clone();
    let smoothers = methods
        .iter()
        .map(|method| {
            let (seconds, (positions, _)) = best_of(repeat, || {
                smooth(&mesh, &topology, method, iterations, &weights, &fixed)
            });
            if method.name() == "laplace" {
                smoothed.positions_mut().copy_from_slice(&positions);
            }
            SmoothTiming {
                method: method.name(),
                seconds,
                vertex_updates_per_s: (mesh.n_vertices() * iterations) as f64 / seconds,
            }
        })
        .collect();
    let laplace = Method::Laplace { lambda: 0.5 };
    let numberings = ["phantom", "scanline", "shuffled"]
        .into_iter()
        .map(|numbering| {
            // The same surface renumbered: vertex i of it is vertex old[i] of the phantom.
            let old: Vec<u32> = match numbering {
                "scanline" => {
                    let (o, n) = topology.neighbor_csr();
                    crate::mesh::order::scanline(mesh.positions(), o, n).old
                }
                "shuffled" => permutation(mesh.n_vertices(), 7),
                _ => (0..mesh.n_vertices() as u32).collect(),
            };
            let mut renamed = renumbered(&mesh, &old);
            if numbering == "shuffled" {
                // A file in no order: its faces listed at random too.
                renamed = relisted(&renamed, &permutation(mesh.n_triangles(), 8));
            }
            // As `smooth` and cohort runs work: a scattered file is renumbered once after
            // reading, and its result put back before writing.
            let working = crate::mesh::order::working_numbering(&renamed);
            let renumbering_seconds = working.as_ref().map(|_| {
                best_of(repeat, || {
                    crate::mesh::order::working_numbering(&renamed).map(|r| {
                        let worked = r.mesh(&renamed);
                        r.restore(&worked).n_vertices()
                    })
                })
                .0
            });
            let worked = match &working {
                Some(r) => std::borrow::Cow::Owned(r.mesh(&renamed)),
                None => std::borrow::Cow::Borrowed(&renamed),
            };
            let t = Topology::build(&worked);
            let w = VertexWeights::uniform(worked.n_vertices());
            let free = vec![false; worked.n_vertices()];
            let (seconds, (positions, _)) = best_of(repeat, || {
                smooth(&worked, &t, &laplace, iterations, &w, &free)
            });
            let passes_seconds = laplace_passes(&worked, &t, iterations, repeat);
            let positions = match &working {
                Some(r) => r.scatter(&positions),
                None => positions,
            };
            let max_difference_mm = positions
                .iter()
                .zip(&old)
                .map(|(p, &v)| {
                    let q = smoothed.positions()[v as usize];
                    (0..3).map(|k| (p[k] - q[k]).abs()).fold(0.0f32, f32::max)
                })
                .fold(0.0f32, f32::max);
            NumberingTiming {
                numbering,
                seconds,
                passes_seconds,
                renumbered: working.is_some(),
                renumbering_seconds,
                max_difference_mm,
            }
        })
        .collect();
    let copy_gb_per_s = copy_bandwidth(repeat);
    // Per iteration: positions read and written, offsets, step scales, and the neighbour lists.
    let (_, neighbors) = topology.neighbor_csr();
    let bytes = (mesh.n_vertices() * (12 + 12 + 4 + 4) + 4 * neighbors.len()) * iterations;
    let laplace_bound_s = bytes as f64 / (copy_gb_per_s * 1e9);
    let passes_one_thread_s =
        on_one_thread(|| laplace_passes(&mesh, &topology, iterations, repeat));
    let (small, _) = big_mesh(IN_CACHE_TRIANGLES);
    let small_topology = Topology::build(&small);
    // Enough iterations that the small mesh's passes take a measurable while.
    let small_iterations = 20 * iterations.max(1);
    let small_s =
        on_one_thread(|| laplace_passes(&small, &small_topology, small_iterations, repeat));
    let in_cache_updates_per_s = (small.n_vertices() * small_iterations) as f64 / small_s;
    let laplace_compute_bound_s = (mesh.n_vertices() * iterations) as f64
        / (in_cache_updates_per_s * rayon::current_num_threads() as f64);
    let (hausdorff_s, _) = best_of(repeat, || {
        crate::metrics::hausdorff_distance(&mesh, &smoothed)
    });
    let (self_intersections_s, self_intersections) = best_of(repeat, || {
        crate::spatial::intersect::self_intersections(&smoothed).len()
    });
    SmoothBench {
        n_vertices: mesh.n_vertices(),
        n_triangles: mesh.n_triangles(),
        iterations,
        threads: rayon::current_num_threads(),
        smoothers,
        numberings,
        copy_gb_per_s,
        laplace_bound_s,
        passes_one_thread_s,
        in_cache_updates_per_s,
        laplace_compute_bound_s,
        hausdorff_s,
        hausdorff_queries_per_s: (2 * mesh.n_vertices()) as f64 / hausdorff_s,
        self_intersections_s,
        self_intersections,
    }
}

/// Results of `destair bench context`.
#[derive(Debug, Serialize)]
pub struct ContextBench {
    pub n_vertices: usize,
    pub n_triangles: usize,
    /// Whether the mesh was [`shuffled`] first (vertex numbering and face order permuted).
    pub shuffled: bool,
    pub threads: usize,
    pub topology_s: f64,
    pub stack_axis_s: f64,
    pub staircase_weights_s: f64,
    pub caps_s: f64,
    /// All of the context analysis as `smooth` and `inspect --context` run it (axis estimated,
    /// staircase weights, caps; the caps searched beside the staircases; s).
    pub context_weights_s: f64,
    /// Building the index over the reference: its cells and its hierarchy (s).
    pub tree_build_s: f64,
    pub n_queries: usize,
    /// Exact point-to-surface queries near the surface (face centroids moved 1.5 mm along x;
    /// s) and their rate.
    pub queries_s: f64,
    pub queries_per_s: f64,
    /// The same number of queries 15 mm out along the faces' normals (12 mm from the surface
    /// on average on the `big` phantom, whose folds come closer to some), as for reference
    /// structures a centimetre or more away (s), their rate and their mean distance (mm).
    pub far_queries_s: f64,
    pub far_queries_per_s: f64,
    pub far_mean_distance_mm: f64,
}

/// How far out along the faces' normals `bench context` puts its far queries (mm).
const FAR_OFFSET_MM: f32 = 15.0;

/// Times context analysis on the `big` phantom of about `triangles` triangles, and exact
/// distance queries for about as many points (face centroids moved 1.5 mm off the surface)
/// against the same mesh as a reference; with `shuffle`, on the mesh [`shuffled`] (vertex
/// numbering and face order permuted).
pub fn context(triangles: usize, shuffle: bool, repeat: usize) -> ContextBench {
    use crate::analysis::{detect_caps, stack_axis, CapParams, StackAxisParams};
    use crate::spatial::TriangleBvh;
    use crate::weights::{staircase_weights, StaircaseParams};
    let (mesh, _) = big_mesh(triangles);
    let mesh = if shuffle { shuffled(&mesh, 7) } else { mesh };
    let (topology_s, topology) = best_of(repeat, || Topology::build(&mesh));
    let (stack_axis_s, _) = best_of(repeat, || {
        stack_axis(&mesh, &topology, &StackAxisParams::default())
    });
    let (staircase_weights_s, stairs) = best_of(repeat, || {
        staircase_weights(
            &mesh,
            &topology,
            [0.0, 0.0, 1.0],
            &StaircaseParams::default(),
        )
    });
    let reach: Vec<bool> = stairs.distance_mm.iter().map(|d| d.is_finite()).collect();
    let (caps_s, _) = best_of(repeat, || {
        detect_caps(&mesh, &topology, Some(&reach), &CapParams::default())
    });
    let (context_weights_s, _) = best_of(repeat, || {
        crate::weights::context_weights(&mesh, &topology, &Default::default(), &[])
    });
    let (tree_build_s, tree) = best_of(repeat, || {
        let tree = TriangleBvh::build(&mesh);
        tree.build_hierarchy();
        tree
    });
    let p = mesh.positions();
    let queries: Vec<[f32; 3]> = mesh
        .triangles()
        .iter()
        .map(|t| {
            let c: [f32; 3] = std::array::from_fn(|k| {
                (p[t[0] as usize][k] + p[t[1] as usize][k] + p[t[2] as usize][k]) / 3.0
            });
            [c[0] + 1.5, c[1], c[2]]
        })
        .collect();
    let (queries_s, _) = best_of(repeat, || tree.distances(&queries));
    let normals = crate::mesh::geometry::face_normals(&mesh);
    let far: Vec<[f32; 3]> = mesh
        .triangles()
        .iter()
        .zip(&normals)
        .map(|(t, n)| {
            std::array::from_fn(|k| {
                (p[t[0] as usize][k] + p[t[1] as usize][k] + p[t[2] as usize][k]) / 3.0
                    + FAR_OFFSET_MM * n[k]
            })
        })
        .collect();
    let (far_queries_s, far_distances) = best_of(repeat, || tree.distances(&far));
    let finite: Vec<f64> = far_distances
        .into_iter()
        .filter(|d| d.is_finite())
        .collect();
    ContextBench {
        n_vertices: mesh.n_vertices(),
        n_triangles: mesh.n_triangles(),
        shuffled: shuffle,
        threads: rayon::current_num_threads(),
        topology_s,
        stack_axis_s,
        staircase_weights_s,
        caps_s,
        context_weights_s,
        tree_build_s,
        n_queries: queries.len(),
        queries_s,
        queries_per_s: queries.len() as f64 / queries_s,
        far_queries_s,
        far_queries_per_s: far.len() as f64 / far_queries_s,
        far_mean_distance_mm: finite.iter().sum::<f64>() / finite.len().max(1) as f64,
    }
}

/// Results of `destair bench extract`.
#[derive(Debug, Serialize)]
pub struct LabelMapBench {
    pub dims: [usize; 3],
    pub n_labels: usize,
    pub threads: usize,
    /// Size of the `.nii.gz` (bytes).
    pub gz_bytes: u64,
    /// Best time to read and decode the `.nii.gz` into a label volume (s).
    pub read_nii_gz_s: f64,
    /// Best time for the same as uncompressed `.nii` (memory-mapped).
    pub read_nii_s: f64,
    /// Best time to extract every label's surface, consistently (s).
    pub extract_s: f64,
    /// Median of the same runs (s): this VM's timings move 20-30 % from run to run.
    pub extract_median_s: f64,
    /// Of which: all interfaces in one scan of the volume (best time, s).
    pub interfaces_s: f64,
    /// Of which: one closed surface per label from the interfaces (best time, s).
    pub assemble_s: f64,
    /// Best time to extract every label's constrained surface with the default settings
    /// (interfaces, smoothed weights, label surfaces; s).
    pub constrained_s: f64,
    /// Median of the same runs (s).
    pub constrained_median_s: f64,
    /// Triangles of all interfaces.
    pub n_interface_triangles: usize,
    /// Counting every label surface's triangles without making them (what the memory budget
    /// of a label-map case takes before extraction), best time (s).
    pub count_s: f64,
    /// Triangles of all label surfaces together, as counted.
    pub n_surface_triangles: u64,
}

/// A 512 x 512 x 300 u8 label map at 0.8 x 0.8 x 1.5 mm with 12 touching labels filling a
/// ball (the reference volume), written to `dir` and read back `repeat` times.
pub fn labelmap(dir: &Path, repeat: usize, keep: bool) -> std::io::Result<LabelMapBench> {
    use crate::volume::{nifti, read_label_map, Grid, LabelVolume, Space};
    let dims = [512usize, 512, 300];
    let grid = Grid::axis_aligned([0.8, 0.8, 1.5], [0.0; 3], Space::Lps);
    let values = (0..dims[2]).flat_map(|k| {
        (0..dims[1]).flat_map(move |j| {
            (0..dims[0]).map(move |i| {
                let (x, y, z) = (i as f64 / 512.0, j as f64 / 512.0, k as f64 / 300.0);
                let r2 = (x - 0.5).powi(2) + (y - 0.5).powi(2) + (z - 0.5).powi(2);
                if r2 > 0.16 {
                    0
                } else {
                    1 + (x * 3.0) as i64 + 3 * (y * 2.0) as i64 + 6 * (z * 2.0) as i64
                }
            })
        })
    });
    let volume = LabelVolume::from_values(dims, grid, values).map_err(std::io::Error::other)?;
    let mut out = LabelMapBench {
        dims,
        n_labels: volume.labels.len(),
        threads: rayon::current_num_threads(),
        gz_bytes: 0,
        read_nii_gz_s: 0.0,
        read_nii_s: 0.0,
        extract_s: 0.0,
        extract_median_s: 0.0,
        interfaces_s: 0.0,
        assemble_s: 0.0,
        constrained_s: 0.0,
        constrained_median_s: 0.0,
        n_interface_triangles: 0,
        count_s: 0.0,
        n_surface_triangles: 0,
    };
    let (s, size) = best_of(repeat, || crate::extract::surface_size(&volume, &[]));
    out.count_s = s;
    out.n_surface_triangles = size.triangles;
    let (s, all) = best_of(repeat, || crate::extract::interfaces(&volume, &[]));
    out.interfaces_s = s;
    (out.assemble_s, _) = best_of(repeat, || crate::extract::label_surfaces(&volume, &all));
    drop(all);
    // Until every surface exists: the outputs are dropped outside the timing, as the last
    // run's are by `best_of`.
    let mut times = Vec::with_capacity(repeat.max(1));
    let (s, (all, _surfaces)) = best_of(repeat, || {
        let t = Instant::now();
        let all = crate::extract::interfaces(&volume, &[]);
        let surfaces = crate::extract::label_surfaces(&volume, &all);
        times.push(t.elapsed().as_secs_f64());
        (all, surfaces)
    });
    out.extract_s = s;
    times.sort_by(f64::total_cmp);
    out.extract_median_s = times[times.len() / 2];
    out.n_interface_triangles = all.triangles.len();
    drop((all, _surfaces));
    let mut times = Vec::with_capacity(repeat.max(1));
    let (s, _surfaces) = best_of(repeat, || {
        let t = Instant::now();
        let smoothing = vec![Default::default(); volume.labels.len() + 1];
        let mut all = crate::extract::interfaces(&volume, &[]);
        crate::extract::constrained::place_on_weights(&volume, &mut all, &smoothing);
        let surfaces = crate::extract::label_surfaces(&volume, &all);
        times.push(t.elapsed().as_secs_f64());
        surfaces
    });
    out.constrained_s = s;
    times.sort_by(f64::total_cmp);
    out.constrained_median_s = times[times.len() / 2];
    drop(_surfaces);
    for gz in [true, false] {
        let path = dir.join(if gz {
            "destair-bench.nii.gz"
        } else {
            "destair-bench.nii"
        });
        let bytes = nifti::encode(&volume, gz).map_err(std::io::Error::other)?;
        crate::io::write_atomically(&path, |w| w.write_all(&bytes))?;
        let (s, read) = best_of(repeat, || read_label_map(&path, Space::Lps));
        if !keep {
            let _ = std::fs::remove_file(&path);
        }
        read.map_err(|e| std::io::Error::other(e.to_string()))?;
        if gz {
            out.gz_bytes = bytes.len() as u64;
            out.read_nii_gz_s = s;
        } else {
            out.read_nii_s = s;
        }
    }
    Ok(out)
}
