//! `rtr recordings`: generate vehicle recordings with a known concealed effect for sim2real.

use std::path::PathBuf;

use clap::Subcommand;

use rtr::io::{Inputs, claim_output_file};
use rtr::sim2real::{CommandTiming, Effect, GeneratorConfig, SensorNoise, Uncatalogued, generate};
use rtr::{Error, Result};

use super::args::count;

#[derive(Subcommand)]
pub enum RecordingsCommand {
    /// Recordings from a plant with one concealed catalogue effect (or none), under sensor
    /// noise: a known answer for `rtr sim2real`.
    Generate {
        /// accel_lag, steer_lag, dead_time, drag, understeer, steer_rate_limit, sideslip, none,
        /// or physics outside the catalogue: speed_dependent_steering, brake_gain, power_limit.
        #[arg(long)]
        effect: String,
        #[arg(long, default_value_t = 11)]
        seed: u64,
        /// One-minute tracks to generate.
        #[arg(long, default_value_t = 24, value_parser = count(3, 10_000))]
        tracks: usize,
        /// Sampling period of the log (s), in [0.02, 0.5].
        #[arg(long, default_value_t = 0.1)]
        period: f64,
        /// Sensor noise as a multiple of the default (0.1 m position, 3 mrad heading,
        /// 0.1 m/s speed), in [0, 5].
        #[arg(long, default_value_t = 1.0)]
        noise_scale: f64,
        /// How the logged commands were applied: `held` over the period after each sample,
        /// or `sampled` from a controller ten times faster than the log.
        #[arg(long, default_value = "held")]
        command_timing: String,
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
        period,
        noise_scale,
        command_timing,
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
    config.period_s = check_in("--period", "seconds", period, 0.02, 0.5)?;
    let scale = check_in(
        "--noise-scale",
        "a multiple of the default noise",
        noise_scale,
        0.0,
        5.0,
    )?;
    config.noise = SensorNoise {
        position_m: config.noise.position_m * scale,
        heading_rad: config.noise.heading_rad * scale,
        speed_m_s: config.noise.speed_m_s * scale,
    };
    config.command_timing = CommandTiming::from_name(&command_timing).ok_or_else(|| {
        Error::InvalidArgument(format!(
            "unknown --command-timing `{command_timing}`: expected {}",
            CommandTiming::NAMES.join(" or ")
        ))
    })?;
    let device = rtr::backend::Backend::NdArray.device(false)?;
    let recordings = generate(&config, &device);
    recordings.save(&out)?;
    rtr::outln!(
        "{} tracks of {} s at {} Hz, commands {}{} -> {}",
        tracks,
        config.duration_s,
        1.0 / config.period_s,
        config.command_timing.name(),
        match (&config.effect, config.uncatalogued) {
            (Some((e, v)), _) => format!(", concealed {e} {v:?}"),
            (None, Some(physics)) => format!(", concealed {physics:?} (not in the catalogue)"),
            (None, None) => ", no concealed effect".into(),
        },
        out.display()
    )?;
    Ok(())
}

/// `value` if it lies in `[min, max]`, else an error naming the flag and the range.
fn check_in(flag: &str, what: &str, value: f64, min: f64, max: f64) -> Result<f64> {
    if value >= min && value <= max {
        Ok(value)
    } else {
        Err(Error::InvalidArgument(format!(
            "{flag} {value}: expected {what} in [{min}, {max}]"
        )))
    }
}
