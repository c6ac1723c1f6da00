//! Evaluation (paper section 4 and appendix "Metrics"): closed-loop rollouts of a policy on
//! the nominal, long-tail and OOD sets, the paper's metrics with bootstrap intervals, the
//! results tables and the plots.
//!
//! - [`histogram`], [`features`], [`reconstruction`]: the measurements;
//! - [`metrics`]: per-scene tallies and the metrics on them; [`bootstrap`]: their intervals;
//! - [`realism`]: the WOSAC-style score;
//! - [`tally`]: a rollout to tallies; [`sets`], [`policy`], [`evaluate`]: scene sets, what
//!   drives them, the evaluation;
//! - [`trained`]: loading a run's policy; [`averaged`]: the weight average of checkpoints;
//! - [`report`], [`plots`]: tables, JSON, figures;
//! - [`study`]: several policies evaluated side by side (training them is `crate::studies`);
//!   [`headline`]: whether they bear out the paper's headline;
//! - [`curate`]: the training scenes a policy fails on (the "Curated" scenario set);
//! - [`watch`]: one scene's rollout with its infractions, for an animation.

pub mod averaged;
pub mod bootstrap;
pub mod collisions;
pub mod curate;
pub mod evaluate;
pub mod features;
pub mod headline;
pub mod histogram;
pub mod metrics;
pub mod plots;
pub mod policy;
pub mod realism;
pub mod reconstruction;
pub mod report;
pub mod sets;
pub mod study;
pub mod tally;
pub mod trained;
pub mod watch;

pub use bootstrap::Estimate;
pub use evaluate::{EvalConfig, SetResult, evaluate, evaluate_tallies, summarise};
pub use features::Feature;
pub use headline::{HeadlineNumbers, HeadlineVerdict};
pub use histogram::{Histogram, jensen_shannon};
pub use metrics::{Metric, SceneTally};
pub use policy::{EvalPolicy, IdmBaseline};
pub use report::{MethodResult, markdown_table, results_json};
pub use sets::{EvalScenes, EvalSet, load_sets};
pub use tally::tally_rollout;
pub use trained::TrainedPolicy;
pub use watch::{WatchedRollout, watch_rollout};
