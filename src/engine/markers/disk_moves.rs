//! The moves one disk of a drawing IMZ makes a marker inside it: the transfer into the
//! disk below when the marker crosses its base, the ring's radial push and its lateral
//! part where the ring's dilation is not the same all round, and the per-disk constants
//! ([`PerDisk`]) they read (summary §3.3; see the module above for the equations).

use super::super::imz::{DiskMotion, PerDisk, Profile, SHAPE_MODES};

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
pub(super) fn transfer(here: &DiskMotion, below: &DiskMotion, a: f64, depth: f64) -> (f64, f64) {
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
    radial_cut(m, a, inv_a).0
}

/// [`radial`]'s move and the length its cap dropped (the push beyond R_old asked for past
/// R_old / 2, the squeeze inside it past a / 2; `caps`).
#[inline]
pub(super) fn radial_cut(m: &DiskMotion, a: f64, inv_a: f64) -> (f64, f64) {
    let p = &m.per_disk;
    if !p.widened || a > m.r || !(a > 0.0) {
        return (0.0, 0.0);
    }
    if a > m.r_old {
        let (cap, fall) = (0.5 * m.r_old, 1.0 - (a - m.r_old) * p.inv_dr);
        (-p.push.min(cap) * fall, (p.push - cap).max(0.0) * fall)
    } else {
        let u = p.take * p.profile.flux_inside(a) * (0.5 * std::f64::consts::FRAC_1_PI) * inv_a;
        (-u.min(0.5 * a), (u - 0.5 * a).max(0.0))
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
    let (lx, ly, _) = lateral_cut(m, ex, ey, a, u);
    (lx, ly)
}

/// [`lateral`]'s move (dx, dy) and the length its cap dropped (asked for past R_old / 4;
/// `caps`).
#[inline]
pub(super) fn lateral_cut(
    m: &DiskMotion,
    ex: f64,
    ey: f64,
    a: f64,
    u: [f64; 2],
) -> (f64, f64, f64) {
    let (r_old, p) = (m.r_old, &m.per_disk);
    if !p.lateral || a > m.r {
        return (0.0, 0.0, 0.0);
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
    for k in 0..SHAPE_MODES {
        let (al, be) = (m.shape[2 * k], m.shape[2 * k + 1]);
        wr += al * pr + be * pi;
        wi += al * pi - be * pr;
        (pr, pi) = (pr * tx - pi * ty, pr * ty + pi * tx);
    }
    let (ux, uy) = (scale * wr, -scale * wi);
    let (cap, len2) = (0.25 * r_old, ux * ux + uy * uy);
    if len2 > cap * cap {
        let len = len2.sqrt();
        let k = cap / len;
        (ux * k, uy * k, len - cap)
    } else {
        (ux, uy, 0.0)
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
            tail: push * (2.0 * m.shape_rest).sqrt(),
            may_cap: false,
        };
        m.per_disk.may_cap = may_cap(m);
    }
}

/// Whether a cap of the moves can bind anywhere in disk `m` (prepared but for this): the
/// push beyond R_old asks for more than R_old / 2; the squeeze u(a) = take F(a) / (2π a)
/// for more than a / 2 somewhere, its largest ratio u / a = take c / (2π) being at the
/// axis (F(a) / a² falls from c there, as the profile's speed falls); or the lateral move,
/// at most push Σ |C_k| (|t| ≤ 1), for more than R_old / 4. Only such disks' moves are
/// checked for what the caps drop (`caps`); the bounds keep a margin for rounding.
fn may_cap(m: &DiskMotion) -> bool {
    let p = &m.per_disk;
    if !p.widened {
        return false;
    }
    let margin = 1.0 - 1e-6;
    let modes = || -> f64 {
        let c = &m.shape;
        (0..c.len() / 2)
            .map(|k| (c[2 * k] * c[2 * k] + c[2 * k + 1] * c[2 * k + 1]).sqrt())
            .sum()
    };
    p.push > 0.5 * m.r_old * margin
        || p.take * p.profile.c / (2.0 * std::f64::consts::PI) > 0.5 * margin
        || (p.lateral && p.push * modes() > 0.25 * m.r_old * margin)
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// Disks of `radii` that did not widen, in open ground, with shear band `w`, disk `i`
    /// passing the void `void(i)` = (Δv_i, Δv_out), prepared for disks of thickness `h`.
    pub(in super::super) fn still_disks(
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
}
