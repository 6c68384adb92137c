//! Loading a scene: every input table read, typed, checked and joined into a [`Scene`].
//!
//! All inputs are read and checked even when an earlier one fails, so one run reports
//! every problem in every file. A cell the reader could not type is reported once, as
//! read, and is then a missing value that the rules below skip. Checks that join two tables
//! (drawpoints to the block grid and to drawbells, the schedule to drawpoints and periods)
//! are skipped when a table they need lacks a required column or its grid, so that one
//! broken file does not bury its own problems under consequences in others.
//!
//! # Rules
//! Densities must be positive (a density above 20 t/m³ is `units-kg-m3`); porosity and
//! max_porosity lie in [0, 1) (a value in [2, 100] is `units-percent`; values in (1, 2)
//! would be porosities under 2 % and are plainly `porosity-range`), with max_porosity ≥
//! porosity (`n1-below-n0`); the friction angle lies in (0, 90) (below 1.6 it is
//! `units-radians`); fragment sizes, Weibull parameters, strengths, opening widths and
//! period lengths are positive; a mean fragment size above 10 m or an opening width above
//! 100 m is `units-mm`; grades, percolation coefficients and tonnes are not negative, and
//! no schedule cell may exceed the block model's in-situ tonnes (`tonnes-exceed-model`). A drawpoint must lie within the
//! grid's horizontal extent and no more than one block height below or above it. Every
//! period `outputs.vtk_periods` names must be a period of the schedule (`unknown-period`,
//! reported against the scenario).
//!
//! # Calibration
//! The scenario's `[calibration]` factors ([`Calibration::apply`](crate::model::scenario::Calibration::apply))
//! are applied to the block model once it breaks no rule. A factor that takes a block out
//! of range, or a `frag_factor` lithology the block model does not have, is
//! `calibration-range`, reported against the block model file.
//!
//! Each table has its own file: `blocks` (the block model and its grid),
//! `drawpoints` (drawbells, drawpoints and their openings), `schedule` (periods
//! and the schedule), `trace` (the trace points, each inside the block model) and
//! `draw_control` (the grade columns `[draw_control]` and `[economics]` name, and that
//! some drawpoint opens under a production target).

mod blocks;
mod draw_control;
mod drawpoints;
mod schedule;
mod trace;

pub use super::block_model::MAX_FRAG_SIZE;
pub use blocks::{
    DEFAULT_PERC_K1, DEFAULT_PERC_K2, DEFAULT_PERC_VMR, FRAG_MEAN_TOLERANCE, MAX_COORDINATE,
    MAX_GRID_CELLS, RADIANS_BELOW, TENSILE_UCS_RATIO,
};
pub use drawpoints::MAX_OPENING_WIDTH;

use std::path::{Path, PathBuf};

use crate::io::{
    read_schedule_into, read_table_into, Collector, InputWarning, Periods, Problem, Problems,
    ScheduleForm, ScheduleTable, Table,
};
use crate::model::{Scenario, Scene};
use crate::schema::{TableSpec, BLOCK_MODEL, DRAWBELLS, DRAWPOINTS, PERIODS, TARGET};

use blocks::in_situ_tonnes;

/// An input file that went into a scene, for the run manifest.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct InputFile {
    /// What the file is: `blocks`, `drawpoints`, `drawbells`, `periods`, `schedule` or
    /// `trace`.
    pub role: String,
    /// Path as given in the scenario (absolute once the scenario is loaded from a file).
    pub path: PathBuf,
    /// SHA-256 of the file's bytes, lower-case hex.
    pub sha256: String,
    /// Number of data rows.
    pub rows: usize,
}

impl InputFile {
    /// Describes an input file (e.g. the scenario file itself), hashing its bytes.
    pub fn new(role: &str, path: &Path, rows: usize) -> std::io::Result<InputFile> {
        let sha256 = crate::io::sha256_hex(&std::fs::read(path)?);
        Ok(InputFile {
            role: role.to_string(),
            path: path.to_path_buf(),
            sha256,
            rows,
        })
    }
}

/// A validated scene, with what it was made from.
#[derive(Debug, Clone)]
pub struct LoadedScene {
    /// What the engine runs.
    pub scene: Scene,
    /// The input files and their hashes.
    pub inputs: Vec<InputFile>,
    /// Remarks that are not errors (ignored columns, defaulted widths, invented periods).
    pub warnings: Vec<InputWarning>,
    /// The points to follow through the draw (`inputs.trace`; empty without one), each
    /// inside the block model.
    pub trace: Vec<[f64; 3]>,
}

/// Reads, checks and joins every input of a scenario. See the module docs for the rules;
/// every problem in every file is returned, each with its file, row, column and rule id.
pub fn load_scene(sc: &Scenario) -> Result<LoadedScene, Problems> {
    let mut l = Loader::default();
    let i = &sc.inputs;
    let blocks = l.read("blocks", &i.blocks, &BLOCK_MODEL);
    let drawpoints = l.read("drawpoints", &i.drawpoints, &DRAWPOINTS);
    let bells = i
        .drawbells
        .as_ref()
        .map(|p| l.read("drawbells", p, &DRAWBELLS));
    let periods = i.periods.as_ref().map(|p| l.read("periods", p, &PERIODS));
    let schedule = l.read_schedule(&i.schedule);
    let trace = i.trace.as_ref().and_then(|p| l.read_trace(p));
    let target = sc
        .draw_control
        .target_table
        .as_ref()
        .map(|p| l.read("target", p, &TARGET));

    let blocks = blocks.and_then(|t| {
        let before = l.problems.total();
        let mut m = l.block_model(&t)?;
        // The scenario's calibration, on a block model that broke no rule (its factors are
        // checked against the values they scale).
        if l.problems.total() == before {
            if let Err(e) = sc.calibration.apply_located(&mut m) {
                let row = e.block.map(|b| t.row(b));
                let column = e.column.map(|c| t.header(c).to_string());
                l.problem(
                    &t.file,
                    row,
                    column.as_deref(),
                    "calibration-range",
                    e.message,
                );
            }
        }
        Some(m)
    });
    // Ok(None): no drawbells table; Err: one was given but its columns could not be read.
    let bells = match bells {
        None => Ok(None),
        Some(Some(t)) => l.drawbells(&t).map(Some).ok_or(()),
        Some(None) => Err(()),
    };
    let drawpoints = drawpoints.and_then(|t| {
        l.drawpoints(
            &t,
            bells.as_ref().ok().and_then(Option::as_ref),
            bells.is_err(),
            blocks.as_ref(),
            sc.flow.default_opening_width,
        )
    });
    let periods = match (periods, &schedule) {
        (Some(t), s) => {
            if let Some(s) = s.as_ref().filter(|s| s.form == ScheduleForm::Wide) {
                l.warnings.push(InputWarning::new(
                    &s.file,
                    "periods-table-wins",
                    "period names and lengths come from the periods table, not from the wide schedule's headers",
                ));
            }
            t.and_then(|t| l.periods(&t))
        }
        (None, Some(s)) => Some(l.periods_from_schedule(s)),
        (None, None) => None,
    };
    if let Some(p) = &periods {
        l.check_chosen_periods("outputs.vtk_periods", &sc.outputs.vtk_periods, p);
    }
    if let (Some(t), Some(b)) = (&trace, &blocks) {
        l.check_trace(t, b);
    }
    if let Some(b) = &blocks {
        l.check_grade_names(sc, b, &crate::io::file_name(&i.blocks));
    }
    if let (Some(b), Some(d), Some(p)) = (&blocks, &drawpoints, &periods) {
        l.check_some_open(sc, b, d, p, &crate::io::file_name(&i.drawpoints));
    }
    let target = match (target, &periods) {
        (Some(Some(t)), Some(p)) => Some(l.target(&t, p)),
        _ => None,
    };
    let model_tonnes = blocks.as_ref().and_then(in_situ_tonnes);
    let schedule = match (&schedule, &drawpoints, &periods) {
        (Some(s), Some(d), Some(p)) => Some(l.schedule(s, d, p, model_tonnes)),
        _ => None,
    };
    let Loader {
        problems,
        inputs,
        warnings,
    } = l;
    match (blocks, drawpoints, periods, schedule) {
        (Some(blocks), Some(drawpoints), Some(periods), Some(schedule)) if problems.is_empty() => {
            Ok(LoadedScene {
                scene: Scene {
                    blocks,
                    drawpoints,
                    periods,
                    schedule,
                    target,
                },
                inputs,
                warnings,
                trace: trace.map(|t| t.points).unwrap_or_default(),
            })
        }
        _ => Err(problems.finish()),
    }
}

#[derive(Default)]
struct Loader {
    problems: Collector,
    inputs: Vec<InputFile>,
    warnings: Vec<InputWarning>,
}

impl Loader {
    fn problem(
        &mut self,
        file: &str,
        row: Option<usize>,
        column: Option<&str>,
        rule: &'static str,
        message: String,
    ) {
        self.problems
            .push(Problem::at(file, row, column, rule, message));
    }

    fn input(&mut self, role: &str, path: &Path, sha256: &str, rows: usize) {
        self.inputs.push(InputFile {
            role: role.into(),
            path: path.to_path_buf(),
            sha256: sha256.into(),
            rows,
        });
    }

    /// Reads one table, recording its problems; None when not even a header could be read.
    fn read(&mut self, role: &str, path: &Path, spec: &TableSpec) -> Option<Table> {
        if path.as_os_str().is_empty() {
            let message = format!("inputs.{role} is not set");
            self.problems
                .push(Problem::file("scenario", "no-input", message));
            return None;
        }
        let t = read_table_into(path, spec, &mut self.problems)?;
        self.input(role, path, &t.sha256, t.len());
        self.warnings.extend(t.warnings.iter().cloned());
        Some(t)
    }

    /// Each period the scenario key `key` names (`chosen`) must be one of `periods`:
    /// `unknown-period`, reported against the scenario.
    fn check_chosen_periods(&mut self, key: &str, chosen: &[i64], periods: &Periods) {
        for c in chosen.iter().filter(|&&c| periods.find(c).is_none()) {
            self.problems.push(Problem::file(
                "scenario",
                "unknown-period",
                format!(
                    "{key}: period {c} is not one of the schedule's periods ({})",
                    periods.span()
                ),
            ));
        }
    }

    fn read_schedule(&mut self, path: &Path) -> Option<ScheduleTable> {
        if path.as_os_str().is_empty() {
            let message = "inputs.schedule is not set";
            self.problems
                .push(Problem::file("scenario", "no-input", message));
            return None;
        }
        let s = read_schedule_into(path, &mut self.problems)?;
        self.input("schedule", path, &s.sha256, s.rows);
        self.warnings.extend(s.warnings.iter().cloned());
        Some(s)
    }
}
