//! The scene sets of the paper's tables: the real A9 test split (nominal), the long-tail
//! evaluation scenarios (drawn from the training families, disjoint from training draws) and
//! the out-of-distribution scenarios (held-out families).

use std::path::Path;
use std::sync::Arc;

use serde::{Deserialize, Serialize};

use crate::data::a9::LANE_NODE_LENGTH;
use crate::data::{A9Dataset, SceneConfig, TrafficStatistics};
use crate::error::{Error, Result};
use crate::map::LaneGraph;
use crate::scenario::{
    ConcreteScenario, GenerateConfig, ScenarioSet, builtin_families, generate_sets, load_families,
    load_scenario_set,
};
use crate::scene::Scene;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EvalSet {
    Nominal,
    Longtail,
    Ood,
    /// Recorded scenes from CommonRoad files (`rtr eval --commonroad PATH`).
    CommonRoad,
}

impl EvalSet {
    pub const ALL: [EvalSet; 4] = [
        EvalSet::Nominal,
        EvalSet::Longtail,
        EvalSet::Ood,
        EvalSet::CommonRoad,
    ];

    pub fn name(self) -> &'static str {
        match self {
            EvalSet::Nominal => "nominal",
            EvalSet::Longtail => "longtail",
            EvalSet::Ood => "ood",
            EvalSet::CommonRoad => "commonroad",
        }
    }

    pub fn parse(text: &str) -> Result<Self> {
        Self::ALL
            .into_iter()
            .find(|s| s.name() == text)
            .ok_or_else(|| {
                Error::InvalidArgument(format!(
                    "unknown scene set `{text}`: expected nominal, longtail, ood or commonroad"
                ))
            })
    }

    /// The sets of a `--set` list, each named once: a set given twice would be evaluated
    /// twice and its columns repeated in the table.
    pub fn parse_list(texts: &[String]) -> Result<Vec<Self>> {
        let mut sets = Vec::with_capacity(texts.len());
        for text in texts {
            let set = Self::parse(text.trim())?;
            if sets.contains(&set) {
                return Err(Error::InvalidArgument(format!(
                    "--set names `{}` twice: expected each of nominal, longtail, ood, \
                     commonroad at most once",
                    set.name()
                )));
            }
            sets.push(set);
        }
        Ok(sets)
    }

    /// Real scenes whose controlled agents have logged futures (reconstruction and JSD
    /// metrics apply); the generated sets have none.
    pub fn has_logs(self) -> bool {
        matches!(self, EvalSet::Nominal | EvalSet::CommonRoad)
    }
}

/// One set's scenes, and for generated sets the scenarios behind them (their hero scripts).
pub struct EvalScenes {
    pub set: EvalSet,
    pub scenes: Vec<Scene>,
    /// Empty for the nominal set; else `scenarios[k]` built `scenes[k]`.
    pub scenarios: Vec<ConcreteScenario>,
}

impl EvalScenes {
    /// Keeps the first `n` scenes (a quick look at a set).
    pub fn keep_first(&mut self, n: usize) {
        self.scenes.truncate(n);
        self.scenarios.truncate(n);
    }

    /// Gives every scene's road (and lane graph) the speed limit `speed_limit` (m/s).
    pub fn set_speed_limit(&mut self, speed_limit: f64) {
        for scene in &mut self.scenes {
            let map = scene.map.with_speed_limit(speed_limit);
            scene.lane_graph = Arc::new(LaneGraph::build(&map, LANE_NODE_LENGTH));
            scene.map = Arc::new(map);
        }
    }

    /// The A9 test split (the recording's last 20 %, never trained on).
    pub fn nominal(dataset: &A9Dataset) -> Result<Self> {
        Ok(Self::real(dataset.scenes(&SceneConfig::default())?.test))
    }

    /// Real logged scenes as a nominal set (e.g. the training split, for curation and for the
    /// downstream study's initial conditions).
    pub fn real(scenes: Vec<Scene>) -> Self {
        Self {
            set: EvalSet::Nominal,
            scenes,
            scenarios: Vec::new(),
        }
    }

    /// Recorded scenes from CommonRoad files.
    pub fn commonroad(scenes: Vec<Scene>) -> Self {
        Self {
            set: EvalSet::CommonRoad,
            scenes,
            scenarios: Vec::new(),
        }
    }

    pub fn generated(set: EvalSet, scenarios: Vec<ConcreteScenario>) -> Result<Self> {
        let scenes = scenarios
            .iter()
            .map(ConcreteScenario::to_scene)
            .collect::<Result<Vec<_>>>()?;
        Ok(Self {
            set,
            scenes,
            scenarios,
        })
    }
}

/// The requested sets. Generated sets come from `scenario_dir` (written by `rtr scenarios
/// generate`: its `eval/` and `ood/`), or are drawn now with the default seed and sizes
/// (the same scenarios `rtr scenarios generate` writes by default).
pub fn load_sets(
    dataset: &A9Dataset,
    scenario_dir: Option<&Path>,
    sets: &[EvalSet],
) -> Result<Vec<EvalScenes>> {
    let wants_generated = sets
        .iter()
        .any(|s| matches!(s, EvalSet::Longtail | EvalSet::Ood));
    let mut generated = None;
    if wants_generated && scenario_dir.is_none() {
        let families = load_families(&builtin_families())?;
        let stats = TrafficStatistics::from_recording(&dataset.recording, &dataset.map, 1.0);
        generated = Some(generate_sets(
            &families,
            &stats,
            &GenerateConfig::default(),
        )?);
    }
    sets.iter()
        .map(|&set| {
            let source = match set {
                EvalSet::Nominal => return EvalScenes::nominal(dataset),
                EvalSet::Longtail => ScenarioSet::Eval,
                EvalSet::Ood => ScenarioSet::Ood,
                EvalSet::CommonRoad => {
                    return Err(Error::InvalidArgument(
                        "the commonroad set is read from CommonRoad files: pass --commonroad \
                         PATH (a file or a folder; repeatable)"
                            .into(),
                    ));
                }
            };
            let scenarios = match (scenario_dir, &generated) {
                (Some(dir), _) => load_scenario_set(dir, source)?,
                (None, Some(g)) => g.set(source).to_vec(),
                (None, None) => Vec::new(),
            };
            if scenarios.is_empty() {
                return Err(Error::InvalidArgument(format!(
                    "the {} set has no scenarios (looked in {})",
                    set.name(),
                    scenario_dir.map_or("the generated sets".into(), |d| d
                        .join(source.name())
                        .display()
                        .to_string())
                )));
            }
            EvalScenes::generated(set, scenarios)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_set_list_names_each_set_once() {
        let list =
            |t: &[&str]| EvalSet::parse_list(&t.iter().map(|s| s.to_string()).collect::<Vec<_>>());
        assert_eq!(
            list(&["nominal", " longtail"]).expect("two sets"),
            [EvalSet::Nominal, EvalSet::Longtail]
        );
        let twice = list(&["nominal", "ood", " nominal"]).expect_err("nominal twice");
        assert!(twice.to_string().contains("`nominal` twice"), "{twice}");
        assert!(list(&["nominal", "bogus"]).is_err());
    }
}
