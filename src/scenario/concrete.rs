//! Concrete scenarios: one draw of a logical scenario, stored as JSON (one file each) with
//! everything needed to simulate it again: the drawn parameters, the map parameters, every
//! vehicle's history, the heroes' concrete scripts, and how the reference driver fared.
//! There is no logged future: long-tail scenarios have no human demonstration, so they give
//! reinforcement signal only (imitation masks find no valid future step).

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

use serde::{Deserialize, Serialize};

use super::hero::{HeroAssignment, HeroScripts, PhaseProgress};
use crate::data::a9::LANE_NODE_LENGTH;
use crate::data::recordings::{JUMP_FACTOR, JUMP_SLACK};
use crate::data::{AgentState, VehicleClass};
use crate::error::{Error, Result};
use crate::io::atomic_write;
use crate::map::{LaneGraph, Map, ProceduralMap};
use crate::scene::{AgentRole, Scene, SceneAgent};

/// Longest simulated window a scenario file may ask for (steps; 10 minutes at 0.5 s).
pub const MAX_FUTURE_STEPS: usize = 1200;
/// Most history steps a scenario file may give (the paper's policy sees 5).
pub const MAX_HISTORY_STEPS: usize = 100;
/// Simulator steps a scenario may be drawn at (s); the paper's is 0.5.
const DT_RANGE: std::ops::RangeInclusive<f64> = 0.05..=2.0;

/// The set a concrete scenario belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ScenarioSet {
    Train,
    Eval,
    Ood,
}

impl ScenarioSet {
    pub const ALL: [ScenarioSet; 3] = [ScenarioSet::Train, ScenarioSet::Eval, ScenarioSet::Ood];

    pub fn name(self) -> &'static str {
        match self {
            ScenarioSet::Train => "train",
            ScenarioSet::Eval => "eval",
            ScenarioSet::Ood => "ood",
        }
    }
}

/// One vehicle: role, size and its states over the history and the current step
/// (`[x, y, heading, speed]` of the box centre; `null` before it enters the road).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioAgent {
    pub role: AgentRole,
    pub class: VehicleClass,
    pub length: f64,
    pub width: f64,
    pub states: Vec<Option<[f64; 4]>>,
}

/// A hero's concrete script.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioHero {
    pub agent: usize,
    pub target: usize,
    pub phases: Vec<super::behaviour::Phase<f64>>,
}

/// The validation run: heroes scripted, every other vehicle driven by the IDM reference
/// driver, no early termination.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReferenceRun {
    /// Draws needed until one passed validation.
    pub attempts: usize,
    /// Per hero, per phase: when it fired and completed.
    pub phases: Vec<Vec<PhaseProgress>>,
    /// Non-hero agents that collided with anything.
    pub collided_agents: Vec<usize>,
    /// Non-hero agents that left the road surface.
    pub offroad_agents: Vec<usize>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConcreteScenario {
    pub family: String,
    pub description: String,
    pub set: ScenarioSet,
    /// Position within its set's files of this family.
    pub index: usize,
    pub seed: u64,
    /// Every drawn value of the logical scenario's ranges, by name.
    pub parameters: BTreeMap<String, f64>,
    pub map: ProceduralMap,
    pub dt: f64,
    pub history_steps: usize,
    pub future_steps: usize,
    /// The agent the heroes act on.
    pub target: usize,
    pub agents: Vec<ScenarioAgent>,
    pub heroes: Vec<ScenarioHero>,
    pub reference: ReferenceRun,
    /// sha256 of everything above, as [`Self::write`] wrote it: a file edited since no longer
    /// matches and is refused. A scenario written by hand leaves it out.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub content_sha256: Option<String>,
}

/// Longest and shortest plausible vehicle (m), and widths.
const VEHICLE_LENGTH: std::ops::RangeInclusive<f64> = 1.0..=25.0;
const VEHICLE_WIDTH: std::ops::RangeInclusive<f64> = 0.5..=5.0;
/// Largest plausible |x|, |y| (m).
const MAX_COORDINATE: f64 = 1e7;

/// One vehicle's size and states are physical: a size a vehicle can have, finite positions,
/// headings in radians (degrees are refused), speeds in m/s.
fn check_agent(source: &str, i: usize, a: &ScenarioAgent) -> Result<()> {
    let fail = |field: String, message: String| Err(Error::invalid(source, field, message));
    if !VEHICLE_LENGTH.contains(&a.length) {
        return fail(
            format!("agents[{i}].length"),
            format!("{} m: expected a vehicle 1-25 m long", a.length),
        );
    }
    if !VEHICLE_WIDTH.contains(&a.width) {
        return fail(
            format!("agents[{i}].width"),
            format!("{} m: expected a vehicle 0.5-5 m wide", a.width),
        );
    }
    let max_speed = crate::vehicle::MAX_SPEED;
    for (k, state) in a.states.iter().enumerate() {
        let Some([x, y, heading, speed]) = *state else {
            continue;
        };
        let field = format!("agents[{i}].states[{k}]");
        if !(x.abs() <= MAX_COORDINATE && y.abs() <= MAX_COORDINATE) {
            return fail(
                field,
                format!("position ({x}, {y}): expected metres, |x|, |y| <= 1e7"),
            );
        }
        if heading.is_nan() || heading.abs() > crate::geometry::MAX_HEADING_RAD {
            return fail(
                field,
                format!(
                    "heading {heading} looks like degrees: expected radians, |heading| <= 2 pi"
                ),
            );
        }
        if !(0.0..=max_speed).contains(&speed) {
            return fail(
                field,
                format!("speed {speed}: expected m/s in [0, {max_speed}]"),
            );
        }
    }
    Ok(())
}

/// One vehicle's history moves as its speeds and headings say: no jump between two states
/// (a teleport, a corrupted row), and speeds and headings that agree with the motion
/// ([`crate::data::motion`]: km/h, degrees, a zeroed speed column).
fn check_history_motion(source: &str, i: usize, a: &ScenarioAgent, dt: f64) -> Result<()> {
    let states: Vec<(usize, [f64; 4])> = a
        .states
        .iter()
        .enumerate()
        .filter_map(|(k, s)| s.map(|s| (k, s)))
        .collect();
    // The recordings reader's rule for a jump between two states.
    let jump = |(j, p): (usize, [f64; 4]), (k, q): (usize, [f64; 4])| {
        let step = (k - j) as f64 * dt;
        let distance = (q[0] - p[0]).hypot(q[1] - p[1]);
        let allowed = JUMP_FACTOR * p[3].max(q[3]) * step + JUMP_SLACK;
        (distance > allowed).then(|| {
            format!(
                "states[{k}] moves {distance:.2} m in {step} s from states[{j}], but its \
                 speeds ({} and {} m/s) allow at most {allowed:.2} m: a jump (teleport or \
                 corrupted state)",
                p[3], q[3]
            )
        })
    };
    // One state far from both neighbours, which agree with each other, is the one at fault,
    // however short the history (its two jumps would otherwise pass for wrong speed units).
    for w in states.windows(3) {
        if jump(w[0], w[1]).is_some() && jump(w[1], w[2]).is_some() && jump(w[0], w[2]).is_none() {
            let message = jump(w[0], w[1]).unwrap_or_default();
            return Err(Error::invalid(source, format!("agents[{i}]"), message));
        }
    }
    let jumps: Vec<String> = states
        .windows(2)
        .filter_map(|pair| jump(pair[0], pair[1]))
        .collect();
    // A few steps too long for their speeds: those states are at fault. Most of them: the
    // speeds are (units, a zeroed column), which the motion check names.
    let steps = states.len().saturating_sub(1);
    if let Some(jump) = jumps.first()
        && 2 * jumps.len() < steps
    {
        return Err(Error::invalid(source, format!("agents[{i}]"), jump.clone()));
    }
    let column = |c: usize| states.iter().map(|(_, s)| s[c]).collect::<Vec<_>>();
    if states.windows(2).all(|w| w[1].0 == w[0].0 + 1)
        && let Err(mismatch) =
            crate::data::motion::check(dt, &column(0), &column(1), &column(2), &column(3))
    {
        return Err(Error::invalid(
            source,
            format!("agents[{i}].states"),
            format!("{mismatch} (states are [x, y, heading, speed])"),
        ));
    }
    match jumps.first() {
        Some(jump) => Err(Error::invalid(source, format!("agents[{i}]"), jump.clone())),
        None => Ok(()),
    }
}

impl ConcreteScenario {
    /// `family-set-index`, e.g. `cut_in_left-eval-003`.
    pub fn id(&self) -> String {
        format!("{}-{}-{:03}", self.family, self.set.name(), self.index)
    }

    pub fn to_json(&self) -> Result<String> {
        serde_json::to_string_pretty(self)
            .map(|mut s| {
                s.push('\n');
                s
            })
            .map_err(|e| {
                Error::InvalidArgument(format!("cannot encode scenario {}: {e}", self.id()))
            })
    }

    /// Writes the scenario with its [`Self::content_sha256`].
    pub fn write(&self, path: &Path) -> Result<()> {
        let stamped = Self {
            content_sha256: Some(self.content_digest()?),
            ..self.clone()
        };
        atomic_write(path, stamped.to_json()?.as_bytes())
    }

    /// sha256 of the scenario without its recorded digest.
    pub fn content_digest(&self) -> Result<String> {
        let bare = Self {
            content_sha256: None,
            ..self.clone()
        };
        let json = serde_json::to_vec(&bare).map_err(|e| {
            Error::InvalidArgument(format!("cannot encode scenario {}: {e}", self.id()))
        })?;
        Ok(crate::data::automatum::sha256_hex(&json))
    }

    /// Refuses a file whose content is not what was written with its digest.
    fn check_digest(&self, source: &str) -> Result<()> {
        let Some(recorded) = &self.content_sha256 else {
            return Ok(());
        };
        if *recorded == self.content_digest()? {
            return Ok(());
        }
        Err(Error::invalid(
            source,
            "content_sha256",
            "is not the digest of the file's content: the file was edited after rtr wrote it, \
             so its labels (family, parameters, reference) may no longer describe it; generate \
             it again, or delete the `content_sha256` line to use the edited file as a scenario \
             of your own (its labels are then checked against its content)",
        ))
    }

    /// Refuses a scenario whose recorded `reference` is not what simulating it with the
    /// reference driver gives (the file was edited after it was generated). One rollout, so
    /// it is done where scenarios are loaded for use rather than at every parse, and only for
    /// a file without its content digest (an older set, a scenario of the user's own): one
    /// whose digest held at parse ([`Self::check_digest`]) is as rtr wrote it, reference and
    /// all, and a set of a few thousand need not be simulated again at every load.
    pub fn check_reference(&self, source: &str) -> Result<()> {
        if self.content_sha256.is_some() {
            return Ok(());
        }
        super::labels::check_reference(self, source)
    }

    pub fn from_json_file(path: &Path) -> Result<Self> {
        let text = crate::io::read_text(path, crate::io::Format::Scenario)?;
        Self::from_json_str(&text, &path.display().to_string())
    }

    /// Parses and checks a scenario; errors name `source_name` and the line or field.
    pub fn from_json_str(text: &str, source_name: &str) -> Result<Self> {
        let scenario: Self = crate::io::parse_json(text, source_name)?;
        scenario.check_digest(source_name)?;
        scenario.check(source_name)?;
        Ok(scenario)
    }

    /// Checks of a loaded file: indices in range, history lengths, physical values (vehicle
    /// sizes, finite positions, headings in radians, speeds), the map's parameters, and labels
    /// that agree with the content ([`super::labels`]).
    fn check(&self, source: &str) -> Result<()> {
        if !(1..=MAX_HISTORY_STEPS).contains(&self.history_steps) {
            return Err(Error::invalid(
                source,
                "history_steps",
                format!("{}: expected 1 to {MAX_HISTORY_STEPS}", self.history_steps),
            ));
        }
        let steps = self.history_steps + 1;
        let n = self.agents.len();
        let od = self
            .map
            .build()
            .map_err(|e| Error::invalid(source, "map", e.to_string()))?;
        for (i, a) in self.agents.iter().enumerate() {
            check_agent(source, i, a)?;
        }
        for (i, a) in self.agents.iter().enumerate() {
            if a.states.len() != steps {
                return Err(Error::invalid(
                    source,
                    format!("agents[{i}].states"),
                    format!(
                        "has {} entries, expected history_steps + 1 = {steps}",
                        a.states.len()
                    ),
                ));
            }
            if a.states[steps - 1].is_none() {
                return Err(Error::invalid(
                    source,
                    format!("agents[{i}].states"),
                    "the current (last) state is null: every agent must be on the road now",
                ));
            }
        }
        if self.target >= n {
            return Err(Error::invalid(
                source,
                "target",
                format!("{} but there are {n} agents", self.target),
            ));
        }
        self.check_heroes(source)?;
        for (field, list) in [
            ("reference.collided_agents", &self.reference.collided_agents),
            ("reference.offroad_agents", &self.reference.offroad_agents),
        ] {
            if let Some(bad) = list.iter().find(|&&i| i >= n) {
                return Err(Error::invalid(
                    source,
                    field,
                    format!("agent {bad} but there are {n} agents"),
                ));
            }
        }
        if !DT_RANGE.contains(&self.dt) {
            return Err(Error::invalid(
                source,
                "dt",
                format!(
                    "{} s: expected a simulator step of {} to {} s",
                    self.dt,
                    DT_RANGE.start(),
                    DT_RANGE.end()
                ),
            ));
        }
        for (i, a) in self.agents.iter().enumerate() {
            check_history_motion(source, i, a, self.dt)?;
        }
        // Windows are allocated per step: a corrupt count must be an error, not an abort.
        if self.future_steps == 0 || self.future_steps > MAX_FUTURE_STEPS {
            return Err(Error::invalid(
                source,
                "future_steps",
                format!("{}: expected 1 to {MAX_FUTURE_STEPS}", self.future_steps),
            ));
        }
        // Where the scenario starts: every vehicle on the road, no two overlapping.
        let map = Map::from_opendrive(&od, source)?;
        super::sample::check_initial(&map, &self.agents)
            .map_err(|why| Error::invalid(source, "agents", why))?;
        super::labels::check_labels(self, source)
    }

    /// Each hero drives another agent, with phases in the family files' bounds.
    fn check_heroes(&self, source: &str) -> Result<()> {
        let n = self.agents.len();
        for (h, hero) in self.heroes.iter().enumerate() {
            let place = format!("heroes[{h}]");
            if hero.agent >= n || hero.target >= n {
                return Err(Error::invalid(
                    source,
                    place,
                    format!(
                        "agent {} / target {} but there are {n} agents",
                        hero.agent, hero.target
                    ),
                ));
            }
            if hero.agent == hero.target {
                return Err(Error::invalid(
                    source,
                    place,
                    format!(
                        "agent {0} targets itself; expected another agent",
                        hero.agent
                    ),
                ));
            }
            if hero.phases.is_empty() {
                return Err(Error::invalid(
                    source,
                    place,
                    "no phases: a hero follows at least one",
                ));
            }
            for (k, phase) in hero.phases.iter().enumerate() {
                phase
                    .check(&format!("{place}.phases[{k}]"))
                    .map_err(|why| Error::invalid(source, format!("{place}.phases[{k}]"), why))?;
            }
        }
        Ok(())
    }

    /// Builds the map and lane graph.
    pub fn build_map(&self) -> Result<(Arc<Map>, Arc<LaneGraph>)> {
        let map = Arc::new(Map::from_opendrive(&self.map.build()?, &self.id())?);
        let graph = Arc::new(LaneGraph::build(&map, LANE_NODE_LENGTH));
        Ok((map, graph))
    }

    /// The scenario as a simulator scene (future steps carry no log).
    pub fn to_scene(&self) -> Result<Scene> {
        let (map, lane_graph) = self.build_map()?;
        Ok(self.scene_on(map, lane_graph))
    }

    /// As [`to_scene`](Self::to_scene) on an already built map.
    pub fn scene_on(&self, map: Arc<Map>, lane_graph: Arc<LaneGraph>) -> Scene {
        let steps = self.history_steps + 1 + self.future_steps;
        let agents = self
            .agents
            .iter()
            .enumerate()
            .map(|(i, a)| {
                let mut states = vec![AgentState::default(); steps];
                let mut valid = vec![false; steps];
                for (k, s) in a.states.iter().enumerate() {
                    if let Some([x, y, heading, speed]) = *s {
                        states[k] = AgentState {
                            x,
                            y,
                            heading,
                            speed,
                            accel: 0.0,
                        };
                        valid[k] = true;
                    }
                }
                SceneAgent {
                    track_id: i,
                    class: a.class.clone(),
                    length: a.length,
                    width: a.width,
                    role: a.role,
                    states,
                    valid,
                }
            })
            .collect();
        Scene {
            id: self.id(),
            t0: 0.0,
            dt: self.dt,
            history_steps: self.history_steps,
            future_steps: self.future_steps,
            map,
            lane_graph,
            agents,
        }
    }

    /// The heroes as assignments for scene `b` of a batch.
    pub fn hero_assignments(&self, b: usize) -> Vec<HeroAssignment> {
        self.heroes
            .iter()
            .map(|h| HeroAssignment {
                scene: b,
                agent: h.agent,
                target: h.target,
                phases: h.phases.clone(),
            })
            .collect()
    }
}

/// The hero script policy for a batch of scenarios, `scenes[b]` built from `scenarios[b]`.
pub fn hero_scripts(scenarios: &[&ConcreteScenario], scenes: &[&Scene]) -> HeroScripts {
    let assignments = scenarios
        .iter()
        .enumerate()
        .flat_map(|(b, s)| s.hero_assignments(b))
        .collect();
    let dt = scenarios.first().map_or(0.5, |s| s.dt);
    HeroScripts::new(
        scenes.iter().map(|s| s.map.clone()).collect(),
        assignments,
        dt,
    )
}
