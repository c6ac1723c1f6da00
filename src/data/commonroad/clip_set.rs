//! Clips read together are checked as a set: every scene id must be unique, and a clip that
//! repeats another's driving under another name (a renamed copy, a copy cut shorter in time,
//! another planning problem over the same traffic) is found, so that its vehicles are read
//! once: twice, a training set would weigh them double and an evaluation count them twice.

use std::collections::{BTreeSet, HashMap};
use std::path::Path;

use super::CommonRoadClip;
use crate::data::track::{Track, TrackSample};
use crate::error::{Error, Result};
use crate::geometry::wrap_angle;

/// How close two samples must be, per channel, to count as the same recorded state: a
/// millimetre, a tenth of a milliradian, a millimetre per second. No two vehicles drive that
/// close to each other for a whole track.
const SAME_POSITION_M: f64 = 1e-3;
const SAME_HEADING_RAD: f64 = 1e-4;
const SAME_SPEED: f64 = 1e-3;

/// Refuses two clips that would give scenes the same id.
pub fn check_clip_names(clips: &[CommonRoadClip]) -> Result<()> {
    let mut names: Vec<(String, &Path)> = Vec::new();
    for clip in clips {
        let name = clip.benchmark_id_or_file();
        if let Some((_, other)) = names.iter().find(|(n, _)| *n == name) {
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

/// A track of one clip, by (clip, track) index.
type TrackRef = (usize, usize);

/// For each clip, the clip that already holds all of its driving, if one does: every vehicle
/// of it recorded (the same states, whatever the ids and times) within that clip. CommonRoad
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
    // Every track's first sample, sorted by x: each sample of every track is then looked up
    // by x among the few first samples within a millimetre, and only those runs compared.
    let mut starts: Vec<(f64, TrackRef)> = Vec::new();
    for (c, clip) in clips.iter().enumerate() {
        for (t, track) in clip.recording.tracks.iter().enumerate() {
            if track.samples.len() >= 2 {
                starts.push((track.samples[0].state.x, (c, t)));
            }
        }
    }
    starts.sort_by(|p, q| p.0.total_cmp(&q.0));
    let mut holders: HashMap<TrackRef, BTreeSet<usize>> = Default::default();
    for (c, clip) in clips.iter().enumerate() {
        for track in &clip.recording.tracks {
            for k in 0..track.samples.len() {
                let x = track.samples[k].state.x;
                let first = starts.partition_point(|s| s.0 < x - SAME_POSITION_M);
                for &(start_x, (bc, bt)) in &starts[first..] {
                    if start_x > x + SAME_POSITION_M {
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

/// Whether `run`'s samples are `track`'s samples from index `from` on, state by state.
fn holds_run(track: &Track, from: usize, run: &Track) -> bool {
    track.samples.len() - from >= run.samples.len()
        && track.samples[from..]
            .iter()
            .zip(&run.samples)
            .all(|(p, q)| same_state(p, q))
}

fn same_state(p: &TrackSample, q: &TrackSample) -> bool {
    let (p, q) = (&p.state, &q.state);
    (p.x - q.x).abs() <= SAME_POSITION_M
        && (p.y - q.y).abs() <= SAME_POSITION_M
        && wrap_angle(p.heading - q.heading).abs() <= SAME_HEADING_RAD
        && (p.speed - q.speed).abs() <= SAME_SPEED
}
