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
use super::infractions::{MapCache, MapCaches, StepBoxes, StepInfractions, check_step};
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

impl Observation<'_> {
    /// Frame-free per-agent inputs for small policies (tests, benchmarks): `[B, N, 3]` =
    /// (speed / 30 m/s, sin heading, cos heading) of the current state.
    pub fn kinematic_features(&self) -> Tensor<3> {
        let h = self.state.heading.clone();
        Tensor::<2>::stack::<3>(
            vec![
                self.state.speed.clone().div_scalar(30.0),
                h.clone().sin(),
                h.cos(),
            ],
            2,
        )
    }
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
    let agents = LoggedAgents::new(batch);
    let [b, n, _] = agents.dims;
    if scenes.len() != b {
        return Err(Error::InvalidArgument(format!(
            "rollout got {} scenes for a batch of {b}",
            scenes.len()
        )));
    }
    let h = batch.history_steps;
    let steps = config.steps.unwrap_or(batch.future_steps);
    let maps: Vec<MapCache> = scenes.iter().map(|s| caches.get(&s.map)).collect();

    let mut frames = logged_frames(batch, h);
    let zero_controls = agents.zero_controls();
    let start = match initial {
        Some(given) => {
            let controlled_t = batch.agent_controlled.clone();
            agents.state_at(h).select(&controlled_t.bool_not(), given)
        }
        None => agents.state_at(h),
    };
    let mut state = dynamics.init_aux(start, &zero_controls);
    let mut present = agents.logged_present(h);
    // Driven agents still simulated.
    let mut alive: Vec<bool> = (0..b * n).map(|i| present[i] && agents.driven[i]).collect();
    let mut trace = Trace::start(agents.pose_of(&state), &present, &alive, &agents.controlled);
    let mut previous_centres = BoxCentres::of(&trace.poses[0]);
    for k in 0..steps {
        let command = policy.act(&Observation {
            batch,
            step: k,
            frames: &frames,
            state: &state,
            wheelbase: &agents.wheelbase,
        });
        trace.actions.push(command.stacked());
        let t_next = h + k + 1;
        let replay = agents.replayed_at(t_next);
        state = agents.advance(dynamics, &state, &command, &alive, &replay, t_next);

        let pose = agents.pose_of(&state);
        // One read-back per step for the (non-differentiated) infraction checks.
        let centres = BoxCentres::of(&pose);
        let before = std::mem::replace(
            &mut present,
            (0..b * n).map(|i| alive[i] || replay[i]).collect(),
        );
        let infractions = check_step(
            &centres.boxes(n, &agents.length, &agents.width, &present),
            Some(&previous_centres.boxes(n, &agents.length, &agents.width, &before)),
            &maps,
        );
        previous_centres = centres;
        let flags = StepFlags::apply(
            &infractions,
            &agents.controlled,
            config.early_termination,
            &mut alive,
            &mut present,
        );
        frames.push(Frame {
            poses: pose.clone(),
            present: bool_tensor(present.clone(), [b, n], &agents.device),
        });
        trace.record(pose, &present, &agents.controlled, flags);
    }
    Ok(trace.into_rollout(&agents, zero_controls, steps))
}

/// What a rollout reads from its batch once: sizes, wheelbases, and host copies of the masks.
struct LoggedAgents<'a> {
    batch: &'a SceneBatch,
    /// B, N and the logged steps.
    dims: [usize; 3],
    device: Device,
    /// `[B, N]` (m).
    wheelbase: Tensor<2>,
    /// Box lengths and widths, `[B * N]`.
    length: Vec<f32>,
    width: Vec<f32>,
    /// Driven by the policy.
    controlled: Vec<bool>,
    /// Simulated through the dynamics: the policy's agents and the scripted heroes.
    driven: Vec<bool>,
    /// `[B * N * T]`: the log has the agent at that step.
    log_valid: Vec<bool>,
}

impl<'a> LoggedAgents<'a> {
    fn new(batch: &'a SceneBatch) -> Self {
        let [b, n, t_total, _] = batch.agent_states.dims();
        let length = batch.agent_size.clone().narrow(2, 0, 1).reshape([b, n]);
        let width = batch.agent_size.clone().narrow(2, 1, 1).reshape([b, n]);
        let controlled = to_bool(&batch.agent_controlled);
        let driven = controlled
            .iter()
            .zip(to_bool(&batch.agent_hero))
            .map(|(c, h)| *c || h)
            .collect();
        Self {
            batch,
            dims: [b, n, t_total],
            device: batch.agent_states.device(),
            // Padding agents have length 0: give them a harmless wheelbase so no NaN appears
            // anywhere.
            wheelbase: length.clone().mul_scalar(WHEELBASE_RATIO).clamp_min(1.0),
            length: to_f32(&length),
            width: to_f32(&width),
            controlled,
            driven,
            log_valid: batch
                .agent_valid
                .to_data()
                .try_into_vec_as::<bool>()
                .unwrap_or_default(),
        }
    }

    /// The logged state at step `t` (the last logged step beyond the log).
    fn state_at(&self, t: usize) -> VehicleState {
        let [b, n, t_total] = self.dims;
        let s: Tensor<3> = self
            .batch
            .agent_states
            .clone()
            .narrow(2, t.min(t_total - 1), 1)
            .reshape([b, n, 5]);
        let feature = |f: usize| s.clone().narrow(2, f, 1).reshape([b, n]);
        VehicleState::from_centre(
            feature(0),
            feature(1),
            feature(2),
            feature(3),
            &self.wheelbase,
        )
    }

    /// `[B * N]`: the log has the agent at step `t`.
    fn logged_present(&self, t: usize) -> Vec<bool> {
        let t_total = self.dims[2];
        (0..self.length.len())
            .map(|i| t < t_total && self.log_valid[i * t_total + t])
            .collect()
    }

    /// `[B * N]`: agents that follow the log into step `t` (not driven, and logged then).
    fn replayed_at(&self, t: usize) -> Vec<bool> {
        let present = self.logged_present(t);
        (0..present.len())
            .map(|i| !self.driven[i] && present[i])
            .collect()
    }

    /// The state at step `t`: driven agents still alive step through the dynamics; replayed
    /// agents (and anything not alive) follow the log where it has them; dead driven agents
    /// stay frozen where they stopped.
    fn advance(
        &self,
        dynamics: &Dynamics,
        state: &VehicleState,
        command: &Controls,
        alive: &[bool],
        replay: &[bool],
        t: usize,
    ) -> VehicleState {
        let [b, n, _] = self.dims;
        let stepped = dynamics.step(state, command, &self.wheelbase);
        // Tensor selects only when some agent needs them (the common case has none).
        let frozen = if replay.iter().any(|&r| r) {
            let replay_t = bool_tensor(replay.to_vec(), [b, n], &self.device);
            let log_next = dynamics.init_aux(self.state_at(t), &self.zero_controls());
            state.clone().select(&replay_t.bool_not(), log_next)
        } else {
            state.clone()
        };
        if alive.iter().all(|&a| a) {
            stepped
        } else {
            stepped.select(&bool_tensor(alive.to_vec(), [b, n], &self.device), frozen)
        }
    }

    /// `[B, N, 4]`: box centre x, y, heading, speed.
    fn pose_of(&self, s: &VehicleState) -> Tensor<3> {
        let (cx, cy) = s.centre(&self.wheelbase);
        Tensor::stack(vec![cx, cy, s.heading.clone(), s.speed.clone()], 2)
    }

    fn zero_controls(&self) -> Controls {
        let [b, n, _] = self.dims;
        Controls {
            accel: Tensor::zeros([b, n], &self.device),
            steer: Tensor::zeros([b, n], &self.device),
        }
    }
}

/// One transition's infraction flags of the policy's agents, `[B * N]`.
struct StepFlags {
    collision: Vec<bool>,
    offroad: Vec<bool>,
    struck: Vec<bool>,
}

impl StepFlags {
    /// Keeps the controlled agents' flags and updates who is simulated: an agent that left
    /// the map is removed at once; with early termination, one with an infraction is present
    /// at the infraction step and removed from the next one.
    fn apply(
        infractions: &StepInfractions,
        controlled: &[bool],
        early_termination: bool,
        alive: &mut [bool],
        present: &mut [bool],
    ) -> Self {
        let count = alive.len();
        let mut flags = Self {
            collision: vec![false; count],
            offroad: vec![false; count],
            struck: vec![false; count],
        };
        for i in 0..count {
            if !alive[i] {
                continue;
            }
            if infractions.exited[i] {
                alive[i] = false;
                present[i] = false;
                continue;
            }
            flags.collision[i] = infractions.collision[i] && controlled[i];
            flags.offroad[i] = infractions.offroad[i] && controlled[i];
            flags.struck[i] = infractions.struck_from_behind[i] && controlled[i];
            if early_termination && (infractions.collision[i] || infractions.offroad[i]) {
                alive[i] = false;
            }
        }
        flags
    }
}

/// A rollout's per-step records, stacked over time at the end.
struct Trace {
    poses: Vec<Tensor<3>>,
    present: Vec<Vec<bool>>,
    simulated: Vec<Vec<bool>>,
    collision: Vec<Vec<bool>>,
    offroad: Vec<Vec<bool>>,
    struck: Vec<Vec<bool>>,
    actions: Vec<Tensor<3>>,
}

impl Trace {
    fn start(pose: Tensor<3>, present: &[bool], alive: &[bool], controlled: &[bool]) -> Self {
        Self {
            poses: vec![pose],
            present: vec![present.to_vec()],
            // The policy's agents only: a scripted hero is driven, never the policy's.
            simulated: vec![
                alive
                    .iter()
                    .zip(controlled)
                    .map(|(a, c)| *a && *c)
                    .collect(),
            ],
            collision: Vec::new(),
            offroad: Vec::new(),
            struck: Vec::new(),
            actions: Vec::new(),
        }
    }

    fn record(&mut self, pose: Tensor<3>, present: &[bool], controlled: &[bool], f: StepFlags) {
        self.poses.push(pose);
        self.present.push(present.to_vec());
        self.simulated.push(
            present
                .iter()
                .zip(controlled)
                .map(|(p, c)| *p && *c)
                .collect(),
        );
        self.collision.push(f.collision);
        self.offroad.push(f.offroad);
        self.struck.push(f.struck);
    }

    fn into_rollout(mut self, agents: &LoggedAgents, zero: Controls, steps: usize) -> Rollout {
        let [b, n, _] = agents.dims;
        let device = &agents.device;
        let last_action = self.actions.last().cloned();
        self.actions
            .push(last_action.unwrap_or_else(|| zero.stacked()));
        let stack_time = |v: Vec<Vec<bool>>| -> Tensor<3, Bool> {
            let t = v.len();
            let mut data = vec![false; b * n * t];
            for (k, row) in v.iter().enumerate() {
                for i in 0..b * n {
                    data[i * t + k] = row[i];
                }
            }
            bool_tensor(data, [b, n, t], device)
        };
        let collision = stack_time(self.collision);
        let offroad = stack_time(self.offroad);
        let rewards = Tensor::<3>::zeros(collision.dims(), device)
            .mask_fill(collision.clone().bool_or(offroad.clone()), -1.0);
        Rollout {
            poses: Tensor::stack(self.poses, 2),
            present: stack_time(self.present),
            simulated: stack_time(self.simulated),
            collision,
            offroad,
            struck_from_behind: stack_time(self.struck),
            rewards,
            actions: Tensor::stack(self.actions, 2),
            steps,
        }
    }
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
