//! The downstream study (paper section 4.2, table "Prediction model trained on synthetic,
//! evaluated on real"): each traffic model drives the same initial conditions (the A9
//! training split), the scenes it simulates become the training set of one fixed trajectory
//! predictor ([`crate::predict`]), and the predictor is scored on the held-out real test
//! split. A model whose behaviour is closer to human driving yields the better predictor.
//!
//! Every seed draws a new synthetic dataset (sampled actions, as a simulator generating data
//! runs) and a new predictor initialisation, so the spread over seeds covers both. A
//! predictor trained on the real training logs is the reference row. With
//! [`DownstreamConfig::mean_actions`] the policies drive with their mean action instead: the
//! data no longer depends on each policy's sigma (which closed-loop IL never trains), only on
//! its behaviour, and every seed redraws only the predictor's initialisation.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::Result;
use crate::eval::evaluate::{EvalConfig, simulate_set};
use crate::eval::sets::{EvalScenes, EvalSet};
use crate::eval::study::{Entry, named_parts};
use crate::predict::{FitConfig, PredictionSample, PredictionScore, fit, scene_samples, score};
use crate::scene::Scene;
use crate::seeding::stream_seed;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DownstreamConfig {
    /// Synthetic datasets and predictors per method.
    pub seeds: usize,
    pub seed: u64,
    pub fit: FitConfig,
    /// Drive with each policy's mean action instead of sampling (not in the paper).
    #[serde(default)]
    pub mean_actions: bool,
}

impl Default for DownstreamConfig {
    fn default() -> Self {
        Self {
            seeds: 4,
            seed: 2023,
            fit: FitConfig::default(),
            mean_actions: false,
        }
    }
}

/// One row: the predictor's scores on real test data, one per seed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DownstreamRow {
    /// "Real logs" or the traffic model's row name.
    pub data: String,
    /// Training examples per seed.
    pub train_examples: Vec<usize>,
    pub scores: Vec<PredictionScore>,
}

/// Mean and sample standard deviation.
pub fn mean_std(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n.max(1.0);
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
    (mean, var.sqrt())
}

impl DownstreamRow {
    /// Mean and standard deviation over seeds of one score field.
    pub fn stat(&self, field: fn(&PredictionScore) -> f64) -> (f64, f64) {
        mean_std(&self.scores.iter().map(field).collect::<Vec<_>>())
    }
}

/// Examples of every scene, in scene order.
fn samples_of(scenes: &[Scene]) -> Vec<PredictionSample> {
    scenes.par_iter().flat_map_iter(scene_samples).collect()
}

/// Trains and scores one predictor per seed on the datasets `dataset(seed_index)` draws.
fn row(
    data: String,
    config: &DownstreamConfig,
    test: &[PredictionSample],
    device: &burn::prelude::Device,
    mut dataset: impl FnMut(usize) -> Result<Vec<PredictionSample>>,
    progress: &indicatif::ProgressBar,
) -> Result<DownstreamRow> {
    let mut out = DownstreamRow {
        data,
        train_examples: Vec::new(),
        scores: Vec::new(),
    };
    for k in 0..config.seeds {
        progress.set_message(format!("{} seed {}", out.data, k + 1));
        let train = dataset(k)?;
        let (predictor, _) = fit(&train, &config.fit, device, stream_seed(config.seed, k, 1))?;
        out.train_examples.push(train.len());
        out.scores.push(score(&predictor, test, device));
        progress.inc(1);
    }
    Ok(out)
}

/// The study: the real-logs reference row, then one row per entry. `train` holds the initial
/// conditions (the nominal training split), `test` the held-out real scenes; `device` is an
/// autodiff device (the rollouts run on its inner device).
pub fn downstream(
    entries: &[Entry],
    train: &EvalScenes,
    test: &EvalScenes,
    device: &burn::prelude::Device,
    config: &DownstreamConfig,
    eval: &EvalConfig,
    progress: &indicatif::ProgressBar,
) -> Result<Vec<DownstreamRow>> {
    debug_assert!(train.set == EvalSet::Nominal && test.set == EvalSet::Nominal);
    progress.set_length(((entries.len() + 1) * config.seeds) as u64);
    let test_samples = samples_of(&test.scenes);
    let real = samples_of(&train.scenes);
    let mut rows = vec![row(
        "Real logs".into(),
        config,
        &test_samples,
        device,
        |_| Ok(real.clone()),
        progress,
    )?];
    let plain = device.clone().inner();
    for (name, _, policy, dynamics) in named_parts(entries) {
        rows.push(row(
            name,
            config,
            &test_samples,
            device,
            |k| {
                let noise = (!config.mean_actions).then(|| stream_seed(config.seed, k, 2));
                let scenes = simulate_set(policy, dynamics, train, &plain, eval, noise)?;
                Ok(samples_of(&scenes))
            },
            progress,
        )?);
    }
    Ok(rows)
}

/// The Markdown table: minFDE, minADE and minCTE (m), mean +- standard deviation over seeds.
pub fn downstream_table(rows: &[DownstreamRow]) -> String {
    let mut out = String::from(
        "| training data | examples | minFDE (m) | minADE (m) | minCTE (m) |\n|---|---|---|---|---|\n",
    );
    for r in rows {
        let cell = |f: fn(&PredictionScore) -> f64| {
            let (m, s) = r.stat(f);
            // One seed has no spread to show: "± 0.00" would claim one.
            match r.scores.len() {
                0 | 1 => format!("{m:.2} (one seed)"),
                _ => format!("{m:.2} ± {s:.2}"),
            }
        };
        let examples = r.train_examples.iter().sum::<usize>() / r.train_examples.len().max(1);
        out.push_str(&format!(
            "| {} | {examples} | {} | {} | {} |\n",
            r.data,
            cell(|s| s.min_fde_m),
            cell(|s| s.min_ade_m),
            cell(|s| s.min_cte_m),
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mean_and_sample_standard_deviation() {
        let (m, s) = mean_std(&[1.0, 2.0, 3.0, 4.0]);
        assert!((m - 2.5).abs() < 1e-12);
        assert!((s - (5.0f64 / 3.0).sqrt()).abs() < 1e-12);
        assert_eq!(mean_std(&[7.0]), (7.0, 0.0));
    }
}
