//! Training checkpoints: both networks, both optimizer states (burnpack) and the loop's
//! position, in one folder `checkpoints/iter-NNNNNN/`. The folder is written under a temporary
//! name and renamed into place, then `checkpoints/latest` is replaced atomically: a run killed
//! at any moment leaves the previous checkpoint whole and pointed to.
//!
//! Integrity: `state.json` records the sha256 of every tensor file, checked on load, and every
//! loaded parameter (here and in [`load_module`], used for any `policy.bpk`) must be finite, so
//! a corrupted file is refused by name instead of evaluated or trained on.

use std::collections::BTreeMap;
use std::path::{Component, Path, PathBuf};

use burn::module::Module;
use burn::optim::ModuleOptimizer;
use burn::store::ModuleRecord;
use burn::tensor::Bytes;
use serde::{Deserialize, Serialize};

use crate::data::automatum::sha256_hex;
use crate::error::{Error, Result};
use crate::io::atomic_write;
use crate::model::{ModelConfig, PolicyNetwork, ValueNetwork};

pub(super) const POLICY: &str = "policy.bpk";
const VALUE: &str = "value.bpk";
const POLICY_OPTIMIZER: &str = "policy_optimizer.bpk";
const VALUE_OPTIMIZER: &str = "value_optimizer.bpk";
pub(super) const STATE: &str = "state.json";
const LATEST: &str = "latest";
/// Checkpoints kept besides the newest (older ones are deleted) unless `run.keep_checkpoints`
/// says otherwise.
pub const DEFAULT_KEEP: usize = 1;

/// Where the loop stands.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LoopState {
    /// Iterations completed.
    pub iteration: usize,
    /// Optimizer steps taken.
    pub updates: usize,
    /// The run's config as TOML, so `--resume` can refuse a changed config.
    pub config_toml: String,
    /// What `ppo.target_kl` has made of the policy's learning rate, as a factor on the
    /// schedule's (1 without it).
    #[serde(default = "unit_scale")]
    pub policy_lr_scale: f64,
    /// sha256 of each tensor file of the checkpoint, by file name (empty in checkpoints written
    /// before checksums were kept; those are loaded unchecked).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub checksums: BTreeMap<String, String>,
    /// sha256 of each file the run reads, by "field path" ([`super::identity`]), so `--resume`
    /// can refuse an input whose contents changed (empty in checkpoints written before).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub input_digests: BTreeMap<String, String>,
    /// Which training this is: drawn when the run starts and kept through its resumes, so two
    /// runs of one run file are told apart (their weights share no basin, and a weight
    /// average must not mix them). Absent in checkpoints written before it was kept.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub run_id: Option<String>,
}

/// A new run's id: the digest of the moment, the process and the folder it starts in.
pub fn new_run_id(run_dir: &Path) -> String {
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    let seed = format!("{now} {} {}", std::process::id(), run_dir.display());
    sha256_hex(seed.as_bytes())[..16].to_string()
}

fn unit_scale() -> f64 {
    1.0
}

/// Everything a resumed run needs.
pub struct Checkpoint {
    pub policy: PolicyNetwork,
    pub value: ValueNetwork,
    pub policy_optimizer: ModuleOptimizer,
    pub value_optimizer: ModuleOptimizer,
    pub state: LoopState,
    pub dir: PathBuf,
}

fn record_error(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::invalid(
        path.display().to_string(),
        "checkpoint",
        format!("{e} (not a checkpoint written by this version of rtr?)"),
    )
}

/// A record that does not fit the module: when only shapes differ the file is fine and the
/// network it is loaded into is not, so say that (with the first mismatch, not all of them).
/// Reads burn's "Apply errors: [\"...\", \"...\"]" list; any other message keeps the
/// generic wording.
/// burn's `Shape { dims: [51, 64] }` as `[51, 64]`.
fn plain_shapes(text: &str) -> String {
    text.replace("Shape { dims: ", "").replace("] }", "]")
}

fn load_error(path: &Path, message: &str) -> Error {
    let mismatches: Vec<&str> = message
        .split("\", \"")
        .filter(|m| m.contains("shape mismatch"))
        .collect();
    match mismatches.first() {
        Some(first) => Error::invalid(
            path.display().to_string(),
            "checkpoint",
            format!(
                "its network has another shape than the [model] it is loaded with ({} of its \
                 parameters differ, first {}): load it with the [model] section of the run \
                 that wrote it (its config.toml)",
                mismatches.len(),
                plain_shapes(
                    first
                        .rsplit('"')
                        .find(|part| part.contains("shape mismatch"))
                        .unwrap_or(first)
                )
            ),
        ),
        None => record_error(path, message),
    }
}

fn read_bytes(path: &Path) -> Result<Bytes> {
    Ok(Bytes::from_bytes_vec(crate::io::read_bytes(
        path,
        crate::io::Format::Parameters,
    )?))
}

/// A module's parameters as burnpack bytes (what `policy.bpk` holds); `path` names it in errors.
pub(crate) fn module_bytes<M: Module>(module: &M, path: &Path) -> Result<Vec<u8>> {
    let bytes = module
        .clone()
        .into_record()
        .into_bytes()
        .map_err(|e| record_error(path, e))?;
    Ok(bytes.to_vec())
}

/// Finds the first parameter holding a non-finite value, by its path in the module.
#[derive(Default)]
struct NonFinite {
    path: Vec<String>,
    found: Option<(String, usize)>,
}

impl burn::module::ModuleVisitor for NonFinite {
    fn enter_module(&mut self, name: &str, _container_type: &str) {
        self.path.push(name.to_string());
    }

    fn exit_module(&mut self, _name: &str, _container_type: &str) {
        self.path.pop();
    }

    fn visit_float<const D: usize>(&mut self, param: &burn::module::Param<burn::Tensor<D>>) {
        if self.found.is_some() {
            return;
        }
        let values: Vec<f32> = param
            .val()
            .into_data()
            .convert::<f32>()
            .try_into_vec::<f32>()
            .unwrap_or_default();
        let bad = values.iter().filter(|v| !v.is_finite()).count();
        if bad > 0 {
            self.found = Some((self.path.join("."), bad));
        }
    }
}

/// The first parameter of `module` holding NaN or infinity: its path and how many values.
pub(crate) fn non_finite_parameter<M: Module>(module: &M) -> Option<(String, usize)> {
    let mut check = NonFinite::default();
    module.visit(&mut check);
    check.found
}

/// Refuses a module (read from `path`) with a NaN or infinite parameter.
fn check_finite<M: Module>(module: &M, path: &Path) -> Result<()> {
    match non_finite_parameter(module) {
        Some((name, count)) => Err(Error::invalid(
            path.display().to_string(),
            format!("parameter `{name}`"),
            format!(
                "{count} values are NaN or infinite: the file is corrupted, or was saved from a \
                 diverged run; expected finite weights"
            ),
        )),
        None => Ok(()),
    }
}

/// Refuses, before reading it, a parameter file far larger than `module`'s parameters (f32,
/// four bytes each, plus names and shapes): not this model's file, and possibly larger than
/// memory.
fn refuse_oversized<M: Module>(module: &M, path: &Path) -> Result<()> {
    let expected = 4 * module.num_params() as u64;
    let limit = 2 * expected + 16 * 1024 * 1024;
    let size = crate::io::open_regular(path)?
        .metadata()
        .map_err(|e| Error::io(path, e))?
        .len();
    if size > limit {
        return Err(Error::invalid(
            path.display().to_string(),
            "size",
            format!(
                "{size} bytes, where this model's {} parameters take about {expected}; \
                 expected the parameter file of a model of this config",
                module.num_params()
            ),
        ));
    }
    Ok(())
}

/// Loads a module's parameters from a burnpack file into `module` (which fixes the shapes);
/// every parameter must be finite.
pub fn load_module<M: Module>(module: M, path: &Path) -> Result<M> {
    refuse_oversized(&module, path)?;
    let bytes = crate::io::read_bytes(path, crate::io::Format::Parameters)?;
    super::recorded_weights::verify(path, &bytes)?;
    let record = ModuleRecord::from_bytes(Bytes::from_bytes_vec(bytes))
        .map_err(|e| record_error(path, e))?;
    let module = module
        .try_load_record(record)
        .map_err(|e| load_error(path, &e.to_string()))?;
    check_finite(&module, path)?;
    Ok(module)
}

/// A policy network of `config` with the parameters of a `policy.bpk`.
pub fn load_policy(
    path: &Path,
    config: &ModelConfig,
    device: &burn::prelude::Device,
) -> Result<PolicyNetwork> {
    load_module(PolicyNetwork::new(config, device), path)
}

/// The folder of the newest checkpoint under `run_dir`, if any.
pub fn latest(run_dir: &Path) -> Result<Option<PathBuf>> {
    let pointer = run_dir.join("checkpoints").join(LATEST);
    if pointer.symlink_metadata().is_err() {
        return Ok(None);
    }
    let name = crate::io::read_text(&pointer, crate::io::Format::Settings)?;
    if name.trim().is_empty() {
        return Err(Error::invalid(
            pointer.display().to_string(),
            "contents",
            "empty; expected the name of the newest checkpoint folder (iter-NNNNNN)",
        ));
    }
    let name = name.trim();
    let named = run_dir.join("checkpoints").join(name);
    let plain = Path::new(name).components().count() == 1
        && matches!(
            Path::new(name).components().next(),
            Some(Component::Normal(_))
        );
    if !plain || !named.is_dir() {
        return Err(Error::invalid(
            pointer.display().to_string(),
            "contents",
            format!(
                "names `{}`, which is not a checkpoint folder beside it; expected the name of \
                 the newest checkpoint folder (iter-NNNNNN) there",
                name.chars().take(80).collect::<String>()
            ),
        ));
    }
    Ok(Some(named))
}

/// The checkpoint a run in `run_dir` starts from: with `resume` the newest one, which must
/// exist; without, none, and `run_dir` must hold no run (it is never overwritten). Cheap, so a
/// command can refuse a wrong `--resume` before loading any data.
pub fn resume_point(run_dir: &Path, resume: bool) -> Result<Option<PathBuf>> {
    match (latest(run_dir)?, resume) {
        (Some(dir), true) => Ok(Some(dir)),
        (Some(dir), false) => Err(Error::InvalidArgument(format!(
            "{} already holds a run (checkpoint {}): pass --resume to continue it, or \
             choose another --out folder",
            run_dir.display(),
            dir.display()
        ))),
        (None, true) => Err(Error::InvalidArgument(format!(
            "{}: no checkpoint to resume ({} is missing); drop --resume to start a new \
             run there",
            run_dir.display(),
            run_dir.join("checkpoints").join(LATEST).display()
        ))),
        (None, false) => {
            refuse_files_without_a_run(run_dir)?;
            Ok(None)
        }
    }
}

/// Refuses a new run's folder that holds anything but what a run stopped before its first
/// checkpoint leaves (a `config.toml` that is a run's config, a `curves.csv` with the curve
/// columns, an empty `checkpoints/`, its kept `inputs/`): a file of the user's there would be
/// replaced.
fn refuse_files_without_a_run(run_dir: &Path) -> Result<()> {
    if !run_dir.is_dir() {
        return Ok(());
    }
    let runs_own = |path: &Path, name: &str| match name {
        "config.toml" => {
            crate::io::read_text(path, crate::io::Format::Settings).is_ok_and(|text| {
                text.contains("method")
                    && super::TrainConfig::from_toml_str(&text, "config.toml").is_ok()
            })
        }
        "curves.csv" => super::curves::read(path).is_ok(),
        "checkpoints" => crate::io::list_folder(path).is_ok_and(|entries| entries.is_empty()),
        super::kept_inputs::KEPT_FOLDER => super::kept_inputs::is_kept_folder(path),
        _ => false,
    };
    let foreign: Vec<String> = crate::io::list_folder(run_dir)?
        .iter()
        .filter_map(|p| {
            let name = p.file_name()?.to_string_lossy().into_owned();
            (!runs_own(p, &name)).then(|| if p.is_dir() { format!("{name}/") } else { name })
        })
        .collect();
    if foreign.is_empty() {
        return Ok(());
    }
    Err(Error::InvalidArgument(format!(
        "{}: holds files but no run ({}); a run writes config.toml, curves.csv, inputs/ \
         and checkpoints/ there, and would replace them. Choose an empty or new folder",
        run_dir.display(),
        foreign.join(", ")
    )))
}

/// Whether `run_dir` holds at least one checkpoint (its `latest` pointer exists).
pub fn has_checkpoint(run_dir: &Path) -> bool {
    run_dir.join("checkpoints").join(LATEST).exists()
}

/// The training run folder that `path` is or lies inside (however spelled), if any: there
/// the trainer replaces and prunes what it finds, so no other command may write there.
pub fn enclosing_run(path: &Path) -> Option<PathBuf> {
    crate::io::resolved(path)
        .ancestors()
        .find(|dir| has_checkpoint(dir))
        .map(Path::to_path_buf)
}

/// Writes a checkpoint for `state.iteration`, points `latest` at it and deletes all but the
/// `keep` checkpoints before it.
pub fn save(
    run_dir: &Path,
    keep: usize,
    policy: &PolicyNetwork,
    value: &ValueNetwork,
    policy_optimizer: &ModuleOptimizer,
    value_optimizer: &ModuleOptimizer,
    state: &LoopState,
) -> Result<PathBuf> {
    let root = run_dir.join("checkpoints");
    let name = format!("iter-{:06}", state.iteration);
    let dir = root.join(&name);
    crate::io::remove_stale_temporaries(&root);
    let tmp = crate::io::temp_name(&root, "checkpoint", None);
    crate::io::create_folder(&tmp)?;
    let written = write_files(
        &tmp,
        policy,
        value,
        policy_optimizer,
        value_optimizer,
        state,
    );
    if let Err(e) = written {
        // A full disk or a failed write: leave nothing half-written beside the checkpoints
        // (best effort, the write's error is the one to report), and name the checkpoint,
        // not its temporary folder.
        let _ = crate::io::remove_folder(&tmp);
        return Err(match e {
            Error::Io { path, source } => match path.strip_prefix(&tmp) {
                Ok(file) => Error::io(dir.join(file), source),
                Err(_) => Error::Io { path, source },
            },
            other => other,
        });
    }
    // A re-run of the same iteration (after a resume) replaces the old folder.
    crate::io::remove_folder(&dir)?;
    crate::io::rename(&tmp, &dir)?;
    atomic_write(&root.join(LATEST), name.as_bytes())?;
    prune(&root, &name, keep)?;
    Ok(dir)
}

/// The checkpoint's files, with the tensors' checksums in its state, into the folder `tmp`.
fn write_files(
    tmp: &Path,
    policy: &PolicyNetwork,
    value: &ValueNetwork,
    policy_optimizer: &ModuleOptimizer,
    value_optimizer: &ModuleOptimizer,
    state: &LoopState,
) -> Result<()> {
    let optimizer_bytes = |o: &ModuleOptimizer, path: &Path| -> Result<Vec<u8>> {
        Ok(o.into_bytes().map_err(|e| record_error(path, e))?.to_vec())
    };
    let tensors: [(&str, Vec<u8>); 4] = [
        (POLICY, module_bytes(policy, &tmp.join(POLICY))?),
        (VALUE, module_bytes(value, &tmp.join(VALUE))?),
        (
            POLICY_OPTIMIZER,
            optimizer_bytes(policy_optimizer, &tmp.join(POLICY_OPTIMIZER))?,
        ),
        (
            VALUE_OPTIMIZER,
            optimizer_bytes(value_optimizer, &tmp.join(VALUE_OPTIMIZER))?,
        ),
    ];
    let state = LoopState {
        checksums: tensors
            .iter()
            .map(|(file, bytes)| (file.to_string(), sha256_hex(bytes)))
            .collect(),
        ..state.clone()
    };
    let state_bytes =
        serde_json::to_vec_pretty(&state).map_err(|e| record_error(&tmp.join(STATE), e))?;
    for (file, bytes) in tensors.iter().chain([&(STATE, state_bytes)]) {
        crate::io::write_new(&tmp.join(file), bytes)?;
    }
    Ok(())
}

/// Deletes all but the newest `keep + 1` checkpoint folders (never `newest`).
fn prune(root: &Path, newest: &str, keep: usize) -> Result<()> {
    let names: Vec<String> = crate::io::list_folder(root)?
        .iter()
        .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .filter(|n| n.starts_with("iter-") && n.as_str() != newest)
        .collect();
    let excess = names.len().saturating_sub(keep);
    for name in &names[..excess] {
        crate::io::remove_folder(&root.join(name))?;
    }
    Ok(())
}

/// Checks each tensor file against the sha256 `state.json` recorded when it was written.
fn verify_checksums(dir: &Path, state: &LoopState) -> Result<()> {
    for (file, expected) in &state.checksums {
        if ![POLICY, VALUE, POLICY_OPTIMIZER, VALUE_OPTIMIZER].contains(&file.as_str()) {
            return Err(Error::invalid(
                dir.join(STATE).display().to_string(),
                "checksums",
                format!("names `{file}`, which is not a file of a checkpoint"),
            ));
        }
        let path = dir.join(file);
        let actual = sha256_hex(&crate::io::read_bytes(
            &path,
            crate::io::Format::Parameters,
        )?);
        if &actual != expected {
            return Err(Error::invalid(
                path.display().to_string(),
                "sha256",
                format!(
                    "is {actual}, but {} recorded {expected} when the checkpoint was written: \
                     the file was changed or corrupted since",
                    dir.join(STATE).display()
                ),
            ));
        }
    }
    Ok(())
}

/// The loop state of the checkpoint in `dir` (without its networks).
pub fn read_state(dir: &Path) -> Result<LoopState> {
    let state_path = dir.join(STATE);
    let state_text = crate::io::read_bytes(&state_path, crate::io::Format::Settings)?;
    serde_json::from_slice(&state_text).map_err(|e| record_error(&state_path, e))
}

/// Loads the checkpoint in `dir` into fresh networks of `config` on `device`.
pub fn load(
    dir: &Path,
    config: &ModelConfig,
    device: &burn::prelude::Device,
    policy_optimizer: ModuleOptimizer,
    value_optimizer: ModuleOptimizer,
) -> Result<Checkpoint> {
    let state = read_state(dir)?;
    verify_checksums(dir, &state)?;
    let optimizer = |o: ModuleOptimizer, file: &str| -> Result<ModuleOptimizer> {
        let path = dir.join(file);
        o.from_bytes(read_bytes(&path)?)
            .map_err(|e| record_error(&path, e))
    };
    Ok(Checkpoint {
        policy: load_policy(&dir.join(POLICY), config, device)?,
        value: load_module(ValueNetwork::new(config, device), &dir.join(VALUE))?,
        policy_optimizer: optimizer(policy_optimizer, POLICY_OPTIMIZER)?,
        value_optimizer: optimizer(value_optimizer, VALUE_OPTIMIZER)?,
        state,
        dir: dir.to_path_buf(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::train::ppo::adapt_lr_scale;

    /// Every learning-rate factor the adaptive schedule can reach reads back bit for bit:
    /// a resumed run continues with exactly the rate the uninterrupted one has.
    #[test]
    fn every_reachable_learning_rate_factor_reads_back_exactly() {
        let mut scale = 1.0;
        let mut reached = 0;
        // A walk that goes down, up and down again visits factors whose shortest decimal
        // form has 17 digits, where an approximate parser rounds the wrong way.
        for step in 0..400 {
            let kl = if (step / 7) % 3 == 1 { 0.0 } else { 1.0 };
            scale = adapt_lr_scale(scale, kl, 0.01);
            let state = LoopState {
                iteration: step,
                updates: step,
                config_toml: String::new(),
                policy_lr_scale: scale,
                checksums: BTreeMap::new(),
                input_digests: BTreeMap::new(),
                run_id: None,
            };
            let text = serde_json::to_vec_pretty(&state).expect("serialises");
            let back: LoopState = serde_json::from_slice(&text).expect("parses");
            assert_eq!(
                back.policy_lr_scale.to_bits(),
                scale.to_bits(),
                "{scale:?} read back as {:?}",
                back.policy_lr_scale
            );
            reached += 1;
        }
        assert_eq!(reached, 400);
    }
}
