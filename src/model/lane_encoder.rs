//! Lane-graph encoder (LaneGCN, paper appendix): node features lifted to `hidden`, then layers
//! of graph convolution over the four relations (successor, predecessor, left, right) with
//! LayerNorm and max aggregation -> h_m per lane node.

use burn::module::Module;
use burn::nn::{LayerNorm, LayerNormConfig, Linear, LinearConfig};
use burn::prelude::*;
use burn::tensor::activation::relu;

use super::input::{LaneInput, LaneRelation};
use super::message::{EdgeMessage, NodeUpdate};
use super::rowwise::rowwise;
use crate::map::LANE_NODE_FEATURES;

/// The lane relations, in [`LaneInput::relations`] order.
pub const LANE_RELATIONS: usize = 4;

#[derive(Module, Debug)]
struct LaneLayer {
    relations: Vec<EdgeMessage>,
    update: NodeUpdate,
}

#[derive(Module, Debug)]
pub struct LaneGraphEncoder {
    input: Linear,
    input_norm: LayerNorm,
    layers: Vec<LaneLayer>,
}

impl LaneGraphEncoder {
    pub fn new(hidden: usize, layers: usize, pose_features: usize, device: &Device) -> Self {
        Self {
            input: LinearConfig::new(LANE_NODE_FEATURES, hidden).init(device),
            input_norm: LayerNormConfig::new(hidden).init(device),
            layers: (0..layers)
                .map(|_| LaneLayer {
                    relations: (0..LANE_RELATIONS)
                        .map(|_| EdgeMessage::new(hidden, pose_features, device))
                        .collect(),
                    update: NodeUpdate::new(hidden, device),
                })
                .collect(),
        }
    }

    /// `[B, L, hidden]`; padded nodes are zero.
    pub fn forward(&self, lanes: &LaneInput) -> Tensor<3> {
        let mut h = relu(
            self.input_norm
                .forward(rowwise(&self.input, lanes.features.clone())),
        );
        for layer in &self.layers {
            h = layer.forward(h, lanes);
        }
        let padded = lanes.mask.clone().bool_not().unsqueeze_dim::<3>(2);
        h.mask_fill(padded, 0.0)
    }
}

impl LaneLayer {
    fn forward(&self, h: Tensor<3>, lanes: &LaneInput) -> Tensor<3> {
        let messages = lane_messages(&self.relations, h.clone(), &lanes.relations);
        self.update.forward(h, messages)
    }
}

/// Sum over the four relations of their max-aggregated messages (also used by the HeteroGNN,
/// which keeps the lane-lane edges).
pub fn lane_messages(
    messages: &[EdgeMessage],
    h: Tensor<3>,
    relations: &[LaneRelation],
) -> Tensor<3> {
    messages
        .iter()
        .zip(relations)
        .map(|(message, edges)| {
            message.aggregate(
                h.clone(),
                edges.index.clone(),
                edges.pose.clone(),
                edges.mask.clone(),
            )
        })
        .reduce(|a, b| a + b)
        .expect("four lane relations")
}
