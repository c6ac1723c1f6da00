//! A training run from its pieces: the config, the shipped (or given) A9 data, the devices.
//! What `rtr train`, the example and the tests call.

use std::path::Path;

use indicatif::ProgressBar;

use super::config::TrainConfig;
use super::sources::TrainingData;
use super::trainer::{TrainSummary, Trainer};
use crate::data::A9Dataset;
use crate::error::Result;

/// The devices of `config.run`: [`super::RunConfig::device_count`] autodiff devices of its
/// backend.
pub fn devices(config: &TrainConfig) -> Result<Vec<burn::prelude::Device>> {
    (0..config.run.device_count())
        .map(|_| config.run.backend.device(true))
        .collect()
}

/// Loads the training data `config` needs.
pub fn training_data(dataset: &A9Dataset, config: &TrainConfig) -> Result<TrainingData> {
    TrainingData::load(dataset, &config.data, config.uses_longtail())
}

/// Trains (or with `resume` continues) the run of `config` in `run_dir`; `stop_after` ends
/// this call after that many iterations, with a checkpoint to resume from.
pub fn train(
    config: TrainConfig,
    dataset: &A9Dataset,
    run_dir: &Path,
    resume: bool,
    stop_after: Option<usize>,
    progress: &ProgressBar,
) -> Result<TrainSummary> {
    let data = training_data(dataset, &config)?;
    let devices = devices(&config)?;
    let mut trainer = Trainer::new(config, &data, devices, run_dir, resume)?;
    trainer.run(progress, stop_after)
}
