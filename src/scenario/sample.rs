//! Concrete sampling: draw every range of a logical scenario with a seeded generator, place
//! the target, the heroes and the A9-statistics background traffic, and validate the result:
//! the initial state must be on the road and collision-free, and in a reference run (heroes
//! scripted, everyone else driven by the IDM + lane-keeping driver) every hero phase must fire
//! and complete with the hero on the road. A draw that fails is redrawn from the next seed of
//! its own stream, so the outcome depends on the seed only.

use burn::prelude::*;

use super::behaviour::Phase;
use super::concrete::{
    ConcreteScenario, ReferenceRun, ScenarioAgent, ScenarioHero, ScenarioSet, hero_scripts,
};
use super::family::{HeroSpec, HeroVehicle, LogicalScenario};
use super::hero::HeroScripts;
use super::placement::{LaneRef, main_lanes_at, main_road_length, place};
use super::range::{Range, Sampler, quantize};
use crate::data::{AgentState, LaneTraffic, TrafficStatistics, VehicleClass, VehicleSample};
use crate::driver::{IdmDriver, IdmParams, host_f64};
use crate::error::{Error, Result};
use crate::geometry::OrientedBox;
use crate::map::{BoxOnRoad, Map, ProceduralMap};
use crate::scene::{AgentRole, Scene, SceneBatch};
use crate::sim::{ActionLimits, Dynamics, MapCaches, Rollout, RolloutConfig, Scripted, rollout};

/// Draws tried per concrete scenario before the family is reported as unable to produce one.
pub const MAX_ATTEMPTS: u64 = 40;
/// A background vehicle keeps at least this much time gap (s) to the scenario's own vehicles.
const MIN_BACKGROUND_HEADWAY_S: f64 = 0.6;

/// What sampling needs besides the family.
pub struct SamplingContext<'a> {
    pub stats: &'a TrafficStatistics,
    pub dt: f64,
    pub history_steps: usize,
}

/// A vehicle being placed.
#[derive(Debug, Clone)]
struct Planned {
    role: AgentRole,
    lane: LaneRef,
    station: f64,
    speed: f64,
    vehicle: VehicleSample,
    /// Part of the scenario's design (target, heroes), never adjusted.
    fixed: bool,
}

/// Samples a valid concrete scenario of `family` from `seed`.
pub fn sample_scenario(
    family: &LogicalScenario,
    ctx: &SamplingContext,
    seed: u64,
    set: ScenarioSet,
    index: usize,
) -> Result<ConcreteScenario> {
    let mut last_problem = String::new();
    for attempt in 0..MAX_ATTEMPTS {
        // Each attempt has its own stream, derived from the seed alone.
        let mut sampler = Sampler::new(seed ^ attempt.wrapping_mul(0x9E37_79B9_7F4A_7C15));
        let drawn = draw(family, ctx, &mut sampler, seed, set, index);
        let mut scenario = match drawn {
            Ok(s) => s,
            Err(problem) => {
                last_problem = problem;
                continue;
            }
        };
        match reference_run(&scenario) {
            Ok(mut run) => {
                run.attempts = attempt as usize + 1;
                scenario.reference = run;
                return Ok(scenario);
            }
            Err(problem) => last_problem = problem,
        }
    }
    Err(Error::invalid(
        format!("scenario family `{}`", family.name),
        "sampling",
        format!(
            "no valid concrete scenario in {MAX_ATTEMPTS} draws from seed {seed}; last problem: {last_problem}"
        ),
    ))
}

/// Draws the map from the template: preset values replaced by drawn ones.
fn draw_map(
    family: &LogicalScenario,
    sampler: &mut Sampler,
) -> std::result::Result<ProceduralMap, String> {
    map_with(family, |key, range| {
        sampler.draw(&format!("map.{key}"), range)
    })
}

/// The map template with each parameter's value given by `value_of(name, range)`.
pub(super) fn map_with(
    family: &LogicalScenario,
    mut value_of: impl FnMut(&str, &super::range::Range) -> f64,
) -> std::result::Result<ProceduralMap, String> {
    let preset = ProceduralMap::preset(&family.map.preset).map_err(|e| e.to_string())?;
    let mut value = serde_json::to_value(&preset).map_err(|e| e.to_string())?;
    let object = value.as_object_mut().ok_or("map preset is not an object")?;
    for (key, range) in &family.map.params {
        let v = value_of(key, range);
        if key == "median_width" {
            object.insert(
                "layout".into(),
                serde_json::json!({ "type": "divided", "median_width": v }),
            );
        } else if object.get(key).is_some_and(|x| x.is_u64()) {
            object.insert(key.clone(), serde_json::json!(v.round() as u64));
        } else {
            object.insert(key.clone(), serde_json::json!(v));
        }
    }
    serde_json::from_value(value).map_err(|e| format!("map parameters: {e}"))
}

/// Rank from the right (0 = rightmost) of a lane reference at `station`.
fn rank(map: &Map, lane: LaneRef, station: f64) -> usize {
    match lane {
        LaneRef::Main(k) => main_lanes_at(map, station).saturating_sub(k),
        _ => 0,
    }
}

fn draw(
    family: &LogicalScenario,
    ctx: &SamplingContext,
    sampler: &mut Sampler,
    seed: u64,
    set: ScenarioSet,
    index: usize,
) -> std::result::Result<ConcreteScenario, String> {
    let procedural = draw_map(family, sampler)?;
    let map = Map::from_opendrive(
        &procedural.build().map_err(|e| e.to_string())?,
        &family.name,
    )
    .map_err(|e| e.to_string())?;
    let stats = ctx.stats;

    let (target, target_error) = plan_target(family, &map, stats, sampler)?;

    // Heroes.
    let mut heroes = Vec::new();
    let mut scripts: Vec<Vec<Phase<f64>>> = Vec::new();
    for (h, spec) in family.heroes.iter().enumerate() {
        let name = format!("heroes[{h}]");
        heroes.push(plan_hero(spec, &name, &target, stats, sampler)?);
        scripts.push(
            spec.phases
                .iter()
                .enumerate()
                .map(|(p, phase)| phase.sample(sampler, &format!("{name}.phases[{p}]")))
                .collect(),
        );
    }

    // Background.
    let mut fixed: Vec<Planned> = vec![target.clone()];
    fixed.extend(heroes.iter().cloned());
    let background = plan_background(family, &map, stats, sampler, &fixed)?;

    // Order: controlled (target first), then heroes.
    let mut planned = vec![target];
    planned.extend(background);
    let first_hero = planned.len();
    planned.extend(heroes);

    let steps = ctx.history_steps;
    let agents = histories(&map, &planned, target_error, ctx)?;
    check_initial(&map, &agents)?;

    let future_steps = (family.duration_s / ctx.dt).round() as usize;
    Ok(ConcreteScenario {
        family: family.name.clone(),
        description: family.description.clone(),
        set,
        index,
        seed,
        parameters: sampler.drawn.clone(),
        map: procedural,
        dt: ctx.dt,
        history_steps: steps,
        future_steps,
        target: 0,
        agents,
        heroes: scripts
            .into_iter()
            .enumerate()
            .map(|(h, phases)| ScenarioHero {
                agent: first_hero + h,
                target: 0,
                phases,
            })
            .collect(),
        reference: ReferenceRun {
            attempts: 0,
            phases: Vec::new(),
            collided_agents: Vec::new(),
            offroad_agents: Vec::new(),
        },
        content_sha256: None,
    })
}

/// The target's plan (a car at a drawn station and speed quantile of its lane) and how far
/// its start is drawn from the lane's centre line.
fn plan_target(
    family: &LogicalScenario,
    map: &Map,
    stats: &TrafficStatistics,
    sampler: &mut Sampler,
) -> std::result::Result<(Planned, PoseError), String> {
    let lane_stats = |r: usize| stats.lane(r).ok_or("the traffic statistics are empty");
    let t = &family.target;
    let station = sampler.draw("target.station", &t.station);
    let q = sampler.draw("target.speed_quantile", &t.speed_band);
    let mut vehicle = lane_stats(rank(map, t.lane, station))?.vehicle_at(q);
    let speed = match &t.speed {
        Some(r) => sampler.draw("target.speed", r),
        None => vehicle.speed,
    };
    if vehicle.class != VehicleClass::Car {
        vehicle = pick_class(stats, VehicleClass::Car, sampler)?;
    }
    let target = Planned {
        role: AgentRole::Controlled,
        lane: t.lane,
        station,
        speed,
        vehicle,
        fixed: true,
    };
    // Drawn only when asked for, so the draws of every other family stay what they were.
    let target_error = PoseError {
        lateral: t
            .lateral_offset
            .as_ref()
            .map_or(0.0, |r| sampler.draw("target.lateral_offset", r)),
        heading: t
            .heading_error
            .as_ref()
            .map_or(0.0, |r| sampler.draw("target.heading_error", r)),
    };

    Ok((target, target_error))
}

/// Every planned agent's logged history: driving along its lane at its speed up to its
/// station (the target from its drawn pose error); refuses an agent with no lane at its start.
fn histories(
    map: &Map,
    planned: &[Planned],
    target_error: PoseError,
    ctx: &SamplingContext,
) -> std::result::Result<Vec<ScenarioAgent>, String> {
    let steps = ctx.history_steps;
    let mut agents = Vec::with_capacity(planned.len());
    for (i, p) in planned.iter().enumerate() {
        let states: Vec<Option<[f64; 4]>> = if i == 0 && target_error != PoseError::NONE {
            target_error.history(map, p, steps, ctx.dt)
        } else {
            (0..=steps)
                .map(|k| {
                    let back = p.speed * (steps - k) as f64 * ctx.dt;
                    place(map, p.lane, p.station - back)
                        .map(|pl| [pl.x, pl.y, pl.heading, p.speed].map(quantize))
                })
                .collect()
        };
        if states[steps].is_none() {
            return Err(format!(
                "agent {i} ({:?}) has no lane {} at station {:.1} m",
                p.role, p.lane, p.station
            ));
        }
        agents.push(ScenarioAgent {
            role: p.role,
            class: p.vehicle.class.clone(),
            length: quantize(p.vehicle.length),
            width: quantize(p.vehicle.width),
            states,
        });
    }
    Ok(agents)
}

/// How far the target starts from driving along its lane's centre line.
#[derive(Debug, Clone, Copy, PartialEq)]
struct PoseError {
    /// Metres to the left of the centre line.
    lateral: f64,
    /// Radians turned left of the lane's heading.
    heading: f64,
}

impl PoseError {
    const NONE: Self = Self {
        lateral: 0.0,
        heading: 0.0,
    };

    /// The vehicle's states when it drove straight, at its speed and with the heading error,
    /// into the offset pose at the current step (index `steps`).
    fn history(&self, map: &Map, p: &Planned, steps: usize, dt: f64) -> Vec<Option<[f64; 4]>> {
        let Some(now) = place(map, p.lane, p.station) else {
            return vec![None; steps + 1];
        };
        let heading = now.heading + self.heading;
        let (x, y) = (
            now.x - self.lateral * now.heading.sin(),
            now.y + self.lateral * now.heading.cos(),
        );
        (0..=steps)
            .map(|k| {
                let back = p.speed * (steps - k) as f64 * dt;
                Some(
                    [
                        x - back * heading.cos(),
                        y - back * heading.sin(),
                        heading,
                        p.speed,
                    ]
                    .map(quantize),
                )
            })
            .collect()
    }
}

/// A recorded vehicle of `class` (any lane), for its size.
fn pick_class(
    stats: &TrafficStatistics,
    class: VehicleClass,
    sampler: &mut Sampler,
) -> std::result::Result<VehicleSample, String> {
    let pool: Vec<&VehicleSample> = stats
        .lanes
        .iter()
        .flat_map(|l| l.vehicles.iter())
        .filter(|v| v.class == class)
        .collect();
    if pool.is_empty() {
        return Err(format!("the traffic statistics have no {class:?}"));
    }
    let k = ((sampler.unit() * pool.len() as f64) as usize).min(pool.len() - 1);
    Ok(pool[k].clone())
}

fn plan_hero(
    spec: &HeroSpec,
    name: &str,
    target: &Planned,
    stats: &TrafficStatistics,
    sampler: &mut Sampler,
) -> std::result::Result<Planned, String> {
    let lane = match (spec.lane, spec.lane_offset, target.lane) {
        (Some(lane), _, _) => lane,
        (None, Some(offset), LaneRef::Main(k)) => {
            let k = k as i64 + offset as i64;
            if k < 1 {
                return Err(format!(
                    "{name}: lane_offset {offset} leaves the road on the left"
                ));
            }
            LaneRef::Main(k as usize)
        }
        _ => {
            return Err(format!(
                "{name}: lane_offset needs the target on a main lane"
            ));
        }
    };
    let station =
        target.station + sampler.draw(&format!("{name}.station_offset"), &spec.station_offset);
    let speed = match (&spec.speed, &spec.speed_offset) {
        (Some(r), _) => sampler.draw(&format!("{name}.speed"), r),
        (None, Some(r)) => target.speed + sampler.draw(&format!("{name}.speed_offset"), r),
        (None, None) => target.speed,
    }
    .max(0.0);
    let class = match spec.vehicle {
        HeroVehicle::Car => VehicleClass::Car,
        HeroVehicle::Truck => VehicleClass::Truck,
    };
    Ok(Planned {
        role: AgentRole::Hero,
        lane,
        station,
        speed,
        vehicle: pick_class(stats, class, sampler)?,
        fixed: true,
    })
}

fn plan_background(
    family: &LogicalScenario,
    map: &Map,
    stats: &TrafficStatistics,
    sampler: &mut Sampler,
    fixed: &[Planned],
) -> std::result::Result<Vec<Planned>, String> {
    let bg = &family.background;
    let centre = fixed[0].station;
    let road_end = main_road_length(map);
    let lanes: Vec<usize> = match &bg.lanes {
        Some(l) => l.clone(),
        None => (1..=main_lanes_at(map, centre)).collect(),
    };
    let headway_q = sampler.draw("background.headway_quantile", &bg.headway_band);
    let speed_band = [bg.speed_band.low(), bg.speed_band.high()];
    let headway_spread = Range::Uniform(
        (headway_q - 0.15).max(bg.headway_band.low()),
        (headway_q + 0.15).min(bg.headway_band.high()),
    );
    let mut out = Vec::new();
    for k in lanes {
        let lane = LaneRef::Main(k);
        let traffic = stats
            .lane(rank(map, lane, centre))
            .ok_or("the traffic statistics are empty")?;
        let start = (centre - bg.behind_m).max(5.0);
        let end = (centre + bg.ahead_m).min(road_end - 10.0);
        let mut on_lane: Vec<Planned> = fixed.iter().filter(|f| f.lane == lane).cloned().collect();
        let mut s = start + sampler.unit() * 30.0;
        while s < end {
            let vehicle = traffic.draw_vehicle(&mut sampler.rng, speed_band);
            let headway = traffic.draw_headway(
                &mut sampler.rng,
                [headway_spread.low(), headway_spread.high()],
            );
            let candidate = Planned {
                role: AgentRole::Controlled,
                lane,
                station: s,
                speed: vehicle.speed,
                vehicle,
                fixed: false,
            };
            let clear = fixed.iter().filter(|f| f.lane == lane).all(|f| {
                (f.station - s).abs()
                    >= 0.5 * (f.vehicle.length + candidate.vehicle.length)
                        + MIN_BACKGROUND_HEADWAY_S * f.speed.max(candidate.speed)
                        + 2.0
            });
            let step = candidate.vehicle.length + headway * candidate.speed.max(5.0);
            if clear && place(map, lane, s).is_some() {
                on_lane.push(candidate);
            }
            s += step.max(8.0);
        }
        on_lane.sort_by(|a, b| a.station.total_cmp(&b.station));
        match_recorded_closing(&mut on_lane, traffic, &mut sampler.rng);
        out.extend(on_lane.into_iter().filter(|p| !p.fixed));
    }
    Ok(out)
}

/// Ties the speeds of a lane's vehicles (sorted by station) to their neighbours' the way the
/// recording does: a background follower closes in on its leader no faster than a closing
/// rate drawn from the recorded followers' ([`LaneTraffic::closing_rates`]), and a background
/// leader ahead of a scenario vehicle is sped up likewise. A drawn rate below 0 (the gap
/// opened) only pins the follower to its leader's speed: recorded opening rates come mostly
/// from short gaps and would slow a follower 100 m back to a crawl. Speeds drawn per vehicle
/// alone put fast cars a few seconds behind slow trucks, far more often than the A9 logs do,
/// so the long-tail collisions would be rear-ends among the background rather than the
/// scenarios' manoeuvres.
fn match_recorded_closing(
    on_lane: &mut [Planned],
    traffic: &LaneTraffic,
    rng: &mut impl rand::Rng,
) {
    let gap = |f: &Planned, l: &Planned| {
        (l.station - f.station - 0.5 * (l.vehicle.length + f.vehicle.length)).max(0.0)
    };
    for i in (0..on_lane.len().saturating_sub(1)).rev() {
        if on_lane[i].fixed {
            continue;
        }
        let rate = traffic.draw_closing_rate(rng).max(0.0);
        let cap = on_lane[i + 1].speed + rate * gap(&on_lane[i], &on_lane[i + 1]);
        let f = &mut on_lane[i];
        f.speed = f.speed.min(cap);
    }
    for i in 1..on_lane.len() {
        if !on_lane[i - 1].fixed || on_lane[i].fixed {
            continue;
        }
        let rate = traffic.draw_closing_rate(rng).max(0.0);
        let floor = on_lane[i - 1].speed - rate * gap(&on_lane[i - 1], &on_lane[i]);
        let l = &mut on_lane[i];
        l.speed = l.speed.max(floor);
    }
}

/// Every vehicle on the road and no two overlapping, at the current step.
pub(super) fn check_initial(
    map: &Map,
    agents: &[ScenarioAgent],
) -> std::result::Result<(), String> {
    let boxes: Vec<OrientedBox> = agents
        .iter()
        .map(|a| {
            let [x, y, h, _] = a.states.last().copied().flatten().unwrap_or_default();
            OrientedBox::new([x, y], h, a.length, a.width)
        })
        .collect();
    for (i, b) in boxes.iter().enumerate() {
        if map.box_on_road(b) != BoxOnRoad::OnRoad {
            return Err(format!("agents[{i}] starts off the road"));
        }
        for (j, other) in boxes.iter().enumerate().skip(i + 1) {
            if b.overlaps(other) {
                return Err(format!("agents[{i}] and agents[{j}] start overlapping"));
            }
        }
    }
    Ok(())
}

/// Simulates `scenario` with its heroes scripted and every other vehicle driven by the IDM
/// reference driver, without early termination.
pub fn simulate_reference(scenario: &ConcreteScenario) -> Result<(Scene, Rollout, HeroScripts)> {
    let scene = scenario.to_scene()?;
    let device = crate::backend::Backend::reference_device(false);
    let batch = SceneBatch::from_scenes(&[&scene], &device)?;
    let dynamics = Dynamics::bicycle(scenario.dt);
    let mut idm = IdmDriver::new(&[&scene], IdmParams::default(), ActionLimits::default());
    let mut heroes = hero_scripts(&[scenario], &[&scene]);
    let mut caches = MapCaches::default();
    let result = {
        let mut policy = Scripted {
            policy: &mut idm,
            script: &mut heroes,
            mask: batch.agent_hero.clone(),
        };
        rollout(
            &[&scene],
            &batch,
            &dynamics,
            &mut policy,
            &mut caches,
            &RolloutConfig {
                steps: None,
                early_termination: false,
            },
        )?
    };
    Ok((scene, result, heroes))
}

/// The scenario as a scene whose future is the reference run (for drawing what happens).
pub fn scene_with_reference_future(scenario: &ConcreteScenario) -> Result<Scene> {
    let (mut scene, result, _) = simulate_reference(scenario)?;
    let poses = host_f64(result.poses.clone());
    let present = result
        .present
        .to_data()
        .try_into_vec_as::<bool>()
        .unwrap_or_default();
    let t1 = result.steps + 1;
    let now = scene.current_step();
    for (i, agent) in scene.agents.iter_mut().enumerate() {
        for k in 1..t1 {
            let step = now + k;
            if step >= agent.states.len() || !present[i * t1 + k] {
                continue;
            }
            let o = (i * t1 + k) * 4;
            agent.states[step] = AgentState {
                x: poses[o],
                y: poses[o + 1],
                heading: poses[o + 2],
                speed: poses[o + 3],
                accel: 0.0,
            };
            agent.valid[step] = true;
        }
    }
    Ok(scene)
}

/// Runs the scenario with the IDM reference driver; `Err` says why it is not valid.
pub fn reference_run(scenario: &ConcreteScenario) -> std::result::Result<ReferenceRun, String> {
    let (scene, result, heroes) = simulate_reference(scenario).map_err(|e| e.to_string())?;
    let phases = heroes.progress();
    for (h, hero) in phases.iter().enumerate() {
        for (p, progress) in hero.iter().enumerate() {
            if let Some(why) = &progress.failed {
                return Err(format!("hero {h} phase {p}: {why}"));
            }
            if progress.fired_step.is_none() {
                return Err(format!("hero {h} phase {p} never triggered"));
            }
            if progress.done_step.is_none() {
                return Err(format!("hero {h} phase {p} did not complete"));
            }
        }
    }
    // Heroes must stay on the road while they act.
    let poses = host_f64(result.poses.clone());
    let present = result
        .present
        .clone()
        .to_data()
        .try_into_vec_as::<bool>()
        .unwrap_or_default();
    let t1 = result.steps + 1;
    for hero in &scenario.heroes {
        let agent = &scenario.agents[hero.agent];
        for k in 0..t1 {
            if !present[hero.agent * t1 + k] {
                continue;
            }
            let o = (hero.agent * t1 + k) * 4;
            let b = OrientedBox::new(
                [poses[o], poses[o + 1]],
                poses[o + 2],
                agent.length,
                agent.width,
            );
            if scene.map.box_on_road(&b) == BoxOnRoad::OffRoad {
                return Err(format!("hero {} leaves the road at step {k}", hero.agent));
            }
        }
    }
    let any = |flags: Tensor<3, burn::tensor::Bool>| -> Vec<usize> {
        let [_, n, t] = flags.dims();
        let v = flags
            .to_data()
            .try_into_vec_as::<bool>()
            .unwrap_or_default();
        (0..n)
            .filter(|i| v[i * t..(i + 1) * t].iter().any(|&f| f))
            .collect()
    };
    Ok(ReferenceRun {
        attempts: 0,
        phases,
        collided_agents: any(result.collision),
        offroad_agents: any(result.offroad),
    })
}
