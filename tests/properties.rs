//! Property tests of every loader a user feeds: recordings CSV, OpenDRIVE, scenario JSON and run
//! files. Each starts from a valid document, breaks one value or adds one key, and checks the
//! rule where the input enters: a value outside its physical range or an unknown key is an
//! error naming the file and the line or field; a value inside it loads and is kept. Arbitrary
//! text never panics. The coverage-guided counterparts are the `cargo fuzz` targets in `fuzz/`.

mod common;

use std::sync::OnceLock;

use proptest::prelude::*;
use rtr::data::{Recordings, TrafficStatistics};
use rtr::map::{Map, ProceduralMap, to_xodr};
use rtr::scenario::{
    ConcreteScenario, GenerateConfig, builtin_families, generate_sets, load_families,
};
use rtr::sim2real::{GeneratorConfig, generate};
use rtr::train::TrainConfig;

/// 48 cases per property in the suite; `PROPTEST_CASES=5000` searches longer.
fn config() -> ProptestConfig {
    ProptestConfig {
        cases: std::env::var("PROPTEST_CASES")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(48),
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

/// Text that is not a finite number, or a number no physical quantity here can take.
fn nonsense() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("nan".to_string()),
        Just("NaN".to_string()),
        Just("inf".to_string()),
        Just("-inf".to_string()),
        Just(String::new()),
        Just("1e308".to_string()),
        Just("-1e308".to_string()),
        "[a-z]{1,6}",
        (1e8f64..1e300).prop_map(|v| format!("{v:e}")),
    ]
}

// ---- recordings CSV ----

/// Three short synthetic tracks (no concealed effect), as CSV.
fn recordings_csv() -> &'static str {
    static CSV: OnceLock<String> = OnceLock::new();
    CSV.get_or_init(|| {
        let device = rtr::backend::Backend::reference_device(false);
        let mut config = GeneratorConfig::with_effect(None, 5);
        config.tracks = 3;
        config.duration_s = 4.0;
        generate(&config, &device).to_csv()
    })
}

/// Every value of loaded recordings is finite, and each track is sampled uniformly.
fn assert_sane(r: &Recordings) {
    for track in &r.tracks {
        assert!(track.len() >= 2 && track.period > 0.0);
        for v in [
            &track.t,
            &track.x,
            &track.y,
            &track.heading,
            &track.speed,
            &track.accel_cmd,
            &track.steer_cmd,
        ] {
            assert!(v.iter().all(|x| x.is_finite()), "{}: non-finite", track.id);
        }
        assert!(track.t.windows(2).all(|w| w[1] > w[0]));
    }
}

/// `csv` with the cell at `row` (0 = the first data row) and `column` replaced by `value`.
fn with_cell(csv: &str, row: usize, column: usize, value: &str) -> String {
    csv.lines()
        .enumerate()
        .map(|(i, line)| {
            if i != row + 1 {
                return line.to_string();
            }
            let mut cells: Vec<&str> = line.split(',').collect();
            cells[column] = value;
            cells.join(",")
        })
        .collect::<Vec<_>>()
        .join("\n")
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn recordings_round_trip_through_csv(seed in 0u64..1000) {
        let device = rtr::backend::Backend::reference_device(false);
        let mut config = GeneratorConfig::with_effect(None, seed);
        config.tracks = 3;
        config.duration_s = 3.0;
        let original = generate(&config, &device);
        let back = Recordings::parse("rec.csv", &original.to_csv()).expect("own CSV loads");
        prop_assert_eq!(back.tracks.len(), original.tracks.len());
        for (a, b) in original.tracks.iter().zip(&back.tracks) {
            prop_assert_eq!(&a.x, &b.x);
            prop_assert_eq!(&a.speed, &b.speed);
            prop_assert_eq!(&a.steer_cmd, &b.steer_cmd);
        }
    }

    /// A number cell that is not a number, or far outside any physical range, is refused
    /// with its line.
    #[test]
    fn a_nonsense_recordings_cell_is_refused_with_its_line(
        row in 0usize..20,
        column in 1usize..8,
        value in nonsense(),
    ) {
        let text = with_cell(recordings_csv(), row, column, &value);
        let err = Recordings::parse("rec.csv", &text).expect_err("nonsense loaded").to_string();
        prop_assert!(err.contains("rec.csv"), "{}", err);
        prop_assert!(err.contains(&format!("line {}", row + 2)), "{}", err);
    }

    /// Any text: recordings whose values are finite, or an error naming the file.
    #[test]
    fn any_text_as_recordings_is_an_error_or_sane(
        header in prop_oneof![
            Just("track_id,t,x,y,heading,speed,accel_cmd,steer_cmd\n".to_string()),
            Just(String::new()),
        ],
        body in "[0-9a-z.,eE+\\- \n]{0,400}",
    ) {
        match Recordings::parse("rec.csv", &format!("{header}{body}")) {
            Ok(r) => assert_sane(&r),
            Err(e) => prop_assert!(e.to_string().contains("rec.csv"), "{}", e),
        }
    }
}

// ---- OpenDRIVE ----

/// A generated curved motorway (line, spiral, arc) with three driving lanes and a shoulder.
fn curve_xodr() -> &'static str {
    static XODR: OnceLock<String> = OnceLock::new();
    XODR.get_or_init(|| {
        let od = ProceduralMap::preset("curve")
            .and_then(|p| p.build())
            .expect("the curve preset builds");
        to_xodr(&od)
    })
}

/// Replaces the value of the `occurrence`-th `name="..."` attribute (counting from 0,
/// wrapping around) with `value`; returns the text and the 1-based line it is on.
fn with_attribute(xodr: &str, name: &str, occurrence: usize, value: &str) -> (String, usize) {
    let needle = format!(" {name}=\"");
    let starts: Vec<usize> = xodr.match_indices(&needle).map(|(i, _)| i).collect();
    let start = starts[occurrence % starts.len()] + needle.len();
    let end = start + xodr[start..].find('"').expect("closing quote");
    let line = xodr[..start].matches('\n').count() + 1;
    (format!("{}{value}{}", &xodr[..start], &xodr[end..]), line)
}

proptest! {
    #![proptest_config(config())]

    /// A lane width between 0 and 10 m is kept as given; anything else is refused with the
    /// element's line (the 1e9 m lane that once hung the map commands among them).
    #[test]
    fn lane_widths_are_kept_in_range_and_refused_outside(
        lane in 0usize..4,
        width in prop_oneof![0.5f64..10.0, -1e9f64..-0.01, 10.01f64..1e9],
    ) {
        let (text, _) = with_attribute(curve_xodr(), "a", lane, &width.to_string());
        let result = Map::from_xodr_str(&text, "curve.xodr");
        if (0.5..=10.0).contains(&width) {
            let map = result.expect("a plausible width loads");
            let widths: Vec<f64> = map.lanes().iter().flat_map(|l| l.widths.clone()).collect();
            prop_assert!(widths.iter().any(|w| (w - width).abs() < 1e-9), "{} not kept", width);
        } else {
            let err = result.expect_err("an implausible width loaded").to_string();
            prop_assert!(err.contains("curve.xodr") && err.contains("wide"), "{}", err);
        }
    }

    /// Any number in any numeric attribute: a map whose lanes are finite, or an error naming
    /// the file.
    #[test]
    fn any_number_anywhere_gives_a_finite_map_or_an_error(
        name in prop_oneof![
            Just("length"), Just("x"), Just("y"), Just("hdg"), Just("curvature"),
            Just("curvStart"), Just("curvEnd"), Just("s"), Just("b"), Just("max"),
        ],
        occurrence in 0usize..8,
        value in prop_oneof![nonsense(), (-1e4f64..1e4).prop_map(|v| v.to_string())],
    ) {
        let (text, _) = with_attribute(curve_xodr(), name, occurrence, &value);
        match Map::from_xodr_str(&text, "curve.xodr") {
            Ok(map) => {
                prop_assert!(!map.lanes().is_empty());
                for lane in map.lanes() {
                    prop_assert!(lane.centerline.iter().flatten().all(|v| v.is_finite()));
                    prop_assert!(lane.widths.iter().all(|w| (0.0..=10.0).contains(w)));
                    prop_assert!(lane.speed_limit > 0.0 && lane.speed_limit <= 90.0, "{}", lane.speed_limit);
                }
            }
            Err(e) => prop_assert!(e.to_string().contains("curve.xodr"), "{}", e),
        }
    }
}

/// A generated on-ramp merge: several roads joined by road links and a junction with lane
/// links.
fn ramp_xodr() -> &'static str {
    static XODR: OnceLock<String> = OnceLock::new();
    XODR.get_or_init(|| {
        let od = ProceduralMap::preset("on_ramp_merge")
            .and_then(|p| p.build())
            .expect("the on-ramp preset builds");
        to_xodr(&od)
    })
}

proptest! {
    #![proptest_config(config())]

    /// Any road named by a link or connection and any lane id named by a lane link: a map
    /// whose joined lanes touch, or an error naming the file (a link to a road whose end lies
    /// elsewhere, to a lane or road that does not exist).
    #[test]
    fn any_link_target_gives_a_connected_map_or_an_error(
        attribute in prop_oneof![
            Just("elementId"), Just("incomingRoad"), Just("connectingRoad"),
            Just("from"), Just("to"), Just("id"),
        ],
        occurrence in 0usize..24,
        value in prop_oneof![(-6i32..7).prop_map(|v| v.to_string()), "[a-z0-9_]{1,4}"],
    ) {
        prop_assume!(ramp_xodr().contains(&format!(" {attribute}=\"")));
        let (text, _) = with_attribute(ramp_xodr(), attribute, occurrence, &value);
        match Map::from_xodr_str(&text, "ramp.xodr") {
            Ok(map) => {
                // Joined lanes touch: a successor starts within a few lane widths of where
                // its lane ends (a link across a gap would put it on another road's far end).
                let lanes = map.lanes();
                for lane in lanes {
                    let Some(end) = lane.centerline.last() else { continue };
                    for &k in &lane.successors {
                        let start = lanes[k].centerline[0];
                        let gap = (end[0] - start[0]).hypot(end[1] - start[1]);
                        prop_assert!(gap < 12.0, "lane {} -> {}: {:.1} m apart", lane.id, lanes[k].id, gap);
                    }
                }
            }
            Err(e) => prop_assert!(e.to_string().contains("ramp.xodr"), "{}", e),
        }
    }
}

// ---- scenario JSON ----

/// One generated long-tail scenario, as JSON.
fn scenario_json() -> &'static str {
    static JSON: OnceLock<String> = OnceLock::new();
    JSON.get_or_init(|| {
        let a9 = common::a9();
        let stats = TrafficStatistics::from_recording(&a9.recording, &a9.map, 1.0);
        let families = load_families(&builtin_families()).expect("shipped families load");
        let config = GenerateConfig {
            in_distribution: 1,
            ood: 0,
            ..GenerateConfig::default()
        };
        let sets = generate_sets(&families, &stats, &config).expect("a scenario generates");
        sets.train[0].to_json().expect("encodes")
    })
}

proptest! {
    #![proptest_config(config())]

    /// Vehicle sizes: 1-25 m long and 0.5-5 m wide load (where they fit on the road beside
    /// their neighbours); others are refused naming the field.
    #[test]
    fn scenario_vehicle_sizes_are_checked_where_they_enter(
        agent in 0usize..64,
        field in prop_oneof![Just("length"), Just("width")],
        value in prop_oneof![0.5f64..25.0, -100.0f64..0.49, 25.01f64..1e6],
    ) {
        let mut json: serde_json::Value = serde_json::from_str(scenario_json()).expect("JSON");
        let agents = json["agents"].as_array_mut().expect("agents");
        let i = agent % agents.len();
        agents[i][field] = value.into();
        let text = json.to_string();
        let range = if field == "length" { 1.0..=25.0 } else { 0.5..=5.0 };
        match ConcreteScenario::from_json_str(&text, "s.json") {
            Ok(s) => {
                prop_assert!(range.contains(&value), "{} {} loaded", field, value);
                let got = if field == "length" { s.agents[i].length } else { s.agents[i].width };
                // serde_json parses floats to within an ulp.
                prop_assert!((got - value).abs() <= 1e-12 * value.abs(), "{} vs {}", got, value);
            }
            // A plausible size may still not fit where the vehicle stands (a wider truck now
            // overlapping its neighbour, or over the edge): refused for that, not the size.
            Err(e) if range.contains(&value) => {
                let err = e.to_string();
                prop_assert!(
                    err.contains("s.json") && (err.contains("overlapping") || err.contains("off the road")),
                    "{} {} refused: {}", field, value, err
                );
            }
            Err(e) => {
                let place = format!("agents[{i}].{field}");
                prop_assert!(e.to_string().contains("s.json") && e.to_string().contains(&place), "{}", e);
            }
        }
    }

    /// A state (x, y, heading, speed) with a value no vehicle has is refused naming the state.
    #[test]
    fn scenario_states_in_degrees_or_kmh_are_refused(
        agent in 0usize..64,
        component in 0usize..4,
        value in prop_oneof![1e7f64..1e300, -1e300f64..-1e7],
    ) {
        let mut json: serde_json::Value = serde_json::from_str(scenario_json()).expect("JSON");
        let agents = json["agents"].as_array_mut().expect("agents");
        let i = agent % agents.len();
        let states = agents[i]["states"].as_array_mut().expect("states");
        let k = states.iter().position(|s| !s.is_null()).expect("a present state");
        states[k][component] = value.into();
        let err = ConcreteScenario::from_json_str(&json.to_string(), "s.json")
            .expect_err("nonsense loaded")
            .to_string();
        prop_assert!(err.contains(&format!("agents[{i}].states[{k}]")), "{}", err);
    }

    /// An unknown key anywhere in the document is refused, naming it.
    #[test]
    fn scenario_unknown_keys_are_refused(key in "[a-z]{3,10}_x", at_agent in any::<bool>()) {
        let mut json: serde_json::Value = serde_json::from_str(scenario_json()).expect("JSON");
        let target = if at_agent { &mut json["agents"][0] } else { &mut json };
        target.as_object_mut().expect("object").insert(key.clone(), 1.into());
        let err = ConcreteScenario::from_json_str(&json.to_string(), "s.json")
            .expect_err("unknown key loaded")
            .to_string();
        prop_assert!(err.contains(&key) && err.contains("s.json"), "{}", err);
    }
}

// ---- run files ----

/// The small RTR run file shipped with the main study (every setting below applies to RTR).
fn run_file() -> toml::Table {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/main/small/rtr.toml");
    toml::from_str(&std::fs::read_to_string(path).expect("run file")).expect("TOML")
}

/// A real-valued setting of the run file and the range it must lie in.
struct Setting {
    section: &'static str,
    key: &'static str,
    low: f64,
    high: f64,
    /// Whether values above `high` are nonsense (shares, factors) or merely large (weights).
    bounded_above: bool,
}

const fn setting(
    section: &'static str,
    key: &'static str,
    low: f64,
    high: f64,
    bounded_above: bool,
) -> Setting {
    Setting {
        section,
        key,
        low,
        high,
        bounded_above,
    }
}

const SETTINGS: [Setting; 8] = [
    setting("", "alpha", 0.0, 1.0, true),
    setting("", "lambda", 0.0, 1e6, false),
    setting("optimizer", "learning_rate", 1e-12, 1.0, true),
    setting("optimizer", "decay", 1e-6, 1.0, true),
    setting("optimizer", "weight_decay", 0.0, 1e3, false),
    setting("optimizer", "grad_clip_norm", 1e-6, 1e6, false),
    setting("ppo", "clip", 1e-6, 0.999, true),
    setting("ppo", "gamma", 0.0, 1.0, true),
];

fn set(table: &mut toml::Table, section: &str, key: &str, value: toml::Value) {
    let target = if section.is_empty() {
        table
    } else {
        table
            .entry(section)
            .or_insert_with(|| toml::Value::Table(toml::Table::new()))
            .as_table_mut()
            .expect("a section")
    };
    target.insert(key.to_string(), value);
}

proptest! {
    #![proptest_config(config())]

    /// A setting inside its range loads as written; outside it (NaN and infinities included,
    /// which TOML can spell) the error names the file and the field.
    #[test]
    fn run_file_settings_are_checked_where_they_enter(
        which in 0usize..SETTINGS.len(),
        inside in any::<bool>(),
        t in 0.0f64..1.0,
        outside in prop_oneof![
            Just(f64::NAN), Just(f64::INFINITY), Just(f64::NEG_INFINITY),
            -1e6f64..-1e-3, 1.001f64..1e3,
        ],
    ) {
        let s = &SETTINGS[which];
        let value = match (inside, outside > 1.0) {
            (true, _) => s.low + t * (s.high - s.low),
            // Above the top only where the top is a real bound; elsewhere below zero.
            (false, true) if s.bounded_above => s.high * outside + 1e-3,
            (false, true) => -outside,
            (false, false) => outside,
        };
        let mut table = run_file();
        set(&mut table, s.section, s.key, toml::Value::Float(value));
        let text = toml::to_string(&table).expect("TOML");
        match TrainConfig::from_toml_str(&text, "run.toml") {
            Ok(_) => prop_assert!(inside, "{} = {} loaded", s.key, value),
            Err(e) => {
                prop_assert!(!inside, "{} = {} refused: {}", s.key, value, e);
                let err = e.to_string();
                prop_assert!(err.contains("run.toml") && err.contains(s.key), "{}", err);
            }
        }
    }

    /// An unknown key in any section is refused with its name and line.
    #[test]
    fn run_file_unknown_keys_are_refused(
        section in prop_oneof![Just(""), Just("optimizer"), Just("ppo"), Just("data"), Just("model")],
        key in "[a-z]{3,10}_x",
    ) {
        let mut table = run_file();
        set(&mut table, section, &key, toml::Value::Integer(1));
        let text = toml::to_string(&table).expect("TOML");
        let err = TrainConfig::from_toml_str(&text, "run.toml").expect_err("unknown key").to_string();
        prop_assert!(err.contains(&key) && err.contains("run.toml") && err.contains("line"), "{}", err);
    }

    /// Any text as a run file: a config or an error naming the file, never a panic.
    #[test]
    fn any_text_as_a_run_file_is_an_error_or_a_config(text in "[a-z_=.\\[\\]0-9\" \n]{0,300}") {
        if let Err(e) = TrainConfig::from_toml_str(&text, "run.toml") {
            prop_assert!(e.to_string().contains("run.toml"), "{}", e);
        }
    }
}
