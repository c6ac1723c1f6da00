//! Clips read together are checked as a set: every scene id must be unique, and a clip that
//! repeats another's driving under another name (a renamed copy, a copy cut shorter in time
//! or moved or turned as a whole, another planning problem over the same traffic) is found, so that its vehicles are read
//! once: twice, a training set would weigh them double and an evaluation count them twice.

use std::collections::{BTreeSet, HashMap};
use std::path::Path;

use super::CommonRoadClip;
use crate::data::track::{Track, TrackSample};
use crate::error::{Error, Result};
use crate::geometry::wrap_angle;
use crate::vehicle::AgentState;

/// How closely a run of samples must repeat another to be the same recorded driving: speeds
/// and headings within a millimetre per second and a tenth of a milliradian, positions apart
/// by one constant offset to within a millimetre (a copy moved as a whole is still a copy).
/// Two vehicles that are really two share neither their speeds nor their positions' noise.
const SAME_SPEED: f64 = 1e-3;
const SAME_HEADING_RAD: f64 = 1e-4;
const SAME_OFFSET_M: f64 = 1e-3;
/// A rotated copy's positions are new numbers, rounded where they were written: its distances
/// from its first sample must agree within a centimetre.
const SAME_DISTANCE_M: f64 = 1e-2;
/// A track that travels less than this (m) is a standing vehicle: any offset would match it,
/// so it must repeat the other's positions themselves.
const STANDING_M: f64 = 1.0;

/// Refuses two clips that would give scenes the same id.
pub fn check_clip_names(clips: &[CommonRoadClip]) -> Result<()> {
    let mut names: Vec<(String, &Path)> = Vec::new();
    for clip in clips {
        let name = clip.benchmark_id_or_file();
        if let Some((_, other)) = names.iter().find(|(n, _)| *n == name) {
            if same_file(other, &clip.path) {
                return Err(Error::invalid(
                    clip.path.display().to_string(),
                    "file",
                    "is given twice (as a file or within a folder); expected each clip once",
                ));
            }
            return Err(Error::invalid(
                clip.path.display().to_string(),
                "benchmarkID",
                format!(
                    "`{name}` also names {}: scene ids would clash (pass each clip once)",
                    other.display()
                ),
            ));
        }
        names.push((name, &clip.path));
    }
    Ok(())
}

fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => a == b,
    }
}

/// A track of one clip, by (clip, track) index.
type TrackRef = (usize, usize);

/// For each clip, the clip that already holds all of its driving, if one does: every vehicle
/// of it recorded (the same motion, whatever the ids, times and a constant shift) within that
/// clip. CommonRoad
/// ships such repeats on purpose (`_1` and `_2` of a benchmark are two planning problems over
/// the same traffic), so a repeat is read once rather than refused. Of two identical clips the
/// later repeats the earlier; a clip cut shorter repeats the longer one.
pub fn repeated_clips(clips: &[CommonRoadClip]) -> Vec<Option<usize>> {
    let holders = clips_holding_each_track(clips);
    let held_in: Vec<BTreeSet<usize>> = clips
        .iter()
        .enumerate()
        .map(|(b, clip)| clips_holding_every_track(b, clip, &holders))
        .collect();
    (0..clips.len())
        .map(|b| {
            held_in[b]
                .iter()
                .copied()
                .find(|&a| a < b || !held_in[a].contains(&b))
        })
        .collect()
}

/// The other clips that hold every track (with two samples or more) of clip `b`; none when it
/// has no such track.
fn clips_holding_every_track(
    b: usize,
    clip: &CommonRoadClip,
    holders: &HashMap<TrackRef, BTreeSet<usize>>,
) -> BTreeSet<usize> {
    let mut common: Option<BTreeSet<usize>> = None;
    for (t, track) in clip.recording.tracks.iter().enumerate() {
        if track.samples.len() < 2 {
            continue;
        }
        let holding = holders.get(&(b, t)).cloned().unwrap_or_default();
        common = Some(match common {
            None => holding,
            Some(so_far) => so_far.intersection(&holding).copied().collect(),
        });
    }
    common.unwrap_or_default()
}

/// For each track (with two samples or more), the other clips that hold its samples as a
/// contiguous run of one of their tracks.
fn clips_holding_each_track(clips: &[CommonRoadClip]) -> HashMap<TrackRef, BTreeSet<usize>> {
    // Every track's first sample, sorted by speed: each sample of every track is then looked
    // up among the few first samples of about its speed, and only those runs compared.
    let mut starts: Vec<(f64, TrackRef)> = Vec::new();
    for (c, clip) in clips.iter().enumerate() {
        for (t, track) in clip.recording.tracks.iter().enumerate() {
            if track.samples.len() >= 2 {
                starts.push((track.samples[0].state.speed, (c, t)));
            }
        }
    }
    starts.sort_by(|p, q| p.0.total_cmp(&q.0));
    let mut holders: HashMap<TrackRef, BTreeSet<usize>> = Default::default();
    for (c, clip) in clips.iter().enumerate() {
        for track in &clip.recording.tracks {
            for k in 0..track.samples.len() {
                let speed = track.samples[k].state.speed;
                let first = starts.partition_point(|s| s.0 < speed - SAME_SPEED);
                for &(start_speed, (bc, bt)) in &starts[first..] {
                    if start_speed > speed + SAME_SPEED {
                        break;
                    }
                    if bc == c {
                        continue;
                    }
                    let run = &clips[bc].recording.tracks[bt];
                    if holds_run(track, k, run) {
                        holders.entry((bc, bt)).or_default().insert(c);
                    }
                }
            }
        }
    }
    holders
}

/// Whether `run`'s samples are `track`'s samples from index `from` on: the same speeds and
/// headings, and positions one constant offset apart (none for a standing vehicle).
fn holds_run(track: &Track, from: usize, run: &Track) -> bool {
    if track.samples.len() - from < run.samples.len() {
        return false;
    }
    let pairs = || track.samples[from..].iter().zip(&run.samples);
    let (p0, q0) = (&track.samples[from].state, &run.samples[0].state);
    // Speeds and turns alike: headings apart by one constant angle (a copy rotated as a
    // whole turns as its original did).
    let same_motion = pairs().all(|(p, q)| {
        let turned =
            wrap_angle(p.state.heading - p0.heading) - wrap_angle(q.state.heading - q0.heading);
        (p.state.speed - q.state.speed).abs() <= SAME_SPEED
            && wrap_angle(turned).abs() <= 2.0 * SAME_HEADING_RAD
    });
    if !same_motion {
        return false;
    }
    let offset = |p: &TrackSample, q: &TrackSample| [p.state.x - q.state.x, p.state.y - q.state.y];
    let first = offset(&track.samples[from], &run.samples[0]);
    let constant = pairs().all(|(p, q)| {
        let d = offset(p, q);
        (d[0] - first[0]).abs() <= SAME_OFFSET_M && (d[1] - first[1]).abs() <= SAME_OFFSET_M
    });
    let rotated = || {
        let from_start =
            |s: &TrackSample, s0: &AgentState| (s.state.x - s0.x).hypot(s.state.y - s0.y);
        pairs().all(|(p, q)| (from_start(p, p0) - from_start(q, q0)).abs() <= SAME_DISTANCE_M)
    };
    if !travels(run) {
        return constant && first[0].hypot(first[1]) <= SAME_OFFSET_M;
    }
    constant || rotated()
}

/// Whether a track moves further than [`STANDING_M`] from its first position.
fn travels(track: &Track) -> bool {
    let start = &track.samples[0].state;
    track
        .samples
        .iter()
        .any(|s| (s.state.x - start.x).hypot(s.state.y - start.y) > STANDING_M)
}
