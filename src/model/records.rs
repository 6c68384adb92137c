//! Production records for back-analysis: what each drawpoint actually delivered and what
//! its samples assayed, read from the `production` table (schemas/production.json) and
//! checked against a run's drawpoints, periods and grades.
//!
//! # Table
//! One row per sample: `drawpoint`, `period` or `date` (or both), `tonnes`, optional
//! `frag_size` (sampled mean fragment size, m), and one column per sampled grade (% by
//! mass), named like the block model's grade columns (case-insensitively; `Mo` matches
//! `mo`). Parquet or CSV, read by the same reader as every input
//! ([`read_table`](crate::io::read_table)), so the cell rules (`not-finite`, `mistyped`,
//! `missing-value`, …) are the same.
//!
//! # Rules
//! Each problem names the file, the data row, the column and the rule:
//! - `unknown-drawpoint`: a drawpoint not in the drawpoints table;
//! - `unknown-period`: a period number not among the run's periods, or a date outside them
//!   (when the periods have start dates);
//! - `bad-date`: a date that is not ISO 8601 (`YYYY-MM-DD`, optionally followed by a time,
//!   which is ignored);
//! - `no-period`: a row with neither a period nor a date (`missing-column` when the file
//!   has neither column);
//! - `period-date-mismatch`: a row whose period and date name different periods;
//! - `negative`: negative tonnes;
//! - `not-finite`: NaN or infinite tonnes, grade or fragment size (from the reader: a
//!   literal `NaN` is an error; an empty grade or fragment size cell is allowed and means
//!   *not sampled*);
//! - `missing-value`: empty tonnes (from the reader);
//! - `grade-range`: a grade outside [0, 100] %;
//! - `unknown-grade`: a numeric column that is not a grade of the block model. This is an
//!   error, not a warning: a misspelt grade column would otherwise drop out of the
//!   reconciliation without a word. The message lists the block model's grades;
//! - `not-positive` and `units-mm`: a sampled fragment size that is not positive, or above
//!   10 m (millimetres).
//!
//! Rows are kept as given: several rows of one drawpoint and period are several samples
//! (shifts, say), not summed.
//!
//! # Dates
//! A row with a date and no period gets its period from the periods' start dates
//! ([`Periods::start`], the periods table's optional `start_date` column). Without start
//! dates a dated row keeps `period = None`, to be matched by cumulative tonnes instead.

use std::collections::HashMap;
use std::path::Path;

use crate::io::{read_table_into, Collector, Problem, Problems, Table};
use crate::model::block_model::MAX_FRAG_SIZE;
use crate::model::{Drawpoints, Periods};
use crate::schema::PRODUCTION;

/// Production records, column-wise: one entry per row of the records file.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ProductionRecords {
    /// File name the records came from (for messages).
    pub file: String,
    /// Data row (1-based, as in messages) of each record in the file.
    pub row: Vec<usize>,
    /// Drawpoint, as an index into the run's [`Drawpoints`].
    pub drawpoint: Vec<usize>,
    /// Period number (`Periods::id`, the `period` column of the run's outputs): as given,
    /// or mapped from the date; None for a dated record when the periods have no start
    /// dates (match it by cumulative tonnes).
    pub period: Vec<Option<i64>>,
    /// Date as `YYYY-MM-DD` (normalised from the file; any time of day dropped); None when
    /// the row gave none.
    pub date: Vec<Option<String>>,
    /// Tonnes produced, t.
    pub tonnes: Vec<f64>,
    /// The sampled grades the file has, as the block model names them, in the block
    /// model's order.
    pub grade_names: Vec<String>,
    /// `grades[g][row]`, % by mass; NaN = not sampled.
    pub grades: Vec<Vec<f64>>,
    /// Sampled mean fragment size per row, m (NaN = not sampled); None when the file has
    /// no `frag_size` column.
    pub frag: Option<Vec<f64>>,
}

impl ProductionRecords {
    /// Number of records.
    pub fn len(&self) -> usize {
        self.tonnes.len()
    }
    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.tonnes.is_empty()
    }
    /// The sampled values of a grade (by the block model's name), if the file has it.
    pub fn grade(&self, name: &str) -> Option<&[f64]> {
        let g = self.grade_names.iter().position(|n| n == name)?;
        Some(&self.grades[g])
    }
}

/// Days from 1970-01-01 to a civil date (proleptic Gregorian; H. Hinnant's algorithm).
pub fn days_from_civil(y: i64, m: u32, d: u32) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (i64::from(m) + 9) % 12;
    let doy = (153 * mp + 2) / 5 + i64::from(d) - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// The civil date of a day number (days since 1970-01-01).
pub fn civil_from_days(z: i64) -> (i64, u32, u32) {
    let z = z + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    (yoe + era * 400 + i64::from(m <= 2), m, d)
}

/// Parses an ISO 8601 calendar date `YYYY-MM-DD` (a trailing time after `T` or a space is
/// allowed and ignored) into days since 1970-01-01; None when it is not a real date.
pub fn parse_iso_date(s: &str) -> Option<i64> {
    let s = s.trim();
    let date = s.split(['T', ' ']).next()?;
    let mut it = date.split('-');
    let (y, m, d) = (it.next()?, it.next()?, it.next()?);
    if it.next().is_some() || y.len() != 4 || m.len() != 2 || d.len() != 2 {
        return None;
    }
    let all_digits = |t: &str| t.bytes().all(|b| b.is_ascii_digit());
    if !(all_digits(y) && all_digits(m) && all_digits(d)) {
        return None;
    }
    let (y, m, d): (i64, u32, u32) = (y.parse().ok()?, m.parse().ok()?, d.parse().ok()?);
    if !(1..=12).contains(&m) || d == 0 {
        return None;
    }
    let days = days_from_civil(y, m, d);
    // Reject 2009-02-30 and friends: the day must round-trip.
    (civil_from_days(days) == (y, m, d)).then_some(days)
}

/// The ISO date (`YYYY-MM-DD`) of a day number; a fractional day is floored.
pub fn iso_date(day: f64) -> String {
    let (y, m, d) = civil_from_days(day.floor() as i64);
    format!("{y:04}-{m:02}-{d:02}")
}

/// Reads production records (Parquet or CSV) and checks them against the run's drawpoints,
/// periods and grade columns (the block model's `grade_names`). See the module docs for the
/// rules; every problem in the file is returned, each with its file, row, column and rule.
pub fn load_records(
    path: &Path,
    drawpoints: &Drawpoints,
    periods: &Periods,
    grade_names: &[String],
) -> Result<ProductionRecords, Problems> {
    let mut problems = Collector::default();
    let r = read_table_into(path, &PRODUCTION, &mut problems)
        .map(|t| check_records(&t, drawpoints, periods, grade_names, &mut problems));
    problems.into_result(r)
}

/// Problems of one records file, capped per rule and column like every input's.
struct Found<'a> {
    file: String,
    c: &'a mut Collector,
}

impl Found<'_> {
    fn push(&mut self, row: usize, column: &str, rule: &'static str, message: String) {
        self.c.push(Problem::at(
            &self.file,
            Some(row),
            Some(column),
            rule,
            message,
        ));
    }
}

/// The checks of [`load_records`] on a table as read (cells the reader reported are
/// missing values here, and are not reported again).
fn check_records(
    t: &Table,
    drawpoints: &Drawpoints,
    periods: &Periods,
    grade_names: &[String],
    problems: &mut Collector,
) -> ProductionRecords {
    let file = t.file.clone();
    let n = t.len();
    let mut f = Found {
        file: file.clone(),
        c: problems,
    };
    let (has_period, has_date) = (t.has("period"), t.has("date"));
    if !has_period && !has_date {
        f.c.push(Problem::at(
            &file,
            None,
            Some("period"),
            "missing-column",
            "production records need a period column (Period) or a date column (Date), or both",
        ));
    }
    // Grade columns: each must be a grade of the block model.
    let mut grade_cols: Vec<(usize, &crate::io::ExtraColumn)> = Vec::new();
    for col in &t.extra {
        match grade_names
            .iter()
            .position(|g| g.eq_ignore_ascii_case(col.name.trim()))
        {
            Some(g) => grade_cols.push((g, col)),
            None => {
                let known = if grade_names.is_empty() {
                    "it has none".to_string()
                } else {
                    format!(
                        "it has: {}",
                        grade_names
                            .iter()
                            .map(|g| format!("`{g}`"))
                            .collect::<Vec<_>>()
                            .join(", ")
                    )
                };
                f.c.push(Problem::at(
                    &file,
                    Some(0),
                    Some(&col.name),
                    "unknown-grade",
                    format!(
                        "column `{}` is not a grade of the block model ({known}); rename it to the block model's grade or remove it",
                        col.name
                    ),
                ));
            }
        }
    }
    grade_cols.sort_by_key(|(g, _)| *g);

    let names = t.str("drawpoint").unwrap_or(&[]);
    let pcol = t.i64("period");
    let dcol = t.str("date");
    let tonnes = t.f64("tonnes").unwrap_or(&[]);
    let frag = t.f64("frag_size");
    let dp: HashMap<&str, usize> = drawpoints
        .name
        .iter()
        .enumerate()
        .map(|(i, n)| (n.as_str(), i))
        .collect();
    let span = periods.span();
    let mut r = ProductionRecords {
        file: file.clone(),
        grade_names: grade_cols
            .iter()
            .map(|(g, _)| grade_names[*g].clone())
            .collect(),
        grades: vec![Vec::with_capacity(n); grade_cols.len()],
        frag: frag.map(|_| Vec::with_capacity(n)),
        ..ProductionRecords::default()
    };
    for i in 0..n {
        let row = t.row(i);
        // Drawpoint.
        let name = names.get(i).map(String::as_str).unwrap_or("");
        let d = match dp.get(name) {
            Some(&d) => d,
            None => {
                if !name.is_empty() {
                    f.push(
                        row,
                        t.header("drawpoint"),
                        "unknown-drawpoint",
                        format!("drawpoint `{name}` is not in the drawpoints table"),
                    );
                }
                usize::MAX
            }
        };
        // Period and date.
        let given = pcol.and_then(|p| p.get(i).copied().flatten());
        if let Some(p) = given {
            if periods.find(p).is_none() {
                f.push(
                    row,
                    t.header("period"),
                    "unknown-period",
                    format!("period {p} is not one of the run's periods ({span})"),
                );
            }
        }
        let text = dcol
            .and_then(|c| c.get(i))
            .map(|s| s.trim())
            .filter(|s| !s.is_empty());
        let mut date = None;
        let mut from_date = None;
        if let Some(text) = text {
            match parse_iso_date(text) {
                None => f.push(
                    row,
                    t.header("date"),
                    "bad-date",
                    format!("`{text}` is not an ISO 8601 date (YYYY-MM-DD)"),
                ),
                Some(day) => {
                    date = Some(iso_date(day as f64));
                    if let Some(start) = &periods.start {
                        match periods.at_day(day as f64) {
                            Some(k) => from_date = Some(periods.id[k]),
                            None => {
                                let (first, last) = (
                                    start[0],
                                    start[start.len() - 1] + periods.days[start.len() - 1],
                                );
                                f.push(
                                    row,
                                    t.header("date"),
                                    "unknown-period",
                                    format!(
                                        "date {text} falls in none of the run's periods (they run from {} to before {})",
                                        iso_date(first),
                                        iso_date(last)
                                    ),
                                );
                            }
                        }
                    }
                }
            }
        }
        if let (Some(p), Some(q)) = (given, from_date) {
            if p != q {
                f.push(
                    row,
                    t.header("date"),
                    "period-date-mismatch",
                    format!(
                        "date {} lies in period {q}, but the row gives period {p}",
                        text.unwrap_or("")
                    ),
                );
            }
        }
        let period_bad = pcol.is_some_and(|_| t.bad("period", i));
        let date_bad = dcol.is_some_and(|_| t.bad("date", i));
        if given.is_none() && text.is_none() && !period_bad && !date_bad {
            let column = if has_period {
                t.header("period")
            } else {
                t.header("date")
            };
            f.push(
                row,
                column,
                "no-period",
                "the row has neither a period nor a date".into(),
            );
        }
        // Tonnes.
        let tn = tonnes.get(i).copied().unwrap_or(f64::NAN);
        if tn < 0.0 {
            f.push(
                row,
                t.header("tonnes"),
                "negative",
                format!("{tn} tonnes must not be negative"),
            );
        }
        // Grades.
        for (k, (_, col)) in grade_cols.iter().enumerate() {
            let v = col.values[i];
            if !v.is_nan() && !(0.0..=100.0).contains(&v) {
                f.push(
                    row,
                    &col.name,
                    "grade-range",
                    format!("grade {} {v} % is outside [0, 100] %", col.name),
                );
            }
            r.grades[k].push(v);
        }
        // Sampled fragment size.
        if let (Some(fr), Some(out)) = (frag, r.frag.as_mut()) {
            let v = fr[i];
            if v <= 0.0 {
                f.push(
                    row,
                    t.header("frag_size"),
                    "not-positive",
                    format!("sampled fragment size {v} m must be positive"),
                );
            } else if v > MAX_FRAG_SIZE {
                f.push(row, t.header("frag_size"), "units-mm", format!(
                    "sampled fragment size {v} m is not plausible (more than {MAX_FRAG_SIZE} m): it looks like mm; divide by 1000 ({} m)",
                    v / 1000.0
                ));
            }
            out.push(v);
        }
        r.row.push(row);
        r.drawpoint.push(d);
        r.period.push(given.or(from_date));
        r.date.push(date);
        r.tonnes.push(tn);
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn iso_dates_round_trip() {
        assert_eq!(parse_iso_date("1970-01-01"), Some(0));
        assert_eq!(parse_iso_date("2009-01-01"), Some(14_245));
        assert_eq!(parse_iso_date("2000-02-29"), Some(11_016));
        assert_eq!(parse_iso_date("2009-02-29"), None);
        assert_eq!(parse_iso_date("2009-13-01"), None);
        assert_eq!(parse_iso_date("2009-1-01"), None);
        assert_eq!(parse_iso_date("01/02/2009"), None);
        assert_eq!(parse_iso_date("2009-03-04T07:30:00Z"), Some(14_307));
        assert_eq!(parse_iso_date("2009-03-04 07:30"), Some(14_307));
        for d in [-800_000, -1, 0, 59, 11_016, 14_245, 2_000_000] {
            let (y, m, dd) = civil_from_days(d);
            assert_eq!(days_from_civil(y, m, dd), d);
        }
        assert_eq!(iso_date(14_245.5), "2009-01-01");
    }
}
