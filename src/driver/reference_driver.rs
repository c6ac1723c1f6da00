//! [`IdmDriver`]: the IDM + lane-keeping baseline. Every driven agent follows the lane it is
//! nearest to (pure pursuit) and keeps the speed it started with unless the IDM brakes it for
//! the vehicle ahead in its lane. It never changes lanes on its own, so it is a reference
//! driver for validating long-tail scenarios and a heuristic baseline for the learned policies.

use std::sync::Arc;

use burn::prelude::*;
use burn::tensor::TensorData;

use super::idm::{IdmParams, idm_accel};
use super::lane_keeping::{ControlCommand, look_ahead, pure_pursuit_steer};
use super::lane_path::LanePath;
use super::snapshot::{AgentView, Snapshot};
use crate::map::Map;
use crate::scene::Scene;
use crate::sim::{ActionLimits, Controls, Observation, Policy, WHEELBASE_RATIO};

/// How far ahead leaders are searched (m): beyond it the IDM interaction term is negligible
/// at motorway speeds (s* / s < 0.2 for s* < 30 m).
pub const LEADER_HORIZON_M: f64 = 150.0;
/// A vehicle counts as in my lane once its near edge is this far inside the lane (m).
const LANE_INTRUSION_M: f64 = 0.3;

/// The vehicle ahead in a lane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Leader {
    /// Index within the scene.
    pub index: usize,
    /// Bumper-to-bumper distance along the path (m).
    pub gap: f64,
    /// The leader's speed along the path (m/s).
    pub speed: f64,
}

/// The nearest vehicle of `agents` (other than `me`) ahead on `path` that intrudes into the
/// path's lane.
pub fn find_leader(path: &LanePath, me: usize, agents: &[AgentView]) -> Option<Leader> {
    let ego = &agents[me];
    let reach = path.end_station() + 10.0;
    let mut best: Option<Leader> = None;
    for (j, other) in agents.iter().enumerate() {
        if j == me || !other.present {
            continue;
        }
        let (dx, dy) = (other.x - ego.x, other.y - ego.y);
        if dx * dx + dy * dy > reach * reach {
            continue;
        }
        let Some((station, lateral)) = path.project([other.x, other.y]) else {
            continue;
        };
        if station <= 0.0 || lateral.abs() - 0.5 * other.width > path.half_width - LANE_INTRUSION_M
        {
            continue;
        }
        let gap = station - 0.5 * (ego.length + other.length);
        if best.is_none_or(|b| gap < b.gap) {
            let along = path.point_at(station, 0.0).heading;
            best = Some(Leader {
                index: j,
                gap,
                speed: other.speed * (other.heading - along).cos(),
            });
        }
    }
    best
}

/// Rear-axle position of a vehicle seen as a box (the simulator's axle rule).
pub(crate) fn rear_axle(agent: &AgentView) -> [f64; 2] {
    let half = 0.5 * WHEELBASE_RATIO * agent.length;
    let d = agent.direction();
    [agent.x - half * d[0], agent.y - half * d[1]]
}

/// Pure-pursuit steering towards `path` shifted `lateral` metres to the left.
pub fn steer_along(agent: &AgentView, path: &LanePath, lateral: f64) -> f64 {
    let target = path.point_at(look_ahead(agent.speed), lateral);
    pure_pursuit_steer(
        rear_axle(agent),
        agent.heading,
        WHEELBASE_RATIO * agent.length,
        target.xy,
    )
}

/// The IDM + lane-keeping command of agent `me` with desired speed `v0`.
pub fn idm_command(
    map: &Map,
    params: &IdmParams,
    agents: &[AgentView],
    me: usize,
    v0: f64,
) -> ControlCommand {
    let agent = &agents[me];
    let Some(projection) = map.lane_projection([agent.x, agent.y], agent.heading) else {
        return ControlCommand::default();
    };
    let path = LanePath::new(map, projection.lane, projection.s, 0.0, LEADER_HORIZON_M);
    let leader = find_leader(&path, me, agents);
    ControlCommand {
        accel: idm_accel(
            params,
            agent.speed,
            v0,
            leader.map(|l| (l.gap, agent.speed - l.speed)),
        ),
        steer: steer_along(agent, &path, 0.0),
    }
}

/// The baseline policy over a batch of scenes.
pub struct IdmDriver {
    maps: Vec<Arc<Map>>,
    pub params: IdmParams,
    pub limits: ActionLimits,
    /// Desired speed per agent (`[b * n + i]`), fixed at the first step.
    desired: Vec<f64>,
}

impl IdmDriver {
    pub fn new(scenes: &[&Scene], params: IdmParams, limits: ActionLimits) -> Self {
        Self {
            maps: scenes.iter().map(|s| s.map.clone()).collect(),
            params,
            limits,
            desired: Vec::new(),
        }
    }

    /// Commands for every agent of the snapshot (zero for absent ones).
    pub fn commands(&mut self, snapshot: &Snapshot) -> Vec<ControlCommand> {
        let n = snapshot.agents_per_scene;
        if self.desired.len() != snapshot.agents.len() {
            self.desired = snapshot
                .agents
                .iter()
                .enumerate()
                .map(|(k, a)| desired_speed(&self.maps[k / n.max(1)], a))
                .collect();
        }
        let mut out = vec![ControlCommand::default(); snapshot.agents.len()];
        for b in 0..snapshot.batch {
            let agents = snapshot.scene(b);
            for (i, agent) in agents.iter().enumerate() {
                if agent.present {
                    out[b * n + i] = idm_command(
                        &self.maps[b],
                        &self.params,
                        agents,
                        i,
                        self.desired[b * n + i],
                    );
                }
            }
        }
        out
    }
}

/// The speed an agent keeps on a free road: the one it has at the start, or the lane's
/// speed limit if it starts (nearly) stopped.
fn desired_speed(map: &Map, agent: &AgentView) -> f64 {
    if agent.speed > 5.0 {
        return agent.speed;
    }
    map.lane_projection([agent.x, agent.y], agent.heading)
        .map_or(25.0, |p| map.lanes()[p.lane].speed_limit)
}

/// Raw controls as `[B, N]` tensors.
pub fn to_controls(
    commands: &[ControlCommand],
    limits: &ActionLimits,
    shape: [usize; 2],
    device: &Device,
) -> Controls {
    let (accel, steer): (Vec<f32>, Vec<f32>) = commands
        .iter()
        .map(|c| {
            let (a, s) = c.raw(limits);
            (a as f32, s as f32)
        })
        .unzip();
    Controls {
        accel: Tensor::from_data(TensorData::new(accel, shape), device),
        steer: Tensor::from_data(TensorData::new(steer, shape), device),
    }
}

impl Policy for IdmDriver {
    fn act(&mut self, obs: &Observation) -> Controls {
        if obs.step == 0 {
            // A new rollout: desired speeds are those at its start.
            self.desired.clear();
        }
        let snapshot = Snapshot::from_observation(obs);
        let commands = self.commands(&snapshot);
        to_controls(
            &commands,
            &self.limits,
            [snapshot.batch, snapshot.agents_per_scene],
            &obs.batch.agent_size.device(),
        )
    }
}
