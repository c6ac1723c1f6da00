//! A run's identity beyond its config: the contents of the files it reads (a dynamics file,
//! a curated scene list, CommonRoad clips, the long-tail scenario folder, a KL reference
//! policy). The config names them by path; the same path with other contents would change
//! the run's physics or data mid-run, so `--resume` (and a sweep reusing a trained point)
//! compares these digests as well.

use std::collections::BTreeMap;
use std::path::Path;

use crate::data::automatum::sha256_hex;
use crate::error::{Error, Result};
use crate::io::Format;

use super::config::TrainConfig;

/// sha256 of every file `config` reads during a run (not its warm start, which only a new run
/// reads), keyed by "field path".
pub fn input_digests(config: &TrainConfig) -> Result<BTreeMap<String, String>> {
    let mut out = BTreeMap::new();
    for (field, path) in config.input_paths() {
        if field == "init.policy" {
            continue;
        }
        let format = match field {
            "dynamics" => Format::Settings,
            "data.curated" => Format::SceneList,
            "data.commonroad.path" => Format::CommonRoad,
            _ => Format::Parameters,
        };
        out.insert(
            format!("{field} {}", path.display()),
            digest(&path, format)?,
        );
    }
    Ok(out)
}

/// sha256 of the file `path`, or of a folder's files (their names relative to it and their
/// contents, in name order; rtr's own hidden files skipped).
fn digest(path: &Path, format: Format) -> Result<String> {
    if !path.is_dir() {
        return Ok(sha256_hex(&crate::io::read_bytes(path, format)?));
    }
    let mut listing = String::new();
    for file in files_under(path)? {
        let relative = file
            .strip_prefix(path)
            .unwrap_or(&file)
            .display()
            .to_string();
        let bytes = crate::io::read_bytes(&file, Format::Parameters)?;
        listing.push_str(&format!("{relative} {}\n", sha256_hex(&bytes)));
    }
    Ok(sha256_hex(listing.as_bytes()))
}

fn files_under(dir: &Path) -> Result<Vec<std::path::PathBuf>> {
    let mut out = Vec::new();
    for path in crate::io::list_folder(dir)? {
        let hidden = path
            .file_name()
            .is_some_and(|n| n.to_string_lossy().starts_with('.'));
        if hidden {
            continue;
        }
        if path.is_dir() {
            out.extend(files_under(&path)?);
        } else {
            out.push(path);
        }
    }
    Ok(out)
}

/// The first input whose contents differ between `recorded` (when the run started) and `now`,
/// as a message; `None` when all agree. A run recorded without digests (an older checkpoint)
/// has nothing to compare.
pub fn changed_input(
    recorded: &BTreeMap<String, String>,
    now: &BTreeMap<String, String>,
) -> Option<String> {
    if recorded.is_empty() {
        return None;
    }
    recorded
        .iter()
        .find_map(|(input, then)| match now.get(input) {
            Some(current) if current == then => None,
            Some(current) => Some(format!(
                "{input} has other contents than when the run started (sha256 {} then, {} now)",
                &then[..12],
                &current[..12]
            )),
            None => Some(format!("{input} is no longer read by this config")),
        })
}

/// Refuses to go on with a run whose inputs changed since it started.
pub fn check_unchanged(
    run_dir: &Path,
    recorded: &BTreeMap<String, String>,
    now: &BTreeMap<String, String>,
) -> Result<()> {
    match changed_input(recorded, now) {
        None => Ok(()),
        Some(change) => Err(Error::InvalidArgument(format!(
            "{}: {change}; resuming would change the run's physics or data mid-run. Restore \
             the file, or start a new --out folder",
            run_dir.display()
        ))),
    }
}

/// Refuses a finished (or stopped) run in `run_dir` that was not made with `config` and the
/// present contents of its inputs: a study that keeps finished runs (a sweep's points) must
/// not keep one trained from another base.
pub fn check_same_run(run_dir: &Path, config: &TrainConfig) -> Result<()> {
    let Some(newest) = super::checkpoint::latest(run_dir)? else {
        return Ok(());
    };
    let state = super::checkpoint::read_state(&newest)?;
    let stored = TrainConfig::from_toml_str(&state.config_toml, &newest.display().to_string())?;
    let difference = match stored.identity_difference(config)? {
        Some(difference) => Some(difference),
        None => changed_input(&state.input_digests, &input_digests(config)?),
    };
    match difference {
        None => Ok(()),
        Some(difference) => Err(Error::InvalidArgument(format!(
            "{} was trained from another config or inputs ({difference}); remove the folder \
             to train it again, or restore what changed",
            run_dir.display()
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_changed_dynamics_file_is_named_and_an_unchanged_run_passes() {
        let dir = tempfile::tempdir().expect("temp dir");
        let dynamics = dir.path().join("dynamics.toml");
        std::fs::write(&dynamics, "[steering_lag]\ntau = 0.3\n").expect("write");
        let mut config = TrainConfig::from_toml_str("method = \"IL\"", "test").expect("config");
        config.dynamics = Some(dynamics.clone());
        let then = input_digests(&config).expect("digests");
        assert_eq!(then.len(), 1);
        assert!(changed_input(&then, &input_digests(&config).expect("again")).is_none());
        std::fs::write(&dynamics, "[steering_lag]\ntau = 0.5\n").expect("write");
        let change = changed_input(&then, &input_digests(&config).expect("now")).expect("changed");
        assert!(change.starts_with("dynamics "), "{change}");
        assert!(
            changed_input(&BTreeMap::new(), &then).is_none(),
            "an old checkpoint"
        );
    }

    #[test]
    fn a_folder_digest_covers_names_and_contents() {
        let dir = tempfile::tempdir().expect("temp dir");
        let sets = dir.path().join("scenarios");
        std::fs::create_dir_all(sets.join("train")).expect("mkdir");
        std::fs::write(sets.join("train/a.json"), "{}").expect("write");
        let first = digest(&sets, Format::Scenario).expect("digest");
        std::fs::write(sets.join(".rtr-output"), "train/a.json\n").expect("write");
        assert_eq!(digest(&sets, Format::Scenario).expect("digest"), first);
        std::fs::write(sets.join("train/a.json"), "{ }").expect("write");
        assert_ne!(digest(&sets, Format::Scenario).expect("digest"), first);
    }
}
