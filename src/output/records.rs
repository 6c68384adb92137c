//! Production records written back as a `production` table (schemas/production.json), as
//! Parquet or CSV by the file's extension. Used for the demo's synthetic records; what it
//! writes, [`load_records`](crate::model::load_records) reads back unchanged.

use std::path::Path;
use std::sync::Arc;

use arrow::array::{ArrayRef, Float64Array, Int64Array, StringArray};

use super::{write_parquet, AtomicFile, OutputError};
use crate::model::{Drawpoints, ProductionRecords};
use crate::schema::PRODUCTION;

/// The fixed columns written: `period` and `date` only when some record has one,
/// `frag_size` only when the records have it.
fn fixed_columns(r: &ProductionRecords) -> Vec<&'static str> {
    let mut fixed = vec!["drawpoint"];
    if r.period.iter().any(Option::is_some) {
        fixed.push("period");
    }
    if r.date.iter().any(Option::is_some) {
        fixed.push("date");
    }
    fixed.push("tonnes");
    if r.frag.is_some() {
        fixed.push("frag_size");
    }
    fixed
}

/// Writes production records atomically: Parquet for `.parquet`/`.pq`, CSV otherwise.
/// Columns: `drawpoint` (name), `period`, `date`, `tonnes`, `frag_size` (each only when
/// present), then one column per grade under its block-model name. A value not given (a
/// None period or date, a NaN grade or size: not sampled) is an empty CSV cell or a Parquet
/// null. Floats are written in Rust's shortest round-trip form, so the CSV reads back bit
/// for bit.
pub fn write_records(
    path: &Path,
    r: &ProductionRecords,
    drawpoints: &Drawpoints,
) -> Result<(), OutputError> {
    let fixed = fixed_columns(r);
    let name = |i: usize| drawpoints.name[r.drawpoint[i]].as_str();
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    if ext == "parquet" || ext == "pq" {
        let opt = |v: &[f64]| {
            Arc::new(
                v.iter()
                    .map(|&x| (!x.is_nan()).then_some(x))
                    .collect::<Float64Array>(),
            ) as ArrayRef
        };
        let mut columns: Vec<ArrayRef> = Vec::new();
        for c in &fixed {
            columns.push(match *c {
                "drawpoint" => Arc::new(StringArray::from_iter_values((0..r.len()).map(name))),
                "period" => Arc::new(r.period.iter().copied().collect::<Int64Array>()),
                "date" => Arc::new(r.date.iter().map(|d| d.as_deref()).collect::<StringArray>()),
                "tonnes" => Arc::new(Float64Array::from(r.tonnes.clone())),
                _ => opt(r.frag.as_deref().unwrap_or(&[])),
            });
        }
        columns.extend(r.grades.iter().map(|g| opt(g)));
        return write_parquet(
            path,
            PRODUCTION.arrow_schema(&fixed, &r.grade_names),
            columns,
        );
    }
    let csv_err = |source| OutputError::Csv {
        path: path.to_path_buf(),
        source,
    };
    let num = |x: f64| {
        if x.is_nan() {
            String::new()
        } else {
            format!("{x}")
        }
    };
    let mut out = csv::WriterBuilder::new()
        .has_headers(false)
        .from_writer(AtomicFile::create(path)?);
    let mut header: Vec<&str> = fixed.clone();
    header.extend(r.grade_names.iter().map(String::as_str));
    out.write_record(&header).map_err(csv_err)?;
    for i in 0..r.len() {
        let mut rec: Vec<String> = Vec::with_capacity(header.len());
        for c in &fixed {
            rec.push(match *c {
                "drawpoint" => name(i).to_string(),
                "period" => r.period[i].map(|p| p.to_string()).unwrap_or_default(),
                "date" => r.date[i].clone().unwrap_or_default(),
                "tonnes" => num(r.tonnes[i]),
                _ => num(r.frag.as_ref().map_or(f64::NAN, |f| f[i])),
            });
        }
        rec.extend(r.grades.iter().map(|g| num(g[i])));
        out.write_record(&rec).map_err(csv_err)?;
    }
    let file = out.into_inner().map_err(|e| OutputError::Io {
        path: path.to_path_buf(),
        source: e.into_error(),
    })?;
    file.commit()
}
