//! Any bytes as one structure of a cohort case (a tumour beside a fixed vein it must keep its
//! distance to; the first byte picks the format and whether it goes through the cfd profile),
//! or as a label map in the case (NIfTI, gzipped NIfTI, NRRD, .nhdr): loading and processing the
//! case (limits and the memory budget, extraction, context, smoothing, the guard, cfd patches and
//! remeshing, reports, pictures) must give a report, failed or not, never panic nor abort under
//! an address-space limit.
#![no_main]
use destair::job::{config::Config, discover::discover, load::load_case, plan::Plan};
use libfuzzer_sys::fuzz_target;
use std::path::PathBuf;
use std::sync::OnceLock;

const CONFIG: &str = r#"
[input]
roots = ["cases"]
case_depth = 1
[output]
root = "out"
formats = ["ply", "stl", "vtp"]
[defaults]
iterations = 5
[[structure]]
pattern = "tumor"
references = ["vein"]
"#;

/// The tumour handed over for flow simulation instead: patches, remeshing, flow extensions,
/// closing, the checks.
const CFD: &str = r#"
profile = "cfd"
method = "taubin"
edge_per_radius = 0.3
flow_extension = 2
close_open_ends = true
"#;

/// A cohort folder with one case holding the vein (a small closed label surface).
fn cohort() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("destair-fuzz-case-{}", std::process::id()));
        let case = dir.join("cases/c1");
        std::fs::create_dir_all(&case).unwrap();
        std::fs::write(dir.join("cohort.toml"), CONFIG).unwrap();
        let grid = destair::volume::grid::Grid::axis_aligned(
            [1.0, 1.0, 2.0],
            [0.0; 3],
            destair::volume::grid::Space::Ras,
        );
        let dims = [12usize, 10, 6];
        let values = (0..dims.iter().product::<usize>()).map(|i| {
            let (x, y, z) = (i % 12, (i / 12) % 10, i / 120);
            i64::from((1..11).contains(&x) && (6..8).contains(&y) && (1..5).contains(&z))
        });
        let volume = destair::volume::LabelVolume::from_values(dims, grid, values).unwrap();
        let interfaces = destair::extract::interfaces(&volume, &[]);
        let vein = &destair::extract::label_surfaces(&volume, &interfaces)[0].mesh;
        let bytes = destair::io::ply::write::encode_ply(vein, &Default::default(), &[]).unwrap();
        std::fs::write(case.join("vein.ply"), bytes).unwrap();
        dir
    })
}

fuzz_target!(|data: &[u8]| {
    let Some((&which, bytes)) = data.split_first() else {
        return;
    };
    let dir = cohort();
    let case = dir.join("cases/c1");
    for name in [
        "tumor.ply",
        "tumor.stl",
        "tumor.obj",
        "seg.nii",
        "seg.nii.gz",
        "seg.nrrd",
        "seg.nhdr",
    ] {
        let _ = std::fs::remove_file(case.join(name));
    }
    let name = if which & 8 != 0 {
        ["seg.nii", "seg.nii.gz", "seg.nrrd", "seg.nhdr"][(which >> 4) as usize % 4]
    } else {
        ["tumor.ply", "tumor.stl", "tumor.obj"][which as usize % 3]
    };
    std::fs::write(case.join(name), bytes).unwrap();
    std::fs::write(case.join("data.raw"), &bytes[bytes.len() / 2..]).unwrap();
    let path = dir.join("cohort.toml");
    let text = if which & 4 != 0 {
        format!("{CONFIG}{CFD}")
    } else {
        CONFIG.to_string()
    };
    let config = Config::parse(&text, &path).unwrap();
    let plan = Plan::new(config, &path).unwrap();
    for input in discover(&plan).cases {
        let loaded = load_case(&plan, input);
        let out = destair::job::case::process_case(&plan, loaded);
        serde_json::to_string(&out.report).unwrap();
    }
});
