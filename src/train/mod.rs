//! Learning (paper section 3.2, appendix "Learning", Algorithm 1): behaviour cloning,
//! closed-loop imitation by backpropagation through the simulator, factorized (and scene-level)
//! PPO, RL-Shaped, BC+RL, RTR, and the KL-L / KL-R imitation-signal ablations, all behind one
//! loop ([`Trainer`]) driven by a TOML run file ([`TrainConfig`]).
//!
//! - [`config`]: the run file, defaults from the paper's hyperparameter table;
//! - [`sources`]: nominal and long-tail initial states and their alpha mixture;
//! - [`experience`]: closed-loop rollouts with sampled actions, rewards, early termination;
//! - [`gae`], [`ppo`]: advantages and the PPO losses; [`shaping`]: RL-Shaped's reward;
//! - [`imitation`]: closed-loop IL (BPTT) and BC; [`perturbation`]: its perturbed start states;
//!   [`agent_dropout`]: its scenes with agents removed;
//! - [`gradients`]: global-norm clipping and multi-device sums; [`shards`]: scenes bucketed by
//!   size and spread over worker devices;
//! - [`checkpoint`], [`curves`]: atomic checkpoints and CSV curves;
//! - [`trainer`]: the loop; [`bench`]: throughput; [`probe`]: PPO probe tasks with known
//!   answers.

pub mod agent_dropout;
pub mod checkpoint;
pub mod config;
pub mod curves;
pub mod experience;
pub mod gae;
pub mod gradients;
pub mod identity;
pub mod imitation;
pub mod kept_inputs;
pub mod perturbation;
pub mod ppo;
pub mod probe;
pub mod recorded_weights;
pub mod session;
pub mod shaping;
pub mod shards;
pub mod sources;
mod step;
pub mod trainer;

pub use checkpoint::{Checkpoint, LoopState, load_policy};
pub use config::{
    A9Bend, CommonRoadSource, DataConfig, ImitationConfig, InitConfig, Method, OptimizerConfig,
    PpoConfig, PpoVariant, ReferenceConfig, RunConfig, ShapingConfig, TrainConfig,
};
pub use curves::CurveRow;
pub use sources::{InitialState, Part, TrainingData};
pub use trainer::{IterationTiming, TrainSummary, Trainer};
