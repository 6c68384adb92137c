//! A run directory: the tables of one run and its manifest.
//!
//! ```text
//! <dir>/extraction.parquet
//! <dir>/imz.parquet
//! <dir>/drawn.parquet
//! <dir>/air_gap.parquet, <dir>/surface.parquet
//! <dir>/markers/period=<N>/part-0.parquet   (Hive-partitioned; `period` is also a column)
//! <dir>/dataset/<table>/scenario=<name>/period=<N>/part-0.parquet   (outputs.hive; see
//!                                           output::dataset)
//! <dir>/stress_levels.parquet, <dir>/stress_sections.parquet   (only with mechanisms.stress)
//! <dir>/trace.parquet                       (only with trace points; output::trace)
//! <dir>/schedule_realised.parquet, closures.parquet, production_target.parquet
//!                                            (only under draw control; output::draw_control)
//! <dir>/value.parquet, best_hod.parquet      (only with [economics]; output::draw_control)
//! <dir>/vtk/                               (only with outputs.vtk, `run --vtk`; output::vtk)
//! <dir>/manifest.json                       (written last)
//! ```
//!
//! The writers take the run's tables by value: their `Vec` columns move into Arrow arrays
//! without a copy, which matters at mine scale (millions of rows). The drawn table and the
//! end snapshot are not held as tables at all: they are read from the engine's markers a
//! part at a time (`engine::marker_tables`, [`PART_ROWS`] rows) and written as they are
//! read, so memory holds the markers, one part and the row group being encoded. Draw
//! anything that needs the run (charts) before writing.

use std::borrow::Cow;
use std::fs;
use std::mem::take;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use arrow::array::{ArrayRef, StringArray};
use arrow::error::ArrowError;
use arrow::record_batch::RecordBatch;

use super::columns::{f64s, f64s_or_null, i64s, names, states, table_batch};
use super::dataset::{write_dataset, write_dataset_with, HiveLayout};
use super::parquet::{write_batch, write_batches, PART_ROWS};
use super::{draw_control, Manifest, OutputError};
use crate::engine::result::{
    AirGapTable, DrawnTable, Extraction, ImzTable, MarkerSnapshot, RunOutput, SurfaceTable,
};
use crate::model::Scene;
use crate::schema::{AIR_GAP, DRAWN, EXTRACTION, IMZ, MARKERS, SURFACE};

/// Maps an Arrow error to the output file it was for.
fn arrow_err(path: &Path) -> impl FnOnce(ArrowError) -> OutputError + '_ {
    move |source| OutputError::Arrow {
        path: path.to_path_buf(),
        source,
    }
}

/// The extraction report: the fixed fields in spec order, then one column per grade under
/// the grade's own name, then `lith_<name>` (mass share) per lithology.
pub fn extraction_batch(scene: &Scene, t: Extraction) -> Result<RecordBatch, ArrowError> {
    let blocks = &scene.blocks;
    let status = Arc::new(StringArray::from(t.status)) as ArrayRef;
    let short_reason = Arc::new(StringArray::from(t.short_reason)) as ArrayRef;
    let fixed = vec![
        ("drawpoint", names(&t.drawpoint, &scene.drawpoints.name)),
        ("period", i64s(t.period)),
        ("scheduled_tonnes", f64s(t.scheduled_tonnes)),
        ("marker_tonnes", f64s(t.marker_tonnes)),
        ("correction", f64s(t.correction)),
        ("tonnes", f64s(t.tonnes)),
        ("shortfall_tonnes", f64s(t.shortfall_tonnes)),
        ("cum_tonnes", f64s(t.cum_tonnes)),
        ("markers", i64s(t.markers)),
        ("dilution", f64s_or_null(t.dilution)),
        ("origin_z", f64s_or_null(t.origin_z)),
        ("hod", f64s(t.hod)),
        ("frag_size", f64s_or_null(t.frag_size)),
        ("fines_share", f64s_or_null(t.fines_share)),
        ("frag_p20", f64s_or_null(t.frag_p20)),
        ("frag_p50", f64s_or_null(t.frag_p50)),
        ("frag_p80", f64s_or_null(t.frag_p80)),
        ("fines_origin_z", f64s_or_null(t.fines_origin_z)),
        ("fines_waste_share", f64s_or_null(t.fines_waste_share)),
        ("percolation", f64s_or_null(t.percolation)),
        ("air_gap", f64s(t.air_gap)),
        ("rilled_share", f64s_or_null(t.rilled_share)),
        ("rill_distance", f64s_or_null(t.rill_distance)),
        ("status", status),
        ("short_reason", short_reason),
        ("fill", f64s_or_null(t.fill)),
    ];
    let grades = blocks
        .grade_names
        .iter()
        .cloned()
        .zip(t.grades.into_iter().map(f64s_or_null));
    let liths = blocks
        .lithology_names
        .iter()
        .map(|l| format!("lith_{l}"))
        .zip(t.lithology.into_iter().map(f64s_or_null));
    table_batch(&EXTRACTION, fixed, grades.chain(liths).collect())
}

/// The IMZ geometry table.
pub fn imz_batch(scene: &Scene, t: ImzTable) -> Result<RecordBatch, ArrowError> {
    let fixed = vec![
        ("drawpoint", names(&t.drawpoint, &scene.drawpoints.name)),
        ("period", i64s(t.period)),
        ("disk", i64s(t.disk)),
        ("z_base", f64s(t.z_base)),
        ("z_top", f64s(t.z_top)),
        ("radius", f64s(t.radius)),
    ];
    table_batch(&IMZ, fixed, Vec::new())
}

/// The drawn markers (the IEZ).
pub fn drawn_batch(scene: &Scene, t: DrawnTable) -> Result<RecordBatch, ArrowError> {
    let fixed = vec![
        ("marker_id", i64s(t.marker_id)),
        ("drawpoint", names(&t.drawpoint, &scene.drawpoints.name)),
        ("period", i64s(t.period)),
        ("origin_x", f64s(t.origin_x)),
        ("origin_y", f64s(t.origin_y)),
        ("origin_z", f64s(t.origin_z)),
        ("mass", f64s(t.mass)),
        ("block_id", i64s(t.block_id)),
        ("frag_size", f64s(t.frag_size)),
        ("rill_distance", f64s(t.rill_distance)),
    ];
    table_batch(&DRAWN, fixed, Vec::new())
}

/// The air-gap table.
pub fn air_gap_batch(t: AirGapTable) -> Result<RecordBatch, ArrowError> {
    let fixed = vec![
        ("period", i64s(t.period)),
        ("x", f64s(t.x)),
        ("y", f64s(t.y)),
        ("air_gap", f64s(t.air_gap)),
    ];
    table_batch(&AIR_GAP, fixed, Vec::new())
}

/// The free-surface table.
pub fn surface_batch(t: SurfaceTable) -> Result<RecordBatch, ArrowError> {
    let fixed = vec![
        ("period", i64s(t.period)),
        ("x", f64s(t.x)),
        ("y", f64s(t.y)),
        ("z", f64s(t.z)),
    ];
    table_batch(&SURFACE, fixed, Vec::new())
}

/// One marker snapshot's rows as a record batch.
pub fn markers_batch(scene: &Scene, t: MarkerSnapshot) -> Result<RecordBatch, ArrowError> {
    let rows = t.marker_id.len();
    let fixed = vec![
        ("marker_id", i64s(t.marker_id)),
        ("period", i64s(vec![t.period; rows])),
        ("x", f64s(t.x)),
        ("y", f64s(t.y)),
        ("z", f64s(t.z)),
        ("origin_x", f64s(t.origin_x)),
        ("origin_y", f64s(t.origin_y)),
        ("origin_z", f64s(t.origin_z)),
        ("mass", f64s(t.mass)),
        ("block_id", i64s(t.block_id)),
        ("state", states(&t.state)),
        ("porosity", f64s(t.porosity)),
        ("frag_size", f64s(t.frag_size)),
        ("shear_strain", f64s(t.shear_strain)),
        ("shear_work", f64s(t.shear_work)),
        ("primary_frag_size", f64s(t.primary_frag_size)),
        ("attrited", f64s(t.attrited)),
        ("percolated", f64s(t.percolated)),
        ("drawpoint", names(&t.drawpoint, &scene.drawpoints.name)),
        ("drawn_period", i64s(t.drawn_period)),
    ];
    table_batch(&MARKERS, fixed, Vec::new())
}

/// Writes one marker snapshot as `<dir>/period=<N>/part-0.parquet` (Hive partitioning, so
/// polars, DuckDB and Arrow datasets read `<dir>` as one table). The `period` column is kept
/// inside the file too, so a single file stands on its own. Returns the file's path.
pub fn write_markers(dir: &Path, scene: &Scene, t: MarkerSnapshot) -> Result<PathBuf, OutputError> {
    let period = t.period;
    write_marker_chunks(dir, scene, period, std::iter::once(t))
}

/// [`write_markers`] of the snapshot of `period` given as consecutive chunks of its rows
/// (at least one, which may be empty), each written as it comes (with chunks of
/// [`PART_ROWS`] rows, the file [`write_markers`] writes from the whole snapshot).
pub fn write_marker_chunks(
    dir: &Path,
    scene: &Scene,
    period: i64,
    chunks: impl Iterator<Item = MarkerSnapshot>,
) -> Result<PathBuf, OutputError> {
    let part = dir.join(format!("period={period}"));
    fs::create_dir_all(&part).map_err(|source| OutputError::Io {
        path: part.clone(),
        source,
    })?;
    let path = part.join("part-0.parquet");
    let batches = chunks.map(|t| markers_batch(scene, t).map_err(arrow_err(&path)));
    write_batches(&path, batches)?;
    Ok(path)
}

/// Writes the drawn table of `run` as `path`, and with `hive` as a Hive dataset under
/// `root` too; returns the files written. A table held whole ([`RunOutput::drawn`]) is
/// moved into one batch that both are written from; the engine's drawn markers
/// ([`RunOutput::end`]) are read a part at a time, for each file.
pub fn write_drawn(
    path: &Path,
    root: &Path,
    scene: &Scene,
    run: &mut RunOutput,
    hive: Option<&HiveLayout>,
) -> Result<Vec<PathBuf>, OutputError> {
    let mut written = vec![path.to_path_buf()];
    if run.end.is_none() {
        let batch = drawn_batch(scene, std::mem::take(&mut run.drawn)).map_err(arrow_err(path))?;
        write_batch(path, &batch)?;
        if let Some(layout) = hive {
            written.extend(write_dataset(root, &batch, &scene.periods, layout)?);
        }
        return Ok(written);
    }
    let batches = run
        .drawn_chunks(PART_ROWS)
        .map(|t| drawn_batch(scene, t.into_owned()).map_err(arrow_err(path)));
    write_batches(path, batches)?;
    if let Some(layout) = hive {
        written.extend(write_drawn_dataset(root, scene, run, layout)?);
    }
    Ok(written)
}

/// The drawn table of `run` as a Hive dataset under `root` ([`write_dataset`]): a table
/// held whole is moved into one batch, the engine's drawn markers are read a row group at
/// a time ([`write_dataset_with`]).
pub fn write_drawn_dataset(
    root: &Path,
    scene: &Scene,
    run: &mut RunOutput,
    layout: &HiveLayout,
) -> Result<Vec<PathBuf>, OutputError> {
    let Some(end) = &run.end else {
        let batch = drawn_batch(scene, std::mem::take(&mut run.drawn)).map_err(arrow_err(root))?;
        return write_dataset(root, &batch, &scene.periods, layout);
    };
    let rows = |at: &[u32]| drawn_batch(scene, end.drawn_at(at)).map_err(arrow_err(root));
    write_dataset_with(
        root,
        end.drawn_periods().map(Some),
        &scene.periods,
        layout,
        rows,
    )
}

/// The tables of a run that are also written as Hive datasets, in the order written (the
/// last four only under draw control or with `[economics]`).
pub const DATASET_TABLES: [&str; 9] = [
    "extraction",
    "imz",
    "drawn",
    "air_gap",
    "surface",
    "schedule_realised",
    "closures",
    "production_target",
    "value",
];

/// Writes the [`DATASET_TABLES`] of `run`, one table at a time (its batch is made, written
/// and let go): each as `<flat>/<table>.parquet` when `flat` is given, and with `hive` as a
/// Hive dataset under `root(table)` ([`write_dataset`]) from the same batch (the engine's
/// drawn table: from the same rows, a part at a time). Takes the tables out of `run`;
/// returns the files written.
pub fn write_tables(
    flat: Option<&Path>,
    root: &dyn Fn(&str) -> PathBuf,
    hive: Option<&HiveLayout>,
    scene: &Scene,
    run: &mut RunOutput,
) -> Result<Vec<PathBuf>, OutputError> {
    let path = |name: &str| flat.map(|d| d.join(format!("{name}.parquet")));
    // One table at a time: its batch is made, written flat and as a dataset, and let go.
    let table = |name: &str, batch: Result<RecordBatch, ArrowError>| {
        let (p, root) = (path(name), root(name));
        let batch = batch.map_err(arrow_err(p.as_deref().unwrap_or(&root)))?;
        let mut written = Vec::new();
        if let Some(p) = p {
            write_batch(&p, &batch)?;
            written.push(p);
        }
        if let Some(layout) = hive {
            written.extend(write_dataset(&root, &batch, &scene.periods, layout)?);
        }
        Ok::<_, OutputError>(written)
    };
    let mut written = table(
        "extraction",
        extraction_batch(scene, take(&mut run.extraction)),
    )?;
    written.extend(table("imz", imz_batch(scene, take(&mut run.imz)))?);
    match (path("drawn"), hive) {
        (Some(p), _) => written.extend(write_drawn(&p, &root("drawn"), scene, run, hive)?),
        (None, Some(layout)) => {
            written.extend(write_drawn_dataset(&root("drawn"), scene, run, layout)?)
        }
        (None, None) => {}
    }
    written.extend(table("air_gap", air_gap_batch(take(&mut run.air_gap)))?);
    written.extend(table("surface", surface_batch(take(&mut run.surface)))?);
    if let Some(rec) = run.control.take() {
        for (name, batch) in draw_control::control_batches(scene, rec) {
            written.extend(table(name, batch)?);
        }
    }
    if let Some((v, best)) = run.value.take() {
        written.extend(table("value", draw_control::value_batch(scene, v))?);
        if let Some(dir) = flat {
            written.push(draw_control::write_best_hod(dir, scene, best)?);
        }
    }
    Ok(written)
}

/// Writes a whole run into `dir` (created if needed) and returns the files written, the
/// manifest last. Consumes the run so its columns move into Arrow without a copy. No
/// Hive datasets (see [`write_run_with`]).
pub fn write_run(
    dir: &Path,
    scene: &Scene,
    run: RunOutput,
    manifest: &Manifest,
) -> Result<Vec<PathBuf>, OutputError> {
    write_run_with(dir, scene, run, manifest, None)
}

/// [`write_run`], and with `hive` also the [`DATASET_TABLES`]
/// tables as Hive-partitioned datasets under `<dir>/dataset/` (see
/// [`dataset`](super::dataset)), from the same record batches as the flat files (the
/// engine's drawn table: from the same rows, a part at a time).
pub fn write_run_with(
    dir: &Path,
    scene: &Scene,
    mut run: RunOutput,
    manifest: &Manifest,
    hive: Option<&HiveLayout>,
) -> Result<Vec<PathBuf>, OutputError> {
    fs::create_dir_all(dir).map_err(|source| OutputError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let root = |name: &str| dir.join("dataset").join(name);
    let mut written = write_tables(Some(dir), &root, hive, scene, &mut run)?;

    let markers = dir.join("markers");
    for snapshot in take(&mut run.snapshots) {
        written.push(write_markers(&markers, scene, snapshot)?);
    }
    if let Some(end) = &run.end {
        if let Some(period) = end.snapshot_period() {
            let chunks = run
                .snapshot_chunks(period, PART_ROWS)
                .into_iter()
                .flatten()
                .map(Cow::into_owned);
            written.push(write_marker_chunks(&markers, scene, period, chunks)?);
        }
    }
    // The markers are written: let them go before the smaller tables.
    run.end = None;

    if !run.stress.is_empty() {
        written.extend(super::stress::write_stress(dir, take(&mut run.stress))?);
    }

    if !run.trace.trace_id.is_empty() {
        written.push(super::trace::write_trace(dir, scene, take(&mut run.trace))?);
    }

    let path = dir.join("manifest.json");
    manifest.write(&path)?;
    written.push(path);
    Ok(written)
}
