//! What the marker pass reads of each disk after an update: its motion ([`DiskMotion`])
//! and the constants worked out from it once per disk ([`PerDisk`]), its vertical profile
//! among them ([`Profile`]).

use super::SHAPE_MODES;

/// Per-disk state that the marker pass reads, accumulated since the last marker update.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
pub struct DiskMotion {
    /// R_i now, m.
    pub r: f64,
    /// R_i at the last marker update (R_i^old), m.
    pub r_old: f64,
    /// Δv_i: void passed up into this disk since the last marker update, m³.
    pub dv: f64,
    /// Void passed out through this disk's top since the last marker update, m³: Δv_{i+1}
    /// for a disk below another (less the air a new disk above took in), or the void that
    /// left the IMZ for the free surface or an air gap. Δv_i − this is the void the disk's
    /// ring absorbed by dilating.
    pub dv_out: f64,
    /// Shear band width w_i = factor × d̄, m.
    pub w: f64,
    /// Janssen normal stress σ_n = ρ_s (1 − n1) g R / (2 tan φ), kPa.
    pub sigma_n: f64,
    /// Flowable share A_f of the disk's area: the void spreads over the material that
    /// exists, so vertical moves are divided by it (1 for a disk in open ground).
    pub area_frac: f64,
    /// Flowable share f of the disk's perimeter: the rays on which a ring dilates and
    /// pushes the interior in.
    pub flow_frac: f64,
    /// Mean fragment size d̄ of the disk, m.
    pub d: f64,
    /// The ring's dilation around the perimeter ([`Stagnant::shape`](super::Stagnant::shape)).
    pub shape: [f64; 2 * SHAPE_MODES],
    /// The variance of the ring's dilation beyond the kept modes, and all of it
    /// ([`Stagnant::shape_rest`](super::Stagnant::shape_rest)).
    pub shape_rest: f64,
    /// See `shape_rest`.
    pub shape_var: f64,
    /// The marker pass's constants of this disk, the same for every marker it moves
    /// (`engine::markers::prepare`; zero until then).
    pub per_disk: PerDisk,
}

/// A disk's constants of the marker pass, worked out once per disk and update
/// (`engine::markers::prepare`) instead of once per marker in it, so that the pass
/// multiplies where the formulas divide.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
pub struct PerDisk {
    /// The disk's vertical profile.
    pub profile: Profile,
    /// The plug's descent per unit void, c / (π A_f) (the void fills the flowable share A_f
    /// of the disk only), 1/m².
    pub fall: f64,
    /// Plan area the dilating ring takes from the interior, (Δv_i − Δv_out) / (h f), m².
    pub take: f64,
    /// Whether the ring pushes in: the disk widened (R > R^old > 0) and absorbed void
    /// (`take` > 0).
    pub widened: bool,
    /// The ring's inward push at R^old, take F(R^old) / (2π R^old), m (0 where the disk
    /// did not widen).
    pub push: f64,
    /// 1 / R^old and 1 / (R − R^old) where the disk widened (0 otherwise), 1/m.
    pub inv_r_old: f64,
    /// See `inv_r_old`.
    pub inv_dr: f64,
    /// Whether the ring's dilation differs around the perimeter (a lateral move).
    pub lateral: bool,
    /// push √(2 σ²), σ² the dilation's variance beyond the kept modes: the RMS of what the
    /// modes left out would move a marker at R_old (`engine::markers::caps`), m.
    pub tail: f64,
    /// Whether a cap of the push, the squeeze or the lateral move can bind in this disk
    /// (`engine::markers::caps`): only then does the pass count what the caps drop.
    pub may_cap: bool,
}

/// The shape of a disk's vertical velocity profile (summary §3.3): a plug of radius
/// R_p = R − w descending at the full speed inside a shear annulus of width w in which the
/// speed falls linearly to zero at R; a cone (R_p = 0, the band the whole radius) when
/// R ≤ w. With void Δv passed into the disk, the plug descends Δv c / π, where
/// c = 3 / (R² + R R_p + R_p²) makes the frustum's volume Δv.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
pub struct Profile {
    /// R_i, m.
    pub r: f64,
    /// R_p, m.
    pub rp: f64,
    /// 1 / the band's width (w, or R for a cone), 1/m.
    pub inv_band: f64,
    /// c, 1/m².
    pub c: f64,
}

impl Profile {
    /// The profile of a disk of radius `r` with shear band `w` (all zero without a radius).
    pub fn new(r: f64, w: f64) -> Profile {
        if !(r > 0.0) {
            return Profile::default();
        }
        let (rp, band) = if r <= w { (0.0, r) } else { (r - w, w) };
        Profile {
            r,
            rp,
            inv_band: 1.0 / band.max(1e-12),
            c: 3.0 / (r * r + r * rp + rp * rp),
        }
    }

    /// The speed at radius `a` relative to the plug's: 1 in the plug, falling linearly to 0
    /// at R, 0 beyond.
    #[inline]
    pub fn shape(&self, a: f64) -> f64 {
        if a > self.r {
            0.0
        } else if a <= self.rp {
            1.0
        } else {
            1.0 - (a - self.rp) * self.inv_band
        }
    }

    /// Vertical displacement Δz_m of a marker at radius `a`, with void `dv` passed into the
    /// disk (in open ground, A_f = 1).
    #[inline]
    pub fn vertical(&self, dv: f64, a: f64) -> f64 {
        -dv * self.c * std::f64::consts::FRAC_1_PI * self.shape(a)
    }

    /// Share F(a) of the disk's vertical flux that passes inside radius `a`:
    /// ∫₀^a |Δz(a′)| 2π a′ da′ / Δv, 0 at the axis and 1 at R (1 without a radius).
    #[inline]
    pub fn flux_inside(&self, a: f64) -> f64 {
        if !(self.r > 0.0) {
            return 1.0;
        }
        let (a, rp) = (a.clamp(0.0, self.r), self.rp);
        if a <= rp {
            self.c * a * a
        } else {
            let (a2, p2) = (a * a, rp * rp);
            self.c * (a2 - 2.0 * ((a2 * a - p2 * rp) / 3.0 - 0.5 * rp * (a2 - p2)) * self.inv_band)
        }
    }

    /// The radius at which the share `f` of the flux passes inside ([`Profile::flux_inside`]
    /// inverted): a square root in the plug, Newton's method kept inside a shrinking
    /// bracket in the shear annulus (F is increasing in a).
    pub fn radius_at_share(&self, f: f64) -> f64 {
        let (f, rp, c) = (f.clamp(0.0, 1.0), self.rp, self.c);
        if f <= c * rp * rp {
            return (f / c).sqrt();
        }
        let (mut lo, mut hi) = (rp, self.r);
        let mut a = (f / c).sqrt().clamp(lo, hi);
        for _ in 0..40 {
            let g = self.flux_inside(a) - f;
            if g.abs() <= 1e-13 {
                break;
            }
            if g < 0.0 {
                lo = a;
            } else {
                hi = a;
            }
            let slope = 2.0 * a * c * self.shape(a);
            let next = a - g / slope;
            a = if slope > 0.0 && next > lo && next < hi {
                next
            } else {
                0.5 * (lo + hi)
            };
            if hi - lo <= 1e-12 * self.r {
                break;
            }
        }
        a
    }
}
