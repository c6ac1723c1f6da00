//! The one line a report ends with when its final model stays above the noise floor: what
//! was tried (the catalogue, discovery) and what it bought, and where the rest of the mismatch
//! sits (the channels furthest above their floors, and the regime holding most of the excess),
//! so a user knows what to look at next without reading the whole report.

use super::report::Report;

/// `None` when the final model is at the noise floor.
pub fn line(report: &Report) -> Option<String> {
    let unexplained = &report.unexplained;
    if unexplained.at_floor {
        return None;
    }
    let kept = if report.findings.is_empty() {
        "none kept".to_string()
    } else {
        format!("kept: {}", report.final_model.model)
    };
    // The two channels furthest above their floors (as the unexplained section lists them):
    // a speed error soon shows in heading too, so the first alone can mislead.
    let channels: Vec<String> = unexplained
        .channels
        .iter()
        .take(2)
        .map(|c| format!("{} ({:.1}x its floor)", c.channel, c.ratio))
        .collect();
    let mut remains = if channels.is_empty() {
        format!(
            "the mismatch left is {:.1}x the noise floor",
            unexplained.ratio
        )
    } else {
        format!(
            "the mismatch left is in the {} channels",
            channels.join(" and ")
        )
    };
    // The regime holding the largest share of the excess says best where to look.
    let largest = unexplained
        .regimes
        .iter()
        .max_by(|a, b| a.share_of_excess_pct.total_cmp(&b.share_of_excess_pct));
    if let Some(r) = largest {
        remains.push_str(&format!(
            ", most where {} is {} {} ({:.0} % of the excess)",
            r.variable, r.range, r.unit, r.share_of_excess_pct
        ));
    }
    Some(format!(
        "still open: tried {}; {}, {kept}; {remains}",
        catalogue_tried(report),
        discovery_tried(report),
    ))
}

/// "the catalogue's N effects (best: E, -x %)".
fn catalogue_tried(report: &Report) -> String {
    let tried = report.candidates.len();
    match report.candidates.first() {
        Some(best) => format!(
            "the catalogue's {tried} effects (best {}: -{:.1} % held-out{})",
            best.effect.name(),
            best.improvement_pct,
            if best.significant {
                ""
            } else {
                ", not significant"
            }
        ),
        None => "no catalogue effect".into(),
    }
}

/// What the open-ended stage did: off, nothing selected, or its equation and what it bought
/// through the rollout.
fn discovery_tried(report: &Report) -> String {
    if !report.options.discover {
        return "discovery kept out (--catalogue-only)".into();
    }
    let selected: Vec<String> = report
        .discovery
        .equations
        .iter()
        .filter(|e| !e.terms.is_empty())
        .map(|e| {
            format!(
                "{} (derivative residual -{:.0} %)",
                e.equation.symbol(),
                100.0 * (1.0 - e.heldout_ms_after / e.heldout_ms_before.max(1e-12))
            )
        })
        .collect();
    match (&report.discovered_candidate, selected.is_empty()) {
        (_, true) => "discovery (no library term selected)".into(),
        (Some(c), false) => format!(
            "discovery of {}: -{:.1} % held-out through the rollout",
            selected.join(" and "),
            c.improvement_pct
        ),
        (None, false) => format!("discovery of {}", selected.join(" and ")),
    }
}
