//! Draw control's tables (`engine::draw_control`), written only under the target
//! strategy: `<dir>/schedule_realised.parquet` (the tonnes each drawpoint drew each period,
//! in the schedule's own long schema, so that it can be run as a fixed schedule),
//! `<dir>/closures.parquet` and `<dir>/production_target.parquet`; and with `[economics]`
//! (any strategy) `<dir>/value.parquet` and `<dir>/best_hod.parquet` (`engine::value`).
//! All but `best_hod` are also written as Hive datasets (`output::run::write_tables`).

use std::path::{Path, PathBuf};

use arrow::error::ArrowError;
use arrow::record_batch::RecordBatch;

use super::columns::{f64s, i64s, names, strs, table_batch, write_table};
use super::OutputError;
use crate::engine::result::{BestHod, ControlRecord, ValueTable};
use crate::model::Scene;
use crate::schema::{BEST_HOD, CLOSURES, PRODUCTION_TARGET, SCHEDULE, VALUE};

/// The three tables of draw control as record batches, by name.
pub fn control_batches(
    scene: &Scene,
    rec: ControlRecord,
) -> [(&'static str, Result<RecordBatch, ArrowError>); 3] {
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
    let realised = table_batch(
        &SCHEDULE,
        vec![
            ("period", i64s(period)),
            ("drawpoint", names(&drawpoint, dp)),
            ("tonnes", f64s(tonnes)),
        ],
        Vec::new(),
    );
    let c = rec.closures;
    let closures = table_batch(
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
    );
    let p = rec.production;
    let counts = |v: Vec<u32>| i64s(v.into_iter().map(i64::from).collect());
    let production = table_batch(
        &PRODUCTION_TARGET,
        vec![
            ("period", i64s(p.period)),
            ("target_tonnes", f64s(p.target_tonnes)),
            ("planned_tonnes", f64s(p.planned_tonnes)),
            ("tonnes", f64s(p.tonnes)),
            ("shortfall_tonnes", f64s(p.shortfall_tonnes)),
            ("open", counts(p.open)),
            ("held", counts(p.held)),
            ("closed", counts(p.closed)),
        ],
        Vec::new(),
    );
    [
        ("schedule_realised", realised),
        ("closures", closures),
        ("production_target", production),
    ]
}

/// The `value` table as a record batch.
pub fn value_batch(scene: &Scene, v: ValueTable) -> Result<RecordBatch, ArrowError> {
    let dp = &scene.drawpoints.name;
    table_batch(
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
    )
}

/// Writes `<dir>/best_hod.parquet`; returns its path.
pub fn write_best_hod(dir: &Path, scene: &Scene, b: BestHod) -> Result<PathBuf, OutputError> {
    let dp = &scene.drawpoints.name;
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
    Ok(best)
}
