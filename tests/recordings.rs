//! Loading vehicle recordings for sim-to-real identification: values, round trips, and one
//! test per kind of bad input (each error must name the source, the line and the column).

use rtr::data::{RecordedTrack, Recordings};

const HEADER: &str = "track_id,t,x,y,heading,speed,accel_cmd,steer_cmd";

/// Parses `text` and returns the error's Display text; panics if it parses.
fn error(text: &str) -> String {
    match Recordings::parse("rec.csv", text) {
        Ok(r) => panic!("expected an error, parsed {} tracks", r.tracks.len()),
        Err(e) => {
            let message = e.to_string();
            assert!(message.starts_with("rec.csv: "), "no source in: {message}");
            message
        }
    }
}

/// Asserts that `message` contains every one of `parts`.
fn assert_contains(message: &str, parts: &[&str]) {
    for part in parts {
        assert!(message.contains(part), "`{part}` not in: {message}");
    }
}

/// A file with one good track `a` (period 0.1 s) and `row` as its third data row (line 4).
fn with_row(row: &str) -> String {
    format!("{HEADER}\na,0.0,0,0,0,1,0,0\na,0.1,0,0,0,1,0,0\n{row}\na,0.3,0,0,0,1,0,0\n")
}

fn assert_same(a: &RecordedTrack, b: &RecordedTrack) {
    assert_eq!(a.id, b.id);
    assert_eq!(a.period.to_bits(), b.period.to_bits());
    assert_eq!(a.t, b.t);
    assert_eq!(a.x, b.x);
    assert_eq!(a.y, b.y);
    assert_eq!(a.heading, b.heading);
    assert_eq!(a.speed, b.speed);
    assert_eq!(a.accel_cmd, b.accel_cmd);
    assert_eq!(a.steer_cmd, b.steer_cmd);
    assert_eq!(a.wheelbase, b.wheelbase);
}

const GOOD: &str = "\
note,steer_cmd,accel_cmd,speed,heading,y,x,t,track_id,wheelbase
first,0.01,0.5,10.0,0.1,2.0,1.0,0.0,car7,2.7
x,0.0,0.0,0.0,-3.0,-1.0,5.0,1.00,truck,4.5
,0.02,0.6,10.05,0.11,2.1,2.0,0.1,car7,2.7
y,0.0,0.1,0.0,-3.0,-1.0,5.0,1.05,truck,4.5
,0.03,0.7,10.1,0.12,2.2,3.0,0.2,car7,2.7005

z,0.0,0.2,0.01,-3.0,-1.0,5.0,1.10,truck,4.5
";

#[test]
fn good_file_with_interleaved_tracks_parses_to_the_right_values() {
    let rec = Recordings::parse("good.csv", GOOD).unwrap();
    assert_eq!(rec.source, "good.csv");
    assert_eq!(rec.tracks.len(), 2);

    let car = &rec.tracks[0];
    assert_eq!(car.id, "car7");
    assert_eq!(car.first_line, 2);
    assert_eq!(car.len(), 3);
    assert!(!car.is_empty());
    assert_eq!(car.t, [0.0, 0.1, 0.2]);
    assert_eq!(car.x, [1.0, 2.0, 3.0]);
    assert_eq!(car.y, [2.0, 2.1, 2.2]);
    assert_eq!(car.heading, [0.1, 0.11, 0.12]);
    assert_eq!(car.speed, [10.0, 10.05, 10.1]);
    assert_eq!(car.accel_cmd, [0.5, 0.6, 0.7]);
    assert_eq!(car.steer_cmd, [0.01, 0.02, 0.03]);
    assert_eq!(car.wheelbase, Some(2.7));
    assert!((car.period - 0.1).abs() < 1e-12, "{}", car.period);
    assert!((car.duration() - 0.2).abs() < 1e-12);

    let truck = &rec.tracks[1];
    assert_eq!(truck.id, "truck");
    assert_eq!(truck.first_line, 3);
    assert_eq!(truck.t, [1.0, 1.05, 1.1]);
    assert_eq!(truck.heading, [-3.0; 3]);
    assert_eq!(truck.speed, [0.0, 0.0, 0.01]);
    assert_eq!(truck.accel_cmd, [0.0, 0.1, 0.2]);
    assert_eq!(truck.wheelbase, Some(4.5));
    assert!((truck.period - 0.05).abs() < 1e-12, "{}", truck.period);
}

#[test]
fn wheelbase_is_optional() {
    let rec = Recordings::parse("rec.csv", &with_row("a,0.2,0,0,0,1,0,0")).unwrap();
    assert_eq!(rec.tracks.len(), 1);
    assert_eq!(rec.tracks[0].wheelbase, None);
    assert_eq!(rec.tracks[0].len(), 4);
    assert!(rec.to_csv().starts_with(&format!("{HEADER}\n")));
}

#[test]
fn to_csv_then_parse_round_trips_exactly() {
    // Values with full f64 precision, a track id that needs quoting, different periods.
    let mut text = format!("{HEADER},wheelbase\n");
    for k in 0..50 {
        let s = k as f64;
        text.push_str(&format!(
            "\"car, \"\"7\"\"\",{},{},{},{},{},{},{},2.845\n",
            s * 0.1,
            s * 1.3 + (s * 0.37).sin() * 0.123456789,
            -(s * 0.11).cos() / 3.0,
            (s * 0.05).sin() * 0.05 * std::f64::consts::PI,
            13.0 + s / 7.0,
            (s * 0.3).sin() * 1.7,
            (s * 0.2).cos() * 0.05,
        ));
        if k % 2 == 0 {
            text.push_str(&format!(
                "bus,{},{},0,{},{},{},-0.0001,12.5\n",
                100.0 + s * 0.04 / 2.0,
                s / 3.0,
                -1.0 / 7.0,
                16.0 + 0.01 * s,
                -1.0 / 3.0
            ));
        }
    }
    let rec = Recordings::parse("gen.csv", &text).unwrap();
    assert_eq!(rec.tracks.len(), 2);
    assert_eq!(rec.tracks[0].id, "car, \"7\"");
    assert_eq!(rec.tracks[1].id, "bus");

    let csv = rec.to_csv();
    assert!(csv.starts_with(&format!("{HEADER},wheelbase\n")));
    let back = Recordings::parse("back.csv", &csv).unwrap();
    assert_eq!(back.tracks.len(), rec.tracks.len());
    for (a, b) in rec.tracks.iter().zip(&back.tracks) {
        assert_same(a, b);
    }
    assert_eq!(back.to_csv(), csv);
}

#[test]
fn save_then_load_round_trips() {
    let rec = Recordings::parse("good.csv", GOOD).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sub").join("rec.csv");
    rec.save(&path).unwrap();
    let back = Recordings::load(&path).unwrap();
    assert_eq!(back.source, path.display().to_string());
    for (a, b) in rec.tracks.iter().zip(&back.tracks) {
        assert_same(a, b);
    }
}

#[test]
fn missing_file_names_the_path() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nope.csv");
    let message = Recordings::load(&path).unwrap_err().to_string();
    assert_contains(&message, &[&path.display().to_string()]);
}

#[test]
fn missing_columns_are_listed_with_the_expected_header() {
    let message = error("track_id,t,x,y,speed,accel_cmd,extra\na,0,0,0,1,0,0\n");
    assert_contains(
        &message,
        &["line 1", "`heading`", "`steer_cmd`", "missing", HEADER],
    );
}

#[test]
fn duplicate_column_is_rejected() {
    let message = error(&format!("{HEADER},x\na,0,0,0,0,1,0,0,0\n"));
    assert_contains(&message, &["line 1", "`x`", "twice"]);
}

/// Extra columns are ignored, but one named like a known column misspelt is refused: its
/// values (a wheelbase) would be dropped without a word.
#[test]
fn a_misspelt_column_is_refused_and_other_extras_ignored() {
    for (column, expected) in [
        ("wheelbse", "`wheelbase`"),
        ("Wheelbase", "`wheelbase`"),
        ("steer_cmmd", "`steer_cmd`"),
        ("X", "`x`"),
    ] {
        let message = error(&format!("{HEADER},{column}\na,0,0,0,0,1,0,0,4.2\n"));
        assert_contains(
            &message,
            &["line 1, column 9", column, expected, "misspelt"],
        );
    }
    for extra in ["z", "id", "lat", "lane", "note"] {
        let text = format!(
            "{HEADER},{extra}\na,0.0,0,0,0,1,0,0,1\na,0.1,0.1,0,0,1,0,0,1\na,0.2,0.2,0,0,1,0,0,1\n"
        );
        Recordings::parse("rec.csv", &text)
            .unwrap_or_else(|e| panic!("`{extra}` is another column: {e}"));
    }
}

#[test]
fn empty_file_is_rejected() {
    assert_contains(&error(""), &["line 1", "empty", HEADER]);
    assert_contains(&error("  \n\n"), &["line 1", "empty"]);
}

#[test]
fn header_without_rows_is_rejected() {
    assert_contains(&error(&format!("{HEADER}\n")), &["no data rows"]);
}

#[test]
fn unparsable_number_names_line_and_column() {
    let message = error(&with_row("a,0.2,abc,0,0,1,0,0"));
    assert_contains(&message, &["line 4", "`x`", "`abc`", "not a number"]);
    let message = error(&with_row("a,0.2,0,,0,1,0,0"));
    assert_contains(&message, &["line 4", "`y`", "empty"]);
}

#[test]
fn nan_is_rejected() {
    let message = error(&with_row("a,0.2,0,0,0,NaN,0,0"));
    assert_contains(&message, &["line 4", "`speed`", "NaN", "finite"]);
}

#[test]
fn infinity_is_rejected() {
    let message = error(&with_row("a,0.2,0,0,0,1,-inf,0"));
    assert_contains(&message, &["line 4", "`accel_cmd`", "infinite", "finite"]);
}

#[test]
fn wrong_field_count_is_a_parse_error() {
    let message = error(&with_row("a,0.2,0,0,0,1,0"));
    assert_contains(&message, &["line 4", "7 fields", "header has 8"]);
}

#[test]
fn empty_track_id_is_rejected() {
    let message = error(&with_row(",0.2,0,0,0,1,0,0"));
    assert_contains(&message, &["line 4", "`track_id`", "empty"]);
}

#[test]
fn heading_in_degrees_is_rejected() {
    let message = error(&with_row("a,0.2,0,0,90,1,0,0"));
    assert_contains(
        &message,
        &["line 4", "`heading`", "90", "degrees", "radians"],
    );
    // Up to one turn (and a little) is fine: unwrapped headings.
    Recordings::parse("rec.csv", &with_row("a,0.2,0,0,-6.29,1,0,0")).unwrap();
}

#[test]
fn steering_wheel_angle_is_rejected() {
    let message = error(&with_row("a,0.2,0,0,0,1,0,-1.5"));
    assert_contains(
        &message,
        &[
            "line 4",
            "`steer_cmd`",
            "-1.5",
            "degrees",
            "steering-wheel",
            "road-wheel",
        ],
    );
}

#[test]
fn speed_in_kmh_is_rejected() {
    let message = error(&with_row("a,0.2,0,0,0,120,0,0"));
    assert_contains(&message, &["line 4", "`speed`", "120", "km/h", "m/s"]);
}

#[test]
fn negative_speed_is_rejected() {
    let message = error(&with_row("a,0.2,0,0,0,-3,0,0"));
    assert_contains(&message, &["line 4", "`speed`", "-3", "negative"]);
    // Small negative speeds (estimator noise) are tolerated.
    Recordings::parse("rec.csv", &with_row("a,0.2,0,0,0,-0.5,0,0")).unwrap();
}

#[test]
fn implausible_acceleration_is_rejected() {
    let message = error(&with_row("a,0.2,0,0,0,1,-35,0"));
    assert_contains(&message, &["line 4", "`accel_cmd`", "-35", "m/s^2"]);
}

/// Like [`with_row`] but with a wheelbase column; `row` is line 4.
fn with_wheelbase_row(row: &str) -> String {
    format!(
        "{HEADER},wheelbase\na,0.0,0,0,0,1,0,0,2.7\na,0.1,0,0,0,1,0,0,2.7\n{row}\n\
         a,0.3,0,0,0,1,0,0,2.7\n"
    )
}

#[test]
fn wheelbase_in_millimetres_is_rejected() {
    let message = error(&format!("{HEADER},wheelbase\na,0,0,0,0,1,0,0,2700\n"));
    assert_contains(
        &message,
        &["line 2", "`wheelbase`", "2700", "millimetres", "metres"],
    );
    let message = error(&with_wheelbase_row("a,0.2,0,0,0,1,0,0,0.5"));
    assert_contains(&message, &["line 4", "`wheelbase`", "0.5", "too small"]);
}

#[test]
fn changing_wheelbase_is_rejected() {
    let message = error(&with_wheelbase_row("a,0.2,0,0,0,1,0,0,2.9"));
    assert_contains(
        &message,
        &["line 4", "`wheelbase`", "2.9", "2.7", "line 2", "constant"],
    );
    // Within 1 mm is the same wheelbase.
    Recordings::parse("rec.csv", &with_wheelbase_row("a,0.2,0,0,0,1,0,0,2.7009")).unwrap();
}

#[test]
fn wheelbase_on_some_rows_only_is_rejected() {
    let message = error(&with_wheelbase_row("a,0.2,0,0,0,1,0,0,"));
    assert_contains(&message, &["line 4", "`wheelbase`", "line 2", "every row"]);
}

#[test]
fn non_increasing_time_is_rejected() {
    let message = error(&with_row("a,0.1,0,0,0,1,0,0"));
    assert_contains(
        &message,
        &["line 4", "`t`", "0.1", "line 3", "strictly increasing"],
    );
    assert_contains(&message, &["repeats the time of the row before"]);
    let message = error(&with_row("a,0.05,0,0,0,1,0,0"));
    assert_contains(&message, &["time 0.05", "does not increase after 0.1"]);
    // A time far past any clock (milliseconds since 1970 read as seconds) is named as such.
    let message = error(&with_row("a,1.7e12,0,0,0,1,0,0"));
    assert_contains(&message, &["line 4", "time 1.7e12 s is implausible"]);
}

/// Times are shown as written, not with the float's rounding digits.
#[test]
fn times_in_messages_are_shown_without_rounding_digits() {
    let rows: String = (0..6)
        .map(|k| {
            format!(
                "a,{},0,0,0,1,0,0\n",
                100.0 + 0.1 * f64::from(k) + if k == 5 { 0.5 } else { 0.0 }
            )
        })
        .collect();
    let message = error(&format!("{HEADER}\n{rows}"));
    assert_contains(&message, &["median step) is 0.1 s", "a step of 0.6 s"]);
    assert!(!message.contains("0000000"), "{message}");
}

#[test]
fn time_gap_is_rejected() {
    // Steps 0.1, 0.1, 0.3, 0.1: period 0.1, the gap ends on line 5.
    let text = format!(
        "{HEADER}\nb,0,0,0,0,1,0,0\nb,0.1,0,0,0,1,0,0\nb,0.2,0,0,0,1,0,0\nb,0.5,0,0,0,1,0,0\n\
         b,0.6,0,0,0,1,0,0\n"
    );
    let message = error(&text);
    assert_contains(
        &message,
        &[
            "line 5",
            "`t`",
            "track `b`",
            "0.5",
            "line 4",
            "period",
            "0.1 s",
            "gap",
        ],
    );
}

#[test]
fn time_jitter_is_rejected() {
    // A step of 0.108 s against a 0.1 s period (8% off).
    let text = format!(
        "{HEADER}\nb,0,0,0,0,1,0,0\nb,0.1,0,0,0,1,0,0\nb,0.2,0,0,0,1,0,0\nb,0.308,0,0,0,1,0,0\n\
         b,0.408,0,0,0,1,0,0\nb,0.508,0,0,0,1,0,0\n"
    );
    let message = error(&text);
    assert_contains(&message, &["line 5", "`t`", "0.308", "period", "jitter"]);
    // 3% jitter is tolerated.
    let ok = text.replace("0.308", "0.303").replace("0.408", "0.403");
    let ok = ok.replace("0.508", "0.503");
    Recordings::parse("rec.csv", &ok).unwrap();
}

#[test]
fn single_sample_track_is_rejected() {
    let text = format!("{HEADER}\na,0,0,0,0,1,0,0\na,0.1,0,0,0,1,0,0\nb,0,0,0,0,1,0,0\n");
    let message = error(&text);
    assert_contains(&message, &["track `b`", "line 4", "at least 2", "period"]);
}

#[test]
fn timestamps_in_milliseconds_are_rejected() {
    // 10 Hz with t in ms: a median step of 100.
    let text = format!("{HEADER}\nm,0,0,0,0,1,0,0\nm,100,0,0,0,1,0,0\nm,200,0,0,0,1,0,0\n");
    let message = error(&text);
    assert_contains(
        &message,
        &[
            "track `m`",
            "`t`",
            "line 2",
            "100",
            "milliseconds",
            "seconds",
        ],
    );
}

#[test]
fn a_log_slower_than_1_hz_is_rejected() {
    let text = format!("{HEADER}\ns,0,0,0,0,1,0,0\ns,10,10,0,0,1,0,0\ns,20,20,0,0,1,0,0\n");
    assert_contains(&error(&text), &["track `s`", "period", "10", "1 Hz"]);
}

/// A horizon shorter than two sampling periods (which once panicked in the simulator) is an
/// error naming the track and the horizon, on any recordings (a file's or the A9's).
#[test]
fn a_horizon_shorter_than_two_samples_is_named_not_a_panic() {
    use rtr::sim2real::{GeneratorConfig, Sim2RealOptions, generate, identify};
    let device = rtr::backend::Backend::reference_device(false);
    let recordings = generate(
        &GeneratorConfig {
            tracks: 4,
            duration_s: 20.0,
            ..GeneratorConfig::with_effect(None, 7)
        },
        &device,
    );
    let options = Sim2RealOptions {
        horizon_s: 0.05,
        ..Sim2RealOptions::default()
    };
    let message = match identify(&recordings, &options, &|_| {}) {
        Ok(_) => panic!("a 0.05 s horizon at 10 Hz was accepted"),
        Err(e) => e.to_string(),
    };
    assert_contains(&message, &["track", "0.05 s horizon", "at least 2 samples"]);
}

#[test]
fn an_absurd_position_in_one_row_is_rejected() {
    let message = error(&with_row("a,0.2,1e308,0,0,1,0,0"));
    assert_contains(&message, &["line 4", "`x`", "1e308 m", "10000000"]);
}

/// A row 1000 m off the track (a teleport) would be fitted as driving; it is refused by line.
#[test]
fn a_teleporting_row_is_rejected() {
    let text = format!(
        "{HEADER}\nj,0,0,0,0,10,0,0\nj,0.1,1,0,0,10,0,0\nj,0.2,1002,0,0,10,0,0\nj,0.3,3,0,0,10,0,0\n"
    );
    let message = error(&text);
    assert_contains(
        &message,
        &["line 4", "track `j`", "1001.00 m", "line 3", "jump"],
    );
    // Ordinary driving with position noise passes.
    let ok = text.replace("1002,", "2.3,");
    Recordings::parse("rec.csv", &ok).unwrap();
}

/// A noisier sensor scatters a standing car's positions by more than a metre between some
/// samples: ordinary for that sensor, not a jump. A glitch of 20 m in the same track still is.
#[test]
fn the_jump_allowance_grows_with_the_tracks_own_noise() {
    // Five samples a second for a minute, 0.45 m of scatter in a fixed pattern (no trend).
    let row = |k: usize, glitch: f64| {
        let noise = |phase: f64| 0.45 * (k as f64 * 2.7 + phase).sin();
        format!(
            "s,{:.1},{:.4},{:.4},0,0.05,0,0\n",
            0.2 * k as f64,
            noise(0.0) + glitch,
            noise(1.1)
        )
    };
    let track = |glitch_at: usize| -> String {
        (0..300)
            .map(|k| row(k, if k == glitch_at { 20.0 } else { 0.0 }))
            .collect()
    };
    let quiet = track(usize::MAX);
    let widest = (1..300)
        .map(|k| {
            let p = |k: usize| 0.45 * (k as f64 * 2.7).sin();
            let q = |k: usize| 0.45 * (k as f64 * 2.7 + 1.1).sin();
            (p(k) - p(k - 1)).hypot(q(k) - q(k - 1))
        })
        .fold(0.0, f64::max);
    assert!(
        widest > 1.05,
        "the scatter alone exceeds the fixed 1 m slack: {widest}"
    );
    Recordings::parse("rec.csv", &format!("{HEADER}\n{quiet}")).expect("a noisy standing car");
    let message = error(&format!("{HEADER}\n{}", track(150)));
    assert_contains(&message, &["track `s`", "jump"]);
}

/// A file that is not UTF-8 text (Latin-1, a binary given by mistake) is named with the line
/// and column where the bad byte sits.
#[test]
fn non_utf8_bytes_name_their_line() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("latin1.csv");
    let mut bytes = format!("{HEADER}\na,0.0,0,0,0,1,0,0\n").into_bytes();
    bytes.extend_from_slice(b"caf\xe9,0.1,0,0,0,1,0,0\n");
    std::fs::write(&path, bytes).expect("write");
    let message = Recordings::load(&path).expect_err("not UTF-8").to_string();
    assert_contains(&message, &["latin1.csv", "line 3", "0xe9", "UTF-8"]);
}

#[test]
fn a_track_recorded_twice_under_two_ids_is_refused() {
    let track = |id: &str, t0: f64| {
        (0..4)
            .map(|k| format!("{id},{},{},0,0,10,0.5,0.01\n", t0 + 0.1 * k as f64, k))
            .collect::<String>()
    };
    let message = error(&format!("{HEADER}\n{}{}", track("a", 0.0), track("b", 7.0)));
    assert_contains(&message, &["track_id b", "same track as track_id a"]);
    // A copy nudged by a micrometre is still a copy.
    let nudged = track("b", 7.0).replace(",0,0,10,", ",0.000001,0,10,");
    let message = error(&format!("{HEADER}\n{}{nudged}", track("a", 0.0)));
    assert_contains(&message, &["track_id b", "same track as track_id a"]);
    // So is a copy moved as a whole (the same motion and commands, a centimetre or a lane
    // over): it carries no information of its own.
    for shift in ["0.01", "3.5"] {
        let moved = track("b", 7.0).replace(",0,0,10,", &format!(",{shift},0,10,"));
        let message = error(&format!("{HEADER}\n{}{moved}", track("a", 0.0)));
        assert_contains(
            &message,
            &["track_id b", "same track as track_id a", "moved"],
        );
    }
    // Another speed on the same path is another track.
    let other = track("c", 0.0).replace(",0,10,", ",0,10.5,");
    Recordings::parse("rec.csv", &format!("{HEADER}\n{}{other}", track("a", 0.0)))
        .expect("two tracks");
}

/// A braking track of 60 samples (10 s at 6 Hz): 20 m/s, braking at 3 m/s^2 from `brake_s`
/// for 2 s. `jitter` scales a fixed pseudo-random pattern added to positions (m), speeds
/// (m/s) and headings (rad / 10).
fn braking_track(id: &str, t0: f64, brake_s: f64, y: f64, jitter: f64) -> String {
    let dt = 1.0 / 6.0;
    let (mut x, mut v) = (0.0, 20.0);
    let mut out = String::new();
    for k in 0..60 {
        let t = k as f64 * dt;
        let accel = if (brake_s..brake_s + 2.0).contains(&t) {
            -3.0
        } else {
            0.0
        };
        // A pattern without a trend: sines at incommensurate rates.
        let noise = |phase: f64| jitter * (k as f64 * 2.7 + phase).sin();
        out.push_str(&format!(
            "{id},{:.4},{:.4},{:.4},{:.5},{:.4},{accel},0\n",
            t0 + t,
            x + noise(0.0),
            y + noise(1.3),
            noise(2.1) / 10.0,
            v + noise(0.7),
        ));
        x += v * dt;
        v += accel * dt;
    }
    out
}

#[test]
fn a_track_copied_with_noise_added_is_refused_and_two_drives_are_not() {
    let original = braking_track("a", 0.0, 3.0, 0.0, 0.0);
    // The copy with 5 cm of noise on positions and speeds, elsewhere and at another time.
    let copy = braking_track("b", 40.0, 3.0, 3.5, 0.05);
    let message = error(&format!("{HEADER}\n{original}{copy}"));
    assert_contains(
        &message,
        &["track_id b", "same track as track_id a", "noise added"],
    );
    // The same braking a second later is another drive, noise or not.
    let later = braking_track("c", 40.0, 4.0, 3.5, 0.05);
    Recordings::parse("rec.csv", &format!("{HEADER}\n{original}{later}")).expect("two drives");
    // Two vehicles cruising side by side (no manoeuvre), each with its own noise, are two.
    let cruise = |id: &str, y: f64, jitter: f64| braking_track(id, 0.0, 99.0, y, jitter);
    let pair = format!(
        "{HEADER}\n{}{}",
        cruise("d", 0.0, 0.03),
        cruise("e", 3.5, -0.03)
    );
    Recordings::parse("rec.csv", &pair).expect("two cruising vehicles");
}
