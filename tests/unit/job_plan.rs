//! Tests of `src/job/plan.rs`.

use destair::job::config::{Config, ConfigError};
use destair::job::plan::*;
use destair::smooth::MethodKind;
use std::path::{Path, PathBuf};

/// The plan of a config text, as if read from /c/cohort.toml.
pub fn plan(text: &str) -> Result<Plan, ConfigError> {
    Plan::new(
        Config::parse(text, Path::new("/c/cohort.toml"))?,
        Path::new("/c/cohort.toml"),
    )
}

#[test]
fn settings_merge_in_order_and_paths_resolve() {
    let p = plan(
        r#"
[input]
roots = ["cases"]
[output]
root = "/abs/out"
[defaults]
method = "laplace"
lambda = 0.4
[[structure]]
pattern = "ve*"
method = "taubin"
[[structure]]
pattern = "vein"
references = ["tumor"]
skip = false
"#,
    )
    .unwrap();
    assert_eq!(p.roots, vec![PathBuf::from("/c/cases")]);
    assert_eq!(p.output_root, PathBuf::from("/abs/out"));
    let vein = p.settings_for("vein");
    assert_eq!(vein.method, MethodKind::Taubin);
    assert_eq!(vein.params.lambda, Some(0.4));
    assert_eq!(vein.references, vec!["tumor"]);
    let tumor = p.settings_for("tumor");
    assert_eq!(tumor.method, MethodKind::Laplace);
    assert!(tumor.references.is_empty());
    assert_eq!(p.matching_tables("vessel"), vec!["ve*"]);
}

#[test]
fn guard_defaults_pairs_and_bad_values() {
    let base = "[input]\nroots = [\"c\"]\n[output]\nroot = \"o\"\n";
    let g = plan(base).unwrap().guard;
    assert_eq!(g, destair::guard::GuardPolicy::default());
    assert_eq!(g.limits("tumor", "vein"), (0.05, true));
    let p = plan(&format!(
        "{base}[guard]\nmax_gap_loss_mm = 0.1\n[[guard.pair]]\na = \"tumor\"\nb = \"vein\"\nforbid_new_contacts = false\n"
    ))
    .unwrap();
    // The pair keeps the section's distance unless it gives its own.
    assert_eq!(p.guard.limits("vein", "tumor"), (0.1, false));
    assert_eq!(p.guard.limits("tumor", "trachea"), (0.1, true));
    assert!(p.guard.self_intersections);
    let off = plan(&format!("{base}[guard]\nself_intersections = false\n")).unwrap();
    assert!(!off.guard.self_intersections);
    for (bad, says) in [
        (
            "[guard]\nmax_gap_loss_mm = -0.1\n",
            "max_gap_loss_mm = -0.1",
        ),
        ("[guard]\nmax_repairs = 21\n", "max_repairs = 21"),
        ("[[guard.pair]]\na = \"x\"\nb = \"x\"\n", "[[guard.pair]]"),
        ("[guard]\nmax_gap_los_mm = 1\n", "max_gap_los_mm"),
    ] {
        let e = plan(&format!("{base}{bad}")).unwrap_err().to_string();
        assert!(e.contains(says), "{bad}: {e}");
    }
}

#[test]
fn bad_values_name_their_table() {
    let base = "[input]\nroots = [\"c\"]\n[output]\nroot = \"o\"\n";
    let cases = [
        ("[defaults]\nmethod = \"smoothest\"\n", "[defaults]"),
        (
            "[[structure]]\npattern = \"v*\"\ncaps = \"keep\"\n",
            "\"v*\"",
        ),
        ("[defaults]\ntau = 1.5\n", "tau"),
        ("[defaults]\ndistance_scaling = \"ramp:3,1\"\n", "ramp"),
        ("[defaults]\naxis = [0, 0, 0]\n", "axis"),
    ];
    for (extra, needle) in cases {
        let err = plan(&format!("{base}{extra}")).unwrap_err().to_string();
        assert!(err.contains(needle), "{err}");
    }
    let err = plan(
        "[input]\nroots = [\"c\"]\n[output]\nroot = \"o\"\nformats = [\"stl\"]\nannotate = true\n",
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("annotate adds vertex properties to PLY outputs"),
        "{err}"
    );
    let err = plan("[input]\nroots = [\"c\"]\n[output]\nroot = \"o\"\nformats = [\"vtk\"]\n")
        .unwrap_err()
        .to_string();
    assert!(err.contains("vtk"));
}
