//! `destair extract`: one surface per label of a label map, all extracted at once so that
//! touching structures share their interface, plus `extract.json`.

use super::{LabelMapInputError, SpaceArg, UsageError};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// Label map (.nii, .nii.gz, .nrrd, .seg.nrrd, .nhdr).
    labelmap: PathBuf,
    /// Output folder: one mesh per label, and extract.json.
    #[arg(long)]
    out: PathBuf,
    /// Names for label values, e.g. 1=tumor,2=vein (they win over names in the file).
    #[arg(long, value_parser = parse_labels)]
    labels: Option<LabelNames>,
    /// Most distinct labels the map may hold (more is an image, not a segmentation).
    #[arg(long, default_value_t = 255, value_parser = clap::value_parser!(u16).range(1..))]
    max_labels: u16,
    /// World convention of the meshes: lps (3D Slicer's) or ras.
    #[arg(long, value_enum, default_value_t = SpaceArg::Lps)]
    space: SpaceArg,
    /// Mesh format: ply or stl.
    #[arg(long, value_enum, default_value_t = FormatArg::Ply)]
    format: FormatArg,
    /// constrained: label weights smoothed with a Gaussian and clamped so every voxel keeps its
    /// label (thesis §6.3), vertices at sub-voxel positions (smooth); binary: vertices at
    /// cell-edge midpoints (terraced).
    #[arg(long, value_enum, default_value_t = SurfaceArg::Constrained)]
    surface: SurfaceArg,
    /// Gaussian sigma for --surface constrained (mm; default 1.5 times the smallest spacing, at most twice it).
    #[arg(long)]
    sigma_mm: Option<f64>,
    /// One- and two-voxel bumps and pits: smooth relaxes their constraint into gentle
    /// swellings (§6.3.3), keep pins them like every voxel.
    #[arg(long, value_enum)]
    noise: Option<NoiseArg>,
    /// Parts one voxel thick: protect keeps a real thickness there (§6.3.4), off lets them
    /// shrink onto their voxel centres.
    #[arg(long, value_enum)]
    thin: Option<ThinArg>,
    /// Which voxels of a label form one object: 26 joins voxels that touch by a face, an edge
    /// or a corner (segmentation tools' convention: thin oblique vessels stay one piece); 6
    /// joins only voxels that share a face.
    #[arg(long, default_value_t = 26, value_parser = parse_connectivity)]
    connectivity: u8,
    /// Also write all interfaces as one PLY with per-face `inner_label` and `outer_label` (the
    /// label values on the two sides; 0 is background), as tetrahedral meshers with regions
    /// take. Further layers of a .seg.nrrd go to FILE_layerN.ply.
    #[arg(long, value_name = "FILE.ply")]
    combined: Option<PathBuf>,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum SurfaceArg {
    Binary,
    Constrained,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum NoiseArg {
    Smooth,
    Keep,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum ThinArg {
    Protect,
    Off,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum FormatArg {
    Ply,
    Stl,
}

fn parse_connectivity(s: &str) -> Result<u8, String> {
    match s.trim() {
        "26" => Ok(26),
        "6" => Ok(6),
        _ => Err(format!("{s:?}: must be 26 or 6")),
    }
}

/// `VALUE=NAME` pairs from `--labels`.
#[derive(Clone, Debug)]
struct LabelNames(Vec<(i64, String)>);

fn parse_labels(s: &str) -> Result<LabelNames, String> {
    s.split(',')
        .map(|pair| {
            let (v, n) = pair
                .split_once('=')
                .ok_or_else(|| format!("expected VALUE=NAME, got {pair:?}"))?;
            let value = v
                .trim()
                .parse::<i64>()
                .map_err(|_| format!("label value {v:?} is not a whole number"))?;
            let name = n.trim();
            if name.is_empty() {
                return Err(format!("label {value} has an empty name"));
            }
            Ok((value, name.to_string()))
        })
        .collect::<Result<_, _>>()
        .map(LabelNames)
}

/// Bytes `extract` holds per surface triangle, with room: measured 66 for 3.4 M triangles of a
/// noise map (constrained surfaces, PLY written).
const EXTRACT_BYTES_PER_TRIANGLE: u64 = 100;

pub fn exec(args: Args) -> anyhow::Result<()> {
    let space = args.space.space();
    if let Some(s) = args.sigma_mm {
        if !(s.is_finite() && s > 0.0) {
            return Err(
                UsageError(format!("--sigma-mm {s}: must be a positive number of mm")).into(),
            );
        }
    }
    if matches!(args.surface, SurfaceArg::Binary) {
        for (given, flag) in [
            (args.sigma_mm.is_some(), "--sigma-mm"),
            (args.noise.is_some(), "--noise"),
            (args.thin.is_some(), "--thin"),
        ] {
            if given {
                return Err(UsageError(format!("{flag} applies to --surface constrained")).into());
            }
        }
    }
    if args.out.exists() && !args.out.is_dir() {
        return Err(UsageError(format!(
            "{}: exists and is not a folder",
            args.out.display()
        ))
        .into());
    }
    let started = std::time::Instant::now();
    let limits = destair::volume::LabelMapLimits {
        max_labels: args.max_labels.into(),
        ..Default::default()
    };
    // What reading and the surfaces need, against what this process may use, before either.
    let memory = destair::job::memory::process_memory_limit();
    let connectivity = match args.connectivity {
        6 => destair::extract::Connectivity::Faces,
        _ => destair::extract::Connectivity::Corners,
    };
    let too_much = |need: u64, what: &str| -> anyhow::Error {
        LabelMapInputError(destair::volume::LabelMapError {
            path: args.labelmap.clone(),
            message: format!(
                "{what} needs about {} MB; this process may use {} MB ({})",
                need.div_ceil(1 << 20),
                memory.bytes.div_ceil(1 << 20),
                memory.source
            ),
        })
        .into()
    };
    let header = destair::volume::read_header(&args.labelmap).map_err(LabelMapInputError)?;
    if header.bytes_to_read() > memory.bytes {
        return Err(too_much(header.bytes_to_read(), "reading its voxels"));
    }
    let mut map = destair::volume::read_label_map_within(&args.labelmap, space, &limits)
        .map_err(LabelMapInputError)?;
    let triangles: u64 = map
        .layers
        .iter()
        .map(|l| {
            destair::extract::surface_size(l, &vec![connectivity; l.labels.len() + 1]).triangles
        })
        .sum();
    let need = header
        .bytes_to_read()
        .saturating_add(triangles.saturating_mul(EXTRACT_BYTES_PER_TRIANGLE));
    if need > memory.bytes {
        return Err(too_much(
            need,
            &format!("making its surfaces ({triangles} triangles)"),
        ));
    }
    if let Some(sigma) = args.sigma_mm {
        for layer in &map.layers {
            destair::extract::constrained::check_sigma(sigma, layer)
                .map_err(|e| UsageError(format!("{}: --sigma-mm: {e}", args.labelmap.display())))?;
        }
    }
    let read_s = started.elapsed().as_secs_f64();
    if let Some(names) = &args.labels {
        for (value, name) in &names.0 {
            let mut found = false;
            for layer in &mut map.layers {
                for l in layer.labels.iter_mut().filter(|l| l.value == *value) {
                    l.name = name.clone();
                    found = true;
                }
            }
            if !found {
                eprintln!("warning: --labels names {value}={name}, but no voxel holds {value}");
            }
        }
    }
    std::fs::create_dir_all(&args.out)
        .map_err(|e| UsageError(format!("{}: cannot create: {e}", args.out.display())))?;
    let meta = destair::io::MeshMeta {
        comments: vec![
            format!("SPACE={}", space.tag()),
            format!(
                "destair extract {}",
                args.labelmap
                    .file_name()
                    .unwrap_or_default()
                    .to_string_lossy()
            ),
        ],
        obj_info: Vec::new(),
    };
    let ext = match args.format {
        FormatArg::Ply => "ply",
        FormatArg::Stl => "stl",
    };
    let mut rows = Vec::new();
    let mut warnings = Vec::new();
    let mut used = std::collections::BTreeSet::new();
    let t_extract = std::time::Instant::now();
    use destair::extract::constrained::{LabelSmoothing, Noise, Surface, Thin};
    let smoothing = LabelSmoothing {
        surface: match args.surface {
            SurfaceArg::Binary => Surface::Binary,
            SurfaceArg::Constrained => Surface::Constrained,
        },
        sigma_mm: args.sigma_mm,
        noise: match args.noise {
            Some(NoiseArg::Keep) => Noise::Keep,
            _ => Noise::Smooth,
        },
        thin: match args.thin {
            Some(ThinArg::Off) => Thin::Off,
            _ => Thin::Protect,
        },
        connectivity,
    };
    let surfaces_of = |layer: &destair::volume::LabelVolume| {
        let per_label = vec![smoothing; layer.labels.len() + 1];
        let mut all = destair::extract::interfaces(
            layer,
            &destair::extract::constrained::connectivity_of(&per_label),
        );
        // The binary surfaces measured too, to report what the smoothing changed (and dropped
        // before the constrained ones are made).
        let binary = (smoothing.surface == Surface::Constrained).then(|| {
            use rayon::prelude::*;
            destair::extract::label_surfaces(layer, &all)
                .into_par_iter()
                .map(|s| {
                    (
                        s.label,
                        destair::extract::report::SurfaceMeasure::of(&s.mesh),
                    )
                })
                .collect::<Vec<_>>()
        });
        let counts = destair::extract::constrained::place_on_weights(layer, &mut all, &per_label);
        (all, counts, binary)
    };
    // Interfaces kept for --combined, which writes the same surfaces as one mesh.
    let mut kept = Vec::new();
    for (layer_index, layer) in map.layers.iter().enumerate() {
        let (all, counts, binary) = surfaces_of(layer);
        let joins = destair::extract::joins_of(layer, &vec![connectivity; layer.labels.len() + 1]);
        let objects = destair::volume::components::label_components(layer, &joins);
        let surfaces = destair::extract::label_surfaces(layer, &all);
        if args.combined.is_some() {
            kept.push(all);
        }
        // File names first (in label order, so clashes resolve the same way every time), then
        // the labels written and measured in parallel.
        let mut jobs = Vec::with_capacity(surfaces.len());
        let mut binary = binary.map(|b| b.into_iter());
        for s in surfaces {
            // Both lists are in label order.
            let binary = binary
                .as_mut()
                .and_then(|b| b.find(|(l, _)| *l == s.label))
                .map(|(_, measure)| measure);
            let label = &layer.labels[s.label as usize - 1];
            let mut stem = destair::volume::label_file_stem(&label.name, label.value);
            if !used.insert(stem.clone()) {
                stem = format!("{stem}_{}", label.value);
                used.insert(stem.clone());
            }
            let file = format!("{stem}.{ext}");
            super::refuse_overwriting_inputs(
                &args.out.join(&file),
                &[args.labelmap.as_path()],
                false,
            )?;
            let extraction = destair::extract::report::Extraction::new(
                layer,
                &smoothing,
                objects[s.label as usize],
                &s.mesh,
                counts[s.label as usize],
            );
            if let Some(w) = extraction.pieces_warning() {
                warnings.push(format!("label {} ({}): {w}", label.value, label.name));
            }
            jobs.push((label, file, s.mesh, extraction, binary));
        }
        use rayon::prelude::*;
        let written: Vec<anyhow::Result<_>> = jobs
            .into_par_iter()
            .map(|(label, file, mesh, extraction, binary)| {
                let path = args.out.join(&file);
                match args.format {
                    FormatArg::Ply => destair::io::ply::write_ply(&path, &mesh, &meta, &[])?,
                    FormatArg::Stl => destair::io::stl::write_stl(&path, &mesh, &meta)?,
                }
                Ok(destair::extract::report::extracted_label(
                    layer_index,
                    label,
                    file,
                    &mesh,
                    &layer.grid,
                    extraction,
                    binary,
                ))
            })
            .collect();
        for row in written {
            rows.push(row?);
        }
    }
    let extract_s = t_extract.elapsed().as_secs_f64();
    if let Some(path) = &args.combined {
        for (layer_index, (layer, all)) in map.layers.iter().zip(&kept).enumerate() {
            let path = if layer_index == 0 {
                path.clone()
            } else {
                let stem = path.file_stem().unwrap_or_default().to_string_lossy();
                path.with_file_name(format!("{stem}_layer{layer_index}.ply"))
            };
            super::refuse_overwriting_inputs(&path, &[args.labelmap.as_path()], false)?;
            let (mesh, sides) = destair::extract::combined_surface(layer, all);
            let int = |v: i64| {
                i32::try_from(v).map_err(|_| {
                    UsageError(format!(
                        "{}: label value {v} does not fit the combined PLY's int face property",
                        args.labelmap.display()
                    ))
                })
            };
            let inner = sides
                .iter()
                .map(|s| int(s[0]))
                .collect::<Result<Vec<_>, _>>()?;
            let outer = sides
                .iter()
                .map(|s| int(s[1]))
                .collect::<Result<Vec<_>, _>>()?;
            destair::io::ply::write_ply_with_faces(
                &path,
                &mesh,
                &meta,
                &[],
                &[("inner_label", &inner), ("outer_label", &outer)],
            )?;
            println!(
                "{}: {} interface triangles of layer {layer_index}",
                path.display(),
                mesh.n_triangles()
            );
        }
    }
    let g = map.layers[0].grid;
    let report = destair::extract::report::ExtractReport {
        source: args.labelmap.display().to_string(),
        space: space.tag().into(),
        dims: map.layers[0].dims,
        spacing_mm: g.spacing(),
        affine: g.affine(),
        labels: rows,
        warnings: map.warnings.iter().cloned().chain(warnings).collect(),
    };
    let json = serde_json::to_vec_pretty(&report)?;
    let path = args.out.join("extract.json");
    destair::io::write_atomically(&path, |w| w.write_all(&json)).map_err(|source| {
        destair::io::WriteError::Io {
            path: path.clone(),
            source,
        }
    })?;
    for l in &report.labels {
        println!(
            "{}: label {} ({}), {} voxels, {} triangles, volume {:.1} mm³ (voxels {:.1} mm³)",
            args.out.join(&l.file).display(),
            l.value,
            l.name,
            l.n_voxels,
            l.n_triangles,
            l.mesh_volume_mm3,
            l.voxel_volume_mm3
        );
    }
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    eprintln!("read in {read_s:.2} s, extracted in {extract_s:.2} s");
    Ok(())
}
