//! The marker report (`marker_report_<N>.txt`) and the trace report
//! (`trace_report_<N>.txt`): MassFlow's marker layout, for the lattice markers of a marker
//! snapshot and for the trace points at the same period's end.
//!
//! Tab-delimited, one row per marker: `MarkerID`, `xStart`, `yStart`, `zStart` (origin),
//! `xCurrent`, `yCurrent`, `zCurrent`, `ParentBlock` (block id of origin), `Active` (1
//! while moving in an IMZ, else 0), one column per grade (the parent block's, %), `Mass`
//! (t; 0 for a trace marker, which carries none), `Volume` (Mass / BulkDen, m³),
//! `Porosity` (n1 once mobilised, n0 in situ), `SolidDen`, `BulkDen` = SolidDen (1 −
//! Porosity) (t/m³), `FricAng` (°), `FragDia` (m), `ShearStr` (accumulated shear strain),
//! `Work` (accumulated shear work, kPa), `DPEnd` (the drawpoint that drew it, or empty),
//! `DayExtr` (the day its period of draw ends, 0 if not drawn), `MassExtr` (the mass drawn,
//! t) and `Type` (0 lattice marker, 1 trace marker).

use std::collections::HashMap;

use super::{days_to_end, line, num};
use crate::engine::result::TraceTable;
use crate::engine::result::{MarkerSnapshot, MarkerState};
use crate::model::Scene;

/// One marker as the report prints it.
struct Row<'a> {
    id: i64,
    start: [f64; 3],
    current: [f64; 3],
    block: Option<usize>,
    state: MarkerState,
    mass: f64,
    frag: f64,
    strain: f64,
    work: f64,
    drawpoint: u32,
    drawn_period: i64,
    kind: u8,
    scene: &'a Scene,
}

impl Row<'_> {
    fn fields(&self) -> Vec<String> {
        let bm = &self.scene.blocks;
        let c = |x: f64| num(x, 3);
        let prop = |v: &[f64]| self.block.map_or(f64::NAN, |b| v[b]);
        let porosity = match self.state {
            MarkerState::InSitu => prop(&bm.n0),
            _ => prop(&bm.n1),
        };
        let solid = prop(&bm.density);
        let bulk = solid * (1.0 - porosity);
        let drawn = self.state == MarkerState::Drawn;
        let mut f = vec![self.id.to_string()];
        f.extend(self.start.iter().chain(&self.current).map(|&x| c(x)));
        f.push(self.block.map_or(String::new(), |b| bm.id[b].to_string()));
        f.push(u8::from(self.state == MarkerState::Moving).to_string());
        f.extend(bm.grades.iter().map(|g| num(prop(g), 4)));
        f.push(num(self.mass, 6));
        f.push(num(self.mass / bulk, 6));
        f.push(num(porosity, 4));
        f.push(num(solid, 4));
        f.push(num(bulk, 4));
        f.push(num(prop(&bm.friction), 2));
        f.push(num(self.frag, 4));
        f.push(num(self.strain, 6));
        f.push(num(self.work, 4));
        let dp = &self.scene.drawpoints.name;
        f.push(if drawn {
            dp[self.drawpoint as usize].clone()
        } else {
            String::new()
        });
        let day = if drawn {
            days_to_end(&self.scene.periods, self.drawn_period)
        } else {
            0.0
        };
        f.push(day.to_string());
        f.push(num(if drawn { self.mass } else { 0.0 }, 6));
        f.push(self.kind.to_string());
        f
    }
}

/// The header line.
fn header(scene: &Scene) -> String {
    let mut h: Vec<String> = [
        "MarkerID",
        "xStart",
        "yStart",
        "zStart",
        "xCurrent",
        "yCurrent",
        "zCurrent",
        "ParentBlock",
        "Active",
    ]
    .map(String::from)
    .to_vec();
    h.extend(scene.blocks.grade_names.iter().cloned());
    h.extend(
        [
            "Mass", "Volume", "Porosity", "SolidDen", "BulkDen", "FricAng", "FragDia", "ShearStr",
            "Work", "DPEnd", "DayExtr", "MassExtr", "Type",
        ]
        .map(String::from),
    );
    line(&h, '\t')
}

/// The marker report of one snapshot.
pub fn marker_report(scene: &Scene, s: &MarkerSnapshot) -> String {
    let bm = &scene.blocks;
    let block_of: HashMap<i64, usize> = bm.id.iter().enumerate().map(|(b, &id)| (id, b)).collect();
    let mut text = header(scene);
    for k in 0..s.marker_id.len() {
        let row = Row {
            id: s.marker_id[k],
            start: [s.origin_x[k], s.origin_y[k], s.origin_z[k]],
            current: [s.x[k], s.y[k], s.z[k]],
            block: block_of.get(&s.block_id[k]).copied(),
            state: s.state[k],
            mass: s.mass[k],
            frag: s.frag_size[k],
            strain: s.shear_strain[k],
            work: s.shear_work[k],
            drawpoint: s.drawpoint[k],
            drawn_period: s.drawn_period[k],
            kind: 0,
            scene,
        };
        text += &line(&row.fields(), '\t');
    }
    text
}

/// The trace report: the trace points at the end of `period`.
pub fn trace_report(scene: &Scene, t: &TraceTable, period: i64) -> String {
    let bm = &scene.blocks;
    let mut text = header(scene);
    for k in (0..t.trace_id.len()).filter(|&k| t.period[k] == period) {
        let start = [t.origin_x[k], t.origin_y[k], t.origin_z[k]];
        let block = bm.locate(start);
        let row = Row {
            id: t.trace_id[k],
            start,
            current: [t.x[k], t.y[k], t.z[k]],
            block,
            state: t.state[k],
            mass: 0.0,
            frag: block.map_or(f64::NAN, |b| bm.frag[b]),
            strain: t.shear_strain[k],
            work: t.shear_work[k],
            drawpoint: t.drawpoint[k],
            drawn_period: t.drawn_period[k],
            kind: 1,
            scene,
        };
        text += &line(&row.fields(), '\t');
    }
    text
}
