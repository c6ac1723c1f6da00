//! The shape of each road of a parsed OpenDRIVE document, checked before it becomes a map:
//! no lane wider than the radius it bends around, no reference line crossing itself, no
//! surface folding onto itself, no road lying on another, in whole or in part. Each would give
//! a map that loads and is wrong (lanes over lanes, two copies of one carriageway). The topology of the
//! network (links, junctions, lane links) is [`super::topology_checks`].

use super::lateral::{for_each_span, section_end};
use super::number_text::Num;
use super::opendrive::{OpenDrive, Road};
use super::reference_line::eval_road;
use super::topology_checks::{
    CHECK_SPACING, LINK_MAX_TURN_RAD, LINK_TOLERANCE, Place, Problem, cross_section, distance,
    to_segment,
};

/// The first shape problem of `od`, if any.
pub(super) fn check(od: &OpenDrive) -> Option<Problem> {
    lanes_fit_their_bends(od)
        .or_else(|| reference_lines_do_not_cross(od))
        .or_else(|| surfaces_do_not_fold(od))
        .or_else(|| roads_are_not_repeated(od))
        .or_else(|| carriageways_do_not_overlap(od))
}

/// The samples `s` of section `k` of `road` the geometric checks use (both ends included).
fn section_samples(road: &Road, k: usize) -> impl Iterator<Item = f64> {
    let s0 = road.lane_sections[k].s;
    let s1 = section_end(road, k).min(road.length);
    let n = ((s1 - s0) / CHECK_SPACING).ceil().max(1.0) as usize;
    (0..=n).map(move |j| s0 + (s1 - s0) * j as f64 / n as f64)
}

/// No lane boundary lies beyond the centre of the bend it follows: at curvature `k`, a
/// boundary `t` to the left of the reference line folds over itself once `t * k >= 1`.
fn lanes_fit_their_bends(od: &OpenDrive) -> Option<Problem> {
    for road in &od.roads {
        for (k, section) in road.lane_sections.iter().enumerate() {
            for s in section_samples(road, k) {
                let curvature = eval_road(road, s).curvature;
                let mut problem = None;
                for_each_span(road, section, s, |lane, span| {
                    if problem.is_none() && span.width() > 0.0 && span.outer * curvature >= 1.0 {
                        problem = Some(Problem {
                            place: Place::Lane {
                                road: road.id.clone(),
                                section: k,
                                lane: lane.id,
                            },
                            message: format!(
                                "lane {} of road {} at s = {:.1} m: its outer edge lies \
                                 {:.2} m from the reference line, beyond the {:.2} m radius of \
                                 the bend there; the lane would fold over itself",
                                lane.id,
                                road.id,
                                Num(s),
                                Num(span.outer.abs()),
                                Num(1.0 / curvature.abs())
                            ),
                        });
                    }
                });
                if problem.is_some() {
                    return problem;
                }
            }
        }
    }
    None
}

/// No road's reference line crosses itself (a loop drawn by its geometry).
fn reference_lines_do_not_cross(od: &OpenDrive) -> Option<Problem> {
    for road in &od.roads {
        let n = (road.length / CHECK_SPACING).ceil().max(1.0) as usize;
        let points: Vec<[f64; 2]> = (0..=n)
            .map(|j| {
                let p = eval_road(road, road.length * j as f64 / n as f64);
                [p.x, p.y]
            })
            .collect();
        if let Some((a, b)) = first_crossing(&points) {
            return Some(Problem {
                place: Place::Road(road.id.clone()),
                message: format!(
                    "road {}: its reference line crosses itself near ({:.1}, {:.1}) (at s = \
                     {:.1} m and s = {:.1} m); expected a line that does not loop over itself",
                    road.id,
                    Num(points[a][0]),
                    Num(points[a][1]),
                    Num(road.length * a as f64 / n as f64),
                    Num(road.length * b as f64 / n as f64)
                ),
            });
        }
    }
    None
}

/// No road's surface lies over itself: two cross-sections of one road never cross (a
/// spiral winding inwards, or loops nested closer than the road is wide, fold the lanes onto
/// each other though the reference line never crosses).
fn surfaces_do_not_fold(od: &OpenDrive) -> Option<Problem> {
    for road in &od.roads {
        let n = (road.length / CHECK_SPACING).ceil().max(1.0) as usize;
        let at = |j: usize| road.length * j as f64 / n as f64;
        let sections: Vec<[[f64; 2]; 2]> = (0..=n).map(|j| cross_section(road, at(j))).collect();
        if let Some((a, b)) = first_crossing_pair(&sections) {
            return Some(Problem {
                place: Place::Road(road.id.clone()),
                message: format!(
                    "road {}: its lanes at s = {:.1} m lie over its lanes at s = {:.1} m (the \
                     road winds back over itself closer than it is wide); expected a surface \
                     that does not fold onto itself",
                    road.id,
                    Num(at(b)),
                    Num(at(a))
                ),
            });
        }
    }
    None
}

/// The first pair of non-neighbouring segments of `segments` that properly cross, by index.
fn first_crossing_pair(segments: &[[[f64; 2]; 2]]) -> Option<(usize, usize)> {
    first_crossing_where(segments, 8.0, |j, i| i - j <= 1)
}

/// The first pair of non-adjacent segments of the polyline `points` that properly cross, by
/// their first indices (a closed polyline's last and first segments are adjacent too).
fn first_crossing(points: &[[f64; 2]]) -> Option<(usize, usize)> {
    let n = points.len().saturating_sub(1);
    let closed = n > 2 && distance(points[0], points[n]) < 1e-9;
    let segments: Vec<[[f64; 2]; 2]> = points.windows(2).map(|w| [w[0], w[1]]).collect();
    first_crossing_where(&segments, 4.0 * CHECK_SPACING, |j, i| {
        i - j <= 1 || (closed && j == 0 && i == n - 1)
    })
}

/// The first pair (j < i) of `segments` that properly cross and are not `neighbours(j, i)`.
/// Segments are bucketed on a grid of `cell` metres so that long roads stay linear.
fn first_crossing_where(
    segments: &[[[f64; 2]; 2]],
    cell: f64,
    neighbours: impl Fn(usize, usize) -> bool,
) -> Option<(usize, usize)> {
    use std::collections::HashMap;
    let key = |p: [f64; 2]| ((p[0] / cell).floor() as i64, (p[1] / cell).floor() as i64);
    let mut grid: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    for (i, &[p, q]) in segments.iter().enumerate() {
        let (a, b) = (key(p), key(q));
        let mut candidates: Vec<usize> = Vec::new();
        for x in a.0.min(b.0)..=a.0.max(b.0) {
            for y in a.1.min(b.1)..=a.1.max(b.1) {
                let bucket = grid.entry((x, y)).or_default();
                candidates.extend(bucket.iter().copied());
                bucket.push(i);
            }
        }
        for j in candidates {
            let [r, s] = segments[j];
            if !neighbours(j, i) && cross(r, s, p, q) {
                return Some((j, i));
            }
        }
    }
    None
}

/// Whether segments pq and rs cross at a point inside both.
fn cross(p: [f64; 2], q: [f64; 2], r: [f64; 2], s: [f64; 2]) -> bool {
    let orient = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
        (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    };
    let (d1, d2) = (orient(r, s, p), orient(r, s, q));
    let (d3, d4) = (orient(p, q, r), orient(p, q, s));
    d1 * d2 < 0.0 && d3 * d4 < 0.0
}

/// No road outside a junction lies on another one with lanes on the same side of the line
/// (a road pasted twice under two ids, either way round): its lanes would be two copies of one
/// carriageway, and agents on either would drive through each other. Two roads on one line the
/// opposite way, each with lanes on its own right, are one two-way road and stay. Roads inside
/// junctions share their first metres by design and are left out.
fn roads_are_not_repeated(od: &OpenDrive) -> Option<Problem> {
    use std::collections::HashMap;
    const CELL: f64 = 4.0 * CHECK_SPACING;
    let cell = |p: [f64; 2]| ((p[0] / CELL).floor() as i64, (p[1] / CELL).floor() as i64);
    let open: Vec<&Road> = od.roads.iter().filter(|r| r.junction.is_none()).collect();
    let samples: Vec<Vec<(f64, f64, f64)>> = open.iter().map(|r| reference_samples(r)).collect();
    let mut grid: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    for (k, points) in samples.iter().enumerate() {
        for &(x, y, _) in points {
            let bucket = grid.entry(cell([x, y])).or_default();
            if bucket.last() != Some(&k) {
                bucket.push(k);
            }
        }
    }
    for (b, points) in samples.iter().enumerate() {
        // Roads passing the first sample's cell or its neighbours (a line within the
        // tolerance may cross into the next cell between two of its samples).
        let (cx, cy) = cell([points[0].0, points[0].1]);
        let mut candidates: Vec<usize> = (-1..=1)
            .flat_map(|dx| (-1..=1).map(move |dy| (cx + dx, cy + dy)))
            .filter_map(|c| grid.get(&c))
            .flatten()
            .copied()
            .filter(|&a| a != b)
            .collect();
        candidates.sort_unstable();
        candidates.dedup();
        for a in candidates {
            let Some(reversed) = [false, true].into_iter().find(|&reversed| {
                points
                    .iter()
                    .all(|&(x, y, h)| near_sample(&samples[a], x, y, h, reversed))
            }) else {
                continue;
            };
            if share_a_side(open[a], open[b], reversed) {
                let (first, second) = if a < b { (a, b) } else { (b, a) };
                let way = if reversed { "the opposite" } else { "the same" };
                return Some(Problem {
                    place: Place::Road(open[second].id.clone()),
                    message: format!(
                        "road {} lies on road {} (its reference line within {LINK_TOLERANCE} m \
                         of the other's, {way} way, with lanes on the same side of the line): \
                         one carriageway given twice; expected each road once",
                        open[second].id, open[first].id
                    ),
                });
            }
        }
    }
    None
}

/// Points (x, y, heading) along `road`'s reference line every [`CHECK_SPACING`].
fn reference_samples(road: &Road) -> Vec<(f64, f64, f64)> {
    let n = (road.length / CHECK_SPACING).ceil().max(1.0) as usize;
    (0..=n)
        .map(|j| {
            let p = eval_road(road, road.length * j as f64 / n as f64);
            (p.x, p.y, p.hdg)
        })
        .collect()
}

/// Whether (x, y) lies within [`LINK_TOLERANCE`] of the polyline `line`, heading its way (or
/// against it, when `reversed`).
fn near_sample(line: &[(f64, f64, f64)], x: f64, y: f64, heading: f64, reversed: bool) -> bool {
    let turn = if reversed { std::f64::consts::PI } else { 0.0 };
    line.windows(2).any(|pair| {
        let ((ax, ay, ah), (bx, by, _)) = (pair[0], pair[1]);
        let along = crate::geometry::wrap_angle(heading + turn - ah).abs() < LINK_MAX_TURN_RAD;
        along && to_segment([x, y], [[ax, ay], [bx, by]]) <= LINK_TOLERANCE
    })
}

/// Whether both roads have lanes on one side of their common line: both to the right of
/// their reference lines, or both to the left; for a road lying on the other `reversed`, one's
/// right is the other's left.
fn share_a_side(a: &Road, b: &Road, reversed: bool) -> bool {
    let sides = |r: &Road| {
        let right = r.lane_sections.iter().any(|s| !s.right.is_empty());
        let left = r.lane_sections.iter().any(|s| !s.left.is_empty());
        (right, left)
    };
    let ((ar, al), (br, bl)) = (sides(a), sides(b));
    let (br, bl) = if reversed { (bl, br) } else { (br, bl) };
    (ar && br) || (al && bl)
}

/// Metres at each end of a road where another road may lie on it: linked roads meet there.
const END_MARGIN: f64 = 2.0;
/// Metres over which a lane's centre may run on another road's surface before the two count
/// as one carriageway over another (a few metres of a tight junction-free fork).
const MAX_OVERLAP: f64 = 5.0;

/// No driving lane of a road outside a junction runs on another such road's surface for more
/// than [`MAX_OVERLAP`]: a road pasted over part of another, or beside it at less than a lane's
/// width, gives lanes through lanes as surely as a road given twice. Lane centres are tested,
/// so roads that only touch (a two-way road as two one-way roads, a ramp beside the main
/// carriageway) pass; so do the first and last metres of each road, where linked roads meet.
fn carriageways_do_not_overlap(od: &OpenDrive) -> Option<Problem> {
    let open: Vec<&Road> = od.roads.iter().filter(|r| r.junction.is_none()).collect();
    let surfaces = SurfaceGrid::new(&open);
    for (b, road) in open.iter().enumerate() {
        for k in 0..road.lane_sections.len() {
            // Per (lane, other road): where the lane's centre went onto the other's surface.
            let mut runs: std::collections::HashMap<(i32, usize), f64> = Default::default();
            for s in section_samples(road, k) {
                if s < END_MARGIN || s > road.length - END_MARGIN {
                    continue;
                }
                let pose = eval_road(road, s);
                let mut on: Vec<(i32, usize)> = Vec::new();
                for_each_span(road, &road.lane_sections[k], s, |lane, span| {
                    if lane.kind != super::opendrive::LaneType::Driving {
                        return;
                    }
                    let centre = pose.offset(0.5 * (span.inner + span.outer));
                    for a in surfaces.roads_under(centre).filter(|&a| a != b) {
                        on.push((lane.id, a));
                    }
                });
                runs.retain(|key, _| on.contains(key));
                for key in on {
                    let start = *runs.entry(key).or_insert(s);
                    if s - start > MAX_OVERLAP {
                        let (lane, a) = key;
                        return Some(overlap_problem(road, b, open[a], a, lane, start));
                    }
                }
            }
        }
    }
    None
}

/// The overlap of `road`'s lane with `other`, placed at whichever of the two comes later in
/// the document (the one pasted over the other).
fn overlap_problem(
    road: &Road,
    road_index: usize,
    other: &Road,
    other_index: usize,
    lane: i32,
    from: f64,
) -> Problem {
    let later = if road_index > other_index {
        road
    } else {
        other
    };
    let earlier = if road_index > other_index {
        other
    } else {
        road
    };
    Problem {
        place: Place::Road(later.id.clone()),
        message: format!(
            "road {} overlaps road {}: the centre of road {}'s lane {lane} runs on road {}'s \
             surface for more than {MAX_OVERLAP} m from s = {:.1}: two carriageways over one \
             another; expected roads that meet only at their ends or in a junction",
            later.id,
            earlier.id,
            road.id,
            other.id,
            Num(from)
        ),
    }
}

/// The driving surfaces of roads as quadrilaterals between cross-sections every
/// [`CHECK_SPACING`], bucketed on a grid.
struct SurfaceGrid {
    quads: Vec<(usize, [[f64; 2]; 4])>,
    cells: std::collections::HashMap<(i64, i64), Vec<usize>>,
}

impl SurfaceGrid {
    const CELL: f64 = 8.0;

    fn new(roads: &[&Road]) -> Self {
        let mut grid = Self {
            quads: Vec::new(),
            cells: Default::default(),
        };
        for (r, road) in roads.iter().enumerate() {
            for k in 0..road.lane_sections.len() {
                let cuts: Vec<[[f64; 2]; 2]> = section_samples(road, k)
                    .map(|s| cross_section(road, s))
                    .collect();
                for pair in cuts.windows(2) {
                    let ([r0, l0], [r1, l1]) = (pair[0], pair[1]);
                    grid.add(r, [r0, r1, l1, l0]);
                }
            }
        }
        grid
    }

    fn cell(p: [f64; 2]) -> (i64, i64) {
        (
            (p[0] / Self::CELL).floor() as i64,
            (p[1] / Self::CELL).floor() as i64,
        )
    }

    fn add(&mut self, road: usize, quad: [[f64; 2]; 4]) {
        let index = self.quads.len();
        self.quads.push((road, quad));
        let (lo, hi) = quad.iter().fold(
            ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]),
            |(lo, hi), p| {
                (
                    [lo[0].min(p[0]), lo[1].min(p[1])],
                    [hi[0].max(p[0]), hi[1].max(p[1])],
                )
            },
        );
        let ((x0, y0), (x1, y1)) = (Self::cell(lo), Self::cell(hi));
        if (x1 - x0) * (y1 - y0) > 10_000 {
            return; // a degenerate quad (refused by the fold check before)
        }
        for x in x0..=x1 {
            for y in y0..=y1 {
                self.cells.entry((x, y)).or_default().push(index);
            }
        }
    }

    /// The roads whose surface holds `p`.
    fn roads_under(&self, p: [f64; 2]) -> impl Iterator<Item = usize> + '_ {
        let mut roads: Vec<usize> = self
            .cells
            .get(&Self::cell(p))
            .into_iter()
            .flatten()
            .map(|&q| &self.quads[q])
            .filter(|(_, quad)| inside(p, quad))
            .map(|&(road, _)| road)
            .collect();
        roads.sort_unstable();
        roads.dedup();
        roads.into_iter()
    }
}

/// Whether `p` lies inside the polygon `corners` (even-odd rule).
fn inside(p: [f64; 2], corners: &[[f64; 2]]) -> bool {
    let mut odd = false;
    let mut j = corners.len() - 1;
    for i in 0..corners.len() {
        let (a, b) = (corners[i], corners[j]);
        if (a[1] > p[1]) != (b[1] > p[1])
            && p[0] < a[0] + (p[1] - a[1]) * (b[0] - a[0]) / (b[1] - a[1])
        {
            odd = !odd;
        }
        j = i;
    }
    odd
}
