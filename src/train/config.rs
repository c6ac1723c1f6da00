//! One training run as a TOML file (`experiments/<name>/*.toml`). Every field has the paper's
//! value (appendix table "Training hyperparameters") as its default, so a run file names only
//! what it changes; unknown fields are errors, so a typo never silently trains the default.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::perturbation::StartPerturbation;
use crate::backend::Backend;
use crate::error::{Error, Result};
use crate::io::parse_toml;
use crate::model::{ActionMode, ModelConfig};
use crate::sim::catalogue::DynamicsFile;
use crate::sim::{ActionLimits, Dynamics};

/// The learning methods of the paper's study (section 4) and its imitation-signal ablation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Method {
    /// Single-step behaviour cloning on logged states (open loop).
    #[serde(rename = "BC")]
    Bc,
    /// Closed-loop imitation by backpropagation through the rollout.
    #[serde(rename = "IL")]
    Il,
    /// Factorized PPO on the infraction reward.
    #[serde(rename = "RL")]
    Rl,
    /// RL plus the speed-limit shaping reward.
    #[serde(rename = "RL-Shaped")]
    RlShaped,
    /// BC loss plus the PPO loss.
    #[serde(rename = "BC+RL")]
    BcRl,
    /// Algorithm 1: closed-loop IL on nominal rollouts + lambda x PPO on all.
    #[serde(rename = "RTR")]
    Rtr,
    /// RTR with the IL term replaced by the KL to a frozen IL policy, as a loss.
    #[serde(rename = "KL-L")]
    KlLoss,
    /// RTR with the IL term replaced by the KL to a frozen IL policy, as a negative reward.
    #[serde(rename = "KL-R")]
    KlReward,
}

impl Method {
    pub const ALL: [Method; 8] = [
        Method::Bc,
        Method::Il,
        Method::Rl,
        Method::RlShaped,
        Method::BcRl,
        Method::Rtr,
        Method::KlLoss,
        Method::KlReward,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Method::Bc => "BC",
            Method::Il => "IL",
            Method::Rl => "RL",
            Method::RlShaped => "RL-Shaped",
            Method::BcRl => "BC+RL",
            Method::Rtr => "RTR",
            Method::KlLoss => "KL-L",
            Method::KlReward => "KL-R",
        }
    }

    /// Uses PPO (collects closed-loop experience with sampled actions).
    pub fn uses_ppo(self) -> bool {
        !matches!(self, Method::Bc | Method::Il)
    }

    /// Takes the closed-loop imitation loss on nominal rollouts.
    pub fn uses_closed_loop_il(self) -> bool {
        matches!(self, Method::Il | Method::Rtr)
    }

    /// Takes the open-loop behaviour-cloning loss.
    pub fn uses_bc(self) -> bool {
        matches!(self, Method::Bc | Method::BcRl)
    }

    /// Needs a frozen reference policy.
    pub fn uses_reference(self) -> bool {
        matches!(self, Method::KlLoss | Method::KlReward)
    }
}

/// The whole run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrainConfig {
    pub method: Method,
    /// Drives every random choice: initialisation, scene sampling, action noise.
    #[serde(default = "default_seed")]
    pub seed: u64,
    /// Weight of the RL loss (paper's lambda). Used by RL-type methods; RL alone ignores it
    /// (its loss is the RL loss).
    #[serde(default = "default_one")]
    pub lambda: f64,
    /// Share of long-tail initial states (paper's alpha); of curated ones where
    /// `data.curated` is set.
    #[serde(default)]
    pub alpha: f64,
    #[serde(default)]
    pub optimizer: OptimizerConfig,
    #[serde(default)]
    pub ppo: PpoConfig,
    #[serde(default)]
    pub imitation: ImitationConfig,
    #[serde(default)]
    pub shaping: ShapingConfig,
    #[serde(default)]
    pub reference: Option<ReferenceConfig>,
    /// Warm start: the policy's initial parameters from an earlier run (BC -> IL -> RTR).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub init: Option<InitConfig>,
    #[serde(default)]
    pub data: DataConfig,
    #[serde(default)]
    pub model: ModelConfig,
    #[serde(default)]
    pub limits: ActionLimits,
    /// Physics terms added to the paper's bicycle (the `dynamics.toml` that `rtr sim2real`
    /// writes), relative to the run file. Default: none.
    #[serde(default)]
    pub dynamics: Option<PathBuf>,
    #[serde(default)]
    pub run: RunConfig,
}

fn default_seed() -> u64 {
    2023
}

fn default_one() -> f64 {
    1.0
}

/// AdamW with the paper's step decay.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OptimizerConfig {
    pub learning_rate: f64,
    /// The learning rate is multiplied by this every `decay_every_epochs`.
    pub decay: f64,
    pub decay_every_epochs: usize,
    pub epochs: usize,
    pub weight_decay: f64,
    /// Global L2 norm of each network's gradient (as PyTorch's `clip_grad_norm_`).
    pub grad_clip_norm: f64,
    /// Initial states per epoch; `None` = as many as the nominal training set holds.
    pub epoch_scenes: Option<usize>,
}

impl Default for OptimizerConfig {
    fn default() -> Self {
        Self {
            learning_rate: 1e-5,
            decay: 0.2,
            decay_every_epochs: 3,
            epochs: 10,
            weight_decay: 1e-4,
            grad_clip_norm: 1.0,
            epoch_scenes: None,
        }
    }
}

impl OptimizerConfig {
    /// Learning rate during `epoch` (0-based).
    pub fn learning_rate_at(&self, epoch: usize) -> f64 {
        let decays = epoch / self.decay_every_epochs.max(1);
        self.learning_rate * self.decay.powi(decays as i32)
    }
}

/// Which PPO: the paper's per-agent one, or the scene-level one of its ablation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PpoVariant {
    /// Per-agent ratios, rewards, values and advantages (paper section 3.2).
    Factorized,
    /// One joint ratio, the summed scene reward and value per scene (the ablation).
    SceneLevel,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PpoConfig {
    /// Initial states collected per policy iteration.
    pub batch: usize,
    /// Initial states per gradient step.
    pub minibatch: usize,
    pub epochs: usize,
    pub clip: f64,
    pub gamma: f64,
    pub gae_lambda: f64,
    pub variant: PpoVariant,
    /// Weight of the value loss inside L_RL = L_policy + c L_value (paper: 1).
    pub value_weight: f64,
    /// Standardise advantages per minibatch (common practice; the paper does not say).
    pub normalize_advantages: bool,
    /// Iterations at the start in which only the value network learns (the policy's loss is
    /// not taken): a warm-started policy is not pushed around by advantages measured against
    /// an untrained value. 0 (the paper, which starts from scratch): none.
    pub value_warmup_iterations: usize,
    /// Not in the paper: per control (acceleration, steering), each agent's exploration noise
    /// as an AR(1) process over its steps, `z_t = rho z_(t-1) + sqrt(1 - rho^2) eta_t` with
    /// `a_t = mu(s_t) + sigma(s_t) z_t` ([`crate::model::ActionDistribution::following`]);
    /// `[0, 0]` (the paper): independent noise per step. Each z keeps the marginal N(0, 1), so
    /// sigma keeps its meaning, and a sampled braking is held for about `1 / (1 - rho)` steps
    /// instead of one: one step of the logs' sigma changes a speed by 0.4 m/s, too little to
    /// decide whether a car closing at 7 m/s meets the one ahead. PPO treats the agent's
    /// previous noise as part of its state, so every ratio stays that of one Normal.
    #[serde(skip_serializing_if = "is_uncorrelated")]
    pub noise_correlation: [f64; 2],
    /// Not in the paper: an agent that drives off the end of the map without an infraction is
    /// a truncated episode, bootstrapped with its last value, instead of a terminated one
    /// worth 0. Every reward is <= 0, so as a termination leaving the map is worth -V more than
    /// staying on it, a bonus for speed near the map's end that no infraction explains.
    /// `false` (every committed run before it): exits are terminations.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub bootstrap_exits: bool,
    /// Not in the paper: a collision costs only the agents at fault. An agent struck from
    /// behind ([`crate::sim::infractions::StepInfractions::struck_from_behind`], nuPlan's rule)
    /// gets no penalty, and its episode, ended by the other's mistake, is a truncation
    /// bootstrapped with its last value. It takes away the paper's push on a car closed on from
    /// behind to pull away and invites a general slowing: slowing down is free when the car
    /// behind takes the blame (`experiments/recipe/ppo_credit/`). `false` (the paper):
    /// both cars of a collision get -1.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub at_fault_collisions: bool,
    /// `false` (not in the paper): PPO explores acceleration only. Its rollouts steer with the
    /// policy's mean and its ratios count the acceleration's density alone, so the steering
    /// is learned by the imitation term (RTR, BC+RL) or kept from the warm start (RL). At the
    /// logs' sigma the steering noise puts about half of the long-tail training agents off the
    /// road and buries the credit for braking (`examples/ppo_signal.rs`,
    /// `experiments/recipe/ppo_credit/`). `true` (the paper): both controls are sampled.
    #[serde(skip_serializing_if = "is_true")]
    pub explore_steering: bool,
    /// Not in the paper: keep each policy step's KL divergence from the policy that collected
    /// the experience near this target by scaling the policy's learning rate (rsl_rl's
    /// adaptive schedule, [`super::ppo::adapt_lr_scale`]); the value network keeps the
    /// scheduled rate. The step a fixed rate takes is Adam's (about the rate per weight),
    /// whatever the gradient; with a sigma as small as the logs' (0.0022 rad of steering) that
    /// moves the mean by several sigmas, so after one step most ratios lie outside the clip and
    /// the epochs that follow push on what is left. `None` (the paper): the fixed schedule.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub target_kl: Option<f64>,
}

fn is_true(b: &bool) -> bool {
    *b
}

impl PpoConfig {
    /// Which controls PPO samples and scores: (acceleration, steering).
    pub fn explored_controls(&self) -> [bool; 2] {
        [true, self.explore_steering]
    }
}

impl Default for PpoConfig {
    fn default() -> Self {
        Self {
            batch: 192,
            minibatch: 32,
            epochs: 1,
            clip: 0.2,
            gamma: 0.79,
            gae_lambda: 1.0,
            variant: PpoVariant::Factorized,
            value_weight: 1.0,
            normalize_advantages: false,
            value_warmup_iterations: 0,
            noise_correlation: [0.0, 0.0],
            bootstrap_exits: false,
            at_fault_collisions: false,
            explore_steering: true,
            target_kl: None,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ImitationConfig {
    /// Initial states per gradient step for IL and BC.
    pub minibatch: usize,
    /// Huber threshold (m) of the trajectory distance.
    pub huber_delta: f64,
    /// Mean action (the paper's choice) or reparameterised samples in the IL rollout.
    pub action: ActionMode,
    /// Perturb each controlled agent's history before the closed-loop IL rollout (IL and
    /// RTR; the logged future stays the target); `None`: start from the logs as recorded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub perturbation: Option<StartPerturbation>,
    /// Remove each agent of an imitation scene with this probability before the rollout (IL
    /// and RTR; [`super::agent_dropout`], not in the paper); 0: every agent as recorded.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub agent_dropout: f64,
}

fn is_uncorrelated(rho: &[f64; 2]) -> bool {
    *rho == [0.0, 0.0]
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

impl Default for ImitationConfig {
    fn default() -> Self {
        Self {
            minibatch: 32,
            huber_delta: 1.0,
            action: ActionMode::Mean,
            perturbation: None,
            agent_dropout: 0.0,
        }
    }
}

/// RL-Shaped: reward + weight (C - delta) / C with delta = |speed - speed limit|; the agent's
/// episode ends once delta >= C.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ShapingConfig {
    pub weight: f64,
    /// C (m/s).
    pub tolerance: f64,
}

impl Default for ShapingConfig {
    fn default() -> Self {
        Self {
            weight: 0.5,
            tolerance: 30.0,
        }
    }
}

/// The frozen policy of KL-L / KL-R.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReferenceConfig {
    /// A policy checkpoint (`policy.bpk`, or a model or run folder holding one) of the same
    /// model config, relative to the run file. Exactly one of `checkpoint` and `init` names
    /// the reference.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub checkpoint: Option<PathBuf>,
    /// The reference is the warm start itself, built as `[init]` builds it (relative-motion
    /// inputs added, sigma from the logs x `init.std_scale`), so the KL starts at zero however
    /// the warm start was adapted for PPO. A plain checkpoint cannot be: it has neither the
    /// added inputs nor the scaled sigma.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub init: bool,
    /// Weight of the KL term (loss weight for KL-L, reward scale for KL-R).
    #[serde(default = "default_one")]
    pub weight: f64,
    /// Give the reference the sigma measured on the logs, as `[init] std_from_logs` gives the
    /// warm start. A closed-loop IL policy never trained its sigma, and the KL to a reference
    /// with an arbitrary sigma is mostly that sigma's mismatch: it is large at the warm start
    /// itself, and under KL-R agents learn to leave the road to end the penalty early.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub std_from_logs: bool,
}

/// A warm start. Only the policy is carried over: the value network, both optimizers and the
/// learning-rate schedule start fresh, so a warm-started run is an ordinary run of its method
/// from other initial weights (the method's loss is unchanged).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InitConfig {
    /// A policy of the same model config: a `policy.bpk`, or a folder holding one (a model in
    /// `models/`, a finished run), relative to the run file.
    pub policy: PathBuf,
    /// Replace the warm-started policy's sigma by a state-independent one measured on the
    /// nominal training logs: per control, the root-mean-square error of its mean against the
    /// logged (inverse-model) action. A policy trained by closed-loop IL through its mean never
    /// trained its sigma, and PPO explores with it: an untrained steering sigma of 0.013 rad at
    /// 35 m/s throws agents off the road within seconds, and PPO then learns lane keeping
    /// against its own noise instead of the infractions of the scenarios.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub std_from_logs: bool,
    /// Not in the paper: multiply the sigma from the logs per control (acceleration, steering),
    /// e.g. `[1.0, 0.25]` to explore with a quarter of the steering noise. One step of a
    /// log-sized steering sigma moves a car a lane within 6 s and decides most outcomes of the
    /// car-following probe (`experiments/recipe/car_following`), which buries PPO's credit for
    /// braking under steering noise. Needs `std_from_logs = true`.
    #[serde(default = "unit_std_scale", skip_serializing_if = "is_unit_std_scale")]
    pub std_scale: [f64; 2],
    /// The warm start was trained with the paper's pose-only agent <- agent edges and this run
    /// gives them relative motion (`[model] agent_edge_motion = true`): load it without, then
    /// add the motion inputs, their weights drawn as a fresh layer's (every trained weight kept;
    /// where no agent moves relative to another the actions are the warm start's).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub add_agent_edge_motion: bool,
    /// With `add_agent_edge_motion`: the new inputs' drawn weights times this. 0 keeps the warm
    /// start's actions exactly (the drawn ones perturbed a warm start's interaction features
    /// enough to add 11-18 points of long-tail collisions, `experiments/recipe/car_following`).
    #[serde(default = "unit_scale", skip_serializing_if = "is_unit_scale")]
    pub agent_edge_motion_scale: f64,
}

fn unit_scale() -> f64 {
    1.0
}

fn is_unit_scale(scale: &f64) -> bool {
    *scale == 1.0
}

fn unit_std_scale() -> [f64; 2] {
    [1.0, 1.0]
}

fn is_unit_std_scale(scale: &[f64; 2]) -> bool {
    *scale == unit_std_scale()
}

impl InitConfig {
    /// The `policy.bpk` this names.
    pub fn policy_file(&self) -> PathBuf {
        if self.policy.is_dir() {
            self.policy.join("policy.bpk")
        } else {
            self.policy.clone()
        }
    }
}

/// Where initial states come from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DataConfig {
    /// Use only the first this many nominal training scenes (tiny runs).
    pub nominal_limit: Option<usize>,
    /// Generated long-tail training scenarios: a folder written by `rtr scenarios generate`
    /// (its `train/` is used), or `None` to generate them at start.
    pub longtail_dir: Option<PathBuf>,
    /// When generating: in-distribution draws (half become training scenarios).
    pub longtail_generate: usize,
    /// Use only the first this many long-tail training scenarios.
    pub longtail_limit: Option<usize>,
    /// Curated scenes: a scene list (`rtr curate`: nominal training scenes an earlier policy
    /// commits an infraction on), relative to the run file. When set, the alpha share of
    /// initial states is drawn from these scenes instead of the long-tail set (the paper's
    /// "Curated" and "Nom+Cur" scenario sets); being real logs, they also get the imitation
    /// loss.
    pub curated: Option<PathBuf>,
    /// Cap on rollout steps (long-tail scenarios run 10-14 s); `None` = each scene's horizon.
    pub max_rollout_steps: Option<usize>,
    /// Weight of the A9 training split among the recorded (nominal) sources.
    pub a9_weight: f64,
    /// More recorded sources: CommonRoad files or folders, each with its weight. A nominal
    /// draw picks a source with probability proportional to its weight, then a scene of it
    /// uniformly. Empty (the default): A9 only.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub commonroad: Vec<CommonRoadSource>,
    /// More recorded sources: the A9 training split on its road bent by a curvature (not in
    /// the paper; `crate::data::bend_scenes`), each with its weight like a CommonRoad source.
    /// Empty (the default): the A9 as recorded only.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub a9_bends: Vec<A9Bend>,
}

/// The A9 training split on its road with `curvature` (1/m, positive to the left along the
/// reference line) added, drawn with `weight` among the recorded sources.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct A9Bend {
    pub curvature: f64,
    pub weight: f64,
}

/// CommonRoad scenario files (a file or a folder of `.xml` / `.xml.gz`) as a source of
/// recorded training scenes; every window of every file is used.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CommonRoadSource {
    /// Relative to the run file.
    pub path: PathBuf,
    pub weight: f64,
    /// Speed limit (m/s) of lanes the files give none; default 130 km/h.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed_limit: Option<f64>,
}

impl Default for DataConfig {
    fn default() -> Self {
        Self {
            nominal_limit: None,
            longtail_dir: None,
            longtail_generate: 333,
            longtail_limit: None,
            curated: None,
            max_rollout_steps: None,
            a9_weight: 1.0,
            commonroad: Vec::new(),
            a9_bends: Vec::new(),
        }
    }
}

/// Where and how the run executes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RunConfig {
    pub backend: Backend,
    /// Worker devices for data-parallel training (each minibatch is split across them);
    /// unset: one per core on the CPU backends, one on a GPU. How a run executes, not what it
    /// computes: losses and gradients agree to float rounding whatever the count, so a run may
    /// be resumed with another.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub devices: Option<usize>,
    /// Write a checkpoint every this many iterations (and always at the end).
    pub checkpoint_every: usize,
    /// Checkpoints kept besides the newest (older ones are deleted); unset: 1. Keeping more
    /// lets late checkpoints be evaluated side by side. How a run is stored, not what it
    /// computes: `--resume` does not compare it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub keep_checkpoints: Option<usize>,
    /// Stop after this many iterations in all (tiny runs, tests); `None` = all epochs.
    pub max_iterations: Option<usize>,
}

impl Default for RunConfig {
    fn default() -> Self {
        Self {
            backend: Backend::cpu_default(),
            devices: None,
            checkpoint_every: 1,
            keep_checkpoints: None,
            max_iterations: None,
        }
    }
}

impl RunConfig {
    /// The worker devices this run uses: `devices`, or the backend's default.
    pub fn device_count(&self) -> usize {
        self.devices
            .unwrap_or_else(|| super::shards::default_devices(self.backend))
    }
}

/// Most scenes or rollouts one batch may hold: far above what fits in memory here (the
/// paper's PPO batch is 192), low enough that a typo is refused instead of exhausting memory.
const MAX_BATCH: usize = 4096;

impl TrainConfig {
    /// What identifies a run for `--resume`: the config as TOML without `run.devices` and
    /// `run.backend` (how many workers computed a step, and on which backend, changes results
    /// by float rounding only: `tests/backends.rs`), so a run started on NdArray resumes on
    /// Flex; nor `run.keep_checkpoints` (how many are kept on disk).
    pub fn identity_toml(&self) -> Result<String> {
        let mut identity = self.clone();
        identity.run.devices = None;
        identity.run.keep_checkpoints = None;
        identity.run.backend = Backend::NdArray;
        toml::to_string(&identity)
            .map_err(|e| Error::InvalidArgument(format!("config does not serialise: {e}")))
    }

    /// Where `given` differs from this run's config in what `--resume` compares
    /// ([`Self::identity_toml`]): the first setting as `key: value in the run, value now`, or
    /// `None` when they agree.
    pub fn identity_difference(&self, given: &TrainConfig) -> Result<Option<String>> {
        if self.identity_toml()? == given.identity_toml()? {
            return Ok(None);
        }
        let flat = |c: &TrainConfig| -> Result<Vec<(String, String)>> {
            let text = c.identity_toml()?;
            let value: toml::Value = toml::from_str(&text)
                .map_err(|e| Error::InvalidArgument(format!("config does not read back: {e}")))?;
            let mut out = Vec::new();
            flatten_toml("", &value, &mut out);
            Ok(out)
        };
        let (run, now) = (flat(self)?, flat(given)?);
        let lookup = |list: &[(String, String)], key: &str| {
            list.iter()
                .find(|(k, _)| k == key)
                .map_or_else(|| "unset".to_string(), |(_, v)| v.clone())
        };
        Ok(run
            .iter()
            .chain(&now)
            .map(|(key, _)| key)
            .find(|key| lookup(&run, key) != lookup(&now, key))
            .map(|key| {
                format!(
                    "{key}: {} in the run, {} now",
                    lookup(&run, key),
                    lookup(&now, key)
                )
            }))
    }

    /// Whether the run trains on long-tail scenarios: a share of them (`alpha > 0`) and no
    /// curated scene list in their place.
    pub fn uses_longtail(&self) -> bool {
        self.alpha > 0.0 && self.data.curated.is_none()
    }

    /// The files and folders the run reads besides its run file, each named by its field, so
    /// that a command can keep its outputs off them.
    pub fn input_paths(&self) -> Vec<(&'static str, PathBuf)> {
        let mut out = Vec::new();
        let mut add = |field: &'static str, path: Option<&PathBuf>| {
            if let Some(p) = path {
                out.push((field, p.clone()));
            }
        };
        add("dynamics", self.dynamics.as_ref());
        add("init.policy", self.init.as_ref().map(|i| &i.policy));
        add(
            "reference.checkpoint",
            self.reference.as_ref().and_then(|r| r.checkpoint.as_ref()),
        );
        if self.uses_longtail() {
            add("data.longtail_dir", self.data.longtail_dir.as_ref());
        }
        add("data.curated", self.data.curated.as_ref());
        for source in &self.data.commonroad {
            add("data.commonroad.path", Some(&source.path));
        }
        out
    }

    /// Reads and validates a run file; a relative reference checkpoint is resolved against the
    /// file's folder.
    pub fn from_toml_file(path: &Path) -> Result<Self> {
        let text = crate::io::read_text(path, crate::io::Format::Settings)?;
        let mut config = Self::from_toml_str(&text, &path.display().to_string())?;
        if let Some(checkpoint) = config
            .reference
            .as_mut()
            .and_then(|r| r.checkpoint.as_mut())
            && checkpoint.is_relative()
        {
            *checkpoint = path.parent().unwrap_or(Path::new(".")).join(&*checkpoint);
        }
        if let Some(dynamics) = config.dynamics.as_mut() {
            if dynamics.is_relative() {
                *dynamics = path.parent().unwrap_or(Path::new(".")).join(&*dynamics);
            }
            // Absolute in the run's config.toml, so the run evaluates from any folder.
            if let Ok(absolute) = dynamics.canonicalize() {
                *dynamics = absolute;
            }
        }
        if let Some(curated) = config.data.curated.as_mut()
            && curated.is_relative()
        {
            *curated = path.parent().unwrap_or(Path::new(".")).join(&*curated);
        }
        if let Some(init) = config.init.as_mut()
            && init.policy.is_relative()
        {
            init.policy = path.parent().unwrap_or(Path::new(".")).join(&init.policy);
        }
        for source in &mut config.data.commonroad {
            if source.path.is_relative() {
                source.path = path.parent().unwrap_or(Path::new(".")).join(&source.path);
            }
        }
        Ok(config)
    }

    /// The simulator this run trains (and is evaluated) in: the paper's bicycle at dt = 0.5 s
    /// with the run's action limits, plus the physics terms of its `dynamics` file, whose
    /// parameters live on `device`.
    pub fn dynamics(&self, device: &burn::prelude::Device) -> Result<Dynamics> {
        let mut dynamics = Dynamics::bicycle(0.5);
        dynamics.limits = Some(self.limits);
        if let Some(path) = &self.dynamics {
            dynamics = DynamicsFile::load(path)?.apply(dynamics, device);
        }
        Ok(dynamics)
    }

    /// Parses and validates a run file's text; a refused value is reported at its line with
    /// the value found.
    pub fn from_toml_str(text: &str, source_name: &str) -> Result<Self> {
        let config: Self = parse_toml(text, source_name)?;
        config.checks().map_err(|(field, message)| {
            crate::io::field_error(text, source_name, field, &message)
        })?;
        config.model.validate_text(text, source_name, "model.")?;
        Ok(config)
    }

    /// Checks every range a run depends on; errors name the field.
    pub fn validate(&self, source_name: &str) -> Result<()> {
        self.checks().map_err(|(field, message)| {
            Error::invalid(source_name, format!("field `{field}`"), message)
        })?;
        self.model.validate(source_name)
    }

    fn checks(&self) -> Check {
        self.check_data()
            .and_then(|()| self.check_optimizer())
            .and_then(|()| self.check_ppo())
            .and_then(|()| self.check_imitation())
            .and_then(|()| self.check_reference())
            .and_then(|()| self.check_init())
            .and_then(|()| self.check_budget())
            .and_then(|()| self.check_paths())
    }

    /// Every path the run reads names something: `""` would resolve to the run file's own
    /// folder or to nothing.
    fn check_paths(&self) -> Check {
        match self
            .input_paths()
            .into_iter()
            .find(|(_, path)| path.as_os_str().is_empty())
        {
            Some((field, _)) => refuse(field, "is empty; expected a path"),
            None => Ok(()),
        }
    }

    /// The mixture: alpha, lambda and the recorded sources.
    fn check_data(&self) -> Check {
        let unit = |x: f64| x.is_finite() && (0.0..=1.0).contains(&x);
        if !unit(self.alpha) {
            return refuse("alpha", "expected a share in [0, 1]");
        }
        if self.data.curated.is_some() && self.data.longtail_dir.is_some() {
            return refuse(
                "data.curated",
                "curated scenes replace the long-tail set as the alpha share; drop data.longtail_dir \
                 (or the --scenarios flag)",
            );
        }
        let weight = |w: f64| w.is_finite() && w >= 0.0;
        if !weight(self.data.a9_weight) {
            return refuse("data.a9_weight", "expected a finite weight >= 0");
        }
        if self.data.commonroad.iter().any(|c| !weight(c.weight)) {
            return refuse("data.commonroad.weight", "expected a finite weight >= 0");
        }
        let max_speed = crate::vehicle::MAX_SPEED;
        if self
            .data
            .commonroad
            .iter()
            .filter_map(|c| c.speed_limit)
            .any(|v| !(v > 0.0 && v <= max_speed))
        {
            return refuse(
                "data.commonroad.speed_limit",
                format!("expected m/s in (0, {max_speed}]"),
            );
        }
        if self.data.a9_bends.iter().any(|b| !weight(b.weight)) {
            return refuse("data.a9_bends.weight", "expected a finite weight >= 0");
        }
        if let Some(problem) = self
            .data
            .a9_bends
            .iter()
            .find_map(|b| crate::map::bend_curvature_problem(b.curvature))
        {
            return refuse("data.a9_bends.curvature", problem);
        }
        let other_weight: f64 = self.data.commonroad.iter().map(|c| c.weight).sum::<f64>()
            + self.data.a9_bends.iter().map(|b| b.weight).sum::<f64>();
        if self.data.a9_weight + other_weight <= 0.0 {
            return refuse(
                "data.a9_weight",
                "the recorded sources' weights (A9, data.commonroad, data.a9_bends) sum to 0",
            );
        }
        if self.data.curated.is_some()
            && !(self.data.commonroad.is_empty() && self.data.a9_bends.is_empty())
        {
            return refuse(
                "data.curated",
                "curated scenes come from the A9 split as recorded; drop data.commonroad and \
                 data.a9_bends, or data.curated",
            );
        }
        if !(self.lambda.is_finite() && self.lambda >= 0.0) {
            return refuse("lambda", "expected a finite weight >= 0");
        }
        Ok(())
    }

    /// `[optimizer]`.
    fn check_optimizer(&self) -> Check {
        let positive = |x: f64| x.is_finite() && x > 0.0;
        let o = &self.optimizer;
        // Adam's step is about the learning rate per parameter: above 1 every step moves each
        // weight by more than the weights' own scale, and training can only diverge.
        if !(positive(o.learning_rate) && o.learning_rate <= 1.0) {
            return refuse("optimizer.learning_rate", "expected a rate in (0, 1]");
        }
        if !(o.decay.is_finite() && o.decay > 0.0 && o.decay <= 1.0) {
            return refuse("optimizer.decay", "expected a factor in (0, 1]");
        }
        if o.epochs == 0 {
            return refuse("optimizer.epochs", "expected at least 1 epoch");
        }
        if o.decay_every_epochs == 0 {
            return refuse(
                "optimizer.decay_every_epochs",
                "expected a decay every 1 or more epochs",
            );
        }
        if !(o.weight_decay.is_finite() && o.weight_decay >= 0.0) {
            return refuse("optimizer.weight_decay", "expected a finite value >= 0");
        }
        if !positive(o.grad_clip_norm) {
            return refuse("optimizer.grad_clip_norm", "expected a finite norm > 0");
        }
        if o.epoch_scenes == Some(0) {
            return refuse("optimizer.epoch_scenes", "expected at least 1 scene");
        }
        Ok(())
    }

    /// `[ppo]`.
    fn check_ppo(&self) -> Check {
        let positive = |x: f64| x.is_finite() && x > 0.0;
        let unit = |x: f64| x.is_finite() && (0.0..=1.0).contains(&x);
        let p = &self.ppo;
        if p.batch == 0 {
            return refuse("ppo.batch", "expected at least 1 rollout per iteration");
        }
        if p.minibatch == 0 || !p.batch.is_multiple_of(p.minibatch) {
            return refuse(
                "ppo.minibatch",
                format!(
                    "expected a divisor of ppo.batch ({}): every minibatch of an iteration the \
                     same size",
                    p.batch
                ),
            );
        }
        if p.epochs == 0 {
            return refuse("ppo.epochs", "expected at least 1");
        }
        if !(positive(p.clip) && p.clip < 1.0) {
            return refuse("ppo.clip", "expected a ratio clip in (0, 1)");
        }
        if !unit(p.gamma) {
            return refuse("ppo.gamma", "expected a discount in [0, 1]");
        }
        if !unit(p.gae_lambda) {
            return refuse("ppo.gae_lambda", "expected a GAE lambda in [0, 1]");
        }
        if !p
            .noise_correlation
            .iter()
            .all(|r| r.is_finite() && (0.0..1.0).contains(r))
        {
            return refuse(
                "ppo.noise_correlation",
                "expected per control a correlation in [0, 1) between one step's noise and the next",
            );
        }
        if !p.explore_steering && p.noise_correlation[1] != 0.0 {
            return refuse(
                "ppo.noise_correlation",
                "a steering correlation needs steering noise: with explore_steering = false set \
                 it to 0",
            );
        }
        if !(p.value_weight.is_finite() && p.value_weight >= 0.0) {
            return refuse("ppo.value_weight", "expected a finite weight >= 0");
        }
        if p.target_kl.is_some_and(|k| !positive(k)) {
            return refuse(
                "ppo.target_kl",
                "expected a KL divergence per agent-step > 0 (e.g. 0.01), or no key for a fixed rate",
            );
        }
        Ok(())
    }

    /// `[imitation]` and `[shaping]`.
    fn check_imitation(&self) -> Check {
        let positive = |x: f64| x.is_finite() && x > 0.0;
        if let Some(why) = self.imitation.perturbation.as_ref().and_then(|p| p.check()) {
            return refuse("imitation.perturbation", why);
        }
        if let Some(why) = super::agent_dropout::check(self.imitation.agent_dropout) {
            return refuse("imitation.agent_dropout", why);
        }
        if self.imitation.minibatch == 0 {
            return refuse("imitation.minibatch", "expected at least 1");
        }
        if !positive(self.imitation.huber_delta) {
            return refuse(
                "imitation.huber_delta",
                "expected a finite threshold > 0 (m)",
            );
        }
        if !positive(self.shaping.tolerance) || !self.shaping.weight.is_finite() {
            return refuse(
                "shaping.tolerance",
                "expected a tolerance > 0 (m/s) and a finite weight",
            );
        }
        Ok(())
    }

    /// `[reference]` against the method and the warm start.
    fn check_reference(&self) -> Check {
        match (&self.reference, self.method.uses_reference()) {
            (None, true) => {
                return refuse(
                    "reference",
                    "KL-L and KL-R need [reference] checkpoint = \"<frozen IL policy.bpk>\" \
                     or init = true (the warm start)",
                );
            }
            (Some(r), _) if !(r.weight.is_finite() && r.weight >= 0.0) => {
                return refuse("reference.weight", "expected a finite weight >= 0");
            }
            (Some(r), _) if r.checkpoint.is_some() == r.init => {
                return refuse(
                    "reference",
                    "expected exactly one of checkpoint = \"<frozen IL policy.bpk>\" and \
                     init = true (the warm start)",
                );
            }
            (Some(r), _) if r.init && self.init.is_none() => {
                return refuse("reference.init", "needs an [init] warm start to refer to");
            }
            (Some(r), _) if r.init && r.std_from_logs => {
                return refuse(
                    "reference.std_from_logs",
                    "the warm start's sigma is [init]'s (std_from_logs, std_scale); drop it here",
                );
            }
            // A section the method never reads would be recorded in the run's config as if
            // it were in effect.
            (Some(_), false) => {
                return refuse(
                    "reference",
                    format!(
                        "only KL-L and KL-R use a [reference]; {} does not: drop the section",
                        self.method.name()
                    ),
                );
            }
            _ => {}
        }
        Ok(())
    }

    /// `[init]`.
    fn check_init(&self) -> Check {
        if self
            .init
            .as_ref()
            .is_some_and(|i| i.add_agent_edge_motion && !self.model.agent_edge_motion)
        {
            return refuse(
                "init.add_agent_edge_motion",
                "adds relative motion to a pose-only warm start: it needs [model] \
                 agent_edge_motion = true",
            );
        }
        if let Some(init) = &self.init {
            if !(init.agent_edge_motion_scale.is_finite() && init.agent_edge_motion_scale >= 0.0)
                || (init.agent_edge_motion_scale != 1.0 && !init.add_agent_edge_motion)
            {
                return refuse(
                    "init.agent_edge_motion_scale",
                    "expected a factor >= 0 for the weights of init.add_agent_edge_motion",
                );
            }
            if !init.std_scale.iter().all(|s| s.is_finite() && *s > 0.0) {
                return refuse("init.std_scale", "expected two finite factors > 0");
            }
            if !init.std_from_logs && !is_unit_std_scale(&init.std_scale) {
                return refuse(
                    "init.std_scale",
                    "scales the sigma from the logs: it needs std_from_logs = true",
                );
            }
        }
        Ok(())
    }

    /// What the method may draw, and the counts that size tensors, loops and the run.
    fn check_budget(&self) -> Check {
        let (o, p) = (&self.optimizer, &self.ppo);
        if !self.method.uses_ppo() && self.alpha > 0.0 {
            return refuse(
                "alpha",
                "BC and IL learn from logs only: long-tail scenarios have no logs (set alpha = 0)",
            );
        }
        if self.data.max_rollout_steps == Some(0) {
            return refuse("data.max_rollout_steps", "expected at least 1 step");
        }
        // Counts that size tensors or loops: bounded, so a typo is an error, not an abort.
        for (field, value, max) in [
            (
                "imitation.minibatch",
                Some(self.imitation.minibatch),
                MAX_BATCH,
            ),
            ("ppo.batch", Some(p.batch), MAX_BATCH),
            ("ppo.epochs", Some(p.epochs), 1_000),
            ("optimizer.epochs", Some(o.epochs), 100_000),
            ("optimizer.epoch_scenes", o.epoch_scenes, 10_000_000),
            ("data.max_rollout_steps", self.data.max_rollout_steps, 1_200),
            ("run.devices", self.run.devices, 256),
            ("run.max_iterations", self.run.max_iterations, 100_000_000),
        ] {
            if value.is_some_and(|v| v > max) {
                return refuse(field, format!("expected at most {max}"));
            }
        }
        for (field, value) in [
            ("data.nominal_limit", self.data.nominal_limit),
            ("run.max_iterations", self.run.max_iterations),
        ] {
            if value == Some(0) {
                return refuse(field, "expected at least 1 (0 would train on nothing)");
            }
        }
        if self.method.uses_ppo() && self.alpha > 0.0 && self.data.longtail_limit == Some(0) {
            return refuse(
                "data.longtail_limit",
                "alpha > 0 draws long-tail scenarios; a limit of 0 leaves none (set alpha = 0 or \
                 raise the limit)",
            );
        }
        if let Err(why) = self.limits.check() {
            return refuse("limits", why);
        }

        if self.run.devices == Some(0) {
            return refuse("run.devices", "expected at least 1 device");
        }
        if self.run.checkpoint_every == 0 {
            return refuse(
                "run.checkpoint_every",
                "expected a checkpoint every 1 or more iterations",
            );
        }
        Ok(())
    }
}

/// A field of a run file and why its value is refused.
type Check = std::result::Result<(), (&'static str, String)>;

fn refuse(field: &'static str, message: impl Into<String>) -> Check {
    Err((field, message.into()))
}

/// Every leaf of `value` as (`dotted.key`, value), arrays indexed (`data.commonroad[0].path`).
fn flatten_toml(prefix: &str, value: &toml::Value, out: &mut Vec<(String, String)>) {
    match value {
        toml::Value::Table(table) => {
            for (key, inner) in table {
                let key = if prefix.is_empty() {
                    key.clone()
                } else {
                    format!("{prefix}.{key}")
                };
                flatten_toml(&key, inner, out);
            }
        }
        toml::Value::Array(items) if items.iter().any(|v| v.is_table()) => {
            for (i, inner) in items.iter().enumerate() {
                flatten_toml(&format!("{prefix}[{i}]"), inner, out);
            }
        }
        leaf => out.push((prefix.to_string(), leaf.to_string())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_paper_table() {
        let c = TrainConfig::from_toml_str("method = \"RTR\"", "t").expect("parses");
        assert_eq!(c.optimizer.learning_rate, 1e-5);
        assert_eq!(c.optimizer.weight_decay, 1e-4);
        assert_eq!(c.optimizer.grad_clip_norm, 1.0);
        assert_eq!(c.optimizer.epochs, 10);
        assert_eq!((c.ppo.batch, c.ppo.minibatch, c.ppo.epochs), (192, 32, 1));
        assert_eq!(
            (c.ppo.clip, c.ppo.gamma, c.ppo.gae_lambda),
            (0.2, 0.79, 1.0)
        );
        assert_eq!(c.imitation.minibatch, 32);
        // 0.2x every 3 epochs.
        let lr = |e| c.optimizer.learning_rate_at(e);
        assert_eq!(lr(2), 1e-5);
        assert!((lr(3) - 2e-6).abs() < 1e-18 && (lr(9) - 8e-8).abs() < 1e-18);
    }

    /// A run started on one backend or worker count resumes on another (results differ by
    /// float rounding only); anything that changes what is computed still counts.
    #[test]
    fn resume_identity_ignores_backend_and_workers_only() {
        let parse = |text: &str| TrainConfig::from_toml_str(text, "run.toml").expect("parses");
        let base = parse("method = \"IL\"\n[run]\nbackend = \"ndarray\"");
        let flex = parse("method = \"IL\"\n[run]\nbackend = \"flex\"\ndevices = 3");
        let other = parse("method = \"IL\"\nseed = 7\n[run]\nbackend = \"ndarray\"");
        let identity = |c: &TrainConfig| c.identity_toml().expect("serialises");
        assert_eq!(identity(&base), identity(&flex));
        assert_ne!(identity(&base), identity(&other));
        assert_eq!(base.identity_difference(&flex).expect("compares"), None);
        // --resume names what differs, so the user knows which file or flag to fix.
        let difference = base.identity_difference(&other).expect("compares");
        assert_eq!(difference.as_deref(), Some("seed: 2023 in the run, 7 now"));
    }

    #[test]
    fn bad_fields_are_named() {
        let err = TrainConfig::from_toml_str("method = \"RTR\"\nalpha = 1.5", "run.toml")
            .expect_err("alpha out of range");
        // At its line, with the value found.
        assert!(
            err.to_string()
                .contains("line 2, column 1: field `alpha` = 1.5: expected a share"),
            "{err}"
        );
        let err = TrainConfig::from_toml_str("method = \"RTR\"\n[ppo]\nbatch = 100", "run.toml")
            .expect_err("batch not a multiple");
        assert!(
            err.to_string().contains("field `ppo.minibatch`")
                && err.to_string().contains("divisor of ppo.batch (100)"),
            "{err}"
        );
        let err = TrainConfig::from_toml_str("method = \"IL\"\n[run]\ncheckpoint_every = 0", "r")
            .expect_err("no checkpoints");
        assert!(
            err.to_string()
                .contains("line 3, column 1: field `run.checkpoint_every` = 0"),
            "{err}"
        );
        let err = TrainConfig::from_toml_str("method = \"KL-R\"", "run.toml")
            .expect_err("needs a reference");
        assert!(err.to_string().contains("reference"), "{err}");
        // The reference is a checkpoint or the warm start, never both or neither.
        for (method, sections, field) in [
            ("KL-L", "[reference]\nweight = 1.0", "reference"),
            (
                "KL-L",
                "[init]\npolicy = \"il\"\n[reference]\ncheckpoint = \"il.bpk\"\ninit = true",
                "reference",
            ),
            ("KL-R", "[reference]\ninit = true", "reference.init"),
            // Checked for every method, though only KL-L and KL-R use it.
            ("RTR", "[reference]\nweight = 1.0", "reference"),
            // A complete section a method never reads.
            ("RTR", "[reference]\ncheckpoint = \"il.bpk\"", "reference"),
        ] {
            let text = format!("method = \"{method}\"\n{sections}");
            let err = TrainConfig::from_toml_str(&text, "run.toml").expect_err(sections);
            assert!(
                err.to_string().contains(&format!("field `{field}`")),
                "{sections}: {err}"
            );
        }
        let err = TrainConfig::from_toml_str(
            "method = \"KL-L\"\n[init]\npolicy = \"il\"\n[reference]\ninit = true\nstd_from_logs = true",
            "run.toml",
        )
        .expect_err("the warm start's sigma is [init]'s");
        assert!(
            err.to_string()
                .contains("line 6, column 1: field `reference.std_from_logs` = true"),
            "{err}"
        );
        let ok = "method = \"KL-R\"\n[init]\npolicy = \"il\"\n[reference]\ninit = true";
        TrainConfig::from_toml_str(ok, "run.toml").expect("the warm start as reference");
        let err = TrainConfig::from_toml_str("method = \"RTR\"\nlamda = 1", "run.toml")
            .expect_err("typo");
        assert!(err.to_string().contains("line 2"), "{err}");
        let err =
            TrainConfig::from_toml_str("method = \"PPO\"", "run.toml").expect_err("unknown method");
        assert!(err.to_string().contains("RTR"), "{err}");
        let widen = "method = \"IL\"\n[init]\npolicy = \"il\"\nadd_agent_edge_motion = true\n";
        let err = TrainConfig::from_toml_str(widen, "run.toml").expect_err("pose-only model");
        assert!(
            err.to_string().contains("init.add_agent_edge_motion")
                && err.to_string().contains("agent_edge_motion = true"),
            "{err}"
        );
        let config =
            TrainConfig::from_toml_str(&format!("{widen}[model]\nagent_edge_motion = true\n"), "r")
                .expect("widening a pose-only warm start");
        assert!(config.model.agent_edge_motion);
        let alone = "method = \"IL\"\n[init]\npolicy = \"il\"\nagent_edge_motion_scale = 0.0\n";
        let err = TrainConfig::from_toml_str(alone, "run.toml").expect_err("nothing to scale");
        assert!(
            err.to_string().contains("init.agent_edge_motion_scale"),
            "{err}"
        );
        let scaled = "method = \"RTR\"\n[init]\npolicy = \"il\"\nstd_scale = [1.0, 0.25]\n";
        let err = TrainConfig::from_toml_str(scaled, "run.toml").expect_err("no sigma to scale");
        assert!(
            err.to_string().contains("init.std_scale")
                && err.to_string().contains("std_from_logs = true"),
            "{err}"
        );
        let scaled = scaled.replace("std_scale", "std_from_logs = true\nstd_scale");
        let config = TrainConfig::from_toml_str(&scaled, "run.toml").expect("scaled sigma");
        assert_eq!(config.init.map(|i| i.std_scale), Some([1.0, 0.25]));
        let err = TrainConfig::from_toml_str(&scaled.replace("0.25", "0.0"), "run.toml")
            .expect_err("zero sigma");
        assert!(err.to_string().contains("init.std_scale"), "{err}");
        let err = TrainConfig::from_toml_str(&scaled.replace(", 0.25", ""), "run.toml")
            .expect_err("one factor");
        assert!(err.to_string().contains("line 5"), "{err}");
    }
}
