//! Closed-loop rollout: from a batch's current step, a policy drives the controlled agents
//! (and a script the heroes of long-tail scenarios) through the dynamics for T steps, seeing
//! the simulated (not the logged) history; replayed agents follow the log while it has them;
//! infractions are flagged per agent and step.
//!
//! Early termination (paper appendix): an agent that collides or goes off-road gets reward -1
//! on that step and is removed from the simulation afterwards. An agent whose box centre
//! passes an open road end has left the map: removed, no infraction.

use burn::prelude::*;
use burn::tensor::{Bool, TensorData};

use super::dynamics::Dynamics;
use super::infractions::{MapCache, MapCaches, StepBoxes, check_step};
use super::state::{Controls, VehicleState, WHEELBASE_RATIO};
use crate::error::{Error, Result};
use crate::scene::{Scene, SceneBatch};

/// Per-step pose features in [`Frame::poses`]: box centre x, y, heading, speed.
pub const FRAME_FEATURES: usize = 4;

/// The scene at one step, as the policy sees it.
#[derive(Debug, Clone)]
pub struct Frame {
    /// `[B, N, 4]`: centre x, y, heading, speed; zero where absent.
    pub poses: Tensor<3>,
    /// `[B, N]`: the agent is on the road at this step.
    pub present: Tensor<2, Bool>,
}

/// What a policy gets at each step.
pub struct Observation<'a> {
    pub batch: &'a SceneBatch,
    /// Steps simulated so far (0 at the scene's current step).
    pub step: usize,
    /// Logged history, then simulated frames; the last one is now.
    pub frames: &'a [Frame],
    /// Kinematic state now (rear axle).
    pub state: &'a VehicleState,
    /// `[B, N]` (m).
    pub wheelbase: &'a Tensor<2>,
}

/// Anything that maps an observation to raw (unlimited) controls for every agent; entries for
/// agents the policy does not drive are ignored.
pub trait Policy {
    fn act(&mut self, obs: &Observation) -> Controls;
}

impl<F: FnMut(&Observation) -> Controls> Policy for F {
    fn act(&mut self, obs: &Observation) -> Controls {
        self(obs)
    }
}

/// A policy that applies no acceleration and no steering: every agent coasts straight.
pub fn coast(obs: &Observation) -> Controls {
    let dims = obs.state.speed.dims();
    let device = obs.state.speed.device();
    Controls {
        accel: Tensor::zeros(dims, &device),
        steer: Tensor::zeros(dims, &device),
    }
}

/// Drives the agents in `mask` with `script` (long-tail heroes: `mask` = the batch's
/// `agent_hero`) and all others with `policy`, both through the same dynamics.
pub struct Scripted<'p, 's> {
    pub policy: &'p mut dyn Policy,
    pub script: &'s mut dyn Policy,
    /// `[B, N]`: agents driven by the script.
    pub mask: Tensor<2, Bool>,
}

impl Policy for Scripted<'_, '_> {
    fn act(&mut self, obs: &Observation) -> Controls {
        let learned = self.policy.act(obs);
        let scripted = self.script.act(obs);
        Controls {
            accel: learned.accel.mask_where(self.mask.clone(), scripted.accel),
            steer: learned.steer.mask_where(self.mask.clone(), scripted.steer),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RolloutConfig {
    /// Steps to simulate; `None` = the batch's future steps.
    pub steps: Option<usize>,
    /// Remove an agent after its infraction (the paper's early termination).
    pub early_termination: bool,
}

impl Default for RolloutConfig {
    fn default() -> Self {
        Self {
            steps: None,
            early_termination: true,
        }
    }
}

/// Result of a rollout. Step 0 is the scene's current step.
#[derive(Debug, Clone)]
pub struct Rollout {
    /// `[B, N, T + 1, 4]`: centre x, y, heading, speed (differentiable).
    pub poses: Tensor<4>,
    /// `[B, N, T + 1]`: agent on the road at that step.
    pub present: Tensor<3, Bool>,
    /// `[B, N, T + 1]`: controlled by the policy and still simulated (not terminated, not
    /// exited); the imitation loss is taken where this and the log are both valid.
    pub simulated: Tensor<3, Bool>,
    /// `[B, N, T]`: infraction flags of the transition into step t + 1, controlled agents
    /// only (a hero's infraction ends its run but is not the policy's).
    pub collision: Tensor<3, Bool>,
    pub offroad: Tensor<3, Bool>,
    /// `[B, N, T]`: the collisions of `collision` in which the agent was struck from behind
    /// ([`crate::sim::infractions::StepInfractions::struck_from_behind`]).
    pub struck_from_behind: Tensor<3, Bool>,
    /// `[B, N, T]`: -1 on an infraction, else 0.
    pub rewards: Tensor<3>,
    /// `[B, N, T + 1]`: raw controls applied at each step (last entry repeats).
    pub actions: Tensor<4>,
    pub steps: usize,
}

fn bool_tensor<const D: usize>(
    data: Vec<bool>,
    shape: [usize; D],
    device: &Device,
) -> Tensor<D, Bool> {
    Tensor::from_data(TensorData::new(data, shape), device)
}

fn to_f32(t: &Tensor<2>) -> Vec<f32> {
    t.to_data()
        .convert::<f32>()
        .try_into_vec::<f32>()
        .unwrap_or_default()
}

fn to_bool(t: &Tensor<2, Bool>) -> Vec<bool> {
    t.to_data().try_into_vec_as::<bool>().unwrap_or_default()
}

/// The logged frames of `batch` from its first step through `step`: what a policy sees before
/// any simulation, and at any step of open-loop (behaviour cloning) training.
pub fn logged_frames(batch: &SceneBatch, step: usize) -> Vec<Frame> {
    let [b, n, t_total, _] = batch.agent_states.dims();
    (0..=step.min(t_total - 1))
        .map(|t| Frame {
            poses: batch
                .agent_states
                .clone()
                .narrow(2, t, 1)
                .narrow(3, 0, FRAME_FEATURES)
                .reshape([b, n, FRAME_FEATURES]),
            present: batch.agent_valid.clone().narrow(2, t, 1).reshape([b, n]),
        })
        .collect()
}

/// Unrolls `policy` from the batch's current step, starting from the logged state.
pub fn rollout(
    scenes: &[&Scene],
    batch: &SceneBatch,
    dynamics: &Dynamics,
    policy: &mut dyn Policy,
    caches: &mut MapCaches,
    config: &RolloutConfig,
) -> Result<Rollout> {
    rollout_from(scenes, batch, dynamics, policy, caches, config, None)
}

/// As [`rollout`], but the controlled agents start from `initial` (rear-axle state, e.g. the
/// kinematically consistent state of the inverse model) instead of the logged one.
pub fn rollout_from(
    scenes: &[&Scene],
    batch: &SceneBatch,
    dynamics: &Dynamics,
    policy: &mut dyn Policy,
    caches: &mut MapCaches,
    config: &RolloutConfig,
    initial: Option<VehicleState>,
) -> Result<Rollout> {
    let [b, n, t_total, _] = batch.agent_states.dims();
    if scenes.len() != b {
        return Err(Error::InvalidArgument(format!(
            "rollout got {} scenes for a batch of {b}",
            scenes.len()
        )));
    }
    let device = batch.agent_states.device();
    let h = batch.history_steps;
    let steps = config.steps.unwrap_or(batch.future_steps);
    let maps: Vec<MapCache> = scenes.iter().map(|s| caches.get(&s.map)).collect();

    let at = |t: usize| -> Tensor<3> {
        batch
            .agent_states
            .clone()
            .narrow(2, t.min(t_total - 1), 1)
            .reshape([b, n, 5])
    };
    let feature = |s: &Tensor<3>, f: usize| s.clone().narrow(2, f, 1).reshape([b, n]);
    let valid_at = |t: usize| -> Tensor<2, Bool> {
        if t < t_total {
            batch.agent_valid.clone().narrow(2, t, 1).reshape([b, n])
        } else {
            Tensor::<2>::zeros([b, n], &device).greater_elem(1.0)
        }
    };
    let length = batch.agent_size.clone().narrow(2, 0, 1).reshape([b, n]);
    let width = batch.agent_size.clone().narrow(2, 1, 1).reshape([b, n]);
    // Padding agents have length 0: give them a harmless wheelbase so no NaN appears anywhere.
    let wheelbase = length.clone().mul_scalar(WHEELBASE_RATIO).clamp_min(1.0);
    let (length_v, width_v) = (to_f32(&length), to_f32(&width));
    let controlled = to_bool(&batch.agent_controlled);
    // Simulated through the dynamics: the policy's agents and the scripted heroes.
    let driven: Vec<bool> = controlled
        .iter()
        .zip(to_bool(&batch.agent_hero))
        .map(|(c, h)| *c || h)
        .collect();
    let log_valid: Vec<bool> = batch
        .agent_valid
        .to_data()
        .try_into_vec_as::<bool>()
        .unwrap_or_default();

    let logged_state = |t: usize| {
        let s = at(t);
        VehicleState::from_centre(
            feature(&s, 0),
            feature(&s, 1),
            feature(&s, 2),
            feature(&s, 3),
            &wheelbase,
        )
    };
    let pose_of = |s: &VehicleState| -> Tensor<3> {
        let (cx, cy) = s.centre(&wheelbase);
        Tensor::stack(vec![cx, cy, s.heading.clone(), s.speed.clone()], 2)
    };

    let mut frames = logged_frames(batch, h);

    let zero_controls = Controls {
        accel: Tensor::zeros([b, n], &device),
        steer: Tensor::zeros([b, n], &device),
    };
    let start = match initial {
        Some(given) => {
            let controlled_t = batch.agent_controlled.clone();
            logged_state(h).select(&controlled_t.bool_not(), given)
        }
        None => logged_state(h),
    };
    let mut state = dynamics.init_aux(start, &zero_controls);
    let mut present = to_bool(&valid_at(h));
    // Driven agents still simulated.
    let mut alive: Vec<bool> = present.iter().zip(&driven).map(|(p, c)| *p && *c).collect();

    let mut poses = vec![pose_of(&state)];
    let mut present_hist = vec![present.clone()];
    // The policy's agents only: a scripted hero is driven, never the policy's.
    let mut simulated_hist = vec![
        alive
            .iter()
            .zip(&controlled)
            .map(|(a, c)| *a && *c)
            .collect::<Vec<bool>>(),
    ];
    let (mut collision_hist, mut offroad_hist) = (Vec::new(), Vec::new());
    let mut struck_hist = Vec::new();
    let mut actions = Vec::new();

    let mut previous_centres = BoxCentres::of(&poses[0]);
    for k in 0..steps {
        let command = policy.act(&Observation {
            batch,
            step: k,
            frames: &frames,
            state: &state,
            wheelbase: &wheelbase,
        });
        actions.push(command.stacked());
        let stepped = dynamics.step(&state, &command, &wheelbase);
        // Replayed agents (and anything not alive) follow the log where it has them; dead
        // controlled agents stay frozen where they stopped.
        let t_next = h + k + 1;
        let replay: Vec<bool> = (0..b * n)
            .map(|i| !driven[i] && t_next < t_total && log_valid[i * t_total + t_next])
            .collect();
        // Tensor selects only when some agent needs them (the common case has none).
        let frozen = if replay.iter().any(|&r| r) {
            let replay_t = bool_tensor(replay.clone(), [b, n], &device);
            let log_next = dynamics.init_aux(logged_state(t_next), &zero_controls);
            state.clone().select(&replay_t.bool_not(), log_next)
        } else {
            state.clone()
        };
        state = if alive.iter().all(|&a| a) {
            stepped
        } else {
            stepped.select(&bool_tensor(alive.clone(), [b, n], &device), frozen)
        };

        let pose = pose_of(&state);
        // One read-back per step for the (non-differentiated) infraction checks.
        let centres = BoxCentres::of(&pose);
        let before = std::mem::replace(
            &mut present,
            (0..b * n).map(|i| alive[i] || replay[i]).collect(),
        );
        let flags = check_step(
            &centres.boxes(n, &length_v, &width_v, &present),
            Some(&previous_centres.boxes(n, &length_v, &width_v, &before)),
            &maps,
        );
        previous_centres = centres;
        let mut collision = vec![false; b * n];
        let mut offroad = vec![false; b * n];
        let mut struck = vec![false; b * n];
        for i in 0..b * n {
            if !alive[i] {
                continue;
            }
            if flags.exited[i] {
                alive[i] = false;
                present[i] = false;
                continue;
            }
            collision[i] = flags.collision[i] && controlled[i];
            offroad[i] = flags.offroad[i] && controlled[i];
            struck[i] = flags.struck_from_behind[i] && controlled[i];
            if config.early_termination && (flags.collision[i] || flags.offroad[i]) {
                // Present at the infraction step, removed from the next one.
                alive[i] = false;
            }
        }
        frames.push(Frame {
            poses: pose.clone(),
            present: bool_tensor(present.clone(), [b, n], &device),
        });
        poses.push(pose);
        present_hist.push(present.clone());
        simulated_hist.push((0..b * n).map(|i| controlled[i] && present[i]).collect());
        collision_hist.push(collision);
        offroad_hist.push(offroad);
        struck_hist.push(struck);
    }
    if let Some(last) = actions.last().cloned() {
        actions.push(last);
    } else {
        actions.push(zero_controls.stacked());
    }

    let stack_time = |v: Vec<Vec<bool>>| -> Tensor<3, Bool> {
        let t = v.len();
        let mut data = vec![false; b * n * t];
        for (k, row) in v.iter().enumerate() {
            for i in 0..b * n {
                data[i * t + k] = row[i];
            }
        }
        bool_tensor(data, [b, n, t], &device)
    };
    let collision = stack_time(collision_hist);
    let offroad = stack_time(offroad_hist);
    let rewards = Tensor::<3>::zeros(collision.dims(), &device)
        .mask_fill(collision.clone().bool_or(offroad.clone()), -1.0);
    Ok(Rollout {
        poses: Tensor::stack(poses, 2),
        present: stack_time(present_hist),
        simulated: stack_time(simulated_hist),
        collision,
        offroad,
        struck_from_behind: stack_time(struck_hist),
        rewards,
        actions: Tensor::stack(actions, 2),
        steps,
    })
}

/// Host copies of one step's box centres and headings, `[B * N]` row-major (the infraction
/// checks run on the CPU).
struct BoxCentres {
    cx: Vec<f32>,
    cy: Vec<f32>,
    heading: Vec<f32>,
}

impl BoxCentres {
    /// From a `[B, N, FRAME_FEATURES]` pose tensor.
    fn of(pose: &Tensor<3>) -> Self {
        let host = pose
            .to_data()
            .convert::<f32>()
            .try_into_vec::<f32>()
            .unwrap_or_default();
        let channel = |c: usize| -> Vec<f32> {
            host.iter()
                .skip(c)
                .step_by(FRAME_FEATURES)
                .copied()
                .collect()
        };
        Self {
            cx: channel(0),
            cy: channel(1),
            heading: channel(2),
        }
    }

    fn boxes<'a>(
        &'a self,
        agents: usize,
        length: &'a [f32],
        width: &'a [f32],
        present: &'a [bool],
    ) -> StepBoxes<'a> {
        StepBoxes {
            agents,
            cx: &self.cx,
            cy: &self.cy,
            heading: &self.heading,
            length,
            width,
            present,
        }
    }
}
