//! The paper's headline (section 4.1): RTR cuts IL's long-tail collisions to a third or less
//! (12.13 -> 3.61 %) while keeping IL's nominal realism. One rule decides whether measured
//! numbers bear it out, so the example's printed verdict and the README's follow the same
//! definition.

use super::Estimate;

/// The measurements the headline rests on, for IL and RTR.
#[derive(Debug, Clone, Copy)]
pub struct HeadlineNumbers {
    pub il_longtail_collision_pct: Estimate,
    pub rtr_longtail_collision_pct: Estimate,
    pub il_nominal_fde_m: f64,
    pub rtr_nominal_fde_m: f64,
    pub rtr_nominal_offroad_pct: f64,
}

/// What the measurements say of the headline.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HeadlineVerdict {
    /// At most a third of IL's long-tail collisions at IL's realism.
    Holds,
    /// The cut is there, but RTR is less realistic than IL.
    CutWithoutRealism,
    /// Fewer collisions than IL beyond the intervals, but not a third.
    DirectionOnly,
    /// More collisions than IL beyond the intervals.
    Reversed,
    /// The intervals overlap.
    NotClear,
}

/// RTR keeps IL's realism when its nominal FDE is within this factor of IL's ...
pub const FDE_RATIO_BAR: f64 = 1.1;
/// ... and at most this share of its nominal agents leave the road (%).
pub const OFFROAD_BAR_PCT: f64 = 2.5;

impl HeadlineVerdict {
    pub fn of(n: &HeadlineNumbers) -> Self {
        let (il, rtr) = (n.il_longtail_collision_pct, n.rtr_longtail_collision_pct);
        let realism_kept = n.rtr_nominal_fde_m <= FDE_RATIO_BAR * n.il_nominal_fde_m
            && n.rtr_nominal_offroad_pct <= OFFROAD_BAR_PCT;
        if rtr.value <= il.value / 3.0 {
            if realism_kept {
                Self::Holds
            } else {
                Self::CutWithoutRealism
            }
        } else if rtr.value + rtr.ci < il.value - il.ci {
            Self::DirectionOnly
        } else if rtr.value - rtr.ci > il.value + il.ci {
            Self::Reversed
        } else {
            Self::NotClear
        }
    }

    /// Two or three words: "holds", "holds in direction only", "does not hold".
    pub fn summary(self) -> &'static str {
        match self {
            Self::Holds => "holds",
            Self::DirectionOnly => "holds in direction only",
            Self::CutWithoutRealism | Self::Reversed | Self::NotClear => "does not hold",
        }
    }

    /// The verdict with its reason, one sentence.
    pub fn sentence(self) -> &'static str {
        match self {
            Self::Holds => {
                "holds: RTR has at most a third of IL's long-tail collisions at IL's nominal \
                 realism (paper 3.61 vs 12.13 %)"
            }
            Self::CutWithoutRealism => {
                "does not hold here: RTR has at most a third of IL's long-tail collisions, but \
                 loses IL's nominal realism (FDE more than 1.1x IL's, or off-road above 2.5 %)"
            }
            Self::DirectionOnly => {
                "holds in direction only: RTR has fewer long-tail collisions than IL (intervals \
                 apart), but not a third of them as in the paper (3.61 vs 12.13 %)"
            }
            Self::Reversed => {
                "does not hold here: RTR has more long-tail collisions than IL (intervals \
                 apart); the paper has 3.61 vs 12.13 %"
            }
            Self::NotClear => {
                "does not hold here: RTR's long-tail collisions are not clearly below IL's \
                 (bootstrap intervals overlap); the paper has 3.61 vs 12.13 %"
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn numbers(rtr_col: f64, rtr_ci: f64, rtr_fde: f64, rtr_off: f64) -> HeadlineNumbers {
        HeadlineNumbers {
            il_longtail_collision_pct: Estimate {
                value: 30.0,
                ci: 2.0,
            },
            rtr_longtail_collision_pct: Estimate {
                value: rtr_col,
                ci: rtr_ci,
            },
            il_nominal_fde_m: 1.3,
            rtr_nominal_fde_m: rtr_fde,
            rtr_nominal_offroad_pct: rtr_off,
        }
    }

    #[test]
    fn each_verdict_at_its_boundary() {
        let of = |n| HeadlineVerdict::of(&n);
        assert_eq!(of(numbers(10.0, 1.0, 1.43, 2.5)), HeadlineVerdict::Holds);
        // A hair past each realism bar, and past the third.
        assert_eq!(
            of(numbers(10.0, 1.0, 1.44, 2.5)),
            HeadlineVerdict::CutWithoutRealism
        );
        assert_eq!(
            of(numbers(10.0, 1.0, 1.3, 2.6)),
            HeadlineVerdict::CutWithoutRealism
        );
        assert_eq!(
            of(numbers(10.1, 1.0, 1.3, 0.0)),
            HeadlineVerdict::DirectionOnly
        );
        // Intervals touching are not apart.
        assert_eq!(of(numbers(26.0, 2.0, 1.3, 0.0)), HeadlineVerdict::NotClear);
        assert_eq!(of(numbers(34.5, 2.0, 1.3, 0.0)), HeadlineVerdict::Reversed);
        assert_eq!(HeadlineVerdict::Holds.summary(), "holds");
        assert!(
            HeadlineVerdict::Reversed
                .sentence()
                .starts_with("does not hold")
        );
    }
}
