//! A policy folder whose weights are the mean of several checkpoints of one run (stochastic
//! weight averaging, [`crate::model::weight_average`]): `policy.bpk`, the run's `config.toml`
//! and `averaged.json` naming every source by path and sha256. It loads wherever a trained
//! policy does (`rtr eval --checkpoint`, the examples).

use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::data::automatum::sha256_hex;
use crate::error::{Error, Result};
use crate::eval::trained::TrainedPolicy;
use crate::model::weight_average::average_parameters;

/// What was averaged, written beside the policy as `averaged.json`.
#[derive(Debug, Clone, Serialize)]
pub struct AveragedSources {
    pub method: String,
    pub sources: Vec<Source>,
}

#[derive(Debug, Clone, Serialize)]
pub struct Source {
    pub policy: PathBuf,
    pub sha256: String,
}

/// Averages the policies at `paths` (run, model or checkpoint folders, or `policy.bpk` files;
/// one model config and one training method) into the new folder `out`.
pub fn write_averaged_policy(
    paths: &[PathBuf],
    out: &Path,
    device: &burn::prelude::Device,
) -> Result<AveragedSources> {
    if paths.len() < 2 {
        return Err(Error::InvalidArgument(format!(
            "{} --checkpoint given; averaging needs at least two",
            paths.len()
        )));
    }
    if out.join("policy.bpk").exists() {
        return Err(Error::InvalidArgument(format!(
            "{} already holds a policy.bpk; choose another --out folder",
            out.display()
        )));
    }
    let policies = paths
        .iter()
        .map(|path| TrainedPolicy::load(path, device))
        .collect::<Result<Vec<_>>>()?;
    let first = &policies[0];
    for other in &policies[1..] {
        if other.config.model != first.config.model || other.method != first.method {
            return Err(Error::InvalidArgument(format!(
                "{} ({}) and {} ({}) differ in model config or method; average checkpoints \
                 of one run",
                first.path.display(),
                first.method,
                other.path.display(),
                other.method
            )));
        }
    }
    let sources = policies
        .iter()
        .map(|p| {
            let bytes = crate::io::read_bytes(&p.path, crate::io::Format::Parameters)?;
            Ok(Source {
                policy: p.path.clone(),
                sha256: sha256_hex(&bytes),
            })
        })
        .collect::<Result<Vec<_>>>()?;
    // The same weights twice would pass for an average of two checkpoints.
    for (k, source) in sources.iter().enumerate() {
        if let Some(earlier) = sources[..k].iter().find(|s| s.sha256 == source.sha256) {
            return Err(Error::InvalidArgument(format!(
                "--checkpoint {} holds the same weights as {} (sha256 {}); average different \
                 checkpoints",
                source.policy.display(),
                earlier.policy.display(),
                &source.sha256[..12]
            )));
        }
    }
    let report = AveragedSources {
        method: first.method.clone(),
        sources,
    };
    let config_text = config_for(first)?;
    let networks = policies.into_iter().map(|p| p.network).collect();
    let mean = average_parameters(networks).map_err(Error::InvalidArgument)?;
    let policy_path = out.join("policy.bpk");
    let bytes = crate::train::checkpoint::module_bytes(&mean, &policy_path)?;
    let json = serde_json::to_string_pretty(&report)
        .map_err(|e| Error::InvalidArgument(format!("cannot encode averaged.json: {e}")))?;
    // The policy goes last: a folder with a policy.bpk is complete.
    crate::io::atomic_write(&out.join("config.toml"), config_text.as_bytes())?;
    crate::io::atomic_write(&out.join("averaged.json"), json.as_bytes())?;
    crate::io::atomic_write(&policy_path, &bytes)?;
    Ok(report)
}

/// The first source's run config as written, except that a dynamics file named relative to
/// its folder is named as loaded (the averaged folder lies elsewhere).
fn config_for(policy: &TrainedPolicy) -> Result<String> {
    let text = crate::io::read_text(&policy.config_path, crate::io::Format::Settings)?;
    let Some(dynamics) = &policy.config.dynamics else {
        return Ok(text);
    };
    let source = policy.config_path.display().to_string();
    let mut table: toml::Table = text
        .parse()
        .map_err(|e| Error::invalid(&source, "config", format!("{e}")))?;
    table.insert(
        "dynamics".to_string(),
        toml::Value::String(dynamics.display().to_string()),
    );
    toml::to_string(&table).map_err(|e| Error::invalid(&source, "config", format!("{e}")))
}
