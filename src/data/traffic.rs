//! Real traffic statistics: what the vehicles of a recording drive at (speed per lane),
//! how closely they follow (time headway per lane), and how big they are. Long-tail scenarios
//! draw their background traffic from these, so density and speeds are the recording's, not
//! invented.
//!
//! The recording is sampled once per `period_s`; each vehicle present then is projected on its
//! nearest lane. Lanes are ranked from the right (0 = rightmost, the slow lane with most
//! trucks), which carries over to maps with other lane counts. A follower's headway is its
//! bumper-to-bumper gap to the next vehicle ahead on the same lane divided by its speed; its
//! closing rate is how fast it closes that gap relative to the gap (speed difference / gap,
//! the inverse time to collision), which ties a follower's speed to its leader's: in real
//! traffic a fast car does not keep its speed a few seconds behind a slow truck.
//! Gaps are bounded by the recorded stretch (266 m on the A9), so very long free-flow gaps are
//! under-represented.

use rand::Rng;
use serde::{Deserialize, Serialize};

use super::automatum::Recording;
use super::track::VehicleClass;
use crate::map::Map;

/// One vehicle at one sampled instant.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VehicleSample {
    pub speed: f64,
    pub length: f64,
    pub width: f64,
    pub class: VehicleClass,
}

/// Statistics of one lane rank.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct LaneTraffic {
    /// Vehicles seen on lanes of this rank, sorted by speed.
    pub vehicles: Vec<VehicleSample>,
    /// Time headways of followers (s), sorted.
    pub headways: Vec<f64>,
    /// Closing rates of followers (1/s): (own speed - leader's speed) / gap, sorted; negative
    /// where the gap opens.
    pub closing_rates: Vec<f64>,
}

/// Per-lane-rank statistics of a recording (index 0 = rightmost lane).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrafficStatistics {
    pub period_s: f64,
    pub lanes: Vec<LaneTraffic>,
}

/// Followers slower than this have no meaningful headway (m/s).
const MIN_FOLLOWER_SPEED: f64 = 2.0;

/// The entry at quantile `u` of a sorted, non-empty slice.
fn at_quantile<T: Clone>(sorted: &[T], u: f64) -> T {
    let k = (u.clamp(0.0, 1.0) * (sorted.len() - 1) as f64).round() as usize;
    sorted[k].clone()
}

impl TrafficStatistics {
    /// Samples `recording` on `map` every `period_s` seconds.
    pub fn from_recording(recording: &Recording, map: &Map, period_s: f64) -> TrafficStatistics {
        let mut lanes: Vec<LaneTraffic> = Vec::new();
        let steps = (recording.duration() / period_s).floor() as usize;
        for k in 0..=steps {
            let t = k as f64 * period_s;
            // (lane index, s along it, speed, length, rank) of every vehicle on a lane now.
            let mut on_lanes: Vec<(usize, f64, f64, f64, usize)> = Vec::new();
            for track in &recording.tracks {
                let Some(state) = track.state_at(t) else {
                    continue;
                };
                let Some(p) = map.lane_projection([state.x, state.y], state.heading) else {
                    continue;
                };
                if p.distance > 0.5 * map.lanes()[p.lane].widths[0].max(2.0) {
                    continue; // between lanes (changing) or off the lanes
                }
                let rank = rank_from_right(map, p.lane);
                if lanes.len() <= rank {
                    lanes.resize(rank + 1, LaneTraffic::default());
                }
                lanes[rank].vehicles.push(VehicleSample {
                    speed: state.speed,
                    length: track.length,
                    width: track.width,
                    class: track.class.clone(),
                });
                on_lanes.push((p.lane, p.s, state.speed, track.length, rank));
            }
            on_lanes.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)));
            for pair in on_lanes.windows(2) {
                let (follower, leader) = (pair[0], pair[1]);
                if follower.0 != leader.0 || follower.2 < MIN_FOLLOWER_SPEED {
                    continue;
                }
                let gap = leader.1 - follower.1 - 0.5 * (leader.3 + follower.3);
                if gap > 0.0 {
                    let lane = &mut lanes[follower.4];
                    lane.headways.push(gap / follower.2);
                    lane.closing_rates.push((follower.2 - leader.2) / gap);
                }
            }
        }
        for lane in &mut lanes {
            lane.vehicles.sort_by(|a, b| a.speed.total_cmp(&b.speed));
            lane.headways.sort_by(f64::total_cmp);
            lane.closing_rates.sort_by(f64::total_cmp);
        }
        TrafficStatistics { period_s, lanes }
    }

    /// The statistics for a lane of rank `rank` from the right; wider roads than the recording
    /// reuse its leftmost lane. `None` when the recording had no traffic at all.
    pub fn lane(&self, rank: usize) -> Option<&LaneTraffic> {
        let usable: Vec<&LaneTraffic> = self
            .lanes
            .iter()
            .filter(|l| !l.vehicles.is_empty() && !l.headways.is_empty())
            .collect();
        usable.get(rank.min(usable.len().checked_sub(1)?)).copied()
    }
}

impl LaneTraffic {
    /// A vehicle drawn from the speed quantile band `[lo, hi]` (e.g. `[0, 0.2]` = the slowest
    /// fifth), with the size and class it was recorded with.
    pub fn draw_vehicle(&self, rng: &mut impl Rng, band: [f64; 2]) -> VehicleSample {
        at_quantile(&self.vehicles, rng.random_range(band[0]..=band[1]))
    }

    /// A time headway (s) drawn from the quantile band `[lo, hi]`.
    pub fn draw_headway(&self, rng: &mut impl Rng, band: [f64; 2]) -> f64 {
        at_quantile(&self.headways, rng.random_range(band[0]..=band[1]))
    }

    /// A closing rate (1/s, see [`LaneTraffic::closing_rates`]) drawn from the whole recorded
    /// distribution.
    pub fn draw_closing_rate(&self, rng: &mut impl Rng) -> f64 {
        at_quantile(&self.closing_rates, rng.random_range(0.0..=1.0))
    }

    /// The vehicle at speed quantile `u`.
    pub fn vehicle_at(&self, u: f64) -> VehicleSample {
        at_quantile(&self.vehicles, u)
    }

    /// Median speed (m/s).
    pub fn median_speed(&self) -> f64 {
        at_quantile(&self.vehicles, 0.5).speed
    }

    pub fn median_headway(&self) -> f64 {
        at_quantile(&self.headways, 0.5)
    }
}

/// Number of same-direction lanes to the right of `lane`.
pub fn rank_from_right(map: &Map, lane: usize) -> usize {
    let mut rank = 0;
    let mut current = lane;
    while let Some(next) = map.lanes()[current].right_neighbour {
        rank += 1;
        current = next;
        if rank > 32 {
            break; // malformed neighbour cycle
        }
    }
    rank
}
