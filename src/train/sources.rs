//! Initial states for training: the nominal real A9 scenes (training split) and the long-tail
//! training scenarios, mixed as rho_0 = (1 - alpha) rho_D + alpha rho_S (paper section 3.2).
//!
//! A draw of K initial states becomes [`Part`]s: scenes that can share one tensor batch (same
//! kind, same window), since long-tail families run longer than the nominal 6 s window.

use std::collections::HashMap;
use std::ops::Range;
use std::path::Path;

use rand::Rng;

use super::config::DataConfig;
use crate::data::commonroad::{
    CommonRoadClip, check_clip_names, commonroad_scenes, load_commonroad, repeated_clips,
};
use crate::data::{A9Dataset, SceneConfig, TrafficStatistics, bend_scenes, read_scene_list};
use crate::error::{Error, Result};
use crate::scenario::{
    ConcreteScenario, GenerateConfig, ScenarioSet, builtin_families, generate_sets, load_families,
    load_scenario_set,
};
use crate::scene::Scene;

/// Everything a run samples its initial states from.
pub struct TrainingData {
    /// Real training scenes (they have logs: imitation targets): the A9 training split, then
    /// the scenes of each `data.commonroad` source.
    pub nominal: Vec<Scene>,
    /// The recorded sources in `nominal`: (index range, weight). One entry (A9) by default.
    pub nominal_sources: Vec<(Range<usize>, f64)>,
    /// Where in `nominal` the bent copies of the A9 split lie (`data.a9_bends`; empty range
    /// without them): scenes made from the recorded ones, not recorded themselves.
    pub bent: Range<usize>,
    /// Long-tail training scenarios and their scenes (no logs of the policy's agents beyond the
    /// reference IDM run, so no imitation loss is taken on them).
    pub longtail: Vec<(ConcreteScenario, Scene)>,
    /// Indices into `nominal` of the curated scenes (`data.curated`); when not empty they are
    /// the alpha share instead of `longtail`.
    pub curated: Vec<usize>,
}

/// One initial state: an index into [`TrainingData::nominal`] or [`TrainingData::longtail`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum InitialState {
    Nominal(usize),
    LongTail(usize),
}

/// Scenes that are batched and rolled out together.
pub struct Part<'a> {
    pub scenes: Vec<&'a Scene>,
    /// The scenarios behind long-tail scenes (their hero scripts); empty for nominal parts.
    pub scenarios: Vec<&'a ConcreteScenario>,
    /// Each scene's position in its draw: seeds its action noise, so a scene samples the same
    /// actions however the draw is batched or split across devices.
    pub slots: Vec<usize>,
}

impl Part<'_> {
    pub fn is_nominal(&self) -> bool {
        self.scenarios.is_empty()
    }
}

impl TrainingData {
    /// Loads the shipped A9 training split and the long-tail training scenarios as `config`
    /// says (a folder from `rtr scenarios generate`, or generated now). `with_longtail = false`
    /// skips the long-tail set (BC and IL never use it).
    pub fn load(dataset: &A9Dataset, config: &DataConfig, with_longtail: bool) -> Result<Self> {
        let mut nominal = dataset.scenes(&SceneConfig::default())?.train;
        if let Some(limit) = config.nominal_limit {
            nominal.truncate(limit);
        }
        if nominal.is_empty() {
            return Err(Error::InvalidArgument(
                "data.nominal_limit leaves no nominal training scene".into(),
            ));
        }
        let mut nominal_sources = vec![(0..nominal.len(), config.a9_weight)];
        let a9_len = nominal.len();
        for bend in &config.a9_bends {
            let bent = bend_scenes(&nominal[..a9_len], bend.curvature)?;
            let start = nominal.len();
            nominal.extend(bent);
            nominal_sources.push((start..nominal.len(), bend.weight));
        }
        let bent = a9_len..nominal.len();
        for (source, clips) in config.commonroad.iter().zip(commonroad_per_source(config)?) {
            let (scenes, _) = commonroad_scenes(&clips, &SceneConfig::default())?;
            if scenes.is_empty() {
                return Err(Error::invalid(
                    source.path.display().to_string(),
                    "data.commonroad",
                    "yields no scene (`rtr data summary --commonroad PATH` says why per file)",
                ));
            }
            let start = nominal.len();
            nominal.extend(scenes);
            nominal_sources.push((start..nominal.len(), source.weight));
        }
        let curated = match &config.curated {
            Some(path) => curated_indices(&nominal, path)?,
            None => Vec::new(),
        };
        let with_longtail = with_longtail && curated.is_empty();
        let mut scenarios = if !with_longtail {
            Vec::new()
        } else if let Some(dir) = &config.longtail_dir {
            load_scenario_set(dir, ScenarioSet::Train)?
        } else {
            let families = load_families(&builtin_families())?;
            let stats = TrafficStatistics::from_recording(&dataset.recording, &dataset.map, 1.0);
            let generate = GenerateConfig {
                in_distribution: config.longtail_generate,
                ood: 0,
                ..GenerateConfig::default()
            };
            generate_sets(&families, &stats, &generate)?.train
        };
        if let Some(limit) = config.longtail_limit {
            scenarios.truncate(limit);
        }
        if with_longtail && scenarios.is_empty() {
            let whence = match (&config.longtail_dir, config.longtail_limit) {
                (_, Some(0)) => "`data.longtail_limit` is 0".to_string(),
                (Some(dir), _) => format!("{} holds none", dir.join("train").display()),
                (None, _) => "`data.longtail_generate` is 0".to_string(),
            };
            return Err(Error::InvalidArgument(format!(
                "alpha > 0 needs long-tail training scenarios, but {whence}; expected the \
                 train/ set of `rtr scenarios generate`"
            )));
        }
        let longtail = scenarios
            .into_iter()
            .map(|s| s.to_scene().map(|scene| (s, scene)))
            .collect::<Result<Vec<_>>>()?;
        Ok(Self {
            nominal,
            nominal_sources,
            bent,
            longtail,
            curated,
        })
    }

    /// The nominal scenes as recorded (every source but the bent copies), in order.
    pub fn recorded(&self) -> impl Iterator<Item = &Scene> {
        self.nominal
            .iter()
            .enumerate()
            .filter(|(k, _)| !self.bent.contains(k))
            .map(|(_, scene)| scene)
    }

    /// `count` i.i.d. initial states: from the alpha share (curated scenes if any, else the
    /// long-tail set) with probability `alpha`, else nominal (a recorded source by weight,
    /// then uniform within it); each set uniform.
    pub fn sample(&self, rng: &mut impl Rng, count: usize, alpha: f64) -> Vec<InitialState> {
        (0..count)
            .map(|_| {
                if !self.curated.is_empty() && rng.random::<f64>() < alpha {
                    InitialState::Nominal(self.curated[rng.random_range(0..self.curated.len())])
                } else if !self.longtail.is_empty() && rng.random::<f64>() < alpha {
                    InitialState::LongTail(rng.random_range(0..self.longtail.len()))
                } else {
                    InitialState::Nominal(self.sample_nominal(rng))
                }
            })
            .collect()
    }

    /// A nominal scene index. With one source this is the draw rtr always made (uniform over
    /// `nominal`), so A9-only run files reproduce.
    fn sample_nominal(&self, rng: &mut impl Rng) -> usize {
        if self.nominal_sources.len() <= 1 {
            return rng.random_range(0..self.nominal.len());
        }
        let total: f64 = self.nominal_sources.iter().map(|(_, w)| w).sum();
        let mut pick = rng.random::<f64>() * total;
        let mut chosen = &self.nominal_sources[0].0;
        for (range, weight) in &self.nominal_sources {
            if *weight > 0.0 && !range.is_empty() {
                chosen = range;
                if pick < *weight {
                    break;
                }
            }
            pick -= weight;
        }
        rng.random_range(chosen.clone())
    }

    /// Groups `states` into batchable parts (nominal first, then long-tail by window length),
    /// keeping the draw order inside each part.
    pub fn parts(&self, states: &[InitialState]) -> Vec<Part<'_>> {
        let mut nominal = Part {
            scenes: Vec::new(),
            scenarios: Vec::new(),
            slots: Vec::new(),
        };
        let mut longtail: Vec<(usize, Part)> = Vec::new();
        for (slot, state) in states.iter().enumerate() {
            match *state {
                InitialState::Nominal(i) => {
                    nominal.scenes.push(&self.nominal[i]);
                    nominal.slots.push(slot);
                }
                InitialState::LongTail(i) => {
                    let (scenario, scene) = &self.longtail[i];
                    let steps = scene.steps();
                    let group = match longtail.iter().position(|(s, _)| *s == steps) {
                        Some(group) => group,
                        None => {
                            longtail.push((
                                steps,
                                Part {
                                    scenes: Vec::new(),
                                    scenarios: Vec::new(),
                                    slots: Vec::new(),
                                },
                            ));
                            longtail.len() - 1
                        }
                    };
                    let part = &mut longtail[group].1;
                    part.scenes.push(scene);
                    part.scenarios.push(scenario);
                    part.slots.push(slot);
                }
            }
        }
        longtail.sort_by_key(|(steps, _)| *steps);
        std::iter::once(nominal)
            .filter(|p| !p.scenes.is_empty())
            .chain(longtail.into_iter().map(|(_, p)| p))
            .collect()
    }
}

/// The positions in `nominal` of the scenes listed in `path`; an id that is not a nominal
/// training scene is an error naming it.
fn curated_indices(nominal: &[Scene], path: &Path) -> Result<Vec<usize>> {
    let position: HashMap<&str, usize> = nominal
        .iter()
        .enumerate()
        .map(|(k, s)| (s.id.as_str(), k))
        .collect();
    crate::io::check_input_file(path, "scene list").map_err(|e| {
        let why = match e {
            Error::InvalidArgument(message) => message,
            other => other.to_string(),
        };
        Error::InvalidArgument(format!("{why}; expected one written by `rtr curate`"))
            .in_field("data.curated")
    })?;
    read_scene_list(path)?
        .iter()
        .map(|id| {
            position.get(id.as_str()).copied().ok_or_else(|| {
                Error::invalid(
                    path.display().to_string(),
                    format!("scene `{id}`"),
                    "not a nominal training scene (curated scenes come from the A9 training \
                     split; is data.nominal_limit cutting it?)",
                )
            })
        })
        .collect()
}

/// The clips of each `data.commonroad` source, read as one set: scene ids unique over all
/// sources, and a clip whose driving another clip (of this source or another) already holds
/// left out, so no vehicle is trained on twice. A source left with no clip is an error.
fn commonroad_per_source(config: &DataConfig) -> Result<Vec<Vec<CommonRoadClip>>> {
    let per_source = config
        .commonroad
        .iter()
        .map(|source| {
            load_commonroad(std::slice::from_ref(&source.path), source.speed_limit)
                .map_err(|e| e.in_field("data.commonroad.path"))
        })
        .collect::<Result<Vec<_>>>()?;
    let all: Vec<CommonRoadClip> = per_source.concat();
    check_clip_names(&all)?;
    let mut repeats = repeated_clips(&all).into_iter();
    let mut kept = Vec::new();
    for (source, clips) in config.commonroad.iter().zip(per_source) {
        let (unique, repeated): (Vec<_>, Vec<_>) = clips
            .into_iter()
            .map(|clip| (clip, repeats.next().flatten()))
            .partition(|(_, repeat_of)| repeat_of.is_none());
        if unique.is_empty()
            && let Some((clip, Some(a))) = repeated.first()
        {
            return Err(Error::invalid(
                source.path.display().to_string(),
                "data.commonroad",
                format!(
                    "every vehicle of it is recorded in {} too ({} repeats that clip's \
                     driving): the source adds nothing",
                    all[*a].path.display(),
                    clip.path.display()
                ),
            ));
        }
        kept.push(unique.into_iter().map(|(clip, _)| clip).collect());
    }
    Ok(kept)
}
