//! `caveflow calibrate`'s engine runs as a study ([`study`](super::study)): each batch of
//! [`calibrate`](super::calibrate) becomes cases of one study, run by the study runner (the
//! code of `caveflow study`) or by an external command such as the Ray driver, and each
//! run's predictions are read back from the study's dataset.
//!
//! # Layout
//!
//! ```text
//! OUT/runs/scenario.toml   the scenario calibrated, without its [calibration]
//! OUT/runs/study.toml      study `calibrate`: keep_periods, and one case per run so far
//! OUT/runs/dataset/…, OUT/runs/variants/…, OUT/runs/summary.parquet   the study's layout
//! ```
//!
//! A run's case sets every `calibration` key (`calibration.frag_factor.<lithology>`,
//! `n1_factor`, `friction_factor`) and, for a twin, `resolution.lattice_offset`
//! ([`Problem::lattice_offset`]), each float written to round-trip exactly. The finer
//! check's case carries its resolution as numbers, `[case_resolution.<case>]` (the one
//! [`Problem::resolution`] gives), which the study runs as given: nothing resolves it
//! again. A case's name is `run-` and 12 hex digits of the SHA-256 of its settings and
//! resolution, so the same run has the same name in every batch and every calibration.
//! Before each batch the study file is rewritten with every case so far; the runner skips
//! the complete ones (by content hash, `analysis::study`, "Identity"). So a run asked twice
//! (the joint fit's first centre is a run of the step before) is made once, and a
//! calibration killed and started again makes none of the runs it completed: with the same
//! inputs it writes the same `calibration.json` and runs nothing it ran before.
//!
//! Each run's extraction is read back from `dataset/extraction/study=calibrate/
//! scenario=<case>/`, partitions in period order, rows in the order written: the frame the
//! run in memory gives, value for value, so the fit is the same as
//! [`InProcess`](super::calibrate::InProcess)'s. Every run's dataset stays (a demo run's
//! tables take about 2.6 MB, so its 46-run calibration about 124 MB): removing `runs/`
//! frees it, and a calibration into that directory then makes every run again.
//!
//! # Runners
//!
//! Locally (default), [`run_study`] on `jobs` workers of `threads` threads. With a
//! command (`calibrate --runner CMD`), `CMD OUT/runs/study.toml --out OUT/runs` is run for
//! each batch, with `CAVEFLOW_BIN` set to this caveflow, so that e.g. `python -m
//! caveflow_ray` runs the batch's cases as Ray tasks of this binary; its output goes to
//! stderr. A command that exits with anything but 0, or leaves a case not complete, is an
//! error naming it.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use polars::prelude::*;

use super::calibrate::{CalibrateError, Problem, Runs, Trial};
use super::reconcile::{predicted_of, read_parquet_frame};
use super::study::runner::{run_study, Progress};
use super::study::spec::StudyFile;
use super::study::{Layout, Outcome, Study};
use crate::engine::ResolvedResolution;
use crate::model::scenario::Calibration;
use crate::model::Scenario;
use crate::output::write_atomic;

/// The study's name: the `study=` partition of every run.
pub const STUDY: &str = "calibrate";

/// A calibration's runs as a study under `dir` (see the module docs).
pub struct StudyRuns {
    dir: PathBuf,
    keep_periods: Option<usize>,
    jobs: usize,
    threads: usize,
    command: Option<Vec<String>>,
    cases: Mutex<BTreeMap<String, Case>>,
    ran: AtomicUsize,
    reused: AtomicUsize,
}

/// No progress display: `calibrate` counts batches.
struct Quiet;

impl Progress for Quiet {
    fn periods(&self, _: u64) {}
    fn finished(&self, _: &str, _: Option<&Outcome>) {}
}

fn runs_error(e: impl std::fmt::Display) -> CalibrateError {
    CalibrateError::Runs(e.to_string())
}

impl StudyRuns {
    /// Prepares `dir` (`OUT/runs`): writes the base scenario, `scenario` without its
    /// calibration and with absolute input paths, and checks that it loads back as itself.
    /// `command`: the external runner and its arguments (None: the local runner on `jobs`
    /// workers of `threads` threads).
    pub fn new(
        dir: &Path,
        scenario: &Scenario,
        keep_periods: Option<usize>,
        jobs: usize,
        threads: usize,
        command: Option<Vec<String>>,
    ) -> Result<StudyRuns, CalibrateError> {
        std::fs::create_dir_all(dir).map_err(|e| runs_error(format!("{}: {e}", dir.display())))?;
        let dir = std::path::absolute(dir).map_err(runs_error)?;
        let mut base = scenario.clone();
        base.calibration = Calibration::default();
        let abs = |p: &mut PathBuf| -> Result<(), CalibrateError> {
            *p = std::path::absolute(&*p).map_err(runs_error)?;
            Ok(())
        };
        let i = &mut base.inputs;
        for p in [&mut i.blocks, &mut i.drawpoints, &mut i.schedule] {
            abs(p)?;
        }
        for p in [&mut i.drawbells, &mut i.periods, &mut i.trace]
            .into_iter()
            .flatten()
        {
            abs(p)?;
        }
        let path = dir.join("scenario.toml");
        let text = toml::to_string(&base).map_err(runs_error)?;
        write_atomic(&path, text.as_bytes()).map_err(runs_error)?;
        let mut back = Scenario::load(&path, &[]).map_err(runs_error)?;
        back.outputs = base.outputs.clone();
        if back != base {
            return Err(runs_error(format!(
                "{}: the scenario written for the runs does not load back as itself",
                path.display()
            )));
        }
        Ok(StudyRuns {
            dir,
            keep_periods,
            jobs,
            threads,
            command,
            cases: Mutex::new(BTreeMap::new()),
            ran: AtomicUsize::new(0),
            reused: AtomicUsize::new(0),
        })
    }

    /// The study's directory (`OUT/runs`).
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Runs made so far, and runs found complete (in this calibration's earlier batches or
    /// left by an earlier calibration).
    pub fn counts(&self) -> (usize, usize) {
        (
            self.ran.load(Ordering::SeqCst),
            self.reused.load(Ordering::SeqCst),
        )
    }

    /// Writes the study file with every case so far.
    fn write_study(&self) -> Result<PathBuf, CalibrateError> {
        let cases = self.cases.lock().expect("no panic holding it");
        let file = StudyFile {
            name: Some(STUDY.into()),
            scenario: "scenario.toml".into(),
            cases: Some(
                cases
                    .iter()
                    .map(|(name, c)| (name.clone(), c.sets.clone()))
                    .collect(),
            ),
            case_resolution: cases
                .iter()
                .filter_map(|(name, c)| Some((name.clone(), c.resolution?)))
                .collect(),
            keep_periods: self.keep_periods,
            ..StudyFile::default()
        };
        let path = self.dir.join("study.toml");
        let text = format!(
            "# Written by `caveflow calibrate`: its engine runs so far, one case each.\n{}",
            toml::to_string(&file).map_err(runs_error)?
        );
        write_atomic(&path, text.as_bytes()).map_err(runs_error)?;
        Ok(path)
    }

    /// Runs the study's cases that are not complete: locally, or by the command.
    fn run(&self, file: &Path, study: &Study, layout: &Layout) -> Result<(), CalibrateError> {
        let Some(cmd) = &self.command else {
            let report = run_study(study, layout, self.jobs, self.threads, &Quiet)
                .map_err(|e| runs_error(crate::analysis::error_text(e.as_ref())))?;
            return match report.failed.first() {
                Some((name, why)) => Err(runs_error(format!("run {name}: {why}"))),
                None => Ok(()),
            };
        };
        let exe = std::env::current_exe().map_err(runs_error)?;
        let status = Command::new(&cmd[0])
            .args(&cmd[1..])
            .arg(file)
            .arg("--out")
            .arg(&self.dir)
            .env("CAVEFLOW_BIN", exe)
            .stdout(Stdio::from(std::io::stderr()))
            .status()
            .map_err(|e| runs_error(format!("--runner {}: {e}", cmd.join(" "))))?;
        if !status.success() {
            return Err(runs_error(format!(
                "--runner {}: exited with {status} on {}",
                cmd.join(" "),
                file.display()
            )));
        }
        Ok(())
    }
}

/// A float as TOML that reads back as the same bits.
fn exact(x: f64) -> String {
    format!("{x:?}")
}

/// A run's case of the study: its settings over the base scenario and the resolution it
/// runs at when not the one its scenario resolves to.
#[derive(Debug, Clone)]
struct Case {
    sets: Vec<String>,
    resolution: Option<ResolvedResolution>,
}

/// A run's case, and its name.
fn case(p: &Problem, t: &Trial) -> Result<(String, Case), CalibrateError> {
    let c = &t.calibration;
    let mut sets: Vec<String> = c
        .frag_factor
        .iter()
        .map(|(l, f)| format!("calibration.frag_factor.{l}={}", exact(*f)))
        .collect();
    sets.push(format!("calibration.n1_factor={}", exact(c.n1_factor)));
    sets.push(format!(
        "calibration.friction_factor={}",
        exact(c.friction_factor)
    ));
    let resolution = if t.finer != 1.0 {
        Some(p.resolution(t)?)
    } else {
        None
    };
    if t.lattice > 0 {
        let [x, y] = p.lattice_offset(t);
        sets.push(format!(
            "resolution.lattice_offset=[{}, {}]",
            exact(x),
            exact(y)
        ));
    }
    let mut identity = sets.join("\n");
    if let Some(r) = &resolution {
        identity.push_str(&format!(
            "\nresolution={}",
            serde_json::to_string(r).map_err(runs_error)?
        ));
    }
    let name = format!("run-{}", &crate::io::sha256_hex(identity.as_bytes())[..12]);
    Ok((name, Case { sets, resolution }))
}

/// A run's predictions from the study's extraction dataset (module docs).
fn read_back(layout: &Layout, name: &str, grades: &[String]) -> Result<DataFrame, CalibrateError> {
    let files = layout
        .partition_files("extraction", name)
        .map_err(|e| runs_error(crate::analysis::error_text(e.as_ref())))?;
    let mut frame: Option<DataFrame> = None;
    for (f, period) in files {
        let mut df = read_parquet_frame(&f)?;
        if let Some(period) = period {
            let n = df.height();
            df.with_column(Column::new("period".into(), vec![period; n]))?;
        }
        let df = predicted_of(df, grades)?;
        match &mut frame {
            None => frame = Some(df),
            Some(all) => {
                all.vstack_mut(&df)?;
            }
        }
    }
    let mut frame = frame.ok_or_else(|| {
        runs_error(format!(
            "run {name}: no extraction rows in {}",
            layout.table_root("extraction").display()
        ))
    })?;
    frame.rechunk_mut();
    Ok(frame)
}

impl Runs for StudyRuns {
    fn predict(&self, p: &Problem, trials: &[Trial]) -> Result<Vec<DataFrame>, CalibrateError> {
        let mut names = Vec::with_capacity(trials.len());
        {
            let mut cases = self.cases.lock().expect("no panic holding it");
            for t in trials {
                let (name, c) = case(p, t)?;
                cases.insert(name.clone(), c);
                names.push(name);
            }
        }
        let file = self.write_study()?;
        let study = Study::expand(&file).map_err(runs_error)?;
        let layout = Layout::new(&self.dir, &study);
        let variant = |n: &str| {
            study
                .variant(n)
                .ok_or_else(|| runs_error(format!("{}: no case {n}", file.display())))
        };
        let mut batch = names.clone();
        batch.sort();
        batch.dedup();
        let mut todo = 0;
        for n in &batch {
            todo += usize::from(!layout.is_complete(variant(n)?));
        }
        self.run(&file, &study, &layout)?;
        for n in &batch {
            if !layout.is_complete(variant(n)?) {
                return Err(runs_error(format!(
                    "run {n} is not complete in {} after the runner",
                    self.dir.display()
                )));
            }
        }
        self.ran.fetch_add(todo, Ordering::SeqCst);
        self.reused.fetch_add(trials.len() - todo, Ordering::SeqCst);
        names
            .iter()
            .map(|n| read_back(&layout, n, &p.scene.blocks.grade_names))
            .collect()
    }
}
