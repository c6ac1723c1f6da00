//! Cutting recordings into simulation windows: each starts from a denoised recorded state
//! and replays the recorded commands over a horizon, for comparison with what was recorded.

use nalgebra::{DMatrix, DVector};

use crate::data::{RecordedTrack, Recordings};
use crate::geometry::wrap_angle;

/// Half-width (s) of the local quadratic fit that denoises a window's initial state.
pub const DENOISE_HALF_WIDTH_S: f64 = 0.5;

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
    /// Commands before the start, newest first.
    pub past: Vec<(f64, f64)>,
    /// Commands at the start and the `steps - 1` samples after it.
    pub commands: Vec<(f64, f64)>,
    /// Recorded x, y (relative to `origin`), unwrapped heading and speed at the `steps`
    /// samples after the start.
    pub recorded: Vec<[f64; 4]>,
}

impl Window {
    pub fn steps(&self) -> usize {
        self.commands.len()
    }
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
) -> Vec<Window> {
    let mut out = Vec::new();
    for &index in tracks {
        let track = &recordings.tracks[index];
        let period = track.period;
        let steps = (horizon_s / period).round() as usize;
        let half = ((DENOISE_HALF_WIDTH_S / period).round() as usize).max(2);
        let stride = ((stride_s / period).round() as usize).max(1);
        let heading = unwrap(&track.heading);
        let mut start = half;
        while start + steps.max(half) < track.len() {
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
    let (x0, _) = smooth(&track.x);
    let (y0, _) = smooth(&track.y);
    let (h0, yaw_rate) = smooth(heading);
    let (v0, accel) = smooth(&track.speed);
    let steer = (wheelbase * yaw_rate / v0.abs().max(1.0)).atan();
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

/// Least-squares quadratic through `(t, v)`: its value and slope at t = 0.
fn quadratic_at_zero(t: &[f64], v: &[f64]) -> (f64, f64) {
    let a = DMatrix::from_fn(t.len(), 3, |r, c| t[r].powi(c as i32));
    let b = DVector::from_column_slice(v);
    match a.svd(true, true).solve(&b, 1e-12) {
        Ok(coef) => (coef[0], coef[1]),
        // Degenerate spans cannot happen with distinct times; fall back to the raw sample.
        Err(_) => (v[t.len() / 2], 0.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quadratic_denoising_recovers_value_and_slope() {
        let t: Vec<f64> = (-5..=5).map(|k| k as f64 * 0.1).collect();
        let v: Vec<f64> = t.iter().map(|t| 3.0 + 2.0 * t - 0.5 * t * t).collect();
        let (value, slope) = quadratic_at_zero(&t, &v);
        assert!((value - 3.0).abs() < 1e-9 && (slope - 2.0).abs() < 1e-9);
    }

    #[test]
    fn unwrap_removes_two_pi_jumps() {
        let wrapped = [3.1, -3.1, -3.0];
        let u = unwrap(&wrapped);
        assert!((u[1] - (3.1 + (2.0 * std::f64::consts::PI - 6.2))).abs() < 1e-9);
        assert!((u[2] - u[1] - 0.1).abs() < 1e-9);
    }
}
