//! A realism score in the style of the Waymo Open Sim Agents Challenge (WOSAC), beyond the
//! paper, so results can be read against that literature: for every logged agent, K sampled
//! rollouts from the same initial state give a histogram of each feature (pooled over the
//! agent's simulated steps); the logged values are scored by their likelihood under it. The
//! score is the geometric mean likelihood per agent and feature, averaged within components
//! (kinematic: acceleration, speed; interactive: lead gap; map: lane deviation) and then over
//! components. 1 means every logged value falls in a bin every sample visits; lower means
//! the policy's distribution misses what the human did.
//!
//! Differences from WOSAC, stated: the features are this crate's four (WOSAC has nine, e.g.
//! angular speed, time to collision, distance to road edge), histograms pool time steps, and
//! the components are equally weighted.

use serde::{Deserialize, Serialize};

use super::bootstrap::Additive;
use super::features::Feature;
use super::histogram::Histogram;

/// Pseudo-count added to every bin, so a logged value no sample reached has a small, finite
/// likelihood (WOSAC's additive smoothing).
pub const SMOOTHING: f64 = 0.1;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Component {
    Kinematic,
    Interactive,
    Map,
}

impl Component {
    pub const ALL: [Component; 3] = [Component::Kinematic, Component::Interactive, Component::Map];

    pub fn of(feature: Feature) -> Component {
        match feature {
            Feature::Acceleration | Feature::Speed => Component::Kinematic,
            Feature::LeadDistance => Component::Interactive,
            Feature::LaneDeviation => Component::Map,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Component::Kinematic => "kinematic",
            Component::Interactive => "interactive",
            Component::Map => "map",
        }
    }
}

/// Per-scene sums of per-agent likelihoods: `[kinematic, interactive, map, composite]`, each
/// with the number of agents that had it.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct RealismTally {
    pub sums: [f64; 4],
    pub counts: [f64; 4],
}

impl Additive for RealismTally {
    fn zero_like(&self) -> Self {
        Self::default()
    }
    fn add_scaled(&mut self, o: &Self, t: f64) {
        for k in 0..4 {
            self.sums[k] += t * o.sums[k];
            self.counts[k] += t * o.counts[k];
        }
    }
}

impl RealismTally {
    /// Index 0..3: a component; 3: the composite score.
    pub fn score(&self, index: usize) -> Option<f64> {
        (self.counts[index] > 0.0).then(|| self.sums[index] / self.counts[index])
    }
}

/// Geometric mean likelihood of `logged` values under the smoothed histogram of `samples`;
/// `None` without either.
pub fn likelihood(feature: Feature, samples: &[f64], logged: &[f64]) -> Option<f64> {
    if samples.is_empty() || logged.is_empty() {
        return None;
    }
    let mut h: Histogram = feature.histogram();
    for &x in samples {
        h.add(x);
    }
    let total = h.total() + SMOOTHING * h.bins() as f64;
    let mean_log = logged
        .iter()
        .filter_map(|&x| h.bin(x))
        .map(|k| ((h.counts[k] + SMOOTHING) / total).ln())
        .sum::<f64>()
        / logged.len() as f64;
    Some(mean_log.exp())
}

/// One agent's contribution: per feature its sampled values (all rollouts, all steps) and its
/// logged values.
pub fn agent_tally(samples: &[Vec<f64>; 4], logged: &[Vec<f64>; 4]) -> RealismTally {
    let mut per_component: [Vec<f64>; 3] = Default::default();
    for (k, f) in Feature::ALL.into_iter().enumerate() {
        if let Some(l) = likelihood(f, &samples[k], &logged[k]) {
            let c = Component::ALL
                .iter()
                .position(|&c| c == Component::of(f))
                .unwrap_or(0);
            per_component[c].push(l);
        }
    }
    let mut tally = RealismTally::default();
    let mut components = Vec::new();
    for (c, values) in per_component.iter().enumerate() {
        if !values.is_empty() {
            let mean = values.iter().sum::<f64>() / values.len() as f64;
            tally.sums[c] = mean;
            tally.counts[c] = 1.0;
            components.push(mean);
        }
    }
    if !components.is_empty() {
        tally.sums[3] = components.iter().sum::<f64>() / components.len() as f64;
        tally.counts[3] = 1.0;
    }
    tally
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn likelihood_is_the_smoothed_bin_probability() {
        // Speed bins are 1 m/s wide over [0, 45]: 45 bins.
        let samples = [10.2, 10.4, 10.6, 20.5];
        let total = 4.0 + SMOOTHING * 45.0;
        let p10 = (3.0 + SMOOTHING) / total;
        let p30 = SMOOTHING / total;
        let l = likelihood(Feature::Speed, &samples, &[10.5]).unwrap();
        assert!((l - p10).abs() < 1e-12);
        // Geometric mean over logged values.
        let l = likelihood(Feature::Speed, &samples, &[10.5, 30.5]).unwrap();
        assert!((l - (p10 * p30).sqrt()).abs() < 1e-12);
        assert!(likelihood(Feature::Speed, &[], &[1.0]).is_none());
    }

    #[test]
    fn a_policy_that_matches_the_log_scores_higher() {
        let logged: [Vec<f64>; 4] = [vec![0.1; 8], vec![25.0; 8], vec![0.05; 8], vec![30.0; 8]];
        let close: [Vec<f64>; 4] = [
            vec![0.12; 32],
            vec![25.2; 32],
            vec![0.04; 32],
            vec![30.5; 32],
        ];
        let far: [Vec<f64>; 4] = [vec![-3.0; 32], vec![12.0; 32], vec![1.5; 32], vec![5.0; 32]];
        let (a, b) = (agent_tally(&close, &logged), agent_tally(&far, &logged));
        for k in 0..4 {
            assert!(a.score(k).unwrap() > 0.5, "{a:?}");
            assert!(b.score(k).unwrap() < 0.01, "{b:?}");
        }
        // No lead vehicle logged: the interactive component is absent, the rest averages.
        let mut no_lead = logged.clone();
        no_lead[3].clear();
        let t = agent_tally(&close, &no_lead);
        assert_eq!(t.counts, [1.0, 0.0, 1.0, 1.0]);
        assert!((t.sums[3] - 0.5 * (t.sums[0] + t.sums[2])).abs() < 1e-12);
    }
}
