//! README.md's quick tour runs as written: every `cargo run --release -- ...` command of its
//! "Quick tour" section, in order (later commands read what earlier ones wrote), through the
//! `rtr` binary, in a fresh folder that sees the project's `data/`, `models/` and
//! `experiments/`. At the reduced sizes the README names: training with `--stop-after 1`,
//! evaluation with `--scenes 2`. The example (`cargo run --release --example rtr`) is the
//! README's main command, not part of the tour.

use std::path::Path;
use std::process::Command;

/// What the test adds to a tour command, by subcommand, to keep it short.
fn reductions(subcommand: &str) -> &'static [&'static str] {
    match subcommand {
        "train" => &["--stop-after", "1"],
        "eval" => &["--scenes", "2"],
        "sweep" => &["--stop-after", "1", "--scenes", "2"],
        _ => &[],
    }
}

/// The commands of the section under `heading` (up to the next `## ` heading): the lines of
/// its `sh` blocks (continuations joined, comments dropped) and its inline code spans that
/// start with `cargo run`.
fn section_commands(readme: &str, heading: &str) -> Vec<String> {
    let start = readme
        .find(heading)
        .unwrap_or_else(|| panic!("README.md has no `{heading}` section"));
    let rest = &readme[start + heading.len()..];
    let section = &rest[..rest.find("\n## ").unwrap_or(rest.len())];
    let mut commands = Vec::new();
    let mut in_block = false;
    let mut pending = String::new();
    for line in section.lines() {
        if line.trim_start().starts_with("```") {
            in_block = line.trim() == "```sh";
            continue;
        }
        if in_block {
            let code = line.split(" #").next().unwrap_or("").trim();
            if let Some(continued) = code.strip_suffix('\\') {
                pending.push_str(continued.trim());
                pending.push(' ');
                continue;
            }
            pending.push_str(code);
            if !pending.trim().is_empty() {
                commands.push(pending.trim().to_string());
            }
            pending.clear();
        } else {
            for (k, span) in line.split('`').enumerate() {
                if k % 2 == 1 && span.starts_with("cargo run") {
                    commands.push(span.trim().to_string());
                }
            }
        }
    }
    commands
}

/// The `rtr` arguments of a `cargo run --release -- ARGS` command; `None` for other commands.
fn rtr_args(command: &str) -> Option<Vec<String>> {
    let args = command.strip_prefix("cargo run --release -- ")?;
    Some(args.split_whitespace().map(str::to_string).collect())
}

#[test]
fn the_quick_tour_is_read_from_the_readme_as_a_user_would_type_it() {
    let readme = "# x\n## Quick tour\n\n```sh\ncargo run --release -- eval --checkpoint a \\\n    \
                  --set nominal   # one row\n\ncargo run --release --example rtr -- --no-train\n```\n\
                  Watch: `cargo run --release -- render --animate --out x.gif`.\n\n## Next\n\
                  ```sh\ncargo run --release -- train --config t.toml\n```\n";
    let commands = section_commands(readme, "## Quick tour");
    assert_eq!(
        commands,
        [
            "cargo run --release -- eval --checkpoint a --set nominal",
            "cargo run --release --example rtr -- --no-train",
            "cargo run --release -- render --animate --out x.gif",
        ]
    );
    assert_eq!(rtr_args(&commands[1]), None);
    assert_eq!(
        rtr_args(&commands[2]).unwrap(),
        ["render", "--animate", "--out", "x.gif"]
    );
}

#[test]
fn every_quick_tour_command_runs() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let readme = std::fs::read_to_string(root.join("README.md")).expect("README.md");
    let commands = section_commands(&readme, "## Quick tour");
    let tour: Vec<Vec<String>> = commands.iter().filter_map(|c| rtr_args(c)).collect();
    assert!(
        tour.len() >= 10,
        "expected the tour's commands, found {commands:?}"
    );
    let work = tempfile::tempdir().expect("temp dir");
    for shared in ["data", "models", "experiments"] {
        std::os::unix::fs::symlink(root.join(shared), work.path().join(shared))
            .expect("link into the work folder");
    }
    for args in &tour {
        let mut full = args.clone();
        full.extend(reductions(&args[0]).iter().map(|s| s.to_string()));
        let start = std::time::Instant::now();
        let out = Command::new(env!("CARGO_BIN_EXE_rtr"))
            .args(&full)
            .current_dir(work.path())
            .output()
            .expect("the rtr binary runs");
        assert!(
            out.status.success(),
            "`rtr {}` failed ({}):\n{}",
            full.join(" "),
            out.status,
            String::from_utf8_lossy(&out.stderr)
        );
        eprintln!(
            "{:6.1} s  rtr {}",
            start.elapsed().as_secs_f64(),
            full.join(" ")
        );
    }
}
