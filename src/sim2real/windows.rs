//! Cutting recordings into simulation windows: each starts from a denoised recorded state
//! and replays the recorded commands over a horizon, for comparison with what was recorded.

use nalgebra::{DMatrix, DVector};

use crate::data::{RecordedTrack, Recordings};
use crate::geometry::wrap_angle;

/// Half-width (s) of the local quadratic fit that denoises a window's initial state.
pub const DENOISE_HALF_WIDTH_S: f64 = 0.5;

/// Below this speed (m/s) the applied controls at a window's start are taken from the last
/// command rather than from the motion.
const MIN_MOTION_SPEED: f64 = 3.0;

/// One simulation window.
#[derive(Debug, Clone)]
pub struct Window {
    /// Index of the track in the recordings.
    pub track: usize,
    /// Sample index of the start.
    pub start: usize,
    pub period: f64,
    /// Declared wheelbase (m).
    pub wheelbase: f64,
    /// Denoised initial state: position relative to `origin`, heading, speed.
    pub origin: (f64, f64),
    pub initial: [f64; 4],
    /// Estimated applied acceleration and steering at the start (from the motion).
    pub applied: (f64, f64),
    /// What the denoising fits say about the sensor noise here (see [`LocalNoise`]).
    pub noise: LocalNoise,
    /// Commands before the start, newest first.
    pub past: Vec<(f64, f64)>,
    /// Commands at the start and the `steps - 1` samples after it.
    pub commands: Vec<(f64, f64)>,
    /// Recorded x, y (relative to `origin`), unwrapped heading and speed at the `steps`
    /// samples after the start.
    pub recorded: Vec<[f64; 4]>,
}

/// Residuals of the local quadratic fits that denoise a window's initial state: a noise
/// estimate per recorded channel, and how much of that noise reaches the initial state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalNoise {
    /// Residual variance (sum of squares over degrees of freedom) of the x, y, heading and
    /// speed fits.
    pub variance: [f64; 4],
    /// Degrees of freedom of each variance (samples minus the quadratic's 3 coefficients).
    pub dof: usize,
    /// Variance of a fitted value at t = 0 per unit sample variance: `[(A^T A)^-1]_00`.
    pub value_factor: f64,
}

impl Window {
    pub fn steps(&self) -> usize {
        self.commands.len()
    }
}

/// A command counts as changed when it moves by more than this in one sample.
pub const ACCEL_CHANGE: f64 = 0.3;
pub const STEER_CHANGE: f64 = 0.005;

/// Whether either command jumps between samples `k - 1` and `k`.
pub fn command_changed(track: &RecordedTrack, k: usize) -> bool {
    k > 0
        && ((track.accel_cmd[k] - track.accel_cmd[k - 1]).abs() > ACCEL_CHANGE
            || (track.steer_cmd[k] - track.steer_cmd[k - 1]).abs() > STEER_CHANGE)
}

/// Where windows may start.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Starts {
    /// Every stride.
    Regular,
    /// Every stride, each moved later until no command jumped within one denoising span
    /// before its own. A quadratic cannot follow the kink a command step puts in speed or
    /// heading, nor closely the transient of a lag just after it, and the biased initial
    /// state it gives would be charged to the model (held-out windows).
    ClearOfCommandChanges,
}

/// Windows of `horizon_s` every `stride_s` over the given tracks, keeping `past_s` of
/// command history; windows need the denoising span inside the track.
pub fn windows(
    recordings: &Recordings,
    tracks: &[usize],
    horizon_s: f64,
    stride_s: f64,
    past_s: f64,
    default_wheelbase: f64,
    starts: Starts,
) -> Vec<Window> {
    let mut out = Vec::new();
    for &index in tracks {
        let track = &recordings.tracks[index];
        let period = track.period;
        let steps = (horizon_s / period).round() as usize;
        let half = denoise_half_width(period);
        let stride = ((stride_s / period).round() as usize).max(1);
        let heading = unwrap(&track.heading);
        let mut start = half;
        loop {
            if starts == Starts::ClearOfCommandChanges
                && let Some(last) = (start + 1 - half..=start + half)
                    .rev()
                    .find(|&k| k < track.len() && command_changed(track, k))
            {
                start = last + 2 * half;
                continue;
            }
            if start + steps.max(half) >= track.len() {
                break;
            }
            out.push(window(
                track,
                index,
                &heading,
                start,
                steps,
                half,
                past_s,
                default_wheelbase,
            ));
            start += stride;
        }
    }
    out
}

/// `windows` cut again from `recordings`, the same tracks with their commands read another
/// way: the same starts and horizons, so two readings' errors stay paired window by window.
pub fn rebuilt(
    recordings: &Recordings,
    windows: &[Window],
    past_s: f64,
    default_wheelbase: f64,
) -> Vec<Window> {
    windows
        .iter()
        .map(|w| {
            let track = &recordings.tracks[w.track];
            window(
                track,
                w.track,
                &unwrap(&track.heading),
                w.start,
                w.steps(),
                denoise_half_width(track.period),
                past_s,
                default_wheelbase,
            )
        })
        .collect()
}

/// Samples on each side of a window's start in its denoising fit.
fn denoise_half_width(period: f64) -> usize {
    ((DENOISE_HALF_WIDTH_S / period).round() as usize).max(2)
}

#[allow(clippy::too_many_arguments)]
fn window(
    track: &RecordedTrack,
    index: usize,
    heading: &[f64],
    start: usize,
    steps: usize,
    half: usize,
    past_s: f64,
    default_wheelbase: f64,
) -> Window {
    let wheelbase = track.wheelbase.unwrap_or(default_wheelbase);
    let span = start - half..start + half + 1;
    let times: Vec<f64> = track.t[span.clone()]
        .iter()
        .map(|t| t - track.t[start])
        .collect();
    let smooth = |values: &[f64]| quadratic_at_zero(&times, &values[span.clone()]);
    let [x, y, h, v] = [
        smooth(&track.x),
        smooth(&track.y),
        smooth(heading),
        smooth(&track.speed),
    ];
    let noise = LocalNoise {
        variance: [x.variance, y.variance, h.variance, v.variance],
        dof: times.len().saturating_sub(3),
        value_factor: x.value_factor,
    };
    let ((x0, y0), (h0, yaw_rate), (v0, accel)) =
        ((x.value, y.value), (h.value, h.slope), (v.value, v.slope));
    // Below a few m/s the motion says little about what the actuators apply (at rest,
    // nothing): the last command is the better estimate there.
    let last_command = (
        track.accel_cmd[start.saturating_sub(1)],
        track.steer_cmd[start.saturating_sub(1)],
    );
    let steer = if v0 >= MIN_MOTION_SPEED {
        (wheelbase * yaw_rate / v0).atan()
    } else {
        last_command.1
    };
    let accel = if v0 >= MIN_MOTION_SPEED {
        accel
    } else {
        last_command.0
    };
    let origin = (x0, y0);
    let past_n = (past_s / track.period).ceil() as usize;
    let past = (1..=past_n.min(start))
        .map(|k| (track.accel_cmd[start - k], track.steer_cmd[start - k]))
        .collect();
    let commands = (start..start + steps)
        .map(|k| (track.accel_cmd[k], track.steer_cmd[k]))
        .collect();
    let recorded = (start + 1..=start + steps)
        .map(|k| {
            [
                track.x[k] - origin.0,
                track.y[k] - origin.1,
                heading[k],
                track.speed[k],
            ]
        })
        .collect();
    Window {
        track: index,
        start,
        period: track.period,
        wheelbase,
        origin,
        initial: [0.0, 0.0, h0, v0],
        applied: (accel, steer),
        noise,
        past,
        commands,
        recorded,
    }
}

/// Heading made continuous (no 2 pi jumps).
pub fn unwrap(heading: &[f64]) -> Vec<f64> {
    let mut out = Vec::with_capacity(heading.len());
    for (k, &h) in heading.iter().enumerate() {
        out.push(match out.last() {
            Some(&last) if k > 0 => last + wrap_angle(h - heading[k - 1]),
            _ => h,
        });
    }
    out
}

/// A least-squares quadratic at t = 0.
#[derive(Debug, Clone, Copy)]
pub(super) struct LocalFit {
    pub value: f64,
    pub slope: f64,
    /// Residual sum of squares over degrees of freedom (NaN without spare samples).
    pub variance: f64,
    /// `[(A^T A)^-1]_00`: the fitted value's variance per unit sample variance.
    pub value_factor: f64,
}

/// Least-squares quadratic through `(t, v)`: its value and slope at t = 0, and what its
/// residuals say about the noise.
pub(super) fn quadratic_at_zero(t: &[f64], v: &[f64]) -> LocalFit {
    let a = DMatrix::from_fn(t.len(), 3, |r, c| t[r].powi(c as i32));
    let b = DVector::from_column_slice(v);
    let dof = t.len().saturating_sub(3);
    let value_factor = (a.transpose() * &a)
        .try_inverse()
        .map_or(f64::NAN, |inv| inv[(0, 0)]);
    match a.clone().svd(true, true).solve(&b, 1e-12) {
        Ok(coef) => {
            let rss = (&a * &coef - &b).norm_squared();
            LocalFit {
                value: coef[0],
                slope: coef[1],
                variance: if dof > 0 { rss / dof as f64 } else { f64::NAN },
                value_factor,
            }
        }
        // Degenerate spans cannot happen with distinct times; fall back to the raw sample.
        Err(_) => LocalFit {
            value: v[t.len() / 2],
            slope: 0.0,
            variance: f64::NAN,
            value_factor,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quadratic_denoising_recovers_value_and_slope() {
        let t: Vec<f64> = (-5..=5).map(|k| k as f64 * 0.1).collect();
        let v: Vec<f64> = t.iter().map(|t| 3.0 + 2.0 * t - 0.5 * t * t).collect();
        let fit = quadratic_at_zero(&t, &v);
        assert!((fit.value - 3.0).abs() < 1e-9 && (fit.slope - 2.0).abs() < 1e-9);
        assert!(fit.variance < 1e-18);
        // Eleven symmetric samples: [(A^T A)^-1]_00 = 3 (3 n^2 - 7) / (4 n (n^2 - 4)).
        let n = 11.0;
        let expected = 3.0 * (3.0 * n * n - 7.0) / (4.0 * n * (n * n - 4.0));
        assert!(
            (fit.value_factor - expected).abs() < 1e-9,
            "{}",
            fit.value_factor
        );
    }

    #[test]
    fn unwrap_removes_two_pi_jumps() {
        let wrapped = [3.1, -3.1, -3.0];
        let u = unwrap(&wrapped);
        assert!((u[1] - (3.1 + (2.0 * std::f64::consts::PI - 6.2))).abs() < 1e-9);
        assert!((u[2] - u[1] - 0.1).abs() < 1e-9);
    }
}
