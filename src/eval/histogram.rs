//! Fixed-bin histograms and the Jensen-Shannon divergence between two of them (nats), the
//! paper's distributional realism metric. Values outside the range fall into the end bins, so
//! every sample counts and a policy cannot hide extreme behaviour beyond the range.

use serde::{Deserialize, Serialize};

/// Equal-width bins over `[lo, hi]`, with counts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Histogram {
    pub lo: f64,
    pub hi: f64,
    pub counts: Vec<f64>,
}

impl Histogram {
    pub fn new(lo: f64, hi: f64, bins: usize) -> Self {
        assert!(hi > lo && bins > 0, "histogram range [{lo}, {hi}] x {bins}");
        Self {
            lo,
            hi,
            counts: vec![0.0; bins],
        }
    }

    pub fn bins(&self) -> usize {
        self.counts.len()
    }

    /// The bin of `x` (clamped into the end bins); `None` for NaN.
    pub fn bin(&self, x: f64) -> Option<usize> {
        if x.is_nan() {
            return None;
        }
        let unit = (x - self.lo) / (self.hi - self.lo);
        let k = (unit * self.bins() as f64).floor();
        Some(k.clamp(0.0, (self.bins() - 1) as f64) as usize)
    }

    pub fn add(&mut self, x: f64) {
        if let Some(k) = self.bin(x) {
            self.counts[k] += 1.0;
        }
    }

    pub fn total(&self) -> f64 {
        self.counts.iter().sum()
    }

    /// Adds `other`'s counts (same bins) `times` times (bootstrap resamples add a scene's
    /// histogram once per draw).
    pub fn add_counts(&mut self, other: &Histogram, times: f64) {
        debug_assert_eq!(self.bins(), other.bins());
        for (a, b) in self.counts.iter_mut().zip(&other.counts) {
            *a += times * b;
        }
    }

    /// Lower edge of bin `k`.
    pub fn edge(&self, k: usize) -> f64 {
        self.lo + (self.hi - self.lo) * k as f64 / self.bins() as f64
    }

    /// Counts normalised to probabilities; `None` when empty.
    pub fn probabilities(&self) -> Option<Vec<f64>> {
        let total = self.total();
        (total > 0.0).then(|| self.counts.iter().map(|c| c / total).collect())
    }
}

/// JSD(P || Q) = (KL(P || M) + KL(Q || M)) / 2 with M = (P + Q) / 2, in nats (at most ln 2).
/// `None` when either histogram is empty (no samples: the divergence is undefined).
pub fn jensen_shannon(p: &Histogram, q: &Histogram) -> Option<f64> {
    let (p, q) = (p.probabilities()?, q.probabilities()?);
    // 0 ln 0 = 0: a bin empty in one distribution contributes only through the other.
    let kl_to_mean = |a: f64, m: f64| if a > 0.0 { a * (a / m).ln() } else { 0.0 };
    let jsd = p
        .iter()
        .zip(&q)
        .map(|(&a, &b)| {
            let m = 0.5 * (a + b);
            0.5 * (kl_to_mean(a, m) + kl_to_mean(b, m))
        })
        .sum::<f64>();
    Some(jsd.max(0.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn from_counts(counts: &[f64]) -> Histogram {
        let mut h = Histogram::new(0.0, counts.len() as f64, counts.len());
        h.counts = counts.to_vec();
        h
    }

    #[test]
    fn identical_histograms_have_zero_divergence() {
        let p = from_counts(&[1.0, 2.0, 3.0]);
        let q = from_counts(&[2.0, 4.0, 6.0]);
        assert!(jensen_shannon(&p, &q).unwrap().abs() < 1e-12);
    }

    #[test]
    fn disjoint_histograms_reach_ln_2() {
        let p = from_counts(&[1.0, 0.0]);
        let q = from_counts(&[0.0, 5.0]);
        assert!((jensen_shannon(&p, &q).unwrap() - 2f64.ln()).abs() < 1e-12);
    }

    #[test]
    fn hand_computed_case() {
        // P = (1/2, 1/2), Q = (1, 0): M = (3/4, 1/4).
        // KL(P||M) = 1/2 ln(2/3) + 1/2 ln 2, KL(Q||M) = ln(4/3).
        let p = from_counts(&[1.0, 1.0]);
        let q = from_counts(&[3.0, 0.0]);
        let expected = 0.5 * (0.5 * (2.0f64 / 3.0).ln() + 0.5 * 2f64.ln() + (4.0f64 / 3.0).ln());
        let jsd = jensen_shannon(&p, &q).unwrap();
        assert!((jsd - expected).abs() < 1e-12, "{jsd} vs {expected}");
        assert!(
            (jsd - jensen_shannon(&q, &p).unwrap()).abs() < 1e-15,
            "symmetric"
        );
    }

    #[test]
    fn empty_histogram_has_no_divergence() {
        assert!(jensen_shannon(&from_counts(&[0.0, 0.0]), &from_counts(&[1.0, 0.0])).is_none());
    }

    #[test]
    fn out_of_range_values_land_in_the_end_bins() {
        let mut h = Histogram::new(-1.0, 1.0, 4);
        for x in [-5.0, -1.0, -0.2, 0.0, 0.99, 1.0, 7.0, f64::NAN] {
            h.add(x);
        }
        assert_eq!(h.counts, vec![2.0, 1.0, 1.0, 3.0]);
        assert_eq!(h.edge(2), 0.0);
    }
}
