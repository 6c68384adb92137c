//! A run directory: everything `caveflow run` writes from one run, written by
//! [`write_run_dir`] in this order (each file atomically):
//!
//! ```text
//! <dir>/charts/…            outputs.charts: sections, grade, trace and stress charts (charts)
//! <dir>/massflow/…          outputs.massflow: MassFlow's report layouts (output::massflow)
//! <dir>/vtk/…               outputs.vtk: VTK files for ParaView (output::vtk)
//! <dir>/report.html         outputs.report: the run report (output::report)
//! <dir>/*.parquet, markers/, dataset/ (outputs.hive), manifest.json last
//!                           the tables (output::run)
//! ```
//!
//! and then the checkpoint the run wrote while it went (`<dir>/checkpoint.bin`,
//! [`checkpoint`]) is removed: the directory is complete. The scenario's `outputs` say
//! where and what; the caller gives the run, its name and what the manifest records.
//!
//! - [`charts`]: which charts a run writes ([`write_run_charts`]);
//! - [`checkpoint`]: when a run writes its checkpoint and what it belongs to
//!   ([`Checkpoints`]).

pub mod charts;
pub mod checkpoint;

use std::path::{Path, PathBuf};
use std::time::Instant;

pub use self::charts::write_run_charts;
pub use self::checkpoint::{remove_checkpoint, Checkpoints, CHECKPOINT_FILE};

use super::charts::ChartError;
use super::dataset::HiveLayout;
use super::report::{write_run_report, ReportError, RunReport};
use super::{massflow, vtk, write_run_with, Manifest, OutputError};
use crate::engine::result::RunOutput;
use crate::model::load::InputFile;
use crate::model::{Scenario, Scene};

/// A finished run to write into its directory, `scenario.outputs.dir`.
#[derive(Debug)]
pub struct RunDir<'a> {
    /// The scene run.
    pub scene: &'a Scene,
    /// The scenario run: its `outputs` say where and what to write.
    pub scenario: &'a Scenario,
    /// The run's name (the scenario file's stem): the report's title, and the datasets'
    /// `scenario=` value unless `outputs.scenario_name` names it.
    pub name: &'a str,
    /// The command line, for the manifest.
    pub command: String,
    /// The input files with their hashes, for the manifest.
    pub inputs: Vec<InputFile>,
    /// When the run started: the manifest's wall time runs from here to when the manifest
    /// is made, after the charts, the MassFlow reports and the VTK files.
    pub started: Instant,
}

/// What [`write_run_dir`] wrote.
#[derive(Debug, Clone, Default)]
pub struct Written {
    /// The tables, their datasets and the manifest ([`write_run_with`]).
    pub tables: Vec<PathBuf>,
    /// The charts ([`write_run_charts`]).
    pub charts: Vec<PathBuf>,
    /// MassFlow's reports.
    pub massflow: Vec<PathBuf>,
    /// The VTK files.
    pub vtk: Vec<PathBuf>,
    /// The run report.
    pub report: Option<PathBuf>,
    /// Wall time of each step, s: charts, MassFlow reports and VTK, report, tables.
    pub timings: Vec<(&'static str, f64)>,
}

impl Written {
    /// Every file written but the charts.
    pub fn files(&self) -> usize {
        self.tables.len()
            + self.massflow.len()
            + self.vtk.len()
            + usize::from(self.report.is_some())
    }
}

/// A failure to write a run directory; each names the file.
#[derive(Debug, thiserror::Error)]
pub enum RunDirError {
    /// A chart.
    #[error(transparent)]
    Chart(#[from] ChartError),
    /// The report.
    #[error(transparent)]
    Report(#[from] ReportError),
    /// A table, a MassFlow report, a VTK file, the manifest or the checkpoint.
    #[error(transparent)]
    Output(#[from] OutputError),
}

/// Writes the run directory of `run` (see the module docs) and returns what it wrote.
/// Consumes the run: the tables' columns move into Arrow without a copy.
pub fn write_run_dir(d: RunDir<'_>, run: RunOutput) -> Result<Written, RunDirError> {
    let (sc, scene) = (d.scenario, d.scene);
    let dir: &Path = &sc.outputs.dir;
    let moments = scene.moments(&sc.outputs.section_periods);
    let mut w = Written::default();
    let mut lap = Instant::now();
    let mut took = |what: &'static str, timings: &mut Vec<(&str, f64)>| {
        timings.push((what, lap.elapsed().as_secs_f64()));
        lap = Instant::now();
    };
    if sc.outputs.charts {
        w.charts = write_run_charts(dir, scene, &run, None, &moments)?;
    }
    took("charts", &mut w.timings);
    if sc.outputs.massflow {
        w.massflow = massflow::write_reports(dir, scene, &run)?;
    }
    if sc.outputs.vtk {
        let periods = scene.vtk_periods(&sc.outputs);
        w.vtk = vtk::write_vtk(&dir.join("vtk"), scene, &run, &periods)?;
    }
    took("MassFlow reports and VTK", &mut w.timings);
    let manifest = Manifest::new(
        d.command,
        sc,
        d.inputs,
        &run,
        rayon::current_num_threads(),
        d.started.elapsed().as_secs_f64(),
    );
    if sc.outputs.report {
        let r = RunReport {
            name: d.name,
            scene,
            run: &run,
            manifest: &manifest,
            charts: &w.charts,
            moments: &moments,
        };
        w.report = Some(write_run_report(dir, &r)?);
    }
    let hive = HiveLayout::new(sc, d.name, scene.periods.len());
    took("report", &mut w.timings);
    w.tables = write_run_with(dir, scene, run, &manifest, hive.as_ref())?;
    took("tables", &mut w.timings);
    remove_checkpoint(dir)?;
    Ok(w)
}
