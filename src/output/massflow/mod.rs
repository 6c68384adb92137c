//! MassFlow's report layouts (`--massflow-reports`, `outputs.massflow`), so that a MassFlow
//! user's existing scripts read caveflow's results. The Parquet tables stay the primary
//! output; these are written beside them, from the same run, into `<dir>/massflow/`:
//!
//! ```text
//! <dir>/massflow/extraction_report.txt      the period extraction report (extraction)
//! <dir>/massflow/marker_report_<N>.txt      the marker report at each marker period N (markers)
//! <dir>/massflow/trace_report_<N>.txt       the trace report at the same periods (markers)
//! <dir>/massflow/trace_daily.csv            the trace points' path (trace_csv)
//! ```
//!
//! The reports are tab-delimited, the daily trace file comma-separated, as MassFlow writes
//! them. Numbers are printed to fixed decimals (tonnes to 0.001 t, grade tonnes to 1e-6 t,
//! coordinates to 1 mm); an empty cell is a value caveflow does not have (a grade where
//! nothing was drawn to read it from).
//!
//! # What differs from MassFlow
//! - caveflow models block and panel caving, with no sublevel-caving rings and no
//!   production levels: `RingMass` is written 0, and the per-level `<n>Orig`/`<n>Dest`
//!   columns are not written (a MassFlow script that looks for them finds none).
//! - MassFlow moves markers once a day; caveflow moves them every draw increment and keeps
//!   no daily state. The daily trace file therefore has one row per trace point per period
//!   end, its `Day` the days from the start of the run to that end, and a drawn marker's
//!   `DayExtr` is the day its period ends.
//! - `Type` is 0 for a marker of the lattice and 1 for a trace marker.
//!
//! Every file is written atomically (`output::parquet::write_atomic`).

mod extraction;
mod markers;
mod trace_csv;

use std::path::{Path, PathBuf};

use super::{write_atomic, OutputError};
use crate::engine::result::RunOutput;
use crate::model::{Periods, Scene};

pub use extraction::extraction_report;
pub use markers::{marker_report, trace_report};
pub use trace_csv::trace_daily;

/// Writes every MassFlow report of `run` into `<dir>/massflow/` (created if needed); returns
/// the files written. The trace files are written only when the run followed trace points.
pub fn write_reports(
    dir: &Path,
    scene: &Scene,
    run: &RunOutput,
) -> Result<Vec<PathBuf>, OutputError> {
    let out = dir.join("massflow");
    std::fs::create_dir_all(&out).map_err(|source| OutputError::Io {
        path: out.clone(),
        source,
    })?;
    // Each report is written as soon as it is made: a mine-scale marker report is large.
    let mut written = Vec::new();
    let mut write = |name: String, text: String| {
        let path = out.join(name);
        write_atomic(&path, text.as_bytes())?;
        written.push(path);
        Ok::<(), OutputError>(())
    };
    write(
        "extraction_report.txt".into(),
        extraction_report(scene, &run.extraction),
    )?;
    let traced = !run.trace.trace_id.is_empty();
    for p in run.snapshot_periods() {
        if let Some(snap) = run.snapshot(p) {
            write(
                format!("marker_report_{p}.txt"),
                marker_report(scene, &snap),
            )?;
        }
        if traced {
            write(
                format!("trace_report_{p}.txt"),
                trace_report(scene, &run.trace, p),
            )?;
        }
    }
    if traced {
        write("trace_daily.csv".into(), trace_daily(scene, &run.trace))?;
    }
    Ok(written)
}

/// Days from the start of the run to the end of period number `period` (0 for a period the
/// scene does not have).
fn days_to_end(periods: &Periods, period: i64) -> f64 {
    periods
        .id
        .iter()
        .position(|&p| p == period)
        .map_or(0.0, |i| periods.days[..=i].iter().sum())
}

/// `x` to `decimals` places; NaN (no value) as an empty cell.
fn num(x: f64, decimals: usize) -> String {
    if x.is_nan() {
        String::new()
    } else {
        format!("{x:.decimals$}")
    }
}

/// One line of fields joined by `sep`, with its newline.
fn line(fields: &[String], sep: char) -> String {
    let mut s = fields.join(&sep.to_string());
    s.push('\n');
    s
}
