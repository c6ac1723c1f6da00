//! The paper's tables from evaluated methods: one Markdown row per method (the columns of the
//! requested sets) and `results.json` with `methods.<METHOD>.<SET>.<METRIC>` and
//! `<METRIC>_ci` (the bootstrap half-width); metrics a set cannot have (reconstruction and
//! JSD on generated sets, which have no human log) are `null`.

use serde_json::{Map, Value, json};

use super::bootstrap::Estimate;
use super::collisions::{Contact, ROLES};
use super::evaluate::SetResult;
use super::metrics::Metric;
use super::sets::EvalSet;

/// One method's evaluation on some sets.
#[derive(Debug, Clone)]
pub struct MethodResult {
    /// The table's row name (e.g. `RTR`).
    pub method: String,
    /// Where its policy came from.
    pub checkpoint: String,
    pub sets: Vec<SetResult>,
}

impl MethodResult {
    pub fn set(&self, set: EvalSet) -> Option<&SetResult> {
        self.sets.iter().find(|s| s.set == set)
    }
}

/// The metrics reported for a set: all of them where logs exist, else the infraction rates.
pub fn columns(set: EvalSet) -> Vec<Metric> {
    Metric::ALL
        .into_iter()
        .filter(|m| set.has_logs() || !m.needs_log())
        .collect()
}

/// `{scenes, agents, <metric>: value|null, <metric>_ci: half-width|null, ...}`.
pub fn set_json(r: &SetResult) -> Value {
    let mut o = Map::new();
    o.insert("scenes".into(), json!(r.scenes));
    o.insert("agents".into(), json!(r.agents));
    for m in Metric::ALL {
        let e = r.get(m);
        o.insert(m.key(), json!(e.map(|e| e.value)));
        o.insert(format!("{}_ci", m.key()), json!(e.map(|e| e.ci)));
    }
    if let Some(c) = &r.collisions {
        o.insert("first_collision_pct".into(), c.json());
        o.insert("first_collision_speeds".into(), c.speeds_json());
    }
    if let Some(realism) = &r.realism {
        let names = [
            "realism_kinematic",
            "realism_interactive",
            "realism_map",
            "realism",
        ];
        for (name, e) in names.iter().zip(realism) {
            o.insert(name.to_string(), json!(e.map(|e| e.value)));
            o.insert(format!("{name}_ci"), json!(e.map(|e| e.ci)));
        }
    }
    Value::Object(o)
}

/// `{"methods": {METHOD: {SET: {...}}}, "checkpoints": {METHOD: path}}`.
pub fn results_json(methods: &[MethodResult]) -> Value {
    let mut by_method = Map::new();
    let mut checkpoints = Map::new();
    for m in methods {
        let sets: Map<String, Value> = m
            .sets
            .iter()
            .map(|s| (s.set.name().to_string(), set_json(s)))
            .collect();
        by_method.insert(m.method.clone(), Value::Object(sets));
        checkpoints.insert(m.method.clone(), json!(m.checkpoint));
    }
    json!({ "methods": by_method, "checkpoints": checkpoints })
}

/// The digits a metric is shown with.
fn decimals(m: Metric) -> usize {
    match m {
        Metric::CollisionPct | Metric::OffroadPct | Metric::InfractionPct | Metric::HitByLogPct => {
            1
        }
        Metric::FdeM | Metric::AteM | Metric::CteM => 2,
        Metric::Jsd(_) => 3,
    }
}

/// A table column: a paper metric, or the realism score (after a set's metrics, where any row
/// has it).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Column {
    Metric(Metric),
    Realism,
}

fn set_columns(set: EvalSet, methods: &[MethodResult]) -> Vec<Column> {
    let mut out: Vec<Column> = columns(set).into_iter().map(Column::Metric).collect();
    if methods
        .iter()
        .any(|m| m.set(set).is_some_and(|r| r.realism.is_some()))
    {
        out.push(Column::Realism);
    }
    out
}

fn estimate_cell(e: Option<Estimate>, decimals: usize) -> String {
    match e {
        Some(e) => format!("{:.d$} ± {:.d$}", e.value, e.ci, d = decimals),
        None => "–".into(),
    }
}

fn cell(r: Option<&SetResult>, c: Column) -> String {
    match c {
        Column::Metric(m) => estimate_cell(r.and_then(|r| r.get(m)), decimals(m)),
        Column::Realism => estimate_cell(r.and_then(|r| r.realism.and_then(|x| x[3])), 3),
    }
}

fn header_of(set: EvalSet, c: Column, sets: &[EvalSet]) -> String {
    let name = match c {
        Column::Metric(m) => m.header(),
        Column::Realism => "Realism".into(),
    };
    if sets.len() == 1 {
        name
    } else {
        format!("{} {name}", set.name())
    }
}

/// The Markdown header and separator for `sets` (a realism column where `methods` have it).
pub fn table_header(methods: &[MethodResult], sets: &[EvalSet]) -> String {
    let headers: Vec<String> = sets
        .iter()
        .flat_map(|&s| set_columns(s, methods).into_iter().map(move |c| (s, c)))
        .map(|(s, c)| header_of(s, c, sets))
        .collect();
    format!(
        "| Method | {} |\n|---|{}\n",
        headers.join(" | "),
        "---|".repeat(headers.len())
    )
}

/// One Markdown row of `m` among `methods` (which fix the columns).
pub fn table_row(m: &MethodResult, methods: &[MethodResult], sets: &[EvalSet]) -> String {
    let cells: Vec<String> = sets
        .iter()
        .flat_map(|&s| set_columns(s, methods).into_iter().map(move |c| (s, c)))
        .map(|(s, c)| cell(m.set(s), c))
        .collect();
    format!("| {} | {} |\n", m.method, cells.join(" | "))
}

/// The whole table.
pub fn markdown_table(methods: &[MethodResult], sets: &[EvalSet]) -> String {
    let mut out = table_header(methods, sets);
    for m in methods {
        out.push_str(&table_row(m, methods, sets));
    }
    out
}

/// Whom each method's agents first collided with, per set (percent of agents; the sides are in
/// the colliding agent's frame: ahead = it drove into the other, behind = the other drove into
/// it), and how many had left the road before. Empty where no set has the breakdown.
pub fn collision_table(methods: &[MethodResult], sets: &[EvalSet]) -> String {
    let mut rows = String::new();
    for &set in sets {
        for m in methods {
            let Some(c) = m.set(set).and_then(|r| r.collisions.as_ref()) else {
                continue;
            };
            rows.push_str(&format!("| {} | {} |", set.name(), m.method));
            for (role, _) in ROLES {
                for side in Contact::ALL {
                    rows.push_str(&format!(" {:.1} |", c.share(role, side)));
                }
            }
            rows.push_str(&format!(" {:.1} |\n", c.after_offroad_pct()));
        }
    }
    if rows.is_empty() {
        return rows;
    }
    let mut head = String::from("| set | method |");
    for (_, role) in ROLES {
        for side in Contact::ALL {
            head.push_str(&format!(" {role} {} % |", side.name()));
        }
    }
    head.push_str(" after off-road % |\n|---|---|");
    head.push_str(&"---|".repeat(3 * ROLES.len() + 1));
    format!(
        "First collisions: percent of agents by the other vehicle's role and where it was \
         (ahead = the agent drove into it, behind = it drove into the agent).\n\n{head}\n{rows}"
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::metrics::SceneTally;

    fn result(set: EvalSet, collision: f64) -> SetResult {
        SetResult {
            set,
            scenes: 3,
            agents: 10,
            metrics: Metric::ALL
                .into_iter()
                .map(|m| {
                    let e = (set.has_logs() || !m.needs_log()).then_some(Estimate {
                        value: if m == Metric::CollisionPct {
                            collision
                        } else {
                            1.0
                        },
                        ci: 0.5,
                    });
                    (m, e)
                })
                .collect(),
            total: SceneTally::default(),
            realism: None,
            collisions: None,
        }
    }

    #[test]
    fn json_has_every_metric_and_its_interval() {
        let m = MethodResult {
            method: "RTR".into(),
            checkpoint: "models/rtr".into(),
            sets: vec![
                result(EvalSet::Nominal, 2.0),
                result(EvalSet::Longtail, 7.5),
            ],
        };
        let j = results_json(&[m]);
        assert_eq!(j["methods"]["RTR"]["nominal"]["collision_pct"], 2.0);
        assert_eq!(j["methods"]["RTR"]["nominal"]["jsd_lead_ci"], 0.5);
        assert_eq!(j["methods"]["RTR"]["longtail"]["collision_pct"], 7.5);
        assert!(j["methods"]["RTR"]["longtail"]["fde_m"].is_null());
        assert_eq!(j["checkpoints"]["RTR"], "models/rtr");
    }

    #[test]
    fn table_has_one_column_per_metric_of_each_set() {
        let m = MethodResult {
            method: "IL".into(),
            checkpoint: String::new(),
            sets: vec![
                result(EvalSet::Nominal, 2.0),
                result(EvalSet::Longtail, 7.5),
            ],
        };
        let sets = [EvalSet::Nominal, EvalSet::Longtail];
        let table = markdown_table(&[m], &sets);
        let lines: Vec<&str> = table.lines().collect();
        assert_eq!(lines.len(), 3);
        // Method + 11 nominal + 3 long-tail columns.
        assert_eq!(lines[0].matches('|').count(), 16);
        assert_eq!(lines[2].matches('|').count(), 16);
        assert!(lines[0].contains("longtail Any (%)"));
        assert!(lines[0].contains("longtail Col (%)"));
        assert!(lines[2].contains("7.5 ± 0.5"));
    }
}
