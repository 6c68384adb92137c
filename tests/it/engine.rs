//! Integration tests: the flow engine against conservation laws and the summary's published
//! behaviour (DESIGN §7). Every scene is a [`UniformBox`] at a coarse, explicit resolution
//! (never the automatic one, so a change of default cannot make these slow or move their
//! numbers); each tolerance says where it comes from. Each test prints what it measured
//! (`cargo test ... engine:: -- --nocapture`).

use std::collections::{BTreeMap, HashMap, HashSet};
use std::f64::consts::E;

use caveflow::engine::markers::Lattice;
use caveflow::engine::{MarkerState, RunOutput, WarningRule};
use caveflow::model::synthetic::UniformBox;
use caveflow::model::{Scenario, Scene};

use crate::fixtures::{run, scenario};

/// Sets a schedule of cumulative tonnes per period (same for every drawpoint).
fn cumulative_schedule(scene: &mut Scene, cum: &[f64]) {
    let nd = scene.drawpoints.len();
    scene.periods.id = (1..=cum.len() as i64).collect();
    scene.periods.name = scene.periods.id.iter().map(|p| p.to_string()).collect();
    scene.periods.days = vec![1.0; cum.len()];
    scene.schedule.tonnes = (0..cum.len())
        .flat_map(|p| {
            let t = cum[p] - if p == 0 { 0.0 } else { cum[p - 1] };
            std::iter::repeat_n(t, nd)
        })
        .collect();
}

/// The disks (z_base, z_top, radius) of drawpoint `dp` at the end of `period`, bottom up.
pub(crate) fn disks(out: &RunOutput, dp: u32, period: i64) -> Vec<(f64, f64, f64)> {
    let t = &out.imz;
    (0..t.radius.len())
        .filter(|&k| t.drawpoint[k] == dp && t.period[k] == period)
        .map(|k| (t.z_base[k], t.z_top[k], t.radius[k]))
        .collect()
}

/// Radius of a disk list at elevation z (0 outside the IMZ).
fn radius_at(d: &[(f64, f64, f64)], z: f64) -> f64 {
    d.iter().find(|x| x.0 <= z && z < x.1).map_or(0.0, |x| x.2)
}

/// Least-squares slope of y on x.
fn ls_slope(pts: &[(f64, f64)]) -> f64 {
    let n = pts.len() as f64;
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    sxy / sxx
}

// ---------------------------------------------------------------------------------------
// 1. Conservation
// ---------------------------------------------------------------------------------------

/// A 1.2 × 0.6 × 1.5 m box of Castro material with three drawpoints on the x axis:
/// - DP01 (x = −0.35) and DP02 (x = −0.05), whose IMZs overlap (superposition);
/// - DP03 (x = 0.45) under a pillar that never caves (x > 0.25): scheduled but undrawable.
///
/// The cave back is at z = 1.0 m until period 5 (an air gap forms under it), and the strip
/// 0.1 < x < 0.25 caves at period 3, which is not in the period list (ids 1, 2, 4, 5, 6,
/// 7), so it becomes flowable at period 4, inside IMZ disks that had already grown past it.
pub(crate) fn caving_scene() -> Scene {
    let b = UniformBox {
        extent: [1.2, 0.6, 1.5],
        drawpoints: vec![(-0.35, 0.0, 0.12), (-0.05, 0.0, 0.12), (0.45, 0.0, 0.12)],
        periods: 6,
        tonnes: 0.012,
        ..UniformBox::castro_isolated()
    };
    let mut scene = b.scene();
    scene.periods.id = vec![1, 2, 4, 5, 6, 7];
    let bm = &mut scene.blocks;
    for k in 0..bm.len() {
        bm.cave_period[k] = if bm.x[k] > 0.25 {
            1000
        } else if bm.x[k] > 0.1 {
            3
        } else if bm.z[k] > 1.0 {
            5
        } else {
            0
        };
    }
    scene
}

pub(crate) fn caving_scenario() -> Scenario {
    let mut sc = scenario(0.05, 0.025, 0.001);
    sc.outputs.marker_periods = vec![1, 2, 4, 5, 6, 7];
    sc
}

#[test]
fn conservation_of_tonnes_and_markers() {
    let scene = caving_scene();
    let sc = caving_scenario();
    let out = run(&scene, &sc);
    let bm = &scene.blocks;
    let ex = &out.extraction;
    let s = sc.resolution.marker_spacing.unwrap();

    // Tonnes (`engine::crediting`). A flowing drawpoint is credited its schedule, period
    // by period, exactly; the correction factor is credited over marker tonnes, a
    // diagnostic of discreteness (NaN in a period that drew no marker), and the markers a
    // drawable drawpoint drew over the run weigh its schedule to 3% (~10³ markers a period).
    for (d, &(sched, credited)) in out.balance.per_drawpoint.iter().enumerate().take(2) {
        let ratio = credited / sched;
        let rows = (0..ex.drawpoint.len()).filter(|&k| ex.drawpoint[k] == d as u32);
        let markers: f64 = rows.map(|k| ex.marker_tonnes[k]).sum();
        eprintln!(
            "DP{:02}: scheduled {sched:.4} t, credited {credited:.4} t, ratio {ratio:.6}; markers {:.4}",
            d + 1,
            markers / sched
        );
        assert!(
            (ratio - 1.0).abs() <= 1e-12,
            "DP{:02} credited/scheduled = {ratio}",
            d + 1
        );
        assert!((markers / sched - 1.0).abs() <= 0.03, "DP{:02}", d + 1);
    }
    for k in (0..ex.tonnes.len()).filter(|&k| ex.status[k] == "ok") {
        assert_eq!(ex.tonnes[k], ex.scheduled_tonnes[k], "row {k}");
        assert_eq!(ex.short_reason[k], "");
        let c = ex.correction[k];
        if ex.marker_tonnes[k] > 0.0 {
            assert!(
                (ex.tonnes[k] - c * ex.marker_tonnes[k]).abs() <= 1e-9,
                "row {k}"
            );
        } else {
            assert!(c.is_nan(), "row {k}");
        }
    }
    let (cmin, cmax) = ex
        .correction
        .iter()
        .filter(|c| c.is_finite())
        .fold((f64::MAX, f64::MIN), |a, &c| (a.0.min(c), a.1.max(c)));
    eprintln!("correction factors in [{cmin:.3}, {cmax:.3}]");

    // The drawpoint under the pillar is reported, not hidden: every one of its rows is
    // `short` with nothing credited, its shortfall is the whole schedule, and the run warns.
    let dp3: Vec<usize> = (0..ex.drawpoint.len())
        .filter(|&k| ex.drawpoint[k] == 2)
        .collect();
    assert_eq!(dp3.len(), scene.periods.len());
    assert!(dp3.iter().all(|&k| ex.status[k] == "short"
        && ex.short_reason[k] == "uncaved"
        && ex.tonnes[k] == 0.0
        && ex.markers[k] == 0));
    let (sched3, credited3) = out.balance.per_drawpoint[2];
    assert_eq!(credited3, 0.0);
    assert!((ex.shortfall_tonnes[*dp3.last().unwrap()] - sched3).abs() <= 1e-12);
    let of = |rule: WarningRule| {
        out.warnings
            .iter()
            .filter(|w| w.rule == rule && w.drawpoint.as_deref() == Some("DP03"))
            .collect::<Vec<_>>()
    };
    // One per period in which DP03 is scheduled under uncaved ground, with the tonnes.
    let uncaved = of(WarningRule::Uncaved);
    assert_eq!(uncaved.len(), scene.periods.len(), "{:?}", out.warnings);
    assert!(uncaved[0].message.contains("not caved") && uncaved[0].amount > 0.0);
    let short = of(WarningRule::Short);
    assert_eq!(short.len(), 1, "{:?}", out.warnings);
    assert!(short[0].message.contains("could not deliver"));
    assert!((short[0].amount - sched3).abs() <= 1e-9);
    // The scene does what it says: DP01 and DP02 reach the cave back before it caves (an
    // air gap is reported by period 4), and the gap closes once the back caves at period 5,
    // so the run ends with no air-gap warning.
    let air = |from: i64, to: i64| {
        (0..ex.tonnes.len())
            .filter(|&k| ex.drawpoint[k] < 2 && (from..=to).contains(&ex.period[k]))
            .map(|k| ex.air_gap[k])
            .fold(0.0, f64::max)
    };
    let (air_by_4, air_at_end) = (air(1, 4), air(7, 7));
    eprintln!("air gap under the cave back by period 4: {air_by_4:.2e} m³, at the end {air_at_end:.2e} m³");
    assert!(air_by_4 > 0.0);
    assert_eq!(air_at_end, 0.0);
    assert!(!out.warnings.iter().any(|w| w.rule == WarningRule::AirGap));
    // Run totals: credited + what is still owed = scheduled.
    let b = &out.balance;
    assert!((b.credited_tonnes + b.final_shortfall_tonnes - b.scheduled_tonnes).abs() <= 1e-9);

    // Markers: none lost or duplicated.
    let n_drawn: i64 = ex.markers.iter().sum();
    assert_eq!(
        out.drawn_len() as i64,
        n_drawn,
        "drawn table vs extraction `markers`"
    );
    assert_eq!(b.markers_drawn as i64, n_drawn);
    let drawn_ids: HashSet<i64> = out.drawn_table().marker_id.iter().cloned().collect();
    assert_eq!(drawn_ids.len(), out.drawn_len(), "a marker was drawn twice");
    let mass_of_block: Vec<f64> = (0..bm.len())
        .map(|k| bm.size.iter().product::<f64>() * bm.density[k] * (1.0 - bm.n0[k]))
        .collect();
    let block_row: HashMap<i64, usize> = (0..bm.len()).map(|k| (bm.id[k], k)).collect();
    let mut last_drawn = 0;
    for snap in &out.snapshot_tables() {
        let p = snap.period;
        // Ids (moving + drawn) strictly increasing: unique.
        assert!(
            snap.marker_id.windows(2).all(|w| w[0] < w[1]),
            "period {p}: duplicated marker id"
        );
        let drawn_now = snap
            .state
            .iter()
            .filter(|&&x| x == MarkerState::Drawn)
            .count();
        assert!(
            drawn_now >= last_drawn,
            "period {p}: drawn markers went missing"
        );
        last_drawn = drawn_now;
        let n_rows: i64 = (0..ex.period.len())
            .filter(|&k| ex.period[k] <= p)
            .map(|k| ex.markers[k])
            .sum();
        assert_eq!(
            drawn_now as i64, n_rows,
            "period {p}: drawn markers vs extraction rows"
        );
        // Mobilised mass per block never exceeds the block's in-situ mass.
        let mut per_block: HashMap<i64, f64> = HashMap::new();
        for k in 0..snap.marker_id.len() {
            *per_block.entry(snap.block_id[k]).or_default() += snap.mass[k];
        }
        for (id, m) in &per_block {
            let cap = mass_of_block[block_row[id]];
            assert!(
                *m <= cap * (1.0 + 1e-9),
                "period {p}: block {id} mobilised {m} t > {cap} t"
            );
        }
        // Moving markers: inside the model, never above its top, and only in ground that
        // is flowable in this period.
        for k in 0..snap.marker_id.len() {
            if snap.state[k] != MarkerState::Moving {
                continue;
            }
            let q = [snap.x[k], snap.y[k], snap.z[k]];
            assert!(
                q[2] <= bm.z_max(),
                "period {p}: marker {} above the model",
                snap.marker_id[k]
            );
            assert!(
                q[2] <= snap.origin_z[k],
                "period {p}: marker {} moved up",
                snap.marker_id[k]
            );
            let blk = bm.locate(q).unwrap_or_else(|| {
                panic!(
                    "period {p}: marker {} left the model at {q:?}",
                    snap.marker_id[k]
                )
            });
            assert!(
                bm.flowable(blk, p),
                "period {p}: marker {} in unflowable block {}",
                snap.marker_id[k],
                bm.id[blk]
            );
        }
    }
    let snaps = out.snapshot_tables();
    let last = snaps.last().unwrap();
    assert_eq!(last.marker_id.len() as u64, b.markers_mobilised);
    let total_block_mass: f64 = mass_of_block.iter().sum();
    let mobilised_mass: f64 = last.mass.iter().sum();
    assert!(mobilised_mass <= total_block_mass);
    eprintln!(
        "markers: {} mobilised ({mobilised_mass:.4} t of {total_block_mass:.3} t), {} drawn",
        b.markers_mobilised, b.markers_drawn
    );

    // And none missing: at the end of every period, every lattice site inside an IMZ, in
    // ground flowable in that period, has been mobilised (a site skipped while its block
    // was uncaved must be engulfed once it caves, even when it caves between two listed
    // periods). Sites within 1e-9 m of a disk boundary are left out (rounding decides
    // those either way).
    let lat = Lattice::new(bm, s);
    let mut checked = 0;
    for snap in &out.snapshot_tables() {
        let p = snap.period;
        let ids: HashSet<i64> = snap.marker_id.iter().cloned().collect();
        for dp in 0..2u32 {
            let dk = disks(&out, dp, p);
            let (x0, y0) = (
                scene.drawpoints.x[dp as usize],
                scene.drawpoints.y[dp as usize],
            );
            for id in 0..lat.len() {
                let q = lat.pos(id);
                let Some(&(zb, zt, r)) = dk.iter().find(|x| x.0 <= q[2] && q[2] < x.1) else {
                    continue;
                };
                let a = ((q[0] - x0).powi(2) + (q[1] - y0).powi(2)).sqrt();
                if a > r - 1e-9 || q[2] - zb < 1e-9 || zt - q[2] < 1e-9 {
                    continue;
                }
                let Some(blk) = bm.locate(q) else { continue };
                if !bm.flowable(blk, p) {
                    continue;
                }
                checked += 1;
                assert!(
                    ids.contains(&(id as i64)),
                    "period {p}: site {id} at {q:?} (block caved at {}) is inside DP{:02}'s IMZ but was never mobilised",
                    bm.cave_period[blk],
                    dp + 1
                );
            }
        }
    }
    eprintln!("{checked} (site, period) pairs inside IMZs checked mobilised");
}

// ---------------------------------------------------------------------------------------
// 3. Isolated draw at Castro scale (summary §3.4, Simulation 2)
// ---------------------------------------------------------------------------------------

/// Cumulative tonnes of the isolated growth runs: ×1.5 per period, 5 kg to 128 kg.
const GROWTH_CUM: [f64; 9] = [
    0.005, 0.0075, 0.01125, 0.0169, 0.0253, 0.038, 0.057, 0.0854, 0.128,
];

/// The isolated Castro scene with mean fragment size `frag`, drawn to [`GROWTH_CUM`]; h =
/// 25 mm, markers 25 mm, 0.4 kg increments.
fn isolated_growth(frag: f64) -> (Scene, Scenario, RunOutput) {
    let b = UniformBox {
        frag,
        ..UniformBox::castro_isolated()
    };
    let mut scene = b.scene();
    cumulative_schedule(&mut scene, &GROWTH_CUM);
    let sc = scenario(0.025, 0.025, 0.0004);
    let out = run(&scene, &sc);
    (scene, sc, out)
}

/// (H, W) per period: IMZ height (top of the top disk) and largest diameter, for the
/// periods whose IMZ is in the far field (H/d̄ ≥ 100) and has not reached the model top.
fn far_field_growth(scene: &Scene, out: &RunOutput, frag: f64) -> Vec<(f64, f64)> {
    let top = scene.blocks.z_max();
    let h = out.resolution.layer_thickness;
    scene
        .periods
        .id
        .iter()
        .map(|&p| {
            let d = disks(out, 0, p);
            let hh = d.iter().map(|x| x.1).fold(0.0, f64::max);
            let w = 2.0 * d.iter().map(|x| x.2).fold(0.0, f64::max);
            (hh, w)
        })
        .filter(|&(hh, _)| hh / frag >= 100.0 && hh < top - h)
        .collect()
}

#[test]
fn isolated_far_field_width_grows_as_sqrt_d_h() {
    let d1 = 0.0083;
    let (scene, _, out) = isolated_growth(d1);
    let g1 = far_field_growth(&scene, &out, d1);
    for (hh, w) in &g1 {
        eprintln!(
            "d̄ {d1}: H {hh:.3} m (H/d̄ {:.0}), W {w:.4} m, W/√(d̄H) {:.2}",
            hh / d1,
            w / (d1 * hh).sqrt()
        );
    }
    // Kinematic theory (Nedderman 1995, summary Fig. 7): far-field W ∝ √(d̄ H). In REBOP
    // the r-law removes a share 10 d̄/(π R²) of the void per unit height, which makes
    // R²/(d̄ H) a similarity variable; the slope bracket (1 − tan β · dR/dz)^q breaks the
    // similarity by terms of order q tan β √(d̄/H), so the exponent approaches 0.5 from
    // above as H/d̄ grows. Measured fits over H/d̄ ≈ 120–340: 0.512, 0.505, 0.488 at h = 50,
    // 25, 12.5 mm (local exponents 0.47–0.59); for 2 d̄ (H/d̄ 100–190) 0.55–0.57. The
    // issue's ±0.1 covers the resolution and the near-field remainder.
    assert!(g1.len() >= 5, "too few far-field points: {g1:?}");
    let pts: Vec<(f64, f64)> = g1.iter().map(|&(hh, w)| (hh.ln(), w.ln())).collect();
    let exponent = ls_slope(&pts);
    eprintln!(
        "W ∝ H^{exponent:.3} over H/d̄ {:.0}–{:.0} ({} points)",
        g1[0].0 / d1,
        g1.last().unwrap().0 / d1,
        g1.len()
    );
    assert!(
        (exponent - 0.5).abs() <= 0.1,
        "far-field exponent {exponent}"
    );

    // The coefficient against Nedderman's kinematic value. In the kinematic model a point
    // orifice that has drawn a volume V displaces the ground at height z and radius r by
    // s = V/(4πBz) exp(−r²/(4Bz)), B the diffusion length. Taking the movement zone's limit
    // where s reaches a fixed displacement (the dilation needed to move, Nedderman 1995)
    // gives r² = 4Bz ln(H/z) for a zone of height H, widest at z = H/e: W = 4√(BH/e). The
    // values of B reported from experiments run from about 1.3 to 3.5 particle diameters
    // (as gathered by Choi, Kudrolli and Bazant 2005, who also see B grow with height), so
    // W/√(d̄H) must lie between 4√(1.3/e) = 2.77 and 4√(3.5/e) = 4.54. That band is the
    // published spread of B, not the engine's noise (the coefficient moves by 0.03 between
    // the far-field points): the engine's 3.92–3.95 is B ≈ 2.6 d̄.
    let (lo, hi) = (4.0 * (1.3 / E).sqrt(), 4.0 * (3.5 / E).sqrt());
    for &(hh, w) in &g1 {
        let c = w / (d1 * hh).sqrt();
        eprintln!(
            "H/d̄ {:.0}: W/√(d̄H) {c:.3}, B = {:.2} d̄ (band {lo:.2}–{hi:.2})",
            hh / d1,
            E * (c / 4.0).powi(2)
        );
        assert!((lo..=hi).contains(&c), "W/√(d̄H) {c} at H {hh}");
    }

    // Doubling d̄ widens the IMZ: at the same drawn mass, and at the same height. At the
    // same height √(d̄ H) predicts a ratio of √2; the coarser material is nearer its near
    // field (H/d̄ 100–200), so the ratio is checked to lie between 1.2 and 1.6.
    let d2 = 2.0 * d1;
    let (scene2, _, out2) = isolated_growth(d2);
    for &p in &scene.periods.id {
        let w = |o: &RunOutput| 2.0 * disks(o, 0, p).iter().map(|x| x.2).fold(0.0, f64::max);
        assert!(
            w(&out2) > w(&out),
            "period {p}: W(2d̄) {} ≤ W(d̄) {}",
            w(&out2),
            w(&out)
        );
    }
    let g2 = far_field_growth(&scene2, &out2, d2);
    assert!(!g2.is_empty());
    let mut ratios = Vec::new();
    for &(hh, w2) in &g2 {
        // W(d̄) at the same H, interpolated log-linearly between the bracketing periods.
        let Some(k) = g1.windows(2).position(|x| x[0].0 <= hh && hh <= x[1].0) else {
            continue;
        };
        let (a, b) = (g1[k], g1[k + 1]);
        let t = (hh / a.0).ln() / (b.0 / a.0).ln();
        let w1 = (a.1.ln() + t * (b.1 / a.1).ln()).exp();
        eprintln!(
            "H {hh:.3}: W(2d̄) {w2:.4} / W(d̄) {w1:.4} = {:.3} (√2 = 1.414)",
            w2 / w1
        );
        ratios.push(w2 / w1);
    }
    assert!(!ratios.is_empty());
    assert!(ratios.iter().all(|r| (1.2..=1.6).contains(r)), "{ratios:?}");
}

#[test]
fn isolated_base_angle_and_iez_inside_imz() {
    let d = 0.0083;
    let (scene, sc, out) = isolated_growth(d);
    let h = out.resolution.layer_thickness;
    let s = sc.resolution.marker_spacing.unwrap();
    let phi = scene.blocks.friction[0];
    let r_open = 0.5 * scene.drawpoints.width[0];
    let beta = 45.0 + 0.5 * phi;
    let max_step = h / beta.to_radians().tan();
    // Base angle: r = 0 at the slope 45 + φ/2, so no disk may be wider than the one below
    // it (or than the opening, for disk 0) by more than h / tan(45 + φ/2). The r-law is
    // integrated within each disk (`Imz::absorb`), so this holds to rounding, at every
    // period and every height, not only within the one-marker-spacing slack the issue
    // allows.
    for &p in &scene.periods.id {
        let dk = disks(&out, 0, p);
        let mut below = r_open;
        for (i, x) in dk.iter().enumerate() {
            assert!(
                x.2 - below <= max_step * (1.0 + 1e-9),
                "period {p} disk {i}: step {} > {max_step}",
                x.2 - below
            );
            below = x.2;
        }
    }
    let last = *scene.periods.id.last().unwrap();
    let dk = disks(&out, 0, last);
    let angle = |dr: f64| (h / dr).atan().to_degrees();
    eprintln!(
        "base angle: opening→disk 0 {:.1}°, disk 0→1 {:.1}°, limit 45 + φ/2 = {beta:.1}°",
        angle(dk[0].2 - r_open),
        angle(dk[1].2 - dk[0].2)
    );
    assert!(angle(dk[1].2 - dk[0].2) >= beta - 1e-6);

    // IEZ ⊂ IMZ: every drawn marker started inside the final IMZ at its origin elevation
    // (material is mobilised only where a disk reaches, and disks never shrink); one
    // marker spacing of slack for the lattice.
    let dr = out.drawn_table();
    assert!(!dr.marker_id.is_empty());
    let mut worst = f64::MIN;
    let (mut iez_w, mut iez_h) = (0.0f64, 0.0f64);
    for k in 0..dr.marker_id.len() {
        let a = dr.origin_x[k].hypot(dr.origin_y[k]);
        let r = radius_at(&dk, dr.origin_z[k]);
        worst = worst.max(a - r);
        iez_w = iez_w.max(2.0 * a);
        iez_h = iez_h.max(dr.origin_z[k]);
        assert!(
            a <= r + s,
            "drawn marker {} from a = {a} > R = {r} at z = {}",
            dr.marker_id[k],
            dr.origin_z[k]
        );
    }
    let imz_w = 2.0 * dk.iter().map(|x| x.2).fold(0.0, f64::max);
    let imz_h = dk.last().unwrap().1;
    eprintln!(
        "{} drawn markers: max (a − R) {worst:.4} m; IEZ {iez_w:.3} m wide × {iez_h:.3} m high, IMZ {imz_w:.3} m × {imz_h:.3} m",
        dr.marker_id.len()
    );
}

// ---------------------------------------------------------------------------------------
// 4. Overlap: IN-T2 (two drawpoints at 700 mm, summary §4)
// ---------------------------------------------------------------------------------------

/// 270 kg a drawpoint a period for four periods: the stage at which both IMZs have long
/// reached the top of the 3.3 m model. (The IMZ holds its material at n1, so it needs
/// 1/(1 − n1) times the draw that the summary's printed radius update needed to reach the
/// same size; at 150 kg a period the layers near the top had been drawn down mostly while
/// the IMZs were still growing through them, CV 0.21–0.28.)
#[test]
fn in_t2_drawdown_is_uniform_above_imz_overlap() {
    let spacing = 0.7;
    let b = UniformBox {
        extent: [1.4, 1.0, 3.3],
        drawpoints: vec![(-0.5 * spacing, 0.0, 0.12), (0.5 * spacing, 0.0, 0.12)],
        periods: 4,
        tonnes: 0.27,
        ..UniformBox::castro_isolated()
    };
    let scene = b.scene();
    let (h, s) = (0.05, 0.025);
    let out = run(&scene, &scenario(h, s, 0.001));
    let w = 10.0 * b.frag;
    let last = *scene.periods.id.last().unwrap();
    let (dk0, dk1) = (disks(&out, 0, last), disks(&out, 1, last));

    // Height above which the two IMZs overlap along the line joining the drawpoints by
    // more than the shear band w = 10 d̄ (the superposed cone/frustum profiles then add up
    // to a plug, Melo et al. 2008).
    let z_overlap = dk0
        .iter()
        .zip(&dk1)
        .find(|(a, b)| a.2 + b.2 - spacing >= w)
        .map(|(a, _)| a.0)
        .expect("the IMZs never overlap by w");

    // Drawdown of each initially horizontal lattice layer along the section y ≈ 0 between
    // and above the drawpoints (x ∈ [−0.35, 0.35]): vertical displacement of every site
    // (0 for ground never mobilised). A layer is judged where it is now (its origin minus
    // its mean drawdown): one drawn down below the overlap height is in non-overlapping
    // flow again. Layers holding drawn markers are left out of the uniform side too (a
    // drawn marker's displacement stops at its origin height).
    let lat = Lattice::new(&scene.blocks, s);
    let snaps = out.snapshot_tables();
    let snap = snaps.last().unwrap();
    let moved: HashMap<usize, (f64, bool)> = (0..snap.marker_id.len())
        .map(|k| {
            (
                snap.marker_id[k] as usize,
                (
                    snap.origin_z[k] - snap.z[k],
                    snap.state[k] == MarkerState::Drawn,
                ),
            )
        })
        .collect();
    let mut layers: BTreeMap<usize, (f64, f64, bool, f64)> = BTreeMap::new();
    for kz in 0..lat.n[2] {
        let mut v = Vec::new();
        let mut any_drawn = false;
        for j in 0..lat.n[1] {
            for i in 0..lat.n[0] {
                let id = lat.id(i, j, kz);
                let q = lat.pos(id);
                if q[1].abs() < s && q[0].abs() <= 0.5 * spacing + 1e-9 {
                    let (dz, drawn) = moved.get(&id).copied().unwrap_or((0.0, false));
                    any_drawn |= drawn;
                    v.push(dz);
                }
            }
        }
        let n = v.len() as f64;
        let mean = v.iter().sum::<f64>() / n;
        let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n).sqrt();
        let z = lat.pos(lat.id(0, 0, kz))[2];
        layers.insert(
            kz,
            (
                z,
                if mean > 0.0 { sd / mean } else { f64::INFINITY },
                any_drawn,
                z - mean,
            ),
        );
    }
    for (z, cv, drawn, now) in layers.values().step_by(4) {
        let ov = radius_at(&dk0, *z) + radius_at(&dk1, *z) - spacing;
        eprintln!(
            "layer from z {z:.3} (now at {now:.3}): CV {cv:.3}{}; overlap at origin {ov:+.3} m (w = {w:.3})",
            if *drawn { " (holds drawn markers)" } else { "" }
        );
    }
    let imz_top = dk0.last().unwrap().1.min(dk1.last().unwrap().1);
    eprintln!("IMZs overlap by w from z = {z_overlap:.3} m; IMZ tops at {imz_top:.3} m");

    // Below the overlap (lower half of the zone below it) drawdown is concentrated over
    // each drawpoint: stagnant ground between them gives CV ≥ 0.5 (measured ≥ 0.63).
    // Every layer now above the overlap height, holding no drawn marker, and starting at
    // least h below the IMZ tops is drawn down uniformly: CV ≤ 0.15 (measured ≤ 0.079,
    // falling to 0.02 near the top; the margin is for resolution).
    let low: Vec<f64> = layers
        .values()
        .filter(|x| x.0 < 0.5 * z_overlap)
        .map(|x| x.1)
        .collect();
    let high: Vec<(f64, f64)> = layers
        .values()
        .filter(|x| x.3 > z_overlap && !x.2 && x.0 < imz_top - h)
        .map(|x| (x.0, x.1))
        .collect();
    assert!(
        !low.is_empty() && high.len() >= 10,
        "low {low:?} high {high:?}"
    );
    let low_min = low.iter().cloned().fold(f64::INFINITY, f64::min);
    let (z_worst, high_max) =
        high.iter()
            .cloned()
            .fold((0.0, 0.0f64), |a, x| if x.1 > a.1 { x } else { a });
    eprintln!(
        "CV of layers from below 0.5 z_overlap ≥ {low_min:.3}; CV of layers now above the overlap ≤ {high_max:.3} (origin z {z_worst:.3}; {} layers from origin {:.3} m)",
        high.len(),
        high[0].0
    );
    assert!(low_min >= 0.5, "low layers not concentrated: {low:?}");
    assert!(high_max <= 0.15, "high layers not uniform: {high:?}");
}

// ---------------------------------------------------------------------------------------
// 5. Convergence
// ---------------------------------------------------------------------------------------

#[test]
fn results_settle_as_resolution_is_refined() {
    // Isolated Castro draw of 40 kg at h = 50, 25 and 12.5 mm, marker spacing h/2 and
    // increment 0.8, 0.4 and 0.2 kg (all three halved each time). The mean grade drawn is
    // the tonne-weighted `elev` grade (the mean origin elevation of what was drawn).
    let b = UniformBox {
        periods: 2,
        tonnes: 0.02,
        ..UniformBox::castro_isolated()
    };
    let scene = b.scene();
    let mut res = Vec::new();
    for (h, inc) in [(0.05, 0.0008), (0.025, 0.0004), (0.0125, 0.0002)] {
        let out = run(&scene, &scenario(h, 0.5 * h, inc));
        let ex = &out.extraction;
        let t: f64 = ex.tonnes.iter().sum();
        let grade = (0..ex.tonnes.len())
            .map(|k| ex.tonnes[k] * ex.grades[0][k])
            .sum::<f64>()
            / t;
        let w = 2.0 * disks(&out, 0, 2).iter().map(|x| x.2).fold(0.0, f64::max);
        eprintln!(
            "h {h}: mean drawn grade {grade:.4} m, max IMZ width {w:.4} m, corrections {:?}",
            ex.correction
        );
        res.push((grade, w));
    }
    let dg = [(res[1].0 - res[0].0).abs(), (res[2].0 - res[1].0).abs()];
    let dw = [(res[1].1 - res[0].1).abs(), (res[2].1 - res[1].1).abs()];
    eprintln!(
        "grade changes {:.5} then {:.5}; width changes {:.5} then {:.5}",
        dg[0], dg[1], dw[0], dw[1]
    );
    // Each halving of h, the spacing and the increment shrinks the change: a first-order
    // method halves it; the measured ratios are 0.36 (grade) and 0.55 (width), so the
    // bound is 0.75, and the last change is under 1% of the value (measured 0.40% and
    // 0.42%): the results have settled at these resolutions.
    assert!(dg[1] < 0.75 * dg[0], "grade: {dg:?}");
    assert!(dw[1] < 0.75 * dw[0], "width: {dw:?}");
    assert!(dg[1] < 0.01 * res[2].0, "grade: {dg:?} at {}", res[2].0);
    assert!(dw[1] < 0.01 * res[2].1, "width: {dw:?} at {}", res[2].1);
}
