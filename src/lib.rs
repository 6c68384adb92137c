//! caveflow: an open, fast and validated simulator of gravity flow of fragmented rock in
//! block and panel caving mines, after REBOP as Pierce (2010) publishes it.
//!
//! Data flows one way through the modules:
//!
//! `schema` (table contracts) → [`io`] (read and validate tables) → [`model`] (block model,
//! drawpoints, schedule, scenario) → [`engine`] (IMZs, markers: one module per mechanism) →
//! [`output`] (Parquet writers, manifest, charts) → `analysis` (reconcile, calibrate) →
//! [`cli`]. No module reaches back up (the integration test `layering` reads every `crate::`
//! path in `src/` and fails on one). [`docs`] holds the notes on the method, its
//! validation and its performance.
#![warn(missing_docs)]

pub mod analysis;
pub mod cli;
pub mod docs;
pub mod engine;
pub mod io;
pub mod model;
pub mod output;
pub mod schema;
