//! Integration tests: the scenario file's rules, each located by line and column.

use std::fs;
use std::path::Path;

use caveflow::model::Scenario;
use tempfile::TempDir;

// ---------------------------------------------------------------------------------------
// The scenario file: every rule located by line and column.

fn scenario_err(text: &str, sets: &[&str]) -> caveflow::model::scenario::ScenarioError {
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    match Scenario::from_toml(text, "scenario.toml", &sets, Path::new("/base")) {
        Ok(_) => panic!("the scenario loaded but should not have"),
        Err(e) => e,
    }
}

/// Scenario text and `--set` values, the rule they break, how the error begins and what
/// else it says; every failing case is named.
#[test]
fn scenario_rules() {
    type ScenarioCase = (
        &'static str,
        &'static str,
        &'static [&'static str],
        &'static str,
        &'static str,
        &'static [&'static str],
    );
    let cases: [ScenarioCase; 6] = [
        (
            "a misspelt key",
            "seed = 1\n[resolution]\nlayer_thicknes = 3.8\n",
            &[],
            "unknown-key",
            "scenario.toml: line 3, column 1: [unknown-key] unknown field `layer_thicknes`",
            &["layer_thickness"],
        ),
        (
            "a number in quotes",
            "[flow]\nq = \"3.5\"\n",
            &[],
            "wrong-type",
            "scenario.toml: line 2, column 5: [wrong-type] invalid type: string \"3.5\", expected f64",
            &[],
        ),
        (
            "an unclosed table header",
            "[flow\nq = 3.5\n",
            &[],
            "toml-syntax",
            "scenario.toml: line 1, column 6: [toml-syntax]",
            &[],
        ),
        ("--set without a value", "", &["flow.q"], "bad-set", "", &["expected key=value"]),
        (
            "--set of an unknown key",
            "",
            &["flow.nope=1"],
            "unknown-key",
            "--set: [unknown-key] unknown field `nope`",
            &[],
        ),
        (
            "a negative layer thickness",
            "[resolution]\nlayer_thickness = -1\n",
            &[],
            "setting-range",
            "",
            &["resolution.layer_thickness must be a positive number, got -1"],
        ),
    ];
    let mut failed = Vec::new();
    for (name, text, sets, rule, begins, says) in cases {
        let e = scenario_err(text, sets);
        let shown = e.to_string();
        if e.rule() != rule {
            failed.push(format!("{name}: rule {}, not {rule}: {shown}", e.rule()));
        } else if !shown.starts_with(begins) {
            failed.push(format!("{name}: does not begin `{begins}`: {shown}"));
        } else if let Some(s) = says.iter().find(|s| !shown.contains(**s)) {
            failed.push(format!("{name}: does not say `{s}`: {shown}"));
        }
    }
    assert!(failed.is_empty(), "{}", failed.join("\n"));
}

#[test]
fn scenario_files_that_cannot_be_read() {
    let dir = TempDir::new().unwrap();
    let missing = dir.path().join("nope.toml");
    let e = Scenario::load(&missing, &[]).unwrap_err();
    assert_eq!(e.rule(), "unreadable");
    assert!(
        e.to_string()
            .contains("nope.toml: [unreadable] cannot read the scenario"),
        "{e}"
    );
    let latin1 = dir.path().join("latin1.toml");
    fs::write(&latin1, b"# caf\xe9\nseed = 1\n").unwrap();
    let e = Scenario::load(&latin1, &[]).unwrap_err();
    assert_eq!(e.rule(), "unreadable");
    assert!(e.to_string().contains("valid UTF-8"), "{e}");
}
