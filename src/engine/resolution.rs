//! The automatic resolution: h, marker spacing and draw increment from the scene, and from
//! an accuracy target when one is set (`resolution.target_grade_rmse`).
//!
//! # The scene default
//! Defaults follow MassFlow's ratios and are refined by the scene:
//! - h = min(0.5 × smallest block dimension, smallest opening width): MassFlow's disks are
//!   0.5 × block size; a disk thicker than the opening cannot resolve the base angle.
//! - marker spacing = 0.25 × smallest block dimension (MassFlow's markers), no wider than
//!   [`DRAWPOINT_SPACING_FRACTION`] of the median distance between neighbouring drawpoints
//!   (an IMZ must hold a few markers across) and never finer than 0.5 h. Markers sample the
//!   block model's grades and the IMZs; the opening width, which can make h thinner than
//!   MassFlow's 0.5 × block, sets neither. Where h is 0.5 × block (the demo: 7.6 m blocks,
//!   h 3.8 m) this is MassFlow's pair, 0.5 h; a mine-scale model of 15.2 m blocks with 4 m
//!   openings gets h 4 m and 3.4 m markers (drawpoint spacing 13.6 m), not 2 m ones with
//!   6.7× the markers for half the daily grade error (`docs::resolution`, "Mine scale").
//! - draw increment = the tonnes of the smallest opening disk (π (w/2)² h) at dilated
//!   density, times the spacing over 0.5 h when the spacing is coarser than that (as for
//!   an accuracy target, below: a marker moves about as many spacings per update as with
//!   MassFlow's pair). The increment is the marker-update interval: the IMZ itself grows
//!   in cycles of at most a sixteenth of its lowest disk (`Imz::draw`), and markers then
//!   move by the void passed "since the last marker update" (summary §3.3). The axial
//!   marker of a cone profile moves up to 3 disks per update at one disk; a third of it
//!   keeps it within one disk at three times the cost (see the speed–accuracy sweep in
//!   `docs::resolution`).
//!
//! # From an accuracy target
//! The speed–accuracy sweep (`analysis::sweep`, `docs::resolution`, "Automatic
//! resolution") measured the whole-demo grade RMSE per drawpoint-period against the
//! converged reference at marker spacings from 0.55 to 1 times the default, at the default
//! h and at h/2. At each h it is a floor plus the sampling noise of discrete markers: a
//! drawpoint-period's grade is the mean of the N markers it draws, N ∝ 1/s³, so
//!
//! E(m)² = F_h² + N_h² m³ (m the spacing as a multiple of the scene default),
//!
//! with F and N in [`FLOOR`] and [`NOISE`]. The floor is what finer markers cannot take
//! away at that h: the disk thickness's bias, and what the reference itself carries. At
//! the default h it is 1.04%, so a tighter target needs thinner disks, and thinner disks
//! are the cheaper way to any target below 1.5%. For a target T the rule takes, at the
//! default h and at h/2, the coarsest spacing whose E(m) ≤ T,
//!
//! m = ((T² − F_h²) / N_h²)^(1/3), bounded to [`SPACING_MULT`],
//!
//! and keeps whichever of the two the cost model ([`H_COST_EXPONENT`],
//! [`SPACING_COST_EXPONENT`]) says is cheaper; a target below both floors gets h/2 at the
//! finest multiple. The spacing is then bounded by the scene: no coarser than the smallest
//! block (lattice sites between blocks would carry no marker; `stability`) and than
//! [`DRAWPOINT_SPACING_FRACTION`] of the median distance between neighbouring drawpoints (an
//! IMZ must hold enough markers across to be sampled), and no finer than [`FRAG_FRACTION`]
//! × d̄ (markers closer than fragments stand for no more material than one fragment). h is
//! never thinner than d̄ (h/d̄ ≥ 1, `stability`). The increment follows the spacing: the
//! opening disk's tonnes times the spacing over 0.5 h when coarser than 0.5 h (a marker
//! then moves about as many spacings per update as at the demo's default), one disk when
//! finer (at the default spacing, increment × 4 adds 0.3 points to the whole-run error and
//! saves a sixth of the time). A tighter target never gives thicker disks, a coarser
//! spacing at the same h, a larger expected error or a cheaper choice (where the rule
//! moves to h/2 the spacing may coarsen, since thinner disks buy more than the markers
//! they replace).
//!
//! The constants are fitted on the demo; another scene's error at the same multiples
//! differs as its grade variability and its tonnes per drawpoint-period do. Run
//! `caveflow sweep` on the scene to check: the chart marks where the automatic choice lands.
//! The error is a smooth function of the spacing because a drawn marker reports its
//! cell's grade (`engine::markers`); with its site's block's grade it jumped between 1.1
//! and 2.0% among spacings from 1.05 to 1.52 m, as the cells fell across the blocks' faces.

use crate::engine::ResolvedResolution;
use crate::model::{Scenario, Scene};

/// Floor F_h of the whole-demo grade RMSE (relative, per drawpoint-period) at the scene
/// default h and at h/2: least-squares fits of E² = F² + N² m³ to the sweep's runs at
/// spacing × 1 to 0.55 (seven at h, 1.74–1.20%, fit within 0.035 points rms; twelve at
/// h/2, four of them at the rule's choice for 1%, 1.19–0.63%, within 0.063), against the
/// mean of the reference's two runs
/// (`docs::resolution`, "Automatic resolution").
pub const FLOOR: [f64; 2] = [0.0104, 0.0043];

/// Sampling-noise coefficient N_h of the same fits: the noise at the default spacing.
pub const NOISE: [f64; 2] = [0.0140, 0.0118];

/// Cost of a run against the scene default as (h0/h)^a × m^(−b), from the whole-demo
/// sweep's wall times (`docs::resolution`, "Speed and accuracy"): h/2 took 1.79 times the
/// default's time at the default spacing (a = 0.84); spacing × 2 took 0.26 times it, and
/// spacing × 0.84 at h/2 1.59 times h/2 at × 1 (b = 1.9 and 2.6; 2 between them).
pub const H_COST_EXPONENT: f64 = 0.84;

/// The spacing's exponent b of the cost model ([`H_COST_EXPONENT`]).
pub const SPACING_COST_EXPONENT: f64 = 2.0;

/// Bounds of the spacing multiple the target can choose: the sweep measured 0.5–4; a quarter
/// of the default is 64× the markers (hours at mine scale), and 4× is as coarse as the
/// blocks in MassFlow's ratios.
pub const SPACING_MULT: (f64, f64) = (0.25, 4.0);

/// Largest marker spacing as a share of the median distance between neighbouring
/// drawpoints: at least 4 marker spacings between neighbouring drawpoints, so each IMZ of
/// the interactive-draw scale holds a few markers across.
pub const DRAWPOINT_SPACING_FRACTION: f64 = 0.25;

/// Smallest marker spacing as a multiple of the mean fragment size d̄.
pub const FRAG_FRACTION: f64 = 1.0;

/// Default `resolution.max_marker_move` as a fraction of the marker spacing: a marker that
/// is slow enough to move less than this per update steps less often (`engine::cadence`).
/// One spacing against half a spacing: 0.103% against 0.090% grade RMSE on the demo sweep,
/// and no measurable change over the mine scene's first 400 days (`docs::resolution`,
/// "Multi-rate cadence").
pub const MAX_MOVE_FRACTION: f64 = 1.0;

/// Default `resolution.max_marker_move` as a fraction of the disk thickness h, where that is
/// less than [`MAX_MOVE_FRACTION`] × the spacing: the motion field changes from disk to
/// disk, so a marker's own step stays within half a disk (this binds where disks are
/// thinner than the markers are apart, as in the thin-disk test of `stability`).
pub const MAX_MOVE_OF_H: f64 = 0.5;

/// The scene default (the rule in the module documentation, first part).
fn scene_default(scene: &Scene) -> (f64, f64, f64, f64) {
    let bm = &scene.blocks;
    let min_block = bm.size.iter().cloned().fold(f64::INFINITY, f64::min);
    let min_open = scene
        .drawpoints
        .width
        .iter()
        .cloned()
        .fold(f64::INFINITY, f64::min);
    let h = (0.5 * min_block).min(min_open);
    let rho1 = if bm.is_empty() {
        1.0
    } else {
        (0..bm.len())
            .map(|b| bm.density[b] * (1.0 - bm.n1[b]))
            .sum::<f64>()
            / bm.len() as f64
    };
    (h, min_block, min_open, rho1)
}

/// The default `max_marker_move` at marker spacing `s` and disk thickness `h`.
pub fn max_move_rule(s: f64, h: f64) -> f64 {
    (MAX_MOVE_FRACTION * s).min(MAX_MOVE_OF_H * h)
}

/// Multipliers of a resolution: of h, of the marker spacing and of the draw increment.
pub type Multipliers = [f64; 3];

/// The resolution `mult` times `base` ([`Multipliers`]): h, marker spacing and increment
/// scaled, and `max_marker_move` following h and the spacing as the default rule does
/// ([`max_move_rule`]), in proportion to `base`'s. The one way a resolution is scaled: the
/// speed–accuracy sweep's grid (`analysis::sweep`) and calibration's finer check
/// (`analysis::calibrate`) both use it.
pub fn scaled(base: &ResolvedResolution, mult: Multipliers) -> ResolvedResolution {
    let (h, s) = (
        base.layer_thickness * mult[0],
        base.marker_spacing * mult[1],
    );
    ResolvedResolution {
        layer_thickness: h,
        marker_spacing: s,
        draw_increment: base.draw_increment * mult[2],
        max_marker_move: base.max_marker_move * max_move_rule(s, h)
            / max_move_rule(base.marker_spacing, base.layer_thickness),
    }
}

/// Default marker spacing as a fraction of the smallest block dimension: MassFlow's.
pub const BLOCK_SPACING_FRACTION: f64 = 0.25;

/// The scene's default marker spacing for disks of thickness `h` (the rule in the module
/// documentation): 0.25 × the smallest block dimension, bounded by the drawpoint spacing,
/// never finer than 0.5 h.
fn default_spacing(scene: &Scene, h: f64, min_block: f64) -> f64 {
    (BLOCK_SPACING_FRACTION * min_block)
        .min(spacing_cap(scene, min_block))
        .max(0.5 * h)
}

/// The coarsest marker spacing the scene allows: the smallest block dimension, and
/// [`DRAWPOINT_SPACING_FRACTION`] of the drawpoint spacing.
fn spacing_cap(scene: &Scene, min_block: f64) -> f64 {
    let dp = drawpoint_spacing(scene);
    if dp.is_finite() {
        min_block.min(DRAWPOINT_SPACING_FRACTION * dp)
    } else {
        min_block
    }
}

/// The rule's choice for an accuracy target, before the scene's bounds: (h multiple, 1 or
/// ½, and spacing multiple m), the cheaper of the two h's that reach the target, or h/2 at
/// the finest multiple when neither does.
pub fn target_multiples(target: f64) -> (f64, f64) {
    let cost = |k: f64, m: f64| k.powf(-H_COST_EXPONENT) * m.powf(-SPACING_COST_EXPONENT);
    let options = [(1.0, 0), (0.5, 1)].map(|(k, i)| {
        let m3 = (target * target - FLOOR[i] * FLOOR[i]) / (NOISE[i] * NOISE[i]);
        let reaches = m3 >= SPACING_MULT.0.powi(3);
        (
            k,
            m3.max(0.0).cbrt().clamp(SPACING_MULT.0, SPACING_MULT.1),
            reaches,
        )
    });
    options
        .iter()
        .filter(|o| o.2)
        .min_by(|a, b| cost(a.0, a.1).total_cmp(&cost(b.0, b.1)))
        .map_or((0.5, SPACING_MULT.0), |o| (o.0, o.1))
}

/// The whole-draw grade RMSE per drawpoint-period the rule expects at disk thickness `k`
/// times the scene default and spacing multiple `m`: E² = F² + N² m³ with F² and N²
/// interpolated linearly in k between h/2 and h (held beyond them; relative, fitted on the
/// demo, so an estimate elsewhere).
pub fn model_grade_rmse(k: f64, m: f64) -> f64 {
    let t = ((k - 0.5) / 0.5).clamp(0.0, 1.0);
    let sq = |v: [f64; 2]| t * v[0] * v[0] + (1.0 - t) * v[1] * v[1];
    (sq(FLOOR) + sq(NOISE) * m.powi(3)).sqrt()
}

/// What the rule says of a resolution: its marker spacing as a multiple m of the scene's
/// default spacing, and the whole-draw grade RMSE per
/// drawpoint-period [`model_grade_rmse`] gives it.
pub fn expected_grade_rmse(scene: &Scene, res: &ResolvedResolution) -> (f64, f64) {
    let (h0, min_block, _, _) = scene_default(scene);
    let m = res.marker_spacing / default_spacing(scene, h0, min_block);
    (m, model_grade_rmse(res.layer_thickness / h0, m))
}

/// Median over drawpoints of the distance to the nearest other drawpoint (NaN with fewer
/// than two).
fn drawpoint_spacing(scene: &Scene) -> f64 {
    scene.drawpoints.median_spacing()
}

/// Mean fragment size d̄ over the blocks, m (NaN without blocks).
fn mean_frag(scene: &Scene) -> f64 {
    let f = &scene.blocks.frag;
    let ok: Vec<f64> = f
        .iter()
        .copied()
        .filter(|d| d.is_finite() && *d > 0.0)
        .collect();
    if ok.is_empty() {
        f64::NAN
    } else {
        ok.iter().sum::<f64>() / ok.len() as f64
    }
}

/// Fills the unset resolution knobs from the scene, and from the accuracy target when one is
/// set.
pub fn resolve(scene: &Scene, sc: &Scenario) -> ResolvedResolution {
    let (h0, min_block, min_open, rho1) = scene_default(scene);
    let set = &sc.resolution;
    // h and the rule's spacing: the scene default, or the one for the accuracy target.
    let (h, s) = match set.target_grade_rmse {
        None => {
            let h = set.layer_thickness.unwrap_or(h0);
            (h, default_spacing(scene, h, min_block))
        }
        Some(target) => {
            let dbar = mean_frag(scene);
            let (k, m) = target_multiples(target);
            let h = if dbar.is_finite() {
                (k * h0).max(dbar.min(0.5 * min_block))
            } else {
                k * h0
            };
            let h = set.layer_thickness.unwrap_or(h);
            let s0 = default_spacing(scene, h0, min_block);
            let s = if m > 1.0 {
                // Coarser: bounded by the blocks and the drawpoint spacing, never below s0.
                (s0 * m).min(spacing_cap(scene, min_block)).max(s0)
            } else {
                // Finer: bounded by the fragments, never above s0.
                let floor = if dbar.is_finite() {
                    FRAG_FRACTION * dbar
                } else {
                    0.0
                };
                (s0 * m).max(floor).min(s0)
            };
            (h, s)
        }
    };
    // The increment follows the rule's spacing (not an explicit one) where it is coarser
    // than 0.5 h.
    let inc_mult = (s / (0.5 * h)).max(1.0);
    let s = set.marker_spacing.unwrap_or(s);
    let r = 0.5 * min_open;
    let inc = set
        .draw_increment
        .unwrap_or(std::f64::consts::PI * r * r * h * rho1 * inc_mult);
    ResolvedResolution {
        layer_thickness: h,
        marker_spacing: s,
        draw_increment: inc,
        // Fines percolation is evaluated per update: every marker then steps every update.
        max_marker_move: if sc.mechanisms.fines {
            0.0
        } else {
            set.max_marker_move.unwrap_or(max_move_rule(s, h))
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::demo::{henderson, scenario, DemoScale};

    /// The demo (7.6 m blocks, h 3.8 m) keeps MassFlow's pair, spacing 0.5 h and one
    /// opening disk an update. The mine scene (15.2 m blocks, 4 m openings: h 4 m) gets
    /// MassFlow's 0.25 × block bounded by a quarter of the drawpoint spacing, and an
    /// increment as many times one disk as the spacing is times 0.5 h; an explicit spacing
    /// leaves that increment alone.
    #[test]
    fn default_spacing_follows_the_blocks_and_the_drawpoints() {
        let small = henderson(DemoScale::Small, 1);
        let sc = scenario(DemoScale::Small, 1);
        let r = resolve(&small, &sc);
        assert_eq!(r.marker_spacing, 0.5 * r.layer_thickness);
        let disk = |scene: &Scene, h: f64| {
            let (_, _, open, rho1) = scene_default(scene);
            std::f64::consts::PI * 0.25 * open * open * h * rho1
        };
        assert_eq!(r.draw_increment, disk(&small, r.layer_thickness));

        let mine = henderson(DemoScale::Mine, 1);
        let mut sc = scenario(DemoScale::Mine, 1);
        let r = resolve(&mine, &sc);
        assert_eq!(r.layer_thickness, 4.0);
        let dp = drawpoint_spacing(&mine);
        assert!(dp < 4.0 * 0.25 * 15.2, "{dp}");
        assert_eq!(r.marker_spacing, DRAWPOINT_SPACING_FRACTION * dp);
        let m = r.marker_spacing / 2.0;
        assert!((r.draw_increment / (disk(&mine, 4.0) * m) - 1.0).abs() < 1e-12);
        sc.resolution.marker_spacing = Some(1.65);
        let fine = resolve(&mine, &sc);
        assert_eq!(fine.marker_spacing, 1.65);
        assert_eq!(fine.draw_increment, r.draw_increment);
    }

    /// Over targets from 10⁻⁵ to 1: a tighter target never gives thicker disks, a coarser
    /// spacing at the same h, a larger expected error or a cheaper run; the choice meets
    /// the target wherever a multiple in bounds can; the default's own error gives the
    /// default h and about the default spacing; and a target between the two floors needs h/2.
    #[test]
    fn tighter_targets_never_give_a_coarser_resolution() {
        let cost = |(k, m): (f64, f64)| k.powf(-H_COST_EXPONENT) * m.powf(-SPACING_COST_EXPONENT);
        let targets: Vec<f64> = (0..=500)
            .map(|i| 10f64.powf(-5.0 + 5.0 * i as f64 / 500.0))
            .collect();
        let chosen: Vec<(f64, f64)> = targets.iter().rev().map(|&t| target_multiples(t)).collect();
        for (w, t) in chosen.windows(2).zip(targets.iter().rev().skip(1)) {
            let ((k0, m0), (k1, m1)) = (w[0], w[1]);
            assert!(k1 <= k0, "{t}: {w:?}");
            assert!(k1 < k0 || m1 <= m0, "{t}: {w:?}");
            assert!(
                model_grade_rmse(k1, m1) <= model_grade_rmse(k0, m0) + 1e-15,
                "{t}: {w:?}"
            );
            assert!(cost(w[1]) >= cost(w[0]) * (1.0 - 1e-12), "{t}: {w:?}");
        }
        for (&t, &(k, m)) in targets.iter().rev().zip(&chosen) {
            if m > SPACING_MULT.0 && m < SPACING_MULT.1 {
                assert!(model_grade_rmse(k, m) <= t * (1.0 + 1e-9), "{t}: {k} {m}");
            }
        }
        let e_default = model_grade_rmse(1.0, 1.0);
        let (k, m) = target_multiples(e_default);
        assert_eq!(k, 1.0);
        assert!((m - 1.0).abs() < 1e-9, "{m}");
        assert_eq!(target_multiples(0.5 * (FLOOR[0] + FLOOR[1])).0, 0.5);
        assert_eq!(target_multiples(1e-5), (0.5, SPACING_MULT.0));
        assert_eq!(target_multiples(1.0), (1.0, SPACING_MULT.1));
    }
}
