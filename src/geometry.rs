//! Planar geometry shared by the map, the data sanity checks and the simulator:
//! oriented bounding boxes and their overlap test.
//!
//! The separating-axis test is written out here (rather than calling parry2d per pair) because
//! it is a dozen lines on two rectangles, allocation-free, and the same formula is what the
//! batched tensor version in the simulator computes; the tests cross-check it against parry2d.

/// Largest |heading| any reader accepts (rad): one turn plus slack for unwrapped angles.
/// Beyond it a heading is almost surely in degrees, and every loader refuses it as such.
pub const MAX_HEADING_RAD: f64 = 2.0 * std::f64::consts::PI + 0.01;

/// Wraps an angle to (-pi, pi].
pub fn wrap_angle(a: f64) -> f64 {
    let two_pi = std::f64::consts::TAU;
    let mut r = a.rem_euclid(two_pi);
    if r > std::f64::consts::PI {
        r -= two_pi;
    }
    r
}

/// A vehicle footprint: a rectangle centred at `center`, its long side along `heading`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrientedBox {
    pub center: [f64; 2],
    /// Radians, counter-clockwise from the x axis.
    pub heading: f64,
    /// Extent along the heading (m).
    pub length: f64,
    /// Extent across the heading (m).
    pub width: f64,
}

impl OrientedBox {
    pub fn new(center: [f64; 2], heading: f64, length: f64, width: f64) -> Self {
        Self {
            center,
            heading,
            length,
            width,
        }
    }

    /// Unit vectors along the length and the width.
    fn axes(&self) -> ([f64; 2], [f64; 2]) {
        let (s, c) = self.heading.sin_cos();
        ([c, s], [-s, c])
    }

    /// Corners counter-clockwise, starting front-right.
    pub fn corners(&self) -> [[f64; 2]; 4] {
        let (f, l) = self.axes();
        let (hl, hw) = (0.5 * self.length, 0.5 * self.width);
        let p = |a: f64, b: f64| {
            [
                self.center[0] + a * f[0] + b * l[0],
                self.center[1] + a * f[1] + b * l[1],
            ]
        };
        [p(hl, -hw), p(hl, hw), p(-hl, hw), p(-hl, -hw)]
    }

    /// Points along the outline, at most `spacing` apart (corners included). A box lies inside
    /// a region made of strips wider than `spacing` exactly when these points do, up to
    /// `spacing` of slack; this is how the map tests "fully on the road".
    pub fn outline_points(&self, spacing: f64) -> Vec<[f64; 2]> {
        self.outline(spacing).collect()
    }

    /// The points of [`Self::outline_points`], without allocating (hot path of the
    /// simulator's off-road test).
    pub fn outline(&self, spacing: f64) -> impl Iterator<Item = [f64; 2]> + use<> {
        let c = self.corners();
        let spacing = spacing.max(1e-3);
        (0..4).flat_map(move |i| {
            let (a, b) = (c[i], c[(i + 1) % 4]);
            let len = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
            let n = (len / spacing).ceil().max(1.0) as usize;
            (0..n).map(move |k| {
                let t = k as f64 / n as f64;
                [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]
            })
        })
    }

    /// Separating-axis test on the four face normals. Touching boxes (zero-area contact)
    /// do not count as overlapping.
    pub fn overlaps(&self, other: &OrientedBox) -> bool {
        let dx = other.center[0] - self.center[0];
        let dy = other.center[1] - self.center[1];
        let (f1, l1) = self.axes();
        let (f2, l2) = other.axes();
        let (a1, b1) = (0.5 * self.length, 0.5 * self.width);
        let (a2, b2) = (0.5 * other.length, 0.5 * other.width);
        let dot = |u: [f64; 2], v: [f64; 2]| u[0] * v[0] + u[1] * v[1];
        for axis in [f1, l1, f2, l2] {
            let r1 = a1 * dot(f1, axis).abs() + b1 * dot(l1, axis).abs();
            let r2 = a2 * dot(f2, axis).abs() + b2 * dot(l2, axis).abs();
            if dot([dx, dy], axis).abs() >= r1 + r2 {
                return false;
            }
        }
        true
    }

    /// Half the length of the box's projection on the unit vector `axis`.
    fn shadow(&self, axis: [f64; 2]) -> f64 {
        let (f, l) = self.axes();
        0.5 * self.length * (f[0] * axis[0] + f[1] * axis[1]).abs()
            + 0.5 * self.width * (l[0] * axis[0] + l[1] * axis[1]).abs()
    }

    /// Radius of the circle around the centre that contains the box (broad phase).
    pub fn bounding_radius(&self) -> f64 {
        0.5 * self.length.hypot(self.width)
    }
}

/// A footprint over one simulation step, from where it starts to where it ends. In between the
/// centre moves along the chord and the heading turns the shorter way at a constant rate.
///
/// Checking the ends of a step alone misses a car that passes through another within it: at
/// 0.5 s steps a car at 30 m/s moves 15 m, three car lengths, so a follower that does not brake
/// for a stopped car can be behind it at one step and past it at the next.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoxMotion {
    pub from: OrientedBox,
    pub to: OrientedBox,
}

impl BoxMotion {
    /// A box that does not move.
    pub fn still(at: OrientedBox) -> Self {
        Self { from: at, to: at }
    }

    /// Heading change over the step, the shorter way round.
    fn turn(&self) -> f64 {
        wrap_angle(self.to.heading - self.from.heading)
    }

    /// The footprint at fraction `s` of the step.
    pub fn at(&self, s: f64) -> OrientedBox {
        let lerp = |a: f64, b: f64| a + s * (b - a);
        OrientedBox {
            center: [
                lerp(self.from.center[0], self.to.center[0]),
                lerp(self.from.center[1], self.to.center[1]),
            ],
            heading: self.from.heading + s * self.turn(),
            ..self.from
        }
    }

    /// The first fraction of the step in [0, 1] at which the two footprints overlap, or `None`
    /// if they never do during it.
    ///
    /// Three stages, cheapest first: the swept bounding circles; a separating axis that holds
    /// at both ends with room for the turn in between (this settles cars in neighbouring lanes);
    /// then parry2d's nonlinear shape cast (conservative advancement) for what is left.
    pub fn first_contact(&self, other: &BoxMotion) -> Option<f64> {
        if !self.circles_meet(other) || self.separated_throughout(other) {
            return None;
        }
        if self.from.overlaps(&other.from) {
            return Some(0.0);
        }
        let hit = parry2d::query::cast_shapes_nonlinear(
            &self.rigid_motion(),
            &self.cuboid(),
            &other.rigid_motion(),
            &other.cuboid(),
            0.0,
            1.0,
            true,
        )
        .ok()
        .flatten()
        .map(|hit| hit.time_of_impact.clamp(0.0, 1.0));
        // The cast stops at a small tolerance; an overlap at the end counts whatever it said.
        hit.or_else(|| self.to.overlaps(&other.to).then_some(1.0))
    }

    /// The bounding circles come within reach of each other at some time of the step (the
    /// circles contain the boxes whatever the heading).
    fn circles_meet(&self, other: &BoxMotion) -> bool {
        let reach = self.from.bounding_radius() + other.from.bounding_radius();
        let start = [
            other.from.center[0] - self.from.center[0],
            other.from.center[1] - self.from.center[1],
        ];
        let motion = [
            (other.to.center[0] - other.from.center[0]) - (self.to.center[0] - self.from.center[0]),
            (other.to.center[1] - other.from.center[1]) - (self.to.center[1] - self.from.center[1]),
        ];
        let len2 = motion[0] * motion[0] + motion[1] * motion[1];
        let s = if len2 > 0.0 {
            (-(start[0] * motion[0] + start[1] * motion[1]) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (dx, dy) = (start[0] + s * motion[0], start[1] + s * motion[1]);
        dx * dx + dy * dy < reach * reach
    }

    /// Some face normal of either box at the start separates the two at both ends, on the same
    /// side, by more than the turns can close: centres move linearly along the axis and a box
    /// turning by d about its centre widens its shadow on any axis by at most its bounding
    /// radius times |d|.
    fn separated_throughout(&self, other: &BoxMotion) -> bool {
        let wobble = self.from.bounding_radius() * self.turn().abs()
            + other.from.bounding_radius() * other.turn().abs();
        let (f1, l1) = self.from.axes();
        let (f2, l2) = other.from.axes();
        [f1, l1, f2, l2].into_iter().any(|axis| {
            let along = |a: &OrientedBox, b: &OrientedBox| {
                (b.center[0] - a.center[0]) * axis[0] + (b.center[1] - a.center[1]) * axis[1]
            };
            let (d0, d1) = (along(&self.from, &other.from), along(&self.to, &other.to));
            let shadows = self.from.shadow(axis).max(self.to.shadow(axis))
                + other.from.shadow(axis).max(other.to.shadow(axis));
            d0 * d1 > 0.0 && d0.abs().min(d1.abs()) - shadows > wobble
        })
    }

    fn rigid_motion(&self) -> parry2d::query::NonlinearRigidMotion {
        use parry2d::math::{Pose, Vector};
        parry2d::query::NonlinearRigidMotion::new(
            Pose::new(
                Vector::new(self.from.center[0], self.from.center[1]),
                self.from.heading,
            ),
            Vector::ZERO,
            Vector::new(
                self.to.center[0] - self.from.center[0],
                self.to.center[1] - self.from.center[1],
            ),
            self.turn(),
        )
    }

    fn cuboid(&self) -> parry2d::shape::Cuboid {
        parry2d::shape::Cuboid::new(parry2d::math::Vector::new(
            0.5 * self.from.length,
            0.5 * self.from.width,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::uniform;
    use std::f64::consts::PI;

    /// A car at 30 m/s (15 m per step) closing on a stopped one is behind it at the start of
    /// the step and past it at the end: the ends do not overlap, the motion does, and it first
    /// touches when its nose reaches the other's tail.
    #[test]
    fn a_car_passing_through_another_within_a_step_collides() {
        let car = |x: f64| OrientedBox::new([x, 0.0], 0.0, 4.6, 1.9);
        let follower = BoxMotion {
            from: car(0.0),
            to: car(15.0),
        };
        let stopped = BoxMotion::still(car(10.0));
        assert!(!follower.from.overlaps(&stopped.from) && !follower.to.overlaps(&stopped.to));
        let s = follower
            .first_contact(&stopped)
            .expect("contact within the step");
        assert!((s - (10.0 - 4.6) / 15.0).abs() < 1e-3, "{s}");
        // Symmetric, and one lane over (3.5 m) nothing touches.
        let s2 = stopped.first_contact(&follower).expect("symmetric");
        assert!((s - s2).abs() < 1e-3);
        let beside = BoxMotion::still(OrientedBox::new([10.0, 3.5], 0.0, 4.6, 1.9));
        assert_eq!(follower.first_contact(&beside), None);
    }

    /// On random close motions with turns, `first_contact` agrees with the overlap test
    /// sampled finely along the step: it misses no contact the samples see, and where both
    /// see one it finds the same first time.
    #[test]
    fn first_contact_agrees_with_finely_sampled_overlaps() {
        let mut rng = 17u64;
        let mut draw = |lo: f64, hi: f64| uniform(&mut rng, lo, hi);
        let samples = 4000;
        let (mut contacts, mut grazes) = (0, 0);
        for case in 0..600 {
            let motion = |draw: &mut dyn FnMut(f64, f64) -> f64| {
                let from = OrientedBox::new(
                    [draw(-10.0, 10.0), draw(-4.0, 4.0)],
                    draw(-PI, PI),
                    draw(3.5, 12.0),
                    draw(1.5, 2.6),
                );
                let to = OrientedBox {
                    center: [
                        from.center[0] + draw(-18.0, 18.0),
                        from.center[1] + draw(-3.0, 3.0),
                    ],
                    heading: from.heading + draw(-0.4, 0.4),
                    ..from
                };
                BoxMotion { from, to }
            };
            let (a, b) = (motion(&mut draw), motion(&mut draw));
            let sampled = (0..=samples)
                .map(|k| k as f64 / samples as f64)
                .find(|&s| a.at(s).overlaps(&b.at(s)));
            match (sampled, a.first_contact(&b)) {
                (Some(s), Some(t)) => {
                    contacts += 1;
                    assert!((s - t).abs() < 2e-3, "case {case}: sampled {s}, cast {t}");
                }
                (Some(s), None) => panic!("case {case}: missed the contact at {s}"),
                (None, Some(_)) => grazes += 1,
                (None, None) => {}
            }
        }
        assert!(contacts > 100, "{contacts} contacts");
        assert!(grazes <= 3, "{grazes} contacts no sample saw");
    }

    #[test]
    fn wrap_angle_lands_in_half_open_interval() {
        assert!((wrap_angle(3.0 * PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(-PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(0.25 - 4.0 * PI) - 0.25).abs() < 1e-12);
    }

    #[test]
    fn corners_of_rotated_box() {
        let b = OrientedBox::new([1.0, 2.0], PI / 2.0, 4.0, 2.0);
        let c = b.corners();
        // front-right of a box facing +y is at +x side, +y front.
        assert!((c[0][0] - 2.0).abs() < 1e-12 && (c[0][1] - 4.0).abs() < 1e-12);
        assert!((c[2][0] - 0.0).abs() < 1e-12 && (c[2][1] - 0.0).abs() < 1e-12);
    }

    #[test]
    fn overlap_known_cases() {
        let a = OrientedBox::new([0.0, 0.0], 0.0, 4.0, 2.0);
        assert!(a.overlaps(&OrientedBox::new([3.9, 0.0], 0.0, 4.0, 2.0)));
        assert!(!a.overlaps(&OrientedBox::new([4.1, 0.0], 0.0, 4.0, 2.0)));
        // Rotated 45 degrees: the corner reaches sqrt(2)*... past the axis-aligned gap.
        let r = OrientedBox::new([3.2, 0.0], PI / 4.0, 2.0, 2.0);
        assert!(a.overlaps(&r)); // corner at 3.2 - sqrt(2) = 1.79 < 2
        let r = OrientedBox::new([3.5, 0.0], PI / 4.0, 2.0, 2.0);
        assert!(!a.overlaps(&r)); // 3.5 - 1.414 = 2.086 > 2
    }

    #[test]
    fn overlap_agrees_with_parry2d_on_random_boxes() {
        use parry2d::math::{Pose, Vector};
        use parry2d::query::intersection_test;
        use parry2d::shape::Cuboid;
        let mut rng = 7u64;
        let (mut hits, mut misses) = (0, 0);
        for _ in 0..20_000 {
            let mut random_box = || {
                OrientedBox::new(
                    [uniform(&mut rng, -8.0, 8.0), uniform(&mut rng, -8.0, 8.0)],
                    uniform(&mut rng, -PI, PI),
                    uniform(&mut rng, 1.0, 16.0),
                    uniform(&mut rng, 0.5, 3.0),
                )
            };
            let (a, b) = (random_box(), random_box());
            let parry = |o: &OrientedBox| {
                (
                    Pose::new(Vector::new(o.center[0], o.center[1]), o.heading),
                    Cuboid::new(Vector::new(0.5 * o.length, 0.5 * o.width)),
                )
            };
            let ((pa, ca), (pb, cb)) = (parry(&a), parry(&b));
            let expected = intersection_test(&pa, &ca, &pb, &cb)
                .expect("cuboid pairs are supported")
                .intersecting;
            assert_eq!(a.overlaps(&b), expected, "{a:?} {b:?}");
            if expected { hits += 1 } else { misses += 1 }
        }
        // Both outcomes are exercised.
        assert!(
            hits > 2_000 && misses > 2_000,
            "{hits} hits, {misses} misses"
        );
    }

    #[test]
    fn outline_points_are_dense_and_on_the_outline() {
        let b = OrientedBox::new([0.0, 0.0], 0.3, 4.0, 2.0);
        let pts = b.outline_points(0.5);
        assert!(pts.len() >= 12);
        for w in pts.windows(2) {
            let d = ((w[1][0] - w[0][0]).powi(2) + (w[1][1] - w[0][1]).powi(2)).sqrt();
            assert!(d <= 0.5 + 1e-9);
        }
    }
}
