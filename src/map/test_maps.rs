//! Tests of the sampled map and its queries on the real A9 map and hand-built roads.

use std::f64::consts::PI;
use std::path::Path;

use super::*;
use crate::geometry::OrientedBox;

pub(super) const A9: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/data/automatum-a9/staticWorld.xodr"
);

pub(super) fn a9() -> Map {
    Map::from_xodr_file(Path::new(A9)).expect("the A9 map loads")
}

/// A straight road along +x from the origin. `lanes`: (id, type, width a b c d, roadMark).
pub(super) fn straight_xodr(
    length: f64,
    lanes: &[(i32, &str, [f64; 4], &str)],
    offset: Option<[f64; 4]>,
) -> String {
    let lane_xml = |l: &(i32, &str, [f64; 4], &str)| {
        format!(
            "<lane id=\"{}\" type=\"{}\"><width sOffset=\"0\" a=\"{}\" b=\"{}\" c=\"{}\" d=\"{}\"/>\
             <roadMark sOffset=\"0\" type=\"{}\"/></lane>",
            l.0, l.1, l.2[0], l.2[1], l.2[2], l.2[3], l.3
        )
    };
    let side = |pos: bool| -> String {
        let mut v: Vec<_> = lanes.iter().filter(|l| (l.0 > 0) == pos).collect();
        v.sort_by_key(|l| -l.0);
        v.into_iter().map(lane_xml).collect()
    };
    let offset = offset.map_or(String::new(), |o| {
        format!(
            "<laneOffset s=\"0\" a=\"{}\" b=\"{}\" c=\"{}\" d=\"{}\"/>",
            o[0], o[1], o[2], o[3]
        )
    });
    format!(
        "<?xml version=\"1.0\"?><OpenDRIVE><header revMajor=\"1\" revMinor=\"6\"/>\
         <road id=\"7\" length=\"{length}\" junction=\"-1\"><planView>\
         <geometry s=\"0\" x=\"0\" y=\"0\" hdg=\"0\" length=\"{length}\"><line/></geometry></planView>\
         <lanes>{offset}<laneSection s=\"0\"><left>{}</left>\
         <center><lane id=\"0\" type=\"none\"><roadMark sOffset=\"0\" type=\"solid\"/></lane></center>\
         <right>{}</right></laneSection></lanes></road></OpenDRIVE>",
        side(true),
        side(false)
    )
}

/// Two lanes each way around a 3 m `none` median: right -1, -2 at y in [-7, 0], left lane 1
/// (median) at [0, 3] and 2, 3 at [3, 10].
fn divided() -> Map {
    let lanes = [
        (1, "none", [3.0, 0.0, 0.0, 0.0], "solid"),
        (2, "driving", [3.5, 0.0, 0.0, 0.0], "broken"),
        (3, "driving", [3.5, 0.0, 0.0, 0.0], "solid"),
        (-1, "driving", [3.5, 0.0, 0.0, 0.0], "broken"),
        (-2, "driving", [3.5, 0.0, 0.0, 0.0], "solid"),
    ];
    Map::from_xodr_str(&straight_xodr(100.0, &lanes, None), "divided").expect("valid map")
}

/// Index of the lane with OpenDRIVE id `id` on road `road` (first section that has it).
pub(super) fn lane_index(map: &Map, road: &str, id: i32) -> usize {
    map.lanes()
        .iter()
        .position(|l| l.road_id == road && l.id == id)
        .unwrap_or_else(|| panic!("lane {id} of road {road} exists"))
}

fn car(center: [f64; 2], heading: f64) -> OrientedBox {
    OrientedBox::new(center, heading, 4.5, 1.8)
}

#[test]
fn a9_length_lanes_and_directions() {
    let map = a9();
    assert!((map.road_length() - 266.281_170_003_393).abs() < 1e-9);
    assert_eq!(map.driving_lane_count(), 6);
    assert_eq!(
        map.lanes().len(),
        10,
        "2 shoulders, 2 median halves, 6 driving lanes"
    );
    let k = -0.000_322_282_793_482_797;
    for lane in map.lanes() {
        assert!((lane.speed_limit - 100.0 / 3.6).abs() < 1e-12);
        assert!(lane.s.windows(2).all(|w| w[1] > w[0]));
        // Lanes are parallel offset curves of the arc: length = L (1 - t k).
        let p = eval_road(&map.opendrive().unwrap().roads[0], lane.road_s[0]);
        let c = lane.centerline[0];
        let t = (c[1] - p.y) * p.hdg.cos() - (c[0] - p.x) * p.hdg.sin();
        let expect = 266.281_170_003_393 * (1.0 - t * k);
        assert!(
            (lane.length() - expect).abs() < 1e-3,
            "lane {} {} vs {expect}",
            lane.id,
            lane.length()
        );
        // Right lanes start at s = 0 along the road, left lanes at s = L against it.
        let start_hdg = if lane.id < 0 { p.hdg } else { p.hdg + PI };
        assert!(
            wrap_angle_diff(lane.headings[0], start_hdg) < 1e-9,
            "lane {}",
            lane.id
        );
    }
    let l = &map.lanes()[lane_index(&map, "0", -2)];
    assert_eq!(
        (l.left_mark.clone(), l.right_mark.clone()),
        (RoadMark::Solid, RoadMark::Broken)
    );
    let l = &map.lanes()[lane_index(&map, "0", 4)];
    assert_eq!(
        (l.left_mark.clone(), l.right_mark.clone()),
        (RoadMark::Broken, RoadMark::Solid)
    );
    assert!((map.lanes()[lane_index(&map, "0", -5)].widths[10] - 2.6).abs() < 1e-12);
}

fn wrap_angle_diff(a: f64, b: f64) -> f64 {
    crate::geometry::wrap_angle(a - b).abs()
}

#[test]
fn a9_neighbours_stay_within_a_carriageway() {
    let map = a9();
    let idx = |id| lane_index(&map, "0", id);
    let lanes = map.lanes();
    assert_eq!(lanes[idx(-2)].left_neighbour, None, "lane -1 is the median");
    assert_eq!(lanes[idx(-2)].right_neighbour, Some(idx(-3)));
    assert_eq!(
        lanes[idx(-4)].right_neighbour,
        None,
        "lane -5 is a shoulder"
    );
    assert_eq!(lanes[idx(3)].left_neighbour, Some(idx(2)));
    assert_eq!(lanes[idx(2)].left_neighbour, None);
    assert!(
        lanes
            .iter()
            .all(|l| l.successors.is_empty() && l.predecessors.is_empty())
    );
}

#[test]
fn a9_box_queries() {
    let map = a9();
    let road = &map.opendrive().unwrap().roads[0];
    let at = |s: f64, t: f64| eval_road(road, s).offset(t);
    let hdg = eval_road(road, 100.0).hdg;
    // Lane -3 is at t in [-10.65, -6.95]; the median (lanes 1 and -1) at [-3.05, 3.05].
    assert_eq!(
        map.box_on_road(&car(at(100.0, -8.8), hdg)),
        BoxOnRoad::OnRoad
    );
    assert_eq!(
        map.box_on_road(&car(at(100.0, 8.8), hdg + PI)),
        BoxOnRoad::OnRoad
    );
    assert_eq!(
        map.box_on_road(&car(at(100.0, 0.0), hdg)),
        BoxOnRoad::OffRoad
    );
    assert_eq!(
        map.box_on_road(&car(at(100.0, -3.5), hdg)),
        BoxOnRoad::OffRoad,
        "straddles the median edge"
    );
    assert_eq!(
        map.box_on_road(&car(at(100.0, -20.0), hdg)),
        BoxOnRoad::OffRoad
    );
    // Half past the end, in a lane: leaving the map.
    let end = eval_road(road, road.length);
    assert_eq!(
        map.box_on_road(&car(end.offset(-8.8), end.hdg)),
        BoxOnRoad::Exiting
    );
    assert_eq!(
        map.point_location(at(road.length + 5.0, -8.8)),
        PointLocation::BeyondRoadEnd
    );
    assert_eq!(
        map.point_location(at(-5.0, 8.8)),
        PointLocation::BeyondRoadEnd
    );
    assert_eq!(map.point_location(at(-5.0, 0.0)), PointLocation::OffRoad);
    assert_eq!(
        map.point_location(at(-5.0 - BEYOND_END_RANGE, 8.8)),
        PointLocation::OffRoad
    );
    assert_eq!(map.point_location([f64::NAN, 0.0]), PointLocation::OffRoad);
}

#[test]
fn straight_road_boxes() {
    let map = divided();
    assert_eq!(map.driving_lane_count(), 4);
    assert_eq!(map.box_on_road(&car([50.0, -1.75], 0.0)), BoxOnRoad::OnRoad);
    assert_eq!(
        map.box_on_road(&car([50.0, -3.5], 0.2)),
        BoxOnRoad::OnRoad,
        "across the lane line"
    );
    assert_eq!(
        map.box_on_road(&car([50.0, -6.5], 0.0)),
        BoxOnRoad::OffRoad,
        "over the right edge"
    );
    assert_eq!(
        map.box_on_road(&car([50.0, 1.5], 0.0)),
        BoxOnRoad::OffRoad,
        "on the median"
    );
    assert_eq!(
        map.box_on_road(&car([50.0, 0.5], 0.0)),
        BoxOnRoad::OffRoad,
        "straddling median edge"
    );
    assert_eq!(
        map.box_on_road(&car([100.5, -1.75], 0.0)),
        BoxOnRoad::Exiting
    );
    assert_eq!(
        map.box_on_road(&car([104.0, -1.75], 0.0)),
        BoxOnRoad::Exiting,
        "fully past the end"
    );
    assert_eq!(map.box_on_road(&car([-1.0, 6.5], PI)), BoxOnRoad::Exiting);
    assert_eq!(
        map.box_on_road(&car([100.5, -6.5], 0.0)),
        BoxOnRoad::OffRoad
    );
    assert_eq!(map.point_location([99.9, -6.9]), PointLocation::OnRoad);
    assert_eq!(map.point_location([99.9, -7.1]), PointLocation::OffRoad);
    assert_eq!(map.bounds(), ([0.0, -7.0], [100.0, 10.0]));
}

#[test]
fn width_polynomials_shape_lanes() {
    let (a, b, c, d) = (3.0, 0.01, 1e-4, -2e-7);
    let w = |s: f64| a + s * (b + s * (c + s * d));
    let text = straight_xodr(100.0, &[(-1, "driving", [a, b, c, d], "solid")], None);
    let map = Map::from_xodr_str(&text, "poly").expect("valid");
    let lane = &map.lanes()[0];
    for (j, &s) in lane.road_s.iter().enumerate() {
        assert!((lane.widths[j] - w(s)).abs() < 1e-12);
        assert!((lane.right_boundary[j][1] + w(s)).abs() < 1e-12);
        assert!((lane.centerline[j][1] + 0.5 * w(s)).abs() < 1e-12);
        // The centerline heading follows the widening: atan(-w'/2).
        let dw = b + s * (2.0 * c + s * 3.0 * d);
        assert!((lane.headings[j] - (-0.5 * dw).atan()).abs() < 1e-12);
    }
    assert!(
        lane.road_s
            .windows(2)
            .all(|p| p[1] - p[0] <= SAMPLE_SPACING + 1e-12)
    );
    assert_eq!(
        map.point_location([80.0, -(w(80.0) - 0.01)]),
        PointLocation::OnRoad
    );
    assert_eq!(
        map.point_location([80.0, -(w(80.0) + 0.01)]),
        PointLocation::OffRoad
    );
}

#[test]
fn lane_offset_shifts_lanes() {
    let lanes = [
        (-1, "driving", [3.0, 0.0, 0.0, 0.0], "solid"),
        (1, "driving", [3.0, 0.0, 0.0, 0.0], "solid"),
    ];
    let map = Map::from_xodr_str(
        &straight_xodr(50.0, &lanes, Some([1.0, 0.02, 0.0, 0.0])),
        "offset",
    )
    .expect("valid");
    let right = &map.lanes()[lane_index(&map, "7", -1)];
    let left = &map.lanes()[lane_index(&map, "7", 1)];
    for (j, &s) in right.road_s.iter().enumerate() {
        assert!((right.centerline[j][1] - (1.0 + 0.02 * s - 1.5)).abs() < 1e-12);
    }
    assert!(
        (left.centerline[0][1] - (1.0 + 0.02 * 50.0 + 1.5)).abs() < 1e-12,
        "left lanes start at s = L"
    );
    assert_eq!(
        map.point_location([40.0, 1.0 + 0.8 - 2.9]),
        PointLocation::OnRoad
    );
    assert_eq!(
        map.point_location([40.0, 1.0 + 0.8 - 3.1]),
        PointLocation::OffRoad
    );
    assert_eq!(map.point_location([0.5, 3.9]), PointLocation::OnRoad);
}

#[test]
fn lane_projection_signs_on_both_carriageways() {
    let map = divided();
    let p = map
        .lane_projection([30.0, -1.75 + 0.3], 0.1)
        .expect("has lanes");
    assert_eq!(map.lanes()[p.lane].id, -1);
    assert!((p.lateral - 0.3).abs() < 1e-9 && (p.heading_error - 0.1).abs() < 1e-9);
    assert!((p.s - 30.0).abs() < 1e-9 && (p.distance - 0.3).abs() < 1e-9);
    // Lane 2 runs along -x with its centre at y = 4.75: +y is the driver's right.
    let p = map
        .lane_projection([30.0, 4.75 + 0.3], PI - 0.1)
        .expect("has lanes");
    assert_eq!(map.lanes()[p.lane].id, 2);
    assert!((p.lateral + 0.3).abs() < 1e-9, "lateral {}", p.lateral);
    assert!((p.heading_error + 0.1).abs() < 1e-9);
    assert!((p.s - 70.0).abs() < 1e-9);
    // Travel direction wins over distance.
    let p = map.lane_projection([30.0, 3.5], 0.0).expect("has lanes");
    assert_eq!(map.lanes()[p.lane].id, -1);
    let p = map.lane_projection([30.0, 3.5], PI).expect("has lanes");
    assert_eq!(map.lanes()[p.lane].id, 2);
    assert!(map.lane_projection([f64::INFINITY, 0.0], 0.0).is_none());
}

#[test]
fn queries_are_fast() {
    let map = a9();
    let road = &map.opendrive().unwrap().roads[0];
    let start = std::time::Instant::now();
    let mut on = 0;
    let n = 2000;
    for i in 0..n {
        let s = road.length * i as f64 / n as f64;
        let p = eval_road(road, s);
        let b = car(p.offset(-8.8 + (i % 7) as f64 - 3.0), p.hdg);
        on += usize::from(map.box_on_road(&b) == BoxOnRoad::OnRoad);
    }
    let per_box = start.elapsed().as_secs_f64() / n as f64;
    crate::errln!("box_on_road: {:.1} us per box on the A9 map", per_box * 1e6);
    assert!(on > n / 3);
    // ~30 outline points each; generous bound for unoptimised test builds.
    assert!(per_box < 2e-3, "{per_box} s per box");
}

#[test]
fn invalid_maps_are_errors_not_panics() {
    let lanes = [(-1, "driving", [3.0, 0.0, 0.0, 0.0], "solid")];
    for length in ["0", "1e15"] {
        let text = straight_xodr(100.0, &lanes, None).replace(
            "length=\"100\" junction",
            &format!("length=\"{length}\" junction"),
        );
        let err = Map::from_xodr_str(&text, "bad.xodr").expect_err("rejected");
        let msg = err.to_string();
        assert!(
            msg.starts_with("bad.xodr") && msg.contains("`length` is") && msg.contains("100000"),
            "{msg}"
        );
    }
    // A child OpenDRIVE does not define there is refused, not ignored.
    let text = straight_xodr(100.0, &lanes, None).replace("<center>", "<center><link/>");
    let msg = Map::from_xodr_str(&text, "bad.xodr")
        .expect_err("unknown child")
        .to_string();
    assert!(msg.contains("<center> has child <link>"), "{msg}");
    let err = Map::from_xodr_file(Path::new("/nonexistent/map.xodr")).expect_err("no file");
    assert!(err.to_string().contains("/nonexistent/map.xodr"));
    let mut od = parse_xodr(&straight_xodr(100.0, &lanes, None), "x").expect("parses");
    od.roads[0].successor = Some(RoadLink {
        element_type: ElementType::Road,
        element_id: "nowhere".into(),
        contact_point: Some(ContactPoint::Start),
    });
    let msg = Map::from_opendrive(&od, "links")
        .expect_err("dangling link")
        .to_string();
    assert!(
        msg.contains("road \"nowhere\", which does not exist"),
        "{msg}"
    );
}

#[test]
fn a9_road_polygon_has_the_drivable_area_and_agrees_with_point_queries() {
    let map = a9();
    let polygons = map.road_polygons();
    // 8 drivable lanes: 3 driving + 1 shoulder per carriageway.
    assert_eq!(polygons.len(), 8);
    let area: f64 = polygons
        .iter()
        .map(|p| {
            let n = p.len();
            0.5 * (0..n)
                .map(|i| p[i][0] * p[(i + 1) % n][1] - p[(i + 1) % n][0] * p[i][1])
                .sum::<f64>()
                .abs()
        })
        .sum();
    // Drivable widths 14.3 m (right) + 14.5 m (left) over 266.28 m; the arc's curvature
    // changes it by far less than the tolerance.
    let expected = (14.3 + 14.5) * 266.281170003393;
    assert!(
        (area - expected).abs() < 0.5,
        "area {area}, expected {expected}"
    );

    // Points strictly inside a lane polygon are on the road.
    let inside = |poly: &[[f64; 2]], q: [f64; 2]| {
        let mut c = false;
        let n = poly.len();
        for i in 0..n {
            let (a, b) = (poly[i], poly[(i + 1) % n]);
            if (a[1] > q[1]) != (b[1] > q[1])
                && q[0] < a[0] + (q[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0])
            {
                c = !c;
            }
        }
        c
    };
    let road = &map.opendrive().unwrap().roads[0];
    let mut agreed = 0;
    for i in 0..400 {
        let s = 5.0 + (i % 40) as f64 * 6.4;
        let t = -19.0 + (i / 40) as f64 * 3.9 + 0.37;
        let q = eval_road(road, s).offset(t);
        let in_polygon = polygons.iter().any(|p| inside(p, q));
        let on_road = map.point_location(q) == PointLocation::OnRoad;
        assert_eq!(in_polygon, on_road, "s {s}, t {t}");
        agreed += usize::from(on_road);
    }
    assert!(agreed > 100 && agreed < 400, "{agreed} points on the road");
}

#[test]
fn with_speed_limit_changes_the_limit_alone() {
    let map = a9();
    let moved = map.with_speed_limit(20.0);
    let (before, after) = (
        super::LaneGraph::build(&map, 10.0),
        super::LaneGraph::build(&moved, 10.0),
    );
    assert_eq!(before.nodes.len(), after.nodes.len());
    for (b, a) in before.nodes.iter().zip(&after.nodes) {
        let (mut fb, fa) = (b.features(), a.features());
        assert_eq!(fa[3], 20.0);
        assert!(
            (fb[3] - 100.0 / 3.6).abs() < 1e-4,
            "the A9 limit: {}",
            fb[3]
        );
        fb[3] = 20.0;
        assert_eq!(fa, fb);
        assert_eq!((a.center, a.heading), (b.center, b.heading));
    }
    let q = [map.bounds().0[0] + 50.0, 0.0];
    assert_eq!(moved.point_location(q), map.point_location(q));
}
