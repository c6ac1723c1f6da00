//! What a vehicle is to every layer: its class, its kinematic state, and the speeds a
//! recording or a road may plausibly give it.

/// Accepted recorded speeds (m/s), for every recording format: slightly negative speeds are
/// tolerated as estimator noise; 90 m/s (324 km/h) is beyond any road vehicle in traffic.
pub const MIN_SPEED: f64 = -1.0;
pub const MAX_SPEED: f64 = 90.0;

/// Vehicle class as the recording labels it.
#[derive(Debug, Clone, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum VehicleClass {
    Car,
    Truck,
    /// Any label the recording uses that rtr does not name (kept verbatim).
    Other(String),
}

impl VehicleClass {
    pub fn from_label(label: &str) -> Self {
        match label {
            "car" => VehicleClass::Car,
            "truck" => VehicleClass::Truck,
            other => VehicleClass::Other(other.to_string()),
        }
    }
}

/// A vehicle's state at one instant. Position is the centre of the box, world frame (m);
/// `speed` and `accel` are longitudinal, in the vehicle frame (m/s, m/s^2), which is what the
/// bicycle model's `v` and `u` are.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct AgentState {
    pub x: f64,
    pub y: f64,
    pub heading: f64,
    pub speed: f64,
    pub accel: f64,
}
