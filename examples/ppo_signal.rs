//! `cargo run --release --example ppo_signal -- RUN_FILE CHECKPOINT SCENARIOS [SCENES] [SIGMA]`:
//! which way does PPO push the acceleration of a car that closes on the one ahead, and how
//! clearly?
//!
//! Collects PPO experience exactly as training does (the run file's data, dynamics, reward and
//! PPO settings; the checkpoint's policy, sigma and value network) from SCENES long-tail initial
//! states of SCENARIOS/train (default 96), and sorts every alive agent-step by what is around
//! the agent:
//! - `closing`: a car ahead in its lane (centre within 1.8 m sideways, 0-100 m ahead) that it
//!   closes on faster than 2 m/s, with a time to contact under 8 s;
//! - `approached`: the agent is that car ahead for some follower;
//! - `free`: neither.
//!
//! At ratio 1 PPO's gradient on an agent's mean action is A (a - mu) / sigma^2, so the sign of
//! E[A eta] (eta = (a - mu) / sigma, the standardised sampled noise) in a class is the direction
//! the update moves that control's mean there. Printed per class and control (JSON): the
//! agent-steps, the agents, E[A eta] and its t statistic with the agents as independent units
//! (their steps share one return). A negative acceleration entry for `closing` is a push towards
//! braking. The t statistic grows with the square root of the scenes: t = 4 over 96 scenes is
//! about 1.2 over the 8 long-tail scenes of one PPO iteration of the recipe.
//!
//! SIGMA (`ACC,STEER`, m/s^2 and rad) replaces the checkpoint's exploration sigma, e.g. to ask
//! whether a wider acceleration sigma makes the braking credit clearer.
//!
//! Why this exists: no PPO run of issue 18 learned to brake for a slower car ahead
//! (`experiments/recipe/steer_feedforward/results.md`).

use std::path::Path;

use burn::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rtr::model::{AgentInput, PolicyNetwork, ValueNetwork};
use rtr::sim::MapCaches;
use rtr::train::experience::{CollectNetworks, Experience, RewardSettings, collect};
use rtr::train::{TrainConfig, TrainingData};

/// Same-lane test: the leader's centre within this many metres sideways (m).
const LANE_HALF_WIDTH_M: f32 = 1.8;
const LOOKAHEAD_M: f32 = 100.0;
const MIN_CLOSING_MPS: f32 = 2.0;
const MAX_TTC_S: f32 = 8.0;
/// Scenes per collected part (as training's minibatch).
const PART_SCENES: usize = 8;
/// The history's speeds are in network units: m/s x 0.1 (`SPEED_SCALE`, src/model/input.rs).
const NETWORK_SPEED_PER_MPS: f32 = 0.1;

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Situation {
    Closing,
    Approached,
    Free,
}

const SITUATIONS: [Situation; 3] = [Situation::Closing, Situation::Approached, Situation::Free];

/// Per agent (the independent unit): its summed A eta per control and its steps, per class.
#[derive(Default, Clone)]
struct AgentSums {
    steps: [usize; 3],
    a_eta: [[f64; 2]; 3],
}

fn main() -> std::process::ExitCode {
    match run().and_then(|()| Ok(rtr::io::console::check_stdout()?)) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            rtr::errln!("ppo_signal: {e}");
            std::process::ExitCode::from(2)
        }
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    rtr::allocator::tune_for_tensors();
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 3 {
        return Err(
            "usage: cargo run --release --example ppo_signal -- RUN_FILE CHECKPOINT \
                    SCENARIOS [SCENES] [ACC_SIGMA,STEER_SIGMA]"
                .into(),
        );
    }
    let scenes: usize = match args.get(3) {
        None => 96,
        Some(s) => s
            .parse()
            .ok()
            .filter(|&k: &usize| k > 0)
            .ok_or_else(|| format!("SCENES: expected a count of scenes >= 1, got `{s}`"))?,
    };
    let sigma = args.get(4).map(|s| parse_sigma(s)).transpose()?;
    let mut config = TrainConfig::from_toml_file(Path::new(&args[0]))?;
    if config.method.uses_reference() {
        return Err(format!(
            "RUN_FILE {}: method {} scores against a frozen reference policy, which this probe \
             does not load; give a run file of BC+RL, RL, RL-Shaped or RTR",
            args[0],
            config.method.name()
        )
        .into());
    }
    let scenarios = Path::new(&args[2]);
    if !scenarios.join("train").is_dir() {
        return Err(format!(
            "SCENARIOS {}: no train/ folder in it; expected the folder `rtr scenarios generate \
             --out` wrote",
            scenarios.display()
        )
        .into());
    }
    config.data.longtail_dir = Some(scenarios.to_path_buf());
    let device = rtr::backend::Backend::reference_device(false);
    let checkpoint = Path::new(&args[1]);
    if !checkpoint.join("value.bpk").is_file() {
        return Err(format!(
            "CHECKPOINT {}: no value.bpk in it; expected a training checkpoint folder (policy.bpk \
             and value.bpk), e.g. RUN/checkpoints/iter-000009",
            checkpoint.display()
        )
        .into());
    }
    let policy = rtr::train::checkpoint::load_policy(
        &checkpoint.join("policy.bpk"),
        &config.model,
        &device,
    )?;
    let policy = match sigma {
        Some(sigma) => policy.with_constant_std(sigma),
        None => policy,
    };
    let value = rtr::train::checkpoint::load_module(
        ValueNetwork::new(&config.model, &device),
        &checkpoint.join("value.bpk"),
    )?;
    let dataset = rtr::data::A9Dataset::load(&rtr::data::a9::default_dir())?;
    let data = TrainingData::load(&dataset, &config.data, true)?;
    let experience = collect_longtail(&config, &data, &policy, &value, scenes, &device)?;
    let sums: Vec<AgentSums> = experience
        .iter()
        .flat_map(|e| agent_sums(e, &policy))
        .collect();
    print_report(&sums, &experience, sigma)?;
    Ok(())
}

/// `ACC,STEER` (m/s^2, rad), both > 0.
fn parse_sigma(text: &str) -> Result<[f64; 2], String> {
    let refuse =
        || format!("SIGMA: expected `ACC,STEER`, two sigmas > 0 (m/s^2, rad), got `{text}`");
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>().map_err(|_| refuse()))
        .collect::<Result<_, _>>()?;
    match values[..] {
        [a, s] if a > 0.0 && s > 0.0 => Ok([a, s]),
        _ => Err(refuse()),
    }
}

fn collect_longtail(
    config: &TrainConfig,
    data: &TrainingData,
    policy: &PolicyNetwork,
    value: &ValueNetwork,
    scenes: usize,
    device: &Device,
) -> rtr::Result<Vec<Experience>> {
    let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
    let states = data.sample(&mut rng, scenes, 1.0);
    let dynamics = config.dynamics(device)?;
    let nets = CollectNetworks {
        policy,
        value,
        reference: None,
    };
    let rewards = RewardSettings::of(config);
    let mut caches = MapCaches::default();
    let mut out = Vec::new();
    for (k, chunk) in states.chunks(PART_SCENES).enumerate() {
        for part in data.parts(chunk) {
            out.push(collect(
                &part,
                &nets,
                device,
                &dynamics,
                &mut caches,
                config.data.max_rollout_steps,
                &config.ppo,
                &rewards,
                config.seed ^ k as u64,
            )?);
        }
    }
    Ok(out)
}

fn host<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.into_data()
        .convert::<f32>()
        .try_into_vec()
        .unwrap_or_default()
}

fn host_bool<const D: usize>(t: Tensor<D, burn::tensor::Bool>) -> Vec<bool> {
    t.into_data().try_into_vec_as().unwrap_or_default()
}

/// Every agent's sums over its alive steps, by situation.
fn agent_sums(exp: &Experience, policy: &PolicyNetwork) -> Vec<AgentSums> {
    let [b, n, steps] = exp.advantages.dims();
    let advantages = host(exp.advantages.clone());
    let alive = host_bool(exp.alive.clone());
    let lengths = host(exp.batch.agent_size.clone().narrow(2, 0, 1).reshape([b, n]));
    let lanes = &exp.lanes;
    let encoded = policy.encode_lanes(lanes);
    let mut sums = vec![AgentSums::default(); b * n];
    for (t, (agents, action)) in exp.observations.iter().zip(&exp.actions).enumerate() {
        let dist = exp.as_sampled(t, policy.forward(agents, lanes, &encoded));
        let eta = host((action.clone() - dist.mean.clone()) / dist.std());
        let situations = situations(agents, &lengths, policy);
        for i in 0..b * n {
            if !alive[i * steps + t] {
                continue;
            }
            let s = situations[i] as usize;
            let a = advantages[i * steps + t] as f64;
            sums[i].steps[s] += 1;
            for c in 0..2 {
                sums[i].a_eta[s][c] += a * eta[i * 2 + c] as f64;
            }
        }
    }
    sums.into_iter()
        .filter(|s| s.steps.iter().any(|&k| k > 0))
        .collect()
}

/// `[B*N]`: each agent's situation at the observed step.
fn situations(agents: &AgentInput, lengths: &[f32], policy: &PolicyNetwork) -> Vec<Situation> {
    let [b, n, h, f] = agents.history.dims();
    let pose = host(agents.pose.clone());
    let present = host_bool(agents.mask.clone());
    let speed_feature = rtr::model::input::history_features(policy.config()) - 4;
    let speed: Vec<f32> = host(
        agents
            .history
            .clone()
            .narrow(2, h - 1, 1)
            .narrow(3, speed_feature, 1)
            .reshape([b, n]),
    )
    .into_iter()
    .map(|v| v / NETWORK_SPEED_PER_MPS)
    .collect();
    debug_assert!(speed_feature < f);
    let mut out = vec![Situation::Free; b * n];
    for s in 0..b {
        for i in 0..n {
            let fi = s * n + i;
            if !present[fi] {
                continue;
            }
            let (hx, hy) = (pose[fi * 3 + 2].cos(), pose[fi * 3 + 2].sin());
            let mut nearest: Option<(f32, usize)> = None;
            for j in (0..n).filter(|&j| j != i && present[s * n + j]) {
                let lj = s * n + j;
                let (dx, dy) = (
                    pose[lj * 3] - pose[fi * 3],
                    pose[lj * 3 + 1] - pose[fi * 3 + 1],
                );
                let (ahead, side) = (dx * hx + dy * hy, -dx * hy + dy * hx);
                if ahead > 0.0 && ahead < LOOKAHEAD_M && side.abs() < LANE_HALF_WIDTH_M {
                    let gap = ahead - 0.5 * (lengths[fi] + lengths[lj]);
                    if nearest.is_none_or(|(g, _)| gap < g) {
                        nearest = Some((gap, lj));
                    }
                }
            }
            if let Some((gap, lj)) = nearest {
                let relative_heading = pose[lj * 3 + 2] - pose[fi * 3 + 2];
                let closing = speed[fi] - speed[lj] * relative_heading.cos();
                if closing > MIN_CLOSING_MPS && gap.max(0.0) / closing < MAX_TTC_S {
                    out[fi] = Situation::Closing;
                    if out[lj] == Situation::Free {
                        out[lj] = Situation::Approached;
                    }
                }
            }
        }
    }
    out
}

fn print_report(
    sums: &[AgentSums],
    experience: &[Experience],
    sigma: Option<[f64; 2]>,
) -> rtr::Result<()> {
    let collided: usize = experience.iter().map(|e| e.stats.collided).sum();
    let offroad: usize = experience.iter().map(|e| e.stats.offroad).sum();
    let agents: usize = experience.iter().map(|e| e.stats.agents).sum();
    let mut classes = Vec::new();
    for (s, situation) in SITUATIONS.iter().enumerate() {
        let units: Vec<&AgentSums> = sums.iter().filter(|a| a.steps[s] > 0).collect();
        let steps: usize = units.iter().map(|a| a.steps[s]).sum();
        let per_control: Vec<serde_json::Value> = (0..2)
            .map(|c| {
                let x: Vec<f64> = units.iter().map(|a| a.a_eta[s][c]).collect();
                let (mean_per_step, t) = clustered_mean(&x, steps);
                serde_json::json!({ "mean_a_eta": mean_per_step, "t": t })
            })
            .collect();
        classes.push(serde_json::json!({
            "situation": format!("{situation:?}").to_lowercase(),
            "agent_steps": steps,
            "agents": units.len(),
            "acceleration": per_control[0],
            "steering": per_control[1],
        }));
    }
    let report = serde_json::json!({
        "sigma": sigma.map_or("the checkpoint's".to_string(), |s| format!("{s:?}")),
        "agents": agents,
        "collided_pct": 100.0 * collided as f64 / agents.max(1) as f64,
        "offroad_pct": 100.0 * offroad as f64 / agents.max(1) as f64,
        "classes": classes,
    });
    rtr::outln!(
        "{}",
        serde_json::to_string_pretty(&report).unwrap_or_default()
    )
}

/// Mean per agent-step of per-agent sums `x` (over `steps` steps in all), and its t statistic
/// with the agents as the independent units.
fn clustered_mean(x: &[f64], steps: usize) -> (f64, f64) {
    let k = x.len() as f64;
    if k < 2.0 || steps == 0 {
        return (0.0, 0.0);
    }
    let total: f64 = x.iter().sum();
    let mean_unit = total / k;
    let var = x.iter().map(|v| (v - mean_unit).powi(2)).sum::<f64>() / (k - 1.0);
    let t = mean_unit / (var / k).sqrt().max(1e-12);
    (total / steps as f64, t)
}
