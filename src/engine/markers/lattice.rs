//! The marker lattice: sites of spacing s over the block grid, each standing for the cube of
//! side s around it at its block's in-situ density (see the module above).

use crate::model::BlockModel;

/// The marker lattice over the block grid.
#[derive(Debug, Clone, Copy)]
pub struct Lattice {
    /// Lattice origin, m: the grid's minimum corner, moved in plan by the offset
    /// ([`with_offset`](Self::with_offset)). Site (i, j, k) lies at origin + (i, j, k, + ½) s,
    /// but for the first and last sites in plan of cells longer or shorter than s
    /// ([`centre`](Self::centre)).
    pub origin: [f64; 3],
    /// The block grid's minimum corner, m (where the first cells start).
    grid_min: [f64; 3],
    /// The block grid's maximum corner, m (where the last cells end).
    grid_max: [f64; 3],
    /// Spacing s, m.
    pub s: f64,
    /// Sites per axis.
    pub n: [usize; 3],
}

impl Lattice {
    /// A lattice of spacing `s` covering the block grid.
    pub fn new(bm: &BlockModel, s: f64) -> Lattice {
        let max = bm.max_corner();
        Lattice {
            origin: bm.origin,
            grid_min: bm.origin,
            grid_max: max,
            s,
            n: [0, 1, 2].map(|a| sites_before(bm.origin[a], max[a], s)),
        }
    }

    /// The same lattice moved in plan by `offset` (x, y) times the spacing, each in
    /// [−½, ½) (`resolution.lattice_offset`), holding the sites whose centres lie on the
    /// grid. The first and last cells along x and y stretch or shrink (to between s/2 and
    /// 3s/2) so that the cells still tile the grid. Another offset samples the same ground
    /// with other sites: the spread of the results between offsets is the markers'
    /// sampling noise (`docs::resolution`, "Sampling noise"). The first and last sites
    /// sit at their cells' middles ([`centre`](Self::centre)).
    pub fn with_offset(mut self, bm: &BlockModel, offset: [f64; 2]) -> Lattice {
        let max = bm.max_corner();
        for a in 0..2 {
            self.origin[a] = self.grid_min[a] + offset[a] * self.s;
            self.n[a] = sites_before(self.origin[a], max[a], self.s);
        }
        self
    }

    /// Total number of sites.
    pub fn len(&self) -> usize {
        self.n[0] * self.n[1] * self.n[2]
    }

    /// Whether the lattice has no sites.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Coordinate along axis `a` of the sites with index `i` on that axis: origin + (i + ½)
    /// s, except that in plan the first or last site of a cell longer or shorter than s
    /// (an offset lattice's, or where s does not divide the grid) sits at its cell's middle.
    /// On the regular lattice such a site lay off it, by up to half its cell: at offset −½
    /// on the grid's low face, a wall, where the walls' images let the flow carry it along
    /// the wall but never off it, so the half cell it stands for was never drawn (D01-01 of
    /// the demo drawing alone: 0.923 of its schedule in markers at offset (−½, 0), 0.990 at
    /// (0, 0)). In z the sites stay on the regular lattice.
    #[inline]
    pub fn centre(&self, a: usize, i: usize) -> f64 {
        match self.moved_len(a, i) {
            Some(len) => {
                let start = if i == 0 {
                    self.grid_min[a]
                } else {
                    self.origin[a] + i as f64 * self.s
                };
                start + 0.5 * len
            }
            None => self.origin[a] + (i as f64 + 0.5) * self.s,
        }
    }

    /// The length of the cell of site `i` along axis `a` if that site sits off the regular
    /// lattice ([`centre`](Self::centre)): a first or last site in plan whose cell is not s.
    #[inline]
    fn moved_len(&self, a: usize, i: usize) -> Option<f64> {
        if a == 2 || (i != 0 && i + 1 != self.n[a]) {
            return None;
        }
        let len = self.cell_len(a, i, self.grid_max[a]);
        (len != self.s).then_some(len)
    }

    /// Position of site `id`.
    #[inline]
    pub fn pos(&self, id: usize) -> [f64; 3] {
        let i = id % self.n[0];
        let j = (id / self.n[0]) % self.n[1];
        let k = id / (self.n[0] * self.n[1]);
        [self.centre(0, i), self.centre(1, j), self.centre(2, k)]
    }

    /// Site index range (inclusive) along axis `a` whose centres lie in [lo, hi).
    #[inline]
    pub fn range(&self, a: usize, lo: f64, hi: f64) -> Option<(usize, usize)> {
        let mut t0 = ((lo - self.origin[a]) / self.s - 0.5).ceil().max(0.0);
        let t1 = ((hi - self.origin[a]) / self.s - 0.5).ceil() - 1.0;
        let last = self.n[a] - 1;
        let mut t1 = t1.min(last as f64);
        // A first or last site off the regular lattice (by at most s/4) is tested where it
        // sits; its neighbours are regular.
        let holds = |i: usize| (lo..hi).contains(&self.centre(a, i));
        if self.moved_len(a, 0).is_some() {
            if holds(0) {
                (t0, t1) = (0.0, t1.max(0.0));
            } else if t0 == 0.0 {
                t0 = 1.0;
            }
        }
        if self.moved_len(a, last).is_some() {
            if holds(last) {
                (t0, t1) = (t0.min(last as f64), last as f64);
            } else if t1 == last as f64 {
                t1 = last as f64 - 1.0;
            }
        }
        (t1 >= t0).then_some((t0 as usize, t1 as usize))
    }

    /// Height of the centres of layer `k`, m (as [`pos`](Self::pos) places them).
    #[inline]
    pub fn layer_z(&self, k: usize) -> f64 {
        self.centre(2, k)
    }

    /// The layers (inclusive index range) whose centres `level` places at level `i`, for a
    /// level that spans heights [lo, hi). The range is found on [lo − s, hi + s) and
    /// trimmed by `level` itself: [`range`](Self::range) on [lo, hi) works out the
    /// boundary by other floating-point operations than the test that puts a marker in a
    /// disk, and a layer exactly on a disk boundary (a disk thickness that is a multiple
    /// of half the spacing, on a drawpoint level with the lattice) then fell in neither
    /// disk: its sites were never engulfed, and the flow ran through ground with no
    /// markers in it (an isolated drawpoint at h = s/2 delivered 0.59 of its schedule in
    /// markers, at h = 1.5 s 0.93).
    pub fn layers_at_level(
        &self,
        lo: f64,
        hi: f64,
        level: impl Fn(f64) -> Option<usize>,
        i: usize,
    ) -> Option<(usize, usize)> {
        let (mut k0, mut k1) = self.range(2, lo - self.s, hi + self.s)?;
        while level(self.layer_z(k0)) != Some(i) {
            if k0 == k1 {
                return None;
            }
            k0 += 1;
        }
        while level(self.layer_z(k1)) != Some(i) {
            k1 -= 1;
        }
        Some((k0, k1))
    }

    /// Calls `f(a², id)` for every site of the layers `kr` (inclusive) whose squared plan
    /// distance a² from the axis (x, y) lies in (r_in², r_out²] ([0, r_out²] when r_in < 0).
    /// Rows are walked over the annulus only; the chords are widened by a nudge so that the
    /// test on a², the one that decides, sees every site near either circle.
    pub fn annulus(
        &self,
        (x, y): (f64, f64),
        kr: (usize, usize),
        (r_in, r_out): (f64, f64),
        mut f: impl FnMut(f64, usize),
    ) {
        let Some(jr) = self.range(1, y - r_out, y + r_out) else {
            return;
        };
        let in2 = if r_in < 0.0 { -1.0 } else { r_in * r_in };
        let (out2, nudge) = (r_out * r_out, 1e-9 * self.s);
        for k in kr.0..=kr.1 {
            for j in jr.0..=jr.1 {
                let dy = self.centre(1, j) - y;
                let outer = (out2 - dy * dy).max(0.0).sqrt() + nudge;
                let inner = (in2 - dy * dy).max(0.0).sqrt() - nudge;
                let spans = if inner > 0.0 {
                    [(x - outer, x - inner), (x + inner, x + outer)]
                } else {
                    [(x - outer, x + outer), (0.0, 0.0)]
                };
                for (lo, hi) in spans {
                    let Some(ir) = self.range(0, lo, hi) else {
                        continue;
                    };
                    for i in ir.0..=ir.1 {
                        let id = self.id(i, j, k);
                        let p = self.pos(id);
                        let a2 = (p[0] - x).powi(2) + (p[1] - y).powi(2);
                        if a2 <= out2 && a2 > in2 {
                            f(a2, id);
                        }
                    }
                }
            }
        }
    }

    /// Site index from per-axis indices.
    #[inline]
    pub fn id(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.n[0] * (j + self.n[1] * k)
    }

    /// In-situ solids per marker of each block at an interior site, ρ (1 − n0) s³: each site
    /// stands for the cube of side s around it, whatever block boundaries cross it. Were a
    /// block's mass shared among the sites inside it instead, then where s does not divide the
    /// block a block with fewer sites would carry heavier markers at the same spacing: the
    /// mine scene's 3.4 m markers on 15.2 m blocks give blocks of 4³ to 5³ sites, markers
    /// 1.95× apart in mass and ground 0.71–1.40× as dense as it is wherever a drawpoint draws
    /// within one block column.
    pub fn unit_masses(&self, bm: &BlockModel) -> Vec<f64> {
        let s3 = self.s.powi(3);
        (0..bm.len())
            .map(|b| s3 * bm.density[b] * (1.0 - bm.n0[b]))
            .collect()
    }

    /// Length along axis `a` of the cell of site `i`: s, except that the first cell starts
    /// at the grid's near face (it is longer or shorter than s by the offset) and the last
    /// runs to the grid's far face (the lattice holds a whole number of sites, so its far
    /// face is within s/2 of the grid's), so that the cells tile the grid.
    #[inline]
    fn cell_len(&self, a: usize, i: usize, max: f64) -> f64 {
        let n = self.n[a];
        // From the site's nominal cell start [origin + i s] to its end (the far face for
        // the last), plus the stretch from the near face to the origin for the first.
        let to_end = if i + 1 == n {
            max - self.origin[a] - (n - 1) as f64 * self.s
        } else {
            self.s
        };
        let from_face = if i == 0 {
            self.origin[a] - self.grid_min[a]
        } else {
            0.0
        };
        let len = to_end + from_face;
        // Where the cell is s, s itself, not s up to rounding.
        if (len - self.s).abs() > 1e-9 * self.s {
            len
        } else {
            self.s
        }
    }

    /// The blocks that the cell of site `id` overlaps, each with the overlap's volume, m³,
    /// into `out` (cleared first; missing blocks left out). The cells tile the grid, so
    /// these volumes add up to the cell's. An overlap thinner than 10⁻⁹ s along an axis
    /// counts as none: a cell whose face lies on a block face is in one block, even where
    /// rounding puts the two faces a hair apart.
    pub fn cell_blocks(&self, bm: &BlockModel, id: usize, out: &mut Vec<(usize, f64)>) {
        out.clear();
        let idx = [
            id % self.n[0],
            (id / self.n[0]) % self.n[1],
            id / (self.n[0] * self.n[1]),
        ];
        // Per axis, the grid cells the site's cell overlaps and the overlaps' lengths.
        let spans: [Vec<(usize, f64)>; 3] = [0, 1, 2].map(|a| {
            let i = idx[a];
            let lo = if i == 0 {
                self.grid_min[a]
            } else {
                self.origin[a] + i as f64 * self.s
            };
            let hi = lo + self.cell_len(a, i, self.grid_max[a]);
            let first = ((lo - bm.origin[a]) / bm.size[a]).floor().max(0.0) as usize;
            (first..bm.dims[a])
                .map(|c| (c, bm.origin[a] + c as f64 * bm.size[a]))
                .take_while(|&(_, c_lo)| c_lo < hi)
                .map(|(c, c_lo)| (c, hi.min(c_lo + bm.size[a]) - lo.max(c_lo)))
                .filter(|&(_, len)| len > 1e-9 * self.s)
                .collect()
        });
        for &(k, lz) in &spans[2] {
            for &(j, ly) in &spans[1] {
                for &(i, lx) in &spans[0] {
                    if let Some(b) = bm.at_cell([i, j, k]) {
                        out.push((b, lx * ly * lz));
                    }
                }
            }
        }
    }

    /// Mass of the marker at site `id` of a block whose interior-site mass is `unit`
    /// (`unit_masses`): `unit` times its cell's volume over s³.
    pub fn site_mass(&self, bm: &BlockModel, id: usize, unit: f64) -> f64 {
        let max = bm.max_corner();
        let idx = [
            id % self.n[0],
            (id / self.n[0]) % self.n[1],
            id / (self.n[0] * self.n[1]),
        ];
        (0..3)
            .map(|a| self.cell_len(a, idx[a], max[a]) / self.s)
            .product::<f64>()
            * unit
    }

    /// In-situ solids the lattice gives each block: the masses of the sites whose centres
    /// lie in it, as `BlockModel::locate` places them (a site exactly on a block face, as
    /// an offset lattice can put it, counts in one block). This is the block's own mass
    /// when s divides the block, and 0.71–1.40× it on the mine scene's 15.2 m blocks at
    /// 3.4 m (`unit_masses`).
    pub fn block_masses(&self, bm: &BlockModel, unit: &[f64]) -> Vec<f64> {
        let max = bm.max_corner();
        // Per axis and grid cell, the cell lengths of the sites centred in it, summed.
        let len: [Vec<f64>; 3] = [0, 1, 2].map(|a| {
            let mut v = vec![0.0; bm.dims[a]];
            for i in 0..self.n[a] {
                if let Some(c) = bm.axis_cell(a, self.centre(a, i)) {
                    v[c] += self.cell_len(a, i, max[a]);
                }
            }
            v
        });
        (0..bm.len())
            .map(|b| {
                let c = bm
                    .cell([bm.x[b], bm.y[b], bm.z[b]])
                    .expect("a block's centre lies in its grid cell");
                let len: f64 = (0..3).map(|a| len[a][c[a]]).product();
                len * unit[b] / self.s.powi(3)
            })
            .collect()
    }
}

/// How far beyond a disk's radius, in marker spacings, its [`Rim`] lists the sites ahead.
const RIM_AHEAD: f64 = 0.5;

/// The lattice sites just beyond one IMZ disk's radius, listed so that the disk's growth
/// takes them in order of distance without walking its annulus again.
///
/// A wide disk grows by millimetres an update, and the sites around a radius R lie
/// millimetres apart in distance (2π R h / s³ of them per metre of radius: 240 at R = 43
/// m, h = 4 m and s = 1.65 m), so nearly every update brings one inside. Walking the new
/// annulus for it visited every lattice row the disk spans, and finding where the next
/// site lay as many again: 11% of the samples of the mine scene at 1.65 m markers. A rim
/// lists the sites not yet engulfed out to half a spacing beyond the radius at which it
/// walks, and the disk takes them off the list as its radius passes them.
/// Engulfing only ever marks sites, so a site listed and marked since is skipped when
/// taken, and the sites taken at each update are those the annulus walk found there.
#[derive(Debug, Clone)]
pub struct Rim {
    /// Radius out to which the sites are listed, m (−1: none yet, not even on the axis).
    reach: f64,
    /// The sites listed and not taken yet, (a², id), farthest first.
    ahead: Vec<(f64, usize)>,
}

impl Default for Rim {
    fn default() -> Rim {
        Rim {
            reach: -1.0,
            ahead: Vec::new(),
        }
    }
}

impl Rim {
    /// Adds to `found` the sites of the disk's layers (`layers`, asked for only when the
    /// rim walks) within `r` of its axis (x, y) that it has not taken before and that
    /// `engulfed` does not mark.
    pub fn take(
        &mut self,
        lat: &Lattice,
        axis: (f64, f64),
        r: f64,
        layers: impl FnOnce() -> Option<(usize, usize)>,
        engulfed: &[bool],
        found: &mut Vec<usize>,
    ) {
        let r2 = r * r;
        while let Some(&(a2, id)) = self.ahead.last() {
            if a2 > r2 {
                break;
            }
            self.ahead.pop();
            if !engulfed[id] {
                found.push(id);
            }
        }
        if r <= self.reach {
            return;
        }
        // Past everything listed (all taken above): walk on to the new reach.
        let reach = r + RIM_AHEAD * lat.s;
        if let Some(kr) = layers() {
            lat.annulus(axis, kr, (self.reach, reach), |a2, id| {
                if !engulfed[id] {
                    if a2 <= r2 {
                        found.push(id);
                    } else {
                        self.ahead.push((a2, id));
                    }
                }
            });
        }
        self.ahead.sort_unstable_by(|a, b| b.0.total_cmp(&a.0));
        self.reach = reach;
    }
}

/// Sites of spacing `s` along an axis, from `origin`, whose centres lie before the grid's
/// far face `max` (at least one): where the extent is an odd multiple of s/2, the last
/// such site lies half a spacing short of the face, not on it (where it would lie in no
/// block).
fn sites_before(origin: f64, max: f64, s: f64) -> usize {
    (((max - origin) / s - 0.5).ceil() as usize).max(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lattice_ranges() {
        let l = Lattice {
            origin: [0.0; 3],
            grid_min: [0.0; 3],
            grid_max: [10.0; 3],
            s: 1.0,
            n: [10, 10, 10],
        };
        assert_eq!(l.range(0, 0.0, 10.0), Some((0, 9)));
        assert_eq!(l.range(0, 2.0, 4.0), Some((2, 3)));
        assert_eq!(l.range(0, 2.6, 2.9), None);
        let id = l.id(3, 4, 5);
        assert_eq!(l.pos(id), [3.5, 4.5, 5.5]);
    }

    /// Sites weigh the cube around them and the cells tile the grid: with 17.5 mm markers
    /// on 50 mm blocks (2 or 3 sites per block along an axis, last cells 10 mm long) the
    /// sites' masses and the blocks' lattice masses both add up to the box's in-situ mass,
    /// at any plan offset of the lattice (first cells 0.5 s to 1.5 s long), with every site
    /// on the grid. Also where the extents are odd multiples of s/2 (3.5 s in plan, 5.5 s
    /// high), where the last sites lay on the far faces, in no block, before
    /// [`sites_before`].
    #[test]
    fn site_masses_tile_the_grid() {
        let castro = crate::model::synthetic::UniformBox::castro_isolated();
        let ties = crate::model::synthetic::UniformBox {
            extent: [3.5, 3.5, 5.5],
            block: [0.5; 3],
            ..castro.clone()
        };
        for (b, s) in [(castro, 0.0175), (ties, 1.0)] {
            site_masses_tile(&b, s);
        }
    }

    fn site_masses_tile(b: &crate::model::synthetic::UniformBox, s: f64) {
        let bm = b.scene().blocks;
        let total = b.extent.iter().product::<f64>() * b.density * (1.0 - b.n0);
        for offset in [[0.0, 0.0], [0.49, -0.5], [-0.5, 0.49], [0.3, -0.2]] {
            let l = Lattice::new(&bm, s).with_offset(&bm, offset);
            let unit = l.unit_masses(&bm);
            let sites: f64 = (0..l.len())
                .map(|id| l.site_mass(&bm, id, unit[bm.locate(l.pos(id)).unwrap()]))
                .sum();
            let blocks: f64 = l.block_masses(&bm, &unit).iter().sum();
            assert!(
                (sites / total - 1.0).abs() < 1e-9,
                "{offset:?}: {sites} {total}"
            );
            assert!(
                (blocks / total - 1.0).abs() < 1e-9,
                "{offset:?}: {blocks} {total}"
            );
            assert_eq!(l.site_mass(&bm, l.id(1, 1, 2), unit[0]), unit[0]);
        }
    }

    /// The cells' overlaps with the blocks tile the blocks: over all sites, the overlaps
    /// with a block add up to its volume, and each site's to its cell's, on lattices that
    /// straddle the block faces (17.5 and 35 mm on 50 mm blocks, at plan offsets that make
    /// the first cells s/2 to 3s/2 long). Where s divides the blocks, on the lattice's own
    /// origin, every cell lies in the one block of its site.
    #[test]
    fn cell_overlaps_tile_the_blocks() {
        let b = crate::model::synthetic::UniformBox {
            extent: [0.6, 0.55, 0.4],
            ..crate::model::synthetic::UniformBox::castro_isolated()
        };
        let bm = b.scene().blocks;
        let block_vol: f64 = bm.size.iter().product();
        let mut cell = Vec::new();
        for (s, offset) in [
            (0.0175, [0.0, 0.0]),
            (0.035, [0.49, -0.5]),
            (0.035, [-0.5, 0.3]),
            (0.025, [0.0, 0.0]),
        ] {
            let l = Lattice::new(&bm, s).with_offset(&bm, offset);
            let mut per_block = vec![0.0; bm.len()];
            let mut straddling = 0;
            for id in 0..l.len() {
                l.cell_blocks(&bm, id, &mut cell);
                let site_vol = l.site_mass(&bm, id, s.powi(3));
                let sum: f64 = cell.iter().map(|&(_, v)| v).sum();
                assert!(
                    (sum / site_vol - 1.0).abs() < 1e-9,
                    "{s} {offset:?} site {id}"
                );
                let own = bm.locate(l.pos(id)).unwrap();
                assert!(cell.iter().any(|&(b, v)| b == own && v > 0.0));
                straddling += usize::from(cell.len() > 1);
                cell.iter().for_each(|&(b, v)| per_block[b] += v);
            }
            for (b, v) in per_block.iter().enumerate() {
                assert!(
                    (v / block_vol - 1.0).abs() < 1e-9,
                    "{s} {offset:?} block {b}: {v}"
                );
            }
            if s == 0.025 {
                assert_eq!(straddling, 0, "s divides the blocks");
            } else {
                assert!(straddling > l.len() / 2, "{s} {offset:?}: {straddling}");
            }
        }
    }

    /// `range` gives exactly the sites whose centres lie in [lo, hi), on the regular lattice
    /// and at offsets that put the first sites' cells anywhere from s/2 to 3s/2 long, whose
    /// sites sit at their cells' middles (on a half cell: s/4 from the grid's face, not on
    /// it).
    #[test]
    fn range_holds_the_sites_centred_in_the_interval() {
        let b = crate::model::synthetic::UniformBox {
            extent: [10.5, 9.5, 4.0],
            block: [0.5; 3],
            ..crate::model::synthetic::UniformBox::castro_isolated()
        };
        let bm = b.scene().blocks;
        for offset in [[0.0, 0.0], [-0.5, 0.25], [0.49, -0.3], [-0.2, 0.0]] {
            let l = Lattice::new(&bm, 1.0).with_offset(&bm, offset);
            for a in 0..2 {
                let c: Vec<f64> = (0..l.n[a]).map(|i| l.centre(a, i)).collect();
                assert!(c.windows(2).all(|w| w[0] < w[1]), "{offset:?} {c:?}");
                if offset[a] == -0.5 {
                    assert_eq!(c[0], bm.origin[a] + 0.25);
                }
                for k in 0..400 {
                    let lo = bm.origin[a] - 1.0 + k as f64 * 0.0317;
                    for w in [0.0, 0.3, 1.0, 2.7, 13.0] {
                        let want: Vec<usize> = (0..c.len())
                            .filter(|&i| (lo..lo + w).contains(&c[i]))
                            .collect();
                        let got = l
                            .range(a, lo, lo + w)
                            .map_or(vec![], |(i0, i1)| (i0..=i1).collect());
                        assert_eq!(got, want, "{offset:?} axis {a} [{lo}, {})", lo + w);
                    }
                }
            }
        }
    }

    /// `layers_at_level` gives exactly the layers whose centres the level function puts at
    /// level i, for disk thicknesses that put layers on the boundaries (multiples of s/2,
    /// on and off the lattice's origin) and others: every layer lies at one level.
    #[test]
    fn layers_at_level_are_the_layers_the_level_test_places_there() {
        let l = Lattice {
            origin: [0.0, 0.0, 2347.0],
            grid_min: [0.0, 0.0, 2347.0],
            grid_max: [1.9, 1.9, 2347.0 + 80.0 * 1.9],
            s: 1.9,
            n: [1, 1, 80],
        };
        for &z0 in &[2347.0, 2347.3, 2347.95] {
            for &h in &[0.95, 1.9, 2.85, 3.8, 2.53, 1.0 / 3.0] {
                let level = |z: f64| {
                    let t = (z - z0) / h;
                    (t >= 0.0).then_some(t as usize)
                };
                let mut seen = vec![0usize; l.n[2]];
                for i in 0..(80.0 * 1.9 / h) as usize + 2 {
                    let lo = z0 + i as f64 * h;
                    let got = l.layers_at_level(lo, lo + h, level, i);
                    let want: Vec<usize> = (0..l.n[2])
                        .filter(|&k| level(l.layer_z(k)) == Some(i))
                        .collect();
                    let got: Vec<usize> = got.map_or(vec![], |(a, b)| (a..=b).collect());
                    assert_eq!(got, want, "z0 {z0} h {h} level {i}");
                    got.iter().for_each(|&k| seen[k] += 1);
                }
                assert!(seen.iter().all(|&c| c == 1), "z0 {z0} h {h}: {seen:?}");
            }
        }
    }

    /// A rim takes, update by update, exactly the sites of its layers that the disk's
    /// growth brings inside (brute force over every site), for axes on and off the
    /// lattice, steps smaller and larger than its reach, a shrinking radius, radii past the
    /// edge and sites marked engulfed in between.
    #[test]
    fn a_rim_takes_the_sites_its_disk_grows_over() {
        let l = Lattice {
            origin: [-3.0, 2.0, 0.0],
            grid_min: [-3.0, 2.0, 0.0],
            grid_max: [9.0, 12.0, 2.0],
            s: 0.5,
            n: [24, 20, 4],
        };
        let layers = l.range(2, 0.5, 1.5);
        let mut taken_total = 0;
        for &(x, y) in &[
            (3.0, 7.0),
            (2.75, 6.75),
            (-2.9, 2.1),
            (8.9, 11.9),
            (3.1, 4.37),
        ] {
            let mut rim = Rim::default();
            let mut engulfed = vec![false; l.len()];
            let mut taken = vec![false; l.len()];
            let mut r_max = 0.0f64;
            for k in 0..80 {
                // Growing in steps from 0.013 m to 2 m, shrinking every seventh update.
                let step = 0.013 * (k * k) as f64 % 2.0;
                let r = if k % 7 == 3 {
                    0.9 * r_max
                } else {
                    r_max + step
                };
                let mut found = Vec::new();
                rim.take(&l, (x, y), r, || layers, &engulfed, &mut found);
                found.sort_unstable();
                let mut want = Vec::new();
                for id in 0..l.len() {
                    let p = l.pos(id);
                    let a2 = (p[0] - x).powi(2) + (p[1] - y).powi(2);
                    let layer = id / (l.n[0] * l.n[1]);
                    let in_layers = layers.is_some_and(|(k0, k1)| (k0..=k1).contains(&layer));
                    if in_layers && a2 <= r * r && !taken[id] && !engulfed[id] {
                        want.push(id);
                    }
                }
                assert_eq!(found, want, "axis ({x}, {y}), update {k}, r {r}");
                for &id in &found {
                    taken[id] = true;
                }
                taken_total += found.len();
                r_max = r_max.max(r);
                // Another disk engulfs a few sites ahead of this one.
                for id in (k * 37..l.len()).step_by(211) {
                    engulfed[id] = true;
                }
            }
        }
        assert!(taken_total > 500, "{taken_total}");
    }
}
