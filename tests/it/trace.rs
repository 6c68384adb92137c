//! Integration tests: trace points (`engine::trace`, issue 19) and MassFlow's report
//! layouts (`output::massflow`). The scene is one small box of Castro material with an
//! isolated drawpoint at its centre ([`box_scene`]), at an explicit coarse resolution, so
//! each run takes about a second. Each test prints what it measured
//! (`cargo test ... trace:: -- --nocapture`).

use std::fs;

use arrow::array::{AsArray, RecordBatch};
use arrow::datatypes::{Float64Type, Int64Type};
use caveflow::engine::result::TraceTable;
use caveflow::engine::{Engine, MarkerState, RunOutput};
use caveflow::model::load::load_scene;
use caveflow::model::synthetic::UniformBox;
use caveflow::model::{Scenario, Scene};
use caveflow::output::inputs::write_scene;
use tempfile::TempDir;

use crate::fixtures::{assert_identical, caveflow_in, entries, expect, read_parquet, scenario};

/// A 0.8 × 0.8 × 1.2 m box of Castro material (8.3 mm fragments, 50 mm blocks) with one
/// 120 mm drawpoint at its centre, drawn 20 kg a period for 8 periods; h = 25 mm, markers
/// 25 mm, 0.4 kg increments.
fn box_scene() -> (Scene, Scenario) {
    let b = UniformBox {
        extent: [0.8, 0.8, 1.2],
        periods: 8,
        tonnes: 0.02,
        ..UniformBox::castro_isolated()
    };
    (b.scene(), scenario(0.025, 0.025, 0.0004))
}

fn run_traced(scene: &Scene, sc: &Scenario, points: &[[f64; 3]]) -> RunOutput {
    Engine::new(scene, sc)
        .unwrap()
        .with_trace(points)
        .run(&mut |_, _| {})
}

/// The rows of trace point `id` (1-based), in period order.
fn rows_of(t: &TraceTable, id: i64) -> Vec<usize> {
    (0..t.trace_id.len())
        .filter(|&k| t.trace_id[k] == id)
        .collect()
}

/// IMZ radius of drawpoint 0 at elevation z at the end of the last period.
fn final_radius_at(out: &RunOutput, z: f64) -> f64 {
    let t = &out.imz;
    let last = t.period.iter().copied().max().unwrap();
    (0..t.radius.len())
        .find(|&k| t.period[k] == last && t.z_base[k] <= z && z < t.z_top[k])
        .map_or(0.0, |k| t.radius[k])
}

#[test]
fn a_point_on_the_axis_is_drawn_before_one_near_the_imz_limit() {
    let (scene, sc) = box_scene();
    let plain = Engine::new(&scene, &sc).unwrap().run(&mut |_, _| {});
    let z = 0.3;
    let r = final_radius_at(&plain, z);
    assert!(r > 0.05, "the IMZ must pass z = {z} (R = {r})");
    let axis = [0.0, 0.0, z];
    let edge = [0.85 * r, 0.0, z];
    let out = run_traced(&scene, &sc, &[axis, edge]);
    let t = &out.trace;
    assert_eq!(t.trace_id.len(), 2 * scene.periods.len());
    let (a, e) = (rows_of(t, 1), rows_of(t, 2));
    let last = |rows: &[usize]| *rows.last().unwrap();
    let drawn_a = t.drawn_period[last(&a)];
    let drawn_e = t.drawn_period[last(&e)];
    eprintln!(
        "IMZ radius at z {z} m: {r:.3} m; axis point drawn in period {drawn_a}, point at {:.3} m from the axis: {drawn_e} (final z {:.3} m, state {})",
        edge[0],
        t.z[last(&e)],
        t.state[last(&e)].name()
    );
    assert!(drawn_a > 0, "the axis point is drawn");
    assert_eq!(t.state[last(&a)], MarkerState::Drawn);
    assert_eq!(t.drawpoint[last(&a)], 0);
    assert!(
        drawn_e == -1 || drawn_e > drawn_a,
        "the point near the IMZ limit is drawn in period {drawn_e}, not after {drawn_a}"
    );
    // The point near the limit is inside the IMZ: mobilised, and it has come down.
    assert_ne!(t.state[last(&e)], MarkerState::InSitu);
    assert!(
        t.z[last(&e)] < z - 0.01,
        "it moved down: z {}",
        t.z[last(&e)]
    );
    // Once drawn, a point stays where it left the IMZ, below the drawpoint's first disk.
    let k = a
        .iter()
        .position(|&k| t.state[k] == MarkerState::Drawn)
        .unwrap();
    assert!(a[k..]
        .iter()
        .all(|&j| t.z[j] == t.z[a[k]] && t.z[j] < 0.025));
}

#[test]
fn a_point_in_stagnant_ground_never_moves() {
    let (scene, sc) = box_scene();
    // Low in a corner of the box (the base angle keeps the IMZ near the opening there), and
    // high in another corner.
    let points = [[0.35, 0.35, 0.05], [-0.375, 0.375, 1.1]];
    // A point on the axis in the same run moves: the draw reaches trace points.
    let out = run_traced(&scene, &sc, &[points[0], points[1], [0.0, 0.0, 0.3]]);
    let t = &out.trace;
    let moved = rows_of(t, 3);
    assert_eq!(t.state[*moved.last().unwrap()], MarkerState::Drawn);
    for (i, p) in points.iter().enumerate() {
        let r = final_radius_at(&out, p[2]);
        let a = p[0].hypot(p[1]);
        eprintln!("point {p:?}: {a:.3} m from the axis, final IMZ radius there {r:.3} m");
        assert!(a > r, "the IMZ reached the point");
        for k in rows_of(t, i as i64 + 1) {
            assert_eq!(t.state[k], MarkerState::InSitu);
            assert_eq!(
                [t.x[k], t.y[k], t.z[k]].map(f64::to_bits),
                p.map(f64::to_bits)
            );
            assert_eq!((t.shear_strain[k], t.drawn_period[k]), (0.0, -1));
        }
    }
}

#[test]
fn trace_points_change_no_other_output_and_survive_a_resume() {
    let (scene, sc) = box_scene();
    let points = [[0.0, 0.0, 0.3], [0.1, -0.05, 0.5], [0.35, 0.35, 0.05]];
    let plain = Engine::new(&scene, &sc).unwrap().run(&mut |_, _| {});
    let traced = run_traced(&scene, &sc, &points);
    assert!(plain.trace.trace_id.is_empty());
    let mut without = traced.clone();
    without.trace = TraceTable::default();
    assert_identical(&plain, &without, "with trace points");

    // The written tables are byte-identical; only trace.parquet is added.
    let write = |out: &RunOutput| {
        let dir = TempDir::new().unwrap();
        let m = caveflow::output::Manifest::new(String::new(), &sc, Vec::new(), out, 1, 0.0);
        caveflow::output::write_run(dir.path(), &scene, out.clone(), &m).unwrap();
        dir
    };
    let (a, b) = (write(&plain), write(&traced));
    let files = entries(a.path());
    let mut compared = 0;
    let snapshot = format!("markers/period={}/part-0.parquet", scene.periods.len());
    let tables = files.iter().filter(|f| f.ends_with(".parquet"));
    for f in tables.chain([&snapshot]) {
        let (x, y) = (
            fs::read(a.path().join(f)).unwrap(),
            fs::read(b.path().join(f)).unwrap(),
        );
        assert!(x == y, "{f} differs with trace points");
        compared += 1;
    }
    assert!(compared >= 6, "{files:?}");
    let mut with = entries(b.path());
    with.retain(|f| !files.contains(f));
    assert_eq!(with, ["trace.parquet"]);

    // A run resumed from a checkpoint follows the trace points to the same places.
    let mut mid = None;
    let e = Engine::new(&scene, &sc).unwrap().with_trace(&points);
    let _ = e.run_from(0, &mut |_, _| {}, &mut |e: &Engine, next: usize| {
        if next == 3 {
            mid = Some(e.checkpoint(next, "tag"));
        }
        Ok::<(), ()>(())
    });
    let (e, at) = Engine::resume(&scene, &sc, &mid.unwrap(), "tag").unwrap();
    let resumed = e
        .run_from(at, &mut |_, _| {}, &mut |_: &Engine, _: usize| {
            Ok::<(), ()>(())
        })
        .unwrap();
    assert_eq!(resumed.trace, traced.trace, "resumed at period index {at}");
    // And a run is a pure function of its inputs.
    assert_eq!(run_traced(&scene, &sc, &points).trace, traced.trace);
}

/// The box scene written as input files with a trace file, and its scenario file.
fn scene_files(trace: &str) -> (TempDir, std::path::PathBuf) {
    let (scene, sc) = box_scene();
    let dir = TempDir::new().unwrap();
    let files = write_scene(dir.path(), &scene, &sc).unwrap();
    fs::write(dir.path().join("trace.txt"), trace).unwrap();
    let scenario = files.last().unwrap().clone();
    (dir, scenario)
}

#[test]
fn a_trace_point_outside_the_model_is_refused() {
    let (dir, scenario) = scene_files("# x y z\n0 0 0.3\n\n0.5 0 0.3\n0.1 0.1 -0.2\n");
    let mut sc = Scenario::load(&scenario, &[]).unwrap();
    sc.inputs.trace = Some(dir.path().join("trace.txt"));
    let Err(p) = load_scene(&sc) else {
        panic!("a trace point outside the model must be refused")
    };
    eprintln!("{p}");
    assert_eq!(p.0.len(), 2, "{p}");
    let pr = expect(&p, "trace.txt", Some(4), None, "outside-model");
    assert_eq!(
        pr.to_string(),
        "trace.txt: row 4: [outside-model] trace point (0.5, 0, 0.3) lies outside the block model, which spans x -0.4..0.4, y -0.4..0.4 and z 0..1.2"
    );
    expect(&p, "trace.txt", Some(5), None, "outside-model");

    // End to end: `validate` and `run` exit 1 with the message, and `run` writes nothing.
    // The scenario key is relative to the scenario file, not to the working directory.
    let elsewhere = TempDir::new().unwrap();
    let scenario = scenario.to_str().unwrap();
    for cmd in ["validate", "run"] {
        let mut args = vec![cmd, scenario, "--set", "inputs.trace=trace.txt"];
        if cmd == "run" {
            args.extend(["--out", "out"]);
        }
        let out = caveflow_in(&args, elsewhere.path());
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{cmd}: {err}");
        assert!(err.contains(&pr.to_string()), "{cmd}: {err}");
    }
    assert!(!elsewhere.path().join("out").exists());
}

/// A report's rows as fields, after `skip` lines.
fn tsv(text: &str, skip: usize) -> (Vec<String>, Vec<Vec<String>>) {
    let mut lines = text.lines().skip(skip);
    let header = lines
        .next()
        .unwrap()
        .split('\t')
        .map(String::from)
        .collect();
    let rows = lines
        .map(|l| l.split('\t').map(String::from).collect())
        .collect();
    (header, rows)
}

fn f64_col<'a>(b: &'a RecordBatch, name: &str) -> &'a arrow::array::Float64Array {
    b.column_by_name(name)
        .unwrap()
        .as_primitive::<Float64Type>()
}

#[test]
fn trace_and_massflow_reports_end_to_end() {
    let (dir, scenario) = scene_files("0 0 0.3\n0.1 -0.05 0.5\n0.35 0.35 0.05\n");
    let scenario = scenario.to_str().unwrap();
    let out = caveflow_in(
        &[
            "run",
            scenario,
            "--trace",
            "trace.txt",
            "--massflow-reports",
            "--out",
            "out",
        ],
        dir.path(),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let run = dir.path().join("out");
    let n_periods = 8;

    // trace.parquet: one row per point per period, with the period's number and name.
    let t = read_parquet(&run.join("trace.parquet"));
    assert_eq!(t.num_rows(), 3 * n_periods);
    let names = t.column_by_name("period_name").unwrap().as_string::<i32>();
    assert_eq!(names.value(0), "1");
    let states = t.column_by_name("state").unwrap().as_string::<i32>();
    assert_eq!(states.value(3 * n_periods - 1), "in_situ");
    assert!(run.join("charts/trace.png").exists());

    // The period extraction report agrees with extraction.parquet to its printed precision.
    let ex = read_parquet(&run.join("extraction.parquet"));
    let text = fs::read_to_string(run.join("massflow/extraction_report.txt")).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("CurPrd\tCurPrdName\tDaysSolved"));
    assert_eq!(lines.next(), Some("8\t8\t8"));
    let (header, rows) = tsv(&text, 2);
    assert_eq!(
        header,
        [
            "DPName",
            "Period",
            "PrdName",
            "CumMass",
            "RingMass",
            "PeriodMass",
            "elevMass"
        ]
    );
    assert_eq!(rows.len(), ex.num_rows());
    let dp = ex.column_by_name("drawpoint").unwrap().as_string::<i32>();
    let period = ex
        .column_by_name("period")
        .unwrap()
        .as_primitive::<Int64Type>();
    let (tonnes, cum, elev) = (
        f64_col(&ex, "tonnes"),
        f64_col(&ex, "cum_tonnes"),
        f64_col(&ex, "elev"),
    );
    let mut worst = [0.0f64; 3];
    for (k, r) in rows.iter().enumerate() {
        assert_eq!(r[0], dp.value(k));
        assert_eq!(r[1], period.value(k).to_string());
        assert_eq!(r[2], period.value(k).to_string());
        let v = |i: usize| r[i].parse::<f64>().unwrap();
        assert_eq!(v(4), 0.0);
        let grade_t = tonnes.value(k) * elev.value(k) / 100.0;
        for (w, (got, want, tol)) in worst.iter_mut().zip([
            (v(3), cum.value(k), 5e-4),
            (v(5), tonnes.value(k), 5e-4),
            (v(6), grade_t, 5e-7),
        ]) {
            let e = (got - want).abs();
            assert!(e <= tol * (1.0 + 1e-9), "row {k}: {got} against {want}");
            *w = w.max(e);
        }
    }
    eprintln!(
        "{} rows read back: largest differences {:.1e} t (CumMass), {:.1e} t (PeriodMass), {:.1e} t (elevMass)",
        rows.len(),
        worst[0],
        worst[1],
        worst[2]
    );

    // The marker and trace reports at the last period, and the daily trace file.
    let mf = run.join("massflow");
    let (mh, markers) = tsv(
        &fs::read_to_string(mf.join("marker_report_8.txt")).unwrap(),
        0,
    );
    let (th, traces) = tsv(
        &fs::read_to_string(mf.join("trace_report_8.txt")).unwrap(),
        0,
    );
    assert_eq!(mh, th);
    assert_eq!(mh.len(), 23, "{mh:?}");
    assert_eq!(mh[9], "elev");
    assert_eq!(mh.last().unwrap(), "Type");
    assert!(!markers.is_empty());
    assert_eq!(traces.len(), 3);
    assert_eq!(traces[2][1..4], ["0.350", "0.350", "0.050"]);
    assert_eq!(traces[2][8], "0", "in situ: not active");
    assert_eq!(traces[0][22], "1", "a trace marker");
    let daily = fs::read_to_string(mf.join("trace_daily.csv")).unwrap();
    let lines: Vec<&str> = daily.lines().collect();
    assert_eq!(lines[0], "Day,MarkerID,TracerID,Easting,Northing,Elevation");
    assert_eq!(lines.len(), 1 + 3 * n_periods);
    assert_eq!(lines[3], "1,3,3,0.350,0.350,0.050");
}
