//! Reading a table: from Parquet (`io::parquet`) or delimited text (`io::text`), each
//! row typed and checked by the table's plan (`io::table`).

use std::path::Path;

use super::problem::{Collector, InputWarning, Problem, Problems};
use super::table::{file_name, is_parquet, sha256_hex, Plan, Table};
use super::text::Text;
use crate::schema::TableSpec;

/// Reads a table from Parquet (`.parquet`, `.pq`) or delimited text (anything else) and
/// types it against `spec`.
///
/// Header names match a field's canonical name or any alias, case-insensitively. Columns
/// that match no field become grade columns ([`Table::extra`]) when the spec has extra
/// columns, and must then be numeric (`mistyped` otherwise); for other specs they are
/// ignored with a warning. Documented MassFlow columns caveflow does not use
/// ([`TableSpec::massflow_unused`]) are skipped with one note for the file. A drawpoint or
/// drawbell file with MassFlow's column count and unfamiliar headers is read by position
/// ([`TableSpec::massflow_layout`]), with a note. Every problem in the file is reported,
/// not just the first.
pub fn read_table(path: &Path, spec: &TableSpec) -> Result<Table, Problems> {
    let mut problems = Collector::default();
    let t = read_table_into(path, spec, &mut problems);
    problems.into_result(t)
}

/// [`read_table`] of delimited text already in memory (`file` names it in messages). The
/// fuzz harness drives the text readers through this, without a file system round trip.
pub fn read_table_bytes(file: &str, bytes: Vec<u8>, spec: &TableSpec) -> Result<Table, Problems> {
    let mut problems = Collector::default();
    let sha256 = sha256_hex(&bytes);
    let t = read_text(&Text::new(file, bytes), spec, &mut problems);
    problems.into_result(t.map(|t| Table { sha256, ..t }))
}

/// [`read_table`] that records problems into `problems` and still returns whatever could be
/// read (None only when not even a header could), so that later checks can run on the
/// readable cells. Unreadable cells are missing values, marked in `Table::bad`.
pub(crate) fn read_table_into(
    path: &Path,
    spec: &TableSpec,
    problems: &mut Collector,
) -> Option<Table> {
    let file = file_name(path);
    if is_parquet(path) {
        return super::parquet::read(path, &file, spec, problems);
    }
    let bytes = read_bytes(path, &file, problems)?;
    let sha256 = sha256_hex(&bytes);
    read_text(&Text::new(&file, bytes), spec, problems).map(|t| Table { sha256, ..t })
}

/// The bytes of a file; None after an `unreadable` problem.
pub(crate) fn read_bytes(path: &Path, file: &str, problems: &mut Collector) -> Option<Vec<u8>> {
    std::fs::read(path)
        .map_err(|e| {
            let message = format!("cannot read {}: {e}", path.display());
            problems.push(Problem::file(file, "unreadable", message))
        })
        .ok()
}

/// Reads delimited text already loaded into `text`.
pub(crate) fn read_text(text: &Text, spec: &TableSpec, problems: &mut Collector) -> Option<Table> {
    let headers = text.headers(problems)?;
    let mut plan = Plan::new(&text.file, &headers, spec, problems);
    let mut row_numbers = Vec::new();
    let (_, skipped) = text.rows(&headers, problems, |row, cells, problems| {
        plan.push_row(row, cells, problems);
        row_numbers.push(row);
    });
    if let Some(first) = skipped.first() {
        plan.warnings.push(InputWarning::new(
            &text.file,
            "empty-rows",
            format!(
                "skipped {} empty row(s), the first at row {first}",
                skipped.len()
            ),
        ));
    }
    Some(plan.finish(problems, row_numbers))
}
