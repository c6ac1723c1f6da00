//! Evaluates a road's reference line: position, heading and curvature at arc length `s`.
//!
//! Line and arc are closed form. Spiral, poly3 and paramPoly3 have no elementary closed form, so
//! we integrate numerically with composite 8-point Gauss-Legendre quadrature on short pieces
//! (spiral: at most 20 m and 0.25 rad of turn; poly3: 10 m of u; paramPoly3: 1/16 of the
//! parameter range); on such pieces the rule is exact to rounding for these smooth integrands.
//! The tests check the clothoid against the closed Fresnel value and a fine Simpson
//! integration to better than 1e-6 m. Poly3 and paramPoly3 are parametrised by true arc length:
//! the arc-length integral is inverted by Newton's method to 1e-10 m.

use super::opendrive::{Geometry, GeometryKind, PRange, Road, record_at};

/// A point of the reference line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefPoint {
    pub x: f64,
    pub y: f64,
    /// Radians, counter-clockwise from +x.
    pub hdg: f64,
    /// Signed (1/m), positive turning left.
    pub curvature: f64,
}

impl RefPoint {
    /// The point `t` metres to the left of the reference line.
    pub fn offset(&self, t: f64) -> [f64; 2] {
        let (s, c) = self.hdg.sin_cos();
        [self.x - t * s, self.y + t * c]
    }
}

const GL_X: [f64; 4] = [
    0.183_434_642_495_649_8,
    0.525_532_409_916_329,
    0.796_666_477_413_626_7,
    0.960_289_856_497_536_3,
];
const GL_W: [f64; 4] = [
    0.362_683_783_378_362,
    0.313_706_645_877_887_3,
    0.222_381_034_453_374_5,
    0.101_228_536_290_376_3,
];

/// Composite 8-point Gauss-Legendre over [a, b] in `n` equal pieces, for a vector integrand.
fn integrate2(a: f64, b: f64, n: usize, f: impl Fn(f64) -> [f64; 2]) -> [f64; 2] {
    // The cap bounds the work on absurd input (kilometre-long tight spirals); real roads
    // need a few dozen pieces.
    let n = n.clamp(1, 100_000);
    let h = (b - a) / n as f64;
    let mut sum = [0.0; 2];
    for k in 0..n {
        let mid = a + (k as f64 + 0.5) * h;
        for (x, w) in GL_X.iter().zip(GL_W) {
            for sign in [-1.0, 1.0] {
                let v = f(mid + sign * x * 0.5 * h);
                sum[0] += w * v[0];
                sum[1] += w * v[1];
            }
        }
    }
    [sum[0] * 0.5 * h, sum[1] * 0.5 * h]
}

fn integrate(a: f64, b: f64, n: usize, f: impl Fn(f64) -> f64) -> f64 {
    integrate2(a, b, n, |t| [f(t), 0.0])[0]
}

/// sin(x)/x, accurate near 0.
fn sinc(x: f64) -> f64 {
    if x.abs() < 1e-4 {
        1.0 - x * x / 6.0
    } else {
        x.sin() / x
    }
}

/// Length (m) of the curve (u(p), v(p)) of a `<paramPoly3>` over its whole range of p.
pub fn param_poly3_length(u: &[f64; 4], v: &[f64; 4], p_range: PRange, length: f64) -> f64 {
    let p_max = match p_range {
        PRange::ArcLength => length,
        PRange::Normalized => 1.0,
    };
    integrate(0.0, p_max, 64, |p| cubic(u, p).1.hypot(cubic(v, p).1))
}

fn cubic(c: &[f64; 4], p: f64) -> (f64, f64, f64) {
    let v = c[0] + p * (c[1] + p * (c[2] + p * c[3]));
    let d1 = c[1] + p * (2.0 * c[2] + p * 3.0 * c[3]);
    let d2 = 2.0 * c[2] + 6.0 * c[3] * p;
    (v, d1, d2)
}

/// Finds the parameter at which the arc length from 0 equals `ds` (Newton's method).
fn invert_arc_length(
    ds: f64,
    guess: f64,
    arc_len: impl Fn(f64) -> f64,
    speed: impl Fn(f64) -> f64,
) -> f64 {
    let mut p = guess;
    for _ in 0..50 {
        let v = speed(p);
        if v < 1e-12 {
            break;
        }
        let step = (arc_len(p) - ds) / v;
        p -= step;
        if (step * v).abs() < 1e-10 {
            break;
        }
    }
    p
}

impl Geometry {
    /// Pose at `ds` metres from the start of this geometry (extrapolates past its ends).
    pub fn eval(&self, ds: f64) -> RefPoint {
        let (sh, ch) = self.hdg.sin_cos();
        // Local (u, v) in the start frame -> global.
        let place = |u: f64, v: f64, local_hdg: f64, curvature: f64| RefPoint {
            x: self.x + u * ch - v * sh,
            y: self.y + u * sh + v * ch,
            hdg: self.hdg + local_hdg,
            curvature,
        };
        match &self.kind {
            GeometryKind::Line => place(ds, 0.0, 0.0, 0.0),
            GeometryKind::Arc { curvature: k } => {
                // Chord of length ds*sinc(k ds/2) along the mean heading.
                let half = 0.5 * k * ds;
                let chord = ds * sinc(half);
                place(chord * half.cos(), chord * half.sin(), k * ds, *k)
            }
            GeometryKind::Spiral {
                curv_start,
                curv_end,
            } => {
                let rate = if self.length > 0.0 {
                    (curv_end - curv_start) / self.length
                } else {
                    0.0
                };
                let theta = |t: f64| curv_start * t + 0.5 * rate * t * t;
                let turn = curv_start.abs() * ds.abs() + 0.5 * rate.abs() * ds * ds;
                let pieces = ((ds.abs() / 20.0).max(turn / 0.25)).ceil() as usize;
                let [u, v] = integrate2(0.0, ds, pieces, |t| {
                    let (s, c) = theta(t).sin_cos();
                    [c, s]
                });
                place(u, v, theta(ds), curv_start + rate * ds)
            }
            GeometryKind::Poly3 { a, b, c, d } => {
                let coef = [*a, *b, *c, *d];
                let speed = |u: f64| cubic(&coef, u).1.hypot(1.0);
                // Bounded pieces: a cubic read from a file may send Newton's u far out.
                let arc =
                    |u: f64| integrate(0.0, u, (u.abs() / 10.0).ceil().min(1e5) as usize, speed);
                let u = invert_arc_length(ds, ds, arc, speed);
                let (v, dv, ddv) = cubic(&coef, u);
                let k = ddv / (1.0 + dv * dv).powf(1.5);
                place(u, v, dv.atan(), k)
            }
            GeometryKind::ParamPoly3 { u, v, p_range } => {
                let p_max = match p_range {
                    PRange::ArcLength => self.length,
                    PRange::Normalized => 1.0,
                };
                let speed = |p: f64| cubic(u, p).1.hypot(cubic(v, p).1);
                let arc = |p: f64| {
                    integrate(
                        0.0,
                        p,
                        (p.abs() / p_max * 16.0).ceil().min(1e5) as usize,
                        speed,
                    )
                };
                let guess = if self.length > 0.0 {
                    ds / self.length * p_max
                } else {
                    0.0
                };
                let p = invert_arc_length(ds, guess, arc, speed);
                let (pu, du, ddu) = cubic(u, p);
                let (pv, dv, ddv) = cubic(v, p);
                let sq = du * du + dv * dv;
                let k = if sq > 0.0 {
                    (du * ddv - dv * ddu) / sq.powf(1.5)
                } else {
                    0.0
                };
                place(pu, pv, dv.atan2(du), k)
            }
        }
    }
}

/// Pose of `road`'s reference line at `s` (the geometry in effect at `s`, extrapolated before
/// the first and after the last one).
pub fn eval_road(road: &Road, s: f64) -> RefPoint {
    match record_at(&road.geometries, s, |g| g.s) {
        Some(g) => g.eval(s - g.s),
        // The parser rejects roads without geometry; an empty hand-built road sits at the origin.
        None => RefPoint {
            x: 0.0,
            y: 0.0,
            hdg: 0.0,
            curvature: 0.0,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{FRAC_PI_2, PI};

    fn geom(hdg: f64, length: f64, kind: GeometryKind) -> Geometry {
        Geometry {
            s: 0.0,
            x: 1.0,
            y: -2.0,
            hdg,
            length,
            kind,
        }
    }

    fn close(a: f64, b: f64, tol: f64) {
        assert!((a - b).abs() < tol, "{a} vs {b} (tol {tol})");
    }

    #[test]
    fn line_goes_along_heading() {
        let g = geom(PI / 6.0, 10.0, GeometryKind::Line);
        let p = g.eval(10.0);
        close(p.x, 1.0 + 10.0 * (PI / 6.0).cos(), 1e-12);
        close(p.y, -2.0 + 5.0, 1e-12);
        close(p.hdg, PI / 6.0, 1e-15);
    }

    #[test]
    fn arc_quarter_circle_endpoint() {
        let r = 50.0;
        let g = geom(0.0, FRAC_PI_2 * r, GeometryKind::Arc { curvature: 1.0 / r });
        let p = g.eval(FRAC_PI_2 * r);
        close(p.x, 1.0 + r, 1e-9);
        close(p.y, -2.0 + r, 1e-9);
        close(p.hdg, FRAC_PI_2, 1e-12);
        // Right-turning arc and a nearly straight one agree with their closed forms too.
        let g = geom(0.0, 10.0, GeometryKind::Arc { curvature: -0.1 });
        let p = g.eval(10.0);
        close(p.x, 1.0 + 10.0 * (1.0f64).sin(), 1e-12);
        close(p.y, -2.0 - 10.0 * (1.0 - (1.0f64).cos()), 1e-12);
        let g = geom(0.0, 10.0, GeometryKind::Arc { curvature: 1e-12 });
        close(g.eval(10.0).x, 11.0, 1e-9);
    }

    #[test]
    fn clothoid_matches_fresnel_value() {
        // k from 0 to pi/100 over 100 m: end = 100 * (C(1), S(1)), heading pi/2.
        let g = geom(
            0.0,
            100.0,
            GeometryKind::Spiral {
                curv_start: 0.0,
                curv_end: PI / 100.0,
            },
        );
        let p = g.eval(100.0);
        close(p.x - 1.0, 100.0 * 0.779_893_400_376_822_8, 1e-6);
        close(p.y + 2.0, 100.0 * 0.438_259_147_390_354_8, 1e-6);
        close(p.hdg, FRAC_PI_2, 1e-12);
        close(p.curvature, PI / 100.0, 1e-12);
    }

    #[test]
    fn clothoid_matches_fine_simpson_integration() {
        let (k0, k1, len, hdg) = (0.01, -0.02, 150.0, 0.7);
        let g = geom(
            hdg,
            len,
            GeometryKind::Spiral {
                curv_start: k0,
                curv_end: k1,
            },
        );
        let theta = |t: f64| hdg + k0 * t + 0.5 * (k1 - k0) / len * t * t;
        let n = 200_000;
        let h = len / n as f64;
        let (mut x, mut y) = (0.0, 0.0);
        for i in 0..=n {
            let w = if i == 0 || i == n {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            };
            x += w * theta(i as f64 * h).cos();
            y += w * theta(i as f64 * h).sin();
        }
        let p = g.eval(len);
        close(p.x - 1.0, x * h / 3.0, 1e-6);
        close(p.y + 2.0, y * h / 3.0, 1e-6);
        close(p.hdg, theta(len), 1e-12);
    }

    /// Length of the polyline through `f` at `n` steps of the parameter over [0, p].
    fn polyline_length(p: f64, n: usize, f: impl Fn(f64) -> (f64, f64)) -> f64 {
        let mut len = 0.0;
        let mut prev = f(0.0);
        for i in 1..=n {
            let q = f(p * i as f64 / n as f64);
            len += (q.0 - prev.0).hypot(q.1 - prev.1);
            prev = q;
        }
        len
    }

    #[test]
    fn poly3_known_points_and_arc_length() {
        // v = u is a 45-degree line in the local frame.
        let g = geom(
            0.0,
            20.0,
            GeometryKind::Poly3 {
                a: 0.0,
                b: 1.0,
                c: 0.0,
                d: 0.0,
            },
        );
        let p = g.eval(10.0 * 2f64.sqrt());
        close(p.x, 11.0, 1e-9);
        close(p.y, 8.0, 1e-9);
        close(p.hdg, PI / 4.0, 1e-12);
        // A cubic in a rotated frame: the point lies on the curve, at the right arc length.
        let (a, b, c, d) = (0.5, 0.1, 0.01, -1e-4);
        let g = geom(0.3, 80.0, GeometryKind::Poly3 { a, b, c, d });
        let p = g.eval(50.0);
        let (dx, dy) = (p.x - 1.0, p.y + 2.0);
        let (u, v) = (
            dx * 0.3f64.cos() + dy * 0.3f64.sin(),
            -dx * 0.3f64.sin() + dy * 0.3f64.cos(),
        );
        let poly = |u: f64| a + u * (b + u * (c + u * d));
        close(v, poly(u), 1e-9);
        close(polyline_length(u, 400_000, |t| (t, poly(t))), 50.0, 1e-6);
        close(
            p.hdg - 0.3,
            (b + 2.0 * c * u + 3.0 * d * u * u).atan(),
            1e-9,
        );
    }

    #[test]
    fn param_poly3_known_points_and_arc_length() {
        let g = geom(
            0.0,
            100.0,
            GeometryKind::ParamPoly3 {
                u: [0.0, 100.0, 0.0, 0.0],
                v: [0.0; 4],
                p_range: PRange::Normalized,
            },
        );
        let p = g.eval(40.0);
        close(p.x, 41.0, 1e-9);
        close(p.y, -2.0, 1e-9);
        let (u, v) = ([0.0, 60.0, 0.0, 0.0], [0.0, 0.0, 0.01, -1e-4]);
        let g = geom(
            0.0,
            62.0,
            GeometryKind::ParamPoly3 {
                u,
                v,
                p_range: PRange::ArcLength,
            },
        );
        let p = g.eval(30.0);
        let param = (p.x - 1.0) / 60.0;
        close(p.y + 2.0, cubic(&v, param).0, 1e-9);
        let len = polyline_length(param, 400_000, |t| (cubic(&u, t).0, cubic(&v, t).0));
        close(len, 30.0, 1e-6);
    }

    #[test]
    fn road_evaluation_picks_the_geometry_in_effect() {
        let mut second = geom(0.0, 5.0, GeometryKind::Line);
        second.s = 10.0;
        second.x = 100.0;
        let road = Road {
            id: "r".into(),
            name: String::new(),
            length: 15.0,
            junction: None,
            predecessor: None,
            successor: None,
            types: vec![],
            geometries: vec![geom(0.0, 10.0, GeometryKind::Line), second],
            lane_offsets: vec![],
            lane_sections: vec![],
        };
        close(eval_road(&road, 9.0).x, 10.0, 1e-12);
        close(eval_road(&road, 12.0).x, 102.0, 1e-12);
    }
}
