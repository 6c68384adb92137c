//! Report pages: self-contained HTML a mine engineer reads in a minute.
//!
//! - [`page`]: the look and the building blocks every report shares ([`Page`]), and what
//!   "self-contained" means;
//! - [`run`]: the run report, `report.html` of every `run` ([`write_run_report`]).
//!
//! `reconcile`'s and `study`'s reports (`analysis`) are built with the same [`Page`].

pub mod draw_control;
pub mod page;
pub mod run;

use std::path::PathBuf;

pub use self::page::{esc, num, EmbedError, Page};
pub use self::run::{write_run_report, RunReport};

use super::charts::ChartError;
use super::OutputError;

/// A failure to write a report. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// A chart of the report could not be drawn.
    #[error(transparent)]
    Chart(#[from] ChartError),
    /// A chart could not be read to embed.
    #[error(transparent)]
    Embed(#[from] EmbedError),
    /// The page could not be written.
    #[error(transparent)]
    Output(#[from] OutputError),
    /// A directory could not be made.
    #[error("{}: {source}", path.display())]
    Io {
        /// The directory.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
}
