//! Integration tests: cli.

use std::path::Path;

use crate::fixtures::{
    caveflow, demo_copy, demo_data, repo, write_parquet, write_small_scene, BLOCKS, DRAWPOINTS_CSV,
    SCHEDULE_CSV, SMALL_SCENE_INPUTS,
};

/// The committed schemas/ are exactly what `caveflow schema` prints, so they cannot drift
/// from the readers and writers.
#[test]
fn committed_schemas_match_the_code() {
    let dir = repo("schemas");
    for t in caveflow::schema::ALL {
        let committed = std::fs::read_to_string(dir.join(format!("{}.json", t.name))).unwrap();
        assert_eq!(
            committed,
            caveflow::cli::schema_json(t),
            "schemas/{}.json is stale: run `caveflow schema --write schemas`",
            t.name
        );
        let out = caveflow().args(["schema", t.name]).output().unwrap();
        assert!(out.status.success());
        assert_eq!(String::from_utf8(out.stdout).unwrap(), committed);
    }
    let out = caveflow().args(["schema", "nope"]).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("no table `nope`"));
}

/// Invalid input on the command line exits 1, as a bad table does: clap's own errors
/// (an unknown flag or subcommand, a value that does not parse) included, each with
/// clap's message, and arguments that cannot work together. Help and version print to stdout and exit 0.
#[test]
fn invalid_flags_exit_1_with_clap_message() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("calibrate");
    for (args, says) in [
        (
            &["run", "data/scenario.toml", "--nope"][..],
            "unexpected argument '--nope'",
        ),
        (&["frobnicate"][..], "unrecognized subcommand 'frobnicate'"),
        (
            &["run"][..],
            "give a scenario file, or --blocks, --drawpoints and --schedule",
        ),
        (
            &["run", "data/scenario.toml", "--threads", "two"][..],
            "invalid value 'two'",
        ),
        (
            &[
                "calibrate",
                "data/scenario.toml",
                "--records",
                "data/records.csv",
                "--grade",
                "Au",
                "--out",
                out.to_str().unwrap(),
            ][..],
            "grade \"Au\" is not sampled in the records",
        ),
        (
            &[
                "calibrate",
                "data/scenario.toml",
                "--records",
                "data/records.csv",
                "--lattices",
                "0",
                "--out",
                out.to_str().unwrap(),
            ][..],
            "invalid value '0' for '--lattices <K>'",
        ),
    ] {
        let got = caveflow()
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .args(args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&got.stderr);
        assert_eq!(got.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
        assert!(got.stdout.is_empty(), "{args:?}");
    }
    assert!(!out.exists(), "invalid input left {}", out.display());
    for args in [&["--help"][..], &["run", "--help"][..], &["--version"][..]] {
        let out = caveflow().args(args).output().unwrap();
        assert_eq!(out.status.code(), Some(0), "{args:?}");
        assert!(!out.stdout.is_empty(), "{args:?}");
    }
}

/// A missing scenario, study, records file or run directory is invalid input: exit 1 and
/// one message that names the file and gives the cause once, nothing on stdout, nothing
/// written.
#[test]
fn missing_files_are_named_with_their_cause_once() {
    let tmp = tempfile::tempdir().unwrap();
    let path = |name: &str| tmp.path().join(name).to_str().unwrap().to_string();
    let (scenario, records, run_dir, out) = (
        path("nonexist.toml"),
        path("nonexist.csv"),
        path("no-run"),
        path("out"),
    );
    let cause = std::fs::read(&scenario).unwrap_err().to_string();
    let o = out.as_str();
    for (args, file) in [
        (vec!["run", &scenario, "--out", o], &scenario),
        (vec!["validate", &scenario], &scenario),
        (vec!["sweep", &scenario, "--out", o], &scenario),
        (vec!["study", &scenario, "--out", o], &scenario),
        (
            vec![
                "calibrate",
                &scenario,
                "--records",
                "data/records.csv",
                "--out",
                o,
            ],
            &scenario,
        ),
        (
            vec![
                "calibrate",
                "data/scenario.toml",
                "--records",
                &records,
                "--out",
                o,
            ],
            &records,
        ),
        (vec!["reconcile", &run_dir, "data/records.csv"], &run_dir),
    ] {
        let got = caveflow()
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .args(&args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&got.stderr);
        assert_eq!(got.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains(file.as_str()), "{args:?}: {err}");
        assert_eq!(err.matches(&cause).count(), 1, "{args:?}: {err}");
        assert!(got.stdout.is_empty(), "{args:?}");
    }
    assert!(!Path::new(&out).exists(), "a missing file left {out}");
}

/// The embedded demo validates, and `validate` refuses a broken table with file, row,
/// column and rule, exit code 1.
#[test]
fn validate_demo_and_a_broken_copy() {
    let data = demo_data();
    let out = caveflow()
        .args(["validate"])
        .arg(data.join("scenario.toml"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("32 drawpoints"));

    let tmp = demo_copy();
    let sched = std::fs::read_to_string(tmp.path().join("schedule.csv")).unwrap();
    std::fs::write(
        tmp.path().join("schedule.csv"),
        format!("{sched}1,NO-SUCH-DP,100\n"),
    )
    .unwrap();
    let out = caveflow()
        .args(["validate"])
        .arg(tmp.path().join("scenario.toml"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("schedule.csv")
            && err.contains("unknown-drawpoint")
            && err.contains("NO-SUCH-DP"),
        "{err}"
    );
}

/// `run` with the tables given directly and --set overrides writes every output file.
#[test]
fn run_with_tables_and_set() {
    let data = demo_data();
    let tmp = tempfile::tempdir().unwrap();
    // Two periods of the demo at a coarse resolution keep this fast.
    let sched = std::fs::read_to_string(data.join("schedule.csv")).unwrap();
    let short: String = sched
        .lines()
        .filter(|l| l.starts_with("period") || l.starts_with("1,") || l.starts_with("2,"))
        .map(|l| format!("{l}\n"))
        .collect();
    std::fs::write(tmp.path().join("schedule.csv"), short).unwrap();
    let out_dir = tmp.path().join("out");
    let out = caveflow()
        .arg("run")
        .arg("--blocks")
        .arg(data.join("blocks.parquet"))
        .arg("--drawpoints")
        .arg(data.join("drawpoints.csv"))
        .arg("--periods")
        .arg(data.join("periods.csv"))
        .arg("--schedule")
        .arg(tmp.path().join("schedule.csv"))
        .arg("--out")
        .arg(&out_dir)
        .args([
            "--set",
            "resolution.layer_thickness=7.6",
            "--set",
            "outputs.charts=false",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for f in [
        "extraction.parquet",
        "imz.parquet",
        "drawn.parquet",
        "manifest.json",
    ] {
        assert!(out_dir.join(f).is_file(), "{f} missing");
    }
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("manifest.json")).unwrap()).unwrap();
    assert_eq!(manifest["resolution"]["layer_thickness"], 7.6);
    assert_eq!(manifest["inputs"].as_array().unwrap().len(), 4);
    let bad = caveflow()
        .args([
            "run",
            "--set",
            "flow.q=-1",
            "--blocks",
            "x",
            "--drawpoints",
            "y",
            "--schedule",
            "z",
        ])
        .output()
        .unwrap();
    // A bad setting is invalid input: exit 1.
    assert_eq!(bad.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("flow.q must be a positive number"));
}

/// `run --keep-periods N` draws only the first N periods; 0 periods, a negative
/// `resolution.max_marker_move` and a `resolution.lattice_offset` off [−0.5, 0.5) are
/// invalid input (exit 1) with a message naming them.
#[test]
fn run_keep_periods_and_cadence_setting() {
    let scenario = demo_data().join("scenario.toml");
    let tmp = tempfile::tempdir().unwrap();
    let run = |extra: &[&str]| {
        caveflow()
            .arg("run")
            .arg(&scenario)
            .arg("--out")
            .arg(tmp.path().join("out"))
            .args(["--set", "resolution.layer_thickness=7.6"])
            .args(["--set", "outputs.charts=false", "--checkpoint-every", "0"])
            .args(extra)
            .output()
            .unwrap()
    };
    let out = run(&["--keep-periods", "2"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // The demo schedule's first two months, summed from the CSV.
    let sched = std::fs::read_to_string(scenario.with_file_name("schedule.csv")).unwrap();
    let first_two: f64 = sched
        .lines()
        .filter(|l| l.starts_with("1,") || l.starts_with("2,"))
        .map(|l| l.rsplit(',').next().unwrap().parse::<f64>().unwrap())
        .sum();
    assert!(
        stdout.contains(&format!("t of {first_two:.0} t scheduled")),
        "{stdout} (expected {first_two:.0} t scheduled)"
    );
    let zero = run(&["--keep-periods", "0"]);
    assert_eq!(zero.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&zero.stderr).contains("--keep-periods must be at least 1"));
    let negative = run(&["--checkpoint-minutes=-1"]);
    assert_eq!(negative.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&negative.stderr)
        .contains("--checkpoint-minutes must be a number of minutes, 0 or more (got -1)"));
    // The same rule for the other commands that take it.
    for cmd in [
        vec!["sweep", "--keep-periods", "0"],
        vec![
            "calibrate",
            "--records",
            "data/records.csv",
            "--keep-periods",
            "0",
        ],
    ] {
        let out = caveflow()
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .arg(cmd[0])
            .arg("data/scenario.toml")
            .args(&cmd[1..])
            .args(["--out", tmp.path().join("zero").to_str().unwrap()])
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(1), "{cmd:?}");
        assert!(
            String::from_utf8_lossy(&out.stderr).contains("--keep-periods must be at least 1"),
            "{cmd:?}"
        );
    }
    // The sweep's reference takes exactly three multipliers, comma-separated.
    let sweep_ref = |r: &str| {
        caveflow()
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .args(["sweep", "data/scenario.toml", "--reference", r, "--out"])
            .arg(tmp.path().join("ref"))
            .output()
            .unwrap()
    };
    let two = sweep_ref("0.5,0.5");
    assert_eq!(two.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&two.stderr).contains(
        "--reference takes three multipliers, h,spacing,increment (e.g. 0.5,0.5,0.25); got 2"
    ));
    let bad = run(&["--set", "resolution.max_marker_move=-1"]);
    assert_eq!(bad.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&bad.stderr)
        .contains("resolution.max_marker_move must be a number ≥ 0"));
    let bad = run(&["--set", "resolution.lattice_offset=[0.5, 0.0]"]);
    assert_eq!(bad.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&bad.stderr).contains(
        "resolution.lattice_offset each must lie in [-0.5, 0.5) (fractions of the marker spacing), got 0.5"
    ));
}

/// A run killed at any moment resumes with `--resume` and writes the same outputs, byte
/// for byte, as an uninterrupted run (the manifest aside: it records wall time).
#[test]
fn killed_run_resumes_to_identical_outputs() {
    use caveflow::model::synthetic::UniformBox;
    let tmp = tempfile::tempdir().unwrap();
    // Two overlapping Castro drawpoints over 30 periods: long enough (a few seconds) to be
    // killed part-way, small enough for the suite.
    let b = UniformBox {
        extent: [1.0, 0.6, 1.5],
        drawpoints: vec![(-0.15, 0.0, 0.12), (0.15, 0.0, 0.12)],
        periods: 30,
        tonnes: 0.003,
        ..UniformBox::castro_isolated()
    };
    let mut sc = caveflow::model::Scenario::default();
    sc.resolution.layer_thickness = Some(0.025);
    sc.resolution.marker_spacing = Some(0.0125);
    sc.resolution.draw_increment = Some(0.0005);
    sc.outputs.charts = false;
    sc.outputs.marker_periods = vec![10, 30];
    caveflow::output::inputs::write_scene(tmp.path(), &b.scene(), &sc).unwrap();
    let scenario = tmp.path().join("scenario.toml");
    // Checkpoints by wall time, the default trigger, at a few milliseconds: one at the end
    // of nearly every period.
    let run = |out: &Path, resume: bool| {
        let mut c = caveflow();
        c.arg("run").arg(&scenario).arg("--out").arg(out);
        c.args(["--checkpoint-minutes", "0.0001"]);
        if resume {
            c.arg("--resume");
        }
        c
    };
    let whole = tmp.path().join("whole");
    let st = run(&whole, false).output().unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    assert!(
        !whole.join(CHECKPOINT).exists(),
        "a finished run keeps no checkpoint"
    );

    // Kill as soon as a checkpoint is on disk; then resume and kill again once the
    // resumed run has written a newer one.
    let cut = tmp.path().join("cut");
    let mtime = || {
        std::fs::metadata(cut.join(CHECKPOINT))
            .and_then(|m| m.modified())
            .ok()
    };
    let mut kills = 0;
    for resume in [false, true] {
        let before = mtime();
        let mut child = run(&cut, resume)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        let start = std::time::Instant::now();
        while child.try_wait().unwrap().is_none() && start.elapsed().as_secs() < 120 {
            if mtime().is_some_and(|m| Some(m) != before) {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(2));
        }
        if child.try_wait().unwrap().is_none() {
            child.kill().unwrap();
            kills += 1;
        }
        child.wait().unwrap();
        // Only whole files: no temporary file survives next to the checkpoint.
        for e in std::fs::read_dir(&cut).unwrap() {
            let name = e.unwrap().file_name().into_string().unwrap();
            assert!(
                name == CHECKPOINT || !name.contains("tmp"),
                "left behind: {name}"
            );
        }
    }
    assert!(kills > 0, "the run finished before it could be killed");
    let st = run(&cut, true).output().unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    assert!(String::from_utf8_lossy(&st.stderr).contains("resuming at period"));
    for f in ["extraction.parquet", "imz.parquet", "drawn.parquet"] {
        assert!(
            std::fs::read(whole.join(f)).unwrap() == std::fs::read(cut.join(f)).unwrap(),
            "{f} differs after kill and resume"
        );
    }
    for p in [10, 30] {
        let part = |d: &Path| {
            std::fs::read_dir(d.join("markers").join(format!("period={p}")))
                .unwrap()
                .map(|e| std::fs::read(e.unwrap().path()).unwrap())
                .collect::<Vec<_>>()
        };
        assert!(part(&whole) == part(&cut), "markers period={p} differ");
    }
    assert!(!cut.join(CHECKPOINT).exists());
}

const CHECKPOINT: &str = caveflow::output::run_dir::CHECKPOINT_FILE;
/// The small valid scene of the io tests, with one file replaced, in a folder with its
/// scenario.toml.
fn scene_dir(name: &str, bytes: &[u8]) -> tempfile::TempDir {
    let tmp = tempfile::tempdir().unwrap();
    write_small_scene(tmp.path());
    let scenario = format!("{SMALL_SCENE_INPUTS}[outputs]\ncharts = false\n");
    std::fs::write(tmp.path().join("scenario.toml"), scenario).unwrap();
    // Only one of those files is replaced: "none" names none of them.
    let replaced = tmp.path().join(name);
    if replaced.exists() {
        std::fs::write(replaced, bytes).unwrap();
    }
    tmp
}

/// Every kind of bad input of issue 9, end to end through `validate` and `run`: exit 1, a
/// message naming the file, the row (or line) and column where there is one, and the rule;
/// and `run` leaves no output directory behind.
#[test]
fn bad_input_exits_1_with_file_row_column_rule_and_writes_nothing() {
    let mut non_utf8 = BLOCKS.as_bytes().to_vec();
    let at = BLOCKS.find("waste").unwrap();
    non_utf8[at + 1] = 0xE1;
    let kg = BLOCKS.replacen("2.7,0.3,0.45,38", "2700,0.3,0.45,38", 1);
    let pct = BLOCKS.replacen("2.7,0.3,0.45,38", "2.7,30,45,38", 1);
    let rad = BLOCKS.replacen("0.3,0.45,38", "0.3,0.45,0.66", 1);
    let mm = BLOCKS.replacen("38,0.2,ore,1.0", "38,230,ore,1.0", 1);
    let ragged = BLOCKS.replacen("15,5,5,2,2.7", "15,5,5,2,2.7,9", 1);
    let dup = BLOCKS.replacen("x,y,z,block_id", "x,y,z,Easting", 1);
    let huge = SCHEDULE_CSV.replacen("1,DP2,100", "1,DP2,1e300", 1);
    let pipes = BLOCKS.replace(',', "|");
    let comma = BLOCKS
        .replace(',', ";")
        .replacen("0.3;0.45;38", "0,3;0.45;38", 1);
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        (
            "blocks.csv",
            kg.into(),
            "blocks.csv: row 1, column solids_density: [units-kg-m3]",
        ),
        (
            "blocks.csv",
            pct.into(),
            "blocks.csv: row 1, column porosity: [units-percent]",
        ),
        (
            "blocks.csv",
            rad.into(),
            "blocks.csv: row 1, column friction_angle: [units-radians]",
        ),
        (
            "blocks.csv",
            mm.into(),
            "blocks.csv: row 1, column frag_size: [units-mm]",
        ),
        (
            "blocks.csv",
            ragged.into(),
            "blocks.csv: row 2: [ragged-row]",
        ),
        (
            "blocks.csv",
            dup.into(),
            "blocks.csv: header, column Easting: [duplicate-header]",
        ),
        (
            "blocks.csv",
            non_utf8,
            "blocks.csv: row 5, column lithology: [not-utf8]",
        ),
        ("blocks.csv", Vec::new(), "blocks.csv: [empty-table]"),
        (
            "blocks.csv",
            pipes.into(),
            "blocks.csv: header: [wrong-delimiter]",
        ),
        (
            "blocks.csv",
            comma.into(),
            "blocks.csv: row 1, column porosity: [mistyped]",
        ),
        (
            "schedule.csv",
            huge.into(),
            "schedule.csv: row 2, column tonnes: [tonnes-exceed-model]",
        ),
        (
            "schedule.csv",
            b"DPName\tJan-09\nDP9\t5\n".to_vec(),
            "schedule.csv: row 1, column DPName: [unknown-drawpoint]",
        ),
        (
            "scenario.toml",
            b"[inputs]\nblocks = 3\n".to_vec(),
            "scenario.toml: line 2, column 10: [wrong-type]",
        ),
        (
            "scenario.toml",
            b"[input]\n".to_vec(),
            "scenario.toml: line 1, column 2: [unknown-key]",
        ),
        (
            "scenario.toml",
            b"[inputs\n".to_vec(),
            "scenario.toml: line 1, column 8: [toml-syntax]",
        ),
        (
            "scenario.toml",
            b"[inputs]\nblocks = \"gone.csv\"\n".to_vec(),
            "gone.csv: [unreadable]",
        ),
    ];
    for (file, bytes, want) in cases {
        let dir = scene_dir(file, &bytes);
        let scenario = dir.path().join("scenario.toml");
        let out_dir = dir.path().join("out");
        for cmd in ["validate", "run"] {
            let mut c = caveflow();
            c.arg(cmd).arg(&scenario);
            if cmd == "run" {
                c.arg("--out").arg(&out_dir);
            }
            let out = c.output().unwrap();
            let err = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(1), "{cmd} {file} ({want}):\n{err}");
            assert!(
                err.contains(want),
                "{cmd} {file}: expected `{want}` in:\n{err}"
            );
            assert!(!err.contains("panicked"), "{err}");
        }
        assert!(
            !out_dir.exists(),
            "{want}: run left {} behind",
            out_dir.display()
        );
    }
    // A Parquet drawpoints table whose width column holds text.
    let dir = scene_dir("none", b"");
    let dp = dir.path().join("drawpoints.parquet");
    let f = |v: Vec<f64>| std::sync::Arc::new(arrow::array::Float64Array::from(v)) as _;
    write_parquet(
        &dp,
        vec![
            (
                "name",
                std::sync::Arc::new(arrow::array::StringArray::from(vec!["DP1", "DP2"])) as _,
            ),
            ("x", f(vec![5.0, 15.0])),
            ("y", f(vec![5.0, 15.0])),
            ("z", f(vec![0.0, 0.0])),
            (
                "width",
                std::sync::Arc::new(arrow::array::StringArray::from(vec!["4", "4 m"])) as _,
            ),
        ],
    );
    let out = caveflow()
        .arg("validate")
        .arg(dir.path().join("scenario.toml"))
        .arg("--drawpoints")
        .arg(&dp)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains(
            "drawpoints.parquet: row 2, column width: [mistyped] expected a number, found `4 m`"
        ),
        "{err}"
    );
    // A Parquet file that panics inside the parquet crate (found by the fuzz harness): the
    // panic is caught without a word on stderr, and reported.
    let dir = scene_dir("none", b"");
    let crash = repo("tests/data/io/fuzz/negative_column_start.parquet");
    let out = caveflow()
        .arg("validate")
        .arg("--blocks")
        .arg(dir.path().join("blocks.csv"))
        .arg("--drawpoints")
        .arg(dir.path().join("drawpoints.csv"))
        .arg("--schedule")
        .arg(&crash)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("negative_column_start.parquet: [unreadable] the Parquet reader failed")
            && !err.contains("panicked"),
        "{err}"
    );
}

/// A scene where REBOP fails is refused by `validate` and `run` (exit 1, the rule and the
/// summary's reason, no output); a degraded one runs, and its warning reaches the run log
/// and the manifest.
#[test]
fn stability_refusal_and_warning_end_to_end() {
    // Fragments of 3 m through 4 m drawpoints: d̄/w = 0.75.
    let coarse = BLOCKS.replace("38,0.2,ore", "38,3,ore");
    let dir = scene_dir("blocks.csv", coarse.as_bytes());
    let out_dir = dir.path().join("out");
    for cmd in ["validate", "run"] {
        let out = caveflow()
            .arg(cmd)
            .arg(dir.path().join("scenario.toml"))
            .args(
                ["--out", out_dir.to_str().unwrap()]
                    .iter()
                    .take(if cmd == "run" { 2 } else { 0 }),
            )
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{cmd}: {err}");
        assert!(
            err.contains("stability [frag-to-width] refused: drawpoint DP1: d̄/w = 0.750")
                && err.contains("(and 1 more drawpoint(s))"),
            "{cmd}: {err}"
        );
    }
    assert!(!out_dir.exists());
    // Fragments of 2 cm: d̄/w = 0.005, over-predicted IMZ widths (summary §3.4).
    let fine = BLOCKS.replace("38,0.2,ore", "38,0.02,ore");
    let dir = scene_dir("blocks.csv", fine.as_bytes());
    let out_dir = dir.path().join("out");
    let out = run_scenario(&dir.path().join("scenario.toml"), &out_dir);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let want = "stability [frag-to-width] degraded: drawpoint DP1: d̄/w = 0.0050";
    assert!(err.contains(want), "{err}");
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("manifest.json")).unwrap()).unwrap();
    assert!(
        manifest["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w.as_str().unwrap().contains(want)),
        "{manifest}"
    );
}

/// What is tolerated is tolerated end to end: a BOM, quoted and padded numbers, tabs,
/// semicolons, a tab-delimited wide schedule, CRLF line ends.
#[test]
fn tolerated_variants_validate() {
    let bom = format!("\u{feff}{BLOCKS}");
    let quoted = BLOCKS.replacen("2.7,0.3", "\" 2.7 \",\"0.3\"", 1);
    let tabs = BLOCKS.replace(',', "\t");
    let semi = BLOCKS.replace(',', ";");
    let crlf = BLOCKS.replace('\n', "\r\n");
    for (file, text) in [
        ("blocks.csv", bom.as_str()),
        ("blocks.csv", quoted.as_str()),
        ("blocks.csv", tabs.as_str()),
        ("blocks.csv", semi.as_str()),
        ("blocks.csv", crlf.as_str()),
        (
            "schedule.csv",
            "DPName\tJan-09\tFeb-09\nDP1\t100\t50\nDP2\t100\t\n",
        ),
    ] {
        let dir = scene_dir(file, text.as_bytes());
        let out = caveflow()
            .arg("validate")
            .arg(dir.path().join("scenario.toml"))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{file}: {text:?}\n{err}");
        assert!(String::from_utf8_lossy(&out.stdout).contains("ok: 8 blocks"));
    }
}

/// The three inputs that crash MassFlow 9.7 (issue 9): a point outside the model is
/// refused with its row; a tab-delimited schedule and a skipped period run.
#[test]
fn massflow_crash_cases() {
    let outside = DRAWPOINTS_CSV.replace("DP2,15,15,0,4", "DP2,500,15,0,4");
    let dir = scene_dir("drawpoints.csv", outside.as_bytes());
    let out = caveflow()
        .arg("validate")
        .arg(dir.path().join("scenario.toml"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains(
            "drawpoints.csv: row 2, column x: [outside-model] drawpoint `DP2` at (500, 15)"
        ),
        "{err}"
    );
    // Periods 1 and 3, no period 2; the schedule tab-delimited.
    let dir = scene_dir(
        "periods.csv",
        b"period,name,days\n1,Jan-09,31\n3,Mar-09,31\n",
    );
    std::fs::write(
        dir.path().join("schedule.csv"),
        "period\tdrawpoint\ttonnes\n1\tDP1\t100\n3\tDP1\t50\n3\tDP2\t80\n",
    )
    .unwrap();
    let out_dir = dir.path().join("out");
    let out = run_scenario(&dir.path().join("scenario.toml"), &out_dir);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("manifest.json")).unwrap()).unwrap();
    let b = &manifest["mass_balance"];
    assert!(b.is_object(), "{manifest}");
    assert_eq!(b["scheduled_tonnes"], 230.0, "{manifest}");
}

/// `caveflow run <scenario> --out <out>`, waited for.
fn run_scenario(scenario: &Path, out: &Path) -> std::process::Output {
    caveflow()
        .arg("run")
        .arg(scenario)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap()
}
