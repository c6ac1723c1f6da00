//! `rtr recordings`: generate vehicle recordings with a known concealed effect for sim2real.

use std::path::PathBuf;

use clap::Subcommand;

use rtr::io::{Inputs, claim_output_file};
use rtr::sim2real::{Effect, GeneratorConfig, Uncatalogued, generate};
use rtr::{Error, Result};

use super::args::count;

#[derive(Subcommand)]
pub enum RecordingsCommand {
    /// Recordings from a plant with one concealed catalogue effect (or none), under sensor
    /// noise: a known answer for `rtr sim2real`.
    Generate {
        /// accel_lag, steer_lag, dead_time, drag, understeer, steer_rate_limit, sideslip, none,
        /// or physics outside the catalogue: speed_dependent_steering, brake_gain.
        #[arg(long)]
        effect: String,
        #[arg(long, default_value_t = 11)]
        seed: u64,
        /// One-minute tracks to generate.
        #[arg(long, default_value_t = 24, value_parser = count(3, 10_000))]
        tracks: usize,
        /// Output CSV.
        #[arg(long)]
        out: PathBuf,
    },
}

pub fn run(command: RecordingsCommand) -> Result<()> {
    let RecordingsCommand::Generate {
        effect,
        seed,
        tracks,
        out,
    } = command;
    let _claim = claim_output_file(&out, "--out", &Inputs::new())?;
    let mut config = match effect.as_str() {
        "none" => GeneratorConfig::with_effect(None, seed),
        name => match (Effect::from_name(name), Uncatalogued::typical(name)) {
            (Some(effect), _) => GeneratorConfig::with_effect(Some(effect), seed),
            (None, Some(physics)) => GeneratorConfig::with_uncatalogued(physics, seed),
            (None, None) => {
                let names: Vec<&str> = Effect::ALL
                    .iter()
                    .map(|e| e.name())
                    .chain(Uncatalogued::NAMES)
                    .collect();
                return Err(Error::InvalidArgument(format!(
                    "unknown --effect `{name}`: expected none or one of {}",
                    names.join(", ")
                )));
            }
        },
    };
    config.tracks = tracks;
    let device = rtr::backend::Backend::NdArray.device(false)?;
    let recordings = generate(&config, &device);
    recordings.save(&out)?;
    rtr::outln!(
        "{} tracks of {} s at {} Hz{} -> {}",
        tracks,
        config.duration_s,
        1.0 / config.period_s,
        match (&config.effect, config.uncatalogued) {
            (Some((e, v)), _) => format!(", concealed {e} {v:?}"),
            (None, Some(physics)) => format!(", concealed {physics:?} (not in the catalogue)"),
            (None, None) => ", no concealed effect".into(),
        },
        out.display()
    )?;
    Ok(())
}
