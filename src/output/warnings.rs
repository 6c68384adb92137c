//! A run's warnings summarised for the terminal: one line per rule, with a count, the total
//! and the worst cases, instead of one line per drawpoint or per drawpoint-period (a daily
//! mine-scale schedule raises hundreds). The full list is in `manifest.json` (`warnings`).

use crate::engine::result::{RunWarning, WarningRule};

/// How many of the worst cases a summary line names.
const WORST: usize = 3;

/// The summary lines of `warnings`, rule by rule in the order of [`WarningRule`].
pub fn summary(warnings: &[RunWarning]) -> Vec<String> {
    use WarningRule::*;
    let mut lines = Vec::new();
    for rule in [
        Stability,
        Resolution,
        Input,
        Uncaved,
        Short,
        Lagging,
        AirGap,
        MassBalance,
    ] {
        let of: Vec<&RunWarning> = warnings.iter().filter(|w| w.rule == rule).collect();
        if of.is_empty() {
            continue;
        }
        let per = per_drawpoint(&of);
        let total: f64 = per.iter().map(|p| p.2).sum();
        match rule {
            Stability | Resolution | Input | MassBalance => {
                lines.extend(of.iter().map(|w| w.message.clone()))
            }
            Uncaved => lines.push(format!(
                "{} drawpoint-periods at {} drawpoints scheduled under ground that has not caved, {} in all, nothing drawn; worst {}; see extraction.status",
                of.len(),
                per.len(),
                tonnes(total),
                worst(&per, |p| format!("{} in {} periods", tonnes(p.2), p.1))
            )),
            Short => lines.push(format!(
                "{} drawpoints short of material, {} in all, worst {}; see extraction.status and shortfall_tonnes",
                per.len(),
                tonnes(total),
                worst(&per, |p| tonnes(p.2))
            )),
            Lagging => lines.push(format!(
                "{} drawpoints' markers ran behind their credits while their lowest disks could feed them, {} in all, worst {}; credited in full, see manifest.json for each ratio",
                per.len(),
                tonnes(total),
                worst(&per, |p| tonnes(p.2))
            )),
            AirGap => lines.push(format!(
                "{} drawpoints end the run under an air gap (IMZ held under uncaved ground), {total:.3e} m³ in all, worst {}; see extraction.air_gap",
                per.len(),
                worst(&per, |p| format!("{:.3e} m³", p.2))
            )),
        }
    }
    if lines.len() < warnings.len() {
        lines.push(format!(
            "{} warnings in all: the full list is in manifest.json",
            warnings.len()
        ));
    }
    lines
}

/// (drawpoint, warnings, summed amount) per drawpoint, the largest amount first (ties by
/// name).
fn per_drawpoint(of: &[&RunWarning]) -> Vec<(String, usize, f64)> {
    let mut per: Vec<(String, usize, f64)> = Vec::new();
    for w in of {
        let name = w.drawpoint.clone().unwrap_or_default();
        match per.iter_mut().find(|p| p.0 == name) {
            Some(p) => {
                p.1 += 1;
                p.2 += w.amount;
            }
            None => per.push((name, 1, w.amount)),
        }
    }
    per.sort_by(|a, b| b.2.total_cmp(&a.2).then_with(|| a.0.cmp(&b.0)));
    per
}

/// The worst [`WORST`] drawpoints, each with `what` of it in brackets.
fn worst(per: &[(String, usize, f64)], what: impl Fn(&(String, usize, f64)) -> String) -> String {
    let mut s: Vec<String> = per
        .iter()
        .take(WORST)
        .map(|p| format!("{} ({})", p.0, what(p)))
        .collect();
    if per.len() > WORST {
        s.push(format!("and {} more", per.len() - WORST));
    }
    s.join(", ")
}

/// Tonnes in the unit that reads best: t, kt or Mt.
fn tonnes(t: f64) -> String {
    if t >= 1e6 {
        format!("{:.2} Mt", t / 1e6)
    } else if t >= 1e4 {
        format!("{:.1} kt", t / 1e3)
    } else {
        format!("{t:.1} t")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn w(rule: WarningRule, dp: &str, amount: f64) -> RunWarning {
        RunWarning {
            rule,
            drawpoint: Some(dp.into()),
            amount,
            message: format!("{dp} {amount}"),
        }
    }

    #[test]
    fn one_line_per_rule_with_count_total_and_worst() {
        let mut ws = vec![RunWarning::general(
            WarningRule::Stability,
            "stability [frag-to-width] degraded: drawpoint DP1: …".into(),
        )];
        for (dp, t) in [
            ("D01", 400.0),
            ("D02", 1_300_000.0),
            ("D03", 20.0),
            ("D04", 9_000.0),
            ("D05", 1.0),
        ] {
            ws.push(w(WarningRule::Short, dp, t));
        }
        for _ in 0..3 {
            ws.push(w(WarningRule::Uncaved, "D07", 150.0));
        }
        ws.push(w(WarningRule::Uncaved, "D08", 100.0));
        ws.push(w(WarningRule::Lagging, "D10", 2_500.0));
        ws.push(w(WarningRule::AirGap, "D09", 3.5e4));
        let lines = summary(&ws);
        assert_eq!(lines.len(), 6, "{lines:#?}");
        assert_eq!(
            lines[0],
            "stability [frag-to-width] degraded: drawpoint DP1: …"
        );
        assert_eq!(
            lines[1],
            "4 drawpoint-periods at 2 drawpoints scheduled under ground that has not caved, 550.0 t in all, nothing drawn; worst D07 (450.0 t in 3 periods), D08 (100.0 t in 1 periods); see extraction.status"
        );
        assert_eq!(
            lines[2],
            "5 drawpoints short of material, 1.31 Mt in all, worst D02 (1.30 Mt), D04 (9000.0 t), D01 (400.0 t), and 2 more; see extraction.status and shortfall_tonnes"
        );
        assert_eq!(
            lines[3],
            "1 drawpoints' markers ran behind their credits while their lowest disks could feed them, 2500.0 t in all, worst D10 (2500.0 t); credited in full, see manifest.json for each ratio"
        );
        assert!(
            lines[4].starts_with("1 drawpoints end the run under an air gap"),
            "{}",
            lines[4]
        );
        assert_eq!(
            lines[5],
            "12 warnings in all: the full list is in manifest.json"
        );
        assert!(summary(&[]).is_empty());
    }
}
