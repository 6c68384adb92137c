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
