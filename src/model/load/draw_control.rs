//! Draw control's settings checked against the tables (`[draw_control]`, `[economics]`;
//! their ranges are checked with the scenario, `model::scenario::DrawControl`).
//!
//! # Rules
//! - `unknown-grade`: the shut-off column or a priced grade is not a grade column of the
//!   block model (the message lists those it has).
//! - The target table (`draw_control.target_table`): each period once (`duplicate-id`),
//!   a period of the periods table (`unknown-period`), tonnes finite and not negative
//!   (`negative`);
//!   a period it does not list has no target, which a warning counts (`no-target`).
//! - `never-open`: under the target strategy, no drawpoint's ground caves (and its
//!   `open_period` comes) within the periods, so no drawpoint ever opens and the target
//!   could never be drawn.

use super::Loader;
use crate::io::{InputWarning, Table};
use crate::model::{BlockModel, Drawpoints, Periods, Scenario};

impl Loader {
    /// The grade columns the scenario names against the block model read from `file`.
    pub(super) fn check_grade_names(&mut self, sc: &Scenario, bm: &BlockModel, file: &str) {
        let named = sc
            .draw_control
            .shutoff_column
            .iter()
            .map(|c| ("draw_control.shutoff_column", c))
            .chain(
                sc.economics
                    .iter()
                    .flat_map(|e| e.price.keys().map(|c| ("economics.price", c))),
            );
        let has = bm
            .grade_names
            .iter()
            .map(|n| format!("`{n}`"))
            .collect::<Vec<_>>()
            .join(", ");
        let missing: Vec<(&str, &String)> =
            named.filter(|(_, c)| !bm.grade_names.contains(c)).collect();
        for (key, c) in missing {
            let message = format!(
                "{key} names grade column `{c}`, which the block model does not have; it has: {has}"
            );
            self.problem(file, None, Some(c), "unknown-grade", message);
        }
    }

    /// Under the target strategy, that some drawpoint opens (its ground caves) by the
    /// last period.
    pub(super) fn check_some_open(
        &mut self,
        sc: &Scenario,
        bm: &BlockModel,
        dp: &Drawpoints,
        periods: &Periods,
        file: &str,
    ) {
        let (Some(&last), true) = (periods.id.last(), sc.draw_control.is_target()) else {
            return;
        };
        let opens = (0..dp.len()).any(|d| {
            dp.opens_at(d).is_none_or(|o| o <= last)
                && bm
                    .locate([dp.x[d], dp.y[d], dp.z[d] + 1e-6])
                    .is_some_and(|b| bm.flowable(b, last))
        });
        if !opens {
            self.problem(
                file,
                None,
                None,
                "never-open",
                format!(
                    "draw_control.strategy = \"target\": the ground above no drawpoint caves by the last period ({last}), so no drawpoint ever opens"
                ),
            );
        }
    }

    /// The target table's tonnes per period index (see the module's rules).
    pub(super) fn target(&mut self, t: &Table, periods: &Periods) -> Vec<f64> {
        let file = t.file.as_str();
        let mut out = vec![0.0; periods.len()];
        let mut listed = vec![false; periods.len()];
        let (Some(ids), Some(tonnes)) = (t.i64("period"), t.f64("tonnes")) else {
            return out;
        };
        for (i, (id, &x)) in ids.iter().zip(tonnes).enumerate() {
            let row = Some(t.row(i));
            let Some(id) = *id else { continue };
            let Some(k) = periods.find(id) else {
                self.problem(
                    file,
                    row,
                    Some(t.header("period")),
                    "unknown-period",
                    format!(
                        "period {id} is not in the periods table ({})",
                        periods.span()
                    ),
                );
                continue;
            };
            if listed[k] {
                self.problem(
                    file,
                    row,
                    Some(t.header("period")),
                    "duplicate-id",
                    format!("period {id} appears more than once"),
                );
            }
            if x < 0.0 || x.is_infinite() {
                self.problem(
                    file,
                    row,
                    Some(t.header("tonnes")),
                    "negative",
                    format!("{x} tonnes: a target must be a finite number, not negative"),
                );
            }
            listed[k] = true;
            out[k] = if x.is_finite() { x } else { 0.0 };
        }
        let missing = listed.iter().filter(|&&l| !l).count();
        if missing > 0 {
            self.warnings.push(InputWarning::new(
                file,
                "no-target",
                format!("{missing} period(s) have no target row; nothing is drawn in them"),
            ));
        }
        out
    }
}
