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
    /// The sha256 of the averaged `policy.bpk`: weights changed since are refused wherever
    /// they load ([`crate::train::recorded_weights`]).
    pub policy_sha256: String,
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
        let differing = differing_run_fields(first, other)?;
        if !differing.is_empty() || other.method != first.method {
            return Err(Error::InvalidArgument(format!(
                "{} ({}) and {} ({}) are not checkpoints of one run (their run files differ in \
                 {}); weights of separate runs (another seed, another recipe) share no basin, \
                 and their mean is no policy",
                first.path.display(),
                first.method,
                other.path.display(),
                other.method,
                if differing.is_empty() {
                    "method".to_string()
                } else {
                    differing.join(", ")
                }
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
    let config_text = config_for(first)?;
    let method = first.method.clone();
    let networks = policies.into_iter().map(|p| p.network).collect();
    let mean = average_parameters(networks).map_err(Error::InvalidArgument)?;
    let policy_path = out.join("policy.bpk");
    let bytes = crate::train::checkpoint::module_bytes(&mean, &policy_path)?;
    let report = AveragedSources {
        method,
        sources,
        policy_sha256: sha256_hex(&bytes),
    };
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

/// The fields in which the run files of two policies differ; a dynamics file counts by its
/// contents (each run names it relative to its own folder).
fn differing_run_fields(a: &TrainedPolicy, b: &TrainedPolicy) -> Result<Vec<String>> {
    let contents = |p: &TrainedPolicy| -> Result<Option<Vec<u8>>> {
        p.config
            .dynamics
            .as_ref()
            .map(|d| crate::io::read_bytes(d, crate::io::Format::Settings))
            .transpose()
    };
    let without_dynamics = |p: &TrainedPolicy| {
        let mut config = p.config.clone();
        config.dynamics = None;
        config
    };
    let mut differing = differing_fields(&without_dynamics(a), &without_dynamics(b));
    if contents(a)? != contents(b)? {
        differing.push("dynamics".into());
    }
    if let (Some(x), Some(y)) = (&a.run_id, &b.run_id)
        && x != y
    {
        differing.push(format!(
            "nothing, but they are two trainings of it: run ids {x} and {y}"
        ));
    }
    Ok(differing)
}

/// The dotted names of the fields whose values differ between two run files.
fn differing_fields<T: Serialize>(a: &T, b: &T) -> Vec<String> {
    fn walk(prefix: &str, a: &serde_json::Value, b: &serde_json::Value, out: &mut Vec<String>) {
        use serde_json::Value::Object;
        match (a, b) {
            (Object(x), Object(y)) => {
                let keys: std::collections::BTreeSet<&String> = x.keys().chain(y.keys()).collect();
                for key in keys {
                    let null = serde_json::Value::Null;
                    let name = if prefix.is_empty() {
                        key.clone()
                    } else {
                        format!("{prefix}.{key}")
                    };
                    walk(
                        &name,
                        x.get(key).unwrap_or(&null),
                        y.get(key).unwrap_or(&null),
                        out,
                    );
                }
            }
            _ if a != b => out.push(prefix.to_string()),
            _ => {}
        }
    }
    let (Ok(a), Ok(b)) = (serde_json::to_value(a), serde_json::to_value(b)) else {
        return vec!["(unreadable)".into()];
    };
    let mut out = Vec::new();
    walk("", &a, &b, &mut out);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn differing_fields_are_named_by_their_dotted_path() {
        #[derive(Serialize)]
        struct Inner {
            rate: f64,
            epochs: usize,
        }
        #[derive(Serialize)]
        struct Run {
            seed: u64,
            optimizer: Inner,
        }
        let a = Run {
            seed: 1,
            optimizer: Inner {
                rate: 1e-4,
                epochs: 2,
            },
        };
        let b = Run {
            seed: 2,
            optimizer: Inner {
                rate: 1e-4,
                epochs: 3,
            },
        };
        assert_eq!(differing_fields(&a, &b), ["optimizer.epochs", "seed"]);
        assert!(differing_fields(&a, &a).is_empty());
    }
}
