//! caveflow: an open, fast and validated simulator of gravity flow of fragmented rock in
//! block and panel caving mines, after REBOP as Pierce (2010) publishes it.
//!
//! Data flows one way through the modules:
//!
//! `schema` (table contracts) → [`io`] (read and validate tables) → [`model`] (block model,
//! drawpoints, schedule, scenario) → [`engine`] (IMZs, markers: one module per mechanism) →
//! [`output`] (Parquet writers, manifest, charts) → `analysis` (reconcile, calibrate) →
//! [`cli`]. No module reaches back up (the integration test `layering` reads every `crate::`
//! path in `src/` and fails on one, and on a circle among a layer's modules). [`docs`]
//! holds the notes on the method, its validation, its resolution and its performance, and
//! [`docs::references`] says what the "summary §" and "DESIGN §" of the doc comments are.
#![warn(missing_docs)]
// `!(x > 0.0)` is how this crate says "not a positive number, NaN included": a NaN input
// takes the same branch as a non-positive one. `partial_cmp` would say the same at more
// length.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod analysis;
pub mod cli;
pub mod docs;
pub mod engine;
pub mod io;
pub mod model;
pub mod output;
pub mod schema;
