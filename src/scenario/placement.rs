//! Where scenario vehicles go on rtr's procedural maps. Positions are given as a lane and a
//! station: metres along the main road from its start (through the junction of ramp maps),
//! so "20 m ahead of the target, one lane to the left" is plain arithmetic.
//!
//! Main-road lanes are numbered from the left, 1 = the fast lane. The main road is road "0" of
//! straight, curved and lane-drop maps, and roads "1", the junction's through connector and
//! "3" of ramp maps (see `map::procedural`). On-ramp stations count along the ramp back from
//! where it joins: the ramp point at station x is `merge_s - x` metres before the junction.

use std::fmt;

use serde::de::{self, Deserializer, Visitor};
use serde::{Deserialize, Serialize, Serializer};

use crate::map::{LaneType, Map};

/// A lane of a procedural map.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LaneRef {
    /// Main-road driving lane, 1 = leftmost.
    Main(usize),
    /// The on-ramp (before the junction).
    Ramp,
    /// The acceleration lane after an on-ramp.
    Accel,
    /// The deceleration lane before an off-ramp.
    Exit,
}

impl fmt::Display for LaneRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LaneRef::Main(k) => write!(f, "{k}"),
            LaneRef::Ramp => f.write_str("ramp"),
            LaneRef::Accel => f.write_str("accel"),
            LaneRef::Exit => f.write_str("exit"),
        }
    }
}

impl Serialize for LaneRef {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            LaneRef::Main(k) => s.serialize_u64(*k as u64),
            other => s.serialize_str(&other.to_string()),
        }
    }
}

/// By hand so that `lane = 2` and `lane = "ramp"` both parse, with one clear message otherwise.
impl<'de> Deserialize<'de> for LaneRef {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct LaneVisitor;
        impl Visitor<'_> for LaneVisitor {
            type Value = LaneRef;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str(
                    "a main-road lane number (1 = leftmost) or \"ramp\", \"accel\", \"exit\"",
                )
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<LaneRef, E> {
                if v >= 1 {
                    Ok(LaneRef::Main(v as usize))
                } else {
                    Err(E::invalid_value(de::Unexpected::Signed(v), &self))
                }
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<LaneRef, E> {
                self.visit_i64(v.min(i64::MAX as u64) as i64)
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<LaneRef, E> {
                match v {
                    "ramp" => Ok(LaneRef::Ramp),
                    "accel" => Ok(LaneRef::Accel),
                    "exit" => Ok(LaneRef::Exit),
                    _ => Err(E::invalid_value(de::Unexpected::Str(v), &self)),
                }
            }
        }
        d.deserialize_any(LaneVisitor)
    }
}

/// A pose on a lane centre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    pub x: f64,
    pub y: f64,
    pub heading: f64,
    /// Index into [`Map::lanes`].
    pub lane: usize,
}

/// The roads of a procedural map (none for a lanelet map, which has no main route).
fn procedural_roads(map: &Map) -> &[crate::map::Road] {
    map.opendrive().map_or(&[], |od| &od.roads)
}

/// The main road as (road id, station where it starts) pieces.
fn main_route(map: &Map) -> Vec<(String, f64)> {
    let roads = procedural_roads(map);
    let length = |id: &str| roads.iter().find(|r| r.id == id).map(|r| r.length);
    if length("0").is_some() {
        return vec![("0".into(), 0.0)];
    }
    let mut route = Vec::new();
    let mut at = 0.0;
    for id in ["1", "10", "20", "3"] {
        if let Some(len) = length(id) {
            route.push((id.to_string(), at));
            at += len;
        }
    }
    route
}

/// Main-road length (m).
pub fn main_road_length(map: &Map) -> f64 {
    let roads = procedural_roads(map);
    main_route(map)
        .last()
        .and_then(|(id, start)| roads.iter().find(|r| &r.id == id).map(|r| start + r.length))
        .unwrap_or(0.0)
}

/// The pose at `station` on `lane`; `None` when the lane does not exist there.
pub fn place(map: &Map, lane: LaneRef, station: f64) -> Option<Placement> {
    let (road_id, road_s) = match lane {
        LaneRef::Ramp => {
            let roads = procedural_roads(map);
            let ramp = roads.iter().find(|r| r.id == "2")?;
            let merge = roads.iter().find(|r| r.id == "1")?.length;
            (ramp.id.clone(), ramp.length - (merge - station))
        }
        _ => {
            let route = main_route(map);
            let (id, start) = route.iter().rev().find(|(_, start)| *start <= station)?;
            (id.clone(), station - start)
        }
    };
    // Lanes of that road covering road_s, in order from the reference line outwards.
    let mut candidates: Vec<usize> = (0..map.lanes().len())
        .filter(|&k| {
            let l = &map.lanes()[k];
            l.road_id == road_id
                && l.id < 0
                && l.is_graph_lane()
                && l.road_s.first().is_some_and(|&a| a <= road_s)
                && l.road_s.last().is_some_and(|&b| road_s <= b)
        })
        .collect();
    candidates.sort_by_key(|&k| std::cmp::Reverse(map.lanes()[k].id));
    let chosen = match lane {
        LaneRef::Main(k) => candidates
            .iter()
            .copied()
            .filter(|&c| map.lanes()[c].kind == LaneType::Driving)
            .nth(k.checked_sub(1)?)?,
        LaneRef::Accel => *candidates
            .iter()
            .find(|&&c| map.lanes()[c].kind == LaneType::Entry)?,
        LaneRef::Exit => *candidates
            .iter()
            .find(|&&c| map.lanes()[c].kind == LaneType::Exit)?,
        LaneRef::Ramp => *candidates.first()?,
    };
    let l = &map.lanes()[chosen];
    let k = l
        .road_s
        .partition_point(|&v| v <= road_s)
        .clamp(1, l.road_s.len() - 1)
        - 1;
    let span = (l.road_s[k + 1] - l.road_s[k]).max(1e-9);
    let u = ((road_s - l.road_s[k]) / span).clamp(0.0, 1.0);
    let (a, b) = (l.centerline[k], l.centerline[k + 1]);
    Some(Placement {
        x: a[0] + u * (b[0] - a[0]),
        y: a[1] + u * (b[1] - a[1]),
        heading: l.headings[k] + u * crate::geometry::wrap_angle(l.headings[k + 1] - l.headings[k]),
        lane: chosen,
    })
}

/// Number of main-road driving lanes at `station`.
pub fn main_lanes_at(map: &Map, station: f64) -> usize {
    (1..=20)
        .take_while(|&k| place(map, LaneRef::Main(k), station).is_some())
        .count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::{Layout, ProceduralMap};

    fn build(p: ProceduralMap) -> Map {
        Map::from_opendrive(&p.build().unwrap(), "t").unwrap()
    }

    #[test]
    fn main_lanes_count_from_the_left_on_one_way_and_divided_roads() {
        let map = build(ProceduralMap::Straight {
            lanes: 3,
            lane_width: 3.75,
            length: 300.0,
            layout: Layout::OneWay,
        });
        let p = place(&map, LaneRef::Main(1), 100.0).unwrap();
        assert!((p.x - 100.0).abs() < 1e-6 && (p.y + 1.875).abs() < 1e-6);
        let p = place(&map, LaneRef::Main(3), 100.0).unwrap();
        assert!((p.y + 9.375).abs() < 1e-6);
        assert!(place(&map, LaneRef::Main(4), 100.0).is_none());
        assert_eq!(main_lanes_at(&map, 100.0), 3);
        let divided = build(ProceduralMap::Straight {
            lanes: 2,
            lane_width: 3.5,
            length: 300.0,
            layout: Layout::Divided { median_width: 3.0 },
        });
        let p = place(&divided, LaneRef::Main(1), 50.0).unwrap();
        assert!((p.y + 1.5 + 1.75).abs() < 1e-6, "{p:?}");
        assert_eq!(main_lanes_at(&divided, 50.0), 2);
    }

    #[test]
    fn ramp_and_acceleration_lane_positions() {
        let map = build(ProceduralMap::preset("on_ramp_merge").unwrap());
        // merge_s = 150: the accel lane starts at station 155 (after the 5 m junction).
        let accel = place(&map, LaneRef::Accel, 200.0).unwrap();
        assert!((accel.x - 200.0).abs() < 1e-6 && (accel.y + 3.5 * 3.75).abs() < 1e-6);
        let ramp = place(&map, LaneRef::Ramp, 140.0).unwrap();
        assert!(ramp.x < 141.0 && ramp.y < -3.0 * 3.75, "{ramp:?}");
        assert!(place(&map, LaneRef::Exit, 200.0).is_none());
        assert!((main_road_length(&map) - 600.0).abs() < 1e-6);
    }
}
