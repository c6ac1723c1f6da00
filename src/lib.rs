//! rtr: learning realistic traffic agents in closed loop (RTR, CoRL 2023) on burn.
//!
//! Data flows one way: `data` and `map` feed `scene`; the simulator, model, training and
//! evaluation build on scenes. See `README.md` for the tour.

pub mod error;
pub mod geometry;
pub mod map;

pub use error::{Error, Result};
