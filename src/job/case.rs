//! Processing one case: read and hash its meshes, then for each structure resolve its settings
//! and references, weight, smooth, measure and encode the outputs. Everything a case produces
//! is returned as bytes and a report; writing them (atomically) is the pipeline's writer's job.
//! A failing structure is recorded in the report; it never stops the case or the cohort.

use super::discover::CaseInput;
use super::plan::{Plan, StructureSettings};
use crate::io::{decode_mesh, extension, with_file_bytes, LoadedMesh, OutputFormat, ReadOptions};
use crate::mesh::{Mesh, Topology};
use crate::report::case::{CaseReport, InputInfo, StructureReport, SCHEMA_VERSION};
use crate::report::compare::compare_prepared;
use crate::report::inspect::context_summary;
use crate::smooth::{boundary_vertices, smooth};
use crate::spatial::TriangleGrid;
use crate::weights::context_weights;
use std::collections::BTreeMap;
use std::time::Instant;

/// One input file, read, hashed and decoded.
#[derive(Debug)]
pub struct LoadedFile {
    pub structure: String,
    pub file: String,
    pub bytes: u64,
    pub blake3: String,
    pub mesh: Result<LoadedMesh, String>,
}

/// A case with its files in memory.
#[derive(Debug)]
pub struct LoadedCase {
    pub input: CaseInput,
    pub files: Vec<LoadedFile>,
    /// Key for resuming: the plan's output fingerprint for these structures and the input hashes.
    pub key: String,
}

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

/// Reads, hashes and decodes the meshes of a case.
pub fn load_case(plan: &Plan, input: CaseInput) -> LoadedCase {
    let options = ReadOptions {
        mode: plan.read_mode,
        ..Default::default()
    };
    let files: Vec<LoadedFile> = input
        .meshes
        .iter()
        .map(|(structure, path)| {
            let file = path
                .file_name()
                .map_or_else(String::new, |f| f.to_string_lossy().into_owned());
            let ext = extension(path);
            match with_file_bytes(path, plan.read_mode, |b| {
                let hash = blake3::hash(b).to_hex().to_string();
                (
                    b.len() as u64,
                    hash,
                    decode_mesh(b, ext.as_deref(), &options),
                )
            }) {
                Ok((bytes, blake3, mesh)) => LoadedFile {
                    structure: structure.clone(),
                    file,
                    bytes,
                    blake3,
                    mesh: mesh.map_err(|e| format!("{}: {e}", plan.display(path))),
                },
                Err(e) => LoadedFile {
                    structure: structure.clone(),
                    file,
                    bytes: 0,
                    blake3: String::new(),
                    mesh: Err(format!("{}: cannot read: {e}", plan.display(path))),
                },
            }
        })
        .collect();
    let key = resume_key(plan, &input, &files);
    LoadedCase { input, files, key }
}

fn resume_key(plan: &Plan, input: &CaseInput, files: &[LoadedFile]) -> String {
    let settings: Vec<(String, StructureSettings)> = input
        .meshes
        .iter()
        .map(|(name, _)| (name.clone(), plan.settings_for(name)))
        .collect();
    let mut h = blake3::Hasher::new();
    h.update(plan.output_fingerprint(&settings).as_bytes());
    for f in files {
        h.update(f.structure.as_bytes());
        h.update(&[0]);
        h.update(f.blake3.as_bytes());
        h.update(&[0]);
    }
    h.finalize().to_hex().to_string()
}

/// Encodes a mesh in each output format as `<stem>.<ext>`; returns (file name, bytes) pairs.
fn encode(
    plan: &Plan,
    stem: &str,
    mesh: &Mesh,
    loaded: &LoadedMesh,
    props: &[(&str, &[f32])],
) -> Result<Vec<(String, Vec<u8>)>, String> {
    plan.formats
        .iter()
        .map(|f| match f {
            OutputFormat::Ply => crate::io::ply::encode_ply(mesh, &loaded.meta, props)
                .map(|b| (format!("{stem}.ply"), b))
                .map_err(|e| e.to_string()),
            OutputFormat::Stl => Ok((
                format!("{stem}.stl"),
                crate::io::stl::encode_stl(mesh, &loaded.meta),
            )),
        })
        .collect()
}

/// Processes every structure of a loaded case.
pub fn process_case(plan: &Plan, case: LoadedCase) -> CaseOutput {
    let started = Instant::now();
    let by_name: BTreeMap<&str, &LoadedFile> = case
        .files
        .iter()
        .map(|f| (f.structure.as_str(), f))
        .collect();
    let mut grids: BTreeMap<String, TriangleGrid> = BTreeMap::new();
    let mut files = Vec::new();
    let mut structures = Vec::new();
    let mut timings = serde_json::Map::new();
    // A case that cannot be processed as listed (unreadable folder, two files for a structure)
    // fails as a whole, without computing anything.
    let inputs: &[LoadedFile] = if case.input.errors.is_empty() {
        &case.files
    } else {
        &[]
    };
    for f in inputs {
        let t0 = Instant::now();
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
        };
        let stem = plan.output_stem(&case.input.id, &f.structure);
        match process_structure(plan, f, &stem, &settings, &by_name, &mut grids, &mut report) {
            Ok(outputs) => {
                report.outputs = outputs.iter().map(|(n, _)| n.clone()).collect();
                files.extend(outputs);
            }
            Err(e) => {
                report.status = "failed".into();
                report.error = Some(e);
            }
        }
        timings.insert(
            f.structure.clone(),
            serde_json::json!(t0.elapsed().as_secs_f64()),
        );
        structures.push(report);
    }
    let mut errors: Vec<String> = case.input.errors.clone();
    errors.extend(
        structures
            .iter()
            .filter_map(|s| s.error.as_ref().map(|e| format!("{}: {e}", s.name))),
    );
    if errors.is_empty() && case.files.is_empty() {
        errors.push("the case holds no meshes".into());
    }
    let report = CaseReport {
        schema_version: SCHEMA_VERSION,
        case: case.input.id.clone(),
        status: if errors.is_empty() { "ok" } else { "failed" }.into(),
        inputs: case
            .files
            .iter()
            .map(|f| InputInfo {
                structure: f.structure.clone(),
                file: f.file.clone(),
                bytes: f.bytes,
                blake3: f.blake3.clone(),
            })
            .collect(),
        structures,
        warnings: case.input.problems.clone(),
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

#[allow(clippy::too_many_arguments)]
fn process_structure(
    plan: &Plan,
    file: &LoadedFile,
    stem: &str,
    settings: &StructureSettings,
    case: &BTreeMap<&str, &LoadedFile>,
    grids: &mut BTreeMap<String, TriangleGrid>,
    report: &mut StructureReport,
) -> Result<Vec<(String, Vec<u8>)>, String> {
    let loaded = file.mesh.as_ref().map_err(|e| e.clone())?;
    let mesh = &loaded.mesh;
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
        reference_meshes.push((r.clone(), rm));
    }
    if settings.skip {
        report.status = "skipped".into();
        return encode(plan, stem, mesh, loaded, &[]);
    }
    let topology = Topology::build(mesh);
    let estimate = crate::analysis::voxel_size(mesh, &topology);
    let voxel = match settings.voxel {
        Some(v) => {
            if settings.method.needs_voxel() && estimate.is_irregular() {
                report.warnings.push(format!(
                    "the configured voxel size is used, but the mesh's voxel size is {}; {} constrains along grid axes this mesh may not follow",
                    crate::report::inspect::describe_voxel_size(&estimate),
                    settings.method.name()
                ));
            }
            Some(v)
        }
        None => estimate.spacing().map(|s| s.map(|x| x as f32)),
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
        if !grids.contains_key(name) {
            grids.insert(name.clone(), TriangleGrid::build(&rm.mesh));
        }
    }
    let refs: Vec<&TriangleGrid> = settings
        .references
        .iter()
        .filter_map(|r| grids.get(r))
        .collect();
    let ctx = context_weights(mesh, &topology, &settings.context, &refs);
    let fixed = if settings.move_boundary {
        vec![false; mesh.n_vertices()]
    } else {
        boundary_vertices(&topology)
    };
    let (positions, stats) = smooth(
        mesh,
        &topology,
        &method,
        settings.iterations,
        &ctx.weights,
        &fixed,
    );
    report.context = Some(context_summary(&ctx, mesh.n_vertices()));
    report.method = Some(method);
    report.smooth = Some(stats);
    crate::smooth::check_result(
        mesh.positions(),
        &positions,
        settings.max_displacement_voxels,
        crate::smooth::displacement_unit(mesh, &topology, voxel),
    )?;
    let mut smoothed = mesh.clone();
    smoothed.positions_mut().copy_from_slice(&positions);
    let named_refs: Vec<(&str, &Mesh, &TriangleGrid)> = reference_meshes
        .iter()
        .filter_map(|(n, m)| grids.get(n).map(|g| (n.as_str(), &m.mesh, g)))
        .collect();
    let metrics = compare_prepared(
        mesh,
        &topology,
        &smoothed,
        &named_refs,
        voxel.map(|v| v.map(f64::from)),
    );
    report.metrics = Some(metrics);
    let displacement: Vec<f32> = crate::metrics::displacements(mesh.positions(), &positions)
        .into_iter()
        .map(|d| d as f32)
        .collect();
    let props: Vec<(&str, &[f32])> = if plan.annotate {
        vec![
            ("weight", ctx.weights.as_slice()),
            ("displacement", &displacement),
        ]
    } else {
        Vec::new()
    };
    let out = encode(plan, stem, &smoothed, loaded, &props)?;
    report.status = "ok".into();
    Ok(out)
}
