//! `cargo run --release --example action_sigma -- CHECKPOINT...`: how much noise does a policy's
//! sampled data carry, against how far its mean misses the logs?
//!
//! The downstream study (`rtr downstream`) trains a predictor on scenes each policy simulates
//! with sampled actions, mean + sigma * eps. A policy whose sigma matches the RMS error of its
//! mean on the logged actions is a calibrated sampler; one whose sigma is larger (the PPO
//! methods start at 2.32 x that error, measured on their training mix, to explore) makes data
//! noisier than its own driving.
//! Printed per policy, over the labelled agent-steps of the A9 training split (the downstream
//! study's initial conditions) seen with the logged history as in BC: the RMS error of the
//! mean, the RMS of the policy's own sigma, and their ratio, per control.

use std::path::Path;

use rtr::data::SceneConfig;
use rtr::eval::TrainedPolicy;
use rtr::train::imitation::logged_action_fit;

/// Scenes per forward batch.
const BATCH: usize = 16;

fn main() -> std::process::ExitCode {
    match run().and_then(|()| Ok(rtr::io::console::check_stdout()?)) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            rtr::errln!("action_sigma: {e}");
            std::process::ExitCode::from(2)
        }
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    rtr::allocator::tune_for_tensors();
    let checkpoints: Vec<String> = std::env::args().skip(1).collect();
    if checkpoints.is_empty() {
        return Err("usage: cargo run --release --example action_sigma -- CHECKPOINT...".into());
    }
    let device = rtr::backend::Backend::Flex.device(false)?;
    // Every policy is loaded before the measurements start: a wrong path fails at once.
    let policies = checkpoints
        .iter()
        .map(|path| TrainedPolicy::load(Path::new(path), &device))
        .collect::<Result<Vec<_>, _>>()?;
    let dataset = rtr::data::a9::A9Dataset::load(&rtr::data::a9::default_dir())?;
    let train = dataset.scenes(&SceneConfig::default())?.train;
    let scenes: Vec<&rtr::scene::Scene> = train.iter().collect();
    rtr::outln!(
        "| policy | agent-steps | acceleration: mean error RMS (m/s^2) | sigma RMS (m/s^2) | sigma / error | steering: mean error RMS (rad) | sigma RMS (rad) | sigma / error |"
    )?;
    rtr::outln!("|---|---|---|---|---|---|---|---|")?;
    for (path, policy) in checkpoints.iter().zip(&policies) {
        let limits = &policy.config.limits;
        let fit = logged_action_fit(&policy.network, &scenes, limits, BATCH, &device)?;
        let [error, sigma] = [fit.mean_error_rms, fit.sigma_rms];
        rtr::outln!(
            "| {path} | {} | {:.3} | {:.3} | {:.2} | {:.5} | {:.5} | {:.2} |",
            fit.count,
            error[0],
            sigma[0],
            sigma[0] / error[0],
            error[1],
            sigma[1],
            sigma[1] / error[1]
        )?;
    }
    Ok(())
}
