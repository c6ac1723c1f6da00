//! Never claiming a fit the data contradict: the final model's held-out error against the
//! noise floor ([`super::noise`]). "Nothing missing" is said only when the error is at the
//! floor; otherwise the report sizes the excess and says which channel and which driving
//! regimes hold it.

use serde::Serialize;

use super::locate::{ChannelRms, VARIABLES, bin_label, regime_values};
use super::noise::NoiseLevels;
use super::simulate::StepError;
use super::windows::Window;
use crate::data::Recordings;

/// Held-out error above this multiple of the floor is more than noise. Sampling alone moves
/// the ratio by a few per cent on the default 12 held-out tracks.
pub const UNEXPLAINED_RATIO: f64 = 1.2;

/// Regime bins need this many short windows to be reported.
const MIN_BIN_WINDOWS: usize = 20;

/// One channel's error against its floor.
#[derive(Debug, Clone, Serialize)]
pub struct ChannelExcess {
    pub channel: String,
    pub unit: String,
    pub rms: f64,
    pub floor: f64,
    pub ratio: f64,
}

/// One regime bin's short-window error against its floor.
#[derive(Debug, Clone, Serialize)]
pub struct RegimeExcess {
    pub variable: String,
    pub unit: String,
    pub range: String,
    pub windows: usize,
    pub pos_rms_m: f64,
    pub floor_m: f64,
    pub ratio: f64,
    /// This bin's share of the squared error above the floor, over all bins of its variable.
    pub share_of_excess_pct: f64,
}

/// The verdict (JSON `unexplained`).
#[derive(Debug, Clone, Serialize)]
pub struct Unexplained {
    /// Sensor noise estimated from the recordings.
    pub noise: NoiseLevels,
    /// Held-out position RMSE a perfect model would show, and the final model's.
    pub floor_pos_m: f64,
    pub heldout_pos_rmse_m: f64,
    pub ratio: f64,
    /// RMS of the part above the floor, sqrt(rmse^2 - floor^2).
    pub excess_m: f64,
    /// Whether the final model's error is at the floor (ratio <= [`UNEXPLAINED_RATIO`]).
    pub at_floor: bool,
    /// Channels, largest ratio first.
    pub channels: Vec<ChannelExcess>,
    /// Regime bins holding the excess, largest ratio first (at most 6).
    pub regimes: Vec<RegimeExcess>,
}

impl Unexplained {
    /// Held-out long windows with the final model's errors, and the short windows with theirs.
    pub fn assess(
        recordings: &Recordings,
        noise: NoiseLevels,
        heldout: &[Window],
        heldout_errors: &[Vec<StepError>],
        short: &[Window],
        short_errors: &[Vec<StepError>],
    ) -> Self {
        let observed = ChannelRms::of(heldout_errors.iter().flatten());
        let floor = noise.floor_over(heldout);
        let ratio = observed.pos_m / floor.pos_m.max(1e-12);
        let channels = channel_excess(&observed, &floor);
        let mut regimes = regime_excess(recordings, &noise, short, short_errors);
        regimes.sort_by(|a, b| b.ratio.total_cmp(&a.ratio));
        regimes.truncate(6);
        Self {
            noise,
            floor_pos_m: floor.pos_m,
            heldout_pos_rmse_m: observed.pos_m,
            ratio,
            excess_m: (observed.pos_m.powi(2) - floor.pos_m.powi(2))
                .max(0.0)
                .sqrt(),
            at_floor: ratio <= UNEXPLAINED_RATIO,
            channels,
            regimes,
        }
    }

    /// Report lines for people.
    pub fn summary(&self) -> Vec<String> {
        let n = &self.noise;
        let mut lines = vec![format!(
            "noise floor: sensor noise from the local fits {:.3} m, {:.4} rad, {:.3} m/s -> a \
             perfect model would show {:.3} m held-out; the final model shows {:.3} m ({:.2}x)",
            n.position_m,
            n.heading_rad,
            n.speed_m_s,
            self.floor_pos_m,
            self.heldout_pos_rmse_m,
            self.ratio
        )];
        if self.at_floor {
            lines.push("unexplained: nothing; the residual is at the noise floor".into());
            return lines;
        }
        lines.push(format!(
            "unexplained: {:.3} m RMS above the noise floor ({:.2}x the floor); the model \
             still lacks something",
            self.excess_m, self.ratio
        ));
        for c in self.channels.iter().take(2) {
            lines.push(format!(
                "  channel {}: {:.4} {} vs floor {:.4} ({:.1}x)",
                c.channel, c.rms, c.unit, c.floor, c.ratio
            ));
        }
        for r in self.regimes.iter().take(3) {
            lines.push(format!(
                "  where {} is {} {}: {:.3} m at 1 s vs floor {:.3} m ({:.1}x, {:.0} % of the excess)",
                r.variable, r.range, r.unit, r.pos_rms_m, r.floor_m, r.ratio, r.share_of_excess_pct
            ));
        }
        lines
    }
}

fn channel_excess(observed: &ChannelRms, floor: &ChannelRms) -> Vec<ChannelExcess> {
    let mut out: Vec<ChannelExcess> = [
        ("along", "m"),
        ("across", "m"),
        ("heading", "rad"),
        ("speed", "m/s"),
    ]
    .into_iter()
    .map(|(channel, unit)| {
        let (rms, floor) = (observed.channel(channel), floor.channel(channel));
        ChannelExcess {
            channel: channel.into(),
            unit: unit.into(),
            rms,
            floor,
            ratio: rms / floor.max(1e-12),
        }
    })
    .collect();
    out.sort_by(|a, b| b.ratio.total_cmp(&a.ratio));
    out
}

/// Short windows' end errors by regime bin against the floor at their end, every bin with
/// enough windows, in variable and bin order.
pub fn regime_excess(
    recordings: &Recordings,
    noise: &NoiseLevels,
    short: &[Window],
    errors: &[Vec<StepError>],
) -> Vec<RegimeExcess> {
    let values: Vec<[f64; 5]> = short.iter().map(|w| regime_values(recordings, w)).collect();
    let mut out = Vec::new();
    for (v, (name, unit, edges)) in VARIABLES.iter().enumerate() {
        let mut bins = Vec::new();
        for b in 0..edges.len() {
            let hi = edges.get(b + 1).copied().unwrap_or(f64::INFINITY);
            let members: Vec<(&Window, &StepError)> = short
                .iter()
                .zip(errors)
                .zip(&values)
                .filter(|(_, x)| x[v] >= edges[b] && x[v] < hi)
                .filter_map(|((w, e), _)| e.last().map(|last| (w, last)))
                .collect();
            if members.len() < MIN_BIN_WINDOWS {
                continue;
            }
            let observed = ChannelRms::of(members.iter().map(|(_, e)| *e)).pos_m;
            let floor = noise
                .floor(members.iter().map(|(w, _)| (*w, w.steps() - 1)))
                .pos_m;
            let excess_sq = (observed.powi(2) - floor.powi(2)).max(0.0) * members.len() as f64;
            bins.push((b, members.len(), observed, floor, excess_sq));
        }
        let total: f64 = bins.iter().map(|b| b.4).sum();
        out.extend(
            bins.into_iter()
                .map(|(b, n, observed, floor, excess_sq)| RegimeExcess {
                    variable: name.to_string(),
                    unit: unit.to_string(),
                    range: bin_label(edges, b),
                    windows: n,
                    pos_rms_m: observed,
                    floor_m: floor,
                    ratio: observed / floor.max(1e-12),
                    share_of_excess_pct: 100.0 * excess_sq / total.max(1e-12),
                }),
        );
    }
    out
}
