//! Training checkpoints: both networks, both optimizer states (burnpack) and the loop's
//! position, in one folder `checkpoints/iter-NNNNNN/`. The folder is written under a temporary
//! name and renamed into place, then `checkpoints/latest` is replaced atomically: a run killed
//! at any moment leaves the previous checkpoint whole and pointed to.

use std::path::{Path, PathBuf};

use burn::module::Module;
use burn::optim::ModuleOptimizer;
use burn::store::ModuleRecord;
use burn::tensor::Bytes;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::io::atomic_write;
use crate::model::{ModelConfig, PolicyNetwork, ValueNetwork};

const POLICY: &str = "policy.bpk";
const VALUE: &str = "value.bpk";
const POLICY_OPTIMIZER: &str = "policy_optimizer.bpk";
const VALUE_OPTIMIZER: &str = "value_optimizer.bpk";
const STATE: &str = "state.json";
const LATEST: &str = "latest";
/// Checkpoints kept besides the newest (older ones are deleted).
const KEEP: usize = 1;

/// Where the loop stands.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LoopState {
    /// Iterations completed.
    pub iteration: usize,
    /// Optimizer steps taken.
    pub updates: usize,
    /// The run's config as TOML, so `--resume` can refuse a changed config.
    pub config_toml: String,
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

fn read_bytes(path: &Path) -> Result<Bytes> {
    Ok(Bytes::from_bytes_vec(
        std::fs::read(path).map_err(|e| Error::io(path, e))?,
    ))
}

fn module_bytes<M: Module>(module: &M, path: &Path) -> Result<Vec<u8>> {
    let bytes = module
        .clone()
        .into_record()
        .into_bytes()
        .map_err(|e| record_error(path, e))?;
    Ok(bytes.to_vec())
}

/// Loads a module's parameters from a burnpack file into `module` (which fixes the shapes).
pub fn load_module<M: Module>(module: M, path: &Path) -> Result<M> {
    let record = ModuleRecord::from_bytes(read_bytes(path)?).map_err(|e| record_error(path, e))?;
    module
        .try_load_record(record)
        .map_err(|e| record_error(path, e))
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
    match std::fs::read_to_string(&pointer) {
        Ok(name) => Ok(Some(run_dir.join("checkpoints").join(name.trim()))),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(Error::io(pointer, e)),
    }
}

/// Writes a checkpoint for `state.iteration` and points `latest` at it.
pub fn save(
    run_dir: &Path,
    policy: &PolicyNetwork,
    value: &ValueNetwork,
    policy_optimizer: &ModuleOptimizer,
    value_optimizer: &ModuleOptimizer,
    state: &LoopState,
) -> Result<PathBuf> {
    let root = run_dir.join("checkpoints");
    let name = format!("iter-{:06}", state.iteration);
    let dir = root.join(&name);
    let tmp = root.join(format!(".{name}.tmp.{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    std::fs::create_dir_all(&tmp).map_err(|e| Error::io(&tmp, e))?;
    let optimizer_bytes = |o: &ModuleOptimizer, path: &Path| -> Result<Vec<u8>> {
        Ok(o.into_bytes().map_err(|e| record_error(path, e))?.to_vec())
    };
    let files: [(&str, Vec<u8>); 5] = [
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
        (
            STATE,
            serde_json::to_vec_pretty(state).map_err(|e| record_error(&tmp.join(STATE), e))?,
        ),
    ];
    for (file, bytes) in &files {
        let path = tmp.join(file);
        std::fs::write(&path, bytes).map_err(|e| Error::io(&path, e))?;
    }
    // A re-run of the same iteration (after a resume) replaces the old folder.
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::rename(&tmp, &dir).map_err(|e| Error::io(&dir, e))?;
    atomic_write(&root.join(LATEST), name.as_bytes())?;
    prune(&root, &name)?;
    Ok(dir)
}

/// Deletes all but the newest `KEEP + 1` checkpoint folders (never `newest`).
fn prune(root: &Path, newest: &str) -> Result<()> {
    let mut names: Vec<String> = std::fs::read_dir(root)
        .map_err(|e| Error::io(root, e))?
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with("iter-") && n.as_str() != newest)
        .collect();
    names.sort();
    let excess = names.len().saturating_sub(KEEP);
    for name in &names[..excess] {
        let path = root.join(name);
        std::fs::remove_dir_all(&path).map_err(|e| Error::io(&path, e))?;
    }
    Ok(())
}

/// Loads the checkpoint in `dir` into fresh networks of `config` on `device`.
pub fn load(
    dir: &Path,
    config: &ModelConfig,
    device: &burn::prelude::Device,
    policy_optimizer: ModuleOptimizer,
    value_optimizer: ModuleOptimizer,
) -> Result<Checkpoint> {
    let state_path = dir.join(STATE);
    let state_text = std::fs::read(&state_path).map_err(|e| Error::io(&state_path, e))?;
    let state: LoopState =
        serde_json::from_slice(&state_text).map_err(|e| record_error(&state_path, e))?;
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
