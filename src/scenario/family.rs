//! Logical scenarios (PEGASUS): a family of concrete scenarios given as data. A TOML file
//! names a procedural map template, the target (the vehicle the heroes act on, driven by the
//! policy under test), background traffic drawn from the real A9 statistics, and the heroes:
//! where they start relative to the target and the phases of their script. Every number may
//! be a range `[low, high]`; a concrete scenario draws one value from each.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use super::behaviour::Phase;
use super::placement::LaneRef;
use super::range::Range;
use crate::error::{Error, Result};
use crate::io::parse_toml;
use crate::map::ProceduralMap;

/// A check's verdict: `Err((field, message))` names the field at fault.
type FieldCheck = std::result::Result<(), (String, String)>;

/// Which scenario sets a family feeds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FamilySet {
    /// In-distribution: its concrete scenarios are split into the train and eval sets.
    Train,
    /// Held out: only the out-of-distribution set.
    Ood,
}

/// A procedural map preset with some of its parameters replaced by ranges.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MapTemplate {
    /// A [`ProceduralMap::preset`] name.
    pub preset: String,
    /// Preset fields to override (`lanes`, `length`, `curvature`, `merge_s`, ...), plus
    /// `median_width` for an A9-like divided road.
    #[serde(flatten)]
    pub params: BTreeMap<String, Range>,
}

/// The vehicle the heroes act on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TargetSpec {
    pub lane: LaneRef,
    /// Main-road station (m).
    pub station: Range,
    /// Speed (m/s); when absent, drawn from the A9 speeds of the lane within `speed_band`.
    #[serde(default)]
    pub speed: Option<Range>,
    /// Quantile band of the A9 lane speeds (0 = slowest) the target's speed is drawn from.
    #[serde(default = "default_band")]
    pub speed_band: Range,
    /// Sideways offset from the lane centre (m, positive = left) at the current step; the
    /// history is a straight drive into that pose. Absent: on the centre line.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lateral_offset: Option<Range>,
    /// Heading relative to the lane (rad, positive = turned left) held over the history.
    /// Absent: along the lane.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub heading_error: Option<Range>,
}

fn default_band() -> Range {
    Range::Uniform(0.1, 0.9)
}

fn default_behind() -> f64 {
    120.0
}

fn default_ahead() -> f64 {
    250.0
}

/// Background traffic around the target, from the A9 statistics of each lane rank.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BackgroundSpec {
    /// Quantile band of the A9 time headways (low = dense traffic).
    #[serde(default = "default_band")]
    pub headway_band: Range,
    /// Quantile band of the A9 lane speeds.
    #[serde(default = "default_band")]
    pub speed_band: Range,
    /// Traffic is placed from this far behind the target...
    #[serde(default = "default_behind")]
    pub behind_m: f64,
    /// ...to this far ahead of it (m).
    #[serde(default = "default_ahead")]
    pub ahead_m: f64,
    /// Main lanes to fill (1 = leftmost); all when absent.
    #[serde(default)]
    pub lanes: Option<Vec<usize>>,
}

impl Default for BackgroundSpec {
    fn default() -> Self {
        Self {
            headway_band: default_band(),
            speed_band: default_band(),
            behind_m: default_behind(),
            ahead_m: default_ahead(),
            lanes: None,
        }
    }
}

/// Vehicle type of a hero; its size is drawn from the A9 vehicles of that class.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum HeroVehicle {
    #[default]
    Car,
    Truck,
}

/// A scripted vehicle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HeroSpec {
    /// An absolute lane...
    #[serde(default)]
    pub lane: Option<LaneRef>,
    /// ...or main lanes relative to the target's (-1 = one to the left).
    #[serde(default)]
    pub lane_offset: Option<i32>,
    /// Station relative to the target's (m, positive = ahead).
    pub station_offset: Range,
    /// Absolute speed (m/s)...
    #[serde(default)]
    pub speed: Option<Range>,
    /// ...or relative to the target's.
    #[serde(default)]
    pub speed_offset: Option<Range>,
    #[serde(default)]
    pub vehicle: HeroVehicle,
    pub phases: Vec<Phase<Range>>,
}

/// One logical scenario.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LogicalScenario {
    /// snake_case identifier, also the file name.
    pub name: String,
    pub description: String,
    pub set: FamilySet,
    /// Simulated time after the current step (s).
    #[serde(default = "default_duration")]
    pub duration_s: f64,
    pub map: MapTemplate,
    pub target: TargetSpec,
    #[serde(default)]
    pub background: BackgroundSpec,
    /// Scripted vehicles; none for a target alone on its road.
    #[serde(default)]
    pub heroes: Vec<HeroSpec>,
}

fn default_duration() -> f64 {
    10.0
}

/// How far apart (relative) two numbers of two families may be for them to draw the same
/// scenarios: far below any difference a family means (ranges differ by metres or m/s).
pub const NEAR_COPY_RELATIVE: f64 = 0.01;

/// The share of one family's draws that another family draws too, above which the two are
/// one family under two names: a held-out family that mostly re-draws a training family's
/// scenarios tests nothing held out.
pub const SHARED_DRAWS_LIMIT: f64 = 0.5;

/// The share of what `a` draws that `b` draws too, for draws uniform over `a`'s ranges: the
/// product over `a`'s ranges of the part of each inside `b`'s (a fixed number counts 1 if `b`
/// has it or draws it, else 0), to within [`NEAR_COPY_RELATIVE`]; 0 where the two differ in
/// shape or in a string (another map, another manoeuvre).
fn shared_draws(a: &serde_json::Value, b: &serde_json::Value) -> f64 {
    use serde_json::Value;
    let slack = |x: f64, y: f64| NEAR_COPY_RELATIVE * x.abs().max(y.abs()) + 1e-9;
    let inside = |x: f64, (low, high): (f64, f64)| {
        f64::from(u8::from(
            x >= low - slack(x, low) && x <= high + slack(x, high),
        ))
    };
    match (a, b, range(a), range(b)) {
        (_, _, Some((low, high)), Some(other)) => {
            // Within `b`'s range up to the slack: all shared; else the part that overlaps.
            if inside(low, other) * inside(high, other) == 1.0 {
                return 1.0;
            }
            let (b_low, b_high) = other;
            if high <= low {
                return 0.0;
            }
            ((high.min(b_high) - low.max(b_low)) / (high - low)).clamp(0.0, 1.0)
        }
        (Value::Number(x), _, _, Some(other)) => x.as_f64().map_or(0.0, |x| inside(x, other)),
        (Value::Number(x), Value::Number(y), _, _) => match (x.as_f64(), y.as_f64()) {
            (Some(x), Some(y)) => f64::from(u8::from((x - y).abs() <= slack(x, y))),
            _ => 0.0,
        },
        (Value::Array(x), Value::Array(y), _, _) if x.len() == y.len() => {
            x.iter().zip(y).map(|(p, q)| shared_draws(p, q)).product()
        }
        (Value::Object(x), Value::Object(y), _, _) if x.len() == y.len() => x
            .iter()
            .map(|(k, v)| y.get(k).map_or(0.0, |w| shared_draws(v, w)))
            .product(),
        _ => f64::from(u8::from(a == b)),
    }
}

/// A drawn range `[low, high]` (two numbers, in order).
fn range(value: &serde_json::Value) -> Option<(f64, f64)> {
    match value.as_array()?.as_slice() {
        [low, high] => {
            let (low, high) = (low.as_f64()?, high.as_f64()?);
            (low <= high).then_some((low, high))
        }
        _ => None,
    }
}

impl FamilySet {
    /// The name a family file gives it (`set = "train"`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Train => "train",
            Self::Ood => "ood",
        }
    }
}

impl LogicalScenario {
    /// The larger share of one family's draws that the other draws too (see
    /// [`SHARED_DRAWS_LIMIT`]): 1 for a copy, a bound nudged by a hair or a range narrowed;
    /// 0 for families of another map, manoeuvre or number of heroes. Name, description and
    /// set do not count.
    pub fn shared_draws(&self, other: &Self) -> f64 {
        let drawn = |family: &Self| {
            let mut value = serde_json::to_value(family).unwrap_or_default();
            if let Some(fields) = value.as_object_mut() {
                for key in ["name", "description", "set"] {
                    fields.remove(key);
                }
            }
            value
        };
        let (a, b) = (drawn(self), drawn(other));
        shared_draws(&a, &b).max(shared_draws(&b, &a))
    }

    /// Every value a concrete scenario of this family draws, by the name it is recorded under
    /// in the scenario's `parameters`, with the range it is drawn from (the sampler's naming:
    /// `map.*`, `target.*`, `heroes[h].*`, `background.*`).
    pub fn drawn_ranges(&self) -> BTreeMap<String, Range> {
        let mut out: BTreeMap<String, Range> = BTreeMap::new();
        for (key, range) in &self.map.params {
            out.insert(format!("map.{key}"), *range);
        }
        let t = &self.target;
        out.insert("target.station".into(), t.station);
        out.insert("target.speed_quantile".into(), t.speed_band);
        let optional = [
            ("target.speed", t.speed),
            ("target.lateral_offset", t.lateral_offset),
            ("target.heading_error", t.heading_error),
        ];
        out.extend(
            optional
                .into_iter()
                .filter_map(|(n, r)| Some((n.to_string(), r?))),
        );
        for (h, hero) in self.heroes.iter().enumerate() {
            let name = format!("heroes[{h}]");
            out.insert(format!("{name}.station_offset"), hero.station_offset);
            match (hero.speed, hero.speed_offset) {
                (Some(r), _) => out.insert(format!("{name}.speed"), r),
                (None, Some(r)) => out.insert(format!("{name}.speed_offset"), r),
                (None, None) => None,
            };
            for (p, phase) in hero.phases.iter().enumerate() {
                for (field, range) in phase.ranges() {
                    out.insert(format!("{name}.phases[{p}].{field}"), range);
                }
            }
        }
        out.insert(
            "background.headway_quantile".into(),
            self.background.headway_band,
        );
        out
    }

    pub fn from_toml_str(text: &str, source_name: &str) -> Result<Self> {
        let family: Self = parse_toml(text, source_name)?;
        family
            .validate()
            .map_err(|(place, message)| Error::invalid(source_name, place, message))?;
        Ok(family)
    }

    pub fn from_toml_file(path: &Path) -> Result<Self> {
        let text = crate::io::read_text(path, crate::io::Format::Settings)?;
        Self::from_toml_str(&text, &path.display().to_string())
    }

    /// Main lanes named by the target and the heroes exist on the narrowest map the family
    /// can draw (1 = leftmost).
    fn check_lane_numbers(&self) -> FieldCheck {
        let lanes = super::sample::map_with(self, |_, range| range.low())
            .ok()
            .and_then(|map| serde_json::to_value(map).ok())
            .and_then(|v| v.get("lanes").and_then(|l| l.as_u64()))
            .unwrap_or(u64::MAX) as usize;
        let named = std::iter::once(("target.lane".to_string(), Some(self.target.lane))).chain(
            self.heroes
                .iter()
                .enumerate()
                .map(|(h, hero)| (format!("heroes[{h}].lane"), hero.lane)),
        );
        for (place, lane) in named {
            if let Some(LaneRef::Main(k)) = lane
                && (k == 0 || k > lanes)
            {
                return Err((
                    format!("field `{place}`"),
                    format!("main lane {k}, but the map has {lanes} (1 = leftmost)"),
                ));
            }
        }
        Ok(())
    }

    /// Checks what can be checked without drawing: names, ranges, the map template's keys.
    /// Errors are (field, message).
    pub fn validate(&self) -> FieldCheck {
        self.check_name_and_duration()?;
        self.check_map_params()?;
        self.check_map_corners()?;
        self.check_lane_numbers()?;
        self.check_target_and_background()?;
        self.check_heroes()
    }

    fn check_name_and_duration(&self) -> FieldCheck {
        let field = |f: &str| format!("field `{f}`");
        if self.name.is_empty()
            || !self
                .name
                .chars()
                .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_')
        {
            return Err((
                field("name"),
                format!("`{}`: expected a snake_case identifier", self.name),
            ));
        }
        if !(1.0..=60.0).contains(&self.duration_s) {
            return Err((
                field("duration_s"),
                format!("{} s: expected 1 to 60 s", self.duration_s),
            ));
        }
        Ok(())
    }

    /// Every `map.*` range names a numeric parameter of the preset, within bounds (whole
    /// numbers where the parameter is a count).
    fn check_map_params(&self) -> FieldCheck {
        let field = |f: &str| format!("field `{f}`");
        let preset = ProceduralMap::preset(&self.map.preset)
            .map_err(|e| (field("map.preset"), e.to_string()))?;
        let known = serde_json::to_value(&preset)
            .ok()
            .and_then(|v| v.as_object().cloned())
            .unwrap_or_default();
        for (key, range) in &self.map.params {
            let numeric = known.get(key).is_some_and(|v| v.is_number());
            let layout = key == "median_width" && known.contains_key("layout");
            if !(numeric || layout) {
                let mut keys: Vec<&str> = known
                    .iter()
                    .filter(|(_, v)| v.is_number())
                    .map(|(k, _)| k.as_str())
                    .collect();
                if known.contains_key("layout") {
                    keys.push("median_width");
                }
                return Err((
                    field(&format!("map.{key}")),
                    format!(
                        "preset `{}` has no parameter `{key}`; expected one of {}",
                        self.map.preset,
                        keys.join(", ")
                    ),
                ));
            }
            range
                .check(&format!("map.{key}"), 0.0, 10_000.0)
                .map_err(|m| (field(&format!("map.{key}")), m))?;
            let whole = known.get(key).is_some_and(|v| v.is_u64());
            if whole && (range.low().fract() != 0.0 || range.high().fract() != 0.0) {
                return Err((
                    field(&format!("map.{key}")),
                    format!("{range}: expected whole numbers"),
                ));
            }
        }
        Ok(())
    }

    fn check_map_corners(&self) -> FieldCheck {
        let field = |f: &str| format!("field `{f}`");
        // The maps at the extremes build: every parameter at its low end, then every one at
        // its high end (a cheap check of the corners that fail first, not every combination).
        for (end, pick) in [
            ("low", Range::low as fn(&Range) -> f64),
            ("high", Range::high),
        ] {
            super::sample::map_with(self, |_, range| pick(range))
                .and_then(|map| map.build().map(|_| ()).map_err(|e| e.to_string()))
                .map_err(|why| {
                    (
                        field("map"),
                        format!("with every parameter at the {end} end of its range: {why}"),
                    )
                })?;
        }
        Ok(())
    }

    fn check_target_and_background(&self) -> FieldCheck {
        let field = |f: &str| format!("field `{f}`");
        let t = &self.target;
        t.station
            .check("target.station", 0.0, 10_000.0)
            .map_err(|m| (field("target.station"), m))?;
        if let Some(speed) = &t.speed {
            speed
                .check("target.speed", 0.0, 60.0)
                .map_err(|m| (field("target.speed"), m))?;
        }
        t.speed_band
            .check("target.speed_band", 0.0, 1.0)
            .map_err(|m| (field("target.speed_band"), m))?;
        let bg = &self.background;
        for (name, band) in [
            ("background.headway_band", &bg.headway_band),
            ("background.speed_band", &bg.speed_band),
        ] {
            band.check(name, 0.0, 1.0).map_err(|m| (field(name), m))?;
        }
        for (name, v) in [
            ("background.behind_m", bg.behind_m),
            ("background.ahead_m", bg.ahead_m),
        ] {
            if !(0.0..=2000.0).contains(&v) {
                return Err((field(name), format!("{v} m: expected 0 to 2000 m")));
            }
        }
        if let Some(offset) = &t.lateral_offset {
            offset
                .check("target.lateral_offset", -10.0, 10.0)
                .map_err(|m| (field("target.lateral_offset"), m))?;
        }
        if let Some(error) = &t.heading_error {
            error
                .check("target.heading_error", -1.0, 1.0)
                .map_err(|m| (field("target.heading_error"), m))?;
        }
        Ok(())
    }

    fn check_heroes(&self) -> FieldCheck {
        let field = |f: &str| format!("field `{f}`");
        // A scenario without heroes is the target alone on its road (and its background): how
        // the PPO probes pose a lane-keeping task.
        for (h, hero) in self.heroes.iter().enumerate() {
            let name = format!("heroes[{h}]");
            if hero.lane.is_some() == hero.lane_offset.is_some() {
                return Err((
                    field(&name),
                    "give exactly one of `lane` and `lane_offset`".into(),
                ));
            }
            if hero.speed.is_some() == hero.speed_offset.is_some() {
                return Err((
                    field(&name),
                    "give exactly one of `speed` and `speed_offset`".into(),
                ));
            }
            hero.station_offset
                .check(&format!("{name}.station_offset"), -1000.0, 1000.0)
                .map_err(|m| (field(&name), m))?;
            if let Some(s) = &hero.speed {
                s.check(&format!("{name}.speed"), 0.0, 60.0)
                    .map_err(|m| (field(&name), m))?;
            }
            if let Some(s) = &hero.speed_offset {
                s.check(&format!("{name}.speed_offset"), -60.0, 60.0)
                    .map_err(|m| (field(&name), m))?;
            }
            if hero.phases.is_empty() {
                return Err((
                    field(&format!("{name}.phases")),
                    "a hero needs at least one phase ([[heroes.phases]])".into(),
                ));
            }
            for (p, phase) in hero.phases.iter().enumerate() {
                let pname = format!("{name}.phases[{p}]");
                phase.check(&pname).map_err(|m| (field(&pname), m))?;
            }
        }
        Ok(())
    }
}
