//! The daily trace file (`trace_daily.csv`): MassFlow's `Day, MarkerID, TracerID, Easting,
//! Northing, Elevation`, comma-separated, one row per trace point per period end (caveflow
//! keeps no daily state; see the module above). `Day` is the days from the start of the
//! run to the period's end; `MarkerID` and `TracerID` are both the trace id (the point's
//! place in the trace file): a trace point is a marker of its own.

use super::{days_to_end, line, num};
use crate::engine::result::TraceTable;
use crate::model::Scene;

/// The file's text.
pub fn trace_daily(scene: &Scene, t: &TraceTable) -> String {
    let header = [
        "Day",
        "MarkerID",
        "TracerID",
        "Easting",
        "Northing",
        "Elevation",
    ];
    let mut s = line(&header.map(String::from), ',');
    for k in 0..t.trace_id.len() {
        let id = t.trace_id[k].to_string();
        s += &line(
            &[
                days_to_end(&scene.periods, t.period[k]).to_string(),
                id.clone(),
                id,
                num(t.x[k], 3),
                num(t.y[k], 3),
                num(t.z[k], 3),
            ],
            ',',
        );
    }
    s
}
