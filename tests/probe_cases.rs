//! Cases from the hostile-input probe of issue 20 (a user feeding nonsense to every loader):
//! each was silently accepted, panicked or left half-written output before its fix, and each
//! must now be a clear error naming the file and the place.

use rtr::map::{Map, ProceduralMap};
use rtr::model::ModelConfig;
use rtr::scenario::{ConcreteScenario, LogicalScenario};
use rtr::sim2real::DynamicsFile;
use rtr::train::TrainConfig;

/// `result` is an error whose message contains every one of `needles`.
#[track_caller]
fn refused<T: std::fmt::Debug>(result: rtr::Result<T>, needles: &[&str]) {
    let err = result.expect_err("nonsense was accepted").to_string();
    for needle in needles {
        assert!(err.contains(needle), "`{needle}` missing from: {err}");
    }
}

// ---- scenario JSON ----

fn scenario_json() -> serde_json::Value {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/fuzz/seeds/scenario_json/brake_fast_lane-train-000.json"
    );
    serde_json::from_str(&std::fs::read_to_string(path).expect("seed")).expect("JSON")
}

fn load_scenario(json: &serde_json::Value) -> rtr::Result<ConcreteScenario> {
    ConcreteScenario::from_json_str(&json.to_string(), "s.json")
}

#[test]
fn the_seed_scenario_loads() {
    load_scenario(&scenario_json()).expect("the generated scenario loads");
}

#[test]
fn scenario_nonsense_is_refused_naming_the_field() {
    // history_steps + 1 once wrapped to 0 and indexed out of bounds (a panic).
    let mut j = scenario_json();
    j["history_steps"] = u64::MAX.into();
    for a in j["agents"].as_array_mut().expect("agents") {
        a["states"] = serde_json::json!([]);
    }
    refused(load_scenario(&j), &["s.json", "history_steps"]);

    let mut j = scenario_json();
    j["dt"] = 100.0.into();
    refused(load_scenario(&j), &["s.json", "dt"]);

    let mut j = scenario_json();
    let hero = j["heroes"][0]["agent"].clone();
    j["heroes"][0]["target"] = hero;
    refused(load_scenario(&j), &["heroes[0]", "itself"]);

    let mut j = scenario_json();
    j["heroes"][0]["phases"] = serde_json::json!([]);
    refused(load_scenario(&j), &["heroes[0]", "no phases"]);

    let mut j = scenario_json();
    j["reference"]["collided_agents"] = serde_json::json!([999]);
    refused(load_scenario(&j), &["reference.collided_agents", "999"]);

    // One vehicle a kilometre off the road, and one on top of another.
    let mut j = scenario_json();
    for state in j["agents"][1]["states"].as_array_mut().expect("states") {
        if let Some(y) = state.get(1).and_then(|y| y.as_f64()) {
            state[1] = (y + 1000.0).into();
        }
    }
    refused(load_scenario(&j), &["s.json", "off the road"]);
    let mut j = scenario_json();
    j["agents"][1]["states"] = j["agents"][0]["states"].clone();
    refused(load_scenario(&j), &["s.json", "overlapping"]);
}

#[test]
fn hero_phases_are_held_to_the_family_bounds() {
    let mut j = scenario_json();
    let phases = j["heroes"][0]["phases"].as_array_mut().expect("phases");
    let brake = phases
        .iter_mut()
        .find(|p| p["action"]["kind"] == "brake")
        .expect("the brake_fast_lane hero brakes");
    brake["action"]["decel"] = 1000.0.into();
    refused(load_scenario(&j), &["heroes[0].phases", "decel"]);
}

// ---- run files, model configs, dynamics files ----

fn run_file(extra: &str) -> rtr::Result<TrainConfig> {
    TrainConfig::from_toml_str(&format!("method = \"IL\"\n{extra}"), "run.toml")
}

#[test]
fn run_file_nonsense_is_refused_naming_the_field() {
    // An unbounded minibatch once exhausted memory (an abort, not an error).
    refused(
        run_file("[imitation]\nminibatch = 100000"),
        &["run.toml", "imitation.minibatch"],
    );
    refused(
        run_file("[run]\nmax_iterations = 0"),
        &["run.max_iterations"],
    );
    refused(
        run_file("[data]\nnominal_limit = 0"),
        &["data.nominal_limit"],
    );
    refused(
        run_file("[limits]\nsteer_max = 90.0"),
        &["limits", "steer_max"],
    );
    refused(
        run_file("[limits]\naccel_min = 5.0\naccel_max = -3.0"),
        &["limits", "accel_min"],
    );
    refused(
        run_file("[limits]\naccel_max = nan"),
        &["limits", "accel_max"],
    );
    run_file("[limits]\naccel_min = -6.0\naccel_max = 3.0\nsteer_max = 0.5").expect("valid");
}

#[test]
fn model_config_pairs_are_exactly_two_and_sigma_stays_finite() {
    let model = |text: &str| ModelConfig::from_toml_str(text, "model.toml");
    refused(
        model("action_scale = [1.0, 1.0, 1.0]"),
        &["model.toml", "two"],
    );
    refused(model("log_std_range = [-100.0, 100.0]"), &["log_std_range"]);
    model("action_scale = [2.0, 0.02]\nlog_std_range = [-5.0, 1.0]").expect("valid");
}

#[test]
fn dynamics_files_refuse_a_repeated_effect_and_absurd_coefficients() {
    let dir = tempfile::tempdir().expect("temp dir");
    let load = |name: &str, text: &str| {
        let path = dir.path().join(name);
        std::fs::write(&path, text).expect("write");
        DynamicsFile::load(&path)
    };
    let lag = "[[terms]]\neffect = \"accel_lag\"\nparams = { tau_s = 0.5 }\n";
    load("one.toml", lag).expect("one lag loads");
    refused(
        load("twice.toml", &format!("{lag}{lag}")),
        &["twice.toml", "already"],
    );
    refused(
        load(
            "coef.toml",
            "[[discovered]]\nequation = \"speed\"\nfeature = \"one\"\ncoefficient = 1e30\n",
        ),
        &["coef.toml", "discovered[0]", "coefficient"],
    );
}

// ---- OpenDRIVE ----

/// One straight 100 m road with one 3.5 m driving lane; `geometry` and `lanes_extra` replace
/// its plan view and add to its `<lanes>`, `width` replaces the lane's width record.
fn xodr(geometry: Option<&str>, lanes_extra: &str, width: Option<&str>) -> String {
    let geometry = geometry
        .unwrap_or(r#"<geometry s="0" x="0" y="0" hdg="0" length="100"><line/></geometry>"#);
    let width = width.unwrap_or(r#"<width sOffset="0" a="3.5" b="0" c="0" d="0"/>"#);
    format!(
        r#"<?xml version="1.0"?>
<OpenDRIVE><header revMajor="1" revMinor="4"/>
<road name="r" length="100" id="1" junction="-1"><planView>{geometry}</planView>
<lanes>{lanes_extra}<laneSection s="0"><center><lane id="0" type="none" level="false"/></center>
<right><lane id="-1" type="driving" level="false">{width}</lane></right></laneSection></lanes>
</road></OpenDRIVE>"#
    )
}

#[test]
fn opendrive_geometry_nonsense_is_refused_with_its_line() {
    let load = |text: String| Map::from_xodr_str(&text, "r.xodr");
    load(xodr(None, "", None)).expect("the base road loads");
    // A width that is 3 m at both ends and the middle but bulges to +-50 m in between.
    refused(
        load(xodr(
            None,
            "",
            Some(r#"<width sOffset="0" a="3" b="5" c="-0.15" d="0.001"/>"#),
        )),
        &["r.xodr", "line", "wide"],
    );
    let geometry = |attrs: &str, shape: &str| format!("<geometry {attrs}>{shape}</geometry>");
    // A heading of 90: degrees, where the standard says radians.
    refused(
        load(xodr(
            Some(&geometry(
                r#"s="0" x="0" y="0" hdg="90" length="100""#,
                "<line/>",
            )),
            "",
            None,
        )),
        &["r.xodr", "line", "`hdg`", "degrees"],
    );
    refused(
        load(xodr(
            Some(&geometry(
                r#"s="0" x="1e300" y="0" hdg="0" length="100""#,
                "<line/>",
            )),
            "",
            None,
        )),
        &["r.xodr", "`x`"],
    );
    refused(
        load(xodr(
            Some(&geometry(
                r#"s="0" x="0" y="0" hdg="0" length="10""#,
                "<line/>",
            )),
            "",
            None,
        )),
        &["r.xodr", "100 m long"],
    );
    let two_at_zero = geometry(r#"s="0" x="0" y="0" hdg="0" length="100""#, "<line/>")
        + &geometry(r#"s="0" x="500" y="500" hdg="0" length="100""#, "<line/>");
    refused(
        load(xodr(Some(&two_at_zero), "", None)),
        &["r.xodr", "previous"],
    );
    refused(
        load(xodr(
            Some(&geometry(
                r#"s="0" x="0" y="0" hdg="0" length="100""#,
                r#"<paramPoly3 aU="0" bU="0" cU="0" dU="0" aV="0" bV="0" cV="0" dV="0" pRange="normalized"/>"#,
            )),
            "",
            None,
        )),
        &["r.xodr", "single point"],
    );
    refused(
        load(xodr(
            Some(&geometry(
                r#"s="0" x="0" y="0" hdg="0" length="100""#,
                r#"<poly3 a="0" b="0" c="0" d="1e6"/>"#,
            )),
            "",
            None,
        )),
        &["r.xodr", "radius"],
    );
    refused(
        load(xodr(
            None,
            r#"<laneOffset s="0" a="1e6" b="0" c="0" d="0"/>"#,
            None,
        )),
        &["r.xodr", "laneOffset"],
    );
}

#[test]
fn procedural_maps_are_held_to_road_sized_parameters() {
    let build = |json: &str| {
        serde_json::from_str::<ProceduralMap>(json)
            .expect("well-formed")
            .build()
    };
    build(r#"{"kind":"straight","lanes":3,"lane_width":3.5,"length":400}"#).expect("valid");
    for (json, field) in [
        (
            r#"{"kind":"straight","lanes":3,"lane_width":0.01,"length":400}"#,
            "lane_width",
        ),
        (
            r#"{"kind":"straight","lanes":3,"lane_width":3.5,"length":0.1}"#,
            "length",
        ),
        (
            r#"{"kind":"curve","lanes":1,"lane_width":3.5,"length":100000,"curvature":0.01}"#,
            "cross itself",
        ),
        (
            r#"{"kind":"lane_drop","lanes":3,"lane_width":3.5,"length":600,"drop_s":300,"taper_length":0.001}"#,
            "taper_length",
        ),
        (
            r#"{"kind":"straight","lanes":3,"lane_width":3.5,"length":400,"layout":{"type":"divided","median_width":1000}}"#,
            "median_width",
        ),
    ] {
        refused(build(json), &[field]);
    }
}

// ---- scenario families ----

fn family(edit: impl FnOnce(&mut toml::Table)) -> rtr::Result<LogicalScenario> {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenarios/families/train/cut_in_ttc.toml"
    );
    let mut table: toml::Table =
        toml::from_str(&std::fs::read_to_string(path).expect("family")).expect("TOML");
    edit(&mut table);
    LogicalScenario::from_toml_str(&toml::to_string(&table).expect("TOML"), "f.toml")
}

/// The `[map]` table: the preset and its overridden parameters.
fn map_params(table: &mut toml::Table) -> &mut toml::Table {
    table["map"].as_table_mut().expect("[map]")
}

#[test]
fn family_maps_and_lanes_are_checked_before_drawing() {
    family(|_| {}).expect("the shipped family loads");
    refused(
        family(|t| {
            map_params(t).insert("lanes".into(), toml::Value::Float(2.5));
        }),
        &["f.toml", "map.lanes", "whole"],
    );
    refused(
        family(|t| {
            map_params(t).insert("lanes".into(), toml::Value::Integer(0));
        }),
        &["f.toml", "map"],
    );
    refused(
        family(|t| {
            map_params(t).insert("length".into(), toml::Value::Integer(10));
        }),
        &["f.toml", "map", "length"],
    );
    refused(
        family(|t| {
            t["target"]["lane"] = toml::Value::Integer(9);
        }),
        &["f.toml", "target.lane", "main lane 9"],
    );
}

// ---- recordings ----

/// A valid 1 kHz log (float timestamps stepping 0.000999...) loads, and sim2real thins it to
/// 100 Hz (every 10th sample) instead of simulating a thousand steps per second.
#[test]
fn a_1khz_recording_loads_and_thins_to_100_hz() {
    let mut text = String::from("track_id,t,x,y,heading,speed,accel_cmd,steer_cmd\n");
    for i in 0..3000 {
        let t = i as f64 * 0.001;
        text.push_str(&format!("1,{t},{},0,0,15,0,0\n", 15.0 * t));
    }
    let recordings = rtr::data::Recordings::parse("1khz.csv", &text).expect("a 1 kHz log loads");
    let track = &recordings.tracks[0];
    assert!((track.period - 0.001).abs() < 1e-9);
    let thinned = track.decimated(10);
    assert_eq!(thinned.len(), 300);
    assert!((thinned.period - 0.01).abs() < 1e-9);
    assert_eq!(thinned.t[1], track.t[10]);
}

/// Recordings in which nothing moves carry no physics to compare: sim2real refuses them by
/// file and column instead of reporting that the model explains them.
#[test]
fn parked_recordings_are_refused_before_any_fit() {
    let mut text = String::from("track_id,t,x,y,heading,speed,accel_cmd,steer_cmd\n");
    for track in 1..=3 {
        for i in 0..600 {
            // Three cars parked one behind the other (the same spot would be one track
            // three times, refused as such).
            text.push_str(&format!(
                "{track},{},{},5,0,0,0,0\n",
                i as f64 * 0.1,
                10 * track
            ));
        }
    }
    let recordings = rtr::data::Recordings::parse("parked.csv", &text).expect("it parses");
    let options = rtr::sim2real::identify::Sim2RealOptions::default();
    refused(
        rtr::sim2real::identify::identify(&recordings, &options, &|_| {}).map(|_| ()),
        &["parked.csv", "speed", "no vehicle drives"],
    );
}
