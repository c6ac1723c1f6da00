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

    /// Radius of the circle around the centre that contains the box (broad phase).
    pub fn bounding_radius(&self) -> f64 {
        0.5 * self.length.hypot(self.width)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::uniform;
    use std::f64::consts::PI;

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
