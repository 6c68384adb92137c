//! Reconciliation: predicted drawpoint grades against sampled production records (summary
//! §8, DESIGN §6).
//!
//! The thesis matched REBOP's predictions to Henderson's sampled grades drawpoint by
//! drawpoint, by eye. Here polars does it for every drawpoint and period at once, lazily:
//!
//! 1. **Match.** Records that name a period are matched to the prediction for the same
//!    drawpoint and period. Records that only carry a date the run cannot place are matched
//!    by cumulative tonnes instead: each record's mid-point cumulative tonnage (its own
//!    drawpoint's records in date order) is joined *as of* the predictions' cumulative
//!    tonnes (the first period whose cumulative draw reaches it). Several records falling in
//!    one drawpoint-period are merged: tonnes summed, grades tonnage-weighted over the
//!    records that sampled them.
//! 2. **Compare.** For each grade g, each matched row gives the error e = ĝ − g (predicted
//!    minus sampled, % by mass). Per drawpoint, per zone (the drawpoints table's `zone`) and
//!    overall:
//!    - n, the rows compared;
//!    - bias = mean e; MAE = mean |e|; RMSE = √(mean e²);
//!    - correlation: Pearson's r between ĝ and g;
//!    - tonnage-weighted error = Σ t e / Σ t with t the sampled tonnes: the metal the model
//!      over- (or under-) calls per tonne produced;
//!    - dilution entry: for the grade named in `[dilution]`, the cumulative tonnes at which a
//!      drawpoint's grade first falls below the cutoff, predicted and sampled, and their
//!      difference (predicted − sampled, t; negative: the model dilutes too early). Zones and
//!      the overall row give the mean over the drawpoints where both are known.
//!
//! The result is two frames: the matched rows (one per drawpoint, period and grade) and the
//! metrics (one per level, key and grade), written by [`write_reconciliation`].

use std::path::Path;

use polars::prelude::*;

use crate::engine::result::Extraction;
use crate::model::records::ProductionRecords;
use crate::model::{Drawpoints, Scene};
use crate::output::columns::{f64s_or_null, i64s, strs, write_table};
use crate::output::OutputError;
use crate::schema::{RECONCILE_METRICS, RECONCILE_ROWS};

/// Why reconcile failed.
#[derive(Debug, thiserror::Error)]
pub enum ReconcileError {
    /// A frame operation failed (a column missing or of the wrong type).
    #[error("reconcile: {0}")]
    Frame(#[from] PolarsError),
    /// Writing a table failed.
    #[error(transparent)]
    Output(#[from] OutputError),
    /// Drawing a chart failed.
    #[error(transparent)]
    Chart(#[from] crate::output::charts::ChartError),
    /// A chart could not be read back to embed in the report.
    #[error(transparent)]
    Embed(#[from] crate::output::report::EmbedError),
    /// Writing the report failed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: std::path::PathBuf,
        /// Cause.
        source: std::io::Error,
    },
}

/// Suffix of a sampled grade column once records and predictions are joined.
const SAMPLED: &str = "_sampled";

/// What to compare.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// Grade columns compared (present in both predictions and records).
    pub grades: Vec<String>,
    /// Grade and cutoff (%) of the dilution entry, when set.
    pub dilution: Option<(String, f64)>,
}

/// The inputs, as frames.
///
/// - `predicted`: `drawpoint` (str), `period` (i64), `tonnes`, `cum_tonnes` (t), and one
///   column per grade (null where nothing was drawn).
/// - `records`: `drawpoint` (str), `period` (i64, null: match by cumulative tonnes), `seq`
///   (i64, order of a drawpoint's records, e.g. by date), `tonnes` (t), and one column per
///   sampled grade (null: not sampled).
/// - `drawpoints`: `drawpoint` (str), `zone` (str), `x`, `y` (m).
#[derive(Debug, Clone)]
pub struct Frames {
    /// Predictions per drawpoint and period.
    pub predicted: DataFrame,
    /// Production records.
    pub records: DataFrame,
    /// Drawpoint attributes.
    pub drawpoints: DataFrame,
}

/// Matched rows and metrics.
#[derive(Debug, Clone)]
pub struct Reconciliation {
    /// One row per drawpoint, period and grade: `drawpoint`, `zone`, `x`, `y`, `period`,
    /// `cum_tonnes`, `predicted_tonnes`, `sampled_tonnes`, `grade`, `predicted`, `sampled`,
    /// `error`.
    pub rows: DataFrame,
    /// One row per level (`drawpoint`, `zone`, `overall`), key and grade: `level`, `key`,
    /// `grade`, `n`, `bias`, `mae`, `rmse`, `correlation`, `tw_error`, `mean_predicted`,
    /// `mean_sampled`, `sampled_tonnes`, `de_predicted`, `de_sampled`, `de_difference`.
    pub metrics: DataFrame,
}

impl Reconciliation {
    /// The metrics row of one level, key and grade.
    pub fn metric(&self, level: &str, key: &str, grade: &str, name: &str) -> Option<f64> {
        let m = self
            .metrics
            .clone()
            .lazy()
            .filter(
                col("level")
                    .eq(lit(level))
                    .and(col("key").eq(lit(key)))
                    .and(col("grade").eq(lit(grade))),
            )
            .select([col(name).cast(DataType::Float64)])
            .collect()
            .ok()?;
        m.column(name).ok()?.f64().ok()?.get(0)
    }

    /// Overall RMSE of a grade (NaN when nothing matched).
    pub fn overall_rmse(&self, grade: &str) -> f64 {
        self.metric("overall", "all", grade, "rmse")
            .unwrap_or(f64::NAN)
    }
}

/// Predictions of a run held in memory, as the `predicted` frame.
pub fn predicted_frame(ext: &Extraction, scene: &Scene) -> PolarsResult<DataFrame> {
    let names: Vec<&str> = ext
        .drawpoint
        .iter()
        .map(|&d| scene.drawpoints.name[d as usize].as_str())
        .collect();
    let mut columns = vec![
        Column::new("drawpoint".into(), names),
        Column::new("period".into(), ext.period.clone()),
        Column::new("tonnes".into(), ext.tonnes.clone()),
        Column::new("cum_tonnes".into(), ext.cum_tonnes.clone()),
    ];
    for (g, name) in scene.blocks.grade_names.iter().enumerate() {
        let v: Vec<Option<f64>> = ext.grades[g]
            .iter()
            .map(|&x| x.is_finite().then_some(x))
            .collect();
        columns.push(Column::new(name.as_str().into(), v));
    }
    DataFrame::new_infer_height(columns)
}

/// Reads a run's `extraction.parquet` as the `predicted` frame.
pub fn read_predicted(path: &Path, grades: &[String]) -> PolarsResult<DataFrame> {
    predicted_of(read_parquet_frame(path)?, grades)
}

/// A Parquet file as a frame.
pub fn read_parquet_frame(path: &Path) -> PolarsResult<DataFrame> {
    let file = std::fs::File::open(path)
        .map_err(|e| PolarsError::ComputeError(format!("{}: {e}", path.display()).into()))?;
    ParquetReader::new(file).finish()
}

/// The `predicted` frame's columns of an extraction table (as `extraction_batch` writes
/// it): drawpoint, period, tonnes, cum_tonnes and `grades`.
pub fn predicted_of(extraction: DataFrame, grades: &[String]) -> PolarsResult<DataFrame> {
    let mut keep = vec![
        col("drawpoint"),
        col("period"),
        col("tonnes"),
        col("cum_tonnes"),
    ];
    keep.extend(grades.iter().map(|g| col(g.as_str())));
    extraction.lazy().select(keep).collect()
}

/// The `drawpoints` frame.
pub fn drawpoints_frame(dp: &Drawpoints) -> PolarsResult<DataFrame> {
    DataFrame::new_infer_height(vec![
        Column::new("drawpoint".into(), dp.name.clone()),
        Column::new("zone".into(), dp.zone.clone()),
        Column::new("x".into(), dp.x.clone()),
        Column::new("y".into(), dp.y.clone()),
    ])
}

/// Production records as the `records` frame: `seq` orders each drawpoint's records by
/// date (then by row), for matching by cumulative tonnes; unsampled grades become null.
pub fn records_frame(r: &ProductionRecords, dp: &Drawpoints) -> PolarsResult<DataFrame> {
    let n = r.tonnes.len();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| r.date[a].cmp(&r.date[b]).then(a.cmp(&b)));
    let mut seq = vec![0i64; n];
    for (k, &i) in order.iter().enumerate() {
        seq[i] = k as i64;
    }
    let mut columns = vec![
        Column::new(
            "drawpoint".into(),
            r.drawpoint
                .iter()
                .map(|&d| dp.name[d].as_str())
                .collect::<Vec<_>>(),
        ),
        Column::new("period".into(), r.period.clone()),
        Column::new("seq".into(), seq),
        Column::new("tonnes".into(), r.tonnes.clone()),
    ];
    for (name, values) in r.grade_names.iter().zip(&r.grades) {
        let v: Vec<Option<f64>> = values.iter().map(|&x| x.is_finite().then_some(x)).collect();
        columns.push(Column::new(name.as_str().into(), v));
    }
    DataFrame::new_infer_height(columns)
}

/// Matches records to predictions and computes the metrics (see the module docs).
pub fn reconcile(f: &Frames, s: &Settings) -> PolarsResult<Reconciliation> {
    let sampled = |g: &String| format!("{g}{SAMPLED}");
    // Records, sampled grades renamed so they survive the join beside the predictions.
    let mut rec_cols = vec![col("drawpoint"), col("period"), col("seq"), col("tonnes")];
    rec_cols.extend(s.grades.iter().map(|g| col(g.as_str()).alias(sampled(g))));
    let records = f.records.clone().lazy().select(rec_cols);
    let keep: Vec<Expr> = ["drawpoint", "period", "tonnes"]
        .iter()
        .map(|c| col(*c))
        .chain(s.grades.iter().map(|g| col(sampled(g))))
        .collect();

    // Records without a period: matched as of the predicted cumulative tonnes.
    let by_tonnes = records
        .clone()
        .filter(col("period").is_null())
        .sort(["drawpoint", "seq"], SortMultipleOptions::default())
        .with_column(
            (col("tonnes").cum_sum(false).over([col("drawpoint")])? - col("tonnes") * lit(0.5))
                .alias("mid_tonnes"),
        )
        .sort(["mid_tonnes"], SortMultipleOptions::default())
        .select(
            ["drawpoint", "seq", "tonnes", "mid_tonnes"]
                .map(col)
                .into_iter()
                .chain(s.grades.iter().map(|g| col(sampled(g))))
                .collect::<Vec<_>>(),
        )
        .join_builder()
        .with(
            f.predicted
                .clone()
                .lazy()
                .select([col("drawpoint"), col("period"), col("cum_tonnes")])
                .sort(["cum_tonnes"], SortMultipleOptions::default()),
        )
        .left_on([col("mid_tonnes")])
        .right_on([col("cum_tonnes")])
        .how(JoinType::AsOf(Box::new(AsOfOptions {
            strategy: AsofStrategy::Forward,
            left_by: Some(vec!["drawpoint".into()]),
            right_by: Some(vec!["drawpoint".into()]),
            allow_eq: true,
            check_sortedness: false,
            ..Default::default()
        })))
        .finish()
        .filter(col("period").is_not_null())
        .select(keep.clone());
    let by_period = records.filter(col("period").is_not_null()).select(keep);

    // One row per drawpoint-period: tonnes summed, grades weighted by the tonnes sampled.
    let mut agg = vec![col("tonnes").sum().alias("sampled_tonnes")];
    for g in &s.grades {
        let gs = sampled(g);
        let has = col(gs.as_str()).is_not_null();
        agg.push(
            ((col("tonnes") * col(gs.as_str())).sum() / col("tonnes").filter(has.clone()).sum())
                .alias(gs.as_str()),
        );
    }
    let matched = concat([by_period, by_tonnes], UnionArgs::default())?
        .group_by([col("drawpoint"), col("period")])
        .agg(agg);

    let joined = f
        .predicted
        .clone()
        .lazy()
        .join(
            matched,
            [col("drawpoint"), col("period")],
            [col("drawpoint"), col("period")],
            JoinArgs::new(JoinType::Inner),
        )
        .join(
            f.drawpoints.clone().lazy(),
            [col("drawpoint")],
            [col("drawpoint")],
            JoinArgs::new(JoinType::Left),
        );

    let per_grade: Vec<LazyFrame> = s
        .grades
        .iter()
        .map(|g| {
            joined
                .clone()
                .select([
                    col("drawpoint"),
                    col("zone").fill_null(lit("")),
                    col("x"),
                    col("y"),
                    col("period"),
                    col("cum_tonnes"),
                    col("tonnes").alias("predicted_tonnes"),
                    col("sampled_tonnes"),
                    lit(g.as_str()).alias("grade"),
                    col(g.as_str()).cast(DataType::Float64).alias("predicted"),
                    col(sampled(g)).alias("sampled"),
                ])
                .filter(
                    col("predicted")
                        .is_not_null()
                        .and(col("sampled").is_not_null())
                        .and(col("sampled").is_finite()),
                )
        })
        .collect();
    let rows = concat(per_grade, UnionArgs::default())?
        .with_column((col("predicted") - col("sampled")).alias("error"))
        .sort(
            ["grade", "drawpoint", "period"],
            SortMultipleOptions::default(),
        )
        .collect()?;

    let metrics = metrics(&rows, s)?;
    Ok(Reconciliation { rows, metrics })
}

/// The error statistics of one group of matched rows.
fn stats() -> Vec<Expr> {
    let e = || col("error");
    vec![
        len().cast(DataType::Int64).alias("n"),
        e().mean().alias("bias"),
        e().abs().mean().alias("mae"),
        (e() * e()).mean().sqrt().alias("rmse"),
        pearson_corr(col("predicted"), col("sampled")).alias("correlation"),
        ((col("sampled_tonnes") * e()).sum() / col("sampled_tonnes").sum()).alias("tw_error"),
        col("predicted").mean().alias("mean_predicted"),
        col("sampled").mean().alias("mean_sampled"),
        col("sampled_tonnes").sum().alias("sampled_tonnes"),
    ]
}

/// Per drawpoint, per zone and overall metrics of the matched rows.
fn metrics(rows: &DataFrame, s: &Settings) -> PolarsResult<DataFrame> {
    let rows = rows.clone().lazy();
    // Dilution entry per drawpoint: the first cumulative tonnes below the cutoff.
    let (de_grade, cutoff) = s
        .dilution
        .clone()
        .unwrap_or_else(|| (String::new(), f64::NAN));
    let entry = |c: &str| {
        col("cum_tonnes")
            .filter(
                col("grade")
                    .eq(lit(de_grade.as_str()))
                    .and(col(c).lt(lit(cutoff))),
            )
            .min()
    };
    let mut per_dp = stats();
    per_dp.push(entry("predicted").alias("de_predicted"));
    per_dp.push(entry("sampled").alias("de_sampled"));
    let drawpoint = rows
        .clone()
        .group_by([col("grade"), col("drawpoint"), col("zone")])
        .agg(per_dp)
        .with_column((col("de_predicted") - col("de_sampled")).alias("de_difference"));

    // Zones and overall: statistics over their rows; dilution entry averaged over the
    // drawpoints where both are known.
    let de_means = |by: Vec<Expr>| {
        drawpoint
            .clone()
            .filter(col("de_difference").is_not_null())
            .group_by(by)
            .agg([
                col("de_predicted").mean(),
                col("de_sampled").mean(),
                col("de_difference").mean(),
            ])
    };
    let zone = rows
        .clone()
        .group_by([col("grade"), col("zone")])
        .agg(stats())
        .join(
            de_means(vec![col("grade"), col("zone")]),
            [col("grade"), col("zone")],
            [col("grade"), col("zone")],
            JoinArgs::new(JoinType::Left),
        );
    let overall = rows.group_by([col("grade")]).agg(stats()).join(
        de_means(vec![col("grade")]),
        [col("grade")],
        [col("grade")],
        JoinArgs::new(JoinType::Left),
    );

    let order = |level: &str, key: Expr| {
        let mut c = vec![lit(level).alias("level"), key.alias("key"), col("grade")];
        c.extend(
            [
                "n",
                "bias",
                "mae",
                "rmse",
                "correlation",
                "tw_error",
                "mean_predicted",
                "mean_sampled",
                "sampled_tonnes",
                "de_predicted",
                "de_sampled",
                "de_difference",
            ]
            .map(col),
        );
        c
    };
    concat(
        [
            overall.select(order("overall", lit("all"))),
            zone.select(order("zone", col("zone"))),
            drawpoint.select(order("drawpoint", col("drawpoint"))),
        ],
        UnionArgs::default(),
    )?
    .collect()
}

fn f64_col(df: &DataFrame, name: &str) -> PolarsResult<Vec<f64>> {
    Ok(df
        .column(name)?
        .cast(&DataType::Float64)?
        .f64()?
        .iter()
        .map(|v| v.unwrap_or(f64::NAN))
        .collect())
}

fn str_col(df: &DataFrame, name: &str) -> PolarsResult<Vec<String>> {
    Ok(df
        .column(name)?
        .str()?
        .iter()
        .map(|v| v.unwrap_or("").to_string())
        .collect())
}

fn i64_col(df: &DataFrame, name: &str) -> PolarsResult<Vec<i64>> {
    Ok(df
        .column(name)?
        .cast(&DataType::Int64)?
        .i64()?
        .iter()
        .map(|v| v.unwrap_or(0))
        .collect())
}

/// A column as plain values: f64 (null → NaN).
pub fn floats(df: &DataFrame, name: &str) -> Vec<f64> {
    f64_col(df, name).unwrap_or_default()
}

/// A column as plain values: strings (null → "").
pub fn strings(df: &DataFrame, name: &str) -> Vec<String> {
    str_col(df, name).unwrap_or_default()
}

/// Writes `reconcile_rows.parquet` and `reconcile.parquet` (schemas `reconcile_rows` and
/// `reconcile`) into `dir`, atomically.
pub fn write_reconciliation(dir: &Path, r: &Reconciliation) -> Result<(), ReconcileError> {
    let frame = ReconcileError::Frame;
    let m = &r.metrics;
    let fl = |df: &DataFrame, c: &str| f64_col(df, c).map(f64s_or_null).map_err(frame);
    let st = |df: &DataFrame, c: &str| str_col(df, c).map(strs).map_err(frame);
    let it = |df: &DataFrame, c: &str| i64_col(df, c).map(i64s).map_err(frame);
    write_table(
        &dir.join("reconcile.parquet"),
        &RECONCILE_METRICS,
        vec![
            ("level", st(m, "level")?),
            ("key", st(m, "key")?),
            ("grade", st(m, "grade")?),
            ("n", it(m, "n")?),
            ("bias", fl(m, "bias")?),
            ("mae", fl(m, "mae")?),
            ("rmse", fl(m, "rmse")?),
            ("correlation", fl(m, "correlation")?),
            ("tw_error", fl(m, "tw_error")?),
            ("mean_predicted", fl(m, "mean_predicted")?),
            ("mean_sampled", fl(m, "mean_sampled")?),
            ("sampled_tonnes", fl(m, "sampled_tonnes")?),
            ("de_predicted", fl(m, "de_predicted")?),
            ("de_sampled", fl(m, "de_sampled")?),
            ("de_difference", fl(m, "de_difference")?),
        ],
        Vec::new(),
    )?;
    let w = &r.rows;
    write_table(
        &dir.join("reconcile_rows.parquet"),
        &RECONCILE_ROWS,
        vec![
            ("drawpoint", st(w, "drawpoint")?),
            ("zone", st(w, "zone")?),
            ("x", fl(w, "x")?),
            ("y", fl(w, "y")?),
            ("period", it(w, "period")?),
            ("cum_tonnes", fl(w, "cum_tonnes")?),
            ("predicted_tonnes", fl(w, "predicted_tonnes")?),
            ("sampled_tonnes", fl(w, "sampled_tonnes")?),
            ("grade", st(w, "grade")?),
            ("predicted", fl(w, "predicted")?),
            ("sampled", fl(w, "sampled")?),
            ("error", fl(w, "error")?),
        ],
        Vec::new(),
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two drawpoints in two zones, three periods; errors chosen by hand.
    fn frames() -> Frames {
        let predicted = polars::df!(
            "drawpoint" => ["A", "A", "A", "B", "B", "B"],
            "period" => [1i64, 2, 3, 1, 2, 3],
            "tonnes" => [100.0, 100.0, 100.0, 200.0, 200.0, 200.0],
            "cum_tonnes" => [100.0, 200.0, 300.0, 200.0, 400.0, 600.0],
            "mo" => [Some(0.30), Some(0.20), Some(0.05), Some(0.40), Some(0.30), None],
        )
        .unwrap();
        // A: sampled by period. B: dated records only (period null), two in period 1 (at
        // mid-tonnes 50 and 150, both ≤ 200), one in period 2 (mid 300).
        let records = polars::df!(
            "drawpoint" => ["A", "A", "A", "B", "B", "B"],
            "period" => [Some(1i64), Some(2), Some(3), None, None, None],
            "seq" => [1i64, 2, 3, 1, 2, 3],
            "tonnes" => [100.0, 100.0, 100.0, 100.0, 100.0, 200.0],
            "mo" => [Some(0.28), Some(0.25), Some(0.15), Some(0.30), Some(0.40), Some(0.32)],
        )
        .unwrap();
        let drawpoints = polars::df!(
            "drawpoint" => ["A", "B"],
            "zone" => ["north", "south"],
            "x" => [0.0, 10.0],
            "y" => [0.0, 0.0],
        )
        .unwrap();
        Frames {
            predicted,
            records,
            drawpoints,
        }
    }

    #[test]
    fn metrics_match_hand_computation() {
        let s = Settings {
            grades: vec!["mo".into()],
            dilution: Some(("mo".into(), 0.1)),
        };
        let r = reconcile(&frames(), &s).unwrap();
        let m = |level, key, name| r.metric(level, key, "mo", name).unwrap();
        // A: errors 0.02, −0.05, −0.10.
        let ea = [0.02, -0.05, -0.10];
        assert_eq!(m("drawpoint", "A", "n"), 3.0);
        assert!((m("drawpoint", "A", "bias") - (-0.13 / 3.0)).abs() < 1e-12);
        assert!((m("drawpoint", "A", "mae") - 0.17 / 3.0).abs() < 1e-12);
        let rmse_a = (ea.iter().map(|e| e * e).sum::<f64>() / 3.0).sqrt();
        assert!((m("drawpoint", "A", "rmse") - rmse_a).abs() < 1e-12);
        // B period 1: (100 × 0.30 + 100 × 0.40) / 200 = 0.35 against 0.40: +0.05;
        // period 2: 0.32 against 0.30: −0.02; period 3: nothing predicted (idle), left out.
        assert_eq!(m("drawpoint", "B", "n"), 2.0);
        assert!((m("drawpoint", "B", "bias") - 0.015).abs() < 1e-12);
        // Tonnage weights of B: 200 and 200.
        assert!((m("drawpoint", "B", "tw_error") - 0.015).abs() < 1e-12);
        // Overall over all five rows; tonnage-weighted with A's 100s and B's 200s.
        let all = [0.02, -0.05, -0.10, 0.05, -0.02];
        assert_eq!(m("overall", "all", "n"), 5.0);
        assert!((m("overall", "all", "bias") - all.iter().sum::<f64>() / 5.0).abs() < 1e-12);
        let tw = (100.0 * (0.02 - 0.05 - 0.10) + 200.0 * (0.05 - 0.02)) / 700.0;
        assert!((m("overall", "all", "tw_error") - tw).abs() < 1e-12);
        // Pearson r of A: predicted (0.30, 0.20, 0.05) against sampled (0.28, 0.25, 0.15).
        let (p, q) = ([0.30, 0.20, 0.05], [0.28, 0.25, 0.15]);
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        let (mp, mq) = (mean(&p), mean(&q));
        let cov: f64 = p.iter().zip(&q).map(|(a, b)| (a - mp) * (b - mq)).sum();
        let sp: f64 = p.iter().map(|a| (a - mp).powi(2)).sum::<f64>().sqrt();
        let sq: f64 = q.iter().map(|b| (b - mq).powi(2)).sum::<f64>().sqrt();
        assert!((m("drawpoint", "A", "correlation") - cov / (sp * sq)).abs() < 1e-12);
        // Dilution entry of A: predicted falls below 0.1 at 300 t; sampled never does.
        assert_eq!(m("drawpoint", "A", "de_predicted"), 300.0);
        assert!(r.metric("drawpoint", "A", "mo", "de_sampled").is_none());
        // Zone rows: north is A alone.
        assert!((m("zone", "north", "rmse") - rmse_a).abs() < 1e-12);
    }
}
