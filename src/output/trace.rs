//! The trace points' outputs (`engine::trace`), written only when the run followed trace
//! points: the table `<dir>/trace.parquet` (schema `trace`), one row per trace point per
//! period, and the [`Section`] of their paths that `output::run_dir::write_run_charts`
//! draws as `<dir>/charts/trace.png`.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use arrow::array::{ArrayRef, StringArray};

use super::charts::Section;
use super::columns::{f64s, i64s, names, states, write_table};
use super::OutputError;
use crate::engine::result::TraceTable;
use crate::model::{Periods, Scene};
use crate::schema::TRACE;

/// The name of period number `period` ("" if the scene has no such period).
pub(crate) fn period_name(periods: &Periods, period: i64) -> &str {
    periods
        .id
        .iter()
        .position(|&p| p == period)
        .map_or("", |i| periods.name[i].as_str())
}

/// Writes `<dir>/trace.parquet`; returns its path.
pub fn write_trace(dir: &Path, scene: &Scene, t: TraceTable) -> Result<PathBuf, OutputError> {
    let path = dir.join("trace.parquet");
    let period_names = Arc::new(StringArray::from_iter_values(
        t.period.iter().map(|&p| period_name(&scene.periods, p)),
    )) as ArrayRef;
    let fixed = vec![
        ("trace_id", i64s(t.trace_id)),
        ("period", i64s(t.period)),
        ("period_name", period_names),
        ("x", f64s(t.x)),
        ("y", f64s(t.y)),
        ("z", f64s(t.z)),
        ("origin_x", f64s(t.origin_x)),
        ("origin_y", f64s(t.origin_y)),
        ("origin_z", f64s(t.origin_z)),
        ("state", states(&t.state)),
        ("drawpoint", names(&t.drawpoint, &scene.drawpoints.name)),
        ("drawn_period", i64s(t.drawn_period)),
        ("shear_strain", f64s(t.shear_strain)),
        ("shear_work", f64s(t.shear_work)),
    ];
    write_table(&path, &TRACE, fixed, Vec::new())?;
    Ok(path)
}

/// The trace chart: every trace point's path from its given position through its position
/// at each period end, projected on a vertical Easting–elevation plane over the model's
/// extent, with the drawpoints that drew one (named). None without trace points.
pub fn trace_section(scene: &Scene, t: &TraceTable) -> Option<Section> {
    let n = t.trace_id.iter().copied().max()? as usize;
    let mut paths: Vec<Vec<(f64, f64)>> = vec![Vec::new(); n];
    let mut drew = vec![false; scene.drawpoints.len()];
    for k in 0..t.trace_id.len() {
        let path = &mut paths[t.trace_id[k] as usize - 1];
        if path.is_empty() {
            path.push((t.origin_x[k], t.origin_z[k]));
        }
        path.push((t.x[k], t.z[k]));
        if let Some(d) = drew.get_mut(t.drawpoint[k] as usize) {
            *d = true;
        }
    }
    let (bm, dp) = (&scene.blocks, &scene.drawpoints);
    let max = bm.max_corner();
    Some(Section {
        axis_label: "Easting (m)".into(),
        x_range: (bm.origin[0], max[0]),
        z_range: (bm.origin[2], max[2]),
        traces: paths,
        drawpoints: (0..dp.len())
            .filter(|&d| drew[d])
            .map(|d| (dp.x[d], dp.z[d], dp.name[d].clone()))
            .collect(),
        ..Section::default()
    })
}
