//! What the networks see, built from a [`SceneBatch`] and the frames of a rollout. Nothing here
//! depends on the global frame except the poses kept apart for relative encodings
//! ([`AgentInput::pose`], [`LaneInput::pose`]), which the networks only ever use in pairs.

use burn::prelude::*;
use burn::tensor::{Bool, Int, TensorData};

use super::agent_rows::{AgentPacking, AgentRows};
use super::config::ModelConfig;
use super::interaction::{InteractionEdges, needed_lane_hops};
use super::lane_crop::CropScope;
use super::relative_pose::{relative_pose, relative_pose_features};
use super::steer_feedforward::lane_steer_feedforward;
use crate::map::LANE_NODE_FEATURES;
use crate::scene::{NeighbourTensors, SceneBatch};
use crate::sim::Frame;

/// Multipliers bringing lane-node features to order one: length / 10 m, width / 3.5 m,
/// curvature x [`ModelConfig::lane_curvature_scale`] (the placeholder here is replaced), speed
/// limit / 30 m/s; the mark one-hots stay as they are.
const LANE_FEATURE_SCALE: [f32; LANE_NODE_FEATURES] = [
    0.1,
    1.0 / 3.5,
    f32::NAN,
    1.0 / 30.0,
    1.0,
    1.0,
    1.0,
    1.0,
    1.0,
    1.0,
    1.0,
    1.0,
];

/// Index of the curvature in [`crate::map::LaneNode::features`].
const CURVATURE_FEATURE: usize = 2;
/// Index of the speed limit in [`crate::map::LaneNode::features`].
const SPEED_LIMIT_FEATURE: usize = 3;

/// Speed (m/s) to network units.
const SPEED_SCALE: f64 = 0.1;
/// Box length and width (m) to network units.
const SIZE_SCALE: [f64; 2] = [0.2, 0.5];

/// Per-step width of [`AgentInput::history`]: relative pose, speed, valid flag, length, width.
pub fn history_features(config: &ModelConfig) -> usize {
    relative_pose_features(config.distance_wavelengths.len()) + 4
}

/// The agents at the current step.
#[derive(Debug, Clone)]
pub struct AgentInput {
    /// `[B, N', H, F]` in `rows`' packed layout: for each of the last H frames (oldest first,
    /// the current one last), the agent's pose then seen from its current pose, its speed, a
    /// present flag, and its box size; zeros (but the size) where it was not present.
    pub history: Tensor<4>,
    /// `[B, N, 3]`: box centre x, y and heading now.
    pub pose: Tensor<3>,
    /// `[B, N]`: a real agent, on the road now.
    pub mask: Tensor<2, Bool>,
    /// `[B, N]`: the steering (rad) that follows each agent's lane, added to the policy's
    /// steering mean; `None` unless `ModelConfig::lane_steer_feedforward`.
    pub steer_feedforward: Option<Tensor<2>>,
    /// The HeteroGNN's agent-side edges on the batch's lane graph, between `rows`' packed
    /// agents: built here once, so the policy and the value network share them, and stored
    /// observations (PPO) keep them.
    pub edges: InteractionEdges,
    /// Which of the `[B, N]` slots the networks compute (the agents in `mask`), packed.
    pub rows: AgentPacking,
}

impl AgentInput {
    /// From the last `config.history_steps` of `frames` (fewer frames: the missing early ones
    /// count as absent).
    ///
    /// # Panics
    /// If `frames` is empty; [`crate::sim::logged_frames`] and the rollout always hold the
    /// current frame.
    pub fn from_frames(batch: &SceneBatch, frames: &[Frame], config: &ModelConfig) -> Self {
        let scope = CropScope::Hops(needed_lane_hops(config));
        Self::with_lane_scope(batch, frames, config, scope)
    }

    /// [`Self::from_frames`] with the lane rounds updating the nodes `scope` names
    /// (`CropScope::WholeGraph`: the uncropped computation, the same outputs).
    pub fn with_lane_scope(
        batch: &SceneBatch,
        frames: &[Frame],
        config: &ModelConfig,
        scope: CropScope,
    ) -> Self {
        Self::with_scope(batch, frames, config, scope, AgentRows::Present)
    }

    /// [`Self::with_lane_scope`] computing the agent `rows` named (`AgentRows::All`: every
    /// padded slot, the same outputs).
    pub fn with_scope(
        batch: &SceneBatch,
        frames: &[Frame],
        config: &ModelConfig,
        scope: CropScope,
        rows: AgentRows,
    ) -> Self {
        let h = config.history_steps;
        let now = frames
            .last()
            .expect("a rollout always has the current frame");
        let [b, n, _] = now.poses.dims();
        let device = now.poses.device();
        let recent = &frames[frames.len().saturating_sub(h)..];
        let missing = h - recent.len();
        let mut poses: Vec<Tensor<3>> = Vec::with_capacity(h);
        let mut present: Vec<Tensor<2, Bool>> = Vec::with_capacity(h);
        for _ in 0..missing {
            poses.push(Tensor::zeros([b, n, 4], &device));
            present.push(Tensor::<2>::zeros([b, n], &device).greater_elem(0.0));
        }
        for frame in recent {
            poses.push(frame.poses.clone());
            present.push(frame.present.clone());
        }
        let past = Tensor::stack::<4>(poses, 2);
        let present = Tensor::stack::<3>(present, 2);
        let pose_now = now.poses.clone().narrow(2, 0, 3);
        let receiver = pose_now.clone().unsqueeze_dim::<4>(2).expand([b, n, h, 3]);
        let relative = relative_pose(
            receiver,
            past.clone().narrow(3, 0, 3),
            &config.distance_wavelengths,
        );
        let speed = past.narrow(3, 3, 1).mul_scalar(SPEED_SCALE);
        let absent = present.clone().bool_not().unsqueeze_dim::<4>(3);
        let motion = Tensor::cat(vec![relative, speed], 3).mask_fill(absent, 0.0);
        let valid = present.float().unsqueeze_dim::<4>(3);
        let size = scaled_size(batch)
            .unsqueeze_dim::<4>(2)
            .expand([b, n, h, 2]);
        let mask = batch.agent_mask.clone().bool_and(now.present.clone());
        let rows = AgentPacking::new(&mask, rows);
        let edges = InteractionEdges::build(
            &rows.pack(now.poses.clone()),
            rows.mask(),
            &batch.lane_poses,
            &batch.lane_mask,
            &batch.lane_relations_host(),
            scope,
            config,
        );
        let steer_feedforward = config.lane_steer_feedforward.then(|| {
            lane_steer_feedforward(
                &now.poses,
                &batch.agent_size.clone().narrow(2, 0, 1).reshape([b, n]),
                &batch.lane_poses,
                &batch
                    .lane_features
                    .clone()
                    .narrow(2, CURVATURE_FEATURE, 1)
                    .squeeze_dim::<2>(2),
                &batch.lane_mask,
            )
            .mask_fill(mask.clone().bool_not(), 0.0)
        });
        Self {
            history: rows.pack(Tensor::cat(vec![motion, valid, size], 3)),
            pose: pose_now,
            mask,
            steer_feedforward,
            edges,
            rows,
        }
    }

    pub fn agents(&self) -> usize {
        self.mask.dims()[1]
    }
}

fn scaled_size(batch: &SceneBatch) -> Tensor<3> {
    let device = batch.agent_size.device();
    let scale = Tensor::<1>::from_data(
        TensorData::new(SIZE_SCALE.map(|s| s as f32).to_vec(), [2]),
        &device,
    );
    batch.agent_size.clone() * scale.reshape([1, 1, 2])
}

/// One lane-graph relation (successor, predecessor, left or right) with the relative pose of
/// every neighbour seen from its receiver.
#[derive(Debug, Clone)]
pub struct LaneRelation {
    /// `[B, L, K]` neighbour indices and their mask.
    pub index: Tensor<3, Int>,
    pub mask: Tensor<3, Bool>,
    /// `[B, L, K, P]`.
    pub pose: Tensor<4>,
}

/// The lane graph: static over a rollout, so it is built (and encoded) once.
#[derive(Debug, Clone)]
pub struct LaneInput {
    /// `[B, L, LANE_NODE_FEATURES]`, scaled to order one.
    pub features: Tensor<3>,
    /// `[B, L, 3]`: node centre x, y and heading.
    pub pose: Tensor<3>,
    /// `[B, L]`: a real lane node.
    pub mask: Tensor<2, Bool>,
    /// Successors, predecessors, left and right neighbours, in that order.
    pub relations: Vec<LaneRelation>,
}

impl LaneInput {
    pub fn from_batch(batch: &SceneBatch, config: &ModelConfig) -> Self {
        let device = batch.lane_features.device();
        let mut scales = LANE_FEATURE_SCALE;
        scales[CURVATURE_FEATURE] = config.lane_curvature_scale as f32;
        if !config.lane_speed_limit_input {
            scales[SPEED_LIMIT_FEATURE] = 0.0;
        }
        let scale = Tensor::<1>::from_data(
            TensorData::new(scales.to_vec(), [LANE_NODE_FEATURES]),
            &device,
        )
        .reshape([1, 1, LANE_NODE_FEATURES]);
        let relation = |table: &NeighbourTensors| {
            let [b, l, k] = table.index.dims();
            let receiver = batch
                .lane_poses
                .clone()
                .unsqueeze_dim::<4>(2)
                .expand([b, l, k, 3]);
            let sender =
                super::aggregate::gather_neighbours(batch.lane_poses.clone(), table.index.clone());
            LaneRelation {
                index: table.index.clone(),
                mask: table.mask.clone(),
                pose: relative_pose(receiver, sender, &config.distance_wavelengths),
            }
        };
        Self {
            features: batch.lane_features.clone() * scale,
            pose: batch.lane_poses.clone(),
            mask: batch.lane_mask.clone(),
            relations: vec![
                relation(&batch.lane_successors),
                relation(&batch.lane_predecessors),
                relation(&batch.lane_left),
                relation(&batch.lane_right),
            ],
        }
    }

    pub fn nodes(&self) -> usize {
        self.mask.dims()[1]
    }
}
