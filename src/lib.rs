//! rtr: learning realistic traffic agents in closed loop (RTR, CoRL 2023) on burn.
//!
//! Data flows one way. The modules stand in layers, lowest first, and a module uses only
//! modules of its own layer or a lower one (`tests/structure.rs` reads this list and `src/`, and
//! fails on an upward `crate::` path). See `README.md` for the tour.
//!
//! 1. `error`, `io`, `xml`, `geometry`, `vehicle`, `agent_view`, `seeding`, `usage`,
//!    `allocator`, `backend`, `test_rng`: foundations;
//! 2. `map`: roads (OpenDRIVE) and their lane graph;
//! 3. `scene`: a map with the agents of one time window, and batches of scenes as tensors;
//! 4. `data`: recordings (AUTOMATUM A9, CommonRoad, CSV) read and cut into scenes;
//! 5. `sim`, `render`: the batched simulator; maps and rollouts drawn;
//! 6. `driver`, `sim2real`: rule-based drivers; physics identified from recordings;
//! 7. `model`: the policy and value networks;
//! 8. `scenario`: long-tail scenario families;
//! 9. `train`: every method's training loop;
//! 10. `eval`: closed-loop evaluation and its metrics;
//! 11. `predict`: downstream motion predictors;
//! 12. `studies`: studies that train and then evaluate (the sweep, downstream prediction).

pub mod agent_view;
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
pub mod seeding;
pub mod sim;
pub mod sim2real;
pub mod studies;
#[cfg(test)]
mod test_rng;
pub mod train;
pub mod usage;
pub mod vehicle;
pub mod xml;

pub use error::{Error, Result};
