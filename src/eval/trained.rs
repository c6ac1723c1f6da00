//! A trained policy as `rtr eval` and the example load it: a run folder (or a `models/`
//! folder) holding the run's `config.toml` and the finished `policy.bpk`, a checkpoint
//! folder `checkpoints/iter-NNNNNN/`, or an unfinished run folder (its newest checkpoint).

use std::path::{Path, PathBuf};

use crate::data::automatum::{sha256_hex, short_digest};
use crate::error::{Error, Result};
use crate::model::PolicyNetwork;
use crate::sim::Dynamics;
use crate::train::{LoopState, TrainConfig, load_policy};

const POLICY: &str = "policy.bpk";
const CONFIG: &str = "config.toml";
const STATE: &str = "state.json";

pub struct TrainedPolicy {
    /// The method's table name (from the run's config).
    pub method: String,
    /// The policy file loaded.
    pub path: PathBuf,
    /// The run's `config.toml` it was read with.
    pub config_path: PathBuf,
    pub config: TrainConfig,
    pub network: PolicyNetwork,
    /// The simulator it was trained in (its action limits and physics terms).
    pub dynamics: Dynamics,
    /// The training it came from ([`LoopState::run_id`]), where its run recorded one.
    pub run_id: Option<String>,
}

/// The policy file and the run config for `path` (a run folder, a checkpoint folder inside
/// one, or a `policy.bpk` file). A run folder without a finished policy gives its newest
/// checkpoint's; one whose `policy.bpk` is there but no file (a FIFO, a folder) is refused.
fn locate(path: &Path) -> Result<(PathBuf, PathBuf)> {
    let (dir, policy) = if path.is_file() {
        let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
        (dir, path.to_path_buf())
    } else if path.join(POLICY).symlink_metadata().is_err()
        && let Some(newest) = crate::train::checkpoint::latest(path)?
    {
        (newest.clone(), newest.join(POLICY))
    } else {
        (path.to_path_buf(), path.join(POLICY))
    };
    if let Some(why) = crate::io::not_regular(&policy) {
        return Err(Error::invalid(policy.display().to_string(), "file", why));
    }
    if !policy.is_file() {
        return Err(Error::InvalidArgument(format!(
            "{}: no {POLICY} there (a finished run folder, models/<method>/, or a \
             checkpoints/iter-* folder was expected)",
            path.display()
        )));
    }
    // A checkpoint folder sits two levels below its run's config.
    let candidates = [dir.join(CONFIG), dir.join("../..").join(CONFIG)];
    // The first one there at all: a `config.toml` that is a folder or a FIFO is named as
    // such, not reported missing.
    let config = candidates
        .iter()
        .find(|c| c.symlink_metadata().is_ok())
        .cloned()
        .ok_or_else(|| {
            Error::InvalidArgument(format!(
                "{}: no {CONFIG} beside the policy or in its run folder; it names the model \
                 size the policy was trained with",
                path.display()
            ))
        })?;
    if let Some(why) = crate::io::not_regular(&config) {
        return Err(Error::invalid(config.display().to_string(), "file", why));
    }
    Ok((policy, config))
}

/// `inputs` with each policy of `paths` (given with `flag`, each checked to be a file or a
/// folder) and every file its run reads (its run file's `dynamics`, `data.curated`, ...): an
/// output written over one of those would change, or stop, that run's own `--resume`. A path
/// that is no trained policy adds itself alone (its loading names what is wrong).
pub fn with_run_inputs<P: AsRef<Path>>(
    inputs: crate::io::Inputs,
    flag: &str,
    paths: impl IntoIterator<Item = P>,
) -> Result<crate::io::Inputs> {
    paths.into_iter().try_fold(inputs, |inputs, path| {
        let path = path.as_ref();
        crate::io::check_input_path(path, flag)?;
        let read = locate(path).ok().and_then(|(_, config_path)| {
            let text = crate::io::read_text(&config_path, crate::io::Format::Settings).ok()?;
            TrainConfig::from_toml_str(&text, &config_path.display().to_string()).ok()
        });
        let run_files = read.map(|c| c.input_paths()).unwrap_or_default();
        Ok(run_files
            .into_iter()
            .fold(inputs.with(flag, path), |inputs, (field, file)| {
                inputs.with(
                    &format!("{flag} {}'s run file's `{field}`", path.display()),
                    file,
                )
            }))
    })
}

impl TrainedPolicy {
    /// The checkpoint (`iter-NNNNNN`) the policy was loaded from, if not a finished run's.
    pub fn checkpoint(&self) -> Option<String> {
        let folder = self.path.parent()?.file_name()?.to_str()?;
        folder.starts_with("iter-").then(|| folder.to_string())
    }

    /// The note a command prints when `given` (what the user named) is a run folder whose run
    /// is not finished, so its newest checkpoint was loaded instead of a final policy.
    pub fn unfinished_note(&self, given: &Path, doing: &str) -> Option<String> {
        let checkpoint = self.checkpoint()?;
        (self.path != given && self.path.parent() != Some(given)).then(|| {
            format!(
                "{}: the run is not finished; {doing} its newest checkpoint, {checkpoint}",
                given.display()
            )
        })
    }

    /// Loads the policy at `path` onto `device` (a plain, non-autodiff device).
    pub fn load(path: &Path, device: &burn::prelude::Device) -> Result<Self> {
        let (policy_path, config_path) = locate(path)?;
        let text = crate::io::read_text(&config_path, crate::io::Format::Settings)?;
        let mut config = TrainConfig::from_toml_str(&text, &config_path.display().to_string())?;
        let recorded = recorded_state(&policy_path, &config_path)?;
        if let Some((dir, state)) = &recorded {
            check_recorded_config(dir, state, &config, &config_path)?;
        }
        // Evaluation needs neither the frozen KL reference nor the training data.
        config.reference = None;
        config.dynamics = resolve_dynamics(config.dynamics.take(), &config_path)?;
        if let (Some((dir, state)), Some(dynamics)) = (&recorded, &config.dynamics) {
            check_recorded_dynamics(dir, state, dynamics)?;
        }
        let network = load_policy(&policy_path, &config.model, device)?;
        let dynamics = config.dynamics(device)?;
        Ok(Self {
            method: config.method.name().to_string(),
            path: policy_path,
            config_path,
            config,
            network,
            dynamics,
            run_id: recorded.and_then(|(_, state)| state.run_id),
        })
    }
}

/// The checkpoint that recorded how `policy` was trained: the checkpoint folder holding it, or
/// the newest checkpoint of the run folder holding the finished policy. `None` for a folder
/// without checkpoints (`models/<method>/`), where `config.toml` is all there is.
fn recorded_state(policy: &Path, config_path: &Path) -> Result<Option<(PathBuf, LoopState)>> {
    let folder = policy.parent().unwrap_or(Path::new("."));
    let dir = if folder.join(STATE).is_file() {
        Some(folder.to_path_buf())
    } else {
        crate::train::checkpoint::latest(config_path.parent().unwrap_or(Path::new(".")))?
    };
    match dir {
        Some(dir) => {
            let state = crate::train::checkpoint::read_state(&dir)?;
            Ok(Some((dir, state)))
        }
        None => Ok(None),
    }
}

/// Refuses a run's `config.toml` that says other than the config its checkpoint recorded in
/// `state.json` (hand-edited, or copied from another run): the policy would be evaluated
/// under settings (limits, physics, model options) it was not trained with.
fn check_recorded_config(
    dir: &Path,
    state: &LoopState,
    config: &TrainConfig,
    config_path: &Path,
) -> Result<()> {
    let origin = dir.join(STATE).display().to_string();
    let recorded = TrainConfig::from_toml_str(&state.config_toml, &origin)?;
    match recorded.identity_difference(config)? {
        None => Ok(()),
        Some(difference) => Err(Error::invalid(
            config_path.display().to_string(),
            "config",
            format!(
                "differs from the config {origin} recorded when the policy was trained \
                 ({difference}); the policy would be evaluated under other settings. Restore \
                 the run's config.toml"
            ),
        )),
    }
}

/// Refuses a dynamics file whose contents changed since the run that trained the policy read
/// it: the same path with other physics.
fn check_recorded_dynamics(dir: &Path, state: &LoopState, dynamics: &Path) -> Result<()> {
    let Some(then) = crate::train::identity::recorded_dynamics_digest(&state.input_digests) else {
        return Ok(());
    };
    let bytes = crate::io::read_bytes(dynamics, crate::io::Format::Settings)?;
    let now = sha256_hex(&bytes);
    if now == then {
        return Ok(());
    }
    // `dir` is a checkpoint, `RUN/checkpoints/iter-N`: the run keeps its inputs in RUN.
    let run_dir = dir.ancestors().nth(2).unwrap_or(dir);
    Err(Error::invalid(
        dynamics.display().to_string(),
        "dynamics",
        format!(
            "has other contents than when the policy in {} was trained (sha256 {} then, {} \
             now); the policy would be evaluated under other physics: {}",
            dir.display(),
            short_digest(then),
            short_digest(&now),
            crate::train::kept_inputs::restore_hint(run_dir, "dynamics", then, dynamics)
        ),
    ))
}

/// The dynamics file a run's `config.toml` names: as written if it exists (absolute, or
/// relative to the current folder as older runs stored it), else beside the config.
fn resolve_dynamics(path: Option<PathBuf>, config_path: &Path) -> Result<Option<PathBuf>> {
    let Some(path) = path else {
        return Ok(None);
    };
    let beside = config_path.parent().map(|dir| dir.join(&path));
    match (path.exists(), beside) {
        (true, _) => Ok(Some(path)),
        (false, Some(beside)) if beside.exists() => Ok(Some(beside)),
        _ => Err(Error::invalid(
            config_path.display().to_string(),
            "field `dynamics`",
            format!(
                "{} not found (looked from the current folder and beside config.toml); \
                 expected the dynamics file the run was trained with",
                path.display()
            ),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_folder_without_a_policy_is_named_in_the_error() {
        let dir = tempfile::tempdir().unwrap();
        let e = locate(dir.path()).unwrap_err().to_string();
        assert!(e.contains("no policy.bpk"), "{e}");
        std::fs::write(dir.path().join(POLICY), b"x").unwrap();
        let e = locate(dir.path()).unwrap_err().to_string();
        assert!(e.contains("no config.toml"), "{e}");
        std::fs::create_dir(dir.path().join(CONFIG)).unwrap();
        let e = locate(dir.path()).unwrap_err().to_string();
        assert!(
            e.contains("config.toml") && e.contains("is a folder"),
            "{e}"
        );
        std::fs::remove_dir(dir.path().join(CONFIG)).unwrap();
        std::fs::write(dir.path().join(CONFIG), b"method = \"IL\"").unwrap();
        let (p, c) = locate(dir.path()).unwrap();
        assert_eq!(p, dir.path().join(POLICY));
        assert_eq!(c, dir.path().join(CONFIG));
    }
}
