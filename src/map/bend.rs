//! Bending a one-road map: a constant curvature is added to its reference line, and any point
//! near the road is carried along in road coordinates (arc length s, lateral offset t), so
//! lanes keep their widths and a recorded vehicle keeps its lane, its offset in it and its
//! heading relative to it.
//!
//! Why: the A9 recording has one curvature per carriageway (+-0.0003 1/m), so a policy imitating
//! it cannot tell "follow the lane" from "steer like the A9", and drifts on roads of other
//! curvature (experiments/recipe/agent_dropout/). Bent copies of the recorded scenes are the
//! same drivers on roads of other curvatures (`crate::data::bend_scenes`).

use super::opendrive::{GeometryKind, OpenDrive, Road};
use super::reference_line::{RefPoint, eval_road};
use crate::geometry::wrap_angle;
use crate::{Error, Result};

/// Largest added curvature accepted (1/m): a 100 m radius, still far from the centre of
/// curvature for any lane of a motorway (|t| < 50 m is checked point by point).
pub const MAX_BEND_CURVATURE: f64 = 0.01;

/// Reference-line samples used to project points (m apart).
const PROJECTION_SPACING: f64 = 1.0;
/// How far before the road's start and after its end points are projected (m): the reference
/// line is extrapolated there (vehicles seen at the edge of the recorded area).
const PROJECTION_MARGIN: f64 = 150.0;
/// A point whose offset reaches this share of the bent radius is refused: the road frame
/// folds at the centre of curvature.
const MAX_OFFSET_SHARE: f64 = 0.5;

/// Why `curvature` (1/m) cannot be a bend, or `None` when it can: the one check behind the
/// run file's `data.a9_bends`, `rtr eval --a9-bend` and [`RoadBend::new`], each naming its field.
pub fn bend_curvature_problem(curvature: f64) -> Option<String> {
    (!(curvature.is_finite() && curvature.abs() <= MAX_BEND_CURVATURE)).then(|| {
        format!("{curvature} 1/m; expected a finite curvature within +-{MAX_BEND_CURVATURE} 1/m")
    })
}

/// A pose carried from the original road onto the bent one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BentPose {
    pub x: f64,
    pub y: f64,
    pub heading: f64,
    /// Ratio of arc lengths along the road at this offset, bent over original: a speed or
    /// acceleration along the road scales by it, one across the road does not.
    pub along_scale: f64,
    /// What a speed along the pose's heading scales by: its along-road part by
    /// `along_scale`, its across part by 1.
    pub speed_scale: f64,
}

/// A one-road OpenDRIVE network and its copy with `added_curvature` added to every geometry of
/// the reference line (the start pose is kept, the rest follows).
#[derive(Clone, Debug)]
pub struct RoadBend {
    source_name: String,
    original: Road,
    bent: OpenDrive,
    added_curvature: f64,
    /// Original reference line sampled from `-PROJECTION_MARGIN` to `length + margin`.
    samples: Vec<(f64, RefPoint)>,
}

impl RoadBend {
    /// Bends the single road of `od`. Line, arc and spiral geometries are supported (adding a
    /// constant curvature to them gives an arc or a spiral again); a network of several roads,
    /// or a poly3 / paramPoly3 plan view, is refused by name.
    pub fn new(od: &OpenDrive, source_name: &str, added_curvature: f64) -> Result<Self> {
        if let Some(problem) = bend_curvature_problem(added_curvature) {
            return Err(Error::invalid(source_name, "bend curvature", problem));
        }
        let [road] = od.roads.as_slice() else {
            return Err(Error::invalid(
                source_name,
                "roads",
                format!(
                    "{} roads; bending needs a map of exactly one road (the road frame of \
                     several joined roads is not defined here)",
                    od.roads.len()
                ),
            ));
        };
        let bent_road = bend_road(road, added_curvature, source_name)?;
        let mut bent = od.clone();
        bent.roads = vec![bent_road];
        let count = ((road.length + 2.0 * PROJECTION_MARGIN) / PROJECTION_SPACING).ceil() as usize;
        let samples = (0..=count)
            .map(|k| {
                let s = -PROJECTION_MARGIN + k as f64 * PROJECTION_SPACING;
                (s, eval_road(road, s))
            })
            .collect();
        Ok(Self {
            source_name: source_name.to_string(),
            original: road.clone(),
            bent,
            added_curvature,
            samples,
        })
    }

    /// The bent network (same lanes, widths and marks; a new plan view).
    pub fn bent_opendrive(&self) -> &OpenDrive {
        &self.bent
    }

    /// Road coordinates (s, t) of `p` on the original reference line: t is the signed offset to
    /// the left.
    pub fn road_coordinates(&self, p: [f64; 2]) -> Result<(f64, f64)> {
        let nearest = self
            .samples
            .iter()
            .map(|(s, r)| (*s, (p[0] - r.x).powi(2) + (p[1] - r.y).powi(2)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(s, _)| s)
            .unwrap_or(0.0);
        // (along-road, across-road) offset of `p` from the reference point at `s`.
        let offsets = |s: f64| {
            let r = eval_road(&self.original, s);
            let (sin, cos) = r.hdg.sin_cos();
            let (dx, dy) = (p[0] - r.x, p[1] - r.y);
            (dx * cos + dy * sin, -dx * sin + dy * cos, r.curvature)
        };
        // Newton on the foot point: the along-road residual over the arc-length rate at
        // offset t; a few steps from a sample 1 m away reach rounding.
        let mut s = nearest;
        for _ in 0..8 {
            let (along, t, curvature) = offsets(s);
            if along.abs() < 1e-10 {
                break;
            }
            s += along / (1.0 - t * curvature).max(MAX_OFFSET_SHARE);
        }
        let (_, t, _) = offsets(s);
        let first = self.samples.first().map_or(0.0, |(s, _)| *s);
        let last = self.samples.last().map_or(0.0, |(s, _)| *s);
        if !(first..=last).contains(&s) || !t.is_finite() {
            return Err(Error::invalid(
                &self.source_name,
                format!("point ({:.1}, {:.1})", p[0], p[1]),
                format!(
                    "more than {PROJECTION_MARGIN} m beyond the ends of the road; a bend \
                     carries only points along the road"
                ),
            ));
        }
        Ok((s, t))
    }

    /// Carries the pose (`p`, `heading`) onto the bent road.
    pub fn pose(&self, p: [f64; 2], heading: f64) -> Result<BentPose> {
        let (s, t) = self.road_coordinates(p)?;
        let old = eval_road(&self.original, s);
        let new = eval_road(&self.bent.roads[0], s);
        let old_rate = 1.0 - t * old.curvature;
        let new_rate = 1.0 - t * new.curvature;
        if old_rate < MAX_OFFSET_SHARE || new_rate < MAX_OFFSET_SHARE {
            return Err(Error::invalid(
                &self.source_name,
                format!("point ({:.1}, {:.1})", p[0], p[1]),
                format!(
                    "{t:.1} m from the reference line, too close to the centre of curvature of \
                     the road bent by {} 1/m",
                    self.added_curvature
                ),
            ));
        }
        let along_scale = new_rate / old_rate;
        // The velocity's along-road part stretches with the arc length, the across part does
        // not, so the heading relative to the road turns a little with it.
        let relative = wrap_angle(heading - old.hdg);
        let (across, along) = relative.sin_cos();
        let turned = across.atan2(along_scale * along);
        let [x, y] = new.offset(t);
        Ok(BentPose {
            x,
            y,
            heading: wrap_angle(new.hdg + turned),
            along_scale,
            speed_scale: (along_scale * along).hypot(across),
        })
    }
}

/// `road` with `added` curvature on every geometry, chained so each starts where the bent one
/// before it ends.
fn bend_road(road: &Road, added: f64, source_name: &str) -> Result<Road> {
    let mut bent = road.clone();
    let mut start: Option<RefPoint> = None;
    for (k, geometry) in bent.geometries.iter_mut().enumerate() {
        geometry.kind = match geometry.kind {
            GeometryKind::Line => GeometryKind::Arc { curvature: added },
            GeometryKind::Arc { curvature } => GeometryKind::Arc {
                curvature: curvature + added,
            },
            GeometryKind::Spiral {
                curv_start,
                curv_end,
            } => GeometryKind::Spiral {
                curv_start: curv_start + added,
                curv_end: curv_end + added,
            },
            GeometryKind::Poly3 { .. } | GeometryKind::ParamPoly3 { .. } => {
                return Err(Error::invalid(
                    source_name,
                    format!("road {} geometry {k}", road.id),
                    "poly3 / paramPoly3; bending supports line, arc and spiral geometries",
                ));
            }
        };
        if let Some(p) = start {
            geometry.x = p.x;
            geometry.y = p.y;
            geometry.hdg = p.hdg;
        }
        start = Some(geometry.eval(geometry.length));
    }
    Ok(bent)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::opendrive::Geometry;

    fn one_road(geometries: Vec<Geometry>) -> OpenDrive {
        let length = geometries.iter().map(|g| g.length).sum();
        OpenDrive {
            roads: vec![Road {
                id: "1".into(),
                name: String::new(),
                length,
                junction: None,
                predecessor: None,
                successor: None,
                types: Vec::new(),
                geometries,
                lane_offsets: Vec::new(),
                lane_sections: Vec::new(),
            }],
            junctions: Vec::new(),
        }
    }

    fn geometry(s: f64, length: f64, kind: GeometryKind) -> Geometry {
        Geometry {
            s,
            x: 10.0,
            y: -5.0,
            hdg: 0.3,
            length,
            kind,
        }
    }

    #[test]
    fn a_bent_line_then_spiral_is_continuous_with_the_curvature_added() {
        let od = one_road(vec![
            geometry(0.0, 100.0, GeometryKind::Line),
            geometry(
                100.0,
                80.0,
                GeometryKind::Spiral {
                    curv_start: 0.0,
                    curv_end: 0.002,
                },
            ),
        ]);
        let bend = RoadBend::new(&od, "test", 0.003).unwrap();
        let road = &bend.bent_opendrive().roads[0];
        let end_of_line = road.geometries[0].eval(100.0);
        let start_of_spiral = road.geometries[1].eval(0.0);
        assert!((end_of_line.x - start_of_spiral.x).abs() < 1e-9);
        assert!((end_of_line.y - start_of_spiral.y).abs() < 1e-9);
        assert!((end_of_line.hdg - start_of_spiral.hdg).abs() < 1e-12);
        for s in [0.0, 50.0, 120.0, 170.0] {
            let old = eval_road(&od.roads[0], s).curvature;
            let new = eval_road(road, s).curvature;
            assert!((new - old - 0.003).abs() < 1e-12, "at s = {s}");
        }
        // A line bent by k is an arc: 100 m turn the heading by 100 k.
        assert!((end_of_line.hdg - (0.3 + 0.3)).abs() < 1e-12);
    }

    #[test]
    fn points_keep_their_road_coordinates_and_a_zero_bend_is_the_identity() {
        let od = one_road(vec![geometry(
            0.0,
            200.0,
            GeometryKind::Arc { curvature: -0.0005 },
        )]);
        let identity = RoadBend::new(&od, "test", 0.0).unwrap();
        let bend = RoadBend::new(&od, "test", 0.002).unwrap();
        for (s, t) in [
            (0.0, 0.0),
            (37.5, 5.2),
            (120.0, -11.0),
            (199.0, 17.5),
            (-20.0, 3.0),
        ] {
            let p = eval_road(&od.roads[0], s).offset(t);
            let same = identity.pose(p, 0.3).unwrap();
            assert!((same.heading - 0.3).abs() < 1e-9);
            assert!((same.x - p[0]).abs() < 1e-9 && (same.y - p[1]).abs() < 1e-9);
            assert!((same.along_scale - 1.0).abs() < 1e-12);
            let (ps, pt) = bend.road_coordinates(p).unwrap();
            assert!((ps - s).abs() < 1e-7 && (pt - t).abs() < 1e-7, "({s}, {t})");
            let moved = bend.pose(p, 0.3).unwrap();
            let on_bent = eval_road(&bend.bent_opendrive().roads[0], s).offset(t);
            assert!((moved.x - on_bent[0]).abs() < 1e-7 && (moved.y - on_bent[1]).abs() < 1e-7);
            let expected = (1.0 - t * 0.0015) / (1.0 + t * 0.0005);
            assert!((moved.along_scale - expected).abs() < 1e-9);
        }
    }

    #[test]
    fn a_heading_along_the_road_stays_along_it() {
        let od = one_road(vec![geometry(0.0, 300.0, GeometryKind::Line)]);
        let bend = RoadBend::new(&od, "test", -0.003).unwrap();
        let p = eval_road(&od.roads[0], 150.0).offset(-3.5);
        let forward = bend.pose(p, 0.3).unwrap();
        let backward = bend.pose(p, 0.3 + std::f64::consts::PI).unwrap();
        let road_heading = 0.3 - 0.003 * 150.0;
        assert!((forward.heading - road_heading).abs() < 1e-9);
        assert!(wrap_angle(backward.heading - road_heading - std::f64::consts::PI).abs() < 1e-9);
        // Right of a right-hand bend: the inside, shorter.
        assert!((forward.along_scale - (1.0 - 3.5 * 0.003)).abs() < 1e-12);
        assert!((forward.speed_scale - forward.along_scale).abs() < 1e-12);
        // Straight across the road: nothing stretches.
        let across = bend.pose(p, 0.3 + std::f64::consts::FRAC_PI_2).unwrap();
        assert!((across.speed_scale - 1.0).abs() < 1e-12);
    }

    #[test]
    fn unsupported_maps_and_bends_are_refused_by_name() {
        let line = one_road(vec![geometry(0.0, 100.0, GeometryKind::Line)]);
        let err = RoadBend::new(&line, "map.xodr", 0.05)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("map.xodr") && err.contains("bend curvature"),
            "{err}"
        );
        let err = RoadBend::new(&line, "map.xodr", f64::NAN)
            .unwrap_err()
            .to_string();
        assert!(err.contains("finite"), "{err}");
        let mut two = line.clone();
        two.roads.push(two.roads[0].clone());
        let err = RoadBend::new(&two, "map.xodr", 0.001)
            .unwrap_err()
            .to_string();
        assert!(err.contains("2 roads"), "{err}");
        let poly = one_road(vec![geometry(
            0.0,
            100.0,
            GeometryKind::Poly3 {
                a: 0.0,
                b: 0.0,
                c: 0.0,
                d: 0.0,
            },
        )]);
        let err = RoadBend::new(&poly, "map.xodr", 0.001)
            .unwrap_err()
            .to_string();
        assert!(err.contains("geometry 0"), "{err}");
        let bend = RoadBend::new(&line, "map.xodr", 0.001).unwrap();
        let err = bend.pose([5000.0, 0.0], 0.0).unwrap_err().to_string();
        assert!(err.contains("beyond the ends"), "{err}");
        let tight = RoadBend::new(&line, "map.xodr", 0.01).unwrap();
        let p = eval_road(&line.roads[0], 50.0).offset(60.0);
        let err = tight.pose(p, 0.3).unwrap_err().to_string();
        assert!(err.contains("centre of curvature"), "{err}");
    }
}
