//! `rtr data`: summarise the nominal A9 dataset or a set of CommonRoad files.

use std::path::PathBuf;

use clap::Subcommand;

use rtr::data::{SceneConfig, commonroad, summarize};
use rtr::{Error, Result};

use super::args::DataArgs;

#[derive(Subcommand)]
pub enum DataCommand {
    /// Counts, scene split and logged-driver infraction rates.
    Summary {
        #[command(flatten)]
        data: DataArgs,
        /// Summarise these CommonRoad files or folders (repeatable) instead of the A9 data:
        /// per file, its vehicles, duration, lanelets and scenes (or why it gives none).
        #[arg(long = "commonroad")]
        commonroad: Vec<PathBuf>,
        /// Speed limit (m/s) of CommonRoad lanes whose file gives none (default: 130 km/h).
        #[arg(long, requires = "commonroad")]
        commonroad_speed_limit: Option<f64>,
        /// Print one JSON object instead of a table.
        #[arg(long)]
        json: bool,
    },
}

pub fn run(command: DataCommand) -> Result<()> {
    let DataCommand::Summary {
        data,
        commonroad,
        commonroad_speed_limit,
        json,
    } = command;
    for path in &commonroad {
        rtr::io::check_input_path(path, "--commonroad")?;
    }
    if !commonroad.is_empty() {
        let clips = commonroad::load_commonroad(&commonroad, commonroad_speed_limit)?;
        let (_, summaries) = commonroad::commonroad_scenes(&clips, &SceneConfig::default())?;
        if json {
            let text = serde_json::to_string_pretty(&summaries)
                .map_err(|e| Error::InvalidArgument(format!("cannot encode summary: {e}")))?;
            rtr::outln!("{text}")?;
        } else {
            rtr::out!("{}", commonroad::describe_clips(&summaries))?;
        }
        return Ok(());
    }
    let dataset = data.load()?;
    let summary = summarize(&dataset, &SceneConfig::default())?;
    if json {
        let text = serde_json::to_string_pretty(&summary)
            .map_err(|e| Error::InvalidArgument(format!("cannot encode summary: {e}")))?;
        rtr::outln!("{text}")?;
    } else {
        let value = serde_json::to_value(&summary)
            .map_err(|e| Error::InvalidArgument(format!("cannot encode summary: {e}")))?;
        if let Some(fields) = value.as_object() {
            for (key, v) in fields {
                rtr::outln!("{key:<26} {v}")?;
            }
        }
    }
    Ok(())
}
