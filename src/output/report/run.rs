//! The run report (`<dir>/report.html`, `outputs.report`): what a run predicts, on one page
//! an engineer reads before opening a table.
//!
//! Top to bottom:
//! 1. **The verdict**: tonnes drawn of scheduled, mean grades, the dilution entry, and what
//!    the warnings say, in two sentences; key figures as cards; the warnings, summarised one
//!    line per kind (`output::warnings`).
//! 2. **Grade against cumulative tonnes** per drawpoint (the run's `grade_<g>.png`, summary
//!    Figs 31–32), with each drawpoint's dilution entry (`output::dilution`) dotted.
//! 3. **Plan maps** (`charts/map_*.svg`): height of draw at the end of the run, dilution
//!    entry, drawn tonnes, and the air gap at the end where there is one.
//! 4. **Sections through the draw** (`section_<k>_p<N>.png` and `section_<k>.png`): each row
//!    of drawpoints at the moments of `outputs.section_periods` (by default a quarter, a half
//!    and three quarters of the scheduled tonnes, and the end), IMZs cut at the free surface,
//!    the air gap shown.
//! 5. **Mass balance**: the distribution of the correction c = credited / marker tonnes over
//!    the drawpoint-periods that drew markers and are `ok` (`charts/correction.svg`; summary
//!    §3.3: the markers' mass should be the scheduled mass, so c is 1 but for discreteness),
//!    and the drawpoints short of material.
//! 6. **Draw control** and **value** (`output::report::draw_control`), when the run had
//!    them: production against target, the closures' plan map, the realised draw's
//!    uniformity, the best heights of draw and a few cumulative value curves.
//! 7. **Resolution**: the h, marker spacing and draw increment used, and what the
//!    speed–accuracy rule (`engine::resolution`) says of them: the spacing as a multiple of
//!    the scene's default and the whole-draw grade error the sweep's fit expects there.
//!
//! Without run charts (`outputs.charts = false`) the page says so where the grade charts and
//! sections would be; its own charts (maps, correction) are drawn either way.

use std::path::{Path, PathBuf};

use super::page::{num, Page};
use super::ReportError;
use crate::engine::resolution::expected_grade_rmse;
use crate::engine::result::RunOutput;
use crate::model::Scene;
use crate::output::charts::{fmt_mass, histogram_chart, plan_map_chart, MapPoint, MapScale};
use crate::output::dilution::{dilution_entries, DILUTION_ENTRY_SHARE};
use crate::output::manifest::Manifest;
use crate::output::parquet::write_atomic;
use crate::output::warnings;

/// Half-width of the band about 1 in which the median correction is discreteness only (the
/// engine warns outside it).
const CORRECTION_BAND: f64 = 0.03;

/// What a run report is made from.
pub struct RunReport<'a> {
    /// The run's name (the scenario file's stem).
    pub name: &'a str,
    /// The scene run.
    pub scene: &'a Scene,
    /// The run's results.
    pub run: &'a RunOutput,
    /// Its manifest (inputs, version, time, resolution, balance).
    pub manifest: &'a Manifest,
    /// The run charts written (`output::run_dir::write_run_charts`; empty without charts).
    pub charts: &'a [PathBuf],
    /// The moments of the sections (`Scene::moments`).
    pub moments: &'a [i64],
}

/// The figures of a run the page reads, worked out once: per drawpoint in the scene's
/// drawpoint order, and the run's mean grades and short drawpoints.
struct Figures {
    /// Height of draw at the drawpoint's last row, m.
    hod: Vec<f64>,
    /// Air gap at the drawpoint's last row, m.
    air_gap: Vec<f64>,
    /// Credited tonnes over the run.
    tonnes: Vec<f64>,
    /// Dilution entry, t (NaN: never reached).
    entry: Vec<f64>,
    /// Markers drawn per drawpoint-period that drew any, ascending (for the median).
    markers: Vec<i64>,
    /// Tonnage-weighted mean of each grade over the run: (grade, mean).
    grades: Vec<(String, f64)>,
    /// The drawpoints whose credited tonnes fall short of their schedule: (name,
    /// scheduled, credited).
    short: Vec<(String, f64, f64)>,
}

impl Figures {
    fn new(scene: &Scene, run: &RunOutput) -> Figures {
        let n = scene.drawpoints.len();
        let e = &run.extraction;
        let (mut hod, mut air_gap, mut tonnes) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let mut last = vec![i64::MIN; n];
        let mut markers = Vec::new();
        for i in 0..e.period.len() {
            let d = e.drawpoint[i] as usize;
            tonnes[d] += e.tonnes[i];
            if e.period[i] >= last[d] {
                last[d] = e.period[i];
                hod[d] = e.hod[i];
                air_gap[d] = e.air_gap[i];
            }
            if e.markers[i] > 0 {
                markers.push(e.markers[i]);
            }
        }
        markers.sort_unstable();
        Figures {
            hod,
            air_gap,
            tonnes,
            entry: dilution_entries(run, n),
            markers,
            grades: mean_grades(scene, run),
            short: per_short(scene, run),
        }
    }

    /// How many drawpoints reached the dilution entry, and their mean entry, t.
    fn mean_entry(&self) -> (usize, f64) {
        let e: Vec<f64> = self
            .entry
            .iter()
            .copied()
            .filter(|x| x.is_finite())
            .collect();
        (e.len(), e.iter().sum::<f64>() / e.len() as f64)
    }
}

/// Writes `report.html` into `dir` and its own charts into `dir/charts/`; returns the page's
/// path.
pub fn write_run_report(dir: &Path, r: &RunReport) -> Result<PathBuf, ReportError> {
    let (scene, run, m) = (r.scene, r.run, r.manifest);
    let charts = dir.join("charts");
    std::fs::create_dir_all(&charts).map_err(|source| ReportError::Io {
        path: charts.clone(),
        source,
    })?;
    let per = Figures::new(scene, run);
    let mut page = Page::new(
        &format!("caveflow run: {}", r.name),
        &[
            format!(
                "caveflow {}, {}; {} threads, {:.1} s",
                m.caveflow_version, m.created_utc, m.threads, m.wall_time_s
            ),
            format!(
                "inputs: {}",
                m.inputs
                    .iter()
                    .map(|f| format!("{} {} ({}…)", f.role, f.path.display(), &f.sha256[..12]))
                    .collect::<Vec<_>>()
                    .join("; ")
            ),
            format!(
                "{} blocks, {} drawpoints, {} periods, seed {}",
                scene.blocks.len(),
                scene.drawpoints.len(),
                scene.periods.len(),
                m.seed
            ),
        ],
    );
    let warn_lines = warnings::summary(&run.warnings);
    page.verdict(&verdict(scene, run, &per));
    page.cards(&cards(scene, run, &per));
    if !warn_lines.is_empty() {
        page.heading("Warnings");
        page.list(&warn_lines, true);
    }

    page.heading("Grade against cumulative tonnes");
    let grade_charts = of_kind(r.charts, |stem| stem.starts_with("grade_"));
    if grade_charts.is_empty() {
        page.note("No grade charts: the run was made with outputs.charts = false.");
    } else {
        page.note(&format!(
            "Predicted grade per period (line) against the drawpoint's cumulative tonnes; dashed, \
             the block grade if the column above the drawpoint were drawn down uniformly; dotted, \
             the dilution entry ({:.0}% waste in a period).",
            100.0 * DILUTION_ENTRY_SHARE
        ));
        for c in grade_charts {
            page.charts(&[c])?;
        }
    }

    page.heading("Plan maps");
    // Two maps a row: four would be too small to read the drawpoints' names.
    for pair in plan_maps(&charts, scene, &per)?.chunks(2) {
        page.charts(&pair.iter().map(PathBuf::as_path).collect::<Vec<_>>())?;
    }

    page.heading("Sections through the draw");
    sections(&mut page, r)?;

    page.heading("Mass balance");
    mass_balance(&mut page, &charts, run, &per)?;

    super::draw_control::section(&mut page, &charts, scene, run, &per.hod)?;

    page.heading("Resolution");
    resolution(&mut page, scene, run, &per);

    page.heading("What the numbers mean");
    page.glossary(&[
        (
            "drawn tonnes",
            "the tonnes credited to a drawpoint: its scheduled tonnes, less what it could not deliver (its column drawn out or drained into an air gap, its ground not caved, or its markers behind its credits: extraction.short_reason)",
        ),
        (
            "dilution entry",
            "the cumulative tonnes of a drawpoint at which the waste share of a period first reaches 10%, read between the midpoints of that period and the one before",
        ),
        (
            "height of draw",
            "the drawpoint's cumulative tonnes over its tributary area and the in-situ bulk density: the height the column would have dropped under uniform drawdown",
        ),
        (
            "air gap",
            "the void between the top of the caved material and the uncaved back above it",
        ),
        (
            "correction",
            "credited over marker tonnes of a drawpoint-period: how far the discrete markers drawn are from the tonnes scheduled",
        ),
    ]);
    let path = dir.join("report.html");
    write_atomic(&path, page.finish().as_bytes())?;
    Ok(path)
}

/// The verdict in two sentences.
fn verdict(scene: &Scene, run: &RunOutput, per: &Figures) -> String {
    let b = &run.balance;
    let share = 100.0 * b.credited_tonnes / b.scheduled_tonnes.max(f64::MIN_POSITIVE);
    let mut s = format!(
        "The run drew {} of the {} scheduled ({share:.1}%)",
        fmt_mass(b.credited_tonnes),
        fmt_mass(b.scheduled_tonnes)
    );
    let grades: Vec<String> = per
        .grades
        .iter()
        .map(|(g, v)| format!("{g} {}", num(*v)))
        .collect();
    if !grades.is_empty() {
        s.push_str(&format!(" at a mean grade of {}", grades.join(", ")));
    }
    let short = per.short.len();
    if short > 0 {
        s.push_str(&format!(
            "; {short} of {} drawpoints fell short of material",
            scene.drawpoints.len()
        ));
    }
    s.push_str(&match per.mean_entry() {
        (0, _) => ". No drawpoint reached 10% waste".to_string(),
        (n, mean) => format!(
            ". {n} of {} drawpoints reached 10% waste, after {} on average (dilution entry)",
            scene.drawpoints.len(),
            fmt_mass(mean)
        ),
    });
    s.push_str(&match run.warnings.len() {
        0 => "; the run raised no warning.".to_string(),
        1 => "; it raised one warning, below.".to_string(),
        n => format!("; it raised {n} warnings, summarised below."),
    });
    s
}

/// Tonnage-weighted mean of each grade column over the run.
fn mean_grades(scene: &Scene, run: &RunOutput) -> Vec<(String, f64)> {
    let e = &run.extraction;
    (0..e.grades.len())
        .map(|g| {
            let (metal, t) = e.grade_metal(g);
            (scene.blocks.grade_names[g].clone(), metal / t)
        })
        .collect()
}

/// The drawpoints whose credited tonnes fall short of their schedule: (name, scheduled,
/// credited).
fn per_short(scene: &Scene, run: &RunOutput) -> Vec<(String, f64, f64)> {
    run.balance
        .per_drawpoint
        .iter()
        .enumerate()
        .filter(|(_, (s, c))| c < s)
        .map(|(d, &(s, c))| (scene.drawpoints.name[d].clone(), s, c))
        .collect()
}

/// The key figures.
fn cards(scene: &Scene, run: &RunOutput, per: &Figures) -> Vec<(String, String)> {
    let b = &run.balance;
    let mut c = vec![
        (fmt_mass(b.credited_tonnes), "drawn".to_string()),
        (fmt_mass(b.scheduled_tonnes), "scheduled".to_string()),
    ];
    for (g, v) in &per.grades {
        c.push((num(*v), format!("mean {g}")));
    }
    if let (1.., mean) = per.mean_entry() {
        c.push((fmt_mass(mean), "mean dilution entry".into()));
    }
    c.push((
        format!("{} / {}", per.short.len(), scene.drawpoints.len()),
        "drawpoints short".into(),
    ));
    c.push((
        format!("{:.3}", b.correction.drawpoint_median),
        "correction, median of the drawpoints".into(),
    ));
    c.push((
        format!("{} m", metres(run.resolution.marker_spacing)),
        "marker spacing".into(),
    ));
    c
}

/// The run charts whose file stem passes `keep`, in name order.
fn of_kind(charts: &[PathBuf], keep: impl Fn(&str) -> bool) -> Vec<&Path> {
    let mut out: Vec<&Path> = charts
        .iter()
        .filter(|p| p.file_stem().is_some_and(|s| keep(&s.to_string_lossy())))
        .map(PathBuf::as_path)
        .collect();
    out.sort();
    out
}

/// Draws the plan maps; returns their files.
fn plan_maps(charts: &Path, scene: &Scene, per: &Figures) -> Result<Vec<PathBuf>, ReportError> {
    let points = |values: &[f64]| drawpoint_points(scene, values);
    let mut maps = vec![
        ("map_hod", "Height of draw at the end", "HOD (m)", &per.hod),
        (
            "map_dilution_entry",
            "Dilution entry (hollow: not reached)",
            "tonnes",
            &per.entry,
        ),
        ("map_tonnes", "Drawn tonnes", "tonnes", &per.tonnes),
    ];
    if per.air_gap.iter().any(|&a| a > 0.0) {
        maps.push((
            "map_air_gap",
            "Air gap at the end",
            "air gap (m)",
            &per.air_gap,
        ));
    }
    let mut out = Vec::new();
    for (file, title, label, values) in maps {
        let path = charts.join(format!("{file}.svg"));
        plan_map_chart(&path, &points(values), title, label, MapScale::Sequential)?;
        out.push(path);
    }
    Ok(out)
}

/// One point of a plan map per drawpoint, with its value in `values` (drawpoint order).
pub(super) fn drawpoint_points(scene: &Scene, values: &[f64]) -> Vec<MapPoint> {
    let dp = &scene.drawpoints;
    (0..dp.len())
        .map(|d| MapPoint {
            x: dp.x[d],
            y: dp.y[d],
            value: values[d],
            label: dp.name[d].clone(),
        })
        .collect()
}

/// The sections at each moment, one row of images per drawpoint row.
fn sections(page: &mut Page, r: &RunReport) -> Result<(), ReportError> {
    let last = r.scene.periods.id.last().copied();
    let total: f64 = r.scene.schedule.tonnes.iter().sum();
    let shown: Vec<String> = r
        .moments
        .iter()
        .map(|p| {
            let cum: f64 = (0..r.scene.periods.len())
                .filter(|&k| r.scene.periods.id[k] <= *p)
                .map(|k| r.scene.schedule.period(k).iter().sum::<f64>())
                .sum();
            format!("{p} ({:.0}% of the scheduled tonnes)", 100.0 * cum / total)
        })
        .collect();
    let rows = of_kind(r.charts, |s| s.starts_with("section_") && !s.contains("_p"));
    if rows.is_empty() {
        page.note("No sections: the run was made with outputs.charts = false.");
        return Ok(());
    }
    page.note(&format!(
        "Each row of drawpoints at the end of periods {}: layers of markers, the IMZs (orange, \
         cut at the free surface), the IEZ (magenta, the drawn markers' origins), the free \
         surface and the air gap (blue).",
        shown.join(", ")
    ));
    for end in rows {
        let stem = end
            .file_stem()
            .map_or(String::new(), |s| s.to_string_lossy().into_owned());
        let mut at: Vec<&Path> = r
            .moments
            .iter()
            .filter(|&&p| Some(p) != last)
            .filter_map(|p| {
                let name = format!("{stem}_p{p}.png");
                r.charts
                    .iter()
                    .find(|c| c.file_name().is_some_and(|f| *f == *name))
            })
            .map(PathBuf::as_path)
            .collect();
        at.push(end);
        page.charts(&at)?;
    }
    Ok(())
}

/// The correction's distribution and the drawpoints short of material.
fn mass_balance(
    page: &mut Page,
    charts: &Path,
    run: &RunOutput,
    per: &Figures,
) -> Result<(), ReportError> {
    let e = &run.extraction;
    let c = &run.balance.correction;
    let values: Vec<f64> = (0..e.period.len())
        .filter(|&i| e.status[i] == "ok" && e.marker_tonnes[i] > 0.0)
        .map(|i| e.correction[i])
        .collect();
    let within = (c.drawpoint_median - 1.0).abs() <= CORRECTION_BAND;
    page.para(&format!(
        "Over {} drawpoint-periods, the correction c = credited / marker tonnes has median \
         {:.3} (10th percentile {:.3}, 90th {:.3}); {} rows are at MassFlow's bounds (0.1 or \
         2). The median over the drawpoints of their run's c is {:.3}, {} 1 ± {CORRECTION_BAND}: {}.",
        c.rows,
        c.median,
        c.p10,
        c.p90,
        c.at_lower_bound + c.at_upper_bound,
        c.drawpoint_median,
        if within { "within" } else { "outside" },
        if within {
            "the markers drawn carry the mass the schedule asks, and the correction only \
             smooths their discreteness"
        } else {
            "the markers drawn do not carry the scheduled mass; grades and the dilution entry \
             carry that bias (see the run's warnings)"
        }
    ));
    let hist = charts.join("correction.svg");
    histogram_chart(
        &hist,
        &values,
        "Correction per drawpoint-period (status ok)",
        "credited / marker tonnes",
        &[
            (1.0 - CORRECTION_BAND, "1 − 0.03"),
            (1.0, "1"),
            (1.0 + CORRECTION_BAND, "1 + 0.03"),
        ],
    )?;
    page.charts(&[&hist])?;
    if !per.short.is_empty() {
        page.note(
            "Drawpoints short of material (extraction.status and short_reason give each period):",
        );
        let rows: Vec<Vec<String>> = per
            .short
            .iter()
            .map(|(name, s, c)| {
                vec![
                    name.clone(),
                    format!("{s:.0}"),
                    format!("{c:.0}"),
                    format!("{:.1}", 100.0 * (s - c) / s),
                ]
            })
            .collect();
        page.table(
            &["drawpoint", "scheduled (t)", "drawn (t)", "short (%)"],
            &rows,
        );
    }
    Ok(())
}

/// The resolution used and what the speed–accuracy rule says of it.
fn resolution(page: &mut Page, scene: &Scene, run: &RunOutput, per: &Figures) {
    let res = &run.resolution;
    let b = &run.balance;
    let rows = [
        ("disk thickness h (m)", metres(res.layer_thickness)),
        ("marker spacing (m)", metres(res.marker_spacing)),
        ("draw increment (t)", format!("{:.1}", res.draw_increment)),
        ("max marker move (m)", metres(res.max_marker_move)),
        (
            "markers mobilised / drawn",
            format!("{} / {}", b.markers_mobilised, b.markers_drawn),
        ),
    ];
    let rows: Vec<Vec<String>> = rows.into_iter().map(|(k, v)| vec![k.into(), v]).collect();
    page.table(&["knob", "value"], &rows);
    let (m, err) = expected_grade_rmse(scene, res);
    let median_markers = per.markers.get(per.markers.len() / 2).copied().unwrap_or(0);
    page.para(&format!(
        "The marker spacing is {m:.2} × the scene's default. At that multiple the speed–accuracy \
         rule (engine::resolution, fitted on the demo's whole draw) expects a relative grade \
         RMSE per drawpoint-period of about {:.1}% against a converged reference: the sampling \
         noise of drawing a median of {median_markers} markers a drawpoint-period. Another scene's \
         error differs with its grade variability and tonnes per period; `caveflow sweep` \
         measures it, and `resolution.target_grade_rmse` sets a target.",
        100.0 * err
    ));
}

/// A length to the millimetre, without trailing zeros ("3.41", "1.9", "4").
fn metres(v: f64) -> String {
    let s = format!("{v:.3}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}
