//! Rule-based drivers: lane geometry ahead of a vehicle, lane keeping (pure pursuit), the
//! Intelligent Driver Model, and [`IdmDriver`], the IDM + lane-keeping baseline policy.
//!
//! They run on the host (nothing here is differentiated) but read and write the same batched
//! observations and controls as the learned policy, so they drive through the same dynamics.
//! Long-tail hero scripts (`scenario`) are built from the same pieces.

mod idm;
mod lane_keeping;
mod lane_path;
mod reference_driver;
mod snapshot;

pub use idm::{IdmParams, idm_accel};
pub use lane_keeping::{ControlCommand, look_ahead, pure_pursuit_steer};
pub use lane_path::{LanePath, PathPoint, locate_on_lane};
pub use reference_driver::{
    IdmDriver, LEADER_HORIZON_M, Leader, find_leader, idm_command, steer_along, to_controls,
};
pub use snapshot::{AgentView, Snapshot, host_f64};
