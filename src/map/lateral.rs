//! Lateral layout of a road: where each lane's boundaries lie across the reference line at a
//! given `s`, from the laneOffset and the width polynomials. `t` is measured to the left of the
//! reference line. Polynomials are not extrapolated backwards: before a record's start its value
//! at the start is used.

use super::opendrive::{Lane, LaneSection, Poly3Record, Road, RoadMark, record_at};

/// Value and s-derivative of the record in effect at `s` (records start at `start(r)`).
fn poly_at(records: &[Poly3Record], s: f64) -> (f64, f64) {
    match record_at(records, s, |r| r.s) {
        Some(r) => {
            let ds = (s - r.s).max(0.0);
            (r.value(ds), r.derivative(ds))
        }
        None => (0.0, 0.0),
    }
}

/// laneOffset: shift of the centre lane from the reference line, and its derivative.
pub fn lane_offset(road: &Road, s: f64) -> (f64, f64) {
    poly_at(&road.lane_offsets, s)
}

/// Index of the lane section in effect at `s`.
pub fn section_index(road: &Road, s: f64) -> usize {
    road.lane_sections
        .partition_point(|sec| sec.s <= s)
        .saturating_sub(1)
}

/// End of section `k`: the next section's start or the road's end.
pub fn section_end(road: &Road, k: usize) -> f64 {
    road.lane_sections
        .get(k + 1)
        .map_or(road.length, |next| next.s)
}

/// Width and its derivative of `lane` at road `s` (negative widths count as 0).
pub fn lane_width(lane: &Lane, section_s: f64, s: f64) -> (f64, f64) {
    let (w, dw) = poly_at(&lane.widths, s - section_s);
    if w > 0.0 { (w, dw) } else { (0.0, 0.0) }
}

/// The boundaries of one lane at some `s`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LaneSpan {
    pub id: i32,
    /// t of the boundary toward the centre lane, and its s-derivative.
    pub inner: f64,
    pub d_inner: f64,
    /// t of the boundary away from the centre lane, and its s-derivative.
    pub outer: f64,
    pub d_outer: f64,
}

impl LaneSpan {
    pub fn contains(&self, t: f64) -> bool {
        self.inner.min(self.outer) <= t && t <= self.inner.max(self.outer)
    }

    pub fn width(&self) -> f64 {
        (self.outer - self.inner).abs()
    }
}

/// Calls `f(lane, span)` for every non-centre lane of `section` at `s`, innermost first on each
/// side. Allocation-free because the map queries call it for every tested point.
pub fn for_each_span(
    road: &Road,
    section: &LaneSection,
    s: f64,
    mut f: impl FnMut(&Lane, LaneSpan),
) {
    let (offset, d_offset) = lane_offset(road, s);
    for (lanes, sign) in [(&section.left, 1.0), (&section.right, -1.0)] {
        let (mut t, mut dt) = (offset, d_offset);
        for lane in lanes {
            let (w, dw) = lane_width(lane, section.s, s);
            let span = LaneSpan {
                id: lane.id,
                inner: t,
                d_inner: dt,
                outer: t + sign * w,
                d_outer: dt + sign * dw,
            };
            f(lane, span);
            t = span.outer;
            dt = span.d_outer;
        }
    }
}

/// The road mark of the boundary between `lane` and its neighbour toward the centre: in
/// OpenDRIVE each lane's `<roadMark>` describes its outer boundary, so the inner one carries
/// the mark of the next lane inward (or of the centre lane).
pub fn inner_mark(section: &LaneSection, lane_id: i32, s: f64) -> RoadMark {
    let inward = lane_id - lane_id.signum();
    section
        .lane(inward)
        .map_or(RoadMark::None, |l| own_mark(l, section.s, s))
}

/// The mark `lane` itself declares at road `s` (its outer boundary).
pub fn own_mark(lane: &Lane, section_s: f64, s: f64) -> RoadMark {
    record_at(&lane.road_marks, s - section_s, |m| m.s_offset)
        .map_or(RoadMark::None, |m| m.kind.clone())
}
