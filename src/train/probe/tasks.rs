//! The probe tasks' scenarios: logical scenario families shipped in `scenarios/probes/` (and
//! compiled in, so the probe runs from any folder), drawn into training and held-out sets by
//! the same sampler as the long-tail sets.

use crate::data::TrafficStatistics;
use crate::error::Result;
use crate::scenario::{ConcreteScenario, GenerateConfig, LogicalScenario, generate_sets};

/// What a probe asks of PPO.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ProbeTask {
    /// A car ahead brakes to a stop, or stands still, on a one-lane straight road: the right
    /// behaviour is to brake in time (gently for some draws, hard for others).
    Brake,
    /// A lone car starts off its lane's centre and heading out of it on a curve: the right
    /// behaviour is to steer back into the lane.
    Recover,
    /// A slow car with a car standing ahead on a one-lane road, where only the acceleration
    /// can change the outcome: the PPO gradient must push the acceleration towards braking
    /// and leave the steering without a direction.
    Credit,
}

impl ProbeTask {
    pub const ALL: [ProbeTask; 3] = [ProbeTask::Brake, ProbeTask::Recover, ProbeTask::Credit];

    pub fn name(self) -> &'static str {
        match self {
            ProbeTask::Brake => "brake",
            ProbeTask::Recover => "recover",
            ProbeTask::Credit => "credit",
        }
    }

    /// The task named `name` (as [`Self::name`] writes it).
    pub fn parse(name: &str) -> std::result::Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|t| t.name() == name)
            .ok_or_else(|| {
                format!("unknown probe task `{name}`: expected brake, recover or credit")
            })
    }

    /// The families whose scenarios pose the task.
    fn family_sources(self) -> &'static [(&'static str, &'static str)] {
        match self {
            ProbeTask::Brake => &[
                (
                    "scenarios/probes/probe_brake_lead.toml",
                    include_str!("../../../scenarios/probes/probe_brake_lead.toml"),
                ),
                (
                    "scenarios/probes/probe_stopped_car.toml",
                    include_str!("../../../scenarios/probes/probe_stopped_car.toml"),
                ),
            ],
            ProbeTask::Credit => &[(
                "scenarios/probes/probe_credit_stop.toml",
                include_str!("../../../scenarios/probes/probe_credit_stop.toml"),
            )],
            ProbeTask::Recover => &[
                (
                    "scenarios/probes/probe_recover_left.toml",
                    include_str!("../../../scenarios/probes/probe_recover_left.toml"),
                ),
                (
                    "scenarios/probes/probe_recover_right.toml",
                    include_str!("../../../scenarios/probes/probe_recover_right.toml"),
                ),
            ],
        }
    }

    pub fn families(self) -> Result<Vec<LogicalScenario>> {
        self.family_sources()
            .iter()
            .map(|(name, text)| LogicalScenario::from_toml_str(text, name))
            .collect()
    }
}

/// A task's concrete scenarios: PPO trains on `train` and is measured on `eval`, other draws
/// of the same families.
pub struct ProbeScenarios {
    pub train: Vec<ConcreteScenario>,
    pub eval: Vec<ConcreteScenario>,
}

/// Draws `train` + `eval` scenarios of `task` (split alternately, as the long-tail sets are)
/// from `seed`, with vehicle sizes from `stats`.
pub fn probe_scenarios(
    task: ProbeTask,
    stats: &TrafficStatistics,
    train: usize,
    eval: usize,
    seed: u64,
) -> Result<ProbeScenarios> {
    // Alternate split: 2k draws give k of each; ask for enough that both sets are full.
    let draws = 2 * train.max(eval);
    let sets = generate_sets(
        &task.families()?,
        stats,
        &GenerateConfig {
            seed,
            in_distribution: draws,
            ood: 0,
            ..GenerateConfig::default()
        },
    )?;
    Ok(ProbeScenarios {
        train: interleaved(sets.train, train),
        eval: interleaved(sets.eval, eval),
    })
}

/// The first `count` of `scenarios` taking the families in turn, so a shorter set keeps
/// every family.
fn interleaved(mut scenarios: Vec<ConcreteScenario>, count: usize) -> Vec<ConcreteScenario> {
    scenarios.sort_by(|a, b| (a.index, &a.family).cmp(&(b.index, &b.family)));
    scenarios.truncate(count);
    scenarios
}
