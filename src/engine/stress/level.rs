//! One level solved: its cave slice, IMZ disks, bins and groups, the stress field with its
//! force balance, and the pillars between bins (summary §5.2–5.3; overview and module map in
//! `stress`).
//!
//! # 4. Several bins: superposition, yield cap, arching, force balance
//! A point in the stagnant ground sees every bin whose elastic zone reaches it (distance
//! r = a + the distance to the nearest disk edge of the bin, exact for one disk):
//! - horizontal (confining) stress σ_h = the least σ_r of those bins (the nearest IMZ
//!   de-confines);
//! - vertical stress demand = the tributary loads add: p0 + Σ elastic excesses, or, inside a
//!   plastic zone, the yield stress at σ_h plus the elastic excesses of the other bins;
//! - **stress:strength ratio** = (σ_v + c cot φ) / (Kp (σ_h + c cot φ)): the demand against
//!   the Mohr–Coulomb strength at the local confinement (1 = at yield). We use the strength
//!   at the local confinement, not the unconfined strength 2c cos φ/(1 − sin φ), because
//!   caved rock is cohesionless or nearly so: its unconfined strength is zero and it is the
//!   confinement, lost next to an IMZ, that decides whether the stagnant ground yields;
//! - the stagnant ground carries at most its yield stress; the excess above yield **arches
//!   outside the draw area** (summary §5.2): together with any other imbalance it goes
//!   first to the ground outside every elastic zone (`Zone::Far`), then to the elastic zones,
//!   each cell taking a share of its headroom to yield, so arching never pushes receiving
//!   ground past yield while other ground has room (see [`balance`]); only what no ground can
//!   take is spread evenly, and that ground then exceeds yield. The cave slice's average
//!   vertical stress is therefore exactly the Janssen average σ̄ (summary §5.3: "the average
//!   cave-scale vertical stresses … remain constant in each cave slice").
//!
//! # 5. Interactive draw flags
//! A **pillar** is the stagnant ground on the segment between the nearest disk edges of two
//! bins of one group (elastic zones overlapping) that crosses no third bin. A pillar yields
//! when its stress:strength ratio is ≥ 1 along its whole length (no elastic core left to
//! carry load: the stagnant ground between the IMZs can flow, Heslop and Laubscher's
//! interactive draw). A level is flagged when any of its pillars yields; its reported ratio
//! is the largest pillar's minimum ratio. The ratio on the pillar is sampled at
//! [`PILLAR_SAMPLES`] points, and "≥ 1" allows 1e-9 for rounding (a fully plastic pillar is
//! at exactly 1).

use std::f64::consts::PI;

use super::shaft::{c_cot, passive_coefficient, stress_strength_ratio, Shaft, ShaftZone};
use super::{StressParams, Zone, GRAVITY};
use crate::engine::imz::ImzGeom;
use crate::model::BlockModel;

/// Points sampled along each pillar between two bins.
pub const PILLAR_SAMPLES: usize = 64;

/// Points per circle when a cluster's union outline is traced (arc error ~ (2π/N)² ≈ 8e-5).
const ARC_SAMPLES: usize = 720;

/// Rounding allowance of the yield test (a fully plastic pillar is at exactly 1).
const YIELD_TOL: f64 = 1e-9;

/// Area and perimeter of a union of disks (x, y, r): exact for one disk; for several, the
/// exposed arcs traced at `ARC_SAMPLES` points per circle, area by Green's theorem.
pub fn union_area_perimeter(disks: &[(f64, f64, f64)]) -> (f64, f64) {
    if let [(_, _, r)] = disks {
        return (PI * r * r, 2.0 * PI * r);
    }
    let Some(&(x0, y0, _)) = disks.first() else {
        return (0.0, 0.0);
    };
    let dt = 2.0 * PI / ARC_SAMPLES as f64;
    let (mut area, mut perim) = (0.0, 0.0);
    for (m, &(cx, cy, r)) in disks.iter().enumerate() {
        // Only disks within r + their radius can cover a point of this circle (the margin
        // keeps the filter exact under rounding); at mine scale a cluster has hundreds.
        let near: Vec<(f64, f64, f64)> = disks
            .iter()
            .enumerate()
            .filter(|&(n, &(ox, oy, or))| {
                n != m && (ox - cx).powi(2) + (oy - cy).powi(2) <= (1.0 + 1e-9) * (r + or).powi(2)
            })
            .map(|(_, &d)| d)
            .collect();
        let (cx, cy) = (cx - x0, cy - y0);
        for s in 0..ARC_SAMPLES {
            let t = (s as f64 + 0.5) * dt;
            let (px, py) = (cx + r * t.cos(), cy + r * t.sin());
            let covered = near
                .iter()
                .any(|&(ox, oy, or)| (px - (ox - x0)).powi(2) + (py - (oy - y0)).powi(2) < or * or);
            if !covered {
                perim += r * dt;
                area += 0.5 * (r * r + r * (cx * t.cos() + cy * t.sin())) * dt;
            }
        }
    }
    (area, perim)
}

/// One IMZ disk at a level.
#[derive(Debug, Clone, Copy)]
pub(super) struct Disk {
    pub(super) imz: usize,
    pub(super) x: f64,
    pub(super) y: f64,
    pub(super) r: f64,
}

/// One bin slice at a level.
#[derive(Debug, Clone)]
pub(super) struct Bin {
    /// Indices into the level's disks.
    pub(super) members: Vec<usize>,
    pub(super) area: f64,
    pub(super) perimeter: f64,
    /// Unit weight of the mobilised rock, kN/m³, and its φ.
    pub(super) gamma: f64,
    pub(super) phi: f64,
    /// Bin stress σ_bin, kPa.
    pub(super) sigma: f64,
    shaft: Shaft,
    /// Bounding box of the disks (x0, x1, y0, y1).
    bbox: [f64; 4],
}

/// The cave slice of one level.
#[derive(Debug, Clone, Default)]
pub(super) struct CaveSlice {
    /// Flowable raster (nx × ny).
    pub(super) flow: Vec<bool>,
    pub(super) area: f64,
    pub(super) perimeter: f64,
    pub(super) gamma: f64,
    pub(super) phi: f64,
}

/// Everything known about one level before the field is evaluated.
#[derive(Debug, Clone, Default)]
pub(super) struct Level {
    pub(super) z: f64,
    pub(super) cave: CaveSlice,
    pub(super) sigma: f64,
    pub(super) disks: Vec<Disk>,
    pub(super) bins: Vec<Bin>,
    /// Group of each bin.
    group: Vec<usize>,
    pub(super) groups: usize,
    /// Force balance (see [`balance`]): share of its headroom (or, when the field carries
    /// too much, of its stress) each zone receives, by `Zone as usize`; whether the shares
    /// apply to headroom; stress added evenly to all stagnant ground once every zone is at
    /// yield; and the arched force over the slice area (reported), kPa.
    fill: [f64; 5],
    on_headroom: bool,
    uniform: f64,
    pub(super) arched: f64,
    /// While the balance is worked out: `finish` returns the stress before the fill, with
    /// the headroom to yield in `ratio`.
    raw: bool,
}

/// The stress grid.
#[derive(Debug, Clone, Copy)]
pub(super) struct Grid {
    pub(super) origin: [f64; 3],
    pub(super) cell: f64,
    pub(super) n: [usize; 3],
}

impl Grid {
    pub(super) fn centre(&self, a: usize, i: usize) -> f64 {
        self.origin[a] + (i as f64 + 0.5) * self.cell
    }
    /// Index range of cell centres within [lo, hi] along axis a.
    fn range(&self, a: usize, lo: f64, hi: f64) -> Option<(usize, usize)> {
        let i0 = ((lo - self.origin[a]) / self.cell - 0.5).ceil().max(0.0);
        let i1 = ((hi - self.origin[a]) / self.cell - 0.5).floor();
        if !(i1 >= i0) || i0 >= self.n[a] as f64 {
            return None;
        }
        Some((i0 as usize, (i1 as usize).min(self.n[a] - 1)))
    }
}

/// Stress at one point of a level, accumulated over the bins that reach it.
#[derive(Debug, Clone, Copy)]
struct Acc {
    imz: Option<usize>,
    plastic: bool,
    elastic: bool,
    sr_min: f64,
    excess: f64,
}

impl Default for Acc {
    fn default() -> Self {
        Acc {
            imz: None,
            plastic: false,
            elastic: false,
            sr_min: f64::INFINITY,
            excess: 0.0,
        }
    }
}

/// Stress at a point: zone, demand σ_v, carried σ_v, σ_h, ratio.
#[derive(Debug, Clone, Copy)]
pub(super) struct PointStress {
    pub(super) zone: Zone,
    pub(super) sigma_v: f64,
    pub(super) sigma_h: f64,
    pub(super) ratio: f64,
}

impl Level {
    /// A level at elevation `z` with its cave slice and IMZ disks, not yet solved.
    pub(super) fn new(z: f64, cave: CaveSlice, disks: Vec<Disk>) -> Level {
        Level {
            z,
            cave,
            disks,
            ..Default::default()
        }
    }

    /// Adds bin `b`'s effect at (x, y).
    fn add(&self, acc: &mut Acc, b: usize, x: f64, y: f64) {
        let bin = &self.bins[b];
        let mut d = f64::INFINITY;
        for &m in &bin.members {
            let k = &self.disks[m];
            d = d.min(((x - k.x).powi(2) + (y - k.y).powi(2)).sqrt() - k.r);
        }
        if d <= 0.0 {
            acc.imz = Some(b);
            return;
        }
        let (zone, sr, sv) = bin.shaft.at(bin.shaft.a + d);
        match zone {
            ShaftZone::Plastic => {
                acc.plastic = true;
                acc.sr_min = acc.sr_min.min(sr);
            }
            ShaftZone::Elastic => {
                acc.elastic = true;
                acc.sr_min = acc.sr_min.min(sr);
                acc.excess += sv - self.sigma;
            }
            ShaftZone::Outside => {}
        }
    }

    /// Stress at a point from its accumulated bins, without and with the receivers' share.
    fn finish(&self, acc: &Acc, params: &StressParams) -> PointStress {
        if let Some(b) = acc.imz {
            let s = self.bins[b].sigma;
            return PointStress {
                zone: Zone::Imz,
                sigma_v: s,
                sigma_h: params.bin_k * s,
                ratio: f64::NAN,
            };
        }
        let p0 = self.sigma;
        let kp = passive_coefficient(self.cave.phi);
        let cc = c_cot(params.cohesion, self.cave.phi);
        let sh = acc.sr_min.min(p0);
        let yield_v = kp * (sh + cc) - cc;
        let (zone, mut demand) = if acc.plastic {
            (Zone::Plastic, yield_v + acc.excess)
        } else if acc.elastic {
            (Zone::Elastic, p0 + acc.excess)
        } else {
            (Zone::Far, p0)
        };
        let mut carried = demand.min(yield_v);
        let headroom = (yield_v - carried).max(0.0);
        let base = PointStress {
            zone,
            sigma_v: carried,
            sigma_h: sh,
            ratio: headroom,
        };
        let share = self.fill[zone as usize] * if self.on_headroom { headroom } else { carried };
        demand += share + self.uniform;
        carried += share + self.uniform;
        if self.raw {
            return base;
        }
        PointStress {
            zone,
            sigma_v: carried,
            sigma_h: sh,
            ratio: stress_strength_ratio(demand, sh, kp, cc),
        }
    }

    /// Stress at (x, y) from every bin.
    pub(super) fn point(&self, x: f64, y: f64, params: &StressParams) -> PointStress {
        self.point_among(0..self.bins.len(), x, y, params)
    }

    /// Stress at (x, y) from the bins `which` (in increasing order; bins that cannot reach
    /// the point may be left out: they add nothing).
    fn point_among(
        &self,
        which: impl Iterator<Item = usize>,
        x: f64,
        y: f64,
        params: &StressParams,
    ) -> PointStress {
        let mut acc = Acc::default();
        for b in which {
            if !self.bins[b].reaches(x, y, x, y) {
                continue;
            }
            self.add(&mut acc, b, x, y);
            if acc.imz.is_some() {
                break;
            }
        }
        self.finish(&acc, params)
    }
}

/// The cave slice at elevation z on the grid.
pub(super) fn cave_slice(bm: &BlockModel, period: i64, grid: &Grid, z: f64) -> CaveSlice {
    let [nx, ny, _] = grid.n;
    let mut flow = vec![false; nx * ny];
    let (mut gamma, mut phi, mut count) = (0.0, 0.0, 0usize);
    for j in 0..ny {
        for i in 0..nx {
            let p = [grid.centre(0, i), grid.centre(1, j), z];
            if let Some(b) = bm.locate(p).filter(|&b| bm.flowable(b, period)) {
                flow[i + nx * j] = true;
                gamma += bm.density[b] * (1.0 - bm.n0[b]) * GRAVITY;
                phi += bm.friction[b];
                count += 1;
            }
        }
    }
    let mut edges = 0usize;
    for j in 0..ny {
        for i in 0..nx {
            if !flow[i + nx * j] {
                continue;
            }
            let open = |di: i64, dj: i64| {
                let (a, b) = (i as i64 + di, j as i64 + dj);
                !(a >= 0
                    && b >= 0
                    && (a as usize) < nx
                    && (b as usize) < ny
                    && flow[a as usize + nx * b as usize])
            };
            edges += [(1, 0), (-1, 0), (0, 1), (0, -1)]
                .into_iter()
                .filter(|&(a, b)| open(a, b))
                .count();
        }
    }
    let c = count.max(1) as f64;
    CaveSlice {
        flow,
        area: count as f64 * grid.cell * grid.cell,
        perimeter: edges as f64 * grid.cell,
        gamma: gamma / c,
        phi: if count > 0 { phi / c } else { 0.0 },
    }
}

/// IMZ disks (radius > 0) at elevation z.
pub(super) fn disks_at(geoms: &[ImzGeom], z: f64) -> Vec<Disk> {
    geoms
        .iter()
        .enumerate()
        .filter_map(|(imz, g)| {
            let t = (z - g.z0) / g.h;
            if !(t >= 0.0) {
                return None;
            }
            let r = *g.radius.get(t as usize)?;
            (r > 0.0).then_some(Disk {
                imz,
                x: g.x,
                y: g.y,
                r,
            })
        })
        .collect()
}

/// Connected components of `n` items under `linked` (union-find); component of each item,
/// numbered in order of first appearance, and the count.
fn components(n: usize, linked: impl Fn(usize, usize) -> bool) -> (Vec<usize>, usize) {
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    for a in 0..n {
        for b in a + 1..n {
            if linked(a, b) {
                let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
                parent[ra.max(rb)] = ra.min(rb);
            }
        }
    }
    let mut id = vec![usize::MAX; n];
    let mut label = Vec::with_capacity(n);
    let mut count = 0;
    for i in 0..n {
        let r = root(&mut parent, i);
        if id[r] == usize::MAX {
            id[r] = count;
            count += 1;
        }
        label.push(id[r]);
    }
    (label, count)
}

/// Bin slices at elevation z: clusters of overlapping disks, with their area, perimeter and
/// mobilised properties (mean over the blocks at the member disks' centres: γ1 = ρ_s (1 − n1)
/// g and φ).
pub(super) fn bins_at(bm: &BlockModel, disks: &[Disk], z: f64) -> Vec<Bin> {
    let (label, count) = components(disks.len(), |a, b| {
        let (p, q) = (&disks[a], &disks[b]);
        (p.x - q.x).powi(2) + (p.y - q.y).powi(2) < (p.r + q.r).powi(2)
    });
    (0..count)
        .map(|c| {
            let members: Vec<usize> = (0..disks.len()).filter(|&m| label[m] == c).collect();
            let circles: Vec<(f64, f64, f64)> = members
                .iter()
                .map(|&m| (disks[m].x, disks[m].y, disks[m].r))
                .collect();
            let (area, perimeter) = union_area_perimeter(&circles);
            let (mut gamma, mut phi, mut n) = (0.0, 0.0, 0.0);
            let mut bbox = [
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
            ];
            for &(x, y, r) in &circles {
                bbox = [
                    bbox[0].min(x - r),
                    bbox[1].max(x + r),
                    bbox[2].min(y - r),
                    bbox[3].max(y + r),
                ];
                if let Some(b) = bm.locate([x, y, z]) {
                    gamma += bm.density[b] * (1.0 - bm.n1[b]) * GRAVITY;
                    phi += bm.friction[b];
                    n += 1.0;
                }
            }
            let n: f64 = if n > 0.0 { n } else { 1.0 };
            Bin {
                members,
                area,
                perimeter,
                gamma: gamma / n,
                phi: phi / n,
                sigma: 0.0,
                shaft: Shaft::new(1.0, 0.0, 0.0, 0.0, 30.0, 0.0),
                bbox,
            }
        })
        .collect()
}

impl Bin {
    /// Whether the box [x0, x1] × [y0, y1] meets this bin's elastic zone's bounding box
    /// (outside it a point has r ≥ R_el and the bin adds nothing).
    fn reaches(&self, x0: f64, y0: f64, x1: f64, y1: f64) -> bool {
        let r = self.shaft.r_el - self.shaft.a;
        !(x1 < self.bbox[0] - r
            || x0 > self.bbox[1] + r
            || y1 < self.bbox[2] - r
            || y0 > self.bbox[3] + r)
    }
}

/// Per-level summary from [`solve_level`].
#[derive(Debug, Clone, Copy)]
pub(super) struct LevelRow {
    pub(super) mean: f64,
    pub(super) pillars: usize,
    pub(super) pillar_ratio: f64,
    pub(super) stagnant_ratio: f64,
    pub(super) flagged: bool,
}

/// Edge-to-edge distance between the closest member disks of two bins, and those disks.
fn closest_disks(l: &Level, a: usize, b: usize) -> (f64, usize, usize) {
    let mut best = (f64::INFINITY, 0, 0);
    for &m in &l.bins[a].members {
        for &n in &l.bins[b].members {
            let (p, q) = (&l.disks[m], &l.disks[n]);
            let d = ((p.x - q.x).powi(2) + (p.y - q.y).powi(2)).sqrt() - p.r - q.r;
            if d < best.0 {
                best = (d, m, n);
            }
        }
    }
    best
}

/// Whether the elastic zones of bins a and b overlap (they are in one group).
fn elastic_overlap(l: &Level, a: usize, b: usize) -> bool {
    let (sa, sb) = (&l.bins[a].shaft, &l.bins[b].shaft);
    closest_disks(l, a, b).0 < (sa.r_el - sa.a) + (sb.r_el - sb.a)
}

/// Shafts, groups, the field on the level's raster with its force balance, and the pillars.
pub(super) fn solve_level(l: &mut Level, grid: &Grid, params: &StressParams) -> LevelRow {
    let mut row = LevelRow {
        mean: f64::NAN,
        pillars: 0,
        pillar_ratio: f64::NAN,
        stagnant_ratio: f64::NAN,
        flagged: false,
    };
    if !(l.cave.area > 0.0 && l.sigma.is_finite()) {
        return row;
    }
    for bin in &mut l.bins {
        let a = 2.0 * bin.area / bin.perimeter;
        bin.shaft = Shaft::new(
            a,
            bin.sigma,
            params.bin_k * bin.sigma,
            l.sigma,
            l.cave.phi,
            params.cohesion,
        );
    }
    let nb = l.bins.len();
    let (group, groups) = components(nb, |a, b| elastic_overlap(l, a, b));
    l.group = group;
    l.groups = groups;

    // The raster: every bin adds itself to the cells its elastic zone reaches.
    let [nx, ny, _] = grid.n;
    let mut accs = vec![Acc::default(); nx * ny];
    for b in 0..nb {
        let bin = &l.bins[b];
        let reach = bin.shaft.r_el - bin.shaft.a;
        let (Some(ir), Some(jr)) = (
            grid.range(0, bin.bbox[0] - reach, bin.bbox[1] + reach),
            grid.range(1, bin.bbox[2] - reach, bin.bbox[3] + reach),
        ) else {
            continue;
        };
        for j in jr.0..=jr.1 {
            for i in ir.0..=ir.1 {
                let c = i + nx * j;
                if l.cave.flow[c] && accs[c].imz.is_none() {
                    l.add(&mut accs[c], b, grid.centre(0, i), grid.centre(1, j));
                }
            }
        }
    }
    let cell_area = grid.cell * grid.cell;
    let field = |l: &Level| -> Vec<Option<PointStress>> {
        (0..nx * ny)
            .map(|c| l.cave.flow[c].then(|| l.finish(&accs[c], params)))
            .collect()
    };
    // Force balance: what the field carries against σ̄ A, the difference arched onto the
    // stagnant ground (outside the draw area first).
    l.fill = [0.0; 5];
    l.uniform = 0.0;
    l.raw = true;
    let raw = field(l);
    l.raw = false;
    let mut carried = 0.0;
    let (mut room, mut load, mut stagnant) = ([0.0; 5], [0.0; 5], 0.0);
    for p in raw.iter().flatten() {
        carried += p.sigma_v * cell_area;
        if p.zone != Zone::Imz {
            // `finish` without the fill reports the headroom in `ratio` (see `raw_point`).
            room[p.zone as usize] += p.ratio * cell_area;
            load[p.zone as usize] += p.sigma_v * cell_area;
            stagnant += cell_area;
        }
    }
    balance(l, l.sigma * l.cave.area - carried, room, load, stagnant);
    let balanced = field(l);
    let (mut total, mut ratio_sum, mut ratio_n) = (0.0, 0.0, 0usize);
    for p in balanced.iter().flatten() {
        total += p.sigma_v * cell_area;
        if matches!(p.zone, Zone::Plastic | Zone::Elastic) && p.ratio.is_finite() {
            ratio_sum += p.ratio;
            ratio_n += 1;
        }
    }
    row.mean = total / l.cave.area;
    if ratio_n > 0 {
        row.stagnant_ratio = ratio_sum / ratio_n as f64;
    }

    // Pillars between bins of one group whose elastic zones overlap.
    for a in 0..nb {
        for b in a + 1..nb {
            if l.group[a] != l.group[b] || !elastic_overlap(l, a, b) {
                continue;
            }
            if let Some(r) = pillar_ratio(l, a, b, params) {
                row.pillars += 1;
                row.pillar_ratio = if row.pillar_ratio.is_nan() {
                    r
                } else {
                    row.pillar_ratio.max(r)
                };
            }
        }
    }
    row.flagged = row.pillar_ratio >= 1.0 - YIELD_TOL;
    row
}

/// Arches the force `missing` (kN; negative when the field carries too much) onto the
/// stagnant ground of level `l`: zone by zone, outside the draw area first (Far, then
/// Elastic, then Plastic), each cell taking a share of its headroom to yield (`room`, kN
/// summed over the zone) so that no receiving ground is pushed past yield while another has
/// room; what no zone can take is spread evenly over all stagnant ground (`stagnant`, m²),
/// which then exceeds yield. An excess is taken back from the zones in the same order, in
/// proportion to what each cell carries (`load`).
fn balance(l: &mut Level, missing: f64, room: [f64; 5], load: [f64; 5], stagnant: f64) {
    l.fill = [0.0; 5];
    l.uniform = 0.0;
    l.arched = missing / l.cave.area;
    let order = [Zone::Far, Zone::Elastic, Zone::Plastic];
    let mut left = missing.abs();
    l.on_headroom = missing > 0.0;
    let pool = if l.on_headroom { room } else { load };
    for z in order {
        let cap = pool[z as usize];
        if left <= 0.0 || !(cap > 0.0) {
            continue;
        }
        let take = left.min(cap);
        l.fill[z as usize] = take / cap * missing.signum();
        left -= take;
    }
    if left > 0.0 && stagnant > 0.0 {
        l.uniform = left / stagnant * missing.signum();
    }
}

/// Least stress:strength ratio along the pillar between bins a and b (None when the segment
/// between their closest disks crosses another bin).
fn pillar_ratio(l: &Level, a: usize, b: usize, params: &StressParams) -> Option<f64> {
    let (gap, m, n) = closest_disks(l, a, b);
    if !(gap > 0.0) {
        return None;
    }
    let (p, q) = (&l.disks[m], &l.disks[n]);
    let dist = ((p.x - q.x).powi(2) + (p.y - q.y).powi(2)).sqrt();
    let (t0, t1) = (p.r / dist, 1.0 - q.r / dist);
    let near: Vec<usize> = (0..l.bins.len())
        .filter(|&k| l.bins[k].reaches(p.x.min(q.x), p.y.min(q.y), p.x.max(q.x), p.y.max(q.y)))
        .collect();
    let mut least = f64::INFINITY;
    for s in 0..PILLAR_SAMPLES {
        let t = t0 + (t1 - t0) * (s as f64 + 0.5) / PILLAR_SAMPLES as f64;
        let (x, y) = (p.x + t * (q.x - p.x), p.y + t * (q.y - p.y));
        let st = l.point_among(near.iter().copied(), x, y, params);
        if st.zone == Zone::Imz {
            return None;
        }
        least = least.min(st.ratio);
    }
    Some(least)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rel(a: f64, b: f64) -> f64 {
        (a - b).abs() / b.abs().max(1e-300)
    }

    /// Two unit disks 1 apart: union area 2π − (2 acos ½ − ½√3) = 5.0548, perimeter
    /// 2 (2π − 2 acos ½) = 8.3776. 720 samples per circle place each arc end within
    /// π/720 rad: 2e-3 relative covers it.
    #[test]
    fn union_of_disks_area_and_perimeter() {
        let lens = 2.0 * (0.5f64).acos() - 0.5 * 3f64.sqrt();
        let (a, p) = union_area_perimeter(&[(100.0, 50.0, 1.0), (101.0, 50.0, 1.0)]);
        assert!(rel(a, 2.0 * PI - lens) < 2e-3, "{a}");
        assert!(rel(p, 2.0 * (2.0 * PI - 2.0 * 0.5f64.acos())) < 2e-3, "{p}");
        let (a, p) = union_area_perimeter(&[(3.0, 4.0, 2.0)]);
        assert_eq!((a, p), (4.0 * PI, 4.0 * PI));
    }

    /// Arching fills the ground outside the draw area first, by headroom, then the elastic
    /// zones; only what no zone can take is spread evenly; an excess is taken back from the
    /// far ground first. Every number is a sum of a few exact terms: 1e-12.
    #[test]
    fn balance_fills_far_ground_first_and_by_headroom() {
        let mut l = Level {
            cave: CaveSlice {
                area: 10.0,
                ..Default::default()
            },
            ..Default::default()
        };
        let (f, e) = (Zone::Far as usize, Zone::Elastic as usize);
        let mut room = [0.0; 5];
        room[f] = 40.0;
        room[e] = 100.0;
        let load = [0.0, 0.0, 0.0, 50.0, 200.0];
        balance(&mut l, 30.0, room, load, 8.0);
        assert!(l.on_headroom && rel(l.fill[f], 0.75) < 1e-12 && l.fill[e] == 0.0);
        assert!(l.uniform == 0.0 && rel(l.arched, 3.0) < 1e-12);
        balance(&mut l, 90.0, room, load, 8.0);
        assert!(rel(l.fill[f], 1.0) < 1e-12 && rel(l.fill[e], 0.5) < 1e-12);
        let mut l2 = l.clone();
        balance(&mut l2, 180.0, room, load, 8.0);
        assert!(rel(l2.fill[e], 1.0) < 1e-12 && rel(l2.uniform, 40.0 / 8.0) < 1e-12);
        let mut l3 = l.clone();
        balance(&mut l3, -100.0, room, load, 8.0);
        assert!(!l3.on_headroom && rel(l3.fill[f], -0.5) < 1e-12 && l3.fill[e] == 0.0);
    }
}
