//! The policy and value networks (paper section 3.3): the same architecture, separate
//! parameters. Context encoders (history, lane graph) -> HeteroGNN -> a per-agent MLP decoding
//! a Normal over (acceleration, steering), or a scalar value.

use burn::module::Module;
use burn::nn::{Linear, LinearConfig};
use burn::prelude::*;
use burn::tensor::activation::{relu, sigmoid};

use super::config::ModelConfig;
use super::distribution::ActionDistribution;
use super::history::HistoryEncoder;
use super::input::{AgentInput, LaneInput, history_features};
use super::interaction::{HeteroGnn, InteractionEdges};
use super::lane_encoder::LaneGraphEncoder;
use super::relative_pose::relative_pose_features;
use super::rowwise::rowwise;

/// Linear layers with ReLU between them (none after the last).
#[derive(Module, Debug)]
pub struct Mlp {
    layers: Vec<Linear>,
}

impl Mlp {
    pub fn new(input: usize, hidden: &[usize], output: usize, device: &Device) -> Self {
        let widths: Vec<usize> = std::iter::once(input)
            .chain(hidden.iter().copied())
            .chain(std::iter::once(output))
            .collect();
        Self {
            layers: widths
                .windows(2)
                .map(|w| LinearConfig::new(w[0], w[1]).init(device))
                .collect(),
        }
    }

    pub fn forward<const D: usize>(&self, mut x: Tensor<D>) -> Tensor<D> {
        let last = self.layers.len() - 1;
        for (i, layer) in self.layers.iter().enumerate() {
            x = rowwise(layer, x);
            if i < last {
                x = relu(x);
            }
        }
        x
    }
}

/// Parameters of one network, by component (`rtr model info`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct ParameterCounts {
    pub history_encoder: usize,
    pub lane_graph_encoder: usize,
    pub interaction: usize,
    pub head: usize,
    pub total: usize,
}

/// History encoder + lane-graph encoder + HeteroGNN: fused features h_i per agent.
#[derive(Module, Debug)]
pub struct SceneEncoder {
    history: HistoryEncoder,
    lanes: LaneGraphEncoder,
    interaction: HeteroGnn,
    #[module(skip)]
    config: ModelConfig,
}

impl SceneEncoder {
    pub fn new(config: &ModelConfig, device: &Device) -> Self {
        let pose = relative_pose_features(config.distance_wavelengths.len());
        Self {
            history: HistoryEncoder::new(
                history_features(config),
                config.hidden,
                config.history_blocks,
                config.history_kernel,
                device,
            ),
            lanes: LaneGraphEncoder::new(config.hidden, config.lane_layers, pose, device),
            interaction: HeteroGnn::new(config.hidden, config.interaction_rounds, pose, device),
            config: config.clone(),
        }
    }

    /// h_m, `[B, L, hidden]`: depends on the map only, so a rollout computes it once.
    pub fn encode_lanes(&self, lanes: &LaneInput) -> Tensor<3> {
        self.lanes.forward(lanes)
    }

    /// Fused agent features `[B, N, hidden]`, zero for agents outside `agents.mask`.
    pub fn forward(&self, agents: &AgentInput, lanes: &LaneInput, h_m: Tensor<3>) -> Tensor<3> {
        let h_a = self.history.forward(agents.history.clone());
        let edges = InteractionEdges::build(agents, lanes, &self.config);
        let fused = self.interaction.forward(h_a, h_m, lanes, &edges);
        fused.mask_fill(agents.mask.clone().bool_not().unsqueeze_dim::<3>(2), 0.0)
    }

    pub fn config(&self) -> &ModelConfig {
        &self.config
    }

    fn parameter_counts(&self, head: &Mlp) -> ParameterCounts {
        let parts = [
            self.history.num_params(),
            self.lanes.num_params(),
            self.interaction.num_params(),
            head.num_params(),
        ];
        ParameterCounts {
            history_encoder: parts[0],
            lane_graph_encoder: parts[1],
            interaction: parts[2],
            head: parts[3],
            total: parts.iter().sum(),
        }
    }
}

/// A scene encoder with a per-agent MLP on top: the shared shape of both networks.
#[derive(Module, Debug)]
pub struct EncoderWithHead {
    encoder: SceneEncoder,
    head: Mlp,
}

impl EncoderWithHead {
    fn new(config: &ModelConfig, outputs: usize, device: &Device) -> Self {
        Self {
            encoder: SceneEncoder::new(config, device),
            head: Mlp::new(config.hidden, &config.head_hidden, outputs, device),
        }
    }

    /// `[B, N, outputs]`.
    fn forward(&self, agents: &AgentInput, lanes: &LaneInput, h_m: Tensor<3>) -> Tensor<3> {
        self.head.forward(self.encoder.forward(agents, lanes, h_m))
    }
}

/// The policy pi(a | s): per agent, a Normal over raw (acceleration, steering).
#[derive(Module, Debug)]
pub struct PolicyNetwork {
    network: EncoderWithHead,
}

/// The value network V(s) per agent: the policy's architecture with its own parameters.
#[derive(Module, Debug)]
pub struct ValueNetwork {
    network: EncoderWithHead,
}

/// What both networks offer besides their forward pass.
macro_rules! shared_network_methods {
    ($network:ty, $outputs:expr) => {
        impl $network {
            pub fn new(config: &ModelConfig, device: &Device) -> Self {
                Self {
                    network: EncoderWithHead::new(config, $outputs, device),
                }
            }

            pub fn config(&self) -> &ModelConfig {
                self.network.encoder.config()
            }

            /// h_m for [`Self::forward`]: the map only, so a rollout computes it once.
            pub fn encode_lanes(&self, lanes: &LaneInput) -> Tensor<3> {
                self.network.encoder.encode_lanes(lanes)
            }

            pub fn parameter_counts(&self) -> ParameterCounts {
                self.network.encoder.parameter_counts(&self.network.head)
            }
        }
    };
}

// Mean and log sigma of the two controls; one value.
shared_network_methods!(PolicyNetwork, 4);
shared_network_methods!(ValueNetwork, 1);

impl PolicyNetwork {
    /// Action distribution of every agent; agents outside `agents.mask` (padding, absent) get
    /// a constant one (mean 0), so nothing flows through them.
    pub fn forward(
        &self,
        agents: &AgentInput,
        lanes: &LaneInput,
        h_m: Tensor<3>,
    ) -> ActionDistribution {
        let config = self.config();
        let out = self.network.forward(agents, lanes, h_m);
        let [b, n, _] = out.dims();
        let device = out.device();
        let scale = Tensor::<1>::from_floats(
            [config.action_scale[0] as f32, config.action_scale[1] as f32],
            &device,
        )
        .reshape([1, 1, 2]);
        let [lo, hi] = config.log_std_range;
        let absent = agents.mask.clone().bool_not().unsqueeze_dim::<3>(2);
        let mean = (out.clone().narrow(2, 0, 2) * scale.clone()).mask_fill(absent.clone(), 0.0);
        // log sigma = ln(scale) + a value squashed into [lo, hi] (smooth, never saturating
        // hard, so PPO can always move it).
        let squashed = sigmoid(out.narrow(2, 2, 2))
            .mul_scalar(hi - lo)
            .add_scalar(lo)
            .mask_fill(absent, 0.0);
        let log_std = squashed + scale.log().expand([b, n, 2]);
        ActionDistribution { mean, log_std }
    }
}

impl ValueNetwork {
    /// `[B, N]` value estimates; 0 outside `agents.mask`.
    pub fn forward(&self, agents: &AgentInput, lanes: &LaneInput, h_m: Tensor<3>) -> Tensor<2> {
        let out = self.network.forward(agents, lanes, h_m);
        let [b, n, _] = out.dims();
        out.reshape([b, n])
            .mask_fill(agents.mask.clone().bool_not(), 0.0)
    }
}
