//! A synthetic scene on any map: cars at constant speed along its lanes. For tests and
//! benchmarks that need scenes of a chosen size without a recording.

use std::sync::Arc;

use super::{AgentRole, Scene, SceneAgent};
use crate::map::{LaneGraph, Map};
use crate::vehicle::{AgentState, VehicleClass};

/// Point and heading at arc length `s` along a polyline with cumulative lengths `cum`.
fn along(points: &[[f64; 2]], cum: &[f64], s: f64) -> ([f64; 2], f64) {
    let i = cum.partition_point(|&c| c <= s).clamp(1, points.len() - 1);
    let (a, b) = (points[i - 1], points[i]);
    let w = ((s - cum[i - 1]) / (cum[i] - cum[i - 1]).max(1e-9)).clamp(0.0, 1.0);
    (
        [a[0] + w * (b[0] - a[0]), a[1] + w * (b[1] - a[1])],
        (b[1] - a[1]).atan2(b[0] - a[0]),
    )
}

/// A scene of `agents` controlled cars spread over the map's graph lanes, each logged at
/// constant speed along its lane centreline for `history` past and `future` steps. `seed`
/// shifts the placement.
pub fn synthetic_scene(
    map: &Arc<Map>,
    graph: &Arc<LaneGraph>,
    agents: usize,
    seed: usize,
    history: usize,
    future: usize,
) -> Scene {
    let lanes: Vec<_> = map.lanes().iter().filter(|l| l.is_graph_lane()).collect();
    let per_lane = agents.div_ceil(lanes.len().max(1));
    let dt = 0.5;
    let steps = history + 1 + future;
    let mut out = Vec::with_capacity(agents);
    for i in 0..agents {
        let lane = lanes[i % lanes.len()];
        let slot = i / lanes.len();
        let spacing = lane.length() / per_lane as f64;
        let speed = 25.0 + ((i * 7 + seed * 3) % 10) as f64;
        let s0 = (slot as f64 + 0.2 + 0.05 * (seed % 5) as f64) * spacing;
        let states = (0..steps)
            .map(|k| {
                let s = (s0 + speed * (k as f64 - history as f64) * dt).clamp(0.0, lane.length());
                let (p, heading) = along(&lane.centerline, &lane.s, s);
                AgentState {
                    x: p[0],
                    y: p[1],
                    heading,
                    speed,
                    accel: 0.0,
                }
            })
            .collect();
        out.push(SceneAgent {
            track_id: i,
            class: VehicleClass::Car,
            length: 4.6,
            width: 1.9,
            role: AgentRole::Controlled,
            states,
            valid: vec![true; steps],
        });
    }
    Scene {
        id: format!("synthetic-{seed}"),
        t0: 0.0,
        dt,
        history_steps: history,
        future_steps: future,
        map: map.clone(),
        lane_graph: graph.clone(),
        agents: out,
    }
}
