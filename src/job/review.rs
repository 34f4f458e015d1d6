//! What a configuration and the cohort it finds say together, before anything runs: errors
//! that make a run pointless (a root that does not exist, no cases, a reference that no case
//! has) and warnings about what is probably a slip (a `[[structure]]` pattern that matches no
//! structure). `check` prints both; `run` refuses on errors and repeats the warnings.

use super::discover::Discovery;
use super::plan::Plan;
use std::collections::BTreeSet;

/// The findings of [`review`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Review {
    pub errors: Vec<String>,
    pub warnings: Vec<String>,
    /// The label structures' names known before any voxel is read: `[labels]` and the label
    /// maps' segment names.
    pub label_names: BTreeSet<String>,
}

/// The names of label structures known before any voxel is read: `[labels]` and the segment
/// names of the label maps' headers (Slicer's) for labels `[labels]` does not name. Label maps
/// name the rest `label_<value>` once read. Empty when no case has a label map.
fn label_structure_names(plan: &Plan, found: &Discovery) -> BTreeSet<String> {
    let mut names = BTreeSet::new();
    let mut label_maps = found.cases.iter().flat_map(|c| &c.label_maps).peekable();
    if label_maps.peek().is_none() {
        return names;
    }
    names.extend(plan.label_names.values().cloned());
    for path in label_maps {
        for seg in crate::volume::declared_segments(path) {
            if plan.label_name(seg.layer, seg.value).is_none() {
                names.insert(seg.name);
            }
        }
    }
    names
}

/// Reviews a plan against its discovered cases.
pub fn review(plan: &Plan, found: &Discovery) -> Review {
    let mut r = Review::default();
    for root in &plan.roots {
        if !root.is_dir() {
            r.errors.push(format!(
                "[input] roots: {} does not exist or is not a folder",
                plan.display(root)
            ));
        }
    }
    if found.cases.is_empty() {
        r.errors.push(format!(
            "no cases found under {} ({}; check [input] roots and case_depth)",
            plan.roots
                .iter()
                .map(|p| plan.display(p))
                .collect::<Vec<_>>()
                .join(", "),
            plan.mesh_selection()
        ));
        return r;
    }
    let mut names: BTreeSet<String> = found
        .cases
        .iter()
        .flat_map(|c| c.meshes.iter().map(|(n, _)| n.clone()))
        .collect();
    let label_maps: Vec<&std::path::PathBuf> =
        found.cases.iter().flat_map(|c| &c.label_maps).collect();
    r.label_names = label_structure_names(plan, found);
    names.extend(r.label_names.iter().cloned());
    let unnamed_label = |n: &str| {
        !label_maps.is_empty()
            && n.strip_prefix("label_")
                .is_some_and(|v| v.parse::<i64>().is_ok())
    };
    let list = names.iter().cloned().collect::<Vec<_>>().join(", ");
    let mut told = BTreeSet::new();
    for name in &names {
        for reference in plan.settings_for(name).references {
            if !names.contains(reference.as_str())
                && !unnamed_label(&reference)
                && told.insert(reference.clone())
            {
                r.errors.push(format!(
                    "reference {reference:?} (of {name:?}) names no structure of any case; the structures are: {list}"
                ));
            }
        }
    }
    for pattern in plan.structure_patterns() {
        let matches = names
            .iter()
            .any(|n| plan.matching_tables(n).contains(&pattern));
        // A pattern such as "label_*" may match the unnamed labels of a label map.
        let may_match_label = !label_maps.is_empty()
            && (pattern.starts_with("label_")
                || glob::Pattern::new(pattern).is_ok_and(|p| p.matches("label_1")));
        if !matches && !may_match_label {
            r.warnings.push(format!(
                "[[structure]] pattern {pattern:?} matches no structure (the structures are: {list})"
            ));
        }
    }
    r
}
