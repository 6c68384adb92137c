//! Integration tests: the flow engine against conservation laws and the summary's published
//! behaviour (DESIGN §7). Every scene is a [`UniformBox`] at a coarse, explicit resolution
//! (never the automatic one, so a change of default cannot make these slow or move their
//! numbers); each tolerance says where it comes from. Each test prints what it measured
//! (`cargo test ... engine:: -- --nocapture`).

use std::collections::{BTreeMap, HashMap, HashSet};

use caveflow::engine::markers::Lattice;
use caveflow::engine::{Engine, EngineError, MarkerState, RunOutput, WarningRule};
use caveflow::model::synthetic::UniformBox;
use caveflow::model::{Scenario, Scene};

use crate::fixtures::{assert_identical, encoded, run, scenario};

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
fn disks(out: &RunOutput, dp: u32, period: i64) -> Vec<(f64, f64, f64)> {
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
fn caving_scene() -> Scene {
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

fn caving_scenario() -> Scenario {
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
// 2. Determinism
// ---------------------------------------------------------------------------------------

#[test]
fn runs_are_deterministic_across_repeats_and_thread_counts() {
    // The conservation scene: overlapping IMZs (superposition in the parallel marker
    // pass), an air gap, late caving and a blocked drawpoint.
    let scene = caving_scene();
    let sc = caving_scenario();
    let a = run(&scene, &sc);
    let b = run(&scene, &sc);
    assert_identical(&a, &b, "two runs");
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let c = pool.install(|| run(&scene, &sc));
        assert_identical(&a, &c, &format!("{threads}-thread pool"));
    }
    eprintln!(
        "{} extraction rows, {} IMZ rows, {} drawn markers identical",
        a.extraction.tonnes.len(),
        a.imz.radius.len(),
        a.drawn_len()
    );
}

#[test]
fn a_run_resumed_from_any_checkpoint_is_identical() {
    // The conservation scene again: resuming must restore overlapping IMZs, an air gap,
    // ground that caves between two listed periods and a blocked drawpoint's carry.
    let scene = caving_scene();
    let sc = caving_scenario();
    // With every mechanism on as well, resumed once mid-run: the percolation draws are
    // keyed by the marker-update count, which the checkpoint must carry.
    let mut all_on = caving_scenario();
    all_on.mechanisms.fragmentation = true;
    all_on.mechanisms.fines = true;
    all_on.mechanisms.rilling = true;
    all_on.mechanisms.stress = true;
    let expected = encoded(&run(&scene, &all_on));
    let mut mid = None;
    let _ = Engine::new(&scene, &all_on).unwrap().run_from(
        0,
        &mut |_, _| {},
        &mut |e: &Engine, next: usize| {
            if next == 3 {
                mid = Some(e.checkpoint(next, "tag"));
            }
            Ok::<(), ()>(())
        },
    );
    let (e, at) = Engine::resume(&scene, &all_on, &mid.unwrap(), "tag").unwrap();
    let resumed = e
        .run_from(at, &mut |_, _| {}, &mut |_: &Engine, _: usize| {
            Ok::<(), ()>(())
        })
        .unwrap();
    assert!(
        encoded(&resumed) == expected,
        "mechanisms on: resumed outputs differ"
    );

    let whole = encoded(&run(&scene, &sc));
    let mut checkpoints = Vec::new();
    let out = Engine::new(&scene, &sc)
        .unwrap()
        .run_from(0, &mut |_, _| {}, &mut |e: &Engine, next: usize| {
            checkpoints.push((next, e.checkpoint(next, "tag")));
            Ok::<(), ()>(())
        })
        .unwrap();
    assert_eq!(encoded(&out), whole, "checkpointing changed the run");
    assert_eq!(checkpoints.len(), scene.periods.len());
    for (next, bytes) in &checkpoints {
        let (e, at) = Engine::resume(&scene, &sc, bytes, "tag").unwrap();
        assert_eq!(at, *next);
        let resumed = e
            .run_from(at, &mut |_, _| {}, &mut |_: &Engine, _: usize| {
                Ok::<(), ()>(())
            })
            .unwrap();
        assert!(
            encoded(&resumed) == whole,
            "resumed at period index {at}: outputs differ"
        );
    }
    // A checkpoint of other inputs, or a torn one, is refused with a reason.
    let bytes = &checkpoints[2].1;
    let err = |r: Result<(Engine, usize), EngineError>| r.err().map(|e| e.to_string()).unwrap();
    assert!(err(Engine::resume(&scene, &sc, bytes, "other")).contains("other inputs"));
    assert!(err(Engine::resume(
        &scene,
        &sc,
        &bytes[..bytes.len() / 2],
        "tag"
    ))
    .contains("unreadable"));
    let other = UniformBox::castro_isolated().scene();
    assert!(err(Engine::resume(&other, &sc, bytes, "tag")).contains("does not fit"));
    eprintln!(
        "{} checkpoints ({} bytes at period index 2) resume to identical outputs",
        checkpoints.len(),
        bytes.len()
    );
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

// ---------------------------------------------------------------------------------------
// 6. Vanishing porosity jump
// ---------------------------------------------------------------------------------------

/// Everything a run wrote is finite (NaN is allowed only in the per-tonne columns of
/// extraction rows that drew nothing), and no radius exceeds the model's plan diagonal.
fn assert_finite(scene: &Scene, out: &RunOutput) {
    let ex = &out.extraction;
    for k in 0..ex.tonnes.len() {
        for (name, v) in [
            ("tonnes", ex.tonnes[k]),
            ("marker_tonnes", ex.marker_tonnes[k]),
            ("correction", ex.correction[k]),
            ("cum_tonnes", ex.cum_tonnes[k]),
            ("hod", ex.hod[k]),
            ("air_gap", ex.air_gap[k]),
        ] {
            assert!(v.is_finite(), "row {k}: {name} = {v}");
        }
        if ex.markers[k] > 0 {
            for v in [
                ex.origin_z[k],
                ex.frag_size[k],
                ex.dilution[k],
                ex.grades[0][k],
            ] {
                assert!(v.is_finite(), "row {k}: {v}");
            }
        }
    }
    let bm = &scene.blocks;
    let max = bm.max_corner();
    let diag = (max[0] - bm.origin[0]).hypot(max[1] - bm.origin[1]);
    assert!(
        out.imz
            .radius
            .iter()
            .all(|r| r.is_finite() && *r > 0.0 && *r <= diag),
        "radii: {:?}",
        out.imz.radius
    );
    for s in &out.snapshot_tables() {
        for v in [&s.x, &s.y, &s.z, &s.shear_strain, &s.shear_work] {
            assert!(v.iter().all(|x| x.is_finite()));
        }
    }
}

#[test]
fn vanishing_porosity_jump_stays_finite_and_conserves_mass() {
    let sc = scenario(0.05, 0.025, 0.001);
    // Wherever n1 − n0 → 0 the radius update R_i ← sqrt(R_i² + r v_i / (π h (n1 − n0)))
    // would divide by zero; the engine instead widens the disk for free across ground
    // already dilated (`engine::imz`). Two ways to get there:
    // (a) Successive draw beside a dilated IMZ: DP01 draws periods 1–3, then DP02, 0.3 m
    // away, draws periods 4–6 into ground DP01 already dilated (jump n1 − n1 = 0 on the
    // shared side).
    let b = UniformBox {
        extent: [1.2, 0.8, 1.5],
        drawpoints: vec![(-0.15, 0.0, 0.12), (0.15, 0.0, 0.12)],
        periods: 6,
        tonnes: 0.015,
        ..UniformBox::castro_isolated()
    };
    let mut scene = b.scene();
    for p in 0..6 {
        scene.schedule.tonnes[2 * p + usize::from(p < 3)] = 0.0;
    }
    // (b) Ground already at its dilated porosity: n0 = n1 above z = 0.6 m (say, the
    // broken remains of a level above), for one drawpoint.
    let b2 = UniformBox {
        extent: [1.0, 1.0, 1.5],
        periods: 4,
        tonnes: 0.015,
        ..UniformBox::castro_isolated()
    };
    let mut scene2 = b2.scene();
    for k in 0..scene2.blocks.len() {
        if scene2.blocks.z[k] > 0.6 {
            scene2.blocks.n0[k] = scene2.blocks.n1[k];
        }
    }
    for (name, scene) in [
        ("successive draw beside a dilated IMZ", &scene),
        ("n0 = n1 above 0.6 m", &scene2),
    ] {
        let out = run(scene, &sc);
        assert_finite(scene, &out);
        let nd = scene.drawpoints.len();
        let last = *scene.periods.id.last().unwrap();
        for (d, &(sched, credited)) in out.balance.per_drawpoint.iter().enumerate() {
            let rmax = disks(&out, d as u32, last)
                .iter()
                .map(|x| x.2)
                .fold(0.0, f64::max);
            let ex = &out.extraction;
            let markers: f64 = (0..ex.drawpoint.len())
                .filter(|&k| ex.drawpoint[k] == d as u32)
                .map(|k| ex.marker_tonnes[k])
                .sum();
            eprintln!(
                "{name}: DP{:02} credited/scheduled {:.6}, markers/scheduled {:.4}, max R {rmax:.3} m",
                d + 1,
                credited / sched,
                markers / sched
            );
            // Same 0.5% as the conservation test.
            assert!(
                (credited / sched - 1.0).abs() <= 0.005,
                "{name}: DP{:02}: {credited} of {sched}",
                d + 1
            );
            // The markers drawn weigh the schedule to 3%, the conservation test's tolerance
            // at ~10³ markers a period (measured 1.014, 1.022 and 1.025): ground widened
            // through for free is not drawn twice, nor is the void left empty.
            assert!(
                (markers / sched - 1.0).abs() <= 0.03,
                "{name}: DP{:02}: markers {markers} of {sched}",
                d + 1
            );
        }
        let c = &out.extraction.correction;
        eprintln!(
            "{name}: corrections {:.3}–{:.3}; warnings {:?}",
            c.iter().cloned().fold(9.0, f64::min),
            c.iter().cloned().fold(0.0, f64::max),
            out.warnings
        );
        assert!(out.extraction.drawpoint.iter().all(|&d| (d as usize) < nd));
        let rmax = |d: u32| disks(&out, d, last).iter().map(|x| x.2).fold(0.0, f64::max);
        if nd == 2 {
            // Ground dilated by DP01 offers DP02 a smaller jump (DESIGN §4.3): after the
            // same 45 kg, DP02's IMZ ends wider than DP01's (measured 0.278 against 0.257 m).
            assert!(rmax(1) > rmax(0), "{} vs {}", rmax(1), rmax(0));
        } else {
            // With no jump at all the disks widen for free to the edge of the dilated
            // ground, here the model walls (half-width 0.5 m; measured R 0.709 m, where
            // the last perimeter point leaves the model), and no further.
            assert!(rmax(0) >= 0.5, "{}", rmax(0));
        }
    }
}

// ---------------------------------------------------------------------------------------
// 7. Walls: IMZs bounded by flowable ground
// ---------------------------------------------------------------------------------------

/// Marker tonnes over scheduled tonnes for one drawpoint over a whole run.
fn marker_share(out: &RunOutput, dp: u32) -> f64 {
    let ex = &out.extraction;
    let (mut m, mut s) = (0.0, 0.0);
    for k in (0..ex.drawpoint.len()).filter(|&k| ex.drawpoint[k] == dp) {
        m += ex.marker_tonnes[k];
        s += ex.scheduled_tonnes[k];
    }
    m / s
}

#[test]
fn imzs_at_walls_stay_in_the_model_and_draw_their_schedule() {
    // Three drawpoints in a 1.2 × 1.2 m Castro box: one in the open (x = 0.3), one against
    // the west wall (x = −0.54, its opening touching the wall) and one in the south-west
    // corner. Far enough apart (≥ 0.6 m) that they barely interact at 60 kg each.
    let b = UniformBox {
        drawpoints: vec![(0.3, 0.3, 0.12), (-0.54, 0.3, 0.12), (-0.54, -0.54, 0.12)],
        periods: 6,
        tonnes: 0.01,
        ..UniformBox::castro_isolated()
    };
    let scene = b.scene();
    let out = run(&scene, &scenario(0.05, 0.025, 0.001));
    let last = *scene.periods.id.last().unwrap();
    // No disk is wider than the farthest point of the model from its axis (the reach of
    // flowable ground at its level); a 1.2 m box seen from the corner reaches √2 × 1.14.
    for dp in 0..3u32 {
        let (x, y) = (
            scene.drawpoints.x[dp as usize],
            scene.drawpoints.y[dp as usize],
        );
        let reach = ((0.6 + x.abs()).powi(2) + (0.6 + y.abs()).powi(2)).sqrt();
        for (_, _, r) in disks(&out, dp, last) {
            assert!(
                r <= reach + 1e-9,
                "DP{:02}: disk radius {r} > reach {reach}",
                dp + 1
            );
        }
    }
    // The void fills only the flowable share A_f of a disk, so the marker tonnes a
    // drawpoint draws do not depend on a wall cutting its IMZ: without dividing vertical
    // moves by A_f the wall drawpoint would draw about half (A_f ≈ 0.5) and the corner one
    // about a quarter of the open one. Discreteness and the early in-situ density (markers
    // engulfed at n0, drawn before the dilation reaches the drawpoint) move each share by
    // up to ~15% (measured 1.09–1.18 here), so the shares must agree within 20%.
    let open = marker_share(&out, 0);
    for dp in 1..3u32 {
        let share = marker_share(&out, dp);
        eprintln!(
            "DP{:02}: marker/scheduled {share:.3} (open ground {open:.3})",
            dp + 1
        );
        assert!(
            (share / open - 1.0).abs() < 0.2,
            "DP{:02}: marker/scheduled {share} vs {open} in open ground",
            dp + 1
        );
    }
    // And every period is credited in full without the correction saturating.
    assert!(out.extraction.status.iter().all(|s| *s == "ok"));
    assert!(out
        .extraction
        .correction
        .iter()
        .all(|&c| (0.5..=1.5).contains(&c)));
}

#[test]
fn draw_beside_a_wall_leaves_no_void_along_it() {
    // IN-T2's two drawpoints in a box only 1.2 × 0.6 m, so their IMZs reach both side
    // walls and the top. Disks wider than the box are cut by the walls (A_f < 1); the
    // inward radial move must not pull the markers off a wall where no dilating ring stands
    // behind them. It used to: the free surface beside the walls fell to 0.5 m of 3.3 m.
    let b = UniformBox {
        extent: [1.2, 0.6, 3.3],
        drawpoints: vec![(-0.35, 0.0, 0.12), (0.35, 0.0, 0.12)],
        periods: 8,
        tonnes: 0.02,
        ..UniformBox::castro_isolated()
    };
    let scene = b.scene();
    let out = run(&scene, &scenario(0.025, 0.0125, 0.0005));
    let sf = &out.surface;
    let mean = sf.z.iter().sum::<f64>() / sf.z.len() as f64;
    let wall = (0..sf.z.len())
        .filter(|&k| sf.x[k].abs() > 0.6 - 0.0125)
        .map(|k| sf.z[k])
        .fold(f64::INFINITY, f64::min);
    eprintln!("free surface: mean {mean:.3} m, lowest beside a wall {wall:.3} m");
    // The draw lowers the surface by a few centimetres overall (measured mean 3.28 m, the lowest wall column 3.30 m; 0.54 m before the fix); the
    // wall columns may sit lower than the mean by the surface's own relief (a few parcels
    // of 12.5 mm), not by metres.
    assert!(
        wall > mean - 0.1,
        "a void opened along the wall: {wall} vs mean {mean}"
    );
}

/// The Castro isolated draw over 3 periods, for the marker-pass tests.
fn castro_3_periods() -> (Scene, Scenario) {
    let b = UniformBox {
        periods: 3,
        ..UniformBox::castro_isolated()
    };
    (b.scene(), scenario(0.025, 0.0125, 0.01))
}

/// The marker pass without a hook (one fused pass) moves every marker exactly as the
/// two-pass path taken with a hook does, when the hook adds nothing: same positions, strains,
/// work and drawn rows, bit for bit.
#[test]
fn fused_marker_pass_matches_the_two_pass_path() {
    use caveflow::engine::markers::{move_markers, Markers, Step};
    let (scene, sc) = castro_3_periods();
    let mut e = Engine::new(&scene, &sc).unwrap();
    for p in 0..scene.periods.len() {
        e.run_period(p);
    }
    let (mut fused, mut two) = (e.markers.clone(), e.markers.clone());
    let noop = |_: &Markers, _: usize, _: &mut Step| {};
    let (drawn_fused, drawn_two) = e.with_last_field(|field| {
        (
            move_markers(&mut fused, field, None),
            move_markers(&mut two, field, Some(&noop)),
        )
    });
    eprintln!("{} markers, {} drawn", fused.len(), drawn_fused.len());
    assert!(fused.len() > 1000 && !drawn_fused.is_empty());
    assert_eq!(drawn_fused, drawn_two);
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    for (a, b) in [
        (&fused.x, &two.x),
        (&fused.y, &two.y),
        (&fused.z, &two.z),
        (&fused.strain, &two.strain),
        (&fused.work, &two.work),
    ] {
        assert_eq!(bits(a), bits(b));
    }
    assert_ne!(bits(&fused.z), bits(&e.markers.z), "the pass moved nothing");
}

/// The active-set marker pass (`markers::move_rows` over every row) moves every marker
/// exactly as the pass over all markers does, with and without a hook; over a subset of
/// rows it moves those rows the same and leaves the others alone.
#[test]
fn active_set_pass_matches_the_pass_over_every_marker() {
    use caveflow::engine::markers::{move_markers, move_rows, Markers, Step};
    let (scene, sc) = castro_3_periods();
    let mut e = Engine::new(&scene, &sc).unwrap();
    for p in 0..scene.periods.len() {
        e.run_period(p);
    }
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let same = |a: &Markers, b: &Markers| {
        for (a, b) in [
            (&a.x, &b.x),
            (&a.y, &b.y),
            (&a.z, &b.z),
            (&a.strain, &b.strain),
            (&a.work, &b.work),
            (&a.percolated, &b.percolated),
        ] {
            assert_eq!(bits(a), bits(b));
        }
    };
    let all: Vec<u32> = (0..e.markers.len() as u32).collect();
    let odd: Vec<u32> = all.iter().copied().filter(|k| k % 3 == 1).collect();
    let hook = |_: &Markers, k: usize, s: &mut Step| {
        s.perc = 1e-4 * (k % 7) as f64;
        s.dz -= s.perc;
    };
    e.with_last_field(|field| {
        for extra in [
            None,
            Some(&hook as &(dyn Fn(&Markers, usize, &mut Step) + Sync)),
        ] {
            let (mut a, mut b) = (e.markers.clone(), e.markers.clone());
            let mut da = move_markers(&mut a, field, extra);
            let mut db = move_rows(&mut b, std::slice::from_ref(field), extra, &all, None);
            da.sort_unstable();
            db.sort_unstable();
            assert!(!da.is_empty());
            assert_eq!(da, db);
            same(&a, &b);
            // A subset: those rows as in the full pass, the others untouched.
            let mut c = e.markers.clone();
            let dc = move_rows(&mut c, std::slice::from_ref(field), extra, &odd, None);
            assert!(dc.iter().all(|(k, _)| k % 3 == 1));
            for k in 0..c.len() {
                let want = if k % 3 == 1 { &a } else { &e.markers };
                assert_eq!(c.z[k].to_bits(), want.z[k].to_bits(), "row {k}");
                assert_eq!(c.x[k].to_bits(), want.x[k].to_bits(), "row {k}");
            }
        }
    });
}

/// Stagnant markers cost nothing: markers mobilised by a drawpoint that has stopped drawing
/// are not stepped while another, far away, draws. The same draw from the other drawpoint
/// takes the same number of marker steps, and gives the same extraction rows, whether the
/// first drawpoint drew before or never did (every marker stepping every update). With the
/// multi-rate cadence (`engine::cadence`) an idle marker steps at most once more, at the end
/// of the window in which its drawpoint last drew.
#[test]
fn idle_markers_are_not_stepped() {
    let run = |first_draws: bool, max_move: f64| {
        let b = UniformBox {
            extent: [2.4, 1.2, 3.3],
            drawpoints: vec![(-0.6, 0.0, 0.12), (0.6, 0.0, 0.12)],
            periods: 4,
            ..UniformBox::castro_isolated()
        };
        let mut scene = b.scene();
        let nd = scene.schedule.n_drawpoints;
        for p in 0..scene.periods.len() {
            // Drawpoint 0 draws in period 0 only (or never); drawpoint 1 from period 1 on.
            scene.schedule.tonnes[p * nd] = if p == 0 && first_draws { 0.02 } else { 0.0 };
            scene.schedule.tonnes[p * nd + 1] = if p == 0 { 0.0 } else { 0.02 };
        }
        let mut sc = scenario(0.025, 0.0125, 0.01);
        sc.resolution.max_marker_move = Some(max_move);
        let mut e = Engine::new(&scene, &sc).unwrap();
        e.run_period(0);
        let (mobilised, before) = (e.markers.len(), e.marker_steps);
        for p in 1..scene.periods.len() {
            e.run_period(p);
        }
        let steps = e.marker_steps - before;
        let out = e.run_from(scene.periods.len(), &mut |_, _| {}, &mut |_, _| {
            Ok::<(), ()>(())
        });
        let ex = out.unwrap().extraction;
        let rows: Vec<(i64, u64, u64)> = (0..ex.period.len())
            .filter(|&i| ex.drawpoint[i] == 1)
            .map(|i| {
                (
                    ex.period[i],
                    ex.marker_tonnes[i].to_bits(),
                    ex.markers[i] as u64,
                )
            })
            .collect();
        (mobilised, steps, rows)
    };
    let (idle, steps_idle, rows_idle) = run(true, 0.0);
    let (none, steps_none, rows_none) = run(false, 0.0);
    eprintln!("mobilised by the idle drawpoint {idle}; steps {steps_idle} vs {steps_none}");
    assert!(idle > 1000 && none == 0);
    assert!(steps_none > 0);
    assert_eq!(steps_idle, steps_none);
    assert_eq!(rows_idle, rows_none);
    let (idle, steps_idle, _) = run(true, 0.00625);
    let (_, steps_none, _) = run(false, 0.00625);
    eprintln!("with the cadence: steps {steps_idle} vs {steps_none}, {idle} idle markers");
    assert!(steps_none > 0);
    assert!(
        steps_idle <= steps_none + idle as u64,
        "{steps_idle} vs {steps_none} + {idle}"
    );
}

/// The multi-rate cadence (`engine::cadence`) on the demo's first 4 months against every
/// marker stepping every update: far fewer marker steps, the same delivered tonnes, grades
/// and IEZ within the resolution's own error, and every marker brought up to date at the end.
#[test]
fn multi_rate_cadence_saves_steps_and_keeps_the_draw() {
    use caveflow::model::demo::{self, DemoScale};
    let mut scene = demo::henderson(DemoScale::Small, 42);
    scene.keep_periods(4);
    let run = |max_move: Option<f64>| {
        let mut sc = demo::scenario(DemoScale::Small, 42);
        sc.resolution.max_marker_move = max_move;
        let mut e = Engine::new(&scene, &sc).unwrap();
        let res = e.resolution;
        for p in 0..scene.periods.len() {
            e.run_period(p);
        }
        let steps = e.marker_steps;
        let out = e
            .run_from(scene.periods.len(), &mut |_, _| {}, &mut |_, _| {
                Ok::<(), ()>(())
            })
            .unwrap();
        (res, steps, out)
    };
    let (res, steps_on, on) = run(None);
    let (_, steps_off, off) = run(Some(0.0));
    // The default: one marker spacing or half a disk, whichever is smaller (here equal).
    assert_eq!(
        res.max_marker_move,
        res.marker_spacing.min(0.5 * res.layer_thickness)
    );
    let ratio = steps_on as f64 / steps_off as f64;
    eprintln!("marker steps {steps_on} with the cadence, {steps_off} without: {ratio:.3}");
    assert!(ratio < 0.6, "{ratio}");
    // The schedule is delivered either way (the mass balance does not depend on it).
    let credited = |o: &RunOutput| o.extraction.tonnes.iter().sum::<f64>();
    assert!((credited(&on) - credited(&off)).abs() <= 1e-9 * credited(&off));
    // Grades per drawpoint-period: the relative RMSE between the two runs is within the
    // default resolution's own error against a converged run (0.086 %, README), i.e. the
    // cadence costs less accuracy than the marker spacing already does.
    let e = caveflow::analysis::sweep::grade_rmse(&on, &off);
    eprintln!("grade RMSE between the runs {:.4} %", 100.0 * e);
    assert!(e > 0.0 && e < 0.00086, "{e}");
    // Every marker is up to date at the end: the final positions of the markers that are
    // in both runs agree to well under a marker spacing for nearly all of them.
    let (on, off) = (on.snapshot_tables(), off.snapshot_tables());
    let (a, b) = (on.last().unwrap(), off.last().unwrap());
    let pos: HashMap<i64, [f64; 3]> = (0..b.marker_id.len())
        .map(|i| (b.marker_id[i], [b.x[i], b.y[i], b.z[i]]))
        .collect();
    let mut d: Vec<f64> = (0..a.marker_id.len())
        .filter_map(|i| {
            let p = pos.get(&a.marker_id[i])?;
            Some(
                ((a.x[i] - p[0]).powi(2) + (a.y[i] - p[1]).powi(2) + (a.z[i] - p[2]).powi(2))
                    .sqrt(),
            )
        })
        .collect();
    d.sort_by(f64::total_cmp);
    let q = |f: f64| d[((d.len() - 1) as f64 * f) as usize];
    eprintln!(
        "{} markers in both; |Δ| median {:.3} m, 90th {:.3} m, max move {:.3} m",
        d.len(),
        q(0.5),
        q(0.9),
        res.max_marker_move
    );
    assert!(d.len() > 10_000);
    assert!(q(0.5) < 0.25 * res.max_marker_move, "{}", q(0.5));
    assert!(q(0.9) < res.max_marker_move, "{}", q(0.9));
}

/// The run's account (`engine::account`) is a view: a run that keeps one writes every
/// output bit for bit as one that does not, and its counters agree with what the engine
/// counts anyway (marker steps, markers engulfed and drawn) and with each other (a hit is
/// a candidate that held the marker; every stepped marker lies in at least one IMZ only
/// where it moves, so hits per step lie between 0 and the candidates per step).
#[test]
fn the_account_changes_no_result_and_adds_up() {
    use caveflow::model::demo::{self, DemoScale};
    let mut scene = demo::henderson(DemoScale::Small, 42);
    scene.keep_periods(4);
    let sc = demo::scenario(DemoScale::Small, 42);
    let plain = Engine::new(&scene, &sc).unwrap().run(&mut |_, _| {});
    let mut e = Engine::new(&scene, &sc).unwrap().keep_account();
    for p in 0..scene.periods.len() {
        e.run_period(p);
    }
    let steps = e.marker_steps;
    let kept = e
        .run_from(scene.periods.len(), &mut |_, _| {}, &mut |_, _| {
            Ok::<(), ()>(())
        })
        .unwrap();
    assert!(plain.account.is_none());
    let account = kept.account.clone().expect("an account");
    assert_eq!(
        encoded(&plain),
        encoded(&kept),
        "the account moved an output"
    );
    let c = account.counters;
    eprintln!("{}", account.report());
    assert_eq!(c.marker_steps, steps, "every marker step counted once");
    assert_eq!(c.engulfed, kept.balance.markers_mobilised);
    assert_eq!(c.drawn, kept.balance.markers_drawn);
    assert!(c.updates > 0 && c.imz_draws >= c.updates && c.disk_cycles >= c.imz_draws);
    assert!(c.hits > 0 && c.hits < c.candidate_tests, "{c:?}");
    use caveflow::engine::account::{Phase, PHASES};
    for p in [
        Phase::Growth,
        Phase::MarkerPass,
        Phase::PeriodEnd,
        Phase::Finish,
    ] {
        assert!(account.time(p).as_nanos() > 0, "{} never charged", p.name());
    }
    let sum: std::time::Duration = PHASES.iter().map(|&p| account.time(p)).sum();
    assert!(account.engine_time() < sum);
}
