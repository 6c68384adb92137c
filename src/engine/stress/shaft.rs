//! The elastic-plastic pressurised shaft: the plastic and elastic zones around one bin in a
//! Mohr–Coulomb material (summary §5.3; overview and module map in `stress`).
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

use std::f64::consts::PI;

/// Passive coefficient Kp = (1 + sin φ)/(1 − sin φ), φ in degrees.
pub fn passive_coefficient(phi_deg: f64) -> f64 {
    let s = phi_deg.to_radians().sin();
    (1.0 + s) / (1.0 - s)
}

/// c cot φ, kPa (0 when c = 0).
pub(super) fn c_cot(c: f64, phi_deg: f64) -> f64 {
    if c > 0.0 {
        c / phi_deg.to_radians().tan()
    } else {
        0.0
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    fn rel(a: f64, b: f64) -> f64 {
        (a - b).abs() / b.abs().max(1e-300)
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
}
