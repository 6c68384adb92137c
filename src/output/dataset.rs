//! Hive-partitioned Parquet datasets of a run's tables, for BI tools (polars, DuckDB,
//! Spark, Arrow datasets).
//!
//! ```text
//! <dir>/dataset/<table>/scenario=<name>/period=<N>/part-0.parquet
//!   or, for runs of many periods:
//! <dir>/dataset/<table>/scenario=<name>/period_group=<first period>/part-0.parquet
//! ```
//!
//! for `<table>` in extraction, imz, drawn, air_gap and surface (and schedule_realised,
//! closures, production_target and value when the run has them). Each file holds the same
//! columns as the flat table, under the same stable names and with the same `unit` and
//! `description` field metadata, except the partition keys: `scenario` is never a column of
//! the files, and with `period=` partitions the `period` column lives in the directory
//! name only (the Hive convention: Spark, pyarrow and DuckDB's own writer do the same; a
//! reader with Hive partitioning adds it back). With `period_group=` partitions (several
//! periods per file) `period` stays a column and `period_group` is the number of the
//! group's first period.
//!
//! # Why partition by period, and when not
//! BI queries filter by period (this month, this year) and by scenario (compare runs), so
//! those are the keys: a reader skips whole directories. A daily mine-scale run has 3650
//! periods, and one file per period per table would be 18 000 small files, which every
//! engine reads slowly. So `outputs.hive_periods_per_partition` (default 0 = automatic)
//! groups periods: one per partition up to [`MAX_AUTO_PARTITIONS`] periods (the monthly
//! demo's 24), else as many as keep the count near [`AUTO_PARTITIONS`] (3650 daily periods:
//! 31 per partition, about one a month, 118 partitions).
//!
//! # Atomic
//! Every file is written through [`AtomicFile`](super::AtomicFile). A table's partitions are
//! first written into a hidden sibling directory (`.scenario=<name>.tmp-<pid>`), which then
//! replaces `scenario=<name>` by two renames (the old one aside, the new one in) before the
//! old one is removed: stale partitions of an earlier run into the same directory never
//! mix with new ones, and a crash leaves the old dataset, the new one, or a hidden
//! directory beside them, never a partial `scenario=` directory.

use std::fs;
use std::path::{Path, PathBuf};

use arrow::array::{AsArray, UInt32Array};
use arrow::compute::take_record_batch;
use arrow::datatypes::Int64Type;
use arrow::record_batch::RecordBatch;

use super::parquet::{write_batches, PART_ROWS};
use super::OutputError;
use crate::model::{Periods, Scenario};

/// Up to this many periods, automatic partitioning gives each period its own partition.
pub const MAX_AUTO_PARTITIONS: usize = 400;
/// Beyond [`MAX_AUTO_PARTITIONS`] periods, automatic partitioning groups periods so that
/// there are about this many partitions.
pub const AUTO_PARTITIONS: usize = 120;

/// How a run's datasets are laid out.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HiveLayout {
    /// The `scenario=` partition value (characters other than letters, digits, `.`, `_` and
    /// `-` are replaced by `_`).
    pub scenario: String,
    /// Periods per partition: 1 gives `period=<N>` partitions, more gives `period_group=`.
    pub periods_per_partition: usize,
}

impl HiveLayout {
    /// The layout the scenario asks for, or None when `outputs.hive` is off. `default_name`
    /// (the scenario file's stem, say) names the scenario unless `outputs.scenario_name`
    /// does; `periods` is the run's period count, for automatic grouping.
    pub fn new(scenario: &Scenario, default_name: &str, periods: usize) -> Option<HiveLayout> {
        let o = &scenario.outputs;
        if !o.hive {
            return None;
        }
        let name = o.scenario_name.as_deref().unwrap_or(default_name);
        let periods_per_partition = match o.hive_periods_per_partition {
            0 if periods <= MAX_AUTO_PARTITIONS => 1,
            0 => periods.div_ceil(AUTO_PARTITIONS),
            n => n,
        };
        Some(HiveLayout {
            scenario: partition_value(name),
            periods_per_partition,
        })
    }
}

/// A value safe in a `key=value` directory name: letters, digits, `.`, `_` and `-` kept,
/// anything else `_` (an empty name is `run`).
pub fn partition_value(name: &str) -> String {
    if name.is_empty() {
        return "run".to_string();
    }
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-') {
                c
            } else {
                '_'
            }
        })
        .collect()
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> OutputError + '_ {
    move |source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Writes one table as a Hive-partitioned dataset under `root` (`<dir>/dataset/<table>`):
/// `root/scenario=<name>/period=<N>/part-0.parquet` per period that has rows (see the
/// module docs), replacing whatever this scenario had there. The batch must have an Int64
/// `period` column. A table with no rows leaves no `scenario=` directory. Returns the
/// files written.
pub fn write_dataset(
    root: &Path,
    batch: &RecordBatch,
    periods: &Periods,
    layout: &HiveLayout,
) -> Result<Vec<PathBuf>, OutputError> {
    let arrow_err = |source| OutputError::Arrow {
        path: root.to_path_buf(),
        source,
    };
    let col = batch.schema().index_of("period").map_err(arrow_err)?;
    let period = batch.column(col).as_primitive::<Int64Type>();
    let rows = |rows: &[u32]| {
        if rows.len() == batch.num_rows() {
            Ok(batch.clone())
        } else {
            take_record_batch(batch, &UInt32Array::from(rows.to_vec())).map_err(arrow_err)
        }
    };
    write_dataset_with(root, period.iter(), periods, layout, rows)
}

/// [`write_dataset`] of a table that is not held as one batch: `period` gives each row's
/// period in row order, and `rows(r)` the batch of rows `r` (ascending row numbers), with
/// the table's `period` column. A partition's rows are asked for
/// [`PART_ROWS`] at a time, so memory holds a part of the table however large a partition
/// is, and the files are those [`write_dataset`] writes from the whole table.
pub fn write_dataset_with(
    root: &Path,
    period: impl Iterator<Item = Option<i64>>,
    periods: &Periods,
    layout: &HiveLayout,
    mut rows: impl FnMut(&[u32]) -> Result<RecordBatch, OutputError>,
) -> Result<Vec<PathBuf>, OutputError> {
    let arrow_err = |source| OutputError::Arrow {
        path: root.to_path_buf(),
        source,
    };
    let per = layout.periods_per_partition.max(1);
    // Rows per partition (by the period's position in the run), in row order.
    let mut parts: Vec<Vec<u32>> = vec![Vec::new(); periods.len().div_ceil(per).max(1)];
    let mut unknown: Vec<u32> = Vec::new();
    for (i, p) in period.enumerate() {
        match p.and_then(|p| periods.find(p)) {
            Some(k) => parts[k / per].push(i as u32),
            None => unknown.push(i as u32),
        }
    }
    if !unknown.is_empty() {
        return Err(OutputError::Encode {
            path: root.to_path_buf(),
            message: format!(
                "{} row(s) have a period that is not one of the run's periods",
                unknown.len()
            ),
        });
    }
    fs::create_dir_all(root).map_err(io_err(root))?;
    let target = root.join(format!("scenario={}", layout.scenario));
    let tmp = root.join(format!(
        ".scenario={}.tmp-{}",
        layout.scenario,
        std::process::id()
    ));
    if tmp.exists() {
        fs::remove_dir_all(&tmp).map_err(io_err(&tmp))?;
    }
    let mut written = Vec::new();
    for (g, part) in parts.iter().enumerate().filter(|(_, r)| !r.is_empty()) {
        let first = periods.id[g * per];
        let dir = if per == 1 {
            format!("period={first}")
        } else {
            format!("period_group={first}")
        };
        let batches = part.chunks(PART_ROWS).map(|r| {
            let batch = rows(r)?;
            if per > 1 {
                return Ok(batch);
            }
            // The key is the directory only: drop the column.
            let col = batch.schema().index_of("period").map_err(arrow_err)?;
            let keep: Vec<usize> = (0..batch.num_columns()).filter(|&c| c != col).collect();
            batch.project(&keep).map_err(arrow_err)
        });
        let dir_path = tmp.join(&dir);
        fs::create_dir_all(&dir_path).map_err(io_err(&dir_path))?;
        write_batches(&dir_path.join("part-0.parquet"), batches)?;
        written.push(target.join(dir).join("part-0.parquet"));
    }
    // Swap the new partitions in.
    let old = root.join(format!(
        ".scenario={}.old-{}",
        layout.scenario,
        std::process::id()
    ));
    if target.exists() {
        fs::rename(&target, &old).map_err(io_err(&target))?;
    }
    if written.is_empty() {
        fs::remove_dir_all(&tmp).ok();
    } else {
        fs::rename(&tmp, &target).map_err(io_err(&target))?;
    }
    if old.exists() {
        fs::remove_dir_all(&old).map_err(io_err(&old))?;
    }
    Ok(written)
}

/// Removes what a killed writer of `scenario` left under `root`: the hidden temporary and
/// old partition directories (`.scenario=<name>.tmp-<pid>`, `.scenario=<name>.old-<pid>`)
/// of [`write_dataset_with`].
pub fn remove_leftovers(root: &Path, scenario: &str) -> Result<(), OutputError> {
    let Ok(entries) = fs::read_dir(root) else {
        return Ok(());
    };
    let tmp = format!(".scenario={scenario}.tmp-");
    let old = format!(".scenario={scenario}.old-");
    for e in entries.flatten() {
        let n = e.file_name().to_string_lossy().into_owned();
        if n.starts_with(&tmp) || n.starts_with(&old) {
            fs::remove_dir_all(e.path()).map_err(io_err(&e.path()))?;
        }
    }
    Ok(())
}
