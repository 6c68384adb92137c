//! The study report (`DIR/report.html`): the variants side by side, on the run report's page
//! (`output::report::Page`), from the study's own dataset and summary, so a study resumed or
//! run on a cluster gets the same page as one run here.
//!
//! Top to bottom: the verdict (how far the variants' recovery, grade and dilution entry
//! spread, and which variant is at each end); the grade–tonnage curves overlaid (the grade
//! of each period, over all drawpoints, against the cumulative tonnes); the recovery–dilution
//! curves overlaid (cumulative metal over the footprint's in-situ metal, against the waste
//! share of the cumulative tonnes); per-drawpoint differences of each variant from the first
//! on a plan map (the drawpoint's mean grade over the run, at the first variant's drawpoint
//! positions); and the summary table.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use arrow::array::{Array, AsArray};
use arrow::datatypes::{DataType, Float64Type, Int64Type};
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;

use super::plan::{Study, Swept};
use super::runner::Layout;
use super::summary::SummaryRow;
use crate::output::charts::{line_chart, plan_map_chart, LineSeries, MapPoint, MapScale};
use crate::output::report::{num, Page};
use crate::output::write_atomic;

/// What a variant drew, read back from its `extraction` partitions.
#[derive(Default)]
struct Drawn {
    /// Per period: (tonnes, metal of the first grade, waste tonnes).
    periods: BTreeMap<i64, (f64, f64, f64)>,
    /// Per drawpoint name: (tonnes, metal of the first grade).
    drawpoints: BTreeMap<String, (f64, f64)>,
}

/// Writes `report.html` (and its charts in `charts/`) into the study directory from the
/// complete variants' `rows`; returns the page's path.
pub fn write_study_report(study: &Study, layout: &Layout, rows: &[SummaryRow]) -> Result<PathBuf> {
    let charts = layout.dir.join("charts");
    std::fs::create_dir_all(&charts).with_context(|| charts.display().to_string())?;
    let grade = rows
        .first()
        .and_then(|r| r.grades.first())
        .map(|(g, _)| g.clone());
    let mut page = Page::new(
        &format!("caveflow study: {}", study.name),
        &[
            format!("study file: {}", study.file.display()),
            format!("base scenario: {}", study.scenario.display()),
            format!(
                "{} of {} variants complete; dataset: {}",
                rows.len(),
                study.variants.len(),
                layout.dir.join("dataset").display()
            ),
        ],
    );
    page.verdict(&verdict(rows));
    let drawn: Vec<Drawn> = match &grade {
        Some(g) => rows
            .iter()
            .map(|r| read_drawn(layout, &r.variant, g))
            .collect::<Result<_>>()?,
        None => Vec::new(),
    };
    if let Some(g) = &grade {
        page.heading("Grade against tonnes, and recovery against dilution");
        page.note(&format!(
            "Left: the {g} grade of each period over all drawpoints against the cumulative \
             tonnes. Right: the {g} drawn so far over the {g} in situ in the footprint \
             (recovery, which counts ground drawn from beyond the footprint and can pass 100%) \
             against the waste share of the tonnes drawn so far."
        ));
        let (gt, rd) = curves(rows, &drawn);
        let gt_path = charts.join("grade_tonnage.svg");
        let rd_path = charts.join("recovery_dilution.svg");
        line_chart(
            &gt_path,
            &gt,
            "Grade against cumulative tonnes",
            "cumulative tonnes (t)",
            &format!("{g} (%)"),
        )?;
        line_chart(
            &rd_path,
            &rd,
            "Recovery against dilution",
            "waste in the tonnes drawn (%)",
            &format!("{g} recovery (%)"),
        )?;
        page.charts(&[&gt_path, &rd_path])?;
        if rows.len() > 1 {
            page.heading(&format!("Per drawpoint, against {}", rows[0].variant));
            differences(&mut page, study, &charts, rows, &drawn, g)?;
        }
    }
    page.heading("Summary");
    summary_table(&mut page, study, rows);
    let path = layout.dir.join("report.html");
    write_atomic(&path, page.finish().as_bytes())?;
    Ok(path)
}

/// The spread of the variants in a sentence.
fn verdict(rows: &[SummaryRow]) -> String {
    if rows.is_empty() {
        return "No variant of the study is complete yet.".into();
    }
    let mut s = format!("{} variants", rows.len());
    let ends = |f: &dyn Fn(&SummaryRow) -> Option<f64>| {
        let mut v: Vec<(f64, &str)> = rows
            .iter()
            .filter_map(|r| f(r).map(|x| (x, r.variant.as_str())))
            .collect();
        v.sort_by(|a, b| a.0.total_cmp(&b.0));
        Some((*v.first()?, *v.last()?))
    };
    if let Some((g, _)) = rows[0].recovery.first() {
        if let Some(((lo, a), (hi, b))) = ends(&|r| r.recovery.first().and_then(|x| x.1)) {
            s.push_str(&format!(
                ": {g} recovery from {:.1}% ({a}) to {:.1}% ({b})",
                100.0 * lo,
                100.0 * hi
            ));
        }
        if let Some(((lo, a), (hi, b))) = ends(&|r| r.grades.first().and_then(|x| x.1)) {
            s.push_str(&format!(
                ", mean {g} grade from {} ({a}) to {} ({b})",
                num(lo),
                num(hi)
            ));
        }
    }
    if let Some(((lo, a), (hi, b))) = ends(&|r| r.dilution_entry) {
        s.push_str(&format!(
            ", and mean dilution entry from {lo:.0} t ({a}) to {hi:.0} t ({b})"
        ));
    }
    s.push('.');
    s
}

/// Reads a variant's `extraction` partitions back.
fn read_drawn(layout: &Layout, variant: &str, grade: &str) -> Result<Drawn> {
    let files = layout.partition_files("extraction", variant)?;
    let mut d = Drawn::default();
    for (file, period_dir) in files {
        let f = std::fs::File::open(&file).with_context(|| file.display().to_string())?;
        let reader = ParquetRecordBatchReaderBuilder::try_new(f)
            .and_then(|b| b.build())
            .with_context(|| file.display().to_string())?;
        for batch in reader {
            let batch = batch.with_context(|| file.display().to_string())?;
            let col = |name: &str| {
                batch
                    .column_by_name(name)
                    .with_context(|| format!("{}: no column {name}", file.display()))
            };
            let floats = |name: &str| -> Result<Vec<f64>> {
                let c = arrow::compute::cast(col(name)?, &DataType::Float64)?;
                let a = c.as_primitive::<Float64Type>();
                Ok((0..a.len())
                    .map(|i| if a.is_null(i) { f64::NAN } else { a.value(i) })
                    .collect())
            };
            let (tonnes, dilution, g) = (floats("tonnes")?, floats("dilution")?, floats(grade)?);
            let names = arrow::compute::cast(col("drawpoint")?, &DataType::Utf8)?;
            let names = names.as_string::<i32>();
            let periods: Vec<i64> = match period_dir {
                Some(p) => vec![p; batch.num_rows()],
                None => {
                    let c = arrow::compute::cast(col("period")?, &DataType::Int64)?;
                    c.as_primitive::<Int64Type>().values().to_vec()
                }
            };
            for i in 0..batch.num_rows() {
                let t = tonnes[i];
                if !(t > 0.0) {
                    continue;
                }
                let metal = if g[i].is_finite() { t * g[i] } else { 0.0 };
                let waste = if dilution[i].is_finite() {
                    t * dilution[i]
                } else {
                    0.0
                };
                let p = d.periods.entry(periods[i]).or_default();
                (p.0, p.1, p.2) = (p.0 + t, p.1 + metal, p.2 + waste);
                let q = d.drawpoints.entry(names.value(i).to_string()).or_default();
                (q.0, q.1) = (q.0 + t, q.1 + metal);
            }
        }
    }
    Ok(d)
}

/// Per variant, (grade–tonnage, recovery–dilution) curves, in %.
fn curves(rows: &[SummaryRow], drawn: &[Drawn]) -> (Vec<LineSeries>, Vec<LineSeries>) {
    let (mut gt, mut rd) = (Vec::new(), Vec::new());
    for (r, d) in rows.iter().zip(drawn) {
        // The footprint's in-situ metal, from the summary: metal drawn / recovery.
        let mean = r.grades.first().and_then(|g| g.1).unwrap_or(f64::NAN);
        let rec = r.recovery.first().and_then(|g| g.1).unwrap_or(f64::NAN);
        let in_situ = r.tonnes * mean / rec;
        let (mut cum, mut metal, mut waste) = (0.0, 0.0, 0.0);
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for &(t, m, w) in d.periods.values() {
            (cum, metal, waste) = (cum + t, metal + m, waste + w);
            a.push((cum, m / t));
            b.push((100.0 * waste / cum, 100.0 * metal / in_situ));
        }
        gt.push(LineSeries {
            name: r.variant.clone(),
            points: a,
        });
        rd.push(LineSeries {
            name: r.variant.clone(),
            points: b,
        });
    }
    (gt, rd)
}

/// Plan maps of each variant's mean grade per drawpoint less the first variant's.
fn differences(
    page: &mut Page,
    study: &Study,
    charts: &Path,
    rows: &[SummaryRow],
    drawn: &[Drawn],
    grade: &str,
) -> Result<()> {
    let base = study
        .variant(&rows[0].variant)
        .context("the first variant left the study")?
        .load()
        .map_err(|e| anyhow::anyhow!("{}", e.join("; ")))?;
    let dp = &base.scene.drawpoints;
    let mean = |d: &Drawn, name: &str| d.drawpoints.get(name).map_or(f64::NAN, |(t, m)| m / t);
    page.note(&format!(
        "Each drawpoint's mean {grade} grade over the run less the first variant's ({}); red: \
         higher, blue: lower, hollow: not drawn in one of the two. Drawpoints are placed as \
         in the first variant's layout.",
        rows[0].variant
    ));
    let mut maps = Vec::new();
    for (k, (r, d)) in rows.iter().zip(drawn).enumerate().skip(1) {
        let points: Vec<MapPoint> = (0..dp.len())
            .map(|i| MapPoint {
                x: dp.x[i],
                y: dp.y[i],
                value: mean(d, &dp.name[i]) - mean(&drawn[0], &dp.name[i]),
                label: dp.name[i].clone(),
            })
            .collect();
        let path = charts.join(format!("difference_{k}.svg"));
        plan_map_chart(
            &path,
            &points,
            &r.variant,
            &format!("Δ {grade} (%)"),
            MapScale::Diverging,
        )?;
        maps.push(path);
    }
    for pair in maps.chunks(2) {
        page.charts(&pair.iter().map(PathBuf::as_path).collect::<Vec<_>>())?;
    }
    Ok(())
}

/// The summary as a table: the swept values, then the results.
fn summary_table(page: &mut Page, study: &Study, rows: &[SummaryRow]) {
    let mut header: Vec<String> = vec!["variant".into()];
    header.extend(study.columns.iter().cloned());
    header.extend(
        [
            "tonnes",
            "scheduled",
            "mean grade",
            "recovery (%)",
            "dilution entry (t)",
            "short (%)",
            "run (s)",
        ]
        .map(String::from),
    );
    let opt = |v: Option<f64>, f: &dyn Fn(f64) -> String| v.map_or("–".into(), f);
    let table: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            let mut row = vec![r.variant.clone()];
            row.extend(r.values.iter().map(|(_, v)| match v {
                Swept::Number(x) => format!("{x}"),
                Swept::Text(t) => t.clone(),
            }));
            row.push(format!("{:.0}", r.tonnes));
            row.push(format!("{:.0}", r.scheduled_tonnes));
            row.push(opt(r.grades.first().and_then(|g| g.1), &num));
            row.push(opt(r.recovery.first().and_then(|g| g.1), &|x| {
                format!("{:.1}", 100.0 * x)
            }));
            row.push(opt(r.dilution_entry, &|x| format!("{x:.0}")));
            row.push(opt(r.short_share, &|x| format!("{:.1}", 100.0 * x)));
            row.push(format!("{:.1}", r.wall_s));
            row
        })
        .collect();
    page.table(
        &header.iter().map(String::as_str).collect::<Vec<_>>(),
        &table,
    );
}
