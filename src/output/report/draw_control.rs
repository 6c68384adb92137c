//! The run report's draw control and value section (`engine::draw_control`,
//! `engine::value`): production against target, where and why drawpoints closed, how
//! uniform the realised draw was, and, with `[economics]`, each drawpoint's cumulative
//! value curve and best height of draw.

use std::path::{Path, PathBuf};

use super::page::Page;
use super::run::drawpoint_points;
use super::ReportError;
use crate::engine::draw_control::Layout;
use crate::engine::result::RunOutput;
use crate::engine::result::{BestHod, ControlRecord, Extraction, ValueTable};
use crate::model::Scene;
use crate::output::charts::{fmt_mass, line_chart, plan_map_chart, LineSeries, MapScale};

/// Most drawpoints whose value curves are drawn (the highest and lowest final values and
/// those between, evenly): more lines than this are not read.
const VALUE_CURVES: usize = 8;

/// The mean over drawpoints with neighbours of |HOD − their neighbours' mean HOD|, m, at
/// the end of the run: how uniform the realised draw was.
pub fn hod_spread(scene: &Scene, hod: &[f64], layout: &Layout) -> f64 {
    let gaps: Vec<f64> = (0..scene.drawpoints.len())
        .filter(|&d| !layout.neighbours[d].is_empty())
        .map(|d| {
            let near = &layout.neighbours[d];
            (hod[d] - near.iter().map(|&e| hod[e]).sum::<f64>() / near.len() as f64).abs()
        })
        .collect();
    gaps.iter().sum::<f64>() / gaps.len().max(1) as f64
}

/// [`hod_spread`] at the end of every period of `ext` (a drawpoint's height of draw held
/// from its last row), in period order.
pub fn hod_spread_by_period(scene: &Scene, ext: &Extraction, layout: &Layout) -> Vec<(i64, f64)> {
    let mut order: Vec<usize> = (0..ext.period.len()).collect();
    order.sort_by_key(|&k| ext.period[k]);
    let mut hod = vec![0.0; scene.drawpoints.len()];
    let mut out: Vec<(i64, f64)> = Vec::new();
    for (n, &k) in order.iter().enumerate() {
        if ext.hod[k].is_finite() {
            hod[ext.drawpoint[k] as usize] = ext.hod[k];
        }
        let last = order
            .get(n + 1)
            .is_none_or(|&j| ext.period[j] != ext.period[k]);
        if last {
            out.push((ext.period[k], hod_spread(scene, &hod, layout)));
        }
    }
    out
}

/// Adds the section (nothing without draw control or economics).
pub fn section(
    page: &mut Page,
    charts: &Path,
    scene: &Scene,
    run: &RunOutput,
    hod: &[f64],
) -> Result<(), ReportError> {
    if let Some(rec) = &run.control {
        page.heading("Draw control");
        control(page, charts, scene, rec, &run.extraction, hod)?;
    }
    if let Some((v, b)) = &run.value {
        page.heading("Value and best height of draw");
        value(page, charts, scene, v, b)?;
    }
    Ok(())
}

fn control(
    page: &mut Page,
    charts: &Path,
    scene: &Scene,
    rec: &ControlRecord,
    ext: &Extraction,
    hod: &[f64],
) -> Result<(), ReportError> {
    let p = &rec.production;
    let (target, drawn): (f64, f64) = (p.target_tonnes.iter().sum(), p.tonnes.iter().sum());
    let short = p
        .shortfall_tonnes
        .iter()
        .filter(|&&s| s > 1e-9 * target)
        .count();
    let mut reasons: Vec<(String, usize)> = Vec::new();
    for r in &rec.closures.reason {
        match reasons.iter_mut().find(|(x, _)| x == r) {
            Some((_, n)) => *n += 1,
            None => reasons.push((r.clone(), 1)),
        }
    }
    let closed = if reasons.is_empty() {
        "no drawpoint closed".to_string()
    } else {
        let by: Vec<String> = reasons.iter().map(|(r, n)| format!("{n} by {r}")).collect();
        format!(
            "{} drawpoints closed ({})",
            rec.closures.reason.len(),
            by.join(", ")
        )
    };
    let layout = Layout::new(scene, rec.neighbour_radius);
    page.para(&format!(
        "The target asked {} over {} periods; the drawpoints drew {} ({:.1}%). In {short} \
         periods the open drawpoints could not take the whole target under their rate limits \
         (production_target.shortfall_tonnes); {closed}. At the end a drawpoint's height of \
         draw lies {:.1} m from its neighbours' mean on average (neighbours within {:.1} m).",
        fmt_mass(target),
        p.period.len(),
        fmt_mass(drawn),
        100.0 * drawn / target.max(f64::MIN_POSITIVE),
        hod_spread(scene, hod, &layout),
        layout.radius,
    ));
    let production = charts.join("production_target.svg");
    let x: Vec<f64> = p.period.iter().map(|&k| k as f64).collect();
    let series = |name: &str, y: &[f64]| LineSeries {
        name: name.into(),
        points: x.iter().copied().zip(y.iter().copied()).collect(),
    };
    line_chart(
        &production,
        &[
            series("target", &p.target_tonnes),
            series("planned", &p.planned_tonnes),
            series("drawn", &p.tonnes),
        ],
        "Production against target",
        "period",
        "tonnes",
    )?;
    let dp = &scene.drawpoints;
    let mut closed_at = vec![f64::NAN; dp.len()];
    for (k, &d) in rec.closures.drawpoint.iter().enumerate() {
        closed_at[d as usize] = rec.closures.period[k] as f64;
    }
    let map = charts.join("map_closures.svg");
    plan_map_chart(
        &map,
        &drawpoint_points(scene, &closed_at),
        "Period of closure (hollow: open at the end)",
        "period",
        MapScale::Sequential,
    )?;
    let uniformity = charts.join("hod_spread.svg");
    let spread = hod_spread_by_period(scene, ext, &layout);
    line_chart(
        &uniformity,
        &[LineSeries {
            name: "mean |HOD − neighbours' mean|".into(),
            points: spread.iter().map(|&(k, g)| (k as f64, g)).collect(),
        }],
        "Uniformity of the realised draw",
        "period",
        "m",
    )?;
    page.charts(&[&production, &map, &uniformity])?;
    Ok(())
}

fn value(
    page: &mut Page,
    charts: &Path,
    scene: &Scene,
    v: &ValueTable,
    b: &BestHod,
) -> Result<(), ReportError> {
    let dp = &scene.drawpoints;
    let passed = (0..b.drawpoint.len())
        .filter(|&k| b.best_hod[k] < b.final_hod[k])
        .count();
    let total: f64 = b.final_value.iter().sum();
    let best: f64 = b.best_value.iter().sum();
    page.para(&format!(
        "The draw is worth {} in all (value.cum_value); stopping each drawpoint at its best \
         height of draw, where its cumulative value peaks, would be worth {}. {passed} of {} \
         drawpoints drew past their best height of draw (best_hod).",
        money(total),
        money(best),
        b.drawpoint.len()
    ));
    let mut best_hod = vec![f64::NAN; dp.len()];
    for (k, &d) in b.drawpoint.iter().enumerate() {
        best_hod[d as usize] = b.best_hod[k];
    }
    let map = charts.join("map_best_hod.svg");
    plan_map_chart(
        &map,
        &drawpoint_points(scene, &best_hod),
        "Best height of draw",
        "HOD (m)",
        MapScale::Sequential,
    )?;
    // The value curves of a few drawpoints, from the highest final value to the lowest.
    let mut order: Vec<usize> = (0..b.drawpoint.len()).collect();
    order.sort_by(|&a, &c| b.final_value[c].total_cmp(&b.final_value[a]));
    let step = (order.len() as f64 / VALUE_CURVES as f64).max(1.0);
    let shown: Vec<usize> = (0..VALUE_CURVES.min(order.len()))
        .map(|i| order[((i as f64 * step) as usize).min(order.len() - 1)])
        .collect();
    let series: Vec<LineSeries> = shown
        .iter()
        .map(|&k| {
            let d = b.drawpoint[k];
            LineSeries {
                name: dp.name[d as usize].clone(),
                points: (0..v.drawpoint.len())
                    .filter(|&r| v.drawpoint[r] == d)
                    .map(|r| (v.hod[r], v.cum_value[r]))
                    .collect(),
            }
        })
        .collect();
    let curves = charts.join("value_curves.svg");
    line_chart(
        &curves,
        &series,
        "Cumulative value against height of draw",
        "height of draw (m)",
        "cumulative value",
    )?;
    let paths: Vec<PathBuf> = vec![map, curves];
    page.charts(&paths.iter().map(PathBuf::as_path).collect::<Vec<_>>())?;
    Ok(())
}

/// A sum of money to three significant figures with a k/M/G suffix.
fn money(v: f64) -> String {
    let a = v.abs();
    let (x, s) = if a >= 1e9 {
        (v / 1e9, "G")
    } else if a >= 1e6 {
        (v / 1e6, "M")
    } else if a >= 1e3 {
        (v / 1e3, "k")
    } else {
        (v, "")
    };
    format!("{x:.3}{s}")
}
