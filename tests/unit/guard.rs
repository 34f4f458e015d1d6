//! Tests of `src/guard/mod.rs`.

use destair::guard::*;

use crate::cuboid;

#[test]
fn distances_contacts_and_far_pairs_by_hand() {
    let a = cuboid([0.0; 3], [1.0; 3]);
    // 0.5 mm from a, then moved to touch it face to face.
    let b0 = cuboid([1.5, 0.0, 0.0], [2.5, 1.0, 1.0]);
    let b1 = cuboid([1.0, 0.2, 0.2], [2.0, 0.8, 0.8]);
    // Overlapping a already in the input, unchanged.
    let c = cuboid([0.5, -1.0, 0.5], [0.8, 0.1, 0.8]);
    // Far from everything.
    let d = cuboid([40.0, 0.0, 0.0], [41.0, 1.0, 1.0]);
    let table = pair_table(
        &[
            Surface {
                name: "b",
                before: &b0,
                after: &b1,
                shares_triangles_with: &[],
            },
            Surface {
                name: "a",
                before: &a,
                after: &a,
                shares_triangles_with: &[],
            },
            Surface {
                name: "c",
                before: &c,
                after: &c,
                shares_triangles_with: &[],
            },
            Surface {
                name: "d",
                before: &d,
                after: &d,
                shares_triangles_with: &[],
            },
        ],
        true,
    );
    let names: Vec<(&str, &str)> = table
        .pairs
        .iter()
        .map(|p| (p.a.as_str(), p.b.as_str()))
        .collect();
    assert_eq!(names, [("a", "b"), ("a", "c"), ("b", "c")]);
    assert_eq!(table.n_far_pairs, 3);
    let ab = &table.pairs[0];
    assert_eq!(ab.min_distance_before_mm, 0.5);
    assert_eq!(ab.min_distance_after_mm, Some(0.0));
    assert_eq!(ab.change_mm, -0.5);
    assert!(!ab.contact_before && ab.contact_after == Some(true) && ab.new_contact);
    // Face to face: the two triangles of b's face meet those of a's, and the edges round.
    assert!(ab.new_contact_triangle_pairs >= 2, "{ab:?}");
    // Overlapping in the input: not new, and not measured after.
    let ac = &table.pairs[1];
    assert!(ac.contact_before && ac.contact_after.is_none() && !ac.new_contact);
    assert_eq!((ac.min_distance_before_mm, ac.change_mm), (0.0, 0.0));
    // b and c: 0.7 apart along x before; after, 0.2 along x and 0.1 along y.
    let bc = &table.pairs[2];
    assert!((bc.min_distance_before_mm - 0.7).abs() < 1e-6, "{bc:?}");
    assert!(
        (bc.min_distance_after_mm.unwrap() - 0.05f64.sqrt()).abs() < 1e-6,
        "{bc:?}"
    );
    assert_eq!(table.pairs.iter().filter(|p| p.new_contact).count(), 1);
    assert!(table
        .structures
        .iter()
        .all(|r| r.self_intersections_before == 0 && r.self_intersections_after == 0));
}

#[test]
fn an_update_after_one_structure_changed_equals_measuring_everything() {
    let a = cuboid([0.0; 3], [1.0; 3]);
    let b0 = cuboid([1.5, 0.0, 0.0], [2.5, 1.0, 1.0]);
    let b1 = cuboid([1.2, 0.0, 0.0], [2.2, 1.0, 1.0]);
    let c = cuboid([0.0, 1.4, 0.0], [1.0, 2.4, 1.0]);
    let surfaces = |b_after| {
        [("a", &a, &a), ("b", &b0, b_after), ("c", &c, &c)].map(|(name, before, after)| Surface {
            name,
            before,
            after,
            shares_triangles_with: &[],
        })
    };
    let first = pair_table(&surfaces(&b0), true);
    let updated = update_pair_table(&surfaces(&b1), &first, &["b"], true);
    assert_eq!(updated, pair_table(&surfaces(&b1), true));
    assert!((updated.pairs[0].change_mm + 0.3).abs() < 1e-6);
}

/// Labels of one map that share interface triangles touch by construction: naming them as such
/// gives the table measuring them gives, without measuring (random label volumes, every pair).
#[test]
fn pairs_known_to_share_triangles_get_the_measured_rows() {
    use destair::volume::{Grid, LabelVolume, Space};
    let mut rng = fastrand::Rng::with_seed(8);
    for _ in 0..6 {
        let dims = [rng.usize(3..9), rng.usize(3..9), rng.usize(2..6)];
        let n: usize = dims.iter().product();
        let grid = Grid::axis_aligned([0.8, 0.8, 2.0], [0.0; 3], Space::Lps);
        let v = LabelVolume::from_values(dims, grid, (0..n).map(|_| rng.i64(0..5))).unwrap();
        let all = destair::extract::interfaces(&v, &[]);
        let surfaces = destair::extract::label_surfaces(&v, &all);
        let names: Vec<String> = surfaces.iter().map(|s| format!("l{}", s.label)).collect();
        let sharing: Vec<Vec<String>> = surfaces
            .iter()
            .map(|s| {
                let mut with: Vec<String> = all
                    .sides
                    .iter()
                    .filter(|x| x.contains(&s.label) && !x.contains(&0))
                    .map(|x| format!("l{}", x[0] + x[1] - s.label))
                    .collect();
                with.sort();
                with.dedup();
                with
            })
            .collect();
        let list = |known: bool| -> Vec<Surface> {
            surfaces
                .iter()
                .zip(&names)
                .zip(&sharing)
                .map(|((s, name), with)| Surface {
                    name,
                    before: &s.mesh,
                    after: &s.mesh,
                    shares_triangles_with: if known { with } else { &[] },
                })
                .collect()
        };
        assert_eq!(
            pair_table(&list(true), false),
            pair_table(&list(false), false)
        );
        assert!(sharing.iter().any(|w| !w.is_empty()));
    }
}
