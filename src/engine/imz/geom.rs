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

/// A uniform 2-D grid over the footprint listing which IMZs may cover each cell.
#[derive(Debug, Clone, Default)]
pub struct ImzGrid {
    origin: [f64; 2],
    cell: f64,
    n: [usize; 2],
    start: Vec<u32>,
    ids: Vec<u32>,
}

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
        let n = [
            ((extent[0] / cell).ceil() as usize).max(1),
            ((extent[1] / cell).ceil() as usize).max(1),
        ];
        let mut counts = vec![0u32; n[0] * n[1] + 1];
        // Per IMZ, the cells its widest disk meets, row by row: (IMZ, row, first and last
        // column). A row's columns are those the circle's chord at the row's nearest edge
        // spans (a hair wider than R, so that a point `ImzGeom::disk_at` takes inside on
        // rounding is never in an unlisted cell).
        let index =
            |c: f64, o: f64, m: usize| (((c - o) / cell).floor().max(0.0) as usize).min(m - 1);
        let mut rows: Vec<(u32, usize, usize, usize)> = Vec::new();
        for &d in which {
            let g = &geoms[d];
            let r = g.max_radius() * (1.0 + 1e-9) + 1e-9 * cell;
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
                rows.push((d as u32, j, i0, i1));
                for i in i0..=i1 {
                    counts[i + n[0] * j + 1] += 1;
                }
            }
        }
        for k in 1..counts.len() {
            counts[k] += counts[k - 1];
        }
        let mut fill = counts.clone();
        let mut ids = vec![0u32; *counts.last().unwrap() as usize];
        for &(d, j, i0, i1) in &rows {
            for i in i0..=i1 {
                let c = i + n[0] * j;
                ids[fill[c] as usize] = d;
                fill[c] += 1;
            }
        }
        ImzGrid {
            origin,
            cell,
            n,
            start: counts,
            ids,
        }
    }

    /// IMZ ids whose footprint may cover (x, y).
    #[inline]
    pub fn at(&self, x: f64, y: f64) -> &[u32] {
        let i = (x - self.origin[0]) / self.cell;
        let j = (y - self.origin[1]) / self.cell;
        if !(i >= 0.0 && j >= 0.0) {
            return &[];
        }
        let (i, j) = (i as usize, j as usize);
        if i >= self.n[0] || j >= self.n[1] {
            return &[];
        }
        let c = i + self.n[0] * j;
        &self.ids[self.start[c] as usize..self.start[c + 1] as usize]
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
            }
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
