//! Bad input gets a clear error that names the file, the place and what was expected; never a
//! panic.

use std::io::Write;
use std::path::Path;

use rtr::Error;
use rtr::data::{A9_DYNAMIC_SHA256, A9Dataset, a9, load_recording};
use rtr::map::Map;

fn gzip(text: &str) -> Vec<u8> {
    let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    enc.write_all(text.as_bytes()).expect("compress");
    enc.finish().expect("finish")
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> std::path::PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).expect("write fixture");
    path
}

/// A minimal recording in the AUTOMATUM layout, with `x` spliced into the x_vec.
fn recording_json(x: &str) -> String {
    format!(
        r#"{{
  "videoInfo": {{"fps": 29.97, "frame_count": 3}},
  "objects": [
    {{
      "UUID": "a", "objType": "car", "length": 4.5, "width": 1.8,
      "time": [0.0, 0.0333, 0.0667],
      "x_vec": [0.0, {x}, 2.0],
      "y_vec": [0.0, 0.0, 0.0],
      "psi_vec": [0.0, 0.0, 0.0],
      "vx_vec": [30.0, 30.0, 30.0],
      "vy_vec": [0.0, 0.0, 0.0],
      "ax_vec": [0.0, 0.0, 0.0],
      "ay_vec": [0.0, 0.0, 0.0],
      "lane_id_vec": [-2, -2, -2]
    }}
  ]
}}"#
    )
}

#[test]
fn a_well_formed_minimal_recording_loads() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = write(dir.path(), "ok.json.gz", &gzip(&recording_json("1.0")));
    let rec = load_recording(&path, None).expect("loads");
    assert_eq!(rec.tracks.len(), 1);
    assert_eq!(rec.tracks[0].samples.len(), 3);
}

#[test]
fn truncated_gzip_is_reported_as_such() {
    let dir = tempfile::tempdir().expect("temp dir");
    let real = std::fs::read(a9::default_dir().join(a9::DYNAMIC_FILE)).expect("shipped file");
    let path = write(dir.path(), "cut.json.gz", &real[..200_000]);
    let err = load_recording(&path, None).expect_err("truncated file must fail");
    let text = err.to_string();
    assert!(matches!(err, Error::InvalidData { .. }), "{text}");
    assert!(
        text.contains("cut.json.gz") && text.contains("gzip"),
        "{text}"
    );
}

#[test]
fn not_gzip_at_all_is_reported() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = write(
        dir.path(),
        "plain.json.gz",
        recording_json("1.0").as_bytes(),
    );
    let err = load_recording(&path, None).expect_err("plain text is not gzip");
    assert!(err.to_string().contains("gzip"), "{err}");
}

#[test]
fn malformed_json_names_line_and_column() {
    let dir = tempfile::tempdir().expect("temp dir");
    let broken = recording_json("1.0").replace("\"y_vec\"", "\"y_vec\" [");
    let path = write(dir.path(), "broken.json.gz", &gzip(&broken));
    match load_recording(&path, None) {
        Err(Error::Parse {
            source_name, line, ..
        }) => {
            assert!(source_name.ends_with("broken.json.gz"));
            assert_eq!(line, 8);
        }
        other => panic!("expected a parse error, got {other:?}"),
    }
}

#[test]
fn nan_coordinate_is_rejected_with_its_line() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = write(dir.path(), "nan.json.gz", &gzip(&recording_json("NaN")));
    let err = load_recording(&path, None).expect_err("NaN is not JSON");
    let text = err.to_string();
    assert!(matches!(err, Error::Parse { line: 7, .. }), "{text}");
    assert!(text.contains("NaN"), "the message explains: {text}");
    let path = write(dir.path(), "null.json.gz", &gzip(&recording_json("null")));
    let err = load_recording(&path, None).expect_err("null is not a coordinate");
    assert!(matches!(err, Error::Parse { line: 7, .. }), "{err}");
}

#[test]
fn columns_of_different_lengths_name_the_field() {
    let dir = tempfile::tempdir().expect("temp dir");
    let text = recording_json("1.0").replace("\"y_vec\": [0.0, 0.0, 0.0]", "\"y_vec\": [0.0, 0.0]");
    let path = write(dir.path(), "short.json.gz", &gzip(&text));
    let err = load_recording(&path, None).expect_err("ragged columns");
    assert!(err.to_string().contains("y_vec"), "{err}");
}

#[test]
fn wrong_checksum_is_refused() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = write(dir.path(), "copy.json.gz", &gzip(&recording_json("1.0")));
    let err = load_recording(&path, Some(A9_DYNAMIC_SHA256)).expect_err("not the A9 file");
    assert!(matches!(err, Error::Checksum { .. }), "{err}");
    assert!(err.to_string().contains(A9_DYNAMIC_SHA256));

    // A modified map next to the real recording: the dataset refuses to load.
    let xodr = std::fs::read_to_string(a9::default_dir().join(a9::STATIC_FILE)).expect("map");
    write(
        dir.path(),
        a9::STATIC_FILE,
        xodr.replace("a=\"3.9\"", "a=\"3.8\"").as_bytes(),
    );
    let err = A9Dataset::load(dir.path()).expect_err("modified map");
    assert!(matches!(err, Error::Checksum { .. }), "{err}");
}

#[test]
fn missing_file_names_the_path() {
    let err = load_recording(Path::new("no/such/recording.json.gz"), None).expect_err("missing");
    assert!(matches!(err, Error::Io { .. }));
    assert!(
        err.to_string().contains("no/such/recording.json.gz"),
        "{err}"
    );
}

#[test]
fn unknown_opendrive_geometry_names_element_and_line() {
    let xodr = std::fs::read_to_string(a9::default_dir().join(a9::STATIC_FILE)).expect("map");
    let bad = xodr.replace(
        "<arc curvature=\"-0.000322282793482797\" />",
        "<cubic a=\"1\" />",
    );
    assert_ne!(bad, xodr, "fixture edit applied");
    let err = Map::from_xodr_str(&bad, "edited.xodr").expect_err("unsupported geometry");
    let text = err.to_string();
    assert!(text.contains("edited.xodr"), "{text}");
    assert!(text.contains("cubic"), "{text}");
    assert!(matches!(err, Error::Parse { line: 12, .. }), "{text}");
}

#[test]
fn non_numeric_opendrive_attribute_is_reported() {
    let xodr = std::fs::read_to_string(a9::default_dir().join(a9::STATIC_FILE)).expect("map");
    let bad = xodr.replace(
        "length=\"266.281170003393\" id=\"0\"",
        "length=\"long\" id=\"0\"",
    );
    assert_ne!(bad, xodr, "fixture edit applied");
    let err = Map::from_xodr_str(&bad, "edited.xodr").expect_err("bad number");
    let text = err.to_string();
    assert!(text.contains("length") && text.contains("long"), "{text}");
}
