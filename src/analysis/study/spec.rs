//! The study file (`STUDY.toml`) as written, and the problems it can have.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::engine::ResolvedResolution;

/// A study file as written: a base scenario, fixed overrides, and the dimensions whose
/// cartesian product are the variants (see the [module docs](super)). Serialised, it is a
/// study file again (what `caveflow calibrate` writes).
#[derive(Debug, Clone, Deserialize, Serialize, Default)]
#[serde(deny_unknown_fields)]
pub struct StudyFile {
    /// The study's name: the `study=` partition value (default: the file's stem).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// The base scenario, relative to the study file.
    pub scenario: PathBuf,
    /// `key=value` overrides applied to every variant, exactly as `run --set`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub set: Vec<String>,
    /// Grids: scenario key → the values to run (a TOML array). Dotted keys may be written
    /// quoted (`"calibration.frag_factor.urad" = [..]`) or as nested tables.
    #[serde(default, skip_serializing_if = "toml::Table::is_empty")]
    pub grid: toml::Table,
    /// Named alternatives: dimension → alternative name → input role → table path
    /// (relative to the study file). An empty alternative (`base = {}`) keeps the base
    /// scenario's tables.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub alternatives: BTreeMap<String, BTreeMap<String, BTreeMap<String, PathBuf>>>,
    /// Cases: case name → its `key=value` overrides, as `set` (an explicit list of
    /// variants, where a grid's product does not fit: `caveflow calibrate`'s runs).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cases: Option<BTreeMap<String, Vec<String>>>,
    /// Resolutions of cases: case name → the resolution it runs at (`layer_thickness`,
    /// `marker_spacing`, `draw_increment` and `max_marker_move`, numbers; the last 0 when
    /// left out), used as given instead of the one its scenario resolves to
    /// (`caveflow calibrate`'s finer check).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub case_resolution: BTreeMap<String, ResolvedResolution>,
    /// Seeds: the scenario's `seed` of each repeat (default: the base scenario's seed only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seeds: Option<Vec<u64>>,
    /// Only the first N periods of every variant, as `run --keep-periods` (default: all).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub keep_periods: Option<usize>,
}

/// One problem with a study, displayed as `file: [rule] key: message`.
///
/// Rules: `unreadable` (the study file), `toml-syntax`, `unknown-key` (in the study file or
/// a grid, `set` or alternative key that is not a scenario key or input role, or a
/// `case_resolution` of no case), `wrong-type`, `setting-range` (a value out of range, by
/// the scenario's own checks, `keep_periods` below 1, or a case resolution that is not
/// positive and finite), `empty-grid` (a grid, alternative dimension, case list or seed
/// list with nothing in it), `grid-not-array`, `bad-name` (a study, case or variant name
/// that cannot name a directory, or
/// two variants with one name), `missing-table` (an input table that does not exist),
/// `bad-variant` (a variant whose tables or scene the loader refuses: the loader's own
/// problem follows, with its file, row, column and rule).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{file}: [{rule}] {key}: {message}")]
pub struct StudyError {
    /// The study file.
    pub file: String,
    /// The study key at fault (`grid.calibration.frag_factor.urad`, `scenario`, ...).
    pub key: String,
    /// Stable rule id (see the type's docs).
    pub rule: &'static str,
    /// What is wrong.
    pub message: String,
}

impl StudyError {
    /// A problem with `key` of the study file `file`.
    pub fn new(
        file: &Path,
        key: impl Into<String>,
        rule: &'static str,
        message: impl Into<String>,
    ) -> StudyError {
        StudyError {
            file: file.display().to_string(),
            key: key.into(),
            rule,
            message: message.into(),
        }
    }
}

/// Every problem of a study, one per line; nothing runs while there is one.
#[derive(Debug, Clone, PartialEq)]
pub struct StudyProblems(pub Vec<StudyError>);

impl std::fmt::Display for StudyProblems {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "{} problem(s) in the study:", self.0.len())?;
        for (i, p) in self.0.iter().enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            write!(f, "{p}")?;
        }
        Ok(())
    }
}

impl std::error::Error for StudyProblems {}

impl StudyProblems {
    /// True when some problem has this rule id.
    pub fn has(&self, rule: &str) -> bool {
        self.0.iter().any(|p| p.rule == rule)
    }
}

impl StudyFile {
    /// Reads and parses a study file (syntax, unknown keys and types only: the values are
    /// checked when the study is expanded).
    pub fn read(path: &Path) -> Result<StudyFile, StudyProblems> {
        let one = |key: &str, rule, message: String| {
            StudyProblems(vec![StudyError::new(path, key, rule, message)])
        };
        let text = std::fs::read_to_string(path).map_err(|e| {
            one(
                "(file)",
                "unreadable",
                format!("cannot read the study: {e}"),
            )
        })?;
        let _: toml::Table = toml::from_str(&text)
            .map_err(|e| one("(file)", "toml-syntax", e.message().trim().to_string()))?;
        toml::from_str(&text).map_err(|e| {
            let message = e.message().trim().to_string();
            let rule = if message.contains("unknown field") {
                "unknown-key"
            } else {
                "wrong-type"
            };
            let line = e.span().map(|r| {
                let before = text.get(..r.start).unwrap_or(&text);
                format!("line {}", before.matches('\n').count() + 1)
            });
            one(&line.unwrap_or_else(|| "(file)".into()), rule, message)
        })
    }
}
