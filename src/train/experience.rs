//! Closed-loop experience for PPO: the policy samples actions for every controlled agent (the
//! heroes of long-tail scenes follow their scripts), and each step's log-probability and
//! value are kept with the inputs the policy saw, so the update can re-evaluate the same
//! observations under new parameters. Rewards, early termination and advantages are computed
//! here, per agent (factorized) and per scene (the ablation).
//!
//! Collection runs on the plain (non-autodiff) device with [`burn::module::Module::valid`]
//! copies of the networks: no graph is recorded for it.

use burn::prelude::*;
use burn::tensor::{Bool, TensorData};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use super::config::{Method, PpoConfig, ShapingConfig, TrainConfig};
use super::gae::gae;
use super::shaping::speed_shaping;
use super::sources::Part;
use crate::error::Result;
use crate::model::{
    ActionDistribution, AgentInput, EncodedLanes, LaneInput, PolicyNetwork, ValueNetwork,
};
use crate::scenario::rollout_with_heroes;
use crate::scene::SceneBatch;
use crate::sim::{
    Controls, Dynamics, Frame, MapCaches, Observation, Policy, Rollout, RolloutConfig,
    logged_frames,
};

/// The networks a collection runs (plain-device copies).
pub struct CollectNetworks<'n> {
    pub policy: &'n PolicyNetwork,
    pub value: &'n ValueNetwork,
    /// The frozen policy of KL-L / KL-R.
    pub reference: Option<&'n PolicyNetwork>,
}

/// How rewards are formed.
#[derive(Debug, Clone)]
pub struct RewardSettings {
    /// RL-Shaped's speed-limit term.
    pub shaping: Option<ShapingConfig>,
    /// KL-R: reward -= weight x (log pi(a) - log pi_ref(a)) per agent-step, a sample of
    /// KL(pi || pi_ref).
    pub kl_weight: Option<f64>,
}

impl RewardSettings {
    /// The reward `config`'s method trains on: the speed-limit term for RL-Shaped, the KL
    /// term (with the reference's weight) for KL-R, the sparse infraction reward alone else.
    pub fn of(config: &TrainConfig) -> Self {
        Self {
            shaping: (config.method == Method::RlShaped).then(|| config.shaping.clone()),
            kl_weight: (config.method == Method::KlReward)
                .then(|| config.reference.as_ref().map_or(0.0, |r| r.weight)),
        }
    }
}

/// What a collection reports (for curves).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CollectStats {
    /// Controlled agents at the start.
    pub agents: usize,
    pub collided: usize,
    pub offroad: usize,
    /// Agent-steps alive (the PPO sample count).
    pub agent_steps: usize,
    /// Sum of the rewards PPO sees.
    pub reward_sum: f64,
}

impl std::ops::AddAssign for CollectStats {
    fn add_assign(&mut self, o: Self) {
        self.agents += o.agents;
        self.collided += o.collided;
        self.offroad += o.offroad;
        self.agent_steps += o.agent_steps;
        self.reward_sum += o.reward_sum;
    }
}

/// One collected part, ready for PPO updates.
pub struct Experience {
    pub batch: SceneBatch,
    /// The batch's lane graph as the networks see it.
    pub lanes: LaneInput,
    /// Per step, what the policy saw (inputs and graph edges: fixed by the rollout, so the
    /// update re-evaluates them under new parameters without rebuilding them).
    pub observations: Vec<AgentInput>,
    pub steps: usize,
    /// Per step, `[B, N, 2]` raw sampled actions.
    pub actions: Vec<Tensor<3>>,
    /// `[B, N, T]`.
    pub old_log_prob: Tensor<3>,
    /// `[B, N, T]`: the agent acted at that step (alive, not early-terminated).
    pub alive: Tensor<3, Bool>,
    pub advantages: Tensor<3>,
    pub returns: Tensor<3>,
    /// `[B, 1, T]`: scene-level counterparts (any agent alive; summed rewards and values).
    pub scene_alive: Tensor<3, Bool>,
    pub scene_advantages: Tensor<3>,
    pub scene_returns: Tensor<3>,
    /// Per step, the frozen policy's distribution (KL-L).
    pub reference: Vec<ActionDistribution>,
    /// `ppo.noise_correlation`, and per step the `[B, N, 2]` standardised noise each agent
    /// carried into it (empty when the noise is independent): the part of the agent's state
    /// the policy's Normal is conditioned on ([`ActionDistribution::following`]).
    pub noise_correlation: [f64; 2],
    pub previous_noise: Vec<Tensor<3>>,
    /// `ppo.explored_controls()`: the controls sampled (the others follow the mean) and
    /// counted in `old_log_prob`.
    pub explored: [bool; 2],
    pub stats: CollectStats,
}

impl Experience {
    /// The policy's distribution at step `t` as it was sampled: conditioned on the agents'
    /// previous noise when that is correlated.
    pub fn as_sampled(&self, t: usize, dist: ActionDistribution) -> ActionDistribution {
        match self.previous_noise.get(t) {
            Some(z) => dist.following(z.clone(), self.noise_correlation),
            None => dist,
        }
    }
}

/// The frames of a finished rollout: the batch's logged history, then every simulated step.
pub fn rollout_frames(batch: &SceneBatch, out: &Rollout) -> Vec<Frame> {
    let [b, n, t1, _] = out.poses.dims();
    let mut frames = logged_frames(batch, batch.history_steps);
    for k in 1..t1 {
        frames.push(Frame {
            poses: out.poses.clone().narrow(2, k, 1).reshape([b, n, 4]),
            present: out.present.clone().narrow(2, k, 1).reshape([b, n]),
        });
    }
    frames
}

/// Standard normal action noise from one seeded host generator per scene, so a scene samples
/// the same actions whatever it is batched with, on however many devices, in any order (a
/// device's global RNG could promise none of this).
struct HostNoise {
    /// Per scene: its generator and its number of agents.
    scenes: Vec<(ChaCha8Rng, usize)>,
}

impl HostNoise {
    fn new(scenes: &[&crate::scene::Scene], slots: &[usize], seed: u64) -> Self {
        Self {
            scenes: scenes
                .iter()
                .zip(slots)
                .map(|(s, &slot)| {
                    let seed = seed ^ (slot as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
                    (ChaCha8Rng::seed_from_u64(seed), s.agents.len())
                })
                .collect(),
        }
    }

    /// `[B, N, 2]` values; padding slots get 0.
    fn normal(&mut self, n: usize) -> Vec<f32> {
        use rand::Rng;
        let mut out = vec![0.0f32; self.scenes.len() * n * 2];
        for (b, (rng, agents)) in self.scenes.iter_mut().enumerate() {
            for v in &mut out[b * n * 2..(b * n + *agents) * 2] {
                // Box-Muller: rand 0.9 keeps its Normal in a separate crate; two lines do.
                let u1: f64 = 1.0 - rng.random::<f64>();
                let u2: f64 = rng.random::<f64>();
                *v = ((-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()) as f32;
            }
        }
        out
    }
}

/// Each agent's exploration noise as an AR(1) process (`ppo.noise_correlation`): the
/// standardised noise z every agent carries from one step to the next.
struct CorrelatedNoise {
    /// Per control.
    rho: [f64; 2],
    /// Row-major `[B, N, 2]`; `None` before the first step, which draws it from N(0, 1), the
    /// process's stationary law, so every step's noise has the same marginal.
    carried: Option<Vec<f32>>,
}

impl CorrelatedNoise {
    /// This step's previous noise z, and the carried noise for the next step
    /// `rho z + sqrt(1 - rho^2) eta`.
    fn step(&mut self, noise: &mut HostNoise, n: usize, eta: &[f32]) -> Vec<f32> {
        let previous = self.carried.take().unwrap_or_else(|| noise.normal(n));
        let rho = self.rho;
        let keep = rho.map(|r| (1.0 - r * r).sqrt());
        self.carried = Some(
            previous
                .iter()
                .zip(eta)
                .enumerate()
                .map(|(k, (&z, &e))| (rho[k % 2] * z as f64 + keep[k % 2] * e as f64) as f32)
                .collect(),
        );
        previous
    }
}

/// The sampling policy: records what PPO needs at every step.
struct Recorder<'n> {
    nets: &'n CollectNetworks<'n>,
    lanes: LaneInput,
    policy_lanes: EncodedLanes,
    value_lanes: EncodedLanes,
    reference_lanes: Option<EncodedLanes>,
    noise: HostNoise,
    correlated: Option<CorrelatedNoise>,
    /// Sampled controls; the others take the mean and leave the log-probabilities.
    explored: [bool; 2],
    observations: Vec<AgentInput>,
    actions: Vec<Tensor<3>>,
    log_probs: Vec<Tensor<2>>,
    values: Vec<Tensor<2>>,
    previous_noise: Vec<Tensor<3>>,
    reference: Vec<ActionDistribution>,
}

impl<'n> Recorder<'n> {
    fn new(
        nets: &'n CollectNetworks<'n>,
        batch: &SceneBatch,
        noise: HostNoise,
        ppo: &PpoConfig,
    ) -> Self {
        let noise_correlation = ppo.noise_correlation;
        let lanes = LaneInput::from_batch(batch, nets.policy.config());
        Self {
            policy_lanes: nets.policy.encode_lanes(&lanes),
            value_lanes: nets.value.encode_lanes(&lanes),
            reference_lanes: nets.reference.map(|r| r.encode_lanes(&lanes)),
            lanes,
            nets,
            noise,
            correlated: (noise_correlation != [0.0, 0.0]).then_some(CorrelatedNoise {
                rho: noise_correlation,
                carried: None,
            }),
            explored: ppo.explored_controls(),
            observations: Vec::new(),
            actions: Vec::new(),
            log_probs: Vec::new(),
            values: Vec::new(),
            previous_noise: Vec::new(),
            reference: Vec::new(),
        }
    }

    /// Per step, `[B, N]`: log pi(a) - log pi_ref(a) at the sampled action, the KL-R penalty.
    ///
    /// Its mean under pi is KL(pi || pi_ref), and unlike the exact KL of each step it depends
    /// on the action taken, so PPO's score-function gradient carries the KL's own gradient
    /// (the per-token penalty of RLHF, e.g. InstructGPT). With the exact KL in the reward
    /// nothing pulls the policy back to the reference: the KL grows, and since an infraction
    /// ends an agent's episode, leaving the road (-1 once) becomes the cheapest way out of it.
    fn sampled_log_ratios(&self) -> Vec<Tensor<2>> {
        self.log_probs
            .iter()
            .zip(&self.reference)
            .zip(&self.actions)
            .map(|((log_prob, reference), action)| {
                log_prob.clone() - reference.log_prob_of(action.clone(), self.explored)
            })
            .collect()
    }

    fn value_of(&self, agents: &AgentInput) -> Tensor<2> {
        self.nets
            .value
            .forward(agents, &self.lanes, &self.value_lanes)
    }
}

impl Policy for Recorder<'_> {
    fn act(&mut self, obs: &Observation) -> Controls {
        let agents = AgentInput::from_frames(obs.batch, obs.frames, self.nets.policy.config());
        let dist = self
            .nets
            .policy
            .forward(&agents, &self.lanes, &self.policy_lanes);
        let dims = dist.mean.dims();
        let device = dist.mean.device();
        let mut eta = self.noise.normal(dims[1]);
        for (k, e) in eta.iter_mut().enumerate() {
            if !self.explored[k % 2] {
                *e = 0.0;
            }
        }
        // With correlated noise both the policy and the reference are conditioned on the
        // agents' previous noise, so PPO's ratios and KL-R's log-ratios compare like with like.
        let previous = self.correlated.as_mut().map(|c| {
            let z = c.step(&mut self.noise, dims[1], &eta);
            (
                Tensor::<3>::from_data(TensorData::new(z, dims), &device),
                c.rho,
            )
        });
        let condition = |d: ActionDistribution| match &previous {
            Some((z, rho)) => d.following(z.clone(), *rho),
            None => d,
        };
        let dist = condition(dist);
        let eta = Tensor::<3>::from_data(TensorData::new(eta, dims), &device);
        let action = dist.mean.clone() + dist.std() * eta;
        self.log_probs
            .push(dist.log_prob_of(action.clone(), self.explored));
        self.values.push(self.value_of(&agents));
        if let (Some(reference), Some(lanes)) = (self.nets.reference, &self.reference_lanes) {
            self.reference
                .push(condition(reference.forward(&agents, &self.lanes, lanes)));
        }
        if let Some((z, _)) = previous {
            self.previous_noise.push(z);
        }
        self.observations.push(agents);
        self.actions.push(action.clone());
        Controls::from_stacked(action)
    }
}

fn host_f32<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.into_data()
        .convert::<f32>()
        .try_into_vec::<f32>()
        .unwrap_or_default()
}

fn host_bool<const D: usize>(t: Tensor<D, Bool>) -> Vec<bool> {
    t.into_data().try_into_vec_as::<bool>().unwrap_or_default()
}

/// Which agent-steps are alive: `simulated` `[B*N, T+1]` (controlled and on the road) cut after
/// the first step that ends the agent's episode (`ends[i][t]`: the transition t -> t+1 was an
/// infraction or a shaping termination). Row-major `[B*N][T+1]`.
pub fn alive_steps(simulated: &[bool], ends: &[bool], agents: usize, steps: usize) -> Vec<bool> {
    let mut alive = vec![false; agents * (steps + 1)];
    for i in 0..agents {
        let row = i * (steps + 1);
        alive[row] = simulated[row];
        for t in 0..steps {
            alive[row + t + 1] = alive[row + t] && simulated[row + t + 1] && !ends[i * steps + t];
        }
    }
    alive
}

/// Per transition t of one agent (T entries), the value its episode is bootstrapped with when
/// the episode was cut by something it did not do (`alive` `[T+1]`, `ends` `[T]`, `values`
/// `[T+1]`): V(s_t), the last value it had, because the state after no longer holds the agent.
/// - With `bootstrap_exits`: it left the map after step t without an infraction or shaping
///   termination.
/// - `struck[t]`: it was struck from behind on that transition and not penalised for it
///   (`ppo.at_fault_collisions`).
///
/// 0 elsewhere.
pub fn truncation_values(
    alive: &[bool],
    ends: &[bool],
    struck: &[bool],
    values: &[f64],
    bootstrap_exits: bool,
) -> Vec<f64> {
    (0..ends.len())
        .map(|t| {
            let exited = bootstrap_exits && alive[t] && !alive[t + 1] && !ends[t];
            if exited || (alive[t] && struck[t]) {
                values[t]
            } else {
                0.0
            }
        })
        .collect()
}

/// Per agent-transition, `[B*N][T]`: struck from behind and not otherwise in fault (not also
/// off the road), so `ppo.at_fault_collisions` waives its collision penalty. All false unless
/// `at_fault_collisions`.
fn waived_collisions(struck: &[bool], offroad: &[bool], at_fault_collisions: bool) -> Vec<bool> {
    struck
        .iter()
        .zip(offroad)
        .map(|(&s, &o)| at_fault_collisions && s && !o)
        .collect()
}

/// Rolls `part` out with sampled actions and computes rewards, advantages and returns.
#[allow(clippy::too_many_arguments)]
pub fn collect(
    part: &Part,
    nets: &CollectNetworks,
    device: &Device,
    dynamics: &Dynamics,
    caches: &mut MapCaches,
    max_steps: Option<usize>,
    ppo: &PpoConfig,
    rewards: &RewardSettings,
    seed: u64,
) -> Result<Experience> {
    let batch = SceneBatch::from_scenes(&part.scenes, device)?;
    let steps = max_steps.map_or(batch.future_steps, |m| m.min(batch.future_steps));
    let config = RolloutConfig {
        steps: Some(steps),
        early_termination: true,
    };
    let noise = HostNoise::new(&part.scenes, &part.slots, seed);
    let mut recorder = Recorder::new(nets, &batch, noise, ppo);
    let out = rollout_with_heroes(
        &part.scenarios,
        &part.scenes,
        &batch,
        dynamics,
        &mut recorder,
        caches,
        &config,
    )?;
    let frames = rollout_frames(&batch, &out);
    let final_agents = AgentInput::from_frames(&batch, &frames, nets.policy.config());
    recorder.values.push(recorder.value_of(&final_agents));

    let signals = Signals::read(&out, &recorder, part, ppo, rewards);
    let [b, n, _, _] = out.poses.dims();
    let targets = Targets::estimate(&signals, [b, n, steps], ppo);
    // Drop the last (state T) column: nobody acts there.
    let acting = |v: &[bool], rows: usize| -> Vec<bool> {
        (0..rows)
            .flat_map(|i| v[i * (steps + 1)..i * (steps + 1) + steps].to_vec())
            .collect()
    };
    let float = |v: Vec<f32>, rows: usize| {
        Tensor::<3>::from_data(TensorData::new(v, [b, rows / b, steps]), device)
    };
    let boolean = |v: Vec<bool>, rows: usize| {
        Tensor::<3, Bool>::from_data(TensorData::new(v, [b, rows / b, steps]), device)
    };
    Ok(Experience {
        old_log_prob: Tensor::stack(recorder.log_probs, 2),
        alive: boolean(acting(&signals.alive, b * n), b * n),
        advantages: float(targets.advantages, b * n),
        returns: float(targets.returns, b * n),
        scene_alive: boolean(acting(&targets.scene_alive, b), b),
        scene_advantages: float(targets.scene_advantages, b),
        scene_returns: float(targets.scene_returns, b),
        actions: recorder.actions,
        reference: recorder.reference,
        noise_correlation: ppo.noise_correlation,
        previous_noise: recorder.previous_noise,
        explored: recorder.explored,
        lanes: recorder.lanes,
        observations: recorder.observations,
        steps,
        batch,
        stats: targets.stats,
    })
}

/// Host copies of a collection's per agent-step signals, row-major `[B*N][T]` (`values` and
/// `alive`: `[B*N][T+1]`).
struct Signals {
    /// The reward PPO sees.
    reward: Vec<f64>,
    /// The transition ended the agent's episode (an infraction or a shaping termination).
    ends: Vec<bool>,
    /// Collisions whose penalty `ppo.at_fault_collisions` waives.
    waived: Vec<bool>,
    collision: Vec<bool>,
    offroad: Vec<bool>,
    values: Vec<f32>,
    alive: Vec<bool>,
}

impl Signals {
    fn read(
        out: &Rollout,
        recorder: &Recorder,
        part: &Part,
        ppo: &PpoConfig,
        rewards: &RewardSettings,
    ) -> Self {
        let [b, n, t1, _] = out.poses.dims();
        let (agents, steps) = (b * n, t1 - 1);
        let collision = host_bool(out.collision.clone());
        let offroad = host_bool(out.offroad.clone());
        let waived = waived_collisions(
            &host_bool(out.struck_from_behind.clone()),
            &offroad,
            ppo.at_fault_collisions,
        );
        // A waived collision still ends the episode (the car is gone), as a truncation.
        let mut reward: Vec<f64> = host_f32(out.rewards.clone())
            .iter()
            .zip(&waived)
            .map(|(&r, &w)| if w { 0.0 } else { r as f64 })
            .collect();
        let mut ends = host_bool(out.collision.clone().bool_or(out.offroad.clone()));
        if let Some(shaping) = &rewards.shaping {
            let speeds = host_f32(out.poses.clone().narrow(3, 3, 1).reshape([b, n, t1]));
            let centres = host_f32(out.poses.clone().narrow(3, 0, 3).reshape([b, n, t1, 3]));
            let terms = speed_shaping(&part.scenes, n, steps, &speeds, &centres, shaping);
            for (k, (bonus, end)) in terms.iter().enumerate() {
                reward[k] += bonus;
                ends[k] |= end;
            }
        }
        if let (Some(weight), false) = (rewards.kl_weight, recorder.reference.is_empty()) {
            let log_ratios = rows_by_agent(&recorder.sampled_log_ratios(), agents);
            for (r, k) in reward.iter_mut().zip(log_ratios) {
                *r -= weight * k as f64;
            }
        }
        let simulated = host_bool(out.simulated.clone());
        Self {
            alive: alive_steps(&simulated, &ends, agents, steps),
            values: rows_by_agent(&recorder.values, agents),
            reward,
            ends,
            waived,
            collision,
            offroad,
        }
    }
}

/// Row-major `[agents][T]` host copy of per-step `[B, N]` tensors.
fn rows_by_agent(per_step: &[Tensor<2>], agents: usize) -> Vec<f32> {
    let t = per_step.len();
    let mut out = vec![0.0; agents * t];
    for (k, column) in per_step.iter().enumerate() {
        for (i, v) in host_f32(column.clone())
            .into_iter()
            .enumerate()
            .take(agents)
        {
            out[i * t + k] = v;
        }
    }
    out
}

/// Advantages and returns per agent (factorized, `[B*N][T]`) and per scene (the ablation:
/// summed rewards and values, `[B][T]`), with the collection's statistics.
struct Targets {
    advantages: Vec<f32>,
    returns: Vec<f32>,
    /// `[B][T+1]`: some agent of the scene is alive.
    scene_alive: Vec<bool>,
    scene_advantages: Vec<f32>,
    scene_returns: Vec<f32>,
    stats: CollectStats,
}

impl Targets {
    fn estimate(s: &Signals, [b, n, steps]: [usize; 3], ppo: &PpoConfig) -> Self {
        let mut out = Self {
            advantages: vec![0.0; b * n * steps],
            returns: vec![0.0; b * n * steps],
            scene_alive: vec![false; b * (steps + 1)],
            scene_advantages: vec![0.0; b * steps],
            scene_returns: vec![0.0; b * steps],
            stats: CollectStats::default(),
        };
        let mut scene_reward = vec![0.0; b * steps];
        let mut scene_value = vec![0.0; b * (steps + 1)];
        let mut scene_truncation = vec![0.0; b * steps];
        for i in 0..b * n {
            let transitions = i * steps..(i + 1) * steps;
            let states = i * (steps + 1)..(i + 1) * (steps + 1);
            let (r, a) = (&s.reward[transitions.clone()], &s.alive[states.clone()]);
            if !a[0] {
                continue;
            }
            let v: Vec<f64> = s.values[states].iter().map(|&x| x as f64).collect();
            let truncation = truncation_values(
                a,
                &s.ends[transitions.clone()],
                &s.waived[transitions.clone()],
                &v,
                ppo.bootstrap_exits,
            );
            let est = gae(r, &v, a, &truncation, ppo.gamma, ppo.gae_lambda);
            let scene = i / n;
            for t in (0..steps).filter(|&t| a[t]) {
                out.advantages[i * steps + t] = est.advantages[t] as f32;
                out.returns[i * steps + t] = est.returns[t] as f32;
                out.stats.agent_steps += 1;
                out.stats.reward_sum += r[t];
                scene_reward[scene * steps + t] += r[t];
                scene_truncation[scene * steps + t] += truncation[t];
            }
            for t in (0..=steps).filter(|&t| a[t]) {
                scene_value[scene * (steps + 1) + t] += v[t];
                out.scene_alive[scene * (steps + 1) + t] = true;
            }
            out.stats.agents += 1;
            out.stats.collided += usize::from(s.collision[transitions.clone()].contains(&true));
            out.stats.offroad += usize::from(s.offroad[transitions].contains(&true));
        }
        for scene in 0..b {
            let (transitions, states) = (
                scene * steps..(scene + 1) * steps,
                scene * (steps + 1)..(scene + 1) * (steps + 1),
            );
            let est = gae(
                &scene_reward[transitions.clone()],
                &scene_value[states.clone()],
                &out.scene_alive[states],
                &scene_truncation[transitions.clone()],
                ppo.gamma,
                ppo.gae_lambda,
            );
            for (t, k) in transitions.enumerate() {
                out.scene_advantages[k] = est.advantages[t] as f32;
                out.scene_returns[k] = est.returns[t] as f32;
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_agent_is_dead_after_the_step_that_ends_it() {
        // Two agents, T = 3. Agent 0 collides on transition 1 -> 2 (still "simulated" at step 2,
        // where the rollout shows the crash); agent 1 exits the map after step 1.
        let simulated = [true, true, true, false, true, true, false, false];
        let ends = [false, true, false, false, false, false];
        let alive = alive_steps(&simulated, &ends, 2, 3);
        assert_eq!(alive, [true, true, false, false, true, true, false, false]);
    }

    #[test]
    fn only_an_exit_is_bootstrapped_and_only_when_asked() {
        // T = 3. Agent 0 exits after step 1; agent 1 collides on transition 1 -> 2.
        let values = [-0.2, -0.4, -0.6, -0.8];
        let exit = [true, true, false, false];
        let no_end = [false, false, false];
        let none = [false; 3];
        assert_eq!(
            truncation_values(&exit, &no_end, &none, &values, true),
            [0.0, -0.4, 0.0]
        );
        assert_eq!(
            truncation_values(&exit, &no_end, &none, &values, false),
            [0.0; 3]
        );
        let crash = [false, true, false];
        assert_eq!(
            truncation_values(&exit, &crash, &none, &values, true),
            [0.0; 3]
        );
        // Alive to the end: bootstrapped by GAE itself, not here.
        assert_eq!(
            truncation_values(&[true; 4], &no_end, &none, &values, true),
            [0.0; 3]
        );
        // Struck from behind on transition 1 -> 2 (an infraction that ends it, not its own).
        let crashed = [true, true, false, false];
        assert_eq!(
            truncation_values(&crashed, &crash, &crash, &values, false),
            [0.0, -0.4, 0.0]
        );
    }

    #[test]
    fn only_a_rear_struck_collision_on_the_road_is_waived_and_only_when_asked() {
        let struck = [true, true, false];
        let offroad = [false, true, false];
        assert_eq!(
            waived_collisions(&struck, &offroad, true),
            [true, false, false]
        );
        assert_eq!(waived_collisions(&struck, &offroad, false), [false; 3]);
    }
}
