//! The REBOP flow engine: one module per mechanism.
//!
//! - [`imz`]: IMZ growth by the r-law (summary §3.3).
//! - [`markers`]: the marker lattice and marker motion (summary §3.3), superposition of
//!   overlapping IMZs (summary §4.2).
//! - [`marker_tables`]: the drawn-marker table and marker snapshots, read from the markers
//!   (at the end of the run a range of rows at a time).
//! - [`cadence`]: multi-rate marker updates: a slow marker steps once every 2^L updates.
//! - [`crediting`]: the tonnes credited per period and the drawn stream they are read from.
//! - [`resolution`]: the automatic choice of h, marker spacing and draw increment.
//! - [`fragmentation`]: primary fragment sizes and secondary fragmentation (summary §6.3).
//! - [`fines`]: fines migration by percolation (summary §7.3).
//! - [`stress`]: the stress logic and interactive-draw flags (summary §5.3), at chosen
//!   periods when `mechanisms.stress` is on.
//! - [`stability`]: where the method is valid, degraded (warned) or refused.
//! - [`trace`]: trace points (MassFlow's trace markers), followed through the draw.
//!
//! # One period
//! Each period's schedule is drawn in steps that interleave the drawpoints (concurrent
//! draw is the limit of small steps; successive draw is the order of the periods). A step:
//! 1. snapshot every IMZ's geometry (so parallel updates read a fixed state);
//! 2. grow the drawing IMZs in parallel (each passes its void up in cycles);
//! 3. engulf the lattice sites the grown disks now cover (stagnant → moving markers);
//! 4. one parallel pass over the moving markers whose cadence level is due, summing the
//!    motion of every IMZ that drew in their window and contains each (superposition),
//!    plus fines percolation when it is on; markers leaving the lowest disk are drawn.
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
pub mod fines;
pub mod fragmentation;
mod height_of_draw;
pub mod imz;
pub mod marker_tables;
pub mod markers;
pub mod plan;
pub mod random;
pub mod resolution;
pub mod result;
pub mod rilling;
pub mod stability;
pub mod stress;
pub mod trace;

use std::time::Instant;

use rayon::prelude::*;

use crate::model::{Scenario, Scene};
use account::{Account, Phase};
pub use balance::{
    correction_stats, correction_warning, CORRECTION_BOUNDS, CORRECTION_MEDIAN_TOLERANCE,
};
use cadence::Cadence;
use crediting::Tally;
use fragmentation::SizeDist;
use height_of_draw::tributary;
use imz::{DiskMotion, Ground, Imz, ImzGeom, ImzGrid, ImzParams, Listing, Mobilised};
use markers::{Bins, DrawnMarkers, Lattice, Markers, MotionField, Rim, WallReach};
pub use plan::RunPlan;
pub use result::*;

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
    /// Sets up the lattice and one IMZ per drawpoint, at the scenario's own plan
    /// ([`RunPlan::new`]).
    pub fn new(scene: &'a Scene, scenario: &'a Scenario) -> Result<Engine<'a>, EngineError> {
        Ok(Engine::with_plan(
            scene,
            scenario,
            RunPlan::new(scene, scenario)?,
        ))
    }

    /// Sets up the lattice and one IMZ per drawpoint, at a plan already made and checked
    /// ([`RunPlan`]).
    pub fn with_plan(scene: &'a Scene, scenario: &'a Scenario, plan: RunPlan) -> Engine<'a> {
        let bm = &scene.blocks;
        let res = plan.resolution();
        let lattice = Lattice::new(bm, res.marker_spacing)
            .with_offset(bm, scenario.resolution.lattice_offset);
        let unit_mass = lattice.unit_masses(bm);
        let max = bm.max_corner();
        let diag = ((max[0] - bm.origin[0]).powi(2) + (max[1] - bm.origin[1]).powi(2)).sqrt();
        // The IMZs sample the ground around them at the marker spacing, but never finer
        // than half their disk thickness (`engine::imz`): markers finer than that sample
        // the grades better and leave the IMZs' geometry alone.
        let ground = res.marker_spacing.max(0.5 * res.layer_thickness);
        let params = ImzParams {
            q: scenario.flow.q,
            shear_band_factor: scenario.flow.shear_band_factor,
            min_jump: scenario.flow.min_porosity_jump,
            resample: 0.5 * ground,
            redilate: 0.05 * ground,
            perimeter_spacing: ground,
            r_cap: diag,
        };
        let dp = &scene.drawpoints;
        let cadence = Cadence::new(res.max_marker_move);
        let imzs = (0..dp.len())
            .map(|d| {
                let h = res.layer_thickness;
                let mut m = Imz::new(d, dp.x[d], dp.y[d], dp.z[d], h, dp.width[d]);
                m.windows = vec![Vec::new(); cadence.max_level as usize];
                for w in &mut m.windows {
                    cadence::restart(w, &m.geom.radius);
                }
                m
            })
            .collect();
        let n_dp = dp.len();
        let mut out = RunOutput {
            resolution: res,
            ..Default::default()
        };
        out.warnings = plan.into_warnings();
        out.extraction.grades = vec![Vec::new(); bm.grades.len()];
        out.extraction.lithology = vec![Vec::new(); bm.lithology_names.len()];
        if scenario.mechanisms.fragmentation {
            let weak = bm.tensile.iter().filter(|t| !(**t > 0.0)).count();
            if weak > 0 {
                out.warnings.push(RunWarning::general(WarningRule::Input, format!(
                    "secondary fragmentation is on but {weak} blocks have no tensile strength or UCS; they do not break"
                )));
            }
        }
        Engine {
            scene,
            scenario,
            resolution: res,
            params,
            lattice,
            lattice_mass: lattice.block_masses(bm, &unit_mass),
            unit_mass,
            engulfed: vec![false; lattice.len()],
            engulfed_mass: vec![0.0; bm.len()],
            imzs,
            rims: vec![Vec::new(); n_dp],
            markers: Markers::default(),
            drawn: DrawnMarkers::default(),
            carry: vec![0.0; n_dp],
            cum: vec![0.0; n_dp],
            sched_cum: vec![0.0; n_dp],
            at: (0, 0.0),
            streams: vec![crediting::Stream::default(); n_dp],
            tally: vec![(0.0, 0); n_dp],
            hod_density_area: tributary(scene),
            drawpoint_block: (0..n_dp)
                .map(|d| {
                    let dp = &scene.drawpoints;
                    bm.locate([dp.x[d], dp.y[d], dp.z[d] + 0.5 * res.layer_thickness])
                        .unwrap_or(0)
                })
                .collect(),
            waste: waste_blocks(scene, scenario),
            fines_frac: fines_fractions(scene, scenario.outputs.fines_cutoff),
            extent: (
                [bm.origin[0], bm.origin[1]],
                [max[0] - bm.origin[0], max[1] - bm.origin[1]],
            ),
            out,
            steps_done: 0,
            marker_steps: 0,
            bins: Bins::new(
                [bm.origin[0], bm.origin[1]],
                [max[0] - bm.origin[0], max[1] - bm.origin[1]],
                grid_cell(bm, res.marker_spacing),
            ),
            rows: Vec::new(),
            geoms: vec![ImzGeom::default(); n_dp],
            listings: vec![Listing::new(); n_dp],
            viewed_at: vec![u64::MAX; n_dp],
            dirty_cols: vec![true; bm.dims[0] * bm.dims[1]],
            all_moved: true,
            fixed_mass: vec![0; bm.len()],
            block_col: block_columns(bm),
            air_col: vec![0.0; bm.dims[0] * bm.dims[1]],
            cadence,
            trace: trace::Trace::default(),
            moments: {
                let o = &scenario.outputs;
                let mut m = scene.moments(&o.section_periods);
                m.extend(scene.vtk_periods(o));
                m
            },
            account: None,
        }
    }

    /// Keeps an account of the run's time per phase and its work counters
    /// ([`account`]), returned in [`RunOutput::account`].
    pub fn keep_account(mut self) -> Self {
        self.account = Some(Box::default());
        self
    }

    /// The account kept so far ([`Engine::keep_account`]), if one is kept.
    pub fn account(&self) -> Option<&Account> {
        self.account.as_deref()
    }

    /// The clock, when an account is kept.
    fn clock(&self) -> Option<Instant> {
        self.account.as_ref().map(|_| Instant::now())
    }

    /// Charges the time since `t` to `phase` (when an account is kept) and restarts `t`.
    fn charge(&mut self, phase: Phase, t: &mut Option<Instant>) {
        if let (Some(a), Some(t)) = (self.account.as_mut(), t.as_mut()) {
            a.charge(phase, t);
        }
    }

    /// Follows `points` through the draw ([`trace`]); they must lie inside the block model
    /// (`model::load` checks it). Call before the first period.
    pub fn with_trace(mut self, points: &[[f64; 3]]) -> Self {
        self.trace = trace::Trace::new(points);
        self
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
    /// date: an IMZ's disks change only when it draws, so only the IMZs that drew since
    /// they were last copied are copied and listed again (in parallel).
    fn refresh_views(&mut self, geoms: &mut [ImzGeom]) {
        let (origin, extent, cell) = (self.extent.0, self.extent.1, self.grid_cell());
        (&self.imzs, geoms, &mut self.listings, &mut self.viewed_at)
            .into_par_iter()
            .filter(|(m, _, _, at)| **at != m.drew_at)
            .for_each(|(m, g, listing, at)| {
                g.clone_from(&m.geom);
                *listing = ImzGrid::listing(g, origin, extent, cell);
                *at = m.drew_at;
            });
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
        let row = scene.schedule.period(p);
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
        let mut t = self.clock();
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
        self.close_period(p, period, &drawing);
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
                let passes = imz.draw(row[imz.id] / steps as f64, &ground, &params);
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
        let fields = level_fields(&geoms, &motion, &grids, ground, seed);
        self.steps_done = u;
        self.trace.step(&fields[0], period);
        let perc = fines::Percolation {
            blocks: bm,
            field: &fields[0],
            period,
            seed: self.scenario.seed,
            step: u,
        };
        let hook = |mk: &Markers, k: usize, st: &mut markers::Step| perc.apply(mk, k, st);
        let extra: Option<markers::StepHook> = self.scenario.mechanisms.fines.then_some(&hook);
        if let Some(a) = self.account.as_mut() {
            a.charge(Phase::Grids, t.as_mut().unwrap());
            let (tests, hits) = markers::count_candidates(&self.markers, &fields, &rows);
            let c = &mut a.counters;
            (c.candidate_tests, c.hits) = (c.candidate_tests + tests, c.hits + hits);
            c.marker_steps += rows.len() as u64;
            a.charge(Phase::Counting, t.as_mut().unwrap());
        }
        let drawn = if cadence.max_level == 0 && rows.len() == self.markers.len() {
            // Every marker is active: the contiguous pass (the same steps, no row windows).
            markers::move_markers(&mut self.markers, &fields[0], extra)
        } else {
            let c = (cadence.max_level > 0).then_some((&cadence, u));
            markers::move_rows(&mut self.markers, &fields, extra, &rows, c)
        };
        drop(fields);
        self.charge(Phase::MarkerPass, &mut t);
        self.geoms = geoms;
        self.restart_windows(&active);
        self.after_move(period, rows, drawn);
        self.charge(Phase::Crediting, &mut t);
    }

    /// Per cadence level 0..=`top`, the IMZs that drew in its window at update `u` (level
    /// 0: `drawing`): the window ending at `u` when `ending`, else the one still open.
    fn active_per_level(
        &self,
        u: u64,
        top: u8,
        drawing: &[usize],
        ending: bool,
    ) -> Vec<Vec<usize>> {
        (0..=top as u32)
            .map(|l| {
                if l == 0 {
                    return drawing.to_vec();
                }
                let start = if ending {
                    u.saturating_sub(1 << l)
                } else {
                    u - u % (1u64 << l)
                };
                (0..self.imzs.len())
                    .filter(|&d| self.imzs[d].drew_at > start)
                    .collect()
            })
            .collect()
    }

    /// The grid over the IMZs active at each cadence level (from the listings that
    /// `refresh_views` keeps).
    fn level_grids(&self, active: &[Vec<usize>]) -> Vec<ImzGrid> {
        let (origin, extent, cell) = (self.extent.0, self.extent.1, self.grid_cell());
        active
            .par_iter()
            .map(|a| ImzGrid::assemble(&self.listings, a, origin, extent, cell))
            .collect()
    }

    /// The window motion (`Imz::window_motion`) of every IMZ active at each level ≥ 1
    /// (empty for the others and for level 0).
    fn window_motions(&self, active: &[Vec<usize>]) -> Vec<Vec<Vec<DiskMotion>>> {
        active
            .iter()
            .enumerate()
            .map(|(l, a)| {
                let mut v = vec![Vec::new(); self.imzs.len()];
                if l > 0 {
                    let got: Vec<Vec<DiskMotion>> = a
                        .par_iter()
                        .map(|&d| {
                            let mut w = self.imzs[d].window_motion(l);
                            markers::prepare(&mut w, self.imzs[d].geom.h);
                            w
                        })
                        .collect();
                    a.iter().zip(got).for_each(|(&d, w)| v[d] = w);
                }
                v
            })
            .collect()
    }

    /// Starts new windows for the levels ≥ 1 in `active` (their windows end now), in the
    /// IMZs that drew in them (the others' windows hold no void and their radii did not
    /// change).
    fn restart_windows(&mut self, active: &[Vec<usize>]) {
        for (l, a) in active.iter().enumerate().skip(1) {
            for &d in a {
                let imz = &mut self.imzs[d];
                cadence::restart(&mut imz.windows[l - 1], &imz.geom.radius);
            }
        }
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
            let tau = self.sched_cum[d] + frac * self.scene.schedule.period(p)[d];
            self.streams[d].push(tau, m, self.drawn.m.len() + j);
            self.drawn.tau.push(tau);
            self.drawn.drawpoint.push(d as u32);
            self.drawn.period.push(period);
        }
        self.drawn.m.append(&mut batch);
    }

    /// Brings every marker up to date (`engine::cadence`): a marker whose level's window is
    /// still open steps by the motion of that window so far, and takes a level whose
    /// window starts now. Called before whatever reads positions exactly.
    fn catch_up(&mut self, period: i64) {
        let u = self.steps_done;
        let cadence = self.cadence;
        if cadence.max_level == 0 || u == 0 {
            return;
        }
        let aligned = cadence.due(u);
        let top = cadence.max_level;
        let active = self.active_per_level(u, top, &[], false);
        // Markers no IMZ of an open window reaches have nothing to catch up.
        let mut geoms = std::mem::take(&mut self.geoms);
        self.refresh_views(&mut geoms);
        let grids = self.level_grids(&active);
        let mk = &self.markers;
        let lagging: Vec<u32> = (0..mk.len() as u32)
            .into_par_iter()
            .filter(|&k| mk.level[k as usize] > aligned && reached(mk, k, &grids))
            .collect();
        if lagging.is_empty() {
            self.geoms = geoms;
            return;
        }
        let owned = self.window_motions(&active);
        let none = vec![false; self.imzs.len()];
        let motion = level_motions(&self.imzs, &none, &owned);
        // A transfer's choice is keyed by the marker and the base, as in any other step.
        let (ground, seed) = ((&self.scene.blocks, period), self.scenario.seed);
        let fields = level_fields(&geoms, &motion, &grids, ground, seed);
        self.marker_steps += lagging.len() as u64;
        if let Some(a) = self.account.as_mut() {
            let (tests, hits) = markers::count_candidates(&self.markers, &fields, &lagging);
            let c = &mut a.counters;
            (c.candidate_tests, c.hits) = (c.candidate_tests + tests, c.hits + hits);
            c.marker_steps += lagging.len() as u64;
        }
        let drawn = markers::move_rows(
            &mut self.markers,
            &fields,
            None,
            &lagging,
            Some((&cadence, u)),
        );
        drop(fields);
        self.geoms = geoms;
        self.after_move(period, lagging, drawn);
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

    /// Free-surface height of every lattice column (i + n_x j) now, m (`rilling::surface`):
    /// the top of the highest marker, or of the highest site never engulfed.
    pub fn free_surface(&self, period: i64) -> Vec<f64> {
        rilling::surface(
            &self.lattice,
            &self.scene.blocks,
            period,
            &self.engulfed,
            &self.markers,
        )
    }

    /// In-situ tonnes of every lattice site engulfed so far (moving, drawn or rilled).
    pub fn engulfed_tonnes(&self) -> f64 {
        self.engulfed_mass.iter().sum()
    }

    /// The in-situ composition of the cell of site `id`, whose centre lies in block `b`:
    /// the blocks the cell overlaps, each with its share of the cell's in-situ solids
    /// (`Lattice::cell_blocks`, weighted by ρ (1 − n0)); `[(b, 1)]` for a cell in one
    /// block. A marker stands for its whole cell, so where the cell straddles a block face
    /// its grade, lithology and waste share are the cell's mix, not its centre block's:
    /// taking the centre block's moved every block face's grade by up to s/2 and made the
    /// demo's whole-run grade error jump between 1.1 and 2.0% among spacings 1.05–1.52 m
    /// (`docs::resolution`, "Automatic resolution"). Size and fines stay the centre
    /// block's, as does the marker's mass (the lattice's, `Lattice::unit_masses`).
    fn composition(&self, id: usize, b: usize) -> Vec<(usize, f64)> {
        let bm = &self.scene.blocks;
        let mut cell = Vec::with_capacity(8);
        self.lattice.cell_blocks(bm, id, &mut cell);
        for (c, w) in cell.iter_mut() {
            *w *= bm.density[*c] * (1.0 - bm.n0[*c]);
        }
        let solids: f64 = cell.iter().map(|&(_, w)| w).sum();
        if cell.len() < 2 || solids <= 0.0 {
            return vec![(b, 1.0)];
        }
        cell.iter_mut().for_each(|(_, w)| *w /= solids);
        cell
    }

    /// Adds row `k` of the drawn markers `mk` to a tally.
    fn contribute(&self, mk: &Markers, k: usize, t: &mut Tally) {
        let bm = &self.scene.blocks;
        let b = mk.block[k] as usize;
        let m = mk.mass[k];
        // The marker's size distribution and fines share: its own (primary size, attrited
        // fraction) when markers are sized, else its block's primary distribution.
        let (dist, fines) = if self.sized() {
            let dist = SizeDist::Attrited {
                d0: mk.frag0[k],
                w: mk.attrited[k],
                m: self.scenario.fragmentation.product_exponent,
            };
            (dist, dist.passing(self.scenario.outputs.fines_cutoff))
        } else {
            (SizeDist::of_block(bm, b), self.fines_frac[b])
        };
        let composition = self.composition(mk.id[k] as usize, b);
        t.mass += m;
        t.count += 1;
        for (g, col) in bm.grades.iter().enumerate() {
            t.grade[g] += m * composition.iter().map(|&(b, w)| w * col[b]).sum::<f64>();
        }
        let mut waste = 0.0;
        for &(b, w) in &composition {
            t.lith[bm.lithology[b] as usize] += m * w;
            if self.waste[b] {
                waste += w;
            }
        }
        t.origin_z += m * self.lattice.pos(mk.id[k] as usize)[2];
        t.frag += m * mk.frag[k];
        t.fines += m * fines;
        t.fines_z += m * fines * self.lattice.pos(mk.id[k] as usize)[2];
        t.sizes.push((dist, m));
        t.percolated += m * mk.percolated[k];
        if waste > 0.0 {
            t.waste += m * waste;
            t.fines_waste += m * fines * waste;
        }
        let rilled = mk.rill[k];
        if rilled > 0.0 {
            t.rilled += m;
            t.rill_dist += m * rilled;
        }
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

    /// Recomputes the mobilised properties (means) of the disks of the IMZs `which` (those
    /// drawing this period) from the markers inside them, in parallel over the IMZs. Each
    /// IMZ visits only the markers binned in the cells its bounding box covers, and sums
    /// them in the order of their ids, whatever the rows' order; the other IMZs' sums
    /// are not read until they draw, and are refreshed then.
    fn refresh_mobilised(&mut self, which: &[usize]) {
        if which.is_empty() {
            return;
        }
        let bm = &self.scene.blocks;
        let mut wanted = vec![false; self.imzs.len()];
        which.iter().for_each(|&d| wanted[d] = true);
        let (mk, bins) = (&self.markers, &self.bins);
        self.imzs
            .par_iter_mut()
            .filter(|imz| wanted[imz.id])
            .for_each(|imz| {
                imz.mobilised
                    .iter_mut()
                    .for_each(|m| *m = Mobilised::default());
                // A marker inside the IMZ lies in its plan bounding box, so in these cells.
                let g = &imz.geom;
                let r = g.max_radius();
                let mut cells = Vec::new();
                bins.cells_in([g.x - r, g.x + r], [g.y - r, g.y + r], 0, &mut cells);
                // The markers inside, keyed by id: the sums run in the order of the ids.
                let mut inside: Vec<(u64, u32)> = cells
                    .iter()
                    .flat_map(|&c| bins.list(c).iter().copied())
                    .filter(|&k| {
                        let k = k as usize;
                        g.contains([mk.x[k], mk.y[k], mk.z[k]])
                    })
                    .map(|k| (mk.id[k as usize], k))
                    .collect();
                inside.sort_unstable();
                for (_, k) in inside {
                    let k = k as usize;
                    let b = mk.block[k] as usize;
                    let i = ((mk.z[k] - g.z0) / g.h) as usize;
                    let m = &mut imz.mobilised[i];
                    m.d += mk.frag[k];
                    m.phi += bm.friction[b];
                    m.rho1 += bm.density[b] * (1.0 - bm.n1[b]);
                    m.rho_s += bm.density[b];
                    m.count += 1;
                }
                for m in imz.mobilised.iter_mut().filter(|m| m.count > 0) {
                    let k = m.count as f64;
                    (m.d, m.phi, m.rho1, m.rho_s) = (m.d / k, m.phi / k, m.rho1 / k, m.rho_s / k);
                }
            });
    }

    /// Writes the period's extraction rows and snapshots, and applies the correction.
    fn close_period(&mut self, p: usize, period: i64, drawing: &[usize]) {
        let mut t = self.clock();
        let scene = self.scene;
        let last = p + 1 == scene.periods.len();
        let surface = &self.scenario.outputs.surface_periods;
        let snapshot = &self.scenario.outputs.marker_periods;
        let moment = self.moments.contains(&period);
        if last || surface.contains(&period) || snapshot.contains(&period) {
            // Positions are read exactly: every marker up to date (`engine::cadence`),
            // before the period's tallies are written.
            self.catch_up(period);
        }
        let row = scene.schedule.period(p);
        let mut caved = vec![false; row.len()];
        drawing.iter().for_each(|&d| caved[d] = true);
        let bm = &scene.blocks;
        let ex = &mut self.out.extraction;
        for d in 0..row.len() {
            let (mass, count) = std::mem::take(&mut self.tally[d]);
            let scheduled = row[d];
            if scheduled <= 0.0 && count == 0 {
                continue;
            }
            // Credited the schedule while flowing and within the budget (`crediting`).
            let s_end = self.sched_cum[d] + scheduled;
            let stream = &self.streams[d];
            let marker = stream
                .mean_mass()
                .unwrap_or(self.unit_mass[self.drawpoint_block[d]]);
            let trail = (crediting::TRAIL_MARKERS * marker).max(scheduled);
            let step = self.resolution.draw_increment;
            let credited = if caved[d] {
                stream.credit(s_end, scheduled, mass, self.cum[d], (trail, marker, step))
            } else {
                mass.min(scheduled)
            };
            let c = if mass > 0.0 {
                credited / mass
            } else {
                f64::NAN
            };
            self.carry[d] += scheduled - credited;
            self.cum[d] += credited;
            ex.drawpoint.push(d as u32);
            ex.period.push(period);
            ex.scheduled_tonnes.push(scheduled);
            ex.marker_tonnes.push(mass);
            ex.correction.push(c);
            ex.tonnes.push(credited);
            ex.shortfall_tonnes.push(self.carry[d]);
            ex.cum_tonnes.push(self.cum[d]);
            ex.markers.push(count);
            ex.hod
                .push(self.cum[d] / self.hod_density_area[d].max(1e-12));
            ex.air_gap.push(self.imzs[d].air);
            // What was drawn is read from the stream at the end (`read_streams`).
            Tally::new(bm.grades.len(), bm.lithology_names.len())
                .derived()
                .push(ex);
            let imz = &self.imzs[d];
            let short = credited < scheduled;
            ex.status.push(if scheduled <= 0.0 {
                "idle"
            } else if short {
                "short"
            } else {
                "ok"
            });
            ex.short_reason.push(if !short {
                ""
            } else if !caved[d] {
                "uncaved"
            } else if imz.blocked && imz.air > 0.0 {
                "blocked"
            } else {
                "exhausted"
            });
        }
        if self.scenario.outputs.imz_every_period || last {
            let imz = &mut self.out.imz;
            for m in &self.imzs {
                for (i, &r) in m.geom.radius.iter().enumerate() {
                    imz.drawpoint.push(m.id as u32);
                    imz.period.push(period);
                    imz.disk.push(i as i64);
                    imz.z_base.push(m.geom.z0 + i as f64 * m.geom.h);
                    imz.z_top.push(m.geom.z0 + (i + 1) as f64 * m.geom.h);
                    imz.radius.push(r);
                }
            }
        }
        self.charge(Phase::PeriodEnd, &mut t);
        self.record_air_gap(period);
        self.charge(Phase::AirGap, &mut t);
        self.trace.record(period, &mut self.out.trace);
        let wanted = &self.scenario.outputs.surface_periods;
        let written = wanted.contains(&period) || (wanted.is_empty() && last);
        if written || moment {
            let h = self.free_surface(period);
            let table = if written {
                &mut self.out.surface
            } else {
                &mut self.out.moment_surface
            };
            surface_rows(&self.lattice, period, &h, table);
        }
        // The end snapshot is read from the markers as `finish` leaves them
        // (`marker_tables`), not made here.
        let wanted = &self.scenario.outputs.marker_periods;
        if wanted.contains(&period) && !last {
            let snap = self.snapshot(period);
            self.out.snapshots.push(snap);
        }
        let stress = &self.scenario.stress;
        if self.scenario.mechanisms.stress
            && (stress.periods.contains(&period) || (stress.periods.is_empty() && last))
        {
            let geoms: Vec<ImzGeom> = self.imzs.iter().map(|m| m.geom.clone()).collect();
            let params = stress::StressParams::new(stress, self.resolution.layer_thickness);
            let mut field = stress::compute(&scene.blocks, period, &geoms, &params, stress);
            field.drawn_tonnes = self.cum.clone();
            self.out.stress.push(field);
        }
        self.charge(Phase::PeriodEnd, &mut t);
    }

    /// Marker states now: every moving and drawn marker, sorted by id.
    pub fn snapshot(&self, period: i64) -> MarkerSnapshot {
        let bm = &self.scene.blocks;
        let rows = marker_tables::MarkerRows {
            moving: &self.markers,
            drawn: &self.drawn,
            lattice: &self.lattice,
            block_id: &bm.id,
            porosity: &bm.n1,
        };
        rows.snapshot(period, &rows.snapshot_order())
    }

    /// What each extraction row drew, read from its drawpoint's stream over the row's
    /// scheduled interval (`crediting`), in place of the row's own markers.
    fn read_streams(&mut self) {
        let scene = self.scene;
        let bm = &scene.blocks;
        let at: std::collections::HashMap<i64, usize> = scene
            .periods
            .id
            .iter()
            .enumerate()
            .map(|(i, &p)| (p, i))
            .collect();
        // Per drawpoint, cumulative scheduled tonnes before each period.
        let n_dp = scene.drawpoints.len();
        let mut before = vec![vec![0.0; n_dp]; scene.periods.len() + 1];
        for p in 0..scene.periods.len() {
            let row = scene.schedule.period(p);
            for d in 0..n_dp {
                before[p + 1][d] = before[p][d] + row[d];
            }
        }
        let ex = &self.out.extraction;
        let derived: Vec<crediting::Derived> = (0..ex.drawpoint.len())
            .into_par_iter()
            .map(|k| {
                let d = ex.drawpoint[k] as usize;
                let p = at[&ex.period[k]];
                let stream = &self.streams[d];
                let rows = stream.window(before[p][d], before[p + 1][d], crediting::GRADE_MARKERS);
                let mut t = Tally::new(bm.grades.len(), bm.lithology_names.len());
                for r in rows {
                    self.contribute(&self.drawn.m, stream.row[r] as usize, &mut t);
                }
                t.derived()
            })
            .collect();
        for (k, dv) in derived.into_iter().enumerate() {
            dv.set(&mut self.out.extraction, k);
        }
    }

    /// Completes the output: the mass balance, the warnings, and the markers handed over as
    /// they are ([`marker_tables::EndMarkers`]: the drawn table and the end snapshot).
    fn finish(mut self) -> RunOutput {
        let mut clock = self.clock();
        // At mine scale the end of the run is where memory peaks: what is read no more is
        // let go as soon as it is not (the draw times are the streams', kept in `drawn`
        // for a resume only; the streams once read).
        self.drawn.tau = Vec::new();
        self.read_streams();
        self.streams = Vec::new();
        self.rims = Vec::new();
        let dm = &self.drawn;
        let sched = &self.scene.schedule;
        let n_dp = self.scene.drawpoints.len();
        let b = &mut self.out.balance;
        b.per_drawpoint = (0..n_dp).map(|d| (sched.total(d), self.cum[d])).collect();
        b.scheduled_tonnes = sched.tonnes.iter().sum();
        b.credited_tonnes = self.cum.iter().sum();
        b.marker_tonnes = self.out.extraction.marker_tonnes.iter().sum();
        b.final_shortfall_tonnes = self.carry.iter().sum();
        b.markers_drawn = dm.m.len() as u64;
        b.markers_mobilised = (dm.m.len() + self.markers.len()) as u64;
        b.correction = correction_stats(&self.out.extraction);
        if let Some(m) = correction_warning(&b.correction) {
            self.out
                .warnings
                .push(RunWarning::general(WarningRule::MassBalance, m));
        }
        for (d, &c) in self.carry.iter().enumerate() {
            if c > 1e-6 * sched.total(d).max(1.0) {
                let name = &self.scene.drawpoints.name[d];
                self.out.warnings.push(RunWarning {
                    rule: WarningRule::Short,
                    drawpoint: Some(name.clone()),
                    amount: c,
                    message: format!("drawpoint {name} could not deliver {c:.1} t of its schedule (IMZ blocked or nothing left to draw)"),
                });
            }
        }
        for imz in &self.imzs {
            if imz.air > 0.0 {
                let name = &self.scene.drawpoints.name[imz.id];
                self.out.warnings.push(RunWarning {
                    rule: WarningRule::AirGap,
                    drawpoint: Some(name.clone()),
                    amount: imz.air,
                    message: format!("drawpoint {name}: IMZ held under uncaved ground; {:.3e} m3 of void is still an air gap at the end of the run", imz.air),
                });
            }
        }
        let scene = self.scene;
        if let Some(&last) = scene.periods.id.last() {
            let wanted = &self.scenario.outputs.marker_periods;
            let snapshot = wanted.is_empty() || wanted.contains(&last);
            self.out.end = Some(marker_tables::EndMarkers::new(
                last,
                snapshot,
                std::mem::take(&mut self.markers),
                std::mem::take(&mut self.drawn),
                self.lattice,
                &scene.blocks,
            ));
        }
        self.charge(Phase::Finish, &mut clock);
        self.out.account = self.account.take().map(|a| *a);
        self.out
    }
}

/// Per cadence level, every IMZ's motion slice: level 0 this update's (for the IMZs in
/// `drawing`), level L ≥ 1 `owned[L]`.
fn level_motions<'m>(
    imzs: &'m [Imz],
    drawing: &[bool],
    owned: &'m [Vec<Vec<DiskMotion>>],
) -> Vec<Vec<&'m [DiskMotion]>> {
    owned
        .iter()
        .enumerate()
        .map(|(l, o)| {
            imzs.iter()
                .map(|m| match (l, drawing[m.id]) {
                    (0, true) => &m.motion[..],
                    (0, false) => &[][..],
                    _ => &o[m.id][..],
                })
                .collect()
        })
        .collect()
}

/// The marker-pass field of each cadence level.
fn level_fields<'f>(
    geoms: &'f [ImzGeom],
    motion: &'f [Vec<&'f [DiskMotion]>],
    grids: &'f [ImzGrid],
    ground: (&'f crate::model::BlockModel, i64),
    seed: u64,
) -> Vec<MotionField<'f>> {
    let reach = WallReach::new(geoms, ground.0);
    (0..grids.len())
        .map(|l| MotionField {
            geoms,
            motion: &motion[l],
            grid: &grids[l],
            ground: Some(ground),
            reach: reach.clone(),
            seed,
            window: l > 0,
        })
        .collect()
}

/// Whether an IMZ active at marker row `k`'s level reaches its cell (elsewhere its step
/// would be zero).
fn reached(mk: &Markers, k: u32, grids: &[ImzGrid]) -> bool {
    let k = k as usize;
    !grids[mk.level[k] as usize].at(mk.x[k], mk.y[k]).is_empty()
}

/// Per block, its column i + n_x j in the block model's grid.
fn block_columns(bm: &crate::model::BlockModel) -> Vec<u32> {
    let mut col = vec![0; bm.len()];
    for (c, &b) in bm.index.iter().enumerate() {
        if b != crate::model::block_model::NO_BLOCK {
            col[b as usize] = (c % (bm.dims[0] * bm.dims[1])) as u32;
        }
    }
    col
}

/// Cell of the plan grids over the IMZs and the marker bins: the smaller block side, or the
/// marker spacing when coarser.
fn grid_cell(bm: &crate::model::BlockModel, spacing: f64) -> f64 {
    bm.size[0].min(bm.size[1]).max(spacing)
}

/// Appends a free-surface height field (`Engine::free_surface`) to a surface table, one row
/// per lattice column that has a surface.
fn surface_rows(lat: &Lattice, period: i64, h: &[f64], t: &mut SurfaceTable) {
    for (c, &z) in h.iter().enumerate() {
        if z.is_finite() {
            t.period.push(period);
            t.x.push(lat.centre(0, c % lat.n[0]));
            t.y.push(lat.centre(1, c / lat.n[0]));
            t.z.push(z);
        }
    }
}

/// Which blocks are waste under the scenario's dilution rule.
fn waste_blocks(scene: &Scene, sc: &Scenario) -> Vec<bool> {
    let bm = &scene.blocks;
    let g = match &sc.dilution.grade {
        Some(name) => bm.grade_names.iter().position(|n| n == name),
        None => (!bm.grades.is_empty()).then_some(0),
    };
    let waste_lith: Vec<bool> = bm
        .lithology_names
        .iter()
        .map(|n| sc.dilution.waste_lithologies.iter().any(|w| w == n))
        .collect();
    (0..bm.len())
        .map(|b| {
            waste_lith[bm.lithology[b] as usize]
                || g.is_some_and(|g| bm.grades[g][b] < sc.dilution.cutoff)
        })
        .collect()
}

/// Mass share of each block's primary fragmentation finer than `cut`: the Weibull CDF
/// 1 − exp(−(cut/β)^α) where α, β are given, else 1 or 0 by the mean size.
fn fines_fractions(scene: &Scene, cut: f64) -> Vec<f64> {
    let bm = &scene.blocks;
    (0..bm.len())
        .map(|b| {
            let (a, s) = (bm.frag_shape[b], bm.frag_scale[b]);
            if a.is_finite() && s.is_finite() && a > 0.0 && s > 0.0 {
                1.0 - (-(cut / s).powf(a)).exp()
            } else if bm.frag[b] < cut {
                1.0
            } else {
                0.0
            }
        })
        .collect()
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

    /// The lattice holds the block model's metal where the density is uniform: Σ over
    /// every site of its mass times its cell's grade ([`Engine::composition`]) is Σ over
    /// the blocks of their in-situ solids times their grade, to rounding, on a lattice whose
    /// layers and columns straddle the block faces (35 mm on 50 mm blocks). Taking each
    /// site's centre block instead is 1.6% off here.
    #[test]
    fn the_lattice_carries_the_block_models_metal() {
        let mut scene = UniformBox {
            extent: [0.6, 0.55, 0.4],
            ..UniformBox::castro_isolated()
        }
        .scene();
        // A grade that is not linear in the blocks' coordinates, whose straddles would
        // cancel.
        scene.blocks.grades[0] = (0..scene.blocks.len())
            .map(|b| (scene.blocks.z[b] * 10.0).powi(2) + scene.blocks.x[b].abs())
            .collect();
        let bm = &scene.blocks;
        let in_situ: f64 = (0..bm.len())
            .map(|b| {
                bm.size.iter().product::<f64>() * bm.density[b] * (1.0 - bm.n0[b]) * bm.grades[0][b]
            })
            .sum();
        for offset in [[0.0, 0.0], [0.3, -0.5]] {
            let mut sc = Scenario::default();
            sc.resolution.marker_spacing = Some(0.035);
            sc.resolution.layer_thickness = Some(0.07);
            sc.resolution.lattice_offset = offset;
            let e = Engine::new(&scene, &sc).unwrap();
            let (mut cells, mut centres) = (0.0, 0.0);
            for id in 0..e.lattice.len() {
                let b = bm.locate(e.lattice.pos(id)).unwrap();
                let m = e.lattice.site_mass(bm, id, e.unit_mass[b]);
                let g: f64 = e
                    .composition(id, b)
                    .iter()
                    .map(|&(c, w)| w * bm.grades[0][c])
                    .sum();
                cells += m * g;
                centres += m * bm.grades[0][b];
            }
            assert!(
                (cells / in_situ - 1.0).abs() < 1e-9,
                "{offset:?}: {cells} {in_situ}"
            );
            let off = (centres / in_situ - 1.0).abs();
            eprintln!("{offset:?}: centre blocks' metal / in-situ − 1 = {off:.2e}");
            assert!(
                off > 1e-2,
                "{offset:?}: the centre blocks' metal is off by {off}"
            );
        }
    }
}
