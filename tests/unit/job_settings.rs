//! Tests of `src/job/settings.rs`.

use crate::job_plan::plan;
use destair::cfd::Inlet;

#[test]
fn the_cfd_profile_is_set_per_structure_and_checked() {
    let base = "[input]\nroots = [\"c\"]\n[output]\nroot = \"o\"\n";
    let p = plan(&format!(
        "{base}[defaults]\nedge_mm = 0.3\n[[structure]]\npattern = \"vessel*\"\nprofile = \"cfd\"\ninlet = [1, 2.5, 3]\nflow_extension = 5\nextend = [2]\nexpect_patches = 3\n"
    ))
    .unwrap();
    assert!(p.settings_for("tumor").cfd.is_none());
    let c = p.settings_for("vessel_a").cfd.unwrap();
    assert_eq!(c.inlet, Inlet::Point([1.0, 2.5, 3.0]));
    assert_eq!(c.expect_patches, Some(3));
    assert_eq!(c.finish.flow_extension, Some(5.0));
    assert_eq!(c.finish.extend_patches, vec![2]);
    assert_eq!(
        c.finish.remesh.map(|r| r.edge),
        Some(destair::remesh::EdgeTarget::Mm(0.3))
    );
    let view = p.settings_for("vessel_a").config_view();
    assert!(
        view.contains("profile = \"cfd\"") && view.contains("edge_mm = 0.3"),
        "{view}"
    );
    // The view parses back into the same settings.
    let again = plan(&format!("{base}[defaults]\n{view}")).unwrap();
    assert_eq!(again.settings_for("x").cfd, Some(c));
    for inlet in ["\"largest\"", "1", "\"2\""] {
        let text = format!("{base}[defaults]\nprofile = \"cfd\"\ninlet = {inlet}\n");
        assert!(plan(&text).is_ok(), "{inlet}");
    }
    let cases = [
        ("edge_mm = 0.3\n", "no table sets"),
        ("profile = \"cdf\"\n", "\"cfd\" or \"none\""),
        (
            "profile = \"cfd\"\nedge_mm = 0.3\nedge_per_radius = 0.5\n",
            "exclude",
        ),
        ("profile = \"cfd\"\nedge_mm = -1.0\n", "edge_mm"),
        ("profile = \"cfd\"\nextend = [2]\n", "set flow_extension"),
        (
            "profile = \"cfd\"\nflow_extension = 5\nextend = [1]\n",
            "wall is 1",
        ),
        ("profile = \"cfd\"\nflow_extension = 1000\n", "longer than"),
        ("profile = \"cfd\"\ninlet = [1, 2]\n", "inlet"),
        ("profile = \"cfd\"\ninlet = -1\n", "inlet"),
        ("profile = \"cfd\"\nexpect_patches = 0\n", "expect_patches"),
    ];
    for (extra, needle) in cases {
        let err = plan(&format!("{base}[defaults]\n{extra}"))
            .unwrap_err()
            .to_string();
        assert!(err.contains(needle), "{extra}: {err}");
    }
}

#[test]
fn connectivity_is_26_by_default_6_where_asked_and_nothing_else() {
    use destair::extract::Connectivity;
    let base = "[input]\nroots = [\"c\"]\n[output]\nroot = \"o\"\n";
    let p = plan(&format!(
        "{base}[[structure]]\npattern = \"airway*\"\nconnectivity = 6\n"
    ))
    .unwrap();
    assert_eq!(
        p.settings_for("vessel").extraction.connectivity,
        Connectivity::Corners
    );
    let airway = p.settings_for("airway_l");
    assert_eq!(airway.extraction.connectivity, Connectivity::Faces);
    let view = airway.config_view();
    assert!(view.contains("connectivity = 6"), "{view}");
    let again = plan(&format!("{base}[defaults]\n{view}")).unwrap();
    assert_eq!(again.settings_for("x").extraction, airway.extraction);
    let quoted = plan(&format!("{base}[defaults]\nconnectivity = \"6\"\n")).unwrap();
    assert_eq!(
        quoted.settings_for("x").extraction.connectivity,
        Connectivity::Faces
    );
    for bad in ["8", "\"corners\"", "18", "26.0"] {
        let err = plan(&format!("{base}[defaults]\nconnectivity = {bad}\n"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("connectivity"), "{bad}: {err}");
    }
}
