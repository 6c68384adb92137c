//! The markers binned by plan cell, so that a step lists only the rows the drawing IMZs can
//! reach.

use rayon::prelude::*;

use super::Markers;

/// Column and row ranges of grid cells, ((i0, i1), (j0, j1)), inclusive.
type SpanIj = ((usize, usize), (usize, usize));

/// The moving markers binned by plan cell, so a marker update visits only the markers a
/// drawing IMZ can reach and stagnant ones cost nothing (DESIGN §9).
///
/// The cells are those of the [`ImzGrid`](crate::engine::imz::ImzGrid) of the step (same origin, size and rounding, see
/// [`Bins::cell_of`]): a marker whose cell no drawing IMZ lists takes a zero step, so
/// stepping only the rows of the listed cells is exact. Rows outside the grid sit in one
/// extra list that no IMZ reaches. Each row knows its cell and its slot in that cell's list,
/// so binning, moving and removing a row are O(1). The bins mirror [`Markers`]' rows and
/// are derived state: [`Bins::sync`] rebuilds them from the markers (on resume).
#[derive(Debug, Clone, Default)]
pub struct Bins {
    origin: [f64; 2],
    cell: f64,
    n: [usize; 2],
    /// Rows per cell; the last list holds the rows outside the grid.
    lists: Vec<Vec<u32>>,
    /// Per row: its cell and its slot in that cell's list.
    at: Vec<(u32, u32)>,
    /// Scratch bit set over rows, to list rows in ascending order.
    bits: Vec<u64>,
}

impl Bins {
    /// Empty bins over the plan rectangle `origin + [0, extent]` in square cells of side
    /// `cell` (the arguments of [`ImzGrid::build`](crate::engine::imz::ImzGrid::build)).
    pub fn new(origin: [f64; 2], extent: [f64; 2], cell: f64) -> Bins {
        let n = [
            ((extent[0] / cell).ceil() as usize).max(1),
            ((extent[1] / cell).ceil() as usize).max(1),
        ];
        Bins {
            origin,
            cell,
            n,
            lists: vec![Vec::new(); n[0] * n[1] + 1],
            at: Vec::new(),
            bits: Vec::new(),
        }
    }

    /// Number of cells in the grid (the outside list is cell `n_cells()`).
    pub fn n_cells(&self) -> usize {
        self.n[0] * self.n[1]
    }

    /// Cell of a plan point, computed as [`ImzGrid::at`](crate::engine::imz::ImzGrid::at) does; `n_cells()` outside.
    #[inline]
    pub fn cell_of(&self, x: f64, y: f64) -> usize {
        let i = (x - self.origin[0]) / self.cell;
        let j = (y - self.origin[1]) / self.cell;
        if !(i >= 0.0 && j >= 0.0) {
            return self.n_cells();
        }
        let (i, j) = (i as usize, j as usize);
        if i >= self.n[0] || j >= self.n[1] {
            return self.n_cells();
        }
        i + self.n[0] * j
    }

    /// Plan rectangle ([x0, x1], [y0, y1]) of cell `c` (< `n_cells()`).
    pub fn cell_rect(&self, c: usize) -> [[f64; 2]; 2] {
        let (i, j) = ((c % self.n[0]) as f64, (c / self.n[0]) as f64);
        [
            [
                self.origin[0] + i * self.cell,
                self.origin[0] + (i + 1.0) * self.cell,
            ],
            [
                self.origin[1] + j * self.cell,
                self.origin[1] + (j + 1.0) * self.cell,
            ],
        ]
    }

    /// Cells within `margin` cells of the plan rectangle [x0, x1] × [y0, y1], pushed to `out`.
    pub fn cells_in(&self, x: [f64; 2], y: [f64; 2], margin: usize, out: &mut Vec<usize>) {
        if let Some(((i0, i1), (j0, j1))) = self.span(x, y, margin) {
            for j in j0..=j1 {
                out.extend((i0..=i1).map(|i| i + self.n[0] * j));
            }
        }
    }

    /// The cells within `margin` cells of any of the plan rectangles `rects`, and the
    /// cells `also` (which may hold the outside list's), ascending and each once.
    pub fn cells_of(
        &self,
        rects: impl Iterator<Item = ([f64; 2], [f64; 2])>,
        margin: usize,
        also: &[usize],
    ) -> Vec<usize> {
        let mut mark = vec![false; self.n_cells() + 1];
        for (x, y) in rects {
            if let Some(((i0, i1), (j0, j1))) = self.span(x, y, margin) {
                for j in j0..=j1 {
                    mark[i0 + self.n[0] * j..=i1 + self.n[0] * j].fill(true);
                }
            }
        }
        also.iter().for_each(|&c| mark[c] = true);
        (0..mark.len()).filter(|&c| mark[c]).collect()
    }

    /// The column and row ranges ((i0, i1), (j0, j1)) of the cells within `margin` cells of
    /// the plan rectangle [x0, x1] × [y0, y1] (None where it misses the grid).
    fn span(&self, x: [f64; 2], y: [f64; 2], margin: usize) -> Option<SpanIj> {
        let span = |lo: f64, hi: f64, o: f64, n: usize| {
            let a = ((lo - o) / self.cell).floor();
            let b = ((hi - o) / self.cell).floor();
            if !(b >= 0.0) || !(a < n as f64) {
                return None;
            }
            let a = (a.max(0.0) as usize).saturating_sub(margin);
            let b = (b.min(n as f64 - 1.0) as usize + margin).min(n - 1);
            Some((a, b))
        };
        Some((
            span(x[0], x[1], self.origin[0], self.n[0])?,
            span(y[0], y[1], self.origin[1], self.n[1])?,
        ))
    }

    fn put(&mut self, row: usize, c: usize) {
        let list = &mut self.lists[c];
        self.at[row] = (c as u32, list.len() as u32);
        list.push(row as u32);
    }

    fn unlink(&mut self, row: usize) {
        let (c, s) = self.at[row];
        let list = &mut self.lists[c as usize];
        list.swap_remove(s as usize);
        if let Some(&moved) = list.get(s as usize) {
            self.at[moved as usize].1 = s;
        }
    }

    /// Bins the rows appended to `mk` since the last call; returns their cells.
    pub fn add_new(&mut self, mk: &Markers, cells: &mut Vec<usize>) {
        for row in self.at.len()..mk.len() {
            self.at.push((0, 0));
            let c = self.cell_of(mk.x[row], mk.y[row]);
            self.put(row, c);
            cells.push(c);
        }
    }

    /// Re-bins `rows` after they moved; pushes the new cells of those that changed cell.
    pub fn update(&mut self, mk: &Markers, rows: &[u32], cells: &mut Vec<usize>) {
        let moved: Vec<(u32, usize)> = rows
            .par_iter()
            .filter_map(|&r| {
                let c = self.cell_of(mk.x[r as usize], mk.y[r as usize]);
                (c != self.at[r as usize].0 as usize).then_some((r, c))
            })
            .collect();
        for (r, c) in moved {
            self.unlink(r as usize);
            self.put(r as usize, c);
            cells.push(c);
        }
    }

    /// Brings the bins in line with `mk` after any change to it (new rows binned, moved
    /// rows re-binned); rows may only have been appended or moved, not removed.
    pub fn sync(&mut self, mk: &Markers) {
        let mut cells = Vec::new();
        let old = self.at.len().min(mk.len()) as u32;
        self.add_new(mk, &mut cells);
        let all: Vec<u32> = (0..old).collect();
        self.update(mk, &all, &mut cells);
    }

    /// Mirrors [`Markers::take_into`]: row `k` leaves and the last row takes its place.
    pub fn swap_remove(&mut self, k: usize) {
        self.unlink(k);
        let last = self.at.len() - 1;
        if k != last {
            let (c, s) = self.at[last];
            self.lists[c as usize][s as usize] = k as u32;
            self.at[k] = (c, s);
        }
        self.at.pop();
    }

    /// Rows binned in cell `c`, in no order.
    pub fn list(&self, c: usize) -> &[u32] {
        &self.lists[c]
    }

    /// Rows binned in `cells` (which may repeat), in ascending order, into `out`.
    pub fn rows_in(&mut self, cells: &[usize], out: &mut Vec<u32>) {
        out.clear();
        self.bits.resize(self.at.len().div_ceil(64), 0);
        let (mut lo, mut hi) = (usize::MAX, 0usize);
        for &c in cells {
            for &r in &self.lists[c] {
                let w = r as usize / 64;
                self.bits[w] |= 1u64 << (r % 64);
                lo = lo.min(w);
                hi = hi.max(w);
            }
        }
        if lo > hi {
            return;
        }
        for w in lo..=hi {
            let mut b = std::mem::take(&mut self.bits[w]);
            while b != 0 {
                out.push((w * 64) as u32 + b.trailing_zeros());
                b &= b - 1;
            }
        }
    }
}
