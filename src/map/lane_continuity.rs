//! Lane edges are continuous along a road. OpenDRIVE describes them piecewise (laneOffset
//! records, width records within a lane section, lane sections linked lane to lane), and each
//! piece is valid alone; a piece that starts away from where the previous one ended puts a
//! step in the carriageway that no vehicle can follow, and a map drawn from it falls apart.

use super::lateral::{LaneSpan, for_each_span};
use super::number_text::Num;
use super::opendrive::{Poly3Record, Road};

/// The largest step an edge may take where one record or section hands over to the next (m):
/// the same bound as between linked roads.
pub const MAX_EDGE_STEP: f64 = super::topology_checks::EDGE_TOLERANCE;

/// The first record of `records` (sorted, each holding until the next starts) that starts
/// more than [`MAX_EDGE_STEP`] away from where the previous one ended: its index and the
/// step. Widths (`widths`) count below zero as zero, as the lane layout does.
pub fn first_step(records: &[Poly3Record], widths: bool) -> Option<(usize, f64)> {
    let clamp = |v: f64| if widths { v.max(0.0) } else { v };
    records.windows(2).enumerate().find_map(|(k, pair)| {
        let end = clamp(pair[0].value(pair[1].s - pair[0].s));
        let step = clamp(pair[1].a) - end;
        (step.abs() > MAX_EDGE_STEP).then_some((k + 1, step))
    })
}

/// The first place where a lane ends a section with its edges more than [`MAX_EDGE_STEP`] from
/// where the lane that continues it ([`super::opendrive::LaneSection::links_to`]: declared
/// links, else the same id) starts the next one: the index of that next section and what is
/// wrong. A lane that closes (narrows to about nothing) merges into its
/// successor, and one that opens splits from its predecessor: their edges need not meet.
pub fn first_section_break(road: &Road) -> Option<(usize, String)> {
    road.lane_sections
        .windows(2)
        .enumerate()
        .find_map(|(k, pair)| {
            let (section, next) = (&pair[0], &pair[1]);
            let at = next.s;
            let mut ends: Vec<LaneSpan> = Vec::new();
            for_each_span(road, section, at, |_, span| ends.push(span));
            let mut starts: Vec<LaneSpan> = Vec::new();
            for_each_span(road, next, at, |_, span| starts.push(span));
            section.links_to(next).into_iter().find_map(|(from, to)| {
                let end = ends.iter().find(|s| s.id == from)?;
                let start = starts.iter().find(|s| s.id == to)?;
                if end.width().min(start.width()) <= MAX_EDGE_STEP {
                    return None;
                }
                let step = (end.inner - start.inner)
                    .abs()
                    .max((end.outer - start.outer).abs());
                (step > MAX_EDGE_STEP).then(|| {
                    (
                        k + 1,
                        format!(
                            "road {}: lane {from} ends the laneSection at s={} with its edges at \
                             t = {:.2} / {:.2} m, but lane {to}, which continues it in the next \
                             one, starts at t = {:.2} / {:.2} m ({:.2} m apart); expected \
                             joined lanes to meet within {MAX_EDGE_STEP} m",
                            road.id,
                            Num(section.s),
                            Num(end.inner),
                            Num(end.outer),
                            Num(start.inner),
                            Num(start.outer),
                            Num(step)
                        ),
                    )
                })
            })
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(s: f64, a: f64, b: f64) -> Poly3Record {
        Poly3Record {
            s,
            a,
            b,
            c: 0.0,
            d: 0.0,
        }
    }

    #[test]
    fn a_record_that_starts_where_the_last_ended_is_continuous() {
        // 3.5 m widening at 0.02 m/m reaches 4.5 m at 50 m.
        let smooth = [record(0.0, 3.5, 0.02), record(50.0, 4.5, 0.0)];
        assert_eq!(first_step(&smooth, true), None);
        let rounded = [record(0.0, 3.5, 0.0), record(50.0, 3.9, 0.0)];
        assert_eq!(first_step(&rounded, true), None);
        let step = [
            record(0.0, 3.5, 0.0),
            record(20.0, 3.5, 0.0),
            record(50.0, 9.0, 0.0),
        ];
        assert_eq!(first_step(&step, true), Some((2, 5.5)));
        // A lane narrowing below zero is a zero-width lane: it may reopen from zero.
        let closed = [record(0.0, 1.0, -0.1), record(30.0, 0.0, 0.1)];
        assert_eq!(first_step(&closed, true), None);
        // An offset has a sign: -2 m to +2 m is a 4 m jump.
        let offset = [record(0.0, -2.0, 0.0), record(10.0, 2.0, 0.0)];
        assert_eq!(first_step(&offset, false), Some((1, 4.0)));
    }
}
