//! The scenario catalogue: the family files shipped in `scenarios/families/` and the default
//! sets drawn from them, sized like the paper's: 333 in-distribution concrete scenarios
//! (167 train, 166 eval) from the training families and 84 out-of-distribution ones from the
//! held-out families.
//!
//! Train and eval are held out on the parameter level: each concrete scenario is its own draw
//! of the family's parameters, alternately assigned to train and eval. Seeds derive from the
//! global seed, the family name and the draw number, so adding a family never changes the
//! scenarios of another, and generation can run in parallel yet stay deterministic.

use std::path::{Path, PathBuf};

use rayon::prelude::*;

use super::concrete::{ConcreteScenario, ScenarioSet};
use super::family::{FamilySet, LogicalScenario};
use super::sample::{SamplingContext, sample_scenario};
use crate::data::TrafficStatistics;
use crate::error::{Error, Result};

pub const DEFAULT_SEED: u64 = 2023;

/// Where the shipped family files live in this source tree.
pub fn builtin_families() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/families")
}

/// Reads every `*.toml` below `dir` (sorted by path); each file's stem must equal its
/// `name`, and names must be unique.
pub fn load_families(dir: &Path) -> Result<Vec<LogicalScenario>> {
    let mut files = Vec::new();
    collect_toml(dir, &mut files)?;
    files.sort();
    if files.is_empty() {
        return Err(Error::InvalidArgument(format!(
            "{}: no scenario family files (*.toml) found",
            dir.display()
        )));
    }
    let mut families: Vec<LogicalScenario> = Vec::new();
    for path in files {
        let family = LogicalScenario::from_toml_file(&path)?;
        let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("");
        if stem != family.name {
            return Err(Error::invalid(
                path.display().to_string(),
                "field `name`",
                format!("`{}` differs from the file name `{stem}`", family.name),
            ));
        }
        // A folder named for a set holds that set's families: one labelled otherwise is a
        // file moved without its label (or the label changed), and would draw into the
        // other set.
        let folder = path
            .parent()
            .and_then(|p| p.file_name())
            .and_then(|n| n.to_str())
            .unwrap_or("");
        if ["train", "ood"].contains(&folder) && folder != family.set.name() {
            return Err(Error::invalid(
                path.display().to_string(),
                "field `set`",
                format!(
                    "`{}` in the folder `{folder}/`; expected set = \"{folder}\" there, or \
                     the file in the `{}/` folder",
                    family.set.name(),
                    family.set.name()
                ),
            ));
        }
        if families.iter().any(|f| f.name == family.name) {
            return Err(Error::invalid(
                path.display().to_string(),
                "field `name`",
                format!("family `{}` is defined twice", family.name),
            ));
        }
        // A copy under another name, or a part of one, doubles its family's share of the
        // draws; a held-out family that mostly re-draws a training family's scenarios puts
        // training scenarios into the OOD set. Two training families may overlap in part (a
        // denser variant weights dense traffic).
        let limit = |other: &LogicalScenario| {
            if other.set == family.set {
                1.0 - super::family::NEAR_COPY_RELATIVE
            } else {
                super::family::SHARED_DRAWS_LIMIT
            }
        };
        let shared = families
            .iter()
            .map(|f| (f, f.shared_draws(&family)))
            .find(|(f, share)| *share > limit(f));
        if let Some((twin, share)) = shared {
            return Err(Error::invalid(
                path.display().to_string(),
                "the family",
                format!(
                    "`{}` ({} set) and `{}` ({} set) draw the same scenarios: {:.0} % of one's \
                     draws are the other's (the same map, manoeuvre and heroes, with ranges \
                     that overlap); expected each family once, {}",
                    family.name,
                    family.set.name(),
                    twin.name,
                    twin.set.name(),
                    share * 100.0,
                    if twin.set == family.set {
                        "not a copy or a part of another".to_string()
                    } else {
                        format!(
                            "and a held-out family sharing at most {:.0} % with a training one",
                            super::family::SHARED_DRAWS_LIMIT * 100.0
                        )
                    }
                ),
            ));
        }
        families.push(family);
    }
    families.sort_by(|a, b| a.name.cmp(&b.name));
    Ok(families)
}

fn collect_toml(dir: &Path, out: &mut Vec<PathBuf>) -> Result<()> {
    out.extend(crate::io::files_in_tree(dir)?.into_iter().filter(|path| {
        path.extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("toml"))
    }));
    Ok(())
}

/// Sizes and seed of the generated sets.
#[derive(Debug, Clone, PartialEq)]
pub struct GenerateConfig {
    pub seed: u64,
    /// Concrete scenarios from the training families, split alternately into train and eval.
    pub in_distribution: usize,
    /// Concrete scenarios from the held-out families.
    pub ood: usize,
    pub dt: f64,
    pub history_steps: usize,
}

impl Default for GenerateConfig {
    fn default() -> Self {
        Self {
            seed: DEFAULT_SEED,
            in_distribution: 333,
            ood: 84,
            dt: 0.5,
            history_steps: 4,
        }
    }
}

#[derive(Debug, Clone, Default)]
pub struct GeneratedSets {
    pub train: Vec<ConcreteScenario>,
    pub eval: Vec<ConcreteScenario>,
    pub ood: Vec<ConcreteScenario>,
}

impl GeneratedSets {
    pub fn set(&self, set: ScenarioSet) -> &[ConcreteScenario] {
        match set {
            ScenarioSet::Train => &self.train,
            ScenarioSet::Eval => &self.eval,
            ScenarioSet::Ood => &self.ood,
        }
    }

    /// Writes `dir/<set>/<id>.json`, one file per scenario (atomically).
    pub fn write(&self, dir: &Path) -> Result<usize> {
        let mut written = 0;
        for set in ScenarioSet::ALL {
            for s in self.set(set) {
                s.write(&dir.join(set.name()).join(format!("{}.json", s.id())))?;
                written += 1;
            }
        }
        Ok(written)
    }
}

/// The seed of draw `draw` of `family` (SplitMix64 over the seed and an FNV-1a hash of the
/// name: stable across platforms and Rust versions, unlike `std`'s hasher).
pub fn family_seed(seed: u64, family: &str, draw: usize) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in family.bytes() {
        h = (h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
    }
    let mut z = seed ^ h ^ (draw as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Draws per family: `total` spread as evenly as possible, the first families getting one more.
fn counts(families: usize, total: usize) -> Vec<usize> {
    (0..families)
        .map(|f| total / families + usize::from(f < total % families))
        .collect()
}

/// Generates the default sets from `families`.
pub fn generate_sets(
    families: &[LogicalScenario],
    stats: &TrafficStatistics,
    config: &GenerateConfig,
) -> Result<GeneratedSets> {
    let ctx = SamplingContext {
        stats,
        dt: config.dt,
        history_steps: config.history_steps,
    };
    // (family, draw, set, index within family and set)
    let mut jobs: Vec<(&LogicalScenario, usize, ScenarioSet, usize)> = Vec::new();
    for (kind, total) in [
        (FamilySet::Train, config.in_distribution),
        (FamilySet::Ood, config.ood),
    ] {
        let group: Vec<&LogicalScenario> = families.iter().filter(|f| f.set == kind).collect();
        if group.is_empty() {
            if total > 0 {
                return Err(Error::InvalidArgument(format!(
                    "{total} {kind:?} scenarios requested but no family has `set = \"{}\"`",
                    if kind == FamilySet::Train {
                        "train"
                    } else {
                        "ood"
                    }
                )));
            }
            continue;
        }
        let mut global = 0;
        for (family, count) in group.iter().zip(counts(group.len(), total)) {
            let (mut train_i, mut eval_i) = (0, 0);
            for draw in 0..count {
                let set = match kind {
                    FamilySet::Ood => ScenarioSet::Ood,
                    FamilySet::Train if global % 2 == 0 => ScenarioSet::Train,
                    FamilySet::Train => ScenarioSet::Eval,
                };
                let index = match set {
                    ScenarioSet::Eval => {
                        eval_i += 1;
                        eval_i - 1
                    }
                    _ => {
                        train_i += 1;
                        train_i - 1
                    }
                };
                jobs.push((family, draw, set, index));
                global += 1;
            }
        }
    }
    let results: Vec<Result<ConcreteScenario>> = jobs
        .par_iter()
        .map(|&(family, draw, set, index)| {
            sample_scenario(
                family,
                &ctx,
                family_seed(config.seed, &family.name, draw),
                set,
                index,
            )
        })
        .collect();
    // Report every family that failed, once each, rather than only the first.
    let mut failures: Vec<String> = Vec::new();
    let mut scenarios = Vec::with_capacity(results.len());
    for r in results {
        match r {
            Ok(s) => scenarios.push(s),
            Err(e) => {
                let text = e.to_string();
                if !failures
                    .iter()
                    .any(|f| f.split(':').next() == text.split(':').next())
                {
                    failures.push(text);
                }
            }
        }
    }
    if !failures.is_empty() {
        return Err(Error::InvalidArgument(format!(
            "{} scenario families could not be sampled:\n  {}",
            failures.len(),
            failures.join("\n  ")
        )));
    }
    let mut sets = GeneratedSets::default();
    for s in scenarios {
        match s.set {
            ScenarioSet::Train => sets.train.push(s),
            ScenarioSet::Eval => sets.eval.push(s),
            ScenarioSet::Ood => sets.ood.push(s),
        }
    }
    Ok(sets)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_spread_evenly_and_sum_to_the_total() {
        let c = counts(25, 333);
        assert_eq!(c.iter().sum::<usize>(), 333);
        assert!(c.iter().all(|&k| k == 13 || k == 14));
        assert_eq!(counts(12, 84), vec![7; 12]);
    }

    /// A family copied under another name, in the same set or as a held-out one, is refused
    /// at the copy; the shipped families are all different.
    #[test]
    fn a_family_copied_under_another_name_is_refused() {
        let shipped = load_families(&builtin_families()).expect("shipped families");
        let source = builtin_families().join("train/brake_fast_lane.toml");
        let text = std::fs::read_to_string(&source).expect("a shipped family");
        for (name, set) in [("brake_fast_lane_twin", "train"), ("zz_held_out", "ood")] {
            let dir = tempfile::tempdir().expect("temp dir");
            std::fs::copy(&source, dir.path().join("brake_fast_lane.toml")).expect("copy");
            let copy = text
                .replace("name = \"brake_fast_lane\"", &format!("name = \"{name}\""))
                .replace("set = \"train\"", &format!("set = \"{set}\""));
            std::fs::write(dir.path().join(format!("{name}.toml")), copy).expect("write");
            let err = load_families(dir.path()).expect_err("a copy").to_string();
            assert!(
                err.contains(&format!("{name}.toml"))
                    && err.contains("and `brake_fast_lane` (train set) draw the same scenarios")
                    && err.contains("100 %"),
                "{err}"
            );
        }
        assert!(shipped.len() > 30);
        // A bound nudged by a hair is the same family.
        let dir = tempfile::tempdir().expect("temp dir");
        std::fs::copy(&source, dir.path().join("brake_fast_lane.toml")).expect("copy");
        let nudged = text
            .replace("name = \"brake_fast_lane\"", "name = \"nudged\"")
            .replace("station = [250, 320]", "station = [250, 320.0001]");
        std::fs::write(dir.path().join("nudged.toml"), nudged).expect("write");
        let err = load_families(dir.path())
            .expect_err("a near copy")
            .to_string();
        assert!(err.contains("draw the same scenarios"), "{err}");
        // A range narrowed draws a part of the family's scenarios, in either set.
        for set in ["train", "ood"] {
            let narrowed = text
                .replace("name = \"brake_fast_lane\"", "name = \"nudged\"")
                .replace("set = \"train\"", &format!("set = \"{set}\""))
                .replace("station = [250, 320]", "station = [260, 300]");
            std::fs::write(dir.path().join("nudged.toml"), narrowed).expect("write");
            let err = load_families(dir.path()).expect_err("a part").to_string();
            assert!(
                err.contains("not a copy or a part of another") || set == "ood",
                "{err}"
            );
            assert!(err.contains("draw the same scenarios"), "{err}");
        }
        // A range moved: 93 % of the draws shared is a training family's in the held-out
        // set, but a training variant of it may overlap; 43 % shared is another family.
        let moved = |set: &str, station: &str| {
            let family = text
                .replace("name = \"brake_fast_lane\"", "name = \"nudged\"")
                .replace("set = \"train\"", &format!("set = \"{set}\""))
                .replace("station = [250, 320]", station);
            std::fs::write(dir.path().join("nudged.toml"), family).expect("write");
            load_families(dir.path())
        };
        let err = moved("ood", "station = [255, 325]")
            .expect_err("mostly the training family's draws")
            .to_string();
        assert!(
            err.contains("93 % of one's draws") && err.contains("at most 50 %"),
            "{err}"
        );
        moved("train", "station = [255, 325]").expect("a training variant");
        moved("ood", "station = [290, 360]").expect("43 % shared");
    }

    /// A family whose set label disagrees with the set folder it lies in is refused there.
    #[test]
    fn a_family_labelled_for_another_sets_folder_is_refused() {
        let source = builtin_families().join("train/brake_fast_lane.toml");
        let text = std::fs::read_to_string(&source).expect("a shipped family");
        let dir = tempfile::tempdir().expect("temp dir");
        std::fs::create_dir(dir.path().join("train")).expect("mkdir");
        let file = dir.path().join("train/brake_fast_lane.toml");
        std::fs::write(&file, text.replace("set = \"train\"", "set = \"ood\"")).expect("write");
        let err = load_families(dir.path())
            .expect_err("mislabelled")
            .to_string();
        assert!(
            err.contains("field `set`") && err.contains("folder `train/`"),
            "{err}"
        );
    }

    #[test]
    fn family_seeds_are_stable_and_distinct() {
        assert_eq!(family_seed(1, "a", 0), family_seed(1, "a", 0));
        assert_ne!(family_seed(1, "a", 0), family_seed(1, "a", 1));
        assert_ne!(family_seed(1, "a", 0), family_seed(1, "b", 0));
        assert_ne!(family_seed(1, "a", 0), family_seed(2, "a", 0));
    }
}
