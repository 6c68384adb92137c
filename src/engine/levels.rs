//! The marker pass at the levels of the multi-rate cadence ([`cadence`]): per level, the
//! IMZs that drew in its window, their grid, their motion over the window and the motion
//! field a marker of that level steps in; the windows restarted when they end; and the
//! catch-up that brings every lagging marker up to date before positions are read.

use rayon::prelude::*;

use super::imz::{DiskMotion, Imz, ImzGeom, ImzGrid};
use super::markers::{self, Markers, MotionField, WallReach};
use super::{cadence, Engine};

impl Engine<'_> {
    /// Per cadence level 0..=`top`, the IMZs that drew in its window at update `u` (level
    /// 0: `drawing`): the window ending at `u` when `ending`, else the one still open.
    pub(super) fn active_per_level(
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
    pub(super) fn level_grids(&self, active: &[Vec<usize>]) -> Vec<ImzGrid> {
        let (origin, extent, cell) = (self.extent.0, self.extent.1, self.grid_cell());
        active
            .par_iter()
            .map(|a| ImzGrid::assemble(&self.listings, a, origin, extent, cell))
            .collect()
    }

    /// The window motion (`Imz::window_motion`) of every IMZ active at each level ≥ 1
    /// (empty for the others and for level 0).
    pub(super) fn window_motions(&self, active: &[Vec<usize>]) -> Vec<Vec<Vec<DiskMotion>>> {
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
    pub(super) fn restart_windows(&mut self, active: &[Vec<usize>]) {
        for (l, a) in active.iter().enumerate().skip(1) {
            for &d in a {
                let imz = &mut self.imzs[d];
                cadence::restart(&mut imz.windows[l - 1], &imz.geom.radius);
            }
        }
    }

    /// Brings every marker up to date (`engine::cadence`): a marker whose level's window is
    /// still open steps by the motion of that window so far, and takes a level whose
    /// window starts now. Called before whatever reads positions exactly.
    pub(super) fn catch_up(&mut self, period: i64) {
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
        let fields = level_fields(&geoms, &motion, &grids, &self.reach, ground, seed);
        self.marker_steps += lagging.len() as u64;
        if let Some(a) = self.account.as_mut() {
            let (tests, hits) = markers::count_candidates(&self.markers, &fields, &lagging);
            let c = &mut a.counters;
            (c.candidate_tests, c.hits) = (c.candidate_tests + tests, c.hits + hits);
            c.marker_steps += lagging.len() as u64;
        }
        let (drawn, caps) = markers::move_rows(
            &mut self.markers,
            &fields,
            None,
            &lagging,
            Some((&cadence, u)),
        );
        drop(fields);
        self.out.marker_caps = self.out.marker_caps.merge(caps);
        self.geoms = geoms;
        self.after_move(period, lagging, drawn);
    }
}

/// Per cadence level, every IMZ's motion slice: level 0 this update's (for the IMZs in
/// `drawing`), level L ≥ 1 `owned[L]`.
pub(super) fn level_motions<'m>(
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
pub(super) fn level_fields<'f>(
    geoms: &'f [ImzGeom],
    motion: &'f [Vec<&'f [DiskMotion]>],
    grids: &'f [ImzGrid],
    reach: &WallReach,
    ground: (&'f crate::model::BlockModel, i64),
    seed: u64,
) -> Vec<MotionField<'f>> {
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
pub(super) fn reached(mk: &Markers, k: u32, grids: &[ImzGrid]) -> bool {
    let k = k as usize;
    !grids[mk.level[k] as usize].at(mk.x[k], mk.y[k]).is_empty()
}
