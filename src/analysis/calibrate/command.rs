//! `caveflow calibrate`'s work around the fit ([`calibrate`](super::calibrate())): the
//! zones fitted by default, the records inside the periods kept, the files written
//! (`calibration.json`, `calibrated.toml`, `profiles.svg`) and the warnings the result
//! calls for. The CLI parses the arguments, loads the inputs, makes the runs' study
//! ([`StudyRuns`](crate::analysis::calibrate_runs::StudyRuns), which builds on this
//! module's [`Runs`]), calls [`Command::run`] and prints.

use std::path::Path;

use polars::prelude::{col, lit, DataFrame, IntoLazy};

use super::{calibrate, CalibrateConfig, CalibrateError, CalibrationReport, Problem, Runs};
use crate::analysis::reconcile::{drawpoints_frame, records_frame, ReconcileError};
use crate::model::records::ProductionRecords;
use crate::model::{Scenario, Scene};
use crate::output::charts::{profile_chart, Profile};

/// One `caveflow calibrate`: the inputs loaded, what to fit, where the runs are made and
/// where the files go.
pub struct Command<'a> {
    /// The scenario; its `calibration` is the starting point.
    pub scenario: &'a Scenario,
    /// The scene loaded without calibration, cut to the periods kept.
    pub scene: &'a Scene,
    /// The production records.
    pub records: &'a ProductionRecords,
    /// Grade fitted.
    pub grade: String,
    /// What to fit; no zones fits [`default_zones`].
    pub config: CalibrateConfig,
    /// Where the engine runs are made (`caveflow calibrate`: a study in `OUT/runs`).
    pub runs: &'a dyn Runs,
    /// The output directory of the files.
    pub out: &'a Path,
}

/// What a calibration did.
pub struct Outcome {
    /// The fit.
    pub report: CalibrationReport,
    /// What limits the result ([`warnings`]), one sentence each.
    pub warnings: Vec<String>,
}

/// The lithologies fitted when none are named: every lithology that is also a drawpoint
/// zone.
pub fn default_zones(scene: &Scene) -> Vec<String> {
    scene
        .blocks
        .lithology_names
        .iter()
        .filter(|l| scene.drawpoints.zone.contains(l))
        .cloned()
        .collect()
}

/// The records as reconcile's frame, without those past the scene's last period (dated
/// ones simply find no match).
pub fn records_kept(
    records: &ProductionRecords,
    scene: &Scene,
) -> Result<DataFrame, CalibrateError> {
    let last = scene.periods.id.last().copied().unwrap_or(0);
    Ok(records_frame(records, &scene.drawpoints)?
        .lazy()
        .filter(col("period").is_null().or(col("period").lt_eq(lit(last))))
        .collect()?)
}

impl Command<'_> {
    /// Fits, and writes the files into `out`. `progress(done, total)` after each batch of
    /// runs.
    pub fn run(
        self,
        progress: &mut (dyn FnMut(usize, usize) + Send),
    ) -> Result<Outcome, CalibrateError> {
        let mut cfg = self.config;
        if cfg.zones.is_empty() {
            cfg.zones = default_zones(self.scene);
        }
        let records = records_kept(self.records, self.scene)?;
        let drawpoints = drawpoints_frame(&self.scene.drawpoints)?;
        let problem = Problem {
            scene: self.scene,
            scenario: self.scenario,
            records: &records,
            drawpoints: &drawpoints,
            grade: self.grade,
            runs: self.runs,
        };
        let report = calibrate(&problem, &cfg, progress)?;
        std::fs::create_dir_all(self.out).map_err(|source| ReconcileError::Io {
            path: self.out.to_path_buf(),
            source,
        })?;
        write_calibration(self.out, &report, self.scenario)?;
        write_profiles(&self.out.join("profiles.svg"), &report)?;
        Ok(Outcome {
            warnings: warnings(&report),
            report,
        })
    }
}

/// The profiles chart: each parameter's RMSE against its factor, the fitted value, its
/// 95% interval and its start.
pub fn write_profiles(path: &Path, report: &CalibrationReport) -> Result<(), CalibrateError> {
    let profiles: Vec<Profile> = report
        .parameters
        .iter()
        .map(|f| Profile {
            name: f.name.clone(),
            points: f.profile.iter().map(|p| (p[0], p[1])).collect(),
            fitted: f.value,
            ci95: (f.ci95[0], f.ci95[1]),
            start: f.start,
        })
        .collect();
    profile_chart(
        path,
        &profiles,
        &format!(
            "Calibration profiles: {} RMSE against each factor",
            report.grade
        ),
    )
    .map_err(ReconcileError::from)?;
    Ok(())
}

/// What limits a result, one sentence each: structure in the residuals (the model does
/// not explain the records; [`diagnosis`](super::diagnosis)), a fit that predicts held-out
/// drawpoints no better than the start, the model's own noise not below the records' (the
/// fit cannot resolve them), and each factor whose resolution or lattice part of the SE
/// exceeds its statistical part.
pub fn warnings(report: &CalibrationReport) -> Vec<String> {
    let mut out = Vec::new();
    let d = &report.diagnosis;
    let stretch = |s: usize| {
        format!(
            "{:.0}–{:.0} t drawn",
            d.stretches.get(s).copied().unwrap_or(f64::NAN),
            d.stretches.get(s + 1).copied().unwrap_or(f64::NAN)
        )
    };
    for z in &d.zones {
        let who = if z.zone == super::diagnosis::ALL {
            "every drawpoint together".to_string()
        } else {
            format!("zone {}", z.zone)
        };
        if !z.shaped.is_empty() {
            let parts: Vec<String> = z
                .shaped
                .iter()
                .map(|&s| {
                    format!(
                        "{} ({:+.4}% {}, t {:.1})",
                        stretch(s),
                        z.shape[s],
                        report.grade,
                        z.shape_t[s]
                    )
                })
                .collect();
            out.push(format!(
                "the model does not explain the records of {who}: {} drawpoints share an error along the draw at {} (beyond the |t| of {:.1} that noise alone passes 5% of the time, p = {:.3}): the factors absorb a difference between model and process, and their intervals measure noise only",
                z.drawpoints,
                parts.join(", "),
                z.shape_limit,
                z.shape_p
            ));
        }
        if z.autocorrelated {
            out.push(format!(
                "the model does not explain the records of {who}: the errors run in streaks along each drawpoint's draw (lag-one autocorrelation {:.2} ± {:.2}, where the model's own noise gives {:.2}): the factors' intervals measure noise only",
                z.autocorrelation, z.autocorrelation_se, z.autocorrelation_noise
            ));
        }
        if z.skill < 0.0 {
            out.push(format!(
                "the fit predicts the drawpoints of {who} no better than the start when each is held out of it (RMSE {:.4}% held out, {:.4}% in the fit, {:.4}% before): the fitted factors do not carry to drawpoints they have not seen",
                z.rmse_held_out, z.rmse_fit, z.rmse_before
            ));
        }
    }
    if !report.resolution_adequate {
        out.push(format!(
            "the model's own noise at this resolution ({:.4}% {}) is not below the records' ({:.4}%): the fit cannot resolve what the records say; calibrate at a finer resolution (resolution.marker_spacing)",
            report.model_noise, report.grade, report.records_noise
        ));
    }
    for f in &report.parameters {
        let stat = (f.se * f.se - f.se_resolution.powi(2) - f.se_lattice.powi(2))
            .max(0.0)
            .sqrt();
        if f.se_resolution > stat {
            out.push(format!(
                "{} moves by {:.3} between this resolution and a finer one, more than its statistical SE {stat:.3}: its value is limited by the resolution",
                f.name, f.se_resolution
            ));
        }
        if f.se_lattice > stat {
            out.push(format!(
                "{}'s fits on the marker lattices leave its mean uncertain by {:.3}, more than its statistical SE {stat:.3}: its value is limited by the markers' sampling (a finer resolution narrows it)",
                f.name, f.se_lattice
            ));
        }
    }
    out
}

/// Writes `calibration.json` (the report) and, when the fit lowered the overall RMSE,
/// `calibrated.toml` (the scenario with the fitted `[calibration]`, to run again) into
/// `dir`, atomically. A fit that did not lower it leaves no `calibrated.toml` (one from an
/// earlier calibration into `dir` is removed, so none is mistaken for this one's result).
pub fn write_calibration(
    dir: &Path,
    report: &CalibrationReport,
    scenario: &Scenario,
) -> Result<(), CalibrateError> {
    let io = |e: crate::output::OutputError| CalibrateError::Reconcile(e.into());
    let json = serde_json::to_string_pretty(report)
        .map_err(|e| CalibrateError::Input(format!("calibration report: {e}")))?;
    crate::output::parquet::write_atomic(&dir.join("calibration.json"), json.as_bytes())
        .map_err(io)?;
    let toml_path = dir.join("calibrated.toml");
    if !report.lowered {
        return match std::fs::remove_file(&toml_path) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(CalibrateError::Input(
                format!("{}: {e}", toml_path.display()),
            )),
            _ => Ok(()),
        };
    }
    let mut sc = scenario.clone();
    sc.calibration = report.calibration.clone();
    let toml = toml::to_string(&sc)
        .map_err(|e| CalibrateError::Input(format!("calibrated scenario: {e}")))?;
    let text = format!(
        "# Written by `caveflow calibrate`: the input scenario with the fitted [calibration].\n\
         # Overall {} RMSE {:.5}% before, {:.5}% after, over {} drawpoint-periods.\n{toml}",
        report.grade, report.rmse_before, report.rmse_after, report.n
    );
    crate::output::parquet::write_atomic(&toml_path, text.as_bytes()).map_err(io)?;
    Ok(())
}
