//! `destair smooth`: one mesh through one of the papers' smoothers.

use super::{read_input, refuse_overwriting_inputs, ContextArgs, Rejected, UsageError};
use destair::io::ReadOptions;
use destair::report::inspect::describe_voxel_size;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// Input mesh (.ply, .stl, .obj).
    input: PathBuf,
    /// Output mesh (.ply or .stl); vertex order is kept.
    #[arg(short, long)]
    output: PathBuf,
    /// laplace, hc, taubin, mcf, npc, cell-size, cell-edge or diamond (default hc, as in a
    /// cohort config).
    #[arg(long, default_value = "hc")]
    method: destair::smooth::MethodKind,
    /// Iterations (the maximum for cell-size, cell-edge and diamond, which stop on convergence).
    #[arg(long)]
    iterations: Option<usize>,
    /// Step factor (default 0.5; 1 for the constrained relaxations).
    #[arg(long)]
    lambda: Option<f32>,
    /// Taubin's negative factor (default -0.53).
    #[arg(long, allow_negative_numbers = true)]
    mu: Option<f32>,
    /// Laplace+HC: pull towards the original (0, default) or previous (1) positions.
    #[arg(long)]
    alpha: Option<f32>,
    /// Laplace+HC: share of a vertex's own correction (default 0.5).
    #[arg(long)]
    beta: Option<f32>,
    /// Voxel size in mm as X,Y,Z (default: reconstructed from the mesh).
    #[arg(long, value_parser = super::parse_voxel)]
    voxel: Option<[f32; 3]>,
    /// Relaxations stop when no vertex moves more than this in one iteration (mm; default 0.002).
    #[arg(long)]
    threshold: Option<f32>,
    /// PLY file with a per-vertex `weight` property in [0, 1] (same vertices as the input).
    #[arg(long)]
    weights: Option<PathBuf>,
    /// Let vertices on open boundary loops move (by default clipped rims stay in place).
    #[arg(long)]
    move_boundary: bool,
    /// Add `weight` and `displacement` (mm) vertex properties to a PLY output.
    #[arg(long)]
    annotate: bool,
    /// Weight by staircases (Moench): smooth artifacts, keep the rest. On by default, as in a
    /// cohort config; `--staircase false` turns it off (caps are still kept unless `--caps
    /// smooth`).
    #[arg(long, default_value_t = true, num_args = 0..=1, default_missing_value = "true",
          action = clap::ArgAction::Set)]
    staircase: bool,
    /// Allow the output to replace the input file.
    #[arg(long)]
    force: bool,
    /// Refuse the result if a vertex moved further than this many voxel diagonals (diverged).
    #[arg(long, default_value_t = destair::smooth::DEFAULT_MAX_DISPLACEMENT_VOXELS)]
    max_displacement_voxels: f32,
    /// `cfd`: ready the vessel for a flow solver. Its patches (caps, open ends) are found
    /// first and held while smoothing; then open ends are closed (--close-open-ends), the
    /// surface is remeshed (--edge-mm or --edge-per-radius), checked (watertight, oriented, no
    /// self-intersection, no degenerate face), and the patch files are written next to the
    /// output (OUTPUT-STEM_solids.stl, one STL per patch, .vtp, _patches.json). Flow extensions
    /// with --flow-extension.
    #[arg(long, conflicts_with = "annotate")]
    profile: Option<Profile>,
    /// cfd profile: remesh to this edge length (mm).
    #[arg(long, requires = "profile")]
    edge_mm: Option<f64>,
    /// cfd profile: remesh to this multiple of the local vessel radius.
    #[arg(long, requires = "profile", conflicts_with = "edge_mm")]
    edge_per_radius: Option<f64>,
    /// cfd profile: close open ends with flat caps.
    #[arg(long, requires = "profile")]
    close_open_ends: bool,
    /// cfd profile: keep the patch rims as the input has them (by default they are smoothed
    /// within their patch's plane, which takes out the voxel zigzag of a clipped rim).
    #[arg(long, requires = "profile")]
    keep_rims: bool,
    /// cfd profile: add a straight flow extension of this many equivalent diameters at every
    /// patch (or at the patches of --extend), ending in a flat cap.
    #[arg(long, requires = "profile")]
    flow_extension: Option<f64>,
    /// cfd profile: the patch ids that get a flow extension (comma-separated; default all).
    #[arg(long, requires = "flow_extension", value_delimiter = ',')]
    extend: Vec<u32>,
    /// cfd profile: the inlet: `largest`, a patch index by decreasing area, or X,Y,Z (mm).
    #[arg(long, default_value = "largest", requires = "profile")]
    inlet: destair::cfd::Inlet,
    /// cfd profile: the number of patches the vessel has; another count fails.
    #[arg(long, requires = "profile")]
    expect_patches: Option<usize>,
    #[command(flatten)]
    ctx: ContextArgs,
}

/// What `--profile` readies a surface for.
#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum Profile {
    Cfd,
}

pub fn exec(args: Args) -> anyhow::Result<()> {
    use destair::smooth::{boundary_vertices, smooth};
    let Args {
        input,
        output,
        method,
        iterations,
        lambda,
        mu,
        alpha,
        beta,
        voxel,
        threshold,
        weights,
        move_boundary,
        annotate,
        staircase,
        force,
        max_displacement_voxels,
        profile,
        edge_mm,
        edge_per_radius,
        close_open_ends,
        keep_rims,
        flow_extension,
        extend,
        inlet,
        expect_patches,
        ctx,
    } = args;
    ctx.check()?;
    let mut inputs = vec![input.as_path()];
    inputs.extend(weights.as_deref());
    inputs.extend(ctx.references.iter().map(PathBuf::as_path));
    refuse_overwriting_inputs(&output, &inputs, force)?;
    if let Some(n) = iterations {
        destair::smooth::check_iterations(n)
            .map_err(|m| UsageError(format!("--iterations: {m}")))?;
    }
    let params = destair::smooth::MethodParams {
        lambda,
        mu,
        alpha,
        beta,
        threshold,
    };
    method.check(&params).map_err(UsageError)?;
    if !(max_displacement_voxels.is_finite() && max_displacement_voxels > 0.0) {
        return Err(
            UsageError("--max-displacement-voxels must be a positive number".into()).into(),
        );
    }
    let format = destair::io::OutputFormat::of_path(&output).ok_or_else(|| {
        UsageError(format!(
            "{}: the output must end in .ply, .stl or .vtp",
            output.display()
        ))
    })?;
    if annotate && !format.holds_arrays() {
        return Err(UsageError(
            "--annotate adds vertex properties, which STL cannot hold: write a .ply or .vtp output"
                .into(),
        )
        .into());
    }
    if profile.is_some() && format == destair::io::OutputFormat::Vtp {
        return Err(UsageError(
            "--profile cfd writes STEM.vtp (with CellEntityIds) itself: name the main output .ply or .stl".into(),
        )
        .into());
    }
    let folder = match output.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => std::path::Path::new("."),
    };
    if !folder.is_dir() {
        return Err(UsageError(format!(
            "{}: the output folder does not exist",
            folder.display()
        ))
        .into());
    }
    let cfd = match profile {
        Some(Profile::Cfd) => Some(
            destair::cfd::CfdProfile::new(destair::cfd::CfdOptions {
                inlet: Some(inlet),
                expect_patches,
                edge_mm,
                edge_per_radius,
                flow_extension,
                extend,
                close_open_ends,
                keep_rims,
            })
            .map_err(|m| UsageError(format!("--profile cfd: {m}")))?,
        ),
        None => None,
    };
    let mut loaded = read_input(&input, &ReadOptions::default())?;
    // A scattered numbering is worked in scanline order, as a cohort run does, and written back
    // in the file's (the cfd profile keeps the file's: its outputs are new surfaces).
    let renumbering = match cfd {
        None => destair::mesh::order::working_numbering(&loaded.mesh),
        Some(_) => None,
    };
    if let Some(r) = &renumbering {
        loaded.mesh = r.mesh(&loaded.mesh);
    }
    let mesh = &loaded.mesh;
    let topology = destair::Topology::build(mesh);
    let stem = output
        .file_stem()
        .map_or_else(|| "vessel".into(), |s| s.to_string_lossy().into_owned());
    // The cfd profile's patches, found before smoothing so the smoother can hold them, and
    // their rims smoothed in their planes.
    let prepared = match &cfd {
        Some(profile) => {
            let prepared = destair::cfd::prepare_surface(mesh, &topology, profile)
                .map_err(|e| Rejected(format!("{}: {e}; nothing written", input.display())))?;
            for path in destair::cfd::outputs::planned_files(folder, &stem, &prepared.patches) {
                refuse_overwriting_inputs(&path, &inputs, force)?;
            }
            Some(prepared)
        }
        None => None,
    };
    // Context weights (as a cohort computes them: staircases when on, caps as `--caps` says,
    // distances when references are given) unless given in a file, found beside the voxel
    // size estimate: both only read the mesh, and each has serial stretches the other fills.
    let trees = match weights {
        None => ctx.reference_trees()?,
        Some(_) => Vec::new(),
    };
    let (estimate, found) = rayon::join(
        || destair::analysis::voxel_size(mesh, &topology),
        || match weights {
            None => {
                let refs: Vec<&destair::spatial::TriangleBvh> = trees.iter().collect();
                // Caps smoothed like the rest change nothing written here: not looked for.
                let params = destair::weights::ContextParams {
                    find_smoothed_caps: false,
                    ..ctx.params(staircase)
                };
                Ok(destair::weights::context_weights(
                    mesh, &topology, &params, &refs,
                ))
            }
            Some(path) => Err(path),
        },
    );
    let voxel = match (voxel, method.needs_voxel()) {
        (Some(v), needs) => {
            if needs && estimate.is_irregular() {
                eprintln!(
                    "warning: {}: --voxel is used, but the voxel size is {}; {} constrains along grid axes that this mesh may not follow",
                    input.display(),
                    describe_voxel_size(&estimate),
                    method.name()
                );
            }
            Some(v)
        }
        (None, false) => estimate.spacing().map(|s| s.map(|x| x as f32)),
        (None, true) => {
            let s = estimate.spacing().ok_or_else(|| {
                UsageError(format!(
                    "{}: {} needs the voxel size, which is {}; pass --voxel X,Y,Z",
                    input.display(),
                    method.name(),
                    describe_voxel_size(&estimate)
                ))
            })?;
            Some(s.map(|x| x as f32))
        }
    };
    let kind = method;
    let method = kind.build(&params, voxel.unwrap_or([1.0; 3]));
    let iterations = iterations.unwrap_or(kind.default_iterations());
    let weights = match found {
        Ok(analysis) => {
            let summary = destair::report::inspect::context_summary(&analysis, mesh.n_vertices());
            eprint!("{}", summary.to_text());
            analysis.weights
        }
        Err(path) => {
            let options = ReadOptions {
                keep_vertex_properties: true,
                ..Default::default()
            };
            let w = read_input(&path, &options)?;
            let values = w
                .vertex_properties
                .into_iter()
                .find(|p| p.name == "weight")
                .ok_or_else(|| {
                    UsageError(format!("{}: no vertex property 'weight'", path.display()))
                })?
                .values;
            let w = destair::weights::VertexWeights::new(values, mesh.n_vertices())
                .map_err(|e| UsageError(format!("{}: {e}", path.display())))?;
            match &renumbering {
                Some(r) => w.gathered(r),
                None => w,
            }
        }
    };
    let mut fixed = if move_boundary {
        vec![false; mesh.n_vertices()]
    } else {
        boundary_vertices(&topology)
    };
    if let Some(p) = &prepared {
        for (f, &h) in fixed.iter_mut().zip(&p.held) {
            *f |= h;
        }
    }
    let start = prepared.as_ref().map_or(mesh, |p| &p.start);
    let started = std::time::Instant::now();
    let (positions, stats) = smooth(start, &topology, &method, iterations, &weights, &fixed);
    let seconds = started.elapsed().as_secs_f64();
    destair::smooth::check_result(
        mesh.positions(),
        &positions,
        max_displacement_voxels,
        destair::smooth::displacement_unit(mesh, &topology, voxel),
        renumbering.as_ref(),
    )
    .map_err(|m| Rejected(format!("{}: {m}; nothing written", input.display())))?;
    // VTP always carries the arrays (it is the viewers' format); PLY with --annotate.
    let lengths: Option<Vec<f32>> =
        (prepared.is_none() && (annotate || format == destair::io::OutputFormat::Vtp)).then(|| {
            destair::metrics::displacements(mesh.positions(), &positions)
                .into_iter()
                .map(|d| d as f32)
                .collect()
        });
    let (smoothed, cfd) = match (&prepared, &cfd) {
        (Some(p), Some(profile)) => {
            let mut smoothed = mesh.clone();
            smoothed.positions_mut().copy_from_slice(&positions);
            let done = destair::cfd::finish_surface(mesh, &smoothed, p, &profile.finish)
                .map_err(|e| Rejected(format!("{}: {e}; nothing written", input.display())))?;
            (done.mesh.clone(), Some(done))
        }
        // The input's own faces take the new positions: no copy of every face (but for a
        // renumbered input, which goes back to the file's numbering).
        _ => {
            let mut smoothed = loaded.mesh;
            smoothed.positions_mut().copy_from_slice(&positions);
            match &renumbering {
                Some(r) => (r.restore(&smoothed), None),
                None => (smoothed, None),
            }
        }
    };
    let mut named: Vec<(&str, Vec<f32>)> = Vec::new();
    if let Some(lengths) = lengths {
        named = vec![("weight", weights.into_inner()), ("displacement", lengths)];
        if let Some(r) = &renumbering {
            for (_, values) in &mut named {
                *values = r.scatter(values);
            }
        }
    }
    let arrays: Vec<(&str, &[f32])> = named.iter().map(|(n, v)| (*n, v.as_slice())).collect();
    destair::io::write_annotated(&output, &smoothed, &loaded.meta, &arrays, "displacement")?;
    println!(
        "{} {}: {} iterations{} in {:.3} s, last step {:.5} mm, {} vertices fixed -> {}",
        method.name(),
        input.display(),
        stats.iterations,
        if method.is_relaxation() {
            if stats.converged {
                " (converged)"
            } else {
                " (not converged)"
            }
        } else {
            ""
        },
        seconds,
        stats.last_max_step,
        stats.n_fixed,
        output.display()
    );
    if let Some(done) = &cfd {
        print!("{}", destair::report::inspect::patches_text(&done.patches));
        let q = &done.checks.quality;
        print!(
            "  checks passed: watertight{}, oriented, no self-intersection, no degenerate face; min angle {:.1} deg (1st percentile {:.1})",
            if done.checks.open_ends_allowed { " but for the open ends" } else { "" },
            q.min_angle_deg,
            q.p1_angle_deg
        );
        if let (Some(e), Some(r)) = (&done.checks.edges, &done.remeshed) {
            print!(
                "; remeshed in {:.2} s: {} triangles, edges {:.3}-{:.3} mm (mean {:.3}), {:.1} % within 20 % of the target, surface moved {:.4} mm at most",
                r.seconds,
                done.mesh.n_triangles(),
                e.min_mm,
                e.max_mm,
                e.mean_mm,
                100.0 * e.within_20_percent,
                r.hausdorff_mm
            );
        }
        println!();
        let written = destair::cfd::write_patch_files(
            folder,
            &stem,
            &done.mesh,
            &loaded.meta,
            &done.patches,
        )?;
        for path in written {
            println!("  wrote {}", path.display());
        }
    }
    Ok(())
}
