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

use burn::module::{Module, Param};
use burn::nn::{LayerNorm, LayerNormConfig, Linear, LinearConfig};
use burn::prelude::*;
use burn::tensor::activation::relu;
use burn::tensor::{Bool, Int, TensorData};
use rand::Rng;

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

    /// The same messages with `extra` more edge inputs appended after the pose. Their weights
    /// are drawn from `rng` as a fresh layer of the widened size draws its own (burn's default
    /// Kaiming-uniform, bound 1 / sqrt(fan-in)), times `scale`; the old weights are kept.
    /// `scale` 0 keeps the outputs exactly; Adam then moves each new weight by about the
    /// learning rate per step, so at a fine-tune's 5e-5 they stay small for the whole run.
    pub fn with_extra_pose_inputs(self, extra: usize, rng: &mut impl Rng, scale: f32) -> Self {
        let weight = self.pose.weight.val();
        let [rows, hidden] = weight.dims();
        let device = weight.device();
        let bound = 1.0 / ((rows + extra) as f32).sqrt();
        let drawn: Vec<f32> = (0..extra * hidden)
            .map(|_| rng.random_range(-bound..bound) * scale)
            .collect();
        let added = Tensor::<2>::from_data(TensorData::new(drawn, [extra, hidden]), &device);
        // Through plain data: a parameter must be a leaf of the autodiff graph, and a `cat`
        // under autodiff is a node even of detached inputs.
        let widened = Tensor::cat(vec![weight.detach(), added], 0).into_data();
        Self {
            pose: Linear {
                weight: Param::from_tensor(Tensor::from_data(widened, &device)),
                bias: self.pose.bias,
            },
            ..self
        }
    }

    /// `W_p`, `[pose inputs, hidden]`.
    #[cfg(test)]
    pub fn pose_weight(&self) -> &Param<Tensor<2>> {
        &self.pose.weight
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

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::Distribution;
    use rand::SeedableRng;

    /// The widened layer's messages on inputs whose new features are zero are the old ones.
    #[test]
    fn extra_inputs_at_zero_leave_the_messages_unchanged() {
        let device = crate::backend::Backend::reference_device(false);
        let (hidden, pose_features, extra) = (8, 5, 3);
        let message = EdgeMessage::new(hidden, pose_features, &device);
        let senders = Tensor::<3>::random([2, 4, hidden], Distribution::Default, &device);
        let pose = Tensor::<4>::random([2, 3, 4, pose_features], Distribution::Default, &device);
        let mask = Tensor::<3>::random([2, 3, 4], Distribution::Default, &device).greater_elem(0.3);
        let before = message.aggregate_dense(senders.clone(), pose.clone(), mask.clone());
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let widened = message.clone().with_extra_pose_inputs(extra, &mut rng, 1.0);
        let padded = Tensor::cat(
            vec![pose.clone(), Tensor::zeros([2, 3, 4, extra], &device)],
            3,
        );
        let after = widened.aggregate_dense(senders.clone(), padded, mask.clone());
        after.into_data().assert_approx_eq::<f32>(
            &before.clone().into_data(),
            burn::tensor::Tolerance::absolute(1e-6),
        );
        // Weights scaled to zero ignore whatever the new inputs hold.
        let zeroed = message.with_extra_pose_inputs(extra, &mut rng, 0.0);
        let moving = Tensor::cat(
            vec![
                pose,
                Tensor::ones([2, 3, 4, extra], &device).mul_scalar(5.0),
            ],
            3,
        );
        zeroed
            .aggregate_dense(senders, moving, mask)
            .into_data()
            .assert_approx_eq::<f32>(&before.into_data(), burn::tensor::Tolerance::absolute(1e-6));
    }
}
