//! Side-by-side speed comparison of this build against an earlier one, interleaved in one run
//! so that a shared, noisy machine slows both alike; only the ratio is meant to be read.
//!
//! ```sh
//! cargo bench --bench side_by_side -- --baseline-commit b1ae3e9 --runs 5 --bench train
//! cargo bench --bench side_by_side -- --baseline-bin /path/to/old/rtr --bench model,sim
//! cargo bench --bench side_by_side -- --baseline-commit b1ae3e9 --bench train -- --ppo-batch 64
//! ```
//!
//! `--baseline-commit REV` checks REV out in a git worktree under
//! `target/side-by-side/` and builds its `rtr` there in release with its own target folder
//! (a cold build the first time, reused after). Each run executes `rtr bench <name>` of the
//! baseline and of this build, alternating which goes first (A B, B A, ...). Arguments after a
//! lone `--` go to both. Prints one JSON object: per benchmark and numeric field, the medians of
//! both builds and their ratio (`speedup` for times and rates, `ratio` current/baseline for
//! anything else, e.g. memory).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::{Map, Value, json};

struct Options {
    baseline: Baseline,
    runs: usize,
    benches: Vec<String>,
    passthrough: Vec<String>,
}

enum Baseline {
    Binary(PathBuf),
    Commit(String),
}

fn usage(message: &str) -> ! {
    rtr::errln!(
        "side_by_side: {message}\nusage: cargo bench --bench side_by_side -- \
         (--baseline-bin PATH | --baseline-commit REV) [--runs N] [--bench train,model,sim] \
         [-- ARGS FOR BOTH]"
    );
    std::process::exit(2)
}

fn parse_options() -> Options {
    // cargo bench appends `--bench` to a harness = false target's arguments (after ours,
    // even after a `--`): drop it.
    let mut all: Vec<String> = std::env::args().skip(1).collect();
    if all.last().is_some_and(|a| a == "--bench") {
        all.pop();
    }
    let mut args = all.into_iter();
    let (mut baseline, mut runs, mut benches) = (None, 5, vec!["model".to_string()]);
    let mut passthrough = Vec::new();
    while let Some(arg) = args.next() {
        let value = |args: &mut dyn Iterator<Item = String>| {
            args.next()
                .unwrap_or_else(|| usage(&format!("{arg} needs a value")))
        };
        match arg.as_str() {
            "--baseline-bin" => baseline = Some(Baseline::Binary(value(&mut args).into())),
            "--baseline-commit" => baseline = Some(Baseline::Commit(value(&mut args))),
            "--runs" => {
                runs = value(&mut args)
                    .parse()
                    .ok()
                    .filter(|&n| n >= 1)
                    .unwrap_or_else(|| usage("--runs expects a whole number >= 1"))
            }
            "--bench" => {
                benches = value(&mut args).split(',').map(str::to_string).collect();
                if let Some(bad) = benches
                    .iter()
                    .find(|b| !["train", "model", "sim"].contains(&b.as_str()))
                {
                    usage(&format!(
                        "unknown benchmark `{bad}`: expected train, model or sim"
                    ));
                }
            }
            "--" => passthrough = args.by_ref().collect(),
            other => usage(&format!("unknown argument `{other}`")),
        }
    }
    Options {
        baseline: baseline.unwrap_or_else(|| usage("name a baseline")),
        runs,
        benches,
        passthrough,
    }
}

fn run_checked(command: &mut Command, what: &str) -> Vec<u8> {
    let output = command
        .output()
        .unwrap_or_else(|e| usage(&format!("cannot start {what}: {e}")));
    if !output.status.success() {
        rtr::errln!("{}", String::from_utf8_lossy(&output.stderr));
        usage(&format!("{what} failed ({})", output.status));
    }
    output.stdout
}

/// The baseline binary: as given, or built from a worktree of the commit.
fn baseline_binary(baseline: &Baseline) -> PathBuf {
    let commit = match baseline {
        Baseline::Binary(path) => return path.clone(),
        Baseline::Commit(rev) => rev,
    };
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let full = String::from_utf8_lossy(&run_checked(
        Command::new("git")
            .args(["rev-parse", "--verify"])
            .arg(format!("{commit}^{{commit}}"))
            .current_dir(root),
        "git rev-parse",
    ))
    .trim()
    .to_string();
    let base = root.join("target/side-by-side");
    let tree = base.join(format!("src-{full}"));
    if !tree.join("Cargo.toml").exists() {
        run_checked(
            Command::new("git")
                .args(["worktree", "add", "--detach"])
                .arg(&tree)
                .arg(&full)
                .current_dir(root),
            "git worktree add",
        );
    }
    let target = base.join("target");
    rtr::errln!("side_by_side: building {commit} in {}", tree.display());
    let status = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()))
        .args(["build", "--release", "--locked", "--bin", "rtr"])
        .arg("--target-dir")
        .arg(&target)
        .current_dir(&tree)
        .status()
        .unwrap_or_else(|e| usage(&format!("cannot start cargo: {e}")));
    if !status.success() {
        usage(&format!("building {commit} failed"));
    }
    let binary = target.join("release/rtr");
    let copy = base.join(format!("rtr-{full}"));
    std::fs::copy(&binary, &copy).unwrap_or_else(|e| usage(&format!("copy {binary:?}: {e}")));
    copy
}

/// One benchmark's JSON object from `binary`.
fn measure(binary: &Path, bench: &str, passthrough: &[String]) -> Map<String, Value> {
    let mut command = Command::new(binary);
    command.args(["bench", bench]).args(passthrough);
    let stdout = run_checked(&mut command, &format!("{} bench {bench}", binary.display()));
    let text = String::from_utf8_lossy(&stdout);
    let line = text
        .lines()
        .rev()
        .find(|l| l.trim_start().starts_with('{'))
        .unwrap_or_else(|| usage(&format!("{} printed no JSON", binary.display())));
    match serde_json::from_str(line) {
        Ok(Value::Object(map)) => map,
        _ => usage(&format!("{} printed no JSON object", binary.display())),
    }
}

fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    }
}

/// Field name -> medians of both builds and their ratio, for the numeric fields both report.
fn compare(baseline: &[Map<String, Value>], current: &[Map<String, Value>]) -> Value {
    let numbers = |runs: &[Map<String, Value>], key: &str| -> Vec<f64> {
        runs.iter()
            .filter_map(|r| r.get(key).and_then(Value::as_f64))
            .collect()
    };
    let mut fields = BTreeMap::new();
    for key in current
        .first()
        .map(|m| m.keys().cloned().collect::<Vec<_>>())
        .unwrap_or_default()
    {
        let (b, c) = (numbers(baseline, &key), numbers(current, &key));
        if c.len() != current.len() {
            continue;
        }
        let c_med = median(c);
        let mut entry = json!({ "current": c_med });
        if b.len() == baseline.len() && !b.is_empty() {
            let b_med = median(b);
            entry["baseline"] = json!(b_med);
            if key.ends_with("_per_s") {
                entry["speedup"] = json!(c_med / b_med);
            } else if key.ends_with("_ms") || key.ends_with("_s") {
                entry["speedup"] = json!(b_med / c_med);
            } else if b_med != 0.0 {
                entry["ratio"] = json!(c_med / b_med);
            }
        }
        fields.insert(key, entry);
    }
    json!(fields)
}

fn main() {
    let options = parse_options();
    let current = PathBuf::from(env!("CARGO_BIN_EXE_rtr"));
    let baseline = baseline_binary(&options.baseline);
    let mut report = Map::new();
    for bench in &options.benches {
        let (mut base_runs, mut cur_runs) = (Vec::new(), Vec::new());
        for run in 0..options.runs {
            rtr::errln!("side_by_side: {bench} run {}/{}", run + 1, options.runs);
            // Alternate the order so a drift in machine load favours neither build.
            if run % 2 == 0 {
                base_runs.push(measure(&baseline, bench, &options.passthrough));
                cur_runs.push(measure(&current, bench, &options.passthrough));
            } else {
                cur_runs.push(measure(&current, bench, &options.passthrough));
                base_runs.push(measure(&baseline, bench, &options.passthrough));
            }
        }
        report.insert(bench.clone(), compare(&base_runs, &cur_runs));
    }
    report.insert(
        "setup".into(),
        json!({
            "runs": options.runs,
            "baseline": baseline.display().to_string(),
            "current": current.display().to_string(),
            "passthrough": options.passthrough,
        }),
    );
    rtr::outln!("{}", Value::Object(report)).expect("standard output");
}
