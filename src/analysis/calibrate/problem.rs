//! The calibration problem and its runs: what one engine run of a calibration is
//! ([`Trial`]), where the runs are made ([`Runs`]), and how a run's predictions become the
//! errors the fit works on (`Eval`, by [`reconcile`](crate::analysis::reconcile)).

use std::collections::BTreeMap;

use polars::prelude::*;
use rayon::prelude::*;

use super::CalibrateError;
use crate::analysis::reconcile::{floats, predicted_frame, reconcile, strings, Frames, Settings};
use crate::engine::{resolution, Engine, ResolvedResolution, RunPlan};
use crate::model::scenario::Calibration;
use crate::model::{Scenario, Scene};

/// Errors of one run: Σ e² and n per zone and overall, and the error of every matched row
/// (keyed by drawpoint and period).
#[derive(Debug, Clone)]
pub(super) struct Eval {
    /// Σ e² and n of each zone's rows.
    pub(super) zones: BTreeMap<String, (f64, usize)>,
    /// Σ e² and n of all rows.
    pub(super) all: (f64, usize),
    /// e of every matched row.
    pub(super) rows: BTreeMap<(String, i64), f64>,
    /// The drawpoint's predicted cumulative tonnes at every matched row (t).
    pub(super) drawn: BTreeMap<(String, i64), f64>,
}

impl Eval {
    /// Σ e² and n of `zone`'s rows (all rows for None or a zone no drawpoint names).
    pub(super) fn of(&self, zone: Option<&str>) -> (f64, usize) {
        zone.and_then(|z| self.zones.get(z).copied())
            .unwrap_or(self.all)
    }
}

/// The RMSE of Σ e² over n rows (NaN without rows).
pub(super) fn rmse((s, n): (f64, usize)) -> f64 {
    if n == 0 {
        f64::NAN
    } else {
        (s / n as f64).sqrt()
    }
}

/// One engine run of a calibration: the calibration tried, at h and the marker spacing
/// `finer` times the ones the scene resolves to (1: as resolved; the increment and
/// `max_marker_move` as resolved; [`Problem::resolution`]), on the scenario's marker lattice
/// or on one of its twins.
#[derive(Debug, Clone, PartialEq)]
pub struct Trial {
    /// The calibration tried.
    pub calibration: Calibration,
    /// h and the marker spacing, as multiples of the resolved ones.
    pub finer: f64,
    /// The run's marker lattice: 0 the scenario's, k ≥ 1 its k-th twin
    /// ([`Resolution::nth_twin_offset`](crate::model::scenario::Resolution::nth_twin_offset)):
    /// another sample of the same ground, to measure the markers' sampling noise.
    pub lattice: usize,
}

/// Where a calibration's engine runs are made. `predict` makes one batch (the runs of one
/// step, independent of one another) and returns each trial's predictions, in order, as
/// reconcile's `predicted` frame ([`predicted_frame`]).
pub trait Runs: Sync {
    /// The predictions of every trial of one batch.
    fn predict(&self, p: &Problem, trials: &[Trial]) -> Result<Vec<DataFrame>, CalibrateError>;
}

/// The runs in this process, a batch in parallel on rayon's pool: the library's way, on a
/// scene in memory. `caveflow calibrate` runs them as a study instead
/// ([`calibrate_runs`](crate::analysis::calibrate_runs)), with the same results.
pub struct InProcess;

impl Runs for InProcess {
    fn predict(&self, p: &Problem, trials: &[Trial]) -> Result<Vec<DataFrame>, CalibrateError> {
        trials.par_iter().map(|t| p.run_here(t)).collect()
    }
}

/// The calibration problem: a scene loaded without calibration, the scenario, the records,
/// and where the runs are made.
pub struct Problem<'a> {
    /// The scene as read (no calibration applied).
    pub scene: &'a Scene,
    /// The scenario; its `calibration` is the starting point.
    pub scenario: &'a Scenario,
    /// Records and drawpoints frames (see [`Frames`]; `predicted` is filled per run).
    pub records: &'a DataFrame,
    /// Drawpoints frame.
    pub drawpoints: &'a DataFrame,
    /// Grade fitted.
    pub grade: String,
    /// Where the engine runs are made ([`InProcess`], or a study).
    pub runs: &'a dyn Runs,
}

impl Problem<'_> {
    /// The scene with `cal` applied, and the scenario with it, as a run with `cal` sees
    /// them.
    pub fn calibrated(&self, cal: &Calibration) -> Result<(Scene, Scenario), CalibrateError> {
        let mut scene = self.scene.clone();
        cal.apply(&mut scene.blocks)
            .map_err(CalibrateError::Apply)?;
        let mut sc = self.scenario.clone();
        sc.calibration = cal.clone();
        Ok((scene, sc))
    }

    /// The marker lattice's plan offset of `t`'s run (`resolution.lattice_offset`).
    pub fn lattice_offset(&self, t: &Trial) -> [f64; 2] {
        self.scenario.resolution.nth_twin_offset(t.lattice)
    }

    /// The resolution of `t`'s run: its calibrated scene's, scaled by h and marker spacing
    /// `t.finer` ([`resolution::scaled`]), with `max_marker_move` held at the resolved
    /// value (the finer check changes the lattice and the disks, not the markers' cadence).
    pub fn resolution(&self, t: &Trial) -> Result<ResolvedResolution, CalibrateError> {
        let (scene, sc) = self.calibrated(&t.calibration)?;
        let r = resolution::resolve(&scene, &sc);
        Ok(ResolvedResolution {
            max_marker_move: r.max_marker_move,
            ..resolution::scaled(&r, [t.finer, t.finer, 1.0])
        })
    }

    /// Runs the engine for `t` here and returns its predictions.
    fn run_here(&self, t: &Trial) -> Result<DataFrame, CalibrateError> {
        let (scene, mut sc) = self.calibrated(&t.calibration)?;
        sc.resolution.lattice_offset = self.lattice_offset(t);
        let plan = RunPlan::at(&scene, &sc, self.resolution(t)?).map_err(|source| {
            CalibrateError::Engine {
                calibration: describe(&t.calibration),
                source,
            }
        })?;
        let out = Engine::with_plan(&scene, &sc, plan).run(&mut |_, _| {});
        Ok(predicted_frame(&out.extraction, &scene)?)
    }

    /// Reconciles one run's predictions with the records.
    pub(super) fn evaluate(&self, predicted: DataFrame) -> Result<Eval, CalibrateError> {
        let frames = Frames {
            predicted,
            records: self.records.clone(),
            drawpoints: self.drawpoints.clone(),
        };
        let settings = Settings {
            grades: vec![self.grade.clone()],
            dilution: None,
        };
        let r = reconcile(&frames, &settings)?;
        // Σ e² and n from the metrics reconcile already made: Σ e² = n RMSE².
        let sse = |n: f64, rmse: f64| (n * rmse * rmse, n as usize);
        let zone_rows = r
            .metrics
            .clone()
            .lazy()
            .filter(col("level").eq(lit("zone")))
            .collect()?;
        let zones = strings(&zone_rows, "key")
            .into_iter()
            .zip(
                floats(&zone_rows, "n")
                    .into_iter()
                    .zip(floats(&zone_rows, "rmse")),
            )
            .map(|(z, (n, rmse))| (z, sse(n, rmse)))
            .collect();
        let all = match r.metric("overall", "all", &self.grade, "n") {
            Some(n) => sse(n, r.overall_rmse(&self.grade)),
            None => (0.0, 0),
        };
        let period = r.rows.column("period")?.cast(&DataType::Int64)?;
        let (mut rows, mut drawn) = (BTreeMap::new(), BTreeMap::new());
        for (((d, t), e), cum) in strings(&r.rows, "drawpoint")
            .into_iter()
            .zip(period.i64()?.iter())
            .zip(floats(&r.rows, "error"))
            .zip(floats(&r.rows, "cum_tonnes"))
        {
            if let (Some(t), true) = (t, e.is_finite()) {
                drawn.insert((d.clone(), t), cum);
                rows.insert((d, t), e);
            }
        }
        Ok(Eval {
            zones,
            all,
            rows,
            drawn,
        })
    }

    /// Runs the trials as one batch and reconciles each.
    pub(super) fn eval_trials(&self, trials: &[Trial]) -> Result<Vec<Eval>, CalibrateError> {
        self.runs
            .predict(self, trials)?
            .into_par_iter()
            .map(|f| self.evaluate(f))
            .collect()
    }

    /// Runs each of `cals` on marker lattice `lattice` ([`Trial::lattice`]), as one batch.
    pub(super) fn eval_all(
        &self,
        cals: &[Calibration],
        lattice: usize,
    ) -> Result<Vec<Eval>, CalibrateError> {
        self.eval_trials(&trials_on(cals, lattice).collect::<Vec<_>>())
    }

    /// [`Problem::eval_all`] of the scenario's calibration with the zones' factors at each
    /// of `ts`.
    pub(super) fn eval_zones(
        &self,
        zones: &[String],
        ts: &[Vec<f64>],
        lattice: usize,
    ) -> Result<Vec<Eval>, CalibrateError> {
        let start = &self.scenario.calibration;
        let cals: Vec<Calibration> = ts.iter().map(|t| zones_to(start, zones, t)).collect();
        self.eval_all(&cals, lattice)
    }
}

/// A calibration in words, for messages.
pub fn describe(c: &Calibration) -> String {
    let mut parts: Vec<String> = c
        .frag_factor
        .iter()
        .map(|(k, v)| format!("frag_factor.{k}={v:.4}"))
        .collect();
    parts.push(format!("n1_factor={:.4}", c.n1_factor));
    parts.push(format!("friction_factor={:.4}", c.friction_factor));
    parts.join(" ")
}

/// The runs of `cals` at the resolved resolution on marker lattice `lattice`.
pub(super) fn trials_on(cals: &[Calibration], lattice: usize) -> impl Iterator<Item = Trial> + '_ {
    cals.iter().map(move |c| Trial {
        calibration: c.clone(),
        finer: 1.0,
        lattice,
    })
}

/// Zone `z`'s fragment factor in `c` (1 where `c` names none).
pub(super) fn frag_factor(c: &Calibration, z: &str) -> f64 {
    c.frag_factor.get(z).copied().unwrap_or(1.0)
}

/// `start` with zone k's fragment factor at `t[k]`.
pub(super) fn zones_to(start: &Calibration, zones: &[String], t: &[f64]) -> Calibration {
    let mut c = start.clone();
    for (z, &v) in zones.iter().zip(t) {
        c.frag_factor.insert(z.clone(), v);
    }
    c
}
