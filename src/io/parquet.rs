//! Parquet input through the parquet crate's Arrow reader.
//!
//! Only the columns the spec uses are decoded. Integers of any width are read as `i64`,
//! `Float32` goes through its shortest decimal form (so a 0.1 written as `f32` reads as 0.1,
//! not 0.10000000149), and text, dictionary, date and other types Arrow can print are read
//! through their text form, with the same rules as a CSV cell.

use std::cell::Cell as Flag;
use std::fs::File;
use std::panic::{self, catch_unwind, AssertUnwindSafe};
use std::path::Path;
use std::sync::Once;

use arrow::array::{Array, ArrayRef, AsArray};
use arrow::compute::{can_cast_types, cast};
use arrow::datatypes::{DataType, Float32Type, Float64Type, Int64Type};
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use parquet::arrow::ProjectionMask;
use sha2::{Digest, Sha256};

use super::problem::{Collector, Problem};
use super::table::{Cell, Plan, Table, Target};
use crate::schema::TableSpec;

/// Reads a Parquet file into a [`Table`], reporting into `problems`.
///
/// The parquet crate can panic on some corrupt files; such a panic is caught, silently, and
/// reported as `unreadable` with its message, so that no input, however malformed, takes
/// the program down or prints a panic (see [`quietly`]).
pub(crate) fn read(
    path: &Path,
    file: &str,
    spec: &TableSpec,
    problems: &mut Collector,
) -> Option<Table> {
    let sha256 = match hash_file(path) {
        Ok(h) => h,
        Err(e) => {
            let message = format!("cannot read {}: {e}", path.display());
            problems.push(Problem::file(file, "unreadable", message));
            return None;
        }
    };
    match quietly(|| read_batches(path, file, spec, problems)) {
        Ok(t) => t.map(|t| Table { sha256, ..t }),
        Err(why) => {
            let message =
                format!("the Parquet reader failed on this file ({why}); it is probably corrupt");
            problems.push(Problem::file(file, "unreadable", message));
            None
        }
    }
}

thread_local! {
    /// Set while this thread runs the parquet crate under [`quietly`].
    static QUIET: Flag<bool> = const { Flag::new(false) };
}

/// Runs `f`, catching a panic as `Err(its message)` without printing it.
///
/// # Why
/// The parquet crate panics on some corrupt files (the fuzz harness found
/// `column start and length should not be negative` in a mangled column chunk), and the
/// default panic hook would print `thread 'main' panicked at …` before the catch, which
/// reads as a crash. The hook installed here (once, wrapping whatever hook was there) stays
/// silent only on a thread inside `quietly`; every other panic, anywhere, is reported as
/// before (and under the fuzzer still aborts, so uncaught panics are still found).
fn quietly<T>(f: impl FnOnce() -> T) -> Result<T, String> {
    static HOOK: Once = Once::new();
    HOOK.call_once(|| {
        let previous = panic::take_hook();
        panic::set_hook(Box::new(move |info| {
            if !QUIET.with(Flag::get) {
                previous(info);
            }
        }));
    });
    let was = QUIET.with(|q| q.replace(true));
    let r = catch_unwind(AssertUnwindSafe(f));
    QUIET.with(|q| q.set(was));
    r.map_err(|payload| {
        payload
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "a panic".into())
    })
}

/// Streams a file through SHA-256.
fn hash_file(path: &Path) -> std::io::Result<String> {
    let mut hasher = Sha256::new();
    std::io::copy(&mut File::open(path)?, &mut hasher)?;
    Ok(hasher
        .finalize()
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect())
}

fn read_batches(
    path: &Path,
    file: &str,
    spec: &TableSpec,
    problems: &mut Collector,
) -> Option<Table> {
    let unreadable = |problems: &mut Collector, e: &dyn std::fmt::Display| {
        let message = format!("not a readable Parquet file: {e}");
        problems.push(Problem::file(file, "unreadable", message));
    };
    let builder = match File::open(path)
        .map_err(|e| e.to_string())
        .and_then(|f| ParquetRecordBatchReaderBuilder::try_new(f).map_err(|e| e.to_string()))
    {
        Ok(b) => b,
        Err(e) => {
            unreadable(problems, &e);
            return None;
        }
    };
    let headers: Vec<String> = builder
        .schema()
        .fields()
        .iter()
        .map(|f| f.name().clone())
        .collect();
    let mut plan = Plan::new(file, &headers, spec, problems);
    let keep: Vec<usize> = plan
        .targets()
        .enumerate()
        .filter(|(_, t)| !matches!(t, Target::Ignored))
        .map(|(i, _)| i)
        .collect();
    let kept_headers: Vec<String> = keep
        .iter()
        .filter_map(|&i| headers.get(i).cloned())
        .collect();
    let mask = ProjectionMask::roots(builder.parquet_schema(), keep);
    let reader = match builder
        .with_projection(mask)
        .with_batch_size(64 * 1024)
        .build()
    {
        Ok(r) => r,
        Err(e) => {
            unreadable(problems, &e);
            return None;
        }
    };
    let mut rows = 0usize;
    let mut bad_type = vec![false; kept_headers.len()];
    for batch in reader {
        let batch = match batch {
            Ok(b) => b,
            Err(e) => {
                unreadable(problems, &e);
                return None;
            }
        };
        for (b, array) in batch.columns().iter().enumerate() {
            if push_array(&mut plan, b, rows + 1, array, problems) {
                continue;
            }
            if let Some(flag @ false) = bad_type.get_mut(b) {
                *flag = true;
                problems.push(Problem::at(
                    file,
                    None,
                    kept_headers.get(b).map(String::as_str),
                    "mistyped",
                    format!(
                        "the column has Arrow type {}, which cannot be read as a number or text",
                        array.data_type()
                    ),
                ));
            }
        }
        rows += batch.num_rows();
    }
    Some(plan.finish(problems, (1..=rows).collect()))
}

/// Pushes one Arrow array into builder `b`; false when its type cannot be read.
fn push_array(
    plan: &mut Plan,
    b: usize,
    first_row: usize,
    array: &ArrayRef,
    problems: &mut Collector,
) -> bool {
    if let Some(a) = array.as_primitive_opt::<Float64Type>() {
        let cells = a.iter().map(|v| v.map_or(Cell::Null, Cell::Float));
        plan.push_column(b, first_row, cells, problems);
        return true;
    }
    let dt = array.data_type();
    if dt.is_nested() {
        // Lists and structs print as text (`[1, 2]`), which is never a cell value.
        return false;
    }
    let target = if dt.is_integer() {
        DataType::Int64
    } else if dt.is_floating() {
        DataType::Float32
    } else {
        DataType::Utf8
    };
    if !can_cast_types(dt, &target) {
        return false;
    }
    let Ok(cast) = cast(array, &target) else {
        return false;
    };
    if let Some(a) = cast.as_primitive_opt::<Int64Type>() {
        let cells = a.iter().map(|v| v.map_or(Cell::Null, Cell::Int));
        plan.push_column(b, first_row, cells, problems);
    } else if let Some(a) = cast.as_primitive_opt::<Float32Type>() {
        let wide = |x: f32| x.to_string().parse::<f64>().unwrap_or(x as f64);
        let cells = a
            .iter()
            .map(|v| v.map_or(Cell::Null, |x| Cell::Float(wide(x))));
        plan.push_column(b, first_row, cells, problems);
    } else if let Some(a) = cast.as_string_opt::<i32>() {
        let cells = a.iter().map(|v| match v.map(str::trim) {
            None | Some("") => Cell::Null,
            Some(s) => Cell::Text(s),
        });
        plan.push_column(b, first_row, cells, problems);
    } else {
        return false;
    }
    true
}
