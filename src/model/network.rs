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
use super::interaction::{HeteroGnn, StaticLaneTerms};
use super::lane_encoder::LaneGraphEncoder;
use super::relative_motion::RELATIVE_MOTION_FEATURES;
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

    /// The last layer with the outputs from `first` on made constants `values`: their
    /// weights zeroed, their biases set. Training moves them again from there.
    fn with_constant_outputs(mut self, first: usize, values: &[f32]) -> Self {
        let Some(last) = self.layers.pop() else {
            return self;
        };
        let width = last.weight.dims()[1];
        let keep: Vec<f32> = (0..width)
            .map(|k| {
                if (first..first + values.len()).contains(&k) {
                    0.0
                } else {
                    1.0
                }
            })
            .collect();
        let set: Vec<f32> = (0..width)
            .map(|k| {
                k.checked_sub(first)
                    .and_then(|i| values.get(i))
                    .copied()
                    .unwrap_or(0.0)
            })
            .collect();
        let weight = last.weight.map(|w| {
            let keep = Tensor::<1>::from_floats(keep.as_slice(), &w.device()).reshape([1, width]);
            rebuilt_leaf(w, |w| w * keep.clone())
        });
        let bias = last.bias.map(|bias| {
            bias.map(|b| {
                let device = b.device();
                let keep = Tensor::<1>::from_floats(keep.as_slice(), &device);
                let set = Tensor::<1>::from_floats(set.as_slice(), &device);
                rebuilt_leaf(b, |b| b * keep.clone() + set.clone())
            })
        });
        self.layers.push(Linear { weight, bias });
        self
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

/// `f` of a parameter's values as a new leaf tensor, tracked if the parameter was: an autodiff
/// op's output cannot become a trained parameter. Asked of the parameter itself: a reshaped
/// copy answers that it is not tracked, which once froze the output bias of every policy given
/// the sigma from the logs (test `sigma_from_the_logs_leaves_every_parameter_trained`).
fn rebuilt_leaf<const D: usize>(t: Tensor<D>, f: impl Fn(Tensor<D>) -> Tensor<D>) -> Tensor<D> {
    let (tracked, device) = (t.is_require_grad(), t.device());
    let out = Tensor::<D>::from_data(f(t.detach()).into_data(), &device);
    if tracked { out.require_grad() } else { out }
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

/// The encoded lane graph of a batch: h_m and what the HeteroGNN's first round derives from it
/// alone. The map does not change during a rollout, so a rollout encodes it once
/// ([`PolicyNetwork::encode_lanes`]) and passes it to every step's forward.
#[derive(Debug, Clone)]
pub struct EncodedLanes {
    /// h_m, `[B, L, hidden]`.
    pub features: Tensor<3>,
    cached: Option<StaticLaneTerms>,
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
            interaction: HeteroGnn::new(
                config.hidden,
                config.interaction_rounds,
                pose,
                pose + agent_edge_motion_features(config),
                device,
            ),
            config: config.clone(),
        }
    }

    /// h_m and the first round's lane terms: the map only, so a rollout computes it once.
    pub fn encode_lanes(&self, lanes: &LaneInput) -> EncodedLanes {
        let features = self.lanes.forward(lanes);
        EncodedLanes {
            cached: self.interaction.static_lane_terms(features.clone(), lanes),
            features,
        }
    }

    /// Fused agent features `[B, N', hidden]` in `agents.rows`' packed layout, zero in rows
    /// without an agent. `encoded` must come from [`Self::encode_lanes`] of `lanes` with these
    /// parameters.
    pub fn forward(
        &self,
        agents: &AgentInput,
        lanes: &LaneInput,
        encoded: &EncodedLanes,
    ) -> Tensor<3> {
        let h_a = self.history.forward(agents.history.clone());
        let fused = self.interaction.forward(
            h_a,
            encoded.features.clone(),
            lanes,
            &agents.edges,
            encoded.cached.as_ref(),
        );
        fused.mask_fill(
            agents.rows.mask().clone().bool_not().unsqueeze_dim::<3>(2),
            0.0,
        )
    }

    pub fn config(&self) -> &ModelConfig {
        &self.config
    }

    /// The same encoder with `agent_edge_motion` switched on, the new inputs' weights drawn
    /// from `rng` times `scale`.
    fn with_agent_edge_motion(self, rng: &mut impl rand::Rng, scale: f32) -> Self {
        if self.config.agent_edge_motion {
            return self;
        }
        Self {
            interaction: self.interaction.with_extra_agent_edge_inputs(
                RELATIVE_MOTION_FEATURES,
                rng,
                scale,
            ),
            config: ModelConfig {
                agent_edge_motion: true,
                ..self.config
            },
            ..self
        }
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

    /// `[B, N, outputs]`, zero in slots without an agent.
    fn forward(&self, agents: &AgentInput, lanes: &LaneInput, encoded: &EncodedLanes) -> Tensor<3> {
        let packed = self
            .head
            .forward(self.encoder.forward(agents, lanes, encoded));
        agents.rows.unpack(packed)
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
    ($network:ty, $outputs:expr, $architecture:expr) => {
        impl $network {
            /// The network of the run's model config `config` (for the value network, at
            /// [`ModelConfig::value_hidden`]'s width).
            pub fn new(config: &ModelConfig, device: &Device) -> Self {
                let architecture: fn(&ModelConfig) -> ModelConfig = $architecture;
                Self {
                    network: EncoderWithHead::new(&architecture(config), $outputs, device),
                }
            }

            pub fn config(&self) -> &ModelConfig {
                self.network.encoder.config()
            }

            /// The encoded lane graph for [`Self::forward`]: the map only, so a rollout
            /// computes it once.
            pub fn encode_lanes(&self, lanes: &LaneInput) -> EncodedLanes {
                self.network.encoder.encode_lanes(lanes)
            }

            pub fn parameter_counts(&self) -> ParameterCounts {
                self.network.encoder.parameter_counts(&self.network.head)
            }
        }
    };
}

// Mean and log sigma of the two controls; one value.
shared_network_methods!(PolicyNetwork, 4, ModelConfig::clone);
shared_network_methods!(ValueNetwork, 1, ModelConfig::value_network);

/// Width of the relative-motion inputs of an agent <- agent edge under `config`.
fn agent_edge_motion_features(config: &ModelConfig) -> usize {
    if config.agent_edge_motion {
        RELATIVE_MOTION_FEATURES
    } else {
        0
    }
}

impl PolicyNetwork {
    /// The same policy with `agent_edge_motion` on, every trained weight kept and the new
    /// inputs' weights drawn from `rng` as a fresh layer's: how a policy trained with the
    /// paper's pose-only edges warm-starts a run that gives the edges relative motion
    /// (`[init] add_agent_edge_motion`). Where no agent moves relative to another (equal
    /// velocities) the new inputs are zero and the actions are the old policy's.
    /// `scale` multiplies the drawn weights: 0 keeps the warm start's actions exactly.
    pub fn with_agent_edge_motion(self, rng: &mut impl rand::Rng, scale: f32) -> Self {
        Self {
            network: EncoderWithHead {
                encoder: self.network.encoder.with_agent_edge_motion(rng, scale),
                head: self.network.head,
            },
        }
    }

    /// The same policy with the state-independent sigma `std` (m/s^2, rad) for every agent:
    /// the action head's log-sigma outputs are made constant, the mean is untouched. Values
    /// outside what the head can express (`log_std_range` times `action_scale`) are clamped.
    pub fn with_constant_std(self, std: [f64; 2]) -> Self {
        let config = self.config().clone();
        let [lo, hi] = config.log_std_range;
        let raw: Vec<f32> = (0..2)
            .map(|k| {
                let relative = (std[k] / config.action_scale[k]).ln();
                // sigmoid(raw) * (hi - lo) + lo = relative, kept inside the open interval.
                let p = ((relative - lo) / (hi - lo)).clamp(1e-4, 1.0 - 1e-4);
                (p / (1.0 - p)).ln() as f32
            })
            .collect();
        Self {
            network: EncoderWithHead {
                encoder: self.network.encoder,
                head: self.network.head.with_constant_outputs(2, &raw),
            },
        }
    }

    /// Action distribution of every agent; agents outside `agents.mask` (padding, absent) get
    /// a constant one (mean 0), so nothing flows through them.
    pub fn forward(
        &self,
        agents: &AgentInput,
        lanes: &LaneInput,
        encoded: &EncodedLanes,
    ) -> ActionDistribution {
        let config = self.config();
        let out = self.network.forward(agents, lanes, encoded);
        let [b, n, _] = out.dims();
        let device = out.device();
        let scale = Tensor::<1>::from_floats(
            [config.action_scale[0] as f32, config.action_scale[1] as f32],
            &device,
        )
        .reshape([1, 1, 2]);
        let [lo, hi] = config.log_std_range;
        let absent = agents.mask.clone().bool_not().unsqueeze_dim::<3>(2);
        let mut mean = out.clone().narrow(2, 0, 2) * scale.clone();
        if let Some(feedforward) = &agents.steer_feedforward {
            let steer = feedforward.clone().unsqueeze_dim::<3>(2);
            mean = mean + Tensor::cat(vec![steer.zeros_like(), steer], 2);
        }
        let mean = mean.mask_fill(absent.clone(), 0.0);
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
    pub fn forward(
        &self,
        agents: &AgentInput,
        lanes: &LaneInput,
        encoded: &EncodedLanes,
    ) -> Tensor<2> {
        let out = self.network.forward(agents, lanes, encoded);
        let [b, n, _] = out.dims();
        out.reshape([b, n])
            .mask_fill(agents.mask.clone().bool_not(), 0.0)
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use burn::optim::GradientsParams;
    use burn::tensor::{Bool, TensorData};

    use super::*;
    use crate::map::{LaneGraph, Map, ProceduralMap};
    use crate::model::interaction::needed_lane_hops;
    use crate::scene::synthetic_scene;
    use crate::scene::{Scene, SceneBatch};
    use crate::sim::logged_frames;

    /// Sum of squares of every gradient of a module's parameters.
    struct SquaredSum<'g> {
        grads: &'g GradientsParams,
        sum: f64,
    }

    impl burn::module::ModuleVisitor for SquaredSum<'_> {
        fn visit_float<const D: usize>(&mut self, param: &burn::module::Param<Tensor<D>>) {
            if let Some(g) = self.grads.get::<D>(param.id) {
                self.sum += g.powi_scalar(2).sum().into_scalar::<f64>();
            }
        }
    }

    fn values(t: Tensor<3>) -> Vec<f32> {
        t.into_data()
            .convert::<f32>()
            .try_into_vec::<f32>()
            .expect("floats")
    }

    /// Three synthetic scenes of 4-6 agents on a merge.
    fn merge_batch(device: &Device) -> SceneBatch {
        let od = ProceduralMap::preset("on_ramp_merge")
            .and_then(|p| p.build())
            .expect("map");
        let map = Arc::new(Map::from_opendrive(&od, "merge").expect("map"));
        let graph = Arc::new(LaneGraph::build(&map, 10.0));
        let scenes: Vec<Scene> = (0..3)
            .map(|k| synthetic_scene(&map, &graph, 4 + k, k, 4, 1))
            .collect();
        let refs: Vec<&Scene> = scenes.iter().collect();
        SceneBatch::from_scenes(&refs, device).expect("batch")
    }

    fn narrow_config() -> ModelConfig {
        ModelConfig {
            hidden: 16,
            lane_layers: 1,
            interaction_rounds: 3,
            head_hidden: vec![16],
            ..ModelConfig::default()
        }
    }

    /// Adding relative motion to a pose-only policy keeps every trained weight, gives a network
    /// of the widened config's shapes, changes the actions only through the new inputs, and the
    /// new weights get a gradient.
    #[test]
    fn adding_edge_motion_keeps_the_weights_and_trains_the_new_inputs() {
        use rand::SeedableRng;
        let device = crate::backend::Backend::reference_device(true);
        let batch = merge_batch(&device);
        let pose_only = narrow_config();
        let policy = PolicyNetwork::new(&pose_only, &device);
        let frames = logged_frames(&batch, batch.history_steps);
        let lanes = LaneInput::from_batch(&batch, &pose_only);
        let before = values(
            policy
                .forward(
                    &AgentInput::from_frames(&batch, &frames, &pose_only),
                    &lanes,
                    &policy.encode_lanes(&lanes),
                )
                .mean,
        );
        let old_rows: Vec<Vec<f32>> = policy
            .network
            .encoder
            .interaction
            .agent_edge_weights()
            .iter()
            .map(|w| {
                w.val()
                    .into_data()
                    .convert::<f32>()
                    .try_to_vec::<f32>()
                    .unwrap()
            })
            .collect();

        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let widened = policy.with_agent_edge_motion(&mut rng, 1.0);
        let with_motion = widened.config().clone();
        assert!(with_motion.agent_edge_motion);
        assert_eq!(
            PolicyNetwork::new(&with_motion, &device).num_params(),
            widened.num_params()
        );
        let weights = widened.network.encoder.interaction.agent_edge_weights();
        for (w, old) in weights.iter().zip(&old_rows) {
            let new: Vec<f32> = w
                .val()
                .into_data()
                .convert::<f32>()
                .try_to_vec::<f32>()
                .unwrap();
            assert_eq!(&new[..old.len()], &old[..], "trained weights changed");
            let bound = 1.0 / (w.dims()[0] as f32).sqrt();
            let added = &new[old.len()..];
            assert!(added.iter().all(|x| x.abs() <= bound) && added.iter().any(|x| *x != 0.0));
        }

        let agents = AgentInput::from_frames(&batch, &frames, &with_motion);
        let after = widened.forward(&agents, &lanes, &widened.encode_lanes(&lanes));
        assert_ne!(
            before,
            values(after.mean.clone()),
            "the motion inputs are not used"
        );
        let grads = GradientsParams::from_grads(after.mean.sum().backward(), &widened);
        let motion_gradient: f64 = weights
            .iter()
            .map(|w| {
                let rows = w.dims()[0];
                let g = grads
                    .get::<2>(w.id)
                    .expect("a gradient for the edge weights");
                g.narrow(0, rows - RELATIVE_MOTION_FEATURES, RELATIVE_MOTION_FEATURES)
                    .abs()
                    .sum()
                    .into_scalar::<f64>()
            })
            .sum();
        assert!(
            motion_gradient > 0.0,
            "no gradient reaches the motion inputs"
        );
    }

    /// The first round's lane terms computed once per rollout give the forward (and gradient)
    /// of computing them at every step.
    #[test]
    fn cached_lane_terms_change_no_output_or_gradient() {
        let device = crate::backend::Backend::reference_device(true);
        let batch = merge_batch(&device);
        let config = narrow_config();
        let policy = PolicyNetwork::new(&config, &device);
        let lanes = LaneInput::from_batch(&batch, &config);
        let agents =
            AgentInput::from_frames(&batch, &logged_frames(&batch, batch.history_steps), &config);
        let cached = policy.encode_lanes(&lanes);
        assert!(cached.cached.is_some());
        let uncached = EncodedLanes {
            features: cached.features.clone(),
            cached: None,
        };
        let with = policy.forward(&agents, &lanes, &cached);
        let without = policy.forward(&agents, &lanes, &uncached);
        let (a, b) = (values(with.mean.clone()), values(without.mean.clone()));
        assert!(a.iter().any(|v| v.abs() > 1e-6));
        for (x, y) in a.iter().zip(&b) {
            assert!((x - y).abs() <= 1e-6 * x.abs().max(1.0), "{x} vs {y}");
        }
        // Gradients of the same scalar, one parameter at a time, agree too.
        let grads_with = GradientsParams::from_grads(with.mean.sum().backward(), &policy);
        let lanes2 = LaneInput::from_batch(&batch, &config);
        let fresh = policy.encode_lanes(&lanes2);
        let uncached = EncodedLanes {
            features: fresh.features,
            cached: None,
        };
        let grads_without = GradientsParams::from_grads(
            policy
                .forward(&agents, &lanes2, &uncached)
                .mean
                .sum()
                .backward(),
            &policy,
        );
        let norm = |g: &GradientsParams| {
            let mut sum = SquaredSum { grads: g, sum: 0.0 };
            policy.visit(&mut sum);
            sum.sum.sqrt()
        };
        let (gw, gwo) = (norm(&grads_with), norm(&grads_without));
        assert!(gw > 0.0 && (gw - gwo).abs() <= 1e-5 * gw, "{gw} vs {gwo}");
    }

    /// Every parameter gradient of a module, flattened in visiting order.
    struct AllGradients<'g> {
        grads: &'g GradientsParams,
        values: Vec<f32>,
    }

    impl burn::module::ModuleVisitor for AllGradients<'_> {
        fn visit_float<const D: usize>(&mut self, param: &burn::module::Param<Tensor<D>>) {
            if let Some(g) = self.grads.get::<D>(param.id) {
                self.values.extend(
                    g.into_data()
                        .convert::<f32>()
                        .iter::<f32>()
                        .collect::<Vec<_>>(),
                );
            }
        }
    }

    /// The lane rounds updating only the nodes the agents can read (scenes of 1, 2 and 6 agents
    /// on a merge, so crops of different sizes share one flat list) give the same actions,
    /// values and parameter gradients as updating the whole lane graph, for two, three and
    /// four interaction rounds; and the crop is smaller than the graph.
    #[test]
    fn cropped_lane_rounds_match_the_whole_graph() {
        use crate::model::lane_crop::CropScope;
        let device = crate::backend::Backend::reference_device(true);
        let od = ProceduralMap::preset("on_ramp_merge")
            .and_then(|p| p.build())
            .expect("map");
        let map = Arc::new(Map::from_opendrive(&od, "merge").expect("map"));
        let graph = Arc::new(LaneGraph::build(&map, 10.0));
        let scenes: Vec<Scene> = [1, 2, 6]
            .iter()
            .enumerate()
            .map(|(k, &agents)| synthetic_scene(&map, &graph, agents, k, 4, 1))
            .collect();
        let refs: Vec<&Scene> = scenes.iter().collect();
        let batch = SceneBatch::from_scenes(&refs, &device).expect("batch");
        let frames = logged_frames(&batch, batch.history_steps);
        for rounds in [2, 3, 4] {
            let config = ModelConfig {
                interaction_rounds: rounds,
                ..narrow_config()
            };
            let policy = PolicyNetwork::new(&config, &device);
            let value = ValueNetwork::new(&config, &device);
            let lanes = LaneInput::from_batch(&batch, &config);
            let run = |scope: CropScope| {
                let agents = AgentInput::with_lane_scope(&batch, &frames, &config, scope);
                let nodes = agents.edges.lane_round_nodes();
                (
                    nodes,
                    outputs_and_gradients(&policy, &value, &agents, &lanes),
                )
            };
            let (whole_nodes, whole) = run(CropScope::WholeGraph);
            let (cropped_nodes, cropped) = run(CropScope::Hops(needed_lane_hops(&config)));
            assert_eq!(whole_nodes, 3 * batch.max_lane_nodes());
            assert!(
                cropped_nodes < whole_nodes,
                "{rounds} rounds: crop {cropped_nodes} of {whole_nodes}"
            );
            whole.assert_close(&cropped, &format!("{rounds} rounds"));
        }
    }

    /// A value network with fewer rounds than the policy (`value_interaction_rounds`) reads the
    /// edges built once for the policy's rounds (a larger lane crop, or one it does not use)
    /// exactly as it reads edges built for its own rounds.
    #[test]
    fn fewer_value_rounds_read_the_policy_edges_exactly() {
        let device = crate::backend::Backend::reference_device(true);
        let batch = merge_batch(&device);
        let frames = logged_frames(&batch, batch.history_steps);
        for value_rounds in [1, 2] {
            let config = ModelConfig {
                interaction_rounds: 4,
                value_interaction_rounds: Some(value_rounds),
                ..narrow_config()
            };
            let own = config.value_network();
            let value = ValueNetwork::new(&config, &device);
            assert_eq!(value.config().interaction_rounds, value_rounds);
            assert!(value.num_params() < ValueNetwork::new(&narrow_config(), &device).num_params());
            // A policy of the value network's rounds, so that both runs are exact for it too.
            let policy = PolicyNetwork::new(&own, &device);
            let lanes = LaneInput::from_batch(&batch, &config);
            let run = |inputs_for: &ModelConfig| {
                let agents = AgentInput::from_frames(&batch, &frames, inputs_for);
                outputs_and_gradients(&policy, &value, &agents, &lanes)
            };
            run(&config).assert_close(&run(&own), &format!("{value_rounds} value rounds"));
        }
    }

    /// A policy's and a value network's outputs on some agents, and their parameters'
    /// gradients of a loss that reads every output.
    struct OutputsAndGradients {
        mean: Vec<f32>,
        log_std: Vec<f32>,
        value: Vec<f32>,
        gradients: Vec<f32>,
    }

    impl OutputsAndGradients {
        fn assert_close(&self, other: &Self, case: &str) {
            let close = |a: &[f32], b: &[f32], what: &str| {
                assert_eq!(a.len(), b.len(), "{case}, {what}");
                let scale = a.iter().fold(1e-3f32, |m, x| m.max(x.abs()));
                for (i, (x, y)) in a.iter().zip(b).enumerate() {
                    assert!(
                        (x - y).abs() <= 1e-4 * scale,
                        "{case}, {what}[{i}]: {x} vs {y}"
                    );
                }
            };
            close(&self.mean, &other.mean, "mean");
            close(&self.log_std, &other.log_std, "log_std");
            close(&self.value, &other.value, "value");
            assert!(self.gradients.iter().any(|g| *g != 0.0), "{case}");
            close(&self.gradients, &other.gradients, "gradient");
        }
    }

    fn outputs_and_gradients(
        policy: &PolicyNetwork,
        value: &ValueNetwork,
        agents: &AgentInput,
        lanes: &LaneInput,
    ) -> OutputsAndGradients {
        let dist = policy.forward(agents, lanes, &policy.encode_lanes(lanes));
        let v = value.forward(agents, lanes, &value.encode_lanes(lanes));
        let (mean, log_std) = (values(dist.mean.clone()), values(dist.log_std.clone()));
        let value_out = values(v.clone().unsqueeze_dim::<3>(2));
        let loss = (dist.mean.sin() * dist.log_std).sum() + v.powi_scalar(2).sum();
        let mut grads = loss.backward();
        let mut all = AllGradients {
            grads: &GradientsParams::from_module(&mut grads, policy),
            values: Vec::new(),
        };
        policy.visit(&mut all);
        let mut gradients = all.values;
        let mut all = AllGradients {
            grads: &GradientsParams::from_module(&mut grads, value),
            values: Vec::new(),
        };
        value.visit(&mut all);
        gradients.extend(all.values);
        OutputsAndGradients {
            mean,
            log_std,
            value: value_out,
            gradients,
        }
    }

    /// Computing only the agents present now (packed) gives the padded computation's actions,
    /// values and parameter gradients, with and without relative-motion edges, where a scene
    /// has agents absent at the current step and another has padding slots.
    #[test]
    fn packed_agent_rows_match_the_padded_computation() {
        use crate::model::agent_rows::AgentRows;
        use crate::model::lane_crop::CropScope;
        let device = crate::backend::Backend::reference_device(true);
        let batch = merge_batch(&device);
        let mut frames = logged_frames(&batch, batch.history_steps);
        // Scenes of 4, 5 and 6 agents; agents 1 and 3 of the last scene have left the road.
        let [b, n] = batch.agent_mask.dims();
        let mut present: Vec<bool> = frames
            .last()
            .expect("current frame")
            .present
            .clone()
            .into_data()
            .try_into_vec_as::<bool>()
            .expect("flags");
        present[2 * n + 1] = false;
        present[2 * n + 3] = false;
        let now = frames.last_mut().expect("current frame");
        now.present = Tensor::<2, Bool>::from_data(TensorData::new(present, [b, n]), &device);
        for agent_edge_motion in [false, true] {
            let config = ModelConfig {
                agent_edge_motion,
                lane_steer_feedforward: agent_edge_motion,
                ..narrow_config()
            };
            let policy = PolicyNetwork::new(&config, &device);
            let value = ValueNetwork::new(&config, &device);
            let lanes = LaneInput::from_batch(&batch, &config);
            let scope = CropScope::Hops(needed_lane_hops(&config));
            let run = |rows: AgentRows| {
                let agents = AgentInput::with_scope(&batch, &frames, &config, scope, rows);
                (
                    agents.rows.rows(),
                    outputs_and_gradients(&policy, &value, &agents, &lanes),
                )
            };
            let (padded_rows, padded) = run(AgentRows::All);
            let (packed_rows, packed) = run(AgentRows::Present);
            assert_eq!((padded_rows, packed_rows), (6, 5));
            packed.assert_close(&padded, &format!("edge motion {agent_edge_motion}"));
        }
    }

    /// A narrower value network (`value_hidden`) has fewer parameters, reads the inputs built
    /// for the policy's config, and gives one value per agent.
    #[test]
    fn a_narrower_value_network_reads_the_policy_inputs() {
        let device = crate::backend::Backend::reference_device(false);
        let batch = merge_batch(&device);
        let config = ModelConfig {
            value_hidden: Some(8),
            ..narrow_config()
        };
        let value = ValueNetwork::new(&config, &device);
        assert!(value.num_params() < ValueNetwork::new(&narrow_config(), &device).num_params());
        assert_eq!(
            PolicyNetwork::new(&config, &device).num_params(),
            PolicyNetwork::new(&narrow_config(), &device).num_params()
        );
        let lanes = LaneInput::from_batch(&batch, &config);
        let agents =
            AgentInput::from_frames(&batch, &logged_frames(&batch, batch.history_steps), &config);
        let v = value.forward(&agents, &lanes, &value.encode_lanes(&lanes));
        assert_eq!(v.dims(), [batch.batch_size(), batch.max_agents()]);
        assert!(v.abs().sum().into_scalar::<f32>() > 0.0);
    }
}
