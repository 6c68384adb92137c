//! Integration tests: scenario studies (`analysis::study`, `caveflow study`) on the tiny
//! two-drawpoint box of `fixtures::tiny` (a run takes well under a second).

use std::collections::BTreeMap;
use std::fs;
use std::path::Path;

use arrow::array::{Array, AsArray};
use arrow::datatypes::Float64Type;
use caveflow::analysis::study::plan::{variant_hash, Swept, VERSION};
use caveflow::analysis::study::runner::{Progress, SUCCESS, TABLES};
use caveflow::analysis::study::{run_study, Layout, Outcome, Study, StudyProblems};

use crate::fixtures::{
    assert_renders, assert_same_study, caveflow, caveflow_out, entries, read_parquet, study_file,
    study_scene_files, tiny_study, STUDY_GRID_ALT,
};

struct Quiet;
impl Progress for Quiet {
    fn periods(&self, _: u64) {}
    fn finished(&self, _: &str, _: Option<&Outcome>) {}
}

#[test]
fn expansion_names_sets_and_hashes() {
    let tmp = tempfile::tempdir().unwrap();
    study_scene_files(tmp.path());
    let grid_alt_seeds = format!("seeds = [1, 2]\n{STUDY_GRID_ALT}");
    let path = study_file(tmp.path(), &grid_alt_seeds);
    let s = Study::expand(&path).unwrap();
    let names: Vec<&str> = s.variants.iter().map(|v| v.name.as_str()).collect();
    // 2 × 2 × 2, the first dimension slowest.
    assert_eq!(
        names,
        [
            "uniform-0.8_schedule-alt_seed-1",
            "uniform-0.8_schedule-alt_seed-2",
            "uniform-0.8_schedule-base_seed-1",
            "uniform-0.8_schedule-base_seed-2",
            "uniform-1.0_schedule-alt_seed-1",
            "uniform-1.0_schedule-alt_seed-2",
            "uniform-1.0_schedule-base_seed-1",
            "uniform-1.0_schedule-base_seed-2",
        ]
    );
    assert_eq!(s.columns, ["calibration.frag_factor.uniform", "schedule"]);
    let v = &s.variants[0];
    assert_eq!(v.sets[0], "calibration.frag_factor.uniform=0.8");
    assert!(v.sets[1].starts_with("inputs.schedule=") && v.sets[1].contains("schedule_alt.csv"));
    assert_eq!(v.sets[2], "seed=1");
    assert_eq!(v.seed, 1);
    assert_eq!(v.scenario.calibration.frag_factor["uniform"], 0.8);
    assert!(v.scenario.inputs.schedule.ends_with("schedule_alt.csv"));
    // Every variant differs, so every hash does.
    let hashes: std::collections::BTreeSet<&str> =
        s.variants.iter().map(|v| v.hash.as_str()).collect();
    assert_eq!(hashes.len(), 8);
    // The same study expanded again, and the same files at another path: the same hashes.
    let again = Study::expand(&path).unwrap();
    let moved = tempfile::tempdir().unwrap();
    study_scene_files(moved.path());
    let moved = Study::expand(&study_file(moved.path(), &grid_alt_seeds)).unwrap();
    for ((a, b), c) in s.variants.iter().zip(&again.variants).zip(&moved.variants) {
        assert_eq!(a.hash, b.hash);
        assert_eq!(
            a.hash, c.hash,
            "{}: the hash does not depend on where the files are",
            a.name
        );
    }
    // One changed byte in the alternative schedule: exactly its four variants change.
    let alt = tmp.path().join("schedule_alt.csv");
    let text = fs::read_to_string(&alt).unwrap();
    fs::write(&alt, format!("{text}\n")).unwrap();
    let changed = Study::expand(&path).unwrap();
    for (a, b) in s.variants.iter().zip(&changed.variants) {
        assert_eq!(
            a.hash != b.hash,
            a.name.contains("schedule-alt"),
            "{}",
            a.name
        );
    }
    // The plan as JSON, as `--plan` prints it.
    let plan = s.plan_json();
    let vs = plan["variants"].as_array().unwrap();
    assert_eq!(vs.len(), 8);
    assert_eq!(vs[0]["name"], names[0]);
    assert_eq!(vs[0]["hash"], s.variants[0].hash.as_str());
    assert_eq!(vs[0]["seed"], 1);
    assert_eq!(vs[0]["values"]["calibration.frag_factor.uniform"], 0.8);
    assert_eq!(vs[0]["values"]["schedule"], "alt");
    assert!(vs[0]["inputs"]["schedule"]
        .as_str()
        .unwrap()
        .ends_with("schedule_alt.csv"));
    assert_eq!(vs[0]["input_sha256"]["blocks"].as_str().unwrap().len(), 64);
    assert!(Path::new(vs[0]["inputs"]["blocks"].as_str().unwrap()).is_absolute());
}

/// The dataset's extraction rows and tonnes per variant, from the partitions.
fn dataset_tonnes(layout: &Layout) -> BTreeMap<String, (usize, f64)> {
    let root = layout.table_root("extraction");
    let mut out = BTreeMap::new();
    for v in entries(&root) {
        let mut rows = 0;
        let mut tonnes = 0.0;
        for p in entries(&root.join(&v))
            .into_iter()
            .filter(|p| p.starts_with("period="))
        {
            let b = read_parquet(&root.join(&v).join(p).join("part-0.parquet"));
            rows += b.num_rows();
            tonnes += b
                .column_by_name("tonnes")
                .unwrap()
                .as_primitive::<Float64Type>()
                .iter()
                .flatten()
                .sum::<f64>();
        }
        out.insert(v, (rows, tonnes));
    }
    out
}

#[test]
fn a_killed_study_resumes_every_variant_exactly_once() {
    let tmp = tempfile::tempdir().unwrap();
    study_scene_files(tmp.path());
    let path = study_file(
        tmp.path(),
        "[grid]\n\"calibration.frag_factor.uniform\" = [0.7, 0.85, 1.0]\n",
    );
    let study = Study::expand(&path).unwrap();
    study.validate(None).unwrap();
    let out = tmp.path().join("out");
    let layout = Layout::new(&out, &study);
    let first = run_study(&study, &layout, 2, 1, &Quiet).unwrap();
    assert_eq!(first.ran.len(), 3);
    assert!(first.skipped.is_empty() && first.failed.is_empty());
    let complete = dataset_tonnes(&layout);
    // 2 drawpoints × 3 periods per variant.
    assert_eq!(complete.len(), 3);
    assert!(
        complete.values().all(|&(rows, _)| rows == 6),
        "{complete:?}"
    );

    // Killed at three points: (a) after its tables, before `_SUCCESS`; (b) in the middle of
    // writing a table: a temporary partition directory left, another table gone; (c) not
    // at all. And (d) one `_SUCCESS` from other inputs (another hash).
    let [a, b, c] = [0, 1, 2].map(|k| study.variants[k].name.clone());
    fs::remove_file(layout.state(&a).join(SUCCESS)).unwrap();
    fs::remove_file(layout.state(&b).join(SUCCESS)).unwrap();
    let torn = layout
        .table_root("imz")
        .join(format!(".scenario={b}.tmp-999999"))
        .join("period=1");
    fs::create_dir_all(&torn).unwrap();
    fs::write(torn.join("part-0.parquet"), b"PAR1 torn").unwrap();
    fs::remove_dir_all(layout.table_root("drawn").join(format!("scenario={b}"))).ok();
    let c_file = layout
        .table_root("extraction")
        .join(format!("scenario={c}"))
        .join("period=1")
        .join("part-0.parquet");
    let c_before = fs::metadata(&c_file).unwrap().modified().unwrap();
    let again = run_study(&study, &layout, 2, 1, &Quiet).unwrap();
    let mut ran: Vec<String> = again.ran.iter().map(|(n, _)| n.clone()).collect();
    ran.sort();
    assert_eq!(ran, [a.clone(), b.clone()]);
    assert_eq!(again.skipped, std::slice::from_ref(&c));
    assert_eq!(
        fs::metadata(&c_file).unwrap().modified().unwrap(),
        c_before,
        "a complete variant is not written again"
    );
    // Every variant exactly once in every table, nothing hidden left, the same rows.
    for t in TABLES {
        let root = layout.table_root(t);
        if !root.exists() {
            continue;
        }
        for e in entries(&root) {
            assert!(e.starts_with("scenario="), "{t}: {e} left behind");
        }
    }
    assert_eq!(
        entries(&layout.table_root("imz")),
        [a.clone(), b.clone(), c.clone()].map(|n| format!("scenario={n}"))
    );
    assert_eq!(dataset_tonnes(&layout), complete);
    for v in &study.variants {
        let h = fs::read_to_string(layout.state(&v.name).join(SUCCESS)).unwrap();
        assert_eq!(h.trim(), v.hash);
        // Each table's partitions carry the mark too.
        for t in ["extraction", "imz", "drawn"] {
            let p = layout.table_root(t).join(format!("scenario={}", v.name));
            let h = fs::read_to_string(p.join(SUCCESS)).unwrap();
            assert_eq!(h.trim(), v.hash, "{t}");
        }
    }
    // (d): a `_SUCCESS` of another hash is not complete.
    fs::write(layout.state(&c).join(SUCCESS), "0000\n").unwrap();
    let third = run_study(&study, &layout, 1, 1, &Quiet).unwrap();
    assert_eq!(third.ran.len(), 1);
    assert_eq!(third.ran[0].0, c);
    assert_eq!(third.skipped.len(), 2);
    assert_eq!(dataset_tonnes(&layout), complete);
    // Once more: nothing to run.
    let fourth = run_study(&study, &layout, 2, 1, &Quiet).unwrap();
    assert!(fourth.ran.is_empty());
    assert_eq!(fourth.skipped.len(), 3);
}

#[test]
fn the_summary_agrees_with_the_dataset() {
    let tmp = tempfile::tempdir().unwrap();
    study_scene_files(tmp.path());
    let path = study_file(tmp.path(), STUDY_GRID_ALT);
    let study = Study::expand(&path).unwrap();
    let layout = Layout::new(&tmp.path().join("out"), &study);
    let report = run_study(&study, &layout, 2, 1, &Quiet).unwrap();
    assert_eq!(report.rows.len(), 4);
    let s = read_parquet(&layout.summary());
    assert_eq!(s.num_rows(), 4);
    let col = |n: &str| {
        s.column_by_name(n)
            .unwrap_or_else(|| panic!("no column {n}"))
    };
    let name = col("variant").as_string::<i32>();
    let hash = col("hash").as_string::<i32>();
    let f = |n: &str, i: usize| col(n).as_primitive::<Float64Type>().value(i);
    let tonnes = dataset_tonnes(&layout);
    for i in 0..4 {
        let v = &study.variants[i];
        assert_eq!(name.value(i), v.name);
        assert_eq!(hash.value(i), v.hash);
        let (_, t) = tonnes[&format!("scenario={}", v.name)];
        assert!(
            (f("tonnes", i) - t).abs() <= 1e-9 * t,
            "{}: {} vs {t}",
            v.name,
            f("tonnes", i)
        );
        assert!(f("wall_s", i) > 0.0);
        // The swept values.
        assert_eq!(
            f("calibration.frag_factor.uniform", i),
            v.scenario.calibration.frag_factor["uniform"]
        );
        let alt = col("schedule").as_string::<i32>().value(i);
        assert_eq!(v.name.contains("schedule-alt"), alt == "alt");
        // The grade (`elev`) and its recovery from the footprint.
        let g = f("elev", i);
        assert!(g > 0.0 && g < 0.9, "mean origin elevation {g}");
        let r = f("recovery_elev", i);
        assert!(r > 0.0 && r < 1.0, "recovery {r}");
        assert!(f("footprint_tonnes", i) > t);
        assert_eq!(
            col("periods")
                .as_primitive::<arrow::datatypes::Int64Type>()
                .value(i),
            3
        );
        assert!(!col("short_share").is_null(i));
    }
    // The alternative schedule asks for two thirds of the tonnes; with one fragment factor
    // it draws less.
    let t = |n: &str| tonnes[&format!("scenario={n}")].1;
    assert!(t("uniform-1.0_schedule-alt") < t("uniform-1.0_schedule-base"));
    let sched = |i: usize| f("scheduled_tonnes", i);
    assert!(
        (sched(0) / sched(1) - 2.0 / 3.0).abs() < 1e-6,
        "{} {}",
        sched(0),
        sched(1)
    );
}

/// The problems of a bad study, as text.
fn problems(dir: &Path, body: &str) -> StudyProblems {
    let p = study_file(dir, body);
    Study::expand(&p)
        .and_then(|s| s.validate(None).map(|_| s))
        .expect_err(body)
}

#[test]
fn bad_studies_are_refused_with_file_key_and_rule() {
    let tmp = tempfile::tempdir().unwrap();
    study_scene_files(tmp.path());
    let d = tmp.path();
    let file = d.join("study.toml").display().to_string();
    let cases: [(&str, &str, &str); 14] = [
        ("sedes = [1]\n", "unknown-key", "unknown field `sedes`"),
        (
            "[grid]\n\"flow.qq\" = [1.0]\n",
            "unknown-key",
            "grid.flow.qq = 1.0: unknown field `qq`",
        ),
        (
            "[grid]\n\"flow.q\" = [3.5, -1.0]\n",
            "setting-range",
            "grid.flow.q = -1.0: flow.q must be a positive number, got -1",
        ),
        (
            "[grid]\n\"flow.q\" = [\"fast\"]\n",
            "wrong-type",
            "grid.flow.q = \"fast\":",
        ),
        (
            "[grid]\n\"flow.q\" = []\n",
            "empty-grid",
            "grid.flow.q: the grid has no values",
        ),
        (
            "[grid]\n\"flow.q\" = 3.5\n",
            "grid-not-array",
            "grid.flow.q: a grid is an array",
        ),
        (
            "[alternatives.schedule]\nx = { schedule = \"nope.csv\" }\n",
            "missing-table",
            "alternatives.schedule.x.schedule: ",
        ),
        (
            "[alternatives.layout]\nx = { dps = \"schedule_alt.csv\" }\n",
            "unknown-key",
            "alternatives.layout.x.dps: an alternative swaps input tables",
        ),
        ("seeds = []\n", "empty-grid", "seeds: no seeds"),
        ("[cases]\n", "empty-grid", "cases: no cases"),
        (
            "[cases]\n\"a b\" = []\n",
            "bad-name",
            "cases.a b: `a b` must be",
        ),
        (
            "[cases]\nx = [\"flow.q=-1\"]\n",
            "setting-range",
            "cases.x: flow.q must be a positive number",
        ),
        (
            "keep_periods = 0\n",
            "setting-range",
            "keep_periods: keep_periods must be at least 1",
        ),
        (
            "[grid]\n\"calibration.frag_factor.granite\" = [0.5]\n",
            "bad-variant",
            "variant granite-0.5: blocks.parquet",
        ),
    ];
    for (body, rule, text) in cases {
        let e = problems(d, body);
        assert!(e.has(rule), "{body}: {e}");
        let s = e.to_string();
        assert!(s.contains(&format!("{file}: [{rule}] ")), "{body}: {s}");
        assert!(s.contains(text), "{body}: expected `{text}` in {s}");
    }
    // The loader's own rule follows a bad variant's problem.
    let e = problems(d, "[grid]\n\"calibration.frag_factor.granite\" = [0.5]\n");
    assert!(e.to_string().contains("[calibration-range]"), "{e}");
    // Every problem at once.
    let e = problems(d, "[grid]\n\"flow.q\" = []\n\"flow.qq\" = [1]\n");
    assert_eq!(e.0.len(), 2, "{e}");
}

#[test]
fn cli_plan_variant_and_study_share_the_layout() {
    let tmp = tempfile::tempdir().unwrap();
    study_scene_files(tmp.path());
    let path = study_file(
        tmp.path(),
        "[grid]\n\"calibration.frag_factor.uniform\" = [0.8, 1.0]\n",
    );
    let study = path.to_str().unwrap();
    let out = tmp.path().join("out");
    let o = out.to_str().unwrap();
    // --plan: the expansion as JSON, nothing written.
    let r = caveflow_out(&["study", "--plan", study]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let plan: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    let names: Vec<&str> = plan["variants"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["uniform-0.8", "uniform-1.0"]);
    assert!(!out.exists());
    // --variant: one variant into the layout, as a cluster task would.
    let r = caveflow_out(&["study", study, "--out", o, "--variant", "uniform-1.0"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let hash = plan["variants"][1]["hash"].as_str().unwrap();
    let success = out.join("variants/uniform-1.0").join(SUCCESS);
    assert_eq!(fs::read_to_string(&success).unwrap().trim(), hash);
    assert!(!out.join("variants/uniform-0.8").exists());
    // The whole study: the other variant runs, that one is skipped, the summary has both.
    let r = caveflow_out(&["study", study, "--out", o, "--jobs", "1"]);
    let stdout = String::from_utf8_lossy(&r.stdout);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(
        stdout.contains("1 ran, 1 complete already, 0 failed"),
        "{stdout}"
    );
    assert_eq!(read_parquet(&out.join("summary.parquet")).num_rows(), 2);
    // The report: both variants' curves overlaid, the second against the first on a map,
    // both in the table; it renders as the run report does.
    let page = out.join("report.html");
    let html = fs::read_to_string(&page).unwrap();
    for part in [
        "Grade against cumulative tonnes",
        "Recovery against dilution",
        "Per drawpoint, against uniform-0.8",
        "<td>uniform-1.0</td>",
    ] {
        assert!(html.contains(part), "no {part:?} in the study report");
    }
    for chart in ["grade_tonnage.svg", "recovery_dilution.svg"] {
        let svg = fs::read_to_string(out.join("charts").join(chart)).unwrap();
        assert_eq!(
            svg.matches("uniform-").count(),
            2,
            "{chart}: a legend entry per variant"
        );
    }
    let name = Study::expand(&path).unwrap().name;
    assert_renders(&page, &format!("caveflow study: {name}"));
    // An unknown variant, and a bad study: exit 1, with the rule; nothing written.
    let r = caveflow_out(&["study", study, "--out", o, "--variant", "nope"]);
    assert_eq!(r.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&r.stderr).contains("no variant `nope`"));
    let bad = study_file(tmp.path(), "[grid]\n\"flow.q\" = []\n");
    let fresh = tmp.path().join("fresh");
    let r = caveflow_out(&[
        "study",
        bad.to_str().unwrap(),
        "--out",
        fresh.to_str().unwrap(),
    ]);
    assert_eq!(r.status.code(), Some(1));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(err.contains("[empty-grid] grid.flow.q"), "{err}");
    assert!(!fresh.exists());
}

#[test]
fn the_cli_killed_mid_study_and_run_again_completes_every_variant_once() {
    let tmp = tempfile::tempdir().unwrap();
    study_scene_files(tmp.path());
    let path = study_file(
        tmp.path(),
        "[grid]\n\"calibration.frag_factor.uniform\" = [0.6, 0.7, 0.8, 0.9, 1.0]\nflow.q = [3.0, 3.5]\n",
    );
    let study = Study::expand(&path).unwrap();
    assert_eq!(study.variants.len(), 10);
    // The reference: the same study, uninterrupted, in process.
    let reference = Layout::new(&tmp.path().join("reference"), &study);
    run_study(&study, &reference, 2, 1, &Quiet).unwrap();
    let out = tmp.path().join("out");
    let layout = Layout::new(&out, &study);
    let complete = || {
        study
            .variants
            .iter()
            .filter(|v| layout.is_complete(v))
            .count()
    };
    // Killed (SIGKILL) as soon as the first variant is complete.
    let mut child = caveflow()
        .args([
            "study",
            path.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
        .args(["--jobs", "1"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let t0 = std::time::Instant::now();
    while complete() == 0 && t0.elapsed().as_secs() < 60 {
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let before = complete();
    eprintln!("killed with {before} of 10 variants complete");
    assert!(
        (1..10).contains(&before),
        "killed mid-study: {before} of 10 complete"
    );
    // Run again: the rest run, once each; the complete ones are skipped.
    let r = caveflow_out(&[
        "study",
        path.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&r.stdout);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(
        stdout.contains(&format!(
            "{} ran, {before} complete already, 0 failed",
            10 - before
        )),
        "{stdout}"
    );
    assert_eq!(complete(), 10);
    // The dataset: every variant once, the rows and tonnes of the uninterrupted study.
    assert_eq!(dataset_tonnes(&layout), dataset_tonnes(&reference));
    for t in TABLES {
        let (a, b) = (layout.table_root(t), reference.table_root(t));
        if b.exists() {
            assert_eq!(entries(&a), entries(&b), "{t}");
        }
    }
    assert_eq!(read_parquet(&layout.summary()).num_rows(), 10);
}

/// `[cases]`: named variants, each with its own overrides (where a grid's product does not
/// fit: `caveflow calibrate`'s runs), crossed with the other dimensions like one; and
/// `keep_periods`, the first periods of every variant.
#[test]
fn cases_are_variants_with_their_own_overrides() {
    let (tmp, path) = tiny_study(
        "keep_periods = 2\nseeds = [1, 2]\n[cases]\nslow = [\"flow.q=3.0\"]\nfine = [\"calibration.frag_factor.uniform=0.8\", \"flow.q=3.0\"]\n",
    );
    let s = Study::expand(&path).unwrap();
    let names: Vec<&str> = s.variants.iter().map(|v| v.name.as_str()).collect();
    assert_eq!(
        names,
        ["fine_seed-1", "fine_seed-2", "slow_seed-1", "slow_seed-2"]
    );
    assert_eq!(s.columns, ["case"]);
    let (fine, slow) = (&s.variants[0], &s.variants[2]);
    assert_eq!(
        fine.values,
        [("case".to_string(), Swept::Text("fine".into()))]
    );
    assert_eq!(fine.scenario.calibration.frag_factor["uniform"], 0.8);
    assert_eq!(fine.scenario.flow.q, 3.0);
    assert!(slow.scenario.calibration.frag_factor.is_empty());
    assert_eq!(slow.scenario.flow.q, 3.0);
    assert_eq!(fine.keep_periods, Some(2));
    assert_eq!(fine.load().unwrap().scene.periods.len(), 2, "of 3");
    assert_eq!(s.plan_json()["keep_periods"], 2);
    // Run: two periods of rows per drawpoint, in the summary with the case's name.
    let layout = Layout::new(&tmp.path().join("out"), &s);
    let report = run_study(&s, &layout, 2, 1, &Quiet).unwrap();
    assert_eq!(report.ran.len(), 4, "{report:?}");
    let sum = read_parquet(&layout.summary());
    let case = sum.column_by_name("case").unwrap().as_string::<i32>();
    assert_eq!(case.value(0), "fine");
    let periods = sum
        .column_by_name("periods")
        .unwrap()
        .as_primitive::<arrow::datatypes::Int64Type>();
    assert!(periods.iter().all(|p| p == Some(2)));
}

/// `[case_resolution.<case>]`: a case runs at exactly the resolution it carries (the
/// engine's plan takes the numbers as given), which its hash and the plan hold; a case
/// without one runs at the resolution its scenario resolves to. A resolution of no case, a
/// value out of range or a key that is not one are refused with their rule.
#[test]
fn a_case_runs_at_the_resolution_it_carries() {
    let (tmp, path) = tiny_study("[cases]\nplain = [\"flow.q=3.0\"]\n");
    let s = Study::expand(&path).unwrap();
    let plain = &s.variants[0];
    let loaded = plain.load().unwrap();
    let resolved = plain.plan(&loaded.scene).unwrap().resolution();
    assert_eq!(plain.resolution, None);
    let r = caveflow::engine::resolution::scaled(&resolved, [0.8, 0.8, 1.0]);
    let body = format!(
        "[cases]\nplain = [\"flow.q=3.0\"]\nexact = [\"flow.q=3.0\"]\n[case_resolution.exact]\n{}",
        toml::to_string(&r).unwrap()
    );
    let s = Study::expand(&study_file(tmp.path(), &body)).unwrap();
    let (exact, plain) = (&s.variants[0], &s.variants[1]);
    assert_eq!(exact.name, "exact");
    assert_eq!(exact.resolution, Some(r));
    assert_eq!(exact.scenario, plain.scenario);
    assert_ne!(exact.hash, plain.hash);
    assert_eq!(exact.plan(&loaded.scene).unwrap().resolution(), r);
    assert_eq!(
        s.plan_json()["variants"][0]["resolution"]["marker_spacing"],
        r.marker_spacing
    );
    let layout = Layout::new(&tmp.path().join("out"), &s);
    let report = run_study(&s, &layout, 1, 1, &Quiet).unwrap();
    assert_eq!(report.ran.len(), 2, "{report:?}");
    let manifest: serde_json::Value = serde_json::from_str(
        &fs::read_to_string(layout.state("exact").join("manifest.json")).unwrap(),
    )
    .unwrap();
    let ran: caveflow::engine::ResolvedResolution =
        serde_json::from_value(manifest["resolution"].clone()).unwrap();
    assert_eq!(ran, r);

    for (extra, rule, key) in [
        (
            "[case_resolution.other]\nlayer_thickness = 1.0\nmarker_spacing = 1.0\ndraw_increment = 1.0\n",
            "unknown-key",
            "case_resolution.other",
        ),
        (
            "[case_resolution.plain]\nlayer_thickness = 1.0\nmarker_spacing = -1.0\ndraw_increment = 1.0\n",
            "setting-range",
            "case_resolution.plain.marker_spacing",
        ),
        (
            "[case_resolution.plain]\nlayer_thickness = 1.0\nmarker_spacing = 1.0\ndraw_increment = 1.0\nmax_marker_mov = 1.0\n",
            "unknown-key",
            "",
        ),
    ] {
        let body = format!("[cases]\nplain = [\"flow.q=3.0\"]\n{extra}");
        let e = Study::expand(&study_file(tmp.path(), &body)).unwrap_err();
        assert!(e.has(rule), "{extra}: {e}");
        assert!(e.0.iter().any(|p| p.key.contains(key)), "{extra}: {e}");
    }
}

/// The variant hash covers caveflow's version, so that an upgraded binary skips no
/// variant an older one computed, and the periods kept; the same inputs give the same hash.
#[test]
fn the_variant_hash_covers_the_version_and_the_periods_kept() {
    let (tmp, path) = tiny_study("");
    let s = Study::expand(&path).unwrap();
    let v = &s.variants[0];
    assert_eq!(v.name, "base");
    let hash = |keep, version| variant_hash(&v.scenario, None, &v.inputs, keep, version);
    assert_eq!(v.hash, hash(None, VERSION));
    assert_eq!(hash(None, "0.1.0"), hash(None, "0.1.0"));
    assert_ne!(hash(None, "0.1.0"), hash(None, "0.1.1"));
    assert_ne!(v.hash, hash(None, "0.0.0-older"));
    let kept = Study::expand(&study_file(tmp.path(), "keep_periods = 2\n")).unwrap();
    assert_eq!(kept.variants[0].hash, hash(Some(2), VERSION));
    assert_ne!(kept.variants[0].hash, v.hash);
    assert_ne!(hash(Some(2), VERSION), hash(Some(1), VERSION));
}

/// `--threads T`: each worker runs its variants in its own pool of T threads; the dataset
/// is the same byte for byte at any number of workers and threads (the engine is
/// deterministic), and each variant's manifest records its worker's threads.
#[test]
fn workers_of_any_size_write_the_same_dataset() {
    let (tmp, path) = tiny_study(STUDY_GRID_ALT);
    let s = path.to_str().unwrap();
    let mut outs = Vec::new();
    for (jobs, threads) in [("1", "1"), ("2", "1"), ("2", "2"), ("1", "3")] {
        let out = tmp.path().join(format!("out-{jobs}-{threads}"));
        let r = caveflow_out(&[
            "study",
            s,
            "--out",
            out.to_str().unwrap(),
            "--jobs",
            jobs,
            "--threads",
            threads,
        ]);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(r.status.success(), "{err}");
        assert!(
            err.contains(&format!("{jobs} worker(s) of {threads} thread(s)")),
            "{err}"
        );
        let manifest: serde_json::Value = serde_json::from_str(
            &fs::read_to_string(out.join("variants/uniform-0.8_schedule-alt/manifest.json"))
                .unwrap(),
        )
        .unwrap();
        assert_eq!(manifest["threads"], threads.parse::<u64>().unwrap());
        outs.push(out);
    }
    for o in &outs[1..] {
        assert!(assert_same_study(&outs[0], o) >= 4 * 9);
    }
    let none = tmp.path().join("none");
    let r = caveflow_out(&[
        "study",
        s,
        "--out",
        none.to_str().unwrap(),
        "--threads",
        "0",
    ]);
    assert_eq!(r.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&r.stderr).contains("--threads must be at least 1"));
    assert!(!none.exists());
}
