//! Integration tests of the optional mechanisms: secondary fragmentation (summary §6.3) and
//! fines migration (summary §7.3). Unit tests of their formulas live in
//! `src/engine/fragmentation.rs` and `src/engine/fines.rs`. Each test prints what it measured
//! (`cargo test --release mechanisms:: -- --nocapture`).

use std::collections::HashMap;

use caveflow::engine::RunOutput;
use caveflow::model::synthetic::UniformBox;
use caveflow::model::{Scenario, Scene};

use crate::fixtures::{assert_identical, run};

/// A scenario at an explicit resolution (never the automatic one), seed 11.
fn scenario(h: f64, s: f64, inc: f64) -> Scenario {
    Scenario {
        seed: 11,
        ..crate::fixtures::scenario(h, s, inc)
    }
}

/// Compares the columns the mechanisms add (bitwise), which `assert_identical` predates.
fn assert_same_additions(a: &RunOutput, b: &RunOutput, what: &str) {
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let (x, y) = (&a.extraction, &b.extraction);
    for (u, v, f) in [
        (&x.frag_p20, &y.frag_p20, "frag_p20"),
        (&x.frag_p50, &y.frag_p50, "frag_p50"),
        (&x.frag_p80, &y.frag_p80, "frag_p80"),
        (&x.fines_origin_z, &y.fines_origin_z, "fines_origin_z"),
        (
            &x.fines_waste_share,
            &y.fines_waste_share,
            "fines_waste_share",
        ),
        (&x.percolation, &y.percolation, "percolation"),
    ] {
        assert_eq!(bits(u), bits(v), "{what}: extraction {f} differs");
    }
    for (s, t) in a.snapshot_tables().iter().zip(&b.snapshot_tables()) {
        for (u, v, f) in [
            (
                &s.primary_frag_size,
                &t.primary_frag_size,
                "primary_frag_size",
            ),
            (&s.attrited, &t.attrited, "attrited"),
            (&s.percolated, &t.percolated, "percolated"),
        ] {
            assert_eq!(bits(u), bits(v), "{what}: snapshot {f} differs");
        }
    }
}

// ---------------------------------------------------------------------------------------
// 1. Off means off
// ---------------------------------------------------------------------------------------

/// Two overlapping drawpoints in Castro material whose blocks have a Weibull primary
/// distribution and a tensile strength, drawn 8 periods.
fn small_scene() -> Scene {
    let b = UniformBox {
        extent: [0.8, 0.5, 0.8],
        drawpoints: vec![(-0.1, 0.0, 0.12), (0.12, 0.0, 0.12)],
        periods: 8,
        tonnes: 0.006,
        ..UniformBox::castro_isolated()
    };
    let mut scene = b.scene();
    let bm = &mut scene.blocks;
    // Weibull α = 1.5 with mean 8.3 mm; σ_t = 50 kPa (weak model material, so that
    // attrition is visible at model-scale stresses of ~1 kPa); VMR = d̄ (summary: d_b).
    bm.frag_shape.iter_mut().for_each(|a| *a = 1.5);
    bm.frag_scale
        .iter_mut()
        .for_each(|s| *s = 0.0083 / 0.902_745_292_950_934);
    bm.tensile.iter_mut().for_each(|t| *t = 50.0);
    bm.perc_vmr.iter_mut().for_each(|v| *v = 0.0083);
    scene
}

fn small_scenario() -> Scenario {
    let mut sc = scenario(0.025, 0.025, 0.0005);
    sc.outputs.marker_periods = vec![4, 8];
    sc
}

/// Turning a mechanism off gives exactly the run without it:
/// - both off: the [fragmentation] constants and the percolation columns are not read, no
///   size is sampled (every marker carries its block's mean size) and nothing moves by
///   percolation;
/// - fragmentation on with K_N = 0 (no attrition) is bit-identical to fragmentation off,
///   with fines on in both (the size sampling they share is keyed per marker, not drawn
///   from a shared stream, so it does not depend on which mechanism asked for it);
/// - fines on with k1 = 0 (no percolation) is bit-identical to fines off, with
///   fragmentation on in both (and every marker stepping every update in both, as fines
///   require).
#[test]
fn turning_a_mechanism_off_gives_the_run_without_it() {
    let scene = small_scene();
    let base = small_scenario();
    let off = run(&scene, &base);
    let mut odd = base.clone();
    odd.fragmentation.k_n = 123.0;
    odd.fragmentation.beta = 0.3;
    let mut scene_odd = scene.clone();
    scene_odd.blocks.perc_k1.iter_mut().for_each(|k| *k = 1e4);
    let off2 = run(&scene_odd, &odd);
    assert_identical(&off, &off2, "both off, other constants");
    assert_same_additions(&off, &off2, "both off, other constants");
    let snaps = off.snapshot_tables();
    let snap = snaps.last().unwrap();
    assert!(!snap.marker_id.is_empty());
    assert!(snap.frag_size.iter().all(|&d| d == 0.0083));
    assert!(snap.attrited.iter().all(|&w| w == 0.0));
    assert!(snap.percolated.iter().all(|&l| l == 0.0));

    let with = |frag: bool, fines: bool| {
        let mut sc = base.clone();
        sc.mechanisms.fragmentation = frag;
        sc.mechanisms.fines = fines;
        sc
    };
    // Fragmentation switched off vs on without effect (fines on in both).
    let fines_only = run(&scene, &with(false, true));
    let mut no_attrition = with(true, true);
    no_attrition.fragmentation.k_n = 0.0;
    let both_k0 = run(&scene, &no_attrition);
    assert_identical(&fines_only, &both_k0, "fragmentation off vs K_N = 0");
    assert_same_additions(&fines_only, &both_k0, "fragmentation off vs K_N = 0");
    // Fines switched off vs on without effect (fragmentation on in both). Fines
    // percolation steps every marker every update (`engine::cadence`), so the run without
    // it is compared at that cadence too.
    let mut frag_every_update = with(true, false);
    frag_every_update.resolution.max_marker_move = Some(0.0);
    let frag_only = run(&scene, &frag_every_update);
    let mut scene_k0 = scene.clone();
    scene_k0.blocks.perc_k1.iter_mut().for_each(|k| *k = 0.0);
    let both_k1_0 = run(&scene_k0, &with(true, true));
    assert_identical(&frag_only, &both_k1_0, "fines off vs k1 = 0");
    assert_same_additions(&frag_only, &both_k1_0, "fines off vs k1 = 0");

    // And each mechanism, on, does change the run (so the comparisons above are not
    // vacuous).
    let both = run(&scene, &with(true, true));
    let moved = |o: &RunOutput| {
        let snaps = o.snapshot_tables();
        let s = snaps.last().unwrap();
        (
            s.attrited.iter().filter(|&&w| w > 0.0).count(),
            s.percolated.iter().filter(|&&l| l > 0.0).count(),
            s.marker_id.len(),
        )
    };
    let (att, perc, n) = moved(&both);
    eprintln!("both on: {att} of {n} markers attrited, {perc} percolated");
    assert!(att > 0 && perc > 0);
    assert_ne!(
        frag_only.extraction.frag_size, both.extraction.frag_size,
        "fines changed nothing"
    );
    assert_ne!(
        fines_only.extraction.frag_size, both.extraction.frag_size,
        "fragmentation changed nothing"
    );
}

/// Same seed, same result, on 1 and 2 threads, with both mechanisms on (the random draws
/// come from per-marker streams).
#[test]
fn mechanisms_are_deterministic_across_thread_counts() {
    let scene = small_scene();
    let mut sc = small_scenario();
    sc.mechanisms.fragmentation = true;
    sc.mechanisms.fines = true;
    let a = run(&scene, &sc);
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let b = pool.install(|| run(&scene, &sc));
        assert_identical(&a, &b, &format!("{threads} threads"));
        assert_same_additions(&a, &b, &format!("{threads} threads"));
    }
    // A different seed gives a different draw.
    let mut sc2 = sc.clone();
    sc2.seed += 1;
    let c = run(&scene, &sc2);
    assert_ne!(a.extraction.frag_size, c.extraction.frag_size);
}

// ---------------------------------------------------------------------------------------
// 2. Castro's fines tests (summary §7.4)
// ---------------------------------------------------------------------------------------

/// Per marker id: the cumulative tonnes drawn (by its drawpoint) at the end of the period
/// in which it was drawn.
fn drawn_at(out: &RunOutput) -> HashMap<i64, f64> {
    let ex = &out.extraction;
    let cum: HashMap<(u32, i64), f64> = (0..ex.period.len())
        .map(|k| ((ex.drawpoint[k], ex.period[k]), ex.cum_tonnes[k]))
        .collect();
    let d = out.drawn_table();
    (0..d.marker_id.len())
        .map(|k| (d.marker_id[k], cum[&(d.drawpoint[k], d.period[k])]))
        .collect()
}

/// The isolated Castro model (8.3 mm bed, 120 mm drawpoint), 0.8 m × 0.8 m × 1.2 m, with
/// fines placed in single 50 mm blocks. Returns the scene and, per group, the block rows.
fn castro_fines_scene(groups: &[(&str, f64, [f64; 3])]) -> (Scene, Vec<Vec<usize>>) {
    let b = UniformBox {
        extent: [0.8, 0.8, 1.2],
        periods: 40,
        tonnes: 0.003,
        ..UniformBox::castro_isolated()
    };
    let mut scene = b.scene();
    let bm = &mut scene.blocks;
    // The summary's spread L* = sqrt(d_b L̄): VMR = d_b, the bed's size.
    bm.perc_vmr.iter_mut().for_each(|v| *v = 0.0083);
    let rows = groups
        .iter()
        .map(|&(_, d, p)| {
            let b = bm.locate(p).expect("inside the model");
            bm.frag[b] = d;
            vec![b]
        })
        .collect();
    (scene, rows)
}

/// Mean cumulative tonnes at which each group's markers were drawn, the share drawn, and
/// the share that stalled: not drawn and outside the final IMZ.
fn group_stats(scene: &Scene, out: &RunOutput, rows: &[usize]) -> (f64, f64, f64, usize) {
    let at = drawn_at(out);
    let bm = &scene.blocks;
    let snaps = out.snapshot_tables();
    let snap = snaps.last().unwrap();
    let last = snap.period;
    let disks: Vec<(f64, f64)> = (0..out.imz.radius.len())
        .filter(|&k| out.imz.period[k] == last)
        .map(|k| (out.imz.z_base[k], out.imz.radius[k]))
        .collect();
    let h = disks[1].0 - disks[0].0;
    let inside = |k: usize| {
        let (x, y, z) = (snap.x[k], snap.y[k], snap.z[k]);
        disks
            .iter()
            .any(|&(zb, r)| zb <= z && z < zb + h && x.hypot(y) <= r)
    };
    let ids: Vec<usize> = (0..snap.marker_id.len())
        .filter(|&k| rows.iter().any(|&b| bm.id[b] == snap.block_id[k]))
        .collect();
    let drawn: Vec<f64> = ids
        .iter()
        .filter_map(|&k| at.get(&snap.marker_id[k]).copied())
        .collect();
    let stalled = ids
        .iter()
        .filter(|&&k| !at.contains_key(&snap.marker_id[k]) && !inside(k))
        .count();
    let n = ids.len() as f64;
    (
        drawn.iter().sum::<f64>() / drawn.len().max(1) as f64,
        drawn.len() as f64 / n,
        stalled as f64 / n,
        ids.len(),
    )
}

/// Castro's fines tests, as the summary back-analyses them (§7.4): fines of 1, 2 and 4 mm in
/// an 8.3 mm bed above an isolated 120 mm drawpoint, with the summary's spread
/// (VMR = d_b). Each group is one 50 mm block holding 64 markers (12.5 mm lattice).
/// - Groups on a ring 75 mm from the axis at 0.425 m, one per quadrant (the lattice and the
///   IMZ are symmetric under quarter turns, so the four origins are equivalent), the fourth
///   of bed material: every group is drawn, the fines earlier than the coarse group and the
///   finer the earlier. Measured (mean cumulative tonnes when drawn): 1 mm 19.0 kg, 2 mm
///   21.1 kg, 4 mm 23.3 kg, bed 24.7 kg. We require the order, and the 1 mm fines at least
///   10 % ahead of the bed (measured 23 %). With fines migration off, the same origins report
///   together (within 2 %).
/// - Groups at 0.225 m, 125 mm from the axis, near the IMZ limit where it curves in towards
///   the drawpoint: the fines percolate straight down out of the narrowing IMZ and stall,
///   while bed material from the same origin is drawn. Measured after 120 kg: stalled
///   outside the IMZ 56 % (1 mm), 48 % (2 mm), 11 % (4 mm), 0 % (bed; 79 % drawn). We
///   require more than half of the 1 mm fines stalled, the finer the more, and no bed
///   marker stalled.
#[test]
fn castro_fines_report_earlier_finer_earlier_and_stall_near_the_imz_limit() {
    let ring = |r: f64, z: f64| {
        [
            ("1 mm", 0.001, [r, 0.0, z]),
            ("2 mm", 0.002, [0.0, r, z]),
            ("4 mm", 0.004, [-r, 0.0, z]),
            ("bed 8.3 mm", 0.0083, [0.0, -r, z]),
        ]
    };
    let runs = |groups: &[(&str, f64, [f64; 3])], fines: bool| {
        let (scene, rows) = castro_fines_scene(groups);
        let mut sc = scenario(0.025, 0.0125, 0.0005);
        sc.mechanisms.fines = fines;
        sc.outputs.marker_periods = vec![40];
        let out = run(&scene, &sc);
        let stats: Vec<_> = rows.iter().map(|r| group_stats(&scene, &out, r)).collect();
        for (g, s) in groups.iter().zip(&stats) {
            eprintln!(
                "  {} (fines {fines}): {} markers, {:.0} % drawn, mean drawn at {:.2} kg, {:.0} % stalled outside the IMZ",
                g.0,
                s.3,
                100.0 * s.1,
                1000.0 * s.0,
                100.0 * s.2
            );
        }
        stats
    };
    eprintln!("ring 75 mm from the axis at 0.425 m:");
    let on = runs(&ring(0.075, 0.425), true);
    let off = runs(&ring(0.075, 0.425), false);
    for s in on.iter().chain(&off) {
        assert!(s.3 == 64 && s.1 == 1.0, "a group was not all drawn: {s:?}");
    }
    assert!(
        on[0].0 < on[1].0 && on[1].0 < on[2].0 && on[2].0 < on[3].0,
        "not finer-earlier: {on:?}"
    );
    assert!(on[0].0 < 0.9 * on[3].0, "{on:?}");
    for s in &off {
        assert!((s.0 / off[3].0 - 1.0).abs() < 0.02, "{off:?}");
    }

    eprintln!("ring 125 mm from the axis at 0.225 m (near the IMZ limit):");
    let on = runs(&ring(0.125, 0.225), true);
    let off = runs(&ring(0.125, 0.225), false);
    // Without percolation nothing leaves the IMZ; with it, most 1 mm fines stall outside it
    // while most of the bed material from the same origin is drawn.
    assert!(off.iter().all(|s| s.2 == 0.0), "{off:?}");
    assert_eq!(on[3].2, 0.0, "{on:?}");
    assert!(on[0].2 > 0.5 && on[3].1 > 0.5, "{on:?}");
    assert!(on[0].1 < on[3].1, "{on:?}");
    assert!(
        on[0].2 > on[1].2 && on[1].2 > on[2].2 && on[2].2 > on[3].2,
        "not finer-stalls-more: {on:?}"
    );
}

// ---------------------------------------------------------------------------------------
// 3. The demo panel with both mechanisms (summary §8)
// ---------------------------------------------------------------------------------------

/// The small demo panel (same generator, same seed) reduced to its drawpoints in `keep`
/// (their schedules unchanged; the block model whole).
fn demo_subset(keep: &[usize]) -> (Scene, Scenario) {
    use caveflow::model::demo::{self, DemoScale};
    let full = demo::henderson(DemoScale::Small, 7);
    let mut scene = full.clone();
    let n = full.drawpoints.len();
    let dp = &full.drawpoints;
    let d = &mut scene.drawpoints;
    d.name = keep.iter().map(|&k| dp.name[k].clone()).collect();
    d.x = keep.iter().map(|&k| dp.x[k]).collect();
    d.y = keep.iter().map(|&k| dp.y[k]).collect();
    d.z = keep.iter().map(|&k| dp.z[k]).collect();
    d.width = keep.iter().map(|&k| dp.width[k]).collect();
    d.zone = keep.iter().map(|&k| dp.zone[k].clone()).collect();
    scene.schedule.n_drawpoints = keep.len();
    scene.schedule.tonnes = (0..full.periods.len())
        .flat_map(|p| keep.iter().map(move |&k| (p, k)))
        .map(|(p, k)| full.schedule.tonnes[p * n + k])
        .collect();
    let sc = demo::scenario(DemoScale::Small, 7);
    (scene, sc)
}

/// Panel-wide figures per period of a demo run: (tonnes, tonnes-weighted reported mean
/// fragment size, waste tonnes, metal (tonnes × % Mo)), and per period the mass-weighted
/// attrited fraction W and size ratio d/d0 of the markers drawn in it.
struct PanelPeriod {
    tonnes: f64,
    frag: f64,
    waste: f64,
    metal: f64,
    attrited: f64,
    size_ratio: f64,
}

fn panel(scene: &Scene, out: &RunOutput) -> Vec<PanelPeriod> {
    let ex = &out.extraction;
    let snaps = out.snapshot_tables();
    let snap = snaps.last().unwrap();
    scene
        .periods
        .id
        .iter()
        .map(|&p| {
            let rows: Vec<usize> = (0..ex.period.len())
                .filter(|&k| ex.period[k] == p && ex.tonnes[k] > 0.0)
                .collect();
            let sum = |f: &dyn Fn(usize) -> f64| rows.iter().map(|&k| f(k)).sum::<f64>();
            let tonnes = sum(&|k| ex.tonnes[k]);
            let drawn: Vec<usize> = (0..snap.marker_id.len())
                .filter(|&k| snap.drawn_period[k] == p)
                .collect();
            let mass: f64 = drawn.iter().map(|&k| snap.mass[k]).sum();
            let per_mass = |f: &dyn Fn(usize) -> f64| {
                drawn.iter().map(|&k| snap.mass[k] * f(k)).sum::<f64>() / mass
            };
            PanelPeriod {
                tonnes,
                frag: sum(&|k| ex.tonnes[k] * ex.frag_size[k]) / tonnes,
                waste: sum(&|k| ex.tonnes[k] * ex.dilution[k]),
                metal: sum(&|k| ex.tonnes[k] * ex.grades[0][k]),
                attrited: per_mass(&|k| snap.attrited[k]),
                size_ratio: per_mass(&|k| snap.frag_size[k] / snap.primary_frag_size[k]),
            }
        })
        .collect()
}

/// Tonnes-weighted mean of `f` over a third (0, 1, 2) of the periods.
fn third(rows: &[PanelPeriod], i: usize, f: impl Fn(&PanelPeriod) -> f64) -> f64 {
    let n = rows.len();
    let part = &rows[i * n / 3..(i + 1) * n / 3];
    part.iter().map(|r| r.tonnes * f(r)).sum::<f64>() / part.iter().map(|r| r.tonnes).sum::<f64>()
}

/// The demo panel with both mechanisms on (summary §8), reduced so that it runs in about
/// 30 s: the 8 westmost drawpoints of the small demo (the two first of each drift: they
/// start first and draw furthest into the 8100 broken material), their 24-month schedule
/// unchanged, the default h (3.8 m) and marker spacing (1.9 m), 150 t increments (the
/// default is 68 t). Both runs have fragmentation on; the second adds fines migration.
///
/// Measured (tonnes-weighted thirds of the schedule, both mechanisms on): reported mean size
/// 0.2336, 0.2315, 0.2067 m; attrited fraction W of the reported material 0.010, 0.017,
/// 0.025, and d/d0 0.993, 0.989, 0.983 (so breakage at the assumed constants takes 1.7 % off
/// the size in the last third; the rest of the fall is the finer 8100 material). With fines
/// migration the cumulative waste tonnes lead the run without it in every period once waste
/// reports (12 t against none in month 15, 770 t against 12 t in month 17, 43 425 t
/// against 27 342 t at the end), and the cumulative grade from waste entry is lower in
/// every period once the lead is a thousandth of the tonnes (by 0.0016–0.0147 % Mo; here
/// from month 17, two months after the first fines' waste). The grades are compared from
/// that month on: a smaller lead cannot move the grade by more than ~0.0002 % Mo, the size
/// of the difference in the ore the two runs draw.
#[test]
fn demo_fragment_size_falls_and_fines_bring_waste_and_the_grade_drop_earlier() {
    let (scene, mut sc) = demo_subset(&[0, 1, 8, 9, 16, 17, 24, 25]);
    sc.resolution.layer_thickness = Some(3.8);
    sc.resolution.marker_spacing = Some(1.9);
    sc.resolution.draw_increment = Some(150.0);
    sc.mechanisms.fragmentation = true;
    let frag_only = panel(&scene, &run(&scene, &sc));
    sc.mechanisms.fines = true;
    let both = panel(&scene, &run(&scene, &sc));

    // Fragment size falls with draw, and breakage is part of why: the attrited fraction of
    // what reports grows, and its size relative to its primary size falls, third by third.
    let size: Vec<f64> = (0..3).map(|i| third(&both, i, |r| r.frag)).collect();
    let w: Vec<f64> = (0..3).map(|i| third(&both, i, |r| r.attrited)).collect();
    let ratio: Vec<f64> = (0..3).map(|i| third(&both, i, |r| r.size_ratio)).collect();
    eprintln!("by thirds of draw: size {size:.4?} m, W {w:.4?}, d/d0 {ratio:.4?}");
    assert!(size[2] < size[0], "{size:?}");
    assert!(w[0] < w[1] && w[1] < w[2], "{w:?}");
    assert!(ratio[0] > ratio[1] && ratio[1] > ratio[2], "{ratio:?}");

    // Waste (the 8100 material above) reports earlier with fines migration, and the
    // cumulative grade from waste entry drops earlier.
    let cum = |rows: &[PanelPeriod], f: &dyn Fn(&PanelPeriod) -> f64| {
        rows.iter()
            .scan(0.0, |c, r| {
                *c += f(r);
                Some(*c)
            })
            .collect::<Vec<f64>>()
    };
    let (waste_off, waste_on) = (cum(&frag_only, &|r| r.waste), cum(&both, &|r| r.waste));
    let entry = waste_off
        .iter()
        .zip(&waste_on)
        .position(|(a, b)| *a > 0.0 || *b > 0.0)
        .expect("no waste reported");
    eprintln!(
        "cumulative waste from month {}: without fines {:.0?} t, with {:.0?} t",
        entry + 1,
        &waste_off[entry..],
        &waste_on[entry..]
    );
    for p in entry..waste_on.len() {
        assert!(waste_on[p] > waste_off[p], "month {}", p + 1);
    }
    let grade = |rows: &[PanelPeriod]| {
        let t = cum(&rows[entry..], &|r| r.tonnes);
        let m = cum(&rows[entry..], &|r| r.metal);
        m.iter().zip(&t).map(|(m, t)| m / t).collect::<Vec<f64>>()
    };
    let (g_off, g_on) = (grade(&frag_only), grade(&both));
    eprintln!("cumulative grade from waste entry: without fines {g_off:.4?}, with {g_on:.4?}");
    let tonnes = cum(&both[entry..], &|r| r.tonnes);
    let lead = (0..tonnes.len())
        .position(|k| waste_on[entry + k] - waste_off[entry + k] >= 1e-3 * tonnes[k])
        .expect("fines never lead by a thousandth of the tonnes");
    assert!(lead <= 2, "the lead took {lead} months to build");
    for (a, b) in g_off[lead..].iter().zip(&g_on[lead..]) {
        assert!(b < a, "{g_off:?} vs {g_on:?}");
    }
}
