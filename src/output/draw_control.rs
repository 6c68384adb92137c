//! Draw control's tables (`engine::draw_control`), written only under the target
//! strategy: `<dir>/schedule_realised.parquet` (the tonnes each drawpoint drew each period,
//! in the schedule's own long schema, so that it can be run as a fixed schedule),
//! `<dir>/closures.parquet` and `<dir>/production_target.parquet`; and with `[economics]`
//! (any strategy) `<dir>/value.parquet` and `<dir>/best_hod.parquet` (`engine::value`).

use std::path::{Path, PathBuf};

use super::columns::{f64s, i64s, names, strs, write_table};
use super::OutputError;
use crate::engine::draw_control::ControlRecord;
use crate::engine::value::{BestHod, ValueTable};
use crate::model::Scene;
use crate::schema::{BEST_HOD, CLOSURES, PRODUCTION_TARGET, SCHEDULE, VALUE};

/// Writes the three tables; returns their paths.
pub fn write_control(
    dir: &Path,
    scene: &Scene,
    rec: ControlRecord,
) -> Result<Vec<PathBuf>, OutputError> {
    let dp = &scene.drawpoints.name;
    let n = dp.len().max(1);
    let (mut period, mut drawpoint, mut tonnes) = (Vec::new(), Vec::new(), Vec::new());
    for (k, &t) in rec.realised.iter().enumerate() {
        if t > 0.0 {
            period.push(scene.periods.id[k / n]);
            drawpoint.push((k % n) as u32);
            tonnes.push(t);
        }
    }
    let realised = dir.join("schedule_realised.parquet");
    write_table(
        &realised,
        &SCHEDULE,
        vec![
            ("period", i64s(period)),
            ("drawpoint", names(&drawpoint, dp)),
            ("tonnes", f64s(tonnes)),
        ],
        Vec::new(),
    )?;
    let c = rec.closures;
    let closures = dir.join("closures.parquet");
    write_table(
        &closures,
        &CLOSURES,
        vec![
            ("drawpoint", names(&c.drawpoint, dp)),
            ("period", i64s(c.period)),
            ("reason", strs(c.reason)),
            ("cum_tonnes", f64s(c.cum_tonnes)),
            ("hod", f64s(c.hod)),
            ("grade", f64s(c.grade)),
        ],
        Vec::new(),
    )?;
    let p = rec.production;
    let production = dir.join("production_target.parquet");
    let counts = |v: Vec<u32>| i64s(v.into_iter().map(i64::from).collect());
    write_table(
        &production,
        &PRODUCTION_TARGET,
        vec![
            ("period", i64s(p.period)),
            ("target_tonnes", f64s(p.target_tonnes)),
            ("planned_tonnes", f64s(p.planned_tonnes)),
            ("tonnes", f64s(p.tonnes)),
            ("shortfall_tonnes", f64s(p.shortfall_tonnes)),
            ("open", counts(p.open)),
            ("closed", counts(p.closed)),
        ],
        Vec::new(),
    )?;
    Ok(vec![realised, closures, production])
}

/// Writes `value.parquet` and `best_hod.parquet`; returns their paths.
pub fn write_value(
    dir: &Path,
    scene: &Scene,
    (v, b): (ValueTable, BestHod),
) -> Result<Vec<PathBuf>, OutputError> {
    let dp = &scene.drawpoints.name;
    let value = dir.join("value.parquet");
    write_table(
        &value,
        &VALUE,
        vec![
            ("drawpoint", names(&v.drawpoint, dp)),
            ("period", i64s(v.period)),
            ("tonnes", f64s(v.tonnes)),
            ("hod", f64s(v.hod)),
            ("value", f64s(v.value)),
            ("cum_value", f64s(v.cum_value)),
        ],
        Vec::new(),
    )?;
    let best = dir.join("best_hod.parquet");
    write_table(
        &best,
        &BEST_HOD,
        vec![
            ("drawpoint", names(&b.drawpoint, dp)),
            ("best_hod", f64s(b.best_hod)),
            ("best_tonnes", f64s(b.best_tonnes)),
            ("best_value", f64s(b.best_value)),
            ("best_period", i64s(b.best_period)),
            ("final_hod", f64s(b.final_hod)),
            ("final_value", f64s(b.final_value)),
        ],
        Vec::new(),
    )?;
    Ok(vec![value, best])
}
