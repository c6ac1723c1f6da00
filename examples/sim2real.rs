//! `cargo run --release --example sim2real [EFFECT ...]`: the sim-to-real demonstration.
//!
//! For each catalogue effect (and for none, and for a wrong declared wheelbase), recordings
//! are generated from a "true" plant with that effect concealed under sensor noise, and the
//! tool is run on them blind. The table shows what it found, the fitted parameter against
//! the truth, and held-out position error over 5 s before and after.

use std::time::Instant;

use rtr::sim2real::{Effect, GeneratorConfig, Sim2RealOptions, Uncatalogued, generate, identify};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    rtr::allocator::tune_for_tensors();
    let wanted: Vec<String> = std::env::args().skip(1).collect();
    let device = rtr::backend::Backend::reference_device(false);
    let mut cases: Vec<(String, GeneratorConfig)> = Effect::ALL
        .iter()
        .map(|&e| {
            (
                e.name().to_string(),
                GeneratorConfig::with_effect(Some(e), 11),
            )
        })
        .collect();
    cases.push(("none".into(), GeneratorConfig::with_effect(None, 11)));
    let mut wrong_wheelbase = GeneratorConfig::with_effect(None, 11);
    wrong_wheelbase.true_wheelbase_m = 3.1;
    cases.push(("wheelbase_3.1_declared_2.8".into(), wrong_wheelbase));
    for name in Uncatalogued::NAMES {
        let physics = Uncatalogued::typical(name).expect("a known name");
        cases.push((name.into(), GeneratorConfig::with_uncatalogued(physics, 11)));
    }
    cases.retain(|(name, _)| wanted.is_empty() || wanted.contains(name));

    rtr::outln!(
        "| concealed | truth | found first | fitted | baseline RMSE (m) | final RMSE (m) | drop | noise floor (m) | unexplained | time (s) |"
    )?;
    rtr::outln!("|---|---|---|---|---|---|---|---|---|---|")?;
    for (name, config) in cases {
        let started = Instant::now();
        let recordings = generate(&config, &device);
        let report = identify(&recordings, &Sim2RealOptions::default(), &|_| {})?.report;
        let truth = match (&config.effect, config.uncatalogued) {
            (Some((e, v)), _) => pairs(e.params().iter().map(|s| s.name).zip(v.iter().copied())),
            (None, Some(physics)) => format!("{physics:?}"),
            (None, None) => format!("wheelbase {} m", config.true_wheelbase_m),
        };
        let (found, fitted) = match report.findings.first() {
            Some(f) => (
                f.name.clone(),
                match &f.equation {
                    Some(equation) => equation.clone(),
                    None => pairs(f.params.iter().map(|(k, v)| (k.as_str(), *v))),
                },
            ),
            None => (
                "nothing".into(),
                format!("wheelbase x{:.3}", report.final_model.wheelbase_scale.value),
            ),
        };
        rtr::outln!(
            "| {name} | {truth} | {found} | {fitted} | {:.3} | {:.3} | {:.0} % | {:.3} | {} | {:.0} |",
            report.baseline.heldout_pos_rmse_m,
            report.final_model.heldout_pos_rmse_m,
            report.final_model.improvement_vs_baseline_pct,
            report.unexplained.floor_pos_m,
            if report.unexplained.at_floor {
                "none".to_string()
            } else {
                format!(
                    "{:.3} m ({:.2}x floor)",
                    report.unexplained.excess_m, report.unexplained.ratio
                )
            },
            started.elapsed().as_secs_f64()
        )?;
        if std::env::var_os("RTR_VERBOSE").is_some() {
            for line in report.summary() {
                rtr::errln!("  {line}");
            }
        }
    }
    Ok(rtr::io::console::check_stdout()?)
}

/// `name value, ...` for a table cell.
fn pairs<'a>(values: impl Iterator<Item = (&'a str, f64)>) -> String {
    values
        .map(|(n, v)| format!("{n} {v:.4}"))
        .collect::<Vec<_>>()
        .join(", ")
}
