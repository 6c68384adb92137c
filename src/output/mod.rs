//! The output layer: everything a run or a command writes to disk.
//!
//! - [`parquet`]: atomic file writing ([`AtomicFile`], [`write_atomic`], [`write_atomic_with`])
//!   and the one Parquet writer ([`write_parquet`]) that every table goes through.
//! - [`run_dir`]: a run directory as `caveflow run` writes it — charts, MassFlow reports,
//!   VTK, the report, the tables and the manifest — and the run's checkpoint
//!   ([`run_dir::write_run_dir`]).
//! - [`run`]: a run's tables — extraction report, IMZ geometry, drawn markers (IEZ),
//!   partitioned marker states — and the manifest ([`write_run`]).
//! - [`dataset`]: the run's tables as Hive-partitioned datasets (`outputs.hive`).
//! - [`manifest`]: the run manifest (`manifest.json`).
//! - [`inputs`]: a [`Scene`](crate::model::Scene) written back as input tables and a scenario
//!   file (used by `caveflow demo`).
//! - [`records`]: production records (the demo's synthetic ones).
//! - [`charts`]: PNG and SVG charts, and the sections and grade series they draw from a
//!   run.
//! - [`report`]: self-contained HTML report pages (`report.html` of a run; the look that
//!   `reconcile` and `study` share).
//! - [`dilution`]: the dilution entry per drawpoint.
//! - [`stress`]: the stress logic's tables and charts.
//! - [`trace`]: the trace points' table.
//! - [`draw_control`]: draw control's realised schedule, closures and production against
//!   target.
//! - [`massflow`]: MassFlow's report layouts (`outputs.massflow`).
//! - [`vtk`]: VTK XML files and `.pvd` collections for ParaView (`outputs.vtk`).
//!
//! # Why every file is written atomically
//!
//! A run directory is read by BI tools and by `reconcile` while other runs are going. A
//! crash or a full disk in the middle of a write must leave either the previous file or no
//! file, never a truncated Parquet file whose footer is missing. Every writer here writes a
//! temporary file next to the target, syncs it, and renames it over the target.

use std::path::PathBuf;

pub mod charts;
pub mod columns;
pub mod dataset;
pub mod dilution;
pub mod draw_control;
pub mod inputs;
pub mod manifest;
pub mod massflow;
pub mod parquet;
pub mod records;
pub mod report;
pub mod run;
pub mod run_dir;
pub mod stress;
pub mod trace;
pub mod vtk;
pub mod warnings;

pub use self::manifest::Manifest;
pub use self::parquet::{write_atomic, write_atomic_with, write_batch, write_parquet, AtomicFile};
pub use self::run::{write_run, write_run_with};
pub use crate::model::load::InputFile;

/// A failure to write an output file. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// Creating, writing, syncing or renaming the file failed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file (or directory).
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// The columns do not fit the table's schema (count, length or type).
    #[error("{}: cannot assemble the table: {source}", path.display())]
    Arrow {
        /// The file.
        path: PathBuf,
        /// Cause.
        source: arrow::error::ArrowError,
    },
    /// The Parquet encoder failed.
    #[error("{}: cannot write Parquet: {source}", path.display())]
    Parquet {
        /// The file.
        path: PathBuf,
        /// Cause.
        source: ::parquet::errors::ParquetError,
    },
    /// The CSV encoder failed.
    #[error("{}: cannot write CSV: {source}", path.display())]
    Csv {
        /// The file.
        path: PathBuf,
        /// Cause.
        source: csv::Error,
    },
    /// A value could not be serialised to JSON or TOML.
    #[error("{}: cannot encode: {message}", path.display())]
    Encode {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
}
