//! No result set inside another. Every output is refused inside another command's result set
//! (a training run, a model, an evaluation: [`super::claim`]); publishing a folder that holds
//! one would make it such an output after the fact, so it could never be written again
//! (`sim2real --out R` around an earlier `eval --out R/eval`). The one exception is a sweep,
//! whose folder holds the training runs of its points.

use std::path::Path;

use crate::error::{Error, Result};

/// The kind of result set (`# rtr sweep` in its record) whose folder holds training runs.
pub const SWEEP_KIND: &str = "rtr sweep";

/// Refuses to publish `target` as the result set of the command `kind` when a folder inside
/// it holds another result set.
pub fn refuse_nested_result_sets(target: &Path, kind: &str) -> Result<()> {
    super::output_tree::walk(target, |path, is_folder| {
        if !is_folder || !super::claim::is_result_set(path) {
            return Ok(true);
        }
        if kind == SWEEP_KIND && is_training_run(path) {
            return Ok(false);
        }
        Err(Error::InvalidArgument(format!(
            "{} holds {}, another rtr command's result (a training run, a model or an \
             evaluation); the results of `{kind}` are not written around it, since no command \
             could write inside them again: choose another folder, or move it out",
            target.display(),
            path.display()
        )))
    })
}

/// A training run's folder (a sweep's point).
fn is_training_run(dir: &Path) -> bool {
    dir.join("checkpoints").join("latest").exists() || dir.join("config.toml").is_file()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_folder_holding_another_result_set_is_refused_but_a_sweeps_runs_are_its_own() {
        let root = tempfile::tempdir().expect("temp dir");
        let out = root.path().join("out");
        let eval = out.join("deep/eval");
        std::fs::create_dir_all(&eval).expect("mkdir");
        std::fs::write(out.join("notes.txt"), "mine").expect("write");
        refuse_nested_result_sets(&out, "rtr sim2real").expect("plain folders");
        std::fs::write(eval.join(super::super::staged::OWN_FILES), "# rtr eval\n").expect("write");
        let err = refuse_nested_result_sets(&out, "rtr sim2real")
            .expect_err("an evaluation inside")
            .to_string();
        assert!(
            err.contains("deep/eval") && err.contains("`rtr sim2real`"),
            "{err}"
        );
        let run = root.path().join("sweep/lambda1_alpha0.5");
        std::fs::create_dir_all(run.join("checkpoints")).expect("mkdir");
        std::fs::write(run.join("config.toml"), "").expect("write");
        std::fs::write(run.join("checkpoints/latest"), "iter-000001").expect("write");
        let sweep = root.path().join("sweep");
        refuse_nested_result_sets(&sweep, SWEEP_KIND).expect("a sweep's points");
        assert!(refuse_nested_result_sets(&sweep, "rtr eval").is_err());
    }
}
