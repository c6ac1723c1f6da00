//! One logged vehicle: its box, its class and its time-stamped states, with interpolation onto
//! the policy's time grid.

use crate::geometry::{OrientedBox, wrap_angle};
pub use crate::vehicle::{AgentState, MAX_SPEED, MIN_SPEED, VehicleClass};

/// One logged sample, at the recording's own rate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackSample {
    /// Seconds since the start of the recording.
    pub t: f64,
    pub state: AgentState,
    /// Lateral speed and acceleration in the vehicle frame (m/s, m/s^2).
    pub lateral_speed: f64,
    pub lateral_accel: f64,
    /// The recording's own lane label (OpenDRIVE lane id of road `road_id`).
    pub lane_id: i32,
}

/// A logged vehicle.
#[derive(Debug, Clone, PartialEq)]
pub struct Track {
    /// Index of the track in its recording (stable, used as the agent id).
    pub id: usize,
    pub uuid: String,
    pub class: VehicleClass,
    pub length: f64,
    pub width: f64,
    /// Strictly increasing in time, uniformly sampled.
    pub samples: Vec<TrackSample>,
}

impl Track {
    pub fn first_time(&self) -> f64 {
        self.samples.first().map_or(f64::NAN, |s| s.t)
    }

    pub fn last_time(&self) -> f64 {
        self.samples.last().map_or(f64::NAN, |s| s.t)
    }

    /// Whether the vehicle was observed at time `t` (within the logged span).
    pub fn covers(&self, t: f64) -> bool {
        t >= self.first_time() - 1e-9 && t <= self.last_time() + 1e-9
    }

    /// State at time `t`, linearly interpolated between the two neighbouring samples (heading
    /// along the shorter arc); `None` outside the logged span.
    pub fn state_at(&self, t: f64) -> Option<AgentState> {
        if !self.covers(t) {
            return None;
        }
        let i = self.samples.partition_point(|s| s.t <= t);
        if i == 0 {
            return Some(self.samples[0].state);
        }
        if i == self.samples.len() {
            return self.samples.last().map(|s| s.state);
        }
        let (a, b) = (&self.samples[i - 1], &self.samples[i]);
        let w = ((t - a.t) / (b.t - a.t)).clamp(0.0, 1.0);
        let lerp = |p: f64, q: f64| p + w * (q - p);
        let (sa, sb) = (a.state, b.state);
        Some(AgentState {
            x: lerp(sa.x, sb.x),
            y: lerp(sa.y, sb.y),
            heading: wrap_angle(sa.heading + w * wrap_angle(sb.heading - sa.heading)),
            speed: lerp(sa.speed, sb.speed),
            accel: lerp(sa.accel, sb.accel),
        })
    }

    /// The vehicle's footprint in a given state.
    pub fn footprint(&self, state: &AgentState) -> OrientedBox {
        OrientedBox::new([state.x, state.y], state.heading, self.length, self.width)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(t: f64, x: f64, heading: f64) -> TrackSample {
        TrackSample {
            t,
            state: AgentState {
                x,
                y: 0.0,
                heading,
                speed: 10.0,
                accel: 0.0,
            },
            lateral_speed: 0.0,
            lateral_accel: 0.0,
            lane_id: -1,
        }
    }

    #[test]
    fn interpolates_position_and_heading_across_the_wrap() {
        let track = Track {
            id: 0,
            uuid: "u".into(),
            class: VehicleClass::Car,
            length: 4.0,
            width: 2.0,
            samples: vec![sample(1.0, 0.0, 3.1), sample(2.0, 10.0, -3.1)],
        };
        let s = track.state_at(1.5).expect("inside the span");
        assert!((s.x - 5.0).abs() < 1e-12);
        // Halfway between 3.1 and -3.1 along the short arc is pi, not 0.
        assert!((s.heading.abs() - std::f64::consts::PI).abs() < 1e-9);
        assert!(track.state_at(0.99).is_none());
        assert!(track.state_at(2.01).is_none());
        assert_eq!(track.state_at(2.0).map(|s| s.x), Some(10.0));
    }
}
