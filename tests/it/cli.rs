//! Integration tests: cli.

use std::path::Path;
use std::process::Command;

fn caveflow() -> Command {
    Command::new(env!("CARGO_BIN_EXE_caveflow"))
}

/// The committed schemas/ are exactly what `caveflow schema` prints, so they cannot drift
/// from the readers and writers.
#[test]
fn committed_schemas_match_the_code() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("schemas");
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
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("no table `nope`"));
}

/// The embedded demo validates, and `validate` refuses a broken table with file, row,
/// column and rule, exit code 1.
#[test]
fn validate_demo_and_a_broken_copy() {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("data");
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

    let tmp = tempfile::tempdir().unwrap();
    for f in [
        "blocks.parquet",
        "drawpoints.csv",
        "periods.csv",
        "schedule.csv",
        "scenario.toml",
    ] {
        std::fs::copy(data.join(f), tmp.path().join(f)).unwrap();
    }
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
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("data");
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
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("flow.q must be a positive number"));
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
    let run = |out: &Path, resume: bool| {
        let mut c = caveflow();
        c.arg("run").arg(&scenario).arg("--out").arg(out);
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

const CHECKPOINT: &str = caveflow::cli::CHECKPOINT_FILE;
