//! The analysis layer: studies made of many runs.
//!
//! - [`sweep`]: the speed–accuracy sweep. One scene is run at a grid of resolutions around
//!   the default and against a converged reference; wall time and error are tabulated
//!   (`sweep.parquet`) and charted (error against time, with the Pareto front).
//!
//! - [`study`]: scenario studies: variants of one scenario (grids over any key, swapped
//!   tables, seeds) run in parallel into one Hive-partitioned dataset, resumable, with a
//!   summary per variant.
//!
//! - [`records`]: synthetic production records, from a run with a hidden "true"
//!   calibration plus sampling noise (the demo's `data/records.csv`).
//! - [`reconcile`]: predicted against sampled drawpoint grades (polars, lazy): matched rows
//!   and error statistics per drawpoint, zone and overall;
//! - [`report`]: the reconciliation as one self-contained HTML page with inline SVG charts;
//! - [`calibrate`]: fit fragment-size, n1 and φ factors to production records by running
//!   the engine many times in parallel;
//! - [`calibrate_runs`]: `caveflow calibrate`'s runs as a study, locally or by an external
//!   runner such as the Ray driver, resumable;
//! - [`lockstep`]: `calibrate`'s fits on several marker lattices made at once, their
//!   batches merged round by round;
//! - [`least_squares`]: the Levenberg–Marquardt step and the covariance of `calibrate`'s
//!   joint fit of several zones.
//!
//! This layer sits above [`output`](crate::output): it runs the engine and writes through the
//! output layer's writers. reconcile, report and calibrate use polars, behind the default
//! `analysis` cargo feature; the sweep does not.

#[cfg(feature = "analysis")]
pub mod calibrate;
#[cfg(feature = "analysis")]
pub mod calibrate_runs;
pub mod least_squares;
#[cfg(feature = "analysis")]
pub mod lockstep;
#[cfg(feature = "analysis")]
pub mod reconcile;
pub mod records;
#[cfg(feature = "analysis")]
pub mod report;
pub mod study;
pub mod sweep;

/// An error as one line: its message, then each cause in turn that the text so far does
/// not already hold (an error that names its cause in its own message and also gives it as
/// its source would otherwise print the cause twice). The CLI prints its errors so, and a
/// study or a calibration reports a failed run so.
pub fn error_text(e: &(dyn std::error::Error + 'static)) -> String {
    let mut text = String::new();
    let mut next = Some(e);
    while let Some(err) = next {
        let cause = err.to_string();
        if text.is_empty() {
            text = cause;
        } else if !text.contains(&cause) {
            text.push_str(": ");
            text.push_str(&cause);
        }
        next = err.source();
    }
    text
}
