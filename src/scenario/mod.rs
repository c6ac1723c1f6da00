//! Long-tail scenarios (paper section 3.4): logical scenario families as TOML data, hero
//! behaviours as composable scripts, seeded concrete sampling validated against the IDM
//! reference driver, and the default train / eval / OOD sets.
//!
//! This module sits above the simulator: hero scripts are simulator policies and validation
//! runs a rollout.

mod behaviour;
mod catalogue;
mod concrete;
mod family;
mod hero;
mod labels;
mod placement;
mod range;
mod sample;
mod scripted_rollout;
mod set_folder;

pub use behaviour::{Action, Direction, Phase, Trigger};
pub use catalogue::{
    DEFAULT_SEED, GenerateConfig, GeneratedSets, builtin_families, family_seed, generate_sets,
    load_families,
};
pub use concrete::{
    ConcreteScenario, ReferenceRun, ScenarioAgent, ScenarioHero, ScenarioSet, hero_scripts,
};
pub use family::{
    BackgroundSpec, FamilySet, HeroSpec, HeroVehicle, LogicalScenario, MapTemplate, TargetSpec,
};
pub use hero::{HeroAssignment, HeroScripts, PhaseProgress};
pub use placement::{LaneRef, Placement, main_lanes_at, main_road_length, place};
pub use range::{Range, Sampler, quantize};
pub use sample::{
    MAX_ATTEMPTS, SamplingContext, reference_run, sample_scenario, scene_with_reference_future,
    simulate_reference,
};
pub use scripted_rollout::rollout_with_heroes;
pub use set_folder::load_scenario_set;
