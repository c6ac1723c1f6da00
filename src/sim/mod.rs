//! The differentiable closed-loop simulator: bicycle dynamics with composable physics terms,
//! smooth action limits, inverse dynamics, infraction checks, the rollout and the Huber
//! imitation loss.

pub mod catalogue;
pub mod dynamics;
pub mod infractions;
pub mod inverse;
pub mod library;
pub mod limits;
pub mod loss;
pub mod replay;
pub mod rollout;
pub mod state;
pub mod terms;

pub use dynamics::{Derivative, Dynamics, DynamicsTerm, Integrator, TermInput};
pub use infractions::{MapCache, MapCaches, StepBoxes, StepInfractions, check_step};
pub use inverse::{InverseActions, KinematicState, inverse_actions};
pub use limits::{ActionLimits, soft_clamp, soft_clamp_inverse};
pub use loss::{ImitationLoss, huber, imitation_loss};
pub use replay::{ReplayReport, replay_logs};
pub use rollout::{
    Frame, Observation, Policy, Rollout, RolloutConfig, Scripted, coast, logged_frames, rollout,
    rollout_from,
};
pub use state::{Controls, VehicleState, WHEELBASE_RATIO, wheelbase_of};
pub use terms::{Channel, DeadTime, Drag, FirstOrderLag, Sideslip, SteerRateLimit, Understeer};
