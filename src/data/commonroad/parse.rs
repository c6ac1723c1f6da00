//! Reads a CommonRoad scenario XML document (formats 2020a and 2018b) into lanelets and
//! recorded obstacle trajectories. Every error names the file, the line and the element.
//!
//! What is read:
//! - `<lanelet>`: bounds (`<point><x><y>`), `<lineMarking>`, predecessor / successor /
//!   adjacentLeft / adjacentRight references (`drivingDir`), `<laneletType>`, a speed limit
//!   (2018b `<speedLimit>`, 2020a `<trafficSignRef>` to a max-speed `<trafficSign>`);
//! - dynamic obstacles (2020a `<dynamicObstacle>`, 2018b `<obstacle>` with
//!   `<role>dynamic</role>`): type, rectangle shape, `<initialState>` and `<trajectory>`
//!   states with exact position, orientation, velocity, optional acceleration and time step.
//!
//! Dynamic obstacles given as occupancy sets (set-based predictions, no recorded states) are
//! counted and skipped, as are static obstacles and the planning problems.

use roxmltree::{Document, Node};

use crate::data::track::{MAX_SPEED, MIN_SPEED};
use crate::error::{Error, Result};
use crate::map::{AdjacentLanelet, LaneType, Lanelet, RoadMark};
use crate::xml::{error_at, parse_document};

/// Format versions this reader knows.
pub const FORMAT_VERSIONS: [&str; 2] = ["2018b", "2020a"];

/// Max-speed sign ids (German catalogue 274, also used by the ZAM scenarios; US R2-1).
const MAX_SPEED_SIGNS: [&str; 3] = ["274", "R2-1", "MAX_SPEED"];

/// Obstacle types that are vehicles the simulator can drive.
pub const VEHICLE_TYPES: [&str; 7] = [
    "car",
    "truck",
    "bus",
    "motorcycle",
    "priorityVehicle",
    "taxi",
    "parkedVehicle",
];

/// The other obstacle types of the 2018b and 2020a formats (read and skipped).
const OTHER_OBSTACLE_TYPES: [&str; 10] = [
    "bicycle",
    "pedestrian",
    "train",
    "constructionZone",
    "roadBoundary",
    "building",
    "pillar",
    "median_strip",
    "medianStrip",
    "unknown",
];

/// One recorded state of an obstacle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObstacleState {
    pub step: i64,
    /// Centre of the obstacle's shape (m).
    pub x: f64,
    pub y: f64,
    pub orientation: f64,
    pub velocity: f64,
    pub acceleration: Option<f64>,
}

/// A dynamic obstacle with its recorded states, in time order.
#[derive(Debug, Clone, PartialEq)]
pub struct Obstacle {
    pub id: String,
    pub kind: String,
    pub length: f64,
    pub width: f64,
    pub states: Vec<ObstacleState>,
}

/// What one file holds.
#[derive(Debug, Clone, PartialEq)]
pub struct CommonRoadDocument {
    pub benchmark_id: String,
    pub version: String,
    /// Seconds per time step.
    pub time_step: f64,
    pub lanelets: Vec<Lanelet>,
    /// Dynamic vehicles with recorded trajectories.
    pub vehicles: Vec<Obstacle>,
    /// Dynamic obstacles left out: (type or reason, count).
    pub skipped: Vec<(String, usize)>,
}

/// A lanelet's widest point must lie in this range (m): a tapering lane may narrow to 0 at an
/// end, but a lane never wider than 0.5 m or wider than a whole carriageway is not one.
const MIN_LANELET_WIDTH_M: f64 = 0.5;
const MAX_LANELET_WIDTH_M: f64 = 20.0;

/// The largest distance from a point of `left` to the polyline `right` (m).
fn widest_gap(left: &[[f64; 2]], right: &[[f64; 2]]) -> f64 {
    let to_segment = |p: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let len2 = dx * dx + dy * dy;
        let u = if len2 > 0.0 {
            (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (p[0] - a[0] - u * dx).hypot(p[1] - a[1] - u * dy)
    };
    left.iter()
        .map(|&p| match right {
            [only] => (p[0] - only[0]).hypot(p[1] - only[1]),
            _ => right
                .windows(2)
                .map(|w| to_segment(p, w[0], w[1]))
                .fold(f64::INFINITY, f64::min),
        })
        .fold(0.0, f64::max)
}

/// Cars a file needs before its median car length is judged.
const MIN_CARS_FOR_MEDIAN: usize = 5;
/// Longest plausible median car of a recording (m).
const MAX_MEDIAN_CAR_M: f64 = 7.0;

struct Reader<'a> {
    doc: &'a Document<'a>,
    source: &'a str,
}

/// Parses the text of a CommonRoad file; `source` names it in errors.
pub fn parse_commonroad(text: &str, source: &str) -> Result<CommonRoadDocument> {
    let doc = parse_document(text, source)?;
    Reader { doc: &doc, source }.document()
}

impl<'a> Reader<'a> {
    fn err(&self, node: Node, message: impl Into<String>) -> Error {
        error_at(self.doc, self.source, node, message)
    }

    fn document(&self) -> Result<CommonRoadDocument> {
        let root = self.doc.root_element();
        if root.tag_name().name() != "commonRoad" {
            return Err(self.err(
                root,
                format!(
                    "root element is <{}>, expected <commonRoad>",
                    root.tag_name().name()
                ),
            ));
        }
        let version = root.attribute("commonRoadVersion").unwrap_or("");
        if !FORMAT_VERSIONS.contains(&version) {
            return Err(self.err(
                root,
                format!(
                    "commonRoadVersion `{version}` is not supported, expected one of {}",
                    FORMAT_VERSIONS.join(", ")
                ),
            ));
        }
        let time_step = self.attribute_number(root, "timeStepSize")?;
        if !(time_step > 0.0 && time_step <= 10.0) {
            return Err(self.err(
                root,
                format!("timeStepSize {time_step} s, expected a positive step of at most 10 s"),
            ));
        }
        let signs = self.speed_signs(root)?;
        let mut lanelets = Vec::new();
        let mut vehicles = Vec::new();
        let mut skipped: Vec<(String, usize)> = Vec::new();
        let mut skip = |what: &str| match skipped.iter_mut().find(|(k, _)| k == what) {
            Some((_, n)) => *n += 1,
            None => skipped.push((what.to_string(), 1)),
        };
        let mut car_nodes = Vec::new();
        for node in root.children().filter(Node::is_element) {
            let dynamic = match node.tag_name().name() {
                "lanelet" => {
                    lanelets.push(self.lanelet(node, &signs)?);
                    false
                }
                "dynamicObstacle" => true,
                "obstacle" => self.child_text(node, "role") == Some("dynamic"),
                _ => false,
            };
            if dynamic && let Some(o) = self.obstacle(node, &mut skip)? {
                self.check_motion(node, &o, time_step)?;
                if vehicles.iter().any(|v: &Obstacle| v.id == o.id) {
                    return Err(self.err(
                        node,
                        format!("obstacle id {} is used twice, expected unique ids", o.id),
                    ));
                }
                if o.kind == "car" {
                    car_nodes.push((o.length, node));
                }
                vehicles.push(o);
            }
        }
        self.check_car_lengths(&mut car_nodes)?;
        Ok(CommonRoadDocument {
            benchmark_id: root.attribute("benchmarkID").unwrap_or("").to_string(),
            version: version.to_string(),
            time_step,
            lanelets,
            vehicles,
            skipped,
        })
    }

    /// The file's cars are car-sized as a whole: one recorded car may be 14 m long (NGSIM has
    /// such errors), but a median car above [`MAX_MEDIAN_CAR_M`] means lengths in another unit
    /// (feet: a 4.5 m car reads 14.8). The error points at the first car of median length.
    fn check_car_lengths(&self, cars: &mut [(f64, Node)]) -> Result<()> {
        if cars.len() < MIN_CARS_FOR_MEDIAN {
            return Ok(());
        }
        cars.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (median, node) = cars[cars.len() / 2];
        if median <= MAX_MEDIAN_CAR_M {
            return Ok(());
        }
        Err(self.err(
            node,
            format!(
                "the median car of this file is {median} m long, expected at most \
                 {MAX_MEDIAN_CAR_M} m (real cars are 3.5-5.5 m): are the lengths in feet \
                 (1 ft = 0.3048 m)?"
            ),
        ))
    }

    /// An obstacle's velocities and orientations agree with how its positions move (so
    /// km/h or degrees are refused, not simulated).
    fn check_motion(&self, node: Node, o: &Obstacle, time_step: f64) -> Result<()> {
        let column = |f: fn(&ObstacleState) -> f64| o.states.iter().map(f).collect::<Vec<_>>();
        crate::data::motion::check(
            time_step,
            &column(|s| s.x),
            &column(|s| s.y),
            &column(|s| s.orientation),
            &column(|s| s.velocity),
        )
        .map_err(|mismatch| {
            let field = match mismatch.column() {
                "speed" => "velocity",
                _ => "orientation",
            };
            self.err(node, format!("obstacle {}: <{field}>: {mismatch}", o.id))
        })
    }

    /// Max speed (m/s) of each 2020a traffic sign that sets one, by sign id.
    fn speed_signs(&self, root: Node) -> Result<Vec<(String, f64)>> {
        let mut signs = Vec::new();
        for sign in root.children().filter(|n| n.has_tag_name("trafficSign")) {
            let id = self.id(sign)?;
            for element in sign
                .children()
                .filter(|n| n.has_tag_name("trafficSignElement"))
            {
                let sign_id = self.child_text(element, "trafficSignID").unwrap_or("");
                if !MAX_SPEED_SIGNS.contains(&sign_id) {
                    continue;
                }
                let speed = self.speed_limit(self.required(element, "additionalValue")?)?;
                signs.push((id.to_string(), speed));
            }
        }
        Ok(signs)
    }

    fn lanelet(&self, node: Node, signs: &[(String, f64)]) -> Result<Lanelet> {
        let id = self.id(node)?.to_string();
        let (left_bound, left_mark) = self.bound(self.required(node, "leftBound")?)?;
        let (right_bound, right_mark) = self.bound(self.required(node, "rightBound")?)?;
        let widest = widest_gap(&left_bound, &right_bound);
        if !(MIN_LANELET_WIDTH_M..=MAX_LANELET_WIDTH_M).contains(&widest) {
            return Err(self.err(
                node,
                format!(
                    "lanelet {id} is {widest:.2} m wide at its widest, expected a lane \
                     {MIN_LANELET_WIDTH_M}-{MAX_LANELET_WIDTH_M} m wide (bounds swapped, \
                     copied or in another unit?)"
                ),
            ));
        }
        let refs = |tag: &str| -> Result<Vec<String>> {
            node.children()
                .filter(|n| n.has_tag_name(tag))
                .map(|n| self.reference(n).map(str::to_string))
                .collect()
        };
        let adjacent = |tag: &str| -> Result<Option<AdjacentLanelet>> {
            let Some(n) = node.children().find(|n| n.has_tag_name(tag)) else {
                return Ok(None);
            };
            let same_direction = match n.attribute("drivingDir") {
                Some("same") => true,
                Some("opposite") => false,
                other => {
                    return Err(self.err(
                        n,
                        format!(
                            "<{tag}> drivingDir is {other:?}, expected \"same\" or \"opposite\""
                        ),
                    ));
                }
            };
            Ok(Some(AdjacentLanelet {
                id: self.reference(n)?.to_string(),
                same_direction,
            }))
        };
        let types: Vec<Node> = node
            .children()
            .filter(|n| n.has_tag_name("laneletType"))
            .collect();
        let kind = self.lane_type(&types)?;
        let mut speed_limit = None;
        if let Some(limit) = node.children().find(|n| n.has_tag_name("speedLimit")) {
            speed_limit = Some(self.speed_limit(limit)?);
        }
        for sign_ref in node.children().filter(|n| n.has_tag_name("trafficSignRef")) {
            let target = self.reference(sign_ref)?;
            if let Some((_, speed)) = signs.iter().find(|(id, _)| id == target) {
                speed_limit = Some(*speed);
            }
        }
        Ok(Lanelet {
            id,
            left_bound,
            right_bound,
            left_mark,
            right_mark,
            predecessors: refs("predecessor")?,
            successors: refs("successor")?,
            adjacent_left: adjacent("adjacentLeft")?,
            adjacent_right: adjacent("adjacentRight")?,
            kind,
            speed_limit,
        })
    }

    /// A speed limit (m/s): positive, at most [`MAX_SPEED`].
    fn speed_limit(&self, node: Node) -> Result<f64> {
        let v = self.number(node)?;
        if !(v > 0.0 && v <= MAX_SPEED) {
            return Err(self.err(
                node,
                format!("speed limit {v} m/s, expected 0-{MAX_SPEED} m/s"),
            ));
        }
        Ok(v)
    }

    fn bound(&self, node: Node) -> Result<(Vec<[f64; 2]>, RoadMark)> {
        let points = node
            .children()
            .filter(|n| n.has_tag_name("point"))
            .map(|p| self.point(p))
            .collect::<Result<Vec<_>>>()?;
        let mark = match node.children().find(|n| n.has_tag_name("lineMarking")) {
            None => RoadMark::Other("unspecified".into()),
            Some(m) => match m.text().unwrap_or("").trim() {
                "solid" | "broad_solid" => RoadMark::Solid,
                "dashed" | "broad_dashed" => RoadMark::Broken,
                "no_marking" => RoadMark::None,
                "unknown" => RoadMark::Other("unknown".into()),
                other => {
                    return Err(self.err(
                        m,
                        format!(
                            "lineMarking `{other}`, expected solid, dashed, broad_solid, \
                             broad_dashed, no_marking or unknown"
                        ),
                    ));
                }
            },
        };
        Ok((points, mark))
    }

    /// The most specific of a lanelet's types: a lane vehicles may not use, else a shoulder,
    /// else a ramp, else a driving lane (also when the file gives no type, as 2018b files do).
    fn lane_type(&self, types: &[Node]) -> Result<LaneType> {
        let mut best = (0, LaneType::Driving);
        for node in types {
            let name = node.text().unwrap_or("").trim();
            let (rank, kind) = match name {
                "urban" | "country" | "highway" | "interstate" | "mainCarriageWay" | "driveWay"
                | "intersection" | "unknown" => (0, LaneType::Driving),
                "accessRamp" => (1, LaneType::OnRamp),
                "exitRamp" => (1, LaneType::OffRamp),
                "shoulder" => (2, LaneType::Shoulder),
                // Buses drive in bus lanes: a recorded bus there is on the road.
                "busLane" => (0, LaneType::Driving),
                "busStop" | "restricted" => (3, LaneType::Restricted),
                "parking" => (3, LaneType::Parking),
                "border" => (3, LaneType::Border),
                "bicycleLane" => (3, LaneType::Biking),
                "sidewalk" | "crosswalk" => (3, LaneType::Sidewalk),
                other => {
                    return Err(self.err(*node, format!("unknown laneletType `{other}`")));
                }
            };
            if rank > best.0 {
                best = (rank, kind);
            }
        }
        Ok(best.1)
    }

    /// A dynamic obstacle's vehicle track; `None` (counted in `skip`) for non-vehicles and
    /// obstacles without recorded states.
    fn obstacle(&self, node: Node, skip: &mut impl FnMut(&str)) -> Result<Option<Obstacle>> {
        let id = self.id(node)?.to_string();
        let type_node = self.required(node, "type")?;
        let kind = type_node.text().unwrap_or("").trim().to_string();
        let kind_str = kind.as_str();
        if !VEHICLE_TYPES.contains(&kind_str) && !OTHER_OBSTACLE_TYPES.contains(&kind_str) {
            return Err(self.err(type_node, format!("unknown obstacle type `{kind}`")));
        }
        if !VEHICLE_TYPES.contains(&kind_str) {
            skip(&kind);
            return Ok(None);
        }
        let shape = self.required(node, "shape")?;
        let Some(rect) = shape.children().find(|n| n.has_tag_name("rectangle")) else {
            let found = shape
                .children()
                .find(Node::is_element)
                .map_or("nothing".to_string(), |n| {
                    format!("<{}>", n.tag_name().name())
                });
            return Err(self.err(
                shape,
                format!("obstacle {id}: shape is {found}, expected a <rectangle>"),
            ));
        };
        let length = self.number(self.required(rect, "length")?)?;
        let width = self.number(self.required(rect, "width")?)?;
        if !(1.0..=25.0).contains(&length) || !(0.5..=5.0).contains(&width) {
            return Err(self.err(
                rect,
                format!(
                    "obstacle {id}: rectangle {length} x {width} m, expected a vehicle 1-25 m \
                     long and 0.5-5 m wide"
                ),
            ));
        }
        let Some(trajectory) = node.children().find(|n| n.has_tag_name("trajectory")) else {
            skip("no recorded trajectory (occupancy set or initial state only)");
            return Ok(None);
        };
        let mut states = Vec::new();
        if let Some(initial) = node.children().find(|n| n.has_tag_name("initialState")) {
            states.push((initial, self.state(initial, &id)?));
        }
        for state in trajectory.children().filter(|n| n.has_tag_name("state")) {
            states.push((state, self.state(state, &id)?));
        }
        if states.is_empty() {
            skip("no recorded trajectory (occupancy set or initial state only)");
            return Ok(None);
        }
        for w in states.windows(2) {
            let (prev, (node, next)) = (w[0].1, w[1]);
            if next.step <= prev.step {
                return Err(self.err(
                    node,
                    format!(
                        "obstacle {id}: time step {} follows {}; time must increase",
                        next.step, prev.step
                    ),
                ));
            }
            if next.step != prev.step + 1 {
                return Err(self.err(
                    node,
                    format!(
                        "obstacle {id}: time gap from step {} to {} (states must be consecutive)",
                        prev.step, next.step
                    ),
                ));
            }
        }
        Ok(Some(Obstacle {
            id,
            kind,
            length,
            width,
            states: states.into_iter().map(|(_, s)| s).collect(),
        }))
    }

    fn state(&self, node: Node, obstacle: &str) -> Result<ObstacleState> {
        let fail = |message: String| Err(self.err(node, format!("obstacle {obstacle}: {message}")));
        let position = self.required(node, "position")?;
        let Some(point) = position.children().find(|n| n.has_tag_name("point")) else {
            return Err(self.err(
                position,
                "position is a region, expected an exact <point> (recorded states only)",
            ));
        };
        let [x, y] = self.point(point)?;
        let step = self.exact(self.required(node, "time")?)?;
        if step.fract() != 0.0 || !(0.0..=1e9).contains(&step) {
            return fail(format!(
                "<time> {step}, expected a non-negative integer step"
            ));
        }
        let orientation = self.exact(self.required(node, "orientation")?)?;
        if orientation.abs() > 100.0 {
            return fail(format!("<orientation> {orientation}, expected radians"));
        }
        let velocity = self.exact(self.required(node, "velocity")?)?;
        if !(MIN_SPEED..=MAX_SPEED).contains(&velocity) {
            return fail(format!(
                "<velocity> {velocity} m/s, expected {MIN_SPEED} to {MAX_SPEED} m/s"
            ));
        }
        let acceleration = match node.children().find(|n| n.has_tag_name("acceleration")) {
            Some(a) => Some(self.exact(a)?),
            None => None,
        };
        if acceleration.is_some_and(|a| a.abs() > 30.0) {
            return fail(format!(
                "<acceleration> {} m/s^2, expected at most 30 m/s^2 in size",
                acceleration.unwrap_or_default()
            ));
        }
        Ok(ObstacleState {
            step: step as i64,
            x,
            y,
            orientation,
            velocity,
            acceleration,
        })
    }

    /// The `<exact>` value of a state variable; an interval is an error (not a recording).
    fn exact(&self, node: Node) -> Result<f64> {
        match node.children().find(|n| n.has_tag_name("exact")) {
            Some(e) => self.number(e),
            None => Err(self.err(
                node,
                format!(
                    "<{}> has no <exact> value (intervals describe goals, not recordings)",
                    node.tag_name().name()
                ),
            )),
        }
    }

    fn point(&self, node: Node) -> Result<[f64; 2]> {
        let x = self.number(self.required(node, "x")?)?;
        let y = self.number(self.required(node, "y")?)?;
        Ok([x, y])
    }

    fn number(&self, node: Node) -> Result<f64> {
        let text = node.text().unwrap_or("").trim();
        match text.parse::<f64>() {
            Ok(v) if v.is_finite() && v.abs() <= 1e7 => Ok(v),
            _ => Err(self.err(
                node,
                format!(
                    "<{}> is `{text}`, expected a finite number of magnitude at most 1e7",
                    node.tag_name().name()
                ),
            )),
        }
    }

    fn attribute_number(&self, node: Node, name: &str) -> Result<f64> {
        let text = node.attribute(name).unwrap_or("");
        text.parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| {
                self.err(
                    node,
                    format!("attribute {name} is `{text}`, expected a number"),
                )
            })
    }

    fn id<'n>(&self, node: Node<'n, 'n>) -> Result<&'n str> {
        node.attribute("id")
            .filter(|id| !id.is_empty())
            .ok_or_else(|| self.err(node, format!("<{}> has no id", node.tag_name().name())))
    }

    fn reference<'n>(&self, node: Node<'n, 'n>) -> Result<&'n str> {
        node.attribute("ref")
            .filter(|id| !id.is_empty())
            .ok_or_else(|| self.err(node, format!("<{}> has no ref", node.tag_name().name())))
    }

    fn required<'n>(&self, node: Node<'n, 'n>, tag: &str) -> Result<Node<'n, 'n>> {
        node.children()
            .find(|n| n.has_tag_name(tag))
            .ok_or_else(|| self.err(node, format!("<{}> has no <{tag}>", node.tag_name().name())))
    }

    fn child_text<'n>(&self, node: Node<'n, 'n>, tag: &str) -> Option<&'n str> {
        node.children()
            .find(|n| n.has_tag_name(tag))
            .and_then(|n| n.text())
            .map(str::trim)
    }
}
