//! CommonRoad scenarios (`.xml`, `.xml.gz`; formats 2020a and 2018b) as rtr recordings:
//! the lanelet network becomes a [`Map`] and its lane graph, the dynamic vehicles' recorded
//! trajectories become [`Track`]s, and the clip is cut into scenes by the same windowing rules
//! as the A9 recording ([`build_all_scenes`]). The CommonRoad tools convert highD, inD, exiD,
//! rounD, INTERACTION and NGSIM into this format.

mod clip_set;
mod parse;

use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::Arc;

pub use clip_set::{check_clip_names, repeated_clips};
pub use parse::{CommonRoadDocument, FORMAT_VERSIONS, Obstacle, ObstacleState, parse_commonroad};

use super::a9::LANE_NODE_LENGTH;
use super::automatum::Recording;
use super::closing_events::{ClosingEvents, closing_events};
use super::track::{AgentState, MAX_SPEED, Track, TrackSample, VehicleClass};
use super::windows::{SceneConfig, build_all_scenes};
use crate::error::{Error, Result};
use crate::geometry::wrap_angle;
use crate::map::{DEFAULT_SPEED_LIMIT, LaneGraph, Map};
use crate::scene::Scene;

/// One CommonRoad file, read.
#[derive(Debug, Clone)]
pub struct CommonRoadClip {
    pub path: PathBuf,
    pub benchmark_id: String,
    pub version: String,
    pub map: Arc<Map>,
    pub lane_graph: Arc<LaneGraph>,
    /// The vehicles' tracks at the file's own rate, time 0 at the file's first state. `fps`
    /// is 1 / timeStepSize and `frame_count` the steps from the first state to the last, so
    /// `duration()` is the time of the last state.
    pub recording: Recording,
    /// Dynamic obstacles left out: (type or reason, count).
    pub skipped: Vec<(String, usize)>,
    /// Lanes that got the default speed limit (the file gives none), and that limit (m/s).
    pub lanes_without_speed_limit: usize,
    pub default_speed_limit: f64,
}

impl CommonRoadClip {
    /// Reads `path` (`.xml`, or gzip-compressed `.xml.gz`). Lanelets without a speed limit
    /// take `default_speed_limit` (m/s).
    pub fn load(path: &Path, default_speed_limit: f64) -> Result<Self> {
        let text = read_text(path)?;
        let source = path.display().to_string();
        let doc = parse_commonroad(&text, &source)?;
        let lanes_without_speed_limit = doc
            .lanelets
            .iter()
            .filter(|l| l.speed_limit.is_none())
            .count();
        let map = Arc::new(Map::from_lanelets(
            &doc.lanelets,
            default_speed_limit,
            &source,
        )?);
        let lane_graph = Arc::new(LaneGraph::build(&map, LANE_NODE_LENGTH));
        let recording = recording(&doc, path);
        Ok(Self {
            path: path.to_path_buf(),
            benchmark_id: doc.benchmark_id,
            version: doc.version,
            map,
            lane_graph,
            recording,
            skipped: doc.skipped,
            lanes_without_speed_limit,
            default_speed_limit,
        })
    }

    /// Whether the benchmark is a CommonRoad planning task with one trajectory-prediction
    /// problem (id ending `T-1`): the converters removed the vehicle the planning problem
    /// stands for, so the clip is read without it.
    pub fn planning_vehicle_removed(&self) -> bool {
        self.benchmark_id.ends_with("_T-1")
    }

    /// Every window of the clip (no train/test split: clips last seconds).
    pub fn scenes(&self, config: &SceneConfig) -> Result<Vec<Scene>> {
        build_all_scenes(
            &self.recording,
            &self.benchmark_id_or_file(),
            self.map.clone(),
            self.lane_graph.clone(),
            config,
        )
    }

    /// Why the clip yields no scene under `config`, or `None` when it yields some.
    pub fn why_no_scene(&self, config: &SceneConfig) -> Result<Option<String>> {
        Ok(self
            .scenes(config)?
            .is_empty()
            .then(|| self.no_scene_reason(config)))
    }

    /// Why a clip that yields no scene under `config` yields none.
    fn no_scene_reason(&self, config: &SceneConfig) -> String {
        let window = config.history_s + config.future_s;
        let longest = self
            .recording
            .tracks
            .iter()
            .map(|t| t.last_time() - t.first_time())
            .fold(0.0f64, f64::max);
        if self.recording.tracks.is_empty() {
            "no vehicle has a recorded trajectory".to_string()
        } else if self.recording.duration() + 1e-9 < window {
            format!(
                "the clip lasts {:.1} s, shorter than one window ({window} s of history + future)",
                self.recording.duration()
            )
        } else {
            format!(
                "no window has a vehicle with {:.1} s of history at its current step (longest \
                 track {longest:.1} s)",
                config.dt
            )
        }
    }

    fn benchmark_id_or_file(&self) -> String {
        if self.benchmark_id.is_empty() {
            file_stem(&self.path)
        } else {
            self.benchmark_id.clone()
        }
    }
}

/// The CommonRoad files a path names: itself, or the `.xml` / `.xml.gz` files of a folder
/// and its sub-folders (by name).
pub fn commonroad_files(path: &Path) -> Result<Vec<PathBuf>> {
    if !path.is_dir() {
        if !path.exists() {
            return Err(Error::io(
                path,
                std::io::Error::new(std::io::ErrorKind::NotFound, "no such file or folder"),
            ));
        }
        return Ok(vec![path.to_path_buf()]);
    }
    // The whole tree: a clip in a sub-folder skipped would leave the user believing it read.
    let files: Vec<PathBuf> = crate::io::files_in_tree(path)?
        .into_iter()
        .filter(|p| {
            // Any case: `clip.XML` skipped would leave the user believing it was read.
            let name = p
                .file_name()
                .map(|n| n.to_string_lossy().to_lowercase())
                .unwrap_or_default();
            name.ends_with(".xml") || name.ends_with(".xml.gz")
        })
        .collect();
    // A clip-named entry that is not a readable file is refused, not skipped: the folder is
    // read as a set.
    for file in &files {
        if let Some(why) = crate::io::not_regular(file) {
            return Err(Error::invalid(file.display().to_string(), "file", why));
        }
    }
    if files.is_empty() {
        return Err(Error::invalid(
            path.display().to_string(),
            "folder",
            "holds no CommonRoad file (*.xml or *.xml.gz)",
        ));
    }
    Ok(files)
}

/// Reads every file the paths name (see [`commonroad_files`]). Lanes take
/// `default_speed_limit` (m/s; `None`: [`DEFAULT_SPEED_LIMIT`]) where a file gives none.
pub fn load_commonroad(
    paths: &[PathBuf],
    default_speed_limit: Option<f64>,
) -> Result<Vec<CommonRoadClip>> {
    let limit = default_speed_limit.unwrap_or(DEFAULT_SPEED_LIMIT);
    if !(limit > 0.0 && limit <= MAX_SPEED) {
        return Err(Error::InvalidArgument(format!(
            "--commonroad-speed-limit {limit} m/s: expected a default speed limit for the \
             CommonRoad lanes in (0, {MAX_SPEED}] m/s"
        )));
    }
    let mut clips = Vec::new();
    for path in paths {
        for file in commonroad_files(path)? {
            clips.push(CommonRoadClip::load(&file, limit)?);
        }
    }
    Ok(clips)
}

/// Where a set of clips' scenes came from, clip by clip.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ClipSummary {
    pub file: String,
    pub benchmark_id: String,
    pub version: String,
    pub lanelets: usize,
    pub lane_graph_nodes: usize,
    pub vehicles: usize,
    pub duration_s: f64,
    pub scenes: usize,
    /// Why the clip gave no scene.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub no_scene_because: Option<String>,
    /// The clip that already holds every vehicle of this one ([`repeated_clips`]): this one
    /// gives no scene.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub repeats: Option<String>,
    /// Dynamic obstacles left out, by type or reason.
    pub skipped: Vec<(String, usize)>,
    pub planning_vehicle_removed: bool,
    pub lanes_without_speed_limit: usize,
    /// m/s, given to those lanes.
    pub default_speed_limit: f64,
    /// Where a driver closes on the car ahead in its lane and what it does next
    /// ([`crate::data::closing_events`]). The files carry no lane label, so a lane change
    /// counts as braking or neither here.
    pub closing: ClosingEvents,
}

/// The scenes of every clip, in order, and a summary per clip.
pub fn commonroad_scenes(
    clips: &[CommonRoadClip],
    config: &SceneConfig,
) -> Result<(Vec<Scene>, Vec<ClipSummary>)> {
    let mut scenes = Vec::new();
    let mut summaries: Vec<ClipSummary> = Vec::new();
    check_clip_names(clips)?;
    let repeats = repeated_clips(clips);
    for (clip, repeat_of) in clips.iter().zip(repeats) {
        let repeats = repeat_of.map(|a| clips[a].path.display().to_string());
        let clip_scenes = match repeats {
            Some(_) => Vec::new(),
            None => clip.scenes(config)?,
        };
        let no_scene_because = match &repeats {
            Some(file) => Some(format!(
                "every vehicle of it is recorded in {file} too: read once, from there"
            )),
            None => clip_scenes.is_empty().then(|| clip.no_scene_reason(config)),
        };
        summaries.push(ClipSummary {
            file: clip.path.display().to_string(),
            benchmark_id: clip.benchmark_id.clone(),
            version: clip.version.clone(),
            lanelets: clip.map.lanes().len(),
            lane_graph_nodes: clip.lane_graph.nodes.len(),
            vehicles: clip.recording.tracks.len(),
            duration_s: clip.recording.duration(),
            scenes: clip_scenes.len(),
            no_scene_because,
            repeats,
            skipped: clip.skipped.clone(),
            planning_vehicle_removed: clip.planning_vehicle_removed(),
            lanes_without_speed_limit: clip.lanes_without_speed_limit,
            default_speed_limit: clip.default_speed_limit,
            closing: closing_events(&clip.recording),
        });
        scenes.extend(clip_scenes);
    }
    Ok((scenes, summaries))
}

/// One line per clip, for people.
pub fn describe_clips(summaries: &[ClipSummary]) -> String {
    let mut text = String::new();
    for s in summaries {
        text.push_str(&format!(
            "{} ({}, {}): {} vehicles, {:.1} s, {} lanelets -> {} scenes",
            s.benchmark_id, s.file, s.version, s.vehicles, s.duration_s, s.lanelets, s.scenes
        ));
        if let Some(why) = &s.no_scene_because {
            text.push_str(&format!(" ({why})"));
        }
        for (what, n) in &s.skipped {
            text.push_str(&format!("; skipped {n} {what}"));
        }
        if s.lanes_without_speed_limit > 0 {
            text.push_str(&format!(
                "; {} lanes without a speed limit take {:.1} m/s",
                s.lanes_without_speed_limit, s.default_speed_limit
            ));
        }
        if s.planning_vehicle_removed {
            text.push_str("; read without the planning problem's vehicle (T-1)");
        }
        text.push_str(&format!(
            "; {} closing on the car ahead, {} of them braking",
            s.closing.events, s.closing.braked
        ));
        text.push('\n');
    }
    let scenes: usize = summaries.iter().map(|s| s.scenes).sum();
    let vehicles: usize = summaries
        .iter()
        .filter(|s| s.repeats.is_none())
        .map(|s| s.vehicles)
        .sum();
    text.push_str(&format!(
        "commonroad: {} files, {vehicles} vehicles, {scenes} scenes\n",
        summaries.len()
    ));
    text
}

fn read_text(path: &Path) -> Result<String> {
    use crate::io::Format;
    let bytes = crate::io::read_bytes(path, Format::CommonRoad)?;
    let source = path.display().to_string();
    let bytes = if bytes.starts_with(&[0x1f, 0x8b]) {
        let mut out = Vec::new();
        crate::io::capped(
            flate2::read::GzDecoder::new(bytes.as_slice()),
            Format::CommonRoad,
        )
        .read_to_end(&mut out)
        .map_err(|e| match e.kind() {
            std::io::ErrorKind::FileTooLarge => crate::io::read_error(path, e),
            _ => Error::invalid(&source, "gzip stream", e.to_string()),
        })?;
        out
    } else {
        bytes
    };
    crate::io::utf8_text(bytes, &source)
}

/// The vehicles' tracks: time = (step - first step of the file) x timeStepSize, so the clip
/// starts at 0 as the windows expect; acceleration from the file, else the central difference
/// of the recorded speed.
fn recording(doc: &CommonRoadDocument, path: &Path) -> Recording {
    let dt = doc.time_step;
    let first_step = doc
        .vehicles
        .iter()
        .filter_map(|o| o.states.first().map(|s| s.step))
        .min()
        .unwrap_or(0);
    let tracks: Vec<Track> = doc
        .vehicles
        .iter()
        .enumerate()
        .map(|(id, o)| Track {
            id,
            uuid: o.id.clone(),
            class: VehicleClass::from_label(&o.kind),
            length: o.length,
            width: o.width,
            samples: samples(&o.states, first_step, dt),
        })
        .collect();
    let last_step = doc
        .vehicles
        .iter()
        .filter_map(|o| o.states.last().map(|s| s.step))
        .max()
        .unwrap_or(0);
    Recording {
        source: path.to_path_buf(),
        fps: 1.0 / dt,
        frame_count: (last_step - first_step) as usize,
        utm_reference: String::new(),
        tracks,
    }
}

fn samples(states: &[ObstacleState], first_step: i64, dt: f64) -> Vec<TrackSample> {
    let n = states.len();
    (0..n)
        .map(|k| {
            let s = states[k];
            let accel = s.acceleration.unwrap_or_else(|| {
                let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
                if b > a {
                    (states[b].velocity - states[a].velocity) / ((b - a) as f64 * dt)
                } else {
                    0.0
                }
            });
            TrackSample {
                t: (s.step - first_step) as f64 * dt,
                state: AgentState {
                    x: s.x,
                    y: s.y,
                    heading: wrap_angle(s.orientation),
                    speed: s.velocity,
                    accel,
                },
                lateral_speed: 0.0,
                lateral_accel: 0.0,
                lane_id: 0,
            }
        })
        .collect()
}

fn file_stem(path: &Path) -> String {
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("clip");
    name.trim_end_matches(".gz")
        .trim_end_matches(".xml")
        .to_string()
}
