//! Draw control's settings checked against the tables (`[draw_control]`, `[economics]`;
//! their ranges are checked with the scenario, `model::scenario::DrawControl`).
//!
//! # Rules
//! - `unknown-grade`: the shut-off column or a priced grade is not a grade column of the
//!   block model (the message lists those it has).
//! - `never-open`: under the target strategy, no drawpoint's ground caves (and its
//!   `open_period` comes) within the periods, so no drawpoint ever opens and the target
//!   could never be drawn.

use super::Loader;
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
}
