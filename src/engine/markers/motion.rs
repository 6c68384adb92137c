//! One marker update: the motion field of the drawing IMZs, summed over the IMZs that hold
//! a marker (summary §3.3, §4.2; see the module above for the equations). Each disk's own
//! moves (the profiles, the transfer into a narrower disk, the ring's push and its lateral
//! part) are in `disk_moves`, the walls' images in `walls`; here they are summed, and a
//! cadence window's step is split at the disk bases it reaches.

use rand::Rng;
use smallvec::SmallVec;

use super::super::random::{marker_rng, TRANSFER_STREAM};

use super::super::imz::{DiskMotion, ImzGeom, ImzGrid};
use super::caps::{Cut, LATERAL, PUSH, RIM, SQUEEZE};
use super::disk_moves::{lateral, lateral_cut, radial, radial_cut, transfer};
use super::WallReach;
use crate::model::BlockModel;

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
    /// Run seed: with a marker's id and the disk base it crosses, the key of its choice of
    /// the IMZ whose transfer it takes where several IMZs move it ([`MotionField::step`]).
    pub seed: u64,
    /// Whether the field is a cadence window of several updates (`engine::cadence`): a
    /// step is then split at the disk bases it reaches.
    pub window: bool,
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
    /// The host IMZ's disk bases the percolation crossed inside the IMZ: those of disks
    /// `perc_planes[0]` to `perc_planes[1] − 1` (`engine::fines`).
    pub perc_planes: [u16; 2],
    /// Whether the percolation left the host IMZ, through the underside of disk
    /// `perc_planes[0] − 1` (`engine::fines`).
    pub perc_left: bool,
}

impl MotionField<'_> {
    /// Displacement of a marker at `p` by every drawing IMZ that contains it.
    ///
    /// Vertical and expansion moves superpose linearly (summary §4.2). The transfer into a
    /// narrower disk below (Δa′, Δz′) is not linear: it maps the whole radius a_m of a
    /// marker that crosses a disk base to a point of that IMZ's disk below. Where several
    /// IMZs move the marker, it takes one IMZ's transfer, in full, drawn with that IMZ's
    /// share of its vertical move, |Δz_d| / Σ|Δz| (drawn from the marker's own random
    /// stream for that base, `random::marker_rng`): alone an IMZ's transfer
    /// applies in full (the summary's rule), and over many crossings each IMZ transfers its
    /// own share of the flux, which is what superposition means for a map.
    ///
    /// Summing every IMZ's transfer at its share instead averaged the destinations, and the
    /// average of a point in one disk below and a point in another need not lie in either.
    /// Where two IMZs' disks overlap above a base and no longer below it, the pulls
    /// cancelled on the divide between them, and the markers near it fell into the gap
    /// between the narrower disks, where nothing moves them again. On the demo that left
    /// 1629 markers (20 kt, 0.9% of what was drawn) outside every IMZ at the end, in
    /// lenses at the lower disks' overlaps up to 2.4 times as dense as n1 ground, and
    /// the lower disks' interiors 5–15% short of n1; 45 markers had left the model
    /// through its walls. Now none does either (`tests::a_marker_in_the_lens_…`).
    ///
    /// Whether a marker crosses a disk base, and how deep below it it ends, is decided on
    /// the summed move: markers cross a base at the rate of the summed flux. Deciding it on
    /// each IMZ's own move instead applied an IMZ's transfer only when its move alone
    /// reached the base, i.e. at the square of its share: where a weak IMZ overlapped a
    /// strong one, the weak one's funnel hardly drew its streamtubes in. On nine
    /// drawpoints 15 m apart (the panel of `engine::imz`'s docs, 300 m of ground, 60
    /// periods, 3.75 m markers) the middle drawpoint's column carried 0.74 of its schedule
    /// to it in markers over periods 20–60, against 0.64 with crossings decided per IMZ
    /// (both measured with the transfers averaged).
    ///
    /// A cadence window's field (`window`, `engine::cadence`) carries the void of up to
    /// 2^L updates, and its step is split at each disk base it reaches: the marker moves
    /// in the motion above for the share of the step that takes it to the base, the
    /// transfer maps it there (Δa′ only), and the rest of the step is the motion below,
    /// found where the marker now is. The summary's transfer carries the depth reached
    /// below the base on by the speed ratio of the one IMZ whose transfer the marker
    /// takes, as if that IMZ had made the whole summed move; where other IMZs' disks
    /// below no longer hold the marker, that overshoots. Within an update's small move
    /// it hardly matters, and a step of one update keeps the summary's rule. Over a
    /// window it did: markers in the overlaps of IMZs crossed bases too deep, and the
    /// demo's drawpoints drew 1.0% more marker mass than scheduled at the default
    /// `max_marker_move` (median over those never short; 1.3% at 2 m, none with every
    /// marker stepping every update), against −0.1% split
    /// (`tests::a_windows_step_split_…`, `docs::validation`).
    #[inline]
    pub fn step(&self, p: [f64; 3], id: u64) -> Step {
        self.step_cut(p, id, &mut Cut::default())
    }

    /// [`MotionField::step`], adding to `cut` what the caps of the moves left out of it
    /// (`caps`).
    #[inline(always)]
    pub fn step_cut(&self, p: [f64; 3], id: u64, cut: &mut Cut) -> Step {
        if !self.window {
            return self.part(p, id, 1.0, false, cut).0;
        }
        let mut sum = Step {
            drawn_by: u32::MAX,
            host: u32::MAX,
            ..Default::default()
        };
        let (mut q, mut left) = (p, 1.0);
        for n in 1..=MAX_PARTS {
            // The last part, if a move reaches that far, takes the rest in one piece.
            let (st, used) = self.part(q, id, left, n < MAX_PARTS, cut);
            q = [q[0] + st.dx, q[1] + st.dy, q[2] + st.dz];
            sum.strain += st.strain;
            sum.work += st.work;
            sum.dbar += st.dbar;
            if sum.host == u32::MAX {
                sum.host = st.host;
            }
            sum.drawn_by = st.drawn_by;
            left *= 1.0 - used;
            if st.drawn_by != u32::MAX || !(left > 0.0) {
                break;
            }
        }
        (sum.dx, sum.dy, sum.dz) = (q[0] - p[0], q[1] - p[1], q[2] - p[2]);
        sum
    }

    /// The share `k` of this field's move from `p`. With `split`, the move stops at the
    /// first disk base it reaches, where the transfer maps the marker into the disk below;
    /// returns the move and the share of it made (1 when no base was reached), and adds
    /// to `cut` what the caps left out of it.
    #[inline]
    fn part(&self, p: [f64; 3], id: u64, k: f64, split: bool, cut: &mut Cut) -> (Step, f64) {
        let mut st = Step {
            drawn_by: u32::MAX,
            ..Default::default()
        };
        // What the caps dropped from this part's disk moves (scaled with them when split).
        let mut own = Cut::default();
        let mut strongest = 0.0f64;
        let mut total = 0.0f64;
        // Disk bases this marker may cross ([`Base`]). Whether it crosses is known only once
        // every IMZ's move is summed.
        let mut bases: SmallVec<[Base; MAX_BASES]> = SmallVec::new();
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
                let pd = &m.per_disk;
                let dz = -k * dv * pd.fall * pd.profile.shape(a);
                let inv_a = if a > 0.0 { 1.0 / a } else { 0.0 };
                let (ux, uy) = (ex * inv_a, ey * inv_a);
                let mut da = k * radial(m, a, inv_a);
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
                let (lx, ly) = lateral(m, ex, ey, a, [ux, uy]);
                let (lx, ly) = (k * lx, k * ly);
                if pd.may_cap {
                    count_cut(&mut own, m, [ex, ey], a, k, da != 0.0);
                }
                st.dx += sx * (da * ux + lx);
                st.dy += sy * (da * uy + ly);
                st.dz += dz;
                total += dz.abs();
                if i > 0 && dz != 0.0 {
                    let base = Base {
                        d,
                        i: i as u32,
                        a: (a + da).max(0.0),
                        e: [ex, ey],
                        s: [sx, sy],
                        dz,
                    };
                    bases.push(base);
                }
                // Shear strain in the annulus (a > R − w; the whole disk when R ≤ w).
                if a > m.r - m.w {
                    let gamma = dz.abs() * pd.profile.inv_band;
                    st.strain += gamma;
                    st.work += gamma * m.sigma_n;
                    st.dbar += gamma * m.d;
                }
                if dz.abs() > strongest {
                    strongest = dz.abs();
                    st.drawn_by = d;
                }
            };
        for d in self.grid.holding(p[0], p[1], p[2]) {
            if let Some(h) = self.geoms[d as usize].disk_at(p) {
                visit(d, 1.0, 1.0, h);
            }
        }
        // The IMZs' images across the model's walls ([`MotionField::images`]).
        self.images(p, |at, q, sx, sy| {
            for d in self.grid.holding(at[0], at[1], q[2]) {
                if let Some(h) = self.geoms[d as usize].disk_at(q) {
                    visit(d, sx, sy, h);
                }
            }
        });
        // Transfer into the disk below (Δa′, Δz′), along one IMZ's streamtube, for every
        // disk base of that IMZ the summed move crosses, by the depth the summed move
        // reaches below it (split: at the first base reached, with no depth). Where
        // several IMZs move the marker, the one whose transfer it takes is drawn with
        // probability its share of the vertical move, |Δz_d| / Σ|Δz| (an IMZ whose base it
        // does not cross transfers nothing).
        let z_new = p[2] + st.dz;
        let base_z = |b: &Base| {
            let g = &self.geoms[b.d as usize];
            g.z0 + b.i as f64 * g.h
        };
        // Split: the base the move reaches first, where the part ends.
        let first = if split {
            bases
                .iter()
                .map(base_z)
                .filter(|&z| z_new < z)
                .fold(f64::NEG_INFINITY, f64::max)
        } else {
            f64::NEG_INFINITY
        };
        let mut used = 1.0;
        if first > f64::NEG_INFINITY {
            used = ((p[2] - first) / (p[2] - z_new)).clamp(0.0, 1.0);
            st.dx *= used;
            st.dy *= used;
            st.strain *= used;
            st.work *= used;
            st.dbar *= used;
            own.scale(used);
            st.dz = first - p[2];
        }
        let crosses = |b: &&Base| {
            if split {
                base_z(b) == first
            } else {
                z_new < base_z(b)
            }
        };
        let mut crossing = bases.iter().filter(crosses);
        let chosen = match crossing.clone().count() {
            0 => None,
            1 if crossing.clone().all(|b| b.dz.abs() == total) => crossing.next(),
            _ => {
                // Keyed by the base, not the update: the same marker crossing the same
                // base takes the same draw in runs whose flow differs a little (a
                // calibration's trials), so their difference is the flow's, not the draw's.
                let level = crossing.clone().next().map_or(0, |b| b.i as u64);
                let u: f64 = marker_rng(self.seed, id, level, TRANSFER_STREAM).random();
                let mut t = u * total;
                crossing.find(|b| {
                    let hit = t < b.dz.abs();
                    t -= b.dz.abs();
                    hit
                })
            }
        };
        if let Some(b) = chosen {
            let g = &self.geoms[b.d as usize];
            let motion = self.motion[b.d as usize];
            if split {
                // At the base: the radius where the move left the marker, mapped to the
                // radius below that carries the same share of the flux.
                let ex = b.e[0] + b.s[0] * st.dx;
                let ey = b.e[1] + b.s[1] * st.dy;
                let a = (ex * ex + ey * ey).sqrt();
                let (m, below) = (&motion[b.i as usize], &motion[b.i as usize - 1]);
                if a > 0.0 && below.r > 0.0 && (below.r != m.r || below.w != m.w) {
                    // Beyond the rim the transfer maps the marker as if at the rim.
                    cut.dropped[RIM] += (a - m.r).max(0.0);
                    let (da, _) = transfer(m, below, a, 0.0);
                    st.dx += da * b.s[0] * ex / a;
                    st.dy += da * b.s[1] * ey / a;
                }
            } else {
                // A move that reaches below the next base down crosses that one too (a step
                // near a narrow opening, or disks thinner than the move): the transfer is
                // applied base by base, each from the radius and depth the one above left.
                let (mut i, mut a, mut z) = (b.i as usize, b.a, z_new);
                let (mut da, mut dz_t) = (0.0, 0.0);
                while i > 0 {
                    let z_base = g.z0 + i as f64 * g.h;
                    if z >= z_base {
                        break;
                    }
                    let (m, below) = (&motion[i], &motion[i - 1]);
                    if below.r > 0.0 && (below.r != m.r || below.w != m.w) {
                        cut.dropped[RIM] += (a - m.r).max(0.0);
                        let (da_i, dz_i) = transfer(m, below, a, z_base - z);
                        (a, z) = ((a + da_i).max(0.0), z + dz_i);
                        (da, dz_t) = (da + da_i, dz_t + dz_i);
                    }
                    i -= 1;
                }
                let a0 = (b.e[0] * b.e[0] + b.e[1] * b.e[1]).sqrt();
                if a0 > 0.0 {
                    st.dx += da * (b.s[0] * (b.e[0] / a0));
                    st.dy += da * (b.s[1] * (b.e[1] / a0));
                }
                st.dz += dz_t;
            }
        }
        if first > f64::NEG_INFINITY {
            // Just below the base, in the disk below.
            st.dz -= BELOW * first.abs().max(1.0);
        }
        // An image's transfer may carry the marker through its wall: the image's move
        // beyond the wall is the mirror of the IMZ's own move of the marker's mirror, so
        // the marker ends at that mirror, inside.
        if let Some((bm, _)) = self.ground {
            let (lo, hi) = (bm.origin, bm.max_corner());
            for (a, d) in [(0, &mut st.dx), (1, &mut st.dy)] {
                let q = p[a] + *d;
                if q < lo[a] {
                    *d = 2.0 * lo[a] - q - p[a];
                } else if q > hi[a] {
                    *d = 2.0 * hi[a] - q - p[a];
                }
            }
        }
        st.host = st.drawn_by;
        if st.drawn_by != u32::MAX && p[2] + st.dz >= self.geoms[st.drawn_by as usize].z0 {
            st.drawn_by = u32::MAX;
        }
        if own.any() {
            cut.add(&own);
        }
        (st, used)
    }
}

impl MotionField<'_> {
    /// How many IMZs (and images across the walls) a marker step ([`MotionField::step`])
    /// tests for a marker at `p`, and how many of them hold it (`engine::account`): the
    /// same candidate loops, counting instead of moving.
    pub fn candidates(&self, p: [f64; 3]) -> (u64, u64) {
        let (mut tests, mut hits) = (0u64, 0u64);
        let mut count = |at: [f64; 2], q: [f64; 3]| {
            for d in self.grid.holding(at[0], at[1], q[2]) {
                tests += 1;
                hits += u64::from(self.geoms[d as usize].disk_at(q).is_some());
            }
        };
        count([p[0], p[1]], p);
        self.images(p, |at, q, _, _| count(at, q));
        (tests, hits)
    }
}

/// Adds to `cut` what the caps dropped from the share `k` of the moves of disk `m` of a
/// marker at offset `e` from its axis, at radius `a` (`caps`); `pushed`: whether the ring
/// pushes on its ray. Kept out of line: only disks where a cap can bind call it.
#[cold]
#[inline(never)]
fn count_cut(cut: &mut Cut, m: &DiskMotion, e: [f64; 2], a: f64, k: f64, pushed: bool) {
    let inv_a = if a > 0.0 { 1.0 / a } else { 0.0 };
    let (_, cut_r) = radial_cut(m, a, inv_a);
    if pushed && cut_r > 0.0 {
        cut.dropped[if a > m.r_old { PUSH } else { SQUEEZE }] += k * cut_r;
    }
    let (_, _, cut_l) = lateral_cut(m, e[0], e[1], a, [e[0] * inv_a, e[1] * inv_a]);
    if cut_l > 0.0 {
        cut.dropped[LATERAL] += k * cut_l;
    }
}

/// Most parts a window's step is split into (bases it crosses, plus one). A step within
/// the default `max_marker_move` (at most half a disk) crosses one base at most.
const MAX_PARTS: usize = 8;

/// Disk bases a marker's move may cross that a step keeps on the stack (more spill to
/// the heap): one per IMZ holding the marker above its lowest disk, images included; a
/// marker step hits 5 IMZs on average on the mine scene.
const MAX_BASES: usize = 16;

/// How far below a disk base a split step leaves a marker, relative to the base's height.
const BELOW: f64 = 1e-12;

/// A disk base that a marker's move may cross: IMZ `d`'s disk `i`, the marker's radius
/// in it after the radial move, its plan offset from the axis as that IMZ (or its image)
/// sees it and the signs that map the IMZ's plan moves to the marker's, and that IMZ's Δz.
#[derive(Debug, Clone, Copy)]
struct Base {
    d: u32,
    i: u32,
    a: f64,
    e: [f64; 2],
    s: [f64; 2],
    dz: f64,
}

#[cfg(test)]
mod tests {
    use super::super::super::imz::Profile;
    use super::super::disk_moves::tests::still_disks;
    use super::super::prepare;
    use super::*;

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
            let mut shape = [0.0; 2 * super::super::super::imz::SHAPE_MODES];
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
            seed: 0,
            window: false,
        };
        let two = MotionField {
            geoms: &two_geoms,
            motion: &two_motion,
            grid: &two_grid,
            ground: None,
            reach: WallReach::default(),
            seed: 0,
            window: false,
        };
        let mut crossed = 0;
        for k in 0..400 {
            // Just above the bases of disks 1–3, where the moves carry markers across.
            let z = (1 + k % 3) as f64 + 0.0001 * (k / 3) as f64;
            let (a, t) = (0.0087 * k as f64, 0.37 * k as f64);
            let p = [a * t.cos(), a * t.sin(), z];
            let (s1, s2) = (one.step(p, k), two.step(p, k));
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

    /// A cadence window's step, split at the disk base it reaches, follows the updates it
    /// stands for. Two IMZs 5 m apart whose disks 1 (R 3 m) overlap and whose disks 0
    /// (R 2 m) do not; 990 markers in the lens between them, up to 0.3 m above the base of
    /// disks 1; 16 updates, against one window with 16 times an update's void (a mean
    /// move of 0.36 m, which carries nearly every marker across the base). The updates'
    /// steps composed are the reference.
    ///
    /// In one piece, the window's summed move below the base was stretched by the speed
    /// ratio of the one IMZ whose transfer the marker takes, as if that IMZ had made the
    /// whole move, although the other IMZ's disk below no longer holds the marker: the
    /// markers end 8 cm (22% of the move) too deep on average, which is how the cadence
    /// over-drew where IMZs overlap. Split at the base, the rest of the window moves in
    /// the field below: 1.3 cm off on average. What remains is each part's motion taken
    /// where the part starts, a second-order error, so the bound is a quarter of the
    /// one-piece error.
    #[test]
    fn a_windows_step_split_at_a_base_follows_the_updates_it_stands_for() {
        let geoms: Vec<ImzGeom> = [0.0, 5.0]
            .iter()
            .map(|&x| ImzGeom {
                x,
                y: 0.0,
                z0: 0.0,
                h: 1.0,
                radius: vec![2.0, 3.0, 3.0],
            })
            .collect();
        let dv_in = [0.45, 0.4, 0.35];
        let disks = |n: f64| {
            let void = |i: usize| (n * dv_in[i], n * dv_in.get(i + 1).copied().unwrap_or(0.3));
            still_disks(&[2.0, 3.0, 3.0], void, 1.0, 1.0)
        };
        let (update, window) = (disks(1.0), disks(16.0));
        let grid = ImzGrid::build(&geoms, &[0, 1], [-4.0, -4.0], [13.0, 8.0], 1.0);
        let field = |m: &[DiskMotion], window: bool, f: &dyn Fn(&MotionField) -> [f64; 3]| {
            let motion: Vec<&[DiskMotion]> = vec![m, m];
            f(&MotionField {
                geoms: &geoms,
                motion: &motion,
                grid: &grid,
                ground: None,
                reach: WallReach::default(),
                seed: 3,
                window,
            })
        };
        let end = |p: [f64; 3], st: Step| [p[0] + st.dx, p[1] + st.dy, p[2] + st.dz];
        let (mut n, mut e_split, mut e_whole, mut deep) = (0, 0.0, 0.0, 0.0);
        let mut n_c = 0;
        let (mut z_c, mut z_s, mut z_w) = (0.0, 0.0, 0.0);
        for i in 0..=10 {
            for j in -4..=4 {
                for k in 0..10 {
                    let p = [
                        2.05 + 0.09 * i as f64,
                        0.2 * j as f64,
                        1.0 + 0.03 * k as f64,
                    ];
                    let id = (100 * i + 10 * (j + 4) + k) as u64;
                    let composed = field(&update, false, &|f| {
                        (0..16).fold(p, |q, _| end(q, f.step(q, id)))
                    });
                    let split = field(&window, true, &|f| end(p, f.step(p, id)));
                    let whole = field(&window, false, &|f| end(p, f.step(p, id)));
                    n_c += (composed[2] < 1.0) as usize;
                    z_c += composed[2];
                    z_s += split[2];
                    z_w += whole[2];
                    n += 1;
                    e_split += (split[2] - composed[2]).abs();
                    e_whole += (whole[2] - composed[2]).abs();
                    deep += (p[2] - composed[2]).abs();
                }
            }
        }
        let (e_split, e_whole, moved) = (e_split / n as f64, e_whole / n as f64, deep / n as f64);
        assert!(n_c > 900, "too few markers cross the base: {n_c} of {n}");
        assert!(
            e_split < 0.25 * e_whole && e_whole > 0.1 * moved,
            "mean |Δz error|: split {e_split}, one piece {e_whole}, of a mean move {moved}"
        );
        assert!(
            (z_s - z_c).abs() < 0.05 * moved * n as f64 && z_c - z_w > 0.1 * moved * n as f64,
            "mean z: updates {}, split {}, one piece {}",
            z_c / n as f64,
            z_s / n as f64,
            z_w / n as f64
        );
    }

    /// Two IMZs on axes 5 m apart whose disks 1 (R 3 m) overlap and whose disks 0 (R 2 m)
    /// do not, so the lens between the disks 1 ends at their common base over a 1 m gap.
    /// Every marker in the lens that the summed move carries across that base ends in
    /// one of the disks 0: it takes one IMZ's transfer, drawn with that IMZ's share of
    /// its vertical move. Summing the two transfers at their shares instead averaged the
    /// destinations: the two pulls cancel on the divide (x = 2.5 m), and the markers
    /// near it fell into the gap, out of every disk, where nothing moves them again. And
    /// at a point where A's share is s, the share of 4000 keys that take A's transfer is s
    /// to 4 standard errors.
    #[test]
    fn a_marker_in_the_lens_of_two_imzs_takes_one_imzs_transfer_by_its_share() {
        let geom = |x: f64| ImzGeom {
            x,
            y: 0.0,
            z0: 0.0,
            h: 1.0,
            radius: vec![2.0, 3.0, 3.0],
        };
        let motion = still_disks(&[2.0, 3.0, 3.0], |_| (0.6, 0.5), 1.0, 1.0);
        let geoms = vec![geom(0.0), geom(5.0)];
        let grid = ImzGrid::build(&geoms, &[0, 1], [-4.0, -4.0], [13.0, 8.0], 1.0);
        let motions: Vec<&[DiskMotion]> = vec![&motion[..], &motion[..]];
        let field = MotionField {
            geoms: &geoms,
            motion: &motions,
            grid: &grid,
            ground: None,
            reach: WallReach::default(),
            seed: 7,
            window: false,
        };
        let z = 1.0 + 1e-4;
        let mut crossed = 0;
        for i in 0..=10 {
            for j in -5..=5 {
                let (x, y) = (2.05 + 0.09 * i as f64, 0.2 * j as f64);
                let (a, b) = (x.hypot(y), (5.0 - x).hypot(y));
                if a >= 3.0 || b >= 3.0 {
                    continue;
                }
                for id in 0..8 {
                    let st = field.step([x, y, z], id);
                    let q = [x + st.dx, y + st.dy, z + st.dz];
                    if q[2] >= 1.0 {
                        continue;
                    }
                    crossed += 1;
                    let (qa, qb) = (q[0].hypot(q[1]), (5.0 - q[0]).hypot(q[1]));
                    assert!(qa <= 2.0 + 1e-9 || qb <= 2.0 + 1e-9, "{x} {y} → {q:?}");
                }
            }
        }
        assert!(crossed > 200, "{crossed}");
        // The split at a point nearer A's axis.
        let p = [2.3, 0.4, z];
        let (va, vb) = (
            Profile::new(3.0, 1.0).vertical(0.6, p[0].hypot(p[1])),
            Profile::new(3.0, 1.0).vertical(0.6, (5.0 - p[0]).hypot(p[1])),
        );
        let share = va / (va + vb);
        let n = 4000;
        let to_a = (0..n)
            .filter(|&id| {
                let st = field.step(p, id);
                (p[0] + st.dx).hypot(p[1] + st.dy) <= 2.0 + 1e-9
            })
            .count() as f64
            / n as f64;
        let se = (share * (1.0 - share) / n as f64).sqrt();
        assert!(share > 0.6 && share < 0.9, "{share}");
        assert!((to_a - share).abs() <= 4.0 * se, "{to_a} vs {share}");
    }
}
