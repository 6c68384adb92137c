//! The periods table and the schedule: period lengths and starts, and the dense
//! schedule of tonnes per period and drawpoint.
//!
//! # Periods and schedule
//! Periods come from the periods table when one is given, else from the wide schedule's
//! headers, else (long schedule alone) from the distinct period numbers of the schedule,
//! one day each, with a warning. Duplicate (period, drawpoint) rows are summed.

use std::collections::{HashMap, HashSet};

use super::Loader;
use crate::io::{InputWarning, ScheduleTable, Table};
use crate::model::{Drawpoints, Periods, Schedule};

impl Loader {
    /// Periods from a periods table; None when a required column is missing.
    pub(super) fn periods(&mut self, t: &Table) -> Option<Periods> {
        let file = t.file.as_str();
        let mut p = Periods::default();
        let (ids, days) = (t.i64("period")?, t.f64("days")?);
        let names = t.str("name");
        let mut seen = HashSet::new();
        let mut rows = Vec::with_capacity(ids.len());
        for (i, (id, &d)) in ids.iter().zip(days).enumerate() {
            let row = Some(t.row(i));
            let Some(id) = *id else {
                continue; // reported by the reader
            };
            if !seen.insert(id) {
                self.problem(
                    file,
                    row,
                    Some(t.header("period")),
                    "duplicate-id",
                    format!("period {id} appears more than once"),
                );
            } else if let Some(&prev) = p.id.last() {
                if id <= prev {
                    self.problem(file, row, Some(t.header("period")), "period-order", format!("period {id} follows period {prev}: period numbers must strictly increase"));
                }
            }
            if d <= 0.0 {
                self.problem(
                    file,
                    row,
                    Some(t.header("days")),
                    "not-positive",
                    format!("period length {d} days must be positive"),
                );
            }
            let name = names
                .and_then(|n| n.get(i))
                .filter(|n| !n.is_empty())
                .cloned()
                .unwrap_or_else(|| id.to_string());
            p.id.push(id);
            p.name.push(name);
            p.days.push(d);
            rows.push(i);
        }
        if let Some(dates) = t.str("start_date") {
            p.start = self.period_starts(t, dates, &rows, &p.days);
        }
        Some(p)
    }

    /// Period starts (days since 1970-01-01) from the `start_date` column, for the periods
    /// read from records `rows`: the first must be given, an empty cell later follows from
    /// the previous period (start + days), and a period must not start before the previous
    /// one ends (`period-order`; a gap, such as a shutdown, is allowed). None after a
    /// problem.
    fn period_starts(
        &mut self,
        t: &Table,
        dates: &[String],
        rows: &[usize],
        days: &[f64],
    ) -> Option<Vec<f64>> {
        let file = t.file.as_str();
        let col = t.header("start_date");
        let mut start: Vec<f64> = Vec::with_capacity(rows.len());
        let mut ok = true;
        for (k, &i) in rows.iter().enumerate() {
            let row = Some(t.row(i));
            let text = dates.get(i).map(|s| s.trim()).unwrap_or("");
            let prev_end = start.last().map(|&s| s + days[k - 1]);
            let s = if text.is_empty() {
                match prev_end {
                    Some(e) => e,
                    None => {
                        if !t.bad("start_date", i) {
                            self.problem(file, row, Some(col), "missing-value", "the first period needs a start_date (later ones may follow from it)".into());
                        }
                        return None;
                    }
                }
            } else {
                match crate::model::records::parse_iso_date(text) {
                    Some(d) => d as f64,
                    None => {
                        self.problem(
                            file,
                            row,
                            Some(col),
                            "bad-date",
                            format!("`{text}` is not an ISO 8601 date (YYYY-MM-DD)"),
                        );
                        ok = false;
                        prev_end.unwrap_or(0.0)
                    }
                }
            };
            if let Some(e) = prev_end.filter(|&e| s < e) {
                self.problem(file, row, Some(col), "period-order", format!(
                    "period starts {} but the previous period runs to {} (its start plus its days): periods must not overlap",
                    crate::model::records::iso_date(s),
                    crate::model::records::iso_date(e)
                ));
                ok = false;
            }
            start.push(s);
        }
        ok.then_some(start)
    }

    /// Periods when no periods table is given: the wide form's headers, or the long form's
    /// distinct period numbers at one day each.
    pub(super) fn periods_from_schedule(&mut self, s: &ScheduleTable) -> Periods {
        if let Some(p) = &s.periods {
            return p.clone();
        }
        let mut ids: Vec<i64> = s.entries.iter().map(|e| e.period).collect();
        ids.sort_unstable();
        ids.dedup();
        self.warnings.push(InputWarning::new(
            &s.file,
            "one-day-periods",
            format!(
                "no periods table: the schedule's {} distinct period numbers are used, each one day long",
                ids.len()
            ),
        ));
        Periods {
            name: ids.iter().map(|i| i.to_string()).collect(),
            days: vec![1.0; ids.len()],
            id: ids,
            start: None,
        }
    }

    /// The dense schedule; unknown drawpoints and periods and negative tonnes are errors,
    /// and so is a cell of more tonnes than the whole block model holds (`model_tonnes`,
    /// when the block model could be read): no drawpoint can deliver that, and the engine
    /// would spend its steps on it.
    pub(super) fn schedule(
        &mut self,
        s: &ScheduleTable,
        d: &Drawpoints,
        p: &Periods,
        model_tonnes: Option<f64>,
    ) -> Schedule {
        let file = s.file.as_str();
        let dp: HashMap<&str, usize> = d
            .name
            .iter()
            .enumerate()
            .map(|(i, n)| (n.as_str(), i))
            .collect();
        let pi: HashMap<i64, usize> = p.id.iter().enumerate().map(|(i, &id)| (id, i)).collect();
        let mut out = Schedule {
            n_drawpoints: d.len(),
            tonnes: vec![0.0; d.len() * p.len()],
        };
        let mut cells = HashSet::new();
        let mut summed = 0usize;
        let mut reported_row = None;
        for e in &s.entries {
            let row = Some(e.row);
            if e.tonnes < 0.0 {
                self.problem(
                    file,
                    row,
                    Some(s.tonnes_header(e)),
                    "negative",
                    format!("{} tonnes must not be negative", e.tonnes),
                );
            } else if let Some(m) = model_tonnes.filter(|&m| e.tonnes > m) {
                self.problem(
                    file,
                    row,
                    Some(s.tonnes_header(e)),
                    "tonnes-exceed-model",
                    format!(
                        "{} t is more than the whole block model holds ({m:.4e} t in situ): check the units (kg for t?) and the value",
                        e.tonnes
                    ),
                );
            }
            let di = dp.get(e.drawpoint.as_str()).copied();
            if di.is_none() && reported_row != Some(e.row) {
                reported_row = Some(e.row);
                self.problem(
                    file,
                    row,
                    Some(&s.drawpoint_column),
                    "unknown-drawpoint",
                    format!("drawpoint `{}` is not in the drawpoints table", e.drawpoint),
                );
            }
            let pk = pi.get(&e.period).copied();
            if pk.is_none() {
                self.problem(
                    file,
                    row,
                    Some(s.period_header(e)),
                    "unknown-period",
                    format!("period {} is not in the periods table", e.period),
                );
            }
            if let (Some(di), Some(pk)) = (di, pk) {
                if !cells.insert((pk, di)) {
                    summed += 1;
                }
                if let Some(t) = out.tonnes.get_mut(pk * d.len() + di) {
                    *t += e.tonnes;
                }
            }
        }
        if summed > 0 {
            self.warnings.push(InputWarning::new(
                file,
                "summed-rows",
                format!("{summed} repeated (period, drawpoint) row(s) were summed"),
            ));
        }
        out
    }
}
