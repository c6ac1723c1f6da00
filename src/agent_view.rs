//! One agent at one step as the rule-based drivers, the evaluation and the recordings'
//! analyses all see it: a box with a heading and a speed; and the car ahead of it in its lane.

use crate::geometry::OrientedBox;

/// One agent at one step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AgentView {
    /// Box centre (m).
    pub x: f64,
    pub y: f64,
    pub heading: f64,
    pub speed: f64,
    pub length: f64,
    pub width: f64,
    pub present: bool,
}

impl AgentView {
    pub fn footprint(&self) -> OrientedBox {
        OrientedBox::new([self.x, self.y], self.heading, self.length, self.width)
    }

    /// Unit vector along the heading.
    pub fn direction(&self) -> [f64; 2] {
        [self.heading.cos(), self.heading.sin()]
    }
}

/// A vehicle ahead counts as the leader when its centre is within this of the follower's
/// centre line (half a lane).
pub const LEAD_LATERAL_M: f64 = 1.75;
/// Leaders further than this (centre to centre) are not looked for.
pub const LEAD_RANGE_M: f64 = 100.0;

/// The gap from vehicle `me` to the nearest present vehicle ahead of it in its lane:
/// longitudinal distance in `me`'s frame minus both half-lengths.
pub fn lead_gap(me: usize, vehicles: &[AgentView]) -> Option<f64> {
    leader(me, vehicles).map(|(_, gap)| gap)
}

/// The vehicle [`lead_gap`] measures to: its index and the gap.
pub fn leader(me: usize, vehicles: &[AgentView]) -> Option<(usize, f64)> {
    let m = &vehicles[me];
    let (sin, cos) = m.heading.sin_cos();
    vehicles
        .iter()
        .enumerate()
        .filter(|&(j, o)| o.present && j != me)
        .filter_map(|(j, o)| {
            let (dx, dy) = (o.x - m.x, o.y - m.y);
            let ahead = dx * cos + dy * sin;
            let side = -dx * sin + dy * cos;
            (ahead > 0.0 && ahead <= LEAD_RANGE_M && side.abs() <= LEAD_LATERAL_M)
                .then(|| (j, (ahead - 0.5 * (m.length + o.length)).max(0.0)))
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
}
