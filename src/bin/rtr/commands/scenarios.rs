//! `rtr scenarios`: list the long-tail scenario families or draw concrete scenario sets.

use std::path::PathBuf;

use clap::Subcommand;

use rtr::Result;
use rtr::io::{Inputs, StagedFolder, claim_output_folder};
use rtr::scenario::{GenerateConfig, ScenarioSet, builtin_families, generate_sets, load_families};

use super::args::{DataArgs, count};

/// Most scenarios one flag may ask for: 100 times the paper's sets, about an hour of drawing.
const MAX_SCENARIOS: u64 = 50_000;

/// The kind of result set `rtr scenarios generate --out` writes.
const SCENARIO_SET: &str = "rtr scenarios generate";

#[derive(Subcommand)]
pub enum ScenariosCommand {
    /// Draw the default train / eval / OOD sets (167 / 166 / 84) from the family files and
    /// write one JSON file per concrete scenario to OUT/train, OUT/eval, OUT/ood.
    Generate {
        #[arg(long)]
        out: PathBuf,
        #[arg(long, default_value_t = rtr::scenario::DEFAULT_SEED)]
        seed: u64,
        /// Folder of family files (*.toml, searched recursively); default: the shipped ones.
        #[arg(long)]
        families: Option<PathBuf>,
        /// Concrete scenarios from the training families (split alternately into train/eval).
        #[arg(long, default_value_t = 333, value_parser = count(0, MAX_SCENARIOS))]
        in_distribution: usize,
        /// Concrete scenarios from the held-out families.
        #[arg(long, default_value_t = 84, value_parser = count(0, MAX_SCENARIOS))]
        ood: usize,
        #[command(flatten)]
        data: DataArgs,
    },
    /// List the families with their set and description.
    List {
        #[arg(long)]
        families: Option<PathBuf>,
    },
}

pub fn run(command: ScenariosCommand) -> Result<()> {
    match command {
        ScenariosCommand::List { families } => {
            let families = load_families(&families_folder(families)?)?;
            for f in &families {
                rtr::outln!(
                    "{:<28} {:<5} {}",
                    f.name,
                    format!("{:?}", f.set).to_lowercase(),
                    f.description
                )?;
            }
            Ok(())
        }
        ScenariosCommand::Generate {
            out,
            seed,
            families,
            in_distribution,
            ood,
            data,
        } => {
            let start = std::time::Instant::now();
            if in_distribution + ood == 0 {
                return Err(rtr::Error::InvalidArgument(
                    "--in-distribution 0 and --ood 0: nothing to generate; expected at least one \
                     scenario"
                        .into(),
                ));
            }
            let inputs = Inputs::new()
                .with_all("--families", &families)
                .with("--data", data.dir());
            let _claim = claim_output_folder(&out, "--out", &inputs)?;
            // The loaders read every file of a set folder: one rtr did not write there would
            // join the new set unseen. An earlier set of rtr's is replaced whole.
            rtr::io::check_result_folder(&out, SCENARIO_SET, &["train", "eval", "ood"])?;
            let families = load_families(&families_folder(families)?)?;
            let dataset = data.load()?;
            let stats =
                rtr::data::TrafficStatistics::from_recording(&dataset.recording, &dataset.map, 1.0);
            let config = GenerateConfig {
                seed,
                in_distribution,
                ood,
                ..Default::default()
            };
            let sets = generate_sets(&families, &stats, &config)?;
            let staged = StagedFolder::new(&out, SCENARIO_SET)?;
            let written = staged.fill(|dir| sets.write(dir))?;
            staged.commit()?;
            for set in ScenarioSet::ALL {
                let list = sets.set(set);
                let collided = list
                    .iter()
                    .filter(|s| !s.reference.collided_agents.is_empty())
                    .count();
                let agents: usize = list.iter().map(|s| s.agents.len()).sum();
                rtr::outln!(
                    "{:<5} {:>4} scenarios, {:>5} agents; IDM reference: a collision in {collided} ({:.1} %)",
                    set.name(),
                    list.len(),
                    agents,
                    100.0 * collided as f64 / list.len().max(1) as f64
                )?;
            }
            rtr::outln!(
                "wrote {written} scenarios to {} in {:.1} s (seed {seed})",
                out.display(),
                start.elapsed().as_secs_f64()
            )?;
            Ok(())
        }
    }
}

/// The families folder: `--families`, checked to be a folder, or the built-in one.
fn families_folder(families: Option<PathBuf>) -> Result<PathBuf> {
    match families {
        Some(dir) => {
            rtr::io::check_input_folder(&dir, "--families", "a folder of family TOML files")?;
            Ok(dir)
        }
        None => Ok(builtin_families()),
    }
}
