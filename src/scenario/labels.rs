//! A concrete scenario's labels against its content. A scenario file says what it is twice:
//! once as labels (the drawn `parameters`, how the IDM reference driver fared in `reference`)
//! and once as the content that is simulated (map, states, hero scripts). A file edited after
//! it was generated can keep labels that no longer describe it, and results broken down by
//! those labels (or a reference rate read from them) would then describe another scenario.
//! Checked at every load ([`check_labels`], cheap):
//! - every drawn map value is the map's, every drawn hero-phase value the script's, and every
//!   number of a hero's script was drawn;
//! - a drawn speed (the target's, a hero's absolute or as an offset from the target's) is the
//!   agent's current speed;
//! - for a family shipped in `scenarios/families/`: the values drawn are that family's, each
//!   within its range, with the family's description, set and duration (a folder drawn from
//!   families of one's own is checked without them).
//!
//! Checked where a set or a single file without its content digest is loaded for use
//! ([`check_reference`], one rollout): simulating the scenario with the reference driver
//! gives the recorded `reference`.

use std::sync::OnceLock;

use serde_json::Value;

use super::concrete::{ConcreteScenario, ScenarioSet};
use super::family::{FamilySet, LogicalScenario};
use crate::error::{Error, Result};

/// Two labels agree with their content when they differ by no more than this, relative to
/// the larger value (drawn values are quantized to 6 decimals before they are stored).
const LABEL_TOLERANCE: f64 = 1e-6;

/// Refuses a scenario whose labels contradict its content, naming the field of `source`.
pub(super) fn check_labels(scenario: &ConcreteScenario, source: &str) -> Result<()> {
    let map = serde_json::to_value(&scenario.map)
        .map_err(|e| Error::invalid(source, "map", e.to_string()))?;
    for (name, &drawn) in &scenario.parameters {
        let field = format!("parameters.{name}");
        let actual = if let Some(key) = name.strip_prefix("map.") {
            map_value(&map, key)
        } else if let Some((hero, path)) = hero_phase_field(name) {
            phase_value(scenario, hero, &path)
        } else if let Some(hero) = hero_speed_label(name) {
            hero_speed(scenario, hero, name, drawn)
        } else if name == "target.speed" {
            current_speed(scenario, scenario.target)
        } else if known_placement_label(name) {
            continue;
        } else {
            return Err(Error::invalid(
                source,
                field,
                "is not a value any scenario family draws (map.*, target.*, heroes[i].*, \
                 background.*)",
            ));
        };
        match actual {
            Some(actual) if agree(actual, drawn) => {}
            Some(actual) => {
                return Err(contradiction(
                    source,
                    &field,
                    &format!("is {drawn}, but the scenario's content has {actual}"),
                ));
            }
            None => {
                return Err(contradiction(
                    source,
                    &field,
                    "names a value the scenario's content does not have",
                ));
            }
        }
    }
    every_script_value_was_drawn(scenario, source)?;
    match shipped_families()
        .iter()
        .find(|f| f.name == scenario.family)
    {
        Some(family) => drawn_from(scenario, family, source),
        None => Ok(()),
    }
}

/// The families of `scenarios/families/`, read once; none when the source tree is not at hand
/// (an installed binary), and then no scenario is held to them.
fn shipped_families() -> &'static [LogicalScenario] {
    static FAMILIES: OnceLock<Vec<LogicalScenario>> = OnceLock::new();
    FAMILIES.get_or_init(|| {
        super::catalogue::load_families(&super::catalogue::builtin_families()).unwrap_or_default()
    })
}

/// The scenario is a draw of the shipped `family`: the same drawn names, each value in its
/// range, and the family's description, set and duration.
fn drawn_from(scenario: &ConcreteScenario, family: &LogicalScenario, source: &str) -> Result<()> {
    let not_a_draw = |field: &str, what: String| {
        contradiction(
            source,
            field,
            &format!(
                "{what}, which no draw of the shipped family `{}` (scenarios/families/{}.toml) \
                 has (a family of your own needs a name of its own)",
                family.name, family.name
            ),
        )
    };
    let ranges = family.drawn_ranges();
    if let Some(name) = ranges
        .keys()
        .find(|n| !scenario.parameters.contains_key(*n))
    {
        return Err(not_a_draw("parameters", format!("has no `{name}`")));
    }
    for (name, &value) in &scenario.parameters {
        let field = format!("parameters.{name}");
        let Some(range) = ranges.get(name) else {
            return Err(not_a_draw(&field, "is drawn".into()));
        };
        let slack = LABEL_TOLERANCE * range.low().abs().max(range.high().abs()).max(1.0);
        if value < range.low() - slack || value > range.high() + slack {
            return Err(not_a_draw(&field, format!("is {value}, outside {range}")));
        }
    }
    if scenario.description != family.description {
        return Err(not_a_draw(
            "description",
            format!("is `{}`", scenario.description),
        ));
    }
    let in_family_set = match family.set {
        FamilySet::Train => scenario.set != ScenarioSet::Ood,
        FamilySet::Ood => scenario.set == ScenarioSet::Ood,
    };
    if !in_family_set {
        return Err(not_a_draw("set", format!("is `{}`", scenario.set.name())));
    }
    let steps = (family.duration_s / scenario.dt).round() as usize;
    if scenario.future_steps != steps {
        return Err(not_a_draw(
            "future_steps",
            format!(
                "is {} (the family's {} s at {} s per step is {steps})",
                scenario.future_steps, family.duration_s, scenario.dt
            ),
        ));
    }
    Ok(())
}

fn contradiction(source: &str, field: &str, what: &str) -> Error {
    Error::invalid(
        source,
        field,
        format!(
            "{what}: the labels no longer describe the scenario (was the file edited after \
             `rtr scenarios generate` wrote it?); generate it again"
        ),
    )
}

fn agree(a: f64, b: f64) -> bool {
    (a - b).abs() <= LABEL_TOLERANCE * a.abs().max(b.abs()).max(1.0)
}

/// The map's value of a drawn `map.<key>` (a divided road's median width lives in its layout).
fn map_value(map: &Value, key: &str) -> Option<f64> {
    if key == "median_width" {
        return map.get("layout")?.get("median_width")?.as_f64();
    }
    map.get(key)?.as_f64()
}

/// `heroes[h].phases[p].<trigger|action>.<field>` as (h, [p, part, field]).
fn hero_phase_field(name: &str) -> Option<(usize, Vec<String>)> {
    let (hero, rest) = hero_index(name)?;
    let rest = rest.strip_prefix(".phases[")?;
    let (phase, rest) = rest.split_once(']')?;
    let (part, field) = rest.strip_prefix('.')?.split_once('.')?;
    if !matches!(part, "trigger" | "action") || field.contains('.') {
        return None;
    }
    Some((hero, vec![phase.to_string(), part.into(), field.into()]))
}

/// `heroes[h]<rest>` as (h, rest).
fn hero_index(name: &str) -> Option<(usize, &str)> {
    let rest = name.strip_prefix("heroes[")?;
    let (index, rest) = rest.split_once(']')?;
    Some((index.parse().ok()?, rest))
}

fn phase_value(scenario: &ConcreteScenario, hero: usize, path: &[String]) -> Option<f64> {
    let phase: usize = path[0].parse().ok()?;
    let phase = scenario.heroes.get(hero)?.phases.get(phase)?;
    let value = serde_json::to_value(phase).ok()?;
    value.get(&path[1])?.get(&path[2])?.as_f64()
}

/// `heroes[h].speed` or `heroes[h].speed_offset`: the hero index.
fn hero_speed_label(name: &str) -> Option<usize> {
    let (hero, rest) = hero_index(name)?;
    matches!(rest, ".speed" | ".speed_offset").then_some(hero)
}

/// The hero's current speed as its label states it: absolute, or as an offset from the
/// target's current speed (a hero never drives backwards, so a negative sum is 0).
fn hero_speed(scenario: &ConcreteScenario, hero: usize, name: &str, drawn: f64) -> Option<f64> {
    let hero = scenario.heroes.get(hero)?;
    let speed = current_speed(scenario, hero.agent)?;
    if name.ends_with(".speed_offset") {
        let target = current_speed(scenario, hero.target)?;
        // A hero at rest had its sum clamped at 0: any offset at or below -target agrees.
        return Some(if speed > 0.0 {
            speed - target
        } else {
            drawn.min(-target)
        });
    }
    Some(speed)
}

fn current_speed(scenario: &ConcreteScenario, agent: usize) -> Option<f64> {
    Some(scenario.agents.get(agent)?.states.last()?.as_ref()?[3])
}

/// Labels of how agents were placed (stations, quantiles of the traffic statistics, pose
/// errors): their content is the states, which the reference run checks as a whole.
fn known_placement_label(name: &str) -> bool {
    let placement = [
        "target.station",
        "target.speed_quantile",
        "target.lateral_offset",
        "target.heading_error",
        "background.headway_quantile",
    ];
    placement.contains(&name) || hero_index(name).is_some_and(|(_, rest)| rest == ".station_offset")
}

/// Every number of a hero script is a drawn parameter: a script value without a label was
/// written by hand, and the breakdown by parameters would not see it.
fn every_script_value_was_drawn(scenario: &ConcreteScenario, source: &str) -> Result<()> {
    for (h, hero) in scenario.heroes.iter().enumerate() {
        for (p, phase) in hero.phases.iter().enumerate() {
            let value = serde_json::to_value(phase).map_err(|e| {
                Error::invalid(source, format!("heroes[{h}].phases[{p}]"), e.to_string())
            })?;
            for part in ["trigger", "action"] {
                let Some(fields) = value.get(part).and_then(Value::as_object) else {
                    continue;
                };
                for (field, v) in fields {
                    let name = format!("heroes[{h}].phases[{p}].{part}.{field}");
                    if v.is_number() && !scenario.parameters.contains_key(&name) {
                        return Err(contradiction(
                            source,
                            &name,
                            &format!("is {v} but `parameters` has no `{name}`"),
                        ));
                    }
                }
            }
        }
    }
    Ok(())
}

/// The recorded reference run is what simulating the scenario gives (how many draws it took
/// is history, not content, and is not compared). One rollout: done where scenarios are
/// loaded for use, not at every parse.
pub(super) fn check_reference(scenario: &ConcreteScenario, source: &str) -> Result<()> {
    let run = super::sample::reference_run(scenario).map_err(|why| {
        contradiction(
            source,
            "reference",
            &format!("says the reference driver passed, but simulating the scenario fails: {why}"),
        )
    })?;
    let recorded = &scenario.reference;
    let differs = [
        ("reference.phases", run.phases != recorded.phases),
        (
            "reference.collided_agents",
            run.collided_agents != recorded.collided_agents,
        ),
        (
            "reference.offroad_agents",
            run.offroad_agents != recorded.offroad_agents,
        ),
    ];
    match differs.iter().find(|(_, d)| *d) {
        Some((field, _)) => Err(contradiction(
            source,
            field,
            &format!(
                "differs from simulating the scenario with the reference driver (collided {:?}, \
                 off-road {:?}, phases {:?})",
                run.collided_agents, run.offroad_agents, run.phases
            ),
        )),
        None => Ok(()),
    }
}
