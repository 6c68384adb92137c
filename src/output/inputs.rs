//! A [`Scene`] written back as input tables plus a scenario file that points at them (used by
//! `caveflow demo` to ship the synthetic Henderson panel as ordinary input files).
//!
//! ```text
//! <dir>/blocks.parquet        canonical block_model columns, grades under their own names
//! <dir>/drawpoints.csv        name,x,y,z,width,zone
//! <dir>/periods.csv           period,name,days
//! <dir>/schedule.csv          period,drawpoint,tonnes (long form, rows with tonnes > 0)
//!   or schedule.parquet       the same columns, when the schedule is large
//! <dir>/scenario.toml         the given scenario with [inputs] set to the files above
//! ```

use std::fs;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use arrow::array::{ArrayRef, Float64Array, Int64Array, StringArray};
use serde::Serialize;

use super::{write_atomic, write_parquet, AtomicFile, OutputError};
use crate::model::{BlockModel, Drawpoints, Periods, Scenario, Scene, Schedule};
use crate::schema::{BLOCK_MODEL, SCHEDULE};

/// Schedules with more non-zero rows than this are written as Parquet rather than CSV: a
/// mine-scale daily schedule is millions of rows, which CSV makes slow to read and large.
pub const SCHEDULE_CSV_MAX_ROWS: usize = 200_000;

/// Writes a CSV file atomically: a header, then `rows`.
fn write_csv<R: Serialize>(
    path: &Path,
    header: &[&str],
    rows: impl Iterator<Item = R>,
) -> Result<(), OutputError> {
    let csv_err = |source| OutputError::Csv {
        path: path.to_path_buf(),
        source,
    };
    let mut out = csv::WriterBuilder::new()
        .has_headers(false)
        .from_writer(AtomicFile::create(path)?);
    out.write_record(header).map_err(csv_err)?;
    for row in rows {
        out.serialize(row).map_err(csv_err)?;
    }
    let file = out.into_inner().map_err(|e| OutputError::Io {
        path: path.to_path_buf(),
        source: e.into_error(),
    })?;
    file.commit()
}

/// Optional float column: NaN (not given) is written as null.
fn optional(v: &[f64]) -> ArrayRef {
    Arc::new(
        v.iter()
            .map(|&x| (!x.is_nan()).then_some(x))
            .collect::<Float64Array>(),
    )
}

/// Writes the block model as Parquet with the canonical `block_model` column names:
/// lithology as text, then one column per grade under its own name. Properties that were not
/// given (NaN) are written as nulls.
pub fn write_block_model(path: &Path, b: &BlockModel) -> Result<(), OutputError> {
    let f = |v: &[f64]| Arc::new(Float64Array::from(v.to_vec())) as ArrayRef;
    let lith = b
        .lithology
        .iter()
        .map(|&l| b.lithology_names[l as usize].as_str());
    let fixed: Vec<(&str, ArrayRef)> = vec![
        ("x", f(&b.x)),
        ("y", f(&b.y)),
        ("z", f(&b.z)),
        ("block_id", Arc::new(Int64Array::from(b.id.clone()))),
        (
            "cave_period",
            Arc::new(Int64Array::from(b.cave_period.clone())),
        ),
        ("solids_density", f(&b.density)),
        ("porosity", f(&b.n0)),
        ("max_porosity", f(&b.n1)),
        ("friction_angle", f(&b.friction)),
        ("frag_size", f(&b.frag)),
        ("frag_shape", optional(&b.frag_shape)),
        ("frag_scale", optional(&b.frag_scale)),
        ("tensile_strength", optional(&b.tensile)),
        ("ucs", optional(&b.ucs)),
        ("perc_k1", f(&b.perc_k1)),
        ("perc_k2", f(&b.perc_k2)),
        ("perc_vmr", f(&b.perc_vmr)),
        ("lithology", Arc::new(StringArray::from_iter_values(lith))),
    ];
    let (names, mut columns): (Vec<&str>, Vec<ArrayRef>) = fixed.into_iter().unzip();
    columns.extend(b.grades.iter().map(|g| f(g)));
    write_parquet(
        path,
        BLOCK_MODEL.arrow_schema(&names, &b.grade_names),
        columns,
    )
}

/// Writes the drawpoints as CSV: `name,x,y,z,width,zone`.
pub fn write_drawpoints(path: &Path, d: &Drawpoints) -> Result<(), OutputError> {
    let rows = (0..d.len()).map(|i| (&d.name[i], d.x[i], d.y[i], d.z[i], d.width[i], &d.zone[i]));
    write_csv(path, &["name", "x", "y", "z", "width", "zone"], rows)
}

/// Writes the periods as CSV: `period,name,days`, and `start_date` when the periods have
/// start dates (given for the first period and after a gap, empty where it follows).
pub fn write_periods(path: &Path, p: &Periods) -> Result<(), OutputError> {
    match &p.start {
        None => {
            let rows = (0..p.len()).map(|i| (p.id[i], &p.name[i], p.days[i]));
            write_csv(path, &["period", "name", "days"], rows)
        }
        Some(start) => {
            // Only the starts that do not follow from the previous period (the first, and
            // after a gap): the rest are left empty, so fractional days never round.
            let rows = (0..p.len()).map(|i| {
                let follows = i > 0 && start[i] == start[i - 1] + p.days[i - 1];
                let date = if follows {
                    String::new()
                } else {
                    crate::model::records::iso_date(start[i])
                };
                (p.id[i], &p.name[i], p.days[i], date)
            });
            write_csv(path, &["period", "name", "days", "start_date"], rows)
        }
    }
}

/// Writes the long-form schedule (`period,drawpoint,tonnes`, only rows with tonnes > 0),
/// period-major, as CSV or — by the file's extension `.parquet` — as Parquet.
pub fn write_schedule(
    path: &Path,
    s: &Schedule,
    periods: &Periods,
    drawpoints: &Drawpoints,
) -> Result<(), OutputError> {
    let rows = || {
        (0..periods.len()).flat_map(move |p| {
            s.period(p)
                .iter()
                .enumerate()
                .filter(|(_, &t)| t > 0.0)
                .map(move |(d, &t)| (periods.id[p], &drawpoints.name[d], t))
        })
    };
    if path.extension().is_some_and(|e| e == "parquet") {
        let period: Int64Array = rows().map(|r| r.0).collect();
        let drawpoint = StringArray::from_iter_values(rows().map(|r| r.1.as_str()));
        let tonnes: Float64Array = rows().map(|r| r.2).collect();
        let columns: Vec<ArrayRef> = vec![Arc::new(period), Arc::new(drawpoint), Arc::new(tonnes)];
        write_parquet(
            path,
            SCHEDULE.arrow_schema(&SCHEDULE.field_names(), &[]),
            columns,
        )
    } else {
        write_csv(path, &["period", "drawpoint", "tonnes"], rows())
    }
}

/// Writes `scene` into `dir` (created if needed) as input tables, and `scenario` as
/// `scenario.toml` with its `[inputs]` pointing at them (relative paths, so the folder can be
/// moved). The schedule is CSV unless it has more than [`SCHEDULE_CSV_MAX_ROWS`] non-zero
/// rows. Returns the files written, the scenario last.
pub fn write_scene(
    dir: &Path,
    scene: &Scene,
    scenario: &Scenario,
) -> Result<Vec<PathBuf>, OutputError> {
    fs::create_dir_all(dir).map_err(|source| OutputError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let nonzero = scene.schedule.tonnes.iter().filter(|&&t| t > 0.0).count();
    let schedule = if nonzero > SCHEDULE_CSV_MAX_ROWS {
        "schedule.parquet"
    } else {
        "schedule.csv"
    };

    write_block_model(&dir.join("blocks.parquet"), &scene.blocks)?;
    write_drawpoints(&dir.join("drawpoints.csv"), &scene.drawpoints)?;
    write_periods(&dir.join("periods.csv"), &scene.periods)?;
    write_schedule(
        &dir.join(schedule),
        &scene.schedule,
        &scene.periods,
        &scene.drawpoints,
    )?;

    let mut sc = scenario.clone();
    sc.inputs.blocks = "blocks.parquet".into();
    sc.inputs.drawpoints = "drawpoints.csv".into();
    sc.inputs.drawbells = None;
    sc.inputs.schedule = schedule.into();
    sc.inputs.periods = Some("periods.csv".into());
    sc.inputs.trace = None;
    let path = dir.join("scenario.toml");
    let text = toml::to_string(&sc).map_err(|e| OutputError::Encode {
        path: path.clone(),
        message: e.to_string(),
    })?;
    write_atomic(&path, text.as_bytes())?;

    Ok([
        "blocks.parquet",
        "drawpoints.csv",
        "periods.csv",
        schedule,
        "scenario.toml",
    ]
    .map(|f| dir.join(f))
    .to_vec())
}
