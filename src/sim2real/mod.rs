//! Sim-to-real: when the simulator and real recordings differ, locate the mismatch, name the
//! physics the kinematic bicycle left out, fit it by gradient descent through the unrolled
//! simulation, and show held-out error fall.
//!
//! Pipeline ([`identify`]): recordings → windows from denoised states → baseline (nominal
//! bicycle, declared wheelbase) → nominal refit (wheelbase) → one fit per catalogue effect →
//! parsimony selection on held-out tracks (pairs when one effect is not enough) → report.

pub mod a9;
mod command_checks;
pub mod command_timing;
pub mod discover;

pub mod fit;
pub mod generator;
pub mod identify;
pub mod locate;
pub mod noise;
pub mod plots;

pub mod report;
pub mod simulate;
pub mod still_open;
pub mod unexplained;
pub mod windows;

pub use crate::sim::catalogue::{DynamicsFile, Effect, FittedTerm};
pub use command_timing::{CommandTiming, TimingDecision, TimingEvidence};
pub use generator::{GeneratorConfig, SensorNoise, Uncatalogued, generate};
pub use identify::{Outcome, Sim2RealOptions, identify, thinning};
pub use report::Report;
