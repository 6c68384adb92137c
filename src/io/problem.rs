//! Validation problems: one [`Problem`] per broken rule, gathered into [`Problems`].

use std::collections::HashMap;
use std::fmt;

/// One thing wrong with an input file.
///
/// Displayed as `blocks.csv: row 12, column porosity: [porosity-range] porosity 1.3 is
/// outside [0, 1)`. `row` counts data rows from 1; `Some(0)` is the header line and shows as
/// `header`; `None` means the problem concerns the whole file or a whole column.
#[derive(Debug, Clone, PartialEq)]
pub struct Problem {
    /// File name (last path component) the problem is in.
    pub file: String,
    /// 1-based data row; 0 = the header line; None = not tied to one row.
    pub row: Option<usize>,
    /// Column, spelled as in the file's header (or the canonical name when it is missing).
    pub column: Option<String>,
    /// Short stable rule id, e.g. `porosity-range`. Tests and tools match on it.
    pub rule: &'static str,
    /// What is wrong and, where it helps, how to fix it.
    pub message: String,
}

impl Problem {
    /// A problem that concerns a whole file.
    pub fn file(file: &str, rule: &'static str, message: impl Into<String>) -> Problem {
        Problem {
            file: file.to_string(),
            row: None,
            column: None,
            rule,
            message: message.into(),
        }
    }

    /// A problem at a row (0 = header) and/or column.
    pub fn at(
        file: &str,
        row: Option<usize>,
        column: Option<&str>,
        rule: &'static str,
        message: impl Into<String>,
    ) -> Problem {
        Problem {
            file: file.to_string(),
            row,
            column: column.map(str::to_string),
            rule,
            message: message.into(),
        }
    }
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:", self.file)?;
        let mut located = false;
        match self.row {
            Some(0) => {
                write!(f, " header")?;
                located = true;
            }
            Some(r) => {
                write!(f, " row {r}")?;
                located = true;
            }
            None => {}
        }
        if let Some(c) = &self.column {
            write!(f, "{} column {c}", if located { "," } else { "" })?;
            located = true;
        }
        if located {
            write!(f, ":")?;
        }
        write!(f, " [{}] {}", self.rule, self.message)
    }
}

/// Something in an input that caveflow reads, but not as written, or not all of (a column
/// ignored, empty rows skipped, a default taken): the file is usable, and the user should
/// know. Like a [`Problem`] it carries a stable rule id that tests and tools match on.
///
/// Displayed as `drawpoints.csv: [no-opening-width] 2 drawpoint(s) have no opening width …`.
#[derive(Debug, Clone, PartialEq)]
pub struct InputWarning {
    /// File name (last path component) the warning is about.
    pub file: String,
    /// Short stable rule id, e.g. `empty-rows`.
    pub rule: &'static str,
    /// What was done, and where it helps, how to avoid it.
    pub message: String,
}

impl InputWarning {
    /// A warning about `file`.
    pub fn new(file: &str, rule: &'static str, message: impl Into<String>) -> InputWarning {
        InputWarning {
            file: file.to_string(),
            rule,
            message: message.into(),
        }
    }
}

impl fmt::Display for InputWarning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: [{}] {}", self.file, self.rule, self.message)
    }
}

/// Every problem found in a set of inputs, in the order found. Displayed one per line.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Problems(pub Vec<Problem>);

impl Problems {
    /// True when some problem has this rule id.
    pub fn has(&self, rule: &str) -> bool {
        self.0.iter().any(|p| p.rule == rule)
    }

    /// The problems with this rule id.
    pub fn with_rule<'a>(&'a self, rule: &'a str) -> impl Iterator<Item = &'a Problem> + 'a {
        self.0.iter().filter(move |p| p.rule == rule)
    }
}

impl fmt::Display for Problems {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, p) in self.0.iter().enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            write!(f, "{p}")?;
        }
        Ok(())
    }
}

impl std::error::Error for Problems {}

impl From<Problem> for Problems {
    fn from(p: Problem) -> Problems {
        Problems(vec![p])
    }
}

/// How many problems of one rule in one column of one file are kept word for word. The
/// rest are counted and summarised in one closing problem, so that a block model with a
/// million kg/m³ densities gives a readable report rather than a million lines.
pub const KEEP_PER_RULE: usize = 20;

/// Gathers problems, keeping at most [`KEEP_PER_RULE`] per (file, column, rule).
#[derive(Debug, Default)]
pub(crate) struct Collector {
    kept: Vec<Problem>,
    total: usize,
    counts: HashMap<(String, Option<String>, &'static str), usize>,
}

impl Collector {
    /// Records a problem.
    pub(crate) fn push(&mut self, p: Problem) {
        self.total += 1;
        let n = self
            .counts
            .entry((p.file.clone(), p.column.clone(), p.rule))
            .or_insert(0);
        *n += 1;
        if *n <= KEEP_PER_RULE {
            self.kept.push(p);
        }
    }

    /// How many problems were recorded, kept or not.
    pub(crate) fn total(&self) -> usize {
        self.total
    }

    /// True when nothing was recorded.
    pub(crate) fn is_empty(&self) -> bool {
        self.total == 0
    }

    /// `Ok(value)` when nothing was recorded and there is a value, else every problem.
    pub(crate) fn into_result<T>(self, value: Option<T>) -> Result<T, Problems> {
        match value {
            Some(v) if self.is_empty() => Ok(v),
            _ => Err(self.finish()),
        }
    }

    /// The problems, with one summary per (file, column, rule) whose count passed the cap.
    pub(crate) fn finish(self) -> Problems {
        let mut out = self.kept;
        let mut over: Vec<_> = self
            .counts
            .into_iter()
            .filter(|(_, n)| *n > KEEP_PER_RULE)
            .collect();
        over.sort_by(|a, b| a.0.cmp(&b.0));
        for ((file, column, rule), n) in over {
            out.push(Problem {
                file,
                row: None,
                column,
                rule,
                message: format!(
                    "{} more rows break this rule (only the first {KEEP_PER_RULE} are listed)",
                    n - KEEP_PER_RULE
                ),
            });
        }
        Problems(out)
    }
}
