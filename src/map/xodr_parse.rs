//! Reads an OpenDRIVE document into [`OpenDrive`]. Every error names the source, the line and
//! column of the offending element, the attribute and what was expected.
//!
//! Inside the elements rtr reads (roads, their links, types, plan view, lanes; junctions and
//! their connections), every attribute and child element must be one the OpenDRIVE standard
//! (1.4 to 1.8) defines there ([`super::xodr_schema`]): a misspelt `<roadmark>` or `colour=`
//! is refused, not dropped. Standard elements that do not change the driving geometry (header
//! details, userData, material, objects, signals, elevation and lateral profiles, surface,
//! rule, access, height, visibility) are skipped, subtree and all. Standard children that
//! *would* change the geometry are errors: a plan-view geometry other than the five supported
//! ones, and lanes described by `<border>` instead of `<width>`.
//!
//! Values are checked for physical sense where they are read: a lane 0-10 m wide everywhere
//! along its section (0 where it opens or ends), every lane vehicles follow wider than 0
//! somewhere in its section and some at least 0.5 m wide, roads of positive length up to
//! 100 km, curvature radii of at least 2 m, road marks 0-1 m wide, records (`sOffset`,
//! `<type s>`) inside their lane section or road, a header of OpenDRIVE 1.0 to 1.8, and at
//! least one road. Anything else (a 1e9 m lane, a negative width, a 1 mm arc) is nonsense that
//! would silently distort or exhaust the map sampler. Numbers in messages are written by one
//! rule ([`Num`]): `1e300`, not 301 digits.

use super::lane_continuity;
use super::number_text::Num;
use super::reference_line::param_poly3_length;
use super::topology_checks::Place;
use super::xodr_schema;
use roxmltree::{Document, Node};

use super::opendrive::*;
use crate::geometry::MAX_HEADING_RAD;
use crate::{Error, Result};

/// Widest plausible lane (m).
const MAX_LANE_WIDTH: f64 = 10.0;
/// Some lane vehicles follow (driving, ramp, entry, exit) must be at least this wide
/// somewhere (m).
const MIN_DRIVING_WIDTH: f64 = 0.5;
/// Widest plausible road mark (m). Longitudinal lines are 0.10-0.30 m wide by national rules
/// (0.12 normal, 0.25-0.30 bold edge and lane-drop lines), block and hatched-area borders up to
/// 0.5 m; 1 m is twice the widest, and a wider "line" would paint over a third of a lane.
const MAX_ROAD_MARK_WIDTH: f64 = 1.0;
/// The minor revisions OpenDRIVE 1 has published (1.0 to 1.8).
const REV_MINORS: [&str; 9] = ["0", "1", "2", "3", "4", "5", "6", "7", "8"];
/// Longest plausible road (m).
const MAX_ROAD_LENGTH: f64 = 100_000.0;
/// Tightest plausible curvature (1/m): a 2 m radius.
const MAX_CURVATURE: f64 = 0.5;

/// How far (as a fraction of the length) a `<paramPoly3>`'s own curve length may differ from
/// its `<geometry>` length: the two describe one curve, and the map is built from both.
const CURVE_LENGTH_TOLERANCE: f64 = 0.02;
/// Farthest plausible position from the map origin (m).
const MAX_COORDINATE: f64 = 1e7;
/// Farthest plausible lane offset from the reference line (m).
const MAX_LANE_OFFSET: f64 = 50.0;

/// How far a geometry may start from where the previous one ended, or the last end from the
/// road's length (m): rounding in real files, not a gap.
/// The largest change of heading (rad) between one geometry's end and the next one's start:
/// a reference line bends, it does not break.
const MAX_KINK_RAD: f64 = 0.05;

/// The road `type` values of OpenDRIVE 1.4 to 1.8.
const ROAD_TYPES: [&str; 13] = [
    "unknown",
    "rural",
    "motorway",
    "town",
    "lowSpeed",
    "pedestrian",
    "bicycle",
    "townExpressway",
    "townCollector",
    "townArterial",
    "townPrivate",
    "townLocal",
    "townPlayStreet",
];

fn chain_slack(road_length: f64) -> f64 {
    0.5f64.max(1e-3 * road_length)
}

/// Largest |curvature| (1/m) of a poly3 or paramPoly3 geometry of `length`, sampled; `None`
/// for the shapes whose curvature is an attribute (checked where read).
fn polynomial_curvature(kind: &GeometryKind, length: f64) -> Option<f64> {
    const SAMPLES: usize = 256;
    let curvature = |du: f64, dv: f64, ddu: f64, ddv: f64| {
        (du * ddv - dv * ddu).abs() / (du * du + dv * dv).powf(1.5).max(1e-300)
    };
    let max_over = |range: f64, at: &dyn Fn(f64) -> f64| {
        (0..=SAMPLES)
            .map(|i| at(range * i as f64 / SAMPLES as f64))
            .fold(0.0, f64::max)
    };
    match *kind {
        // The road follows the cubic until it has run `length` metres, at some u <= length:
        // find that u, then sample the curvature up to it.
        GeometryKind::Poly3 { b, c, d, .. } => {
            // Walked in steps of arc length, not of u: a cubic that turns to near the
            // vertical within micrometres of u (a huge `d`) does so between any two u
            // samples, but its turn per metre of road is the curvature either way.
            let slope = |u: f64| b + 2.0 * c * u + 3.0 * d * u * u;
            let step = length / 4096.0;
            let (mut u, mut steepest) = (0.0_f64, 0.0_f64);
            for _ in 0..4096 {
                let heading = slope(u).atan();
                u += step * heading.cos();
                let turn = (slope(u).atan() - heading).abs();
                steepest = steepest.max(turn / step);
            }
            let sampled = max_over(u, &|u| curvature(1.0, slope(u), 0.0, 2.0 * c + 6.0 * d * u));
            Some(if steepest.is_finite() {
                sampled.max(steepest)
            } else {
                f64::INFINITY
            })
        }
        GeometryKind::ParamPoly3 { u, v, p_range } => {
            let range = match p_range {
                PRange::ArcLength => length,
                PRange::Normalized => 1.0,
            };
            let d1 = |c: [f64; 4], p: f64| c[1] + 2.0 * c[2] * p + 3.0 * c[3] * p * p;
            let d2 = |c: [f64; 4], p: f64| 2.0 * c[2] + 6.0 * c[3] * p;
            Some(max_over(range, &|p| {
                curvature(d1(u, p), d1(v, p), d2(u, p), d2(v, p))
            }))
        }
        _ => None,
    }
}

/// Rounding slack of a width polynomial that should end at exactly 0 (m).
const WIDTH_SLACK: f64 = 1e-6;

/// Parses OpenDRIVE text; `source_name` (usually the file path) is used in error messages.
pub fn parse_xodr(text: &str, source_name: &str) -> Result<OpenDrive> {
    parse(text, source_name, true)
}

/// [`parse_xodr`] without the road and lane topology checks: the reader alone, for tests of
/// documents that are only fragments of a network.
#[cfg(test)]
pub(super) fn read_xodr(text: &str, source_name: &str) -> Result<OpenDrive> {
    parse(text, source_name, false)
}

fn parse(text: &str, source_name: &str, check_topology: bool) -> Result<OpenDrive> {
    let doc = crate::xml::parse_document(text, source_name)?;
    let cx = Ctx {
        source: source_name,
        doc: &doc,
    };
    let root = doc.root_element();
    if root.tag_name().name() != "OpenDRIVE" {
        return Err(cx.err(
            root,
            format!(
                "root element is <{}>, expected <OpenDRIVE>",
                root.tag_name().name()
            ),
        ));
    }
    if let Some((node, message)) = xodr_schema::first_unknown(root, &xodr_schema::OPENDRIVE) {
        return Err(cx.err(node, message));
    }
    if let Some(header) = element(root, "header") {
        cx.enumerated(header, "revMajor", &["1"])?;
        cx.enumerated(header, "revMinor", &REV_MINORS)?;
    }
    let mut out = OpenDrive::default();
    for child in root.children().filter(Node::is_element) {
        match child.tag_name().name() {
            "road" => out.roads.push(cx.road(child)?),
            "junction" => out.junctions.push(cx.junction(child)?),
            _ => {}
        }
    }
    if out.roads.is_empty() {
        return Err(cx.err(
            root,
            "the document has no <road>; expected at least one road",
        ));
    }
    if check_topology {
        cx.check_junction_references(root, &out)?;
    }
    let widest_driving = out
        .roads
        .iter()
        .flat_map(|r| r.lane_sections.iter().map(move |s| (r, s)))
        .flat_map(|(r, sec)| {
            let end = section_end(r, sec);
            sec.left
                .iter()
                .chain(&sec.right)
                .filter(|l| l.kind.is_graph_lane())
                .flat_map(move |l| width_samples(l, sec.s, end).map(|(_, w)| w))
        })
        .fold(0.0, f64::max);
    if widest_driving < MIN_DRIVING_WIDTH {
        return Err(cx.err(
            root,
            format!(
                "no driving lane is {MIN_DRIVING_WIDTH} m wide anywhere (widest {} m); \
                 expected lanes {MIN_DRIVING_WIDTH}-{MAX_LANE_WIDTH} m wide",
                Num(widest_driving)
            ),
        ));
    }
    cx.check_no_vanishing_lane(root, &out)?;
    if let Some(problem) = check_topology
        .then(|| super::topology_checks::check(&out))
        .flatten()
    {
        return Err(cx.err(cx.node_of(root, &problem.place), problem.message));
    }
    Ok(out)
}

/// Where `sec` ends: the next section's start, or the road's end.
fn section_end(road: &Road, sec: &LaneSection) -> f64 {
    road.lane_sections
        .iter()
        .map(|s| s.s)
        .filter(|&s| s > sec.s)
        .fold(road.length, f64::min)
}

/// A lane's width at the start, middle and end of each `<width>` record's span within the
/// section `[start, end]`, with the road s of each sample.
fn width_samples(lane: &Lane, start: f64, end: f64) -> impl Iterator<Item = (f64, f64)> + '_ {
    lane.widths.iter().enumerate().flat_map(move |(k, w)| {
        let span_end = lane
            .widths
            .get(k + 1)
            .map_or(end - start, |next| next.s)
            .max(w.s);
        let length = span_end - w.s;
        cubic_extremes(w, length).map(move |ds| (start + w.s + ds, w.value(ds)))
    })
}

/// Where a cubic record takes its extreme values over `[0, length]`: the two ends and the
/// roots of its derivative inside (so a width that bulges between samples is still seen).
fn cubic_extremes(p: &Poly3Record, length: f64) -> impl Iterator<Item = f64> + use<> {
    // p'(ds) = b + 2c ds + 3d ds^2.
    let (qa, qb, qc) = (3.0 * p.d, 2.0 * p.c, p.b);
    let roots: [Option<f64>; 2] = if qa.abs() < 1e-15 {
        [(qb.abs() > 1e-15).then(|| -qc / qb), None]
    } else {
        let disc = qb * qb - 4.0 * qa * qc;
        if disc < 0.0 {
            [None, None]
        } else {
            let r = disc.sqrt();
            [Some((-qb + r) / (2.0 * qa)), Some((-qb - r) / (2.0 * qa))]
        }
    };
    [Some(0.0), Some(length)]
        .into_iter()
        .chain(roots)
        .flatten()
        .filter(move |ds| ds.is_finite() && (0.0..=length).contains(ds))
}

struct Ctx<'a, 'input> {
    source: &'a str,
    doc: &'a Document<'input>,
}

fn elements<'a, 'input>(
    node: Node<'a, 'input>,
    name: &'a str,
) -> impl Iterator<Item = Node<'a, 'input>> {
    node.children()
        .filter(move |c| c.is_element() && c.tag_name().name() == name)
}

fn element<'a, 'input>(node: Node<'a, 'input>, name: &str) -> Option<Node<'a, 'input>> {
    node.children()
        .find(|c| c.is_element() && c.tag_name().name() == name)
}

/// The `<lane>` of id `id` in the `section`th `<laneSection>` of `lanes` (in document order,
/// which is `s` order: the reader refuses sections out of order).
fn lane_node<'a, 'input>(
    lanes: Node<'a, 'input>,
    section: usize,
    id: i32,
) -> Option<Node<'a, 'input>> {
    elements(lanes, "laneSection").nth(section).and_then(|sec| {
        sec.descendants().find(|n| {
            n.has_tag_name("lane")
                && n.attribute("id").and_then(|v| v.trim().parse().ok()) == Some(id)
        })
    })
}

fn sort_by_s<T>(v: &mut [T], s: impl Fn(&T) -> f64) {
    v.sort_by(|a, b| s(a).total_cmp(&s(b)));
}

impl Ctx<'_, '_> {
    fn err(&self, node: Node, message: impl Into<String>) -> Error {
        crate::xml::error_at(self.doc, self.source, node, message)
    }

    /// The element of the document under `root` that `place` names (the nearest enclosing
    /// one that exists), for the line of a topology problem.
    fn node_of<'a, 'input>(&self, root: Node<'a, 'input>, place: &Place) -> Node<'a, 'input> {
        let with_id = |parent: Node<'a, 'input>, tag: &'a str, id: &str| {
            elements(parent, tag).find(|n| n.attribute("id").map(str::trim) == Some(id))
        };
        match place {
            Place::Road(id) => with_id(root, "road", id).unwrap_or(root),
            Place::Link { road, which } => with_id(root, "road", road)
                .map(|r| {
                    element(r, "link")
                        .and_then(|l| element(l, which))
                        .unwrap_or(r)
                })
                .unwrap_or(root),
            Place::Lane {
                road,
                section,
                lane,
            } => with_id(root, "road", road)
                .map(|r| {
                    element(r, "lanes")
                        .and_then(|l| elements(l, "laneSection").nth(*section))
                        .map(|sec| {
                            sec.descendants()
                                .find(|n| {
                                    n.has_tag_name("lane")
                                        && n.attribute("id").and_then(|v| v.trim().parse().ok())
                                            == Some(*lane)
                                })
                                .unwrap_or(sec)
                        })
                        .unwrap_or(r)
                })
                .unwrap_or(root),
            Place::Connection { junction, id } => with_id(root, "junction", junction)
                .map(|j| with_id(j, "connection", id).unwrap_or(j))
                .unwrap_or(root),
            Place::Junction(id) => with_id(root, "junction", id).unwrap_or(root),
        }
    }

    fn req_str<'n>(&self, node: Node<'n, '_>, name: &str) -> Result<&'n str> {
        node.attribute(name).ok_or_else(|| {
            self.err(
                node,
                format!(
                    "<{}> is missing required attribute `{name}`",
                    node.tag_name().name()
                ),
            )
        })
    }

    fn number(&self, node: Node, name: &str, raw: &str) -> Result<f64> {
        match raw.trim().parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(self.err(
                node,
                format!(
                    "<{}> attribute `{name}`: expected a finite number, found {raw:?}",
                    node.tag_name().name()
                ),
            )),
        }
    }

    fn req_f64(&self, node: Node, name: &str) -> Result<f64> {
        let raw = self.req_str(node, name)?;
        self.number(node, name, raw)
    }

    fn opt_f64(&self, node: Node, name: &str) -> Result<Option<f64>> {
        node.attribute(name)
            .map(|raw| self.number(node, name, raw))
            .transpose()
    }

    fn non_negative(&self, node: Node, name: &str) -> Result<f64> {
        let v = self.req_f64(node, name)?;
        if v < 0.0 {
            return Err(self.err(
                node,
                format!(
                    "<{}> attribute `{name}` is {}, expected a value >= 0",
                    node.tag_name().name(),
                    Num(v)
                ),
            ));
        }
        Ok(v)
    }

    /// A curvature (1/m) no tighter than a 2 m radius.
    fn curvature(&self, node: Node, name: &str) -> Result<f64> {
        let k = self.req_f64(node, name)?;
        if k.abs() > MAX_CURVATURE {
            return Err(self.err(
                node,
                format!(
                    "<{}> attribute `{name}` is {} 1/m, a radius of {} m; expected a radius of \
                     at least {} m (|{name}| <= {MAX_CURVATURE})",
                    node.tag_name().name(),
                    Num(k),
                    Num(1.0 / k.abs()),
                    1.0 / MAX_CURVATURE
                ),
            ));
        }
        Ok(k)
    }

    fn req_i32(&self, node: Node, name: &str) -> Result<i32> {
        let raw = self.req_str(node, name)?;
        raw.trim().parse::<i32>().map_err(|_| {
            self.err(
                node,
                format!(
                    "<{}> attribute `{name}`: expected an integer, found {raw:?}",
                    node.tag_name().name()
                ),
            )
        })
    }

    fn contact_point(&self, node: Node, name: &str) -> Result<Option<ContactPoint>> {
        match node.attribute(name) {
            None => Ok(None),
            Some("start") => Ok(Some(ContactPoint::Start)),
            Some("end") => Ok(Some(ContactPoint::End)),
            Some(other) => Err(self.err(
                node,
                format!(
                    "<{}> attribute `{name}`: expected \"start\" or \"end\", found {other:?}",
                    node.tag_name().name()
                ),
            )),
        }
    }

    /// A speed in the given unit, converted to m/s; "no limit" / "undefined" give `None`.
    fn speed(&self, node: Node) -> Result<Option<f64>> {
        let raw = self.req_str(node, "max")?;
        if matches!(raw.trim(), "no limit" | "undefined") {
            return Ok(None);
        }
        let v = self.number(node, "max", raw)?;
        let factor = match node.attribute("unit").unwrap_or("m/s") {
            "m/s" => 1.0,
            "km/h" => 1.0 / 3.6,
            "mph" => 0.44704,
            other => {
                return Err(self.err(
                    node,
                    format!(
                        "<speed> attribute `unit`: expected \"m/s\", \"km/h\" or \"mph\", found {other:?}"
                    ),
                ));
            }
        };
        let speed = v * factor;
        let max = crate::vehicle::MAX_SPEED;
        if !(speed > 0.0 && speed <= max) {
            return Err(self.err(
                node,
                format!(
                    "<speed> attribute `max` is {} ({} m/s); expected a limit in (0, {max}] m/s",
                    Num(v),
                    Num(speed)
                ),
            ));
        }
        Ok(Some(speed))
    }

    /// The attribute `name` of `node`, if given, refused unless it is one of `allowed` (the
    /// standard's values: a misspelt one would be taken for something else in silence).
    fn enumerated<'a>(
        &self,
        node: Node<'a, 'a>,
        name: &str,
        allowed: &[&str],
    ) -> Result<Option<&'a str>> {
        match node.attribute(name) {
            Some(value) if !allowed.contains(&value) => Err(self.err(
                node,
                format!(
                    "<{}> attribute `{name}` is `{value}`; expected one of {}",
                    node.tag_name().name(),
                    allowed.join(", ")
                ),
            )),
            value => Ok(value),
        }
    }

    /// Every road's `junction` names a `<junction>` of the document.
    fn check_junction_references(&self, root: Node, od: &OpenDrive) -> Result<()> {
        for (road, node) in od.roads.iter().zip(elements(root, "road")) {
            if let Some(junction) = &road.junction
                && !od.junctions.iter().any(|j| &j.id == junction)
            {
                return Err(self.err(
                    node,
                    format!(
                        "road {} lies in junction `{junction}`, which the document does not \
                         define; expected the id of a <junction>, or -1 for none",
                        road.id
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The road's `<planView>`: its geometries, in increasing s and chained end to start.
    fn plan_view(&self, node: Node, road: &mut Road) -> Result<()> {
        let plan_view = element(node, "planView")
            .ok_or_else(|| self.err(node, format!("road {} has no <planView>", road.id)))?;
        for g in elements(plan_view, "geometry") {
            let geometry = self.geometry(g)?;
            // The standard lists them in increasing s; a file that does not was written
            // wrong, and sorting would hide which record is.
            if let Some(previous) = road.geometries.last()
                && geometry.s <= previous.s
            {
                return Err(self.err(
                    g,
                    format!(
                        "road {}: <geometry> at s = {} comes after the previous one, at s = \
                         {}; expected geometries in increasing s",
                        road.id,
                        Num(geometry.s),
                        Num(previous.s)
                    ),
                ));
            }
            road.geometries.push(geometry);
        }
        if road.geometries.is_empty() {
            return Err(self.err(
                plan_view,
                format!("road {}: <planView> has no <geometry>", road.id),
            ));
        }
        sort_by_s(&mut road.geometries, |g| g.s);
        self.check_plan_view(plan_view, road)?;
        Ok(())
    }

    fn road(&self, node: Node) -> Result<Road> {
        let id = self.req_str(node, "id")?.to_string();
        if id.trim().is_empty() {
            return Err(self.err(node, "<road> attribute `id` is empty; expected an id"));
        }
        self.enumerated(node, "rule", &["RHT", "LHT"])?;
        let junction = match node.attribute("junction").map(str::trim) {
            None | Some("-1") | Some("") => None,
            Some(j) => Some(j.to_string()),
        };
        if node.attribute("rule") == Some("LHT") {
            return Err(self.err(
                node,
                format!(
                    "road {id} has rule=\"LHT\"; rtr supports right-hand traffic only (rule=\"RHT\")"
                ),
            ));
        }
        let mut road = Road {
            name: node.attribute("name").unwrap_or("").to_string(),
            length: self.road_length(node)?,
            junction,
            predecessor: None,
            successor: None,
            types: Vec::new(),
            geometries: Vec::new(),
            lane_offsets: Vec::new(),
            lane_sections: Vec::new(),
            id,
        };
        if let Some(link) = element(node, "link") {
            if let Some(p) = element(link, "predecessor") {
                road.predecessor = Some(self.road_link(p)?);
            }
            if let Some(p) = element(link, "successor") {
                road.successor = Some(self.road_link(p)?);
            }
        }
        for t in elements(node, "type") {
            let speed = match element(t, "speed") {
                Some(sp) => self.speed(sp)?,
                None => None,
            };
            self.enumerated(t, "type", &ROAD_TYPES)?;
            road.types.push(RoadType {
                s: self.road_position(t, &road)?,
                kind: self.req_str(t, "type")?.to_string(),
                speed,
            });
        }
        sort_by_s(&mut road.types, |t| t.s);
        self.plan_view(node, &mut road)?;
        let lanes = element(node, "lanes")
            .ok_or_else(|| self.err(node, format!("road {} has no <lanes>", road.id)))?;
        self.lane_offsets(lanes, &mut road)?;
        let mut section_nodes = Vec::new();
        for sec in elements(lanes, "laneSection") {
            let section = self.lane_section(sec)?;
            // A section starting at or past the road's end has no lanes to sample: refused,
            // not dropped in silence.
            if !(section.s >= 0.0 && section.s < road.length) {
                return Err(self.err(
                    sec,
                    format!(
                        "road {}: <laneSection> attribute `s` is {}; expected metres in [0, {}) \
                         (the road's length)",
                        road.id,
                        Num(section.s),
                        Num(road.length)
                    ),
                ));
            }
            if let Some(previous) = road.lane_sections.last()
                && section.s <= previous.s
            {
                return Err(self.err(
                    sec,
                    format!(
                        "road {}: <laneSection> at s = {} follows one at s = {}; expected lane \
                         sections in increasing s",
                        road.id,
                        Num(section.s),
                        Num(previous.s)
                    ),
                ));
            }
            road.lane_sections.push(section);
            section_nodes.push(sec);
        }
        if road.lane_sections.is_empty() {
            return Err(self.err(
                lanes,
                format!("road {}: <lanes> has no <laneSection>", road.id),
            ));
        }
        // The first section starts the road: before it, the road would have no lanes.
        let first = road.lane_sections[0].s;
        if first > chain_slack(road.length) {
            return Err(self.err(
                section_nodes[0],
                format!(
                    "road {}: the first <laneSection> starts at s = {first}; expected s = 0 \
                     (the road's first {first} m would have no lanes)",
                    road.id,
                    first = Num(first)
                ),
            ));
        }
        sort_by_s(&mut road.lane_sections, |s| s.s);
        self.check_widths(lanes, &road)?;
        if let Some((k, message)) = lane_continuity::first_section_break(&road) {
            return Err(self.err(section_nodes[k], message));
        }
        Ok(road)
    }

    /// The road's `<laneOffset>` records, in `s` order, each within reach of the reference
    /// line and starting where the previous one ended.
    fn lane_offsets(&self, lanes: Node, road: &mut Road) -> Result<()> {
        let mut offset_nodes = Vec::new();
        for o in elements(lanes, "laneOffset") {
            self.road_position(o, road)?;
            let offset = self.poly3(o, "s")?;
            let length = (road.length - offset.s).max(0.0);
            if let Some(ds) =
                cubic_extremes(&offset, length).find(|&ds| offset.value(ds).abs() > MAX_LANE_OFFSET)
            {
                return Err(self.err(
                    o,
                    format!(
                        "road {}: <laneOffset> moves the lanes {} m from the reference line at \
                         s={}; expected at most {MAX_LANE_OFFSET} m",
                        road.id,
                        Num(offset.value(ds)),
                        Num(offset.s + ds)
                    ),
                ));
            }
            if let Some(previous) = road.lane_offsets.last()
                && offset.s <= previous.s
            {
                return Err(self.err(
                    o,
                    format!(
                        "road {}: <laneOffset> at s = {} comes after the previous one, at s = \
                         {}; expected lane offsets in increasing s",
                        road.id,
                        Num(offset.s),
                        Num(previous.s)
                    ),
                ));
            }
            offset_nodes.push((offset.s, o));
            road.lane_offsets.push(offset);
        }
        if let Some((k, step)) = lane_continuity::first_step(&road.lane_offsets, false) {
            return Err(self.err(
                offset_nodes[k].1,
                format!(
                    "road {}: <laneOffset> at s={} moves the lanes {:.2} m sideways at once; \
                     expected it to start within {} m of where the previous one ended",
                    road.id,
                    Num(road.lane_offsets[k].s),
                    Num(step),
                    lane_continuity::MAX_EDGE_STEP
                ),
            ));
        }
        Ok(())
    }

    /// The `s` of a record along `road` (a `<type>`, a `<laneOffset>`): on the road, in
    /// [0, length].
    fn road_position(&self, node: Node, road: &Road) -> Result<f64> {
        let s = self.req_f64(node, "s")?;
        if !(0.0..=road.length).contains(&s) {
            return Err(self.err(
                node,
                format!(
                    "road {}: <{}> attribute `s` is {}; expected metres in [0, {}] (the \
                     road's length)",
                    road.id,
                    node.tag_name().name(),
                    Num(s),
                    Num(road.length)
                ),
            ));
        }
        Ok(s)
    }

    fn road_length(&self, node: Node) -> Result<f64> {
        let length = self.req_f64(node, "length")?;
        if !(length > 0.0 && length <= MAX_ROAD_LENGTH) {
            return Err(self.err(
                node,
                format!(
                    "<road> attribute `length` is {}; expected metres in (0, {MAX_ROAD_LENGTH}]",
                    Num(length)
                ),
            ));
        }
        Ok(length)
    }

    /// Every lane is 0-10 m wide along its whole section, and every lane record starts
    /// within it.
    fn check_widths(&self, lanes: Node, road: &Road) -> Result<()> {
        for (k, sec) in road.lane_sections.iter().enumerate() {
            let end = section_end(road, sec);
            for lane in sec.left.iter().chain(&sec.right) {
                self.check_lane_records(lanes, road, k, lane)?;
                let bad = width_samples(lane, sec.s, end)
                    .find(|&(_, w)| !(-WIDTH_SLACK..=MAX_LANE_WIDTH).contains(&w));
                if let Some((s, w)) = bad {
                    return Err(self.err(
                        lanes,
                        format!(
                            "road {}: lane {} of the laneSection at s={} is {} m wide at s={}; \
                             expected 0-{MAX_LANE_WIDTH} m",
                            road.id,
                            lane.id,
                            Num(sec.s),
                            Num(w),
                            Num(s)
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    /// Every lane vehicles follow is wider than 0 somewhere in its section: one 0 m wide all
    /// along would vanish from the map in silence (a lane that opens or closes passes).
    fn check_no_vanishing_lane(&self, root: Node, od: &OpenDrive) -> Result<()> {
        for (road, node) in od.roads.iter().zip(elements(root, "road")) {
            for (k, sec) in road.lane_sections.iter().enumerate() {
                let end = section_end(road, sec);
                let vanished = sec.left.iter().chain(&sec.right).find(|lane| {
                    lane.kind.is_graph_lane()
                        && width_samples(lane, sec.s, end).all(|(_, w)| w <= WIDTH_SLACK)
                });
                let Some(lane) = vanished else {
                    continue;
                };
                let lanes = element(node, "lanes").unwrap_or(node);
                return Err(self.err(
                    lane_node(lanes, k, lane.id).unwrap_or(lanes),
                    format!(
                        "road {}: lane {} ({}) of the laneSection at s={} is 0 m wide along the \
                         whole section, so it would vanish from the map; expected a lane \
                         vehicles follow to open somewhere (or a type such as `none`)",
                        road.id,
                        lane.id,
                        lane.kind.name(),
                        Num(sec.s)
                    ),
                ));
            }
        }
        Ok(())
    }

    /// A lane's `<width>`, `<roadMark>` and `<speed>` records start within the lane section
    /// (the `k`th of `road`): one past its end describes nothing of the road, written for
    /// another section or with `s` where `sOffset` belongs.
    fn check_lane_records(&self, lanes: Node, road: &Road, k: usize, lane: &Lane) -> Result<()> {
        let sec = &road.lane_sections[k];
        let length = section_end(road, sec) - sec.s;
        let limit = length + chain_slack(road.length);
        let late = (lane.widths.iter().map(|w| ("width", w.s)))
            .chain(lane.road_marks.iter().map(|m| ("roadMark", m.s_offset)))
            .chain(lane.speeds.iter().map(|v| ("speed", v.s_offset)))
            .find(|&(_, s)| s > limit);
        let Some((tag, s)) = late else {
            return Ok(());
        };
        // The width check came first and blamed <lanes>; the other records are found by line.
        let node = if tag == "width" {
            lanes
        } else {
            lane_node(lanes, k, lane.id)
                .and_then(|l| {
                    elements(l, tag).find(|r| {
                        r.attribute("sOffset")
                            .and_then(|v| v.trim().parse::<f64>().ok())
                            == Some(s)
                    })
                })
                .unwrap_or(lanes)
        };
        Err(self.err(
            node,
            format!(
                "road {}: lane {} of the laneSection at s={} has a <{tag}> at sOffset={}, past \
                 the section's end ({} m long); expected offsets within the section",
                road.id,
                lane.id,
                Num(sec.s),
                Num(s),
                Num(length)
            ),
        ))
    }

    fn road_link(&self, node: Node) -> Result<RoadLink> {
        let element_type = match self.req_str(node, "elementType")? {
            "road" => ElementType::Road,
            "junction" => ElementType::Junction,
            other => {
                return Err(self.err(
                    node,
                    format!(
                        "<{}> attribute `elementType`: expected \"road\" or \"junction\", found {other:?}",
                        node.tag_name().name()
                    ),
                ));
            }
        };
        let contact_point = self.contact_point(node, "contactPoint")?;
        if element_type == ElementType::Road && contact_point.is_none() {
            return Err(self.err(
                node,
                format!(
                    "<{}> links to a road but has no `contactPoint` (expected \"start\" or \"end\")",
                    node.tag_name().name()
                ),
            ));
        }
        Ok(RoadLink {
            element_type,
            element_id: self.req_str(node, "elementId")?.to_string(),
            contact_point,
        })
    }

    fn poly3(&self, node: Node, s_name: &str) -> Result<Poly3Record> {
        Ok(Poly3Record {
            s: self.req_f64(node, s_name)?,
            a: self.req_f64(node, "a")?,
            b: self.req_f64(node, "b")?,
            c: self.req_f64(node, "c")?,
            d: self.req_f64(node, "d")?,
        })
    }

    /// The one shape child (`<line>`, `<arc>`, ...) of a `<geometry>`; additional data beside it
    /// is not a shape.
    fn shape<'a, 'input>(&self, node: Node<'a, 'input>) -> Result<Node<'a, 'input>> {
        let shapes: Vec<Node> = node
            .children()
            .filter(|c| c.is_element() && !xodr_schema::is_additional_data(*c))
            .collect();
        let shape = match shapes.as_slice() {
            [one] => *one,
            [] => return Err(self.err(node, "<geometry> has no shape child; expected one of line, arc, spiral, poly3, paramPoly3")),
            [_, second, ..] => return Err(self.err(*second, "<geometry> has more than one shape child; expected exactly one of line, arc, spiral, poly3, paramPoly3")),
        };
        Ok(shape)
    }

    fn geometry(&self, node: Node) -> Result<Geometry> {
        let shape = self.shape(node)?;
        let kind = match shape.tag_name().name() {
            "line" => GeometryKind::Line,
            "arc" => GeometryKind::Arc {
                curvature: self.curvature(shape, "curvature")?,
            },
            "spiral" => GeometryKind::Spiral {
                curv_start: self.curvature(shape, "curvStart")?,
                curv_end: self.curvature(shape, "curvEnd")?,
            },
            "poly3" => GeometryKind::Poly3 {
                a: self.req_f64(shape, "a")?,
                b: self.req_f64(shape, "b")?,
                c: self.req_f64(shape, "c")?,
                d: self.req_f64(shape, "d")?,
            },
            "paramPoly3" => {
                let mut u = [0.0; 4];
                let mut v = [0.0; 4];
                for (i, k) in ["a", "b", "c", "d"].iter().enumerate() {
                    u[i] = self.req_f64(shape, &format!("{k}U"))?;
                    v[i] = self.req_f64(shape, &format!("{k}V"))?;
                }
                let p_range = match shape.attribute("pRange") {
                    None | Some("normalized") => PRange::Normalized,
                    Some("arcLength") => PRange::ArcLength,
                    Some(other) => {
                        return Err(self.err(
                            shape,
                            format!(
                                "<paramPoly3> attribute `pRange`: expected \"arcLength\" or \"normalized\", found {other:?}"
                            ),
                        ));
                    }
                };
                if u[1..].iter().chain(&v[1..]).all(|c| *c == 0.0) {
                    return Err(self.err(
                        shape,
                        "<paramPoly3> has every b, c, d coefficient 0: the curve is a single \
                         point; expected a curve",
                    ));
                }
                GeometryKind::ParamPoly3 { u, v, p_range }
            }
            other => {
                return Err(self.err(
                    shape,
                    format!(
                        "unsupported planView geometry <{other}>; expected one of line, arc, spiral, poly3, paramPoly3"
                    ),
                ));
            }
        };
        let geometry = Geometry {
            s: self.non_negative(node, "s")?,
            x: self.coordinate(node, "x")?,
            y: self.coordinate(node, "y")?,
            hdg: self.heading(node, "hdg")?,
            length: self.non_negative(node, "length")?,
            kind,
        };
        if geometry.length <= 0.0 {
            return Err(self.err(
                node,
                "<geometry> attribute `length` is 0; expected metres > 0",
            ));
        }
        if let GeometryKind::ParamPoly3 { u, v, p_range } = &geometry.kind {
            let curve = param_poly3_length(u, v, *p_range, geometry.length);
            if (curve - geometry.length).abs() > CURVE_LENGTH_TOLERANCE * geometry.length + 0.1 {
                return Err(self.err(
                    shape,
                    format!(
                        "<paramPoly3> draws a curve {:.2} m long, but its <geometry> says \
                         `length` {} m; expected the two to agree (within {} %)",
                        Num(curve),
                        Num(geometry.length),
                        CURVE_LENGTH_TOLERANCE * 100.0
                    ),
                ));
            }
        }
        if let GeometryKind::ParamPoly3 { .. } = &geometry.kind {
            // A curve whose (u, v) run against +u starts the road backwards: cars would be
            // placed facing one way and driven the other.
            let turn = crate::geometry::wrap_angle(geometry.eval(0.0).hdg - geometry.hdg).abs();
            if turn > std::f64::consts::FRAC_PI_2 {
                return Err(self.err(
                    shape,
                    format!(
                        "<paramPoly3> starts {turn:.2} rad away from its <geometry> `hdg` (bU \
                         and bV point backwards): the curve is drawn against the road's \
                         direction; expected it to start along `hdg`"
                    ),
                ));
            }
        }
        if let Some(k) = polynomial_curvature(&geometry.kind, geometry.length)
            && k > MAX_CURVATURE
        {
            return Err(self.err(
                shape,
                format!(
                    "<{}> bends at a radius of {} m; expected a radius of at least {} m",
                    shape.tag_name().name(),
                    Num(1.0 / k),
                    1.0 / MAX_CURVATURE
                ),
            ));
        }
        Ok(geometry)
    }

    /// A heading in radians, as the standard says: beyond one turn it is almost surely degrees
    /// (every other reader of rtr refuses headings the same way).
    fn heading(&self, node: Node, name: &str) -> Result<f64> {
        let h = self.req_f64(node, name)?;
        if h.abs() > MAX_HEADING_RAD {
            return Err(self.err(
                node,
                format!(
                    "<{}> attribute `{name}` is {}: looks like degrees; expected radians, \
                     |{name}| <= 2 pi",
                    node.tag_name().name(),
                    Num(h)
                ),
            ));
        }
        Ok(h)
    }

    /// A position (m) within [`MAX_COORDINATE`] of the origin.
    fn coordinate(&self, node: Node, name: &str) -> Result<f64> {
        let v = self.req_f64(node, name)?;
        if v.abs() > MAX_COORDINATE {
            return Err(self.err(
                node,
                format!(
                    "<{}> attribute `{name}` is {} m; expected |{name}| <= {MAX_COORDINATE} m \
                     (metres from the map origin)",
                    node.tag_name().name(),
                    Num(v)
                ),
            ));
        }
        Ok(v)
    }

    /// The road's geometries, sorted, follow one another: each starts where the previous one
    /// ends, in s and in place and heading, and the last ends at the road's length (within
    /// [`chain_slack`] and [`MAX_KINK_RAD`]).
    fn check_plan_view(&self, plan_view: Node, road: &Road) -> Result<()> {
        for pair in road.geometries.windows(2) {
            let (previous, next) = (&pair[0], &pair[1]);
            let end = previous.eval(previous.length);
            let gap = (end.x - next.x).hypot(end.y - next.y);
            let kink = crate::geometry::wrap_angle(next.hdg - end.hdg).abs();
            if gap > chain_slack(road.length) || kink > MAX_KINK_RAD {
                let node = elements(plan_view, "geometry")
                    .find(|n| n.attribute("s").and_then(|v| v.trim().parse().ok()) == Some(next.s))
                    .unwrap_or(plan_view);
                return Err(self.err(
                    node,
                    format!(
                        "road {}: the <geometry> at s={} starts at ({}, {}) heading {} rad, but \
                         the previous one ends at ({:.3}, {:.3}) heading {:.4} rad ({:.3} m \
                         and {:.4} rad apart); expected a reference line without jumps or \
                         kinks",
                        road.id,
                        Num(next.s),
                        Num(next.x),
                        Num(next.y),
                        Num(next.hdg),
                        Num(end.x),
                        Num(end.y),
                        Num(end.hdg),
                        Num(gap),
                        Num(kink)
                    ),
                ));
            }
        }
        let mut end = 0.0;
        for g in &road.geometries {
            if (g.s - end).abs() > chain_slack(road.length) {
                return Err(self.err(
                    plan_view,
                    format!(
                        "road {}: a <geometry> starts at s={} but the previous one ends at s={}; \
                         expected geometries that follow one another",
                        road.id,
                        Num(g.s),
                        Num(end)
                    ),
                ));
            }
            end = g.s + g.length;
        }
        if (end - road.length).abs() > chain_slack(road.length) {
            return Err(self.err(
                plan_view,
                format!(
                    "road {}: the <geometry> elements end at s={} but the road is {} m long; \
                     expected them to cover the road",
                    road.id,
                    Num(end),
                    Num(road.length)
                ),
            ));
        }
        Ok(())
    }

    fn lane_section(&self, node: Node) -> Result<LaneSection> {
        self.enumerated(node, "singleSide", &["true", "false", "0", "1"])?;
        let mut sec = LaneSection {
            s: self.req_f64(node, "s")?,
            left: Vec::new(),
            center: None,
            right: Vec::new(),
        };
        for side in node.children().filter(Node::is_element) {
            let name = side.tag_name().name();
            for lane_node in elements(side, "lane") {
                let lane = self.lane(lane_node)?;
                let ok = match name {
                    "left" => lane.id > 0,
                    "right" => lane.id < 0,
                    "center" => lane.id == 0,
                    _ => true,
                };
                if !ok {
                    return Err(self.err(
                        lane_node,
                        format!(
                            "lane id {} in <{name}>; expected positive ids in <left>, 0 in <center>, negative in <right>",
                            lane.id
                        ),
                    ));
                }
                match name {
                    "left" => sec.left.push(lane),
                    "right" => sec.right.push(lane),
                    "center" => sec.center = Some(lane),
                    _ => {}
                }
            }
        }
        if sec.center.is_none() {
            return Err(self.err(
                node,
                format!(
                    "laneSection at s={}: no <center> lane; expected <center><lane id=\"0\" \
                     .../></center> (the reference line the lanes are counted from)",
                    Num(sec.s)
                ),
            ));
        }
        sec.left.sort_by_key(|l| l.id);
        sec.right.sort_by_key(|l| -l.id);
        for side in [&sec.left, &sec.right] {
            for (k, lane) in side.iter().enumerate() {
                if lane.id.unsigned_abs() as usize != k + 1 {
                    return Err(self.err(
                        node,
                        format!(
                            "laneSection at s={}: lane ids on one side must be consecutive from ±1, found {}",
                            Num(sec.s),
                            side.iter().map(|l| l.id.to_string()).collect::<Vec<_>>().join(", ")
                        ),
                    ));
                }
            }
        }
        Ok(sec)
    }

    fn lane(&self, node: Node) -> Result<Lane> {
        let id = self.req_i32(node, "id")?;
        self.enumerated(node, "level", &["true", "false", "0", "1"])?;
        let kind = self.req_str(node, "type")?;
        if !LaneType::is_standard(kind) {
            return Err(self.err(
                node,
                format!(
                    "lane {id}: unknown lane type `{kind}`; expected one of OpenDRIVE's: {}",
                    LaneType::standard_names().join(", ")
                ),
            ));
        }
        let mut lane = Lane {
            id,
            kind: LaneType::from_name(kind),
            widths: Vec::new(),
            road_marks: Vec::new(),
            speeds: Vec::new(),
            predecessors: Vec::new(),
            successors: Vec::new(),
        };
        let mut last_offset: std::collections::HashMap<&str, f64> = Default::default();
        let mut width_nodes = Vec::new();
        for child in node.children().filter(Node::is_element) {
            let tag = child.tag_name().name();
            if matches!(tag, "width" | "roadMark" | "speed") {
                let offset = self.s_offset(child)?;
                if let Some(previous) = last_offset.insert(tag, offset)
                    && offset <= previous
                {
                    // Each record holds from its sOffset to the next one's: out of order, the
                    // lane would take one record's value everywhere.
                    return Err(self.err(
                        child,
                        format!(
                            "lane {id}: <{tag}> at sOffset = {} follows one at sOffset = {}; \
                             expected <{tag}> records in increasing sOffset",
                            Num(offset),
                            Num(previous)
                        ),
                    ));
                }
            }
            match tag {
                "width" => {
                    lane.widths.push(self.poly3(child, "sOffset")?);
                    width_nodes.push(child);
                }
                "border" => {
                    return Err(self.err(
                        child,
                        format!(
                            "lane {id} is described by <border>, which rtr does not support; expected <width> records"
                        ),
                    ));
                }
                "roadMark" => lane.road_marks.push(self.road_mark(child)?),
                "speed" => lane.speeds.push(LaneSpeed {
                    s_offset: self.s_offset(child)?,
                    max: self.speed(child)?,
                }),
                "link" => {
                    for p in elements(child, "predecessor") {
                        lane.predecessors.push(self.req_i32(p, "id")?);
                    }
                    for p in elements(child, "successor") {
                        lane.successors.push(self.req_i32(p, "id")?);
                    }
                }
                _ => {}
            }
        }
        if id != 0 && lane.widths.is_empty() {
            return Err(self.err(node, format!("lane {id} has no <width> record")));
        }
        // In document order, which is sOffset order (checked above).
        if let Some((k, step)) = lane_continuity::first_step(&lane.widths, true) {
            return Err(self.err(
                width_nodes[k],
                format!(
                    "lane {id}: <width> at sOffset = {} changes the lane's width by {:.2} m \
                     at once; expected it to start within {} m of the width the previous record \
                     ended with",
                    Num(lane.widths[k].s),
                    Num(step),
                    lane_continuity::MAX_EDGE_STEP
                ),
            ));
        }
        sort_by_s(&mut lane.widths, |w| w.s);
        sort_by_s(&mut lane.road_marks, |m| m.s_offset);
        sort_by_s(&mut lane.speeds, |m| m.s_offset);
        Ok(lane)
    }

    /// A lane record's `sOffset`: metres from the lane section's start, so >= 0 (its end is
    /// checked with the section's, in [`Self::check_lane_records`]).
    fn s_offset(&self, node: Node) -> Result<f64> {
        let offset = self.req_f64(node, "sOffset")?;
        if offset < 0.0 {
            return Err(self.err(
                node,
                format!(
                    "<{}> attribute `sOffset` is {}; expected metres >= 0 from the lane section \
                     start",
                    node.tag_name().name(),
                    Num(offset)
                ),
            ));
        }
        Ok(offset)
    }

    fn road_mark(&self, node: Node) -> Result<RoadMarkRecord> {
        let width = self.opt_f64(node, "width")?;
        if let Some(w) = width
            && !(0.0..=MAX_ROAD_MARK_WIDTH).contains(&w)
        {
            return Err(self.err(
                node,
                format!(
                    "<roadMark> attribute `width` is {} m; expected a line 0-{MAX_ROAD_MARK_WIDTH} \
                     m wide",
                    Num(w)
                ),
            ));
        }
        Ok(RoadMarkRecord {
            s_offset: self.s_offset(node)?,
            kind: RoadMark::from_name(
                self.enumerated(node, "type", &RoadMark::standard_names())?
                    .unwrap_or(self.req_str(node, "type")?),
            ),
            color: self
                .enumerated(node, "color", &ROAD_MARK_COLORS)?
                .map(str::to_string),
            width,
        })
    }

    fn junction(&self, node: Node) -> Result<Junction> {
        let mut j = Junction {
            id: self.req_str(node, "id")?.to_string(),
            name: node.attribute("name").unwrap_or("").to_string(),
            connections: Vec::new(),
        };
        for c in elements(node, "connection") {
            let contact_point = self.contact_point(c, "contactPoint")?.ok_or_else(|| {
                self.err(
                    c,
                    "<connection> is missing required attribute `contactPoint` (expected \"start\" or \"end\")",
                )
            })?;
            let mut lane_links = Vec::new();
            for l in elements(c, "laneLink") {
                lane_links.push((self.req_i32(l, "from")?, self.req_i32(l, "to")?));
            }
            j.connections.push(Connection {
                id: self.req_str(c, "id")?.to_string(),
                incoming_road: self.req_str(c, "incomingRoad")?.to_string(),
                connecting_road: self.req_str(c, "connectingRoad")?.to_string(),
                contact_point,
                lane_links,
            });
        }
        Ok(j)
    }
}
