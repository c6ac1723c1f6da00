//! The scenario features whose distributions the JSD metrics compare (paper appendix
//! "Metrics"): kinematics (acceleration, speed), a map interaction (lateral deviation from the
//! lane centerline) and an agent interaction (distance to the lead vehicle). The same
//! functions run on simulated and on logged states, so the two histograms differ only by who
//! drove.

use serde::{Deserialize, Serialize};

use super::histogram::Histogram;
pub use crate::agent_view::{AgentView, LEAD_LATERAL_M, LEAD_RANGE_M, lead_gap, leader};
use crate::map::Map;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Feature {
    /// Speed change over one step divided by dt (m/s^2).
    Acceleration,
    /// m/s.
    Speed,
    /// Signed distance of the box centre from the nearest aligned lane centerline (m).
    LaneDeviation,
    /// Bumper-to-bumper gap to the nearest vehicle ahead in the same lane (m).
    LeadDistance,
}

impl Feature {
    pub const ALL: [Feature; 4] = [
        Feature::Acceleration,
        Feature::Speed,
        Feature::LaneDeviation,
        Feature::LeadDistance,
    ];

    /// Short name, as in the metric names `jsd_<name>`.
    pub fn name(self) -> &'static str {
        match self {
            Feature::Acceleration => "acc",
            Feature::Speed => "speed",
            Feature::LaneDeviation => "lat",
            Feature::LeadDistance => "lead",
        }
    }

    pub fn label(self) -> &'static str {
        match self {
            Feature::Acceleration => "acceleration (m/s^2)",
            Feature::Speed => "speed (m/s)",
            Feature::LaneDeviation => "lateral deviation from lane centerline (m)",
            Feature::LeadDistance => "distance to lead vehicle (m)",
        }
    }

    /// The empty histogram of this feature. Ranges cover highway driving; bins are fine enough
    /// to see a policy that brakes too hard or drifts within its lane.
    pub fn histogram(self) -> Histogram {
        match self {
            Feature::Acceleration => Histogram::new(-6.0, 6.0, 48),
            Feature::Speed => Histogram::new(0.0, 45.0, 45),
            Feature::LaneDeviation => Histogram::new(-2.0, 2.0, 40),
            Feature::LeadDistance => Histogram::new(0.0, 100.0, 50),
        }
    }
}

/// Signed lateral deviation from the nearest lane centerline that runs the vehicle's way.
pub fn lane_deviation(map: &Map, v: &AgentView) -> Option<f64> {
    map.lane_projection([v.x, v.y], v.heading)
        .map(|p| p.lateral)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn car(x: f64, y: f64, heading: f64) -> AgentView {
        AgentView {
            x,
            y,
            heading,
            speed: 20.0,
            length: 4.0,
            width: 2.0,
            present: true,
        }
    }

    #[test]
    fn leader_is_the_nearest_vehicle_ahead_in_the_lane() {
        let cars = [
            car(0.0, 0.0, 0.0),
            car(30.0, 0.5, 0.0),  // ahead, same lane: gap 30 - 4 = 26
            car(12.0, 3.5, 0.0),  // next lane
            car(-10.0, 0.0, 0.0), // behind
            car(50.0, 0.0, 0.0),  // further ahead
        ];
        assert_eq!(lead_gap(0, &cars), Some(26.0));
        // Absent vehicles are not leaders.
        let mut without = cars;
        without[1].present = false;
        assert_eq!(lead_gap(0, &without), Some(46.0));
        // Nobody ahead of the front car.
        assert_eq!(lead_gap(4, &cars), None);
    }

    #[test]
    fn leader_search_follows_the_heading() {
        // Heading north: the car 20 m north is ahead, the one 20 m east is beside.
        let h = std::f64::consts::FRAC_PI_2;
        let cars = [car(0.0, 0.0, h), car(20.0, 0.0, h), car(0.3, 20.0, h)];
        assert!((lead_gap(0, &cars).unwrap() - 16.0).abs() < 1e-9);
    }

    #[test]
    fn overlapping_vehicles_have_zero_gap() {
        let cars = [car(0.0, 0.0, 0.0), car(2.0, 0.0, 0.0)];
        assert_eq!(lead_gap(0, &cars), Some(0.0));
    }
}
