//! A scenario folder as `rtr scenarios generate` writes it (`train/`, `eval/`, `ood/`, one
//! JSON file per concrete scenario), read as sets: every file of a set folder is scored or
//! trained on, so a file that does not belong there would change the result unseen. Refused:
//! a hidden `.json` (the leftover of an interrupted write), a scenario labelled with another
//! set than its folder, the same scenario twice under two names (also with its states nudged:
//! the same draw of the same family), a scenario of another set (a training scenario copied
//! into `eval/`), a scenario of the set moved into another set's folder, and a scenario whose
//! recorded reference run is not what simulating it gives.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use rayon::prelude::*;
use sha2::{Digest, Sha256};

use super::{ConcreteScenario, ScenarioSet};
use crate::error::{Error, Result};

/// The scenarios of `set` in `root/<set>/`, in file-name order, checked as a set.
pub fn load_scenario_set(root: &Path, set: ScenarioSet) -> Result<Vec<ConcreteScenario>> {
    let dir = root.join(set.name());
    if !dir.is_dir() && root.is_dir() {
        return Err(Error::InvalidArgument(format!(
            "{}: no `{}` folder, so no {} set (a scenario folder holds train/, eval/ and ood/; \
             `rtr scenarios generate` leaves out a set drawn with no scenarios)",
            root.display(),
            set.name(),
            set.name()
        )));
    }
    let paths = scenario_files(&dir)?;
    let mut seen: BTreeMap<String, PathBuf> = BTreeMap::new();
    let mut scenarios = Vec::with_capacity(paths.len());
    for path in &paths {
        let scenario = ConcreteScenario::from_json_file(path)?;
        if scenario.set != set {
            return Err(Error::invalid(
                path.display().to_string(),
                "set",
                format!(
                    "is `{}`, but the file lies in the {} set's folder {}; a scenario is scored \
                     in the set it was drawn for",
                    scenario.set.name(),
                    set.name(),
                    dir.display()
                ),
            ));
        }
        for key in identities(&scenario)? {
            if let Some(first) = seen.insert(key, path.clone()) {
                return Err(duplicate(path, &first));
            }
        }
        scenarios.push(scenario);
    }
    refuse_other_sets(root, set, &seen)?;
    // The rollouts that check each `reference` are independent: in parallel.
    scenarios
        .par_iter()
        .zip(&paths)
        .try_for_each(|(scenario, path)| scenario.check_reference(&path.display().to_string()))?;
    Ok(scenarios)
}

/// The `.json` files of `dir` in name order. Anything else but rtr's own records is refused: a
/// set is scored whole, and a file or folder skipped in silence (`x.JSON`, `old/`) would
/// leave the user believing it was.
fn scenario_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for path in crate::io::list_folder(dir)? {
        if crate::io::is_bookkeeping(&path) {
            continue;
        }
        if path.is_dir() || path.extension().is_none_or(|e| e != "json") {
            return Err(Error::invalid(
                path.display().to_string(),
                if path.is_dir() { "folder" } else { "file" },
                "is not a scenario file (`*.json`) in a scenario set folder, whose every file \
                 is scored; move it out",
            ));
        }
        let hidden = path
            .file_name()
            .is_some_and(|n| n.to_string_lossy().starts_with('.'));
        if hidden {
            return Err(Error::invalid(
                path.display().to_string(),
                "file",
                "is hidden (the leftover of an interrupted write?) in a scenario set whose every \
                 file is scored; remove it",
            ));
        }
        out.push(path);
    }
    Ok(out)
}

/// What makes two scenarios the same drive, either of two keys:
/// - the content but the labels a copy could change (family, description, set, index, seed);
/// - the draw: every drawn value by name, when one of them is continuous. Two independent
///   draws never repeat a continuous value to the last digit, so a copy whose states were
///   nudged (a millimetre, a hundred metres) or whose family was renamed is still the draw it
///   was.
fn identities(scenario: &ConcreteScenario) -> Result<Vec<String>> {
    let mut keys = vec![fingerprint(scenario)?];
    if scenario.parameters.values().any(|v| v.fract() != 0.0) {
        let draw: Vec<String> = scenario
            .parameters
            .iter()
            .map(|(name, value)| format!("{name}={:x}", value.to_bits()))
            .collect();
        keys.push(format!("draw {}", draw.join(" ")));
    }
    Ok(keys)
}

/// The content key of [`identities`].
fn fingerprint(scenario: &ConcreteScenario) -> Result<String> {
    let bare = ConcreteScenario {
        family: String::new(),
        description: String::new(),
        set: ScenarioSet::Train,
        index: 0,
        seed: 0,
        content_sha256: None,
        ..scenario.clone()
    };
    let json = serde_json::to_vec(&bare)
        .map_err(|e| Error::InvalidArgument(format!("a scenario does not serialise: {e}")))?;
    Ok(Sha256::digest(&json)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect())
}

fn duplicate(path: &Path, first: &Path) -> Error {
    Error::invalid(
        path.display().to_string(),
        "scenario",
        format!(
            "is the same scenario as {}; a set that holds one twice weighs it twice",
            first.display()
        ),
    )
}

/// Refuses a scenario of `seen` ([`identities`] -> file) that is also in another set's folder
/// under `root`, and a scenario of `set` that lies in another set's folder. Files there that
/// do not load are left to that set's own loading.
fn refuse_other_sets(
    root: &Path,
    set: ScenarioSet,
    seen: &BTreeMap<String, PathBuf>,
) -> Result<()> {
    for other in ScenarioSet::ALL.into_iter().filter(|s| *s != set) {
        let dir = root.join(other.name());
        if !dir.is_dir() {
            continue;
        }
        for path in scenario_files(&dir).unwrap_or_default() {
            let Ok(scenario) = ConcreteScenario::from_json_file(&path) else {
                continue;
            };
            if scenario.set == set {
                // Moved out of this set's folder: the set would be scored without it.
                return Err(Error::invalid(
                    path.display().to_string(),
                    "set",
                    format!(
                        "is `{}`, but the file lies in the {} set's folder; the {} set in {} \
                         would be used without it. Move it back",
                        set.name(),
                        other.name(),
                        set.name(),
                        root.join(set.name()).display()
                    ),
                ));
            }
            let ours = identities(&scenario)?
                .into_iter()
                .find_map(|key| seen.get(&key));
            if let Some(ours) = ours {
                return Err(Error::invalid(
                    ours.display().to_string(),
                    "scenario",
                    format!(
                        "is the same scenario as {} of the {} set: sets must not share a \
                         scenario (one seen in training would be scored as unseen)",
                        path.display(),
                        other.name()
                    ),
                ));
            }
        }
    }
    Ok(())
}
