//! One row per variant (`summary.parquet`, `schemas/study_summary.json`): what it drew,
//! at what grade, how much of the footprint's metal, when dilution entered, how often
//! drawpoints fell short, and how long it ran.

use std::path::Path;
use std::sync::Arc;

use arrow::array::{ArrayRef, Float64Array, Int64Array, StringArray};
use arrow::datatypes::Schema;
use arrow::record_batch::RecordBatch;
use serde::{Deserialize, Serialize};

use super::plan::Swept;
use crate::engine::result::RunOutput;
use crate::model::Scene;
use crate::output::dilution::dilution_entries;
use crate::output::{write_batch, OutputError};
use crate::schema::{arrow_field, Kind, STUDY_SUMMARY};

/// A variant's summary row (kept as `summary.json` beside its `_SUCCESS`, so that the
/// summary of a resumed study needs no variant run again). NaN is `None`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SummaryRow {
    /// Variant name.
    pub variant: String,
    /// Content hash.
    pub hash: String,
    /// Seed.
    pub seed: u64,
    /// Swept values (column → value), in the study's dimension order.
    pub values: Vec<(String, Swept)>,
    /// Credited tonnes over the run, t.
    pub tonnes: f64,
    /// Scheduled tonnes, t.
    pub scheduled_tonnes: f64,
    /// Tonnage-weighted mean grade of everything drawn, per grade (name, %).
    pub grades: Vec<(String, Option<f64>)>,
    /// Metal drawn over metal in situ in the [`footprint`], per grade (name, -). Simple
    /// and honest about what it is: what was drawn from beyond the footprint (the sides,
    /// broken material above) counts as drawn, so it can exceed 1 (the demo: 1.03 at a
    /// Urad factor of 0.65).
    pub recovery: Vec<(String, Option<f64>)>,
    /// In-situ tonnes of the footprint's blocks, t.
    pub footprint_tonnes: f64,
    /// Mean over the drawpoints whose waste share reaches 10 % of the cumulative tonnes at
    /// which it does (`analysis::sweep`'s dilution entry), t.
    pub dilution_entry: Option<f64>,
    /// Drawpoints whose waste share reached 10 %.
    pub diluted_drawpoints: u64,
    /// Share of the scheduled drawpoint-periods (not idle) that were short.
    pub short_share: Option<f64>,
    /// The draw's value (`[economics]`, `engine::value`); None without economics.
    #[serde(default)]
    pub value: Option<f64>,
    /// Drawpoints closed by draw control's closure rules; None without draw control.
    #[serde(default)]
    pub closed_drawpoints: Option<u64>,
    /// Periods run.
    pub periods: u64,
    /// Wall time of the engine run, s.
    pub wall_s: f64,
}

fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

/// The footprint: the block columns whose centre lies within s/√2 of a drawpoint axis, s
/// the median distance between neighbouring drawpoints (the circle around a drawpoint
/// that holds its square of a regular layout); with one drawpoint, its opening width.
/// Blocks from the lowest drawpoint's elevation up. Returns, per block, whether it is in.
pub fn footprint(scene: &Scene) -> Vec<bool> {
    let d = &scene.drawpoints;
    let n = d.len();
    let mut nearest: Vec<f64> = (0..n)
        .map(|i| {
            (0..n)
                .filter(|&j| j != i)
                .map(|j| (d.x[i] - d.x[j]).hypot(d.y[i] - d.y[j]))
                .fold(f64::INFINITY, f64::min)
        })
        .filter(|x| x.is_finite())
        .collect();
    nearest.sort_by(f64::total_cmp);
    let r = match nearest.get(nearest.len() / 2) {
        Some(s) => s / std::f64::consts::SQRT_2,
        None => d.width.first().copied().unwrap_or(0.0),
    };
    let floor = d.z.iter().copied().fold(f64::INFINITY, f64::min) - 0.5 * scene.blocks.size[2];
    let b = &scene.blocks;
    (0..b.len())
        .map(|k| b.z[k] >= floor && (0..n).any(|i| (b.x[k] - d.x[i]).hypot(b.y[k] - d.y[i]) <= r))
        .collect()
}

impl SummaryRow {
    /// The row of a finished run. `values` and the identity come from the plan.
    pub fn new(
        variant: &str,
        hash: &str,
        seed: u64,
        values: Vec<(String, Swept)>,
        scene: &Scene,
        out: &RunOutput,
        wall_s: f64,
    ) -> SummaryRow {
        let e = &out.extraction;
        let tonnes: f64 = e.tonnes.iter().sum();
        let b = &scene.blocks;
        let inside = footprint(scene);
        let vol: f64 = b.size.iter().product();
        let insitu = |k: usize| vol * b.density[k] * (1.0 - b.n0[k]);
        let footprint_tonnes: f64 = (0..b.len()).filter(|&k| inside[k]).map(insitu).sum();
        let mut grades = Vec::new();
        let mut recovery = Vec::new();
        for (g, name) in b.grade_names.iter().enumerate() {
            let (metal, t) = e.grade_metal(g);
            let in_situ: f64 = (0..b.len())
                .filter(|&k| inside[k] && b.grades[g][k].is_finite())
                .map(|k| insitu(k) * b.grades[g][k])
                .sum();
            grades.push((name.clone(), finite(metal / t)));
            recovery.push((name.clone(), finite(metal / in_situ)));
        }
        let entries: Vec<f64> = dilution_entries(out, scene.drawpoints.len())
            .into_iter()
            .filter(|x| x.is_finite())
            .collect();
        let scheduled = e.status.iter().filter(|&&s| s != "idle").count();
        let short = e.status.iter().filter(|&&s| s == "short").count();
        SummaryRow {
            variant: variant.to_string(),
            hash: hash.to_string(),
            seed,
            values,
            tonnes,
            scheduled_tonnes: e.scheduled_tonnes.iter().sum(),
            grades,
            recovery,
            footprint_tonnes,
            dilution_entry: finite(entries.iter().sum::<f64>() / entries.len() as f64),
            diluted_drawpoints: entries.len() as u64,
            short_share: finite(short as f64 / scheduled as f64),
            value: out.value.as_ref().map(|(_, b)| b.final_value.iter().sum()),
            closed_drawpoints: out
                .control
                .as_ref()
                .map(|c| c.closures.drawpoint.len() as u64),
            periods: scene.periods.len() as u64,
            wall_s,
        }
    }
}

/// Writes `summary.parquet` (atomically): the fixed columns of
/// [`crate::schema::STUDY_SUMMARY`], then one column per swept dimension
/// (`columns`: Float64 when every value is a number, else Utf8), then the mean grade and
/// the recovery of each grade of the first row's block model.
pub fn write_summary(
    path: &Path,
    columns: &[String],
    rows: &[SummaryRow],
) -> Result<(), OutputError> {
    let f = |g: &dyn Fn(&SummaryRow) -> Option<f64>| -> ArrayRef {
        Arc::new(Float64Array::from(rows.iter().map(g).collect::<Vec<_>>()))
    };
    let i = |g: &dyn Fn(&SummaryRow) -> i64| -> ArrayRef {
        Arc::new(Int64Array::from(rows.iter().map(g).collect::<Vec<_>>()))
    };
    let s = |g: &dyn Fn(&SummaryRow) -> String| -> ArrayRef {
        Arc::new(StringArray::from(rows.iter().map(g).collect::<Vec<_>>()))
    };
    let fixed: Vec<(&str, ArrayRef)> = vec![
        ("variant", s(&|r| r.variant.clone())),
        ("hash", s(&|r| r.hash.clone())),
        ("seed", i(&|r| r.seed as i64)),
        ("tonnes", f(&|r| Some(r.tonnes))),
        ("scheduled_tonnes", f(&|r| Some(r.scheduled_tonnes))),
        ("footprint_tonnes", f(&|r| Some(r.footprint_tonnes))),
        ("dilution_entry", f(&|r| r.dilution_entry)),
        ("diluted_drawpoints", i(&|r| r.diluted_drawpoints as i64)),
        ("short_share", f(&|r| r.short_share)),
        ("value", f(&|r| r.value)),
        (
            "closed_drawpoints",
            Arc::new(Int64Array::from(
                rows.iter()
                    .map(|r| r.closed_drawpoints.map(|n| n as i64))
                    .collect::<Vec<_>>(),
            )),
        ),
        ("periods", i(&|r| r.periods as i64)),
        ("wall_s", f(&|r| Some(r.wall_s))),
    ];
    let (names, mut arrays): (Vec<&str>, Vec<ArrayRef>) = fixed.into_iter().unzip();
    let mut fields: Vec<_> = STUDY_SUMMARY
        .arrow_schema(&names, &[])
        .fields()
        .iter()
        .map(|f| f.as_ref().clone())
        .collect();
    let value = |r: &SummaryRow, c: &str| {
        r.values
            .iter()
            .find(|(k, _)| k == c)
            .map(|(_, v)| v.clone())
    };
    for c in columns {
        let numeric = rows
            .iter()
            .all(|r| matches!(value(r, c), Some(Swept::Number(_)) | None));
        if numeric {
            arrays.push(f(&|r| match value(r, c) {
                Some(Swept::Number(x)) => Some(x),
                _ => None,
            }));
            fields.push(arrow_field(
                c,
                Kind::F64,
                "-",
                "Swept value of this grid key",
                true,
            ));
        } else {
            arrays.push(Arc::new(StringArray::from(
                rows.iter()
                    .map(|r| match value(r, c) {
                        Some(Swept::Text(t)) => Some(t),
                        Some(Swept::Number(x)) => Some(x.to_string()),
                        None => None,
                    })
                    .collect::<Vec<_>>(),
            )));
            fields.push(arrow_field(
                c,
                Kind::Str,
                "-",
                "Swept value (grid value as text, or the alternative's name)",
                true,
            ));
        }
    }
    let grade_names: Vec<String> = rows
        .first()
        .map(|r| r.grades.iter().map(|(n, _)| n.clone()).collect())
        .unwrap_or_default();
    let pick =
        |v: &[(String, Option<f64>)], n: &str| v.iter().find(|(k, _)| k == n).and_then(|(_, x)| *x);
    for n in &grade_names {
        arrays.push(f(&|r| pick(&r.grades, n)));
        fields.push(arrow_field(
            n,
            Kind::F64,
            "%",
            "Tonnage-weighted mean grade of everything drawn",
            true,
        ));
    }
    for n in &grade_names {
        arrays.push(f(&|r| pick(&r.recovery, n)));
        fields.push(arrow_field(
            &format!("recovery_{n}"),
            Kind::F64,
            "-",
            "Metal drawn over metal in situ in the footprint (analysis::study::summary::footprint)",
            true,
        ));
    }
    let schema = STUDY_SUMMARY.arrow_schema(&[], &[]);
    let schema = Arc::new(Schema::new(fields).with_metadata(schema.metadata().clone()));
    let batch = RecordBatch::try_new(schema, arrays).map_err(|source| OutputError::Arrow {
        path: path.to_path_buf(),
        source,
    })?;
    write_batch(path, &batch)
}
