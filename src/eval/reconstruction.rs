//! Reconstruction geometry (paper appendix "Metrics"): the final displacement error, and the
//! simulated position projected onto the logged trajectory, split into the along-track error
//! (ATE: how far ahead or behind, i.e. speed) and the cross-track error (CTE: how far to the
//! side).

/// Euclidean distance between two positions.
pub fn displacement(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// A logged trajectory as a polyline with arc length, for projecting simulated positions.
#[derive(Debug, Clone)]
pub struct LoggedPath {
    points: Vec<[f64; 2]>,
    /// Arc length at each point.
    s: Vec<f64>,
    /// Direction used when the logged vehicle did not move (a single distinct point).
    heading: f64,
}

/// Points closer than this are one point (a standing vehicle's jitter adds no direction).
const MIN_SEGMENT_M: f64 = 1e-3;

impl LoggedPath {
    /// `points` in time order; `heading` is the logged heading, used only when the vehicle did
    /// not move. `None` for no points.
    pub fn new(points: &[[f64; 2]], heading: f64) -> Option<Self> {
        let mut kept: Vec<[f64; 2]> = Vec::with_capacity(points.len());
        let mut s = Vec::with_capacity(points.len());
        for &p in points {
            match kept.last() {
                None => {
                    kept.push(p);
                    s.push(0.0);
                }
                Some(&last) => {
                    let d = displacement(last, p);
                    if d >= MIN_SEGMENT_M {
                        s.push(s.last().copied().unwrap_or(0.0) + d);
                        kept.push(p);
                    }
                }
            }
        }
        (!kept.is_empty()).then_some(Self {
            points: kept,
            s,
            heading,
        })
    }

    /// Arc length and signed lateral offset (left positive) of `p` projected onto the path.
    /// The first and last segments extend as rays, so a simulated vehicle ahead of the log's
    /// end (or behind its start) keeps a growing along-track coordinate.
    pub fn project(&self, p: [f64; 2]) -> (f64, f64) {
        if self.points.len() == 1 {
            let (sin, cos) = self.heading.sin_cos();
            let d = [p[0] - self.points[0][0], p[1] - self.points[0][1]];
            return (d[0] * cos + d[1] * sin, -d[0] * sin + d[1] * cos);
        }
        let last = self.points.len() - 2;
        let mut best = (f64::INFINITY, 0.0, 0.0);
        for (k, w) in self.points.windows(2).enumerate() {
            let (a, b) = (w[0], w[1]);
            let ab = [b[0] - a[0], b[1] - a[1]];
            let len = ab[0].hypot(ab[1]);
            let ap = [p[0] - a[0], p[1] - a[1]];
            let mut u = (ap[0] * ab[0] + ap[1] * ab[1]) / (len * len);
            if k > 0 {
                u = u.max(0.0);
            }
            if k < last {
                u = u.min(1.0);
            }
            let foot = [a[0] + u * ab[0], a[1] + u * ab[1]];
            let distance = displacement(foot, p);
            if distance < best.0 {
                let side = (ab[0] * ap[1] - ab[1] * ap[0]).signum();
                best = (distance, self.s[k] + u * len, side * distance);
            }
        }
        (best.1, best.2)
    }

    /// ATE and CTE (both >= 0) of the simulated position `sim` against the logged position
    /// `logged` at the same time.
    pub fn errors(&self, sim: [f64; 2], logged: [f64; 2]) -> (f64, f64) {
        let (s_sim, lateral) = self.project(sim);
        let (s_log, _) = self.project(logged);
        ((s_sim - s_log).abs(), lateral.abs())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn assert_close(a: f64, b: f64) {
        assert!((a - b).abs() < 1e-9, "{a} vs {b}");
    }

    #[test]
    fn straight_path_splits_into_along_and_cross_track() {
        let path = LoggedPath::new(&[[0.0, 0.0], [10.0, 0.0], [20.0, 0.0]], 0.0).unwrap();
        // Logged at x = 10; simulated 3 m behind and 2 m to the right.
        let (ate, cte) = path.errors([7.0, -2.0], [10.0, 0.0]);
        assert_close(ate, 3.0);
        assert_close(cte, 2.0);
        assert_close(displacement([7.0, -2.0], [10.0, 0.0]), 13f64.sqrt());
        // Beyond the last point the last segment extends: 5 m ahead stays 5 m ahead.
        let (ate, cte) = path.errors([25.0, 1.0], [20.0, 0.0]);
        assert_close(ate, 5.0);
        assert_close(cte, 1.0);
        let (s, lateral) = path.project([-4.0, 0.5]);
        assert_close(s, -4.0);
        assert_close(lateral, 0.5);
    }

    #[test]
    fn bent_path_measures_along_the_arc() {
        // An L: 10 m east, then 10 m north. Logged at the corner's end (s = 15).
        let path = LoggedPath::new(&[[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]], 0.0).unwrap();
        let (ate, cte) = path.errors([9.0, 5.0], [10.0, 5.0]);
        assert_close(ate, 0.0);
        assert_close(cte, 1.0);
        // On the first leg at x = 4: 11 m of arc behind.
        let (ate, cte) = path.errors([4.0, 0.0], [10.0, 5.0]);
        assert_close(ate, 11.0);
        assert_close(cte, 0.0);
    }

    #[test]
    fn standing_vehicle_uses_its_heading() {
        let heading = std::f64::consts::FRAC_PI_2;
        let path = LoggedPath::new(&[[1.0, 1.0], [1.0, 1.0 + 1e-5]], heading).unwrap();
        let (ate, cte) = path.errors([2.0, 4.0], [1.0, 1.0]);
        assert_close(ate, 3.0);
        assert_close(cte, 1.0);
        assert!(LoggedPath::new(&[], 0.0).is_none());
    }
}
