//! Interaction module (paper appendix, GoRela's HeteroGNN): agent nodes join the lane graph;
//! each agent receives from its closest lane nodes, each lane node from its closest agents
//! within a radius, agents are fully connected to each other, and the lane-lane edges stay.
//! Every edge type has its own message weights, and messages carry the sender's pose in the
//! receiver's frame. Several synchronous rounds give the fused feature h_i of every agent.
//!
//! Edges are chosen on detached positions (the choice is discrete); the relative poses along
//! them stay differentiable, so imitation gradients reach the simulated positions.

use burn::module::Module;
use burn::prelude::*;
use burn::tensor::{Bool, Int};

use super::aggregate::gather_neighbours;
use super::config::ModelConfig;
use super::input::LaneInput;
use super::lane_crop::{CropInputs, CropScope, LaneCrop};
use super::lane_encoder::{LANE_RELATIONS, lane_messages};
use super::message::{EdgeMessage, NodeUpdate};
use super::relative_motion::relative_motion;
use super::relative_pose::relative_pose;
use crate::scene::HostNeighbours;

/// Distance given to padded or absent nodes so nearest-neighbour choices rank them last.
const FAR: f64 = 1e9;

/// The agent-side edges of one forward pass.
#[derive(Debug, Clone)]
pub struct InteractionEdges {
    /// Agent <- agent, dense: `[B, N, N, P]` pose (and relative motion with
    /// `agent_edge_motion`) and `[B, N, N]` mask (no self edges).
    agent_agent_pose: Tensor<4>,
    agent_agent_mask: Tensor<3, Bool>,
    /// Agent <- its closest lane nodes: `[B, N, K]` (node indices of the whole graph).
    agent_lane_index: Tensor<3, Int>,
    agent_lane_pose: Tensor<4>,
    agent_lane_mask: Tensor<3, Bool>,
    /// The lane nodes the lane rounds update (`None` without lane rounds), and each of those
    /// nodes' closest agents within the radius: `[1, M, K]` over the crop's flat node list
    /// (agent index scene x N + agent), or `[B, L, K]` without a crop.
    crop: Option<LaneCrop>,
    lane_agent_index: Tensor<3, Int>,
    lane_agent_pose: Tensor<4>,
    lane_agent_mask: Tensor<3, Bool>,
}

/// `[B, R, K]` bool: `mask` (`[B, M]`) of the gathered senders.
fn gather_mask(mask: Tensor<2, Bool>, index: Tensor<3, Int>) -> Tensor<3, Bool> {
    let [b, m] = mask.dims();
    let [_, r, k] = index.dims();
    gather_neighbours(mask.float().reshape([b, m, 1]), index)
        .reshape([b, r, k])
        .greater_elem(0.5)
}

/// Each receiver's `k` nearest senders: `[B, R, k]` index, relative pose, sender mask and
/// distance.
struct Nearest {
    index: Tensor<3, Int>,
    pose: Tensor<4>,
    mask: Tensor<3, Bool>,
    distance: Tensor<3>,
}

impl Nearest {
    /// `distance` is `[B, R, S]` (senders to skip pushed to `FAR`); `k` is capped at S.
    fn pick(
        distance: Tensor<3>,
        k: usize,
        receiver_pose: &Tensor<3>,
        sender_pose: &Tensor<3>,
        sender_mask: &Tensor<2, Bool>,
        wavelengths: &[f64],
    ) -> Self {
        let [b, r, s] = distance.dims();
        let k = k.min(s);
        let (negated, index) = distance.neg().topk_with_indices(k, 2);
        let pose = relative_pose(
            receiver_pose
                .clone()
                .unsqueeze_dim::<4>(2)
                .expand([b, r, k, 3]),
            gather_neighbours(sender_pose.clone(), index.clone()),
            wavelengths,
        );
        Self {
            mask: gather_mask(sender_mask.clone(), index.clone()),
            index,
            pose,
            distance: negated.neg(),
        }
    }
}

impl InteractionEdges {
    /// The edges of agents in `agent_state` / `agent_mask` (`[B, N, 4]`: x, y, heading, speed /
    /// `[B, N]`) on the lane graph at `lane_pose` / `lane_mask` (`[B, L, 3]` / `[B, L]`) whose
    /// relations are `lane_relations` ([`LaneInput::relations`]' order). The lane rounds will
    /// update the nodes `scope` names (see [`super::lane_crop`]; `CropScope::Hops` with
    /// [`needed_lane_hops`] is exact).
    pub fn build(
        agent_state: &Tensor<3>,
        agent_mask: &Tensor<2, Bool>,
        lane_pose: &Tensor<3>,
        lane_mask: &Tensor<2, Bool>,
        lane_relations: &[&HostNeighbours],
        scope: CropScope,
        config: &ModelConfig,
    ) -> Self {
        let agent_pose = &agent_state.clone().narrow(2, 0, 3);
        let [b, n, _] = agent_pose.dims();
        let l = lane_mask.dims()[1];
        let wavelengths = &config.distance_wavelengths;
        let device = agent_pose.device();

        // A [B, M] mask repeated along a new axis `dim` to `shape`.
        let spread = |mask: &Tensor<2, Bool>, dim: usize, shape: [usize; 3]| {
            mask.clone().unsqueeze_dim::<3>(dim).expand(shape)
        };

        // Agent <- agent: receivers along dim 2 against senders along dim 1.
        let pairs = |states: &Tensor<3>, dim: usize| {
            let [_, _, c] = states.dims();
            states.clone().unsqueeze_dim::<4>(dim).expand([b, n, n, c])
        };
        let mut agent_agent_pose =
            relative_pose(pairs(agent_pose, 2), pairs(agent_pose, 1), wavelengths);
        if config.agent_edge_motion {
            let motion = relative_motion(pairs(agent_state, 2), pairs(agent_state, 1))
                .mul_scalar(config.agent_edge_motion_gain);
            agent_agent_pose = Tensor::cat(vec![agent_agent_pose, motion], 3);
        }
        let not_self = Tensor::<2, Int>::eye(n, &device)
            .equal_elem(0)
            .unsqueeze_dim::<3>(0)
            .expand([b, n, n]);
        let agent_agent_mask = spread(agent_mask, 2, [b, n, n])
            .bool_and(spread(agent_mask, 1, [b, n, n]))
            .bool_and(not_self);

        // Distances agent x lane node on detached positions (choosing edges is discrete).
        let xy = |pose: &Tensor<3>| pose.clone().detach().narrow(2, 0, 2);
        let (a_xy, l_xy) = (xy(agent_pose), xy(lane_pose));
        let diff = a_xy.unsqueeze_dim::<4>(2).expand([b, n, l, 2])
            - l_xy.unsqueeze_dim::<4>(1).expand([b, n, l, 2]);
        let distance = diff.powi_scalar(2).sum_dim(3).reshape([b, n, l]).sqrt();
        let lane_absent = spread(&lane_mask.clone().bool_not(), 1, [b, n, l]);
        let agent_absent = spread(&agent_mask.clone().bool_not(), 2, [b, n, l]);

        // Agent <- its closest lane nodes.
        let agent_lane = Nearest::pick(
            distance.clone().mask_fill(lane_absent, FAR),
            config.agent_lane_edges,
            agent_pose,
            lane_pose,
            lane_mask,
            wavelengths,
        );
        // Lane node <- its closest agents within the radius.
        let lane_agent = Nearest::pick(
            distance.mask_fill(agent_absent, FAR).swap_dims(1, 2),
            config.lane_agent_edges,
            lane_pose,
            agent_pose,
            agent_mask,
            wavelengths,
        );
        let lane_agent_mask = lane_agent
            .distance
            .lower_equal_elem(config.lane_agent_radius)
            .bool_and(lane_agent.mask);
        let crop = (config.interaction_rounds >= 2).then(|| {
            LaneCrop::build(
                &CropInputs {
                    agent_lane_index: &host_indices(&agent_lane.index),
                    agent_lane_mask: &host_flags(agent_lane.mask.clone()),
                    agent_mask: &host_flags(agent_mask.clone().unsqueeze_dim::<3>(2)),
                    shape: agent_lane.index.dims(),
                    lane_nodes: l,
                    relations: lane_relations,
                    scope,
                },
                &device,
            )
        });
        // The cropped nodes' agent edges point into the batch's agents as one flat list.
        let (lane_agent_index, lane_agent_pose, lane_agent_mask) = match &crop {
            Some(crop) => {
                let offset = Tensor::<1, Int>::arange(0..b as i64, &device)
                    .mul_scalar(n as i64)
                    .reshape([b, 1, 1]);
                (
                    crop.rows_int(lane_agent.index + offset),
                    crop.rows(lane_agent.pose),
                    crop.rows_bool(lane_agent_mask),
                )
            }
            None => (lane_agent.index, lane_agent.pose, lane_agent_mask),
        };

        Self {
            agent_agent_pose,
            agent_agent_mask,
            agent_lane_index: agent_lane.index,
            agent_lane_pose: agent_lane.pose,
            agent_lane_mask: agent_lane.mask,
            crop,
            lane_agent_index,
            lane_agent_pose,
            lane_agent_mask,
        }
    }

    /// Lane nodes the lane rounds update, over the whole batch.
    pub fn lane_round_nodes(&self) -> usize {
        self.lane_agent_index.dims()[1]
    }
}

/// The lane hops beyond the agents' nearest nodes that `config`'s lane rounds must update.
pub fn needed_lane_hops(config: &ModelConfig) -> usize {
    config.interaction_rounds.saturating_sub(2)
}

fn host_indices(t: &Tensor<3, Int>) -> Vec<i64> {
    t.clone()
        .into_data()
        .convert::<i64>()
        .try_into_vec::<i64>()
        .expect("integer node indices")
}

fn host_flags(t: Tensor<3, Bool>) -> Vec<bool> {
    t.into_data()
        .try_into_vec_as::<bool>()
        .expect("boolean masks")
}

/// One round's update of the agent nodes.
#[derive(Module, Debug)]
struct AgentRound {
    from_agents: EdgeMessage,
    from_lanes: EdgeMessage,
    update: NodeUpdate,
}

/// One round's update of the lane nodes (lane-lane edges per relation, and agents).
#[derive(Module, Debug)]
struct LaneRound {
    from_lanes: Vec<EdgeMessage>,
    from_agents: EdgeMessage,
    update: NodeUpdate,
}

impl AgentRound {
    /// `from_lanes`: this round's aggregated lane messages, `[B, N, C]`.
    fn forward(
        &self,
        agents: Tensor<3>,
        from_lanes: Tensor<3>,
        edges: &InteractionEdges,
    ) -> Tensor<3> {
        let messages = self.from_agents.aggregate_dense(
            agents.clone(),
            edges.agent_agent_pose.clone(),
            edges.agent_agent_mask.clone(),
        ) + from_lanes;
        self.update.forward(agents, messages)
    }

    /// Messages from the lane encoding of the whole graph `[B, L, C]` (`projected`: already
    /// through the sender weights).
    fn whole_graph_messages(&self, projected: Tensor<3>, edges: &InteractionEdges) -> Tensor<3> {
        self.from_lanes.aggregate_projected(
            projected,
            edges.agent_lane_index.clone(),
            edges.agent_lane_pose.clone(),
            edges.agent_lane_mask.clone(),
        )
    }

    /// Messages from the cropped lane nodes `[1, M, C]`.
    fn crop_messages(
        &self,
        lanes: Tensor<3>,
        crop: &LaneCrop,
        edges: &InteractionEdges,
    ) -> Tensor<3> {
        let [b, n, k, p] = edges.agent_lane_pose.dims();
        let messages = self.from_lanes.aggregate_projected(
            self.from_lanes.project(lanes),
            crop.agent_lane_index(),
            edges.agent_lane_pose.clone().reshape([1, b * n, k, p]),
            edges.agent_lane_mask.clone().reshape([1, b * n, k]),
        );
        let c = messages.dims()[2];
        messages.reshape([b, n, c])
    }
}

impl LaneRound {
    /// The cropped nodes `lanes` (`[1, M, C]`) updated from `lane_lane` (their lane-lane
    /// messages) and the batch's agents.
    fn forward(
        &self,
        agents: Tensor<3>,
        lanes: Tensor<3>,
        lane_lane: Tensor<3>,
        edges: &InteractionEdges,
    ) -> Tensor<3> {
        let [b, n, c] = agents.dims();
        let messages = lane_lane
            + self.from_agents.aggregate(
                agents.reshape([1, b * n, c]),
                edges.lane_agent_index.clone(),
                edges.lane_agent_pose.clone(),
                edges.lane_agent_mask.clone(),
            );
        self.update.forward(lanes, messages)
    }
}

/// What the first round computes from the encoded lane graph alone. The map is static, so a
/// rollout computes it once with h_m instead of at every step; the forward is unchanged.
#[derive(Debug, Clone)]
pub struct StaticLaneTerms {
    /// The first agent round's sender projection of h_m, `[B, L, C]`.
    agent_round_lanes: Tensor<3>,
    /// The first lane round's summed lane -> lane messages, `[B, L, C]` (none with one round).
    lane_round_lanes: Option<Tensor<3>>,
}

/// Synchronous rounds: round r updates agents and lane nodes from both sets' round r - 1
/// features. The last round updates agents only (updated lane nodes would reach no agent), so
/// there is one lane round fewer and every parameter gets a gradient.
#[derive(Module, Debug)]
pub struct HeteroGnn {
    agent_rounds: Vec<AgentRound>,
    lane_rounds: Vec<LaneRound>,
}

impl HeteroGnn {
    /// `pose_features`: width of every edge's relative pose; `agent_edge_features`: of the
    /// agent <- agent edges' (the pose, with relative motion when configured).
    pub fn new(
        hidden: usize,
        rounds: usize,
        pose_features: usize,
        agent_edge_features: usize,
        device: &Device,
    ) -> Self {
        let message = || EdgeMessage::new(hidden, pose_features, device);
        Self {
            agent_rounds: (0..rounds)
                .map(|_| AgentRound {
                    from_agents: EdgeMessage::new(hidden, agent_edge_features, device),
                    from_lanes: message(),
                    update: NodeUpdate::new(hidden, device),
                })
                .collect(),
            lane_rounds: (1..rounds)
                .map(|_| LaneRound {
                    from_lanes: (0..LANE_RELATIONS).map(|_| message()).collect(),
                    from_agents: message(),
                    update: NodeUpdate::new(hidden, device),
                })
                .collect(),
        }
    }

    /// The same layers with `extra` more agent <- agent edge inputs (see
    /// [`EdgeMessage::with_extra_pose_inputs`]).
    pub fn with_extra_agent_edge_inputs(
        self,
        extra: usize,
        rng: &mut impl rand::Rng,
        scale: f32,
    ) -> Self {
        Self {
            agent_rounds: self
                .agent_rounds
                .into_iter()
                .map(|round| AgentRound {
                    from_agents: round.from_agents.with_extra_pose_inputs(extra, rng, scale),
                    ..round
                })
                .collect(),
            ..self
        }
    }

    /// The agent <- agent edge-input weights of every round (tests inspect their gradient).
    #[cfg(test)]
    pub fn agent_edge_weights(&self) -> Vec<&burn::module::Param<Tensor<2>>> {
        self.agent_rounds
            .iter()
            .map(|round| round.from_agents.pose_weight())
            .collect()
    }

    /// The first round's terms that depend on the lane features `lanes` (h_m) only; `None`
    /// without rounds.
    pub fn static_lane_terms(
        &self,
        lanes: Tensor<3>,
        lane_input: &LaneInput,
    ) -> Option<StaticLaneTerms> {
        let first = self.agent_rounds.first()?;
        Some(StaticLaneTerms {
            agent_round_lanes: first.from_lanes.project(lanes.clone()),
            lane_round_lanes: self
                .lane_rounds
                .first()
                .map(|round| lane_messages(&round.from_lanes, lanes, &lane_input.relations)),
        })
    }

    /// Agent features `[B, N, C]` and lane features `[B, L, C]` -> fused agent features
    /// `[B, N, C]` (the agents' input features when there are no rounds). `cached` must come
    /// from [`Self::static_lane_terms`] of the same `lanes` and parameters. The lane rounds
    /// update only the nodes of `edges`' crop (see [`super::lane_crop`]).
    pub fn forward(
        &self,
        agents: Tensor<3>,
        lanes: Tensor<3>,
        lane_input: &LaneInput,
        edges: &InteractionEdges,
        cached: Option<&StaticLaneTerms>,
    ) -> Tensor<3> {
        let crop = edges.crop.as_ref();
        // The crop's lane relations, for the lane rounds after the first.
        let cropped_relations = crop
            .filter(|_| self.lane_rounds.len() > 1)
            .map(|crop| crop.relations(&lane_input.relations));
        let mut a = agents;
        // The cropped nodes' features after the last lane round, `[1, M, C]`.
        let mut m: Option<Tensor<3>> = None;
        for (r, agent_round) in self.agent_rounds.iter().enumerate() {
            let from_lanes = match &m {
                // The first round reads the lane encoding itself, of the whole graph.
                None => agent_round.whole_graph_messages(
                    match cached {
                        Some(c) => c.agent_round_lanes.clone(),
                        None => agent_round.from_lanes.project(lanes.clone()),
                    },
                    edges,
                ),
                Some(m) => agent_round.crop_messages(
                    m.clone(),
                    crop.expect("lane rounds come with a crop"),
                    edges,
                ),
            };
            let next_a = agent_round.forward(a.clone(), from_lanes, edges);
            if let Some(lane_round) = self.lane_rounds.get(r) {
                let crop = crop.expect("edges built for this network's rounds");
                let (nodes, lane_lane) = match m.take() {
                    None => {
                        let whole = match cached.and_then(|c| c.lane_round_lanes.clone()) {
                            Some(messages) => messages,
                            None => lane_messages(
                                &lane_round.from_lanes,
                                lanes.clone(),
                                &lane_input.relations,
                            ),
                        };
                        (crop.rows(lanes.clone()), crop.rows(whole))
                    }
                    Some(m) => {
                        let relations = cropped_relations.as_ref().expect("built above");
                        let messages = lane_messages(&lane_round.from_lanes, m.clone(), relations);
                        (m, messages)
                    }
                };
                m = Some(lane_round.forward(a, nodes, lane_lane, edges));
            }
            a = next_a;
        }
        a
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::{Distribution, Tolerance};

    use crate::model::relative_motion::RELATIVE_MOTION_FEATURES;

    /// The gain multiplies the relative-motion columns of the agent <- agent edges and nothing
    /// else.
    #[test]
    fn motion_gain_scales_only_the_motion_inputs() {
        let device = crate::backend::Backend::reference_device(false);
        let (b, n, l) = (2, 4, 6);
        let agents = Tensor::<3>::random([b, n, 4], Distribution::Uniform(-20.0, 20.0), &device);
        let lanes = Tensor::<3>::random([b, l, 3], Distribution::Uniform(-20.0, 20.0), &device);
        let agent_mask = Tensor::<2>::ones([b, n], &device).greater_elem(0.5);
        let lane_mask = Tensor::<2>::ones([b, l], &device).greater_elem(0.5);
        let edges = |gain: f64| {
            let config = ModelConfig {
                agent_edge_motion: true,
                agent_edge_motion_gain: gain,
                ..ModelConfig::small()
            };
            let unlinked = HostNeighbours {
                width: 1,
                index: vec![0; b * l],
                mask: vec![false; b * l],
            };
            InteractionEdges::build(
                &agents,
                &agent_mask,
                &lanes,
                &lane_mask,
                &[&unlinked; 4],
                CropScope::Hops(needed_lane_hops(&config)),
                &config,
            )
            .agent_agent_pose
        };
        let (unit, tenfold) = (edges(1.0), edges(10.0));
        let width = unit.dims()[3];
        let pose = width - RELATIVE_MOTION_FEATURES;
        let split = |t: &Tensor<4>| {
            (
                t.clone().narrow(3, 0, pose),
                t.clone().narrow(3, pose, RELATIVE_MOTION_FEATURES),
            )
        };
        let ((pose_1, motion_1), (pose_10, motion_10)) = (split(&unit), split(&tenfold));
        pose_10
            .into_data()
            .assert_approx_eq::<f32>(&pose_1.into_data(), Tolerance::absolute(1e-6));
        motion_10.into_data().assert_approx_eq::<f32>(
            &motion_1.clone().mul_scalar(10.0).into_data(),
            Tolerance::absolute(1e-4),
        );
        assert!(
            motion_1.abs().max().into_scalar::<f32>() > 0.01,
            "random agents move relative to each other"
        );
    }
}
