//! Procedural highway maps. Each generator produces an [`OpenDrive`] (so generated maps take
//! the same path as real ones through [`Map::from_opendrive`](super::Map::from_opendrive), and
//! can be written with [`to_xodr`](super::to_xodr) and opened in any OpenDRIVE viewer).
//!
//! Layout conventions: a carriageway lies right of its reference line (right-hand traffic,
//! lanes -1, -2, ... travel along +s), driving lanes are separated by broken marks, the
//! outermost driving lane has a solid outer mark, and a shoulder runs along the outside.
//! Ramp and lane-drop maps are one-way; straight and curved roads can also be A9-like divided
//! roads (two carriageways around a median of type `none`).

use serde::{Deserialize, Serialize};

use super::number_text::Num;
use super::opendrive::{GeometryKind, Lane, LaneType, OpenDrive, RoadMark};
use super::procedural_parts::{carriageway, center_lane, chain, constant, lane, road, section};
use super::procedural_ramps::{lane_drop_map, off_ramp_map, on_ramp_map};
use crate::{Error, Result};

/// Width of the shoulder outside each carriageway (m).
pub const SHOULDER_WIDTH: f64 = 2.5;
/// Speed limit written into generated roads (120 km/h in m/s).
pub const PROCEDURAL_SPEED_LIMIT: f64 = 120.0 / 3.6;
/// Length of the connecting roads inside generated junctions (m).
pub const JUNCTION_LENGTH: f64 = 5.0;

/// Cross-section of straight and curved roads.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum Layout {
    /// One carriageway; all lanes travel along the reference line.
    #[default]
    OneWay,
    /// Two carriageways (`lanes` each) separated by a median of type `none`, like the A9.
    Divided { median_width: f64 },
}

/// Parameters of one generated map; lengths in metres, curvature in 1/m.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ProceduralMap {
    Straight {
        lanes: usize,
        lane_width: f64,
        length: f64,
        #[serde(default)]
        layout: Layout,
    },
    /// Line, clothoid into an arc of `curvature`, clothoid out, line.
    Curve {
        lanes: usize,
        lane_width: f64,
        length: f64,
        curvature: f64,
        #[serde(default)]
        layout: Layout,
    },
    /// A ramp road joins at `merge_s` through a junction into an acceleration lane that runs
    /// `accel_lane_length` and then tapers to zero width over `taper_length`.
    OnRampMerge {
        lanes: usize,
        lane_width: f64,
        length: f64,
        merge_s: f64,
        accel_lane_length: f64,
        taper_length: f64,
    },
    /// An exit lane opens over `taper_length`, runs `decel_lane_length`, and at `diverge_s` a
    /// junction forks it onto a ramp road curving away from the main road.
    OffRampFork {
        lanes: usize,
        lane_width: f64,
        length: f64,
        diverge_s: f64,
        decel_lane_length: f64,
        taper_length: f64,
    },
    /// The rightmost lane tapers to zero width over `taper_length` from `drop_s`.
    LaneDrop {
        lanes: usize,
        lane_width: f64,
        length: f64,
        drop_s: f64,
        taper_length: f64,
    },
}

pub fn straight(lanes: usize, lane_width: f64, length: f64) -> Result<OpenDrive> {
    ProceduralMap::Straight {
        lanes,
        lane_width,
        length,
        layout: Layout::OneWay,
    }
    .build()
}

pub fn curve(lanes: usize, lane_width: f64, length: f64, curvature: f64) -> Result<OpenDrive> {
    ProceduralMap::Curve {
        lanes,
        lane_width,
        length,
        curvature,
        layout: Layout::OneWay,
    }
    .build()
}

pub fn on_ramp_merge(
    lanes: usize,
    lane_width: f64,
    length: f64,
    merge_s: f64,
    accel_lane_length: f64,
    taper_length: f64,
) -> Result<OpenDrive> {
    ProceduralMap::OnRampMerge {
        lanes,
        lane_width,
        length,
        merge_s,
        accel_lane_length,
        taper_length,
    }
    .build()
}

pub fn off_ramp_fork(
    lanes: usize,
    lane_width: f64,
    length: f64,
    diverge_s: f64,
    decel_lane_length: f64,
    taper_length: f64,
) -> Result<OpenDrive> {
    ProceduralMap::OffRampFork {
        lanes,
        lane_width,
        length,
        diverge_s,
        decel_lane_length,
        taper_length,
    }
    .build()
}

pub fn lane_drop(
    lanes: usize,
    lane_width: f64,
    length: f64,
    drop_s: f64,
    taper_length: f64,
) -> Result<OpenDrive> {
    ProceduralMap::LaneDrop {
        lanes,
        lane_width,
        length,
        drop_s,
        taper_length,
    }
    .build()
}

fn bad(message: String) -> Error {
    Error::InvalidArgument(message)
}

fn positive(name: &str, v: f64) -> Result<()> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(bad(format!(
            "procedural map: {name} is {v}, expected a positive number",
            v = Num(v)
        )))
    }
}

fn check_common(lanes: usize, min_lanes: usize, lane_width: f64, length: f64) -> Result<()> {
    if lanes < min_lanes || lanes > 20 {
        return Err(bad(format!(
            "procedural map: lanes is {lanes}, expected {min_lanes} to 20"
        )));
    }
    if !(MIN_LANE_WIDTH..=10.0).contains(&lane_width) {
        return Err(bad(format!(
            "procedural map: lane_width is {lane_width} m, expected a driving lane \
             {MIN_LANE_WIDTH}-10 m wide",
            lane_width = Num(lane_width)
        )));
    }
    if !(MIN_LENGTH..=crate::map::MAX_ROAD_LENGTH).contains(&length) {
        return Err(bad(format!(
            "procedural map: length is {length} m, expected {MIN_LENGTH} to {} m",
            crate::map::MAX_ROAD_LENGTH,
            length = Num(length)
        )));
    }
    Ok(())
}

/// Narrowest generated driving lane (m).
const MIN_LANE_WIDTH: f64 = 2.0;
/// Shortest generated road (m): room for a few vehicles.
const MIN_LENGTH: f64 = 20.0;
/// Shortest lane that opens or ends (a taper) or an auxiliary lane (m).
const MIN_TRANSITION: f64 = 10.0;
/// Widest median of a divided road (m).
const MAX_MEDIAN: f64 = 50.0;

/// Checks that `parts` (name, value) are positive and end before `length`.
fn check_fits(length: f64, parts: &[(&str, f64)]) -> Result<()> {
    for (name, v) in parts {
        positive(name, *v)?;
        // A lane that appears, ends or runs alongside over a few centimetres is no lane.
        if (name.contains("taper") || name.contains("lane_length")) && *v < MIN_TRANSITION {
            return Err(bad(format!(
                "procedural map: {name} is {v} m, expected at least {MIN_TRANSITION} m",
                v = Num(*v)
            )));
        }
    }
    let total: f64 = parts.iter().map(|p| p.1).sum();
    if total >= length {
        let names: Vec<&str> = parts.iter().map(|p| p.0).collect();
        return Err(bad(format!(
            "procedural map: {} add up to {total} m, expected less than length {length} m",
            names.join(" + "),
            total = Num(total),
            length = Num(length)
        )));
    }
    Ok(())
}

/// Names accepted by [`ProceduralMap::preset`].
pub const PRESET_NAMES: [&str; 5] = [
    "straight",
    "curve",
    "on_ramp_merge",
    "off_ramp_fork",
    "lane_drop",
];

impl ProceduralMap {
    /// A three-lane motorway example of each kind (3.75 m lanes, German motorway widths), for
    /// the command line and as a starting point for scenario families.
    pub fn preset(name: &str) -> Result<ProceduralMap> {
        let (lanes, lane_width) = (3, 3.75);
        Ok(match name {
            "straight" => ProceduralMap::Straight {
                lanes,
                lane_width,
                length: 400.0,
                layout: Layout::OneWay,
            },
            "curve" => ProceduralMap::Curve {
                lanes,
                lane_width,
                length: 500.0,
                curvature: 1.0 / 800.0,
                layout: Layout::OneWay,
            },
            "on_ramp_merge" => ProceduralMap::OnRampMerge {
                lanes,
                lane_width,
                length: 600.0,
                merge_s: 150.0,
                accel_lane_length: 200.0,
                taper_length: 60.0,
            },
            "off_ramp_fork" => ProceduralMap::OffRampFork {
                lanes,
                lane_width,
                length: 600.0,
                diverge_s: 300.0,
                decel_lane_length: 150.0,
                taper_length: 60.0,
            },
            "lane_drop" => ProceduralMap::LaneDrop {
                lanes,
                lane_width,
                length: 500.0,
                drop_s: 200.0,
                taper_length: 100.0,
            },
            other => {
                return Err(Error::InvalidArgument(format!(
                    "unknown procedural map `{other}`: expected one of {}",
                    PRESET_NAMES.join(", ")
                )));
            }
        })
    }

    /// Validates the parameters and generates the map.
    pub fn build(&self) -> Result<OpenDrive> {
        match *self {
            ProceduralMap::Straight {
                lanes,
                lane_width,
                length,
                layout,
            } => {
                check_common(lanes, 1, lane_width, length)?;
                check_layout(layout, lanes, lane_width)?;
                Ok(single_road(
                    length,
                    vec![(length, GeometryKind::Line)],
                    lanes,
                    lane_width,
                    layout,
                ))
            }
            ProceduralMap::Curve {
                lanes,
                lane_width,
                length,
                curvature,
                layout,
            } => curve_map(lanes, lane_width, length, curvature, layout),
            ProceduralMap::OnRampMerge {
                lanes,
                lane_width,
                length,
                merge_s,
                accel_lane_length,
                taper_length,
            } => {
                check_common(lanes, 1, lane_width, length)?;
                check_fits(
                    length,
                    &[
                        ("merge_s", merge_s),
                        ("accel_lane_length", accel_lane_length),
                        ("taper_length", taper_length),
                    ],
                )?;
                Ok(on_ramp_map(
                    lanes,
                    lane_width,
                    length,
                    merge_s,
                    accel_lane_length,
                    taper_length,
                ))
            }
            ProceduralMap::OffRampFork {
                lanes,
                lane_width,
                length,
                diverge_s,
                decel_lane_length,
                taper_length,
            } => {
                check_common(lanes, 1, lane_width, length)?;
                positive("diverge_s", diverge_s)?;
                check_fits(
                    diverge_s,
                    &[
                        ("decel_lane_length", decel_lane_length),
                        ("taper_length", taper_length),
                    ],
                )?;
                if diverge_s + JUNCTION_LENGTH >= length {
                    return Err(bad(format!(
                        "procedural map: diverge_s {diverge_s} m leaves no road after the junction, expected \
                         less than length - {JUNCTION_LENGTH} m",
                        diverge_s = Num(diverge_s)
                    )));
                }
                Ok(off_ramp_map(
                    lanes,
                    lane_width,
                    length,
                    diverge_s,
                    decel_lane_length,
                    taper_length,
                ))
            }
            ProceduralMap::LaneDrop {
                lanes,
                lane_width,
                length,
                drop_s,
                taper_length,
            } => {
                check_common(lanes, 2, lane_width, length)?;
                check_fits(
                    length,
                    &[("drop_s", drop_s), ("taper_length", taper_length)],
                )?;
                Ok(lane_drop_map(
                    lanes,
                    lane_width,
                    length,
                    drop_s,
                    taper_length,
                ))
            }
        }
    }
}

/// A road that bends through clothoid - arc - clothoid between two straights.
fn curve_map(
    lanes: usize,
    lane_width: f64,
    length: f64,
    curvature: f64,
    layout: Layout,
) -> Result<OpenDrive> {
    check_common(lanes, 1, lane_width, length)?;
    let width = check_layout(layout, lanes, lane_width)?;
    if !curvature.is_finite() || curvature.abs() * width >= 0.5 {
        return Err(bad(format!(
            "procedural map: curvature {curvature} 1/m is too tight for a {width} m wide road \
                 (expected |curvature| * width < 0.5)",
            curvature = Num(curvature),
            width = Num(width)
        )));
    }
    // The arc and the two clothoids turn the road by 0.45 * length * curvature.
    let turn = 0.45 * length * curvature.abs();
    if turn > std::f64::consts::PI {
        return Err(bad(format!(
            "procedural map: curvature {curvature} 1/m over {length} m turns the road by \
                 {turn:.2} rad, so it would cross itself; expected at most pi",
            curvature = Num(curvature),
            length = Num(length),
            turn = Num(turn)
        )));
    }
    let k = curvature;
    let pieces = vec![
        (0.2 * length, GeometryKind::Line),
        (
            0.15 * length,
            GeometryKind::Spiral {
                curv_start: 0.0,
                curv_end: k,
            },
        ),
        (0.3 * length, GeometryKind::Arc { curvature: k }),
        (
            0.15 * length,
            GeometryKind::Spiral {
                curv_start: k,
                curv_end: 0.0,
            },
        ),
        (0.2 * length, GeometryKind::Line),
    ];
    Ok(single_road(length, pieces, lanes, lane_width, layout))
}

/// Validates the layout; returns the total road width (m).
fn check_layout(layout: Layout, lanes: usize, lane_width: f64) -> Result<f64> {
    let side = lanes as f64 * lane_width + SHOULDER_WIDTH;
    match layout {
        Layout::OneWay => Ok(side),
        Layout::Divided { median_width } => {
            positive("median_width", median_width)?;
            if median_width > MAX_MEDIAN {
                return Err(bad(format!(
                    "procedural map: median_width is {median_width} m, expected at most {MAX_MEDIAN} m",
                    median_width = Num(median_width)
                )));
            }
            Ok(2.0 * side + median_width)
        }
    }
}

fn single_road(
    length: f64,
    pieces: Vec<(f64, GeometryKind)>,
    lanes: usize,
    w: f64,
    layout: Layout,
) -> OpenDrive {
    let mut section = section(0.0, RoadMark::Solid, carriageway(lanes, w, 0));
    if let Layout::Divided { median_width } = layout {
        section.center = Some(center_lane(RoadMark::None));
        let mut right = vec![lane(
            -1,
            LaneType::None,
            constant(0.5 * median_width),
            RoadMark::Solid,
        )];
        right.extend(carriageway(lanes, w, 1));
        section.left = right.iter().map(mirrored).collect();
        section.right = right;
    }
    OpenDrive {
        roads: vec![road(
            "0",
            length,
            chain([0.0, 0.0, 0.0], &pieces),
            vec![section],
        )],
        junctions: vec![],
    }
}

/// The same lane on the other side of the reference line (positive id).
fn mirrored(l: &Lane) -> Lane {
    let mut m = l.clone();
    m.id = -l.id;
    m
}
