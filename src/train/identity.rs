//! A run's identity beyond its config: the contents of the files it reads (a dynamics file,
//! a curated scene list, CommonRoad clips, the long-tail scenario folder, a KL reference
//! policy). The config names them by path; the same path with other contents would change
//! the run's physics or data mid-run, so `--resume` (and a sweep reusing a trained point)
//! compares these digests as well.

use std::collections::BTreeMap;
use std::path::Path;

use crate::data::automatum::{sha256_hex, short_digest};
use crate::error::{Error, Result};
use crate::io::Format;

use super::config::TrainConfig;

/// sha256 of every file `config` reads during a run, keyed by "field path"; a folder input
/// gives one entry per file the run reads from it ("field folder/file"), so a change is named
/// by its file and a file the run does not read (a scenario folder's eval/, a note beside the
/// clips) changes nothing. The warm start is recorded as `reference.init` where the KL
/// reference is built from it (every resume reads it again), else as [`WARM_START`]: only a
/// new run reads it, so a resume ignores it, but a study reusing a finished run does not.
pub fn input_digests(config: &TrainConfig) -> Result<BTreeMap<String, String>> {
    let mut out = BTreeMap::new();
    if let Some(init) = &config.init {
        let file = init.policy_file();
        let reference = reference_is_warm_start(config);
        // A warm start that is gone only matters to a new run, whose loading names it.
        if reference || file.is_file() {
            let field = if reference {
                "reference.init"
            } else {
                WARM_START
            };
            let bytes =
                crate::io::read_bytes(&file, Format::Parameters).map_err(|e| e.in_field(field))?;
            out.insert(format!("{field} {}", file.display()), sha256_hex(&bytes));
        }
    }
    for (field, path) in config.input_paths() {
        if field == "init.policy" {
            continue;
        }
        if !path.is_dir() {
            let bytes =
                crate::io::read_bytes(&path, format_of(field)).map_err(|e| e.in_field(field))?;
            out.insert(format!("{field} {}", path.display()), sha256_hex(&bytes));
            continue;
        }
        for file in crate::io::files_in_tree(&path).map_err(|e| e.in_field(field))? {
            let relative = file.strip_prefix(&path).unwrap_or(&file);
            if read_from_folder(field, relative) {
                let bytes = crate::io::read_bytes(&file, format_of(field))
                    .map_err(|e| e.in_field(field))?;
                out.insert(format!("{field} {}", file.display()), sha256_hex(&bytes));
            }
        }
    }
    Ok(out)
}

/// The field under which a warm start that only a new run reads is recorded.
const WARM_START: &str = "init.policy";

/// Whether `input` (a key of [`input_digests`]) is the warm start that only a new run reads.
fn is_warm_start(input: &str) -> bool {
    input
        .strip_prefix(WARM_START)
        .is_some_and(|rest| rest.starts_with(' '))
}

/// What a run is compared against: a resume reads its inputs again, but not its warm start
/// (the weights come from the checkpoint); a study reusing a finished run asks whether the
/// run is what it would train now, warm start included.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Compare {
    Resume,
    Reuse,
}

/// The digests a resumed run records: `now`'s, but the warm start's as the run recorded it
/// (the run was trained from that file, whatever lies at its path now); none if it recorded
/// none.
pub fn resumed_digests(
    recorded: &BTreeMap<String, String>,
    now: BTreeMap<String, String>,
) -> BTreeMap<String, String> {
    let kept = recorded.iter().filter(|(k, _)| is_warm_start(k));
    now.into_iter()
        .filter(|(k, _)| !is_warm_start(k))
        .chain(kept.map(|(k, v)| (k.clone(), v.clone())))
        .collect()
}

/// Whether the run builds its KL reference from the warm start, on every start and resume.
fn reference_is_warm_start(config: &TrainConfig) -> bool {
    config.method.uses_reference() && config.reference.as_ref().is_some_and(|r| r.init)
}

/// The read cap of the files a run file's path `field` names.
pub fn format_of(field: &str) -> Format {
    match field {
        "dynamics" => Format::Settings,
        "data.curated" => Format::SceneList,
        "data.commonroad.path" => Format::CommonRoad,
        "data.longtail_dir" => Format::Scenario,
        _ => Format::Parameters,
    }
}

/// Whether a run reads the file `relative` of the folder a `field` names: the training set of
/// a scenario folder, the clips of a CommonRoad folder, any file of another folder.
fn read_from_folder(field: &str, relative: &Path) -> bool {
    let name = relative.to_string_lossy();
    match field {
        "data.longtail_dir" => relative.starts_with("train") && name.ends_with(".json"),
        "data.commonroad.path" => {
            let name = name.to_lowercase();
            name.ends_with(".xml") || name.ends_with(".xml.gz")
        }
        // A model or run folder as the KL reference: its policy alone.
        "reference.checkpoint" => relative == Path::new("policy.bpk"),
        _ => true,
    }
}

/// The digests runs recorded before [`input_digests`] kept one entry per file: one per folder,
/// over all its files' names and contents.
fn folder_digests(config: &TrainConfig) -> Result<BTreeMap<String, String>> {
    let mut out = BTreeMap::new();
    for (field, path) in config.input_paths() {
        if field == "init.policy" || !path.is_dir() {
            continue;
        }
        let mut listing = String::new();
        for file in crate::io::files_in_tree(&path)? {
            let relative = file
                .strip_prefix(&path)
                .unwrap_or(&file)
                .display()
                .to_string();
            let bytes = crate::io::read_bytes(&file, Format::Parameters)?;
            listing.push_str(&format!("{relative} {}\n", sha256_hex(&bytes)));
        }
        out.insert(
            format!("{field} {}", path.display()),
            sha256_hex(listing.as_bytes()),
        );
    }
    Ok(out)
}

/// The first input whose contents differ between `recorded` (when the run started) and now
/// (`config`'s inputs as they are), as a message; `None` when all agree. A run recorded
/// without digests (an older checkpoint) has nothing to compare; one recorded with a digest
/// per folder is compared folder by folder.
pub fn changed_input(
    run_dir: &Path,
    recorded: &BTreeMap<String, String>,
    config: &TrainConfig,
    compare: Compare,
) -> Result<Option<Change>> {
    if recorded.is_empty() {
        return Ok(None);
    }
    // The warm start is compared only for a reuse, and only where the run recorded it.
    let warm_start_counts = compare == Compare::Reuse && recorded.keys().any(|k| is_warm_start(k));
    let recorded: BTreeMap<&String, &String> = recorded
        .iter()
        .filter(|(k, _)| warm_start_counts || !is_warm_start(k))
        .collect();
    let mut now = input_digests(config)?;
    now.retain(|k, _| warm_start_counts || !is_warm_start(k));
    let per_folder = folder_digests(config)?;
    for (&input, &then) in &recorded {
        let current = now.get(input).or_else(|| per_folder.get(input));
        let (field, path) = input.split_once(' ').unwrap_or((input.as_str(), ""));
        let change = match current {
            Some(current) if current == then => continue,
            Some(current) => Change {
                what: format!(
                    "{input} has other contents than when the run started (sha256 {} then, {} \
                     now)",
                    short_digest(then),
                    short_digest(current)
                ),
                restore: super::kept_inputs::restore_hint(run_dir, field, then, Path::new(path)),
            },
            None => Change {
                what: format!("{input} is no longer read (removed, or not named by this config)"),
                restore: "restore the file".into(),
            },
        };
        return Ok(Some(change));
    }
    // A file the run reads now and did not read then (added to a folder); a run recorded
    // with a digest per folder has compared it above.
    let per_file = !recorded.keys().any(|k| per_folder.contains_key(*k));
    if per_file && let Some(added) = now.keys().find(|k| !recorded.contains_key(k)) {
        return Ok(Some(Change {
            what: format!("{added} was not there when the run started"),
            restore: "remove it".into(),
        }));
    }
    Ok(None)
}

/// An input that changed since a run started, and how to undo the change.
#[derive(Debug, Clone, PartialEq)]
pub struct Change {
    pub what: String,
    /// "restore the file", or the command that puts the run's kept copy back.
    pub restore: String,
}

/// The sha256 a run recorded for its dynamics file, if it read one.
pub fn recorded_dynamics_digest(recorded: &BTreeMap<String, String>) -> Option<&str> {
    recorded
        .iter()
        .find(|(input, _)| input.starts_with("dynamics "))
        .map(|(_, digest)| digest.as_str())
}

/// Refuses to go on with a run whose inputs changed since it started.
pub fn check_unchanged(
    run_dir: &Path,
    recorded: &BTreeMap<String, String>,
    config: &TrainConfig,
) -> Result<()> {
    match changed_input(run_dir, recorded, config, Compare::Resume)? {
        None => Ok(()),
        Some(change) => Err(Error::InvalidArgument(format!(
            "{}: {}; resuming would change the run's physics or data mid-run: {}, or start a \
             new --out folder",
            run_dir.display(),
            change.what,
            change.restore
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
        None => {
            changed_input(run_dir, &state.input_digests, config, Compare::Reuse)?.map(|change| {
                format!(
                    "{}; to use the run as it was, {}",
                    change.what, change.restore
                )
            })
        }
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
        assert!(
            changed_input(dir.path(), &then, &config, Compare::Resume)
                .expect("compare")
                .is_none()
        );
        // The run keeps what it read: once the file is replaced, the message says how to
        // put it back.
        let run = dir.path().join("run");
        crate::train::kept_inputs::keep(&run, &config).expect("kept");
        std::fs::write(&dynamics, "[steering_lag]\ntau = 0.5\n").expect("write");
        let change = changed_input(&run, &then, &config, Compare::Resume)
            .expect("compare")
            .expect("changed");
        assert!(change.what.starts_with("dynamics "), "{change:?}");
        let copy = crate::train::kept_inputs::kept_copy(
            &run,
            "dynamics",
            &then.values().next().expect("one").clone(),
        )
        .expect("a kept copy");
        assert_eq!(
            std::fs::read_to_string(&copy).expect("copy"),
            "[steering_lag]\ntau = 0.3\n"
        );
        assert!(
            change.restore.starts_with(&format!(
                "the run kept what it read: `cp {}",
                copy.display()
            )),
            "{change:?}"
        );
        assert!(crate::train::kept_inputs::is_kept_folder(
            &run.join("inputs")
        ));
        std::fs::write(run.join("inputs/notes.txt"), "mine").expect("write");
        assert!(!crate::train::kept_inputs::is_kept_folder(
            &run.join("inputs")
        ));
        assert!(
            changed_input(dir.path(), &BTreeMap::new(), &config, Compare::Resume)
                .expect("compare")
                .is_none(),
            "an old checkpoint"
        );
    }

    /// A scenario folder counts by its training files only, each named when it changes; a
    /// run recorded with one digest for the whole folder is still compared.
    #[test]
    fn a_scenario_folder_is_compared_file_by_file_over_what_training_reads() {
        let dir = tempfile::tempdir().expect("temp dir");
        let sets = dir.path().join("scenarios");
        for set in ["train", "eval"] {
            std::fs::create_dir_all(sets.join(set)).expect("mkdir");
            std::fs::write(sets.join(set).join("a.json"), "{}").expect("write");
        }
        let mut config =
            TrainConfig::from_toml_str("method = \"RTR\"\nalpha = 0.5", "test").expect("config");
        config.data.longtail_dir = Some(sets.clone());
        let then = input_digests(&config).expect("digests");
        assert_eq!(then.len(), 1, "{then:?}");
        let legacy = folder_digests(&config).expect("per folder");
        // What training does not read changes nothing.
        std::fs::write(sets.join("eval/a.json"), "{ }").expect("write");
        std::fs::write(sets.join("train/notes.txt"), "mine").expect("write");
        std::fs::write(sets.join(".rtr-output"), "train/a.json\n").expect("write");
        assert!(
            changed_input(dir.path(), &then, &config, Compare::Resume)
                .expect("compare")
                .is_none()
        );
        // A changed or added training scenario is named.
        std::fs::write(sets.join("train/a.json"), "{ }").expect("write");
        let change = changed_input(dir.path(), &then, &config, Compare::Resume)
            .expect("compare")
            .expect("changed");
        assert!(change.what.contains("train/a.json"), "{change:?}");
        std::fs::write(sets.join("train/a.json"), "{}").expect("write");
        std::fs::write(sets.join("train/b.json"), "{}").expect("write");
        let change = changed_input(dir.path(), &then, &config, Compare::Resume)
            .expect("compare")
            .expect("added");
        assert!(
            change.what.contains("train/b.json") && change.what.contains("not there"),
            "{change:?}"
        );
        // A run recorded with the folder's digest: compared as a whole.
        let change = changed_input(dir.path(), &legacy, &config, Compare::Resume)
            .expect("compare")
            .expect("changed");
        assert!(change.what.contains("has other contents"), "{change:?}");
        std::fs::remove_file(sets.join("train/b.json")).expect("remove");
        std::fs::write(sets.join("eval/a.json"), "{}").expect("write");
        std::fs::remove_file(sets.join("train/notes.txt")).expect("remove");
        assert!(
            changed_input(dir.path(), &legacy, &config, Compare::Resume)
                .expect("compare")
                .is_none()
        );
    }

    /// A warm start only a new run reads: a resume does not look at it, a study reusing the
    /// run does, and a resumed run keeps the digest of the file it was trained from.
    #[test]
    fn a_changed_warm_start_stops_a_reuse_but_not_a_resume() {
        let dir = tempfile::tempdir().expect("temp dir");
        let warm = dir.path().join("il");
        std::fs::create_dir(&warm).expect("mkdir");
        std::fs::write(warm.join("policy.bpk"), "weights").expect("write");
        let dynamics = dir.path().join("dynamics.toml");
        std::fs::write(&dynamics, "[steering_lag]\ntau = 0.3\n").expect("write");
        let text = format!(
            "method = \"RL\"\n[init]\npolicy = {:?}",
            warm.display().to_string()
        );
        let mut config = TrainConfig::from_toml_str(&text, "test").expect("config");
        config.dynamics = Some(dynamics);
        let then = input_digests(&config).expect("digests");
        assert_eq!(
            then.keys().filter(|k| is_warm_start(k)).count(),
            1,
            "{then:?}"
        );
        std::fs::write(warm.join("policy.bpk"), "other weights").expect("write");
        assert!(
            changed_input(dir.path(), &then, &config, Compare::Resume)
                .expect("compare")
                .is_none()
        );
        let change = changed_input(dir.path(), &then, &config, Compare::Reuse)
            .expect("compare")
            .expect("changed");
        assert!(
            change.what.starts_with("init.policy ") && change.what.contains("other contents"),
            "{change:?}"
        );
        let now = input_digests(&config).expect("digests");
        assert_eq!(resumed_digests(&then, now.clone()), then);
        // Gone, it stops neither a resume nor the record of what the run was trained from.
        std::fs::remove_file(warm.join("policy.bpk")).expect("remove");
        assert!(
            changed_input(dir.path(), &then, &config, Compare::Resume)
                .expect("compare")
                .is_none()
        );
        let gone = input_digests(&config).expect("digests without the warm start");
        assert_eq!(resumed_digests(&then, gone), then);
        // A run recorded before warm starts were: nothing to compare the warm start with.
        let older: BTreeMap<String, String> = then
            .into_iter()
            .filter(|(k, _)| !is_warm_start(k))
            .collect();
        assert!(
            !resumed_digests(&older, now)
                .keys()
                .any(|k| is_warm_start(k))
        );
        assert!(
            changed_input(dir.path(), &older, &config, Compare::Reuse)
                .expect("compare")
                .is_none()
        );
    }
}
