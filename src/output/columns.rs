//! Arrow columns from the engine's `Vec` columns, and one table written from named
//! columns under its schema (`crate::schema`). Every table writer of `output` and
//! `analysis` builds its tables with these.

use std::path::Path;
use std::sync::Arc;

use arrow::array::{ArrayRef, Float64Array, Int64Array, StringArray};
use arrow::error::ArrowError;
use arrow::record_batch::RecordBatch;

use super::parquet::write_batch;
use super::OutputError;
use crate::engine::result::MarkerState;
use crate::schema::TableSpec;

/// Float column.
pub(crate) fn f64s(v: Vec<f64>) -> ArrayRef {
    Arc::new(Float64Array::from(v))
}

/// Float column where NaN (no marker drawn, so no value) is written as null.
pub(crate) fn f64s_or_null(v: Vec<f64>) -> ArrayRef {
    Arc::new(Float64Array::from_iter(
        v.into_iter().map(|x| (!x.is_nan()).then_some(x)),
    ))
}

/// String column (the analysis layer's tables).
#[cfg(feature = "analysis")]
pub(crate) fn strs(v: Vec<String>) -> ArrayRef {
    Arc::new(StringArray::from(v))
}

/// Integer column.
pub(crate) fn i64s(v: Vec<i64>) -> ArrayRef {
    Arc::new(Int64Array::from(v))
}

/// Marker states as their names (`MarkerState::name`).
pub(crate) fn states(v: &[MarkerState]) -> ArrayRef {
    Arc::new(StringArray::from_iter_values(v.iter().map(|s| s.name())))
}

/// Drawpoint names for drawpoint indices; [`u32::MAX`] (not drawn) becomes "".
pub(crate) fn names(index: &[u32], names: &[String]) -> ArrayRef {
    Arc::new(StringArray::from_iter_values(
        index
            .iter()
            .map(|&d| names.get(d as usize).map_or("", String::as_str)),
    ))
}

/// Writes named columns as one table: the schema is `spec`'s fields under these names (in
/// this order) with `extra` names for the variable columns that follow them.
pub(crate) fn write_table(
    path: &Path,
    spec: &TableSpec,
    fixed: Vec<(&str, ArrayRef)>,
    extra: Vec<(String, ArrayRef)>,
) -> Result<(), OutputError> {
    let batch = table_batch(spec, fixed, extra).map_err(|source| OutputError::Arrow {
        path: path.to_path_buf(),
        source,
    })?;
    write_batch(path, &batch)
}

/// Named columns as one record batch, with `spec`'s schema (see [`write_table`]).
pub(crate) fn table_batch(
    spec: &TableSpec,
    fixed: Vec<(&str, ArrayRef)>,
    extra: Vec<(String, ArrayRef)>,
) -> Result<RecordBatch, ArrowError> {
    let (fixed_names, mut columns): (Vec<&str>, Vec<ArrayRef>) = fixed.into_iter().unzip();
    let (extra_names, extra_columns): (Vec<String>, Vec<ArrayRef>) = extra.into_iter().unzip();
    columns.extend(extra_columns);
    RecordBatch::try_new(spec.arrow_schema(&fixed_names, &extra_names), columns)
}
