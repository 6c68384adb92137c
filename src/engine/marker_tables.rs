//! The marker tables of a run, the drawn markers (the IEZ, [`DrawnTable`]) and marker
//! snapshots ([`MarkerSnapshot`]), and how they are read from the engine's marker columns:
//! a snapshot of a chosen period made whole when the period ends, the drawn table and the
//! end-of-run snapshot read from the markers a range of rows at a time ([`EndMarkers`]).
//!
//! A table row is a marker's columns, in the order of the markers' ids, with its origin
//! (from the lattice) and its block's id and porosity beside them (`MarkerRows`).
//!
//! # Why the end tables are not made whole
//! Made whole, the end snapshot and the drawn table copy every marker a second and a
//! third time: at mine scale with 1.65 m markers that is 850 MB and 380 MB beside the
//! 680 MB of drawn markers they are read from. So the engine hands its markers over as
//! they are, sorted by id in place ([`EndMarkers`], in
//! [`RunOutput::end`](super::RunOutput::end)), and whoever reads the tables reads them a
//! range of rows at a time ([`RunOutput::drawn_chunks`](super::RunOutput::drawn_chunks),
//! [`RunOutput::snapshot_chunks`](super::RunOutput::snapshot_chunks)): the Parquet
//! writers a part of a row group at a time, the charts a chunk at a time. The rows read
//! are the rows the whole table would have, bit for bit. A run made by hand (tests, other
//! tools) may hold its drawn table and its last snapshot whole instead
//! ([`RunOutput::drawn`](super::RunOutput::drawn),
//! [`RunOutput::snapshots`](super::RunOutput::snapshots)); the accessors read either.

use std::ops::Range;

use rayon::prelude::*;

use super::markers::{DrawnMarkers, Lattice, Markers};
use crate::model::BlockModel;

/// Marker states (`markers.state`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[repr(u8)]
pub enum MarkerState {
    /// Never mobilised: at its lattice origin.
    InSitu = 0,
    /// Inside an IMZ (dilated, moving).
    Moving = 1,
    /// Left the lowest disk of an IMZ.
    Drawn = 2,
}

impl MarkerState {
    /// Name written to Parquet.
    pub fn name(self) -> &'static str {
        match self {
            MarkerState::InSitu => "in_situ",
            MarkerState::Moving => "moving",
            MarkerState::Drawn => "drawn",
        }
    }
}

/// Drawn markers (IEZ).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DrawnTable {
    /// Marker id.
    pub marker_id: Vec<i64>,
    /// Drawpoint index.
    pub drawpoint: Vec<u32>,
    /// Period number.
    pub period: Vec<i64>,
    /// Origin.
    pub origin_x: Vec<f64>,
    /// Origin.
    pub origin_y: Vec<f64>,
    /// Origin.
    pub origin_z: Vec<f64>,
    /// Mass, t.
    pub mass: Vec<f64>,
    /// Block id.
    pub block_id: Vec<i64>,
    /// Horizontal distance rilled on the free surface, m.
    pub rill_distance: Vec<f64>,
    /// Fragment size when drawn, m.
    pub frag_size: Vec<f64>,
}

/// Marker states at the end of one period.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MarkerSnapshot {
    /// Period number.
    pub period: i64,
    /// Marker id.
    pub marker_id: Vec<i64>,
    /// Position.
    pub x: Vec<f64>,
    /// Position.
    pub y: Vec<f64>,
    /// Position.
    pub z: Vec<f64>,
    /// Origin.
    pub origin_x: Vec<f64>,
    /// Origin.
    pub origin_y: Vec<f64>,
    /// Origin.
    pub origin_z: Vec<f64>,
    /// Mass, t.
    pub mass: Vec<f64>,
    /// Block id.
    pub block_id: Vec<i64>,
    /// State.
    pub state: Vec<MarkerState>,
    /// Porosity.
    pub porosity: Vec<f64>,
    /// Fragment size, m.
    pub frag_size: Vec<f64>,
    /// Accumulated shear strain Γ.
    pub shear_strain: Vec<f64>,
    /// Accumulated shear work Γσ_n, kPa.
    pub shear_work: Vec<f64>,
    /// Primary fragment size d0, m.
    pub primary_frag_size: Vec<f64>,
    /// Attrited mass fraction W.
    pub attrited: Vec<f64>,
    /// Accumulated percolation distance, m.
    pub percolated: Vec<f64>,
    /// Drawpoint index that drew it (u32::MAX if not drawn).
    pub drawpoint: Vec<u32>,
    /// Period drawn (-1 if not drawn).
    pub drawn_period: Vec<i64>,
}

/// Rows per chunk that the accessors' callers use by default: a Parquet row group
/// (`output::parquet::MAX_ROW_GROUP_ROWS`).
pub const CHUNK_ROWS: usize = 1 << 20;

/// The moving and drawn markers at one moment, borrowed, with what their table rows need
/// besides: the lattice (origins) and each block's id and porosity n1.
#[derive(Clone, Copy)]
pub(crate) struct MarkerRows<'m> {
    pub moving: &'m Markers,
    pub drawn: &'m DrawnMarkers,
    pub lattice: &'m Lattice,
    pub block_id: &'m [i64],
    pub porosity: &'m [f64],
}

/// Gathers one column over snapshot rows: row `r` below `n_moving` is moving marker `r`,
/// else drawn marker `r − n_moving`.
fn gather<T: Send>(
    rows: &[u32],
    n_moving: usize,
    moving: impl Fn(usize) -> T + Sync,
    drawn: impl Fn(usize) -> T + Sync,
) -> Vec<T> {
    rows.par_iter()
        .map(|&r| {
            let r = r as usize;
            if r < n_moving {
                moving(r)
            } else {
                drawn(r - n_moving)
            }
        })
        .collect()
}

/// The rows of `ids` (numbered in order from 0) sorted by (id, row). Ids below 2³² (those
/// of every lattice the engine accepts, `MAX_SITES`) are sorted packed with their row into
/// one u64: half the memory of (id, row) pairs, which at the end of a mine-scale run is
/// tens of megabytes.
fn order_by_id<'i>(ids: impl Iterator<Item = &'i u64> + Clone) -> Vec<u32> {
    if ids.clone().all(|&id| id <= u64::from(u32::MAX)) {
        let mut keys: Vec<u64> = ids
            .enumerate()
            .map(|(r, &id)| id << 32 | r as u64)
            .collect();
        keys.par_sort_unstable();
        keys.into_iter().map(|k| k as u32).collect()
    } else {
        let mut keys: Vec<(u64, u32)> = ids.enumerate().map(|(r, &id)| (id, r as u32)).collect();
        keys.par_sort_unstable();
        keys.into_iter().map(|(_, r)| r).collect()
    }
}

/// One column over drawn-marker rows.
fn gather_drawn<T: Send>(rows: &[u32], f: impl Fn(usize) -> T + Sync) -> Vec<T> {
    rows.par_iter().map(|&k| f(k as usize)).collect()
}

impl MarkerRows<'_> {
    /// The snapshot's rows in order: every moving and drawn marker sorted by (id, drawn,
    /// row), as snapshot row numbers (see [`gather`]).
    pub fn snapshot_order(&self) -> Vec<u32> {
        // Moving rows come before drawn rows, so (id, row) orders as (id, drawn, row).
        order_by_id(self.moving.id.iter().chain(&self.drawn.m.id))
    }

    /// The snapshot rows `rows` (snapshot row numbers, see [`gather`]) at the end of
    /// `period`.
    pub fn snapshot(&self, period: i64, rows: &[u32]) -> MarkerSnapshot {
        let (m, d) = (self.moving, &self.drawn.m);
        let n = m.len();
        let (lat, block_id, porosity) = (self.lattice, self.block_id, self.porosity);
        let origin = |a: usize| {
            gather(
                rows,
                n,
                |k| lat.pos(m.id[k] as usize)[a],
                |k| lat.pos(d.id[k] as usize)[a],
            )
        };
        macro_rules! column {
            ($c:ident) => {
                gather(rows, n, |k| m.$c[k], |k| d.$c[k])
            };
        }
        MarkerSnapshot {
            period,
            marker_id: gather(rows, n, |k| m.id[k] as i64, |k| d.id[k] as i64),
            x: column!(x),
            y: column!(y),
            z: column!(z),
            origin_x: origin(0),
            origin_y: origin(1),
            origin_z: origin(2),
            mass: column!(mass),
            block_id: gather(
                rows,
                n,
                |k| block_id[m.block[k] as usize],
                |k| block_id[d.block[k] as usize],
            ),
            state: gather(rows, n, |_| MarkerState::Moving, |_| MarkerState::Drawn),
            porosity: gather(
                rows,
                n,
                |k| porosity[m.block[k] as usize],
                |k| porosity[d.block[k] as usize],
            ),
            frag_size: column!(frag),
            shear_strain: column!(strain),
            shear_work: column!(work),
            primary_frag_size: column!(frag0),
            attrited: column!(attrited),
            percolated: column!(percolated),
            drawpoint: gather(rows, n, |_| u32::MAX, |k| self.drawn.drawpoint[k]),
            drawn_period: gather(rows, n, |_| -1, |k| self.drawn.period[k]),
        }
    }

    /// The drawn-table rows of drawn markers `rows`.
    pub fn drawn(&self, rows: &[u32]) -> DrawnTable {
        let (dm, lat, block_id) = (self.drawn, self.lattice, self.block_id);
        let origin = |a: usize| gather_drawn(rows, |k| lat.pos(dm.m.id[k] as usize)[a]);
        DrawnTable {
            marker_id: gather_drawn(rows, |k| dm.m.id[k] as i64),
            drawpoint: gather_drawn(rows, |k| dm.drawpoint[k]),
            period: gather_drawn(rows, |k| dm.period[k]),
            origin_x: origin(0),
            origin_y: origin(1),
            origin_z: origin(2),
            mass: gather_drawn(rows, |k| dm.m.mass[k]),
            block_id: gather_drawn(rows, |k| block_id[dm.m.block[k] as usize]),
            rill_distance: gather_drawn(rows, |k| dm.m.rill[k]),
            frag_size: gather_drawn(rows, |k| dm.m.frag[k]),
        }
    }
}

/// The markers as the run left them (moved out of the engine, not copied), sorted by id,
/// read as the drawn table and, when the run keeps one, as the end snapshot.
#[derive(Clone)]
pub struct EndMarkers {
    /// The last period's number.
    period: i64,
    /// Whether the run keeps a snapshot at the end of the last period.
    snapshot: bool,
    /// Moving markers, sorted by id (empty when no end snapshot is kept).
    moving: Markers,
    /// Drawn markers, sorted by id: row k is row k of the drawn table.
    drawn: DrawnMarkers,
    lattice: Lattice,
    /// Per block, its id and its porosity n1 (a copy of two block-model columns, so that
    /// the tables can be read without the scene).
    block_id: Vec<i64>,
    porosity: Vec<f64>,
    /// The end snapshot's rows in order ([`MarkerRows::snapshot_order`]; empty when none is
    /// kept).
    snapshot_order: Vec<u32>,
}

impl std::fmt::Debug for EndMarkers {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EndMarkers")
            .field("period", &self.period)
            .field("snapshot", &self.snapshot)
            .field("moving", &self.moving.len())
            .field("drawn", &self.drawn.m.len())
            .finish_non_exhaustive()
    }
}

/// `v` reordered: element k is the old element `order[k]`.
fn reordered<T: Copy + Send + Sync>(v: &[T], order: &[u32]) -> Vec<T> {
    order.par_iter().map(|&k| v[k as usize]).collect()
}

impl EndMarkers {
    /// The end of a run whose last period is `period`: its moving and drawn markers, with
    /// an end snapshot when `snapshot`. The markers are sorted by id in place (a column at
    /// a time), so the tables' rows are read in storage order; columns no table reads
    /// (cadence levels, draw times) are let go.
    pub(crate) fn new(
        period: i64,
        snapshot: bool,
        mut moving: Markers,
        mut drawn: DrawnMarkers,
        lattice: Lattice,
        bm: &BlockModel,
    ) -> EndMarkers {
        let order = order_by_id(drawn.m.id.iter());
        drawn.m.permute(&order);
        drawn.drawpoint = reordered(&drawn.drawpoint, &order);
        drawn.period = reordered(&drawn.period, &order);
        drawn.tau = Vec::new();
        drawn.m.level = Vec::new();
        drop(order);
        if snapshot {
            let order = order_by_id(moving.id.iter());
            moving.permute(&order);
            moving.level = Vec::new();
        } else {
            moving = Markers::default();
        }
        let mut end = EndMarkers {
            period,
            snapshot,
            moving,
            drawn,
            lattice,
            block_id: bm.id.clone(),
            porosity: bm.n1.clone(),
            snapshot_order: Vec::new(),
        };
        if snapshot {
            end.snapshot_order = end.rows().snapshot_order();
        }
        end
    }

    fn rows(&self) -> MarkerRows<'_> {
        MarkerRows {
            moving: &self.moving,
            drawn: &self.drawn,
            lattice: &self.lattice,
            block_id: &self.block_id,
            porosity: &self.porosity,
        }
    }

    /// The period of the end snapshot, if the run keeps one.
    pub fn snapshot_period(&self) -> Option<i64> {
        self.snapshot.then_some(self.period)
    }

    /// Rows of the end snapshot (0 when none is kept).
    pub fn snapshot_len(&self) -> usize {
        self.snapshot_order.len()
    }

    /// Rows `range` of the end snapshot (sorted by marker id). Panics if `range` is out
    /// of bounds.
    pub fn snapshot_range(&self, range: Range<usize>) -> MarkerSnapshot {
        self.rows()
            .snapshot(self.period, &self.snapshot_order[range])
    }

    /// Rows of the drawn table.
    pub fn drawn_len(&self) -> usize {
        self.drawn.m.len()
    }

    /// Rows `range` of the drawn table (sorted by marker id). Panics if `range` is out of
    /// bounds.
    pub fn drawn_range(&self, range: Range<usize>) -> DrawnTable {
        let rows: Vec<u32> = (range.start as u32..range.end as u32).collect();
        self.rows().drawn(&rows)
    }

    /// The rows `at` of the drawn table (in that order). Panics if one is out of bounds.
    pub fn drawn_at(&self, at: &[u32]) -> DrawnTable {
        self.rows().drawn(at)
    }

    /// The period in which each row of the drawn table was drawn, in row order.
    pub fn drawn_periods(&self) -> impl Iterator<Item = i64> + '_ {
        self.drawn.period.iter().copied()
    }
}
