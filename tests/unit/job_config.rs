//! Tests of `src/job/config.rs`.

use destair::job::config::*;
use std::path::Path;

#[test]
fn unknown_keys_are_rejected_with_their_place() {
    let text = "[input]\nroots = [\"cases\"]\n\n[output]\nroot = \"out\"\n\n[defaults]\nmethod = \"hc\"\nlamda = 0.5\n";
    let err = Config::parse(text, Path::new("cohort.toml"))
        .unwrap_err()
        .to_string();
    assert!(err.starts_with("cohort.toml:9:1:"), "{err}");
    assert!(err.contains("lamda"), "{err}");
}

#[test]
fn structures_override_defaults() {
    let text = r#"
[input]
roots = ["cases"]
case_depth = 1
[output]
root = "out"
formats = ["ply", "stl"]
[defaults]
method = "hc"
staircase = true
[[structure]]
pattern = "vein*"
references = ["tumor"]
distance_scaling = "margin:2"
"#;
    let c = Config::parse(text, Path::new("c.toml")).unwrap();
    assert_eq!(c.structures[0].pattern, "vein*");
    assert_eq!(
        c.structures[0].settings.references.as_deref(),
        Some(&["tumor".to_string()][..])
    );
    assert_eq!(c.defaults.method.as_deref(), Some("hc"));
}
