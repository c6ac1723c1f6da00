//! The paper's metrics (appendix "Metrics") from per-scene tallies: collision and off-road %
//! of policy-controlled agents (and the % with either, so a low collision rate bought by
//! leaving the road shows), FDE at 5 s and its along-/cross-track split (ATE, CTE), and JSDs of feature
//! histograms (simulated vs logged). Every metric is a function of tallies summed over scenes,
//! so the bootstrap over scenes resamples tallies ([`super::bootstrap`]).

use serde::{Deserialize, Serialize};

use super::bootstrap::Additive;
use super::features::Feature;
use super::histogram::{Histogram, jensen_shannon};

/// Sums over one scene's policy-controlled agents.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneTally {
    /// Controlled agents evaluated.
    pub agents: f64,
    /// Agents with at least one collision / off-road step.
    pub collided: f64,
    pub offroad: f64,
    /// Agents with at least one collision or off-road step (either infraction).
    #[serde(default)]
    pub infracted: f64,
    /// Agents whose only collisions were log-replayed vehicles running into them from behind
    /// (not in `collided`: [`super::collisions::hit_only_by_log`]).
    #[serde(default)]
    pub hit_by_log: f64,
    /// FDE, ATE and CTE summed over the agents simulated and logged at the FDE horizon, and
    /// their count. ATE and CTE split the final displacement along and across the logged path
    /// (as the paper's table, where ATE^2 + CTE^2 ~ FDE^2).
    pub fde_sum: f64,
    pub ate_sum: f64,
    pub cte_sum: f64,
    pub fde_agents: f64,
    /// Per [`Feature::ALL`]: histograms of simulated and of logged agent-steps.
    pub simulated: Vec<Histogram>,
    pub logged: Vec<Histogram>,
}

impl Default for SceneTally {
    fn default() -> Self {
        Self {
            agents: 0.0,
            collided: 0.0,
            offroad: 0.0,
            infracted: 0.0,
            hit_by_log: 0.0,
            fde_sum: 0.0,
            ate_sum: 0.0,
            cte_sum: 0.0,
            fde_agents: 0.0,
            simulated: Feature::ALL.iter().map(|f| f.histogram()).collect(),
            logged: Feature::ALL.iter().map(|f| f.histogram()).collect(),
        }
    }
}

impl Additive for SceneTally {
    fn zero_like(&self) -> Self {
        Self::default()
    }

    fn add_scaled(&mut self, o: &Self, t: f64) {
        self.agents += t * o.agents;
        self.collided += t * o.collided;
        self.offroad += t * o.offroad;
        self.infracted += t * o.infracted;
        self.hit_by_log += t * o.hit_by_log;
        self.fde_sum += t * o.fde_sum;
        self.ate_sum += t * o.ate_sum;
        self.cte_sum += t * o.cte_sum;
        self.fde_agents += t * o.fde_agents;
        for (a, b) in self.simulated.iter_mut().zip(&o.simulated) {
            a.add_counts(b, t);
        }
        for (a, b) in self.logged.iter_mut().zip(&o.logged) {
            a.add_counts(b, t);
        }
    }
}

/// One column of the paper's tables.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum Metric {
    CollisionPct,
    OffroadPct,
    /// Agents with either infraction (not in the paper).
    InfractionPct,
    /// Agents run into from behind by a log-replayed vehicle and in no other collision (not
    /// in the paper, whose scenes replay no vehicle; not counted in `CollisionPct`).
    HitByLogPct,
    FdeM,
    AteM,
    CteM,
    Jsd(Feature),
}

impl Metric {
    /// The columns in the paper's order.
    pub const ALL: [Metric; 11] = [
        Metric::CollisionPct,
        Metric::OffroadPct,
        Metric::InfractionPct,
        Metric::HitByLogPct,
        Metric::FdeM,
        Metric::AteM,
        Metric::CteM,
        Metric::Jsd(Feature::Acceleration),
        Metric::Jsd(Feature::Speed),
        Metric::Jsd(Feature::LaneDeviation),
        Metric::Jsd(Feature::LeadDistance),
    ];

    /// The JSON key (`methods.<METHOD>.<SET>.<key>` in results.json).
    pub fn key(self) -> String {
        match self {
            Metric::CollisionPct => "collision_pct".into(),
            Metric::OffroadPct => "offroad_pct".into(),
            Metric::InfractionPct => "infraction_pct".into(),
            Metric::HitByLogPct => "hit_by_log_pct".into(),
            Metric::FdeM => "fde_m".into(),
            Metric::AteM => "ate_m".into(),
            Metric::CteM => "cte_m".into(),
            Metric::Jsd(f) => format!("jsd_{}", f.name()),
        }
    }

    /// The Markdown column header.
    pub fn header(self) -> String {
        match self {
            Metric::CollisionPct => "Col (%)".into(),
            Metric::OffroadPct => "Off (%)".into(),
            Metric::InfractionPct => "Any (%)".into(),
            Metric::HitByLogPct => "Hit by log (%)".into(),
            Metric::FdeM => "FDE (m)".into(),
            Metric::AteM => "ATE (m)".into(),
            Metric::CteM => "CTE (m)".into(),
            Metric::Jsd(f) => format!("JSD {}", f.name()),
        }
    }

    /// Needs the logs of real scenes: logged futures of the controlled agents, or (hit by the
    /// log) replayed vehicles. Real nominal scenes only.
    pub fn needs_log(self) -> bool {
        !matches!(
            self,
            Metric::CollisionPct | Metric::OffroadPct | Metric::InfractionPct
        )
    }

    /// The metric on summed tallies; `None` where it has no samples.
    pub fn value(self, t: &SceneTally) -> Option<f64> {
        let ratio = |num: f64, den: f64| (den > 0.0).then(|| num / den);
        match self {
            Metric::CollisionPct => ratio(100.0 * t.collided, t.agents),
            Metric::OffroadPct => ratio(100.0 * t.offroad, t.agents),
            Metric::InfractionPct => ratio(100.0 * t.infracted, t.agents),
            Metric::HitByLogPct => ratio(100.0 * t.hit_by_log, t.agents),
            Metric::FdeM => ratio(t.fde_sum, t.fde_agents),
            Metric::AteM => ratio(t.ate_sum, t.fde_agents),
            Metric::CteM => ratio(t.cte_sum, t.fde_agents),
            Metric::Jsd(f) => {
                let k = Feature::ALL.iter().position(|g| *g == f)?;
                jensen_shannon(&t.simulated[k], &t.logged[k])
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn metrics_are_ratios_of_summed_tallies() {
        let mut a = SceneTally {
            agents: 4.0,
            collided: 1.0,
            offroad: 0.0,
            infracted: 1.0,
            fde_sum: 6.0,
            ate_sum: 2.0,
            cte_sum: 1.0,
            fde_agents: 3.0,
            ..SceneTally::default()
        };
        let b = SceneTally {
            agents: 6.0,
            collided: 0.0,
            offroad: 3.0,
            infracted: 3.0,
            fde_sum: 1.0,
            ate_sum: 2.0,
            cte_sum: 1.0,
            fde_agents: 1.0,
            ..SceneTally::default()
        };
        a.add_scaled(&b, 1.0);
        assert_eq!(Metric::CollisionPct.value(&a), Some(10.0));
        assert_eq!(Metric::OffroadPct.value(&a), Some(30.0));
        assert_eq!(Metric::InfractionPct.value(&a), Some(40.0));
        assert_eq!(Metric::FdeM.value(&a), Some(7.0 / 4.0));
        assert_eq!(Metric::AteM.value(&a), Some(1.0));
        assert_eq!(Metric::CteM.value(&a), Some(0.5));
        // No feature samples: no JSD.
        assert_eq!(Metric::Jsd(Feature::Speed).value(&a), None);
        assert_eq!(Metric::FdeM.value(&SceneTally::default()), None);
    }

    #[test]
    fn jsd_compares_simulated_with_logged_histograms() {
        let mut t = SceneTally::default();
        let k = 1; // speed
        t.simulated[k].add(10.0);
        t.logged[k].add(30.0);
        let jsd = Metric::Jsd(Feature::Speed).value(&t).unwrap();
        assert!((jsd - 2f64.ln()).abs() < 1e-12);
        t.simulated[k].add(30.0);
        t.logged[k].add(10.0);
        assert!(Metric::Jsd(Feature::Speed).value(&t).unwrap() < 1e-12);
    }

    #[test]
    fn keys_are_the_documented_ones() {
        let keys: Vec<String> = Metric::ALL.iter().map(|m| m.key()).collect();
        assert_eq!(
            keys,
            [
                "collision_pct",
                "offroad_pct",
                "infraction_pct",
                "hit_by_log_pct",
                "fde_m",
                "ate_m",
                "cte_m",
                "jsd_acc",
                "jsd_speed",
                "jsd_lat",
                "jsd_lead"
            ]
        );
    }
}
