//! Tests of the procedural maps: they build, connect as intended, are continuous across
//! joins, can be driven on, and survive a round trip through the OpenDRIVE writer.

use std::collections::{HashSet, VecDeque};

use super::test_maps::lane_index;
use super::*;
use crate::Error;
use crate::geometry::OrientedBox;

fn map_of(od: &OpenDrive) -> Map {
    Map::from_opendrive(od, "procedural").expect("generated maps are valid")
}

fn all_kinds() -> Vec<(ProceduralMap, usize)> {
    vec![
        (
            ProceduralMap::Straight {
                lanes: 3,
                lane_width: 3.75,
                length: 300.0,
                layout: Layout::OneWay,
            },
            3,
        ),
        (
            ProceduralMap::Straight {
                lanes: 3,
                lane_width: 3.75,
                length: 300.0,
                layout: Layout::Divided { median_width: 6.1 },
            },
            6,
        ),
        (
            ProceduralMap::Curve {
                lanes: 2,
                lane_width: 3.5,
                length: 400.0,
                curvature: 0.005,
                layout: Layout::OneWay,
            },
            2,
        ),
        (
            ProceduralMap::Curve {
                lanes: 2,
                lane_width: 3.5,
                length: 400.0,
                curvature: -0.004,
                layout: Layout::Divided { median_width: 4.0 },
            },
            4,
        ),
        // Merge and fork: the main lanes appear on the upstream, junction and downstream roads.
        (
            ProceduralMap::OnRampMerge {
                lanes: 2,
                lane_width: 3.75,
                length: 600.0,
                merge_s: 200.0,
                accel_lane_length: 150.0,
                taper_length: 60.0,
            },
            6,
        ),
        (
            ProceduralMap::OffRampFork {
                lanes: 3,
                lane_width: 3.75,
                length: 600.0,
                diverge_s: 400.0,
                decel_lane_length: 120.0,
                taper_length: 60.0,
            },
            9,
        ),
        (
            ProceduralMap::LaneDrop {
                lanes: 3,
                lane_width: 3.5,
                length: 500.0,
                drop_s: 200.0,
                taper_length: 80.0,
            },
            3,
        ),
    ]
}

/// Roads reachable from `start` lanes by following lane successors.
fn reachable_roads(map: &Map, start: usize) -> HashSet<String> {
    let mut seen = HashSet::from([start]);
    let mut queue = VecDeque::from([start]);
    while let Some(i) = queue.pop_front() {
        for &j in &map.lanes()[i].successors {
            if seen.insert(j) {
                queue.push_back(j);
            }
        }
    }
    seen.into_iter()
        .map(|i| map.lanes()[i].road_id.clone())
        .collect()
}

fn lane_in(map: &Map, road: &str, section: usize, id: i32) -> usize {
    map.lanes()
        .iter()
        .position(|l| l.road_id == road && l.section == section && l.id == id)
        .unwrap_or_else(|| panic!("lane {id} in section {section} of road {road}"))
}

#[test]
fn every_kind_builds_with_expected_driving_lanes_and_round_trips() {
    for (params, driving) in all_kinds() {
        let od = params.build().expect("valid parameters");
        let map = map_of(&od);
        assert_eq!(map.driving_lane_count(), driving, "{params:?}");
        assert_eq!(
            parse_xodr(&to_xodr(&od), "written").expect("parses"),
            od,
            "{params:?}"
        );
        let json = serde_json::to_string(&params).expect("serialises");
        let back: ProceduralMap = serde_json::from_str(&json).expect("deserialises");
        assert_eq!(back, params);
        let graph = LaneGraph::build(&map, 10.0);
        assert!(
            graph
                .nodes
                .iter()
                .all(|n| n.features().iter().all(|f| f.is_finite()))
        );
    }
}

#[test]
fn curve_turns_by_its_spirals_and_arc() {
    let (length, k) = (400.0, 0.005);
    let od = curve(2, 3.5, length, k).expect("valid");
    let road = &od.roads[0];
    assert_eq!(road.geometries.len(), 5);
    assert!(matches!(
        road.geometries[1].kind,
        GeometryKind::Spiral { .. }
    ));
    // Each spiral turns by k * Ls / 2, the arc by k * La.
    let end = eval_road(road, road.length);
    assert!((end.hdg - k * (0.15 * length + 0.3 * length)).abs() < 1e-9);
    for w in road.geometries.windows(2) {
        let p = w[0].eval(w[0].length);
        assert!((p.x - w[1].x).hypot(p.y - w[1].y) < 1e-9 && (p.hdg - w[1].hdg).abs() < 1e-12);
    }
}

#[test]
fn centerlines_are_continuous_across_joins() {
    for (params, _) in all_kinds() {
        let map = map_of(&params.build().expect("valid"));
        for lane in map.lanes() {
            for &j in &lane.successors {
                let next = &map.lanes()[j];
                let (a, b) = (
                    lane.centerline[lane.centerline.len() - 1],
                    next.centerline[0],
                );
                let gap = (a[0] - b[0]).hypot(a[1] - b[1]);
                // A lane tapering to nothing merges into (or opens from) its neighbour: the
                // centerlines then meet at the neighbour's edge, half a lane apart.
                let tapered =
                    lane.widths.last().is_some_and(|w| *w < 1e-6) || next.widths[0] < 1e-6;
                let allowed = if tapered {
                    0.5 * next.widths[0].max(lane.widths[0]) + 0.05
                } else {
                    0.05
                };
                assert!(
                    gap < allowed,
                    "{params:?}: {} {} -> {} {}: gap {gap}",
                    lane.road_id,
                    lane.id,
                    next.road_id,
                    next.id
                );
            }
        }
    }
}

#[test]
fn boxes_along_every_lane_stay_on_the_road() {
    for (params, _) in all_kinds() {
        let map = map_of(&params.build().expect("valid"));
        for lane in map.lanes().iter().filter(|l| l.is_graph_lane()) {
            for j in (0..lane.centerline.len()).step_by(3) {
                // Near an open lane end half the box hangs past the road: that is exiting.
                let near_open_start = lane.predecessors.is_empty() && lane.s[j] < 2.5;
                let near_open_end = lane.successors.is_empty() && lane.length() - lane.s[j] < 2.5;
                if near_open_start || near_open_end {
                    continue;
                }
                let b = OrientedBox::new(lane.centerline[j], lane.headings[j], 4.5, 1.8);
                assert_eq!(
                    map.box_on_road(&b),
                    BoxOnRoad::OnRoad,
                    "{params:?}: road {} lane {} at s {}",
                    lane.road_id,
                    lane.id,
                    lane.s[j]
                );
            }
        }
    }
}

#[test]
fn merge_leads_ramp_and_acceleration_lane_into_main_lanes() {
    let map = map_of(&on_ramp_merge(2, 3.75, 600.0, 200.0, 150.0, 60.0).expect("valid"));
    let ramp = lane_index(&map, "2", -1);
    assert_eq!(map.lanes()[ramp].kind, LaneType::OnRamp);
    let roads = reachable_roads(&map, ramp);
    assert!(roads.contains("11") && roads.contains("3"), "{roads:?}");
    let taper = lane_in(&map, "3", 1, -3);
    assert_eq!(map.lanes()[taper].kind, LaneType::Entry);
    assert_eq!(
        map.lanes()[taper].successors,
        vec![lane_in(&map, "3", 2, -2)]
    );
    assert!(
        map.lanes()[taper]
            .widths
            .last()
            .is_some_and(|w| w.abs() < 1e-9)
    );
    // In the lane graph too: the acceleration lane's last node leads into main lane -2.
    let g = LaneGraph::build(&map, 10.0);
    let last = g.lane_nodes[taper].clone().last().expect("has nodes");
    assert_eq!(
        g.successors[last],
        vec![g.lane_nodes[lane_in(&map, "3", 2, -2)].start]
    );
    // The upstream main lanes continue through the junction.
    let up = lane_index(&map, "1", -1);
    assert_eq!(map.lanes()[up].successors, vec![lane_index(&map, "10", -1)]);
    assert!(reachable_roads(&map, up).contains("3"));
    // Ends with a junction are not exits; the downstream end is.
    let end_of_up = [200.0 + 2.5, -1.875];
    assert_eq!(map.point_location(end_of_up), PointLocation::OnRoad);
    assert_eq!(
        map.point_location([601.0, -1.875]),
        PointLocation::BeyondRoadEnd
    );
}

#[test]
fn lane_drop_ends_the_dropped_lane() {
    let map = map_of(&lane_drop(3, 3.5, 500.0, 200.0, 80.0).expect("valid"));
    let dropped = lane_in(&map, "0", 1, -3);
    assert!(map.lanes()[dropped].successors.is_empty());
    assert_eq!(
        map.lanes()[dropped].predecessors,
        vec![lane_in(&map, "0", 0, -3)]
    );
    assert_eq!(
        map.lanes()[lane_in(&map, "0", 1, -2)].successors,
        vec![lane_in(&map, "0", 2, -2)]
    );
    let g = LaneGraph::build(&map, 10.0);
    let last = g.lane_nodes[dropped].clone().last().expect("has nodes");
    assert!(g.successors[last].is_empty());
    // Past the taper the dropped lane's place is shoulder: still road, but no lane.
    assert_eq!(
        map.lanes()[lane_in(&map, "0", 2, -3)].kind,
        LaneType::Shoulder
    );
}

#[test]
fn fork_gives_an_upstream_node_two_successor_paths() {
    let map = map_of(&off_ramp_fork(2, 3.75, 600.0, 400.0, 120.0, 60.0).expect("valid"));
    let main = lane_in(&map, "1", 0, -2);
    let g = LaneGraph::build(&map, 10.0);
    let last = g.lane_nodes[main].clone().last().expect("has nodes");
    assert_eq!(g.successors[last].len(), 2);
    let mut reached = Vec::new();
    for &next in &g.successors[last] {
        reached.push(reachable_roads(&map, g.nodes[next].lane));
    }
    assert!(
        reached.iter().any(|r| r.contains("2") && r.contains("21")),
        "{reached:?}"
    );
    assert!(
        reached.iter().any(|r| r.contains("3") && !r.contains("2")),
        "{reached:?}"
    );
    let exit = lane_in(&map, "1", 2, -3);
    assert_eq!(map.lanes()[exit].kind, LaneType::Exit);
    assert_eq!(
        map.lanes()[exit].successors,
        vec![lane_index(&map, "21", -1)]
    );
}

#[test]
fn nonsense_parameters_are_rejected() {
    let bad = [
        straight(0, 3.5, 100.0),
        straight(2, 3.5, -1.0),
        straight(2, f64::NAN, 100.0),
        straight(2, 0.0, 100.0),
        curve(3, 3.5, 100.0, 0.2),
        on_ramp_merge(2, 3.5, 300.0, 200.0, 150.0, 60.0),
        on_ramp_merge(2, 3.5, 600.0, -5.0, 150.0, 60.0),
        off_ramp_fork(2, 3.5, 600.0, 100.0, 120.0, 60.0),
        off_ramp_fork(2, 3.5, 402.0, 400.0, 120.0, 60.0),
        lane_drop(1, 3.5, 500.0, 200.0, 80.0),
        lane_drop(3, 3.5, 250.0, 200.0, 80.0),
        ProceduralMap::Straight {
            lanes: 2,
            lane_width: 3.5,
            length: 100.0,
            layout: Layout::Divided { median_width: -1.0 },
        }
        .build(),
    ];
    for (i, result) in bad.into_iter().enumerate() {
        assert!(
            matches!(result, Err(Error::InvalidArgument(_))),
            "case {i}: {result:?}"
        );
    }
}

#[test]
fn every_preset_builds_a_drivable_connected_map() {
    for name in PRESET_NAMES {
        let od = ProceduralMap::preset(name)
            .and_then(|p| p.build())
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let map = map_of(&od);
        assert!(map.driving_lane_count() >= 3, "{name}");
        let graph = LaneGraph::build(&map, 10.0);
        let linked = graph.successors.iter().filter(|s| !s.is_empty()).count();
        assert!(
            linked + 8 >= graph.nodes.len(),
            "{name}: most nodes have a successor"
        );
    }
    assert!(ProceduralMap::preset("roundabout").is_err());
}

/// A key the map kind does not have (a typo, a parameter of another kind) is an error naming
/// it, in the map and in its layout, not silently the default.
#[test]
fn unknown_keys_in_a_procedural_spec_are_named() {
    let spec = r#"{"kind":"straight","lanes":3,"lane_width":3.5,"length":300,"lenght":500}"#;
    let err = serde_json::from_str::<ProceduralMap>(spec).expect_err("typo");
    assert!(err.to_string().contains("lenght"), "{err}");
    let divided = r#"{"kind":"straight","lanes":2,"lane_width":3.5,"length":300,
        "layout":{"type":"divided","median_width":2.0}}"#;
    assert!(serde_json::from_str::<ProceduralMap>(divided).is_ok());
    let typo = divided.replace("median_width", "median");
    let err = serde_json::from_str::<ProceduralMap>(&typo).expect_err("layout typo");
    assert!(err.to_string().contains("median"), "{err}");
}

#[test]
fn a_huge_parameter_is_quoted_with_an_exponent() {
    let err = super::straight(3, 1e308, 500.0)
        .expect_err("a 1e308 m lane")
        .to_string();
    assert!(err.contains("lane_width is 1e308 m"), "{err}");
    let err = super::curve(3, 3.5, 500.0, 1e300)
        .expect_err("a 1e-300 m radius")
        .to_string();
    assert!(err.contains("curvature 1e300 1/m"), "{err}");
}
