//! The trace points (`inputs.trace`, `--trace`): MassFlow's trace-marker file, read by
//! [`io`](crate::io) and checked here against the block model.
//!
//! # Rule
//! A trace point must lie in a block of the model (`outside-model`): outside the grid, or in
//! a cell of the grid with no block, there is no ground to follow. MassFlow 9.7.47 crashes on
//! such a point; caveflow names its file, row and coordinates, and the model's extent.

use std::path::Path;

use super::Loader;
use crate::io::{read_trace_into, TracePoints};
use crate::model::BlockModel;

impl Loader {
    /// Reads the trace file (recording it as an input); None when it cannot be read.
    pub(super) fn read_trace(&mut self, path: &Path) -> Option<TracePoints> {
        let t = read_trace_into(path, &mut self.problems)?;
        self.input("trace", path, &t.sha256, t.points.len());
        Some(t)
    }

    /// Checks every trace point against the block model (see the module docs).
    pub(super) fn check_trace(&mut self, t: &TracePoints, bm: &BlockModel) {
        // The extent to the micrometre (the grid's corners carry rounding noise).
        let um = |v: f64| (v * 1e6).round() / 1e6;
        let (lo, hi) = (bm.origin.map(um), bm.max_corner().map(um));
        for (p, &row) in t.points.iter().zip(&t.rows) {
            if bm.locate(*p).is_some() {
                continue;
            }
            let at = format!("trace point ({}, {}, {})", p[0], p[1], p[2]);
            let message = if bm.cell(*p).is_none() {
                format!(
                    "{at} lies outside the block model, which spans x {}..{}, y {}..{} and z {}..{}",
                    lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]
                )
            } else {
                format!("{at} lies in a cell of the block grid that has no block")
            };
            self.problem(&t.file, Some(row), None, "outside-model", message);
        }
    }
}
