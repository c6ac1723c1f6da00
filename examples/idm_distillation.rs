//! `cargo run --release --example idm_distillation -- POLICY RUN_FILE SCENARIOS OUT
//! [STEPS [LR]] [--motion] [--accel-only | --keep-steering]`: can the policy network represent
//! braking for a car ahead at all?
//!
//! No imitation or PPO run of issue 18 taught a policy to brake for a slower car ahead
//! (`experiments/recipe/ppo_credit/results.md`). That is either a network that cannot express
//! the response or a training signal that does not ask for it. This probe separates the two: it
//! fits the network to a driver that does brake, the IDM reference, with a dense per-step target
//! (DAgger: the network drives with its mean action, IDM labels every state it visits, so the
//! states are the network's own, collisions included).
//!
//! Starting from POLICY (a trained policy folder), each of STEPS AdamW steps (default 300, LR
//! default 2e-4, burn's default weight decay 1e-4, global gradient norm clipped at 1; LR 0 only
//! measures the fit) rolls out 8 initial states drawn as RUN_FILE's training does (its data
//! mixture, alpha and dynamics; long-tail states from SCENARIOS/train) and minimises, over the
//! controlled agents present, the squared distance of the network's mean controls to IDM's as
//! the dynamics apply them (after the limits' soft clamp), each control divided by the model's
//! `action_scale`.
//! `--accel-only` leaves the steering out of the loss (its scaled error can dominate the
//! clipped gradient); `--keep-steering` fits the steering to a frozen copy of POLICY instead of
//! IDM, so only the acceleration is taught and the lane keeping stays the starting policy's.
//! `--motion` first adds the relative-motion agent edges from zero weights (`[model]
//! agent_edge_motion`), as the RTR recipe runs do.
//!
//! Printed (JSON lines on stdout): every 10 steps the fit on the states the step just drew,
//! before its update, so every number is on unseen states: the acceleration RMSE over all
//! agent-steps and over those where IDM brakes harder than 1 m/s^2, the network's mean
//! acceleration there against IDM's, the steering RMSE against its target, and the network's
//! mean acceleration per range of IDM's ([`LABEL_BINS`]). At the end the fitted policy is
//! written to OUT (policy.bpk and config.toml, loadable by `rtr eval` and `car_following`):
//! whether it then avoids the long-tail collisions is the answer.

use std::path::{Path, PathBuf};

use burn::module::Module;
use burn::optim::{AdamWConfig, GradientsParams};
use burn::prelude::*;
use burn::tensor::Bool;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rtr::driver::{IdmDriver, IdmParams};
use rtr::eval::TrainedPolicy;
use rtr::model::{ActionMode, NetworkPolicy, PolicyNetwork};
use rtr::scenario::rollout_with_heroes;
use rtr::scene::SceneBatch;
use rtr::sim::{ActionLimits, Controls, MapCaches, Observation, Policy, RolloutConfig};
use rtr::train::gradients::clip_global_norm;
use rtr::train::{Part, TrainConfig, TrainingData};

const SCENES_PER_STEP: usize = 8;
const GRAD_CLIP_NORM: f64 = 1.0;
const REPORT_EVERY: usize = 10;
/// IDM labels below this (m/s^2) count as braking in the report.
const BRAKING_MPS2: f32 = -1.0;
/// IDM label ranges (m/s^2) the report splits the fit by: hard braking (mostly a contact
/// about to happen), moderate and light braking, and the rest.
const LABEL_BINS: [(f32, f32); 4] = [(-8.0, -6.0), (-6.0, -3.0), (-3.0, -1.0), (-1.0, 4.0)];

fn main() -> std::process::ExitCode {
    match run().and_then(|()| Ok(rtr::io::console::check_stdout()?)) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            rtr::errln!("idm_distillation: {e}");
            std::process::ExitCode::from(2)
        }
    }
}

struct Args {
    policy: PathBuf,
    run_file: PathBuf,
    scenarios: PathBuf,
    out: PathBuf,
    steps: usize,
    learning_rate: f64,
    motion: bool,
    steering: SteeringTarget,
}

/// What the network's steering is fitted to.
#[derive(Clone, Copy, PartialEq, Eq)]
enum SteeringTarget {
    /// IDM's pure-pursuit lane keeping (the default).
    Idm,
    /// Nothing (`--accel-only`): steering is left out of the loss.
    None,
    /// The starting policy's own steering in the same state (`--keep-steering`): a frozen copy
    /// of POLICY, so only the acceleration is taught and lane keeping stays what it was.
    Start,
}

fn parse_args() -> Result<Args, String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let options = ["--motion", "--accel-only", "--keep-steering"];
    if let Some(flag) = args
        .iter()
        .find(|a| a.starts_with("--") && !options.contains(&a.as_str()))
    {
        return Err(format!(
            "unknown option {flag}: the options are {}",
            options.join(", ")
        ));
    }
    let motion = args.iter().any(|a| a == "--motion");
    let steering = match (
        args.iter().any(|a| a == "--accel-only"),
        args.iter().any(|a| a == "--keep-steering"),
    ) {
        (false, false) => SteeringTarget::Idm,
        (true, false) => SteeringTarget::None,
        (false, true) => SteeringTarget::Start,
        (true, true) => return Err("--accel-only and --keep-steering exclude each other".into()),
    };
    let positional: Vec<&String> = args.iter().filter(|a| !a.starts_with("--")).collect();
    if !(4..=6).contains(&positional.len()) {
        return Err(
            "usage: cargo run --release --example idm_distillation -- POLICY RUN_FILE \
                    SCENARIOS OUT [STEPS [LR]] [--motion] [--accel-only | --keep-steering]"
                .into(),
        );
    }
    let steps = match positional.get(4) {
        None => 300,
        Some(s) => s
            .parse()
            .ok()
            .filter(|&k: &usize| k > 0)
            .ok_or_else(|| format!("STEPS: expected a count >= 1, got `{s}`"))?,
    };
    let learning_rate = match positional.get(5) {
        None => 2e-4,
        Some(s) => s
            .parse()
            .ok()
            .filter(|&lr: &f64| lr >= 0.0 && lr.is_finite())
            .ok_or_else(|| format!("LR: expected a learning rate >= 0, got `{s}`"))?,
    };
    let scenarios = PathBuf::from(positional[2]);
    if !scenarios.join("train").is_dir() {
        return Err(format!(
            "SCENARIOS {}: no train/ folder in it; expected the folder `rtr scenarios generate \
             --out` wrote",
            scenarios.display()
        ));
    }
    let out = PathBuf::from(positional[3]);
    if out.join("policy.bpk").exists() {
        return Err(format!(
            "OUT {}: already holds a policy.bpk; choose another folder",
            out.display()
        ));
    }
    Ok(Args {
        policy: PathBuf::from(positional[0]),
        run_file: PathBuf::from(positional[1]),
        scenarios,
        out,
        steps,
        learning_rate,
        motion,
        steering,
    })
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    rtr::allocator::tune_for_tensors();
    let args = parse_args()?;
    let mut config = TrainConfig::from_toml_file(&args.run_file)?;
    config.data.longtail_dir = Some(args.scenarios.clone());
    let device = rtr::backend::Backend::Flex.device(true)?;
    let start = TrainedPolicy::load(&args.policy, &device)?;
    let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
    // `no_grad`: the frozen copy builds no autodiff graph (its lane encoding would otherwise
    // hold one for the whole rollout).
    let frozen = (args.steering == SteeringTarget::Start).then(|| start.network.clone().no_grad());
    let mut policy = if args.motion {
        start.network.with_agent_edge_motion(&mut rng, 0.0)
    } else {
        start.network
    };
    let dataset = rtr::data::A9Dataset::load(&rtr::data::a9::default_dir())?;
    let data = TrainingData::load(&dataset, &config.data, true)?;
    let dynamics = config.dynamics(&device)?;
    let distillation = Distillation {
        frozen: frozen.as_ref(),
        dynamics: &dynamics,
        config: &config,
        device: &device,
        weights: control_weights(policy.config().action_scale, args.steering),
    };
    let mut optimizer = AdamWConfig::new().init();
    let mut caches = MapCaches::default();
    let mut report = Report::default();
    let wall = std::time::Instant::now();
    for step in 1..=args.steps {
        let states = data.sample(&mut rng, SCENES_PER_STEP, config.alpha);
        let mut fits = Vec::new();
        for part in data.parts(&states) {
            fits.push(distillation.fit(&policy, &part, &mut caches)?);
        }
        let count: usize = fits.iter().map(|f| f.count).sum();
        if count == 0 {
            continue;
        }
        let mut grads = GradientsParams::new();
        for fit in &mut fits {
            let mut g = fit.loss.clone().div_scalar(count as f64).backward();
            let part = GradientsParams::from_module(&mut g, &policy);
            grads = merge(&policy, grads, part);
            report.add(&fit.pairs);
        }
        clip_global_norm(&policy, &mut grads, GRAD_CLIP_NORM);
        policy = optimizer.step(args.learning_rate, policy, grads);
        if step % REPORT_EVERY == 0 || step == args.steps {
            rtr::outln!("{}", report.json(step, wall.elapsed().as_secs_f64()))?;
            report = Report::default();
        }
    }
    save(&policy, &start.config, &args.out)?;
    rtr::errln!(
        "idm_distillation: wrote {} after {} steps in {:.0} s",
        args.out.display(),
        args.steps,
        wall.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Sums `b` into `a` (gradients of one step's parts).
fn merge(policy: &PolicyNetwork, a: GradientsParams, b: GradientsParams) -> GradientsParams {
    let mut sum = burn::optim::GradientsAccumulator::new();
    sum.accumulate(policy, a);
    sum.accumulate(policy, b);
    sum.grads()
}

/// One part's summed squared control error, its agent-step count and the host (network, IDM)
/// acceleration pairs.
struct Fit {
    loss: Tensor<1>,
    count: usize,
    pairs: Vec<ControlPair>,
}

/// What every step's fit shares.
struct Distillation<'a> {
    /// `--keep-steering`: the frozen starting policy, whose steering replaces IDM's.
    frozen: Option<&'a PolicyNetwork>,
    dynamics: &'a rtr::sim::Dynamics,
    config: &'a TrainConfig,
    device: &'a Device,
    /// Per control: 1 / action_scale, or 0 for a control left out of the loss.
    weights: [f32; 2],
}

impl Distillation<'_> {
    /// Rolls out `part` with `policy`'s mean action and scores it against IDM's controls in
    /// every visited state.
    fn fit(&self, policy: &PolicyNetwork, part: &Part, caches: &mut MapCaches) -> rtr::Result<Fit> {
        let (config, dynamics) = (self.config, self.dynamics);
        let batch = SceneBatch::from_scenes(&part.scenes, self.device)?;
        let steps = config
            .data
            .max_rollout_steps
            .map_or(batch.future_steps, |m| m.min(batch.future_steps));
        let rollout_config = RolloutConfig {
            steps: Some(steps),
            early_termination: true,
        };
        let mut labelled = Labelled {
            student: NetworkPolicy::new(policy, &batch, ActionMode::Mean),
            teacher: IdmDriver::new(&part.scenes, IdmParams::default(), config.limits),
            steering_teacher: self
                .frozen
                .map(|f| NetworkPolicy::new(f, &batch, ActionMode::Mean)),
            weights: self.weights,
            limits: config.limits,
            loss: Vec::new(),
            count: 0,
            pairs: Vec::new(),
        };
        rollout_with_heroes(
            &part.scenarios,
            &part.scenes,
            &batch,
            dynamics,
            &mut labelled,
            caches,
            &rollout_config,
        )?;
        let loss = Tensor::cat(labelled.loss, 0).sum();
        Ok(Fit {
            loss,
            count: labelled.count,
            pairs: labelled.pairs,
        })
    }
}

/// Each control's weight in the loss: 1 / its action scale, steering 0 with `--accel-only`.
fn control_weights(action_scale: [f64; 2], steering: SteeringTarget) -> [f32; 2] {
    let steer = if steering == SteeringTarget::None {
        0.0
    } else {
        1.0 / action_scale[1]
    };
    [1.0 / action_scale[0] as f32, steer as f32]
}

/// Drives with the network's (detached) mean and records, per step, its squared distance to
/// IDM's controls on the controlled agents present.
struct Labelled<'n> {
    student: NetworkPolicy<'n>,
    teacher: IdmDriver,
    /// `--keep-steering`: the frozen starting policy, whose steering replaces IDM's.
    steering_teacher: Option<NetworkPolicy<'n>>,
    /// Per control: 1 / action_scale, or 0 for a control left out of the loss.
    weights: [f32; 2],
    limits: ActionLimits,
    loss: Vec<Tensor<1>>,
    count: usize,
    pairs: Vec<ControlPair>,
}

/// One agent-step's applied controls (acceleration m/s^2, steering rad): the network's mean and
/// its target (IDM's; the starting policy's steering with `--keep-steering`).
#[derive(Clone, Copy)]
struct ControlPair {
    network: [f32; 2],
    target: [f32; 2],
}

impl Policy for Labelled<'_> {
    fn act(&mut self, obs: &Observation) -> Controls {
        // Compared as applied (after the limits' soft clamp): IDM's raw braking command can be
        // -60 m/s^2, which the limits turn into about -8.
        let mut target = self.teacher.act(obs);
        if let Some(frozen) = &self.steering_teacher {
            target.steer = Controls::from_stacked(frozen.distribution(obs).mean).steer;
        }
        let target = self.limits.apply(&target).stacked().detach();
        let mean = self.student.distribution(obs).mean;
        let applied = self
            .limits
            .apply(&Controls::from_stacked(mean.clone()))
            .stacked();
        let [b, n, _] = mean.dims();
        let present: Tensor<2, Bool> = obs.frames[obs.frames.len() - 1].present.clone();
        let mask = present.bool_and(obs.batch.agent_controlled.clone());
        let weights = Tensor::<1>::from_floats(self.weights, &mean.device()).reshape([1, 1, 2]);
        let error = (applied.clone() - target.clone()) * weights;
        let squared = error
            .powi_scalar(2)
            .sum_dim(2)
            .reshape([b, n])
            .mask_fill(mask.clone().bool_not(), 0.0);
        self.loss.push(squared.sum().reshape([1]));
        let mask_host = mask
            .into_data()
            .try_into_vec_as::<bool>()
            .unwrap_or_default();
        let host = |t: &Tensor<3>| -> Vec<f32> {
            t.clone()
                .into_data()
                .convert::<f32>()
                .try_into_vec::<f32>()
                .unwrap_or_default()
        };
        let (network, targets) = (host(&applied), host(&target));
        for (k, &m) in mask_host.iter().enumerate() {
            if m {
                self.count += 1;
                self.pairs.push(ControlPair {
                    network: [network[2 * k], network[2 * k + 1]],
                    target: [targets[2 * k], targets[2 * k + 1]],
                });
            }
        }
        Controls::from_stacked(mean.detach())
    }
}

/// Fit statistics over the control pairs of some steps.
#[derive(Default)]
struct Report {
    pairs: Vec<ControlPair>,
}

impl Report {
    fn add(&mut self, pairs: &[ControlPair]) {
        self.pairs.extend_from_slice(pairs);
    }

    fn json(&self, step: usize, wall_s: f64) -> serde_json::Value {
        let rmse = |pairs: &[&ControlPair], c: usize| -> f64 {
            let sum: f64 = pairs
                .iter()
                .map(|p| ((p.network[c] - p.target[c]) as f64).powi(2))
                .sum();
            (sum / pairs.len().max(1) as f64).sqrt()
        };
        let mean = |values: Vec<f32>| -> f64 {
            values.iter().map(|&v| v as f64).sum::<f64>() / values.len().max(1) as f64
        };
        let all: Vec<&ControlPair> = self.pairs.iter().collect();
        let braking: Vec<&ControlPair> = self
            .pairs
            .iter()
            .filter(|p| p.target[0] < BRAKING_MPS2)
            .collect();
        serde_json::json!({
            "step": step,
            "wall_s": (wall_s * 10.0).round() / 10.0,
            "agent_steps": all.len(),
            "acc_rmse": rmse(&all, 0),
            "steer_rmse": rmse(&all, 1),
            "braking_agent_steps": braking.len(),
            "braking_acc_rmse": rmse(&braking, 0),
            "braking_idm_acc": mean(braking.iter().map(|p| p.target[0]).collect()),
            "braking_network_acc": mean(braking.iter().map(|p| p.network[0]).collect()),
            "by_idm_acc": LABEL_BINS.map(|(lo, hi)| {
                let bin: Vec<&ControlPair> = self
                    .pairs
                    .iter()
                    .filter(|p| (lo..hi).contains(&p.target[0]))
                    .collect();
                serde_json::json!({
                    "idm_acc_from": lo,
                    "to": hi,
                    "agent_steps": bin.len(),
                    "network_acc": mean(bin.iter().map(|p| p.network[0]).collect()),
                })
            }),
        })
    }
}

/// Writes `policy` with `config` (its model config replaced by the policy's) to `out`; the
/// policy file goes last, so a folder with a policy.bpk is complete.
fn save(policy: &PolicyNetwork, config: &TrainConfig, out: &Path) -> rtr::Result<()> {
    rtr::io::create_folder(out)?;
    let mut config = config.clone();
    config.model = policy.config().clone();
    let text = toml::to_string(&config)
        .map_err(|e| rtr::Error::InvalidArgument(format!("config does not serialise: {e}")))?;
    rtr::io::atomic_write(&out.join("config.toml"), text.as_bytes())?;
    let path = out.join("policy.bpk");
    let bytes = policy
        .clone()
        .into_record()
        .into_bytes()
        .map_err(|e| rtr::Error::InvalidArgument(format!("{}: {e}", path.display())))?;
    rtr::io::atomic_write(&path, &bytes)
}
