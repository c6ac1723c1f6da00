//! Fitting a candidate's parameters by gradient descent (Adam, burn autodiff) through the
//! unrolled simulation of every training window, and their uncertainty.

use burn::module::{Module, Param};
use burn::optim::{AdamConfig, GradientsParams};
use burn::prelude::*;
use nalgebra::{DMatrix, DVector};

use super::simulate::{Candidate, HEADING_WEIGHT_M, SPEED_WEIGHT_S, StepError, WindowBatch};
use super::windows::Window;
use crate::sim::catalogue::unbounded;

/// Gradient-descent settings.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct FitOptions {
    pub iterations: usize,
    /// Adam step on the raw (sigmoid-space) parameters; decays cosine-wise to a tenth.
    pub learning_rate: f64,
}

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            iterations: 120,
            learning_rate: 0.15,
        }
    }
}

/// The raw parameter vector as a module, so burn's Adam can step it.
#[derive(Module, Debug)]
struct RawParameters {
    values: Param<Tensor<1>>,
}

/// A fitted candidate.
#[derive(Debug, Clone)]
pub struct Fit {
    pub candidate: Candidate,
    /// Raw parameters (see [`Candidate::specs`]).
    pub raw: Vec<f64>,
    /// Physical values, same order.
    pub values: Vec<f64>,
    /// Standard errors of `values` (NaN where not fitted or not estimable).
    pub std_errors: Vec<f64>,
    /// Mean squared error per loss term on the training windows (m^2).
    pub train_mse: f64,
}

impl Fit {
    /// The candidate at its starting values, unfitted (the baseline).
    pub fn unfitted(candidate: Candidate) -> Self {
        let specs = candidate.specs();
        Self {
            raw: specs.iter().map(|s| unbounded(s.start, s)).collect(),
            values: specs.iter().map(|s| s.start).collect(),
            std_errors: vec![f64::NAN; specs.len()],
            train_mse: f64::NAN,
            candidate,
        }
    }
}

fn raw_tensor(raw: &[f64], device: &Device) -> Tensor<1> {
    let values: Vec<f32> = raw.iter().map(|&v| v as f32).collect();
    Tensor::from_data(burn::tensor::TensorData::new(values, [raw.len()]), device)
}

/// Fits `candidate` on `train` (batches built on `device`, which must have autodiff).
pub fn fit(
    candidate: &Candidate,
    train: &[WindowBatch],
    device: &Device,
    options: &FitOptions,
) -> Fit {
    let start = Fit::unfitted(candidate.clone());
    let mut params = RawParameters {
        values: Param::from_tensor(raw_tensor(&start.raw, device).require_grad()),
    };
    let mut optimizer = AdamConfig::new().init();
    let mut last = f64::NAN;
    for iteration in 0..options.iterations {
        let progress = iteration as f64 / options.iterations.max(1) as f64;
        let lr = options.learning_rate
            * (0.1 + 0.9 * 0.5 * (1.0 + (std::f64::consts::PI * progress).cos()));
        let raw = params.values.val();
        let (mut total, mut count) = (None, 0usize);
        for batch in train {
            let (sum, n) = batch.loss_sum(&batch.simulate(candidate, &raw));
            total = Some(match total {
                Some(t) => t + sum,
                None => sum,
            });
            count += n;
        }
        let Some(total) = total else { break };
        let loss = total.div_scalar(count.max(1) as f64);
        last = loss.clone().into_scalar::<f64>();
        if !last.is_finite() {
            break;
        }
        let mut grads = loss.backward();
        let grads = GradientsParams::from_module(&mut grads, &params);
        params = optimizer.step(lr, params, grads);
    }
    let raw: Vec<f64> = params
        .values
        .val()
        .to_data()
        .convert::<f64>()
        .try_into_vec::<f64>()
        .expect("f64 data");
    let specs = candidate.specs();
    let values = raw
        .iter()
        .zip(&specs)
        .map(|(&r, s)| s.min + (s.max - s.min) / (1.0 + (-r).exp()))
        .collect();
    Fit {
        candidate: candidate.clone(),
        raw,
        values,
        std_errors: vec![f64::NAN; specs.len()],
        train_mse: last,
    }
}

/// Per-window step errors of a fit (in the order of `windows`), on a plain device.
pub fn evaluate(
    fit: &Fit,
    batches: &[WindowBatch],
    windows: usize,
    device: &Device,
) -> Vec<Vec<StepError>> {
    let raw = raw_tensor(&fit.raw, device);
    let mut out = vec![Vec::new(); windows];
    for batch in batches {
        let errors = batch.errors(&batch.simulate(&fit.candidate, &raw));
        for (&w, e) in batch.windows.iter().zip(errors) {
            out[w] = e;
        }
    }
    out
}

/// Standard errors of the fitted values by the cluster-robust sandwich estimator
/// (clusters = tracks, since errors within a track are correlated over time), with the
/// Jacobian of the residuals by central differences in the physical parameters.
pub fn standard_errors(
    fit: &mut Fit,
    batches: &[WindowBatch],
    windows: &[Window],
    device: &Device,
) {
    let specs = fit.candidate.specs();
    let free: Vec<usize> = (0..specs.len())
        .filter(|&k| k > 0 || fit.candidate.fit_wheelbase)
        .collect();
    if free.is_empty() {
        return;
    }
    let residuals = |raw: &[f64]| -> Vec<f64> {
        let probe = Fit {
            raw: raw.to_vec(),
            ..fit.clone()
        };
        evaluate(&probe, batches, windows.len(), device)
            .iter()
            .flatten()
            .flat_map(|e| {
                [
                    e.along,
                    e.across,
                    HEADING_WEIGHT_M * e.heading,
                    SPEED_WEIGHT_S * e.speed,
                ]
            })
            .collect()
    };
    let r0 = residuals(&fit.raw);
    let mut jacobian = DMatrix::zeros(r0.len(), free.len());
    for (column, &k) in free.iter().enumerate() {
        let spec = &specs[k];
        let step = 2e-3 * (spec.max - spec.min);
        let shifted = |sign: f64| {
            let mut raw = fit.raw.clone();
            raw[k] = unbounded(fit.values[k] + sign * step, spec);
            let actual = spec.min + (spec.max - spec.min) / (1.0 + (-raw[k]).exp());
            (residuals(&raw), actual)
        };
        let ((plus, at_plus), (minus, at_minus)) = (shifted(1.0), shifted(-1.0));
        let h = at_plus - at_minus;
        if h <= 0.0 {
            continue;
        }
        for (row, (p, m)) in plus.iter().zip(&minus).enumerate() {
            jacobian[(row, column)] = (p - m) / h;
        }
    }
    let jtj = jacobian.transpose() * &jacobian;
    let Some(inverse) = jtj.try_inverse() else {
        return;
    };
    // Residual rows per window, grouped by track.
    let per_window = r0.len() / windows.len().max(1);
    let mut meat = DMatrix::zeros(free.len(), free.len());
    let mut tracks: Vec<usize> = windows.iter().map(|w| w.track).collect();
    tracks.sort_unstable();
    tracks.dedup();
    for track in tracks {
        let mut score = DVector::zeros(free.len());
        for (w, window) in windows.iter().enumerate() {
            if window.track != track {
                continue;
            }
            let rows = w * per_window..(w + 1) * per_window;
            for (row, residual) in rows.clone().zip(&r0[rows]) {
                score += jacobian.row(row).transpose() * *residual;
            }
        }
        meat += &score * score.transpose();
    }
    let covariance = &inverse * meat * &inverse;
    for (column, &k) in free.iter().enumerate() {
        fit.std_errors[k] = covariance[(column, column)].max(0.0).sqrt();
    }
}
