//! Vehicle recordings for sim-to-real identification: uniformly sampled states of real vehicles
//! together with the commands they were driven with.
//!
//! The format is CSV with a header. Required columns (any order, SI units):
//!
//! | column      | meaning                                              | unit  |
//! |-------------|------------------------------------------------------|-------|
//! | `track_id`  | vehicle / run identifier (any text)                  |       |
//! | `t`         | time                                                 | s     |
//! | `x`, `y`    | position                                             | m     |
//! | `heading`   | yaw angle                                            | rad   |
//! | `speed`     | longitudinal speed                                   | m/s   |
//! | `accel_cmd` | commanded longitudinal acceleration                  | m/s^2 |
//! | `steer_cmd` | commanded road-wheel steering angle                  | rad   |
//!
//! An optional `wheelbase` column (m) may be given per row; within a track it must be constant
//! and given on every row or on none. Other columns are ignored, except one named like a
//! column above misspelt (`wheelbse`), which is refused. Fields are trimmed of
//! surrounding whitespace; blank lines are skipped.
//!
//! Rows are grouped by `track_id` (tracks keep the order of their first row, rows keep file
//! order, rows of different tracks may interleave). Each track must have at least two samples,
//! strictly increasing times and a uniform sampling period: the period is the median time step
//! and every step must be within 5% of it, between 1 ms and 1 s (timestamps in seconds). Gaps and jitter are rejected rather than silently
//! resampled. Values whose magnitude suggests a unit mistake (degrees, km/h, millimetres) are
//! rejected too, and so are positions beyond 1e7 m and rows whose position jumps further than
//! twice what the recorded speeds allow plus 1 m (a teleport or a glitch).

use std::collections::HashMap;
use std::path::Path;

use super::track::{MAX_SPEED, MIN_SPEED};
use crate::error::{Error, Result};

/// The required columns, in the order [`Recordings::to_csv`] writes them.
const REQUIRED: [&str; 8] = [
    "track_id",
    "t",
    "x",
    "y",
    "heading",
    "speed",
    "accel_cmd",
    "steer_cmd",
];

/// The optional per-row wheelbase column.
const WHEELBASE: &str = "wheelbase";

/// Largest accepted |steer_cmd| (rad) for a road-wheel angle.
const MAX_STEER: f64 = 1.0;
/// Largest accepted |accel_cmd| (m/s^2).
const MAX_ACCEL: f64 = 20.0;
/// Accepted wheelbase range (m).
const MIN_WHEELBASE: f64 = 1.0;
const MAX_WHEELBASE: f64 = 20.0;
/// Largest accepted change of the wheelbase within one track (m).
const WHEELBASE_TOLERANCE: f64 = 1e-3;
/// Largest accepted relative deviation of a time step from the track's period.
const PERIOD_TOLERANCE: f64 = 0.05;
/// Accepted sampling periods (s): 1 kHz to 1 Hz. Outside, the timestamps are almost surely
/// not seconds (milliseconds give periods of 10-1000).
const MIN_PERIOD: f64 = 1e-3;
const MAX_PERIOD: f64 = 1.0;
/// Largest accepted |x|, |y| (m): any local metric frame, UTM included.
const MAX_COORDINATE: f64 = 1e7;
/// Largest plausible timestamp (s): Unix time in seconds is about 1.8e9. Beyond, a 1 kHz
/// log's steps are lost to the rounding of the numbers.
const MAX_TIME: f64 = 1e10;
/// A step's travelled distance may exceed what its recorded speeds allow by this factor plus
/// [`JUMP_SLACK`] (position noise) before the row is called a jump (a teleport, a glitch).
pub(crate) const JUMP_FACTOR: f64 = 2.0;
pub(crate) const JUMP_SLACK: f64 = 1.0;
/// Or this many of the track's position-noise widths ([`position_noise`]), when larger: the
/// step between two noisy samples scatters by sqrt(2) widths, so eight keep a sensor's
/// ordinary scatter (over 10^4 steps) well inside while a metre-scale glitch stays out.
const JUMP_NOISE_WIDTHS: f64 = 8.0;
/// Samples a track needs before its own noise is estimated.
const NOISE_MIN_SAMPLES: usize = 20;

/// A robust estimate of a track's position noise (m, one axis): the median absolute second
/// difference of x and y scaled to a standard deviation (a second difference of white noise
/// has sqrt(6) of its width; 1.4826 turns a median absolute value into a width). Driving adds
/// little to second differences at logging rates, and a glitch does not move the median of a
/// track long enough to have one ([`NOISE_MIN_SAMPLES`]; shorter tracks get 0).
fn position_noise(track: &RecordedTrack) -> f64 {
    if track.len() < NOISE_MIN_SAMPLES {
        return 0.0;
    }
    let second = |v: &[f64], k: usize| (v[k] - 2.0 * v[k - 1] + v[k - 2]).abs();
    let mut d: Vec<f64> = (2..track.len())
        .flat_map(|k| [second(&track.x, k), second(&track.y, k)])
        .collect();
    let mid = d.len() / 2;
    let (_, median, _) = d.select_nth_unstable_by(mid, f64::total_cmp);
    1.4826 * *median / 6f64.sqrt()
}

/// One vehicle's uniformly sampled recording.
#[derive(Debug, Clone)]
pub struct RecordedTrack {
    /// The `track_id` of its rows.
    pub id: String,
    /// 1-based line of the track's first row in the source.
    pub first_line: usize,
    /// Sampling period (s): the median time step.
    pub period: f64,
    /// Time (s).
    pub t: Vec<f64>,
    /// Position (m).
    pub x: Vec<f64>,
    /// Position (m).
    pub y: Vec<f64>,
    /// Yaw angle (rad).
    pub heading: Vec<f64>,
    /// Longitudinal speed (m/s).
    pub speed: Vec<f64>,
    /// Commanded longitudinal acceleration (m/s^2).
    pub accel_cmd: Vec<f64>,
    /// Commanded road-wheel steering angle (rad).
    pub steer_cmd: Vec<f64>,
    /// Wheelbase (m), when the recording gives one.
    pub wheelbase: Option<f64>,
}

impl RecordedTrack {
    /// A track with no samples yet (`first_line` 0: not read from a file).
    pub fn empty(id: String, period: f64, wheelbase: Option<f64>) -> Self {
        Self {
            id,
            first_line: 0,
            period,
            t: Vec::new(),
            x: Vec::new(),
            y: Vec::new(),
            heading: Vec::new(),
            speed: Vec::new(),
            accel_cmd: Vec::new(),
            steer_cmd: Vec::new(),
            wheelbase,
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Whether the track has no samples.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Every `k`-th sample (k >= 1): the same track at a `k` times longer period.
    pub fn decimated(&self, k: usize) -> Self {
        let k = k.max(1);
        let every = |v: &[f64]| v.iter().step_by(k).copied().collect::<Vec<f64>>();
        Self {
            id: self.id.clone(),
            first_line: self.first_line,
            period: self.period * k as f64,
            t: every(&self.t),
            x: every(&self.x),
            y: every(&self.y),
            heading: every(&self.heading),
            speed: every(&self.speed),
            accel_cmd: every(&self.accel_cmd),
            steer_cmd: every(&self.steer_cmd),
            wheelbase: self.wheelbase,
        }
    }

    /// Time from the first to the last sample (s); 0 with fewer than two samples.
    pub fn duration(&self) -> f64 {
        match (self.t.first(), self.t.last()) {
            (Some(first), Some(last)) => last - first,
            _ => 0.0,
        }
    }
}

/// All tracks of one recordings file.
#[derive(Debug, Clone)]
pub struct Recordings {
    /// Where the recordings came from (a path or another name), used in error messages.
    pub source: String,
    /// Tracks in order of their first row.
    pub tracks: Vec<RecordedTrack>,
}

/// The longest header line read: far above any real one's, far below what would hold a
/// whole binary file.
const MAX_HEADER_BYTES: usize = 64 * 1024;

/// The text of the recordings file `path`, refused at the first line longer than a header
/// may be (a data row is a few hundred bytes).
pub fn read_recordings_text(path: &Path) -> Result<String> {
    crate::io::read_lines(path, crate::io::Format::Recordings, MAX_HEADER_BYTES)
}

impl Recordings {
    /// Reads and parses a recordings CSV file.
    pub fn load(path: &Path) -> Result<Self> {
        let text = read_recordings_text(path)?;
        Self::parse(&path.display().to_string(), &text)
    }

    /// Parses recordings CSV text; `source` names it in error messages.
    pub fn parse(source: &str, text: &str) -> Result<Self> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        if text.trim().is_empty() {
            return Err(Error::invalid(
                source,
                "line 1",
                format!(
                    "the file is empty; expected the header `{}` followed by data rows",
                    expected_header()
                ),
            ));
        }
        let header_len = text.find('\n').unwrap_or(text.len());
        if header_len > MAX_HEADER_BYTES {
            return Err(Error::invalid(
                source,
                "line 1",
                format!(
                    "the first line is {header_len} bytes long; expected the header `{}` (a \
                     recordings CSV's header is a few dozen bytes)",
                    expected_header()
                ),
            ));
        }
        let mut reader = csv::ReaderBuilder::new()
            .has_headers(true)
            .flexible(false)
            .trim(csv::Trim::All)
            .from_reader(text.as_bytes());
        let header = reader.headers().map_err(|e| csv_error(source, &e))?.clone();
        let columns = Columns::find(source, &header)?;

        let mut builders: Vec<TrackBuilder> = Vec::new();
        let mut index: HashMap<String, usize> = HashMap::new();
        let mut record = csv::StringRecord::new();
        loop {
            match reader.read_record(&mut record) {
                Ok(true) => {}
                Ok(false) => break,
                Err(e) => return Err(csv_error(source, &e)),
            }
            let line = record
                .position()
                .map(|p| p.line() as usize)
                .unwrap_or_default();
            let row = Row::parse(source, &columns, &record, line)?;
            let slot = match index.get(&row.id) {
                Some(&slot) => slot,
                None => {
                    index.insert(row.id.clone(), builders.len());
                    builders.push(TrackBuilder::new(row.id.clone(), line));
                    builders.len() - 1
                }
            };
            builders[slot].push(source, row, line)?;
        }
        if builders.is_empty() {
            return Err(Error::invalid(
                source,
                "line 2",
                format!(
                    "the file has a header but no data rows; expected rows under `{}`",
                    expected_header()
                ),
            ));
        }
        let tracks = builders
            .into_iter()
            .map(|b| b.finish(source))
            .collect::<Result<Vec<_>>>()?;
        super::repeated_tracks::refuse_repeated_tracks(source, &tracks)?;
        Ok(Recordings {
            source: source.to_string(),
            tracks,
        })
    }

    /// Writes the recordings as CSV that [`Recordings::parse`] reads back exactly: the header
    /// `track_id,t,x,y,heading,speed,accel_cmd,steer_cmd`, plus `wheelbase` when every track
    /// has one, and one row per sample, tracks one after the other.
    pub fn to_csv(&self) -> String {
        let with_wheelbase =
            !self.tracks.is_empty() && self.tracks.iter().all(|t| t.wheelbase.is_some());
        let mut out = expected_header();
        if with_wheelbase {
            out.push(',');
            out.push_str(WHEELBASE);
        }
        out.push('\n');
        for track in &self.tracks {
            let id = quote(&track.id);
            for k in 0..track.len() {
                let values = [
                    track.t[k],
                    track.x[k],
                    track.y[k],
                    track.heading[k],
                    track.speed[k],
                    track.accel_cmd[k],
                    track.steer_cmd[k],
                ];
                out.push_str(&id);
                for v in values {
                    out.push(',');
                    out.push_str(&v.to_string());
                }
                if let (true, Some(wb)) = (with_wheelbase, track.wheelbase) {
                    out.push(',');
                    out.push_str(&wb.to_string());
                }
                out.push('\n');
            }
        }
        out
    }

    /// Writes [`Recordings::to_csv`] to `path` atomically.
    pub fn save(&self, path: &Path) -> Result<()> {
        crate::io::atomic_write(path, self.to_csv().as_bytes())
    }
}

/// The required header as one CSV line.
/// Recordings as an output: a `.csv` file that starts with the recordings header.
pub const RECORDINGS_CSV: crate::io::FileKind = crate::io::FileKind {
    name: "a recordings CSV",
    extensions: &["csv"],
    recognise: |head| head.starts_with(expected_header().as_bytes()),
};

fn expected_header() -> String {
    REQUIRED.join(",")
}

/// A time in seconds as a message shows it: to the microsecond, without the float's rounding
/// digits (`0.10000000000000142` is `0.1`); very small or large ones in exponent form.
fn seconds(v: f64) -> String {
    if v != 0.0 && !(1e-6..1e12).contains(&v.abs()) {
        return format!("{v:e}");
    }
    let text = format!("{v:.6}");
    text.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// Quotes a CSV field when it needs it (separator, quote, line break, surrounding spaces).
fn quote(field: &str) -> String {
    let needs = field.contains([',', '"', '\n', '\r']) || field.trim() != field;
    if needs {
        format!("\"{}\"", field.replace('"', "\"\""))
    } else {
        field.to_string()
    }
}

/// Converts a CSV syntax error into [`Error::Parse`].
fn csv_error(source: &str, e: &csv::Error) -> Error {
    let (line, column, message) = match e.kind() {
        csv::ErrorKind::UnequalLengths {
            pos,
            expected_len,
            len,
        } => (
            pos.as_ref().map(|p| p.line() as usize).unwrap_or_default(),
            (*len).min(*expected_len) as usize + 1,
            format!(
                "the row has {len} fields but the header has {expected_len}; every row needs \
                 one field per header column"
            ),
        ),
        csv::ErrorKind::Utf8 { pos, err } => (
            pos.as_ref().map(|p| p.line() as usize).unwrap_or_default(),
            err.field() + 1,
            format!("invalid UTF-8: {err}"),
        ),
        _ => (
            e.position().map(|p| p.line() as usize).unwrap_or_default(),
            0,
            e.to_string(),
        ),
    };
    Error::Parse {
        source_name: source.to_string(),
        line,
        column,
        message,
    }
}

/// Field indices of the columns rtr reads.
struct Columns {
    /// Indices of [`REQUIRED`], in that order.
    required: [usize; 8],
    wheelbase: Option<usize>,
}

/// Refuses an extra column whose name is a known column's misspelt (`wheelbse`, `Speed`):
/// ignored like any other extra column, it would silently drop what the user recorded (a
/// 4.2 m wheelbase read as the 2.8 m default). A near miss is a case-insensitive match, or
/// one edit away for names of four letters or more, two for eight or more; short names
/// (`t`, `x`, `y`) are only matched up to case, since `z` or `id` are other columns.
fn refuse_misspelt_columns(source: &str, header: &csv::StringRecord) -> Result<()> {
    let known: Vec<&str> = REQUIRED.iter().copied().chain([WHEELBASE]).collect();
    let near = |given: &str, name: &str| {
        let (given, name) = (given.to_lowercase(), name.to_lowercase());
        let edits = strsim::damerau_levenshtein(&given, name.as_str());
        let allowed = match name.chars().count() {
            0..4 => 0,
            4..8 => 1,
            _ => 2,
        };
        edits <= allowed
    };
    for (k, given) in header.iter().enumerate() {
        if known.contains(&given) {
            continue;
        }
        if let Some(name) = known.iter().find(|name| near(given, name)) {
            return Err(Error::invalid(
                source,
                format!("line 1, column {}", k + 1),
                format!(
                    "the header names `{given}`, which is no column rtr reads; expected \
                     `{name}` (other extra columns are ignored, but this one looks like \
                     `{name}` misspelt, and its values would be dropped)"
                ),
            ));
        }
    }
    Ok(())
}

impl Columns {
    fn find(source: &str, header: &csv::StringRecord) -> Result<Self> {
        let position = |name: &str| -> Result<Option<usize>> {
            let mut hits = header.iter().enumerate().filter(|(_, h)| *h == name);
            let first = hits.next().map(|(i, _)| i);
            if let Some((second, _)) = hits.next() {
                return Err(Error::invalid(
                    source,
                    format!("line 1, column `{name}`"),
                    format!(
                        "the header names `{name}` twice (fields {} and {}); expected each \
                         column once",
                        first.unwrap_or_default() + 1,
                        second + 1
                    ),
                ));
            }
            Ok(first)
        };
        let mut required = [0; 8];
        let mut missing = Vec::new();
        for (slot, name) in required.iter_mut().zip(REQUIRED) {
            match position(name)? {
                Some(i) => *slot = i,
                None => missing.push(format!("`{name}`")),
            }
        }
        if !missing.is_empty() {
            let found = header.iter().collect::<Vec<_>>().join(",");
            return Err(Error::invalid(
                source,
                "line 1 (header)",
                format!(
                    "missing required column{} {}; expected a header with `{}` (any order, \
                     optional `{WHEELBASE}`, other columns ignored), found `{found}`",
                    if missing.len() == 1 { "" } else { "s" },
                    missing.join(", "),
                    expected_header()
                ),
            ));
        }
        refuse_misspelt_columns(source, header)?;
        Ok(Columns {
            required,
            wheelbase: position(WHEELBASE)?,
        })
    }
}

/// One parsed and range-checked data row.
struct Row {
    id: String,
    /// t, x, y, heading, speed, accel_cmd, steer_cmd.
    values: [f64; 7],
    wheelbase: Option<f64>,
}

impl Row {
    fn parse(
        source: &str,
        columns: &Columns,
        record: &csv::StringRecord,
        line: usize,
    ) -> Result<Self> {
        let field = |i: usize| record.get(i).unwrap_or("");
        let id = field(columns.required[0]).to_string();
        if id.is_empty() {
            return Err(Error::invalid(
                source,
                format!("line {line}, column `track_id`"),
                "the track id is empty; expected a non-empty identifier",
            ));
        }
        let mut values = [0.0; 7];
        for (k, value) in values.iter_mut().enumerate() {
            let name = REQUIRED[k + 1];
            let i = columns.required[k + 1];
            *value = number(source, line, i, name, field(i))?;
            check_range(source, line, name, *value)?;
        }
        let wheelbase = match columns.wheelbase {
            Some(i) if !field(i).is_empty() => {
                let wb = number(source, line, i, WHEELBASE, field(i))?;
                check_range(source, line, WHEELBASE, wb)?;
                Some(wb)
            }
            _ => None,
        };
        Ok(Row {
            id,
            values,
            wheelbase,
        })
    }
}

/// Parses a finite number from field `index` (0-based) named `name`.
fn number(source: &str, line: usize, index: usize, name: &str, text: &str) -> Result<f64> {
    let parse_error = |message: String| Error::Parse {
        source_name: source.to_string(),
        line,
        column: index + 1,
        message,
    };
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(v) => Err(parse_error(format!(
            "column `{name}`: `{text}` is {}; expected a finite number",
            if v.is_nan() { "NaN" } else { "infinite" }
        ))),
        Err(_) if text.is_empty() => Err(parse_error(format!(
            "column `{name}` is empty; expected a finite number"
        ))),
        Err(_) => Err(parse_error(format!(
            "column `{name}`: `{text}` is not a number; expected a finite decimal number"
        ))),
    }
}

/// Rejects values whose magnitude suggests a unit mistake.
fn check_range(source: &str, line: usize, name: &str, v: f64) -> Result<()> {
    let problem = match name {
        "t" if v.abs() > MAX_TIME => Some(format!(
            "time {v:e} s is implausible; expected seconds with |t| <= {MAX_TIME:e} (Unix time \
             in seconds is about 1.8e9; in milliseconds or nanoseconds it is not)"
        )),
        "x" | "y" if v.abs() > MAX_COORDINATE => Some(format!(
            "position {v:e} m is implausible; expected metres in a local frame with |{name}| <= \
             {MAX_COORDINATE}"
        )),
        "heading" if v.abs() > crate::geometry::MAX_HEADING_RAD => Some(format!(
            "heading {v} looks like degrees; expected radians with |heading| <= 2*pi"
        )),
        "steer_cmd" if v.abs() > MAX_STEER => Some(format!(
            "steering command {v} rad is too large for a road-wheel angle (|steer_cmd| <= \
             {MAX_STEER} rad); it looks like degrees or a steering-wheel angle: expected the \
             road-wheel angle in radians"
        )),
        "speed" if v > MAX_SPEED => Some(format!(
            "speed {v} looks like km/h; expected m/s in [{MIN_SPEED}, {MAX_SPEED}]"
        )),
        "speed" if v < MIN_SPEED => Some(format!(
            "speed {v} is negative; expected m/s in [{MIN_SPEED}, {MAX_SPEED}]"
        )),
        "accel_cmd" if v.abs() > MAX_ACCEL => Some(format!(
            "acceleration command {v} is implausible; expected m/s^2 with |accel_cmd| <= \
             {MAX_ACCEL}"
        )),
        WHEELBASE if v > MAX_WHEELBASE => Some(format!(
            "wheelbase {v} looks like millimetres or centimetres; expected metres in \
             [{MIN_WHEELBASE}, {MAX_WHEELBASE}]"
        )),
        WHEELBASE if v < MIN_WHEELBASE => Some(format!(
            "wheelbase {v} is too small; expected metres in [{MIN_WHEELBASE}, {MAX_WHEELBASE}]"
        )),
        _ => None,
    };
    match problem {
        Some(message) => Err(Error::invalid(
            source,
            format!("line {line}, column `{name}`"),
            message,
        )),
        None => Ok(()),
    }
}

/// Rows of one track as they are read.
struct TrackBuilder {
    track: RecordedTrack,
    /// Line of every row.
    lines: Vec<usize>,
    /// Line of the first row that gave a wheelbase, with its value.
    wheelbase_from: Option<usize>,
    /// Line of the first row without a wheelbase.
    no_wheelbase_from: Option<usize>,
}

impl TrackBuilder {
    fn new(id: String, first_line: usize) -> Self {
        TrackBuilder {
            track: RecordedTrack {
                first_line,
                ..RecordedTrack::empty(id, 0.0, None)
            },
            lines: Vec::new(),
            wheelbase_from: None,
            no_wheelbase_from: None,
        }
    }

    fn push(&mut self, source: &str, row: Row, line: usize) -> Result<()> {
        let tr = &mut self.track;
        let [t, x, y, heading, speed, accel_cmd, steer_cmd] = row.values;
        if let (Some(&prev), Some(&prev_line)) = (tr.t.last(), self.lines.last())
            && t <= prev
        {
            return Err(Error::invalid(
                source,
                format!("line {line}, column `t`"),
                format!(
                    "time {} of track `{}` {} (line {prev_line}); expected strictly increasing \
                     times within a track",
                    seconds(t),
                    tr.id,
                    if t == prev {
                        "repeats the time of the row before".to_string()
                    } else {
                        format!("does not increase after {}", seconds(prev))
                    }
                ),
            ));
        }
        match (row.wheelbase, tr.wheelbase) {
            (Some(wb), Some(first)) if (wb - first).abs() > WHEELBASE_TOLERANCE => {
                return Err(Error::invalid(
                    source,
                    format!("line {line}, column `{WHEELBASE}`"),
                    format!(
                        "wheelbase {wb} of track `{}` differs from {first} (line {}); a \
                         track's wheelbase must be constant (within {WHEELBASE_TOLERANCE} m)",
                        tr.id,
                        self.wheelbase_from.unwrap_or_default()
                    ),
                ));
            }
            (Some(wb), None) => {
                tr.wheelbase = Some(wb);
                self.wheelbase_from = Some(line);
            }
            (None, _) => {
                self.no_wheelbase_from.get_or_insert(line);
            }
            (Some(_), Some(_)) => {}
        }
        if let (Some(with), Some(without)) = (self.wheelbase_from, self.no_wheelbase_from) {
            return Err(Error::invalid(
                source,
                format!("line {}, column `{WHEELBASE}`", with.max(without)),
                format!(
                    "track `{}` gives a wheelbase on line {with} but none on line {without}; \
                     expected it on every row of the track or on none",
                    tr.id
                ),
            ));
        }
        tr.t.push(t);
        tr.x.push(x);
        tr.y.push(y);
        tr.heading.push(heading);
        tr.speed.push(speed);
        tr.accel_cmd.push(accel_cmd);
        tr.steer_cmd.push(steer_cmd);
        self.lines.push(line);
        Ok(())
    }

    /// Refuses a row whose position is not where the recorded speeds could have taken the
    /// vehicle: a teleport or a glitch would otherwise be fitted as if it were driving.
    /// The slack grows with the track's own position noise, so a noisier sensor's ordinary
    /// scatter is not called a jump.
    fn check_jumps(source: &str, track: &RecordedTrack, lines: &[usize]) -> Result<()> {
        let slack = JUMP_SLACK.max(JUMP_NOISE_WIDTHS * position_noise(track));
        for k in 1..track.len() {
            let distance = (track.x[k] - track.x[k - 1]).hypot(track.y[k] - track.y[k - 1]);
            let step = track.t[k] - track.t[k - 1];
            let allowed = JUMP_FACTOR * track.speed[k].max(track.speed[k - 1]) * step + slack;
            if distance > allowed {
                return Err(Error::invalid(
                    source,
                    format!("line {}, columns `x`, `y`", lines[k]),
                    format!(
                        "track `{}` moves {distance:.2} m in {step} s from line {}, but its \
                         recorded speeds ({} and {} m/s) allow at most {allowed:.2} m: a jump \
                         (teleport or glitch); remove or repair the row",
                        track.id,
                        lines[k - 1],
                        track.speed[k - 1],
                        track.speed[k]
                    ),
                ));
            }
        }
        Ok(())
    }

    fn finish(self, source: &str) -> Result<RecordedTrack> {
        let mut track = self.track;
        if track.len() < 2 {
            return Err(Error::invalid(
                source,
                format!("track `{}`", track.id),
                format!(
                    "only {} sample (line {}); expected at least 2 samples to know the \
                     sampling period",
                    track.len(),
                    track.first_line
                ),
            ));
        }
        let steps: Vec<f64> = track.t.windows(2).map(|w| w[1] - w[0]).collect();
        let mut sorted = steps.clone();
        sorted.sort_by(f64::total_cmp);
        let n = sorted.len();
        let period = if n % 2 == 1 {
            sorted[n / 2]
        } else {
            0.5 * (sorted[n / 2 - 1] + sorted[n / 2])
        };
        // A relative slack, so a 1 kHz log whose float timestamps step 0.000999... passes.
        if !(MIN_PERIOD * (1.0 - 1e-6)..=MAX_PERIOD * (1.0 + 1e-6)).contains(&period) {
            let hint = if period > MAX_PERIOD {
                "timestamps in milliseconds? "
            } else {
                "timestamps in microseconds? "
            };
            return Err(Error::invalid(
                source,
                format!(
                    "track `{}`, column `t` (line {})",
                    track.id, track.first_line
                ),
                format!(
                    "sampling period (median step) is {}; {hint}expected seconds, \
                     sampled between {} Hz and {} kHz",
                    seconds(period),
                    1.0 / MAX_PERIOD,
                    1e-3 / MIN_PERIOD
                ),
            ));
        }
        for (k, &step) in steps.iter().enumerate() {
            if (step - period).abs() > PERIOD_TOLERANCE * period {
                let line = self.lines[k + 1];
                return Err(Error::invalid(
                    source,
                    format!("line {line}, column `t`"),
                    format!(
                        "track `{}` jumps from t = {} (line {}) to t = {}, a step of {} s, \
                         but its sampling period (median step) is {} s; steps deviating \
                         more than {}% are gaps or jitter: expected uniformly sampled \
                         recordings (resample them first)",
                        track.id,
                        seconds(track.t[k]),
                        self.lines[k],
                        seconds(track.t[k + 1]),
                        seconds(step),
                        seconds(period),
                        PERIOD_TOLERANCE * 100.0
                    ),
                ));
            }
        }
        track.period = period;
        Self::check_jumps(source, &track, &self.lines)?;
        check_motion(source, &track)?;
        Ok(track)
    }
}

/// The speed and heading columns agree with how the positions move ([`super::motion`]), so
/// speeds in km/h, headings in degrees or pointing backwards are refused, not fitted.
fn check_motion(source: &str, track: &RecordedTrack) -> Result<()> {
    let place = format!("track `{}` (from line {})", track.id, track.first_line);
    super::motion::check(
        track.period,
        &track.x,
        &track.y,
        &track.heading,
        &track.speed,
    )
    .map_err(|mismatch| {
        Error::invalid(
            source,
            format!("{place}, column `{}`", mismatch.column()),
            mismatch.to_string(),
        )
    })
}
