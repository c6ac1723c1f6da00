//! Scenes (one map plus the agents of a time window) and `SceneBatch`, their padded tensor
//! form.
//!
//! Tensor layout follows the design guide: agents `[batch, agents, time, feature]`, lane nodes
//! `[batch, lanes, feature]`; every padded axis travels with a bool mask, and graph edges are
//! fixed-width neighbour index tensors plus masks (indices are scene-local lane-node indices,
//! padded with 0 and masked out).

use std::sync::Arc;

use burn::prelude::*;
use burn::tensor::{Bool, Int, TensorData};

use crate::error::{Error, Result};
use crate::geometry::OrientedBox;
use crate::map::{LANE_NODE_FEATURES, LaneGraph, Map, neighbour_table};
use crate::vehicle::{AgentState, VehicleClass};

mod synthetic;
pub use synthetic::synthetic_scene;

/// Per-step agent features in `SceneBatch::agent_states`, in this order.
pub const AGENT_STATE_FEATURES: [&str; 5] = ["x", "y", "heading", "speed", "accel"];

/// What drives an agent in closed-loop simulation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AgentRole {
    /// Driven by the policy from the current step on; its logged future is the imitation
    /// target.
    Controlled,
    /// Replayed from the log while the log has it (vehicles that enter after the current
    /// step, or had no history to start from).
    Replayed,
    /// A long-tail scenario's scripted agent: simulated through the same dynamics, driven by
    /// its script instead of the policy, and left out of losses, rewards and metrics.
    Hero,
}

/// One vehicle of a scene, over every step of the window.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneAgent {
    /// Track index in the source recording (or scenario agent index).
    pub track_id: usize,
    pub class: VehicleClass,
    pub length: f64,
    pub width: f64,
    pub role: AgentRole,
    /// One state per step; zero where `valid` is false.
    pub states: Vec<AgentState>,
    pub valid: Vec<bool>,
}

impl SceneAgent {
    /// Footprint at `step`, if the agent is present then.
    pub fn footprint(&self, step: usize) -> Option<OrientedBox> {
        let s = self.states.get(step)?;
        self.valid[step].then(|| OrientedBox::new([s.x, s.y], s.heading, self.length, self.width))
    }
}

/// A time window: `history_steps` past steps, the current step, `future_steps` future steps,
/// spaced `dt` apart, on one map.
#[derive(Debug, Clone)]
pub struct Scene {
    pub id: String,
    /// Recording time of the current step (s); 0 for generated scenarios.
    pub t0: f64,
    pub dt: f64,
    pub history_steps: usize,
    pub future_steps: usize,
    pub map: Arc<Map>,
    pub lane_graph: Arc<LaneGraph>,
    /// Controlled agents first, then heroes, then replayed ones.
    pub agents: Vec<SceneAgent>,
}

impl Scene {
    /// Total number of steps in the window.
    pub fn steps(&self) -> usize {
        self.history_steps + 1 + self.future_steps
    }

    /// Index of the current step (where closed-loop control starts).
    pub fn current_step(&self) -> usize {
        self.history_steps
    }

    pub fn controlled_count(&self) -> usize {
        self.count(AgentRole::Controlled)
    }

    pub fn count(&self, role: AgentRole) -> usize {
        self.agents.iter().filter(|a| a.role == role).count()
    }
}

/// Fixed-width neighbour lists as tensors: `index[b, l, k]` is the k-th neighbour of lane node
/// `l` in scene `b`, valid where `mask[b, l, k]`. The same table stays on the host too: which
/// lane nodes a step needs is decided there ([`crate::model::LaneCrop`]).
#[derive(Debug, Clone)]
pub struct NeighbourTensors {
    pub index: Tensor<3, Int>,
    pub mask: Tensor<3, Bool>,
    pub host: Arc<HostNeighbours>,
}

/// [`NeighbourTensors`] on the host, row-major `[B, L, width]`.
#[derive(Debug, Clone, PartialEq)]
pub struct HostNeighbours {
    pub width: usize,
    pub index: Vec<i64>,
    pub mask: Vec<bool>,
}

impl HostNeighbours {
    /// The valid neighbours of lane node `node` in scene `scene` of a batch of `nodes` lane
    /// slots per scene.
    pub fn of(&self, scene: usize, nodes: usize, node: usize) -> impl Iterator<Item = usize> + '_ {
        let start = (scene * nodes + node) * self.width;
        (start..start + self.width)
            .filter(|&i| self.mask[i])
            .map(|i| self.index[i] as usize)
    }
}

/// Scenes padded into tensors on one device.
#[derive(Debug, Clone)]
pub struct SceneBatch {
    /// `[B, A, T, 5]`, features as [`AGENT_STATE_FEATURES`]; zero where invalid.
    pub agent_states: Tensor<4>,
    /// `[B, A, T]`: the agent is present at that step.
    pub agent_valid: Tensor<3, Bool>,
    /// `[B, A]`: a real agent (not padding).
    pub agent_mask: Tensor<2, Bool>,
    /// `[B, A]`: driven by the policy.
    pub agent_controlled: Tensor<2, Bool>,
    /// `[B, A]`: driven by a long-tail scenario's script.
    pub agent_hero: Tensor<2, Bool>,
    /// `[B, A, 2]`: length, width (m).
    pub agent_size: Tensor<3>,
    /// `[B, L, LANE_NODE_FEATURES]`: frame-free lane-node features.
    pub lane_features: Tensor<3>,
    /// `[B, L, 3]`: node centre x, y and heading (kept apart from the features so the model
    /// can encode poses relative to each other).
    pub lane_poses: Tensor<3>,
    /// `[B, L]`: a real lane node.
    pub lane_mask: Tensor<2, Bool>,
    pub lane_successors: NeighbourTensors,
    pub lane_predecessors: NeighbourTensors,
    pub lane_left: NeighbourTensors,
    pub lane_right: NeighbourTensors,
    pub dt: f64,
    pub history_steps: usize,
    pub future_steps: usize,
}

impl SceneBatch {
    /// Pads `scenes` (which must share `dt` and window lengths) into tensors on `device`.
    pub fn from_scenes(scenes: &[&Scene], device: &Device) -> Result<Self> {
        let first = scenes.first().ok_or_else(|| {
            Error::InvalidArgument("a scene batch needs at least one scene".into())
        })?;
        for s in scenes {
            if s.steps() != first.steps()
                || s.history_steps != first.history_steps
                || s.dt != first.dt
            {
                return Err(Error::InvalidArgument(format!(
                    "scene {} has window {}+1+{} steps at dt {} but scene {} has {}+1+{} at dt {}: \
                     a batch needs one window shape",
                    s.id,
                    s.history_steps,
                    s.future_steps,
                    s.dt,
                    first.id,
                    first.history_steps,
                    first.future_steps,
                    first.dt
                )));
            }
        }
        let b = scenes.len();
        let t = first.steps();
        let a = scenes
            .iter()
            .map(|s| s.agents.len())
            .max()
            .unwrap_or(0)
            .max(1);
        let l = scenes
            .iter()
            .map(|s| s.lane_graph.nodes.len())
            .max()
            .unwrap_or(0)
            .max(1);
        let nf = AGENT_STATE_FEATURES.len();

        let mut states = vec![0f32; b * a * t * nf];
        let mut valid = vec![false; b * a * t];
        let mut agent_mask = vec![false; b * a];
        let mut controlled = vec![false; b * a];
        let mut hero = vec![false; b * a];
        let mut size = vec![0f32; b * a * 2];
        let mut lane_features = vec![0f32; b * l * LANE_NODE_FEATURES];
        let mut lane_poses = vec![0f32; b * l * 3];
        let mut lane_mask = vec![false; b * l];

        for (bi, scene) in scenes.iter().enumerate() {
            for (ai, agent) in scene.agents.iter().enumerate() {
                let slot = bi * a + ai;
                agent_mask[slot] = true;
                controlled[slot] = agent.role == AgentRole::Controlled;
                hero[slot] = agent.role == AgentRole::Hero;
                size[slot * 2] = agent.length as f32;
                size[slot * 2 + 1] = agent.width as f32;
                for (ti, (st, &ok)) in agent.states.iter().zip(&agent.valid).enumerate() {
                    if !ok {
                        continue;
                    }
                    valid[slot * t + ti] = true;
                    let o = (slot * t + ti) * nf;
                    states[o..o + nf].copy_from_slice(&[
                        st.x as f32,
                        st.y as f32,
                        st.heading as f32,
                        st.speed as f32,
                        st.accel as f32,
                    ]);
                }
            }
            for (ni, node) in scene.lane_graph.nodes.iter().enumerate() {
                let slot = bi * l + ni;
                lane_mask[slot] = true;
                lane_features[slot * LANE_NODE_FEATURES..(slot + 1) * LANE_NODE_FEATURES]
                    .copy_from_slice(&node.features());
                lane_poses[slot * 3..slot * 3 + 3].copy_from_slice(&[
                    node.center[0] as f32,
                    node.center[1] as f32,
                    node.heading as f32,
                ]);
            }
        }

        let graphs: Vec<&LaneGraph> = scenes.iter().map(|s| s.lane_graph.as_ref()).collect();
        Ok(Self {
            agent_states: Tensor::from_data(TensorData::new(states, [b, a, t, nf]), device),
            agent_valid: Tensor::from_data(TensorData::new(valid, [b, a, t]), device),
            agent_mask: Tensor::from_data(TensorData::new(agent_mask, [b, a]), device),
            agent_controlled: Tensor::from_data(TensorData::new(controlled, [b, a]), device),
            agent_hero: Tensor::from_data(TensorData::new(hero, [b, a]), device),
            agent_size: Tensor::from_data(TensorData::new(size, [b, a, 2]), device),
            lane_features: Tensor::from_data(
                TensorData::new(lane_features, [b, l, LANE_NODE_FEATURES]),
                device,
            ),
            lane_poses: Tensor::from_data(TensorData::new(lane_poses, [b, l, 3]), device),
            lane_mask: Tensor::from_data(TensorData::new(lane_mask, [b, l]), device),
            lane_successors: pad_neighbours(&graphs, l, |g| &g.successors, device),
            lane_predecessors: pad_neighbours(&graphs, l, |g| &g.predecessors, device),
            lane_left: pad_neighbours(&graphs, l, |g| &g.left, device),
            lane_right: pad_neighbours(&graphs, l, |g| &g.right, device),
            dt: first.dt,
            history_steps: first.history_steps,
            future_steps: first.future_steps,
        })
    }

    pub fn batch_size(&self) -> usize {
        self.agent_mask.dims()[0]
    }

    pub fn max_agents(&self) -> usize {
        self.agent_mask.dims()[1]
    }

    pub fn max_lane_nodes(&self) -> usize {
        self.lane_mask.dims()[1]
    }

    /// The lane relations on the host, in [`crate::model::LaneInput::relations`]' order.
    pub fn lane_relations_host(&self) -> [&HostNeighbours; 4] {
        [
            &self.lane_successors.host,
            &self.lane_predecessors.host,
            &self.lane_left.host,
            &self.lane_right.host,
        ]
    }
}

/// Pads one relation of every scene's lane graph to a common `[B, L, K]` table.
fn pad_neighbours(
    graphs: &[&LaneGraph],
    l: usize,
    relation: impl Fn(&LaneGraph) -> &Vec<Vec<usize>>,
    device: &Device,
) -> NeighbourTensors {
    let tables: Vec<_> = graphs
        .iter()
        .map(|g| neighbour_table(relation(g)))
        .collect();
    let k = tables.iter().map(|t| t.width).max().unwrap_or(1).max(1);
    let b = graphs.len();
    let mut index = vec![0i64; b * l * k];
    let mut mask = vec![false; b * l * k];
    for (bi, table) in tables.iter().enumerate() {
        let nodes = table.mask.len() / table.width.max(1);
        for ni in 0..nodes {
            for ki in 0..table.width {
                let src = ni * table.width + ki;
                let dst = (bi * l + ni) * k + ki;
                index[dst] = table.index[src];
                mask[dst] = table.mask[src];
            }
        }
    }
    NeighbourTensors {
        index: Tensor::from_data(TensorData::new(index.clone(), [b, l, k]), device),
        mask: Tensor::from_data(TensorData::new(mask.clone(), [b, l, k]), device),
        host: Arc::new(HostNeighbours {
            width: k,
            index,
            mask,
        }),
    }
}
