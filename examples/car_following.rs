//! `cargo run --release --example car_following -- CHECKPOINT...`: does a trained policy brake
//! for a slower car ahead?
//!
//! On a generated straight 3 x 3.75 m road, a policy-driven follower starts in the middle lane
//! behind a replayed leader (it follows its scripted log, whatever the follower does), both
//! with a straight constant-speed 2 s history. The leader drives at 28 m/s, either steadily or
//! braking at 4 m/s^2 to 16 m/s from the first simulated step; the follower starts 0, 4 or 8
//! m/s faster, 20, 40 or 60 m behind (bumper to bumper). Simulated for 6 s with the mean action
//! (as `rtr eval`), on the CPU (Flex). Printed per policy and case: the follower's mean
//! acceleration over the first 2 s, the smallest bumper gap (negative: the boxes overlapped
//! along the lane), whether the two boxes ever overlapped (a contact) and the lateral offset
//! from its lane centre at 6 s. A follower that brakes
//! for what is ahead shows negative accelerations growing with the closing speed and the
//! leader's braking, and keeps the gap positive. `--idm` adds the IDM reference driver;
//! `--kicks` adds a second table: the follower's first action offset by one exploration sigma
//! per control, and the change of its training return ([`print_kicks`]); `--approached` a third:
//! the policy car's acceleration when a faster car closes on it from behind
//! ([`print_approached`]).
//!
//! This is the long-tail collision of `experiments/recipe/car_following/results.md` in
//! isolation: there the cars that ran into a slower car ahead started about 7 m/s faster and
//! held their speed.

use std::path::Path;
use std::sync::Arc;

use rtr::data::{AgentState, VehicleClass};
use rtr::eval::evaluate::simulate_set;
use rtr::eval::{EvalConfig, EvalPolicy, EvalScenes, EvalSet, IdmBaseline, TrainedPolicy};
use rtr::geometry::{BoxMotion, OrientedBox};
use rtr::map::{LaneGraph, Map};
use rtr::scene::{AgentRole, Scene, SceneAgent, SceneBatch};
use rtr::sim::{Controls, Dynamics, Observation, Policy};

const DT: f64 = 0.5;
const HISTORY_STEPS: usize = 4;
const FUTURE_STEPS: usize = 12;
const LENGTH_M: f64 = 4.6;
const WIDTH_M: f64 = 1.9;
const LANE_WIDTH_M: f64 = 3.75;
const LEADER_SPEED: f64 = 28.0;
const CLOSING_SPEEDS: [f64; 3] = [0.0, 4.0, 8.0];
const GAPS_M: [f64; 3] = [20.0, 40.0, 60.0];
/// The braking leader's deceleration and the speed it stops braking at.
const LEADER_BRAKING: f64 = 4.0;
const LEADER_BRAKED_SPEED: f64 = 16.0;
/// Where the follower starts along the road (m): room behind for its history.
const FOLLOWER_START_M: f64 = 100.0;
/// Steps over which the early acceleration is measured (2 s).
const EARLY_STEPS: usize = 4;
/// `--kicks`: one exploration sigma per control, (m/s^2, rad): the recipe's sigma from the
/// logs (`init: sigma from the logs`: 0.838 m/s^2, 0.00363 rad for the RTR recipe run), and
/// PPO's discount.
const KICK_SIGMA: [f64; 2] = [0.84, 0.0036];
const KICK_GAMMA: f64 = 0.99;

/// One probe case.
#[derive(Debug, Clone, Copy)]
struct Case {
    closing: f64,
    gap: f64,
    leader_brakes: bool,
}

// Errors print as their message (Display) with exit status 2, as in the other probes; returning
// them from `main` would print their Debug form.
fn main() -> std::process::ExitCode {
    match run().and_then(|()| Ok(rtr::io::console::check_stdout()?)) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            rtr::errln!("car_following: {e}");
            std::process::ExitCode::from(2)
        }
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    rtr::allocator::tune_for_tensors();
    let args: Vec<String> = std::env::args().skip(1).collect();
    let options = ["--idm", "--kicks", "--approached"];
    if let Some(flag) = args
        .iter()
        .find(|a| a.starts_with("--") && !options.contains(&a.as_str()))
    {
        return Err(format!(
            "unknown option {flag}: the options are --idm, --kicks and --approached"
        )
        .into());
    }
    let with_idm = args.iter().any(|a| a == "--idm");
    let with_kicks = args.iter().any(|a| a == "--kicks");
    let with_approached = args.iter().any(|a| a == "--approached");
    let checkpoints: Vec<&String> = args
        .iter()
        .filter(|a| !options.contains(&a.as_str()))
        .collect();
    if checkpoints.is_empty() && !with_idm {
        return Err(
            "usage: cargo run --release --example car_following -- [--idm] [--kicks] [--approached] \
             CHECKPOINT..."
                .into(),
        );
    }
    let device = rtr::backend::Backend::Flex.device(false)?;
    let map = Arc::new(Map::from_opendrive(
        &rtr::map::straight(3, LANE_WIDTH_M, 900.0)?,
        "straight 3 x 3.75 m",
    )?);
    let graph = Arc::new(LaneGraph::build(&map, 10.0));
    let lane_y = middle_lane_centre(&map)?;
    let cases: Vec<Case> = [false, true]
        .into_iter()
        .flat_map(|leader_brakes| {
            CLOSING_SPEEDS.into_iter().flat_map(move |closing| {
                GAPS_M.into_iter().map(move |gap| Case {
                    closing,
                    gap,
                    leader_brakes,
                })
            })
        })
        .collect();
    let set = probe_set(
        cases
            .iter()
            .enumerate()
            .map(|(k, case)| scene(k, case, &map, &graph, lane_y))
            .collect(),
    );
    let config = EvalConfig {
        resamples: 10,
        realism_samples: 0,
        ..Default::default()
    };

    let mut drivers: Vec<(String, Box<dyn EvalPolicy>, Dynamics)> = Vec::new();
    for path in checkpoints {
        let policy = TrainedPolicy::load(Path::new(path), &device)?;
        drivers.push((path.clone(), Box::new(policy.network), policy.dynamics));
    }
    if with_idm {
        let idm = IdmBaseline {
            params: Default::default(),
            limits: Default::default(),
        };
        drivers.push(("IDM".into(), Box::new(idm), Dynamics::bicycle(DT)));
    }

    rtr::outln!(
        "| policy | leader | closing speed (m/s) | gap (m) | follower accel, first 2 s (m/s^2) | smallest gap (m) | lateral offset at 6 s (m) | contact |"
    )?;
    rtr::outln!("|---|---|---|---|---|---|---|---|")?;
    let mut summaries = Vec::new();
    for (name, policy, dynamics) in &drivers {
        let simulated = simulate_set(policy.as_ref(), dynamics, &set, &device, &config, None)?;
        let measured: Vec<Following> = simulated.iter().map(|s| measure(s, lane_y)).collect();
        summaries.push((name.clone(), summary(&cases, &measured)));
        for (case, m) in cases.iter().zip(&measured) {
            rtr::outln!(
                "| {name} | {} | {:.0} | {:.0} | {:+.2} | {:.1} | {:.2} | {} |",
                if case.leader_brakes {
                    "brakes 4 m/s^2"
                } else {
                    "steady"
                },
                case.closing,
                case.gap,
                m.early_accel,
                m.smallest_gap,
                m.lateral_offset,
                if m.contact { "yes" } else { "no" }
            )?;
        }
    }
    rtr::outln!()?;
    rtr::outln!(
        "| policy | accel, steady leader, closing 0 / 4 / 8 m/s (m/s^2) | accel, braking leader, closing 0 / 4 / 8 m/s (m/s^2) | cases with a contact |"
    )?;
    rtr::outln!("|---|---|---|---|")?;
    for (name, s) in summaries {
        let show = |a: &[f64; 3]| format!("{:+.2} / {:+.2} / {:+.2}", a[0], a[1], a[2]);
        rtr::outln!(
            "| {name} | {} | {} | {} of {} |",
            show(&s.steady),
            show(&s.braking),
            s.contacts,
            cases.len()
        )?;
    }
    if with_kicks {
        rtr::outln!()?;
        print_kicks(&drivers, &set, &cases, lane_y, &device, &config)?;
    }
    if with_approached {
        rtr::outln!()?;
        let road = (&map, &graph, lane_y);
        print_approached(&drivers, road, &device, &config)?;
    }
    Ok(())
}

/// The policy car approached from behind: a replayed car in its lane, 20, 40 or 60 m behind,
/// closing at 0, 4 or 8 m/s. A car-following driver does not react (IDM looks ahead only); a
/// policy that brakes here reads a closing car behind as one ahead, and in closed loop its
/// own followers run into it.
fn print_approached(
    drivers: &[(String, Box<dyn EvalPolicy>, Dynamics)],
    (map, graph, lane_y): (&Arc<Map>, &Arc<LaneGraph>, f64),
    device: &burn::prelude::Device,
    config: &EvalConfig,
) -> Result<(), Box<dyn std::error::Error>> {
    let cases: Vec<(f64, f64)> = CLOSING_SPEEDS
        .into_iter()
        .flat_map(|closing| GAPS_M.into_iter().map(move |gap| (closing, gap)))
        .collect();
    let set = probe_set(
        cases
            .iter()
            .enumerate()
            .map(|(k, &(closing, gap))| approached_scene(k, closing, gap, map, graph, lane_y))
            .collect(),
    );
    rtr::outln!(
        "| policy | accel when approached from behind, closing 0 / 4 / 8 m/s, first 2 s (m/s^2) |"
    )?;
    rtr::outln!("|---|---|")?;
    for (name, policy, dynamics) in drivers {
        let simulated = simulate_set(policy.as_ref(), dynamics, &set, device, config, None)?;
        let accel: Vec<f64> = simulated
            .iter()
            .map(|s| measure(s, lane_y).early_accel)
            .collect();
        let mean = |closing: f64| {
            let picked: Vec<f64> = cases
                .iter()
                .zip(&accel)
                .filter(|((c, _), _)| *c == closing)
                .map(|(_, a)| *a)
                .collect();
            picked.iter().sum::<f64>() / picked.len().max(1) as f64
        };
        let [a0, a4, a8] = CLOSING_SPEEDS.map(mean);
        rtr::outln!("| {name} | {a0:+.2} / {a4:+.2} / {a8:+.2} |")?;
    }
    Ok(())
}

/// One step of exploration noise: what PPO's per-step credit assignment can see.
///
/// PPO learns from the return that follows each sampled action. Here the follower's first
/// simulated action gets one exploration sigma added (the recipe's sigma from the logs) in
/// one control, and the policy's mean drives every later step. The change of the follower's
/// training return (-gamma^t at its first collision or off-road step, as the sparse reward
/// with early termination) against the unkicked rollout is the finite difference PPO's
/// gradient estimates for that control in that state.
fn print_kicks(
    drivers: &[(String, Box<dyn EvalPolicy>, Dynamics)],
    set: &EvalScenes,
    cases: &[Case],
    lane_y: f64,
    device: &burn::prelude::Device,
    config: &EvalConfig,
) -> Result<(), Box<dyn std::error::Error>> {
    let kicks = [
        ("none", 0.0, 0.0),
        ("brake 1 sigma", -KICK_SIGMA[0], 0.0),
        ("accelerate 1 sigma", KICK_SIGMA[0], 0.0),
        ("steer left 1 sigma", 0.0, KICK_SIGMA[1]),
        ("steer right 1 sigma", 0.0, -KICK_SIGMA[1]),
    ];
    rtr::outln!(
        "| policy | first action kicked | contacts | off-road | lateral offset at 6 s (m) | return change vs none, mean over cases (x 1000) | cases whose outcome changed |"
    )?;
    rtr::outln!("|---|---|---|---|---|---|---|")?;
    for (name, policy, dynamics) in drivers {
        let mut baseline: Option<Vec<Outcome>> = None;
        for (label, accel, steer) in kicks {
            let kicked = Kicked {
                inner: policy.as_ref(),
                accel,
                steer,
            };
            let simulated = simulate_set(&kicked, dynamics, set, device, config, None)?;
            let outcomes: Vec<Outcome> = simulated.iter().map(|s| outcome(s, lane_y)).collect();
            let base = baseline.get_or_insert_with(|| outcomes.clone());
            let change = outcomes
                .iter()
                .zip(base.iter())
                .map(|(o, b)| o.training_return() - b.training_return())
                .sum::<f64>()
                / cases.len() as f64;
            let changed = outcomes
                .iter()
                .zip(base.iter())
                .filter(|(o, b)| o.first_infraction_step != b.first_infraction_step)
                .count();
            let offset =
                outcomes.iter().map(|o| o.lateral_offset).sum::<f64>() / cases.len() as f64;
            rtr::outln!(
                "| {name} | {label} | {} | {} | {offset:+.2} | {:+.1} | {changed} of {} |",
                outcomes.iter().filter(|o| o.contact).count(),
                outcomes.iter().filter(|o| o.offroad).count(),
                1000.0 * change,
                cases.len()
            )?;
        }
    }
    Ok(())
}

/// A policy whose actions at the first simulated step are offset by (`accel`, `steer`).
struct Kicked<'p> {
    inner: &'p dyn EvalPolicy,
    accel: f64,
    steer: f64,
}

impl EvalPolicy for Kicked<'_> {
    fn policy<'a>(
        &'a self,
        scenes: &[&Scene],
        batch: &SceneBatch,
        noise: Option<u64>,
    ) -> Box<dyn Policy + 'a> {
        let mut inner = self.inner.policy(scenes, batch, noise);
        let (accel, steer) = (self.accel, self.steer);
        Box::new(move |obs: &Observation| {
            let controls = inner.act(obs);
            if obs.step == 0 {
                Controls {
                    accel: controls.accel.add_scalar(accel),
                    steer: controls.steer.add_scalar(steer),
                }
            } else {
                controls
            }
        })
    }
}

/// The follower's first infraction under the training reward.
#[derive(Debug, Clone)]
struct Outcome {
    contact: bool,
    offroad: bool,
    /// Simulated step (1 = after the first action) of the first contact or off-road step.
    first_infraction_step: Option<usize>,
    lateral_offset: f64,
}

impl Outcome {
    /// The follower's discounted return: -1 at its first infraction, nothing after (it is
    /// terminated), discounted as the recipe's PPO (gamma 0.99).
    fn training_return(&self) -> f64 {
        self.first_infraction_step
            .map_or(0.0, |t| -KICK_GAMMA.powi(t as i32 - 1))
    }
}

fn outcome(scene: &Scene, lane_y: f64) -> Outcome {
    let (follower, leader) = (&scene.agents[0].states, &scene.agents[1].states);
    let now = HISTORY_STEPS;
    let footprint = |a: &AgentState| OrientedBox::new([a.x, a.y], a.heading, LENGTH_M, WIDTH_M);
    // On the straight road along +x, a box is off the road when its lateral extent passes the
    // outer lane edges (1.5 lanes either side of the middle lane's centre).
    let off_road = |a: &AgentState| {
        let half_extent =
            0.5 * (WIDTH_M * a.heading.cos().abs() + LENGTH_M * a.heading.sin().abs());
        (a.y - lane_y).abs() + half_extent > 1.5 * LANE_WIDTH_M
    };
    // As the simulator counts it: the boxes touch at any time of the step into t.
    let motion = |states: &[AgentState], t: usize| BoxMotion {
        from: footprint(&states[t - 1]),
        to: footprint(&states[t]),
    };
    let contact_at = (now + 1..follower.len()).find(|&t| {
        motion(follower, t)
            .first_contact(&motion(leader, t))
            .is_some()
    });
    let offroad_at = (now + 1..follower.len()).find(|&t| off_road(&follower[t]));
    let first = match (contact_at, offroad_at) {
        (Some(c), Some(o)) => Some(c.min(o)),
        (c, o) => c.or(o),
    };
    Outcome {
        contact: contact_at.is_some(),
        offroad: offroad_at.is_some(),
        first_infraction_step: first.map(|t| t - now),
        lateral_offset: follower[follower.len() - 1].y - lane_y,
    }
}

/// Per policy: the early acceleration per closing speed (mean over the gaps), for each leader,
/// and in how many cases the follower touched the leader.
struct Summary {
    steady: [f64; 3],
    braking: [f64; 3],
    contacts: usize,
}

fn summary(cases: &[Case], measured: &[Following]) -> Summary {
    let mean = |brakes: bool, closing: f64| {
        let picked: Vec<f64> = cases
            .iter()
            .zip(measured)
            .filter(|(c, _)| c.leader_brakes == brakes && c.closing == closing)
            .map(|(_, m)| m.early_accel)
            .collect();
        picked.iter().sum::<f64>() / picked.len().max(1) as f64
    };
    Summary {
        steady: CLOSING_SPEEDS.map(|c| mean(false, c)),
        braking: CLOSING_SPEEDS.map(|c| mean(true, c)),
        contacts: measured.iter().filter(|m| m.contact).count(),
    }
}

/// The y of the middle lane's centre (the generated straight road runs along +x).
fn middle_lane_centre(map: &Map) -> Result<f64, Box<dyn std::error::Error>> {
    let mut centres: Vec<f64> = map
        .lanes()
        .iter()
        .filter(|l| l.is_graph_lane() && l.is_drivable())
        .map(|l| l.centerline.iter().map(|p| p[1]).sum::<f64>() / l.centerline.len() as f64)
        .collect();
    centres.sort_by(f64::total_cmp);
    centres
        .get(centres.len() / 2)
        .copied()
        .ok_or_else(|| "the straight road has no drivable lane".into())
}

/// Constant-speed history, then the leader's script (steady or braking) for the future.
fn leader_states(case: &Case, start_x: f64, y: f64) -> Vec<AgentState> {
    let mut states = Vec::with_capacity(HISTORY_STEPS + FUTURE_STEPS + 1);
    let mut x = start_x - LEADER_SPEED * DT * HISTORY_STEPS as f64;
    let mut speed = LEADER_SPEED;
    for k in 0..=HISTORY_STEPS + FUTURE_STEPS {
        let braking = case.leader_brakes && k >= HISTORY_STEPS && speed > LEADER_BRAKED_SPEED;
        let accel = if braking { -LEADER_BRAKING } else { 0.0 };
        states.push(AgentState {
            x,
            y,
            heading: 0.0,
            speed,
            accel,
        });
        let next = (speed + accel * DT).max(LEADER_BRAKED_SPEED.min(speed));
        x += 0.5 * (speed + next) * DT;
        speed = next;
    }
    states
}

/// Probe scenes as an evaluation set (no long-tail scenarios: no scripted heroes).
fn probe_set(scenes: Vec<Scene>) -> EvalScenes {
    EvalScenes {
        set: EvalSet::Nominal,
        scenes,
        scenarios: Vec::new(),
    }
}

/// Constant speed along the middle lane, passing `x_now` at the scene's current step.
fn steady_states(x_now: f64, speed: f64, y: f64) -> Vec<AgentState> {
    (0..=HISTORY_STEPS + FUTURE_STEPS)
        .map(|i| AgentState {
            x: x_now + speed * DT * (i as f64 - HISTORY_STEPS as f64),
            y,
            heading: 0.0,
            speed,
            accel: 0.0,
        })
        .collect()
}

fn scene(k: usize, case: &Case, map: &Arc<Map>, graph: &Arc<LaneGraph>, y: f64) -> Scene {
    let follower = steady_states(FOLLOWER_START_M, LEADER_SPEED + case.closing, y);
    let leader = leader_states(case, FOLLOWER_START_M + case.gap + LENGTH_M, y);
    two_car_scene(format!("following-{k}"), follower, leader, map, graph)
}

/// The policy car (agent 0) at the leader's speed, with a replayed car `gap` m behind it
/// closing at `closing` m/s.
fn approached_scene(
    k: usize,
    closing: f64,
    gap: f64,
    map: &Arc<Map>,
    graph: &Arc<LaneGraph>,
    y: f64,
) -> Scene {
    let policy_car = steady_states(FOLLOWER_START_M, LEADER_SPEED, y);
    let behind = steady_states(FOLLOWER_START_M - gap - LENGTH_M, LEADER_SPEED + closing, y);
    two_car_scene(format!("approached-{k}"), policy_car, behind, map, graph)
}

/// Agent 0 driven by the policy, agent 1 replayed.
fn two_car_scene(
    id: String,
    controlled: Vec<AgentState>,
    replayed: Vec<AgentState>,
    map: &Arc<Map>,
    graph: &Arc<LaneGraph>,
) -> Scene {
    let agent = |id: usize, role: AgentRole, states: Vec<AgentState>| SceneAgent {
        track_id: id,
        class: VehicleClass::Car,
        length: LENGTH_M,
        width: WIDTH_M,
        role,
        valid: vec![true; states.len()],
        states,
    };
    Scene {
        id,
        t0: 0.0,
        dt: DT,
        history_steps: HISTORY_STEPS,
        future_steps: FUTURE_STEPS,
        map: map.clone(),
        lane_graph: graph.clone(),
        agents: vec![
            agent(0, AgentRole::Controlled, controlled),
            agent(1, AgentRole::Replayed, replayed),
        ],
    }
}

struct Following {
    early_accel: f64,
    smallest_gap: f64,
    /// The two boxes overlapped at some simulated step (a rear-end or a side contact; a car
    /// that passes in the next lane has a negative gap but no contact).
    contact: bool,
    lateral_offset: f64,
}

/// The follower (agent 0) against the leader (agent 1) over the simulated steps.
fn measure(scene: &Scene, lane_y: f64) -> Following {
    let (follower, leader) = (&scene.agents[0].states, &scene.agents[1].states);
    let now = HISTORY_STEPS;
    let early =
        (follower[now + EARLY_STEPS].speed - follower[now].speed) / (EARLY_STEPS as f64 * DT);
    let smallest_gap = (now..follower.len())
        .map(|t| leader[t].x - follower[t].x - LENGTH_M)
        .fold(f64::INFINITY, f64::min);
    let outcome = outcome(scene, lane_y);
    Following {
        early_accel: early,
        smallest_gap,
        contact: outcome.contact,
        lateral_offset: outcome.lateral_offset,
    }
}
