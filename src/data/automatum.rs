//! Loader for AUTOMATUM DATA drone recordings (`dynamicWorld*.json.gz`, format release 3.0).
//!
//! The file is a gzip-compressed JSON object with `videoInfo { fps, frame_count }` and an
//! `objects` array; each object holds per-frame vectors (`time`, `x_vec`, `y_vec`, `psi_vec`,
//! `vx_vec`, `vy_vec`, `ax_vec`, `ay_vec`, `lane_id_vec`) plus `length`, `width`, `objType`.
//! Velocities and accelerations are in the vehicle frame (x forward, y left).
//!
//! The JSON text (146 MB for the A9 recording) is never held in memory: serde_json reads the
//! gzip stream and keeps only the fields rtr uses; the per-frame relation/TTC dictionaries are
//! skipped while parsing.

use std::io::Read;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use sha2::{Digest, Sha256};

use super::track::{AgentState, Track, TrackSample, VehicleClass};
use crate::error::{Error, Result};

/// sha256 of `data/automatum-a9/dynamicWorld.v3_0-4-4.json.gz` as published.
pub const A9_DYNAMIC_SHA256: &str =
    "df00221739215a0c5378f0c5886f2ced98f423040df72601c41a608822334dd4";
/// sha256 of `data/automatum-a9/staticWorld.xodr` as published.
pub const A9_STATIC_SHA256: &str =
    "99105cf6a5df572ebfa18325a3db5646c0b8272f710d0ed99ab34aff9840bf2b";

/// A loaded recording: every vehicle track plus the video's timing.
#[derive(Debug, Clone)]
pub struct Recording {
    pub source: PathBuf,
    /// Frames per second of the drone video (29.97 for the A9 recording).
    pub fps: f64,
    pub frame_count: usize,
    /// UTM reference point of the local frame, verbatim from the file.
    pub utm_reference: String,
    pub tracks: Vec<Track>,
}

impl Recording {
    /// Length of the recording (s).
    pub fn duration(&self) -> f64 {
        self.frame_count as f64 / self.fps
    }
}

#[derive(Deserialize)]
struct RawFile {
    #[serde(rename = "videoInfo")]
    video_info: RawVideoInfo,
    #[serde(rename = "UTM-ReferencePoint", default)]
    utm_reference: String,
    objects: Vec<RawObject>,
}

#[derive(Deserialize)]
struct RawVideoInfo {
    fps: f64,
    frame_count: usize,
}

#[derive(Deserialize)]
struct RawObject {
    #[serde(rename = "UUID")]
    uuid: String,
    #[serde(rename = "objType")]
    obj_type: String,
    length: f64,
    width: f64,
    time: Vec<f64>,
    x_vec: Vec<f64>,
    y_vec: Vec<f64>,
    psi_vec: Vec<f64>,
    vx_vec: Vec<f64>,
    vy_vec: Vec<f64>,
    ax_vec: Vec<f64>,
    ay_vec: Vec<f64>,
    lane_id_vec: Vec<i32>,
}

/// Computes the sha256 of a file as lowercase hex.
pub fn sha256_file(path: &Path) -> Result<String> {
    let bytes = crate::io::read_bytes(path, crate::io::Format::Automatum)?;
    Ok(sha256_hex(&bytes))
}

/// The sha256 of `bytes` as lowercase hex.
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// The first 12 characters of a hex digest, for messages; a digest read from a hand-edited
/// file may be shorter (or not hex), and is then shown whole.
pub fn short_digest(digest: &str) -> &str {
    digest.get(..12).unwrap_or(digest)
}

/// Loads a recording. With `expected_sha256`, the file is first checked against it (the
/// shipped data must be the published bytes); pass `None` for other recordings.
pub fn load_recording(path: &Path, expected_sha256: Option<&str>) -> Result<Recording> {
    let compressed = crate::io::read_bytes(path, crate::io::Format::Automatum)?;
    if let Some(expected) = expected_sha256 {
        let actual = sha256_hex(&compressed);
        if actual != expected {
            return Err(Error::Checksum {
                path: path.to_path_buf(),
                expected: expected.to_string(),
                actual,
            });
        }
    }
    let source = path.display().to_string();
    let mut decoder = GzipErrors {
        inner: crate::io::capped(
            flate2::read::GzDecoder::new(compressed.as_slice()),
            crate::io::Format::Automatum,
        ),
        error: None,
    };
    let parsed = crate::io::parse_json_reader::<RawFile>(
        std::io::BufReader::with_capacity(1 << 20, &mut decoder),
        &source,
    );
    // A gzip failure surfaces inside serde as an I/O error; report the gzip one, which says
    // what is actually wrong with the file.
    if let Some(gzip_error) = decoder.error.take() {
        if gzip_error.kind() == std::io::ErrorKind::FileTooLarge {
            return Err(crate::io::read_error(path, gzip_error));
        }
        return Err(Error::invalid(
            &source,
            "gzip stream",
            format!("{gzip_error} (truncated or not a gzip file?)"),
        ));
    }
    let raw = parsed?;
    // The gzip trailer (CRC, length) follows the JSON: read it so a damaged tail is caught.
    let mut rest = Vec::new();
    if let Err(e) = decoder.inner.read_to_end(&mut rest) {
        return Err(Error::invalid(&source, "gzip stream", e.to_string()));
    }
    convert(raw, path)
}

/// Remembers the first I/O error of the gzip stream, which serde_json would otherwise turn
/// into a generic message.
struct GzipErrors<R> {
    inner: R,
    error: Option<std::io::Error>,
}

impl<R: Read> Read for GzipErrors<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.inner.read(buf).inspect_err(|e| {
            if self.error.is_none() {
                self.error = Some(std::io::Error::new(e.kind(), e.to_string()));
            }
        })
    }
}

fn convert(raw: RawFile, path: &Path) -> Result<Recording> {
    let source = path.display().to_string();
    let fps = raw.video_info.fps;
    if !(fps.is_finite() && fps > 0.0) {
        return Err(Error::invalid(
            &source,
            "videoInfo.fps",
            format!("expected a positive frame rate, found {fps}"),
        ));
    }
    let tracks = raw
        .objects
        .into_iter()
        .enumerate()
        .map(|(id, object)| convert_object(id, object, &source))
        .collect::<Result<Vec<_>>>()?;
    Ok(Recording {
        source: path.to_path_buf(),
        fps,
        frame_count: raw.video_info.frame_count,
        utm_reference: raw.utm_reference,
        tracks,
    })
}

fn convert_object(id: usize, o: RawObject, source: &str) -> Result<Track> {
    let place = |field: &str| format!("objects[{id}] (UUID {}) field `{field}`", o.uuid);
    for (field, value) in [("length", o.length), ("width", o.width)] {
        if !(value.is_finite() && value > 0.0) {
            return Err(Error::invalid(
                source,
                place(field),
                format!("expected a positive size in metres, found {value}"),
            ));
        }
    }
    let n = o.time.len();
    let columns: [(&str, &[f64]); 8] = [
        ("time", &o.time),
        ("x_vec", &o.x_vec),
        ("y_vec", &o.y_vec),
        ("psi_vec", &o.psi_vec),
        ("vx_vec", &o.vx_vec),
        ("vy_vec", &o.vy_vec),
        ("ax_vec", &o.ax_vec),
        ("ay_vec", &o.ay_vec),
    ];
    for (field, column) in columns {
        if column.len() != n {
            return Err(Error::invalid(
                source,
                place(field),
                format!("has {} entries but `time` has {n}", column.len()),
            ));
        }
        if let Some(k) = column.iter().position(|v| !v.is_finite()) {
            return Err(Error::invalid(
                source,
                format!("{}[{k}]", place(field)),
                format!("expected a finite number, found {}", column[k]),
            ));
        }
    }
    if o.lane_id_vec.len() != n {
        return Err(Error::invalid(
            source,
            place("lane_id_vec"),
            format!("has {} entries but `time` has {n}", o.lane_id_vec.len()),
        ));
    }
    if n < 2 {
        return Err(Error::invalid(
            source,
            place("time"),
            format!("expected at least 2 samples, found {n}"),
        ));
    }
    if let Some(k) = o.time.windows(2).position(|w| w[1] <= w[0]) {
        return Err(Error::invalid(
            source,
            format!("{}[{}]", place("time"), k + 1),
            format!(
                "time must increase strictly, but {} follows {}",
                o.time[k + 1],
                o.time[k]
            ),
        ));
    }
    let samples = (0..n)
        .map(|k| TrackSample {
            t: o.time[k],
            state: AgentState {
                x: o.x_vec[k],
                y: o.y_vec[k],
                heading: crate::geometry::wrap_angle(o.psi_vec[k]),
                speed: o.vx_vec[k],
                accel: o.ax_vec[k],
            },
            lateral_speed: o.vy_vec[k],
            lateral_accel: o.ay_vec[k],
            lane_id: o.lane_id_vec[k],
        })
        .collect();
    Ok(Track {
        id,
        uuid: o.uuid,
        class: VehicleClass::from_label(&o.obj_type),
        length: o.length,
        width: o.width,
        samples,
    })
}
