//! Stress logic: vertical and horizontal stress in and around IMZs without finite elements,
//! and the levels where stagnant ground between IMZs may yield and flow (interactive draw,
//! Heslop and Laubscher 1981). Summary §5 ("Interactive draw and the role of stress"), §5.3
//! (REBOP logic); DESIGN §4.4.
//!
//! [`compute`] is a pure function of the block model, the period and the IMZ geometries
//! ([`ImzGeom`]); the engine calls it at the end of the periods the scenario asks for
//! (`[stress] periods`), so it costs nothing when `mechanisms.stress` is off.
//!
//! # Slices (summary §5.3)
//! The caved volume is cut into horizontal levels `cell` apart (default: the IMZ disk
//! thickness h, so a slice is a disk). At each level there are three nested kinds of slice:
//! - **cave slice**: the flowable (caved) ground of the level, from the block model and the
//!   period (`BlockModel::flowable`);
//! - **bin slices**: an isolated IMZ disk, or a cluster of overlapping IMZ disks;
//! - **group slices**: bins whose elastic zones overlap (connected components).
//!
//! # 1. Cave-average vertical stress: Janssen differential slices
//! Top-down over the levels, each slice of thickness Δ, area A, perimeter P, unit weight γ
//! (ρ_s (1 − n0) g, the mean over its flowable cells) obeys Janssen's (1895) balance
//! dσ̄/dd = γ − K μ_w P σ̄ / A. Within a slice the coefficients are constant, so the step is
//! the exact solution σ̄(d + Δ) = γλ + (σ̄(d) − γλ) e^(−Δ/λ), λ = A / (K μ_w P)
//! ([`janssen_step`]). For a uniform cylinder this is the closed form
//! σ̄(d) = γλ (1 − e^(−d/λ)) ([`janssen_closed_form`]) to rounding, and the slices carry
//! non-uniform cave outlines and densities. A level without caved ground resets σ̄ to 0 (an
//! air gap or an uncaved arch above is a free surface for the caved rock below).
//! - **K** (`[stress] cave_k`): Jaky's at-rest K0 = 1 − sin φ by default (the stagnant
//!   caved column hardly strains sideways); Rankine's active Ka = (1 − sin φ)/(1 + sin φ)
//!   as the option.
//! - **Wall friction** μ_w = tan φ_w, φ_w = the caved rock's φ by default (rough rock walls:
//!   slip happens inside the caved rock), or `[stress] wall_friction_deg`.
//! - A and P are counted on the stress grid: A = flowable cells × cell², P = edges between
//!   flowable and other cells × cell. Block-model caves are rasters, so for a cave outline
//!   on the grid this is exact.
//!
//! # 2. Bin stress (low stresses inside IMZs)
//! Inside an IMZ the stress follows Janssen for a tall narrow bin with the IMZ's own radius
//! and friction (summary §5.2): K_bin = `[stress] bin_k` (default 1: DEM and continuum models
//! show vertical and radial stresses inside the IMZ about equal), μ = tan φ of the mobilised
//! rock (the IMZ wall is a shear band inside the caved rock), γ1 = ρ_s (1 − n1) g, A and P of
//! the bin (a cluster's union of disks: exact arcs, see `union_area_perimeter`). The summary
//! finds IMZ stresses independent of IMZ and overburden height, so each IMZ's slices start
//! at the steady (asymptotic) bin stress γ1 λ_bin at its top and are stepped down with
//! [`janssen_step`], following the changing radius. A bin never carries more than the cave
//! average around it: σ_bin ≤ σ̄ (near the cave top).
//!
//! # 3. Plastic and elastic zones: the pressurised shaft (Carranza-Torres 2002)
//! Each bin is a shaft of radius a = 2A/P (its own radius for one disk) in a Mohr–Coulomb
//! material (c, φ of the stagnant ground), with internal pressure p_i = K_bin σ_bin and far
//! field p0 = σ̄: the summary says the plastic zone grows with the vertical stress around
//! the IMZ, so the shaft's far field is the cave-average vertical stress, and the shaft's
//! tangential stress is read as the vertical stress the stagnant ground carries around the
//! IMZ (it is the major stress there, as σ_θ is around a tunnel). With
//! Kp = (1 + sin φ)/(1 − sin φ) and c cot φ ([`Shaft`], Salençon 1969, Carranza-Torres 2002):
//!
//! ```text
//! R_pl = a [2 (p0 + c cot φ) / ((Kp + 1)(p_i + c cot φ))]^(1/(Kp − 1))   (a when ≤ 1)
//! plastic  a ≤ r ≤ R_pl:  σ_r = (p_i + c cot φ)(r/a)^(Kp−1) − c cot φ,  σ_v = Kp σ_r + 2c√Kp
//! elastic  r ≥ R_pl:      σ_r = p0 − D (R_pl/r)²,  σ_v = p0 + D (R_pl/r)²,
//!                         D = p0 − σ_r(R_pl) = p0 − (2 p0 − 2c√Kp)/(Kp + 1)
//! ```
//! - **Elastic zone radius** (the thesis does not print one): the annulus R_pl ≤ r ≤ R_el
//!   whose Lamé excess D (R_pl/r)² carries exactly the vertical force the bin and its
//!   plastic zone shed relative to p0: 2π D R_pl² ln(R_el/R_pl) = S ([`Shaft::shed`]). An
//!   isolated bin in a wide cave slice then balances by itself (tributary area theory).
//!   Beyond R_el the ground is undisturbed (σ_v = σ_h = p0).
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

use rayon::prelude::*;

use super::imz::ImzGeom;
use crate::model::scenario::{LateralRatio, StressSettings};
use crate::model::BlockModel;

/// Gravitational acceleration, m/s²: t/m³ × g = kN/m³, so stresses come out in kPa.
pub const GRAVITY: f64 = 9.81;

/// Points sampled along each pillar between two bins.
pub const PILLAR_SAMPLES: usize = 64;

/// Points per circle when a cluster's union outline is traced (arc error ~ (2π/N)² ≈ 8e-5).
const ARC_SAMPLES: usize = 720;

/// Rounding allowance of the yield test (a fully plastic pillar is at exactly 1).
const YIELD_TOL: f64 = 1e-9;

// ---------------------------------------------------------------------------------------
// Closed forms
// ---------------------------------------------------------------------------------------

/// Passive coefficient Kp = (1 + sin φ)/(1 − sin φ), φ in degrees.
pub fn passive_coefficient(phi_deg: f64) -> f64 {
    let s = phi_deg.to_radians().sin();
    (1.0 + s) / (1.0 - s)
}

/// Lateral stress ratio K of a cave slice for φ in degrees.
pub fn lateral_ratio(kind: LateralRatio, phi_deg: f64) -> f64 {
    let s = phi_deg.to_radians().sin();
    match kind {
        LateralRatio::Jaky => 1.0 - s,
        LateralRatio::Rankine => (1.0 - s) / (1.0 + s),
    }
}

/// c cot φ, kPa (0 when c = 0).
fn c_cot(c: f64, phi_deg: f64) -> f64 {
    if c > 0.0 {
        c / phi_deg.to_radians().tan()
    } else {
        0.0
    }
}

/// Janssen's closed form for a uniform bin: mean vertical stress at depth `depth` below a
/// surcharge `q`: σ = γλ (1 − e^(−d/λ)) + q e^(−d/λ), λ = A / (K μ P).
pub fn janssen_closed_form(
    gamma: f64,
    area: f64,
    perimeter: f64,
    k: f64,
    mu: f64,
    depth: f64,
    q: f64,
) -> f64 {
    let lambda = area / (k * mu * perimeter);
    gamma * lambda * (1.0 - (-depth / lambda).exp()) + q * (-depth / lambda).exp()
}

/// Janssen length λ = A / (K μ P) of a slice, m (infinite without walls).
pub fn janssen_length(area: f64, perimeter: f64, k: f64, mu: f64) -> f64 {
    let d = k * mu * perimeter;
    if d > 0.0 {
        area / d
    } else {
        f64::INFINITY
    }
}

/// One exact Janssen step down a slice of constant γ and λ: σ(d + Δ) = γλ + (σ − γλ) e^(−Δ/λ)
/// (σ + γΔ, geostatic, when λ is infinite).
pub fn janssen_step(sigma: f64, gamma: f64, lambda: f64, dz: f64) -> f64 {
    if lambda.is_infinite() {
        return sigma + gamma * dz;
    }
    let x = -dz / lambda;
    // σ e^x + γλ (1 − e^x), with exp_m1 so thin slices keep full precision.
    sigma * x.exp() - gamma * lambda * x.exp_m1()
}

/// One horizontal slice of the Janssen integration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JanssenSlice {
    /// Thickness Δ, m.
    pub thickness: f64,
    /// Area A, m² (0: no caved ground).
    pub area: f64,
    /// Perimeter P in contact with walls, m.
    pub perimeter: f64,
    /// Unit weight γ, kN/m³.
    pub unit_weight: f64,
    /// Lateral stress ratio K.
    pub k: f64,
    /// Wall friction coefficient μ.
    pub mu: f64,
}

/// Mean vertical stress at mid-depth of each slice, top slice first, under a surcharge `q`
/// at the top (method of differential slices, Janssen 1895). A slice with no area gets NaN
/// and resets the stress to 0 below it.
pub fn janssen_profile(slices: &[JanssenSlice], q: f64) -> Vec<f64> {
    let mut sigma = q;
    slices
        .iter()
        .map(|s| {
            if !(s.area > 0.0) {
                sigma = 0.0;
                return f64::NAN;
            }
            let lambda = janssen_length(s.area, s.perimeter, s.k, s.mu);
            let mid = janssen_step(sigma, s.unit_weight, lambda, 0.5 * s.thickness);
            sigma = janssen_step(sigma, s.unit_weight, lambda, s.thickness);
            mid
        })
        .collect()
}

/// Plastic radius of a pressurised shaft of radius `a` in a Mohr–Coulomb material
/// (Salençon 1969; Carranza-Torres 2002): internal pressure `p_i`, far field `p0`, φ in
/// degrees, cohesion `c`:
/// R_pl = a [2 (p0 + c cot φ) / ((Kp + 1)(p_i + c cot φ))]^(1/(Kp − 1)), and a when the
/// bracket is ≤ 1 (no yield). Infinite when p_i + c cot φ ≤ 0 < p0 + c cot φ.
pub fn plastic_radius(a: f64, p_i: f64, p0: f64, phi_deg: f64, c: f64) -> f64 {
    let kp = passive_coefficient(phi_deg);
    let cc = c_cot(c, phi_deg);
    if p_i + cc <= 0.0 {
        return if p0 + cc > 0.0 { f64::INFINITY } else { a };
    }
    let bracket = 2.0 * (p0 + cc) / ((kp + 1.0) * (p_i + cc));
    if bracket <= 1.0 {
        a
    } else {
        a * bracket.powf(1.0 / (kp - 1.0))
    }
}

/// Where a point lies relative to one bin's shaft solution.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ShaftZone {
    /// a ≤ r < R_pl.
    Plastic,
    /// R_pl ≤ r < R_el.
    Elastic,
    /// r ≥ R_el: undisturbed.
    Outside,
}

/// The pressurised-shaft solution around one bin (see the module docs, §3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shaft {
    /// Shaft (bin) radius a, m.
    pub a: f64,
    /// Internal pressure p_i, kPa.
    pub p_i: f64,
    /// Far-field stress p0, kPa.
    pub p0: f64,
    /// Friction angle, degrees.
    pub phi: f64,
    /// Cohesion, kPa.
    pub c: f64,
    /// Kp.
    pub kp: f64,
    /// c cot φ, kPa.
    pub cc: f64,
    /// Plastic radius, m.
    pub r_pl: f64,
    /// Radial stress at R_pl, kPa.
    pub sr_pl: f64,
    /// Lamé amplitude D = p0 − σ_r(R_pl), kPa.
    pub d: f64,
    /// Elastic zone radius R_el, m.
    pub r_el: f64,
}

impl Shaft {
    /// The solution for a bin of radius `a` carrying `sigma_bin` inside (its own vertical
    /// stress, which sets what it sheds) with internal pressure `p_i`.
    pub fn new(a: f64, sigma_bin: f64, p_i: f64, p0: f64, phi: f64, c: f64) -> Shaft {
        let kp = passive_coefficient(phi);
        let cc = c_cot(c, phi);
        let r_pl = plastic_radius(a, p_i, p0, phi, c);
        // Radial stress at R_pl: from yield where there is a plastic zone, p_i where not.
        let sr_pl = if r_pl > a {
            (2.0 * p0 - 2.0 * c * kp.sqrt()) / (kp + 1.0)
        } else {
            p_i
        };
        let mut s = Shaft {
            a,
            p_i,
            p0,
            phi,
            c,
            kp,
            cc,
            r_pl,
            sr_pl,
            d: p0 - sr_pl,
            r_el: r_pl,
        };
        let shed = s.shed(sigma_bin);
        if shed > 0.0 && s.d > 0.0 && r_pl.is_finite() {
            // Bounded at 20 a: beyond that the Lamé tail is below the grid's noise anyway.
            let x = (shed / (2.0 * PI * s.d * r_pl * r_pl)).min((20.0 * a / r_pl).ln().max(0.0));
            s.r_el = r_pl * x.exp();
        }
        s
    }

    /// Vertical force, relative to p0 everywhere, that the bin (carrying `sigma_bin`) and its
    /// plastic zone do not carry, kN: S = (p0 − σ_bin) π a² + ∫_a^R_pl (p0 − σ_v) 2πr dr.
    pub fn shed(&self, sigma_bin: f64) -> f64 {
        let (a, r, kp, cc) = (self.a, self.r_pl, self.kp, self.cc);
        let bin = (self.p0 - sigma_bin) * PI * a * a;
        if !(r > a) || !r.is_finite() {
            return bin;
        }
        // ∫ σ_v 2πr dr with σ_v + cc = Kp (p_i + cc)(r/a)^(Kp−1).
        let carried = 2.0 * PI * kp * (self.p_i + cc) * a * a * ((r / a).powf(kp + 1.0) - 1.0)
            / (kp + 1.0)
            - cc * PI * (r * r - a * a);
        bin + self.p0 * PI * (r * r - a * a) - carried
    }

    /// Zone, radial stress σ_r and vertical stress σ_v at distance `r` ≥ a from the axis.
    pub fn at(&self, r: f64) -> (ShaftZone, f64, f64) {
        if r < self.r_pl {
            let sr = (self.p_i + self.cc) * (r / self.a).powf(self.kp - 1.0) - self.cc;
            (ShaftZone::Plastic, sr, self.yield_stress(sr))
        } else {
            let f = self.d * (self.r_pl / r).powi(2);
            let zone = if r < self.r_el {
                ShaftZone::Elastic
            } else {
                ShaftZone::Outside
            };
            (zone, self.p0 - f, self.p0 + f)
        }
    }

    /// Major stress at yield for a minor stress σ3: Kp σ3 + 2c√Kp.
    pub fn yield_stress(&self, s3: f64) -> f64 {
        self.kp * (s3 + self.cc) - self.cc
    }
}

/// Stress:strength ratio (σ1 + c cot φ) / (Kp (σ3 + c cot φ)); infinite without confinement.
pub fn stress_strength_ratio(s1: f64, s3: f64, kp: f64, cc: f64) -> f64 {
    let strength = kp * (s3 + cc);
    if strength > 0.0 {
        (s1 + cc) / strength
    } else {
        f64::INFINITY
    }
}

/// Area and perimeter of a union of disks (x, y, r): exact for one disk; for several, the
/// exposed arcs traced at [`ARC_SAMPLES`] points per circle, area by Green's theorem.
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

// ---------------------------------------------------------------------------------------
// The field
// ---------------------------------------------------------------------------------------

/// What a point of a cave slice is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[repr(u8)]
pub enum Zone {
    /// Not caved (or outside the model): no stress computed.
    Uncaved = 0,
    /// Inside an IMZ (a bin).
    Imz = 1,
    /// Stagnant, in a plastic zone.
    Plastic = 2,
    /// Stagnant, in an elastic zone.
    Elastic = 3,
    /// Stagnant, outside every elastic zone (outside the draw area).
    Far = 4,
}

impl Zone {
    /// Name written to Parquet.
    pub fn name(self) -> &'static str {
        match self {
            Zone::Uncaved => "uncaved",
            Zone::Imz => "imz",
            Zone::Plastic => "plastic",
            Zone::Elastic => "elastic",
            Zone::Far => "far",
        }
    }
}

/// Orientation of a section.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Orientation {
    /// Vertical, along Northing at a fixed Easting.
    NorthSouth,
    /// Vertical, along Easting at a fixed Northing.
    EastWest,
    /// Horizontal, at a fixed elevation.
    Plan,
}

impl Orientation {
    /// Name written to Parquet.
    pub fn name(self) -> &'static str {
        match self {
            Orientation::NorthSouth => "ns",
            Orientation::EastWest => "ew",
            Orientation::Plan => "plan",
        }
    }
}

/// Stress on one section, on a regular grid of `shape.0` × `shape.1` points (u fastest):
/// (Northing, z) for N-S, (Easting, z) for E-W, (Easting, Northing) for plan.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StressSection {
    /// Orientation (None only in `Default`).
    pub orientation: Option<Orientation>,
    /// Easting (N-S), Northing (E-W) or elevation (plan) of the section, m.
    pub at: f64,
    /// Grid points (n_u, n_v).
    pub shape: (usize, usize),
    /// Grid spacing, m.
    pub cell: f64,
    /// Point coordinates, m.
    pub x: Vec<f64>,
    /// Point coordinates, m.
    pub y: Vec<f64>,
    /// Point coordinates, m.
    pub z: Vec<f64>,
    /// Vertical stress carried, kPa (NaN where uncaved).
    pub sigma_v: Vec<f64>,
    /// Horizontal (radial) stress, kPa (NaN where uncaved).
    pub sigma_h: Vec<f64>,
    /// Stress:strength ratio of stagnant ground (NaN in IMZs and uncaved ground).
    pub ratio: Vec<f64>,
    /// Zone of each point.
    pub zone: Vec<Zone>,
    /// Vertical sections: IMZ disks cut by the plane, per drawpoint: (axis u, [(z_base,
    /// z_top, half chord)]). Plan sections: IMZ circles (x, y, r) in `circles`.
    pub imz: Vec<(f64, Vec<(f64, f64, f64)>)>,
    /// Plan sections: IMZ disks cut by the plane (x, y, r).
    pub circles: Vec<(f64, f64, f64)>,
    /// Drawpoints on (vertical) or under (plan) the section: (u, v, drawpoint index).
    pub drawpoints: Vec<(f64, f64, usize)>,
}

impl StressSection {
    /// Section name, e.g. `ns_x=0.000`.
    pub fn name(&self) -> String {
        match self.orientation {
            Some(Orientation::NorthSouth) => format!("ns_x={:.3}", self.at),
            Some(Orientation::EastWest) => format!("ew_y={:.3}", self.at),
            Some(Orientation::Plan) => format!("plan_z={:.3}", self.at),
            None => "section".into(),
        }
    }
}

/// Per-level results (one row per level, bottom up).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StressLevels {
    /// Level elevation (slice mid-height), m.
    pub z: Vec<f64>,
    /// Cave slice area, m².
    pub cave_area: Vec<f64>,
    /// Cave slice perimeter, m.
    pub cave_perimeter: Vec<f64>,
    /// Janssen cave-average vertical stress σ̄, kPa (NaN without caved ground).
    pub sigma_v_cave: Vec<f64>,
    /// Area-weighted mean of the redistributed vertical stress over the cave slice, kPa.
    pub sigma_v_mean: Vec<f64>,
    /// Bin slices.
    pub bins: Vec<i64>,
    /// Group slices.
    pub groups: Vec<i64>,
    /// Pillars between bins of one group.
    pub pillars: Vec<i64>,
    /// Largest pillar minimum stress:strength ratio (NaN without pillars).
    pub pillar_ratio: Vec<f64>,
    /// Mean stress:strength ratio of the stagnant ground inside the elastic zones (NaN
    /// without IMZs).
    pub stagnant_ratio: Vec<f64>,
    /// Force arched onto the stagnant ground to keep the slice average (outside the draw
    /// area first), over the slice area, kPa; negative when taken back.
    pub arched: Vec<f64>,
    /// Potential stress-driven flow of stagnant ground (a pillar yields).
    pub flagged: Vec<bool>,
}

/// The stress logic's result at the end of one period.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StressField {
    /// Period number.
    pub period: i64,
    /// Grid cell and level spacing used, m.
    pub cell: f64,
    /// Per-level results.
    pub levels: StressLevels,
    /// Sections.
    pub sections: Vec<StressSection>,
    /// Cumulative tonnes drawn per drawpoint so far (labels; filled by the engine).
    pub drawn_tonnes: Vec<f64>,
}

/// Resolved parameters of one computation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StressParams {
    /// Grid cell and level spacing, m.
    pub cell: f64,
    /// Cohesion c, kPa.
    pub cohesion: f64,
    /// K of the cave slices.
    pub cave_k: LateralRatio,
    /// K inside IMZs.
    pub bin_k: f64,
    /// Wall friction angle, degrees (None: the caved rock's φ).
    pub wall_friction: Option<f64>,
}

impl StressParams {
    /// From the scenario's settings; `h` is the IMZ disk thickness (default cell).
    pub fn new(s: &StressSettings, h: f64) -> StressParams {
        StressParams {
            cell: s.cell.unwrap_or(h),
            cohesion: s.cohesion_kpa,
            cave_k: s.cave_k,
            bin_k: s.bin_k,
            wall_friction: s.wall_friction_deg,
        }
    }
}

/// One IMZ disk at a level.
#[derive(Debug, Clone, Copy)]
struct Disk {
    imz: usize,
    x: f64,
    y: f64,
    r: f64,
}

/// One bin slice at a level.
#[derive(Debug, Clone)]
struct Bin {
    /// Indices into the level's disks.
    members: Vec<usize>,
    area: f64,
    perimeter: f64,
    /// Unit weight of the mobilised rock, kN/m³, and its φ.
    gamma: f64,
    phi: f64,
    /// Bin stress σ_bin, kPa.
    sigma: f64,
    shaft: Shaft,
    /// Bounding box of the disks (x0, x1, y0, y1).
    bbox: [f64; 4],
}

/// The cave slice of one level.
#[derive(Debug, Clone, Default)]
struct CaveSlice {
    /// Flowable raster (nx × ny).
    flow: Vec<bool>,
    area: f64,
    perimeter: f64,
    gamma: f64,
    phi: f64,
}

/// Everything known about one level before the field is evaluated.
#[derive(Debug, Clone, Default)]
struct Level {
    z: f64,
    cave: CaveSlice,
    sigma: f64,
    disks: Vec<Disk>,
    bins: Vec<Bin>,
    /// Group of each bin.
    group: Vec<usize>,
    groups: usize,
    /// Force balance (see [`balance`]): share of its headroom (or, when the field carries
    /// too much, of its stress) each zone receives, by `Zone as usize`; whether the shares
    /// apply to headroom; stress added evenly to all stagnant ground once every zone is at
    /// yield; and the arched force over the slice area (reported), kPa.
    fill: [f64; 5],
    on_headroom: bool,
    uniform: f64,
    arched: f64,
    /// While the balance is worked out: `finish` returns the stress before the fill, with
    /// the headroom to yield in `ratio`.
    raw: bool,
}

/// The stress grid.
#[derive(Debug, Clone, Copy)]
struct Grid {
    origin: [f64; 3],
    cell: f64,
    n: [usize; 3],
}

impl Grid {
    fn centre(&self, a: usize, i: usize) -> f64 {
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
struct PointStress {
    zone: Zone,
    sigma_v: f64,
    sigma_h: f64,
    ratio: f64,
}

impl Level {
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
    fn point(&self, x: f64, y: f64, params: &StressParams) -> PointStress {
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

/// Computes the stress field at the end of `period` for the IMZ geometries `geoms` (one per
/// drawpoint, in drawpoint order). See the module docs for the method.
pub fn compute(
    bm: &BlockModel,
    period: i64,
    geoms: &[ImzGeom],
    params: &StressParams,
    settings: &StressSettings,
) -> StressField {
    let cell = params.cell;
    let max = bm.max_corner();
    let n = [0, 1, 2].map(|a| (((max[a] - bm.origin[a]) / cell - 1e-9).ceil() as usize).max(1));
    let grid = Grid {
        origin: bm.origin,
        cell,
        n,
    };
    let mut levels: Vec<Level> = (0..n[2])
        .into_par_iter()
        .map(|k| {
            let z = grid.centre(2, k);
            Level {
                z,
                cave: cave_slice(bm, period, &grid, z),
                disks: disks_at(geoms, z),
                ..Default::default()
            }
        })
        .collect();

    // 1. Janssen cave average, top-down.
    let slices: Vec<JanssenSlice> = levels
        .iter()
        .rev()
        .map(|l| {
            let wall = params.wall_friction.unwrap_or(l.cave.phi);
            JanssenSlice {
                thickness: cell,
                area: l.cave.area,
                perimeter: l.cave.perimeter,
                unit_weight: l.cave.gamma,
                k: lateral_ratio(params.cave_k, l.cave.phi),
                mu: wall.to_radians().tan(),
            }
        })
        .collect();
    let profile = janssen_profile(&slices, 0.0);
    for (l, s) in levels.iter_mut().rev().zip(profile) {
        l.sigma = s;
    }

    // 2. Bins and their Janssen stress, top-down per IMZ.
    let mut state = vec![f64::NAN; geoms.len()];
    for l in levels.iter_mut().rev() {
        l.bins = bins_at(bm, &l.disks, l.z);
        let mut below = Vec::new();
        for bin in &mut l.bins {
            let lambda = janssen_length(
                bin.area,
                bin.perimeter,
                params.bin_k,
                bin.phi.to_radians().tan(),
            );
            let steady = bin.gamma * lambda;
            let (mut s, mut w) = (0.0, 0.0);
            for &m in &bin.members {
                let k = &l.disks[m];
                if state[k.imz].is_finite() {
                    s += state[k.imz] * k.r * k.r;
                    w += k.r * k.r;
                }
            }
            let top = if w > 0.0 { s / w } else { steady };
            let mid = janssen_step(top, bin.gamma, lambda, 0.5 * cell);
            let bottom = janssen_step(top, bin.gamma, lambda, cell);
            below.extend(bin.members.iter().map(|&m| (l.disks[m].imz, bottom)));
            bin.sigma = if l.sigma.is_finite() {
                mid.min(l.sigma)
            } else {
                mid
            };
        }
        for (imz, s) in below {
            state[imz] = s;
        }
    }

    // 3–5. Shafts, groups, the field, force balance, pillars and sections, per level.
    let specs = section_specs(bm, geoms, settings, &grid);
    let per_level: Vec<(LevelRow, Vec<SectionRows>)> = levels
        .par_iter_mut()
        .map(|l| {
            let row = solve_level(l, &grid, params);
            let rows = specs
                .iter()
                .map(|s| section_rows(l, s, &grid, params, geoms))
                .collect();
            (row, rows)
        })
        .collect();

    let mut out = StressField {
        period,
        cell,
        ..Default::default()
    };
    let lv = &mut out.levels;
    for (l, (row, _)) in levels.iter().zip(&per_level) {
        lv.z.push(l.z);
        lv.cave_area.push(l.cave.area);
        lv.cave_perimeter.push(l.cave.perimeter);
        lv.sigma_v_cave.push(l.sigma);
        lv.sigma_v_mean.push(row.mean);
        lv.bins.push(l.bins.len() as i64);
        lv.groups.push(l.groups as i64);
        lv.pillars.push(row.pillars as i64);
        lv.pillar_ratio.push(row.pillar_ratio);
        lv.stagnant_ratio.push(row.stagnant_ratio);
        lv.arched.push(l.arched);
        lv.flagged.push(row.flagged);
    }
    for (s, spec) in specs.iter().enumerate() {
        let mut sec = StressSection {
            orientation: Some(spec.orientation),
            at: spec.at,
            cell,
            ..Default::default()
        };
        for (_, rows) in &per_level {
            let r = &rows[s];
            sec.x.extend(&r.x);
            sec.y.extend(&r.y);
            sec.z.extend(&r.z);
            sec.sigma_v.extend(&r.sigma_v);
            sec.sigma_h.extend(&r.sigma_h);
            sec.ratio.extend(&r.ratio);
            sec.zone.extend(&r.zone);
        }
        let nu = spec.u.len();
        sec.shape = (nu, if nu > 0 { sec.x.len() / nu } else { 0 });
        decorate(&mut sec, geoms);
        out.sections.push(sec);
    }
    out
}

/// The cave slice at elevation z on the grid.
fn cave_slice(bm: &BlockModel, period: i64, grid: &Grid, z: f64) -> CaveSlice {
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
                !(a >= 0 && b >= 0 && (a as usize) < nx && (b as usize) < ny)
                    || !flow[a as usize + nx * b as usize]
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
fn disks_at(geoms: &[ImzGeom], z: f64) -> Vec<Disk> {
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
fn bins_at(bm: &BlockModel, disks: &[Disk], z: f64) -> Vec<Bin> {
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
struct LevelRow {
    mean: f64,
    pillars: usize,
    pillar_ratio: f64,
    stagnant_ratio: f64,
    flagged: bool,
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
fn solve_level(l: &mut Level, grid: &Grid, params: &StressParams) -> LevelRow {
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

/// Where a section is and the grid coordinates it samples.
#[derive(Debug, Clone)]
struct SectionSpec {
    orientation: Orientation,
    at: f64,
    /// Along-section coordinates (y for N-S, x for E-W and plan).
    u: Vec<f64>,
    /// Plan sections: Northings.
    v: Vec<f64>,
}

/// The sections asked for, defaults filled in (see `StressSettings`): N-S and E-W through the
/// drawpoint axis nearest the centre of the drawpoints (so the section cuts IMZs on their
/// axes, like the summary's Fig 24), and a plan at the mean mid-height of the IMZs.
fn section_specs(
    bm: &BlockModel,
    geoms: &[ImzGeom],
    settings: &StressSettings,
    grid: &Grid,
) -> Vec<SectionSpec> {
    let max = bm.max_corner();
    let axis_near_centre = |coord: &dyn Fn(&ImzGeom) -> f64, a: usize| -> f64 {
        if geoms.is_empty() {
            return 0.5 * (bm.origin[a] + max[a]);
        }
        let lo = geoms.iter().map(coord).fold(f64::INFINITY, f64::min);
        let hi = geoms.iter().map(coord).fold(f64::NEG_INFINITY, f64::max);
        let c = 0.5 * (lo + hi);
        geoms
            .iter()
            .map(coord)
            .min_by(|p, q| (p - c).abs().total_cmp(&(q - c).abs()))
            .unwrap_or(c)
    };
    let ns = settings
        .ns_x
        .clone()
        .unwrap_or_else(|| vec![axis_near_centre(&|g| g.x, 0)]);
    let ew = settings
        .ew_y
        .clone()
        .unwrap_or_else(|| vec![axis_near_centre(&|g| g.y, 1)]);
    let plan = settings.plan_z.clone().unwrap_or_else(|| {
        let mids: Vec<f64> = geoms
            .iter()
            .filter_map(|g| {
                let top = g.radius.iter().rposition(|&r| r > 0.0)?;
                Some(g.z0 + 0.5 * (top + 1) as f64 * g.h)
            })
            .collect();
        if mids.is_empty() {
            vec![0.5 * (bm.origin[2] + max[2])]
        } else {
            vec![mids.iter().sum::<f64>() / mids.len() as f64]
        }
    });
    let xs: Vec<f64> = (0..grid.n[0]).map(|i| grid.centre(0, i)).collect();
    let ys: Vec<f64> = (0..grid.n[1]).map(|j| grid.centre(1, j)).collect();
    let mut specs = Vec::new();
    for at in ns {
        specs.push(SectionSpec {
            orientation: Orientation::NorthSouth,
            at,
            u: ys.clone(),
            v: Vec::new(),
        });
    }
    for at in ew {
        specs.push(SectionSpec {
            orientation: Orientation::EastWest,
            at,
            u: xs.clone(),
            v: Vec::new(),
        });
    }
    for at in plan {
        specs.push(SectionSpec {
            orientation: Orientation::Plan,
            at,
            u: xs.clone(),
            v: ys.clone(),
        });
    }
    specs
}

/// The points one level contributes to one section.
#[derive(Debug, Clone, Default)]
struct SectionRows {
    x: Vec<f64>,
    y: Vec<f64>,
    z: Vec<f64>,
    sigma_v: Vec<f64>,
    sigma_h: Vec<f64>,
    ratio: Vec<f64>,
    zone: Vec<Zone>,
}

fn section_rows(
    l: &Level,
    spec: &SectionSpec,
    grid: &Grid,
    params: &StressParams,
    _geoms: &[ImzGeom],
) -> SectionRows {
    let points: Vec<(f64, f64)> = match spec.orientation {
        Orientation::NorthSouth => spec.u.iter().map(|&y| (spec.at, y)).collect(),
        Orientation::EastWest => spec.u.iter().map(|&x| (x, spec.at)).collect(),
        Orientation::Plan => {
            let h = 0.5 * grid.cell;
            if !(spec.at >= l.z - h && spec.at < l.z + h) {
                return SectionRows::default();
            }
            spec.v
                .iter()
                .flat_map(|&y| spec.u.iter().map(move |&x| (x, y)))
                .collect()
        }
    };
    let mut rows = SectionRows::default();
    for (x, y) in points {
        let i = ((x - grid.origin[0]) / grid.cell).floor();
        let j = ((y - grid.origin[1]) / grid.cell).floor();
        let inside = i >= 0.0 && j >= 0.0 && (i as usize) < grid.n[0] && (j as usize) < grid.n[1];
        let flow = inside
            && l.cave.area > 0.0
            && l.sigma.is_finite()
            && l.cave.flow[i as usize + grid.n[0] * j as usize];
        rows.x.push(x);
        rows.y.push(y);
        rows.z.push(l.z);
        if flow {
            let p = l.point(x, y, params);
            rows.sigma_v.push(p.sigma_v);
            rows.sigma_h.push(p.sigma_h);
            rows.ratio.push(p.ratio);
            rows.zone.push(p.zone);
        } else {
            rows.sigma_v.push(f64::NAN);
            rows.sigma_h.push(f64::NAN);
            rows.ratio.push(f64::NAN);
            rows.zone.push(Zone::Uncaved);
        }
    }
    rows
}

/// IMZ outlines and drawpoints for a section's charts.
fn decorate(sec: &mut StressSection, geoms: &[ImzGeom]) {
    let half = 0.5 * sec.cell;
    for (d, g) in geoms.iter().enumerate() {
        match sec.orientation {
            Some(o @ (Orientation::NorthSouth | Orientation::EastWest)) => {
                let (off, axis) = if o == Orientation::NorthSouth {
                    (g.x - sec.at, g.y)
                } else {
                    (g.y - sec.at, g.x)
                };
                let stack: Vec<(f64, f64, f64)> = g
                    .radius
                    .iter()
                    .enumerate()
                    .filter(|(_, &r)| r > off.abs())
                    .map(|(i, &r)| {
                        let zb = g.z0 + i as f64 * g.h;
                        (zb, zb + g.h, (r * r - off * off).sqrt())
                    })
                    .collect();
                if !stack.is_empty() {
                    sec.imz.push((axis, stack));
                }
                if off.abs() <= half {
                    sec.drawpoints.push((axis, g.z0, d));
                }
            }
            Some(Orientation::Plan) => {
                sec.drawpoints.push((g.x, g.y, d));
            }
            None => {}
        }
    }
    if sec.orientation == Some(Orientation::Plan) {
        sec.circles = disks_at(geoms, sec.at)
            .into_iter()
            .map(|k| (k.x, k.y, k.r))
            .collect();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::synthetic::UniformBox;

    fn rel(a: f64, b: f64) -> f64 {
        (a - b).abs() / b.abs().max(1e-300)
    }

    /// A uniform cylinder (R = 0.5 m, γ = 17 kN/m³, φ = 35°, Jaky K, μ = tan φ), 3 m in 60
    /// slices: the slice profile is the closed form at every mid-depth. Each step is the
    /// exact solution, so only rounding separates them (measured below 1e-14); the brief's
    /// 1e-6 is the bound asserted. The Python reference values pin the closed form itself.
    #[test]
    fn janssen_slices_match_the_closed_form_for_a_uniform_cylinder() {
        let (r, gamma, phi) = (0.5, 17.0, 35.0);
        let (area, perim) = (PI * r * r, 2.0 * PI * r);
        let k = lateral_ratio(LateralRatio::Jaky, phi);
        let mu = f64::tan(phi.to_radians());
        let slice = JanssenSlice {
            thickness: 0.05,
            area,
            perimeter: perim,
            unit_weight: gamma,
            k,
            mu,
        };
        let profile = janssen_profile(&[slice; 60], 0.0);
        let mut worst: f64 = 0.0;
        for (i, s) in profile.iter().enumerate() {
            let d = (i as f64 + 0.5) * 0.05;
            worst = worst.max(rel(
                *s,
                janssen_closed_form(gamma, area, perim, k, mu, d, 0.0),
            ));
        }
        eprintln!("worst relative difference {worst:.2e}");
        assert!(worst < 1e-6, "{worst}");
        // Independent values (Python, same formula): depth 1.0 and 2.95 m.
        let cf = |d| janssen_closed_form(gamma, area, perim, k, mu, d, 0.0);
        assert!(rel(cf(1.0), 9.922329855038772) < 1e-12);
        assert!(rel(cf(2.95), 13.813879805735656) < 1e-12);
        // Slice 58's mid-depth is 2.925 m (Python: 13.801152463141731).
        assert!(rel(profile[58], 13.801152463141731) < 1e-6);
        // With a surcharge, and across a level without caved ground (reset to 0).
        let with_q = janssen_profile(&[slice; 4], 5.0);
        assert!(
            rel(
                with_q[3],
                janssen_closed_form(gamma, area, perim, k, mu, 0.175, 5.0)
            ) < 1e-12
        );
        let gap = JanssenSlice { area: 0.0, ..slice };
        let p = janssen_profile(&[slice, gap, slice], 0.0);
        assert!(p[1].is_nan() && rel(p[2], p[0]) < 1e-15);
    }

    /// R_pl against the closed form evaluated independently (Python): a = 1, p_i = 10,
    /// p0 = 100 kPa, φ = 30°, c = 5 kPa gives 1.7063243337302858; c = 0, φ = 40°, p_i = 1,
    /// p0 = 30 gives 1.9329073792445255. Both are one formula evaluation: 1e-12.
    #[test]
    fn plastic_radius_matches_the_mohr_coulomb_closed_form() {
        assert!(
            rel(
                plastic_radius(1.0, 10.0, 100.0, 30.0, 5.0),
                1.7063243337302858
            ) < 1e-12
        );
        assert!(
            rel(
                plastic_radius(0.1, 1.0, 30.0, 40.0, 0.0),
                0.19329073792445255
            ) < 1e-12
        );
        // No yield when the inner pressure reaches σ_r at the would-be boundary.
        assert_eq!(plastic_radius(2.0, 60.0, 100.0, 30.0, 0.0), 2.0);
        // The closed form is what continuity gives: at R_pl the plastic σ_r equals the
        // elastic one and the elastic side is exactly at yield (σ_v = Kp σ_r + 2c√Kp).
        let s = Shaft::new(1.0, 10.0, 10.0, 100.0, 30.0, 5.0);
        let r = s.r_pl;
        let (z_in, sr_in, _) = s.at(r * (1.0 - 1e-12));
        let (z_out, sr_out, sv_out) = s.at(r);
        assert_eq!((z_in, z_out), (ShaftZone::Plastic, ShaftZone::Elastic));
        assert!(rel(sr_in, sr_out) < 1e-9, "{sr_in} {sr_out}");
        let c_kp = 2.0 * 5.0 * s.kp.sqrt();
        assert!(rel(sv_out, s.kp * sr_out + c_kp) < 1e-12);
        // Lamé in the elastic zone: σ_r + σ_v = 2 p0.
        let (_, a, b) = s.at(1.3 * r);
        assert!(rel(a + b, 200.0) < 1e-12);
        // At the wall σ_r = p_i.
        assert!(rel(s.at(1.0).1, 10.0) < 1e-12);
    }

    /// The elastic zone radius makes one isolated bin balance: ∫_0^R_el σ_v 2πr dr =
    /// p0 π R_el². Midpoint quadrature with 2e5 rings: error ~1e-9; asserted 1e-6.
    #[test]
    fn an_isolated_bin_sheds_exactly_what_its_elastic_zone_carries() {
        for (sigma_bin, c) in [(2.0, 0.0), (2.0, 3.0), (25.0, 0.0)] {
            let s = Shaft::new(0.2, sigma_bin, sigma_bin, 30.0, 40.0, c);
            let n = 200_000;
            let mut force = sigma_bin * PI * s.a * s.a;
            let dr = (s.r_el - s.a) / n as f64;
            for k in 0..n {
                let r = s.a + (k as f64 + 0.5) * dr;
                force += s.at(r).2 * 2.0 * PI * r * dr;
            }
            let want = 30.0 * PI * s.r_el * s.r_el;
            eprintln!(
                "σ_bin {sigma_bin} c {c}: R_pl {:.4} R_el {:.4}",
                s.r_pl, s.r_el
            );
            assert!(s.r_el > s.r_pl);
            assert!(rel(force, want) < 1e-6, "{force} {want}");
        }
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

    fn geom(x: f64, y: f64, radii: &[f64]) -> ImzGeom {
        ImzGeom {
            x,
            y,
            z0: 0.0,
            h: 0.05,
            radius: radii.to_vec(),
        }
    }

    /// Per level, the redistributed vertical stress averages to the Janssen cave average
    /// over the cave slice. The balance is imposed on the same raster it is checked on, so
    /// only rounding remains (sums of ~1e4 cells): 1e-9 relative.
    #[test]
    fn redistribution_keeps_the_cave_slice_average() {
        let scene = UniformBox {
            extent: [1.2, 1.0, 1.0],
            ..UniformBox::castro_isolated()
        }
        .scene();
        // Two IMZs 0.3 m apart, widening upward, and one cluster of two overlapping ones.
        let r: Vec<f64> = (0..16).map(|i| 0.06 + 0.006 * i as f64).collect();
        let geoms = vec![
            geom(-0.35, 0.0, &r),
            geom(-0.05, 0.0, &r),
            geom(0.3, 0.2, &r),
            geom(0.35, 0.25, &r),
        ];
        let settings = StressSettings::default();
        for c in [0.0, 2.0] {
            let params = StressParams {
                cell: 0.02,
                cohesion: c,
                ..StressParams::new(&settings, 0.05)
            };
            let f = compute(&scene.blocks, 1, &geoms, &params, &settings);
            let lv = &f.levels;
            let mut n = 0;
            for k in 0..lv.z.len() {
                assert!(
                    rel(lv.sigma_v_mean[k], lv.sigma_v_cave[k]) < 1e-9,
                    "z {} mean {} cave {}",
                    lv.z[k],
                    lv.sigma_v_mean[k],
                    lv.sigma_v_cave[k]
                );
                n += (lv.bins[k] > 0) as usize;
            }
            assert!(n >= 30, "levels with bins: {n}");
            // Bins: at least one cluster (two overlapping IMZs count once).
            assert!(lv.bins.iter().any(|&b| b == 3));
        }
    }
}
