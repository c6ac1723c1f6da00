//! The `rtr` command-line tool. Thin: parses arguments, calls the library, prints.

mod commands;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

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
        command: commands::data::DataCommand,
    },
    /// Draw a scene (A9, CommonRoad or a long-tail scenario: road, lane marks, boxes, history,
    /// logged future), or animate a policy's rollout on it (--animate, GIF).
    Render(commands::render::RenderArgs),
    /// Throughput benchmarks, printed as JSON.
    Bench {
        #[command(subcommand)]
        command: commands::bench::BenchCommand,
    },
    /// OpenDRIVE and procedural maps: describe, draw, export.
    Map {
        #[command(subcommand)]
        command: commands::map::MapCommand,
    },
    /// The policy and value networks.
    Model {
        #[command(subcommand)]
        command: commands::model::ModelCommand,
    },
    /// Long-tail scenarios: logical families, concrete sets.
    Scenarios {
        #[command(subcommand)]
        command: commands::scenarios::ScenariosCommand,
    },
    /// Probe tasks with known answers: does PPO learn to brake, to recover a lane, and does
    /// its gradient reach the right control?
    Probe {
        #[command(subcommand)]
        command: commands::probe::ProbeCommand,
    },
    /// Train a policy from a run file (experiments/*/*.toml): BC, IL, RL, RL-Shaped, BC+RL,
    /// RTR, KL-L or KL-R. Writes OUT/curves.csv, OUT/config.toml and OUT/checkpoints/.
    Train(commands::train::TrainArgs),
    /// Evaluate trained policies on the nominal (real A9 test), long-tail and OOD sets: prints
    /// the paper's table (Markdown, one row per checkpoint) and writes JSON and figures.
    Eval(commands::eval::EvalArgs),
    /// The lambda x alpha study: train RTR at every point from one base run file, then
    /// evaluate each (paper table "Balancing realism and infraction avoidance").
    Sweep(commands::sweep::SweepArgs),
    /// The downstream study (paper section 4.2): each policy simulates the A9 training split,
    /// a trajectory predictor is trained on each simulated dataset and scored on the real test
    /// split (minFDE, minCTE over modes; mean +- std over seeds).
    Downstream(commands::downstream::DownstreamArgs),
    /// List the nominal A9 training scenes a trained policy commits an infraction on (the
    /// paper's "Curated" scenario set): a scene list for a run file's `data.curated`.
    Curate(commands::curate::CurateArgs),
    /// Sim-to-real: locate where the simulator and vehicle recordings differ, name the physics
    /// the bicycle model left out, fit it and show held-out error before and after.
    Sim2real(commands::sim2real::Sim2RealArgs),
    /// Vehicle recordings for sim-to-real.
    Recordings {
        #[command(subcommand)]
        command: commands::recordings::RecordingsCommand,
    },
}

/// The command line, with `-1` read as a value on every (sub)command, so that `--index -1`
/// is refused by that flag's own parser (naming it) rather than taken for an unknown flag.
fn parse_cli() -> Cli {
    use clap::{CommandFactory, FromArgMatches};
    fn allow_negative_numbers(command: clap::Command) -> clap::Command {
        command
            .allow_negative_numbers(true)
            .mut_subcommands(allow_negative_numbers)
    }
    let matches = allow_negative_numbers(Cli::command())
        .try_get_matches()
        .unwrap_or_else(|e| exit_with(e));
    Cli::from_arg_matches(&matches).unwrap_or_else(|e| exit_with(e))
}

/// Ends the process for a clap outcome that is not a command: help and version go through the
/// console (a full stdout is an error, a closed one is not), usage errors to stderr as clap
/// prints them.
fn exit_with(e: clap::Error) -> ! {
    use clap::error::ErrorKind;
    if !matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) {
        e.exit();
    }
    let printed = rtr::out!("{}", e.render()).and_then(|()| rtr::io::console::check_stdout());
    match printed {
        Ok(()) => std::process::exit(0),
        Err(error) => {
            rtr::errln!("error: {error}");
            std::process::exit(1);
        }
    }
}

fn main() -> ExitCode {
    rtr::allocator::tune_for_tensors();
    rtr::io::release_locks_on_signal();
    match run(parse_cli()).and_then(|()| rtr::io::console::check_stdout()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            rtr::errln!("error: {}", rtr::io::console::bounded(&e.to_string()));
            let mut shown = e.to_string();
            let mut source = std::error::Error::source(&e);
            while let Some(cause) = source {
                // Variants that wrap a cause already print it in their own message.
                let text = cause.to_string();
                if !shown.contains(&text) {
                    rtr::errln!("  caused by: {}", rtr::io::console::bounded(&text));
                    shown.push_str(&text);
                }
                source = cause.source();
            }
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> rtr::Result<()> {
    match cli.command {
        Command::Data { command } => commands::data::run(command),
        Command::Render(args) => commands::render::run(args),
        Command::Bench { command } => commands::bench::run(command),
        Command::Map { command } => commands::map::run(command),
        Command::Model { command } => commands::model::run(command),
        Command::Scenarios { command } => commands::scenarios::run(command),
        Command::Train(args) => commands::train::run(args),
        Command::Eval(args) => commands::eval::run(args),
        Command::Sweep(args) => commands::sweep::run(args),
        Command::Downstream(args) => commands::downstream::run(args),
        Command::Curate(args) => commands::curate::run(args),
        Command::Probe { command } => commands::probe::run(command),
        Command::Sim2real(args) => commands::sim2real::run(args),
        Command::Recordings { command } => commands::recordings::run(command),
    }
}
