//! Isolated movement zones (summary §3.3, DESIGN §4.1).
//!
//! This module holds the IMZ, its parameters and the r-law; the growth of an IMZ by a
//! draw (the cycles, the disks' passes and the ring's integration) is in `growth`, the
//! sampling of the ground around it in `ground`, its geometry and the plan grids in `geom`,
//! and the motion a disk hands to the marker pass in `disk_motion`.
//!
//! An IMZ is a stack of horizontal disks of thickness `h` on its drawpoint's vertical axis.
//! Drawing a volume Δv opens a void at the drawpoint that is passed upward disk by disk.
//! In disk i the void v_i is filled partly by dilation of the stagnant ring at the disk's
//! perimeter (share r) and partly by material from the disk above (share 1 − r):
//!
//! ```text
//! r   = min(1, (10 d̄ h / (π R_i²)) · max(0, 1 − (R_i − R_{i−1}) tan(45° + φ/2) / h)^q)
//! R_i ← sqrt(R_i² + r v_i / (π h ε)),   ε = (n1 − n0) / (1 − n1)
//! v_{i+1} = (1 − r) v_i
//! ```
//!
//! # The volume balance
//! Three volumes meet in a disk, and each is a bulk volume at a stated porosity:
//! - the void Δv opened at the drawpoint is the bulk volume, at the dilated porosity n1, of
//!   the tonnes drawn: Δv = tonnes / (ρ_s (1 − n1)), solids Δv (1 − n1);
//! - the ring R_i → R_i′ that a disk gains is stagnant ground at n0 (bulk π h (R_i′² − R_i²),
//!   solids × (1 − n0)) that dilates to n1 at constant solids. Its bulk then grows by the
//!   factor (1 − n0)/(1 − n1): it creates ε = (n1 − n0)/(1 − n1) of void per unit of its own
//!   bulk, and that is what fills the share r v_i;
//! - the material inside the disk stays at n1 throughout.
//!
//! So r v_i = π h (R_i′² − R_i²) ε. Summed over a draw whose void all stays in the IMZ, the
//! ground mobilised, V, satisfies V (n1 − n0) = Σ Δv (1 − n1): the solids that left are the
//! solids the dilation freed, and the IMZ's material is at n1, the stagnant ground at n0.
//!
//! **Where this departs from the summary.** The summary prints the update as
//! R_i ← sqrt(R_i² + r v_i / (π h (n1 − n0))): it credits a ring of bulk V with V (n1 − n0)
//! of void. That is the void created only when the ring's bulk is counted at a porosity
//! of zero; ground going from n0 to n1 at constant solids creates V (n1 − n0)/(1 − n1). As
//! printed, the update makes the IMZ 1/(1 − n1) times too large for the void drawn (1.8×
//! at n1 = 0.45), and the marker field, which moves exactly the volume drawn, cannot fill
//! it at n1: the markers in the IMZ stay denser than n1 (by ~7% at n0 0.35, n1 0.45), the
//! drawpoints draw that much more marker mass than scheduled, and a mass correction of
//! ~0.90 hid it. The form above is the one that conserves mass. The r-law itself is the
//! summary's, unchanged. The far-field width and the base angle under both forms are
//! measured side by side in `docs::validation`.
//!
//! The marker pass reads the same balance (`engine::markers`): each disk records the void
//! that entered its base (`DiskMotion::dv`) and the void that left through its top
//! (`DiskMotion::dv_out`, which includes void that left the IMZ for the free surface or an
//! air gap). The vertical move stretches the disk's material by their difference, the void
//! the disk absorbed; the radial move takes that same volume out of the interior and gives
//! it to the ring, which so dilates from n0 to n1 while the interior stays at n1.
//!
//! # Choices where the summary is silent
//! - **Threshold slope.** The summary gives no value for the threshold negative slope β_T
//!   below which r = 1. We read it as the slope at which the formula reaches 1, i.e.
//!   r = min(1, formula). At the minimum positive slope 45 + φ/2 the bracket is 0 and r = 0.
//! - **Lowest disk.** Disk 0 starts with the radius of the drawpoint opening; its R_{−1} is
//!   that opening radius, so the base can widen only up to the 45 + φ/2 limit.
//! - **New disks.** When void reaches the top disk a new, empty disk is opened on top
//!   (R = 0, so r = 1 and the void dilates it). A disk is only opened where the ground on
//!   the axis is flowable; otherwise the void leaves the IMZ through the top disk: under
//!   uncaved ground it is an air gap (`Imz::air`) above the top disk's markers, and above
//!   the top of the model it is the subsidence of the free surface. Once the ground above
//!   caves, the next void to reach the top carries the stored air up with it into the new
//!   disk, so the air gap closes as the cave catches up.
//! - **Properties.** d̄ and φ of a disk are the mobilised properties (mean of the markers in
//!   the disk, refreshed each period; the stagnant ones until it holds markers). n0 and n1
//!   are the stagnant properties: n1 the mean over 24 perimeter points of the block model,
//!   n0 = n1 less the mean jump over the flowable perimeter in its current state (a point
//!   inside another IMZ is already dilated: its jump is 0; see the next item).
//! - **Overlap: paying for the ground a ring gains** (summary §4.2's variable porosity
//!   jump). The void a ring absorbs must be the dilation of the stagnant ground it gains
//!   and nothing else, or the union of the IMZs stops matching the void drawn. Three
//!   things make that so. The dilation state (which perimeter points lie inside another
//!   IMZ) is sampled at points at most one sampling length g apart (at least 24), each
//!   with its own block's jump, not only at the 24 block samples, so a stagnant gap between
//!   two neighbours is seen and ground beyond a wall is not paid for; it is sampled
//!   again each time the disk has widened by 0.05 g, and within one cycle a disk widens at
//!   most that far on one sample; the block properties are resampled every g/2. g is the
//!   marker spacing, never less than h/2: markers finer than that sample the grades better
//!   and leave the IMZs alone, so a run with finer markers only (as records made at a finer
//!   resolution) differs from a coarser one by its markers' sampling and not by its IMZs
//!   (`analysis::calibrate`). On nine drawpoints 15 m apart on 15 m blocks (4 m openings,
//!   n0 0.30, n1 0.45, 45 kt each), the union of the IMZs then holds the dilation of
//!   397 kt of the 405 kt drawn (−1.9%). With only the 24 block samples, resampled every
//!   half spacing, it held 360 kt (−11%) before the free widening below was made to look
//!   at as many points, and 442 kt (+9%) after: a ring that set out across neighbours'
//!   dilated ground at a small mean jump took the stagnant ground beyond it nearly free.
//!   The jump's variation around the perimeter is kept for the marker pass
//!   (`Stagnant::shape`, read by `engine::markers::lateral`).
//! - **Vanishing porosity jump.** Where every sampled point of the perimeter is already
//!   dilated (inside a neighbour, or in a block whose own n1 − n0 is below
//!   `min_porosity_jump`), no void is needed to mobilise it: the disk widens at no cost,
//!   stepping out until it meets a stagnant point, and the formula then uses the jump
//!   found there, however small. So no division by zero, and overlapped ground is engulfed,
//!   as superposition requires (summary §4.2). Free widening keeps to the base angle (at
//!   most h / tan(45 + φ/2) wider than the disk below), so overlapping IMZs merge through a
//!   funnel, not a step. Widening at no cost wherever the *mean* jump of the perimeter was
//!   below `min_porosity_jump` instead took the stagnant pockets between three or four
//!   neighbours into the IMZ undilated (one point in 30 stagnant is a mean of 0.005 at a
//!   jump of 0.15), and their markers reached the drawpoints denser than n1: at mine scale
//!   the drawpoints at least 40 m from the model's walls drew a median 1.022 of their
//!   schedule in markers, against 0.993 now (`docs::validation`,
//!   `growth::tests::a_ring_pays_for_the_stagnant_ground_it_gains_however_little`).
//! - **Flowable reach.** A disk never widens past the farthest flowable point of its level
//!   (`Ground::reach`): ground outside the model or not yet caved cannot be mobilised. A
//!   disk may still be wider than the ground on one side. Past one of the model's walls
//!   the marker pass moves the ground by the IMZ's mirror image (`engine::markers`), so
//!   the disk's flux stays whole in the model; where uncaved ground cuts it, the void
//!   fills only the flowable share A_f of its area
//!   (`Ground::area_fraction`), and the marker pass divides vertical moves by A_f.
//! - **Unflowable perimeter.** Points in uncaved blocks or outside the model cannot
//!   dilate; the fraction f of flowable points scales the area that can grow:
//!   R_i ← sqrt(R_i² + r v_i / (π h ε f)); with f = 0 the disk cannot widen (r = 0).
//!   A disk that reaches its reach widens no further and passes the rest of its void up.
//! - **Integration.** r depends on R_i, which grows as the void is taken, so within a disk
//!   the law is integrated over the void (d(R_i²) = r(R_i) dv / (π h ε f)) in sub-steps
//!   small against the distance over which r changes (`Imz::absorb`). The void a disk
//!   takes is then exactly the dilation of the ring it gains, r falls to zero as the
//!   boundary reaches 45 + φ/2 (never past it), and a new top disk stops where the law says
//!   instead of swallowing a whole cycle. Evaluating r once per cycle let new and small
//!   disks (r = 1) overshoot by up to ~1.6 × the opening radius per cycle; the IMZ then
//!   widened upward like a funnel at fine h, and its width did not converge as h shrank.

mod disk_motion;
mod geom;
mod ground;
mod growth;

use std::f64::consts::PI;

use super::cadence::Window;

pub use disk_motion::{DiskMotion, PerDisk, Profile};
pub use geom::{ImzGeom, ImzGrid, Listing};
pub use ground::{Ground, Stagnant};
pub use growth::{Passes, MERGE_TOLERANCE};

/// Number of perimeter points sampled for stagnant properties (summary §3.3).
pub const PERIMETER_POINTS: usize = 24;

/// Most perimeter points sampled for a disk's dilation state ([`Ground::dilation`]).
pub const MAX_DILATION_POINTS: usize = 512;

/// Fourier modes kept of the ring's dilation around the perimeter ([`Stagnant::shape`]).
pub const SHAPE_MODES: usize = 6;

/// Rings of points sampled for a disk's flowable area share.
const AREA_RINGS: usize = 4;

/// (cos t, sin t) at t = 2π x / [`PERIMETER_POINTS`] for x = 0, ½, 1, … : the sampling
/// angles of the perimeter (whole x) and of the area rings (x = k + ½ ring), computed once.
static UNIT_CIRCLE: std::sync::LazyLock<Vec<(f64, f64)>> = std::sync::LazyLock::new(|| {
    (0..2 * PERIMETER_POINTS + AREA_RINGS)
        .map(|j| {
            let t = 2.0 * PI * (0.5 * j as f64) / PERIMETER_POINTS as f64;
            (t.cos(), t.sin())
        })
        .collect()
});

/// The r-law: share of the void in disk i filled by dilation of the stagnant perimeter.
///
/// `d` = d̄ (m), `h` disk thickness (m), `r_i` = R_i, `r_below` = R_{i−1}, `phi` in degrees,
/// `q` the exponent (3.5 by default).
#[inline]
pub fn r_law(d: f64, h: f64, r_i: f64, r_below: f64, phi: f64, q: f64) -> f64 {
    r_law_sloped(d, h, r_i, r_below, base_slope(phi), q)
}

/// tan(45° + φ/2): the slope of the base angle, φ in degrees.
#[inline]
pub fn base_slope(phi: f64) -> f64 {
    (45.0 + 0.5 * phi).to_radians().tan()
}

/// [`r_law`] with the base-angle slope tan(45° + φ/2) given.
#[inline]
fn r_law_sloped(d: f64, h: f64, r_i: f64, r_below: f64, slope: f64, q: f64) -> f64 {
    if r_i <= 0.0 {
        return 1.0;
    }
    let bracket = (1.0 - (r_i - r_below) * slope / h).max(0.0);
    if bracket == 0.0 && q > 0.0 {
        // At or past the base angle: 0^q (a disk at its limit passes all its void up).
        return 0.0;
    }
    (10.0 * d * h / (PI * r_i * r_i) * pow_q(bracket, q)).min(1.0)
}

/// b^q for b ≥ 0, by multiplications and one square root when 2q is a small whole number
/// (the default q = 3.5 is b³ √b): the r-law is evaluated in every sub-step of every
/// disk's absorption, where `powf` was a twentieth of the run.
#[inline]
fn pow_q(b: f64, q: f64) -> f64 {
    let twice = 2.0 * q;
    if twice == twice.trunc() && (0.0..=16.0).contains(&twice) {
        let n = twice as i32;
        let whole = b.powi(n / 2);
        if n % 2 == 1 {
            whole * b.sqrt()
        } else {
            whole
        }
    } else {
        b.powf(q)
    }
}

/// The void ε = (n1 − n0)/(1 − n1) that ground creates per unit of its bulk when it dilates
/// from n0 to n1 at constant solids (`jump` = n1 − n0; see the module docs).
#[inline]
pub fn dilation(jump: f64, n1: f64) -> f64 {
    jump / (1.0 - n1)
}

/// The radius update R_i ← sqrt(R_i² + r v_i / (π h ε f)), ε the [`dilation`].
#[inline]
pub fn grown_radius(r_i: f64, r: f64, v: f64, h: f64, eps: f64, flow_frac: f64) -> f64 {
    (r_i * r_i + r * v / (PI * h * eps * flow_frac)).sqrt()
}

/// Mobilised properties of one disk: the means over the markers inside it (summed in the
/// order of their ids, then divided once, `Engine::refresh_mobilised`; the growth reads
/// them every cycle).
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
pub struct Mobilised {
    /// Mean d̄ of the markers, m.
    pub d: f64,
    /// Mean φ, degrees.
    pub phi: f64,
    /// Mean ρ_s (1 − n1), t/m³.
    pub rho1: f64,
    /// Mean ρ_s, t/m³.
    pub rho_s: f64,
    /// Number of markers.
    pub count: u32,
}

/// One drawpoint's IMZ.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Imz {
    /// Index of this IMZ (= drawpoint index).
    pub id: usize,
    /// Geometry (axis, base, h, radii).
    pub geom: ImzGeom,
    /// Opening radius (R_{−1} of disk 0), m.
    pub r_open: f64,
    /// Per-disk motion accumulated since the last marker update.
    pub motion: Vec<DiskMotion>,
    /// Per-disk stagnant properties (cached; resampled when the radius moves).
    pub stagnant: Vec<Stagnant>,
    /// Per-disk mobilised sums (refreshed each period, plus newly engulfed markers).
    pub mobilised: Vec<Mobilised>,
    /// Per disk, the reach of flowable ground at its level (`Ground::reach`), the most a
    /// disk can widen; NaN until computed, reset when ground caves.
    pub reach: Vec<f64>,
    /// Void held under uncaved ground inside the model: the air gap above this IMZ, m³
    /// (released into the ground above once it caves).
    pub air: f64,
    /// Void that left the IMZ through the top of the model over the run, m³: the
    /// subsidence of the free surface that the top disk's markers make.
    #[serde(default)]
    pub vented: f64,
    /// Per disk, the void that fines left when they percolated out through the disk's
    /// underside since the IMZ last drew, m³ (`engine::fines`; passed up by
    /// [`Imz::refill`]).
    #[serde(default)]
    pub leaked: Vec<f64>,
    /// Per disk base, the volume fines percolated across it that the bulk's counterflow
    /// has not yet carried back, m³ (`engine::fines`).
    #[serde(default)]
    pub owed: Vec<f64>,
    /// True once the top could not open a new disk.
    pub blocked: bool,
    /// Per cadence level L ≥ 1 (index L − 1), per disk: the void and starting radius of
    /// the level's current window (`engine::cadence`).
    pub windows: Vec<Vec<Window>>,
    /// The last marker update at which this IMZ drew (0: never).
    pub drew_at: u64,
    /// The marker update at which the mobilised sums were last refreshed (0: never).
    pub refreshed_at: u64,
    /// Per disk, the friction angle φ last seen and its tan(45° + φ/2) (`Imz::slope`).
    #[serde(skip)]
    slopes: Vec<(f64, f64)>,
}

/// IMZ parameters from the scenario.
#[derive(Debug, Clone, Copy)]
pub struct ImzParams {
    /// r-law exponent q.
    pub q: f64,
    /// w = factor × d̄.
    pub shear_band_factor: f64,
    /// A block's porosity jump below which its ground counts as already dilated
    /// (`flow.min_porosity_jump`); also the jump a disk that can widen no further uses.
    pub min_jump: f64,
    /// Resample stagnant properties when R moved by more than this, m.
    pub resample: f64,
    /// Resample the perimeter's dilation state when R moved by more than this, m.
    pub redilate: f64,
    /// Largest spacing of the perimeter points whose dilation state is sampled, m.
    pub perimeter_spacing: f64,
    /// Largest radius a disk may reach (model half-diagonal), m.
    pub r_cap: f64,
}

impl Imz {
    /// A new IMZ: disk 0 sized by the opening (radius = width / 2).
    pub fn new(id: usize, x: f64, y: f64, z0: f64, h: f64, width: f64) -> Imz {
        let r_open = 0.5 * width;
        Imz {
            id,
            geom: ImzGeom {
                x,
                y,
                z0,
                h,
                radius: vec![r_open],
            },
            r_open,
            motion: vec![DiskMotion {
                r: r_open,
                r_old: 0.0,
                ..Default::default()
            }],
            stagnant: vec![Stagnant {
                sampled_at: f64::NAN,
                ..Default::default()
            }],
            mobilised: vec![Mobilised::default()],
            reach: vec![f64::NAN],
            air: 0.0,
            vented: 0.0,
            leaked: Vec::new(),
            owed: Vec::new(),
            blocked: false,
            windows: Vec::new(),
            drew_at: 0,
            refreshed_at: 0,
            slopes: Vec::new(),
        }
    }

    /// Number of disks.
    pub fn disks(&self) -> usize {
        self.geom.radius.len()
    }

    /// Mid-height of disk i.
    pub fn z_mid(&self, i: usize) -> f64 {
        self.geom.z0 + (i as f64 + 0.5) * self.geom.h
    }

    /// Whether the IMZ holds an air gap under ground that has not caved by `period`: its
    /// void waits above the top disk until the ground there caves, and the IMZ's next draw
    /// closes it (`Imz::draw`).
    pub fn under_air_gap(&self, blocks: &crate::model::BlockModel, period: i64) -> bool {
        let top = [self.geom.x, self.geom.y, self.z_mid(self.disks())];
        self.air > 0.0
            && !blocks
                .locate(top)
                .is_some_and(|b| blocks.flowable(b, period))
    }

    /// d̄, φ, ρ_s(1 − n1) and ρ_s of disk i: mobilised where the disk holds markers, else
    /// stagnant.
    pub fn props(&self, i: usize) -> (f64, f64, f64) {
        let m = &self.mobilised[i];
        if m.count > 0 {
            (m.d, m.phi, m.rho1)
        } else {
            let s = &self.stagnant[i];
            (s.d, s.phi, s.rho1)
        }
    }

    /// Newly caved ground: perimeters and reaches must be looked at again.
    pub fn ground_changed(&mut self) {
        self.reach.iter_mut().for_each(|r| *r = f64::NAN);
        self.stagnant
            .iter_mut()
            .for_each(|s| s.sampled_at = f64::NAN);
    }

    /// The largest radius disk i may reach: the reach of flowable ground at its level,
    /// and never more than `r_cap`.
    fn cap(&mut self, i: usize, g: &Ground, p: &ImzParams) -> f64 {
        if self.reach[i].is_nan() {
            self.reach[i] = g.reach(self.geom.x, self.geom.y, self.z_mid(i));
        }
        // Disk 0 keeps at least its opening.
        let floor = if i == 0 { self.r_open } else { 0.0 };
        self.reach[i].min(p.r_cap).max(floor)
    }

    /// Resamples disk i's stagnant properties once its radius moved by more than
    /// `resample` from where they were sampled, and its dilation state once the radius moved
    /// by more than `redilate`.
    fn refresh_stagnant(&mut self, i: usize, g: &Ground, p: &ImzParams) {
        self.refresh_at(i, self.geom.radius[i], g, p);
    }

    /// [`Imz::refresh_stagnant`] at radius `r`.
    fn refresh_at(&mut self, i: usize, r: f64, g: &Ground, p: &ImzParams) {
        let r = r.max(1e-6);
        let (x, y, z) = (self.geom.x, self.geom.y, self.z_mid(i));
        let s = &mut self.stagnant[i];
        if !(s.sampled_at.is_finite() && (r - s.sampled_at).abs() <= p.resample) {
            *s = g.stagnant(self.id, [x, y, z], r, p);
        } else if !(s.dilation_at.is_finite() && (r - s.dilation_at).abs() <= p.redilate) {
            g.dilation(self.id, [x, y, z], r, p, s);
        }
    }

    /// Marks the start of a new marker-update interval: R_old ← R, Δv ← 0.
    pub fn begin_interval(&mut self) {
        for (m, &r) in self.motion.iter_mut().zip(&self.geom.radius) {
            *m = DiskMotion {
                r,
                r_old: r,
                ..Default::default()
            };
        }
    }

    /// The motion over cadence level `level`'s window (≥ 1): the disks as they are now, with
    /// the window's void in and out and starting radius R_i^old.
    pub fn window_motion(&self, level: usize) -> Vec<DiskMotion> {
        self.motion
            .iter()
            .zip(&self.windows[level - 1])
            .map(|(m, w)| DiskMotion {
                dv: w.dv,
                dv_out: w.dv_out,
                r_old: w.r_old,
                ..*m
            })
            .collect()
    }

    /// Fills the per-disk motion fields read by the marker pass (after the draw),
    /// resampling the ground of the disks that moved.
    pub fn finish_interval(&mut self, g: &Ground, p: &ImzParams) {
        for i in 0..self.disks() {
            if self.motion[i].dv > 0.0 {
                self.refresh_stagnant(i, g, p);
            }
            let (d, phi, rho1) = self.props(i);
            let st = self.stagnant[i];
            let m = &mut self.motion[i];
            m.r = self.geom.radius[i];
            m.area_frac = st.area_frac.max(1.0 / 96.0);
            m.flow_frac = st.flow_frac.max(1.0 / PERIMETER_POINTS as f64);
            m.shape = st.shape;
            (m.shape_rest, m.shape_var) = (st.shape_rest, st.shape_var);
            m.w = p.shear_band_factor * d;
            m.d = d;
            m.sigma_n = rho1 * 9.81 * m.r / (2.0 * phi.to_radians().tan().max(1e-6));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn r_law_limits() {
        // Empty disk: r = 1.
        assert_eq!(r_law(0.2, 1.0, 0.0, 1.0, 40.0, 3.5), 1.0);
        // Slope at the minimum positive slope 45 + φ/2: r = 0.
        let phi: f64 = 40.0;
        let dr = 1.0 / (45.0 + phi / 2.0).to_radians().tan();
        // (The bracket is 1 − dr tan β, zero up to rounding, so r is zero up to ~1e-16^q.)
        assert!(r_law(0.2, 1.0, 2.0 + dr, 2.0, phi, 3.5) < 1e-50);
        assert_eq!(r_law(0.2, 1.0, 2.0 + 1.001 * dr, 2.0, phi, 3.5), 0.0);
        // Vertical wall: the bare factor 10 d h / (π R²).
        let r = r_law(0.1, 0.5, 3.0, 3.0, 40.0, 3.5);
        assert!((r - 10.0 * 0.1 * 0.5 / (PI * 9.0)).abs() < 1e-15);
        // Negative slope steep enough: capped at 1.
        assert_eq!(r_law(0.1, 0.5, 0.5, 3.0, 40.0, 3.5), 1.0);
    }

    #[test]
    fn radius_update_conserves_solids() {
        // The ring R → R' of stagnant ground at n0 dilates to n1 at constant solids and fills
        // the share r v of the void, with the disk's material at n1 before and after:
        // (π R² h − r v)(1 − n1) + π h (R'² − R²)(1 − n0) = π R'² h (1 − n1), exactly.
        let (r0, r, v, h, n0, n1) = (2.0, 0.3, 5.0, 0.5, 0.3, 0.45);
        let r1 = grown_radius(r0, r, v, h, dilation(n1 - n0, n1), 1.0);
        let before =
            (PI * r0 * r0 * h - r * v) * (1.0 - n1) + PI * h * (r1 * r1 - r0 * r0) * (1.0 - n0);
        let after = PI * r1 * r1 * h * (1.0 - n1);
        assert!(
            (before - after).abs() < 1e-12 * after,
            "{before} vs {after}"
        );
    }

    #[test]
    fn pow_q_is_powf() {
        for q in [3.5, 3.0, 0.5, 2.25, 0.0, 8.5, 9.0] {
            for b in [0.0, 1e-9, 0.013, 0.5, 0.999, 1.0] {
                let (got, want) = (pow_q(b, q), f64::powf(b, q));
                assert!(
                    (got - want).abs() <= 1e-14 * want.max(1e-300),
                    "{b}^{q}: {got} vs {want}"
                );
            }
        }
    }
}
