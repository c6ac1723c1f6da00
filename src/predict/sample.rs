//! Training and test examples of the downstream trajectory predictor: at an anchor step, one
//! controlled agent's recent past, the lane ahead of it and its leader, all in the agent's own
//! frame, with the 5 s of future that followed (logged, or simulated by a traffic model).
//!
//! The same extraction runs on real scenes and on scenes whose futures a policy simulated, so
//! two datasets differ only in who drove.

use crate::driver::{AgentView, LanePath};
use crate::eval::features::leader;
use crate::eval::tally::logged_view;
use crate::scene::{AgentRole, Scene};

/// Past steps the predictor sees besides the anchor (2 s at dt = 0.5 s).
pub const HISTORY_STEPS: usize = 4;
/// Future steps predicted (5 s, the paper's FDE horizon).
pub const HORIZON_STEPS: usize = 10;
/// Stations (m) along the lane ahead whose centreline points are inputs.
const LANE_STATIONS: [f64; 9] = [0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0];
/// Input scales: positions in tens of metres, speeds in tens of m/s.
const POSITION_SCALE: f64 = 10.0;
const SPEED_SCALE: f64 = 10.0;
/// Leader gaps are capped here (beyond it nobody leads).
const LEAD_CAP_M: f64 = 100.0;

/// Per history step (anchor first): x, y, cos and sin of the heading, speed, present.
const PER_STEP: usize = 6;
/// Length of [`PredictionSample::input`].
pub const INPUT_SIZE: usize = PER_STEP * (HISTORY_STEPS + 1) + 2 * LANE_STATIONS.len() + 1 + 3;

/// One example.
#[derive(Debug, Clone, PartialEq)]
pub struct PredictionSample {
    /// [`INPUT_SIZE`] features (see the module doc).
    pub input: Vec<f32>,
    /// Positions (m) at anchor + 1 ..= anchor + [`HORIZON_STEPS`], in the anchor's agent frame
    /// (x forward, y left).
    pub future: Vec<[f32; 2]>,
    /// Speed at the anchor (m/s): the constant-velocity prior the model predicts offsets from.
    pub speed: f32,
}

/// A pose in the frame of `origin` (centre x, y, heading).
fn to_frame(origin: [f64; 3], p: [f64; 2]) -> [f64; 2] {
    let (sin, cos) = origin[2].sin_cos();
    let (dx, dy) = (p[0] - origin[0], p[1] - origin[1]);
    [dx * cos + dy * sin, -dx * sin + dy * cos]
}

/// Every example of `scene`: each controlled agent at each anchor from the current step on
/// whose full horizon lies inside the window and is present throughout.
pub fn scene_samples(scene: &Scene) -> Vec<PredictionSample> {
    let steps = scene.steps();
    let mut out = Vec::new();
    for anchor in scene.current_step()..steps.saturating_sub(HORIZON_STEPS) {
        let views: Vec<AgentView> = (0..scene.agents.len())
            .map(|j| logged_view(scene, j, anchor))
            .collect();
        for (i, agent) in scene.agents.iter().enumerate() {
            let complete = (anchor..=anchor + HORIZON_STEPS).all(|t| agent.valid[t]);
            if agent.role == AgentRole::Controlled && complete {
                out.push(sample(scene, i, anchor, &views));
            }
        }
    }
    out
}

fn sample(scene: &Scene, i: usize, anchor: usize, views: &[AgentView]) -> PredictionSample {
    let agent = &scene.agents[i];
    let now = agent.states[anchor];
    let origin = [now.x, now.y, now.heading];
    let mut input = Vec::with_capacity(INPUT_SIZE);
    for k in 0..=HISTORY_STEPS {
        match anchor.checked_sub(k).filter(|&t| agent.valid[t]) {
            Some(t) => {
                let s = agent.states[t];
                let [x, y] = to_frame(origin, [s.x, s.y]);
                let h = s.heading - now.heading;
                input.extend([
                    x / POSITION_SCALE,
                    y / POSITION_SCALE,
                    h.cos(),
                    h.sin(),
                    s.speed / SPEED_SCALE,
                    1.0,
                ]);
            }
            None => input.extend([0.0; PER_STEP]),
        }
    }
    match scene.map.lane_projection([now.x, now.y], now.heading) {
        Some(p) => {
            let path = LanePath::new(
                &scene.map,
                p.lane,
                p.s,
                0.0,
                *LANE_STATIONS.last().unwrap_or(&0.0) + 10.0,
            );
            for station in LANE_STATIONS {
                let [x, y] = to_frame(origin, path.point_at(station, 0.0).xy);
                input.extend([x / POSITION_SCALE, y / POSITION_SCALE]);
            }
            input.push(1.0);
        }
        None => input.extend([0.0; 2 * LANE_STATIONS.len() + 1]),
    }
    match leader(i, views).filter(|&(_, gap)| gap < LEAD_CAP_M) {
        Some((j, gap)) => input.extend([
            gap / LEAD_CAP_M,
            (views[j].speed - now.speed) / SPEED_SCALE,
            1.0,
        ]),
        None => input.extend([1.0, 0.0, 0.0]),
    }
    let future = (anchor + 1..=anchor + HORIZON_STEPS)
        .map(|t| {
            let s = agent.states[t];
            to_frame(origin, [s.x, s.y]).map(|v| v as f32)
        })
        .collect();
    PredictionSample {
        input: input.into_iter().map(|v| v as f32).collect(),
        future,
        speed: now.speed as f32,
    }
}
