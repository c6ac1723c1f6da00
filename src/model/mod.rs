//! The multi-agent policy and value networks of the paper (section 3.3, appendix "Model
//! Architecture"), as burn modules that never name a backend:
//!
//! - [`input`]: viewpoint-invariant inputs from a [`crate::scene::SceneBatch`] and the frames of
//!   a rollout ([`relative_pose`] encodes one pose seen from another, [`relative_motion`] one
//!   agent's motion relative to another's);
//! - [`agent_rows`]: the networks compute only the agents present now, packed;
//! - [`history`]: 1D residual CNN + GRU -> h_a per agent;
//! - [`lane_encoder`]: LaneGCN over successor / predecessor / left / right -> h_m per lane node;
//! - [`interaction`]: HeteroGNN over agents and lane nodes -> fused h_i per agent;
//! - [`network`]: [`PolicyNetwork`] (Normal over acceleration and steering, see
//!   [`distribution`]) and [`ValueNetwork`] (scalar per agent), same architecture, no shared
//!   parameters;
//! - [`network_policy`]: a policy network driving the simulator;
//! - [`steer_feedforward`]: (not in the paper) the lane's steady-state steering under the
//!   policy's steering mean;
//! - [`weight_average`]: the mean of several checkpoints' parameters (stochastic weight
//!   averaging).

pub mod agent_rows;
pub mod aggregate;
pub mod config;
pub mod distribution;
#[cfg(feature = "flex")]
mod fused_max;
mod gru_last_state;
pub mod history;
pub mod input;
pub mod interaction;
pub mod lane_crop;
pub mod lane_encoder;
pub mod message;
pub mod network;
pub mod network_policy;
pub mod relative_motion;
pub mod relative_pose;
pub mod rowwise;
pub mod steer_feedforward;
pub mod weight_average;

pub use config::ModelConfig;
pub use distribution::ActionDistribution;
pub use input::{AgentInput, LaneInput};
pub use lane_crop::LaneCrop;
pub use network::{EncodedLanes, ParameterCounts, PolicyNetwork, SceneEncoder, ValueNetwork};
pub use network_policy::{ActionMode, NetworkPolicy};
