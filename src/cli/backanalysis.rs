//! `caveflow reconcile` and `caveflow calibrate`: the back-analysis commands (polars, behind
//! the default `analysis` feature).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::Args;

use super::{keep_periods, load, progress, scenario, InputArgs, UsageError};
use crate::analysis::calibrate::{self, CalibrateConfig, Command};
use crate::analysis::calibrate_runs::StudyRuns;
use crate::analysis::reconcile::{self, records_frame, Frames, Settings};
use crate::analysis::report::{write_report, ReportInfo};
use crate::analysis::study::runner::default_threads;
use crate::model::records::load_records;
use crate::model::{Scenario, Scene};

/// Exit code of a calibration whose fit did not lower the overall RMSE (1 is invalid
/// input, 2 any other error).
pub const CALIBRATION_FAILED: u8 = 3;

/// `caveflow reconcile`.
#[derive(Debug, Args)]
pub struct ReconcileArgs {
    /// A run's output directory (holds manifest.json and extraction.parquet).
    pub run_dir: PathBuf,
    /// Production records (Parquet or CSV; `caveflow schema production`).
    pub records: PathBuf,
    /// Where to write reconcile.parquet, reconcile_rows.parquet and report.html
    /// (default: <run-dir>/reconcile).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Grade summarised in the report (default: the `[dilution]` grade, else the first
    /// grade sampled).
    #[arg(long)]
    pub grade: Option<String>,
}

/// `caveflow calibrate`.
#[derive(Debug, Args)]
pub struct CalibrateArgs {
    /// Inputs (scenario file and overrides).
    #[command(flatten)]
    pub input: InputArgs,
    /// Production records (Parquet or CSV).
    #[arg(long)]
    pub records: PathBuf,
    /// Lithologies whose fragment-size factor is fitted (default: every lithology that is
    /// also a drawpoint zone).
    #[arg(long, value_delimiter = ',')]
    pub zones: Vec<String>,
    /// Also fit a factor on the dilated porosity n1.
    #[arg(long)]
    pub fit_n1: bool,
    /// Also fit a factor on the friction angle φ.
    #[arg(long)]
    pub fit_friction: bool,
    /// Coarse grid of fragment-size factors.
    #[arg(long, value_delimiter = ',')]
    pub coarse: Option<Vec<f64>>,
    /// Marker lattices the zones are fitted on, a whole fit on each: the factors are the
    /// fits' mean and their spread is part of the SE. 1 takes a quarter of the runs and
    /// sees less of what the markers' sampling does to the fit.
    #[arg(long, value_name = "K", default_value_t = calibrate::LATTICES as u32,
          value_parser = clap::value_parser!(u32).range(1..))]
    pub lattices: u32,
    /// Use only the first N periods (and the records inside them).
    #[arg(long, value_name = "N")]
    pub keep_periods: Option<usize>,
    /// Grade fitted (default: the `[dilution]` grade, else the first grade sampled).
    #[arg(long)]
    pub grade: Option<String>,
    /// Output directory for calibration.json, calibrated.toml and profiles.svg, and
    /// `runs/`, the engine runs as a study (`analysis::calibrate_runs`): a calibration
    /// run again into it reruns none that are complete.
    #[arg(long, default_value = "calibrate")]
    pub out: PathBuf,
    /// Runs made at once by the local runner (default: one per core).
    #[arg(long, value_name = "N")]
    pub jobs: Option<usize>,
    /// Threads of each run (default: every core, so that the last runs of a batch, alone,
    /// use them all).
    #[arg(long, value_name = "T")]
    pub threads: Option<usize>,
    /// Run each batch of runs with this command instead of locally: `CMD STUDY --out DIR`
    /// (split at spaces), e.g. `--runner "python -m caveflow_ray"`; `CAVEFLOW_BIN` is set
    /// to this caveflow.
    #[arg(long, value_name = "CMD")]
    pub runner: Option<String>,
}

/// The scenario a run was made with, from its manifest.
fn run_scenario(run_dir: &Path) -> Result<Scenario> {
    let path = run_dir.join("manifest.json");
    // A run directory that is not one is invalid input, like a missing scenario: exit 1.
    let text = std::fs::read_to_string(&path).map_err(|e| {
        UsageError(format!(
            "{}: not a caveflow run directory: {e}",
            path.display()
        ))
    })?;
    let v: serde_json::Value =
        serde_json::from_str(&text).with_context(|| path.display().to_string())?;
    let sc = v
        .get("scenario")
        .cloned()
        .with_context(|| format!("{}: no scenario", path.display()))?;
    serde_json::from_value(sc).with_context(|| format!("{}: scenario", path.display()))
}

/// The grades both tables hold, and the one summarised.
fn grades(
    scene: &Scene,
    sampled: &[String],
    sc: &Scenario,
    asked: Option<&str>,
) -> Result<(Vec<String>, String)> {
    let both: Vec<String> = sampled
        .iter()
        .filter(|g| scene.blocks.grade_names.contains(g))
        .cloned()
        .collect();
    if both.is_empty() {
        return Err(UsageError(format!(
            "the records sample none of the block model's grades ({})",
            scene.blocks.grade_names.join(", ")
        ))
        .into());
    }
    let main = match asked {
        Some(g) if both.iter().any(|b| b == g) => g.to_string(),
        Some(g) => {
            return Err(UsageError(format!(
                "grade {g:?} is not sampled in the records (they hold {})",
                both.join(", ")
            ))
            .into())
        }
        None => match &sc.dilution.grade {
            Some(g) if both.contains(g) => g.clone(),
            _ => both[0].clone(),
        },
    };
    Ok((both, main))
}

pub(super) fn reconcile_cmd(a: ReconcileArgs) -> Result<ExitCode> {
    let sc = run_scenario(&a.run_dir)?;
    let Some(loaded) = load(&sc) else {
        return Ok(ExitCode::from(1));
    };
    let scene = &loaded.scene;
    let records = match load_records(
        &a.records,
        &scene.drawpoints,
        &scene.periods,
        &scene.blocks.grade_names,
    ) {
        Ok(r) => r,
        Err(problems) => {
            eprintln!("{} problem(s) in the records:", problems.0.len());
            eprintln!("{problems}");
            return Ok(ExitCode::from(1));
        }
    };
    let (compared, main) = grades(scene, &records.grade_names, &sc, a.grade.as_deref())?;
    let frames = Frames {
        predicted: reconcile::read_predicted(&a.run_dir.join("extraction.parquet"), &compared)?,
        records: records_frame(&records, &scene.drawpoints)?,
        drawpoints: reconcile::drawpoints_frame(&scene.drawpoints)?,
    };
    let settings = Settings {
        grades: compared,
        dilution: sc.dilution.grade.clone().map(|g| (g, sc.dilution.cutoff)),
    };
    let r = reconcile::reconcile(&frames, &settings)?;
    let out = a.out.unwrap_or_else(|| a.run_dir.join("reconcile"));
    std::fs::create_dir_all(&out).with_context(|| out.display().to_string())?;
    reconcile::write_reconciliation(&out, &r)?;
    let info = ReportInfo {
        title: format!("Reconciliation: {} drawpoints", scene.drawpoints.len()),
        sources: vec![
            format!("run: {}", a.run_dir.display()),
            format!("records: {}", a.records.display()),
        ],
        grade: main.clone(),
    };
    let page = write_report(&out, &r, scene, &info)?;
    let m = |k| r.metric("overall", "all", &main, k).unwrap_or(f64::NAN);
    println!(
        "{main}: {:.0} drawpoint-periods, bias {:+.4}%, RMSE {:.4}%, r {:.2}",
        m("n"),
        m("bias"),
        m("rmse"),
        m("correlation")
    );
    println!(
        "wrote {} and {}",
        out.join("reconcile.parquet").display(),
        page.display()
    );
    Ok(ExitCode::SUCCESS)
}

pub(super) fn calibrate_cmd(a: CalibrateArgs) -> Result<ExitCode> {
    let sc = scenario(&a.input)?;
    // The scene as read: the calibration is applied per run, from the scenario's start.
    let mut raw = sc.clone();
    raw.calibration = Default::default();
    let Some(mut loaded) = load(&raw) else {
        return Ok(ExitCode::from(1));
    };
    let records = match load_records(
        &a.records,
        &loaded.scene.drawpoints,
        &loaded.scene.periods,
        &loaded.scene.blocks.grade_names,
    ) {
        Ok(r) => r,
        Err(problems) => {
            eprintln!("{} problem(s) in the records:", problems.0.len());
            eprintln!("{problems}");
            return Ok(ExitCode::from(1));
        }
    };
    if !keep_periods(&mut loaded.scene, a.keep_periods) {
        return Ok(ExitCode::from(1));
    }
    let scene = &loaded.scene;
    let (_, grade) = grades(scene, &records.grade_names, &sc, a.grade.as_deref())?;
    let jobs = a.jobs.unwrap_or_else(|| default_threads(1));
    let runner: Option<Vec<String>> = a
        .runner
        .as_deref()
        .map(|c| c.split_whitespace().map(String::from).collect());
    if jobs == 0 || a.threads == Some(0) || runner.as_ref().is_some_and(|c| c.is_empty()) {
        return Err(UsageError(
            "--jobs and --threads must be at least 1, and --runner a command".into(),
        )
        .into());
    }
    let mut config = CalibrateConfig {
        zones: a.zones,
        fit_n1: a.fit_n1,
        fit_friction: a.fit_friction,
        lattices: a.lattices as usize,
        ..CalibrateConfig::default()
    };
    if let Some(c) = a.coarse {
        config.coarse = c;
    }
    let runs = StudyRuns::new(
        &a.out.join("runs"),
        &sc,
        a.keep_periods,
        jobs,
        a.threads.unwrap_or_else(|| default_threads(1)),
        runner,
    )?;
    let command = Command {
        scenario: &sc,
        scene,
        records: &records,
        grade,
        config,
        runs: &runs,
        out: &a.out,
    };
    let bar = progress(0, "runs");
    let done = command.run(&mut |done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    })?;
    bar.finish_and_clear();
    let report = &done.report;
    for f in &report.parameters {
        let mut res = if f.se_resolution.is_finite() {
            format!(
                ", of which resolution {:.3} and marker sampling {:.3}",
                f.se_resolution, f.se_lattice
            )
        } else {
            String::new()
        };
        if !f.lattice_values.is_empty() {
            let each: Vec<String> = f.lattice_values.iter().map(|v| format!("{v:.3}")).collect();
            res += &format!("; on each lattice {}", each.join(", "));
        }
        println!(
            "{}: {:.3} → {:.3} ± {:.3}{res} (95%: {:.3}–{:.3}); RMSE of its {} rows {:.4}% → {:.4}%",
            f.name, f.start, f.value, f.se, f.ci95[0], f.ci95[1], f.n, f.rmse_before, f.rmse_after
        );
    }
    println!(
        "overall {} RMSE {:.4}% → {:.4}% over {} drawpoint-periods, {} runs; the model's own noise {:.4}%, the records' {:.4}%",
        report.grade,
        report.rmse_before,
        report.rmse_after,
        report.n,
        report.runs,
        report.model_noise,
        report.records_noise
    );
    for z in &report.diagnosis.zones {
        let largest = z
            .shape_t
            .iter()
            .filter(|t| t.is_finite())
            .fold(0.0f64, |m, t| m.max(t.abs()));
        println!(
            "zone {} ({} drawpoints): RMSE {:.4}% before, {:.4}% in the fit, {:.4}% held out (skill {:.2}); shape along the draw |t| ≤ {largest:.1} (noise limit {:.1}); autocorrelation {:.2} (noise {:.2})",
            z.zone,
            z.drawpoints,
            z.rmse_before,
            z.rmse_fit,
            z.rmse_held_out,
            z.skill,
            z.shape_limit,
            z.autocorrelation,
            z.autocorrelation_noise
        );
    }
    let (ran, reused) = runs.counts();
    println!(
        "{ran} run(s) made, {reused} complete already in {}",
        runs.dir().display()
    );
    for w in &done.warnings {
        eprintln!("warning: {w}");
    }
    if !report.lowered {
        eprintln!(
            "calibration failed: the fit does not lower the overall {} RMSE ({:.4}% → {:.4}%), so it is no calibration; no calibrated.toml written. The profiles are in {} and {}",
            report.grade,
            report.rmse_before,
            report.rmse_after,
            a.out.join("calibration.json").display(),
            a.out.join("profiles.svg").display()
        );
        return Ok(ExitCode::from(CALIBRATION_FAILED));
    }
    println!("wrote {}", a.out.join("calibrated.toml").display());
    Ok(ExitCode::SUCCESS)
}
