//! An IMZ's geometry as the other IMZs and the marker pass see it, and the plan grid that
//! lists the IMZs that may cover a point.

/// Geometry of one IMZ as seen by other IMZs and the marker pass.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct ImzGeom {
    /// Axis Easting, m.
    pub x: f64,
    /// Axis Northing, m.
    pub y: f64,
    /// Base elevation (drawpoint), m.
    pub z0: f64,
    /// Disk thickness h, m.
    pub h: f64,
    /// Disk radii R_i, m.
    pub radius: Vec<f64>,
}

impl ImzGeom {
    /// Largest disk radius.
    pub fn max_radius(&self) -> f64 {
        self.radius.iter().cloned().fold(0.0, f64::max)
    }
    /// Height `z` in disk units above the IMZ's base, (z − z0) / h: disk i holds
    /// i ≤ t < i + 1. Every test of which disk a point or a lattice site lies in reads
    /// this, so that one on a disk boundary lies in exactly one disk.
    #[inline]
    pub fn height(&self, z: f64) -> f64 {
        (z - self.z0) / self.h
    }

    /// The disk level that holds height `z` (whatever its radius), if z is not below the
    /// base: ⌊[`height`](Self::height)⌋.
    #[inline]
    pub fn level(&self, z: f64) -> Option<usize> {
        let t = self.height(z);
        (t >= 0.0).then_some(t as usize)
    }

    /// Whether a point lies inside this IMZ.
    #[inline]
    pub fn contains(&self, p: [f64; 3]) -> bool {
        self.disk_at(p).is_some()
    }

    /// The disk that holds a point, if one does: its index i, the point's height in disk
    /// units above the IMZ's base (i ≤ t < i + 1), and its plan offset (dx, dy) from the
    /// axis with the squared distance dx² + dy².
    #[inline]
    pub fn disk_at(&self, p: [f64; 3]) -> Option<(usize, f64, [f64; 2], f64)> {
        let t = self.height(p[2]);
        if !(t >= 0.0) {
            return None;
        }
        let i = t as usize;
        let (dx, dy) = (p[0] - self.x, p[1] - self.y);
        let a2 = dx * dx + dy * dy;
        self.radius
            .get(i)
            .is_some_and(|&r| a2 <= r * r)
            .then_some((i, t, [dx, dy], a2))
    }
}

/// A uniform 2-D grid over the footprint listing which IMZs may cover each cell, each with
/// the span of heights in which its disks can reach the cell.
#[derive(Debug, Clone, Default)]
pub struct ImzGrid {
    origin: [f64; 2],
    cell: f64,
    n: [usize; 2],
    start: Vec<u32>,
    ids: Vec<u32>,
    /// Per listed IMZ, [z_lo, z_hi): below z_lo every disk of the IMZ is narrower than the
    /// distance from its axis to the cell, and above z_hi it has no disk, so no point of
    /// the cell outside that span lies in it ([`ImzGrid::holding`]).
    span: Vec<[f64; 2]>,
}

/// The cells of a plan grid one IMZ is listed in, each with the span of heights
/// [z_lo, z_hi) in which its disks can reach the cell ([`ImzGrid::listing`]).
pub type Listing = Vec<(u32, [f64; 2])>;

impl ImzGrid {
    /// Builds the grid for the IMZs `which` (indices into `geoms`): each is listed, in the
    /// order of `which`, in the cells its widest disk meets, not in every cell of its
    /// bounding square (at mine scale a marker's cell then lists 16.6 IMZs instead of 19,
    /// fewer for the marker pass and the perimeter sampling to reject).
    pub fn build(
        geoms: &[ImzGeom],
        which: &[usize],
        origin: [f64; 2],
        extent: [f64; 2],
        cell: f64,
    ) -> ImzGrid {
        let mut listings = vec![Listing::new(); geoms.len()];
        for &d in which {
            listings[d] = ImzGrid::listing(&geoms[d], origin, extent, cell);
        }
        ImzGrid::assemble(&listings, which, origin, extent, cell)
    }

    /// Cells per axis of a grid over `extent` in cells of side `cell`.
    fn cells(extent: [f64; 2], cell: f64) -> [usize; 2] {
        [
            ((extent[0] / cell).ceil() as usize).max(1),
            ((extent[1] / cell).ceil() as usize).max(1),
        ]
    }

    /// The cells of the grid (origin, extent, cell) that IMZ `g`'s widest disk meets, row
    /// by row, with the span of heights in which its disks reach each. A row's cells are
    /// those the circle's chord at the row's nearest edge spans, and a cell's span starts
    /// at the lowest disk at or below which some disk is as wide as the cell is far from
    /// the axis (radii a hair wider than R, so that a point `ImzGeom::disk_at` takes inside
    /// on rounding is never in an unlisted cell or outside its span). An IMZ's listing
    /// changes only when its disks do, so a run keeps it between updates and lists again
    /// only the IMZs that drew.
    pub fn listing(g: &ImzGeom, origin: [f64; 2], extent: [f64; 2], cell: f64) -> Listing {
        let n = ImzGrid::cells(extent, cell);
        let index =
            |c: f64, o: f64, m: usize| (((c - o) / cell).floor().max(0.0) as usize).min(m - 1);
        let inflate = |r: f64| r * (1.0 + 1e-9) + 1e-9 * cell;
        // The widest disk at or below each level.
        let mut m = 0.0f64;
        let widest: Vec<f64> = g
            .radius
            .iter()
            .map(|&r| {
                m = m.max(r);
                inflate(m)
            })
            .collect();
        let r = inflate(g.max_radius());
        // Heights a hair outside the disks' own (ImzGeom::height rounds).
        let z_hi = g.z0 + (g.radius.len() as f64 + 1e-6) * g.h;
        let mut out = Listing::new();
        for j in index(g.y - r, origin[1], n[1])..=index(g.y + r, origin[1], n[1]) {
            let (y0, y1) = (
                origin[1] + j as f64 * cell,
                origin[1] + (j + 1) as f64 * cell,
            );
            let dy = (y0 - g.y).max(g.y - y1).max(0.0);
            let half = (r * r - dy * dy).max(0.0).sqrt();
            let (i0, i1) = (
                index(g.x - half, origin[0], n[0]),
                index(g.x + half, origin[0], n[0]),
            );
            for i in i0..=i1 {
                let (x0, x1) = (
                    origin[0] + i as f64 * cell,
                    origin[0] + (i + 1) as f64 * cell,
                );
                let dx = (x0 - g.x).max(g.x - x1).max(0.0);
                // Squared distances: rounding may only list a disk lower, never higher.
                let near2 = dx * dx + dy * dy;
                let first = widest.partition_point(|&w| w * w < near2);
                let z_lo = g.z0 + (first as f64 - 1e-6) * g.h;
                out.push(((i + n[0] * j) as u32, [z_lo, z_hi]));
            }
        }
        out
    }

    /// The grid of the IMZs `which`, in that order in every cell, from their listings
    /// ([`ImzGrid::listing`] on the same grid; `listings` indexed by IMZ).
    pub fn assemble(
        listings: &[Listing],
        which: &[usize],
        origin: [f64; 2],
        extent: [f64; 2],
        cell: f64,
    ) -> ImzGrid {
        let n = ImzGrid::cells(extent, cell);
        let mut counts = vec![0u32; n[0] * n[1] + 1];
        for &d in which {
            for &(c, _) in &listings[d] {
                counts[c as usize + 1] += 1;
            }
        }
        for k in 1..counts.len() {
            counts[k] += counts[k - 1];
        }
        let mut fill = counts.clone();
        let total = *counts.last().unwrap() as usize;
        let (mut ids, mut span) = (vec![0u32; total], vec![[0.0; 2]; total]);
        for &d in which {
            for &(c, s) in &listings[d] {
                let at = &mut fill[c as usize];
                ids[*at as usize] = d as u32;
                span[*at as usize] = s;
                *at += 1;
            }
        }
        ImzGrid {
            origin,
            cell,
            n,
            start: counts,
            ids,
            span,
        }
    }

    /// The IMZs listed at (x, y) whose disks can reach height z there, in the order of
    /// [`ImzGrid::at`]: the others cannot hold a point (x, y, z), nor its mirror across a
    /// wall when (x, y) is the point just inside the wall (the mirror lies farther from
    /// every axis inside).
    #[inline]
    pub fn holding(&self, x: f64, y: f64, z: f64) -> impl Iterator<Item = u32> + '_ {
        let c = self.cell_at(x, y);
        let (a, b) = c.map_or((0, 0), |c| {
            (self.start[c] as usize, self.start[c + 1] as usize)
        });
        self.ids[a..b]
            .iter()
            .zip(&self.span[a..b])
            .filter(move |(_, s)| z >= s[0] && z < s[1])
            .map(|(&d, _)| d)
    }

    /// IMZ ids whose footprint may cover (x, y).
    #[inline]
    pub fn at(&self, x: f64, y: f64) -> &[u32] {
        match self.cell_at(x, y) {
            Some(c) => &self.ids[self.start[c] as usize..self.start[c + 1] as usize],
            None => &[],
        }
    }

    /// The cell that holds (x, y), if the grid covers it.
    #[inline]
    fn cell_at(&self, x: f64, y: f64) -> Option<usize> {
        let i = (x - self.origin[0]) / self.cell;
        let j = (y - self.origin[1]) / self.cell;
        if !(i >= 0.0 && j >= 0.0) {
            return None;
        }
        let (i, j) = (i as usize, j as usize);
        (i < self.n[0] && j < self.n[1]).then_some(i + self.n[0] * j)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Every IMZ whose disk holds a point is listed at the point's cell, in the order of
    /// `which` (the marker pass sums the IMZs' moves in that order), and the listing by the
    /// widest disk's circle skips cells that its bounding square would list: 60 random IMZs
    /// (radii up to 30 m, some leaving the grid) over a 200 m square in 5 m and 15 m cells,
    /// 40 000 random points, several right on a disk's rim.
    #[test]
    fn the_grid_lists_every_imz_that_holds_a_point_and_only_near_ones() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let geoms: Vec<ImzGeom> = (0..60)
            .map(|_| ImzGeom {
                x: rng.random_range(-10.0..210.0),
                y: rng.random_range(-10.0..210.0),
                z0: rng.random_range(0.0..8.0),
                h: 4.0,
                radius: (0..12)
                    .map(|i| rng.random_range(0.0..2.5) * (1 + i) as f64)
                    .collect(),
            })
            .collect();
        let which: Vec<usize> = (0..geoms.len()).rev().step_by(2).collect();
        // The circle's share of its square tends to π/4 as the cells shrink: here 0.84 of the
        // square's cells are listed at 5 m and 0.90 at 15 m.
        for (cell, share) in [(5.0, 0.86), (15.0, 0.92)] {
            let grid = ImzGrid::build(&geoms, &which, [0.0, 0.0], [200.0, 200.0], cell);
            let (mut tested, mut all) = (0, 0);
            for k in 0..40_000 {
                let p = if k % 4 == 0 {
                    // On the rim of a disk (to rounding).
                    let g = &geoms[which[k % which.len()]];
                    let i = k % g.radius.len();
                    let t: f64 = rng.random_range(0.0..std::f64::consts::TAU);
                    let r = g.radius[i];
                    [
                        g.x + r * t.cos(),
                        g.y + r * t.sin(),
                        g.z0 + (i as f64 + 0.5) * g.h,
                    ]
                } else {
                    [
                        rng.random_range(0.0..200.0),
                        rng.random_range(0.0..200.0),
                        rng.random_range(0.0..56.0),
                    ]
                };
                if !(0.0..200.0).contains(&p[0]) || !(0.0..200.0).contains(&p[1]) {
                    continue;
                }
                let listed = grid.at(p[0], p[1]);
                let pos = |d: usize| listed.iter().position(|&e| e as usize == d);
                let holding: Vec<usize> = which
                    .iter()
                    .copied()
                    .filter(|&d| geoms[d].disk_at(p).is_some())
                    .collect();
                for &d in &holding {
                    assert!(
                        pos(d).is_some(),
                        "cell {cell}: IMZ {d} holds {p:?}, not listed"
                    );
                }
                for w in holding.windows(2) {
                    assert!(pos(w[0]) < pos(w[1]), "cell {cell}: order at {p:?}");
                }
                // The listing by height keeps every IMZ that holds the point, in order.
                let by_height: Vec<usize> =
                    grid.holding(p[0], p[1], p[2]).map(|d| d as usize).collect();
                let kept: Vec<usize> = by_height
                    .iter()
                    .copied()
                    .filter(|d| holding.contains(d))
                    .collect();
                assert_eq!(kept, holding, "cell {cell}: by height at {p:?}");
                tested += by_height.len();
                all += listed.len();
            }
            eprintln!("cell {cell}: {tested} of {all} listed IMZs reach the points' heights");
            assert!(tested < all);
            // The listing against the bounding squares'.
            let listed: usize = which
                .iter()
                .map(|&d| {
                    let g = &geoms[d];
                    let r = g.max_radius();
                    let last = (200.0 / cell).ceil() - 1.0;
                    let span = |c: f64| {
                        let lo = ((c - r) / cell).floor().clamp(0.0, last);
                        let hi = ((c + r) / cell).floor().clamp(0.0, last);
                        (hi - lo + 1.0) as usize
                    };
                    span(g.x) * span(g.y)
                })
                .sum();
            assert!(
                (grid.ids.len() as f64) < share * listed as f64,
                "cell {cell}: {} of {listed}",
                grid.ids.len()
            );
        }
    }
}
