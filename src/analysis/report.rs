//! The reconciliation report: one self-contained HTML page (no script, no network: every chart
//! is inline SVG) that a mine engineer can read in a minute.
//!
//! Top to bottom: the overall figures in words and numbers; a plan map of the bias per
//! drawpoint and the predicted-against-sampled scatter side by side; predicted and sampled
//! grade against cumulative tonnes for the drawpoints that miss most, with the block grade
//! under uniform drawdown (summary Figs 31–32); the zone table; every drawpoint, worst first;
//! and what each number means. The charts are also left beside the page as SVG files. The
//! page is built with the run report's [`Page`], so the two
//! look alike and share what "self-contained" means.

use std::path::{Path, PathBuf};

use polars::prelude::*;

use super::reconcile::{floats, strings, ReconcileError, Reconciliation};
use crate::model::Scene;
use crate::output::charts::{
    grade_tonnage_chart, plan_map_chart, scatter_chart, GradeSeries, MapPoint, MapScale,
    ScatterPoint,
};
use crate::output::parquet::write_atomic;
use crate::output::report::{num, Page};

/// Drawpoints shown on the first grade chart: those with the largest RMSE.
pub const WORST_SHOWN: usize = 12;

/// What the page is about.
#[derive(Debug, Clone, PartialEq)]
pub struct ReportInfo {
    /// Page title.
    pub title: String,
    /// Lines set under the title (run directory, records file, …).
    pub sources: Vec<String>,
    /// Grade charted and summarised.
    pub grade: String,
}

/// Grade against cumulative tonnes under uniform drawdown of the ground above each
/// drawpoint: the "block grade" line of the summary's Figs 31–32.
///
/// Every block column is given to the nearest drawpoint in plan, if that drawpoint is no
/// farther than the largest nearest-neighbour drawpoint spacing (columns beyond the panel
/// belong to none). A drawpoint's column is then drawn down layer by layer from its base
/// up: each layer adds its in-situ solids ρ_s (1 − n0) V and their mass-weighted grade.
/// Returns, per drawpoint, (cumulative tonnes at the top of each layer, layer grade).
// The level index k walks the block grid (i, j, k) and the per-drawpoint levels at once.
#[allow(clippy::needless_range_loop)]
pub fn block_grade_curves(scene: &Scene, grade: usize) -> Vec<Vec<(f64, f64)>> {
    let (bm, dp) = (&scene.blocks, &scene.drawpoints);
    let n = dp.len();
    let nearest = |x: f64, y: f64, skip: usize| {
        (0..n)
            .filter(|&d| d != skip)
            .map(|d| (d, (dp.x[d] - x).hypot(dp.y[d] - y)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
    };
    let reach = (0..n)
        .filter_map(|d| nearest(dp.x[d], dp.y[d], d).map(|(_, r)| r))
        .fold(0.0f64, f64::max);
    let reach = if reach > 0.0 { reach } else { f64::INFINITY };
    let [nx, ny, nz] = bm.dims;
    let volume = bm.size[0] * bm.size[1] * bm.size[2];
    // Per drawpoint and level: (solids, solids × grade).
    let mut layers = vec![vec![(0.0f64, 0.0f64); nz]; n];
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let b = bm.index[i + nx * (j + ny * k)];
                if b == crate::model::block_model::NO_BLOCK {
                    continue;
                }
                let b = b as usize;
                let Some((d, r)) = nearest(bm.x[b], bm.y[b], usize::MAX) else {
                    continue;
                };
                if r > reach || bm.z[b] < dp.z[d] {
                    continue;
                }
                let t = bm.density[b] * (1.0 - bm.n0[b]) * volume;
                layers[d][k].0 += t;
                layers[d][k].1 += t * bm.grades[grade][b];
            }
        }
    }
    layers
        .into_iter()
        .map(|levels| {
            let mut cum = 0.0;
            levels
                .into_iter()
                .filter(|&(t, _)| t > 0.0)
                .map(|(t, tg)| {
                    cum += t;
                    (cum, tg / t)
                })
                .collect()
        })
        .collect()
}

/// The metrics rows of one level for `grade`, sorted by RMSE (largest first).
fn level_rows(r: &Reconciliation, level: &str, grade: &str) -> PolarsResult<DataFrame> {
    r.metrics
        .clone()
        .lazy()
        .filter(col("level").eq(lit(level)).and(col("grade").eq(lit(grade))))
        .sort(
            ["rmse"],
            SortMultipleOptions::default()
                .with_order_descending(true)
                .with_nulls_last(true),
        )
        .collect()
}

/// Writes `report.html` and its charts (`charts/*.svg`) into `dir`; returns the page's path.
pub fn write_report(
    dir: &Path,
    r: &Reconciliation,
    scene: &Scene,
    info: &ReportInfo,
) -> Result<PathBuf, ReconcileError> {
    let g = info.grade.as_str();
    let label = format!("{g} (%)");
    let charts = dir.join("charts");
    std::fs::create_dir_all(&charts).map_err(|source| ReconcileError::Io {
        path: charts.clone(),
        source,
    })?;
    let rows = r
        .rows
        .clone()
        .lazy()
        .filter(col("grade").eq(lit(g)))
        .collect()?;
    let dps = level_rows(r, "drawpoint", g)?;
    let zones = level_rows(r, "zone", g)?;

    // Scatter, coloured by zone.
    let mut zone_names: Vec<String> = strings(&zones, "key");
    zone_names.sort();
    let zone_of = strings(&rows, "zone");
    let points: Vec<ScatterPoint> = floats(&rows, "sampled")
        .into_iter()
        .zip(floats(&rows, "predicted"))
        .zip(&zone_of)
        .map(|((sampled, predicted), z)| ScatterPoint {
            sampled,
            predicted,
            zone: zone_names.iter().position(|n| n == z).unwrap_or(0),
        })
        .collect();
    let scatter = charts.join("scatter.svg");
    scatter_chart(
        &scatter,
        &points,
        &zone_names,
        "Predicted against sampled",
        &label,
    )?;

    // Map of the bias per drawpoint (every drawpoint of the scene; unmatched ones hollow).
    let (dp_names, dp_bias) = (strings(&dps, "key"), floats(&dps, "bias"));
    let sd = &scene.drawpoints;
    let map_points: Vec<MapPoint> = (0..sd.len())
        .map(|d| MapPoint {
            x: sd.x[d],
            y: sd.y[d],
            value: dp_names
                .iter()
                .position(|n| *n == sd.name[d])
                .map_or(f64::NAN, |k| dp_bias[k]),
            label: sd.name[d].clone(),
        })
        .collect();
    let map = charts.join("bias_map.svg");
    plan_map_chart(
        &map,
        &map_points,
        "Bias per drawpoint (predicted − sampled)",
        &label,
        MapScale::Diverging,
    )?;

    // Grade curves: the worst drawpoints first, then all of them.
    let grade_index = scene.blocks.grade_names.iter().position(|n| n == g);
    let blocks = grade_index.map(|k| block_grade_curves(scene, k));
    let (row_dp, row_cum) = (strings(&rows, "drawpoint"), floats(&rows, "cum_tonnes"));
    let (row_pred, row_samp) = (floats(&rows, "predicted"), floats(&rows, "sampled"));
    let series_of = |name: &str| {
        let at: Vec<usize> = (0..row_dp.len()).filter(|&k| row_dp[k] == name).collect();
        GradeSeries {
            name: name.to_string(),
            cum_tonnes: at.iter().map(|&k| row_cum[k]).collect(),
            predicted: at.iter().map(|&k| row_pred[k]).collect(),
            sampled: Some(at.iter().map(|&k| (row_cum[k], row_samp[k])).collect()),
            block_grade: blocks
                .as_ref()
                .and_then(|b| sd.find(name).map(|d| b[d].clone())),
            dilution_entry: None,
        }
    };
    let worst: Vec<GradeSeries> = dp_names
        .iter()
        .take(WORST_SHOWN)
        .map(|n| series_of(n))
        .collect();
    let mut grade_charts = Vec::new();
    if !worst.is_empty() {
        let title = format!("The {} drawpoints with the largest RMSE", worst.len());
        grade_charts.push((
            title.clone(),
            grade_tonnage_chart(&charts.join("worst.svg"), &worst, &title, &label)?,
        ));
        let all: Vec<GradeSeries> = dp_names.iter().map(|n| series_of(n)).collect();
        grade_charts.push((
            "Every drawpoint".to_string(),
            grade_tonnage_chart(&charts.join("all.svg"), &all, "Every drawpoint", &label)?,
        ));
    }

    let html = page(r, info, &zones, &dps, &[scatter, map], &grade_charts)?;
    let path = dir.join("report.html");
    write_atomic(&path, html.as_bytes())?;
    Ok(path)
}

/// The overall figures as one sentence.
fn verdict(r: &Reconciliation, g: &str) -> String {
    let m = |name| r.metric("overall", "all", g, name).unwrap_or(f64::NAN);
    let (bias, tw, rmse, corr, mean) = (
        m("bias"),
        m("tw_error"),
        m("rmse"),
        m("correlation"),
        m("mean_sampled"),
    );
    let side = if bias >= 0.0 { "over" } else { "under" };
    let rel = if mean > 0.0 {
        format!(" ({:.1}% of the mean sampled grade)", 100.0 * rmse / mean)
    } else {
        String::new()
    };
    format!(
        "Over {n:.0} drawpoint-periods the model {side}-predicts {g} by {b:.4}% on average \
         ({tw:.4}% weighted by tonnes); the typical miss (RMSE) is {rmse:.4}%{rel}, and \
         predicted and sampled grades correlate at r = {corr:.2}.",
        n = m("n"),
        b = bias.abs(),
    )
}

fn page(
    r: &Reconciliation,
    info: &ReportInfo,
    zones: &DataFrame,
    dps: &DataFrame,
    side_by_side: &[PathBuf],
    grade_charts: &[(String, Vec<PathBuf>)],
) -> Result<String, ReconcileError> {
    let g = info.grade.as_str();
    let mut p = Page::new(&info.title, &info.sources);
    p.verdict(&verdict(r, g));
    let cards: Vec<(String, String)> = [
        ("rows compared", "n", ""),
        ("bias", "bias", "%"),
        ("tonnage-weighted error", "tw_error", "%"),
        ("MAE", "mae", "%"),
        ("RMSE", "rmse", "%"),
        ("correlation r", "correlation", ""),
        ("dilution entry, predicted − sampled", "de_difference", " t"),
    ]
    .into_iter()
    .map(|(name, key, unit)| {
        let v = r.metric("overall", "all", g, key).unwrap_or(f64::NAN);
        let shown = match key {
            "n" => format!("{v:.0}"),
            "de_difference" if v.is_finite() => format!("{v:+.0}"),
            _ => num(v),
        };
        let unit = if v.is_finite() { unit } else { "" };
        (format!("{shown}{unit}"), name.to_string())
    })
    .collect();
    p.cards(&cards);
    p.charts(
        &side_by_side
            .iter()
            .map(PathBuf::as_path)
            .collect::<Vec<_>>(),
    )?;
    for (title, pages) in grade_charts {
        p.heading(title);
        p.note(
            "Predicted grade (line) and sampled grade (points) against cumulative tonnes; \
             dashed: the block grade if the ground above the drawpoint were drawn down \
             uniformly.",
        );
        for c in pages {
            p.charts(&[c])?;
        }
    }
    p.heading("Zones");
    table(&mut p, zones, "zone");
    p.heading("Drawpoints, largest RMSE first");
    table(&mut p, dps, "drawpoint");
    p.heading("What the numbers mean");
    p.glossary(&[
        (
            "error",
            "predicted − sampled grade of a drawpoint-period (% by mass); bias is its mean, MAE the mean of its size, RMSE the root of its mean square",
        ),
        (
            "tonnage-weighted error",
            "Σ tonnes × error / Σ tonnes, the metal the model over- or under-calls per tonne produced",
        ),
        ("r", "Pearson correlation of predicted and sampled grades"),
        (
            "dilution entry",
            "cumulative tonnes at which the grade first falls below the cutoff; negative differences mean the model dilutes too early",
        ),
    ]);
    Ok(p.finish())
}

/// A metrics table: one row per key.
fn table(p: &mut Page, df: &DataFrame, what: &str) {
    let keys = strings(df, "key");
    let cols = [
        ("n", "n"),
        ("bias", "bias (%)"),
        ("tw_error", "TW error (%)"),
        ("mae", "MAE (%)"),
        ("rmse", "RMSE (%)"),
        ("correlation", "r"),
        ("mean_predicted", "mean predicted (%)"),
        ("mean_sampled", "mean sampled (%)"),
        ("de_difference", "DE diff (t)"),
    ];
    let values: Vec<Vec<f64>> = cols.iter().map(|(c, _)| floats(df, c)).collect();
    let header: Vec<&str> = std::iter::once(what)
        .chain(cols.iter().map(|(_, t)| *t))
        .collect();
    let rows: Vec<Vec<String>> = keys
        .iter()
        .enumerate()
        .map(|(k, key)| {
            let mut row = vec![if key.is_empty() { "(none)" } else { key }.to_string()];
            row.extend(values.iter().enumerate().map(|(c, v)| {
                // n and the dilution-entry tonnes are whole numbers.
                if (c == 0 || c == cols.len() - 1) && v[k].is_finite() {
                    format!("{:.0}", v[k])
                } else {
                    num(v[k])
                }
            }));
            row
        })
        .collect();
    p.table(&header, &rows);
}
