//! The draw schedule, in either of its two layouts.
//!
//! - **Long** (`period, drawpoint, tonnes`), from Parquet or text, typed against
//!   [`SCHEDULE`](crate::schema::SCHEDULE).
//! - **Wide** (MassFlow): one row per drawpoint, the drawpoint name in the first column
//!   (any header, e.g. `DPName`), then one column per period. Periods are numbered 1..n in
//!   column order. A period header is one of:
//!   - an integer `N`: the period is named `N` and lasts N days (MassFlow's integer header
//!     carries both the name and the length);
//!   - a month and year, `Sept-08`, `Sep-08`, `September 2008`, `Jan-2009` (`-`, `/`, `_`
//!     or a space between them; any month-name prefix of three or more letters): that
//!     month's length in days, leap years included, named as written. Two-digit years
//!     follow POSIX `strptime`: 69–99 are 1969–1999, 00–68 are 2000–2068;
//!   - `Name%Days`, e.g. `Q1%90.5`: the period is named `Name` and lasts `Days` days.
//!
//!   An empty cell is zero tonnes. Periods are positional, as in MassFlow: the period
//!   number is the identity and names may repeat (the manual's `DPName,7,7,7,7` is four
//!   periods, each named `7` and 7 days long).
//!
//! The layout is detected from the header: a file with a period column and a tonnes column
//! (by the long form's names and aliases) is long; anything else is wide. The wide form is
//! read from delimited text only, as MassFlow writes it.

use std::path::Path;

use super::problem::{Collector, InputWarning, Problem, Problems};
use super::read::{read_bytes, read_table_into, read_text};
use super::table::{
    file_name, is_parquet, names_field, not_a_number, parse_f64, sha256_hex, Cell, Table,
};
use super::text::Text;
use super::Periods;
use crate::schema::SCHEDULE;

/// Which layout a schedule file had.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScheduleForm {
    /// One row per (period, drawpoint).
    Long,
    /// MassFlow: one row per drawpoint, one column per period.
    Wide,
}

/// One scheduled draw as read, before it is joined to drawpoints and periods.
#[derive(Debug, Clone, PartialEq)]
pub struct ScheduleEntry {
    /// 1-based data row of the file.
    pub row: usize,
    /// Index into [`ScheduleTable::columns`] of the column holding the tonnes.
    pub column: usize,
    /// Period number.
    pub period: i64,
    /// Drawpoint name.
    pub drawpoint: String,
    /// Tonnes to draw.
    pub tonnes: f64,
}

/// A schedule file, read and typed.
#[derive(Debug, Clone)]
pub struct ScheduleTable {
    /// File name for messages.
    pub file: String,
    /// SHA-256 of the file, hex.
    pub sha256: String,
    /// Number of data rows in the file.
    pub rows: usize,
    /// Layout found.
    pub form: ScheduleForm,
    /// Periods named by the wide form's headers (None for the long form).
    pub periods: Option<Periods>,
    /// Headers of the file, as written.
    pub columns: Vec<String>,
    /// Header of the drawpoint column.
    pub drawpoint_column: String,
    /// Header of the period column (long form only).
    pub period_column: Option<String>,
    /// Every (period, drawpoint, tonnes) cell, in file order.
    pub entries: Vec<ScheduleEntry>,
    /// Non-fatal remarks.
    pub warnings: Vec<InputWarning>,
}

impl ScheduleTable {
    /// Header of the column holding an entry's tonnes.
    pub fn tonnes_header(&self, e: &ScheduleEntry) -> &str {
        self.columns
            .get(e.column)
            .map(String::as_str)
            .unwrap_or("tonnes")
    }

    /// Header of the column naming an entry's period (the tonnes column in the wide form).
    pub fn period_header(&self, e: &ScheduleEntry) -> &str {
        self.period_column
            .as_deref()
            .unwrap_or_else(|| self.tonnes_header(e))
    }
}

/// Reads a schedule in the long or the wide (MassFlow) form; see the module docs.
pub fn read_schedule(path: &Path) -> Result<ScheduleTable, Problems> {
    let mut problems = Collector::default();
    let t = read_schedule_into(path, &mut problems);
    problems.into_result(t)
}

/// [`read_schedule`] that records problems into `problems` and still returns the entries
/// that could be read.
pub(crate) fn read_schedule_into(path: &Path, problems: &mut Collector) -> Option<ScheduleTable> {
    if is_parquet(path) {
        return read_table_into(path, &SCHEDULE, problems).map(from_long);
    }
    let file = file_name(path);
    let bytes = read_bytes(path, &file, problems)?;
    schedule_text(&file, bytes, problems)
}

/// [`read_schedule`] of delimited text already in memory (`file` names it in messages).
pub fn read_schedule_bytes(file: &str, bytes: Vec<u8>) -> Result<ScheduleTable, Problems> {
    let mut problems = Collector::default();
    let t = schedule_text(file, bytes, &mut problems);
    problems.into_result(t)
}

/// A text schedule in either form.
fn schedule_text(file: &str, bytes: Vec<u8>, problems: &mut Collector) -> Option<ScheduleTable> {
    let sha256 = sha256_hex(&bytes);
    let text = Text::new(file, bytes);
    let headers = text.headers(problems)?;
    let field = |name: &str| {
        SCHEDULE
            .field(name)
            .is_some_and(|f| headers.iter().any(|h| names_field(h.trim(), f)))
    };
    if field("period") && field("tonnes") {
        read_text(&text, &SCHEDULE, problems).map(|t| from_long(Table { sha256, ..t }))
    } else {
        read_wide(&text, &headers, sha256, problems)
    }
}

/// The entries of a long-form table.
fn from_long(t: Table) -> ScheduleTable {
    let (period, drawpoint, tonnes) = (t.i64("period"), t.str("drawpoint"), t.f64("tonnes"));
    let mut entries = Vec::with_capacity(t.len());
    if let (Some(period), Some(drawpoint), Some(tonnes)) = (period, drawpoint, tonnes) {
        for (i, ((p, d), w)) in period.iter().zip(drawpoint).zip(tonnes).enumerate() {
            // Rows with a missing period or drawpoint were reported by the reader.
            if let (Some(p), false) = (p, d.is_empty()) {
                entries.push(ScheduleEntry {
                    row: t.row(i),
                    column: 2,
                    period: *p,
                    drawpoint: d.clone(),
                    tonnes: *w,
                });
            }
        }
    }
    ScheduleTable {
        file: t.file.clone(),
        sha256: t.sha256.clone(),
        rows: t.len(),
        form: ScheduleForm::Long,
        periods: None,
        columns: ["period", "drawpoint", "tonnes"]
            .iter()
            .map(|c| t.header(c).to_string())
            .collect(),
        drawpoint_column: t.header("drawpoint").to_string(),
        period_column: Some(t.header("period").to_string()),
        entries,
        warnings: t.warnings,
    }
}

fn read_wide(
    text: &Text,
    headers: &[String],
    sha256: String,
    problems: &mut Collector,
) -> Option<ScheduleTable> {
    let file = text.file.as_str();
    let columns: Vec<String> = headers.iter().map(|h| h.trim().to_string()).collect();
    let Some(dp_column) = columns.first().filter(|_| columns.len() >= 2).cloned() else {
        problems.push(Problem::at(
            file,
            Some(0),
            None,
            "missing-column",
            "a schedule needs either period, drawpoint and tonnes columns (long form) or a drawpoint column followed by one column per period (MassFlow wide form)",
        ));
        return None;
    };
    let mut periods = Periods::default();
    for (k, h) in columns.iter().enumerate().skip(1) {
        match parse_period_header(h) {
            Ok((name, days)) => {
                periods.id.push(k as i64);
                periods.name.push(name);
                periods.days.push(days);
            }
            Err(message) => problems.push(Problem::at(
                file,
                Some(0),
                Some(h),
                "period-header",
                message,
            )),
        }
    }
    let mut entries = Vec::new();
    let (rows, skipped) = text.rows(headers, problems, |row, cells, problems| {
        let drawpoint = match cells.first() {
            Some(Cell::Text(s)) => s.to_string(),
            Some(Cell::Null) => {
                let message = "the drawpoint name is empty";
                problems.push(Problem::at(
                    file,
                    Some(row),
                    Some(&dp_column),
                    "missing-value",
                    message,
                ));
                return;
            }
            _ => return,
        };
        for (k, cell) in cells.iter().enumerate().skip(1) {
            let header = columns.get(k).map(String::as_str);
            let mut report =
                |rule, message| problems.push(Problem::at(file, Some(row), header, rule, message));
            let tonnes = match cell {
                Cell::Null => 0.0,
                Cell::Text(s) => match parse_f64(s) {
                    Some(x) if x.is_finite() => x,
                    Some(_) => {
                        report("not-finite", format!("`{s}` is not a finite number"));
                        continue;
                    }
                    None => {
                        report("mistyped", not_a_number(s));
                        continue;
                    }
                },
                _ => continue,
            };
            entries.push(ScheduleEntry {
                row,
                column: k,
                period: k as i64,
                drawpoint: drawpoint.clone(),
                tonnes,
            });
        }
    });
    if rows == skipped.len() {
        let message = "the schedule has a header but no drawpoint rows";
        problems.push(Problem::file(file, "empty-table", message));
    }
    let mut warnings = Vec::new();
    if let Some(first) = skipped.first() {
        warnings.push(InputWarning::new(
            file,
            "empty-rows",
            format!(
                "skipped {} empty row(s), the first at row {first}",
                skipped.len()
            ),
        ));
    }
    Some(ScheduleTable {
        file: file.to_string(),
        sha256,
        rows,
        form: ScheduleForm::Wide,
        periods: Some(periods),
        drawpoint_column: dp_column,
        columns,
        period_column: None,
        entries,
        warnings,
    })
}

const MONTHS: [&str; 12] = [
    "january",
    "february",
    "march",
    "april",
    "may",
    "june",
    "july",
    "august",
    "september",
    "october",
    "november",
    "december",
];

/// Name and length in days of a wide-schedule period header; see the module docs.
pub fn parse_period_header(h: &str) -> Result<(String, f64), String> {
    let h = h.trim();
    if let Some((name, days)) = h.rsplit_once('%') {
        let name = name.trim();
        return match parse_f64(days) {
            Some(d) if d.is_finite() && d > 0.0 && !name.is_empty() => Ok((name.to_string(), d)),
            _ => Err(format!(
                "period header `{h}`: expected Name%Days with a name and a positive number of days"
            )),
        };
    }
    if !h.is_empty() && h.bytes().all(|b| b.is_ascii_digit()) {
        return match h.parse::<u32>() {
            Ok(n) if n > 0 => Ok((h.to_string(), n as f64)),
            _ => Err(format!(
                "period header `{h}`: an integer header is the period's length in days and must be positive"
            )),
        };
    }
    if let Some(days) = month_days(h) {
        return Ok((h.to_string(), days as f64));
    }
    Err(format!(
        "cannot read the period header `{h}`: expected an integer (days), a month such as Sept-08 or Jan-2009, or Name%Days such as Q1%90.5"
    ))
}

/// Days in the month a header such as `Sept-08` or `Feb 2012` names.
fn month_days(h: &str) -> Option<u32> {
    let (mon, year) = h.split_once(['-', ' ', '/', '_'])?;
    let mon = mon.trim().to_ascii_lowercase();
    let year = year.trim();
    if mon.len() < 3 || !year.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    let m = MONTHS.iter().position(|full| full.starts_with(&mon))?;
    let y: u32 = match (year.len(), year.parse::<u32>().ok()?) {
        (2, y) if y >= 69 => 1900 + y,
        (2, y) => 2000 + y,
        (4, y) => y,
        _ => return None,
    };
    let leap = (y % 4 == 0 && y % 100 != 0) || y % 400 == 0;
    Some(match m {
        1 if leap => 29,
        1 => 28,
        3 | 5 | 8 | 10 => 30,
        _ => 31,
    })
}
