//! One optimizer step's losses: which terms a method takes and with which weights
//! ([`LossPlan`]), the counts each term is divided by over the whole minibatch
//! ([`MinibatchStatistics`]), and one device's gradient of its share ([`shard_gradients`]).

use std::ops::AddAssign;

use burn::optim::GradientsParams;
use burn::prelude::*;

use super::agent_dropout::drop_agents;
use super::config::{Method, PpoVariant, TrainConfig};
use super::experience::Experience;
use super::gradients::{GraphLoss, GraphwiseGradients};
use super::imitation::{BcLabels, behaviour_cloning, closed_loop_imitation, imitation_count};
use super::ppo::{AdvantageScale, ppo_terms};
use super::sources::Part;
use crate::error::Result;
use crate::model::{PolicyNetwork, ValueNetwork};
use crate::scene::{Scene, SceneBatch};
use crate::sim::{Dynamics, MapCaches};

/// The scenes an imitation rollout of `part` starts from in `iteration`: agents dropped and
/// histories perturbed as `config.imitation` asks; `None`: the part's scenes as recorded. The
/// draws are seeded, so every call for the same part and iteration gives the same scenes.
pub(super) fn imitation_scenes(
    config: &TrainConfig,
    part: &Part,
    iteration: usize,
) -> Option<Vec<Scene>> {
    let imitation = &config.imitation;
    let mut scenes = (imitation.agent_dropout > 0.0).then(|| {
        drop_agents(
            &part.scenes,
            &part.slots,
            imitation.agent_dropout,
            config.seed,
            iteration,
        )
    });
    if let Some(perturbation) = imitation.perturbation {
        let starts: Vec<&Scene> = match &scenes {
            Some(scenes) => scenes.iter().collect(),
            None => part.scenes.clone(),
        };
        scenes = Some(perturbation.apply(&starts, &part.slots, config.seed, iteration));
    }
    scenes
}

/// Steps a part is rolled out for.
pub(super) fn rollout_steps(part: &Part, cap: Option<usize>) -> usize {
    let future = part.scenes.first().map_or(0, |s| s.future_steps);
    cap.map_or(future, |c| c.min(future))
}

/// One part of a minibatch as one device sees it.
pub(super) struct Work<'a> {
    pub part: Part<'a>,
    pub experience: Option<Experience>,
    pub labels: Option<BcLabels>,
}

/// Per-device results of one gradient computation.
pub(super) struct ShardGradients {
    pub policy: GradientsParams,
    pub value: Option<GradientsParams>,
}

/// Host values of the loss terms (already divided by their counts).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct TermValues {
    pub total: f64,
    pub il: f64,
    pub bc: f64,
    pub policy: f64,
    pub value: f64,
    pub kl: f64,
    pub clipped: usize,
    /// Summed over the PPO entries ([`super::ppo::Surrogate::approx_kl`]).
    pub approx_kl: f64,
}

impl AddAssign for TermValues {
    fn add_assign(&mut self, o: Self) {
        self.total += o.total;
        self.il += o.il;
        self.bc += o.bc;
        self.policy += o.policy;
        self.value += o.value;
        self.kl += o.kl;
        self.clipped += o.clipped;
        self.approx_kl += o.approx_kl;
    }
}

/// Weights of the PPO terms in one update.
#[derive(Debug, Clone, Copy)]
struct PpoWeights {
    policy: f64,
    value: f64,
    /// KL(pi || pi_ref) as a loss (KL-L).
    kl: f64,
}

impl PpoWeights {
    /// Some PPO term counts, so the stored observations are re-evaluated. RTR at lambda 0 has
    /// none, and building the unused graph anyway got its run killed for memory (24.4 GB during
    /// the value warm-up, when nothing else is differentiated).
    fn any(&self) -> bool {
        self.policy != 0.0 || self.value != 0.0 || self.kl != 0.0
    }

    /// A gradient reaches the policy (not during the value warm-up).
    fn policy_tracked(&self) -> bool {
        self.policy != 0.0 || self.kl != 0.0
    }
}

/// The counts every term is divided by, over the whole minibatch (known before any forward,
/// so shards on different devices add up to the single-device loss).
#[derive(Debug, Clone, Copy, Default)]
struct Normalisers {
    il: usize,
    bc: usize,
    ppo: usize,
    kl: usize,
}

/// Which loss terms one step takes and with which weights: decided once per step from the
/// method and the iteration.
#[derive(Debug, Clone, Copy)]
pub(super) struct LossPlan {
    /// Closed-loop imitation on the nominal parts (IL, RTR).
    imitation: bool,
    /// Behaviour cloning on the parts that carry labels (BC, BC+RL).
    cloning: bool,
    ppo: PpoWeights,
    /// The PPO terms include KL(pi || pi_ref) as a loss (KL-L).
    kl_loss: bool,
    /// During the value warm-up only the value loss is taken and only the value network steps.
    pub warming_up: bool,
    /// The method trains a value network.
    pub uses_value: bool,
}

impl LossPlan {
    pub fn of(config: &TrainConfig, iteration: usize) -> Self {
        let method = config.method;
        let uses_value = method.uses_ppo();
        let warming_up = uses_value && iteration < config.ppo.value_warmup_iterations;
        let policy_weight = if warming_up { 0.0 } else { 1.0 };
        let rl_weight = match method {
            Method::Rl | Method::RlShaped => 1.0,
            _ => config.lambda,
        };
        let kl_weight = config.reference.as_ref().map_or(0.0, |r| r.weight);
        Self {
            imitation: method.uses_closed_loop_il() && !warming_up,
            cloning: !warming_up,
            ppo: PpoWeights {
                policy: policy_weight * rl_weight,
                value: rl_weight * config.ppo.value_weight,
                kl: policy_weight * kl_weight,
            },
            kl_loss: method == Method::KlLoss,
            warming_up,
            uses_value,
        }
    }
}

/// What one step needs to know about its whole minibatch before any forward pass.
#[derive(Debug, Clone)]
pub(super) struct MinibatchStatistics {
    norm: Normalisers,
    /// Initial states in the minibatch.
    pub scenes: usize,
    /// The advantages' standardisation (`ppo.normalize_advantages`) over the minibatch.
    scale: AdvantageScale,
}

impl MinibatchStatistics {
    pub fn of(config: &TrainConfig, work: &[Vec<Work>], iteration: usize) -> Self {
        let method = config.method;
        let mut norm = Normalisers::default();
        let mut scenes = 0;
        let mut advantages: Vec<f32> = Vec::new();
        for w in work.iter().flatten() {
            scenes += w.part.scenes.len();
            if method.uses_closed_loop_il() && w.part.is_nominal() {
                let steps = rollout_steps(&w.part, config.data.max_rollout_steps);
                norm.il += match imitation_scenes(config, &w.part, iteration) {
                    Some(scenes) => imitation_count(&scenes.iter().collect::<Vec<_>>(), steps),
                    None => imitation_count(&w.part.scenes, steps),
                };
            }
            if let Some(labels) = &w.labels {
                norm.bc += labels.count;
            }
            if let Some(e) = &w.experience {
                let (alive, adv) = match config.ppo.variant {
                    PpoVariant::Factorized => (e.alive.clone(), e.advantages.clone()),
                    PpoVariant::SceneLevel => (e.scene_alive.clone(), e.scene_advantages.clone()),
                };
                norm.ppo += alive.clone().int().sum().into_scalar::<i64>() as usize;
                norm.kl += e.stats.agent_steps;
                if config.ppo.normalize_advantages {
                    advantages.extend(AdvantageScale::alive_values(adv, alive));
                }
            }
        }
        Self {
            norm,
            scenes,
            scale: AdvantageScale::of(&advantages),
        }
    }

    /// The PPO entries of the minibatch (alive agent-steps; scene-steps for the scene-level
    /// variant).
    pub fn ppo_entries(&self) -> usize {
        self.norm.ppo
    }
}

/// What every device's share of one step shares.
pub(super) struct StepContext<'c> {
    pub config: &'c TrainConfig,
    pub plan: LossPlan,
    pub minibatch: &'c MinibatchStatistics,
    pub iteration: usize,
    pub dynamics: &'c Dynamics,
}

/// One device's gradient of its parts' losses, the terms' values, and the parts back. Each
/// graph is differentiated as soon as it is built (only one is alive at a time); a non-finite
/// loss stops the shard before any backward of it (no gradients).
pub(super) fn shard_gradients<'a>(
    ctx: &StepContext,
    policy: &PolicyNetwork,
    value: &ValueNetwork,
    work: Vec<Work<'a>>,
    device: &Device,
    caches: &mut MapCaches,
) -> Result<(Option<ShardGradients>, TermValues, Vec<Work<'a>>)> {
    let mut terms = TermValues::default();
    let mut gradients = GraphwiseGradients::new(policy, ctx.plan.uses_value.then_some(value));
    let mut differentiate = |loss: GraphLoss, terms: &mut TermValues| -> bool {
        terms.total += loss.value;
        if !loss.value.is_finite() {
            return false;
        }
        gradients.backward(loss);
        true
    };
    for w in &work {
        if let Some(loss) = imitation_loss(ctx, policy, w, device, caches, &mut terms)?
            && !differentiate(loss, &mut terms)
        {
            return Ok((None, terms, work));
        }
        if let Some(loss) = cloning_loss(ctx, policy, w, device, &mut terms)?
            && !differentiate(loss, &mut terms)
        {
            return Ok((None, terms, work));
        }
        if let Some(loss) = ppo_loss(ctx, policy, value, w, &mut terms)
            && !differentiate(loss, &mut terms)
        {
            return Ok((None, terms, work));
        }
    }
    // Where no term had weight (RTR at lambda 0 during the value warm-up: the value loss is
    // weighted by lambda, the policy waits) the gradients are empty.
    let (policy, value) = gradients.finish();
    Ok((Some(ShardGradients { policy, value }), terms, work))
}

/// Closed-loop imitation of a nominal part: rolled out again with the current parameters
/// (from perturbed or thinned start states where `[imitation]` asks).
fn imitation_loss(
    ctx: &StepContext,
    policy: &PolicyNetwork,
    w: &Work,
    device: &Device,
    caches: &mut MapCaches,
    terms: &mut TermValues,
) -> Result<Option<GraphLoss>> {
    if !(ctx.plan.imitation && w.part.is_nominal()) {
        return Ok(None);
    }
    let config = ctx.config;
    let changed = imitation_scenes(config, &w.part, ctx.iteration);
    let scenes: Vec<&Scene> = match &changed {
        Some(scenes) => scenes.iter().collect(),
        None => w.part.scenes.clone(),
    };
    let batch = match (&w.experience, &changed) {
        (Some(e), None) => e.batch.clone(),
        _ => SceneBatch::from_scenes(&scenes, &device.clone().inner())?,
    };
    let sum = closed_loop_imitation(
        policy,
        &scenes,
        &batch,
        ctx.dynamics,
        caches,
        rollout_steps(&w.part, config.data.max_rollout_steps),
        &config.imitation,
    )?;
    let mut loss = GraphLoss::default();
    terms.il += loss.add(sum, ctx.minibatch.norm.il, 1.0).unwrap_or(0.0);
    Ok(Some(loss))
}

/// Behaviour cloning of a part's logged actions.
fn cloning_loss(
    ctx: &StepContext,
    policy: &PolicyNetwork,
    w: &Work,
    device: &Device,
    terms: &mut TermValues,
) -> Result<Option<GraphLoss>> {
    let Some(labels) = w.labels.as_ref().filter(|_| ctx.plan.cloning) else {
        return Ok(None);
    };
    let batch = match &w.experience {
        Some(e) => e.batch.clone(),
        None => SceneBatch::from_scenes(&w.part.scenes, &device.clone().inner())?,
    };
    let mut loss = GraphLoss::default();
    let sum = behaviour_cloning(policy, &batch, labels);
    terms.bc += loss.add(sum, ctx.minibatch.norm.bc, 1.0).unwrap_or(0.0);
    Ok(Some(loss))
}

/// The PPO terms (policy, value, and KL-L's KL) of a part's collected experience.
fn ppo_loss(
    ctx: &StepContext,
    policy: &PolicyNetwork,
    value: &ValueNetwork,
    w: &Work,
    terms: &mut TermValues,
) -> Option<GraphLoss> {
    let weights = ctx.plan.ppo;
    let e = w.experience.as_ref().filter(|_| weights.any())?;
    let norm = &ctx.minibatch.norm;
    // The policy, value and KL terms share the policy's forward pass; during the value
    // warm-up it is taken without a graph (no gradient reaches it).
    let ppo_policy = if weights.policy_tracked() {
        policy.clone()
    } else {
        policy.clone().no_grad()
    };
    let t = ppo_terms(
        &ppo_policy,
        value,
        e,
        &ctx.config.ppo,
        ctx.minibatch.scale,
        ctx.plan.kl_loss,
    );
    terms.clipped += t.clipped;
    terms.approx_kl += t.approx_kl;
    let mut loss = GraphLoss::default();
    terms.policy += loss
        .add(t.policy.sum, norm.ppo, weights.policy)
        .unwrap_or(0.0);
    terms.value += loss
        .add(t.value.sum, norm.ppo, weights.value)
        .unwrap_or(0.0);
    if let Some(kl) = t.kl {
        terms.kl += loss.add(kl.sum, norm.kl, weights.kl).unwrap_or(0.0);
    }
    Some(loss)
}
