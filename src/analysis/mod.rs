//! The analysis layer: studies made of many runs.
//!
//! - [`sweep`]: the speed–accuracy sweep. One scene is run at a grid of resolutions around
//!   the default and against a converged reference; wall time and error are tabulated
//!   (`sweep.parquet`) and charted (error against time, with the Pareto front).
//!
//! - [`records`]: synthetic production records, from a run with a hidden "true"
//!   calibration plus sampling noise (the demo's `data/records.csv`).
//!
//! This layer sits above [`output`](crate::output): it runs the engine and writes through the
//! output layer's writers. It is not gated behind the `analysis` cargo feature (polars);
//! nothing here needs polars.

pub mod records;
pub mod sweep;
