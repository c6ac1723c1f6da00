//! `rtr model`: configuration and parameter counts of the policy and value networks, and the
//! weight average of checkpoints.

use std::path::PathBuf;

use clap::Subcommand;

use rtr::backend::Backend;
use rtr::model::{ModelConfig, PolicyNetwork, ValueNetwork};
use rtr::{Error, Result};

#[derive(Subcommand)]
pub enum ModelCommand {
    /// Configuration and parameter counts of the policy and value networks.
    Info {
        /// A model config (TOML; missing fields take the paper's defaults), or a run file or
        /// a run's config.toml, whose `[model]` table is read.
        #[arg(long)]
        config: Option<PathBuf>,
        /// The small configuration of the tests and the quick example.
        #[arg(long, conflicts_with = "config")]
        small: bool,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Average the weights of several checkpoints of one run (stochastic weight averaging)
    /// into a new policy folder that `rtr eval --checkpoint` loads.
    Average {
        /// A checkpoint folder (checkpoints/iter-*), run folder or policy.bpk. Repeat (two or
        /// more).
        #[arg(long = "checkpoint", required = true)]
        checkpoints: Vec<PathBuf>,
        /// The new folder: policy.bpk, the run's config.toml and averaged.json.
        #[arg(long)]
        out: PathBuf,
    },
}

pub fn run(command: ModelCommand) -> Result<()> {
    match command {
        ModelCommand::Info {
            config,
            small,
            json,
        } => info(config, small, json),
        ModelCommand::Average { checkpoints, out } => average(&checkpoints, &out),
    }
}

/// The kind of result set `rtr model average` writes ([`rtr::io::StagedFolder`]).
const AVERAGED_MODEL: &str = "rtr model average";

fn average(checkpoints: &[PathBuf], out: &std::path::Path) -> Result<()> {
    for path in checkpoints {
        rtr::io::check_input_path(path, "--checkpoint")?;
        // averaged.json names each source by its path, and JSON holds only UTF-8.
        if path.to_str().is_none() {
            return Err(Error::InvalidArgument(format!(
                "--checkpoint {}: the path is not UTF-8, and averaged.json records every \
                 source by its path; rename or link it under a UTF-8 name",
                path.display()
            )));
        }
    }
    let inputs =
        rtr::eval::trained::with_run_inputs(rtr::io::Inputs::new(), "--checkpoint", checkpoints)?;
    if let Some(run) = rtr::train::checkpoint::enclosing_run(out) {
        return Err(Error::InvalidArgument(format!(
            "--out {}: lies in the training run {}, whose trainer replaces and prunes what is \
             there; choose a folder outside it",
            out.display(),
            run.display()
        )));
    }
    let _claim = rtr::io::claim_output_folder(out, "--out", &inputs)?;
    // A model or training run there is refused (it is no average's); an earlier average is
    // replaced whole.
    rtr::io::check_result_folder(
        out,
        AVERAGED_MODEL,
        &["policy.bpk", "config.toml", "averaged.json"],
    )?;
    let device = Backend::NdArray.device(false)?;
    // Staged: the policy, its config and averaged.json appear together or not at all.
    let staged = rtr::io::StagedFolder::new(out, AVERAGED_MODEL)?;
    let report =
        staged.fill(|dir| rtr::eval::averaged::write_averaged_policy(checkpoints, dir, &device))?;
    staged.commit()?;
    rtr::outln!(
        "{}: the mean of {} {} checkpoints",
        out.display(),
        report.sources.len(),
        report.method
    )?;
    Ok(())
}

/// The model a settings file describes: a run file (it names a `method`) by its `[model]`
/// table, checked as the whole run file; a file holding only a `[model]` table (copied out of
/// a run file) by that table; otherwise the file is a model config.
fn model_of(path: &std::path::Path) -> Result<ModelConfig> {
    /// A `[model]` table alone.
    #[derive(serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    struct ModelTable {
        model: ModelConfig,
    }
    let text = rtr::io::read_text(path, rtr::io::Format::Settings)?;
    let table = toml::from_str::<toml::Table>(&text).ok();
    let has = |key: &str| table.as_ref().is_some_and(|t| t.contains_key(key));
    let name = path.display().to_string();
    if has("method") {
        Ok(rtr::train::TrainConfig::from_toml_str(&text, &name)?.model)
    } else if table
        .as_ref()
        .is_some_and(|t| t.get("model").is_some_and(toml::Value::is_table))
    {
        let model = rtr::io::parse_toml::<ModelTable>(&text, &name)?.model;
        model.validate_text(&text, &name, "model.")?;
        Ok(model)
    } else {
        ModelConfig::from_toml_str(&text, &name)
    }
}

fn info(config: Option<PathBuf>, small: bool, json: bool) -> Result<()> {
    let config = match (&config, small) {
        (Some(path), _) => {
            rtr::io::check_input_file(path, "--config")?;
            model_of(path)?
        }
        (None, true) => ModelConfig::small(),
        (None, false) => ModelConfig::default(),
    };
    // Parameter counting needs no gradients; the plain CPU device is always compiled in.
    let device = Backend::NdArray.device(false)?;
    let policy = PolicyNetwork::new(&config, &device).parameter_counts();
    let value = ValueNetwork::new(&config, &device).parameter_counts();
    if json {
        let report = serde_json::json!({
            "config": config,
            "policy": policy,
            "value": value,
            "params": policy.total + value.total,
        });
        rtr::outln!("{report:#}")?;
        return Ok(());
    }
    let text = toml::to_string(&config)
        .map_err(|e| Error::InvalidArgument(format!("cannot encode config: {e}")))?;
    rtr::outln!("# model config\n{text}")?;
    rtr::outln!("{:<22} {:>12} {:>12}", "parameters", "policy", "value")?;
    let rows = [
        (
            "history encoder",
            policy.history_encoder,
            value.history_encoder,
        ),
        (
            "lane-graph encoder",
            policy.lane_graph_encoder,
            value.lane_graph_encoder,
        ),
        ("interaction (GNN)", policy.interaction, value.interaction),
        ("head (MLP)", policy.head, value.head),
        ("total", policy.total, value.total),
    ];
    for (name, p, v) in rows {
        rtr::outln!("{name:<22} {p:>12} {v:>12}")?;
    }
    rtr::outln!("policy + value: {}", policy.total + value.total)?;
    Ok(())
}
