//! How well a predictor forecasts real futures (paper section 4.2): over held-out examples,
//! the minimum over modes of the final displacement error at 5 s (minFDE), and of the
//! cross-track error of the mode's final point projected on the true path (minCTE), as the
//! reconstruction metrics of the main table measure it.

use burn::module::Module;
use burn::prelude::*;
use serde::{Deserialize, Serialize};

use super::model::{Predictor, SampleBatch};
use super::sample::PredictionSample;
use crate::eval::reconstruction::{LoggedPath, displacement};

/// Means over the examples scored.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PredictionScore {
    pub examples: usize,
    /// Minimum over modes of the displacement at the horizon (m).
    pub min_fde_m: f64,
    /// Minimum over modes of the average displacement over the horizon (m).
    pub min_ade_m: f64,
    /// Minimum over modes of the final point's distance across the true path (m).
    pub min_cte_m: f64,
}

/// Examples scored per forward pass.
const CHUNK: usize = 1024;

/// Scores `predictor` (trained on an autodiff device) on `samples`, on that device's inner
/// (plain) device.
pub fn score(
    predictor: &Predictor,
    samples: &[PredictionSample],
    device: &Device,
) -> PredictionScore {
    let model = predictor.valid();
    let device = device.clone().inner();
    let (mut fde, mut ade, mut cte) = (0.0, 0.0, 0.0);
    for chunk in samples.chunks(CHUNK) {
        let picked: Vec<&PredictionSample> = chunk.iter().collect();
        let batch = SampleBatch::new(&picked, &device);
        let (trajectories, _) = model.forward(&batch);
        let [_, k, h, _] = trajectories.dims();
        let values: Vec<f32> = trajectories
            .into_data()
            .convert::<f32>()
            .try_into_vec::<f32>()
            .unwrap_or_default();
        for (n, sample) in chunk.iter().enumerate() {
            let modes: Vec<Vec<[f64; 2]>> = (0..k)
                .map(|m| {
                    (0..h)
                        .map(|t| {
                            let i = ((n * k + m) * h + t) * 2;
                            [values[i] as f64, values[i + 1] as f64]
                        })
                        .collect()
                })
                .collect();
            let truth: Vec<[f64; 2]> = sample.future.iter().map(|p| p.map(f64::from)).collect();
            let [f, a, c] = best_of_modes(&modes, &truth);
            fde += f;
            ade += a;
            cte += c;
        }
    }
    let n = samples.len().max(1) as f64;
    PredictionScore {
        examples: samples.len(),
        min_fde_m: fde / n,
        min_ade_m: ade / n,
        min_cte_m: cte / n,
    }
}

/// Minimum over `modes` of the final displacement, the average displacement, and the final
/// point's cross-track error on the true path (which starts at the agent, the origin), each
/// minimised separately. `modes` and `truth` share their length.
pub fn best_of_modes(modes: &[Vec<[f64; 2]>], truth: &[[f64; 2]]) -> [f64; 3] {
    let last = truth.len() - 1;
    let mut path_points = vec![[0.0, 0.0]];
    path_points.extend(truth);
    let path = LoggedPath::new(&path_points, 0.0);
    let best =
        |f: &dyn Fn(&Vec<[f64; 2]>) -> f64| modes.iter().map(f).fold(f64::INFINITY, f64::min);
    [
        best(&|m| displacement(m[last], truth[last])),
        best(&|m| {
            m.iter()
                .zip(truth)
                .map(|(p, q)| displacement(*p, *q))
                .sum::<f64>()
                / truth.len() as f64
        }),
        best(&|m| {
            path.as_ref()
                .map_or(0.0, |p| p.errors(m[last], truth[last]).1)
        }),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_error_takes_its_own_best_mode() {
        // Truth: straight ahead, 10 m per step, 2 steps.
        let truth = [[10.0, 0.0], [20.0, 0.0]];
        // Mode A: right on the path but 4 m short at the end; mode B: 3 m to the side.
        let a = vec![[10.0, 0.0], [16.0, 0.0]];
        let b = vec![[10.0, 3.0], [20.0, 3.0]];
        let [fde, ade, cte] = best_of_modes(&[a.clone(), b.clone()], &truth);
        assert!((fde - 3.0).abs() < 1e-12, "B ends 3 m away, A 4 m");
        assert!(
            (ade - 2.0).abs() < 1e-12,
            "A averages (0 + 4) / 2, B (3 + 3) / 2"
        );
        assert!(cte.abs() < 1e-12, "A's end lies on the path");
        assert_eq!(best_of_modes(&[b], &truth), [3.0, 3.0, 3.0]);
    }
}
