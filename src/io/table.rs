//! The generic table reader: any [`TableSpec`] from Parquet or delimited text, typed and
//! checked cell by cell.
//!
//! # Cells
//! - Numbers must be finite: `NaN`, `inf` and friends are `not-finite`.
//! - An empty cell in a required column is `missing-value`. In an optional column it is
//!   missing: NaN in a float column (unambiguous, since NaN is never accepted as data),
//!   `None` in an integer column, `""` in a text column. Grade (extra) columns follow the
//!   optional rule; whoever uses them decides whether a gap is allowed.
//! - Integer columns accept floats with an integral value (`3.0`); `3.5` is `mistyped`.
//!   Float columns accept integers. Text columns accept numbers as written.
//! - Parquet columns of any integer or float width, or of text, are read; other Arrow types
//!   (dates, booleans, decimals) are read through their text form, so that a `Date32` date
//!   column arrives as ISO text.

use std::path::Path;

use sha2::{Digest, Sha256};

use super::problem::{Collector, InputWarning, Problem};
use crate::schema::{FieldSpec, Kind, TableSpec};

/// One typed column.
#[derive(Debug, Clone, PartialEq)]
pub enum Column {
    /// Float column; NaN marks a missing value (only possible in optional columns).
    F64(Vec<f64>),
    /// Integer column; None marks a missing value.
    I64(Vec<Option<i64>>),
    /// Text column; `""` marks a missing value.
    Str(Vec<String>),
}

/// A numeric column beyond the spec's fixed fields: a grade.
#[derive(Debug, Clone, PartialEq)]
pub struct ExtraColumn {
    /// Header as written in the file.
    pub name: String,
    /// Values; NaN where the cell was empty.
    pub values: Vec<f64>,
}

/// A table read and typed against a [`TableSpec`].
#[derive(Debug, Clone)]
pub struct Table {
    /// File name (last path component) for messages.
    pub file: String,
    /// SHA-256 of the file's bytes, lower-case hex.
    pub sha256: String,
    /// Extra (grade) columns, in file order, for specs that allow them.
    pub extra: Vec<ExtraColumn>,
    /// Things worth telling the user that are not errors (ignored columns, skipped rows).
    pub warnings: Vec<InputWarning>,
    /// (canonical name, header as written, values) of every fixed field found.
    pub(crate) columns: Vec<(&'static str, String, Column)>,
    /// Data row number of every record.
    pub(crate) row_numbers: Vec<usize>,
    /// Per column (canonical name, or header for grades): the records whose cell was
    /// reported as unreadable, in order.
    pub(crate) bad: Vec<(String, Vec<usize>)>,
}

impl Table {
    /// Number of data rows.
    pub fn len(&self) -> usize {
        self.row_numbers.len()
    }

    /// True when the table has no rows.
    pub fn is_empty(&self) -> bool {
        self.row_numbers.is_empty()
    }

    /// Data row number (1-based, as in messages) of record `i`. Differs from `i + 1` when
    /// blank rows were skipped.
    pub fn row(&self, i: usize) -> usize {
        self.row_numbers.get(i).copied().unwrap_or(i + 1)
    }

    /// Whether record `i` of a column (canonical name, or header for grades) held a cell
    /// the reader already reported, so that later checks need not report it again.
    pub(crate) fn bad(&self, name: &str, i: usize) -> bool {
        self.bad
            .iter()
            .any(|(n, rows)| n == name && rows.binary_search(&i).is_ok())
    }

    fn column(&self, name: &str) -> Option<&Column> {
        self.columns.iter().find(|c| c.0 == name).map(|c| &c.2)
    }

    /// Whether the file has a column for this canonical field.
    pub fn has(&self, name: &str) -> bool {
        self.column(name).is_some()
    }

    /// The header the file uses for a canonical field (e.g. `InSituPor` for `porosity`), or
    /// the canonical name when the column is absent.
    pub fn header<'a>(&'a self, name: &'a str) -> &'a str {
        self.columns
            .iter()
            .find(|c| c.0 == name)
            .map(|c| c.1.as_str())
            .unwrap_or(name)
    }

    /// A float column by canonical name; None when absent.
    pub fn f64(&self, name: &str) -> Option<&[f64]> {
        match self.column(name)? {
            Column::F64(v) => Some(v),
            _ => None,
        }
    }

    /// An integer column by canonical name; None when absent.
    pub fn i64(&self, name: &str) -> Option<&[Option<i64>]> {
        match self.column(name)? {
            Column::I64(v) => Some(v),
            _ => None,
        }
    }

    /// A text column by canonical name; None when absent.
    pub fn str(&self, name: &str) -> Option<&[String]> {
        match self.column(name)? {
            Column::Str(v) => Some(v),
            _ => None,
        }
    }
}

/// One cell as a reader found it, before typing.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Cell<'a> {
    /// Empty or null.
    Null,
    /// Text to parse.
    Text(&'a str),
    /// An integer (Parquet).
    Int(i64),
    /// A float (Parquet).
    Float(f64),
    /// A cell already reported as unreadable.
    Invalid,
}

/// File name for messages: the last path component.
pub(crate) fn file_name(path: &Path) -> String {
    path.file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.display().to_string())
}

/// Whether a path names a Parquet file (`.parquet` or `.pq`, any case).
pub(crate) fn is_parquet(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("parquet") || e.eq_ignore_ascii_case("pq"))
}

/// Hex SHA-256 of some bytes.
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// Whether `header` names `field` (canonical name or an alias, case-insensitively).
pub(crate) fn names_field(header: &str, field: &FieldSpec) -> bool {
    header.eq_ignore_ascii_case(field.name)
        || field.aliases.iter().any(|a| header.eq_ignore_ascii_case(a))
}

/// What to do with each column of a file.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Target {
    /// A fixed field of the spec.
    Field(&'static FieldSpec),
    /// A grade column.
    Extra,
    /// Not read.
    Ignored,
}

/// The column plan of one file: which header feeds which builder.
pub(crate) struct Plan {
    file: String,
    /// Per file column: target and builder index.
    targets: Vec<(Target, usize)>,
    builders: Vec<Builder>,
    /// Warnings gathered so far.
    pub(crate) warnings: Vec<InputWarning>,
}

impl Plan {
    /// Matches headers to the spec, reporting `duplicate-header` and `missing-column`.
    pub(crate) fn new(
        file: &str,
        headers: &[String],
        spec: &TableSpec,
        problems: &mut Collector,
    ) -> Plan {
        let mut targets = Vec::with_capacity(headers.len());
        let mut builders: Vec<Builder> = Vec::new();
        let mut warnings = Vec::new();
        let mut seen: Vec<(String, Option<&'static str>)> = Vec::new();
        let layout = positional(headers, spec);
        if let Some(layout) = layout {
            let written: Vec<String> = headers.iter().map(|h| format!("`{}`", h.trim())).collect();
            warnings.push(InputWarning::new(file, "positional-columns", format!(
                "the headers {} are not all MassFlow's; as MassFlow does, the {} columns are read by position as {}",
                written.join(", "),
                layout.len(),
                layout.join(", ")
            )));
        }
        let mut unused = Vec::new();
        for (i, raw) in headers.iter().enumerate() {
            // By position, the documented name decides the column; messages still use the
            // header as written (or the documented name where the header is empty).
            let (key, name) = match layout.and_then(|l| l.get(i)) {
                Some(&l) if raw.trim().is_empty() => (l, l),
                Some(&l) => (l, raw.trim()),
                None => (raw.trim(), raw.trim()),
            };
            if let Some(u) = spec
                .massflow_unused()
                .iter()
                .find(|u| u.eq_ignore_ascii_case(key))
            {
                unused.push(*u);
                targets.push((Target::Ignored, 0));
                continue;
            }
            if name.is_empty() {
                warnings.push(InputWarning::new(
                    file,
                    "no-header",
                    format!("column {} has no header and was ignored", i + 1),
                ));
                targets.push((Target::Ignored, 0));
                continue;
            }
            let field = spec.fields.iter().find(|f| names_field(key, f));
            let clash = seen.iter().find(|(h, f)| {
                h.eq_ignore_ascii_case(key) || (field.is_some() && *f == field.map(|f| f.name))
            });
            if let Some((first, _)) = clash {
                let what = match field {
                    Some(f) if !first.eq_ignore_ascii_case(name) => {
                        format!("both `{first}` and `{name}` name the column {}", f.name)
                    }
                    _ => format!("the header `{name}` appears more than once"),
                };
                problems.push(Problem::at(
                    file,
                    Some(0),
                    Some(name),
                    "duplicate-header",
                    what,
                ));
                targets.push((Target::Ignored, 0));
                continue;
            }
            seen.push((key.to_string(), field.map(|f| f.name)));
            let target = match (field, &spec.extra) {
                (Some(f), _) => Target::Field(f),
                (None, Some(_)) => Target::Extra,
                (None, None) => {
                    warnings.push(InputWarning::new(
                        file,
                        "unknown-column",
                        format!(
                            "column `{name}` is not a {} column and was ignored",
                            spec.name
                        ),
                    ));
                    Target::Ignored
                }
            };
            if !matches!(target, Target::Ignored) {
                builders.push(Builder::new(name, target));
            }
            targets.push((target, builders.len().saturating_sub(1)));
        }
        if !unused.is_empty() {
            warnings.push(InputWarning::new(
                file,
                "massflow-unused",
                format!(
                    "MassFlow column(s) {} recognised but not used by caveflow (ignored)",
                    unused.join(", ")
                ),
            ));
        }
        for f in spec.fields.iter().filter(|f| f.required) {
            if !targets
                .iter()
                .any(|(t, _)| matches!(t, Target::Field(g) if g.name == f.name))
            {
                let mut names = vec![f.name];
                names.extend(f.aliases.iter().copied());
                problems.push(Problem::at(
                    file,
                    None,
                    Some(f.name),
                    "missing-column",
                    format!(
                        "the required column {} is missing (accepted headers: {})",
                        f.name,
                        names.join(", ")
                    ),
                ));
            }
        }
        Plan {
            file: file.to_string(),
            targets,
            builders,
            warnings,
        }
    }

    /// The target of every file column, in file order (Parquet uses it to skip ignored
    /// columns).
    pub(crate) fn targets(&self) -> impl Iterator<Item = Target> + '_ {
        self.targets.iter().map(|t| t.0)
    }

    /// Feeds one row of cells, in file column order.
    pub(crate) fn push_row(&mut self, row: usize, cells: &[Cell<'_>], problems: &mut Collector) {
        for (cell, (target, b)) in cells.iter().zip(&self.targets) {
            if matches!(target, Target::Ignored) {
                continue;
            }
            if let Some(builder) = self.builders.get_mut(*b) {
                builder.push(*cell, row, &self.file, problems);
            }
        }
    }

    /// Feeds one column's cells (Parquet reads column-wise); `b` indexes the non-ignored
    /// columns in file order, `first_row` is the 1-based row of the first cell.
    pub(crate) fn push_column<'a>(
        &mut self,
        b: usize,
        first_row: usize,
        cells: impl Iterator<Item = Cell<'a>>,
        problems: &mut Collector,
    ) {
        if let Some(builder) = self.builders.get_mut(b) {
            for (i, cell) in cells.enumerate() {
                builder.push(cell, first_row + i, &self.file, problems);
            }
        }
    }

    /// Finishes the table; `row_numbers` lists the data row of every record.
    pub(crate) fn finish(self, problems: &mut Collector, row_numbers: Vec<usize>) -> Table {
        if row_numbers.is_empty() {
            let message = "the table has a header but no data rows";
            problems.push(Problem::file(&self.file, "empty-table", message));
        }
        let mut columns = Vec::new();
        let mut extra = Vec::new();
        let mut bad = Vec::new();
        for b in self.builders {
            if let Some((row, text)) = &b.non_numeric {
                problems.push(Problem::at(
                    &self.file,
                    Some(*row),
                    Some(&b.header),
                    "mistyped",
                    format!(
                        "`{text}` is not a number: a column that is not one of the table's fields is read as a grade and must be numeric (remove or rename the column)"
                    ),
                ));
            }
            if !b.bad.is_empty() {
                let key = match b.target {
                    Target::Field(f) => f.name.to_string(),
                    _ => b.header.clone(),
                };
                bad.push((key, b.bad));
            }
            match b.target {
                Target::Field(f) => columns.push((f.name, b.header, b.data)),
                _ => {
                    if let Column::F64(values) = b.data {
                        extra.push(ExtraColumn {
                            name: b.header,
                            values,
                        });
                    }
                }
            }
        }
        Table {
            file: self.file,
            sha256: String::new(),
            extra,
            warnings: self.warnings,
            columns,
            row_numbers,
            bad,
        }
    }
}

/// The spec's MassFlow layout when a file is to be read by position, as MassFlow reads it:
/// it has exactly the layout's number of columns, some header is not one caveflow knows
/// (no field name or alias, no unused MassFlow column), and no known header stands at
/// another column's place (`name,x,y,z,width,comment` is read by name).
fn positional(headers: &[String], spec: &TableSpec) -> Option<&'static [&'static str]> {
    let layout = spec.massflow_layout()?;
    if headers.len() != layout.len() {
        return None;
    }
    // What a header names: a field, an unused MassFlow column, or nothing known.
    let known = |h: &str| -> Option<&'static str> {
        spec.fields
            .iter()
            .find(|f| names_field(h, f))
            .map(|f| f.name)
            .or_else(|| {
                spec.massflow_unused()
                    .iter()
                    .find(|u| u.eq_ignore_ascii_case(h))
                    .copied()
            })
    };
    let mut unfamiliar = false;
    for (h, l) in headers.iter().zip(layout) {
        match known(h.trim()) {
            None => unfamiliar = true,
            Some(k) if Some(k) != known(l) => return None,
            Some(_) => {}
        }
    }
    unfamiliar.then_some(layout)
}

/// Accumulates one typed column.
struct Builder {
    header: String,
    target: Target,
    data: Column,
    /// First non-numeric cell of a grade column.
    non_numeric: Option<(usize, String)>,
    /// Records whose cell was reported.
    bad: Vec<usize>,
}

impl Builder {
    fn new(header: &str, target: Target) -> Builder {
        let kind = match target {
            Target::Field(f) => f.kind,
            _ => Kind::F64,
        };
        let data = match kind {
            Kind::F64 => Column::F64(Vec::new()),
            Kind::I64 | Kind::U32 => Column::I64(Vec::new()),
            Kind::Str => Column::Str(Vec::new()),
        };
        Builder {
            header: header.to_string(),
            target,
            data,
            non_numeric: None,
            bad: Vec::new(),
        }
    }

    fn len(&self) -> usize {
        match &self.data {
            Column::F64(v) => v.len(),
            Column::I64(v) => v.len(),
            Column::Str(v) => v.len(),
        }
    }

    fn push(&mut self, cell: Cell<'_>, row: usize, file: &str, problems: &mut Collector) {
        let (required, extra) = match self.target {
            Target::Field(f) => (f.required, false),
            _ => (false, true),
        };
        let record = self.len();
        let before = problems.total();
        let mut flagged = matches!(cell, Cell::Invalid);
        let col = Some(self.header.as_str());
        let mut report = |rule: &'static str, message: String| {
            problems.push(Problem::at(file, Some(row), col, rule, message))
        };
        if matches!(cell, Cell::Null) && required {
            report(
                "missing-value",
                "the cell is empty but the column is required".into(),
            );
        }
        match &mut self.data {
            Column::F64(v) => v.push(match cell {
                Cell::Null | Cell::Invalid => f64::NAN,
                Cell::Int(i) => i as f64,
                Cell::Float(x) => finite(x, &mut report),
                Cell::Text(s) => match parse_f64(s) {
                    Some(x) => finite(x, &mut report),
                    None => {
                        if !extra {
                            report("mistyped", not_a_number(s));
                        } else if self.non_numeric.is_none() {
                            self.non_numeric = Some((row, s.to_string()));
                        }
                        flagged = true;
                        f64::NAN
                    }
                },
            }),
            Column::I64(v) => v.push(match cell {
                Cell::Null | Cell::Invalid => None,
                Cell::Int(i) => Some(i),
                Cell::Float(x) => float_to_int(x, &mut report),
                Cell::Text(s) => match s.parse::<i64>() {
                    Ok(i) => Some(i),
                    Err(_) => match parse_f64(s) {
                        Some(x) => float_to_int(x, &mut report),
                        None => {
                            report("mistyped", format!("expected a whole number, found `{s}`"));
                            None
                        }
                    },
                },
            }),
            Column::Str(v) => v.push(match cell {
                Cell::Null | Cell::Invalid => String::new(),
                Cell::Text(s) => s.to_string(),
                Cell::Int(i) => i.to_string(),
                Cell::Float(x) => x.to_string(),
            }),
        }
        if flagged || problems.total() > before {
            self.bad.push(record);
        }
    }
}

/// A finite float as is; NaN (missing) after reporting `not-finite` otherwise.
fn finite(x: f64, report: &mut impl FnMut(&'static str, String)) -> f64 {
    if x.is_finite() {
        x
    } else {
        report("not-finite", format!("{x} is not a finite number"));
        f64::NAN
    }
}

/// An integral float as an integer; `not-finite` or `mistyped` otherwise.
fn float_to_int(x: f64, report: &mut impl FnMut(&'static str, String)) -> Option<i64> {
    if !x.is_finite() {
        report("not-finite", format!("{x} is not a finite number"));
        None
    } else if x.fract() != 0.0 || x.abs() > 9.0e15 {
        report("mistyped", format!("expected a whole number, found {x}"));
        None
    } else {
        Some(x as i64)
    }
}

/// Parses a number as Rust does (so `NaN` and `inf` parse, to be reported as not finite).
pub(crate) fn parse_f64(s: &str) -> Option<f64> {
    s.trim().parse::<f64>().ok()
}

/// The message for text where a number was expected.
pub(crate) fn not_a_number(s: &str) -> String {
    if s.contains(',') && !s.contains('.') {
        format!("expected a number, found `{s}` (use a decimal point, not a comma)")
    } else {
        format!("expected a number, found `{s}`")
    }
}
