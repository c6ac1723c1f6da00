//! Recordings checked as a set: a track recorded twice under two ids. Split into fitting and
//! held-out tracks, one copy would be scored against the other and the held-out error would
//! be a training error. A copy is recognised whole or in part: moved, rotated or mirrored as a
//! whole, at other times, cut shorter, every k-th sample kept, or with noise added.

use super::recordings::RecordedTrack;
use crate::error::{Error, Result};
use crate::geometry::wrap_angle;

/// How close (per channel) two tracks' samples must all be for the tracks to count as one
/// recorded twice: speeds and commands within a millimetre (per second), headings within a
/// tenth of a milliradian, positions one constant offset apart to within a millimetre (a copy
/// moved as a whole is still a copy). Two runs that are really two differ at least by their
/// noise.
const SAME_OFFSET_M: f64 = 1e-3;
const SAME_ANGLE_RAD: f64 = 1e-4;
const SAME_SPEED: f64 = 1e-3;
/// A rotated or mirrored copy's positions are new numbers, rounded where they were written:
/// its distances from its first sample must agree within a centimetre.
const SAME_DISTANCE_M: f64 = 1e-2;
/// A track that travels less than this (m) stands: it must repeat the other's positions
/// themselves, not up to an offset.
const STANDING_M: f64 = 1.0;
/// A copy with noise added to its samples: RMS differences (after one constant offset of the
/// positions) within these of a track that manoeuvres (brakes or speeds up by
/// [`MANOEUVRE_SPEED`], or turns by [`MANOEUVRE_HEADING_RAD`]) over at least
/// [`NOISY_COPY_SAMPLES`] samples. Two vehicles do not repeat each other's manoeuvres to a few
/// centimetres over a whole track; two cruising at one speed on a straight road could, so a
/// track without a manoeuvre is only compared to the millimetre.
const NOISY_COPY_POSITION_M: f64 = 0.25;
const NOISY_COPY_SPEED: f64 = 0.25;
const NOISY_COPY_HEADING_RAD: f64 = 0.02;
const MANOEUVRE_SPEED: f64 = 2.0;
const MANOEUVRE_HEADING_RAD: f64 = 0.1;
const NOISY_COPY_SAMPLES: usize = 20;
/// A part of a track (cut, thinned, rotated or mirrored) counts as a copy from this many
/// samples on, and only where it manoeuvres: two vehicles cruising at one constant speed
/// repeat each other's samples without being one.
const PARTIAL_COPY_SAMPLES: usize = 10;
/// Largest relative mismatch between a thinned copy's period and k times the original's.
const PERIOD_TOLERANCE: f64 = 0.05;

/// Refuses the first track that repeats another (see the module documentation).
pub(super) fn refuse_repeated_tracks(source: &str, tracks: &[RecordedTrack]) -> Result<()> {
    let Some(repeat) = whole_copy(tracks)
        .or_else(|| partial_copy(tracks))
        .or_else(|| shared_positions(tracks))
    else {
        return Ok(());
    };
    Err(Error::invalid(
        source,
        format!("track_id {}", tracks[repeat.copy].id),
        format!(
            "is the same track as track_id {} ({}, under another id); a repeated track would \
             be held out against its own copy",
            tracks[repeat.original].id, repeat.how
        ),
    ))
}

/// A track found to repeat another, and how it was changed.
struct Repeat {
    copy: usize,
    original: usize,
    how: String,
}

/// Two tracks of one length whose samples agree one by one: the same within a millimetre,
/// moved as a whole, or with noise added. The later one in the file is the copy.
fn whole_copy(tracks: &[RecordedTrack]) -> Option<Repeat> {
    // Candidates share a length and nearly a first speed: sorted so, each track is compared
    // with the few that follow it within the tolerance.
    let mut order: Vec<usize> = (0..tracks.len())
        .filter(|&i| !tracks[i].x.is_empty())
        .collect();
    order.sort_by(|&a, &b| {
        (tracks[a].len(), tracks[a].speed[0])
            .partial_cmp(&(tracks[b].len(), tracks[b].speed[0]))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    for (k, &a) in order.iter().enumerate() {
        for &b in &order[k + 1..] {
            let (ta, tb) = (&tracks[a], &tracks[b]);
            if tb.len() != ta.len() || tb.speed[0] - ta.speed[0] > NOISY_COPY_SPEED * 4.0 {
                break;
            }
            let how = if same_motion(ta, tb) {
                "the same samples within a millimetre, or moved as a whole"
            } else if noisy_copy(ta, tb) {
                "the same manoeuvres within 0.25 m RMS: a copy with noise added"
            } else {
                continue;
            };
            return Some(Repeat {
                copy: a.max(b),
                original: a.min(b),
                how: how.into(),
            });
        }
    }
    None
}

/// Whether every sample of `a` and `b` agrees within the tolerances above.
fn same_motion(a: &RecordedTrack, b: &RecordedTrack) -> bool {
    let close = |x: &[f64], y: &[f64], tolerance: f64| {
        x.iter().zip(y).all(|(p, q)| (p - q).abs() <= tolerance)
    };
    let same_channels = close(&a.heading, &b.heading, SAME_ANGLE_RAD)
        && close(&a.speed, &b.speed, SAME_SPEED)
        && close(&a.accel_cmd, &b.accel_cmd, SAME_SPEED)
        && close(&a.steer_cmd, &b.steer_cmd, SAME_ANGLE_RAD);
    if !same_channels {
        return false;
    }
    let offset = (a.x[0] - b.x[0], a.y[0] - b.y[0]);
    let constant = (0..a.len()).all(|k| {
        (a.x[k] - b.x[k] - offset.0).abs() <= SAME_OFFSET_M
            && (a.y[k] - b.y[k] - offset.1).abs() <= SAME_OFFSET_M
    });
    constant && (travels(a) || offset.0.hypot(offset.1) <= SAME_OFFSET_M)
}

/// Whether `b` is `a` with noise added ([`NOISY_COPY_POSITION_M`] and the constants beside
/// it): the same manoeuvres, sample for sample, within a few centimetres RMS. The first
/// sample's speed sorts the candidates, so a copy's may differ by a few noise widths.
fn noisy_copy(a: &RecordedTrack, b: &RecordedTrack) -> bool {
    let n = a.len();
    if n < NOISY_COPY_SAMPLES || b.len() != n {
        return false;
    }
    let rms =
        |d: &dyn Fn(usize) -> f64| ((0..n).map(|k| d(k).powi(2)).sum::<f64>() / n as f64).sqrt();
    let mean = |d: &dyn Fn(usize) -> f64| (0..n).map(d).sum::<f64>() / n as f64;
    let offset = (mean(&|k| a.x[k] - b.x[k]), mean(&|k| a.y[k] - b.y[k]));
    let position = rms(&|k| (a.x[k] - b.x[k] - offset.0).hypot(a.y[k] - b.y[k] - offset.1));
    let speed = rms(&|k| a.speed[k] - b.speed[k]);
    let heading = rms(&|k| wrap_angle(a.heading[k] - b.heading[k]));
    if position > NOISY_COPY_POSITION_M
        || speed > NOISY_COPY_SPEED
        || heading > NOISY_COPY_HEADING_RAD
    {
        return false;
    }
    if !travels(a) {
        // Two standing vehicles are one only where they stand in one place.
        return offset.0.hypot(offset.1) <= NOISY_COPY_POSITION_M;
    }
    manoeuvres(a)
}

fn travels(track: &RecordedTrack) -> bool {
    (0..track.len()).any(|k| distance(track, 0, k) > STANDING_M)
}

fn manoeuvres(track: &RecordedTrack) -> bool {
    let range = |v: &[f64]| {
        let (lo, hi) = v
            .iter()
            .fold((f64::MAX, f64::MIN), |(lo, hi), &x| (lo.min(x), hi.max(x)));
        hi - lo
    };
    range(&track.speed) >= MANOEUVRE_SPEED || range(&track.heading) >= MANOEUVRE_HEADING_RAD
}

fn distance(track: &RecordedTrack, from: usize, to: usize) -> f64 {
    (track.x[to] - track.x[from]).hypot(track.y[to] - track.y[from])
}

/// A track whose samples are samples of another, exactly: every `k`-th from some sample on
/// (a cut, a thinned or a whole copy), moved, rotated or mirrored as a whole, at any times.
/// The other is found through the speeds: one sample of the copy, the one whose speed is
/// rarest in the file, must be one of the original's.
fn partial_copy(tracks: &[RecordedTrack]) -> Option<Repeat> {
    let mut speeds: Vec<(f64, usize, usize)> = tracks
        .iter()
        .enumerate()
        .flat_map(|(t, track)| track.speed.iter().enumerate().map(move |(i, &v)| (v, t, i)))
        .collect();
    speeds.sort_by(|a, b| a.0.total_cmp(&b.0));
    let near = |v: f64| {
        let lo = speeds.partition_point(|e| e.0 < v - SAME_SPEED);
        let hi = speeds.partition_point(|e| e.0 <= v + SAME_SPEED);
        &speeds[lo..hi]
    };
    for (c, copy) in tracks.iter().enumerate() {
        if copy.len() < PARTIAL_COPY_SAMPLES || !manoeuvres(copy) {
            continue;
        }
        let Some(anchor) = (0..copy.len()).min_by_key(|&j| near(copy.speed[j]).len()) else {
            continue;
        };
        for &(_, o, i) in near(copy.speed[anchor]) {
            let original = &tracks[o];
            let Some((k, first)) = alignment(original, copy, anchor, i) else {
                continue;
            };
            if o == c || (original.len() == copy.len() && o > c) {
                // Itself, or a whole copy found again from its later twin.
                continue;
            }
            if let Some(how) = copied(original, copy, k, first) {
                return Some(Repeat {
                    copy: c,
                    original: o,
                    how,
                });
            }
        }
    }
    None
}

/// Two tracks that pass through the very same recorded positions (to the millimetre, in
/// place) at [`PARTIAL_COPY_SAMPLES`] samples or more, over more than [`STANDING_M`]: one
/// vehicle's samples under two ids, whatever their order (a track split in two that overlap,
/// a copy played backwards). Two vehicles never share ten positions to the millimetre.
fn shared_positions(tracks: &[RecordedTrack]) -> Option<Repeat> {
    use std::collections::{BTreeMap, HashMap};
    let key = |x: f64, y: f64| {
        (
            (x / SAME_OFFSET_M).round() as i64,
            (y / SAME_OFFSET_M).round() as i64,
        )
    };
    let mut owner: HashMap<(i64, i64), usize> = HashMap::new();
    // (original, copy) -> the copy's samples found in the original.
    let mut shared: BTreeMap<(usize, usize), Vec<usize>> = BTreeMap::new();
    for (c, track) in tracks.iter().enumerate() {
        for j in 0..track.len() {
            match owner.entry(key(track.x[j], track.y[j])) {
                std::collections::hash_map::Entry::Occupied(o) if *o.get() != c => {
                    shared.entry((*o.get(), c)).or_default().push(j);
                }
                std::collections::hash_map::Entry::Occupied(_) => {}
                std::collections::hash_map::Entry::Vacant(v) => {
                    v.insert(c);
                }
            }
        }
    }
    shared.into_iter().find_map(|((original, copy), samples)| {
        let track = &tracks[copy];
        let spread = samples
            .iter()
            .map(|&j| distance(track, samples[0], j))
            .fold(0.0, f64::max);
        (samples.len() >= PARTIAL_COPY_SAMPLES && spread > STANDING_M).then(|| Repeat {
            copy,
            original,
            how: format!(
                "{} of its samples at that track's very positions, its samples {}-{}",
                samples.len(),
                samples[0] + 1,
                samples[samples.len() - 1] + 1
            ),
        })
    })
}

/// The thinning `k` and first sample of `original` that would put the copy's sample `anchor`
/// on the original's sample `at`, when the copy's period and length allow it.
fn alignment(
    original: &RecordedTrack,
    copy: &RecordedTrack,
    anchor: usize,
    at: usize,
) -> Option<(usize, usize)> {
    let k = (copy.period / original.period).round();
    if k < 1.0 || (copy.period - k * original.period).abs() > PERIOD_TOLERANCE * copy.period {
        return None;
    }
    let k = k as usize;
    let first = at.checked_sub(k * anchor)?;
    (first + k * (copy.len() - 1) < original.len()).then_some((k, first))
}

/// Whether every sample `j` of `copy` is sample `first + k j` of `original`, moved, rotated
/// and perhaps mirrored as a whole: the same speeds and acceleration commands, the same
/// steering commands and heading changes (both negated in a mirror image). Those alone make
/// it a copy (the caller asks for a manoeuvre over [`PARTIAL_COPY_SAMPLES`] samples, which no
/// two vehicles repeat to the millimetre per second); positions that are not the same
/// distances from the first sample were scaled, noised or redrawn. Says how the copy was
/// made.
fn copied(
    original: &RecordedTrack,
    copy: &RecordedTrack,
    k: usize,
    first: usize,
) -> Option<String> {
    let matches = |mirror: f64| {
        (0..copy.len()).all(|j| {
            let i = first + k * j;
            let turned = wrap_angle(original.heading[i] - original.heading[first]);
            (original.speed[i] - copy.speed[j]).abs() <= SAME_SPEED
                && (original.accel_cmd[i] - copy.accel_cmd[j]).abs() <= SAME_SPEED
                && (mirror * original.steer_cmd[i] - copy.steer_cmd[j]).abs() <= SAME_ANGLE_RAD
                && wrap_angle(mirror * turned - (copy.heading[j] - copy.heading[0])).abs()
                    <= 2.0 * SAME_ANGLE_RAD
        })
    };
    let mirror = [1.0, -1.0].into_iter().find(|&m| matches(m))?;
    let same_distances = (0..copy.len()).all(|j| {
        let i = first + k * j;
        (distance(original, first, i) - distance(copy, 0, j)).abs() <= SAME_DISTANCE_M
    });
    let last = first + k * (copy.len() - 1);
    let mut how = Vec::new();
    if !same_distances {
        how.push("its positions scaled, noised or redrawn".to_string());
    }
    if first > 0 || last + 1 < original.len() {
        how.push(format!("cut from its samples {}-{}", first + 1, last + 1));
    }
    if k > 1 {
        how.push(format!("one sample in {k} kept"));
    }
    if mirror < 0.0 {
        how.push("mirrored".into());
    }
    let rotation = wrap_angle(copy.heading[0] - mirror * original.heading[first]);
    if rotation.abs() > 2.0 * SAME_ANGLE_RAD {
        how.push(format!("rotated by {:.1} degrees", rotation.to_degrees()));
    }
    if how.is_empty() {
        how.push("moved as a whole".into());
    }
    Some(how.join(", "))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// A braking and turning track of `n` samples at `period`.
    fn manoeuvring(id: &str, n: usize, period: f64) -> RecordedTrack {
        let mut track = RecordedTrack::empty(id.into(), period, None);
        let (mut x, mut y, mut heading, mut speed) = (0.0, 0.0, 0.3_f64, 20.0);
        for k in 0..n {
            let accel = if (20..40).contains(&k) { -3.0 } else { 0.5 };
            let steer = 0.02 * (k as f64 * 0.1).sin();
            track.t.push(k as f64 * period);
            track.x.push(x);
            track.y.push(y);
            track.heading.push(heading);
            track.speed.push(speed);
            track.accel_cmd.push(accel);
            track.steer_cmd.push(steer);
            x += speed * heading.cos() * period;
            y += speed * heading.sin() * period;
            heading += speed * steer.tan() / 2.8 * period;
            speed = (speed + accel * period).max(0.0);
        }
        track
    }

    /// `track` rotated by `angle` about the origin, mirrored first when `mirror`, shifted in
    /// time by `dt`, renamed `id`.
    fn transformed(
        track: &RecordedTrack,
        id: &str,
        angle: f64,
        mirror: bool,
        dt: f64,
    ) -> RecordedTrack {
        let mut out = track.clone();
        out.id = id.into();
        let m = if mirror { -1.0 } else { 1.0 };
        let (s, c) = angle.sin_cos();
        for k in 0..track.len() {
            let (x, y) = (track.x[k], m * track.y[k]);
            out.x[k] = c * x - s * y + 100.0;
            out.y[k] = s * x + c * y - 50.0;
            out.heading[k] = wrap_angle(angle + m * track.heading[k]);
            out.steer_cmd[k] = m * track.steer_cmd[k];
            out.t[k] = track.t[k] + dt;
        }
        out
    }

    fn cut(track: &RecordedTrack, from: usize, to: usize) -> RecordedTrack {
        let mut out = track.clone();
        for v in [
            &mut out.t,
            &mut out.x,
            &mut out.y,
            &mut out.heading,
            &mut out.speed,
            &mut out.accel_cmd,
            &mut out.steer_cmd,
        ] {
            *v = v[from..to].to_vec();
        }
        out
    }

    fn refused(tracks: &[RecordedTrack]) -> String {
        refuse_repeated_tracks("rec.csv", tracks)
            .expect_err("a repeated track")
            .to_string()
    }

    #[test]
    fn a_copy_cut_thinned_rotated_mirrored_or_shifted_in_time_is_refused() {
        let a = manoeuvring("a", 120, 0.1);
        let cases = [
            (cut(&a, 30, 90), "cut from its samples 31-90"),
            (a.decimated(2), "one sample in 2 kept"),
            (
                transformed(&a, "b", 0.7, false, 33.0),
                "rotated by 40.1 degrees",
            ),
            (transformed(&a, "b", 0.0, true, 0.0), "mirrored"),
            (
                cut(&transformed(&a, "b", -2.0, true, 5.0), 10, 60).decimated(3),
                "cut from its samples 11-59, one sample in 3 kept, mirrored, rotated by",
            ),
        ];
        // Positions scaled by 1 %, or a cut with 5 cm of noise on its positions: the speeds,
        // commands and heading changes still repeat the original's sample for sample.
        let mut scaled = a.clone();
        for k in 0..scaled.len() {
            scaled.x[k] *= 1.01;
            scaled.y[k] *= 1.01;
        }
        let mut noised = cut(&a, 20, 100);
        for k in 0..noised.len() {
            noised.x[k] += 0.05 * (k as f64 * 1.7).sin();
            noised.y[k] += 0.05 * (k as f64 * 2.3).cos();
        }
        let cases = cases.into_iter().chain([
            (scaled, "positions scaled, noised or redrawn"),
            (
                noised,
                "positions scaled, noised or redrawn, cut from its samples 21-100",
            ),
        ]);
        for (mut copy, expected) in cases {
            copy.id = "b".into();
            let message = refused(&[a.clone(), copy]);
            assert!(
                message.contains("track_id b") && message.contains("same track as track_id a"),
                "{message}"
            );
            assert!(message.contains(expected), "`{expected}` not in {message}");
        }
    }

    #[test]
    fn another_drive_or_a_short_cruise_is_not_a_copy() {
        let a = manoeuvring("a", 120, 0.1);
        // The same path braking a tenth of a metre per second harder.
        let mut other = transformed(&a, "b", 0.5, false, 0.0);
        for v in &mut other.speed[25..] {
            *v -= 0.01;
        }
        refuse_repeated_tracks("rec.csv", &[a.clone(), other]).expect("another drive");
        // A piece too short to say, and a piece of a track without a manoeuvre.
        let mut short = cut(&a, 20, 20 + PARTIAL_COPY_SAMPLES - 1);
        short.id = "c".into();
        refuse_repeated_tracks("rec.csv", &[a.clone(), short]).expect("too short");
        let mut cruise = manoeuvring("d", 60, 0.1);
        for k in 0..60 {
            cruise.speed[k] = 25.0;
            cruise.accel_cmd[k] = 0.0;
            cruise.steer_cmd[k] = 0.0;
            cruise.heading[k] = 0.0;
            cruise.x[k] = 2.5 * k as f64;
            cruise.y[k] = 0.0;
        }
        // The second car drives the same line, never through the first one's very positions.
        let mut piece = cut(&cruise, 10, 40);
        piece.id = "e".into();
        for x in &mut piece.x {
            *x += 0.37;
        }
        refuse_repeated_tracks("rec.csv", &[cruise, piece]).expect("two cruising cars");
    }

    #[test]
    fn two_tracks_through_the_same_positions_are_one_vehicle() {
        let a = manoeuvring("a", 120, 0.1);
        // Split in two that overlap by 30 samples (40-69), the second part renamed.
        let (first, mut second) = (cut(&a, 0, 70), cut(&a, 40, 119));
        second.id = "b".into();
        let message = refused(&[first, second]);
        assert!(
            message.contains("30 of its samples at that track's very positions"),
            "{message}"
        );
        // Played backwards (headings turned round, so no sample matches its original's).
        let mut backwards = a.clone();
        backwards.id = "b".into();
        for channel in [&mut backwards.x, &mut backwards.y, &mut backwards.speed] {
            channel.reverse();
        }
        backwards.heading = a.heading.iter().rev().map(|h| wrap_angle(h + PI)).collect();
        let message = refused(&[a, backwards]);
        assert!(message.contains("120 of its samples"), "{message}");
    }
}
