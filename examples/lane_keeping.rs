//! `cargo run --release --example lane_keeping -- CHECKPOINT...`: how well trained policies keep
//! their lane, away from the traffic they learned it in.
//!
//! 1. *A lone car*: one car on the lane centre with a 2 s history along it at 20, 25, 30, 35 and
//!    40 m/s, on each of the A9's six main lanes, on each lane of a generated straight
//!    3 x 3.75 m road, and on generated 3 x 3.75 m roads curving at the A9's curvature
//!    (0.0003 1/m, a 3.3 km radius; its two carriageways curve one each way), at 0.001 and at
//!    0.002 1/m (the generated long-tail roads curve at up to 0.0028), to the left (+) and to
//!    the right (-), started on the arc; simulated for 6 s. Reported:
//!    how far it is from the nearest lane centre (mean over the 6 s), and the share of cars in
//!    another lane (or off the road) at 6 s. A driver keeping its lane stays near 0 m and 0 %.
//! 2. *Alone vs in traffic*: every controlled agent of the A9 test scenes, simulated in its
//!    logged traffic and with every other vehicle removed (same history, same map). Reported:
//!    the mean distance to its logged position at 2, 4 and 6 s, each car compared only while
//!    its log lasts.
//!
//! Policies are run with their mean action (as `rtr eval` does), on the CPU (Flex).

use std::path::Path;
use std::sync::Arc;

use rtr::data::{AgentState, VehicleClass};
use rtr::eval::evaluate::simulate_set;
use rtr::eval::{EvalConfig, EvalScenes, EvalSet, TrainedPolicy};
use rtr::map::{LaneGraph, Map};
use rtr::scene::{AgentRole, Scene, SceneAgent};

const SPEEDS: [f64; 5] = [20.0, 25.0, 30.0, 35.0, 40.0];
const HISTORY_STEPS: usize = 4;
const FUTURE_STEPS: usize = 12;
/// Curvatures (1/m) of the generated curved roads: the A9's and two sharper ones, each way.
const CURVATURES: [f64; 6] = [0.0003, -0.0003, 0.001, -0.001, 0.002, -0.002];
/// The curved roads' length and where the lone cars start on them: a generated curve is a
/// line for its first 20 %, a clothoid for 15 % and the arc for 30 % (420-780 m here), so the
/// cars start 10 m into the arc and stay on it for the 6 s at up to 40 m/s (240 m); their 2 s
/// history lies on the clothoid into it.
const CURVE_LENGTH_M: f64 = 1200.0;
const CURVE_START_M: f64 = 430.0;
/// Lanes of a map's main road shorter than this are ramps or gores: skipped.
const MIN_LANE_LENGTH_M: f64 = 60.0;
/// Successor hops searched when deciding whether a car is still in its start lane.
const SUCCESSOR_HOPS: usize = 8;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    rtr::allocator::tune_for_tensors();
    let checkpoints: Vec<String> = std::env::args().skip(1).collect();
    if checkpoints.is_empty() {
        return Err("usage: cargo run --release --example lane_keeping -- CHECKPOINT...".into());
    }
    let device = rtr::backend::Backend::Flex.device(false)?;
    let dataset = rtr::data::a9::A9Dataset::load(&rtr::data::a9::default_dir())?;
    let straight = Arc::new(Map::from_opendrive(
        &rtr::map::straight(3, 3.75, 900.0)?,
        "straight 3 x 3.75 m",
    )?);
    let straight_graph = Arc::new(LaneGraph::build(&straight, 10.0));
    let mut lone_sets = vec![
        (
            "A9".to_string(),
            lone_cars(&dataset.map, &dataset.lane_graph, Some(0), None),
        ),
        (
            "straight".to_string(),
            lone_cars(&straight, &straight_graph, None, None),
        ),
    ];
    for curvature in CURVATURES {
        let curve = Arc::new(Map::from_opendrive(
            &rtr::map::curve(3, 3.75, CURVE_LENGTH_M, curvature)?,
            "curve",
        )?);
        let graph = Arc::new(LaneGraph::build(&curve, 10.0));
        lone_sets.push((
            format!("curve {curvature:+} 1/m"),
            lone_cars(&curve, &graph, None, Some(CURVE_START_M)),
        ));
    }
    let test = EvalScenes::nominal(&dataset)?;
    let alone = without_traffic(&test);
    let config = EvalConfig {
        resamples: 10,
        realism_samples: 0,
        ..Default::default()
    };

    rtr::outln!(
        "| policy | map | lone cars | mean distance to a lane centre (m) | in another lane or off road at 6 s |"
    )?;
    rtr::outln!("|---|---|---|---|---|")?;
    let mut traffic_rows = Vec::new();
    for path in &checkpoints {
        let policy = TrainedPolicy::load(Path::new(path), &device)?;
        let run = |set: &EvalScenes| {
            simulate_set(
                &policy.network,
                &policy.dynamics,
                set,
                &device,
                &config,
                None,
            )
        };
        for (name, set) in &lone_sets {
            let (centre, left) = lone_car_drift(&run(set)?);
            rtr::outln!(
                "| {path} | {name} | {} | {centre:.2} | {:.0} % |",
                set.scenes.len(),
                100.0 * left
            )?;
        }
        let in_traffic = run(&test)?;
        let on_its_own = run(&alone.scenes)?;
        traffic_rows.push((
            path.clone(),
            tracking_errors(&test, &in_traffic, &alone, &on_its_own),
        ));
    }
    rtr::outln!()?;
    rtr::outln!("| policy | agents | error to log at 2 / 4 / 6 s in traffic (m) | alone (m) |")?;
    rtr::outln!("|---|---|---|---|")?;
    for (path, errors) in traffic_rows {
        let show = |e: &[f64]| {
            e.iter()
                .map(|x| format!("{x:.2}"))
                .collect::<Vec<_>>()
                .join(" / ")
        };
        rtr::outln!(
            "| {path} | {} | {} | {} |",
            errors.agents,
            show(&errors.in_traffic),
            show(&errors.alone)
        )?;
    }
    Ok(rtr::io::console::check_stdout()?)
}

/// One scene per (lane, speed): a lone car on the lane centre with a constant-speed history
/// along it. `road`: only that road's lanes (the A9 main road), else every lane. `start`: the
/// car's station at the current step (default 10 m, or half a short lane).
fn lone_cars(
    map: &Arc<Map>,
    graph: &Arc<LaneGraph>,
    road: Option<usize>,
    start: Option<f64>,
) -> EvalScenes {
    let mut scenes = Vec::new();
    for (index, lane) in map.lanes().iter().enumerate() {
        let usable = lane.is_graph_lane()
            && lane.is_drivable()
            && lane.length() >= MIN_LANE_LENGTH_M
            && road.is_none_or(|r| lane.road == r);
        if !usable {
            continue;
        }
        for speed in SPEEDS {
            let start = start.unwrap_or(10.0_f64.min(lane.length() / 2.0));
            let states = (0..=HISTORY_STEPS + FUTURE_STEPS)
                .map(|k| {
                    let s = start + speed * (k as f64 - HISTORY_STEPS as f64) * 0.5;
                    let (p, heading) = point_along(&lane.centerline, &lane.s, s);
                    AgentState {
                        x: p[0],
                        y: p[1],
                        heading,
                        speed,
                        accel: 0.0,
                    }
                })
                .collect::<Vec<_>>();
            let steps = states.len();
            scenes.push(Scene {
                id: format!("lane{index}-{speed}"),
                t0: 0.0,
                dt: 0.5,
                history_steps: HISTORY_STEPS,
                future_steps: FUTURE_STEPS,
                map: map.clone(),
                lane_graph: graph.clone(),
                agents: vec![SceneAgent {
                    track_id: 0,
                    class: VehicleClass::Car,
                    length: 4.6,
                    width: 1.9,
                    role: AgentRole::Controlled,
                    states,
                    valid: vec![true; steps],
                }],
            });
        }
    }
    EvalScenes {
        set: EvalSet::Nominal,
        scenes,
        scenarios: Vec::new(),
    }
}

/// Point and heading at arc length `s` of a polyline, extended straight beyond its ends.
fn point_along(points: &[[f64; 2]], arc: &[f64], s: f64) -> ([f64; 2], f64) {
    let k = arc.partition_point(|&c| c <= s).clamp(1, arc.len() - 1);
    let (a, b) = (points[k - 1], points[k]);
    let heading = (b[1] - a[1]).atan2(b[0] - a[0]);
    let t = (s - arc[k - 1]) / (arc[k] - arc[k - 1]).max(1e-9);
    let t = if k == 1 { t.min(1.0) } else { t.max(0.0) };
    (
        [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])],
        heading,
    )
}

/// (mean distance to the nearest lane centre over the simulated steps, share of cars in a lane
/// not reached from their start lane by successors, or off every lane, at the last step).
fn lone_car_drift(simulated: &[Scene]) -> (f64, f64) {
    let (mut distance, mut samples, mut left) = (0.0, 0usize, 0usize);
    for scene in simulated {
        let car = &scene.agents[0];
        let lane_at = |k: usize| {
            let s = car.states[k];
            scene.map.lane_projection([s.x, s.y], s.heading)
        };
        let start = lane_at(HISTORY_STEPS).map(|p| p.lane);
        for k in HISTORY_STEPS + 1..car.states.len() {
            if let Some(p) = lane_at(k) {
                distance += p.distance;
                samples += 1;
            }
        }
        let end = lane_at(car.states.len() - 1).map(|p| p.lane);
        let kept = match (start, end) {
            (Some(a), Some(b)) => reachable(&scene.map, a, b),
            _ => false,
        };
        left += usize::from(!kept);
    }
    (
        distance / samples.max(1) as f64,
        left as f64 / simulated.len().max(1) as f64,
    )
}

/// Whether lane `to` is `from` or follows it within [`SUCCESSOR_HOPS`] successor links.
fn reachable(map: &Map, from: usize, to: usize) -> bool {
    let mut frontier = vec![from];
    for _ in 0..=SUCCESSOR_HOPS {
        if frontier.contains(&to) {
            return true;
        }
        frontier = frontier
            .iter()
            .flat_map(|&l| map.lanes()[l].successors.iter().copied())
            .collect();
    }
    false
}

/// The test scenes with every vehicle but one controlled agent removed, one scene per agent.
struct Alone {
    scenes: EvalScenes,
    /// (test scene, agent) behind each scene.
    origin: Vec<(usize, usize)>,
}

fn without_traffic(test: &EvalScenes) -> Alone {
    let mut scenes = Vec::new();
    let mut origin = Vec::new();
    for (k, scene) in test.scenes.iter().enumerate() {
        for (i, agent) in scene.agents.iter().enumerate() {
            if agent.role == AgentRole::Controlled {
                let mut one = scene.clone();
                one.agents = vec![agent.clone()];
                one.id = format!("{}-agent{i}", scene.id);
                scenes.push(one);
                origin.push((k, i));
            }
        }
    }
    Alone {
        scenes: EvalScenes {
            set: EvalSet::Nominal,
            scenes,
            scenarios: Vec::new(),
        },
        origin,
    }
}

struct TrackingErrors {
    agents: usize,
    in_traffic: Vec<f64>,
    alone: Vec<f64>,
}

const CHECK_STEPS: [usize; 3] = [4, 8, 12];

/// Mean distance to the log at [`CHECK_STEPS`] after the current step, over the agents whose
/// log and both simulations last that long.
fn tracking_errors(
    test: &EvalScenes,
    in_traffic: &[Scene],
    alone: &Alone,
    on_its_own: &[Scene],
) -> TrackingErrors {
    let mut sums = [[0.0; 2]; CHECK_STEPS.len()];
    let mut counts = [0usize; CHECK_STEPS.len()];
    for (j, &(k, i)) in alone.origin.iter().enumerate() {
        let now = test.scenes[k].current_step();
        let log = &test.scenes[k].agents[i];
        let traffic = &in_traffic[k].agents[i];
        let solo = &on_its_own[j].agents[0];
        for (c, &dt) in CHECK_STEPS.iter().enumerate() {
            let t = now + dt;
            if t >= log.valid.len() || !(log.valid[t] && traffic.valid[t] && solo.valid[t]) {
                continue;
            }
            let error = |a: &AgentState| (a.x - log.states[t].x).hypot(a.y - log.states[t].y);
            sums[c][0] += error(&traffic.states[t]);
            sums[c][1] += error(&solo.states[t]);
            counts[c] += 1;
        }
    }
    let mean = |c: usize, w: usize| sums[c][w] / counts[c].max(1) as f64;
    TrackingErrors {
        agents: alone.origin.len(),
        in_traffic: (0..CHECK_STEPS.len()).map(|c| mean(c, 0)).collect(),
        alone: (0..CHECK_STEPS.len()).map(|c| mean(c, 1)).collect(),
    }
}
