//! Markers (summary §3.3, DESIGN §4.2): tracked parcels of material, held column-wise.
//!
//! Markers start on a regular lattice of spacing `s` over the block grid. A lattice site
//! stands for the cube of side s around it at its block's in-situ density, ρ (1 − n0) s³
//! (the cells of the last sites along an axis run to the grid's face), so the marker field
//! is as dense as the ground everywhere and its mass adds up to the block model's where the
//! density is uniform; a block's own mass is exact where s divides it. Stagnant ground is
//! never materialised: a site becomes a marker (row of [`Markers`]) only when an IMZ
//! engulfs it, and the marker id is the site index. So stagnant ground costs nothing per increment, and the lattice itself
//! is the spatial index of the stagnant markers.
//!
//! # Motion of a marker at radius a_m in disk i (per IMZ, summed by superposition)
//! - Vertical, cone (R_i ≤ w_i): Δz = −3 Δv_i (1 − a_m/R_i) / (π R_i²).
//! - Vertical, frustum (R_i > w_i, plug radius R_p = R_i − w_i):
//!   plug Δz = −3 Δv_i / (π (R_i² + R_i R_p + R_p²)); annulus the same × (1 − (a_m − R_p)/w_i).
//! - Radial, from disk expansion ΔR_i = R_i − R_i^old. The ring R_i^old → R_i is stagnant
//!   ground at n0 that dilates to n1 (`engine::imz`, the volume balance): it swells inward
//!   by the void the disk absorbed, v_a = Δv_i − Δv_out (the void in through its base less
//!   the void out through its top), over the flowable share f of the perimeter (rays with
//!   no ring are not pushed), and squeezes the interior by as much. The squeeze follows the
//!   vertical move's profile, streamtube by streamtube: the area inside radius a ≤ R_old
//!   loses the share F(a) of v_a / (h f) that the profile passes inside a ([`radial`]);
//!   beyond R_old the move falls linearly to zero at the new radius. To first order the
//!   peak, at R_old, is ΔR_i (n1 − n0)/(1 − n1), the thickness the ring gains. The summary
//!   prints the factor inverted, (1 − n1)/(n1 − n0); taken literally that moves a marker of
//!   a new disk (R^old = 0) by ~3.7 R across the axis, and diverges as the porosity jump
//!   vanishes, so we use the volume-balance form (`tests::radial_move_is_the_ring_dilation`).
//!   Ground widened into for free (already dilated by a neighbour) absorbs no void and is
//!   not pushed. A new disk (R^old = 0) has no interior to push; its ring dilates by the
//!   vertical move alone.
//! - Lateral, where the ring's dilation differs around the perimeter (part of it inside a
//!   neighbour, already at n1): the radial move pushes the same on every ray, so the part
//!   inside the neighbour would dilate past n1 and the stagnant part stop short of it. A
//!   potential flow inside R_old carries the difference across the disk, from the side
//!   that must dilate to the side that must not ([`lateral`]); it changes no volume inside
//!   the disk. Two drawpoints 8 m apart (4 m openings, 15 m blocks, 2.5 m markers) draw
//!   1.001 of their schedule in markers with it and 0.973–0.976 without; 15 m apart, 0.996
//!   and 0.978–0.982 (an isolated one, 0.981: markers still on their way).
//! - The vertical move interpolates the void linearly from Δv_i at the disk's base to
//!   Δv_out at its top, so it stretches the disk's material by v_a, the volume the radial
//!   move took from the interior: the interior stays at n1 and the ring reaches n1. Void
//!   that leaves the top disk (to the free surface, or into an air gap under uncaved
//!   ground) moves the top disk's markers down by it, so the surface subsides by the void
//!   that left and an air gap opens above the markers, not inside them.
//! - Transfer into the disk below: a marker that crosses a disk's base keeps its
//!   streamtube (`transfer`); under overlap, each IMZ's transfer is applied at its share of
//!   the marker's vertical move, on crossings decided by the summed move
//!   ([`MotionField::step`]). Between two cones this is the summary's Δa′ = −(1 −
//!   R_{i−1}/R_i) a_m and Δz′ = −p (R_i² − R_{i−1}²)/R_{i−1}², p the depth reached below the
//!   disk base z_i (the summary's Δz′ with its Δz cancelled); between profiles of other
//!   shapes it is the volume-conserving form of the same idea.
//! - Walls (method of images): an IMZ whose disk passes one of the model's vertical walls
//!   also moves each marker as its mirror image across that wall would, plan components
//!   mirrored ([`MotionField::step`]). Along the wall the two cancel through it, so nothing
//!   crosses, and the disk's flux, which the wall would cut, stays whole inside the model
//!   (`tests::walls_mirror_the_imzs`). Dividing the moves by the flowable share A_f instead
//!   keeps the volume but not where it goes: the transfers map each ray by the uncut
//!   disk's shares, so the rays towards a wall let out more than they take in. On the
//!   demo, whose IMZs widen across the whole model, the drawpoints next to the walls then
//!   drew 0.85–0.95 of their schedule in markers and the row inside them 1.09–1.21; with
//!   images, 0.92–1.03 (never-short drawpoints, p10 0.931, p90 1.014). Past a corner, the
//!   IMZ's double image (mirrored across both walls, both plan components mirrored) moves
//!   the marker too: without it the demo's two corner drawpoints that are never short drew
//!   0.971 of their schedule, with it 0.988 and 0.991. A marker visits a wall's images
//!   only where it is within their reach at its height ([`WallReach`]): the demo's IMZs
//!   all reach the walls near the top, and visiting every wall's images wherever the
//!   widest disk reached cost 1.21× the run against that. Nothing measurable at mine scale.
//! - Shear strain in the shear annulus: Γ = |Δz| / min(R, w); shear work Γ σ_n with the
//!   Janssen σ_n = ρ_s (1 − n1) g R / (2 tan φ) (summary §6.3).
//!
//! A marker that leaves the lowest disk is drawn, credited to the IMZ that moved it most.

use rayon::prelude::*;

use super::cadence::Cadence;
use super::imz::{DiskMotion, ImzGeom, ImzGrid, PerDisk};
use crate::model::BlockModel;

/// The marker lattice over the block grid.
#[derive(Debug, Clone, Copy)]
pub struct Lattice {
    /// Lattice origin (grid minimum corner), m.
    pub origin: [f64; 3],
    /// Spacing s, m.
    pub s: f64,
    /// Sites per axis.
    pub n: [usize; 3],
}

impl Lattice {
    /// A lattice of spacing `s` covering the block grid.
    pub fn new(bm: &BlockModel, s: f64) -> Lattice {
        let max = bm.max_corner();
        let n = [0, 1, 2].map(|a| (((max[a] - bm.origin[a]) / s).round() as usize).max(1));
        Lattice {
            origin: bm.origin,
            s,
            n,
        }
    }

    /// Total number of sites.
    pub fn len(&self) -> usize {
        self.n[0] * self.n[1] * self.n[2]
    }

    /// Whether the lattice has no sites.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Position of site `id`.
    #[inline]
    pub fn pos(&self, id: usize) -> [f64; 3] {
        let i = id % self.n[0];
        let j = (id / self.n[0]) % self.n[1];
        let k = id / (self.n[0] * self.n[1]);
        [
            self.origin[0] + (i as f64 + 0.5) * self.s,
            self.origin[1] + (j as f64 + 0.5) * self.s,
            self.origin[2] + (k as f64 + 0.5) * self.s,
        ]
    }

    /// Site index range (inclusive) along axis `a` whose centres lie in [lo, hi).
    #[inline]
    pub fn range(&self, a: usize, lo: f64, hi: f64) -> Option<(usize, usize)> {
        let t0 = ((lo - self.origin[a]) / self.s - 0.5).ceil().max(0.0);
        let t1 = ((hi - self.origin[a]) / self.s - 0.5).ceil() - 1.0;
        let t1 = t1.min(self.n[a] as f64 - 1.0);
        (t1 >= t0).then_some((t0 as usize, t1 as usize))
    }

    /// The smallest squared plan distance a² > r² from the axis (x, y) of a site in the
    /// layers whose centres lie in [z0, z1) (∞ if none): while a disk there stays within
    /// this, it covers no new site, so engulfing can skip it. a² is computed as engulfing
    /// computes it. Per row, the nearest sites outside the chord are those just beyond the
    /// chord's ends (or nearest the axis when the row misses the circle); beyond the rows
    /// the circle spans, the nearest row on each side dominates every farther one.
    pub fn next_site_a2(&self, x: f64, y: f64, z0: f64, z1: f64, r: f64) -> f64 {
        let Some(kr) = self.range(2, z0, z1) else {
            return f64::INFINITY;
        };
        let last = |a: usize| self.n[a] as isize - 1;
        let idx = |a: usize, c: f64| ((c - self.origin[a]) / self.s - 0.5).floor() as isize;
        let (j0, j1) = ((idx(1, y - r) - 1).max(0), (idx(1, y + r) + 2).min(last(1)));
        let mut best = f64::INFINITY;
        // Row j is the same in every layer; only a² matters.
        let k = kr.0;
        for j in j0..=j1 {
            let dy = self.origin[1] + (j as f64 + 0.5) * self.s - y;
            let outer = (r * r - dy * dy).max(0.0).sqrt();
            let (lo, hi) = match self.range(0, x - outer, x + outer + 1e-9 * self.s) {
                Some((a, b)) => (a as isize - 1, b as isize + 1),
                None => (idx(0, x) - 1, idx(0, x) + 2),
            };
            let mut try_site = |i: isize| {
                if (0..=last(0)).contains(&i) {
                    let p = self.pos(self.id(i as usize, j as usize, k));
                    let a2 = (p[0] - x).powi(2) + (p[1] - y).powi(2);
                    if a2 > r * r && a2 < best {
                        best = a2;
                    }
                }
            };
            for i in [lo - 1, lo, lo + 1, hi - 1, hi, hi + 1] {
                try_site(i);
            }
        }
        best
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

    /// Length along axis `a` of the cell of site `i`: s, except that the last cell runs to
    /// the grid's far face (the lattice holds a whole number of sites, so its far face is
    /// within s/2 of the grid's), so that the cells tile the grid.
    #[inline]
    fn cell_len(&self, a: usize, i: usize, max: f64) -> f64 {
        let last = max - self.origin[a] - (self.n[a] - 1) as f64 * self.s;
        // Where s divides the grid, the last cell is s itself, not s up to rounding.
        if i + 1 == self.n[a] && (last - self.s).abs() > 1e-9 * self.s {
            last
        } else {
            self.s
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
    /// lie in it. This is the block's own mass when s divides the block, and 0.71–1.40× it
    /// on the mine scene's 15.2 m blocks at 3.4 m (`unit_masses`).
    pub fn block_masses(&self, bm: &BlockModel, unit: &[f64]) -> Vec<f64> {
        let max = bm.max_corner();
        (0..bm.len())
            .map(|b| {
                let c = [bm.x[b], bm.y[b], bm.z[b]];
                let len: f64 = (0..3)
                    .map(|a| {
                        self.range(a, c[a] - 0.5 * bm.size[a], c[a] + 0.5 * bm.size[a])
                            .map_or(0.0, |(i0, i1)| {
                                (i0..=i1).map(|i| self.cell_len(a, i, max[a])).sum::<f64>()
                            })
                    })
                    .product();
                len * unit[b] / self.s.powi(3)
            })
            .collect()
    }
}

/// Mobilised markers, struct of arrays. Row order is an implementation detail; `id` is
/// the stable identity (the lattice site).
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct Markers {
    /// Marker id (lattice site index).
    pub id: Vec<u64>,
    /// Current position.
    pub x: Vec<f64>,
    /// Current position.
    pub y: Vec<f64>,
    /// Current position.
    pub z: Vec<f64>,
    /// Mass, t.
    pub mass: Vec<f64>,
    /// Block of origin (row in the block model).
    pub block: Vec<u32>,
    /// Representative fragment size, m.
    pub frag: Vec<f64>,
    /// Accumulated shear strain Γ.
    pub strain: Vec<f64>,
    /// Accumulated shear work Γ σ_n, kPa.
    pub work: Vec<f64>,
    /// Horizontal distance rilled on the free surface so far, m (`engine::rilling`).
    pub rill: Vec<f64>,
    /// Primary fragment size d0, m (`engine::fragmentation`).
    pub frag0: Vec<f64>,
    /// Attrited mass fraction W (`engine::fragmentation`).
    pub attrited: Vec<f64>,
    /// Accumulated percolation distance, m (`engine::fines`).
    pub percolated: Vec<f64>,
    /// Cadence level L: the marker steps once every 2^L updates (`engine::cadence`).
    pub level: Vec<u8>,
}

/// Drawn markers: the moving columns plus who drew them and when.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct DrawnMarkers {
    /// The markers as they were when drawn.
    pub m: Markers,
    /// Drawpoint that drew each.
    pub drawpoint: Vec<u32>,
    /// Period number in which each was drawn.
    pub period: Vec<i64>,
    /// Draw time τ of each: its drawpoint's cumulative scheduled tonnes at the middle of the
    /// step that drew it, t (`engine::crediting`).
    #[serde(default)]
    pub tau: Vec<f64>,
}

impl Markers {
    /// Number of markers.
    pub fn len(&self) -> usize {
        self.id.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.id.is_empty()
    }

    /// Whether every column has one value per marker (a decoded checkpoint may not).
    pub fn is_consistent(&self) -> bool {
        let n = self.id.len();
        [
            self.x.len(),
            self.y.len(),
            self.z.len(),
            self.mass.len(),
            self.block.len(),
            self.frag.len(),
            self.strain.len(),
            self.work.len(),
            self.rill.len(),
            self.frag0.len(),
            self.attrited.len(),
            self.percolated.len(),
            self.level.len(),
        ]
        .iter()
        .all(|&l| l == n)
    }

    /// Appends a marker.
    #[allow(clippy::too_many_arguments)]
    pub fn push(&mut self, id: u64, p: [f64; 3], mass: f64, block: u32, frag: f64) {
        self.id.push(id);
        self.x.push(p[0]);
        self.y.push(p[1]);
        self.z.push(p[2]);
        self.mass.push(mass);
        self.block.push(block);
        self.frag.push(frag);
        self.strain.push(0.0);
        self.work.push(0.0);
        self.rill.push(0.0);
        self.frag0.push(frag);
        self.attrited.push(0.0);
        self.percolated.push(0.0);
        self.level.push(0);
    }

    /// Moves row `k` out (swap-remove) and appends it to `to`.
    pub fn take_into(&mut self, k: usize, to: &mut Markers) {
        to.id.push(self.id.swap_remove(k));
        to.x.push(self.x.swap_remove(k));
        to.y.push(self.y.swap_remove(k));
        to.z.push(self.z.swap_remove(k));
        to.mass.push(self.mass.swap_remove(k));
        to.block.push(self.block.swap_remove(k));
        to.frag.push(self.frag.swap_remove(k));
        to.strain.push(self.strain.swap_remove(k));
        to.work.push(self.work.swap_remove(k));
        to.rill.push(self.rill.swap_remove(k));
        to.frag0.push(self.frag0.swap_remove(k));
        to.attrited.push(self.attrited.swap_remove(k));
        to.percolated.push(self.percolated.swap_remove(k));
        to.level.push(self.level.swap_remove(k));
    }
}

/// Read-only view of the drawing IMZs for one marker update.
pub struct MotionField<'a> {
    /// Geometry of every IMZ.
    pub geoms: &'a [ImzGeom],
    /// Per-disk motion of every IMZ (empty slices for IMZs that did not draw).
    pub motion: &'a [&'a [DiskMotion]],
    /// Grid over the drawing IMZs.
    pub grid: &'a ImzGrid,
    /// The block model and period, to tell where a disk cut by a wall or uncaved ground has
    /// no dilating ring behind a marker, and where the model's walls mirror the IMZs (None:
    /// open ground everywhere).
    pub ground: Option<(&'a BlockModel, i64)>,
    /// How far from each wall an IMZ's image can reach, by height ([`WallReach`]).
    pub reach: WallReach,
}

/// How far from each of the model's vertical walls (x low, x high, y low, y high) the
/// IMZs' images reach, per band of height h from the lowest IMZ base: the most, over the
/// disks that overlap the band, of R_i less the distance from the IMZ's axis to the wall.
/// The image of a disk across a wall holds a point only if the point is within that of the
/// wall (the image lies as far beyond the wall as the axis lies inside it), so farther
/// markers skip the wall's images, and a corner's unless they are within reach of both
/// walls. In the lower half of the demo, where the disks are narrow, that is most markers.
#[derive(Debug, Clone, Default)]
pub struct WallReach {
    z0: f64,
    h: f64,
    bands: Vec<[f64; 4]>,
}

impl WallReach {
    /// The reach of the disks `geoms` in the walls of `bm`.
    pub fn new(geoms: &[ImzGeom], bm: &BlockModel) -> WallReach {
        let (lo, hi) = (bm.origin, bm.max_corner());
        let z0 = geoms.iter().map(|g| g.z0).fold(f64::INFINITY, f64::min);
        let h = geoms.iter().map(|g| g.h).fold(f64::INFINITY, f64::min);
        if !(z0.is_finite() && h > 0.0) {
            return WallReach::default();
        }
        // Each IMZ's reach per band, merged by the maximum (in parallel: a mine holds
        // hundreds of IMZs, and the maximum does not depend on the order).
        let one = |g: &ImzGeom| {
            let mut bands: Vec<[f64; 4]> = Vec::new();
            let dist = [g.x - lo[0], hi[0] - g.x, g.y - lo[1], hi[1] - g.y];
            for (i, &r) in g.radius.iter().enumerate() {
                let base = g.z0 + i as f64 * g.h - z0;
                let k0 = (base / h).floor().max(0.0) as usize;
                let k1 = ((base + g.h) / h).ceil() as usize;
                if bands.len() < k1 {
                    bands.resize(k1, [f64::NEG_INFINITY; 4]);
                }
                for band in &mut bands[k0..k1] {
                    for w in 0..4 {
                        band[w] = band[w].max(r - dist[w]);
                    }
                }
            }
            bands
        };
        let merge = |mut a: Vec<[f64; 4]>, b: Vec<[f64; 4]>| {
            if a.len() < b.len() {
                a.resize(b.len(), [f64::NEG_INFINITY; 4]);
            }
            for (x, y) in a.iter_mut().zip(&b) {
                for w in 0..4 {
                    x[w] = x[w].max(y[w]);
                }
            }
            a
        };
        let bands = geoms.par_iter().map(one).reduce(Vec::new, merge);
        WallReach { z0, h, bands }
    }

    /// The reach of the band that holds height `z` (−∞ where no disk is).
    #[inline]
    pub fn at(&self, z: f64) -> [f64; 4] {
        let t = (z - self.z0) / self.h;
        if t >= 0.0 {
            if let Some(b) = self.bands.get(t as usize) {
                return *b;
            }
        }
        [f64::NEG_INFINITY; 4]
    }
}

/// Result of moving one marker.
#[derive(Debug, Clone, Copy, Default)]
pub struct Step {
    /// Displacement.
    pub dx: f64,
    /// Displacement.
    pub dy: f64,
    /// Displacement.
    pub dz: f64,
    /// Shear strain increment.
    pub strain: f64,
    /// Shear work increment, kPa.
    pub work: f64,
    /// Drawpoint that drew it, or u32::MAX.
    pub drawn_by: u32,
    /// Σ Γ d̄ over the disks that shear it (Γ-weighted d̄ = dbar / strain), m.
    pub dbar: f64,
    /// The IMZ that moved it most, or u32::MAX.
    pub host: u32,
    /// Percolation distance (downward, ≥ 0) included in `dz`, m (`engine::fines`).
    pub perc: f64,
}

/// Vertical displacement Δz_m of a marker at radius `a` in a disk of radius `r`, shear
/// band `w`, with void `dv` passed into it (cone when R ≤ w, frustum otherwise).
#[inline]
pub fn vertical(dv: f64, r: f64, w: f64, a: f64) -> f64 {
    if r <= 0.0 || a > r {
        return 0.0;
    }
    if r <= w {
        -3.0 * dv * (1.0 - a / r) / (std::f64::consts::PI * r * r)
    } else {
        let rp = r - w;
        let plug = -3.0 * dv / (std::f64::consts::PI * (r * r + r * rp + rp * rp));
        if a <= rp {
            plug
        } else {
            plug * (1.0 - (a - rp) / w)
        }
    }
}

/// Share F(a) of a disk's vertical flux ([`vertical`]) that passes inside radius `a`:
/// ∫₀^a |Δz(a′)| 2π a′ da′ / Δv, 0 at the axis and 1 at the disk's radius `r`.
#[inline]
pub fn flux_inside(r: f64, w: f64, a: f64) -> f64 {
    if !(r > 0.0) {
        return 1.0;
    }
    let a = a.clamp(0.0, r);
    // The cone is the frustum with no plug and a band as wide as the disk.
    let (rp, w) = if r <= w { (0.0, r) } else { (r - w, w) };
    let c = 3.0 / (r * r + r * rp + rp * rp);
    if a <= rp {
        c * a * a
    } else {
        let (a2, p2) = (a * a, rp * rp);
        c * (p2 + (a2 - p2) - 2.0 * ((a2 * a - p2 * rp) / 3.0 - 0.5 * rp * (a2 - p2)) / w)
    }
}

/// The radius at which the share `f` of a disk's vertical flux passes inside
/// ([`flux_inside`] inverted): a square root in the plug, Newton's method kept inside a
/// shrinking bracket in the shear annulus (F is increasing in a).
fn radius_at_share(r: f64, w: f64, f: f64) -> f64 {
    let f = f.clamp(0.0, 1.0);
    let (rp, band) = if r <= w { (0.0, r) } else { (r - w, w) };
    let c = 3.0 / (r * r + r * rp + rp * rp);
    if f <= c * rp * rp {
        return (f / c).sqrt();
    }
    let (mut lo, mut hi) = (rp, r);
    let mut a = (f / c).sqrt().clamp(lo, hi);
    for _ in 0..40 {
        let g = flux_inside(r, w, a) - f;
        if g.abs() <= 1e-13 {
            break;
        }
        if g < 0.0 {
            lo = a;
        } else {
            hi = a;
        }
        let slope = 2.0 * a * c * (1.0 - (a - rp) / band);
        let next = a - g / slope;
        a = if slope > 0.0 && next > lo && next < hi {
            next
        } else {
            0.5 * (lo + hi)
        };
        if hi - lo <= 1e-12 * r {
            break;
        }
    }
    a
}

/// The transfer (Δa′, Δz′) of a marker at radius `a` in disk `here` that the update carried
/// `depth` below the disk's base, into the disk `below`.
///
/// The marker keeps its streamtube: it moves to the radius a′ below at which the same share
/// of the flux passes inside (F_below(a′) = F_here(a)), and the depth it reached is
/// stretched by the ratio of the vertical speeds there, so the crossing material keeps its
/// volume, streamtube by streamtube. Where the two disks' profiles have the same shape (two
/// cones) this is the summary's transfer, Δa′ = −(1 − R_{i−1}/R_i) a and
/// Δz′ = −p (R_i² − R_{i−1}²)/R_{i−1}²; with a plug of another relative width (frustums of
/// other radii, w being the same), the summary's linear map sends more of the flux to the
/// outer part of the narrower disk than its profile carries away, and material piles up
/// there (by 20–80% near the base of an isolated IMZ). It also applies where the disk
/// below is the wider one, which the summary leaves unmoved.
fn transfer(here: &DiskMotion, below: &DiskMotion, a: f64, depth: f64) -> (f64, f64) {
    let a = a.min(here.r);
    let a_new = radius_at_share(below.r, below.w, flux_inside(here.r, here.w, a));
    let speed = |m: &DiskMotion, a: f64| -vertical(1.0, m.r, m.w, a) / m.area_frac;
    let (v_here, v_below) = (speed(here, a), speed(below, a_new));
    // At the very rim both speeds vanish; their ratio tends to the ratio of the areas.
    let stretch = if v_here > 1e-9 * speed(here, 0.0) {
        v_below / v_here
    } else {
        (here.r * here.r * here.area_frac) / (below.r * below.r * below.area_frac)
    };
    (a_new - a, -depth * (stretch - 1.0))
}

/// Inward radial displacement (negative) of a marker at radius `a` in a disk of radius `r`
/// and shear band `w` that expanded from `r_old` to `r_new`, its dilating ring taking
/// `take` of plan area from the interior (the void the disk absorbed over its height and
/// its flowable share of the perimeter; see the module docs).
///
/// Inside R_old the squeeze follows the vertical move's profile: the ring of radius a
/// loses the share F(a) ([`flux_inside`]) of `take`, so u(a) = −take F(a) / (2π a), and
/// each streamtube's squeeze is its vertical stretch. Between R_old and the new radius it
/// falls linearly to zero. At most half a marker's radius is taken in one step (only a
/// disk that more than doubles its radius in a step asks for more).
#[inline]
pub fn radial(r_old: f64, r_new: f64, r: f64, w: f64, take: f64, a: f64) -> f64 {
    let dr = r_new - r_old;
    if dr <= 0.0 || a > r_new || !(take > 0.0) || !(r_old > 0.0) || !(a > 0.0) {
        return 0.0;
    }
    let at = |a: f64| (take * flux_inside(r, w, a) / (2.0 * std::f64::consts::PI * a)).min(0.5 * a);
    if a > r_old {
        -at(r_old) * (1.0 - (a - r_old) / dr)
    } else {
        -at(a)
    }
}

/// Lateral move (dx, dy) of a marker at offset (ex, ey) from the axis of a disk that
/// expanded from `m.r_old` to `m.r`, its ring taking `take` of plan area from the interior
/// ([`radial`]'s), where the ring's dilation is not the same all round (`m.shape`).
///
/// [`radial`] pushes the same on every ray, as if the whole ring were stagnant ground at
/// the mean jump. Where part of the perimeter lies inside another IMZ (already at n1) that
/// part must not dilate, and the stagnant part must dilate by the full jump: the ring's
/// dilation per unit angle is w(θ) times the mean, w the point's jump over the mean. The
/// difference, (w − 1) times the uniform push, is the flux this move adds across R_old. It
/// is the gradient of the harmonic potential φ = Re W, W(z) = Σ C_k z^k, whose radial
/// derivative at R_old is that flux over R_old (the k = 1 mode is a translation of the
/// interior towards the dilated side, higher modes strain it): inside R_old it moves
/// material without changing its volume, so the interior stays at n1, and the material the
/// stagnant side of the ring gives up goes to the side that must not dilate. Beyond R_old
/// it falls linearly to zero at the new radius, like the radial push.
///
/// `m.per_disk` must be prepared ([`prepare`]).
#[inline]
pub fn lateral(m: &DiskMotion, ex: f64, ey: f64, a: f64) -> (f64, f64) {
    let (r_old, r) = (m.r_old, m.r);
    if !m.per_disk.lateral || a > r {
        return (0.0, 0.0);
    }
    // u_a(R_old, θ) = s Σ α_k cos kθ + β_k sin kθ: the uniform push at R_old times w − 1.
    let s = -m.per_disk.push;
    let (scale, tx, ty) = if a <= r_old {
        (s, ex / r_old, ey / r_old)
    } else {
        (s * (r - a) / (r - r_old), ex / a, ey / a)
    };
    // W'(z) = s Σ (α_k − i β_k) t^(k−1), t = z / R_old; u = (Re W', −Im W').
    let (mut wr, mut wi) = (0.0, 0.0);
    let (mut pr, mut pi) = (1.0, 0.0);
    for k in 0..super::imz::SHAPE_MODES {
        let (al, be) = (m.shape[2 * k], m.shape[2 * k + 1]);
        wr += al * pr + be * pi;
        wi += al * pi - be * pr;
        (pr, pi) = (pr * tx - pi * ty, pr * ty + pi * tx);
    }
    let (ux, uy) = (scale * wr, -scale * wi);
    let (cap, len2) = (0.25 * r_old, ux * ux + uy * uy);
    if len2 > cap * cap {
        let k = cap / len2.sqrt();
        (ux * k, uy * k)
    } else {
        (ux, uy)
    }
}

/// Fills each disk's constants of the marker pass ([`PerDisk`]) from its motion, for IMZ
/// disks of thickness `h`: the same for every marker the disk moves, so the pass reads
/// them instead of working them out per marker (with the same arithmetic: the moves are
/// bit for bit those of the formulas in [`radial`] and [`lateral`]).
pub fn prepare(motion: &mut [DiskMotion], h: f64) {
    for m in motion {
        let take = (m.dv - m.dv_out) / (h * m.flow_frac);
        let widened = m.r > m.r_old && m.r_old > 0.0 && take > 0.0;
        let push = if widened {
            take * flux_inside(m.r, m.w, m.r_old) / (2.0 * std::f64::consts::PI * m.r_old)
        } else {
            0.0
        };
        let lateral = widened && m.shape.iter().any(|&c| c != 0.0);
        m.per_disk = PerDisk {
            take,
            push,
            lateral,
        };
    }
}

impl MotionField<'_> {
    /// Displacement of a marker at `p` by every drawing IMZ that contains it.
    ///
    /// Vertical and expansion moves superpose linearly (summary §4.2). The transfer into a
    /// narrower disk below (Δa′, Δz′) is not linear: it maps the whole radius a_m of a
    /// marker that crosses a disk base. Each IMZ's transfer is therefore weighted by that
    /// IMZ's share of the marker's vertical move, |Δz_d| / Σ|Δz|: alone it applies in
    /// full (the summary's rule), and a marker that the draw of one IMZ carries across
    /// another's disk boundary by a hair is not pulled towards the other's axis.
    ///
    /// Whether a marker crosses a disk base, and how deep below it it ends, is decided on
    /// the summed move: markers cross a base at the rate of the summed flux, and each
    /// crossing carries every IMZ's transfer at its share, so over many steps each IMZ
    /// transfers its own flux, which is what superposition means. Deciding it on each IMZ's
    /// own move instead applied an IMZ's transfer only when its move alone reached the base,
    /// i.e. at the square of its share: where a weak IMZ overlapped a strong one, the weak
    /// one's funnel hardly drew its streamtubes in. On nine drawpoints 15 m apart (the
    /// panel of `engine::imz`'s docs, 300 m of ground, 60 periods, 3.75 m markers) the
    /// middle drawpoint's column carries 0.74 of its schedule to it in markers over
    /// periods 20–60, against 0.64 with crossings decided per IMZ.
    #[inline]
    pub fn step(&self, p: [f64; 3]) -> Step {
        let mut st = Step {
            drawn_by: u32::MAX,
            ..Default::default()
        };
        let mut strongest = 0.0f64;
        let mut total = 0.0f64;
        // Disk bases this marker may cross, per IMZ: (IMZ, disk, radius after the radial
        // move, unit ray, Δz of that IMZ). Whether it crosses is known only once every
        // IMZ's move is summed.
        type Base = (u32, u32, f64, f64, f64, f64);
        let mut bases: [Base; 8] = [(0, 0, 0.0, 0.0, 0.0, 0.0); 8];
        let mut extra: Vec<Base> = Vec::new();
        let mut n_b = 0usize;
        // The moves of IMZ d at a point q in its disk i, at (ex, ey) from its axis, their plan
        // components multiplied by (sx, sy): q = p for the IMZ itself, p's mirror across a
        // wall for the IMZ's image. Most IMZs listed for a cell miss the marker; the callers
        // reject them inline on the geometry's radii (`ImzGeom::disk_at`) before the disk's
        // motion is read (the motion's radius is the geometry's: both are the current one).
        let mut visit =
            |d: u32, sx: f64, sy: f64, (i, t, [ex, ey], a2): (usize, f64, [f64; 2], f64)| {
                let g = &self.geoms[d as usize];
                let motion = self.motion[d as usize];
                let Some(m) = motion.get(i) else { return };
                debug_assert_eq!(m.r, g.radius[i]);
                let a = a2.sqrt();
                // The void entering the disk's base is Δv_i and the void leaving through its top
                // Δv_out (Δv_{i+1} = (1 − r) Δv_i below another disk; at the top disk, what left
                // the IMZ); the share absorbed dilates the disk. Interpolating Δv linearly over
                // the disk's height spreads that dilation through the disk (markers move apart
                // vertically), instead of moving the disk rigidly and leaving the void as a
                // marker-free gap at its top. Both integrate to the same volumes through the
                // disk's base and top. The void fills the flowable share A_f of the disk only,
                // so the move is divided by it.
                let t_in = t - i as f64;
                let dv = m.dv + (m.dv_out - m.dv) * t_in;
                let dz = vertical(dv, m.r, m.w, a) / m.area_frac;
                let (ux, uy) = if a > 0.0 {
                    (ex / a, ey / a)
                } else {
                    (0.0, 0.0)
                };
                let mut da = radial(m.r_old, m.r, m.r, m.w, m.per_disk.take, a);
                // The inward move is the dilating ring pushing in along the marker's ray. In a
                // disk cut by a wall or uncaved ground (A_f < 1) there is no ring on a ray that
                // leaves the flowable ground before the new radius, so nothing pushes there
                // (otherwise markers are pulled off the wall, leaving a void behind them).
                if da != 0.0 && m.area_frac < 1.0 {
                    if let Some((bm, period)) = self.ground {
                        let reach = m.r * (1.0 - 1e-9);
                        let rim = bm.mirror([g.x + ux * reach, g.y + uy * reach, p[2]]);
                        if !bm.locate(rim).is_some_and(|b| bm.flowable(b, period)) {
                            da = 0.0;
                        }
                    }
                }
                let (lx, ly) = lateral(m, ex, ey, a);
                st.dx += sx * (da * ux + lx);
                st.dy += sy * (da * uy + ly);
                st.dz += dz;
                total += dz.abs();
                if i > 0 && dz != 0.0 {
                    let base = (d, i as u32, (a + da).max(0.0), sx * ux, sy * uy, dz);
                    if n_b < bases.len() {
                        bases[n_b] = base;
                        n_b += 1;
                    } else {
                        extra.push(base);
                    }
                }
                // Shear strain in the annulus (a > R − w; the whole disk when R ≤ w).
                if a > m.r - m.w {
                    let gamma = dz.abs() / m.r.min(m.w).max(1e-12);
                    st.strain += gamma;
                    st.work += gamma * m.sigma_n;
                    st.dbar += gamma * m.d;
                }
                if dz.abs() > strongest {
                    strongest = dz.abs();
                    st.drawn_by = d;
                }
            };
        for &d in self.grid.at(p[0], p[1]) {
            if let Some(h) = self.geoms[d as usize].disk_at(p) {
                visit(d, 1.0, 1.0, h);
            }
        }
        // The model's vertical walls (method of images): an IMZ whose disk passes a wall
        // also moves the marker as its mirror image across that wall would, so the flow
        // along a wall has no component through it and a cut disk's flux stays whole in the
        // model. The images of the IMZs of the cell at the wall nearest the mirrored point
        // are the candidates, where the marker is within the images' reach of the wall
        // ([`WallReach`]). Within reach of two walls, the images across both (the
        // corner's) as well.
        if let Some((bm, _)) = self.ground {
            let (lo, hi) = (bm.origin, bm.max_corner());
            let reach = self.reach.at(p[2]);
            // Per axis, the two walls: (the wall, a point just inside it, its reach index).
            let walls = |a: usize| {
                [
                    (lo[a], lo[a] + 1e-9, 2 * a),
                    (hi[a], hi[a] - 1e-9, 2 * a + 1),
                ]
                .into_iter()
                .filter(move |&(wall, _, w)| (p[a] - wall).abs() <= reach[w])
            };
            // The images of the IMZs listed at plan point `at` that hold `q`, plan components
            // multiplied by (sx, sy).
            let mut images = |at: [f64; 2], q: [f64; 3], sx: f64, sy: f64| {
                for &d in self.grid.at(at[0], at[1]) {
                    if let Some(h) = self.geoms[d as usize].disk_at(q) {
                        visit(d, sx, sy, h);
                    }
                }
            };
            for (wall, inside, _) in walls(0) {
                images([inside, p[1]], [2.0 * wall - p[0], p[1], p[2]], -1.0, 1.0);
            }
            for (wall, inside, _) in walls(1) {
                images([p[0], inside], [p[0], 2.0 * wall - p[1], p[2]], 1.0, -1.0);
            }
            for (wx, in_x, _) in walls(0) {
                for (wy, in_y, _) in walls(1) {
                    images(
                        [in_x, in_y],
                        [2.0 * wx - p[0], 2.0 * wy - p[1], p[2]],
                        -1.0,
                        -1.0,
                    );
                }
            }
        }
        // Transfer into the disk below (Δa′, Δz′), along each IMZ's streamtube, for every
        // disk base the summed move crosses, by the depth the summed move reaches below it.
        let z_new = p[2] + st.dz;
        for &(d, i, a, ux, uy, dz) in bases[..n_b].iter().chain(&extra) {
            let g = &self.geoms[d as usize];
            let z_base = g.z0 + i as f64 * g.h;
            if z_new >= z_base {
                continue;
            }
            let motion = self.motion[d as usize];
            let (m, below) = (&motion[i as usize], &motion[i as usize - 1]);
            if below.r > 0.0 && (below.r != m.r || below.w != m.w) {
                let (da_t, dz_t) = transfer(m, below, a, z_base - z_new);
                let share = dz.abs() / total;
                st.dx += share * da_t * ux;
                st.dy += share * da_t * uy;
                st.dz += share * dz_t;
            }
        }
        st.host = st.drawn_by;
        if st.drawn_by != u32::MAX && p[2] + st.dz >= self.geoms[st.drawn_by as usize].z0 {
            st.drawn_by = u32::MAX;
        }
        st
    }
}

/// A hook that adds to a marker's step before it is applied (fines percolation): the
/// markers, the marker's row and its step. Pure per marker, like the step itself.
pub type StepHook<'a> = &'a (dyn Fn(&Markers, usize, &mut Step) + Sync);

/// Moves every marker once (parallel, pure per marker, so the result does not depend on
/// the number of threads). Returns the rows drawn, in row order, with their drawpoint.
/// `extra` may add to each marker's step before it is applied (fines percolation); it must
/// be pure per marker too.
pub fn move_markers(
    mk: &mut Markers,
    field: &MotionField,
    extra: Option<StepHook>,
) -> Vec<(usize, u32)> {
    let Some(extra) = extra else {
        // No hook reads the markers: step and apply in one pass. A marker's step depends
        // on its own position only, so this is the two-pass result bit for bit, without the
        // per-update array of steps (72 bytes a marker, fresh pages every update).
        return (
            mk.x.par_iter_mut(),
            mk.y.par_iter_mut(),
            mk.z.par_iter_mut(),
            mk.strain.par_iter_mut(),
            mk.work.par_iter_mut(),
        )
            .into_par_iter()
            .enumerate()
            .filter_map(|(k, (x, y, z, g, w))| {
                let s = field.step([*x, *y, *z]);
                *x += s.dx;
                *y += s.dy;
                *z += s.dz;
                *g += s.strain;
                *w += s.work;
                (s.drawn_by != u32::MAX).then_some((k, s.drawn_by))
            })
            .collect();
    };
    let steps: Vec<Step> = (0..mk.len())
        .into_par_iter()
        .map(|k| {
            let mut s = field.step([mk.x[k], mk.y[k], mk.z[k]]);
            extra(mk, k, &mut s);
            s
        })
        .collect();
    (
        mk.x.par_iter_mut(),
        mk.y.par_iter_mut(),
        mk.z.par_iter_mut(),
        mk.strain.par_iter_mut(),
        mk.work.par_iter_mut(),
        &steps,
    )
        .into_par_iter()
        .for_each(|(x, y, z, g, w, s)| {
            *x += s.dx;
            *y += s.dy;
            *z += s.dz;
            *g += s.strain;
            *w += s.work;
        });
    mk.percolated
        .par_iter_mut()
        .zip(&steps)
        .for_each(|(l, s)| *l += s.perc);
    steps
        .iter()
        .enumerate()
        .filter(|(_, s)| s.drawn_by != u32::MAX)
        .map(|(k, s)| (k, s.drawn_by))
        .collect()
}

/// Moves the marker rows `rows` (ascending, distinct) once: [`move_markers`] restricted to
/// the markers that a drawing IMZ can reach (the rows of the active cells of [`Bins`]).
/// Every other marker would take a zero step, so the result is [`move_markers`]'s bit for
/// bit. Parallel over chunks of rows, each writing its own window of the columns.
///
/// `fields[L]` is the motion of cadence level L (`engine::cadence`). Without a cadence
/// every row steps by `fields[0]`; with `(cadence, u)` each row steps by its own level's
/// field and then takes its next level for update `u`.
pub fn move_rows(
    mk: &mut Markers,
    fields: &[MotionField],
    extra: Option<StepHook>,
    rows: &[u32],
    cadence: Option<(&Cadence, u64)>,
) -> Vec<(usize, u32)> {
    if rows.is_empty() {
        return Vec::new();
    }
    debug_assert!(rows.windows(2).all(|w| w[0] < w[1]));
    let chunk = (rows.len() / (16 * rayon::current_num_threads())).max(256);
    let chunks: Vec<&[u32]> = rows.chunks(chunk).collect();
    let spans: Vec<(usize, usize)> = chunks
        .iter()
        .map(|c| (c[0] as usize, c[c.len() - 1] as usize + 1))
        .collect();
    let steps: Vec<Step> = match extra {
        Some(extra) => rows
            .par_iter()
            .map(|&k| {
                let k = k as usize;
                let mut s = fields[0].step([mk.x[k], mk.y[k], mk.z[k]]);
                extra(mk, k, &mut s);
                s
            })
            .collect(),
        None => Vec::new(),
    };
    let (hooked, steps) = (extra.is_some(), &steps[..]);
    let firsts: Vec<usize> = (0..chunks.len()).map(|c| c * chunk).collect();
    let drawn: Vec<Vec<(usize, u32)>> = (
        (chunks, spans.clone(), firsts),
        windows(&mut mk.x, &spans),
        windows(&mut mk.y, &spans),
        windows(&mut mk.z, &spans),
        windows(&mut mk.strain, &spans),
        windows(&mut mk.work, &spans),
        windows(&mut mk.percolated, &spans),
        windows(&mut mk.level, &spans),
    )
        .into_par_iter()
        .map(|((rows, (lo, _), first), x, y, z, g, w, l, lv)| {
            let mut drawn = Vec::new();
            for (n, &k) in rows.iter().enumerate() {
                let i = k as usize - lo;
                let s = if hooked {
                    steps[first + n]
                } else {
                    let level = if cadence.is_some() { lv[i] } else { 0 };
                    fields[level as usize].step([x[i], y[i], z[i]])
                };
                x[i] += s.dx;
                y[i] += s.dy;
                z[i] += s.dz;
                g[i] += s.strain;
                w[i] += s.work;
                if hooked {
                    l[i] += s.perc;
                }
                if let Some((c, u)) = cadence {
                    let moved = (s.dx * s.dx + s.dy * s.dy + s.dz * s.dz).sqrt();
                    lv[i] = c.next_level(lv[i], moved, u);
                }
                if s.drawn_by != u32::MAX {
                    drawn.push((k as usize, s.drawn_by));
                }
            }
            drawn
        })
        .collect();
    drawn.concat()
}

/// Disjoint windows `col[lo..hi]` for ascending, non-overlapping spans.
fn windows<'a, T>(mut col: &'a mut [T], spans: &[(usize, usize)]) -> Vec<&'a mut [T]> {
    let mut out = Vec::with_capacity(spans.len());
    let mut at = 0;
    for &(lo, hi) in spans {
        let (_, rest) = std::mem::take(&mut col).split_at_mut(lo - at);
        let (w, rest) = rest.split_at_mut(hi - lo);
        out.push(w);
        col = rest;
        at = hi;
    }
    out
}

/// Column and row ranges of grid cells, ((i0, i1), (j0, j1)), inclusive.
type SpanIj = ((usize, usize), (usize, usize));

/// The moving markers binned by plan cell, so a marker update visits only the markers a
/// drawing IMZ can reach and stagnant ones cost nothing (DESIGN §9).
///
/// The cells are those of the [`ImzGrid`] of the step (same origin, size and rounding, see
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
    /// `cell` (the arguments of [`ImzGrid::build`]).
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

    /// Cell of a plan point, computed as [`ImzGrid::at`] does; `n_cells()` outside.
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

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// ∫ Δz dA over the disk equals −Δv for both profiles (volume continuity), to the
    /// quadrature error of 20 000 rings (< 1e-6 relative).
    #[test]
    fn vertical_profiles_integrate_to_the_void() {
        for &(r, w) in &[(1.0, 2.0), (3.0, 1.0), (5.0, 0.5)] {
            let dv = 2.0;
            let n = 20_000;
            let mut vol = 0.0;
            for k in 0..n {
                let a = (k as f64 + 0.5) * r / n as f64;
                vol += vertical(dv, r, w, a) * 2.0 * PI * a * (r / n as f64);
            }
            assert!((vol + dv).abs() < 1e-6 * dv, "r={r} w={w}: {vol}");
        }
    }

    /// F(a) is the quadrature of the vertical profile, for the cone and the frustum.
    #[test]
    fn flux_inside_is_the_profile_integral() {
        for &(r, w) in &[(1.0, 2.0), (3.0, 1.0), (5.0, 0.5)] {
            let n = 20_000;
            let mut vol = 0.0;
            for k in 0..n {
                let a = (k as f64 + 0.5) * r / n as f64;
                vol -= vertical(1.0, r, w, a) * 2.0 * PI * a * (r / n as f64);
                if (k + 1) % 2000 == 0 {
                    let f = flux_inside(r, w, (k + 1) as f64 * r / n as f64);
                    assert!(
                        (f - vol).abs() < 1e-6,
                        "r {r} w {w} a {}: {f} vs {vol}",
                        (k + 1) as f64 * r / n as f64
                    );
                }
            }
        }
        assert_eq!(flux_inside(2.0, 1.0, 0.0), 0.0);
        assert_eq!(flux_inside(2.0, 1.0, 3.0), flux_inside(2.0, 1.0, 2.0));
        // And its inverse, in the plug, the annulus and the cone.
        for &(r, w) in &[(1.0, 2.0), (3.0, 1.0), (5.0, 0.5)] {
            for k in 0..=20 {
                let a = r * k as f64 / 20.0;
                // At the rim F is flat (1 − F ∝ (r − a)²), so a is found to √ε there.
                let back = radius_at_share(r, w, flux_inside(r, w, a));
                assert!((back - a).abs() < 1e-6 * r, "r {r} w {w}: {a} → {back}");
            }
        }
    }

    #[test]
    fn radial_move_is_the_ring_dilation() {
        // The ring 2 → 2.01 m at n0 0.30 dilates to n1 0.45: it takes ε ΔA of plan area from
        // the interior (ε = Δn/(1 − n1)). At R_old the interior has lost the profile's share
        // F(R_old) of it, so the peak is the ring's thickness gain ΔR ε F(R_old) to first
        // order in ΔR.
        let (r0, r1, w, eps) = (2.0, 2.01, 0.5, 0.15 / 0.55);
        let take = eps * PI * (r1 * r1 - r0 * r0);
        let peak = -radial(r0, r1, r1, w, take, r0);
        let f = flux_inside(r1, w, r0);
        assert!(f > 0.99 && f < 1.0, "{f}");
        assert!((peak / ((r1 - r0) * eps * f) - 1.0).abs() < 0.01, "{peak}");
        // Streamtube by streamtube, the area inside a loses take × F(a): 2π a u(a).
        for a in [0.1, 0.7, 1.5, 1.9] {
            let u = radial(r0, r1, r1, w, take, a);
            assert!((2.0 * PI * a * u + take * flux_inside(r1, w, a)).abs() < 1e-12);
        }
        // Zero at the axis and at R_new; nothing without absorbed void, nor in a new disk.
        assert_eq!(radial(r0, r1, r1, w, take, 0.0), 0.0);
        assert!(radial(r0, r1, r1, w, take, r1).abs() < 1e-12);
        assert_eq!(radial(r0, r1, r1, w, 0.0, r0), 0.0);
        for k in 1..=10 {
            let a = 0.1 * k as f64;
            assert_eq!(radial(0.0, 1.0, 1.0, w, 0.5, a), 0.0);
            // A squeeze larger than the interior takes at most half a marker's radius.
            assert!(a + radial(0.5, 1.0, 1.0, w, 10.0, a) >= 0.5 * a - 1e-12);
        }
    }

    #[test]
    fn lattice_ranges() {
        let l = Lattice {
            origin: [0.0; 3],
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
    /// sites' masses and the blocks' lattice masses both add up to the box's in-situ mass.
    #[test]
    fn site_masses_tile_the_grid() {
        let b = crate::model::synthetic::UniformBox::castro_isolated();
        let bm = b.scene().blocks;
        let l = Lattice::new(&bm, 0.0175);
        let unit = l.unit_masses(&bm);
        let sites: f64 = (0..l.len())
            .map(|id| l.site_mass(&bm, id, unit[bm.locate(l.pos(id)).unwrap()]))
            .sum();
        let blocks: f64 = l.block_masses(&bm, &unit).iter().sum();
        let total = b.extent.iter().product::<f64>() * b.density * (1.0 - b.n0);
        assert!((sites / total - 1.0).abs() < 1e-9, "{sites} {total}");
        assert!((blocks / total - 1.0).abs() < 1e-9, "{blocks} {total}");
        assert_eq!(l.site_mass(&bm, l.id(3, 4, 5), unit[0]), unit[0]);
    }

    /// `next_site_a2` is the brute-force minimum over every site of the layer, for axes on
    /// and off the lattice, radii from zero to past the edge, and sites exactly on a circle.
    #[test]
    fn next_site_is_the_nearest_site_beyond_the_radius() {
        let l = Lattice {
            origin: [-3.0, 2.0, 0.0],
            s: 0.5,
            n: [24, 20, 4],
        };
        let brute = |x: f64, y: f64, r: f64| {
            let mut best = f64::INFINITY;
            for j in 0..l.n[1] {
                for i in 0..l.n[0] {
                    let p = l.pos(l.id(i, j, 1));
                    let a2 = (p[0] - x).powi(2) + (p[1] - y).powi(2);
                    if a2 > r * r && a2 < best {
                        best = a2;
                    }
                }
            }
            best
        };
        let mut checked = 0;
        for &(x, y) in &[
            (3.0, 7.0),
            (2.75, 6.75),
            (-2.9, 2.1),
            (8.9, 11.9),
            (3.1, 4.37),
        ] {
            for k in 0..60 {
                let r = 0.137 * k as f64;
                let got = l.next_site_a2(x, y, 0.5, 1.0, r);
                assert_eq!(
                    got.to_bits(),
                    brute(x, y, r).to_bits(),
                    "axis ({x}, {y}), r {r}"
                );
                checked += 1;
            }
            // Exactly on a circle of sites: the next one is strictly beyond.
            let on = l.pos(l.id(5, 5, 1));
            let r = ((on[0] - x).powi(2) + (on[1] - y).powi(2)).sqrt();
            assert_eq!(l.next_site_a2(x, y, 0.5, 1.0, r), brute(x, y, r));
        }
        assert_eq!(checked, 300);
        // No layer in the height range: nothing to reach.
        assert_eq!(l.next_site_a2(3.0, 7.0, 10.0, 11.0, 1.0), f64::INFINITY);
    }

    /// Superposition: two IMZs on the same axis, each passing half the void, move every
    /// marker as one IMZ passing all of it, transfers at the disk bases included (each
    /// IMZ's own move there is half the summed one, so deciding a crossing on it would miss
    /// the transfers of markers that only the sum carries across). The disks narrow to the
    /// base (radii 1, 2, 3, 3.5 m, h = 1 m, w = 0.8 m), expand between updates, and the
    /// ring's dilation is lopsided (a shape mode), so every move is exercised. The void is
    /// small enough that no move reaches the caps on the radial and lateral moves (which
    /// are not linear).
    #[test]
    fn co_located_imzs_move_markers_as_one_imz_with_their_summed_void() {
        let geom = ImzGeom {
            x: 0.0,
            y: 0.0,
            z0: 0.0,
            h: 1.0,
            radius: vec![1.0, 2.0, 3.0, 3.5],
        };
        let disks = |scale: f64| -> Vec<DiskMotion> {
            let mut shape = [0.0; 2 * super::super::imz::SHAPE_MODES];
            shape[0] = 0.4;
            geom.radius
                .iter()
                .enumerate()
                .map(|(i, &r)| DiskMotion {
                    r,
                    r_old: 0.9 * r,
                    dv: scale * (0.2 - 0.03 * i as f64),
                    dv_out: scale * (0.17 - 0.03 * i as f64),
                    w: 0.8,
                    area_frac: 1.0,
                    flow_frac: 1.0,
                    shape,
                    ..Default::default()
                })
                .collect::<Vec<_>>()
        };
        let prepared = |mut m: Vec<DiskMotion>| {
            prepare(&mut m, geom.h);
            m
        };
        let (whole, half) = (prepared(disks(1.0)), prepared(disks(0.5)));
        let one_geom = vec![geom.clone()];
        let two_geoms = vec![geom.clone(), geom.clone()];
        let one_grid = ImzGrid::build(&one_geom, &[0], [-5.0, -5.0], [10.0, 10.0], 1.0);
        let two_grid = ImzGrid::build(&two_geoms, &[0, 1], [-5.0, -5.0], [10.0, 10.0], 1.0);
        let one_motion: Vec<&[DiskMotion]> = vec![&whole[..]];
        let two_motion: Vec<&[DiskMotion]> = vec![&half[..], &half[..]];
        let one = MotionField {
            geoms: &one_geom,
            motion: &one_motion,
            grid: &one_grid,
            ground: None,
            reach: WallReach::default(),
        };
        let two = MotionField {
            geoms: &two_geoms,
            motion: &two_motion,
            grid: &two_grid,
            ground: None,
            reach: WallReach::default(),
        };
        let mut crossed = 0;
        for k in 0..400 {
            // Just above the bases of disks 1–3, where the moves carry markers across.
            let z = (1 + k % 3) as f64 + 0.0001 * (k / 3) as f64;
            let (a, t) = (0.0087 * k as f64, 0.37 * k as f64);
            let p = [a * t.cos(), a * t.sin(), z];
            let (s1, s2) = (one.step(p), two.step(p));
            // Each IMZ's transfer is taken at the radius its own radial move reached, so
            // the halves' transfers are taken at a + Δa/2, not a + Δa: a difference of
            // second order, Δa · dΔa′/da, under 1 mm here. Missing a transfer (a crossing
            // decided on one IMZ's own move) is off by the whole transfer, 0.1–0.5 m.
            let close = |x: f64, y: f64| (x - y).abs() <= 1e-3;
            assert!(
                close(s1.dx, s2.dx) && close(s1.dy, s2.dy) && close(s1.dz, s2.dz),
                "at {p:?}: {s1:?} vs {s2:?}"
            );
            let base = z.floor();
            if z >= 1.0 && z + s1.dz < base && s1.dz != 0.0 {
                crossed += 1;
            }
        }
        assert!(
            crossed > 20,
            "too few markers cross a disk base to test: {crossed}"
        );
    }

    /// [`WallReach`] never skips an image that holds the marker: over a grid of points in the
    /// Castro box and three IMZs of different widths and bases, wherever the mirror of a
    /// point across a wall lies in some IMZ's disk, the point is within the wall's reach
    /// at its height; and the reach does skip most of the points (it is a filter).
    #[test]
    fn wall_reach_never_skips_an_image_that_holds_the_marker() {
        let scene = crate::model::synthetic::UniformBox::castro_isolated().scene();
        let bm = &scene.blocks;
        let (lo, hi) = (bm.origin, bm.max_corner());
        let imz = |x: f64, y: f64, z0: f64, r: &[f64]| ImzGeom {
            x,
            y,
            z0,
            h: 0.1,
            radius: r.to_vec(),
        };
        let geoms = vec![
            imz(-0.45, 0.0, lo[2], &[0.06, 0.12, 0.2, 0.3, 0.4]),
            imz(0.3, 0.4, lo[2] + 0.05, &[0.06, 0.1, 0.15]),
            imz(0.0, -0.2, lo[2], &[0.06, 0.08]),
        ];
        let reach = WallReach::new(&geoms, bm);
        let (mut held, mut skipped, mut points) = (0, 0, 0);
        for i in 0..48 {
            for j in 0..48 {
                for k in 0..12 {
                    let p = [
                        lo[0] + (i as f64 + 0.5) * 0.025,
                        lo[1] + (j as f64 + 0.5) * 0.025,
                        lo[2] + (k as f64 + 0.5) * 0.05,
                    ];
                    let r = reach.at(p[2]);
                    for (w, (a, wall)) in [(0, lo[0]), (0, hi[0]), (1, lo[1]), (1, hi[1])]
                        .into_iter()
                        .enumerate()
                    {
                        let mut q = p;
                        q[a] = 2.0 * wall - p[a];
                        let near = (p[a] - wall).abs() <= r[w];
                        if geoms.iter().any(|g| g.disk_at(q).is_some()) {
                            held += 1;
                            assert!(near, "{p:?} wall {w}: reach {}", r[w]);
                        }
                        skipped += usize::from(!near);
                        points += 1;
                    }
                }
            }
        }
        assert!(held > 100, "{held}");
        assert!(skipped > points / 2, "{skipped} of {points}");
    }

    /// The model's walls mirror the IMZs (method of images): an IMZ whose disk passes a wall
    /// moves nothing through it, and the void it passes moves its whole volume of ground
    /// inside the model. The Castro box (1.2 m square, walls at x, y = ±0.6 m) with one IMZ
    /// 0.1 m from the wall x = −0.6 m, disks widened from 0.28 m to 0.3 m (cut by the wall
    /// over a fifth of their area, so their rings push the ground in on both sides of it)
    /// that take in 0.01 m³ of void and pass 0.009 m³ up, w = 0.05 m. At mid-height the
    /// void is 0.0095 m³; the flux is summed over a 2 mm grid inside the model, whose error
    /// on a 0.3 m disk is under 0.5%. Without the images the wall takes a radial push and
    /// the model holds four fifths of the flux. The same IMZ moved into the corner of the
    /// walls x, y = −0.6 m (0.1 m from both): without the corner's double image the ground
    /// at the walls moves through them (2 mm in x per 40 mm down).
    #[test]
    fn walls_mirror_the_imzs() {
        let scene = crate::model::synthetic::UniformBox::castro_isolated().scene();
        let bm = &scene.blocks;
        let [wx, wy, _] = bm.origin;
        let mut motion: Vec<DiskMotion> = (0..4)
            .map(|_| DiskMotion {
                r: 0.3,
                r_old: 0.28,
                dv: 0.01,
                dv_out: 0.009,
                w: 0.05,
                area_frac: 1.0,
                flow_frac: 1.0,
                ..Default::default()
            })
            .collect();
        prepare(&mut motion, 0.1);
        // A disk cut by the wall x = wx, then one in the corner of x = wx and y = wy.
        for (x, y) in [(wx + 0.1, 0.0), (wx + 0.1, wy + 0.1)] {
            let geom = ImzGeom {
                x,
                y,
                z0: bm.origin[2],
                h: 0.1,
                radius: vec![0.3; 4],
            };
            let geoms = vec![geom.clone()];
            let grid = ImzGrid::build(&geoms, &[0], [wx, wy], [1.2, 1.2], 0.05);
            let motion_ref: Vec<&[DiskMotion]> = vec![&motion[..]];
            let field = MotionField {
                geoms: &geoms,
                motion: &motion_ref,
                grid: &grid,
                ground: Some((bm, 1)),
                reach: WallReach::new(&geoms, bm),
            };
            let z = geom.z0 + 0.25;
            // Along each wall the disk reaches (1 nm inside it) nothing moves through it,
            // to the field's change over 2 nm.
            for k in 0..50 {
                let t = 0.011 * k as f64 - 0.27;
                let st = field.step([wx + 1e-9, y + t, z]);
                assert!(st.dx.abs() < 1e-6 * st.dz.abs(), "({x}, {y}) t {t}: {st:?}");
                if y < wy + 0.3 && x + t > wx {
                    let st = field.step([x + t, wy + 1e-9, z]);
                    assert!(st.dy.abs() < 1e-6 * st.dz.abs(), "({x}, {y}) t {t}: {st:?}");
                }
            }
            // The void moves its whole volume of ground inside the model.
            let cell = 0.002;
            let mut volume = 0.0;
            for i in 0..200 {
                for j in 0..300 {
                    let p = [
                        wx + (i as f64 + 0.5) * cell,
                        y - 0.3 + (j as f64 + 0.5) * cell,
                        z,
                    ];
                    if p[1] > wy {
                        volume -= field.step(p).dz * cell * cell;
                    }
                }
            }
            assert!(
                (volume / 0.0095 - 1.0).abs() < 0.005,
                "({x}, {y}): {volume} m³ of 0.0095"
            );
        }
    }
}
