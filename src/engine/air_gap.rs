//! The air gap: the height of air above the caved ground of each block column, recorded
//! per period (`air_gap` table).

use rayon::prelude::*;

use super::Engine;

impl Engine<'_> {
    /// Notes that markers moved, appeared or left in plan cells `cells` (for the air gap).
    pub(super) fn mark_moved(&mut self, cells: &[usize]) {
        if self.moved_cells.len() != self.bins.n_cells() + 1 {
            self.moved_cells = vec![false; self.bins.n_cells() + 1];
        }
        cells.iter().for_each(|&c| self.moved_cells[c] = true);
    }

    /// Air-gap height of every block column, appended to the air-gap table: the air blocks
    /// (caved, holding less than `rilling.air_fill` of their in-situ mass) at the top of
    /// each caved stretch of the column.
    ///
    /// A column's air gap changes only where markers moved, appeared or left (the plan cells
    /// noted by `mark_moved`), or when ground caves or rills; only those columns are
    /// recomputed, the others keep their last value. A block's mass sums its markers in
    /// ascending row order, as a pass over every marker would.
    pub(super) fn record_air_gap(&mut self, period: i64) {
        let bm = &self.scene.blocks;
        let [nx, ny, nz] = bm.dims;
        let vol = bm.size.iter().product::<f64>();
        // Block columns to recompute, and the rows of the markers that may lie in them.
        let mut cols = vec![self.all_moved; nx * ny];
        if self.all_moved {
            self.rows.clear();
            self.rows.extend(0..self.markers.len() as u32);
        } else {
            let mut cells = Vec::new();
            for (c, _) in self.moved_cells.iter().enumerate().filter(|m| *m.1) {
                if c == self.bins.n_cells() {
                    continue;
                }
                let [x, y] = self.bins.cell_rect(c);
                let span = |lo: f64, hi: f64, a: usize| {
                    let t0 = ((lo - bm.origin[a]) / bm.size[a]).floor().max(0.0) as usize;
                    let t1 = ((hi - bm.origin[a]) / bm.size[a]).floor().max(0.0) as usize;
                    (t0.saturating_sub(1), (t1 + 1).min(bm.dims[a] - 1))
                };
                let ((i0, i1), (j0, j1)) = (span(x[0], x[1], 0), span(y[0], y[1], 1));
                for j in j0..=j1 {
                    for i in i0..=i1 {
                        if !cols[i + nx * j] {
                            cols[i + nx * j] = true;
                            let lo = [
                                bm.origin[0] + i as f64 * bm.size[0],
                                bm.origin[1] + j as f64 * bm.size[1],
                            ];
                            self.bins.cells_in(
                                [lo[0], lo[0] + bm.size[0]],
                                [lo[1], lo[1] + bm.size[1]],
                                1,
                                &mut cells,
                            );
                        }
                    }
                }
            }
            cells.push(self.bins.n_cells());
            cells.sort_unstable();
            cells.dedup();
            self.bins.rows_in(&cells, &mut self.rows);
        }
        self.all_moved = false;
        self.moved_cells.iter_mut().for_each(|m| *m = false);
        let block = |i: usize, j: usize, k: usize| {
            let b = bm.index[i + nx * (j + ny * k)];
            (b != crate::model::block_model::NO_BLOCK).then_some(b as usize)
        };
        let full = |b: usize| vol * bm.density[b] * (1.0 - bm.n0[b]);
        let mass = &mut self.block_mass;
        for j in 0..ny {
            for i in (0..nx).filter(|&i| cols[i + nx * j]) {
                for b in (0..nz).filter_map(|k| block(i, j, k)) {
                    mass[b] = self.lattice_mass[b] - self.engulfed_mass[b];
                }
            }
        }
        // Each row's block is found in parallel; the masses are then summed exactly, in
        // fixed point, so that the sums do not depend on the rows' order.
        let mk = &self.markers;
        let blocks: Vec<u32> = self
            .rows
            .par_iter()
            .map(|&k| {
                let k = k as usize;
                bm.cell([mk.x[k], mk.y[k], mk.z[k]])
                    .filter(|c| cols[c[0] + nx * c[1]])
                    .and_then(|c| block(c[0], c[1], c[2]))
                    .map_or(u32::MAX, |b| b as u32)
            })
            .collect();
        let mut fixed = vec![0i64; mass.len()];
        for (&k, &b) in self.rows.iter().zip(&blocks) {
            if b != u32::MAX {
                fixed[b as usize] += (mk.mass[k as usize] * FIXED).round() as i64;
            }
        }
        for (m, &f) in mass.iter_mut().zip(&fixed) {
            if f != 0 {
                *m += f as f64 / FIXED;
            }
        }
        let fill = self.scenario.rilling.air_fill;
        let t = &mut self.out.air_gap;
        for j in 0..ny {
            for i in 0..nx {
                if cols[i + nx * j] {
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
                        if open && mass[b] < fill * full(b) {
                            air += bm.size[2];
                        } else {
                            open = false;
                        }
                    }
                    self.air_col[i + nx * j] = air;
                }
                let air = self.air_col[i + nx * j];
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
