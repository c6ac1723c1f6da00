//! The noise floor: the held-out error a perfect model would still show, estimated from the
//! recordings themselves.
//!
//! A window starts from a denoised state (local quadratic fits, [`super::windows`]) and is
//! compared with noisy samples. Even the true plant then misses by the noise of the compared
//! sample plus the initial-state error carried forward: a speed error grows along track as
//! `dv t`, a heading error across track as `v dtheta t`. The fits' residuals give the sensor
//! noise of each channel; the fit design says how much of it reaches the initial state. With
//! both, the expected squared error of a perfect model at every step of every window follows,
//! and a model whose held-out error stays clearly above it is missing something.

use serde::Serialize;

use super::locate::ChannelRms;
use super::windows::Window;

/// Sensor noise (standard deviations) estimated from the denoising fits' residuals.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct NoiseLevels {
    pub position_m: f64,
    pub heading_rad: f64,
    pub speed_m_s: f64,
    /// Local fits pooled.
    pub fits: usize,
}

impl NoiseLevels {
    /// Pooled over `windows`: the median of the per-window residual variances, corrected to
    /// the mean of a chi-square with the fits' degrees of freedom. The median keeps windows
    /// whose 1 s span holds a manoeuvre the quadratic cannot follow (a brake step) from
    /// inflating the estimate.
    pub fn estimate(windows: &[Window]) -> Self {
        let dof = windows.first().map_or(0, |w| w.noise.dof).max(1) as f64;
        // Wilson-Hilferty: the median of chi-square(k) / k is about (1 - 2 / (9 k))^3.
        let median_to_mean = 1.0 / (1.0 - 2.0 / (9.0 * dof)).powi(3);
        let pooled = |channels: &[usize]| {
            let mut values: Vec<f64> = windows
                .iter()
                .flat_map(|w| channels.iter().map(move |&c| w.noise.variance[c]))
                .filter(|v| v.is_finite())
                .collect();
            (median(&mut values) * median_to_mean).sqrt()
        };
        Self {
            position_m: pooled(&[0, 1]),
            heading_rad: pooled(&[2]),
            speed_m_s: pooled(&[3]),
            fits: windows.len(),
        }
    }

    /// Expected squared error of a perfect model at step `k` (0-based) of `w`, per channel:
    /// along, across (m^2), heading (rad^2), speed (m^2/s^2).
    pub fn floor_sq(&self, w: &Window, k: usize) -> [f64; 4] {
        let c0 = w.noise.value_factor;
        let t = (k + 1) as f64 * w.period;
        let v = w.initial[3];
        let (p2, h2, s2) = (
            self.position_m.powi(2),
            self.heading_rad.powi(2),
            self.speed_m_s.powi(2),
        );
        [
            p2 * (1.0 + c0) + c0 * s2 * t * t,
            p2 * (1.0 + c0) + c0 * h2 * v * v * t * t,
            h2 * (1.0 + c0),
            s2 * (1.0 + c0),
        ]
    }

    /// The floor as RMS per channel over the given (window, step) pairs.
    pub fn floor<'a>(&self, steps: impl IntoIterator<Item = (&'a Window, usize)>) -> ChannelRms {
        let mut sums = [0.0; 4];
        let mut n = 0;
        for (w, k) in steps {
            for (sum, f) in sums.iter_mut().zip(self.floor_sq(w, k)) {
                *sum += f;
            }
            n += 1;
        }
        ChannelRms::from_sums(sums, n)
    }

    /// The floor over every step of `windows`.
    pub fn floor_over(&self, windows: &[Window]) -> ChannelRms {
        self.floor(
            windows
                .iter()
                .flat_map(|w| (0..w.steps()).map(move |k| (w, k))),
        )
    }
}

fn median(values: &mut [f64]) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    values.sort_by(f64::total_cmp);
    let mid = values.len() / 2;
    if values.len() % 2 == 1 {
        values[mid]
    } else {
        0.5 * (values[mid - 1] + values[mid])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::{RecordedTrack, Recordings};
    use crate::sim2real::windows::{Starts, windows};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    /// Straight constant-speed tracks under known white noise.
    fn noisy_tracks(sigma: [f64; 3]) -> Recordings {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let [p, h, s] = sigma.map(|s| Normal::new(0.0, s).unwrap());
        let tracks = (0..6)
            .map(|i| {
                let mut track = RecordedTrack::empty(format!("{i}"), 0.1, Some(2.8));
                for k in 0..300 {
                    let t = k as f64 * 0.1;
                    track.t.push(t);
                    track.x.push(20.0 * t + p.sample(&mut rng));
                    track.y.push(p.sample(&mut rng));
                    track.heading.push(h.sample(&mut rng));
                    track.speed.push(20.0 + s.sample(&mut rng));
                    track.accel_cmd.push(0.0);
                    track.steer_cmd.push(0.0);
                }
                track
            })
            .collect();
        Recordings {
            source: "test".into(),
            tracks,
        }
    }

    #[test]
    fn the_sensor_noise_is_recovered_from_the_fit_residuals() {
        let recordings = noisy_tracks([0.1, 0.003, 0.2]);
        let all: Vec<usize> = (0..6).collect();
        let ws = windows(&recordings, &all, 1.0, 0.5, 0.0, 2.8, Starts::Regular);
        let noise = NoiseLevels::estimate(&ws);
        for (got, truth) in [
            (noise.position_m, 0.1),
            (noise.heading_rad, 0.003),
            (noise.speed_m_s, 0.2),
        ] {
            assert!((got / truth - 1.0).abs() < 0.1, "{noise:?}");
        }
    }

    #[test]
    fn the_floor_matches_the_error_of_the_true_model() {
        // The true model of a straight constant-speed track: the denoised initial state
        // carried forward at its own speed and heading.
        let recordings = noisy_tracks([0.1, 0.003, 0.2]);
        let all: Vec<usize> = (0..6).collect();
        let ws = windows(&recordings, &all, 5.0, 1.0, 0.0, 2.8, Starts::Regular);
        let noise = NoiseLevels::estimate(&ws);
        let (mut sum, mut n) = (0.0, 0);
        for w in &ws {
            let [x0, y0, h0, v0] = w.initial;
            for (k, rec) in w.recorded.iter().enumerate() {
                let t = (k + 1) as f64 * w.period;
                let (x, y) = (x0 + v0 * h0.cos() * t, y0 + v0 * h0.sin() * t);
                sum += (x - rec[0]).powi(2) + (y - rec[1]).powi(2);
                n += 1;
            }
        }
        let observed = (sum / n as f64).sqrt();
        let floor = noise.floor_over(&ws).pos_m;
        assert!(
            (observed / floor - 1.0).abs() < 0.1,
            "observed {observed}, floor {floor}"
        );
    }
}
