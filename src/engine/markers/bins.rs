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
    /// Rows binned or drawn since the last [`Bins::sort`] (new, moved to another cell, or
    /// filled by the last row): how far the rows have left the sorted order.
    unsorted: usize,
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
            unsorted: 0,
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
        self.unsorted += 1;
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

    /// Bins the rows appended to `mk` since the last call.
    pub fn add_new(&mut self, mk: &Markers) {
        for row in self.at.len()..mk.len() {
            self.at.push((0, 0));
            let c = self.cell_of(mk.x[row], mk.y[row]);
            self.put(row, c);
        }
    }

    /// Re-bins `rows` after they moved.
    pub fn update(&mut self, mk: &Markers, rows: &[u32]) {
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
        }
    }

    /// Brings the bins in line with `mk` after any change to it (new rows binned, moved
    /// rows re-binned); rows may only have been appended or moved, not removed.
    pub fn sync(&mut self, mk: &Markers) {
        let old = self.at.len().min(mk.len()) as u32;
        self.add_new(mk);
        let all: Vec<u32> = (0..old).collect();
        self.update(mk, &all);
    }

    /// Sorts the rows (by cell and height, `Bins::sort`) once a tenth of them have left
    /// that order.
    pub fn tidy(&mut self, mk: &mut Markers) {
        if self.unsorted > mk.len() / 10 {
            self.sort(mk);
        }
    }

    /// Reorders the rows of `mk` cell by cell, and by height in bands of 1/16 m within a
    /// cell ([`Markers::permute`]), and bins them again.
    ///
    /// A marker update visits the rows in ascending order, and each visit reads the IMZs
    /// its cell lists and their disks at its height. Rows drawn (the last row takes their
    /// place) and rows engulfed (appended) leave the rows in no spatial order within a few
    /// hundred periods, and every visit then fetches its IMZs' geometry and motion anew;
    /// sorted, consecutive rows share them, and they stay in cache. Row order changes no
    /// result: every sum over markers is taken in the order of their ids or exactly
    /// (`tests::the_rows_order_changes_no_result` in `engine`).
    fn sort(&mut self, mk: &mut Markers) {
        let mut key: Vec<((usize, i64), u32)> = (0..mk.len())
            .into_par_iter()
            .map(|k| (self.sort_key(mk, k), k as u32))
            .collect();
        key.par_sort_unstable();
        let perm: Vec<u32> = key.iter().map(|t| t.1).collect();
        mk.permute(&perm);
        self.lists.iter_mut().for_each(Vec::clear);
        self.at.clear();
        for (row, &((c, _), _)) in key.iter().enumerate() {
            self.at.push((0, 0));
            self.put(row, c);
        }
        self.unsorted = 0;
    }

    /// Where row `k` of `mk` goes in [`Bins::sort`]'s order: its cell, then its height in
    /// bands of 1/16 m.
    fn sort_key(&self, mk: &Markers, k: usize) -> (usize, i64) {
        (
            self.cell_of(mk.x[k], mk.y[k]),
            (mk.z[k] * 16.0).floor() as i64,
        )
    }

    /// Mirrors [`Markers::take_into`]: row `k` leaves and the last row takes its place.
    pub fn swap_remove(&mut self, k: usize) {
        self.unsorted += 1;
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Whether the rows are in the order of their cells and heights.
    fn sorted(bins: &Bins, mk: &Markers) -> bool {
        (1..mk.len()).all(|k| bins.sort_key(mk, k - 1) <= bins.sort_key(mk, k))
    }

    /// Sorting lists each cell's rows as one run of rows, by height within it, keeps every
    /// marker (the same ids at the same positions) and leaves the bins consistent with the
    /// rows; `tidy` sorts only once a tenth of the rows have left the order.
    #[test]
    fn sorting_groups_the_rows_by_cell_and_height() {
        let mut mk = Markers::default();
        // 400 markers scattered over 4 × 4 cells of 10 m, ids in no spatial order.
        for k in 0..400u64 {
            let h = k.wrapping_mul(2654435761) % 1000;
            let p = [(h % 40) as f64 + 0.5, (h / 25) as f64, (k % 7) as f64];
            mk.push(k, p, 1.0, 0, 0.1);
        }
        let before: Vec<(u64, [u64; 3])> = (0..mk.len())
            .map(|k| (mk.id[k], [mk.x[k], mk.y[k], mk.z[k]].map(f64::to_bits)))
            .collect();
        let mut bins = Bins::new([0.0, 0.0], [40.0, 40.0], 10.0);
        bins.sync(&mk);
        bins.tidy(&mut mk);
        assert_eq!(bins.unsorted, 0);
        let mut after: Vec<(u64, [u64; 3])> = (0..mk.len())
            .map(|k| (mk.id[k], [mk.x[k], mk.y[k], mk.z[k]].map(f64::to_bits)))
            .collect();
        after.sort_unstable();
        assert_eq!(after, before);
        assert!(sorted(&bins, &mk));
        let mut seen = 0;
        for c in 0..=bins.n_cells() {
            let mut rows = Vec::new();
            bins.rows_in(&[c], &mut rows);
            assert!(
                rows.windows(2).all(|w| w[1] == w[0] + 1),
                "cell {c}: {rows:?}"
            );
            assert!(rows
                .iter()
                .all(|&k| bins.cell_of(mk.x[k as usize], mk.y[k as usize]) == c));
            seen += rows.len();
        }
        assert_eq!(seen, mk.len());
        // Thirty rows drawn: fewer than a tenth, so no sort; then twenty more.
        let mut drawn = Markers::default();
        for k in (0..30).rev() {
            mk.take_into(k * 13, &mut drawn);
            bins.swap_remove(k * 13);
        }
        let order = mk.id.clone();
        bins.tidy(&mut mk);
        assert_eq!(mk.id, order);
        for k in (0..20).rev() {
            mk.take_into(k * 17, &mut drawn);
            bins.swap_remove(k * 17);
        }
        assert!(!sorted(&bins, &mk));
        bins.tidy(&mut mk);
        assert!(sorted(&bins, &mk));
    }
}
