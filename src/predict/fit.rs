//! Training the predictor: winner-takes-all regression (the Huber distance of the mode
//! nearest the true future, by average displacement) plus the cross-entropy that teaches the
//! mode scores which mode won, minimised with AdamW over shuffled minibatches.

use burn::module::Module;
use burn::optim::{AdamWConfig, GradientsParams};
use burn::prelude::*;
use burn::tensor::activation::log_softmax;
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::model::{Predictor, PredictorConfig, SampleBatch};
use super::sample::PredictionSample;
use crate::error::{Error, Result};
use crate::seeding::{Materialise, stream_seed, with_seeded_device};
use crate::sim::loss::huber;

/// The training recipe, fixed across the datasets compared.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FitConfig {
    pub model: PredictorConfig,
    pub epochs: usize,
    pub minibatch: usize,
    pub learning_rate: f64,
    /// The learning rate falls linearly to this share of itself by the last epoch.
    pub final_lr_share: f64,
    pub weight_decay: f64,
    /// Huber threshold (m) of the regression.
    pub huber_delta: f64,
    /// Weight of the mode-score cross-entropy.
    pub score_weight: f64,
}

impl Default for FitConfig {
    fn default() -> Self {
        Self {
            model: PredictorConfig::default(),
            epochs: 100,
            minibatch: 128,
            learning_rate: 1e-3,
            final_lr_share: 0.1,
            weight_decay: 1e-4,
            huber_delta: 1.0,
            score_weight: 0.1,
        }
    }
}

/// The loss of `predictor` on `batch` (scalar).
pub fn loss(predictor: &Predictor, batch: &SampleBatch, config: &FitConfig) -> Tensor<1> {
    let (trajectories, logits) = predictor.forward(batch);
    let [b, k, h, _] = trajectories.dims();
    let diff = trajectories - batch.future.clone().unsqueeze_dim::<4>(1);
    // Winner by average displacement; the choice itself carries no gradient.
    let ade = diff
        .clone()
        .detach()
        .powi_scalar(2)
        .sum_dim(3)
        .sqrt()
        .mean_dim(2)
        .reshape([b, k]);
    let winner = ade.argmin(1);
    let chosen = diff.gather(1, winner.clone().reshape([b, 1, 1, 1]).expand([b, 1, h, 2]));
    let regression = huber(chosen, config.huber_delta).sum_dim(3).mean();
    let score = log_softmax(logits, 1).gather(1, winner).mean().neg();
    regression + score * config.score_weight
}

/// Trains a predictor on `samples` on the autodiff `device`, seeded by `seed` (its
/// initialisation and the minibatch order). Returns it and the mean loss of each epoch.
pub fn fit(
    samples: &[PredictionSample],
    config: &FitConfig,
    device: &Device,
    seed: u64,
) -> Result<(Predictor, Vec<f64>)> {
    if samples.is_empty() {
        return Err(Error::InvalidArgument(
            "the predictor has no training example (no agent with a full 5 s future)".into(),
        ));
    }
    let mut predictor = with_seeded_device(device, stream_seed(seed, 0, u64::MAX), || {
        let p = Predictor::new(&config.model, device);
        p.visit(&mut Materialise);
        p
    });
    let mut optimizer = AdamWConfig::new()
        .with_weight_decay(config.weight_decay as f32)
        .init();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut order: Vec<usize> = (0..samples.len()).collect();
    let mut epoch_losses = Vec::with_capacity(config.epochs);
    for epoch in 0..config.epochs {
        let progress = epoch as f64 / (config.epochs.max(2) - 1) as f64;
        let lr = config.learning_rate * (1.0 - progress * (1.0 - config.final_lr_share));
        order.shuffle(&mut rng);
        let (mut sum, mut count) = (0.0, 0usize);
        for chunk in order.chunks(config.minibatch.max(1)) {
            let picked: Vec<&PredictionSample> = chunk.iter().map(|&i| &samples[i]).collect();
            let batch = SampleBatch::new(&picked, device);
            let l = loss(&predictor, &batch, config);
            let value = l.clone().into_scalar::<f64>();
            if !value.is_finite() {
                return Err(Error::InvalidArgument(format!(
                    "the predictor's loss diverged at epoch {epoch} (seed {seed})"
                )));
            }
            sum += value * picked.len() as f64;
            count += picked.len();
            let grads = GradientsParams::from_grads(l.backward(), &predictor);
            predictor = optimizer.step(lr, predictor, grads);
        }
        epoch_losses.push(sum / count.max(1) as f64);
    }
    Ok((predictor, epoch_losses))
}
