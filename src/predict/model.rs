//! The downstream trajectory predictor: a multimodal MLP over one agent's context
//! ([`super::sample`]) that outputs K future trajectories and a score per mode, each mode an
//! offset from constant-velocity extrapolation along the agent's heading.
//!
//! The paper trains GoRela on each synthetic dataset; what matters for the comparison is that
//! one fixed model and recipe is trained on every method's data, so a compact model that
//! trains in seconds on a CPU stands in for it (stated in the results).

use burn::module::Module;
use burn::prelude::*;
use serde::{Deserialize, Serialize};

use super::sample::{HORIZON_STEPS, INPUT_SIZE, PredictionSample};
use crate::model::network::Mlp;

/// Predicted offsets are in units of this many metres.
const OFFSET_SCALE: f64 = 5.0;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PredictorConfig {
    /// Widths of the hidden layers.
    pub hidden: Vec<usize>,
    /// Trajectories predicted per agent (the metrics take the best).
    pub modes: usize,
    /// Step of the predicted trajectory (s), the scenes' dt.
    pub dt: f64,
}

impl Default for PredictorConfig {
    fn default() -> Self {
        Self {
            hidden: vec![128, 128, 128],
            modes: 6,
            dt: 0.5,
        }
    }
}

#[derive(Module, Debug)]
pub struct Predictor {
    mlp: Mlp,
    #[module(skip)]
    modes: usize,
    #[module(skip)]
    dt: f64,
}

/// A batch of examples as tensors.
pub struct SampleBatch {
    /// `[B, INPUT_SIZE]`.
    pub input: Tensor<2>,
    /// `[B]` (m/s).
    pub speed: Tensor<1>,
    /// `[B, H, 2]` (m).
    pub future: Tensor<3>,
}

impl SampleBatch {
    pub fn new(samples: &[&PredictionSample], device: &Device) -> Self {
        let b = samples.len();
        let input: Vec<f32> = samples
            .iter()
            .flat_map(|s| s.input.iter().copied())
            .collect();
        let speed: Vec<f32> = samples.iter().map(|s| s.speed).collect();
        let future: Vec<f32> = samples
            .iter()
            .flat_map(|s| s.future.iter().flatten().copied())
            .collect();
        Self {
            input: Tensor::<1>::from_floats(input.as_slice(), device).reshape([b, INPUT_SIZE]),
            speed: Tensor::<1>::from_floats(speed.as_slice(), device),
            future: Tensor::<1>::from_floats(future.as_slice(), device).reshape([
                b,
                HORIZON_STEPS,
                2,
            ]),
        }
    }
}

impl Predictor {
    pub fn new(config: &PredictorConfig, device: &Device) -> Self {
        Self {
            mlp: Mlp::new(
                INPUT_SIZE,
                &config.hidden,
                config.modes * (2 * HORIZON_STEPS + 1),
                device,
            ),
            modes: config.modes,
            dt: config.dt,
        }
    }

    pub fn modes(&self) -> usize {
        self.modes
    }

    /// Trajectories `[B, K, H, 2]` (m, agent frame) and mode logits `[B, K]`.
    pub fn forward(&self, batch: &SampleBatch) -> (Tensor<4>, Tensor<2>) {
        let [b, _] = batch.input.dims();
        let (k, h) = (self.modes, HORIZON_STEPS);
        let out = self
            .mlp
            .forward(batch.input.clone())
            .reshape([b, k, 2 * h + 1]);
        let offsets = out.clone().narrow(2, 0, 2 * h).reshape([b, k, h, 2]) * OFFSET_SCALE;
        let logits = out.narrow(2, 2 * h, 1).reshape([b, k]);
        let device = batch.input.device();
        // Constant velocity along the heading: x = v * dt * step, y = 0.
        let steps: Vec<f32> = (1..=h)
            .flat_map(|t| [(t as f64 * self.dt) as f32, 0.0])
            .collect();
        let unit = Tensor::<1>::from_floats(steps.as_slice(), &device).reshape([1, 1, h, 2]);
        let prior = batch.speed.clone().reshape([b, 1, 1, 1]) * unit;
        (offsets + prior, logits)
    }
}
