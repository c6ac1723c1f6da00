//! Several policies on several sets, as `rtr eval` and the example run them: evaluate each,
//! name its row, then write the table, `results.json` and the figures.

use std::path::{Path, PathBuf};

use indicatif::ProgressBar;

use super::evaluate::{EvalConfig, evaluate, simulated_scenes};
use super::metrics::Metric;
use super::plots;
use super::policy::{EvalPolicy, IdmBaseline};
use super::report::{MethodResult, collision_table, markdown_table, results_json};
use super::sets::{EvalScenes, EvalSet};
use super::trained::TrainedPolicy;
use crate::driver::IdmParams;
use crate::error::{Error, Result};
use crate::io::atomic_write;
use crate::sim::{ActionLimits, Dynamics};

/// A row of the study: a trained policy, or the IDM reference driver.
pub enum Entry {
    Trained(Box<TrainedPolicy>),
    Idm {
        driver: IdmBaseline,
        dynamics: Dynamics,
    },
}

impl Entry {
    /// The IDM reference with the default action limits in the paper's bicycle.
    pub fn idm() -> Self {
        let limits = ActionLimits::default();
        let mut dynamics = Dynamics::bicycle(0.5);
        dynamics.limits = Some(limits);
        Entry::Idm {
            driver: IdmBaseline {
                params: IdmParams::default(),
                limits,
            },
            dynamics,
        }
    }

    /// Method name, source, policy and simulator.
    fn parts(&self) -> (String, String, &dyn EvalPolicy, &Dynamics) {
        match self {
            Entry::Trained(t) => (
                t.method.clone(),
                t.path.display().to_string(),
                &t.network,
                &t.dynamics,
            ),
            Entry::Idm { driver, dynamics } => (
                "IDM".into(),
                "driver::IdmDriver (not learned)".into(),
                driver,
                dynamics,
            ),
        }
    }
}

/// Row names: the method, or `method (parent/folder)` where two rows share a method (e.g. a
/// run trained here and the shipped model of the same method).
fn row_names(entries: &[(String, String)]) -> Vec<String> {
    entries
        .iter()
        .map(|(method, path)| {
            let shared = entries.iter().filter(|(m, _)| m == method).count() > 1;
            if !shared {
                return method.clone();
            }
            let folder: Vec<String> = Path::new(path)
                .parent()
                .map(|p| {
                    p.components()
                        .rev()
                        .take(2)
                        .map(|c| c.as_os_str().to_string_lossy().into_owned())
                        .collect()
                })
                .unwrap_or_default();
            let folder: Vec<&str> = folder.iter().rev().map(String::as_str).collect();
            format!("{method} ({})", folder.join("/"))
        })
        .collect()
}

/// The entries of `checkpoints` (loaded onto the plain `device`), then with `idm` the IDM
/// reference.
pub fn load_entries(
    checkpoints: &[PathBuf],
    idm: bool,
    device: &burn::prelude::Device,
) -> Result<Vec<Entry>> {
    let mut entries = checkpoints
        .iter()
        .map(|c| TrainedPolicy::load(c, device).map(|t| Entry::Trained(Box::new(t))))
        .collect::<Result<Vec<_>>>()?;
    // One policy named twice (a run folder and its newest checkpoint, a trailing slash) would
    // be two rows of one method.
    let policies: Vec<(PathBuf, &PathBuf)> = entries
        .iter()
        .zip(checkpoints)
        .filter_map(|(e, given)| match e {
            Entry::Trained(t) => Some((t.path.canonicalize().unwrap_or(t.path.clone()), given)),
            Entry::Idm { .. } => None,
        })
        .collect();
    for (k, (policy, given)) in policies.iter().enumerate() {
        if let Some((_, first)) = policies[..k].iter().find(|(p, _)| p == policy) {
            return Err(Error::InvalidArgument(format!(
                "--checkpoint {} names the same policy as --checkpoint {} ({}); pass each once",
                given.display(),
                first.display(),
                policy.display()
            )));
        }
    }
    if idm {
        entries.push(Entry::idm());
    }
    Ok(entries)
}

/// Every entry as (row name ([`row_names`]), source, policy, simulator).
pub(crate) fn named_parts(entries: &[Entry]) -> Vec<(String, String, &dyn EvalPolicy, &Dynamics)> {
    let parts: Vec<_> = entries.iter().map(Entry::parts).collect();
    let names = row_names(
        &parts
            .iter()
            .map(|(m, p, _, _)| (m.clone(), p.clone()))
            .collect::<Vec<_>>(),
    );
    parts
        .into_iter()
        .zip(names)
        .map(|((_, source, policy, dynamics), name)| (name, source, policy, dynamics))
        .collect()
}

/// Evaluates every entry on every set (in that order); `progress` counts entry x set.
pub fn evaluate_entries(
    entries: &[Entry],
    sets: &[EvalScenes],
    device: &burn::prelude::Device,
    config: &EvalConfig,
    progress: &ProgressBar,
) -> Result<Vec<MethodResult>> {
    progress.set_length((entries.len() * sets.len()) as u64);
    named_parts(entries)
        .into_iter()
        .map(|(name, checkpoint, policy, dynamics)| {
            let results = sets
                .iter()
                .map(|set| {
                    progress.set_message(format!("{name} on {}", set.set.name()));
                    let r = evaluate(policy, dynamics, set, device, config);
                    progress.inc(1);
                    r
                })
                .collect::<Result<Vec<_>>>()?;
            Ok(MethodResult {
                method: name,
                checkpoint,
                sets: results,
            })
        })
        .collect()
}

/// Writes `results.json` and `table.md` into `dir` and the figures into `dir/figures/`: the
/// Pareto plots (long-tail collisions against nominal FDE and against nominal speed JSD) when
/// both sets were evaluated, each method's feature histograms, training curves of the trained
/// entries, and the first scene of each set driven by every entry beside its log. Returns
/// what it wrote.
pub fn write_study(
    dir: &Path,
    entries: &[Entry],
    results: &[MethodResult],
    sets: &[EvalScenes],
    device: &burn::prelude::Device,
) -> Result<Vec<PathBuf>> {
    crate::io::create_folder(dir)?;
    let mut written = Vec::new();
    let json = serde_json::to_string_pretty(&results_json(results))
        .map_err(|e| Error::InvalidArgument(format!("results do not serialise: {e}")))?;
    atomic_write(&dir.join("results.json"), json.as_bytes())?;
    written.push(dir.join("results.json"));
    let set_names: Vec<EvalSet> = sets.iter().map(|s| s.set).collect();
    let mut table = markdown_table(results, &set_names);
    let collisions = collision_table(results, &set_names);
    if !collisions.is_empty() {
        table.push('\n');
        table.push_str(&collisions);
    }
    atomic_write(&dir.join("table.md"), table.as_bytes())?;
    written.push(dir.join("table.md"));
    let figures = dir.join("figures");
    crate::io::create_folder(&figures)?;
    for realism in [Metric::FdeM, Metric::Jsd(super::features::Feature::Speed)] {
        written.extend(plots::pareto(&figures, results, realism)?);
    }
    for r in results {
        written.extend(plots::histograms(&figures, r)?);
    }
    let curves: Vec<(String, Vec<crate::train::CurveRow>)> = entries
        .iter()
        .zip(results)
        .filter_map(|(e, r)| match e {
            Entry::Trained(t) => {
                let run = t.path.parent()?;
                let rows = crate::train::curves::read(&run.join("curves.csv")).ok()?;
                Some((r.method.clone(), rows))
            }
            Entry::Idm { .. } => None,
        })
        .collect();
    written.extend(plots::training_curves(&figures, &curves)?);
    // The first scene of each set, driven by every entry, beside its log.
    for set in sets {
        if set.scenes.is_empty() {
            continue;
        }
        let mut rollouts = Vec::new();
        for (e, r) in entries.iter().zip(results) {
            let (_, _, policy, dynamics) = e.parts();
            let sim = simulated_scenes(policy, dynamics, set, &[0], device)?;
            rollouts.extend(sim.into_iter().map(|s| (r.method.clone(), s)));
        }
        written.extend(plots::rollout_pictures(
            &figures,
            &set.scenes[0],
            &rollouts,
        )?);
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_sharing_a_method_are_told_apart_by_folder() {
        let entries = [
            ("RTR".to_string(), "results/runs/rtr/policy.bpk".to_string()),
            ("RTR".to_string(), "/x/models/rtr/policy.bpk".to_string()),
            ("IL".to_string(), "models/il/policy.bpk".to_string()),
        ];
        assert_eq!(
            row_names(&entries),
            ["RTR (runs/rtr)", "RTR (models/rtr)", "IL"]
        );
    }
}
