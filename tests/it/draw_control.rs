//! Integration tests: draw control (`engine::draw_control`) on the demo panel: the target
//! shared within the rate limits, closures that stop a drawpoint in the period their rule
//! is met, uniform draw keeping neighbours' heights of draw together, and the realised
//! schedule run as a fixed schedule drawing the same.

use caveflow::engine::draw_control::Layout;
use caveflow::engine::fill::EXHAUSTED_FILL;
use caveflow::engine::{Engine, RunOutput};
use caveflow::model::demo::{self, DemoScale};
use caveflow::model::scenario::{DrawControl, Strategy};
use caveflow::model::{Scenario, Scene};
use caveflow::output::report::draw_control::{hod_spread, hod_spread_by_period};

/// The demo panel over its first `periods` months, at 3 m markers (a quick run: these
/// tests are about the control, not the flow's resolution).
fn demo_scene(periods: usize) -> (Scene, Scenario) {
    let mut scene = demo::henderson(DemoScale::Small, 42);
    scene.keep_periods(periods);
    let mut sc = demo::scenario(DemoScale::Small, 42);
    sc.resolution.marker_spacing = Some(3.0);
    (scene, sc)
}

fn target(rate: f64) -> DrawControl {
    DrawControl {
        strategy: Strategy::Target,
        target_rate: Some(rate),
        max_rate: Some(150.0),
        ..Default::default()
    }
}

fn run(scene: &Scene, sc: &Scenario) -> RunOutput {
    sc.check().unwrap();
    Engine::new(scene, sc).unwrap().run(&mut |_, _| {})
}

/// Realised tonnes of drawpoint `d` in period index `p`.
fn realised(out: &RunOutput, scene: &Scene, p: usize, d: usize) -> f64 {
    out.control.as_ref().unwrap().realised[p * scene.drawpoints.len() + d]
}

/// Each period's plan is min(target, what the open drawpoints may take), and no drawpoint
/// takes more than its limit: `max_rate` × days × the rate curve at its height of draw
/// over its column when the period starts (read back from the extraction rows).
///
/// A drawpoint whose IMZ held an air gap at the end of the period before, under a block
/// that has not caved by this period (read from the `imz` and `extraction` tables), is held:
/// it draws nothing and has no room. One that ran out (`exhausted`) may take no more a day
/// than it delivered then until its fill is back at `EXHAUSTED_FILL`, and one that
/// delivered nothing is closed.
#[test]
fn each_period_draws_the_target_within_the_rate_limits() {
    let (scene, mut sc) = demo_scene(24);
    sc.draw_control = DrawControl {
        rate_curve: vec![[0.0, 0.25], [0.2, 1.0]],
        max_rate: Some(300.0),
        ..target(4000.0)
    };
    sc.outputs.imz_every_period = true;
    let out = run(&scene, &sc);
    let rec = out.control.as_ref().unwrap();
    let layout = Layout::new(&scene, None);
    let n = scene.drawpoints.len();
    let (ex, bm) = (&out.extraction, &scene.blocks);
    let (mut hod, mut air, mut top) = (vec![0.0; n], vec![0.0; n], vec![f64::NAN; n]);
    let (mut running_out, mut closed) = (vec![None::<f64>; n], vec![false; n]);
    let (mut limited, mut short_periods, mut held_all, mut capped) = (0, 0, 0, 0);
    for p in 0..scene.periods.len() {
        let (days, period) = (scene.periods.days[p], scene.periods.id[p]);
        let mut room = 0.0;
        let mut held = 0;
        for (d, &h) in hod.iter().enumerate() {
            let t = realised(&out, &scene, p, d);
            if closed[d] {
                assert_eq!(t, 0.0, "period {p}: drawpoint {d} drawn after its closure");
                continue;
            }
            // The middle of the disk above the IMZ's top, where its air gap waits.
            let above = [scene.drawpoints.x[d], scene.drawpoints.y[d], top[d]];
            let caved = bm.locate(above).is_some_and(|b| bm.flowable(b, period));
            if air[d] > 0.0 && !caved {
                assert_eq!(t, 0.0, "period {p}: drawpoint {d} drawn under an air gap");
                held += 1;
                continue;
            }
            let share = h / layout.column[d];
            let rate = 300.0 * days * sc.draw_control.rate_share(share);
            let limit = rate.min(running_out[d].map_or(f64::INFINITY, |r| r * days));
            capped += usize::from(limit < rate);
            assert!(
                t <= limit * (1.0 + 1e-12),
                "period {p}, drawpoint {d}: {t} t over its limit {limit}"
            );
            room += limit;
            limited += usize::from(t >= limit * (1.0 - 1e-12) && t > 0.0);
        }
        assert_eq!(rec.production.held[p], held, "period {p}");
        held_all += held;
        let target = 4000.0 * days;
        let planned: f64 = (0..n).map(|d| realised(&out, &scene, p, d)).sum();
        let want = target.min(room);
        assert!(
            (planned - want).abs() <= 1e-9 * target,
            "period {p}: planned {planned}, min(target {target}, room {room}) = {want}"
        );
        assert!((rec.production.shortfall_tonnes[p] - (target - want)).abs() <= 1e-6 * target);
        short_periods += usize::from(room < target);
        for k in (0..ex.drawpoint.len()).filter(|&k| ex.period[k] == period) {
            let d = ex.drawpoint[k] as usize;
            hod[d] = ex.hod[k];
            air[d] = ex.air_gap[k];
            if ex.short_reason[k] == "exhausted" {
                running_out[d] = Some(ex.tonnes[k] / days);
                if ex.tonnes[k] == 0.0 {
                    let c = &rec.closures;
                    let at = c.drawpoint.iter().position(|&e| e as usize == d);
                    assert!(
                        at.is_some_and(|i| c.period[i] == period && c.reason[i] == "exhausted"),
                        "period {p}: drawpoint {d} delivered nothing and did not close"
                    );
                }
            } else if ex.fill[k] >= EXHAUSTED_FILL {
                running_out[d] = None;
            }
        }
        for (i, &d) in rec.closures.drawpoint.iter().enumerate() {
            closed[d as usize] |= rec.closures.period[i] == period;
        }
        let imz = &out.imz;
        for k in (0..imz.drawpoint.len()).filter(|&k| imz.period[k] == period) {
            let d = imz.drawpoint[k] as usize;
            top[d] = imz.z_top[k] + 0.5 * (imz.z_top[k] - imz.z_base[k]);
        }
    }
    assert!(
        held_all > 0,
        "no drawpoint was held: the rule is not exercised"
    );
    eprintln!("{held_all} drawpoint-periods held, {capped} held to what they delivered");
    assert!(
        capped > 0,
        "no drawpoint ran out: the rule is not exercised"
    );
    // Both sides of the min are exercised: young drawpoints held by the curve, and
    // periods whose target the panel could take.
    assert!(
        short_periods > 0 && short_periods < scene.periods.len(),
        "{short_periods}"
    );
    assert!(limited > 0);
}

/// A drawpoint closes in the period its rule is first met and draws nothing after: with
/// a shut-off grade above every grade over two periods, each drawpoint closes in the
/// second period in which it drew.
#[test]
fn a_drawpoint_closes_when_its_rule_is_met_and_draws_no_more() {
    let (scene, mut sc) = demo_scene(6);
    sc.draw_control = DrawControl {
        shutoff_column: Some("mo".into()),
        shutoff_grade: Some(1e9),
        shutoff_periods: Some(2),
        ..target(3000.0)
    };
    let out = run(&scene, &sc);
    let rec = out.control.as_ref().unwrap();
    let n = scene.drawpoints.len();
    let mut closed = 0;
    for d in 0..n {
        let drew: Vec<usize> = (0..scene.periods.len())
            .filter(|&p| realised(&out, &scene, p, d) > 0.0)
            .collect();
        match rec.closed[d] {
            Some(p) => {
                closed += 1;
                assert_eq!(drew.get(1), Some(&p), "drawpoint {d} drew in {drew:?}");
                assert_eq!(drew.last(), Some(&p), "drawpoint {d} drew after closing");
                let k = rec
                    .closures
                    .drawpoint
                    .iter()
                    .position(|&x| x as usize == d)
                    .unwrap();
                assert_eq!(rec.closures.period[k], scene.periods.id[p]);
                assert_eq!(rec.closures.reason[k], "shutoff_grade");
            }
            None => assert!(
                drew.len() < 2,
                "drawpoint {d} drew in {drew:?} and never closed"
            ),
        }
    }
    assert!(closed > 10, "{closed}");
}

/// Uniform draw keeps the heights of draw of neighbours together: with a 5 m tolerance
/// the mean gap between a drawpoint's height of draw and its neighbours' mean at the end
/// is smaller than with the target shared by rate alone.
#[test]
fn uniform_draw_keeps_neighbours_heights_of_draw_closer() {
    let (scene, mut sc) = demo_scene(10);
    let layout = Layout::new(&scene, None);
    // The report's uniformity chart, per period; its last point is the end's spread.
    let gaps = |out: &RunOutput| {
        let by_period = hod_spread_by_period(&scene, &out.extraction, &layout);
        let mut hod = vec![0.0; scene.drawpoints.len()];
        let ex = &out.extraction;
        for k in 0..ex.drawpoint.len() {
            hod[ex.drawpoint[k] as usize] = ex.hod[k];
        }
        assert_eq!(by_period.len(), 10);
        assert_eq!(by_period[9].1, hod_spread(&scene, &hod, &layout));
        by_period.iter().map(|g| g.1).collect::<Vec<f64>>()
    };
    sc.draw_control = DrawControl {
        max_rate: Some(400.0),
        ..target(3500.0)
    };
    let free = gaps(&run(&scene, &sc));
    sc.draw_control.uniform_tolerance = Some(5.0);
    let uniform = gaps(&run(&scene, &sc));
    eprintln!(
        "mean |HOD − neighbours' mean| per period: {free:.2?} m by rate, {uniform:.2?} m uniform"
    );
    let (free, uniform) = (free[9], uniform[9]);
    assert!(uniform < 0.8 * free, "uniform {uniform} vs by rate {free}");
}

/// A controlled run's realised schedule, drawn as a fixed schedule with the same seed and
/// resolution, gives the same extraction rows, bit for bit.
#[test]
fn the_realised_schedule_drawn_as_a_schedule_draws_the_same() {
    let (scene, mut sc) = demo_scene(5);
    sc.draw_control = DrawControl {
        uniform_tolerance: Some(10.0),
        ..target(3000.0)
    };
    let controlled = run(&scene, &sc);
    let mut fixed = scene.clone();
    fixed.schedule.tonnes = controlled.control.as_ref().unwrap().realised.clone();
    sc.draw_control = DrawControl::default();
    let replay = run(&fixed, &sc);
    let bytes = |o: &RunOutput| {
        bincode::serde::encode_to_vec(&o.extraction, bincode::config::standard()).unwrap()
    };
    assert!(controlled.extraction.drawpoint.len() > 50);
    assert!(
        bytes(&controlled) == bytes(&replay),
        "the replay's extraction rows differ"
    );
}

/// The same round trip as a user makes it, through the files: `caveflow run` of a
/// controlled scenario writes `schedule_realised.parquet`; the scenario without
/// `[draw_control]` and with that file as its schedule, run again, writes the same
/// `extraction.parquet`, byte for byte.
#[test]
fn the_realised_schedule_file_run_as_the_schedule_writes_the_same_extraction() {
    let (scene, mut sc) = demo_scene(4);
    sc.draw_control = DrawControl {
        uniform_tolerance: Some(10.0),
        ..target(3000.0)
    };
    let dir = tempfile::tempdir().unwrap();
    let (ctl, fix) = (dir.path().join("controlled"), dir.path().join("fixed"));
    caveflow::output::inputs::write_scene(&ctl, &scene, &sc).unwrap();
    sc.draw_control = DrawControl::default();
    caveflow::output::inputs::write_scene(&fix, &scene, &sc).unwrap();
    let run_cli = |scenario: &std::path::Path, out: &std::path::Path| {
        let r = crate::fixtures::caveflow_out(&[
            "run",
            scenario.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    };
    run_cli(&ctl.join("scenario.toml"), &ctl.join("out"));
    let report = std::fs::read_to_string(ctl.join("out/report.html")).unwrap();
    for part in [
        "Draw control",
        "Production against target",
        "Uniformity of the realised draw",
    ] {
        assert!(report.contains(part), "the report lacks {part}");
    }
    std::fs::copy(
        ctl.join("out/schedule_realised.parquet"),
        fix.join("realised.parquet"),
    )
    .unwrap();
    let toml_path = fix.join("scenario.toml");
    let mut doc: toml::Table = std::fs::read_to_string(&toml_path)
        .unwrap()
        .parse()
        .unwrap();
    doc["inputs"]["schedule"] = "realised.parquet".into();
    std::fs::write(&toml_path, doc.to_string()).unwrap();
    run_cli(&toml_path, &fix.join("out"));
    let read = |d: &std::path::Path| std::fs::read(d.join("out/extraction.parquet")).unwrap();
    assert!(
        read(&ctl) == read(&fix),
        "the extraction tables of the controlled run and of its realised schedule differ"
    );
}

/// The example study of draw control (`data/study_draw.toml`) plans its three strategies:
/// every variant's scenario loads and passes its checks (`study --plan` runs nothing).
#[test]
fn the_example_study_compares_three_strategies() {
    let out = tempfile::tempdir().unwrap();
    let r = crate::fixtures::caveflow_out(&[
        "study",
        crate::fixtures::repo("data/study_draw.toml")
            .to_str()
            .unwrap(),
        "--out",
        out.path().to_str().unwrap(),
        "--plan",
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let plan = String::from_utf8_lossy(&r.stdout);
    for case in ["\"schedule\"", "\"uniform\"", "\"shutoff\""] {
        assert!(plan.contains(case), "{case} not planned: {plan}");
    }
}

/// The small scene's tables with `blocks` as its block model, loaded under `toml`: the
/// single problem it has.
fn only_problem(blocks: &str, toml: &str) -> caveflow::io::Problem {
    use crate::fixtures::{write_small_scene, SMALL_SCENE_INPUTS};
    let dir = tempfile::tempdir().unwrap();
    write_small_scene(dir.path());
    std::fs::write(dir.path().join("blocks.csv"), blocks).unwrap();
    let text = format!("{SMALL_SCENE_INPUTS}{toml}");
    let sc = Scenario::from_toml(&text, "scenario.toml", &[], dir.path())
        .unwrap_or_else(|e| panic!("{e}"));
    let p = match caveflow::model::load::load_scene(&sc) {
        Ok(_) => panic!("the scene loaded but should not have"),
        Err(p) => p,
    };
    assert_eq!(p.0.len(), 1, "{p}");
    p.0[0].clone()
}

/// A grade column that `[draw_control]` or `[economics]` names and the block model lacks,
/// and a target no drawpoint can ever draw, are named with their file, column and rule.
#[test]
fn draw_control_settings_the_tables_cannot_meet_are_named() {
    use crate::fixtures::BLOCKS;
    let target = "[draw_control]\nstrategy = \"target\"\ntarget_rate = 100.0\n";
    let p = only_problem(
        BLOCKS,
        &format!("{target}shutoff_column = \"mo\"\nshutoff_grade = 0.1\n"),
    );
    assert_eq!(
        p.to_string(),
        "blocks.csv: column mo: [unknown-grade] draw_control.shutoff_column names grade column `mo`, which the block model does not have; it has: `cu`"
    );
    let p = only_problem(BLOCKS, "[economics]\nprice = { au = 50.0 }\n");
    assert_eq!(p.rule, "unknown-grade");
    assert!(
        p.message
            .starts_with("economics.price names grade column `au`"),
        "{p}"
    );
    // Every block caves in period 99, after the schedule's last (2).
    let mut late = String::new();
    for (k, line) in BLOCKS.lines().enumerate() {
        late.push_str(line);
        late.push_str(if k == 0 { ",cave_period\n" } else { ",99\n" });
    }
    let p = only_problem(&late, target);
    assert_eq!(p.rule, "never-open");
    assert_eq!(
        p.to_string(),
        "drawpoints.csv: [never-open] draw_control.strategy = \"target\": the ground above no drawpoint caves by the last period (2), so no drawpoint ever opens"
    );
}

/// A drawpoint with an `open_period` draws nothing before it, and the others take its
/// share meanwhile.
#[test]
fn a_drawpoint_opens_at_its_open_period() {
    let (mut scene, mut sc) = demo_scene(5);
    let n = scene.drawpoints.len();
    scene.drawpoints.open_period = (0..n).map(|d| (d % 2 == 0).then_some(4)).collect();
    sc.draw_control = target(2000.0);
    let out = run(&scene, &sc);
    for p in 0..scene.periods.len() {
        let late: f64 = (0..n)
            .step_by(2)
            .map(|d| realised(&out, &scene, p, d))
            .sum();
        let early: f64 = (1..n)
            .step_by(2)
            .map(|d| realised(&out, &scene, p, d))
            .sum();
        if scene.periods.id[p] < 4 {
            assert_eq!(late, 0.0, "period index {p}");
            assert!(early > 0.0);
        } else {
            assert!(late > 0.0, "period index {p}");
        }
    }
}

/// A target table gives each period's target; its bad rows are named.
#[test]
fn a_target_table_sets_each_periods_target_and_its_bad_rows_are_named() {
    use crate::fixtures::{write_small_scene, SMALL_SCENE_INPUTS};
    let dir = tempfile::tempdir().unwrap();
    write_small_scene(dir.path());
    let load = |table: &str| {
        std::fs::write(dir.path().join("target.csv"), table).unwrap();
        let text = format!(
            "{SMALL_SCENE_INPUTS}[draw_control]\nstrategy = \"target\"\ntarget_table = \"target.csv\"\n"
        );
        let sc = Scenario::from_toml(&text, "scenario.toml", &[], dir.path()).unwrap();
        (caveflow::model::load::load_scene(&sc), sc)
    };
    let (loaded, sc) = load("period,tonnes\n1,120\n2,80\n");
    let loaded = loaded.unwrap_or_else(|p| panic!("{p}"));
    assert_eq!(loaded.scene.target, Some(vec![120.0, 80.0]));
    let out = run(&loaded.scene, &sc);
    let planned = &out.control.as_ref().unwrap().production.planned_tonnes;
    assert_eq!(planned, &vec![120.0, 80.0]);
    let (loaded, _) = load("period,tonnes\n1,120\n");
    let w = &loaded.unwrap_or_else(|p| panic!("{p}")).warnings;
    assert!(w.iter().any(|w| w.rule == "no-target"), "{w:?}");
    let (err, _) = load("period,tonnes\n1,-5\n3,10\n1,4\n");
    let Err(p) = err else {
        panic!("the bad rows loaded")
    };
    let s = p.to_string();
    for line in [
        "target.csv: row 1, column tonnes: [negative] -5 tonnes: a target must be a finite number, not negative",
        "target.csv: row 2, column period: [unknown-period] period 3 is not in the periods table (1–2)",
        "target.csv: row 3, column period: [duplicate-id] period 1 appears more than once",
    ] {
        assert!(s.contains(line), "expected `{line}` in {s}");
    }
}

/// The height-of-draw limit closes a drawpoint in the first period that takes it to the
/// limit, with its height of draw recorded.
#[test]
fn the_height_of_draw_limit_closes_at_the_limit() {
    let (scene, mut sc) = demo_scene(6);
    sc.draw_control = DrawControl {
        max_hod: Some(8.0),
        ..target(3000.0)
    };
    let out = run(&scene, &sc);
    let rec = out.control.as_ref().unwrap();
    let ex = &out.extraction;
    assert!(
        rec.closures.drawpoint.len() > 10,
        "{:?}",
        rec.closures.drawpoint
    );
    for (k, &d) in rec.closures.drawpoint.iter().enumerate() {
        assert_eq!(rec.closures.reason[k], "hod_limit");
        assert!(rec.closures.hod[k] >= 8.0);
        // Below the limit at the end of every earlier period.
        let period = rec.closures.period[k];
        for r in (0..ex.drawpoint.len()).filter(|&r| ex.drawpoint[r] == d && ex.period[r] < period)
        {
            assert!(
                ex.hod[r] < 8.0,
                "drawpoint {d} passed the limit in period {}",
                ex.period[r]
            );
        }
    }
}
