//! The two building blocks of every graph layer here (lane encoder and HeteroGNN).
//!
//! [`EdgeMessage`]: one edge type's messages, `relu(W_s h_sender + W_p pose_ij)`, max-aggregated
//! over a receiver's neighbours. `pose_ij` is the sender's pose in the receiver's frame, so
//! messages are conditioned on relative geometry (GoRela). The relu is applied after the max
//! (`max_j relu(x_j) = relu(max_j x_j)`, relu being monotone), on `[B, R, C]` instead of every
//! edge's `[B, R, K, C]`: the same output and gradient for one full-size op fewer forward and
//! backward. A receiver term inside the relu would be redundant for the same reason
//! (`max_j relu(a_j + c) = relu(max_j a_j + c)`), so the receiver enters through [`NodeUpdate`]
//! instead. Projecting the senders once per node (not once per edge) keeps the per-edge cost to
//! one small matmul of the pose features.
//!
//! [`NodeUpdate`]: LaneGCN's fusion, `h' = relu(h + LN(W_o relu(LN(W_self h + sum of messages))))`.

use burn::module::Module;
use burn::nn::{LayerNorm, LayerNormConfig, Linear, LinearConfig};
use burn::prelude::*;
use burn::tensor::activation::relu;
use burn::tensor::{Bool, Int};

use super::aggregate::{gather_neighbours, masked_max};
use super::rowwise::rowwise;

#[derive(Module, Debug)]
pub struct EdgeMessage {
    sender: Linear,
    pose: Linear,
}

impl EdgeMessage {
    pub fn new(hidden: usize, pose_features: usize, device: &Device) -> Self {
        Self {
            sender: LinearConfig::new(hidden, hidden).init(device),
            pose: LinearConfig::new(pose_features, hidden)
                .with_bias(false)
                .init(device),
        }
    }

    /// Sparse edges: `senders` `[B, M, C]`, per receiver `index` / `mask` `[B, R, K]` and
    /// relative `pose` `[B, R, K, P]` -> `[B, R, C]`.
    pub fn aggregate(
        &self,
        senders: Tensor<3>,
        index: Tensor<3, Int>,
        pose: Tensor<4>,
        mask: Tensor<3, Bool>,
    ) -> Tensor<3> {
        self.aggregate_projected(self.project(senders), index, pose, mask)
    }

    /// `W_s h` for every sender `[B, M, C]`: what [`Self::aggregate_projected`] takes, so
    /// senders that do not change over a rollout (the encoded lane graph) are projected once.
    pub fn project(&self, senders: Tensor<3>) -> Tensor<3> {
        rowwise(&self.sender, senders)
    }

    /// [`Self::aggregate`] with the senders already [`Self::project`]ed.
    pub fn aggregate_projected(
        &self,
        projected: Tensor<3>,
        index: Tensor<3, Int>,
        pose: Tensor<4>,
        mask: Tensor<3, Bool>,
    ) -> Tensor<3> {
        let gathered = gather_neighbours(projected, index);
        relu(masked_max(gathered + rowwise(&self.pose, pose), mask))
    }

    /// Every sender to every receiver: `senders` `[B, M, C]`, `pose` `[B, R, M, P]`, `mask`
    /// `[B, R, M]` -> `[B, R, C]`.
    pub fn aggregate_dense(
        &self,
        senders: Tensor<3>,
        pose: Tensor<4>,
        mask: Tensor<3, Bool>,
    ) -> Tensor<3> {
        let [b, r, m, _] = pose.dims();
        let c = senders.dims()[2];
        let projected = rowwise(&self.sender, senders)
            .unsqueeze_dim::<4>(1)
            .expand([b, r, m, c]);
        relu(masked_max(projected + rowwise(&self.pose, pose), mask))
    }
}

#[derive(Module, Debug)]
pub struct NodeUpdate {
    own: Linear,
    first_norm: LayerNorm,
    output: Linear,
    second_norm: LayerNorm,
}

impl NodeUpdate {
    pub fn new(hidden: usize, device: &Device) -> Self {
        Self {
            own: LinearConfig::new(hidden, hidden).init(device),
            first_norm: LayerNormConfig::new(hidden).init(device),
            output: LinearConfig::new(hidden, hidden).init(device),
            second_norm: LayerNormConfig::new(hidden).init(device),
        }
    }

    /// `nodes` and the summed aggregated `messages`, both `[B, R, C]` -> `[B, R, C]`.
    pub fn forward(&self, nodes: Tensor<3>, messages: Tensor<3>) -> Tensor<3> {
        let fused = relu(
            self.first_norm
                .forward(rowwise(&self.own, nodes.clone()) + messages),
        );
        relu(nodes + self.second_norm.forward(rowwise(&self.output, fused)))
    }
}
