//! Trace markers (MassFlow's trace points): given points followed through the draw.
//!
//! A trace point is a marker without mass. It starts in situ at its given position; it is
//! mobilised (moving) at the first step that finds it inside a disk of a drawing IMZ, in
//! caved ground, as a lattice site is engulfed (`Engine::engulf`); from then on it moves every step by the
//! step's motion field ([`MotionField::step`], the superposed motion of the drawing IMZs),
//! and it is drawn, credited to the IMZ that moved it most, when it leaves the lowest disk,
//! exactly as a marker is.
//!
//! # What it does not do
//! - It carries no mass and feeds nothing back: no IMZ, marker, tally or table other than
//!   the trace table reads it, so a run's other outputs are byte-identical with or without
//!   trace points.
//! - It steps at every update, REBOP's scheme, whatever `resolution.max_marker_move` lets
//!   the lattice markers do (`engine::cadence`): trace points are few, and this way a
//!   trace point's path is the exact one at the run's draw increment.
//! - It does not rill on the free surface nor percolate (`mechanisms.rilling`,
//!   `mechanisms.fines`): those move the lattice markers that stand for mass, and a trace
//!   point follows the flow of the caved rock. In a run with rilling, a trace point on the
//!   free surface stays where the flow leaves it.
//!
//! Its shear strain and work accumulate as a marker's do. The state is part of a
//! checkpoint, and is a pure function of the run's steps, so runs are deterministic and
//! resumed runs identical.

use serde::{Deserialize, Serialize};

use super::markers::MotionField;
use super::result::{MarkerState, TraceTable};

/// Trace point k's id in the keys of its random choices ([`MotionField::step`]): k with the
/// top bit set, apart from every marker's.
const TRACE_IDS: u64 = 1 << 63;

/// The trace points' state between steps, struct of arrays; row k is trace id k + 1.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Trace {
    /// Given position, m.
    pub origin: Vec<[f64; 3]>,
    /// Current position, m.
    pub pos: Vec<[f64; 3]>,
    /// In situ, moving or drawn.
    pub state: Vec<MarkerState>,
    /// Drawpoint index that drew it (u32::MAX if not drawn).
    pub drawpoint: Vec<u32>,
    /// Period number in which it was drawn (-1 if not drawn).
    pub drawn_period: Vec<i64>,
    /// Accumulated shear strain Γ.
    pub strain: Vec<f64>,
    /// Accumulated shear work Γσ_n, kPa.
    pub work: Vec<f64>,
}

impl Trace {
    /// Trace points in situ at `points`.
    pub fn new(points: &[[f64; 3]]) -> Trace {
        let n = points.len();
        Trace {
            origin: points.to_vec(),
            pos: points.to_vec(),
            state: vec![MarkerState::InSitu; n],
            drawpoint: vec![u32::MAX; n],
            drawn_period: vec![-1; n],
            strain: vec![0.0; n],
            work: vec![0.0; n],
        }
    }

    /// Number of trace points.
    pub fn len(&self) -> usize {
        self.pos.len()
    }

    /// Whether there is no trace point.
    pub fn is_empty(&self) -> bool {
        self.pos.is_empty()
    }

    /// Whether the arrays agree in length (a checkpoint's state is checked with it).
    pub fn is_consistent(&self) -> bool {
        let n = self.len();
        [
            self.origin.len(),
            self.state.len(),
            self.drawpoint.len(),
            self.drawn_period.len(),
            self.strain.len(),
            self.work.len(),
        ]
        .iter()
        .all(|&l| l == n)
    }

    /// One engine step in `period`: mobilises the trace points in situ that the grown disks
    /// of the drawing IMZs (those of `field.grid`) now hold in caved ground, as
    /// `Engine::engulf` mobilises lattice sites, and moves the moving ones by `field`.
    pub fn step(&mut self, field: &MotionField, period: i64) {
        for k in 0..self.len() {
            let p = self.pos[k];
            match self.state[k] {
                MarkerState::Drawn => continue,
                MarkerState::InSitu => {
                    let caved = field
                        .ground
                        .is_none_or(|(bm, _)| bm.locate(p).is_some_and(|b| bm.flowable(b, period)));
                    let geoms = field.geoms;
                    let held = || {
                        let mut near = field.grid.at(p[0], p[1]).iter();
                        near.any(|&d| geoms[d as usize].contains(p))
                    };
                    if !(caved && held()) {
                        continue;
                    }
                    self.state[k] = MarkerState::Moving;
                }
                MarkerState::Moving => {}
            }
            let s = field.step(p, TRACE_IDS | k as u64);
            self.pos[k] = [p[0] + s.dx, p[1] + s.dy, p[2] + s.dz];
            self.strain[k] += s.strain;
            self.work[k] += s.work;
            if s.drawn_by != u32::MAX {
                self.state[k] = MarkerState::Drawn;
                self.drawpoint[k] = s.drawn_by;
                self.drawn_period[k] = period;
            }
        }
    }

    /// Appends every trace point's state at the end of `period` to `t`.
    pub fn record(&self, period: i64, t: &mut TraceTable) {
        for k in 0..self.len() {
            let (p, o) = (self.pos[k], self.origin[k]);
            t.trace_id.push(k as i64 + 1);
            t.period.push(period);
            t.x.push(p[0]);
            t.y.push(p[1]);
            t.z.push(p[2]);
            t.origin_x.push(o[0]);
            t.origin_y.push(o[1]);
            t.origin_z.push(o[2]);
            t.state.push(self.state[k]);
            t.drawpoint.push(self.drawpoint[k]);
            t.drawn_period.push(self.drawn_period[k]);
            t.shear_strain.push(self.strain[k]);
            t.shear_work.push(self.work[k]);
        }
    }
}
