//! Bootstrap over scenes (the paper's +- uncertainty): scenes are resampled with replacement
//! and each metric is recomputed on the resampled totals. Metrics are ratios of per-scene sums
//! (and JSDs of summed histograms), so a resample is a weighted sum of per-scene tallies and
//! every metric of one resample comes from the same draw.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// A per-scene quantity that adds up across scenes.
pub trait Additive: Clone {
    /// The empty tally of the same shape as `self`.
    fn zero_like(&self) -> Self;
    /// `self += times * other`.
    fn add_scaled(&mut self, other: &Self, times: f64);
}

/// A metric with the half-width of its 95 % percentile bootstrap interval.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Estimate {
    pub value: f64,
    pub ci: f64,
}

/// The sum of all scenes' tallies; `None` when there are none.
pub fn total<A: Additive>(scenes: &[A]) -> Option<A> {
    let mut sum = scenes.first()?.zero_like();
    for s in scenes {
        sum.add_scaled(s, 1.0);
    }
    Some(sum)
}

/// `resamples` totals, each over `scenes.len()` scenes drawn with replacement (seeded).
pub fn resampled_totals<A: Additive>(scenes: &[A], resamples: usize, seed: u64) -> Vec<A> {
    let Some(first) = scenes.first() else {
        return Vec::new();
    };
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = scenes.len();
    (0..resamples)
        .map(|_| {
            let mut times = vec![0u32; n];
            for _ in 0..n {
                times[rng.random_range(0..n)] += 1;
            }
            let mut sum = first.zero_like();
            for (scene, &k) in scenes.iter().zip(&times) {
                if k > 0 {
                    sum.add_scaled(scene, k as f64);
                }
            }
            sum
        })
        .collect()
}

/// The statistic on the full total and the half-width of the 2.5-97.5 % percentile interval
/// of its resampled values; `None` when the statistic is undefined on the full total.
pub fn estimate<A>(
    full: &A,
    resampled: &[A],
    statistic: impl Fn(&A) -> Option<f64>,
) -> Option<Estimate> {
    let value = statistic(full)?;
    let mut values: Vec<f64> = resampled.iter().filter_map(&statistic).collect();
    if values.len() < 2 {
        return Some(Estimate { value, ci: 0.0 });
    }
    values.sort_by(f64::total_cmp);
    let q = |p: f64| {
        // Linear interpolation between order statistics.
        let x = p * (values.len() - 1) as f64;
        let (i, f) = (x.floor() as usize, x.fract());
        values[i] + f * (values[(i + 1).min(values.len() - 1)] - values[i])
    };
    Some(Estimate {
        value,
        ci: 0.5 * (q(0.975) - q(0.025)),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_distr::{Distribution, StandardNormal};

    /// A sum and a count, whose ratio is the mean.
    #[derive(Clone)]
    struct Mean(f64, f64);

    impl Additive for Mean {
        fn zero_like(&self) -> Self {
            Mean(0.0, 0.0)
        }
        fn add_scaled(&mut self, o: &Self, t: f64) {
            self.0 += t * o.0;
            self.1 += t * o.1;
        }
    }

    fn mean(m: &Mean) -> Option<f64> {
        (m.1 > 0.0).then(|| m.0 / m.1)
    }

    #[test]
    fn interval_of_a_mean_matches_the_normal_theory() {
        // 400 draws of N(0, 1): the 95 % half-width of the mean is 1.96 / sqrt(400) = 0.098.
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let scenes: Vec<Mean> = (0..400)
            .map(|_| Mean(StandardNormal.sample(&mut rng), 1.0))
            .collect();
        let full = total(&scenes).unwrap();
        let e = estimate(&full, &resampled_totals(&scenes, 2000, 9), mean).unwrap();
        let sample_mean = scenes.iter().map(|m| m.0).sum::<f64>() / 400.0;
        assert!((e.value - sample_mean).abs() < 1e-12);
        assert!((e.ci - 0.098).abs() < 0.015, "half-width {}", e.ci);
    }

    #[test]
    fn constant_scenes_have_no_uncertainty() {
        let scenes = vec![Mean(2.0, 1.0); 30];
        let full = total(&scenes).unwrap();
        let e = estimate(&full, &resampled_totals(&scenes, 200, 1), mean).unwrap();
        assert_eq!(
            e,
            Estimate {
                value: 2.0,
                ci: 0.0
            }
        );
    }

    #[test]
    fn same_seed_same_interval_and_empty_input() {
        let scenes: Vec<Mean> = (0..20).map(|i| Mean(i as f64, 1.0)).collect();
        let full = total(&scenes).unwrap();
        let a = estimate(&full, &resampled_totals(&scenes, 100, 5), mean);
        let b = estimate(&full, &resampled_totals(&scenes, 100, 5), mean);
        assert_eq!(a, b);
        assert!(total::<Mean>(&[]).is_none());
        assert!(resampled_totals::<Mean>(&[], 10, 0).is_empty());
    }
}
