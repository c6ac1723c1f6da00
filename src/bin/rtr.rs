//! The `rtr` command-line tool. Thin: parses arguments, calls the library, prints.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand, ValueEnum};

use rtr::data::{A9Dataset, SceneConfig, a9, summarize};
use rtr::render::{RenderOptions, output_paths, render_scene};
use rtr::{Error, Result};

#[derive(Parser)]
#[command(
    name = "rtr",
    version,
    about = "Learning realistic traffic agents in closed loop"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// The nominal dataset (real A9 recording).
    Data {
        #[command(subcommand)]
        command: DataCommand,
    },
    /// Draw a scene of the nominal dataset (road, lane marks, boxes, history, logged future).
    Render(RenderArgs),
}

#[derive(Subcommand)]
enum DataCommand {
    /// Counts, scene split and logged-driver infraction rates.
    Summary {
        #[command(flatten)]
        data: DataArgs,
        /// Print one JSON object instead of a table.
        #[arg(long)]
        json: bool,
    },
}

#[derive(Args)]
struct DataArgs {
    /// Folder with the AUTOMATUM A9 files (default: the copy shipped in data/automatum-a9).
    #[arg(long)]
    data: Option<PathBuf>,
}

impl DataArgs {
    fn load(&self) -> Result<A9Dataset> {
        let dir = self.data.clone().unwrap_or_else(a9::default_dir);
        A9Dataset::load(&dir)
    }
}

#[derive(Clone, Copy, ValueEnum)]
enum Split {
    Train,
    Test,
}

#[derive(Args)]
struct RenderArgs {
    #[command(flatten)]
    data: DataArgs,
    #[arg(long, value_enum, default_value = "test")]
    split: Split,
    /// Scene id (as printed by `rtr data summary`), e.g. a9-test-t0450.0.
    #[arg(long, conflicts_with = "index")]
    scene: Option<String>,
    /// Position of the scene in its split.
    #[arg(long, default_value_t = 0)]
    index: usize,
    /// Output file (.png or .svg), or a prefix without extension for both.
    #[arg(long)]
    out: PathBuf,
    /// Image width in pixels.
    #[arg(long, default_value_t = 2400)]
    width: u32,
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            let mut source = std::error::Error::source(&e);
            while let Some(cause) = source {
                eprintln!("  caused by: {cause}");
                source = cause.source();
            }
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Data {
            command: DataCommand::Summary { data, json },
        } => {
            let dataset = data.load()?;
            let summary = summarize(&dataset, &SceneConfig::default())?;
            if json {
                let text = serde_json::to_string_pretty(&summary)
                    .map_err(|e| Error::InvalidArgument(format!("cannot encode summary: {e}")))?;
                println!("{text}");
            } else {
                let value = serde_json::to_value(&summary)
                    .map_err(|e| Error::InvalidArgument(format!("cannot encode summary: {e}")))?;
                if let Some(fields) = value.as_object() {
                    for (key, v) in fields {
                        println!("{key:<26} {v}");
                    }
                }
            }
            Ok(())
        }
        Command::Render(args) => render(args),
    }
}

fn render(args: RenderArgs) -> Result<()> {
    let dataset = args.data.load()?;
    let split = dataset.scenes(&SceneConfig::default())?;
    let scenes = match args.split {
        Split::Train => &split.train,
        Split::Test => &split.test,
    };
    let scene = match &args.scene {
        Some(id) => scenes.iter().find(|s| &s.id == id).ok_or_else(|| {
            Error::InvalidArgument(format!(
                "no scene `{id}` in this split; ids run from {} to {}",
                scenes.first().map_or("-", |s| s.id.as_str()),
                scenes.last().map_or("-", |s| s.id.as_str())
            ))
        })?,
        None => scenes.get(args.index).ok_or_else(|| {
            Error::InvalidArgument(format!(
                "--index {} is past the split's {} scenes",
                args.index,
                scenes.len()
            ))
        })?,
    };
    let opts = RenderOptions {
        width_px: args.width,
        ..Default::default()
    };
    let targets = match args.out.extension() {
        Some(_) => vec![args.out.clone()],
        None => output_paths(&args.out).to_vec(),
    };
    for path in &targets {
        render_scene(scene, path, &opts)?;
        println!("wrote {}", path.display());
    }
    println!(
        "scene {}: {} agents ({} controlled, blue; replayed, orange); solid line = history, \
         faded line and dots = logged future",
        scene.id,
        scene.agents.len(),
        scene.controlled_count()
    );
    Ok(())
}
