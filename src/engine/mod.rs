//! The REBOP flow engine: one module per mechanism.
//!
//! - [`imz`]: IMZ growth by the r-law (summary §3.3).
//! - [`markers`]: the marker lattice and marker motion (summary §3.3), superposition of
//!   overlapping IMZs (summary §4.2).
//! - [`marker_tables`]: the drawn-marker table and marker snapshots, read from the markers
//!   (at the end of the run a range of rows at a time).
//! - [`cadence`]: multi-rate marker updates: a slow marker steps once every 2^L updates.
//! - [`crediting`]: the tonnes credited per period and the drawn stream they are read from.
//! - [`fill`]: the fill of a drawpoint's lowest disks, and why a short period could not
//!   deliver.
//! - [`resolution`]: the automatic choice of h, marker spacing and draw increment.
//! - [`fragmentation`]: primary fragment sizes and secondary fragmentation (summary §6.3).
//! - [`fines`]: fines migration by percolation (summary §7.3), and the bed's counterflow.
//! - [`stress`]: the stress logic and interactive-draw flags (summary §5.3), at chosen
//!   periods when `mechanisms.stress` is on.
//! - [`stability`]: where the method is valid, degraded (warned) or refused.
//! - [`trace`]: trace points (MassFlow's trace markers), followed through the draw.
//!
//! The [`Engine`] is one struct whose methods lie in files by concept: its set-up
//! (`setup`), the update loop (here), the marker pass at the cadence's levels and the
//! catch-up of lagging markers (`levels`), the air gap (`air_gap`), the end of a period
//! (`period_end`) and the end of the run (`finish`).
//!
//! # One period
//! Each period's schedule is drawn in steps that interleave the drawpoints (concurrent
//! draw is the limit of small steps; successive draw is the order of the periods). A step:
//! 1. snapshot every IMZ's geometry (so parallel updates read a fixed state);
//! 2. grow the drawing IMZs in parallel (each passes its void up in cycles, and the void
//!    fines left in it when they percolated out);
//! 3. engulf the lattice sites the grown disks now cover (stagnant → moving markers);
//! 4. one parallel pass over the moving markers whose cadence level is due, summing the
//!    motion of every IMZ that drew in their window and contains each (superposition),
//!    plus fines percolation and its counterflow when it is on; markers leaving the
//!    lowest disk are drawn.
//!    With secondary fragmentation on, the attrited fractions and sizes of the markers
//!    that moved are then updated from their accumulated strain and work.
//!
//! # Mass balance
//! The kinematics conserve mass (`imz`, the volume balance): the IMZ's material is at n1,
//! the stagnant ground at n0, and the marker mass drawn equals the tonnes scheduled up to the
//! discreteness of markers (heavily overlapping IMZs, closer than about three openings,
//! still lose a few percent in superposition; `docs::validation`). Each period is credited
//! its schedule while its drawpoint is flowing and its credits stay within the discreteness
//! of its markers over its whole draw, and its grades are read from the drawpoint's stream
//! of drawn markers over the period's scheduled interval ([`crediting`]); a drawpoint
//! that really could not deliver is `short`, with the reason. The distribution of credited
//! over marker tonnes (per drawpoint-period, and per drawpoint over the run) goes into the
//! run's mass balance (`manifest.json`), and a run whose drawpoints' median ratio leaves
//! 1 ± [`CORRECTION_MEDIAN_TOLERANCE`] warns: that is a bias of the kinematics, not
//! discreteness.

pub mod account;
mod air_gap;
mod balance;
pub mod cadence;
pub mod checkpoint;
pub mod crediting;
pub mod draw_control;
pub mod fill;
pub mod fines;
mod finish;
pub mod fragmentation;
mod height_of_draw;
pub mod imz;
mod levels;
pub mod marker_tables;
pub mod markers;
mod period_end;
pub mod plan;
pub mod random;
pub mod resolution;
pub mod result;
pub mod rilling;
mod setup;
pub mod stability;
pub mod stress;
pub mod trace;
pub mod value;

use rayon::prelude::*;

use crate::model::{Scenario, Scene};
use account::{Account, Mark, Phase};
pub use balance::{
    correction_stats, correction_warning, CORRECTION_BOUNDS, CORRECTION_MEDIAN_TOLERANCE,
};
use cadence::Cadence;
use imz::{DiskMotion, Ground, Imz, ImzGeom, ImzGrid, ImzParams, Listing};
use levels::{level_fields, level_motions, reached};
use markers::{Bins, DrawnMarkers, Lattice, Markers, MotionField, Rim, WallReach};
pub use plan::RunPlan;
pub use result::*;
use setup::grid_cell;

/// Engine errors (bad settings that validation cannot see).
#[derive(Debug, thiserror::Error)]
pub enum EngineError {
    /// The lattice would not fit in memory.
    #[error("marker spacing {spacing} m gives {sites} lattice sites; more than {limit}. Increase resolution.marker_spacing")]
    TooManySites {
        /// Spacing.
        spacing: f64,
        /// Sites.
        sites: usize,
        /// Limit.
        limit: usize,
    },
    /// A checkpoint that cannot be resumed.
    #[error("cannot resume from the checkpoint: {0}")]
    Checkpoint(String),
    /// The scene lies where REBOP's method fails ([`stability`]).
    #[error("{0}")]
    Refused(String),
}

/// Largest lattice the engine accepts (one byte of state per site).
pub const MAX_SITES: usize = 2_000_000_000;

/// The engine's state between steps. Create with [`Engine::new`], drive with
/// [`Engine::run`].
pub struct Engine<'a> {
    scene: &'a Scene,
    scenario: &'a Scenario,
    /// Resolution in use.
    pub resolution: ResolvedResolution,
    params: ImzParams,
    lattice: Lattice,
    /// Marker mass of each block at an interior lattice site, t (`Lattice::unit_masses`).
    unit_mass: Vec<f64>,
    /// In-situ mass the lattice gives each block, t (`Lattice::block_masses`).
    lattice_mass: Vec<f64>,
    engulfed: Vec<bool>,
    /// In-situ mass engulfed per block, t (for the block fill and the air gap).
    engulfed_mass: Vec<f64>,
    /// One IMZ per drawpoint.
    pub imzs: Vec<Imz>,
    /// Per IMZ and disk, the lattice sites just beyond the disk's radius (a cache: empty
    /// after a resume or when ground caves, when the disks walk their whole area again).
    rims: Vec<Vec<Rim>>,
    /// Moving markers.
    pub markers: Markers,
    /// Drawn markers.
    pub drawn: DrawnMarkers,
    carry: Vec<f64>,
    cum: Vec<f64>,
    /// Per drawpoint, its cumulative scheduled tonnes before the period being drawn, t.
    sched_cum: Vec<f64>,
    /// The schedule drawn: the scene's, or under draw control the realised one, each
    /// period's row set when the period starts (`engine::draw_control`).
    schedule: std::borrow::Cow<'a, crate::model::Schedule>,
    /// The drawpoints' columns and neighbours, under draw control.
    control: Option<draw_control::Layout>,
    /// Index of the period being drawn, and how far through it the step that is moving
    /// markers is (½ step in: the draw time of what it draws, `engine::crediting`).
    at: (usize, f64),
    /// Per drawpoint, its drawn markers as a stream (derived from `drawn`).
    streams: Vec<crediting::Stream>,
    /// Per drawpoint, the marker mass (t) and count drawn in the period being drawn (what
    /// the markers were is read from the streams at the end, `read_streams`).
    tally: Vec<(f64, i64)>,
    hod_density_area: Vec<f64>,
    /// Per drawpoint, the block just above it (for the mass of its markers before any is
    /// drawn).
    drawpoint_block: Vec<usize>,
    waste: Vec<bool>,
    fines_frac: Vec<f64>,
    extent: ([f64; 2], [f64; 2]),
    out: RunOutput,
    /// Marker updates done so far (keys the per-marker random streams).
    steps_done: u64,
    /// Marker steps computed so far (the active markers summed over the updates): the
    /// marker pass's work, which grows with the moving markers only.
    pub marker_steps: u64,
    /// The moving markers binned by plan cell (derived from `markers`; the active set).
    bins: Bins,
    /// Scratch list of active marker rows.
    rows: Vec<u32>,
    /// A copy of every IMZ's geometry, as the step's parallel parts read it, and each
    /// IMZ's listing in the plan grids ([`ImzGrid::listing`]): kept between updates and
    /// made again only for the IMZs that drew since (`Engine::refresh_views`).
    geoms: Vec<ImzGeom>,
    /// See `geoms`.
    listings: Vec<Listing>,
    /// Per IMZ, its `drew_at` when its copy and listing were made (`u64::MAX`: never).
    viewed_at: Vec<u64>,
    /// How far the IMZs' images reach from the walls, widened by the IMZs that drew
    /// (`Engine::refresh_views`).
    reach: WallReach,
    /// Per block column (i + n_x j), whether its marker mass changed since the air gap was
    /// last recorded (`air_gap`).
    dirty_cols: Vec<bool>,
    /// Whether every block column's air gap must be recomputed (ground caved, rilling).
    all_moved: bool,
    /// Per block, the mass of the moving markers that lie in it, in fixed point (`air_gap`).
    fixed_mass: Vec<i64>,
    /// Per block, its column i + n_x j.
    block_col: Vec<u32>,
    /// How often each marker steps (`engine::cadence`).
    cadence: Cadence,
    /// Air-gap height per block column (i + n_x j) as last recorded, m.
    air_col: Vec<f64>,
    /// The trace points (`trace`; none unless [`Engine::with_trace`]).
    trace: trace::Trace,
    /// The periods whose free surface the charts' sections through time and the VTK export
    /// need (`Scene::moments`, `Scene::vtk_periods`).
    moments: Vec<i64>,
    /// Time per phase and work counters, when asked for ([`Engine::keep_account`]).
    account: Option<Box<Account>>,
}

impl<'a> Engine<'a> {
    /// The clock, when an account is kept.
    fn clock(&self) -> Option<Mark> {
        self.account.as_ref().map(|_| Mark::now())
    }

    /// Charges the time since `t` to `phase` (when an account is kept) and restarts `t`.
    fn charge(&mut self, phase: Phase, t: &mut Option<Mark>) {
        if let (Some(a), Some(t)) = (self.account.as_mut(), t.as_mut()) {
            a.charge(phase, t);
        }
    }

    /// Whether markers carry individual sizes (a size mechanism is on).
    fn sized(&self) -> bool {
        self.scenario.mechanisms.fragmentation || self.scenario.mechanisms.fines
    }

    /// Runs every period; `progress(done, total)` is called after each period.
    pub fn run(self, progress: &mut dyn FnMut(usize, usize)) -> RunOutput {
        let none = &mut |_: &Engine, _: usize| Ok::<(), std::convert::Infallible>(());
        match self.run_from(0, progress, none) {
            Ok(out) => out,
            Err(never) => match never {},
        }
    }

    /// Runs the periods from index `first` on. After each period, `progress(done, total)`
    /// is called, then `after(&engine, next)` with the index of the next period (the
    /// place to write a checkpoint); an error from `after` stops the run.
    pub fn run_from<E>(
        mut self,
        first: usize,
        progress: &mut dyn FnMut(usize, usize),
        after: &mut dyn FnMut(&Engine, usize) -> Result<(), E>,
    ) -> Result<RunOutput, E> {
        let n = self.scene.periods.len();
        for p in first..n {
            // The rows in the order of their cells, for the cache (`Bins::tidy`).
            let mut t = self.clock();
            self.bins.tidy(&mut self.markers);
            self.charge(Phase::PeriodEnd, &mut t);
            self.run_period(p);
            progress(p + 1, n);
            after(&self, p + 1)?;
        }
        Ok(self.finish())
    }

    fn grid_cell(&self) -> f64 {
        grid_cell(&self.scene.blocks, self.resolution.marker_spacing)
    }

    /// Rows (ascending) of the markers binned in the cells that the IMZs `which` can
    /// reach (their plan bounding boxes and one cell around), into `self.rows`.
    fn rows_near(&mut self, geoms: &[ImzGeom], which: &[usize]) {
        let rects = which.iter().map(|&d| {
            let g = &geoms[d];
            let r = g.max_radius();
            ([g.x - r, g.x + r], [g.y - r, g.y + r])
        });
        let cells = self.bins.cells_of(rects, 1, &[]);
        self.bins.rows_in(&cells, &mut self.rows);
    }

    /// Brings the copies of the IMZs' geometry (`geoms`) and their grid listings up to
    /// date, and the walls' reach with them: an IMZ's disks change only when it draws, so
    /// only the IMZs that drew since they were last copied are copied and listed again (in
    /// parallel).
    fn refresh_views(&mut self, geoms: &mut [ImzGeom]) {
        let (origin, extent, cell) = (self.extent.0, self.extent.1, self.grid_cell());
        let copied: Vec<usize> = (
            &self.imzs,
            &mut *geoms,
            &mut self.listings,
            &mut self.viewed_at,
        )
            .into_par_iter()
            .filter(|(m, _, _, at)| **at != m.drew_at)
            .map(|(m, g, listing, at)| {
                g.clone_from(&m.geom);
                *listing = ImzGrid::listing(g, origin, extent, cell);
                *at = m.drew_at;
                m.id
            })
            .collect();
        for d in copied {
            self.reach.widen(&geoms[d], &self.scene.blocks);
        }
    }

    /// Calls `f` with the motion field of every IMZ's last interval, as a marker update
    /// sees it (for benchmarks and tests of the marker pass).
    pub fn with_last_field<R>(&self, f: impl FnOnce(&MotionField) -> R) -> R {
        let geoms: Vec<ImzGeom> = self.imzs.iter().map(|m| m.geom.clone()).collect();
        let all: Vec<usize> = (0..geoms.len()).collect();
        let grid = ImzGrid::build(&geoms, &all, self.extent.0, self.extent.1, self.grid_cell());
        let motion: Vec<&[DiskMotion]> = self.imzs.iter().map(|m| &m.motion[..]).collect();
        let last = self.scene.periods.id.last().copied().unwrap_or(0);
        f(&MotionField {
            geoms: &geoms,
            motion: &motion,
            grid: &grid,
            ground: Some((&self.scene.blocks, last)),
            reach: WallReach::new(&geoms, &self.scene.blocks),
            seed: self.scenario.seed,
            window: false,
        })
    }

    /// Draws period index `p`.
    pub fn run_period(&mut self, p: usize) {
        let scene = self.scene;
        let period = scene.periods.id[p];
        let bm = &scene.blocks;
        // Ground that caved since the previous period (period numbers need not be
        // consecutive: a block caving at a number between two listed periods is flowable
        // from the later one).
        let prev = if p == 0 {
            i64::MIN
        } else {
            scene.periods.id[p - 1]
        };
        if p == 0 || bm.cave_period.iter().any(|&c| c > prev && c <= period) {
            // Newly caved ground: perimeters and engulfment must be looked at again.
            self.imzs.iter_mut().for_each(Imz::ground_changed);
            self.rims.iter_mut().for_each(Vec::clear);
            self.all_moved = true;
        }
        let mut t = self.clock();
        self.control_plan(p);
        self.charge(Phase::Control, &mut t);
        let row = self.schedule.period(p).to_vec();
        let row = &row[..];
        let scheduled: Vec<usize> = (0..row.len()).filter(|&d| row[d] > 0.0).collect();
        // With the multi-rate cadence, most markers step rarely, and the sums they feed
        // change as slowly: an IMZ's sums are refreshed once per longest window it draws
        // in (`engine::cadence`); without it, every period.
        let window = 1u64 << self.cadence.max_level;
        let stale: Vec<usize> = scheduled
            .iter()
            .copied()
            .filter(|&d| {
                let m = &self.imzs[d];
                window == 1 || m.refreshed_at == 0 || m.drew_at >= m.refreshed_at + window
            })
            .collect();
        self.refresh_mobilised(&stale);
        self.charge(Phase::Mobilised, &mut t);
        for &d in &stale {
            self.imzs[d].refreshed_at = self.steps_done.max(1);
        }
        let inc = self.resolution.draw_increment;
        let max_t = row.iter().cloned().fold(0.0, f64::max);
        let steps = ((max_t / inc).ceil() as usize).max(1);
        let drawing: Vec<usize> = (0..row.len())
            .filter(|&d| row[d] > 0.0)
            .filter(|&d| {
                let g = &self.imzs[d].geom;
                let ok = bm.locate([g.x, g.y, g.z0 + 0.5 * g.h]).is_some_and(|b| bm.flowable(b, period));
                if !ok {
                    let name = &scene.drawpoints.name[d];
                    self.out.warnings.push(RunWarning {
                        rule: WarningRule::Uncaved,
                        drawpoint: Some(name.clone()),
                        amount: row[d],
                        message: format!("period {period}: drawpoint {name} is scheduled but the ground above it is not caved; nothing drawn"),
                    });
                }
                ok
            })
            .collect();
        let rill = self.scenario.mechanisms.rilling;
        let every = self.scenario.rilling.every_steps as u64;
        if max_t > 0.0 && !drawing.is_empty() {
            for j in 0..steps {
                self.at = (p, (j as f64 + 0.5) / steps as f64);
                self.step(period, row, steps, &drawing);
                if rill && every > 0 && self.steps_done % every == 0 {
                    self.rill(period);
                }
            }
        }
        // What is drawn from here on (catching lagging markers up) is drawn at the end.
        self.at = (p, 1.0);
        if rill {
            self.rill(period);
        }
        let first_row = self.out.extraction.drawpoint.len();
        self.close_period(p, period, &drawing);
        let mut t = self.clock();
        self.control_review(p, first_row);
        self.charge(Phase::Control, &mut t);
        for (cum, t) in self.sched_cum.iter_mut().zip(row) {
            *cum += t;
        }
    }

    fn step(&mut self, period: i64, row: &[f64], steps: usize, drawing: &[usize]) {
        let mut t = self.clock();
        let bm = &self.scene.blocks;
        let mut geoms = std::mem::take(&mut self.geoms);
        self.refresh_views(&mut geoms);
        let all: Vec<usize> = (0..geoms.len()).collect();
        let cell = self.grid_cell();
        let grid = ImzGrid::assemble(&self.listings, &all, self.extent.0, self.extent.1, cell);
        let ground = Ground {
            blocks: bm,
            period,
            geoms: &geoms,
            grid: &grid,
        };
        let params = self.params;
        let mut is_drawing = vec![false; self.imzs.len()];
        drawing.iter().for_each(|&d| is_drawing[d] = true);
        let u = self.steps_done + 1;
        let cadence = self.cadence;
        self.charge(Phase::Grids, &mut t);
        let passes: imz::Passes = self
            .imzs
            .par_iter_mut()
            .filter(|m| is_drawing[m.id])
            .map(|imz| {
                imz.begin_interval();
                let mut passes = imz.draw(row[imz.id] / steps as f64, &ground, &params);
                passes += imz.refill(&ground, &params);
                imz.finish_interval(&ground, &params);
                markers::prepare(&mut imz.motion, imz.geom.h);
                imz.drew_at = u;
                if cadence.max_level > 0 {
                    let dv = imz.motion.iter().map(|m| (m.dv, m.dv_out));
                    cadence::accumulate(&mut imz.windows, dv);
                }
                passes
            })
            .sum();
        for &d in drawing {
            let imz = &self.imzs[d];
            let caps = &mut self.out.marker_caps;
            caps.add_disks(&imz.motion, &imz.stagnant, imz.geom.h);
        }
        self.charge(Phase::Growth, &mut t);
        let before = self.markers.len();
        self.engulf(period, drawing);
        self.bins.add_new(&self.markers);
        if let Some(a) = self.account.as_mut() {
            let c = &mut a.counters;
            c.updates += 1;
            c.disk_cycles += passes.made;
            c.merged_cycles += passes.merged;
            c.imz_draws += drawing.len() as u64;
            c.engulfed += (self.markers.len() - before) as u64;
        }
        self.charge(Phase::Engulf, &mut t);
        self.refresh_views(&mut geoms);
        // The levels whose windows end now, and the IMZs that drew in each window.
        let due = cadence.due(u);
        let active = self.active_per_level(u, due, drawing, true);
        // The active set: only markers binned where a drawing IMZ reaches can move, and of
        // those only the ones whose level is due.
        let grids = self.level_grids(&active);
        self.charge(Phase::Grids, &mut t);
        let rows = if cadence.max_level > 0 {
            // A marker steps when its level is due and an IMZ that drew in its window
            // reaches its cell (elsewhere its step would be zero). Such a marker is binned
            // in a cell near the IMZs of the longest window due (its level's IMZs are among
            // them), so the test over every row, in parallel, finds the rows the bins of
            // those cells would list and filter; the serial listing cost more at mine scale.
            // A row whose level is not due costs one byte read; ground no IMZ has reached
            // has no markers yet (`Engine::engulf`), so it still costs nothing.
            let mk = &self.markers;
            cadence::rows_due(&mk.level, due, |k| reached(mk, k as u32, &grids))
        } else {
            self.rows_near(&geoms, &active[due as usize]);
            std::mem::take(&mut self.rows)
        };
        self.marker_steps += rows.len() as u64;
        self.charge(Phase::Rows, &mut t);
        let owned = self.window_motions(&active);
        let motion = level_motions(&self.imzs, &is_drawing, &owned);
        let (ground, seed) = ((&self.scene.blocks, period), self.scenario.seed);
        let fields = level_fields(&geoms, &motion, &grids, &self.reach, ground, seed);
        self.steps_done = u;
        self.trace.step(&fields[0], period);
        let perc = fines::Percolation {
            blocks: bm,
            field: &fields[0],
            period,
            seed: self.scenario.seed,
            step: u,
            owed: match self.scenario.mechanisms.fines {
                true => self.imzs.iter().map(|m| &m.owed[..]).collect(),
                false => Vec::new(),
            },
            settled: Default::default(),
        };
        let extra: Option<markers::StepHook> = self.scenario.mechanisms.fines.then_some(&perc);
        if let Some(a) = self.account.as_mut() {
            a.charge(Phase::Grids, t.as_mut().unwrap());
            let (tests, hits) = markers::count_candidates(&self.markers, &fields, &rows);
            let c = &mut a.counters;
            (c.candidate_tests, c.hits) = (c.candidate_tests + tests, c.hits + hits);
            c.marker_steps += rows.len() as u64;
            a.charge(Phase::Counting, t.as_mut().unwrap());
        }
        let (drawn, caps) = if cadence.max_level == 0 && rows.len() == self.markers.len() {
            // Every marker is active: the contiguous pass (the same steps, no row windows).
            markers::move_markers(&mut self.markers, &fields[0], extra)
        } else {
            let c = (cadence.max_level > 0).then_some((&cadence, u));
            markers::move_rows(&mut self.markers, &fields, extra, &rows, c)
        };
        let settled = perc.into_settled();
        drop(fields);
        if self.scenario.mechanisms.fines {
            self.settle_counterflow(settled);
        }
        self.out.marker_caps = self.out.marker_caps.merge(caps);
        self.charge(Phase::MarkerPass, &mut t);
        self.geoms = geoms;
        self.restart_windows(&active);
        self.after_move(period, rows, drawn);
        self.charge(Phase::Crediting, &mut t);
    }

    /// After a marker pass over `rows`: attrition, the bins, the air gap's block masses,
    /// and the drawn markers credited and moved out.
    fn after_move(&mut self, period: i64, rows: Vec<u32>, mut drawn: Vec<(usize, u32)>) {
        if self.scenario.mechanisms.fragmentation {
            let bm = &self.scene.blocks;
            fragmentation::attrite(&mut self.markers, bm, &self.scenario.fragmentation, &rows);
        }
        self.bins.update(&self.markers, &rows);
        self.count_moved(&rows);
        self.rows = rows;
        // Moved out in descending row order (a swap-remove fills the row it empties from
        // the last one, which has been visited), then credited in the order of their ids,
        // so that neither the tallies' sums nor the drawn table depend on the rows' order
        // (`Markers::permute`).
        drawn.sort_unstable_by_key(|b| std::cmp::Reverse(b.0));
        let mut batch = Markers::default();
        let mut by = Vec::with_capacity(drawn.len());
        for (k, d) in drawn {
            self.count_drawn(k);
            self.markers.take_into(k, &mut batch);
            self.bins.swap_remove(k);
            by.push(d);
        }
        if let Some(a) = self.account.as_mut() {
            a.counters.drawn += by.len() as u64;
        }
        let mut order: Vec<u32> = (0..by.len() as u32).collect();
        order.sort_unstable_by_key(|&j| batch.id[j as usize]);
        batch.permute(&order);
        let (p, frac) = self.at;
        for (j, &o) in order.iter().enumerate() {
            let d = by[o as usize] as usize;
            let m = batch.mass[j];
            let t = &mut self.tally[d];
            t.0 += m;
            t.1 += 1;
            let tau = self.sched_cum[d] + frac * self.schedule.period(p)[d];
            self.streams[d].push(tau, m, self.drawn.m.len() + j);
            self.drawn.tau.push(tau);
            self.drawn.drawpoint.push(d as u32);
            self.drawn.period.push(period);
        }
        self.drawn.m.append(&mut batch);
    }

    /// One rilling step on the free surface (`rilling::rill`).
    fn rill(&mut self, period: i64) {
        self.catch_up(period);
        let (bm, seed, sized) = (&self.scene.blocks, self.scenario.seed, self.sized());
        let size = move |b: usize, id: u64| fragmentation::initial_size(bm, b, seed, id, sized);
        let mut st = rilling::RillState {
            lattice: &self.lattice,
            blocks: &self.scene.blocks,
            period,
            engulfed: &mut self.engulfed,
            engulfed_mass: &mut self.engulfed_mass,
            unit_mass: &self.unit_mass,
            markers: &mut self.markers,
            size: &size,
        };
        rilling::rill(&mut st);
        self.bins.sync(&self.markers);
        self.count_all();
    }

    /// In-situ tonnes of every lattice site engulfed so far (moving, drawn or rilled).
    pub fn engulfed_tonnes(&self) -> f64 {
        self.engulfed_mass.iter().sum()
    }

    /// Turns lattice sites newly covered by the drawing IMZs into moving markers.
    fn engulf(&mut self, period: i64, drawing: &[usize]) {
        let lat = self.lattice;
        let bm = &self.scene.blocks;
        let sized = self.sized();
        let seed = self.scenario.seed;
        let engulfed = &self.engulfed;
        let mut is_drawing = vec![false; self.imzs.len()];
        drawing.iter().for_each(|&d| is_drawing[d] = true);
        // Per drawing IMZ, the sites its disks newly cover ([`Rim`]).
        let scanned: Vec<Vec<usize>> = (&self.imzs, &mut self.rims)
            .into_par_iter()
            .filter(|(m, _)| is_drawing[m.id])
            .map(|(imz, rims)| {
                let g = &imz.geom;
                rims.resize_with(g.radius.len(), Default::default);
                let mut found = Vec::new();
                for (i, (&r, rim)) in g.radius.iter().zip(rims).enumerate() {
                    let layers = || {
                        let zb = g.z0 + i as f64 * g.h;
                        lat.layers_at_level(zb, zb + g.h, |z| g.level(z), i)
                    };
                    rim.take(&lat, (g.x, g.y), r, layers, engulfed, &mut found);
                }
                found
            })
            .collect();
        let mut sites = scanned.concat();
        sites.sort_unstable();
        sites.dedup();
        for id in sites {
            let p = lat.pos(id);
            let Some(b) = bm.locate(p) else { continue };
            if !bm.flowable(b, period) {
                continue;
            }
            self.engulfed[id] = true;
            let m = lat.site_mass(bm, id, self.unit_mass[b]);
            self.engulfed_mass[b] += m;
            let d0 = fragmentation::initial_size(bm, b, seed, id as u64, sized);
            self.markers.push(id as u64, p, m, b as u32, d0);
            self.count_new(self.markers.len() - 1);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::synthetic::UniformBox;

    /// Row order changes no result, bit for bit, so [`Bins::tidy`] may reorder the rows:
    /// a run whose moving markers' rows are reversed before every period gives the tables
    /// of a run whose rows are sorted by cell. Three drawpoints whose IMZs overlap and
    /// reach the walls, with the multi-rate cadence and markers carrying their own sizes
    /// (fragmentation: the sizes are summed into the disks' d̄).
    #[test]
    fn the_rows_order_changes_no_result() {
        let mut scene = UniformBox {
            extent: [0.6, 0.6, 1.0],
            drawpoints: vec![(-0.08, 0.0, 0.12), (0.08, 0.0, 0.12), (0.0, 0.14, 0.12)],
            periods: 12,
            ..UniformBox::castro_isolated()
        }
        .scene();
        // Blocks that differ, so that the sums over markers depend on their order.
        let bm = &mut scene.blocks;
        for b in 0..bm.len() {
            let t = (b as f64 * 0.618).fract();
            bm.frag[b] *= 0.7 + 0.6 * t;
            bm.friction[b] += 6.0 * t - 3.0;
        }
        let mut sc = Scenario::default();
        sc.mechanisms.fragmentation = true;
        let sorted = Engine::new(&scene, &sc).unwrap().run(&mut |_, _| {});
        let mut e = Engine::new(&scene, &sc).unwrap();
        let mut reversals = 0;
        for p in 0..scene.periods.len() {
            let rows: Vec<u32> = (0..e.markers.len() as u32).rev().collect();
            reversals += usize::from(rows.len() > 1);
            e.markers.permute(&rows);
            e.bins = Bins::new(e.extent.0, e.extent.1, e.grid_cell());
            e.bins.sync(&e.markers);
            e.run_period(p);
        }
        let reversed = e.finish();
        assert!(reversals > 8 && sorted.balance.markers_drawn > 100);
        // Compared as printed (every digit of every value), so that NaNs (grades of
        // periods without markers) compare equal.
        let same = |a: &dyn std::fmt::Debug, b: &dyn std::fmt::Debug, what: &str| {
            assert!(format!("{a:?}") == format!("{b:?}"), "{what} differs");
        };
        same(&sorted.extraction, &reversed.extraction, "extraction");
        let (sorted, reversed) = (sorted.with_tables(), reversed.with_tables());
        same(&sorted.drawn, &reversed.drawn, "drawn");
        same(&sorted.imz, &reversed.imz, "imz");
        same(&sorted.air_gap, &reversed.air_gap, "air gap");
        same(&sorted.surface, &reversed.surface, "surface");
        same(&sorted.snapshots, &reversed.snapshots, "snapshots");
    }
}
