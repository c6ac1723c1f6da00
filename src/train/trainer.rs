//! The training loop shared by every method (paper Algorithm 1 and its baselines).
//!
//! One *iteration* draws initial states from (1 - alpha) nominal + alpha long-tail with its own
//! seed, so a resumed run draws exactly what an uninterrupted one would:
//! - PPO methods collect `ppo.batch` closed-loop rollouts with sampled actions (old policy),
//!   then take one AdamW step per minibatch of `ppo.minibatch` initial states (for
//!   `ppo.epochs` passes). Each step's loss is the method's: RL / RL-Shaped: L_RL;
//!   BC+RL: L_BC + lambda L_RL; RTR: L_IL + lambda L_RL, where L_IL rolls the minibatch's
//!   nominal scenes out again with the current parameters (mean action; from perturbed
//!   start states when `imitation.perturbation` is set) and backpropagates through time;
//!   KL-L: lambda L_RL + w KL(pi || pi_ref); KL-R: lambda L_RL with -w (log pi(a) - log pi_ref(a))
//!   in the reward. L_RL = L_policy + c L_value (the value network has its own parameters and
//!   optimizer, so the policy loss never reaches it).
//! - BC and IL take one step per `imitation.minibatch` nominal initial states.
//!
//! An *epoch* is as many initial states as `optimizer.epoch_scenes` (default: the nominal
//! training set); the learning rate decays per epoch. Every minibatch is cut into buckets of
//! similar-size scenes spread over the devices (data parallel, [`super::shards`]): each device
//! computes its buckets' gradient on a fork of the networks, and the sums are added on the
//! first device before the step.

use std::path::{Path, PathBuf};
use std::time::Instant;

use burn::module::Module;
use burn::optim::{AdamWConfig, GradientsParams, ModuleOptimizer};

use burn::prelude::*;
use indicatif::ProgressBar;
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;

use super::checkpoint::{self, LoopState};
use super::config::{InitConfig, ReferenceConfig, TrainConfig};
use super::curves::{CurveRow, Curves};
use super::experience::{CollectNetworks, CollectStats, RewardSettings, collect};
use super::gradients::{clip_global_norm, sum_on_device};
use super::imitation::BcLabels;
use super::ppo::adapt_lr_scale;
use super::shards::{BUCKET_SCENES, per_device, plan};
use super::sources::{InitialState, Part, TrainingData};
use super::step::{
    LossPlan, MinibatchStatistics, ShardGradients, StepContext, TermValues, Work, rollout_steps,
    shard_gradients,
};
use crate::error::{Error, Result};
use crate::model::{ModelConfig, PolicyNetwork, ValueNetwork};
use crate::seeding::{DEVICE_RNG, Materialise, stream_seed, with_seeded_device};
use crate::sim::{Dynamics, MapCaches};

/// What a finished (or stopped) run reports.
#[derive(Debug, Clone)]
pub struct TrainSummary {
    pub iterations: usize,
    pub updates: usize,
    pub checkpoint: PathBuf,
    pub last: Option<CurveRow>,
}

pub struct Trainer<'d> {
    config: TrainConfig,
    data: &'d TrainingData,
    run_dir: PathBuf,
    /// Autodiff devices; the first holds the master parameters.
    devices: Vec<Device>,
    dynamics: Dynamics,
    policy: PolicyNetwork,
    value: ValueNetwork,
    policy_optimizer: ModuleOptimizer,
    value_optimizer: ModuleOptimizer,
    reference: Option<PolicyNetwork>,
    caches: Vec<MapCaches>,
    state: LoopState,
    curves: Curves,
    started: Instant,
    timing: IterationTiming,
    /// The policy has taken a step since this iteration's experience was collected.
    policy_stepped: bool,
}

/// Where the last iteration's wall time went (`rtr bench train`).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct IterationTiming {
    /// Closed-loop rollouts with sampled actions (PPO methods; no autodiff).
    pub collect_s: f64,
    /// Loss forward, backward and optimizer steps.
    pub update_s: f64,
}

/// Recorded nominal training scenes the warm start's sigma is measured on (every k-th, for a
/// spread).
const STD_SCENES: usize = 128;

/// The frozen policy of KL-L / KL-R that `[reference]` names, on `device` (not autodiff): a
/// checkpoint, or the warm start rebuilt as `[init]` builds it (rebuilt, not copied, so a
/// resumed run has the same one).
fn kl_reference(
    r: &ReferenceConfig,
    data: &TrainingData,
    config: &TrainConfig,
    device: &Device,
) -> Result<PolicyNetwork> {
    let blank = || PolicyNetwork::new(&config.model, device);
    // TrainConfig::validate refuses every other combination; a config built in code gets the
    // same message here.
    match (&r.checkpoint, r.init, &config.init, r.std_from_logs) {
        (Some(path), false, _, calibrate) => {
            // A model or run folder stands for its policy, as `[init] policy` takes one.
            let file = if path.is_dir() {
                path.join("policy.bpk")
            } else {
                path.clone()
            };
            let policy = checkpoint::load_module(blank(), &file)
                .map_err(|e| e.in_field("reference.checkpoint"))?;
            if calibrate {
                std_from_logs("reference", [1.0, 1.0], policy, data, config, device)
            } else {
                Ok(policy)
            }
        }
        (None, true, Some(init), false) => {
            warm_start("reference", init, blank(), data, config, device)
        }
        _ => Err(Error::invalid(
            "run file",
            "field `reference`",
            "expected exactly one of checkpoint = \"<policy.bpk>\" and init = true (with an \
             [init] warm start, and without std_from_logs here)",
        )),
    }
}

/// The warm start `init` describes, on `device`: its policy loaded into `blank` (a network of
/// the run's model config; unused when the relative-motion inputs are added, which loads the
/// pose-only network they extend), with the sigma from the logs where it asks for it.
/// Deterministic (the added weights draw from a stream of their own), so the KL reference
/// built from it again is the same policy.
fn warm_start(
    what: &str,
    init: &InitConfig,
    blank: PolicyNetwork,
    data: &TrainingData,
    config: &TrainConfig,
    device: &Device,
) -> Result<PolicyNetwork> {
    let policy = if init.add_agent_edge_motion {
        let pose_only = ModelConfig {
            agent_edge_motion: false,
            ..config.model.clone()
        };
        // Its own stream: the seeded initialisation of the run is unchanged.
        let mut rng = ChaCha8Rng::seed_from_u64(stream_seed(config.seed, 0, u64::MAX - 1));
        checkpoint::load_policy(&init.policy_file(), &pose_only, device)
            .map_err(|e| e.in_field("init.policy"))?
            .with_agent_edge_motion(&mut rng, init.agent_edge_motion_scale as f32)
    } else {
        checkpoint::load_module(blank, &init.policy_file())
            .map_err(|e| e.in_field("init.policy"))?
    };
    if init.std_from_logs {
        std_from_logs(what, init.std_scale, policy, data, config, device)
    } else {
        Ok(policy)
    }
}

/// `policy` with the sigma of [`crate::train::config::InitConfig::std_from_logs`] times
/// `scale` per control, said on stderr after `what` (the warm start or the KL reference).
fn std_from_logs(
    what: &str,
    scale: [f64; 2],
    policy: PolicyNetwork,
    data: &TrainingData,
    config: &TrainConfig,
    device: &Device,
) -> Result<PolicyNetwork> {
    // Recorded scenes only: the bent copies of data.a9_bends are the same drivers again, and
    // leaving them out keeps the sample (every k-th scene) what it was without them.
    let recorded: Vec<&crate::scene::Scene> = data.recorded().collect();
    let stride = recorded.len().div_ceil(STD_SCENES).max(1);
    let scenes: Vec<&crate::scene::Scene> = recorded.into_iter().step_by(stride).collect();
    let (std, count) =
        super::imitation::logged_action_rms(&policy, &scenes, &config.limits, 16, device)?;
    crate::errln!(
        "{what}: sigma from the logs = {:.4} m/s^2, {:.5} rad (RMS error of its mean over \
         {count} logged agent-steps of {} scenes)",
        std[0],
        std[1],
        scenes.len()
    );
    if scale != [1.0, 1.0] {
        crate::errln!(
            "{what}: sigma scaled by [{}, {}] (init.std_scale)",
            scale[0],
            scale[1]
        );
    }
    let scaled = [std[0] * scale[0], std[1] * scale[1]];
    // The head would clamp a sigma it cannot express, and the run would explore with another
    // sigma than the one asked for.
    let [lo, hi] = config.model.log_std_range;
    for (k, (sigma, control)) in scaled.iter().zip(["acceleration", "steering"]).enumerate() {
        let range = [lo.exp(), hi.exp()].map(|f| f * config.model.action_scale[k]);
        if !(range[0]..=range[1]).contains(sigma) {
            return Err(Error::InvalidArgument(format!(
                "{what}: the {control} sigma {sigma:.3e} (from the logs x init.std_scale) is \
                 outside what the policy head can express, {:.3e} to {:.3e} (model.action_scale \
                 x exp(model.log_std_range)): change init.std_scale or model.log_std_range",
                range[0], range[1]
            )));
        }
    }
    Ok(policy.with_constant_std(scaled))
}

fn optimizer(config: &TrainConfig) -> ModuleOptimizer {
    AdamWConfig::new()
        .with_weight_decay(config.optimizer.weight_decay as f32)
        .init()
}

impl<'d> Trainer<'d> {
    /// A new run in `run_dir` (which must hold no checkpoint), or with `resume` the
    /// continuation of the run there (whose config must equal `config`).
    pub fn new(
        config: TrainConfig,
        data: &'d TrainingData,
        devices: Vec<Device>,
        run_dir: &Path,
        resume: bool,
    ) -> Result<Self> {
        let main = devices
            .first()
            .cloned()
            .ok_or_else(|| Error::InvalidArgument("training needs at least one device".into()))?;
        let config_toml = toml::to_string(&config)
            .map_err(|e| Error::InvalidArgument(format!("config does not serialise: {e}")))?;
        let start = checkpoint::resume_point(run_dir, resume)?;
        let digests = super::identity::input_digests(&config)?;
        let (policy, value, policy_optimizer, value_optimizer, state) = match start {
            Some(dir) => {
                let c = checkpoint::load(
                    &dir,
                    &config.model,
                    &main,
                    optimizer(&config),
                    optimizer(&config),
                )?;
                let stored = TrainConfig::from_toml_str(&c.state.config_toml, "checkpoint");
                let difference = match &stored {
                    Ok(stored) => stored.identity_difference(&config)?,
                    Err(e) => Some(format!("its stored config does not load: {e}")),
                };
                if let Some(difference) = difference {
                    return Err(Error::InvalidArgument(format!(
                        "{}: the run there was made with another config ({difference}); resume \
                         with the same file and flags, or start a new --out folder",
                        run_dir.display(),
                    )));
                }
                super::identity::check_unchanged(run_dir, &c.state.input_digests, &config)?;
                check_position(&c.state, &dir, &config, data)?;
                let mut c = c;
                // Unchanged: recorded from here on as this version records them (a run
                // recorded without digests, or with one per folder, is brought up to date).
                c.state.input_digests =
                    super::identity::resumed_digests(&c.state.input_digests, digests);
                (
                    c.policy,
                    c.value,
                    c.policy_optimizer,
                    c.value_optimizer,
                    c.state,
                )
            }
            None => {
                // Initialisation draws from the device's global RNG, and burn initialises
                // parameters lazily: seed, then force every value, under a lock, so runs in
                // parallel threads (tests) cannot interleave their draws.
                let (policy, value) =
                    with_seeded_device(&main, stream_seed(config.seed, 0, u64::MAX), || {
                        let policy = PolicyNetwork::new(&config.model, &main);
                        let value = ValueNetwork::new(&config.model, &main);
                        policy.visit(&mut Materialise);
                        value.visit(&mut Materialise);
                        (policy, value)
                    });
                let policy = match &config.init {
                    Some(init) => warm_start("init", init, policy, data, &config, &main)?,
                    None => policy,
                };
                (
                    policy,
                    value,
                    optimizer(&config),
                    optimizer(&config),
                    LoopState {
                        iteration: 0,
                        updates: 0,
                        config_toml,
                        policy_lr_scale: 1.0,
                        checksums: Default::default(),
                        input_digests: digests,
                        run_id: Some(checkpoint::new_run_id(run_dir)),
                    },
                )
            }
        };
        let reference = match (&config.reference, config.method.uses_reference()) {
            (Some(r), true) => Some(kl_reference(r, data, &config, &main.clone().inner())?),
            _ => None,
        };
        // Everything that can refuse the run is loaded before the run folder is written.
        let dynamics = config.dynamics(&main.clone().inner())?;
        crate::io::create_folder(run_dir)?;
        super::kept_inputs::keep(run_dir, &config)?;
        crate::io::atomic_write(&run_dir.join("config.toml"), state.config_toml.as_bytes())?;
        let curves_path = run_dir.join("curves.csv");
        let curves = if resume {
            Curves::resume(curves_path, state.iteration)?
        } else {
            Curves::new(curves_path)
        };
        Ok(Self {
            caches: devices.iter().map(|_| MapCaches::default()).collect(),
            data,
            run_dir: run_dir.to_path_buf(),
            devices,
            dynamics,
            policy,
            value,
            policy_optimizer,
            value_optimizer,
            reference,
            state,
            curves,
            started: Instant::now(),
            timing: IterationTiming::default(),
            policy_stepped: false,
            config,
        })
    }

    pub fn policy(&self) -> &PolicyNetwork {
        &self.policy
    }

    pub fn value(&self) -> &ValueNetwork {
        &self.value
    }

    pub fn state(&self) -> &LoopState {
        &self.state
    }

    pub fn curves(&self) -> &[CurveRow] {
        self.curves.rows()
    }

    pub fn last_timing(&self) -> IterationTiming {
        self.timing
    }

    pub fn iterations_per_epoch(&self) -> usize {
        iterations_per_epoch(&self.config, self.data)
    }

    /// Iterations of the whole run (all epochs, capped by `run.max_iterations`).
    pub fn total_iterations(&self) -> usize {
        total_iterations(&self.config, self.data)
    }

    /// Runs until the last iteration, checkpointing as configured; `stop_after` ends early
    /// after that many iterations of this call (as if killed right after a checkpoint).
    pub fn run(
        &mut self,
        progress: &ProgressBar,
        stop_after: Option<usize>,
    ) -> Result<TrainSummary> {
        let total = self.total_iterations();
        progress.set_length(total as u64);
        progress.set_position(self.state.iteration as u64);
        let mut last_checkpoint = checkpoint::latest(&self.run_dir)?;
        let mut done_here = 0;
        while self.state.iteration < total && stop_after.is_none_or(|s| done_here < s) {
            let row = self.iteration(self.state.iteration, last_checkpoint.as_deref())?;
            crate::allocator::release_free_memory();
            self.state.iteration += 1;
            done_here += 1;
            let finished = self.state.iteration == total;
            if finished
                || self
                    .state
                    .iteration
                    .is_multiple_of(self.config.run.checkpoint_every)
                || stop_after == Some(done_here)
            {
                self.refuse_non_finite_weights(
                    self.state.iteration - 1,
                    last_checkpoint.as_deref(),
                )?;
                last_checkpoint = Some(self.save()?);
            }
            progress.set_message(format!(
                "loss {:.4} collision {:.1}%",
                row.loss, row.collision_pct
            ));
            progress.inc(1);
        }
        let checkpoint = match last_checkpoint {
            Some(c) => c,
            None => self.save()?,
        };
        if self.state.iteration == total {
            // The finished policy at a stable path (for `[reference]`, evaluation, models/).
            let bytes = crate::io::read_bytes(
                &checkpoint.join("policy.bpk"),
                crate::io::Format::Parameters,
            )?;
            crate::io::atomic_write(&self.run_dir.join("policy.bpk"), &bytes)?;
        }
        Ok(TrainSummary {
            iterations: self.state.iteration,
            updates: self.state.updates,
            checkpoint,
            last: self.curves.rows().last().cloned(),
        })
    }

    /// A step can turn weights non-finite while its loss and gradients were finite (a
    /// learning rate far too large): such weights are never saved, and the run stops at the
    /// last good checkpoint.
    fn refuse_non_finite_weights(&self, i: usize, last_checkpoint: Option<&Path>) -> Result<()> {
        let found = checkpoint::non_finite_parameter(&self.policy)
            .map(|p| ("policy", p))
            .or_else(|| checkpoint::non_finite_parameter(&self.value).map(|p| ("value", p)));
        match found {
            Some((network, (name, count))) => Err(self.diverged(
                i,
                &format!("{network} network's parameter `{name}` ({count} values)"),
                f64::NAN,
                last_checkpoint,
            )),
            None => Ok(()),
        }
    }

    /// Writes a checkpoint of the run as it stands. If that fails (a full disk), the curve
    /// rows of the iterations it would have held are dropped again, so `curves.csv` matches
    /// the newest checkpoint there is.
    fn save(&mut self) -> Result<PathBuf> {
        self.write_checkpoint().inspect_err(|_| {
            let saved = checkpoint::latest(&self.run_dir)
                .ok()
                .flatten()
                .and_then(|dir| checkpoint::read_state(&dir).ok())
                .map_or(0, |state| state.iteration);
            // Best effort: the checkpoint's error is the one to report.
            let _ = self.curves.truncate(saved);
        })
    }

    fn write_checkpoint(&self) -> Result<PathBuf> {
        checkpoint::save(
            &self.run_dir,
            self.config
                .run
                .keep_checkpoints
                .unwrap_or(checkpoint::DEFAULT_KEEP),
            &self.policy,
            &self.value,
            &self.policy_optimizer,
            &self.value_optimizer,
            &self.state,
        )
    }

    /// One iteration; returns its last curve row.
    fn iteration(&mut self, i: usize, last_checkpoint: Option<&Path>) -> Result<CurveRow> {
        let config = self.config.clone();
        let epoch = i / self.iterations_per_epoch();
        let lr = config.optimizer.learning_rate_at(epoch);
        let mut rng = ChaCha8Rng::seed_from_u64(stream_seed(config.seed, i, 0));
        {
            // Only reparameterised IL samples (imitation.action = "sample") draw from it.
            let _guard = DEVICE_RNG.lock().unwrap_or_else(|p| p.into_inner());
            for d in &self.devices {
                d.seed(stream_seed(config.seed, i, 1));
            }
        }
        let data = self.data;
        let start = Instant::now();
        if !config.method.uses_ppo() {
            let states = data.sample(&mut rng, config.imitation.minibatch, 0.0);
            let work = self.prepare(data.parts(&states), None)?;
            let row = self
                .update(i, epoch, lr, work, CollectStats::default(), last_checkpoint)
                .map(|(row, _)| row);
            self.timing = IterationTiming {
                collect_s: 0.0,
                update_s: start.elapsed().as_secs_f64(),
            };
            return row;
        }
        let states = data.sample(&mut rng, config.ppo.batch, config.alpha);
        let minibatches: Vec<&[InitialState]> = states.chunks(config.ppo.minibatch).collect();
        let mut collected: Vec<Vec<Vec<Work>>> = Vec::with_capacity(minibatches.len());
        let mut stats = CollectStats::default();
        for (m, states) in minibatches.iter().enumerate() {
            let work = self.prepare(
                data.parts(states),
                Some(stream_seed(config.seed, i, 2 + m as u64)),
            )?;
            for shard in &work {
                for w in shard {
                    if let Some(e) = &w.experience {
                        stats += e.stats;
                    }
                }
            }
            collected.push(work);
        }
        let collect_s = start.elapsed().as_secs_f64();
        self.policy_stepped = false;
        let mut order: Vec<usize> = (0..collected.len()).collect();
        let mut row = None;
        for pass in 0..config.ppo.epochs {
            if pass > 0 {
                order.shuffle(&mut rng);
            }
            for &m in &order {
                // Later passes reuse the experience; the work is rebuilt around it.
                let work = std::mem::take(&mut collected[m]);
                let (r, back) = self.update(i, epoch, lr, work, stats, last_checkpoint)?;
                collected[m] = back;
                row = Some(r);
            }
        }
        self.timing = IterationTiming {
            collect_s,
            update_s: start.elapsed().as_secs_f64() - collect_s,
        };
        row.ok_or_else(|| Error::InvalidArgument("ppo.batch produced no minibatch".into()))
    }

    /// Splits `parts` across the devices and, for PPO (`collect_seed`), collects their
    /// experience with the current policy; builds BC labels where the method needs them.
    fn prepare<'a>(
        &mut self,
        parts: Vec<Part<'a>>,
        collect_seed: Option<u64>,
    ) -> Result<Vec<Vec<Work<'a>>>> {
        let config = &self.config;
        let shards = plan(parts, self.devices.len(), BUCKET_SCENES);
        let devices: Vec<Device> = self.devices.iter().map(|d| d.clone().inner()).collect();
        let policy = self.policy.valid();
        let value = self.value.valid();
        let reference = self.reference.clone();
        let dynamics = &self.dynamics;
        let rewards = RewardSettings::of(config);
        per_device(shards, &mut self.caches, |k, parts, caches| {
            let device = &devices[k];
            let (policy, value) = (policy.clone().fork(device), value.clone().fork(device));
            let reference = reference.clone().map(|r| r.fork(device));
            let nets = CollectNetworks {
                policy: &policy,
                value: &value,
                reference: reference.as_ref(),
            };
            parts
                .into_iter()
                .map(|part| {
                    let experience = match collect_seed {
                        Some(seed) => Some(collect(
                            &part,
                            &nets,
                            device,
                            dynamics,
                            caches,
                            config.data.max_rollout_steps,
                            &config.ppo,
                            &rewards,
                            seed,
                        )?),
                        None => None,
                    };
                    let labels = (config.method.uses_bc() && part.is_nominal()).then(|| {
                        let n = part
                            .scenes
                            .iter()
                            .map(|s| s.agents.len())
                            .max()
                            .unwrap_or(1);
                        let steps = rollout_steps(&part, config.data.max_rollout_steps);
                        BcLabels::new(&part.scenes, n.max(1), steps, &config.limits, device)
                    });
                    Ok(Work {
                        part,
                        experience,
                        labels,
                    })
                })
                .collect()
        })
    }

    /// The policy's learning rate for this step: the schedule's `lr`, times the factor that
    /// `ppo.target_kl` adapts to the KL this minibatch measured. The KL is only news once the
    /// policy has stepped since the experience was collected (before that it is 0).
    fn policy_learning_rate(&mut self, lr: f64, approx_kl: f64, warming_up: bool) -> f64 {
        if let Some(target) = self.config.ppo.target_kl
            && self.policy_stepped
            && !warming_up
        {
            self.state.policy_lr_scale =
                adapt_lr_scale(self.state.policy_lr_scale, approx_kl, target);
        }
        lr * self.state.policy_lr_scale
    }

    /// One optimizer step on a minibatch; hands the work back (PPO reuses its experience).
    fn update<'a>(
        &mut self,
        i: usize,
        epoch: usize,
        lr: f64,
        work: Vec<Vec<Work<'a>>>,
        stats: CollectStats,
        last_checkpoint: Option<&Path>,
    ) -> Result<(CurveRow, Vec<Vec<Work<'a>>>)> {
        let config = self.config.clone();
        let plan = LossPlan::of(&config, i);
        let minibatch = MinibatchStatistics::of(&config, &work, i);
        let ctx = StepContext {
            config: &config,
            plan,
            minibatch: &minibatch,
            iteration: i,
            dynamics: &self.dynamics,
        };
        let devices = self.devices.clone();
        let (policy, value) = (&self.policy, &self.value);
        let results = per_device(work, &mut self.caches, |k, work, caches| {
            let device = &devices[k];
            let (policy, value) = if k == 0 {
                (policy.clone(), value.clone())
            } else {
                (policy.clone().fork(device), value.clone().fork(device))
            };
            shard_gradients(&ctx, &policy, &value, work, device, caches)
        })?;
        let (terms, gradients, returned) = gather_shards(results);
        let diverged = |what: &str, value: f64| self.diverged(i, what, value, last_checkpoint);
        let gradients = match gradients {
            Some(g) if terms.total.is_finite() => g,
            _ => return Err(diverged("loss", terms.total)),
        };
        let approx_kl = terms.approx_kl / minibatch.ppo_entries().max(1) as f64;
        let step = self.step_networks(lr, approx_kl, &plan, gradients, i, last_checkpoint)?;
        let row = self.curve_row(i, epoch, &terms, &minibatch, &step, &stats, approx_kl);
        self.curves.push(row.clone())?;
        Ok((row, returned))
    }

    /// The error of a step whose `what` came out non-finite.
    fn diverged(&self, i: usize, what: &str, value: f64, last_checkpoint: Option<&Path>) -> Error {
        Error::Diverged {
            iteration: i,
            update: self.state.updates,
            what: what.to_string(),
            value,
            checkpoint: last_checkpoint
                .map_or("none written yet".into(), |p| p.display().to_string()),
        }
    }

    /// Sums the shards' gradients on the first device, clips each network's to
    /// `optimizer.grad_clip_norm` and steps the optimizers (the policy's not during the value
    /// warm-up, at the rate `ppo.target_kl` adapts).
    fn step_networks(
        &mut self,
        lr: f64,
        approx_kl: f64,
        plan: &LossPlan,
        (policy_parts, value_parts): (Vec<GradientsParams>, Vec<GradientsParams>),
        i: usize,
        last_checkpoint: Option<&Path>,
    ) -> Result<StepNorms> {
        let clip = self.config.optimizer.grad_clip_norm;
        let main = self.devices[0].clone();
        let mut policy_grads = sum_on_device(&self.policy, policy_parts, &main);
        let policy_norm = clip_global_norm(&self.policy, &mut policy_grads, clip);
        if !policy_norm.is_finite() {
            return Err(self.diverged(i, "policy gradient norm", policy_norm, last_checkpoint));
        }
        let mut value_norm = 0.0;
        let value_grads = if plan.uses_value {
            let mut g = sum_on_device(&self.value, value_parts, &main);
            value_norm = clip_global_norm(&self.value, &mut g, clip);
            if !value_norm.is_finite() {
                return Err(self.diverged(i, "value gradient norm", value_norm, last_checkpoint));
            }
            Some(g)
        } else {
            None
        };
        let policy_lr = self.policy_learning_rate(lr, approx_kl, plan.warming_up);
        if !plan.warming_up {
            self.policy = self
                .policy_optimizer
                .step(policy_lr, self.policy.clone(), policy_grads);
            self.policy_stepped = true;
        }
        if let Some(g) = value_grads {
            self.value = self.value_optimizer.step(lr, self.value.clone(), g);
        }
        self.state.updates += 1;
        Ok(StepNorms {
            policy_lr,
            policy_norm,
            value_norm,
        })
    }

    /// The curve row of the step just taken.
    #[allow(clippy::too_many_arguments)]
    fn curve_row(
        &self,
        i: usize,
        epoch: usize,
        terms: &TermValues,
        minibatch: &MinibatchStatistics,
        step: &StepNorms,
        stats: &CollectStats,
        approx_kl: f64,
    ) -> CurveRow {
        let pct = |k: usize| 100.0 * k as f64 / stats.agents.max(1) as f64;
        CurveRow {
            iteration: i,
            update: self.state.updates,
            epoch,
            learning_rate: step.policy_lr,
            loss: terms.total,
            il_loss: terms.il,
            bc_loss: terms.bc,
            policy_loss: terms.policy,
            value_loss: terms.value,
            kl: terms.kl,
            clip_fraction: terms.clipped as f64 / minibatch.ppo_entries().max(1) as f64,
            policy_grad_norm: step.policy_norm,
            value_grad_norm: step.value_norm,
            collision_pct: pct(stats.collided),
            offroad_pct: pct(stats.offroad),
            mean_reward: stats.reward_sum / stats.agent_steps.max(1) as f64,
            ppo_agent_steps: stats.agent_steps,
            scenes: minibatch.scenes,
            elapsed_s: self.started.elapsed().as_secs_f64(),
            approx_kl,
        }
    }
}

/// What one step did to the networks.
struct StepNorms {
    policy_lr: f64,
    policy_norm: f64,
    value_norm: f64,
}

/// The shards' results put together: their summed terms, their gradients (`None` where one
/// met a non-finite loss) and their parts.
#[allow(clippy::type_complexity)]
fn gather_shards<'a>(
    results: Vec<(Option<ShardGradients>, TermValues, Vec<Work<'a>>)>,
) -> (
    TermValues,
    Option<(Vec<GradientsParams>, Vec<GradientsParams>)>,
    Vec<Vec<Work<'a>>>,
) {
    let mut terms = TermValues::default();
    let (mut policy, mut value) = (Vec::new(), Vec::new());
    let mut returned = Vec::new();
    let mut finite = true;
    for (grads, t, work) in results {
        terms += t;
        returned.push(work);
        match grads {
            Some(g) => {
                policy.push(g.policy);
                value.extend(g.value);
            }
            None => finite = false,
        }
    }
    (terms, finite.then_some((policy, value)), returned)
}

/// Initial states one iteration consumes.
fn scenes_per_iteration(config: &TrainConfig) -> usize {
    if config.method.uses_ppo() {
        config.ppo.batch
    } else {
        config.imitation.minibatch
    }
}

fn iterations_per_epoch(config: &TrainConfig, data: &TrainingData) -> usize {
    let scenes = config.optimizer.epoch_scenes.unwrap_or(data.nominal.len());
    scenes.div_ceil(scenes_per_iteration(config)).max(1)
}

fn total_iterations(config: &TrainConfig, data: &TrainingData) -> usize {
    let all = iterations_per_epoch(config, data) * config.optimizer.epochs;
    config.run.max_iterations.map_or(all, |m| m.min(all))
}

/// Optimizer steps one iteration takes.
fn updates_per_iteration(config: &TrainConfig) -> usize {
    if config.method.uses_ppo() {
        config.ppo.batch / config.ppo.minibatch * config.ppo.epochs
    } else {
        1
    }
}

/// Refuses a checkpoint whose recorded position cannot be where this run stood: an iteration
/// beyond the run, a step count that iteration cannot have taken, or a folder of another
/// iteration (a hand-edited or mixed-up `state.json`).
fn check_position(
    state: &LoopState,
    dir: &Path,
    config: &TrainConfig,
    data: &TrainingData,
) -> Result<()> {
    let total = total_iterations(config, data);
    let expected_updates = state
        .iteration
        .saturating_mul(updates_per_iteration(config));
    let expected_dir = format!("iter-{:06}", state.iteration);
    let problem = if state.iteration > total {
        Some(format!(
            "iteration {} is beyond the run's {total} iterations",
            state.iteration
        ))
    } else if state.updates != expected_updates {
        Some(format!(
            "{} optimizer steps, but {} iterations of this run take {expected_updates}",
            state.updates, state.iteration
        ))
    } else if dir.file_name().is_none_or(|n| n != expected_dir.as_str()) {
        Some(format!(
            "iteration {} is stored in {}, expected a folder named {expected_dir}",
            state.iteration,
            dir.display()
        ))
    } else {
        None
    };
    match problem {
        Some(p) => Err(Error::invalid(
            dir.join("state.json").display().to_string(),
            "iteration",
            format!("{p}: the state does not match its run; start a new --out folder"),
        )),
        None => Ok(()),
    }
}
