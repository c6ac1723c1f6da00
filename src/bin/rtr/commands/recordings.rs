//! `rtr recordings`: generate vehicle recordings with a known concealed effect for sim2real.

use std::path::PathBuf;

use clap::Subcommand;

use rtr::data::recordings::RECORDINGS_CSV;
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
        /// The concealed catalogue effect's parameters, comma-separated in the catalogue's
        /// order (e.g. `--effect sideslip --values 0.4` for lr_m, `--effect drag --values
        /// 0.0006,0.15` for c_d, c_r); default: a typical passenger car's. Each within the
        /// range sim2real fits.
        #[arg(long, value_delimiter = ',')]
        values: Option<Vec<f64>>,
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
        values,
        out,
    } = command;
    let _claim = claim_output_file(&out, "--out", &Inputs::new(), &RECORDINGS_CSV)?;
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
    if let Some(values) = values {
        set_effect_values(&mut config, &effect, values)?;
    }
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

/// The concealed effect's parameters from `--values`: one per catalogue parameter, each within
/// the range sim2real fits (so the answer is one it could give).
fn set_effect_values(config: &mut GeneratorConfig, effect: &str, values: Vec<f64>) -> Result<()> {
    let Some(concealed) = config.effect.as_ref().map(|(e, _)| *e) else {
        return Err(Error::InvalidArgument(format!(
            "--values: --effect {effect} has no catalogue parameters to set; expected --values \
             only with one of {}",
            Effect::ALL.map(|e| e.name()).join(", ")
        )));
    };
    let specs = concealed.params();
    if values.len() != specs.len() {
        let names: Vec<&str> = specs.iter().map(|p| p.name).collect();
        return Err(Error::InvalidArgument(format!(
            "--values: {} given, but {concealed} has {} ({}); expected them comma-separated in \
             that order",
            values.len(),
            specs.len(),
            names.join(", ")
        )));
    }
    for (value, spec) in values.iter().zip(specs) {
        let what = format!("{}'s {} in {}", concealed, spec.name, spec.unit);
        check_in("--values", &what, *value, spec.min, spec.max)?;
    }
    config.effect = Some((concealed, values));
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
