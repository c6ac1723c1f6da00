//! Inverse dynamics: the controls that make the bicycle model reproduce a logged trajectory,
//! for behaviour-cloning labels and log replay.
//!
//! Forward Euler moves the rear axle by v_t dt along theta_t, so a logged rear-axle path is
//! reproduced exactly when theta_t is the direction of the step p_t -> p_t+1 and v_t its length
//! over dt. The controls then follow from consecutive steps: u_t = (v_t+1 - v_t) / dt and
//! phi_t = atan(L (theta_t+1 - theta_t) / (v_t dt)), mapped through the inverse of the smooth
//! action limits. Positions are reproduced up to the limits and float rounding; the replay
//! test states the figure.

use super::limits::{ActionLimits, soft_clamp_inverse};
use super::state::wheelbase_of;
use crate::data::AgentState;
use crate::geometry::wrap_angle;
use crate::scene::SceneAgent;

/// Below this step length (m) the direction of motion is noise; the logged heading is used.
const MIN_STEP_M: f64 = 0.05;
/// Below this speed (m/s) steering has no effect on the path; it is set to 0.
const MIN_STEER_SPEED: f64 = 0.5;

/// Rear-axle state consistent with forward Euler, per step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KinematicState {
    pub x: f64,
    pub y: f64,
    pub heading: f64,
    pub speed: f64,
}

/// Controls per step for one agent: `raw` are the commands before the smooth limits (what a
/// policy outputs), `applied` after them. `valid[t]` when steps t, t+1 and t+2 are logged.
#[derive(Debug, Clone, PartialEq)]
pub struct InverseActions {
    pub raw_accel: Vec<f64>,
    pub raw_steer: Vec<f64>,
    pub accel: Vec<f64>,
    pub steer: Vec<f64>,
    pub valid: Vec<bool>,
    /// Kinematically consistent state per step (where `t` and `t + 1` are logged).
    pub states: Vec<Option<KinematicState>>,
}

fn rear_axle(s: &AgentState, wheelbase: f64) -> [f64; 2] {
    let (sin, cos) = s.heading.sin_cos();
    [s.x - 0.5 * wheelbase * cos, s.y - 0.5 * wheelbase * sin]
}

/// Inverse dynamics of one scene agent at step `dt`.
pub fn inverse_actions(agent: &SceneAgent, dt: f64, limits: &ActionLimits) -> InverseActions {
    let t = agent.states.len();
    let wheelbase = wheelbase_of(agent.length).max(1.0);
    let mut states = vec![None; t];
    for (k, slot) in states.iter_mut().enumerate().take(t.saturating_sub(1)) {
        if !(agent.valid[k] && agent.valid[k + 1]) {
            continue;
        }
        let p = rear_axle(&agent.states[k], wheelbase);
        let q = rear_axle(&agent.states[k + 1], wheelbase);
        let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
        let len = dx.hypot(dy);
        let logged = agent.states[k].heading;
        let (heading, speed) = if len < MIN_STEP_M {
            (logged, (dx * logged.cos() + dy * logged.sin()) / dt)
        } else {
            let dir = dy.atan2(dx);
            // Reversing: the direction of motion is opposite to the vehicle.
            if wrap_angle(dir - logged).abs() > std::f64::consts::FRAC_PI_2 {
                (wrap_angle(dir + std::f64::consts::PI), -len / dt)
            } else {
                (dir, len / dt)
            }
        };
        *slot = Some(KinematicState {
            x: p[0],
            y: p[1],
            heading,
            speed,
        });
    }
    let mut out = InverseActions {
        raw_accel: vec![0.0; t],
        raw_steer: vec![0.0; t],
        accel: vec![0.0; t],
        steer: vec![0.0; t],
        valid: vec![false; t],
        states: states.clone(),
    };
    for k in 0..t.saturating_sub(1) {
        let (Some(a), Some(b)) = (states[k], states[k + 1]) else {
            continue;
        };
        let accel = (b.speed - a.speed) / dt;
        let steer = if a.speed.abs() < MIN_STEER_SPEED {
            0.0
        } else {
            (wheelbase * wrap_angle(b.heading - a.heading) / (a.speed * dt)).atan()
        };
        out.raw_accel[k] = soft_clamp_inverse(accel, limits.accel_min, limits.accel_max);
        out.raw_steer[k] = soft_clamp_inverse(steer, -limits.steer_max, limits.steer_max);
        // What the limits let through (equal to the target inside the limits).
        out.accel[k] = limited(out.raw_accel[k], limits.accel_min, limits.accel_max);
        out.steer[k] = limited(out.raw_steer[k], -limits.steer_max, limits.steer_max);
        out.valid[k] = true;
    }
    out
}

/// Scalar version of [`super::limits::soft_clamp`].
fn limited(c: f64, lo: f64, hi: f64) -> f64 {
    if c >= 0.0 {
        hi * (c / hi).tanh()
    } else {
        -lo * (c / -lo).tanh()
    }
}
