//! rtr: learning realistic traffic agents in closed loop (RTR, CoRL 2023) on burn.
//!
//! Data flows one way: `data` and `map` feed `scene`; the simulator, model, training and
//! evaluation build on scenes. See `README.md` for the tour.

pub mod allocator;
pub mod backend;
pub mod data;
pub mod driver;
pub mod error;
pub mod eval;
pub mod geometry;
pub mod io;
pub mod map;
pub mod model;
pub mod predict;
pub mod render;
pub mod scenario;
pub mod scene;
pub mod sim;
pub mod sim2real;
#[cfg(test)]
mod test_rng;
pub mod train;
pub mod usage;
pub mod xml;

pub use error::{Error, Result};
