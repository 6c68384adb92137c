//! Integration tests: the run report (`output::report`), read as HTML and rendered in
//! headless Chromium as an engineer's browser would show it.
//!
//! The browser test needs `CAVEFLOW_PY` (a Python with `playwright`, which `.ci/run` puts in
//! its venv) and Debian's `chromium` (`.ci/run` installs it where missing); without them it
//! prints a note and checks the page's HTML only.

use std::fs;

use crate::fixtures::{assert_renders, caveflow_in, demo_copy};

/// Runs the demo into `out/` of a copy of it; returns the copy and the run's stdout.
fn demo_run(extra: &[&str]) -> (tempfile::TempDir, String) {
    let tmp = demo_copy();
    let mut args = vec![
        "run",
        "scenario.toml",
        "--out",
        "out",
        "--set",
        "outputs.hive=false",
    ];
    args.extend(extra);
    let out = caveflow_in(&args, tmp.path());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    (tmp, String::from_utf8_lossy(&out.stdout).into_owned())
}

/// The demo's report opens with its verdict, holds every part the issue lists, embeds every
/// chart (nothing to fetch: no `src` but `data:` URIs, no script, a policy that refuses any
/// load), and renders in headless Chromium without a console error, without a request
/// beyond the file itself, and not blank.
#[test]
fn demo_report_is_self_contained_and_renders_in_chromium() {
    let (tmp, stdout) = demo_run(&[]);
    let page = tmp.path().join("out/report.html");
    assert!(stdout.contains("report: out/report.html"), "{stdout}");
    let html = fs::read_to_string(&page).unwrap();
    let manifest: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(tmp.path().join("out/manifest.json")).unwrap())
            .unwrap();
    let b = &manifest["mass_balance"];
    let pct =
        100.0 * b["credited_tonnes"].as_f64().unwrap() / b["scheduled_tonnes"].as_f64().unwrap();
    // The verdict comes first and states the run's own figures.
    let verdict = &html[html.find("class=\"verdict\"").expect("a verdict")..];
    let verdict = &verdict[..verdict.find("</p>").unwrap()];
    assert!(verdict.contains(&format!("({pct:.1}%)")), "{verdict}");
    assert!(verdict.contains("at a mean grade of mo 0."), "{verdict}");
    assert!(verdict.contains("dilution entry"), "{verdict}");
    for part in [
        "Grade against cumulative tonnes",
        "Plan maps",
        "Sections through the draw",
        "Mass balance",
        "Resolution",
        "Height of draw at the end",
        "Dilution entry (hollow: not reached)",
        "Drawn tonnes",
        "Air gap at the end",
        "Correction per drawpoint-period",
    ] {
        assert!(html.contains(part), "no {part:?} in the report");
    }
    // Every section row at its four moments (a quarter, a half, three quarters, the end)
    // and the grade grid are embedded: 4 rows × 4 + 1 images.
    assert_eq!(html.matches("<img ").count(), 17);
    assert_eq!(
        html.matches("src=\"data:image/png;base64,").count(),
        html.matches("src=").count(),
        "only data: URIs are loaded"
    );
    assert!(!html.contains("<script") && !html.contains("href=\"http"));
    assert!(html.contains("Content-Security-Policy") && html.contains("default-src 'none'"));

    if let Some((w, h)) = assert_renders(&page, "caveflow run: scenario") {
        assert!(
            w >= 1000 && h > 5000,
            "{w} × {h}: the whole page, charts and all"
        );
    }
}

/// `outputs.report = false` writes no page, and the tables are those of a run with one.
#[test]
fn report_can_be_turned_off() {
    let (tmp, stdout) = demo_run(&["--set", "outputs.report=false", "--keep-periods", "3"]);
    assert!(!tmp.path().join("out/report.html").exists());
    assert!(!stdout.contains("report:"), "{stdout}");
}
