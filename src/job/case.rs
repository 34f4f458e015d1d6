//! Processing one loaded case ([`super::load`]): for each structure resolve its settings and
//! references, weight, smooth, measure and encode the outputs. Everything a case produces
//! is returned as bytes and a report; writing them (atomically) is the pipeline's writer's job.
//! A failing structure is recorded in the report; it never stops the case or the cohort.

use super::guard::{guard_case, Kept};
use super::label_map::{header_geometry, label_structures, Place};
use super::load::{LoadedCase, LoadedFile};
use super::pictures::PictureInput;
use super::plan::{Plan, StructureSettings};
use crate::io::{LoadedMesh, OutputFormat};
use crate::mesh::order::Renumbering;
use crate::mesh::{Mesh, Topology};
use crate::report::case::{CaseReport, CfdReport, InputInfo, StructureReport, SCHEMA_VERSION};
use crate::report::compare::compare_prepared;
use crate::report::inspect::context_summary;
use crate::smooth::{boundary_vertices, smooth};
use crate::spatial::TriangleBvh;
use crate::weights::{context_weights, AxisChoice, ContextParams};
use std::collections::BTreeMap;
use std::time::Instant;

/// Everything a processed case leaves behind.
#[derive(Debug)]
pub struct CaseOutput {
    pub id: String,
    /// Output files (name within the case's output folder, bytes).
    pub files: Vec<(String, Vec<u8>)>,
    pub report: CaseReport,
    /// Seconds per stage and structure (not deterministic, so kept out of the report).
    pub timings: serde_json::Value,
    pub key: String,
}

impl CaseOutput {
    /// Whether the case failed.
    pub fn failed(&self) -> bool {
        self.report.status != "ok"
    }
}

/// Encodes a mesh in each output format as `<stem>.<ext>`; returns (file name, bytes) pairs.
/// VTP carries the per-vertex `arrays` always, PLY only with `[output] annotate`. `formats`
/// is the plan's list, less any a caller writes itself. A mesh worked in the file's
/// `renumbering` goes back to the file's numbering first, its arrays with it.
fn encode(
    plan: &Plan,
    formats: &[OutputFormat],
    stem: &str,
    mesh: &Mesh,
    loaded: &LoadedMesh,
    arrays: &[(&str, &[f32])],
    renumbering: Option<&Renumbering>,
) -> Result<Vec<(String, Vec<u8>)>, String> {
    // Whether format `f` writes the arrays: they are scattered back only if one does.
    let written = |f: OutputFormat| f != OutputFormat::Ply || plan.annotate;
    let keep_arrays = formats.iter().any(|&f| written(f));
    let (restored, scattered): (Mesh, Vec<(&str, Vec<f32>)>);
    let (mesh, arrays) = match renumbering {
        Some(r) => {
            restored = r.restore(mesh);
            let kept = arrays.iter().filter(|_| keep_arrays);
            scattered = kept.map(|&(n, v)| (n, r.scatter(v))).collect();
            let named = scattered.iter().map(|(n, v)| (*n, v.as_slice())).collect();
            (&restored, named)
        }
        None => (mesh, arrays.to_vec()),
    };
    formats
        .iter()
        .map(|&f| {
            let arrays = if written(f) { &arrays[..] } else { &[][..] };
            crate::io::encode_annotated(f, mesh, &loaded.meta, arrays, "displacement")
                .map(|b| (format!("{stem}.{}", f.extension()), b))
                .map_err(|e| e.to_string())
        })
        .collect()
}

/// Processes every structure of a loaded case.
pub fn process_case(plan: &Plan, case: LoadedCase) -> CaseOutput {
    let started = Instant::now();
    let mut trees: BTreeMap<(String, Option<usize>), TriangleBvh> = BTreeMap::new();
    let mut files = Vec::new();
    let mut structures = Vec::new();
    let mut timings = serde_json::Map::new();
    let mut case_errors: Vec<String> = case.input.errors.clone();
    let mut case_warnings: Vec<String> = case.input.problems.clone();
    // Label maps: every label becomes a structure, beside the mesh files.
    let mut label_map_infos = Vec::new();
    let mut all: Vec<LoadedFile> = Vec::new();
    let had_label_maps = !case.label_maps.is_empty();
    if case_errors.is_empty() {
        // Each volume is dropped as soon as its surfaces are out (it is the case's largest part).
        for (index, loaded) in case.label_maps.into_iter().enumerate() {
            let map = match &loaded.map {
                Ok(map) => map,
                Err(e) => {
                    case_errors.push(e.clone());
                    continue;
                }
            };
            let t0 = Instant::now();
            let (structures, info) = label_structures(plan, index, &loaded, map);
            timings.insert(
                format!("extract {}", loaded.file),
                serde_json::json!(t0.elapsed().as_secs_f64()),
            );
            case_warnings.extend(info.warnings.iter().map(|w| format!("{}: {w}", info.file)));
            label_map_infos.push(info);
            for st in structures {
                all.push(LoadedFile {
                    structure: st.name,
                    file: loaded.file.clone(),
                    bytes: 0,
                    blake3: String::new(),
                    mesh: match st.refused {
                        Some(why) => Err(why),
                        None => Ok(st.mesh),
                    },
                    place: st.place,
                    source: Some(st.source),
                    binary: st.binary,
                    renumbering: None,
                    shares_triangles_with: st.shares_triangles_with,
                });
            }
        }
    }
    let mesh_inputs: Vec<InputInfo> = case
        .files
        .iter()
        .map(|f| InputInfo {
            structure: f.structure.clone(),
            file: f.file.clone(),
            bytes: f.bytes,
            blake3: f.blake3.clone(),
        })
        .collect();
    all.extend(case.files);
    all.sort_by(|a, b| a.structure.cmp(&b.structure));
    // A name given twice (a mesh file and a label, or two labels) is ambiguous: the case fails.
    for pair in all.windows(2) {
        if pair[0].structure == pair[1].structure {
            case_errors.push(format!(
                "structure {:?} comes from both {} and {}; rename one (a [labels] entry names labels: \"2\" for value 2 in every layer, \"1:2\" for value 2 in layer 1)",
                pair[0].structure,
                origin(&pair[0]),
                origin(&pair[1])
            ));
        }
    }
    let by_name: BTreeMap<&str, &LoadedFile> =
        all.iter().map(|f| (f.structure.as_str(), f)).collect();
    // A case that cannot be processed as listed (unreadable folder, two files for a structure)
    // fails as a whole, without computing anything.
    let inputs: &[LoadedFile] = if case_errors.is_empty() { &all } else { &[] };
    // Each processed structure before and after, in world mm, for the pair table, with the
    // index of its input and whether a repair can re-smooth it.
    let mut kept: Vec<Kept> = Vec::new();
    for (index, f) in inputs.iter().enumerate() {
        let t0 = Instant::now();
        let (report, outputs) = run_structure(
            plan,
            &case.input.id,
            f,
            &by_name,
            &mut trees,
            None,
            &files,
            &mut kept,
            index,
        );
        files.extend(outputs);
        timings.insert(
            f.structure.clone(),
            serde_json::json!(t0.elapsed().as_secs_f64()),
        );
        structures.push(report);
    }
    let guard = (!kept.is_empty()).then(|| {
        let t0 = Instant::now();
        let names: Vec<String> = inputs.iter().map(|f| f.structure.clone()).collect();
        let mut rerun = |input: usize,
                         held: &[bool],
                         files: &mut Vec<(String, Vec<u8>)>,
                         kept: &mut Vec<Kept>| {
            let (report, outputs) = run_structure(
                plan,
                &case.input.id,
                &inputs[input],
                &by_name,
                &mut trees,
                Some(held),
                files,
                kept,
                input,
            );
            files.extend(outputs);
            report
        };
        let table = guard_case(
            &plan.guard,
            &names,
            &mut files,
            &mut structures,
            &mut kept,
            &mut rerun,
        );
        timings.insert(
            "guard".into(),
            serde_json::json!(t0.elapsed().as_secs_f64()),
        );
        table
    });
    if plan.pictures {
        let t0 = Instant::now();
        let jobs: Vec<super::pictures::PictureJob> = kept
            .iter()
            .filter_map(|k| Some((k.name.as_str(), &k.before, &k.after, k.picture.as_ref()?)))
            .collect();
        super::pictures::draw_case_pictures(&jobs, &mut structures, &mut files);
        timings.insert(
            "pictures".into(),
            serde_json::json!(t0.elapsed().as_secs_f64()),
        );
    }
    drop(kept);
    let mut errors = case_errors;
    errors.extend(
        structures
            .iter()
            .filter_map(|s| s.error.as_ref().map(|e| format!("{}: {e}", s.name))),
    );
    if errors.is_empty() && all.is_empty() {
        errors.push(if !had_label_maps {
            "the case holds no meshes".into()
        } else {
            "the case's label maps hold no labels (every voxel is background)".into()
        });
    }
    let report = CaseReport {
        schema_version: SCHEMA_VERSION,
        case: case.input.id.clone(),
        status: if errors.is_empty() { "ok" } else { "failed" }.into(),
        inputs: mesh_inputs,
        label_maps: label_map_infos,
        structures,
        guard,
        warnings: case_warnings,
        errors,
    };
    timings.insert(
        "case".into(),
        serde_json::json!(started.elapsed().as_secs_f64()),
    );
    CaseOutput {
        id: case.input.id.clone(),
        files,
        report,
        timings: serde_json::Value::Object(timings),
        key: case.key,
    }
}

/// Processes one structure (again, with `held` vertices kept in place, for a repair): its
/// report and outputs, and its surfaces in `kept` (replacing an earlier entry for it).
#[allow(clippy::too_many_arguments)]
fn run_structure(
    plan: &Plan,
    case_id: &str,
    f: &LoadedFile,
    by_name: &BTreeMap<&str, &LoadedFile>,
    trees: &mut BTreeMap<(String, Option<usize>), TriangleBvh>,
    held: Option<&[bool]>,
    files: &[(String, Vec<u8>)],
    kept: &mut Vec<Kept>,
    index: usize,
) -> (StructureReport, Vec<(String, Vec<u8>)>) {
    let settings = plan.settings_for(&f.structure);
    let mut report = StructureReport {
        name: f.structure.clone(),
        status: "failed".into(),
        error: None,
        settings: serde_json::to_value(&settings).unwrap_or_default(),
        n_vertices: 0,
        n_triangles: 0,
        method: None,
        smooth: None,
        context: None,
        metrics: None,
        outputs: Vec::new(),
        warnings: Vec::new(),
        source: f.source.clone(),
        cfd: None,
        picture: None,
        displacement_histogram: None,
    };
    let stem = plan.output_stem(case_id, &f.structure);
    let mut surface = None;
    let processed = process_structure(
        plan,
        f,
        &stem,
        &settings,
        by_name,
        trees,
        &mut report,
        &mut surface,
        held,
    );
    kept.retain(|k| k.input != index);
    let outputs = match processed {
        Ok(outputs) => {
            // Two structures must not write one file (`vessel` with the cfd profile writes
            // vessel_wall.stl, as a structure `vessel_wall` would).
            let taken = outputs
                .iter()
                .find(|(n, _)| files.iter().any(|(m, _)| m == n));
            if let Some((name, _)) = taken {
                report.status = "failed".into();
                report.error = Some(format!(
                    "its output {name} is also an output of another structure of this case; rename one (or change [output] naming)"
                ));
                Vec::new()
            } else {
                if let Some(Surfaces {
                    before,
                    after,
                    picture,
                }) = surface
                {
                    kept.push(Kept {
                        input: index,
                        name: f.structure.clone(),
                        repairable: report.smooth.is_some()
                            && report.cfd.is_none()
                            && after.n_vertices() == before.n_vertices(),
                        before,
                        after,
                        picture,
                        shares_triangles_with: f.shares_triangles_with.clone(),
                    });
                    kept.sort_by_key(|k| k.input);
                }
                report.outputs = outputs.iter().map(|(n, _)| n.clone()).collect();
                outputs
            }
        }
        Err(e) => {
            report.status = "failed".into();
            report.error = Some(e);
            Vec::new()
        }
    };
    (report, outputs)
}

/// A processed structure's surfaces in world mm, for the guard and the pictures.
struct Surfaces {
    before: Mesh,
    after: Mesh,
    picture: Option<PictureInput>,
}

/// Largest change of a label structure's enclosed volume from its voxels' volume (a share)
/// before the report warns.
const LABEL_VOLUME_TOLERANCE: f64 = 0.1;

/// Where a structure's file came from, for messages.
fn origin(f: &LoadedFile) -> String {
    match &f.source {
        // The layer only where there can be several (a .seg.nrrd's layers reuse values).
        Some(s) if s.layer > 0 => {
            format!("label {} (layer {}) of {}", s.label, s.layer, s.label_map)
        }
        Some(s) => format!("label {} of {}", s.label, s.label_map),
        None => f.file.clone(),
    }
}

/// A mesh in world mm for writing: as it is, or moved out of its grid's frame.
fn in_world<'a>(place: &Place, mesh: &'a Mesh) -> std::borrow::Cow<'a, Mesh> {
    match place.mesh_in(mesh, &Place::World) {
        Some(m) => std::borrow::Cow::Owned(m),
        None => std::borrow::Cow::Borrowed(mesh),
    }
}

#[allow(clippy::too_many_arguments)]
fn process_structure(
    plan: &Plan,
    file: &LoadedFile,
    stem: &str,
    settings: &StructureSettings,
    case: &BTreeMap<&str, &LoadedFile>,
    trees: &mut BTreeMap<(String, Option<usize>), TriangleBvh>,
    report: &mut StructureReport,
    surfaces: &mut Option<Surfaces>,
    held: Option<&[bool]>,
) -> Result<Vec<(String, Vec<u8>)>, String> {
    let loaded = file.mesh.as_ref().map_err(|e| e.clone())?;
    let mesh = &loaded.mesh;
    let place = file.place;
    let frame_key = match place {
        Place::Frame(i, _) => Some(i),
        Place::World => None,
    };
    report.n_vertices = mesh.n_vertices();
    report.n_triangles = mesh.n_triangles();
    report.warnings.extend(loaded.warnings.iter().cloned());
    // References must exist in the case and be readable.
    let mut reference_meshes = Vec::new();
    for r in &settings.references {
        let Some(rf) = case.get(r.as_str()) else {
            let have: Vec<&str> = case.keys().copied().collect();
            return Err(format!(
                "reference {r:?} named in the config is not in this case (it has: {})",
                have.join(", ")
            ));
        };
        let rm = rf
            .mesh
            .as_ref()
            .map_err(|e| format!("reference {r:?} could not be read: {e}"))?;
        // References are measured in this structure's coordinates.
        let moved = rf.place.checked_mesh_in(&rm.mesh, &place);
        let rm =
            match moved.map_err(|e| format!("reference {r:?} in this structure's grid: {e}"))? {
                Some(m) => std::borrow::Cow::Owned(m),
                None => std::borrow::Cow::Borrowed(&rm.mesh),
            };
        reference_meshes.push((r.clone(), rm));
    }
    if settings.skip {
        report.status = "skipped".into();
        if settings.cfd.is_some() {
            report
                .warnings
                .push("skip = true: copied unchanged, without the cfd profile".into());
        }
        let world = in_world(&place, mesh).into_owned();
        let out = encode(
            plan,
            &plan.formats,
            stem,
            &world,
            loaded,
            &[],
            file.renumbering.as_ref(),
        );
        *surfaces = Some(Surfaces {
            before: world.clone(),
            after: world,
            picture: None,
        });
        return out;
    }
    let topology = Topology::build(mesh);
    // The cfd profile's patches, found before smoothing so the smoother holds them, and their
    // rims smoothed in their planes, in world mm (the inlet point, the patch table and the
    // files are in world coordinates).
    let cfd = match &settings.cfd {
        Some(profile) => {
            let world = in_world(&place, mesh);
            let moved = matches!(world, std::borrow::Cow::Owned(_));
            let world_topology = moved.then(|| Topology::build(&world));
            let prepared = crate::cfd::prepare_surface(
                &world,
                world_topology.as_ref().unwrap_or(&topology),
                profile,
            )
            .map_err(|e| format!("cfd profile: {e}"))?;
            Some((profile, world, prepared))
        }
        None => None,
    };
    // Where smoothing starts: the input, with the cfd profile's smoothed rims brought back
    // into this structure's coordinates (only the vertices that moved, so held caps keep their
    // exact coordinates).
    let start: std::borrow::Cow<Mesh> = match &cfd {
        Some((_, world, prepared)) if prepared.start.positions() != world.positions() => {
            let mut m = mesh.clone();
            let moved = world.positions().iter().zip(prepared.start.positions());
            for (p, (w, s)) in m.positions_mut().iter_mut().zip(moved) {
                if w != s {
                    *p = place.of_world(s.map(f64::from)).map(|x| x as f32);
                }
            }
            std::borrow::Cow::Owned(m)
        }
        _ => std::borrow::Cow::Borrowed(mesh),
    };
    let header = file
        .source
        .as_ref()
        .and_then(|s| header_geometry(&place, s));
    // The metrics need the input's average normal curvature, which the context finds on its
    // way (a constrained label surface is measured against its binary extraction instead).
    let mut context_params = ContextParams {
        measure_curvature: file.binary.is_none(),
        ..settings.context.clone()
    };
    if let Some((voxel, axis)) = header {
        // The mesh is in its grid's frame: the header's voxel size holds along its axes.
        context_params.grid_mm = Some(voxel);
        context_params.axis = match settings.context.axis {
            AxisChoice::Auto => AxisChoice::Given(axis),
            // A configured axis is a world direction.
            AxisChoice::Given(a) => AxisChoice::Given(
                place
                    .direction_from_world(a.map(f64::from))
                    .map(|x| x as f32),
            ),
        };
    }
    let estimate = crate::analysis::voxel_size(mesh, &topology);
    let voxel = match (header, settings.voxel) {
        (Some((v, _)), configured) => {
            if let Some(c) = configured {
                if (0..3).any(|k| (c[k] - v[k]).abs() > 1e-3 * v[k]) {
                    report.warnings.push(format!(
                        "the configured voxel {c:?} mm is not used: the label map's header gives {v:?} mm along its grid axes"
                    ));
                }
            }
            Some(v)
        }
        (None, Some(v)) => {
            if settings.method.needs_voxel() && estimate.is_irregular() {
                report.warnings.push(format!(
                    "the configured voxel size is used, but the mesh's voxel size is {}; {} constrains along grid axes this mesh may not follow",
                    crate::report::inspect::describe_voxel_size(&estimate),
                    settings.method.name()
                ));
            }
            Some(v)
        }
        (None, None) => estimate.spacing().map(|s| s.map(|x| x as f32)),
    };
    if settings.method.needs_voxel() && voxel.is_none() {
        return Err(format!(
            "method {} needs the voxel size, which is {}; set `voxel` in the config",
            settings.method.name(),
            crate::report::inspect::describe_voxel_size(&estimate)
        ));
    }
    let method = settings
        .method
        .build(&settings.params, voxel.unwrap_or([1.0; 3]));
    for (name, rm) in &reference_meshes {
        let key = (name.clone(), frame_key);
        trees.entry(key).or_insert_with(|| TriangleBvh::build(rm));
    }
    let refs: Vec<&TriangleBvh> = settings
        .references
        .iter()
        .filter_map(|r| trees.get(&(r.clone(), frame_key)))
        .collect();
    // A constrained label surface is smooth and true to its voxels already: a mesh smoother
    // runs on it only when `method` is configured.
    let smoother = file.binary.is_none() || settings.method_configured;
    let (positions, context) = if smoother {
        let ctx = context_weights(mesh, &topology, &context_params, &refs);
        let mut fixed = if settings.move_boundary {
            vec![false; mesh.n_vertices()]
        } else {
            boundary_vertices(&topology)
        };
        if let Some((_, _, prepared)) = &cfd {
            for (f, &h) in fixed.iter_mut().zip(&prepared.held) {
                *f |= h;
            }
        }
        // Vertices the inter-structure guard holds back stay where they are.
        if let Some(held) = held {
            for (f, &h) in fixed.iter_mut().zip(held) {
                *f |= h;
            }
        }
        let (positions, stats) = smooth(
            &start,
            &topology,
            &method,
            settings.iterations,
            &ctx.weights,
            &fixed,
        );
        let mut summary = context_summary(&ctx, mesh.n_vertices());
        if header.is_some() {
            // Directions as the world sees them; the axis came from the header.
            let world = |d: [f32; 3]| place.direction_to_world(d.map(f64::from)).map(|x| x as f32);
            summary.axis = summary.axis.map(world);
            for cap in &mut summary.caps {
                cap.normal = world(cap.normal);
            }
            if matches!(settings.context.axis, AxisChoice::Auto) && summary.axis.is_some() {
                summary.axis_source = "label_map_header".into();
            }
        }
        // A cap is a clipped end; a structure that reaches no edge of its volume was clipped
        // by no field of view, so its caps are cuts made in the segmentation, or terraces.
        if let Some(source) = file.source.as_ref().filter(|s| !s.reaches_volume_edge) {
            if !summary.caps.is_empty() {
                summary.warnings.push(format!(
                    "{} cap(s) found, but label {} of {} reaches no edge of its volume (within {} voxels): nothing was clipped by the field of view there; check that they are ends cut in the segmentation, or set caps = \"smooth\"",
                    summary.caps.len(),
                    source.label,
                    source.label_map,
                    crate::report::label_map::EDGE_MARGIN_VOXELS
                ));
            }
        }
        report.warnings.extend(summary.warnings.iter().cloned());
        report.context = Some(summary);
        report.method = Some(method);
        report.smooth = Some(stats);
        crate::smooth::check_result(
            mesh.positions(),
            &positions,
            settings.max_displacement_voxels,
            crate::smooth::displacement_unit(mesh, &topology, voxel),
            file.renumbering.as_ref(),
        )?;
        (positions, Some(ctx))
    } else {
        (start.positions().to_vec(), None)
    };
    // Metrics and displacements from the binary extraction for constrained label surfaces,
    // else from the input (the triangles are the same).
    let before = file.binary.as_ref().unwrap_or(mesh);
    let mut smoothed = mesh.clone();
    smoothed.positions_mut().copy_from_slice(&positions);
    let named_refs: Vec<(&str, &Mesh, &TriangleBvh)> = reference_meshes
        .iter()
        .filter_map(|(n, m)| {
            trees
                .get(&(n.clone(), frame_key))
                .map(|g| (n.as_str(), m.as_ref(), g))
        })
        .collect();
    // The input's curvature, found by the context (not asked for where `before` is a binary
    // extraction: see `context_params`).
    let known_curvature = (context.as_ref()).and_then(|c| c.average_normal_curvature_deg);
    let metrics = compare_prepared(
        before,
        &topology,
        known_curvature,
        &smoothed,
        &named_refs,
        voxel.map(|v| v.map(f64::from)),
    );
    // A label's surface far from its voxels' volume (small and thin labels shrink in the
    // constrained extraction): said, not reported as plain ok.
    if let Some(source) = file.source.as_ref() {
        let (enclosed, voxels) = (metrics.volume_smoothed_mm3.abs(), source.voxel_volume_mm3);
        if voxels > 0.0 && (enclosed - voxels).abs() > LABEL_VOLUME_TOLERANCE * voxels {
            report.warnings.push(format!(
                "{}: the surface encloses {enclosed:.1} mm³, {:.0} % of its voxels' {voxels:.1} mm³ (more than {:.0} % off): small or thin parts lost or gained volume; compare with surface = \"binary\"",
                origin(file),
                100.0 * enclosed / voxels,
                100.0 * LABEL_VOLUME_TOLERANCE
            ));
        }
        if let Some(w) = source.extraction.pieces_warning() {
            report.warnings.push(format!("{}: {w}", origin(file)));
        }
    }
    report.metrics = Some(metrics);
    let displacement: Vec<f32> = crate::metrics::displacements(before.positions(), &positions)
        .into_iter()
        .map(|d| d as f32)
        .collect();
    if let Some((profile, world, prepared)) = &cfd {
        let smoothed_world = in_world(&place, &smoothed);
        let done = crate::cfd::finish_surface(world, &smoothed_world, prepared, &profile.finish)
            .map_err(|e| format!("cfd profile: {e}"))?;
        if plan.annotate {
            report.warnings.push(
                "annotations are not written for the cfd profile's outputs (the surface is new); CellEntityIds are in the .vtp".into(),
            );
        }
        // The cfd profile's .vtp is the patch file, with CellEntityIds.
        let formats: Vec<OutputFormat> = plan
            .formats
            .iter()
            .copied()
            .filter(|&f| f != OutputFormat::Vtp)
            .collect();
        // New surfaces, written as made (a cfd structure is worked in the file's numbering).
        let mut out = encode(plan, &formats, stem, &done.mesh, loaded, &[], None)?;
        out.extend(
            crate::cfd::encode_patch_files(stem, &done.mesh, &loaded.meta, &done.patches)
                .map_err(|e| e.to_string())?,
        );
        report.cfd = Some(CfdReport {
            n_vertices: done.mesh.n_vertices(),
            n_triangles: done.mesh.n_triangles(),
            patches: done.patches,
            checks: done.checks,
            rims: done.rims,
            remeshed: done.remeshed,
        });
        report.status = "ok".into();
        let picture = plan.pictures.then(|| PictureInput {
            stem: stem.to_string(),
            start: None,
            arrays: context
                .as_ref()
                .map(|c| c.vertex_arrays(mesh.n_vertices()))
                .unwrap_or_default(),
            patches: report.cfd.as_ref().map(|c| {
                let names = c.patches.patches.iter().map(|p| (p.id, p.name.clone()));
                (c.patches.face_ids.clone(), names.collect())
            }),
        });
        *surfaces = Some(Surfaces {
            before: in_world(&place, mesh).into_owned(),
            after: done.mesh,
            picture,
        });
        return Ok(out);
    }
    // Per-vertex arrays, for VTP, annotated PLY and pictures only: the analysis behind the
    // weights when a smoother ran, and the displacement.
    let wanted = plan.annotate || plan.pictures || plan.formats.contains(&OutputFormat::Vtp);
    let mut arrays = match &context {
        Some(c) if wanted => c.vertex_arrays(mesh.n_vertices()),
        _ => Vec::new(),
    };
    report.displacement_histogram = Some(crate::report::pictures::histogram(&displacement));
    arrays.push(("displacement", displacement));
    let smoothed_world = in_world(&place, &smoothed).into_owned();
    let named: Vec<(&str, &[f32])> = arrays.iter().map(|(n, v)| (*n, v.as_slice())).collect();
    let out = encode(
        plan,
        &plan.formats,
        stem,
        &smoothed_world,
        loaded,
        &named,
        file.renumbering.as_ref(),
    )?;
    report.status = "ok".into();
    // Pictures are drawn once the guard is done; a label surface's pictures start from its
    // binary extraction, which the displacements are measured from.
    let picture = plan.pictures.then(|| PictureInput {
        stem: stem.to_string(),
        start: file
            .binary
            .as_ref()
            .map(|b| in_world(&place, b).into_owned()),
        arrays,
        patches: None,
    });
    *surfaces = Some(Surfaces {
        before: in_world(&place, mesh).into_owned(),
        after: smoothed_world,
        picture,
    });
    Ok(out)
}
