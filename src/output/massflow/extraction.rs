//! The period extraction report (`extraction_report.txt`), MassFlow's layout of the
//! extraction table.
//!
//! Tab-delimited. A two-line preamble: `CurPrd CurPrdName DaysSolved` and their values (the
//! last period run, its name, and the days from the start of the run to its end). Then one
//! row per row of `extraction.parquet`, in its order: `DPName`, `Period` (the number),
//! `PrdName`, `CumMass` (cum_tonnes), `RingMass` (0: no rings, see the module above),
//! `PeriodMass` (tonnes), and per grade `<grade>Mass` = PeriodMass × grade / 100, the
//! tonnes of the grade (empty where tonnes were credited but no marker was there to read
//! the grade from, 0 where nothing was drawn).

use super::{days_to_end, line, num};
use crate::engine::result::Extraction;
use crate::model::Scene;
use crate::output::trace::period_name;

/// Decimals of tonnes (0.001 t).
pub const TONNES_DECIMALS: usize = 3;
/// Decimals of grade tonnes (1e-6 t).
pub const GRADE_TONNES_DECIMALS: usize = 6;

/// The report's text.
pub fn extraction_report(scene: &Scene, ex: &Extraction) -> String {
    let periods = &scene.periods;
    let bm = &scene.blocks;
    let last = periods.id.last().copied().unwrap_or(0);
    let mut s = line(
        &["CurPrd".into(), "CurPrdName".into(), "DaysSolved".into()],
        '\t',
    );
    s += &line(
        &[
            last.to_string(),
            period_name(periods, last).to_string(),
            days_to_end(periods, last).to_string(),
        ],
        '\t',
    );
    let mut header: Vec<String> = [
        "DPName",
        "Period",
        "PrdName",
        "CumMass",
        "RingMass",
        "PeriodMass",
    ]
    .map(String::from)
    .to_vec();
    header.extend(bm.grade_names.iter().map(|g| format!("{g}Mass")));
    s += &line(&header, '\t');
    for k in 0..ex.drawpoint.len() {
        let t = ex.tonnes[k];
        let mut row = vec![
            scene.drawpoints.name[ex.drawpoint[k] as usize].clone(),
            ex.period[k].to_string(),
            period_name(periods, ex.period[k]).to_string(),
            num(ex.cum_tonnes[k], TONNES_DECIMALS),
            num(0.0, TONNES_DECIMALS),
            num(t, TONNES_DECIMALS),
        ];
        for g in &ex.grades {
            let m = if t == 0.0 { 0.0 } else { t * g[k] / 100.0 };
            row.push(num(m, GRADE_TONNES_DECIMALS));
        }
        s += &line(&row, '\t');
    }
    s
}
