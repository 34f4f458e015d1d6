//! Label maps written by `tests/data/labels/make.py` (numpy + nibabel; objects counted by
//! scipy): tubes of radius 0.8-4 mm along, across and oblique to the 2.5 mm slices, vessels
//! stepping one voxel per slice, oblique one-voxel sheets and walls, a helix, one- and
//! four-voxel labels, a septum and a sphere. Whatever the surface and connectivity, every
//! label's surface is a closed oriented 2-manifold with every voxel centre on its side, and
//! with 26-connectivity (the default) it has exactly one piece per object scipy counts.

use destair::extract::constrained::{connectivity_of, place_on_weights, LabelSmoothing, Surface};
use destair::extract::report::outer_shells;
use destair::extract::{interfaces, label_surfaces, Connectivity};
use destair::mesh::manifold::is_closed_oriented_manifold;
use destair::volume::{read_label_map, Space};
use std::path::Path;

fn data() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/labels"))
}

#[test]
fn every_object_is_one_closed_surface_around_its_voxels() {
    let truth: serde_json::Value =
        serde_json::from_slice(&std::fs::read(data().join("truth.json")).unwrap()).unwrap();
    let maps = truth.as_object().unwrap();
    assert!(maps.len() >= 10);
    let mut failures = Vec::new();
    let mut checked = [0usize; 2];
    for (name, info) in maps {
        let map = read_label_map(&data().join(format!("{name}.nii.gz")), Space::Lps).unwrap();
        let volume = &map.layers[0];
        for surface in [Surface::Binary, Surface::Constrained] {
            for connectivity in [Connectivity::Corners, Connectivity::Faces] {
                let smoothing = vec![
                    LabelSmoothing {
                        surface,
                        connectivity,
                        ..LabelSmoothing::default()
                    };
                    volume.labels.len() + 1
                ];
                let mut all = interfaces(volume, &connectivity_of(&smoothing));
                place_on_weights(volume, &mut all, &smoothing);
                let surfaces = label_surfaces(volume, &all);
                for s in &surfaces {
                    let label = &volume.labels[s.label as usize - 1];
                    let want = &info["labels"][label.value.to_string()];
                    let (by_26, by_6) = (
                        want["objects_26"].as_u64().unwrap(),
                        want["objects_6"].as_u64().unwrap(),
                    );
                    let pieces = outer_shells(&s.mesh);
                    let what = format!("{name} label {} {surface:?} {connectivity:?}", label.value);
                    let right = match connectivity {
                        Connectivity::Corners => pieces == by_26,
                        // A 6-connected label still wins the middle of a face where its two
                        // corners are diagonal and two other labels hold the others.
                        Connectivity::Faces => (by_26..=by_6).contains(&pieces),
                    };
                    if !right {
                        failures.push(format!(
                            "{what}: {pieces} pieces, scipy {by_26} (26) {by_6} (6)"
                        ));
                    }
                    if !is_closed_oriented_manifold(&s.mesh) {
                        failures.push(format!("{what}: not a closed oriented manifold"));
                    }
                    checked[0] += 1;
                }
                // Voxel centres where labels meet (a voxel with a neighbour of another label,
                // across a face, an edge or a corner): inside their own surface only. Binary
                // vertices sit at cell-edge midpoints, so the constrained surfaces, whose
                // vertices moved, are the ones to check.
                if surface == Surface::Binary {
                    continue;
                }
                let [nx, ny, nz] = volume.dims.map(|d| d as i64);
                let label_at = |i: i64, j: i64, k: i64| {
                    let outside = i < 0 || j < 0 || k < 0 || i >= nx || j >= ny || k >= nz;
                    if outside {
                        0
                    } else {
                        volume.at(i as usize, j as usize, k as usize)
                    }
                };
                for k in 0..nz {
                    for j in 0..ny {
                        for i in 0..nx {
                            let own = label_at(i, j, k);
                            let near: Vec<u16> = (0..27)
                                .map(|d| label_at(i + d % 3 - 1, j + d / 3 % 3 - 1, k + d / 9 - 1))
                                .filter(|&l| l != own)
                                .collect();
                            if near.is_empty() {
                                continue;
                            }
                            let p = volume.grid.world([i as f64, j as f64, k as f64]);
                            for s in surfaces
                                .iter()
                                .filter(|s| s.label == own || near.contains(&s.label))
                            {
                                let w = super::extract::winding(&s.mesh, p);
                                let want = if s.label == own { 1.0 } else { 0.0 };
                                if (w - want).abs() > 1e-3 {
                                    failures.push(format!(
                                        "{name} {surface:?} {connectivity:?}: voxel ({i},{j},{k}) of label {own}: winding {w:.3} for label {}",
                                        s.label
                                    ));
                                }
                                checked[1] += 1;
                            }
                        }
                    }
                }
            }
        }
    }
    assert!(checked[0] > 150 && checked[1] > 100_000, "{checked:?}");
    let n = failures.len();
    failures.truncate(20);
    assert!(n == 0, "{n} failures:\n{}", failures.join("\n"));
}

/// Issue 62, item 2, as far as it holds today (figures in CHANGELOG): the constrained surface
/// keeps what the binary one keeps. Single voxels and two-voxel labels exactly; tubes of
/// radius 1 mm and more at least 0.93 of the binary volume across the slices and 0.87 in the
/// slice plane (measured 0.945-1.00 and 0.878-0.99; the plain Gaussian kept 0.18 of it for
/// in-slice tubes); labels of 1000+ voxels whose binary surface holds their voxel volume within
/// 1 % stay within 3 % of it (sphere 1.5 %); one-voxel sheets and the septum 0.5-1.3 of their
/// voxel volume.
#[test]
fn constrained_surfaces_keep_the_size_the_binary_surface_keeps() {
    use destair::mesh::geometry::signed_volume;
    let truth: serde_json::Value =
        serde_json::from_slice(&std::fs::read(data().join("truth.json")).unwrap()).unwrap();
    let mut failures = Vec::new();
    let mut checked = [0usize; 4];
    for (name, info) in truth.as_object().unwrap() {
        let map = read_label_map(&data().join(format!("{name}.nii.gz")), Space::Lps).unwrap();
        let volume = &map.layers[0];
        let volumes = |surface: Surface| {
            let smoothing = vec![
                LabelSmoothing {
                    surface,
                    ..LabelSmoothing::default()
                };
                volume.labels.len() + 1
            ];
            let mut all = interfaces(volume, &[]);
            place_on_weights(volume, &mut all, &smoothing);
            label_surfaces(volume, &all)
                .iter()
                .map(|s| (s.label, signed_volume(&s.mesh)))
                .collect::<Vec<_>>()
        };
        let (binary, constrained) = (volumes(Surface::Binary), volumes(Surface::Constrained));
        for (&(label, b), &(_, c)) in binary.iter().zip(&constrained) {
            let l = &volume.labels[label as usize - 1];
            let voxels = l.n_voxels as f64 * volume.grid.voxel_volume();
            let want = &info["labels"][l.value.to_string()];
            let shape = want["shape"].as_str().unwrap_or("");
            let what = format!(
                "{name} label {}: constrained {c:.2}, binary {b:.2}, voxels {voxels:.2} mm³",
                l.value
            );
            eprintln!("{what}");
            let mut expect = |i: usize, ok: bool| {
                checked[i] += 1;
                if !ok {
                    failures.push(what.clone());
                }
            };
            if l.n_voxels <= 2 {
                expect(0, c >= 0.99 * b);
            }
            if shape == "tube" && want["radius_mm"].as_f64().unwrap() >= 1.0 {
                // Tubes lying in the slices are one or two slices thick, nearly all corners.
                let in_slice = name.starts_with("tubes-along-x") || name.starts_with("tubes-xy");
                expect(1, c >= if in_slice { 0.87 } else { 0.93 } * b);
            }
            if l.n_voxels >= 1000 && (b / voxels - 1.0).abs() <= 0.01 {
                expect(2, (c / voxels - 1.0).abs() <= 0.03);
            }
            if name == "sheets" || (name == "septum" && l.value == 3) {
                expect(3, (0.5..=1.3).contains(&(c / voxels)));
            }
        }
    }
    // Small labels, tubes, large labels, sheets and the septum were all seen.
    assert!(
        checked[0] >= 3 && checked[1] >= 25 && checked[2] >= 3 && checked[3] >= 3,
        "{checked:?}"
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Issue 62, item 4: within the range `check_sigma` accepts, a larger `sigma_mm` is smoother
/// (mean normal curvature) on the 12 mm sphere at 0.8 x 0.8 x 2.5 mm, and keeps its volume
/// within 3 % (measured 2026-12-08: 21.1, 10.2, 7.3, 6.3 degrees at 0.4, 0.8, 1.2, 1.6 mm).
#[test]
fn a_larger_sigma_is_smoother_within_the_accepted_range() {
    use destair::extract::constrained::check_sigma;
    use destair::mesh::geometry::signed_volume;
    use destair::mesh::Topology;
    use destair::metrics::normal_curvature::average_normal_curvature;
    let map = read_label_map(&data().join("sphere.nii.gz"), Space::Lps).unwrap();
    let volume = &map.layers[0];
    let voxels = volume.labels[0].n_voxels as f64 * volume.grid.voxel_volume();
    let mut curvatures = Vec::new();
    for sigma in [0.4, 0.8, 1.2, 1.6] {
        check_sigma(sigma, volume).unwrap();
        let smoothing = vec![
            LabelSmoothing {
                sigma_mm: Some(sigma),
                ..LabelSmoothing::default()
            };
            volume.labels.len() + 1
        ];
        let mut all = interfaces(volume, &[]);
        place_on_weights(volume, &mut all, &smoothing);
        let mesh = label_surfaces(volume, &all).remove(0).mesh;
        let curvature = average_normal_curvature(&mesh, &Topology::build(&mesh));
        let kept = signed_volume(&mesh) / voxels;
        eprintln!("sigma {sigma} mm: {curvature:.2} degrees, volume {kept:.4} of the voxels");
        assert!((kept - 1.0).abs() < 0.03, "sigma {sigma}: volume {kept}");
        curvatures.push(curvature);
    }
    assert!(curvatures.windows(2).all(|w| w[1] < w[0]), "{curvatures:?}");
    // The next step up is refused with the range.
    assert!(check_sigma(2.0, volume).is_err());
}
