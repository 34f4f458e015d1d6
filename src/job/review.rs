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
    let names: BTreeSet<&str> = found
        .cases
        .iter()
        .flat_map(|c| c.meshes.iter().map(|(n, _)| n.as_str()))
        .collect();
    let list = names.iter().copied().collect::<Vec<_>>().join(", ");
    let mut told = BTreeSet::new();
    for name in &names {
        for reference in plan.settings_for(name).references {
            if !names.contains(reference.as_str()) && told.insert(reference.clone()) {
                r.errors.push(format!(
                    "reference {reference:?} (of {name:?}) names no structure of any case; the structures are: {list}"
                ));
            }
        }
    }
    for pattern in plan.structure_patterns() {
        if !names
            .iter()
            .any(|n| plan.matching_tables(n).contains(&pattern))
        {
            r.warnings.push(format!(
                "[[structure]] pattern {pattern:?} matches no structure (the structures are: {list})"
            ));
        }
    }
    r
}
