//! Integration tests: the Ray driver (`src/python/caveflow_ray`), `caveflow study
//! --summary-only`, and DuckDB reading a study's dataset, on the demo's example study and
//! on the studies of the tiny two-drawpoint box (`fixtures::study_scene_files`).
//!
//! The Python-backed tests need a Python with `ray` and `duckdb` (`.ci/run` makes one under
//! `~/.cache/caveflow/venv`): its path in `CAVEFLOW_PY`. Without it they print a note and
//! pass. Each starts a local Ray cluster of 2 CPUs on 127.0.0.1 (a few seconds); they take
//! a lock so that two clusters never share the 2 cores.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::Mutex;

use arrow::array::{Array, AsArray, RecordBatch};
use arrow::datatypes::Float64Type;

use crate::fixtures::{
    assert_same_study, caveflow_out, dataset_files, demo_copy, read_parquet, repo, study_file,
    study_scene_files, STUDY_GRID_ALT,
};

/// One local Ray cluster at a time.
static RAY: Mutex<()> = Mutex::new(());

/// The Python of `CAVEFLOW_PY`, or `None` after a note that `what` is skipped.
fn python(what: &str) -> Option<PathBuf> {
    match std::env::var_os("CAVEFLOW_PY") {
        Some(p) if !p.is_empty() => Some(PathBuf::from(p)),
        _ => {
            eprintln!("note: {what} skipped: CAVEFLOW_PY is not set (a Python with ray and duckdb; .ci/run makes one)");
            None
        }
    }
}

/// `CAVEFLOW_PY -m caveflow_ray args…` with the binary under test; the cluster lock held.
fn driver(py: &Path, args: &[&str]) -> Output {
    let _one = RAY.lock().unwrap_or_else(|e| e.into_inner());
    let out = Command::new(py)
        .args(["-m", "caveflow_ray"])
        .args(args)
        .env("PYTHONPATH", repo("src/python"))
        .env("CAVEFLOW_BIN", env!("CARGO_BIN_EXE_caveflow"))
        .env_remove("RAY_ADDRESS")
        .output()
        .unwrap();
    eprintln!(
        "driver {args:?}: {}\n--- stdout\n{}--- stderr (tail)\n{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        tail(&String::from_utf8_lossy(&out.stderr), 15)
    );
    out
}

fn tail(s: &str, n: usize) -> String {
    let lines: Vec<&str> = s.lines().collect();
    lines[lines.len().saturating_sub(n)..].join("\n")
}

/// The `attempt` lines of a variant's driver log.
fn attempts(out: &Path, variant: &str) -> usize {
    let log = fs::read_to_string(out.join("ray").join(format!("{variant}.log"))).unwrap();
    log.lines().filter(|l| l.starts_with("attempt on ")).count()
}

#[test]
fn summary_only_runs_nothing_and_names_the_variants_not_complete() {
    let tmp = tempfile::tempdir().unwrap();
    study_scene_files(tmp.path());
    let path = study_file(
        tmp.path(),
        "[grid]\n\"calibration.frag_factor.uniform\" = [0.8, 1.0]\n",
    );
    let (s, out) = (path.to_str().unwrap(), tmp.path().join("out"));
    let o = out.to_str().unwrap();
    let r = caveflow_out(&["study", s, "--out", o, "--variant", "uniform-1.0"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let r = caveflow_out(&["study", s, "--out", o, "--summary-only"]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{err}");
    assert!(err.contains("1 variant(s) not complete"), "{err}");
    assert!(err.contains(": uniform-0.8"), "{err}");
    assert!(!out.join("variants/uniform-0.8").exists(), "nothing run");
    assert_eq!(read_parquet(&out.join("summary.parquet")).num_rows(), 1);
    let r = caveflow_out(&["study", s, "--out", o, "--variant", "uniform-0.8"]);
    assert!(r.status.success());
    let r = caveflow_out(&["study", s, "--out", o, "--summary-only"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(String::from_utf8_lossy(&r.stdout).contains("2 of 2 variant(s) complete"));
    assert_eq!(read_parquet(&out.join("summary.parquet")).num_rows(), 2);
    // Not with --plan or --variant.
    let r = caveflow_out(&["study", s, "--out", o, "--summary-only", "--plan"]);
    assert_eq!(r.status.code(), Some(1));
}

/// The demo's example study (`data/study.toml`: 2 Urad fragment factors × 2 schedules),
/// cut to its first 6 periods to stay cheap, run by the local runner and by the Ray driver:
/// the same Parquet, file for file and byte for byte; run again on Ray, nothing is
/// submitted and nothing changes.
#[test]
fn the_ray_driver_writes_the_parquet_of_the_local_runner() {
    let Some(py) = python("the_ray_driver_writes_the_parquet_of_the_local_runner") else {
        return;
    };
    let tmp = demo_copy();
    fs::copy(
        repo("data/schedule_slow.csv"),
        tmp.path().join("schedule_slow.csv"),
    )
    .unwrap();
    let study = fs::read_to_string(repo("data/study.toml"))
        .unwrap()
        .replace(
            "scenario = \"scenario.toml\"\n",
            "scenario = \"scenario.toml\"\nkeep_periods = 6\n",
        );
    assert!(study.contains("keep_periods = 6"));
    let path = tmp.path().join("study.toml");
    fs::write(&path, study).unwrap();
    let s = path.to_str().unwrap();
    let (local, ray) = (tmp.path().join("local"), tmp.path().join("ray"));
    let r = caveflow_out(&["study", s, "--out", local.to_str().unwrap(), "--jobs", "2"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let r = driver(&py, &[s, "--out", ray.to_str().unwrap()]);
    assert!(r.status.success());
    let stdout = String::from_utf8_lossy(&r.stdout);
    assert!(stdout.contains("4 variant(s), 4 to run on Ray"), "{stdout}");
    // 4 variants × 6 periods × (extraction, imz, drawn), and air_gap/surface where written.
    let n = assert_same_study(&local, &ray);
    assert!(n >= 4 * 18, "{n} Parquet files");
    assert_eq!(read_parquet(&ray.join("summary.parquet")).num_rows(), 4);
    // Run again: every variant complete, none submitted, the same files.
    let before = dataset_files(&ray);
    let r = driver(&py, &[s, "--out", ray.to_str().unwrap()]);
    assert!(r.status.success());
    assert!(String::from_utf8_lossy(&r.stdout).contains("4 variant(s), 0 to run on Ray"));
    assert!(dataset_files(&ray) == before);
}

#[test]
fn a_ray_task_killed_once_is_retried_and_the_dataset_is_the_same() {
    let Some(py) = python("a_ray_task_killed_once_is_retried_and_the_dataset_is_the_same") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    study_scene_files(tmp.path());
    let path = study_file(
        tmp.path(),
        "[grid]\n\"calibration.frag_factor.uniform\" = [0.8, 1.0]\n",
    );
    let s = path.to_str().unwrap();
    let (local, ray) = (tmp.path().join("local"), tmp.path().join("ray"));
    let r = caveflow_out(&["study", s, "--out", local.to_str().unwrap()]);
    assert!(r.status.success());
    // The first attempt of uniform-0.8 kills caveflow and then its own Ray worker (SIGKILL).
    let killed = "uniform-0.8";
    let r = driver(
        &py,
        &[
            s,
            "--out",
            ray.to_str().unwrap(),
            "--kill-once",
            killed,
            "--kill-after",
            "0.05",
        ],
    );
    assert!(r.status.success());
    assert!(ray.join("ray").join(format!("{killed}.killed")).exists());
    assert_eq!(attempts(&ray, killed), 2, "killed once, retried once");
    assert_eq!(attempts(&ray, "uniform-1.0"), 1);
    let log = fs::read_to_string(ray.join("ray").join(format!("{killed}.log"))).unwrap();
    assert!(log.contains("fault injection"), "{log}");
    assert!(log.trim_end().ends_with("exit 0"), "{log}");
    assert_same_study(&local, &ray);
}

#[test]
fn a_variant_with_invalid_input_is_not_retried_and_is_reported() {
    let Some(py) = python("a_variant_with_invalid_input_is_not_retried_and_is_reported") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    study_scene_files(tmp.path());
    // A schedule with negative tonnes: that variant's input is invalid (exit 1).
    let good = fs::read_to_string(tmp.path().join("schedule.csv")).unwrap();
    let mut lines: Vec<String> = good.lines().map(String::from).collect();
    let last = lines.last_mut().unwrap();
    let cut = last.rfind(',').unwrap();
    last.replace_range(cut + 1.., "-1");
    fs::write(tmp.path().join("schedule_bad.csv"), lines.join("\n") + "\n").unwrap();
    let path = study_file(
        tmp.path(),
        "[alternatives.schedule]\nbase = {}\nalt = { schedule = \"schedule_alt.csv\" }\nbad = { schedule = \"schedule_bad.csv\" }\n",
    );
    let s = path.to_str().unwrap();
    let ray = tmp.path().join("ray");
    let r = driver(&py, &[s, "--out", ray.to_str().unwrap()]);
    assert_eq!(r.status.code(), Some(1));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("error: variant schedule-bad: invalid input (exit 1)"),
        "{err}"
    );
    assert!(
        err.contains("not complete") && err.contains("schedule-bad"),
        "{err}"
    );
    assert_eq!(attempts(&ray, "schedule-bad"), 1, "not retried");
    let log = fs::read_to_string(ray.join("ray/schedule-bad.log")).unwrap();
    assert!(
        log.contains("schedule_bad.csv") && log.contains("exit 1"),
        "{log}"
    );
    // The others complete, and in the summary.
    let summary = read_parquet(&ray.join("summary.parquet"));
    let names = summary
        .column_by_name("variant")
        .unwrap()
        .as_string::<i32>();
    let names: Vec<&str> = names.iter().flatten().collect();
    assert_eq!(names, ["schedule-alt", "schedule-base"]);
}

/// Tonnes and the tonnage-weighted `elev` per variant from DuckDB over the Hive-partitioned
/// extraction dataset, and the same columns of `summary.parquet` read by DuckDB too.
const DUCKDB: &str = r#"
import duckdb, json, sys
out = sys.argv[1]
con = duckdb.connect()
ds = con.execute(f"""
    select scenario, study, count(*) as n, sum(tonnes) as t,
           sum(tonnes * elev) filter (where tonnes > 0 and isfinite(elev))
             / sum(tonnes) filter (where tonnes > 0 and isfinite(elev)) as g
    from read_parquet('{out}/dataset/extraction/**/*.parquet', hive_partitioning = true)
    group by scenario, study order by scenario""").fetchall()
sm = con.execute(f"select variant, tonnes, elev from read_parquet('{out}/summary.parquet') order by variant").fetchall()
print(json.dumps({"dataset": ds, "summary": sm}))
"#;

#[test]
fn duckdb_reads_the_tonnes_and_grades_of_the_summary_from_the_dataset() {
    let Some(py) = python("duckdb_reads_the_tonnes_and_grades_of_the_summary_from_the_dataset")
    else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    study_scene_files(tmp.path());
    let path = study_file(tmp.path(), STUDY_GRID_ALT);
    let out = tmp.path().join("out");
    let r = caveflow_out(&[
        "study",
        path.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(r.status.success());
    let r = Command::new(&py)
        .args(["-c", DUCKDB, out.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let v: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    let (ds, sm) = (
        v["dataset"].as_array().unwrap(),
        v["summary"].as_array().unwrap(),
    );
    assert_eq!(ds.len(), 4, "{v}");
    assert_eq!(sm.len(), 4, "{v}");
    // The summary as the Rust reader sees it, for good measure.
    let summary: RecordBatch = read_parquet(&out.join("summary.parquet"));
    assert_eq!(summary.num_rows(), 4);
    let elev = summary
        .column_by_name("elev")
        .unwrap()
        .as_primitive::<Float64Type>();
    assert!(!elev.is_null(0));
    for (d, s) in ds.iter().zip(sm) {
        let name = d[0].as_str().unwrap();
        assert_eq!(name, s[0].as_str().unwrap());
        assert_eq!(d[1], "t", "the study= partition");
        assert_eq!(d[2], 6, "{name}: 2 drawpoints × 3 periods");
        let (t, g) = (d[3].as_f64().unwrap(), d[4].as_f64().unwrap());
        let (st, sg) = (s[1].as_f64().unwrap(), s[2].as_f64().unwrap());
        eprintln!("{name}: DuckDB {t:.9} t at {g:.9}; summary {st:.9} t at {sg:.9}");
        assert!(
            t > 0.0 && (t - st).abs() <= 1e-12 * st.max(1.0),
            "{name}: tonnes {t} vs {st}"
        );
        assert!(
            (g - sg).abs() <= 1e-12 * sg.abs().max(1.0),
            "{name}: grade {g} vs {sg}"
        );
    }
}

/// `caveflow calibrate --runner "PY -m caveflow_ray"`: every batch of the calibration's
/// runs as Ray tasks of the same binary (`analysis::calibrate_runs`), read back from the
/// same layout: the `calibration.json` of the local runner, byte for byte, on the smallest
/// calibration of the back-analysis tests.
#[test]
fn calibrate_through_the_ray_driver_writes_the_calibration_of_the_local_runner() {
    let Some(py) =
        python("calibrate_through_the_ray_driver_writes_the_calibration_of_the_local_runner")
    else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let args = crate::backanalysis::calibration_files(tmp.path());
    let (_, local) = crate::backanalysis::calibrate_cli(&args, &tmp.path().join("local"), &[]);
    let ray = tmp.path().join("ray");
    let runner = format!("{} -m caveflow_ray", py.display());
    let _one = RAY.lock().unwrap_or_else(|e| e.into_inner());
    let mut all: Vec<&str> = args.iter().map(String::as_str).collect();
    all.extend(["--out", ray.to_str().unwrap(), "--runner", &runner]);
    let r = Command::new(env!("CARGO_BIN_EXE_caveflow"))
        .args(&all)
        .env("PYTHONPATH", repo("src/python"))
        .env_remove("RAY_ADDRESS")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&r.stderr);
    eprintln!(
        "{}\n{}",
        String::from_utf8_lossy(&r.stdout),
        tail(&stderr, 30)
    );
    assert!(matches!(r.status.code(), Some(0 | 3)), "{stderr}");
    assert!(stderr.contains("to run on Ray"), "the driver ran: {stderr}");
    let logs = fs::read_dir(ray.join("runs/ray")).unwrap().count();
    assert!(logs > 0, "the driver's task logs");
    assert_eq!(
        fs::read_to_string(ray.join("calibration.json")).unwrap(),
        local
    );
}
