//! Where the mismatch is: residuals of a model broken down by channel (along-track,
//! across-track, heading, speed), by horizon, by driving regime, by track and by time.
//!
//! Regimes are read at the start of short windows (1 s), so an error is charged to the
//! conditions that produced it rather than to everything that came after.

use serde::Serialize;

use super::simulate::StepError;
use super::windows::{Window, command_changed};
use crate::data::Recordings;

/// RMS errors per channel.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct ChannelRms {
    pub n: usize,
    pub pos_m: f64,
    pub along_m: f64,
    pub across_m: f64,
    pub heading_rad: f64,
    pub speed_m_s: f64,
}

impl ChannelRms {
    /// Over the given steps.
    pub fn of<'a>(errors: impl IntoIterator<Item = &'a StepError>) -> Self {
        let mut sums = [0.0; 4];
        let mut n = 0;
        for e in errors {
            sums[0] += e.along * e.along;
            sums[1] += e.across * e.across;
            sums[2] += e.heading * e.heading;
            sums[3] += e.speed * e.speed;
            n += 1;
        }
        Self::from_sums(sums, n)
    }

    /// From sums of squares (along, across, heading, speed) over `n` steps.
    pub fn from_sums(sums: [f64; 4], n: usize) -> Self {
        let rms = |s: f64| if n == 0 { 0.0 } else { (s / n as f64).sqrt() };
        Self {
            n,
            pos_m: rms(sums[0] + sums[1]),
            along_m: rms(sums[0]),
            across_m: rms(sums[1]),
            heading_rad: rms(sums[2]),
            speed_m_s: rms(sums[3]),
        }
    }

    pub fn channel(&self, name: &str) -> f64 {
        match name {
            "along" => self.along_m,
            "across" => self.across_m,
            "heading" => self.heading_rad,
            _ => self.speed_m_s,
        }
    }
}

/// One bin of a regime variable.
#[derive(Debug, Clone, Serialize)]
pub struct RegimeBin {
    pub range: String,
    pub rms: ChannelRms,
}

/// Errors binned by one regime variable.
#[derive(Debug, Clone, Serialize)]
pub struct Regime {
    pub variable: String,
    pub unit: String,
    pub bins: Vec<RegimeBin>,
}

/// A place where one channel's error is well above its average.
#[derive(Debug, Clone, Serialize)]
pub struct Concentration {
    pub variable: String,
    pub range: String,
    pub channel: String,
    pub rms: f64,
    pub overall_rms: f64,
    pub ratio: f64,
}

/// One track's share of the error.
#[derive(Debug, Clone, Serialize)]
pub struct TrackError {
    pub track_id: String,
    pub pos_rmse_m: f64,
    pub share_of_squared_error_pct: f64,
}

/// The localisation breakdown (JSON `mismatch`).
#[derive(Debug, Clone, Serialize)]
pub struct Mismatch {
    /// Over the long (evaluation) windows.
    pub channels: ChannelRms,
    /// Position RMSE at each whole second of horizon.
    pub by_horizon_s: Vec<(f64, f64)>,
    /// Short-window errors by regime at the window start.
    pub short_window_s: f64,
    pub regimes: Vec<Regime>,
    /// Largest concentrations, strongest first.
    pub concentrations: Vec<Concentration>,
    /// Worst tracks first (at most 5).
    pub by_track: Vec<TrackError>,
    /// Short-window errors in the first, middle and last third of each track.
    pub by_time_in_track: Vec<RegimeBin>,
}

/// A regime variable: name, unit, bin edges.
pub(super) type Variable = (&'static str, &'static str, &'static [f64]);

pub(super) const VARIABLES: [Variable; 5] = [
    ("speed", "m/s", &[0.0, 10.0, 20.0, 30.0]),
    ("lateral_accel", "m/s^2", &[0.0, 0.5, 1.5, 3.0]),
    ("accel_cmd_abs", "m/s^2", &[0.0, 0.5, 1.5, 3.0]),
    ("steer_cmd_rate", "rad/s", &[0.0, 0.02, 0.1, 0.3]),
    ("since_command_change", "s", &[0.0, 0.5, 1.0, 2.0]),
];

/// The regime variables of a window, in [`VARIABLES`] order.
pub(super) fn regime_values(recordings: &Recordings, w: &Window) -> [f64; 5] {
    let track = &recordings.tracks[w.track];
    let v = w.initial[3];
    let (accel, steer) = w.commands[0];
    let lateral = v * v * steer.tan().abs() / w.wheelbase;
    let rate = w
        .commands
        .windows(2)
        .map(|c| (c[1].1 - c[0].1).abs() / w.period)
        .fold(0.0, f64::max);
    let mut since = 0.0;
    let mut k = w.start;
    while k > 0 && since < 5.0 {
        if command_changed(track, k) {
            break;
        }
        since += w.period;
        k -= 1;
    }
    [v.abs(), lateral, accel.abs(), rate, since]
}

pub(super) fn bin_label(edges: &[f64], b: usize) -> String {
    match edges.get(b + 1) {
        Some(hi) => format!("[{}, {})", edges[b], hi),
        None => format!(">= {}", edges[b]),
    }
}

/// The breakdown from long-window errors (`long`, for channels and horizons) and short
/// windows with their errors (for regimes, tracks, time).
pub fn locate(
    recordings: &Recordings,
    long: &[Vec<StepError>],
    long_period: f64,
    short_windows: &[Window],
    short: &[Vec<StepError>],
) -> Mismatch {
    let channels = ChannelRms::of(long.iter().flatten());
    let steps = long.iter().map(Vec::len).max().unwrap_or(0);
    let per_second = (1.0 / long_period).round().max(1.0) as usize;
    let by_horizon_s = (1..=steps / per_second)
        .map(|s| {
            let k = s * per_second - 1;
            let rms = ChannelRms::of(long.iter().filter_map(|w| w.get(k)));
            (s as f64, rms.pos_m)
        })
        .collect();
    // Short windows: the error at their end.
    let ends: Vec<&StepError> = short.iter().filter_map(|w| w.last()).collect();
    let overall = ChannelRms::of(ends.iter().copied());
    let values: Vec<[f64; 5]> = short_windows
        .iter()
        .map(|w| regime_values(recordings, w))
        .collect();
    let mut regimes = Vec::new();
    let mut concentrations = Vec::new();
    for (v, (name, unit, edges)) in VARIABLES.iter().enumerate() {
        let mut bins = Vec::new();
        for b in 0..edges.len() {
            let hi = edges.get(b + 1).copied().unwrap_or(f64::INFINITY);
            let members = values
                .iter()
                .zip(&ends)
                .filter(|(x, _)| x[v] >= edges[b] && x[v] < hi)
                .map(|(_, e)| *e);
            let rms = ChannelRms::of(members);
            if rms.n == 0 {
                continue;
            }
            // Bins need enough windows to say anything.
            if rms.n >= 20 {
                for channel in ["along", "across", "heading", "speed"] {
                    let all = overall.channel(channel);
                    if all > 0.0 {
                        concentrations.push(Concentration {
                            variable: name.to_string(),
                            range: bin_label(edges, b),
                            channel: channel.to_string(),
                            rms: rms.channel(channel),
                            overall_rms: all,
                            ratio: rms.channel(channel) / all,
                        });
                    }
                }
            }
            bins.push(RegimeBin {
                range: bin_label(edges, b),
                rms,
            });
        }
        regimes.push(Regime {
            variable: name.to_string(),
            unit: unit.to_string(),
            bins,
        });
    }
    concentrations.sort_by(|a, b| b.ratio.total_cmp(&a.ratio));
    concentrations.truncate(8);

    let total_sq: f64 = ends.iter().map(|e| e.position_sq()).sum();
    let mut by_track: Vec<TrackError> = (0..recordings.tracks.len())
        .filter_map(|t| {
            let errs: Vec<&StepError> = short_windows
                .iter()
                .zip(&ends)
                .filter(|(w, _)| w.track == t)
                .map(|(_, e)| *e)
                .collect();
            (!errs.is_empty()).then(|| {
                let sq: f64 = errs.iter().map(|e| e.position_sq()).sum();
                TrackError {
                    track_id: recordings.tracks[t].id.clone(),
                    pos_rmse_m: (sq / errs.len() as f64).sqrt(),
                    share_of_squared_error_pct: 100.0 * sq / total_sq.max(1e-12),
                }
            })
        })
        .collect();
    by_track.sort_by(|a, b| b.pos_rmse_m.total_cmp(&a.pos_rmse_m));
    by_track.truncate(5);

    let by_time_in_track = ["first third", "middle third", "last third"]
        .iter()
        .enumerate()
        .map(|(third, label)| {
            let members = short_windows.iter().zip(&ends).filter(|(w, _)| {
                let len = recordings.tracks[w.track].len().max(1);
                (3 * w.start / len).min(2) == third
            });
            RegimeBin {
                range: label.to_string(),
                rms: ChannelRms::of(members.map(|(_, e)| *e)),
            }
        })
        .collect();
    Mismatch {
        channels,
        by_horizon_s,
        short_window_s: short.first().map_or(0.0, |w| w.len() as f64 * long_period),
        regimes,
        concentrations,
        by_track,
        by_time_in_track,
    }
}
