//! The air gap: the height of air above the caved ground of each block column, recorded
//! per period (`air_gap` table).
//!
//! A block is air when it holds less than `rilling.air_fill` of its in-situ mass: its
//! stagnant mass (what the lattice gives it, less what has been engulfed) plus the mass of
//! the moving markers that lie in it now. The markers' mass per block is kept as the
//! markers move, not summed again each period: each marker carries the block it was last
//! counted in (`Markers::at`), and a marker that steps into another block, appears or is
//! drawn moves its mass between the blocks' sums and marks their columns. The sums are
//! exact (fixed point, [`FIXED`] units a tonne), so they are the sums a pass over every
//! marker would make, in any order, and only the marked columns are recomputed each period.

use rayon::prelude::*;

use super::Engine;

impl Engine<'_> {
    /// Fixed-point units of a marker's mass in its block's sum.
    fn units(mass: f64) -> i64 {
        (mass * FIXED).round() as i64
    }

    /// Moves `units` of marker mass from block `from` to block `to` (`u32::MAX`: none) and
    /// marks their columns.
    fn shift_mass(&mut self, from: u32, to: u32, units: i64) {
        for (b, sign) in [(from, -1), (to, 1)] {
            if b != u32::MAX {
                self.fixed_mass[b as usize] += sign * units;
                self.dirty_cols[self.block_col[b as usize] as usize] = true;
            }
        }
    }

    /// The block a marker at `p` lies in (`u32::MAX` outside every block).
    fn block_at(&self, p: [f64; 3]) -> u32 {
        self.scene.blocks.locate(p).map_or(u32::MAX, |b| b as u32)
    }

    /// Counts a marker just appended at row `k` (it lies in `Markers::at`, its block of
    /// origin).
    pub(super) fn count_new(&mut self, k: usize) {
        let (b, m) = (self.markers.at[k], self.markers.mass[k]);
        self.shift_mass(u32::MAX, b, Self::units(m));
    }

    /// Stops counting row `k`, about to be drawn.
    pub(super) fn count_drawn(&mut self, k: usize) {
        let (b, m) = (self.markers.at[k], self.markers.mass[k]);
        self.shift_mass(b, u32::MAX, Self::units(m));
    }

    /// Moves the mass of the markers `rows`, which have just moved, to the blocks they lie
    /// in now.
    pub(super) fn count_moved(&mut self, rows: &[u32]) {
        let mk = &self.markers;
        let changed: Vec<(u32, u32)> = rows
            .par_iter()
            .filter_map(|&k| {
                let i = k as usize;
                let b = self.block_at([mk.x[i], mk.y[i], mk.z[i]]);
                (b != mk.at[i]).then_some((k, b))
            })
            .collect();
        for (k, b) in changed {
            let k = k as usize;
            let (from, m) = (self.markers.at[k], self.markers.mass[k]);
            self.markers.at[k] = b;
            self.shift_mass(from, b, Self::units(m));
        }
    }

    /// Counts every marker again from its position (after rilling moved or added markers
    /// outside the marker pass, or on resuming), and marks every column.
    pub(super) fn count_all(&mut self) {
        let mk = &self.markers;
        let at: Vec<u32> = (0..mk.len())
            .into_par_iter()
            .map(|k| self.block_at([mk.x[k], mk.y[k], mk.z[k]]))
            .collect();
        self.markers.at = at;
        self.fixed_mass.iter_mut().for_each(|f| *f = 0);
        for (&b, &m) in self.markers.at.iter().zip(&self.markers.mass) {
            if b != u32::MAX {
                self.fixed_mass[b as usize] += Self::units(m);
            }
        }
        self.all_moved = true;
    }

    /// Air-gap height of every block column, appended to the air-gap table: the air blocks
    /// (caved, holding less than `rilling.air_fill` of their in-situ mass) at the top of
    /// each caved stretch of the column.
    ///
    /// A column's air gap changes only where marker mass came, went or moved between
    /// blocks (the columns marked since the last record), or when ground caves or rills;
    /// only those columns are recomputed, the others keep their last value.
    pub(super) fn record_air_gap(&mut self, period: i64) {
        let bm = &self.scene.blocks;
        let [nx, ny, nz] = bm.dims;
        let vol = bm.size.iter().product::<f64>();
        if self.all_moved {
            self.dirty_cols.iter_mut().for_each(|c| *c = true);
            self.all_moved = false;
        }
        let block = |i: usize, j: usize, k: usize| {
            let b = bm.index[i + nx * (j + ny * k)];
            (b != crate::model::block_model::NO_BLOCK).then_some(b as usize)
        };
        let full = |b: usize| vol * bm.density[b] * (1.0 - bm.n0[b]);
        let fill = self.scenario.rilling.air_fill;
        let t = &mut self.out.air_gap;
        for j in 0..ny {
            for i in 0..nx {
                let col = i + nx * j;
                if std::mem::take(&mut self.dirty_cols[col]) {
                    // From the top of each caved stretch of the column (under uncaved ground
                    // or open to the top of the model) down to its first block that is not
                    // air. A thin block deep in the flow (markers near a drawpoint move
                    // several blocks per update) is not an air gap.
                    let mut air = 0.0;
                    let mut open = true;
                    for k in (0..nz).rev() {
                        let Some(b) = block(i, j, k).filter(|&b| bm.flowable(b, period)) else {
                            open = true;
                            continue;
                        };
                        let mut mass = self.lattice_mass[b] - self.engulfed_mass[b];
                        let f = self.fixed_mass[b];
                        if f != 0 {
                            mass += f as f64 / FIXED;
                        }
                        if open && mass < fill * full(b) {
                            air += bm.size[2];
                        } else {
                            open = false;
                        }
                    }
                    self.air_col[col] = air;
                }
                let air = self.air_col[col];
                if air > 0.0 {
                    t.period.push(period);
                    t.x.push(bm.origin[0] + (i as f64 + 0.5) * bm.size[0]);
                    t.y.push(bm.origin[1] + (j as f64 + 0.5) * bm.size[1]);
                    t.air_gap.push(air);
                }
            }
        }
    }
}

/// Units per tonne of the air gap's exact mass sums: 2^32 (a block of 10^6 t is 2^52 units).
const FIXED: f64 = 4294967296.0;
