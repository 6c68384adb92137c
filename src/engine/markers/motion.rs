//! One marker update: the motion field of the drawing IMZs (the profiles, the transfer
//! into a narrower disk, the ring's push and its lateral part, the walls' images), summed
//! over the IMZs that hold a marker (summary §3.3, §4.2; see the module above for the
//! equations).

use rand::Rng;
use rayon::prelude::*;

use super::super::random::{marker_rng, TRANSFER_STREAM};

use super::super::imz::{DiskMotion, ImzGeom, ImzGrid, PerDisk, Profile};
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
    let (p_here, p_below) = (&here.per_disk.profile, &below.per_disk.profile);
    let a = a.min(here.r);
    let a_new = p_below.radius_at_share(p_here.flux_inside(a));
    let speed = |m: &DiskMotion, a: f64| m.per_disk.fall * m.per_disk.profile.shape(a);
    let (v_here, v_below) = (speed(here, a), speed(below, a_new));
    // At the very rim both speeds vanish; their ratio tends to the ratio of the areas.
    let stretch = if v_here > 1e-9 * speed(here, 0.0) {
        v_below / v_here
    } else {
        (here.r * here.r * here.area_frac) / (below.r * below.r * below.area_frac)
    };
    (a_new - a, -depth * (stretch - 1.0))
}

/// Inward radial displacement (negative) of a marker at radius `a` (`inv_a` = 1/a, 0 at
/// the axis) in disk `m` that expanded from R^old to R, its dilating ring taking
/// `take` of plan area from the interior (the void the disk absorbed over its height and
/// its flowable share of the perimeter; see the module docs).
///
/// Inside R_old the squeeze follows the vertical move's profile: the ring of radius a
/// loses the share F(a) ([`Profile::flux_inside`]) of `take`, so u(a) = −take F(a) / (2π a), and
/// each streamtube's squeeze is its vertical stretch. Between R_old and the new radius it
/// falls linearly to zero. At most half a marker's radius is taken in one step (only a
/// disk that more than doubles its radius in a step asks for more).
///
/// `m.per_disk` must be prepared ([`prepare`]).
#[inline]
pub fn radial(m: &DiskMotion, a: f64, inv_a: f64) -> f64 {
    let p = &m.per_disk;
    if !p.widened || a > m.r || !(a > 0.0) {
        return 0.0;
    }
    if a > m.r_old {
        -p.push.min(0.5 * m.r_old) * (1.0 - (a - m.r_old) * p.inv_dr)
    } else {
        let u = p.take * p.profile.flux_inside(a) * (0.5 * std::f64::consts::FRAC_1_PI) * inv_a;
        -u.min(0.5 * a)
    }
}

/// Lateral move (dx, dy) of a marker at offset (ex, ey) from the axis of a disk that
/// expanded from `m.r_old` to `m.r`, at radius `a` on the ray of unit vector `u`, its ring
/// taking `take` of plan area from the interior ([`radial`]'s), where the ring's dilation
/// is not the same all round (`m.shape`).
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
pub fn lateral(m: &DiskMotion, ex: f64, ey: f64, a: f64, u: [f64; 2]) -> (f64, f64) {
    let (r_old, p) = (m.r_old, &m.per_disk);
    if !p.lateral || a > m.r {
        return (0.0, 0.0);
    }
    // u_a(R_old, θ) = s Σ α_k cos kθ + β_k sin kθ: the uniform push at R_old times w − 1.
    let s = -p.push;
    let (scale, tx, ty) = if a <= r_old {
        (s, ex * p.inv_r_old, ey * p.inv_r_old)
    } else {
        (s * (m.r - a) * p.inv_dr, u[0], u[1])
    };
    // W'(z) = s Σ (α_k − i β_k) t^(k−1), t = z / R_old; u = (Re W', −Im W').
    let (mut wr, mut wi) = (0.0, 0.0);
    let (mut pr, mut pi) = (1.0, 0.0);
    for k in 0..super::super::imz::SHAPE_MODES {
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
/// them instead of working them out per marker.
pub fn prepare(motion: &mut [DiskMotion], h: f64) {
    for m in motion {
        let profile = Profile::new(m.r, m.w);
        let take = (m.dv - m.dv_out) / (h * m.flow_frac);
        let widened = m.r > m.r_old && m.r_old > 0.0 && take > 0.0;
        let (push, inv_r_old, inv_dr) = if widened {
            let push = take * profile.flux_inside(m.r_old) / (2.0 * std::f64::consts::PI * m.r_old);
            (push, 1.0 / m.r_old, 1.0 / (m.r - m.r_old))
        } else {
            (0.0, 0.0, 0.0)
        };
        m.per_disk = PerDisk {
            profile,
            fall: profile.c / (std::f64::consts::PI * m.area_frac),
            take,
            widened,
            push,
            inv_r_old,
            inv_dr,
            lateral: widened && m.shape.iter().any(|&c| c != 0.0),
        };
    }
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
        if !self.window {
            return self.part(p, id, 1.0, false).0;
        }
        let mut sum = Step {
            drawn_by: u32::MAX,
            host: u32::MAX,
            ..Default::default()
        };
        let (mut q, mut left) = (p, 1.0);
        for n in 1..=MAX_PARTS {
            // The last part, if a move reaches that far, takes the rest in one piece.
            let (st, used) = self.part(q, id, left, n < MAX_PARTS);
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
    /// returns the move and the share of it made (1 when no base was reached).
    #[inline]
    fn part(&self, p: [f64; 3], id: u64, k: f64, split: bool) -> (Step, f64) {
        let mut st = Step {
            drawn_by: u32::MAX,
            ..Default::default()
        };
        let mut strongest = 0.0f64;
        let mut total = 0.0f64;
        // Disk bases this marker may cross ([`Base`]). Whether it crosses is known only once
        // every IMZ's move is summed.
        let mut bases = [Base::default(); 8];
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
                    if n_b < bases.len() {
                        bases[n_b] = base;
                        n_b += 1;
                    } else {
                        extra.push(base);
                    }
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
            bases[..n_b]
                .iter()
                .chain(&extra)
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
            st.dz = first - p[2];
        }
        let crosses = |b: &&Base| {
            if split {
                base_z(b) == first
            } else {
                z_new < base_z(b)
            }
        };
        let mut crossing = bases[..n_b].iter().chain(&extra).filter(crosses);
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
        (st, used)
    }
}

impl MotionField<'_> {
    /// The model's vertical walls (method of images): an IMZ whose disk passes a wall
    /// also moves the marker as its mirror image across that wall would, so the flow
    /// along a wall has no component through it and a cut disk's flux stays whole in the
    /// model. The images of the IMZs of the cell at the wall nearest the mirrored point
    /// are the candidates, where the marker is within the images' reach of the wall
    /// ([`WallReach`]). Within reach of two walls, the images across both (the
    /// corner's) as well. Calls `f(at, q, sx, sy)` per image: the plan point whose grid
    /// cell lists the candidates, the marker's mirror `q`, and the signs (sx, sy) that map
    /// the image's plan moves to the marker's.
    #[inline]
    fn images(&self, p: [f64; 3], mut f: impl FnMut([f64; 2], [f64; 3], f64, f64)) {
        let Some((bm, _)) = self.ground else { return };
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
        for (wall, inside, _) in walls(0) {
            f([inside, p[1]], [2.0 * wall - p[0], p[1], p[2]], -1.0, 1.0);
        }
        for (wall, inside, _) in walls(1) {
            f([p[0], inside], [p[0], 2.0 * wall - p[1], p[2]], 1.0, -1.0);
        }
        for (wx, in_x, _) in walls(0) {
            for (wy, in_y, _) in walls(1) {
                f(
                    [in_x, in_y],
                    [2.0 * wx - p[0], 2.0 * wy - p[1], p[2]],
                    -1.0,
                    -1.0,
                );
            }
        }
    }

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

/// Most parts a window's step is split into (bases it crosses, plus one). A step within
/// the default `max_marker_move` (at most half a disk) crosses one base at most.
const MAX_PARTS: usize = 8;

/// How far below a disk base a split step leaves a marker, relative to the base's height.
const BELOW: f64 = 1e-12;

/// A disk base that a marker's move may cross: IMZ `d`'s disk `i`, the marker's radius
/// in it after the radial move, its plan offset from the axis as that IMZ (or its image)
/// sees it and the signs that map the IMZ's plan moves to the marker's, and that IMZ's Δz.
#[derive(Debug, Clone, Copy, Default)]
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
    use super::*;
    use std::f64::consts::PI;

    /// Disks of `radii` that did not widen, in open ground, with shear band `w`, disk `i`
    /// passing the void `void(i)` = (Δv_i, Δv_out), prepared for disks of thickness `h`.
    fn still_disks(
        radii: &[f64],
        void: impl Fn(usize) -> (f64, f64),
        w: f64,
        h: f64,
    ) -> Vec<DiskMotion> {
        let mut m: Vec<DiskMotion> = radii
            .iter()
            .enumerate()
            .map(|(i, &r)| {
                let (dv, dv_out) = void(i);
                DiskMotion {
                    r,
                    r_old: r,
                    dv,
                    dv_out,
                    w,
                    area_frac: 1.0,
                    flow_frac: 1.0,
                    ..Default::default()
                }
            })
            .collect();
        prepare(&mut m, h);
        m
    }

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
                vol += Profile::new(r, w).vertical(dv, a) * 2.0 * PI * a * (r / n as f64);
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
                vol -= Profile::new(r, w).vertical(1.0, a) * 2.0 * PI * a * (r / n as f64);
                if (k + 1) % 2000 == 0 {
                    let f = Profile::new(r, w).flux_inside((k + 1) as f64 * r / n as f64);
                    assert!(
                        (f - vol).abs() < 1e-6,
                        "r {r} w {w} a {}: {f} vs {vol}",
                        (k + 1) as f64 * r / n as f64
                    );
                }
            }
        }
        assert_eq!(Profile::new(2.0, 1.0).flux_inside(0.0), 0.0);
        assert_eq!(
            Profile::new(2.0, 1.0).flux_inside(3.0),
            Profile::new(2.0, 1.0).flux_inside(2.0)
        );
        // And its inverse, in the plug, the annulus and the cone.
        for &(r, w) in &[(1.0, 2.0), (3.0, 1.0), (5.0, 0.5)] {
            for k in 0..=20 {
                let a = r * k as f64 / 20.0;
                // At the rim F is flat (1 − F ∝ (r − a)²), so a is found to √ε there.
                let back = Profile::new(r, w).radius_at_share(Profile::new(r, w).flux_inside(a));
                assert!((back - a).abs() < 1e-6 * r, "r {r} w {w}: {a} → {back}");
            }
        }
    }

    /// A disk of shear band `w` in open ground that widened from `r_old` to `r`, its ring
    /// taking `take` of plan area from the interior, prepared.
    fn widened_disk(r_old: f64, r: f64, w: f64, take: f64) -> DiskMotion {
        let mut m = [DiskMotion {
            r,
            r_old,
            dv: take,
            w,
            area_frac: 1.0,
            flow_frac: 1.0,
            ..Default::default()
        }];
        prepare(&mut m, 1.0);
        m[0]
    }

    #[test]
    fn radial_move_is_the_ring_dilation() {
        // The ring 2 → 2.01 m at n0 0.30 dilates to n1 0.45: it takes ε ΔA of plan area from
        // the interior (ε = Δn/(1 − n1)). At R_old the interior has lost the profile's share
        // F(R_old) of it, so the peak is the ring's thickness gain ΔR ε F(R_old) to first
        // order in ΔR.
        let (r0, r1, w, eps) = (2.0, 2.01, 0.5, 0.15 / 0.55);
        let take = eps * PI * (r1 * r1 - r0 * r0);
        let m = widened_disk(r0, r1, w, take);
        let radial_at = |m: &DiskMotion, a: f64| radial(m, a, if a > 0.0 { 1.0 / a } else { 0.0 });
        let peak = -radial_at(&m, r0);
        let f = Profile::new(r1, w).flux_inside(r0);
        assert!(f > 0.99 && f < 1.0, "{f}");
        assert!((peak / ((r1 - r0) * eps * f) - 1.0).abs() < 0.01, "{peak}");
        // Streamtube by streamtube, the area inside a loses take × F(a): 2π a u(a).
        for a in [0.1, 0.7, 1.5, 1.9] {
            let u = radial_at(&m, a);
            assert!((2.0 * PI * a * u + take * Profile::new(r1, w).flux_inside(a)).abs() < 1e-12);
        }
        // Zero at the axis and at R_new; nothing without absorbed void, nor in a new disk.
        assert_eq!(radial_at(&m, 0.0), 0.0);
        assert!(radial_at(&m, r1).abs() < 1e-12);
        assert_eq!(radial_at(&widened_disk(r0, r1, w, 0.0), r0), 0.0);
        for k in 1..=10 {
            let a = 0.1 * k as f64;
            assert_eq!(radial_at(&widened_disk(0.0, 1.0, w, 0.5), a), 0.0);
            // A squeeze larger than the interior takes at most half a marker's radius.
            assert!(a + radial_at(&widened_disk(0.5, 1.0, w, 10.0), a) >= 0.5 * a - 1e-12);
        }
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

    /// A marker beside a wall whose IMZ narrows below it never leaves the model: where it
    /// takes the image's transfer, which points beyond the wall, it ends at the mirror of
    /// where that move would carry it. The Castro box's wall x = −0.6 m, an IMZ 0.1 m from
    /// it with disks of 0.2 m below 0.3 m; points within 5 cm of the wall just above the
    /// disks' base, 16 keys each.
    #[test]
    fn an_images_transfer_never_carries_a_marker_through_its_wall() {
        let scene = crate::model::synthetic::UniformBox::castro_isolated().scene();
        let bm = &scene.blocks;
        let [wx, _, _] = bm.origin;
        let z0 = bm.origin[2];
        let motion = still_disks(&[0.2, 0.3, 0.3], |_| (0.004, 0.003), 0.05, 0.1);
        let geoms = vec![ImzGeom {
            x: wx + 0.1,
            y: 0.0,
            z0,
            h: 0.1,
            radius: vec![0.2, 0.3, 0.3],
        }];
        let grid = ImzGrid::build(&geoms, &[0], [wx, -0.6], [1.2, 1.2], 0.05);
        let motions: Vec<&[DiskMotion]> = vec![&motion[..]];
        let field = MotionField {
            geoms: &geoms,
            motion: &motions,
            grid: &grid,
            ground: Some((bm, 1)),
            reach: WallReach::new(&geoms, bm),
            seed: 1,
            window: false,
        };
        let (mut crossed, mut image) = (0, 0);
        for i in 0..10 {
            for j in -10..=10 {
                let p = [
                    wx + 0.005 * (i as f64 + 0.5),
                    0.02 * j as f64,
                    z0 + 0.1 + 1e-4,
                ];
                for id in 0..16 {
                    let st = field.step(p, id);
                    assert!(p[0] + st.dx >= wx, "{p:?}: {st:?}");
                    if p[2] + st.dz < z0 + 0.1 {
                        crossed += 1;
                        // The IMZ's own transfer pulls the marker off the wall (+x).
                        image += usize::from(st.dx < 0.0);
                    }
                }
            }
        }
        assert!(
            crossed > 1000 && image > 100,
            "{crossed} crossed, {image} by the image"
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
                seed: 0,
                window: false,
            };
            let z = geom.z0 + 0.25;
            // Along each wall the disk reaches (1 nm inside it) nothing moves through it,
            // to the field's change over 2 nm.
            for k in 0..50 {
                let t = 0.011 * k as f64 - 0.27;
                let st = field.step([wx + 1e-9, y + t, z], k);
                assert!(st.dx.abs() < 1e-6 * st.dz.abs(), "({x}, {y}) t {t}: {st:?}");
                if y < wy + 0.3 && x + t > wx {
                    let st = field.step([x + t, wy + 1e-9, z], k);
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
                        volume -= field.step(p, 0).dz * cell * cell;
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
