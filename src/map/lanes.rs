//! [`Map`]: an OpenDRIVE road network sampled into lane polylines with topology, the form the
//! scene builder, the simulator and the lane graph use. Real and procedural maps both come
//! through [`Map::from_opendrive`].
//!
//! Right-hand traffic: right lanes (negative ids) travel along +s, left lanes (positive ids)
//! along -s. Every per-sample vector of a [`Lane`] is ordered in its travel direction, so
//! "left" is the driver's left, which is always the boundary toward the centre lane.

use std::collections::{HashMap, HashSet};
use std::path::Path;

use super::lateral::{for_each_span, inner_mark, own_mark, section_end};
use super::opendrive::{LaneType, OpenDrive, RoadMark, record_at};
use super::query::{CenterlineIndex, RoadSurface, Surface};
use super::reference_line::{RefPoint, eval_road};
use super::topology;
use super::xodr_parse::parse_xodr;
use crate::geometry::wrap_angle;
use crate::{Error, Result};

/// Longest step between reference-line samples (m).
pub const SAMPLE_SPACING: f64 = 0.5;

/// Speed limit of a lane when neither the lane nor the road gives one (130 km/h, the German
/// recommended motorway speed, in m/s).
pub const DEFAULT_SPEED_LIMIT: f64 = 130.0 / 3.6;

/// Widths below this (m) count as zero: such a lane has no area.
const MIN_WIDTH: f64 = 1e-6;

/// Longest road accepted (m): sampling is linear in length, so a corrupt length such as 1e15
/// must be an error rather than an endless loop.
pub const MAX_ROAD_LENGTH: f64 = 100_000.0;

/// One lane of one lane section, sampled in its travel direction.
#[derive(Clone, Debug, PartialEq)]
pub struct Lane {
    /// Index of the road in [`Map::opendrive`]`().roads`.
    pub road: usize,
    pub road_id: String,
    /// Index of the lane section within the road.
    pub section: usize,
    /// OpenDRIVE lane id: negative on the right (travels +s), positive on the left (travels -s).
    pub id: i32,
    pub kind: LaneType,
    pub centerline: Vec<[f64; 2]>,
    /// Heading of the centerline in travel direction (rad).
    pub headings: Vec<f64>,
    /// Arc length along the centerline from the lane's start (m).
    pub s: Vec<f64>,
    /// Reference-line `s` of each sample (decreasing for left lanes).
    pub road_s: Vec<f64>,
    pub widths: Vec<f64>,
    pub left_boundary: Vec<[f64; 2]>,
    pub right_boundary: Vec<[f64; 2]>,
    /// Mark on each boundary at each sample.
    pub left_marks: Vec<RoadMark>,
    pub right_marks: Vec<RoadMark>,
    /// The mark found over most of the lane's length.
    pub left_mark: RoadMark,
    pub right_mark: RoadMark,
    /// m/s: the lane's `<speed>`, else the road `<type>` speed, else [`DEFAULT_SPEED_LIMIT`].
    pub speed_limit: f64,
    /// Lanes one can drive into from this lane's end (indices into [`Map::lanes`]).
    pub successors: Vec<usize>,
    pub predecessors: Vec<usize>,
    /// Adjacent graph lane on the driver's left/right with the same travel direction.
    pub left_neighbour: Option<usize>,
    pub right_neighbour: Option<usize>,
}

impl LaneType {
    /// Part of the road surface a vehicle may legally occupy (the road polygon).
    pub fn is_drivable(&self) -> bool {
        self.is_graph_lane() || *self == LaneType::Shoulder
    }

    /// Lanes vehicles follow.
    pub fn is_graph_lane(&self) -> bool {
        matches!(
            self,
            LaneType::Driving
                | LaneType::Entry
                | LaneType::Exit
                | LaneType::OnRamp
                | LaneType::OffRamp
                | LaneType::ConnectingRamp
        )
    }
}

impl Lane {
    /// Length of the centerline (m).
    pub fn length(&self) -> f64 {
        self.s.last().copied().unwrap_or(0.0)
    }

    pub fn is_drivable(&self) -> bool {
        self.kind.is_drivable()
    }

    pub fn is_graph_lane(&self) -> bool {
        self.kind.is_graph_lane()
    }

    /// Whether the lane travels along increasing reference-line `s`.
    pub fn along_reference(&self) -> bool {
        self.id < 0
    }

    /// The lane's outline as a closed polygon: left boundary forward, right boundary back.
    pub fn polygon(&self) -> Vec<[f64; 2]> {
        self.left_boundary
            .iter()
            .chain(self.right_boundary.iter().rev())
            .copied()
            .collect()
    }
}

/// The sampled reference line of one road.
#[derive(Clone, Debug)]
pub(super) struct RoadSamples {
    pub s: Vec<f64>,
    pub points: Vec<RefPoint>,
}

/// A road network with sampled lanes, topology and a spatial index for queries.
#[derive(Clone, Debug)]
pub struct Map {
    source: String,
    pub(super) surface: Surface,
    pub(super) lanes: Vec<Lane>,
    pub(super) centerlines: CenterlineIndex,
    bounds: ([f64; 2], [f64; 2]),
    /// The grid cache of on-road queries, made on first use and kept with the map, so every
    /// rollout on it reuses the tiles filled so far.
    raster: std::sync::OnceLock<std::sync::Arc<super::raster::RoadRaster>>,
}

impl Map {
    /// The same map with every lane's speed limit set to `speed_limit` (m/s): a probe of how
    /// much a policy reads the limit (`rtr eval --generated-speed-limit`).
    pub fn with_speed_limit(&self, speed_limit: f64) -> Map {
        let mut map = self.clone();
        for lane in &mut map.lanes {
            lane.speed_limit = speed_limit;
        }
        map
    }

    /// Samples `od` into lanes; `source_name` names the file or generator in errors.
    pub fn from_opendrive(od: &OpenDrive, source_name: &str) -> Result<Map> {
        validate(od, source_name)?;
        let mut roads = Vec::with_capacity(od.roads.len());
        let mut lanes = Vec::new();
        for (r, road) in od.roads.iter().enumerate() {
            let mut samples = RoadSamples {
                s: Vec::new(),
                points: Vec::new(),
            };
            for k in 0..road.lane_sections.len() {
                let (s0, s1) = (
                    road.lane_sections[k].s.max(0.0),
                    section_end(road, k).min(road.length),
                );
                if s1 - s0 < 1e-9 {
                    continue;
                }
                let n = ((s1 - s0) / SAMPLE_SPACING).ceil().max(1.0) as usize;
                let grid: Vec<f64> = (0..=n)
                    .map(|j| s0 + (s1 - s0) * j as f64 / n as f64)
                    .collect();
                let points: Vec<RefPoint> = grid.iter().map(|&s| eval_road(road, s)).collect();
                sample_section(od, r, k, &grid, &points, &mut lanes);
                // Section boundaries appear once in the road's reference polyline.
                let skip = usize::from(samples.s.last() == Some(&grid[0]));
                samples.s.extend_from_slice(&grid[skip..]);
                samples.points.extend_from_slice(&points[skip..]);
            }
            roads.push(samples);
        }
        let connected_ends = topology::connect(od, &mut lanes, source_name)?;
        let surface = Surface::Roads(RoadSurface::new(od.clone(), roads, &connected_ends));
        Ok(Map::assemble(source_name, surface, lanes))
    }

    /// A map from its lanes (topology filled in) and the surface that answers on-road queries.
    pub(super) fn assemble(source_name: &str, surface: Surface, lanes: Vec<Lane>) -> Map {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for lane in &lanes {
            for p in lane.left_boundary.iter().chain(&lane.right_boundary) {
                for d in 0..2 {
                    lo[d] = lo[d].min(p[d]);
                    hi[d] = hi[d].max(p[d]);
                }
            }
        }
        if lanes.is_empty() {
            (lo, hi) = ([0.0; 2], [0.0; 2]);
        }
        Map {
            source: source_name.to_string(),
            surface,
            centerlines: CenterlineIndex::build(&lanes),
            lanes,
            bounds: (lo, hi),
            raster: std::sync::OnceLock::new(),
        }
    }

    /// The map's grid cache of on-road queries at [`super::RASTER_CELL`] (filled lazily).
    pub fn raster(&self) -> std::sync::Arc<super::raster::RoadRaster> {
        self.raster
            .get_or_init(|| {
                std::sync::Arc::new(super::raster::RoadRaster::new(self, super::RASTER_CELL))
            })
            .clone()
    }

    pub fn from_xodr_str(text: &str, source_name: &str) -> Result<Map> {
        Map::from_opendrive(&parse_xodr(text, source_name)?, source_name)
    }

    pub fn from_xodr_file(path: &Path) -> Result<Map> {
        let text = crate::io::read_text(path, crate::io::Format::OpenDrive)?;
        Map::from_xodr_str(&text, &path.display().to_string())
    }

    pub fn lanes(&self) -> &[Lane] {
        &self.lanes
    }

    /// Sum of the road lengths (m): the OpenDRIVE reference lines, or for a lanelet map the
    /// lanes with no same-direction neighbour on their left (one per carriageway piece).
    pub fn road_length(&self) -> f64 {
        match &self.surface {
            Surface::Roads(r) => r.opendrive.roads.iter().map(|r| r.length).sum(),
            Surface::Lanelets(_) => self
                .lanes
                .iter()
                .filter(|l| l.is_graph_lane() && l.left_neighbour.is_none())
                .map(Lane::length)
                .sum(),
        }
    }

    /// Driving lanes, each (road, lane id) counted once however many sections it spans.
    pub fn driving_lane_count(&self) -> usize {
        self.lanes
            .iter()
            .filter(|l| l.kind == LaneType::Driving)
            .map(|l| (l.road, l.id))
            .collect::<HashSet<_>>()
            .len()
    }

    /// The drivable road polygon (driving, shoulder and ramp lanes) as the union of one
    /// polygon per lane; `box_on_road` answers containment in it.
    pub fn road_polygons(&self) -> Vec<Vec<[f64; 2]>> {
        self.lanes
            .iter()
            .filter(|l| l.is_drivable())
            .map(Lane::polygon)
            .collect()
    }

    /// Axis-aligned bounds (min, max) of all lane boundaries.
    pub fn bounds(&self) -> ([f64; 2], [f64; 2]) {
        self.bounds
    }

    pub fn source(&self) -> &str {
        &self.source
    }

    /// The OpenDRIVE network the map was sampled from; `None` for a lanelet map (CommonRoad).
    pub fn opendrive(&self) -> Option<&OpenDrive> {
        match &self.surface {
            Surface::Roads(r) => Some(&r.opendrive),
            Surface::Lanelets(_) => None,
        }
    }
}

/// Checks what the sampler relies on: unique road ids and positive road lengths.
fn validate(od: &OpenDrive, source: &str) -> Result<()> {
    let mut seen = HashSet::new();
    for road in &od.roads {
        let place = format!("road {}", road.id);
        if !seen.insert(road.id.as_str()) {
            return Err(Error::invalid(source, place, "road id is used twice"));
        }
        if !(road.length > 0.0 && road.length <= MAX_ROAD_LENGTH) {
            return Err(Error::invalid(
                source,
                place,
                format!(
                    "length is {}, expected a positive number of at most {MAX_ROAD_LENGTH} m",
                    road.length
                ),
            ));
        }
        if road.geometries.is_empty() || road.lane_sections.is_empty() {
            return Err(Error::invalid(
                source,
                place,
                "expected at least one planView geometry and one lane section",
            ));
        }
    }
    Ok(())
}

/// Per-sample values of one lane while a section is being sampled.
#[derive(Default)]
struct Acc {
    id: i32,
    kind: Option<LaneType>,
    center: Vec<[f64; 2]>,
    headings: Vec<f64>,
    widths: Vec<f64>,
    inner: Vec<[f64; 2]>,
    outer: Vec<[f64; 2]>,
    inner_marks: Vec<RoadMark>,
    outer_marks: Vec<RoadMark>,
}

fn sample_section(
    od: &OpenDrive,
    r: usize,
    k: usize,
    grid: &[f64],
    points: &[RefPoint],
    out: &mut Vec<Lane>,
) {
    let road = &od.roads[r];
    let sec = &road.lane_sections[k];
    let mut accs: HashMap<i32, Acc> = HashMap::new();
    for (&s, p) in grid.iter().zip(points) {
        for_each_span(road, sec, s, |lane, span| {
            let acc = accs.entry(lane.id).or_default();
            acc.id = lane.id;
            acc.kind = Some(lane.kind.clone());
            let tc = 0.5 * (span.inner + span.outer);
            let dtc = 0.5 * (span.d_inner + span.d_outer);
            acc.center.push(p.offset(tc));
            // Heading of the offset curve r(s) + t(s) n(s): tangent (1 - t k) T + t' n.
            acc.headings.push(p.hdg + dtc.atan2(1.0 - tc * p.curvature));
            acc.widths.push(span.width());
            acc.inner.push(p.offset(span.inner));
            acc.outer.push(p.offset(span.outer));
            acc.inner_marks.push(inner_mark(sec, lane.id, s));
            acc.outer_marks.push(own_mark(lane, sec.s, s));
        });
    }
    let mid = 0.5 * (grid[0] + grid[grid.len() - 1]);
    let road_speed = record_at(&road.types, mid, |t| t.s).and_then(|t| t.speed);
    let mut ids: Vec<i32> = accs.keys().copied().collect();
    // Right lanes from the centre outward, then left lanes: a stable, readable order.
    ids.sort_by_key(|&id| (id > 0, id.abs()));
    for id in ids {
        let Some(mut a) = accs.remove(&id) else {
            continue;
        };
        if a.widths.iter().all(|&w| w < MIN_WIDTH) {
            continue;
        }
        let lane_speed = sec
            .lane(a.id)
            .and_then(|l| record_at(&l.speeds, mid - sec.s, |sp| sp.s_offset))
            .map(|sp| sp.max);
        let speed_limit = match lane_speed {
            Some(v) => v,
            None => road_speed,
        }
        .unwrap_or(DEFAULT_SPEED_LIMIT);
        let mut road_s = grid.to_vec();
        if a.id > 0 {
            // Left lanes travel against s.
            for v in [&mut a.center, &mut a.inner, &mut a.outer] {
                v.reverse();
            }
            a.headings.reverse();
            a.headings
                .iter_mut()
                .for_each(|h| *h += std::f64::consts::PI);
            a.widths.reverse();
            a.inner_marks.reverse();
            a.outer_marks.reverse();
            road_s.reverse();
        }
        a.headings.iter_mut().for_each(|h| *h = wrap_angle(*h));
        let mut s = Vec::with_capacity(a.center.len());
        let mut acc_len = 0.0;
        for (j, p) in a.center.iter().enumerate() {
            if j > 0 {
                let q = a.center[j - 1];
                acc_len += (p[0] - q[0]).hypot(p[1] - q[1]);
            }
            s.push(acc_len);
        }
        out.push(Lane {
            road: r,
            road_id: road.id.clone(),
            section: k,
            id: a.id,
            kind: a.kind.unwrap_or(LaneType::None),
            centerline: a.center,
            headings: a.headings,
            s,
            road_s,
            widths: a.widths,
            left_boundary: a.inner,
            right_boundary: a.outer,
            left_mark: dominant(&a.inner_marks),
            right_mark: dominant(&a.outer_marks),
            left_marks: a.inner_marks,
            right_marks: a.outer_marks,
            speed_limit,
            successors: Vec::new(),
            predecessors: Vec::new(),
            left_neighbour: None,
            right_neighbour: None,
        });
    }
}

/// The most frequent value (the first one on ties).
fn dominant(marks: &[RoadMark]) -> RoadMark {
    let mut counts: Vec<(&RoadMark, usize)> = Vec::new();
    for m in marks {
        match counts.iter_mut().find(|(k, _)| *k == m) {
            Some((_, c)) => *c += 1,
            None => counts.push((m, 1)),
        }
    }
    let mut best: Option<(&RoadMark, usize)> = None;
    for (m, c) in counts {
        if best.is_none_or(|(_, bc)| c > bc) {
            best = Some((m, c));
        }
    }
    best.map_or(RoadMark::None, |(m, _)| m.clone())
}
