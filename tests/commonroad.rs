//! CommonRoad import: the committed NGSIM US-101 clips (`data/commonroad-us101/`, formats
//! 2020a and 2018b) and hand-made files for every malformed case.

mod common;

use std::io::Read;
use std::path::{Path, PathBuf};

use rtr::data::commonroad::{CommonRoadClip, commonroad_scenes, load_commonroad};
use rtr::data::{SceneConfig, logged_infractions};
use rtr::geometry::OrientedBox;
use rtr::geometry::wrap_angle;
use rtr::map::BoxOnRoad;
use rtr::map::{DEFAULT_SPEED_LIMIT, LANELET_SHOULDER_WIDTH, Map, PointLocation};

fn us101_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/commonroad-us101")
}

fn clip(name: &str) -> CommonRoadClip {
    CommonRoadClip::load(&us101_dir().join(name), DEFAULT_SPEED_LIMIT).expect("clip loads")
}

/// (obstacle id, [(step, x, y, orientation, velocity)]) of every dynamic obstacle with a
/// trajectory, read straight from the XML, independently of the reader under test.
fn recorded_states(path: &Path) -> Vec<(String, Vec<[f64; 5]>)> {
    let mut text = String::new();
    flate2::read::GzDecoder::new(std::fs::File::open(path).unwrap())
        .read_to_string(&mut text)
        .unwrap();
    let doc = roxmltree::Document::parse(&text).unwrap();
    let value = |n: roxmltree::Node, path: &[&str]| -> f64 {
        let mut node = n;
        for tag in path {
            node = node.children().find(|c| c.has_tag_name(*tag)).unwrap();
        }
        node.text().unwrap().trim().parse().unwrap()
    };
    let mut out = Vec::new();
    for o in doc.root_element().children().filter(|n| {
        n.has_tag_name("dynamicObstacle")
            || (n.has_tag_name("obstacle")
                && n.children()
                    .any(|c| c.has_tag_name("role") && c.text() == Some("dynamic")))
    }) {
        let Some(trajectory) = o.children().find(|c| c.has_tag_name("trajectory")) else {
            continue;
        };
        let initial = o.children().filter(|c| c.has_tag_name("initialState"));
        let states = initial
            .chain(trajectory.children().filter(|c| c.has_tag_name("state")))
            .map(|s| {
                [
                    value(s, &["time", "exact"]),
                    value(s, &["position", "point", "x"]),
                    value(s, &["position", "point", "y"]),
                    value(s, &["orientation", "exact"]),
                    value(s, &["velocity", "exact"]),
                ]
            })
            .collect();
        out.push((o.attribute("id").unwrap().to_string(), states));
    }
    out
}

#[test]
fn every_recorded_state_is_reproduced_within_a_millimetre() {
    // One clip of each format version.
    for name in ["USA_US101-15_1_T-1.xml.gz", "USA_US101-3_1_T-1.xml.gz"] {
        let clip = clip(name);
        let recorded = recorded_states(&us101_dir().join(name));
        assert_eq!(clip.recording.tracks.len(), recorded.len(), "{name}");
        let dt = 1.0 / clip.recording.fps;
        let mut checked = 0;
        for (id, states) in &recorded {
            let track = clip
                .recording
                .tracks
                .iter()
                .find(|t| &t.uuid == id)
                .unwrap();
            assert_eq!(track.samples.len(), states.len(), "{name} obstacle {id}");
            for [step, x, y, orientation, velocity] in states {
                let s = track.state_at(step * dt).expect("state inside the track");
                let position_error = (s.x - x).hypot(s.y - y);
                assert!(
                    position_error < 1e-3,
                    "{name} {id} step {step}: {position_error} m"
                );
                assert!(wrap_angle(s.heading - orientation).abs() < 1e-6);
                assert!((s.speed - velocity).abs() < 1e-3);
                checked += 1;
            }
        }
        assert!(checked > 1000, "{name}: only {checked} states");
    }
}

#[test]
fn the_ramp_clip_has_the_lanes_successors_and_neighbours_drawn_in_the_file() {
    // USA_US101-15_1: five main lanes and an on-ramp, each cut into two lanelets at the same
    // station (left to right: 30->28, 42->40, 26->25, 23->22, 20->19; ramp 17->16). A solid
    // line separates the ramp's first lanelet from the main road; its second lanelet (16) is
    // the auxiliary lane right of 19, behind a dashed line.
    let clip = clip("USA_US101-15_1_T-1.xml.gz");
    let lanes = clip.map.lanes();
    assert_eq!(lanes.len(), 12);
    let lane = |id: &str| lanes.iter().position(|l| l.road_id == id).unwrap();
    let first = ["30", "42", "26", "23", "20"];
    let second = ["28", "40", "25", "22", "19"];
    for (a, b) in first.iter().zip(second).chain([(&"17", "16")]) {
        assert_eq!(lanes[lane(a)].successors, vec![lane(b)], "{a} -> {b}");
        assert_eq!(lanes[lane(b)].predecessors, vec![lane(a)], "{b} <- {a}");
        assert!(lanes[lane(b)].successors.is_empty(), "{b} ends the clip");
    }
    for row in [first, second] {
        for w in row.windows(2) {
            assert_eq!(lanes[lane(w[0])].right_neighbour, Some(lane(w[1])));
            assert_eq!(lanes[lane(w[1])].left_neighbour, Some(lane(w[0])));
        }
        assert_eq!(
            lanes[lane(row[0])].left_neighbour,
            None,
            "median on the left"
        );
    }
    assert_eq!(lanes[lane("20")].right_neighbour, None);
    assert_eq!(lanes[lane("17")].left_neighbour, None);
    assert_eq!(lanes[lane("19")].right_neighbour, Some(lane("16")));
    assert_eq!(lanes[lane("16")].left_neighbour, Some(lane("19")));
    // Lanes 3.1-4.1 m wide, 77-108 m long; the lane graph cuts them into ~10 m nodes with
    // the same relations.
    for l in lanes {
        let length = l.length();
        assert!(
            (77.0..=108.0).contains(&length),
            "{}: {length} m",
            l.road_id
        );
        assert!(
            l.widths.iter().all(|w| (3.0..=4.1).contains(w)),
            "{}",
            l.road_id
        );
    }
    let graph = &clip.lane_graph;
    let (r17, r16, r19) = (
        &graph.lane_nodes[lane("17")],
        &graph.lane_nodes[lane("16")],
        &graph.lane_nodes[lane("19")],
    );
    assert!(graph.successors[r17.end - 1].contains(&r16.start));
    assert!(graph.nodes.iter().all(|n| (5.0..=15.0).contains(&n.length)));
    let right_of_19: Vec<usize> = r19.clone().flat_map(|k| graph.right[k].clone()).collect();
    assert!(!right_of_19.is_empty() && right_of_19.iter().all(|k| r16.contains(k)));
    assert!(r17.clone().all(|k| graph.left[k].is_empty()));
}

/// Point in polygon by the crossing rule.
fn inside(polygon: &[[f64; 2]], p: [f64; 2]) -> bool {
    let mut inside = false;
    for (i, a) in polygon.iter().enumerate() {
        let b = polygon[(i + 1) % polygon.len()];
        if (a[1] > p[1]) != (b[1] > p[1]) {
            let x = a[0] + (p[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
            inside ^= p[0] < x;
        }
    }
    inside
}

#[test]
fn every_recorded_vehicle_lies_on_a_lane() {
    let clips = load_commonroad(&[us101_dir()], None).unwrap();
    assert_eq!(clips.len(), 12);
    let mut vehicles = 0;
    for clip in &clips {
        let polygons: Vec<Vec<[f64; 2]>> = clip.map.lanes().iter().map(|l| l.polygon()).collect();
        for track in &clip.recording.tracks {
            // The centre inside the polygon of a lane (bounds as drawn, no shoulder).
            let on_lane = track
                .samples
                .iter()
                .filter(|s| {
                    polygons
                        .iter()
                        .any(|poly| inside(poly, [s.state.x, s.state.y]))
                })
                .count();
            let share = on_lane as f64 / track.samples.len() as f64;
            assert!(
                share >= 0.99,
                "{} {}: {share}",
                clip.benchmark_id,
                track.uuid
            );
            vehicles += 1;
        }
        // The whole logged box stays on the road surface (lanes and their shoulder strips).
        let logged = logged_infractions(&clip.recording, &clip.map);
        assert_eq!(logged.offroad_samples, 0, "{}", clip.benchmark_id);
        for track in &clip.recording.tracks {
            let off = track.samples.iter().any(|s| {
                let b = OrientedBox::new(
                    [s.state.x, s.state.y],
                    s.state.heading,
                    track.length,
                    track.width,
                );
                clip.map.box_on_road(&b) == BoxOnRoad::OffRoad
            });
            assert!(!off, "{} {} leaves the road", clip.benchmark_id, track.uuid);
        }
    }
    assert_eq!(vehicles, 291);
}

#[test]
fn clips_become_scenes_by_the_a9_windows_and_say_why_not() {
    let clips = load_commonroad(&[us101_dir()], None).unwrap();
    let config = SceneConfig::default();
    let (scenes, summaries) = commonroad_scenes(&clips, &config).unwrap();
    // 2 s history + 6 s future at a 1 s stride: an 8.0 s clip gives one window, 10.0 s three,
    // 12.9 s five; the others are shorter than a window or hold no trajectory.
    let count = |id: &str| summaries.iter().find(|s| s.benchmark_id == id).unwrap();
    assert_eq!(count("USA_US101-24_2_T-1").scenes, 5);
    assert_eq!(count("USA_US101-5_1_T-1").scenes, 3);
    assert_eq!(count("USA_US101-15_1_T-1").scenes, 1);
    assert_eq!(scenes.len(), 12);
    let short = count("USA_US101-8_1_T-1").no_scene_because.clone().unwrap();
    assert!(
        short.contains("7.5 s") && short.contains("shorter"),
        "{short}"
    );
    let set_based = count("USA_US101-3_3_S-1");
    assert!(
        set_based
            .no_scene_because
            .as_deref()
            .unwrap()
            .contains("no vehicle has a recorded trajectory")
    );
    assert_eq!(set_based.skipped[0].1, 33);
    assert!(count("USA_US101-15_1_T-1").planning_vehicle_removed);
    // `_1` and `_2` of benchmark 1 are two planning problems over the same two vehicles.
    let repeat = count("USA_US101-1_2_T-1");
    assert!(
        repeat
            .repeats
            .as_deref()
            .unwrap()
            .ends_with("USA_US101-1_1_T-1.xml.gz"),
        "{:?}",
        repeat.repeats
    );
    assert!(count("USA_US101-1_1_T-1").repeats.is_none());
    assert_eq!(summaries.iter().filter(|s| s.repeats.is_some()).count(), 1);
    for scene in &scenes {
        assert_eq!(scene.dt, 0.5);
        assert!(scene.controlled_count() >= 1);
        assert!(scene.id.starts_with("USA_US101-"), "{}", scene.id);
    }
}

/// A small 2020a clip: two lanelets side by side (10 m long, 3.5 m wide) and one car driving
/// along the right one for `steps` states at 0.1 s.
fn template(steps: usize) -> String {
    let state = |k: usize, tag: &str| {
        format!(
            "<{tag}><position><point><x>{x}</x><y>-1.75</y></point></position>\
             <orientation><exact>0.0</exact></orientation><time><exact>{k}</exact></time>\
             <velocity><exact>1.0</exact></velocity></{tag}>",
            x = 0.1 * k as f64
        )
    };
    let states: String = (1..steps).map(|k| state(k, "state")).collect();
    format!(
        r#"<?xml version="1.0"?>
<commonRoad commonRoadVersion="2020a" benchmarkID="ZAM_Test-1_1_T-1" timeStepSize="0.1">
  <lanelet id="1">
    <leftBound><point><x>0</x><y>3.5</y></point><point><x>100</x><y>3.5</y></point></leftBound>
    <rightBound><point><x>0</x><y>0</y></point><point><x>100</x><y>0</y></point></rightBound>
    <adjacentRight ref="2" drivingDir="same"/>
    <laneletType>highway</laneletType>
  </lanelet>
  <lanelet id="2">
    <leftBound><point><x>0</x><y>0</y></point><point><x>100</x><y>0</y></point></leftBound>
    <rightBound><point><x>0</x><y>-3.5</y></point><point><x>100</x><y>-3.5</y></point></rightBound>
    <adjacentLeft ref="1" drivingDir="same"/>
    <laneletType>highway</laneletType>
  </lanelet>
  <dynamicObstacle id="7">
    <type>car</type>
    <shape><rectangle><length>4.5</length><width>1.8</width></rectangle></shape>
    {initial}
    <trajectory>{states}</trajectory>
  </dynamicObstacle>
</commonRoad>
"#,
        initial = state(0, "initialState")
    )
}

fn write(dir: &tempfile::TempDir, name: &str, text: &str) -> PathBuf {
    let path = dir.path().join(name);
    std::fs::write(&path, text).unwrap();
    path
}

fn load_error(text: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    let path = write(&dir, "bad.xml", text);
    let err = CommonRoadClip::load(&path, DEFAULT_SPEED_LIMIT)
        .expect_err("a malformed file is an error")
        .to_string();
    assert!(err.contains("bad.xml"), "names the file: {err}");
    err
}

#[test]
fn a_well_formed_small_clip_reads_as_xml_and_as_gzip() {
    let dir = tempfile::tempdir().unwrap();
    let text = template(100);
    let plain = write(&dir, "ok.xml", &text);
    let gz = dir.path().join("ok.xml.gz");
    let mut encoder =
        flate2::write::GzEncoder::new(std::fs::File::create(&gz).unwrap(), Default::default());
    std::io::Write::write_all(&mut encoder, text.as_bytes()).unwrap();
    encoder.finish().unwrap();
    let (a, b) = (
        CommonRoadClip::load(&plain, DEFAULT_SPEED_LIMIT).unwrap(),
        CommonRoadClip::load(&gz, DEFAULT_SPEED_LIMIT).unwrap(),
    );
    assert_eq!(a.recording.tracks, b.recording.tracks);
    assert_eq!(a.map.lanes(), b.map.lanes());
    let track = &a.recording.tracks[0];
    assert_eq!(track.samples.len(), 100);
    assert!((a.recording.duration() - 9.9).abs() < 1e-9);
    // The car at step 42 is at x = 4.2, in the right lane; both lanes are neighbours.
    let s = track.state_at(4.2).unwrap();
    assert!((s.x - 4.2).abs() < 1e-9 && (s.y + 1.75).abs() < 1e-9);
    let lanes = a.map.lanes();
    assert_eq!(
        (lanes[0].right_neighbour, lanes[1].left_neighbour),
        (Some(1), Some(0))
    );
    assert_eq!(lanes[0].speed_limit, DEFAULT_SPEED_LIMIT);
    // A folder of both reads both.
    assert_eq!(
        load_commonroad(&[dir.path().to_path_buf()], None)
            .unwrap()
            .len(),
        2
    );
}

#[test]
fn lanelet_maps_locate_points_on_lanes_past_open_ends_and_off_the_road() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(&dir, "map.xml", &template(2));
    let map: &Map = &CommonRoadClip::load(&path, DEFAULT_SPEED_LIMIT)
        .unwrap()
        .map;
    assert_eq!(map.point_location([50.0, 2.0]), PointLocation::OnRoad);
    assert_eq!(map.point_location([50.0, -3.4]), PointLocation::OnRoad);
    assert_eq!(
        map.point_location([50.0, 0.0]),
        PointLocation::OnRoad,
        "shared bound"
    );
    // The outer bounds have a shoulder strip of LANELET_SHOULDER_WIDTH (1 m).
    assert_eq!(LANELET_SHOULDER_WIDTH, 1.0);
    assert_eq!(map.point_location([50.0, 4.4]), PointLocation::OnRoad);
    assert_eq!(map.point_location([50.0, -4.4]), PointLocation::OnRoad);
    assert_eq!(map.point_location([50.0, 4.6]), PointLocation::OffRoad);
    assert_eq!(map.point_location([50.0, -4.6]), PointLocation::OffRoad);
    // Both lanes end and start open: past either end, within the road's width, is leaving.
    assert_eq!(
        map.point_location([120.0, 1.0]),
        PointLocation::BeyondRoadEnd
    );
    assert_eq!(
        map.point_location([120.0, 4.4]),
        PointLocation::BeyondRoadEnd
    );
    assert_eq!(
        map.point_location([-20.0, -2.0]),
        PointLocation::BeyondRoadEnd
    );
    assert_eq!(map.point_location([120.0, 5.0]), PointLocation::OffRoad);
    assert_eq!(map.point_location([200.0, 1.0]), PointLocation::OffRoad);
    let p = map.lane_projection([50.0, -1.0], 0.0).unwrap();
    assert_eq!(p.lane, 1);
    assert!((p.lateral - 0.75).abs() < 1e-9 && (p.s - 50.0).abs() < 1e-9);
}

#[test]
fn a_reference_to_a_missing_lanelet_is_an_error_naming_both() {
    let text = template(10).replace(r#"<adjacentRight ref="2""#, r#"<adjacentRight ref="99""#);
    let err = load_error(&text);
    assert!(err.contains("lanelet 1") && err.contains("99"), "{err}");
    let text = template(10).replace(
        r#"<laneletType>highway</laneletType>
  </lanelet>
  <lanelet id="2">"#,
        r#"<laneletType>highway</laneletType><successor ref="5"/>
  </lanelet>
  <lanelet id="2">"#,
    );
    let err = load_error(&text);
    assert!(err.contains("successor 5 is not a lanelet"), "{err}");
}

#[test]
fn a_time_gap_or_backwards_time_is_an_error_at_its_line() {
    let gap = template(10).replace("<exact>5</exact>", "<exact>6</exact>");
    let err = load_error(&gap);
    assert!(
        err.contains("time gap from step 4 to 6") && err.contains("line 19"),
        "{err}"
    );
    let backwards = template(10).replace("<exact>5</exact>", "<exact>3</exact>");
    let err = load_error(&backwards);
    assert!(
        err.contains("step 3 follows 4") && err.contains("time must increase"),
        "{err}"
    );
}

#[test]
fn an_unknown_format_version_is_an_error() {
    let err = load_error(&template(10).replace("2020a", "2017a"));
    assert!(
        err.contains("2017a") && err.contains("2018b, 2020a"),
        "{err}"
    );
}

#[test]
fn a_shape_that_is_not_a_rectangle_is_an_error() {
    let text = template(10).replace(
        "<rectangle><length>4.5</length><width>1.8</width></rectangle>",
        "<circle><radius>2</radius></circle>",
    );
    let err = load_error(&text);
    assert!(
        err.contains("obstacle 7") && err.contains("<circle>"),
        "{err}"
    );
}

#[test]
fn coordinates_that_are_not_finite_are_errors() {
    let err = load_error(&template(10).replace("<x>100</x><y>3.5</y>", "<x>NaN</x><y>3.5</y>"));
    assert!(err.contains("finite") && err.contains("line 4"), "{err}");
    let err = load_error(&template(10).replace("<y>-1.75</y>", "<y>inf</y>"));
    assert!(err.contains("`inf`"), "{err}");
}

#[test]
fn a_file_without_a_usable_window_says_why() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(&dir, "short.xml", &template(30));
    let clip = CommonRoadClip::load(&path, DEFAULT_SPEED_LIMIT).unwrap();
    let why = clip.why_no_scene(&SceneConfig::default()).unwrap().unwrap();
    assert!(
        why.contains("2.9 s") && why.contains("shorter than one window"),
        "{why}"
    );
    let long = write(&dir, "long.xml", &template(81));
    let clip = CommonRoadClip::load(&long, DEFAULT_SPEED_LIMIT).unwrap();
    assert_eq!(clip.why_no_scene(&SceneConfig::default()).unwrap(), None);
    assert_eq!(clip.scenes(&SceneConfig::default()).unwrap().len(), 1);
}

#[test]
fn commonroad_sources_join_the_nominal_draws_by_weight_and_train_il() {
    use indicatif::ProgressBar;
    use rand::SeedableRng;
    use rtr::train::session::devices;
    use rtr::train::{
        CommonRoadSource, DataConfig, InitialState, TrainConfig, Trainer, TrainingData,
    };

    let config = DataConfig {
        nominal_limit: Some(50),
        a9_weight: 0.5,
        commonroad: vec![CommonRoadSource {
            path: us101_dir().join("USA_US101-24_2_T-1.xml.gz"),
            weight: 0.5,
            speed_limit: None,
        }],
        ..DataConfig::default()
    };
    let data = TrainingData::load(common::a9(), &config, false).expect("loads");
    assert_eq!(
        data.nominal.len(),
        55,
        "50 A9 scenes + the clip's 5 windows"
    );
    assert_eq!(data.nominal_sources, vec![(0..50, 0.5), (50..55, 0.5)]);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let draws = data.sample(&mut rng, 2000, 0.0);
    let us101 = draws
        .iter()
        .filter(|s| matches!(s, InitialState::Nominal(i) if *i >= 50))
        .count() as f64
        / 2000.0;
    assert!((0.45..0.55).contains(&us101), "US-101 share {us101}");
    // Scenes of both roads batch together as nominal (logged, so imitation applies) ...
    let parts = data.parts(&draws[..8]);
    assert!(parts.iter().all(|p| p.is_nominal()));
    // ... and the existing trainer runs IL on them.
    let run = TrainConfig::from_toml_str(
        r#"
method = "IL"
seed = 5
[optimizer]
epochs = 2
epoch_scenes = 4
[imitation]
minibatch = 4
[data]
max_rollout_steps = 3
[model]
hidden = 16
lane_layers = 1
interaction_rounds = 1
history_blocks = 1
head_hidden = [16]
"#,
        "tiny.toml",
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut trainer = Trainer::new(
        run.clone(),
        &data,
        devices(&run).unwrap(),
        dir.path(),
        false,
    )
    .unwrap();
    trainer.run(&ProgressBar::hidden(), None).unwrap();
    let rows = trainer.curves();
    assert_eq!(rows.len(), 2);
    assert!(rows.iter().all(|r| r.loss.is_finite() && r.loss > 0.0));
}

#[test]
fn a_commonroad_source_that_repeats_another_sources_clip_is_refused_by_name() {
    use rtr::train::{CommonRoadSource, DataConfig, TrainingData};
    let dir = tempfile::tempdir().unwrap();
    let mut text = String::new();
    flate2::read::GzDecoder::new(
        std::fs::File::open(us101_dir().join("USA_US101-24_2_T-1.xml.gz")).unwrap(),
    )
    .read_to_string(&mut text)
    .unwrap();
    let copy = write(
        &dir,
        "copy.xml",
        &text.replace("USA_US101-24_2_T-1", "USA_US101-99_1_T-1"),
    );
    let source = |path: PathBuf| CommonRoadSource {
        path,
        weight: 0.25,
        speed_limit: None,
    };
    let config = DataConfig {
        nominal_limit: Some(10),
        a9_weight: 0.5,
        commonroad: vec![
            source(us101_dir().join("USA_US101-24_2_T-1.xml.gz")),
            source(copy),
        ],
        ..DataConfig::default()
    };
    let err = TrainingData::load(common::a9(), &config, false)
        .err()
        .expect("a source repeating another is refused")
        .to_string();
    assert!(
        err.contains("copy.xml") && err.contains("USA_US101-24_2_T-1.xml.gz"),
        "{err}"
    );
}

#[test]
fn run_files_name_commonroad_sources_relative_to_themselves_and_check_weights() {
    let dir = tempfile::tempdir().unwrap();
    let run = |body: &str| {
        let path = dir.path().join("run.toml");
        std::fs::write(&path, format!("method = \"IL\"\n{body}")).unwrap();
        rtr::train::TrainConfig::from_toml_file(&path)
    };
    let config = run("[[data.commonroad]]\npath = \"clips\"\nweight = 0.3\n").unwrap();
    assert_eq!(config.data.commonroad[0].path, dir.path().join("clips"));
    assert_eq!(config.data.a9_weight, 1.0);
    let err = run("[[data.commonroad]]\npath = \"clips\"\nweight = -1\n").unwrap_err();
    assert!(err.to_string().contains("data.commonroad.weight"), "{err}");
    let err =
        run("[[data.commonroad]]\npath = \"clips\"\nweight = 1\nspeed_limit = 120\n").unwrap_err();
    assert!(
        err.to_string().contains("data.commonroad.speed_limit"),
        "{err}"
    );
    let err = run("[data]\na9_weight = 0\n").unwrap_err();
    assert!(err.to_string().contains("sum to 0"), "{err}");
    let err = run("[[data.commonroad]]\npath = \"clips\"\nwieght = 1\n").unwrap_err();
    assert!(err.to_string().contains("wieght"), "{err}");
}

/// The raster's one documented approximation: a feature narrower than a cell that fits
/// between agreeing corners. On a lanelet map that includes the tip of the gap between two
/// shoulder strips (US-101's gore between the main road and the on-ramp, about 2 m wide where
/// the two 1 m strips meet), so a handful of sweep points may differ.
#[test]
fn the_simulators_road_raster_agrees_with_the_exact_lanelet_query() {
    use rtr::map::{RASTER_CELL, RoadRaster};
    let clip = clip("USA_US101-15_1_T-1.xml.gz");
    let map = &clip.map;
    let raster = RoadRaster::new(map, RASTER_CELL);
    let (min, max) = map.bounds();
    let (mut n, mut on, mut beyond, mut differ) = (0, 0, 0, 0);
    // An irregular sweep (0.37 m x 0.53 m) so points do not sit on grid corners.
    let mut y = min[1] - 12.0;
    while y < max[1] + 12.0 {
        let mut x = min[0] - 12.0;
        while x < max[0] + 12.0 {
            let exact = map.point_location([x, y]);
            differ += usize::from(raster.point_location(map, [x, y]) != exact);
            on += usize::from(exact == PointLocation::OnRoad);
            beyond += usize::from(exact == PointLocation::BeyondRoadEnd);
            n += 1;
            x += 0.37;
        }
        y += 0.53;
    }
    assert!(
        on > 10_000 && beyond > 1_000 && on + beyond < n,
        "{on} / {beyond} of {n}"
    );
    assert!(differ * 10_000 <= n, "{differ} of {n} points differ");
}

#[test]
fn lanelets_that_cannot_be_a_road_are_errors() {
    // Left and right bound swapped on lanelet 1.
    let swapped = template(10).replacen(
        "<leftBound><point><x>0</x><y>3.5</y></point><point><x>100</x><y>3.5</y></point></leftBound>\n    <rightBound><point><x>0</x><y>0</y></point><point><x>100</x><y>0</y></point></rightBound>",
        "<leftBound><point><x>0</x><y>0</y></point><point><x>100</x><y>0</y></point></leftBound>\n    <rightBound><point><x>0</x><y>3.5</y></point><point><x>100</x><y>3.5</y></point></rightBound>",
        1,
    );
    let err = load_error(&swapped);
    assert!(
        err.contains("lanelet 1") && err.contains("swapped"),
        "{err}"
    );
    // A right bound 1e6 m away (would be sampled into millions of points).
    let err =
        load_error(&template(10).replace("<x>100</x><y>-3.5</y>", "<x>1000000</x><y>-3.5</y>"));
    assert!(
        err.contains("lanelet 2") && err.contains("at most"),
        "{err}"
    );
    // Nothing drivable.
    let err = load_error(&template(10).replace("highway", "sidewalk"));
    assert!(err.contains("no drivable lanelet"), "{err}");
}

#[test]
fn a_clip_that_starts_late_starts_at_time_zero_and_two_clips_with_one_id_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    // The same 8.1 s clip, its steps shifted by 5000.
    let mut text = template(81);
    for k in (0..81).rev() {
        text = text.replace(
            &format!("<time><exact>{k}</exact>"),
            &format!("<time><exact>{}</exact>", k + 5000),
        );
    }
    let late = write(&dir, "late.xml", &text);
    let clip = CommonRoadClip::load(&late, DEFAULT_SPEED_LIMIT).unwrap();
    assert_eq!(clip.recording.tracks[0].samples[0].t, 0.0);
    assert!((clip.recording.duration() - 8.0).abs() < 1e-9);
    assert_eq!(clip.scenes(&SceneConfig::default()).unwrap().len(), 1);
    let again = write(&dir, "again.xml", &template(81));
    let clips = load_commonroad(&[late, again.clone()], None).unwrap();
    let err = commonroad_scenes(&clips, &SceneConfig::default())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("again.xml") && err.contains("ZAM_Test-1_1_T-1"),
        "{err}"
    );
}

/// `text` (a clip of [`template`]'s shape) turned a quarter round the origin, then moved
/// `shift` metres along x: every point (x, y) becomes (shift - y, x), every heading grows by
/// pi / 2.
fn quarter_turned(text: &str, shift: f64) -> String {
    let mut out = String::new();
    let mut rest = text;
    while let Some(at) = rest.find("<point><x>") {
        let (head, tail) = rest.split_at(at);
        out.push_str(head);
        let end = tail.find("</point>").expect("a point") + "</point>".len();
        let number = |open: &str, close: &str| -> f64 {
            let from = tail.find(open).expect(open) + open.len();
            let to = from + tail[from..].find(close).expect(close);
            tail[from..to].parse().expect("a number")
        };
        let (x, y) = (number("<x>", "</x>"), number("<y>", "</y>"));
        out.push_str(&format!("<point><x>{}</x><y>{x}</y></point>", shift - y));
        rest = &tail[end..];
    }
    out.push_str(rest);
    out.replace(
        "<orientation><exact>0.0</exact>",
        &format!(
            "<orientation><exact>{}</exact>",
            std::f64::consts::FRAC_PI_2
        ),
    )
}

/// `template` with its steps shifted by `shift`, its benchmark id and obstacle id replaced and
/// its car moved sideways by `dy` metres.
fn variant(steps: usize, shift: usize, id: &str, dy: f64) -> String {
    let mut text = template(steps);
    for k in (0..steps).rev() {
        text = text.replace(
            &format!("<time><exact>{k}</exact>"),
            &format!("<time><exact>{}</exact>", k + shift),
        );
    }
    text.replace("ZAM_Test-1_1_T-1", id)
        .replace(r#"dynamicObstacle id="7""#, r#"dynamicObstacle id="70""#)
        .replace("<y>-1.75</y>", &format!("<y>{}</y>", -1.75 + dy))
}

#[test]
fn a_clip_repeated_under_another_id_or_cut_shorter_is_read_once() {
    let dir = tempfile::tempdir().unwrap();
    let original = write(&dir, "a.xml", &template(101));
    // The same traffic under another benchmark id, obstacle id and start step.
    let renamed = write(&dir, "b.xml", &variant(101, 300, "ZAM_Copy-1_1_T-1", 0.0));
    // The same car's first 8.1 s only: a run of the original's states.
    let cut = write(&dir, "c.xml", &variant(81, 0, "ZAM_Cut-1_1_T-1", 0.0));
    // Another car, a lane over at another speed: different traffic, kept.
    write(
        &dir,
        "d.xml",
        &variant(101, 0, "ZAM_Other-1_1_T-1", 3.5).replace(
            "<velocity><exact>1.0</exact>",
            "<velocity><exact>1.05</exact>",
        ),
    );
    // The first clip moved 2 cm sideways as a whole: still its traffic.
    write(&dir, "e.xml", &variant(101, 0, "ZAM_Moved-1_1_T-1", 0.02));
    // The first clip turned a quarter round and moved 1 km: still its traffic.
    write(
        &dir,
        "f.xml",
        &quarter_turned(&variant(101, 0, "ZAM_Turned-1_1_T-1", 0.0), 1000.0),
    );
    let config = SceneConfig::default();
    let single = commonroad_scenes(&load_commonroad(&[original], None).unwrap(), &config)
        .unwrap()
        .0
        .len();
    assert_eq!(single, 3);
    let (scenes, summaries) = commonroad_scenes(
        &load_commonroad(&[dir.path().to_path_buf()], None).unwrap(),
        &config,
    )
    .unwrap();
    let repeats: Vec<Option<&str>> = summaries.iter().map(|s| s.repeats.as_deref()).collect();
    let a = dir.path().join("a.xml").display().to_string();
    assert_eq!(
        repeats,
        [
            None,
            Some(a.as_str()),
            Some(a.as_str()),
            None,
            Some(a.as_str()),
            Some(a.as_str())
        ]
    );
    assert_eq!(scenes.len(), 2 * single);
    assert!(
        scenes
            .iter()
            .all(|s| s.id.starts_with("ZAM_Test") || s.id.starts_with("ZAM_Other"))
    );
    let why = summaries[1].no_scene_because.as_deref().unwrap();
    assert!(why.contains("a.xml") && why.contains("read once"), "{why}");
    // The clip cut shorter repeats the longer one whatever the order they are read in.
    let clips = load_commonroad(&[cut.clone(), renamed], None).unwrap();
    let (_, summaries) = commonroad_scenes(&clips, &config).unwrap();
    assert_eq!(
        summaries[0].repeats.as_deref(),
        Some(dir.path().join("b.xml").display().to_string().as_str())
    );
    assert_eq!(summaries[1].repeats, None);
}

/// Vehicle lengths in feet are refused as a whole even where each one is a possible length
/// (a 4.5 m car reads 14.8, and NGSIM does record a few 14 m "cars"): the file's median car
/// is judged, and the error names the file, a line and the likely unit.
#[test]
fn a_file_whose_cars_are_measured_in_feet_is_refused() {
    let mut text = String::new();
    flate2::read::GzDecoder::new(
        std::fs::File::open(us101_dir().join("USA_US101-15_1_T-1.xml.gz")).unwrap(),
    )
    .read_to_string(&mut text)
    .unwrap();
    let mut feet = String::new();
    let mut rest = text.as_str();
    while let Some(at) = rest.find("<length>") {
        let (head, tail) = rest.split_at(at + "<length>".len());
        let end = tail.find("</length>").unwrap();
        let metres: f64 = tail[..end].trim().parse().unwrap();
        feet.push_str(head);
        // Longer vehicles would be refused one by one (over 25 m): only cars and vans here.
        let length = if metres / 0.3048 <= 25.0 {
            metres / 0.3048
        } else {
            metres
        };
        feet.push_str(&format!("{length:.4}"));
        rest = &tail[end..];
    }
    feet.push_str(rest);
    let err = load_error(&feet);
    assert!(
        err.contains("feet") && err.contains("median car") && err.contains("line "),
        "{err}"
    );
}

/// A lanelet whose bounds coincide (0 m wide) or lie 40 m apart is not a lane, and two
/// vehicles may not share an id: each is an error at its element.
#[test]
fn degenerate_lanelets_and_duplicate_vehicle_ids_are_errors() {
    let zero = template(10).replace(
        "<rightBound><point><x>0</x><y>0</y></point><point><x>100</x><y>0</y></point></rightBound>",
        "<rightBound><point><x>0</x><y>3.5</y></point><point><x>100</x><y>3.5</y></point></rightBound>",
    );
    let err = load_error(&zero);
    assert!(
        err.contains("lanelet 1") && err.contains("0.00 m wide") && err.contains("line 3"),
        "{err}"
    );
    let wide = template(10).replace("<y>-3.5</y>", "<y>-40</y>");
    let err = load_error(&wide);
    assert!(
        err.contains("lanelet 2") && err.contains("40.00 m wide"),
        "{err}"
    );

    let text = template(10);
    let start = text.find("  <dynamicObstacle").unwrap();
    let end = text.find("</dynamicObstacle>").unwrap() + "</dynamicObstacle>\n".len();
    let twice = format!("{}{}{}", &text[..end], &text[start..end], &text[end..]);
    let err = load_error(&twice);
    assert!(err.contains("obstacle id 7 is used twice"), "{err}");
}
