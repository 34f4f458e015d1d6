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
