//! Integration tests: the marker pass's shortcuts against the plain computation: the fused
//! pass, the active set, idle markers, the multi-rate cadence, and the run's account.

use std::collections::HashMap;

use caveflow::engine::{Engine, RunOutput};
use caveflow::model::synthetic::UniformBox;
use caveflow::model::{Scenario, Scene};

use crate::fixtures::{encoded, scenario};

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
    let ((drawn_fused, caps_fused), (drawn_two, caps_two)) = e.with_last_field(|field| {
        (
            move_markers(&mut fused, field, None),
            move_markers(&mut two, field, Some(&noop)),
        )
    });
    eprintln!("{} markers, {} drawn", fused.len(), drawn_fused.len());
    assert!(fused.len() > 1000 && !drawn_fused.is_empty());
    assert_eq!(drawn_fused, drawn_two);
    assert_eq!(caps_fused, caps_two);
    assert_eq!(caps_fused.moves, fused.len() as u64);
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
    use caveflow::engine::markers::{move_markers, move_rows, Markers, Step, StepExtra};
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
        for extra in [None, Some(&hook as &dyn StepExtra)] {
            let (mut a, mut b) = (e.markers.clone(), e.markers.clone());
            let (mut da, caps_a) = move_markers(&mut a, field, extra);
            let (mut db, caps_b) =
                move_rows(&mut b, std::slice::from_ref(field), extra, &all, None);
            da.sort_unstable();
            db.sort_unstable();
            assert!(!da.is_empty());
            assert_eq!(da, db);
            assert_eq!(caps_a, caps_b);
            same(&a, &b);
            // A subset: those rows as in the full pass, the others untouched.
            let mut c = e.markers.clone();
            let (dc, caps_c) = move_rows(&mut c, std::slice::from_ref(field), extra, &odd, None);
            assert_eq!(caps_c.moves, odd.len() as u64);
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
    // default resolution's own error against a converged run (0.086 %, `docs::validation`), i.e. the
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
/// where it moves, so hits per step lie between 0 and the candidates per step); each
/// phase is charged wall and CPU time.
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
        assert!(
            account.cpu(p).as_nanos() > 0,
            "{} never charged CPU time",
            p.name()
        );
    }
    let sum: std::time::Duration = PHASES.iter().map(|&p| account.time(p)).sum();
    assert!(account.engine_time() < sum);
}

/// The caps of the marker moves (`engine::markers::caps`) are counted over every marker
/// step the run makes, the cadence's catch-up steps included, and their tally is the same
/// whether one thread or two split the passes (its sums are integers). On the Castro
/// isolated draw the one IMZ widens by a small part of its radius per update in uniform
/// ground, so no cap on the push, the squeeze or the lateral move binds, and the manifest
/// would report zeros for them.
#[test]
fn the_caps_count_every_marker_step_whatever_the_threads() {
    let (scene, sc) = castro_3_periods();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let out = Engine::new(&scene, &sc)
                .unwrap()
                .keep_account()
                .run(&mut |_, _| {});
            (out.account.unwrap().counters.marker_steps, out.marker_caps)
        })
    };
    let ((steps, one), (_, two)) = (run(1), run(2));
    assert_eq!(one, two);
    let r = one.report();
    eprintln!("{r:?}");
    assert_eq!(r.moves, steps);
    assert!(r.moves > 10_000 && r.moved_tonne_metres > 0.0);
    for c in [r.push, r.squeeze, r.lateral] {
        assert_eq!((c.moves, c.dropped_tonne_metres), (0, 0.0), "{r:?}");
    }
}
