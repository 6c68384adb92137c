//! Calibration: fit inputs to production records by running the engine many times, a
//! batch of independent runs at a time, and reconciling each run (DESIGN §6; summary §8,
//! where the Primos fragment size was found by trying 0.23 m and 0.04 m by hand). Where a
//! batch runs is the [`Runs`] given: [`InProcess`] (rayon over the runs), or a study
//! ([`calibrate_runs`](super::calibrate_runs), what `caveflow calibrate` uses), with the
//! same results.
//!
//! # What is fitted
//! - a multiplicative factor f_z on the mean primary fragment size d̄ of each chosen
//!   lithology z (`[calibration] frag_factor`), which sets how fast each IMZ widens through
//!   the r-law and so where dilution enters;
//! - optionally one factor on the dilated porosity n1 and one on the friction angle φ of
//!   every block (`n1_factor`, `friction_factor`).
//!
//! # How
//! The objective is the sum of squared grade errors S = Σ e² (e = predicted − sampled, the
//! rows of [`reconcile`](super::reconcile)) over every matched drawpoint-period.
//!
//! 1. **coarse**: one run per value of the coarse grid, every fitted zone set to that value;
//!    each zone takes the value that minimises S over the rows of the drawpoints whose
//!    `zone` it is (all rows when no drawpoint names it). This is a starting point only:
//!    with every zone at one value, a zone's rows also feel its neighbours' factor (a
//!    drawpoint near a contact draws both lithologies), so when several zones are away from
//!    1, each zone's coarse best is pulled towards the others'.
//!
//!    1b. **one zone at a time** (several zones): each zone over the coarse grid with the
//!    others at their coarse best, K × grid runs; each zone takes its best on all rows.
//!    This finds the right valley where the first pass has two (on the three-zone truth of
//!    the tests with records from a run at 0.7 times the fit's h and spacing, Primos' coarse
//!    best was 0.8 against a truth of 1.3, and the joint step stayed in that valley).
//! 2. **joint**: the zone factors θ together, by Gauss–Newton on the residuals of all rows
//!    ([`least_squares`](super::least_squares)). Each iteration runs the centre and every
//!    zone at θ_k (1 ± h) with the others at the centre (2K + 1 runs in one parallel batch,
//!    K zones). The residuals and the Jacobian J = ∂e/∂θ at the centre are, row by row, the
//!    least-squares plane e = a + J (θ − centre) through every run made so far within 20%
//!    of the centre on every factor (the coarse grid's and 1b's runs count): a regression
//!    over many runs, not a difference of two. The step goes to the minimum of the
//!    linearised S, no factor moving by more than 30% and none leaving the coarse grid's
//!    range. h is 15%, then 10%: the engine's response is ragged at the scale of single
//!    markers (a slightly wider IMZ hands a few markers to a neighbour), so the probes must
//!    span many markers' worth. Up to 3 iterations, fewer when no factor moves by 1%. The
//!    result is the last step's minimum of the *linearised* S, not the best run seen: on a
//!    ragged surface the lowest of many runs is the one whose markers happened to fall best
//!    (on the tests' three-zone truth, picking the best run put Urad at 0.720 ± 0.012
//!    against a truth of 0.75; the linearised minimum gives 0.751). J's off-diagonal terms
//!    are how the zones' influence on one another enters.
//!
//!    Steps 1 and 2 are made whole on each of K marker lattices
//!    ([`CalibrateConfig::lattices`], 4 by default: the scenario's and its first three
//!    twins, below), and each zone's factor is the mean of the K fits ("Lattice"). The K
//!    fits are made at once, their batches of each step merged into one
//!    ([`lockstep`](super::lockstep)): the runner sees a K-th of their batches, K times
//!    larger, and each fit is what it would be alone.
//! 3. **globals** (when asked): n1 then φ factors, each on a grid around 1 with the zones
//!    fixed, judged on all rows; θ̂ from the profile's parabola (below).
//! 4. a run at the fitted values gives the error after, the same run on three other marker
//!    lattices the model's own noise, and a run at finer resolution the resolution's part of
//!    the uncertainty (below).
//!
//! # Uncertainty
//! **Zones.** With A = JᵀJ at the last iteration and the residuals of the run at θ̂, the
//! statistical covariance is the larger (on the diagonal) of σ̂² A⁻¹, σ̂² = S / (n − K), and
//! the cluster-robust covariance with one cluster per drawpoint
//! ([`least_squares`](super::least_squares): a drawpoint's errors are correlated over its
//! periods). Their correlation matrix is reported.
//!
//! **Resolution.** The records come from ground, not from a run at the fit's resolution,
//! so the fit also absorbs what the resolution gets wrong. A run at θ̂ with h and the marker
//! spacing × 2^(−1/2) (2.8 times the markers, twice as many disks) measures it: the
//! Gauss–Newton step −A⁻¹ Jᵀ (e_finer − e_fit) is how far the factors would move had the
//! fit been made at the finer resolution. Its size is each factor's `se_resolution`, added
//! in quadrature to the statistical SE. It is a lower bound of the resolution's error (a
//! run converged in resolution would move the factors further).
//!
//! **Lattice.** The markers sample the ground at their lattice's sites, and a fit made with
//! one lattice leans on that sample's noise in the same way in every trial run (the same
//! markers fall the same way), so it is biased by it, beyond what the residuals' scatter
//! shows. The zones are therefore fitted whole on K lattices, each another sample of the
//! same ground, and each factor is the K fits' mean; its `se_lattice` is the standard
//! error of that mean (the fits' sample standard deviation over √K), added in quadrature.
//! It has K − 1 degrees of freedom, so with the default 4 it is itself uncertain by about
//! 40%. On the three-zone truth of the tests (twice the default h and spacing, records from
//! a run at half the fit's spacing), one set of records fitted on four lattices gave
//! contact 0.81–1.21 (standard deviation 0.19) and Primos 1.03–1.28 (0.11). Each single fit
//! said its lattice part was 0.02–0.06: the estimate with K = 1, below, reads the other
//! lattices through the fit's own Jacobian, and on a surface ragged at the scale of single
//! markers that Jacobian does not say where another lattice's fit lands. With one lattice,
//! such fits missed the truth by up to 8 of their SEs (`docs::validation`,
//! "Back-analysis").
//!
//! With K = 1 (a quarter of the runs), the runs at θ̂ on the three twin lattices (below)
//! give the estimate: the step −A⁻¹ Jᵀ (e_twin − e_fit) is how far the factors would move
//! had the fit been made on a twin lattice, the difference of two equally noisy fits, so
//! √2 times one fit's part; `se_lattice` is the RMS of the three steps over √2.
//!
//! **Noise.** The model's own noise is the markers' sampling noise (`docs::resolution`,
//! "Sampling noise"). The run at θ̂ is made once more on each twin lattice, moved in plan by
//! k × [`TWIN_OFFSET`](crate::model::scenario::TWIN_OFFSET), k = 1, 2, 3: each an equally
//! good sample of the same ground, √2 times the noise away from the first, so the noise is
//! the RMS of e_twin − e_fit over the rows of all three, over √2. The records' noise is
//! what is left beside it, √(RMSE² − model²): when the model's noise is not below the
//! records', the fit cannot resolve what the records say, and `calibrate` says so.
//! Measured with the finer run instead, RMS(e_finer − e_fit)/√2, the model's noise came
//! out 2–15% low (the finer run's own noise is smaller, and two unequal noises are not √2
//! one of them apart), and the records' 8% high when they came from a finer run. A
//! drawpoint's errors are correlated over its periods, so one pair is a rough sample of
//! the noise: on the whole demo the pairs of five lattice offsets lie 1.3–1.9% apart over
//! √2 (`docs::resolution`, "Sampling noise").
//!
//! **Globals.** Near its minimum each profile is a parabola, S(θ) ≈ S_min + a (θ − θ̂)²,
//! fitted by least squares to the evaluated points within 30% of the best one. As in
//! nonlinear least squares, a = Σ (∂e/∂θ)² and σ̂² = S_min / (n − 1), so the noise gives θ̂ a
//! standard error σ̂ / √a; the vertex's spread under the points' scatter about the parabola
//! (the regression's covariance) is added in quadrature. Where the profile has a flat
//! valley, the profile interval is taken too: the evaluated values whose S lies within
//! χ²₁(95%) = 3.84 σ̂² of the best, widened to the next evaluated value on each side; the SE
//! is the larger of the curvature's and the interval's half-width / 1.96.
//!
//! Every parameter's profile points are reported, so a flat or two-valleyed surface is
//! seen, not hidden behind one number: a zone's are its rows' RMSE at the coarse grid and
//! at every run where only its factor differed from a centre (steps 1b and 2).

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Mutex;

use nalgebra::{DMatrix, DVector};
use polars::prelude::*;
use rayon::prelude::*;

use super::least_squares::Linearised;
use super::lockstep::Lockstep;
use super::reconcile::{
    floats, predicted_frame, reconcile, strings, Frames, ReconcileError, Settings,
};
use crate::engine::{Engine, EngineError, ResolvedResolution, RunPlan};
use crate::model::scenario::Calibration;
use crate::model::{Scenario, Scene};

/// Why calibration failed.
#[derive(Debug, thiserror::Error)]
pub enum CalibrateError {
    /// The engine refused a run.
    #[error("run with {calibration}: {source}")]
    Engine {
        /// The calibration tried.
        calibration: String,
        /// Cause.
        source: EngineError,
    },
    /// A calibration could not be applied.
    #[error("{0}")]
    Apply(String),
    /// Reconciling a run failed.
    #[error(transparent)]
    Reconcile(#[from] ReconcileError),
    /// Nothing to fit, or no rows matched.
    #[error("{0}")]
    Input(String),
    /// The runs could not be made or read back (`calibrate_runs`: a study that failed, a
    /// runner command that did).
    #[error("calibration runs: {0}")]
    Runs(String),
}

impl From<PolarsError> for CalibrateError {
    fn from(e: PolarsError) -> Self {
        CalibrateError::Reconcile(ReconcileError::Frame(e))
    }
}

/// What to fit and where to look.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrateConfig {
    /// Lithologies whose fragment-size factor is fitted.
    pub zones: Vec<String>,
    /// Fit a factor on n1.
    pub fit_n1: bool,
    /// Fit a factor on φ.
    pub fit_friction: bool,
    /// Coarse grid of fragment-size factors; its ends bound the joint fit.
    pub coarse: Vec<f64>,
    /// Grid of n1 and φ factors.
    pub global: Vec<f64>,
    /// Marker lattices the zones are fitted on, each fit made whole on its own lattice;
    /// the zone factors are the fits' mean (module docs, "Lattice"). 1 fits on the
    /// scenario's lattice alone, at a quarter of the runs, and says less of what the
    /// markers' sampling does to the fit.
    pub lattices: usize,
}

impl Default for CalibrateConfig {
    fn default() -> Self {
        CalibrateConfig {
            zones: Vec::new(),
            fit_n1: false,
            fit_friction: false,
            coarse: vec![0.4, 0.6, 0.8, 1.0, 1.25, 1.5],
            global: vec![0.9, 0.95, 1.0, 1.05, 1.1],
            lattices: LATTICES,
        }
    }
}

/// One parameter's fit.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Fitted {
    /// `frag_factor.<lithology>`, `n1_factor` or `friction_factor`.
    pub name: String,
    /// Value before calibration.
    pub start: f64,
    /// Fitted value θ̂.
    pub value: f64,
    /// Standard error of θ̂ (module docs, "Uncertainty"; NaN when there is no minimum).
    pub se: f64,
    /// The part of `se` that the resolution gives: how far the factor would move had it
    /// been fitted at 2^(−1/2) times the marker spacing (zone factors; NaN for the global
    /// ones). Part of `se` in quadrature.
    pub se_resolution: f64,
    /// The part of `se` that the markers' sampling gives: the standard error of the mean of
    /// the fits on [`CalibrateConfig::lattices`] lattices (on one, how far the factor
    /// would move had it been fitted on another, over √2; module docs, "Lattice"). Zone
    /// factors; NaN for the global ones. `se` is the statistical SE, this and
    /// `se_resolution` in quadrature.
    pub se_lattice: f64,
    /// The fit on each marker lattice, the scenario's first (zone factors with more than
    /// one lattice; empty otherwise): `value` is their mean.
    pub lattice_values: Vec<f64>,
    /// 95% interval: θ̂ ± 1.96 SE and the profile interval, whichever reaches further.
    pub ci95: [f64; 2],
    /// Rows the parameter is judged on.
    pub n: usize,
    /// The profile: (value, RMSE of the rows it is judged on), sorted by value.
    pub profile: Vec<[f64; 2]>,
    /// RMSE of its rows before and after.
    pub rmse_before: f64,
    /// RMSE after.
    pub rmse_after: f64,
}

/// The result of a calibration.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CalibrationReport {
    /// Grade fitted.
    pub grade: String,
    /// The parameters.
    pub parameters: Vec<Fitted>,
    /// Correlation matrix of the zone factors, in the order of their parameters.
    pub correlation: Vec<Vec<f64>>,
    /// Overall RMSE before (at the scenario's own calibration).
    pub rmse_before: f64,
    /// Overall RMSE after (at the fitted values).
    pub rmse_after: f64,
    /// The model's own noise: the markers' sampling noise of a row's predicted grade, the
    /// RMS change between the fit's run and its twins (the same run on other lattice
    /// offsets) over √2.
    pub model_noise: f64,
    /// The records' noise left when the model's is taken out of the RMSE after:
    /// √(RMSE² − model_noise²).
    pub records_noise: f64,
    /// Whether the model's noise at this resolution is below the records' (otherwise the
    /// fit cannot resolve what the records say: fit at a finer resolution).
    pub resolution_adequate: bool,
    /// Rows compared.
    pub n: usize,
    /// Engine runs the fit evaluated (`caveflow calibrate` reuses those its study layout
    /// holds complete already, and says how many it ran).
    pub runs: usize,
    /// Whether the fit lowered the overall RMSE. A fit that does not is no calibration:
    /// it is reported, with its profiles, and no `calibrated.toml` is written.
    pub lowered: bool,
    /// The fitted calibration.
    #[serde(skip)]
    pub calibration: Calibration,
}

/// The profile points within this factor of the best one make the parabola's fit.
const BRACKET: f64 = 1.3;
/// The 95% point of χ² with one degree of freedom.
const CHI2_95: f64 = 3.84;

/// Errors of one run: Σ e² and n per zone and overall, and the error of every matched row
/// (keyed by drawpoint and period).
#[derive(Debug, Clone)]
struct Eval {
    zones: BTreeMap<String, (f64, usize)>,
    all: (f64, usize),
    rows: BTreeMap<(String, i64), f64>,
}

impl Eval {
    fn of(&self, zone: Option<&str>) -> (f64, usize) {
        zone.and_then(|z| self.zones.get(z).copied())
            .unwrap_or(self.all)
    }
}

fn rmse((s, n): (f64, usize)) -> f64 {
    if n == 0 {
        f64::NAN
    } else {
        (s / n as f64).sqrt()
    }
}

/// One engine run of a calibration: the calibration tried, at h and the marker spacing
/// `finer` times the ones the scene resolves to (1: as resolved; the increment and
/// `max_marker_move` as resolved), on the scenario's marker lattice or on one of its twins.
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
/// ([`calibrate_runs`](super::calibrate_runs)), with the same results.
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

    /// The resolution of `t`'s run: h and the marker spacing `t.finer` times the ones its
    /// calibrated scene resolves to, the increment and `max_marker_move` as resolved.
    pub fn resolution(&self, t: &Trial) -> Result<ResolvedResolution, CalibrateError> {
        let (scene, sc) = self.calibrated(&t.calibration)?;
        let r = crate::engine::resolution::resolve(&scene, &sc);
        Ok(ResolvedResolution {
            layer_thickness: t.finer * r.layer_thickness,
            marker_spacing: t.finer * r.marker_spacing,
            ..r
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
    fn evaluate(&self, predicted: DataFrame) -> Result<Eval, CalibrateError> {
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
        let rows = strings(&r.rows, "drawpoint")
            .into_iter()
            .zip(period.i64()?.iter())
            .zip(floats(&r.rows, "error"))
            .filter_map(|((d, t), e)| Some(((d, t?), e)).filter(|_| e.is_finite()))
            .collect();
        Ok(Eval { zones, all, rows })
    }

    /// Runs the trials as one batch and reconciles each.
    fn eval_trials(&self, trials: &[Trial]) -> Result<Vec<Eval>, CalibrateError> {
        self.runs
            .predict(self, trials)?
            .into_par_iter()
            .map(|f| self.evaluate(f))
            .collect()
    }

    /// Runs each of `cals` on marker lattice `lattice` ([`Trial::lattice`]), as one batch.
    fn eval_all(&self, cals: &[Calibration], lattice: usize) -> Result<Vec<Eval>, CalibrateError> {
        self.eval_trials(&trials_on(cals, lattice).collect::<Vec<_>>())
    }

    /// [`Problem::eval_all`] of the scenario's calibration with the zones' factors at each
    /// of `ts`.
    fn eval_zones(
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

/// A parameter's profile: (value, (Σ e², n)) per run.
type Profile = Vec<(f64, (f64, usize))>;

/// The value with the least Σ e² (1 for an empty profile).
fn argmin(prof: &Profile) -> f64 {
    prof.iter()
        .min_by(|a, b| a.1 .0.total_cmp(&b.1 .0))
        .map_or(1.0, |p| p.0)
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

/// θ̂ and its standard error from the profile points inside `bracket` (see the module
/// docs); `None` when fewer than 3 points or the parabola does not open upwards.
///
/// The standard error adds two parts in quadrature: the noise part σ̂ / √a, and the fit
/// part, the spread of the vertex −b / 2a that the points' scatter about the parabola
/// allows (the regression's covariance of a and b, propagated). The engine's response to a
/// factor is not smooth at the scale of single markers (a slightly wider IMZ hands a few
/// markers to a neighbour), so the profile is ragged about its trend; the fit part says by
/// how much that moves θ̂.
fn parabola(points: &[(f64, (f64, usize))], bracket: (f64, f64)) -> Option<(f64, f64)> {
    let near: Vec<(f64, f64, usize)> = points
        .iter()
        .filter(|(t, _)| *t >= bracket.0 && *t <= bracket.1)
        .map(|&(t, (s, n))| (t, s, n))
        .collect();
    let m = near.len();
    if m < 3 {
        return None;
    }
    // Least squares for s = a x² + b x + c, x = t − t0 centred for conditioning.
    let t0 = near.iter().map(|p| p.0).sum::<f64>() / m as f64;
    let mut xtx = nalgebra::Matrix3::<f64>::zeros();
    let mut xts = nalgebra::Vector3::<f64>::zeros();
    for &(t, s, _) in &near {
        let x = t - t0;
        let row = nalgebra::Vector3::new(x * x, x, 1.0);
        xtx += row * row.transpose();
        xts += row * s;
    }
    let inv = xtx.try_inverse()?;
    let coef = inv * xts;
    let (a, b, c) = (coef[0], coef[1], coef[2]);
    if !(a > 0.0) {
        return None;
    }
    // Never outside the points fitted: a profile still falling at the edge of the grid
    // puts θ̂ at that edge (and its interval says how far the data let it go).
    let (t_lo, t_hi) = near
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| {
            (l.min(p.0), h.max(p.0))
        });
    let x_hat = (-b / (2.0 * a)).clamp(t_lo - t0, t_hi - t0);
    let s_min = (a * x_hat * x_hat + b * x_hat + c).max(0.0);
    let n = near[0].2;
    if n < 2 {
        return None;
    }
    let noise = s_min / (n - 1) as f64 / a;
    let fit = if m > 3 {
        let rss: f64 = near
            .iter()
            .map(|&(t, s, _)| {
                let x = t - t0;
                (s - (a * x * x + b * x + c)).powi(2)
            })
            .sum();
        let cov = inv * (rss / (m - 3) as f64);
        let (ga, gb) = (b / (2.0 * a * a), -1.0 / (2.0 * a));
        ga * ga * cov[(0, 0)] + 2.0 * ga * gb * cov[(0, 1)] + gb * gb * cov[(1, 1)]
    } else {
        0.0
    };
    Some((t0 + x_hat, (noise + fit).sqrt()))
}

/// Fits the chosen parameters (see the module docs). `progress(done, total)` after each
/// batch of runs.
pub fn calibrate(
    p: &Problem,
    cfg: &CalibrateConfig,
    progress: &mut (dyn FnMut(usize, usize) + Send),
) -> Result<CalibrationReport, CalibrateError> {
    if cfg.zones.is_empty() && !cfg.fit_n1 && !cfg.fit_friction {
        return Err(CalibrateError::Input(
            "nothing to fit: give zones, n1 or friction".into(),
        ));
    }
    let zone_rows: BTreeMap<String, Option<String>> = {
        let names = p.drawpoints.column("zone")?.str()?.clone();
        let known: Vec<&str> = names.iter().flatten().collect();
        cfg.zones
            .iter()
            .map(|z| (z.clone(), known.contains(&z.as_str()).then(|| z.clone())))
            .collect()
    };
    let start = p.scenario.calibration.clone();
    // 1. Coarse: every zone at the same value. The start runs in the same parallel batch,
    // and a grid value that is the start itself shares its run.
    let coarse: Vec<Calibration> = if cfg.zones.is_empty() {
        Vec::new()
    } else {
        cfg.coarse
            .iter()
            .map(|&f| zones_to(&start, &cfg.zones, &vec![f; cfg.zones.len()]))
            .collect()
    };
    let first: Vec<Calibration> = std::iter::once(start.clone())
        .chain(coarse.iter().filter(|c| **c != start).cloned())
        .collect();
    // The lattices the zones are fitted on (steps 1–2 on each; module docs).
    let lattices = if cfg.zones.is_empty() {
        1
    } else {
        cfg.lattices.max(1)
    };
    // At most: on each lattice the first runs, step 1b and the joint fit's every
    // iteration; then the globals and the final runs.
    let total = lattices
        * (first.len()
            + usize::from(cfg.zones.len() > 1) * (1 + cfg.zones.len() * cfg.coarse.len())
            + usize::from(!cfg.zones.is_empty())
                * MAX_ITERATIONS
                * runs_per_iteration(cfg.zones.len()))
        + usize::from(cfg.fit_n1) * cfg.global.len()
        + usize::from(cfg.fit_friction) * cfg.global.len()
        + 2;
    let mut runs = 0;
    let mut tick = |k: usize, runs: &mut usize| {
        *runs += k;
        progress(*runs, total);
    };
    // The start and the coarse grid on every lattice, as one batch.
    let trials: Vec<Trial> = (0..lattices)
        .flat_map(|lattice| trials_on(&first, lattice))
        .collect();
    let mut first_evals: Vec<Vec<Eval>> = Vec::with_capacity(lattices);
    let mut evals = p.eval_trials(&trials)?.into_iter();
    for _ in 0..lattices {
        first_evals.push(evals.by_ref().take(first.len()).collect());
    }
    tick(trials.len(), &mut runs);
    let before = first_evals[0][0].clone();
    let mut cal = start.clone();
    let mut profiles: BTreeMap<String, Profile> = BTreeMap::new();
    let mut joint_fit: Option<Joint> = None;
    // Per zone, its fit on each lattice (with more than one).
    let mut lattice_values: Vec<Vec<f64>> = Vec::new();

    if !cfg.zones.is_empty() {
        let step1 = First {
            cals: &first,
            coarse: &coarse,
            zone_rows: &zone_rows,
        };
        // Steps 1–2 on each lattice, each on its own thread, their batches made together
        // (`lockstep`); the scenario's lattice's profiles are reported.
        let run = |trials: Vec<Trial>| p.runs.predict(p, &trials);
        let group = Lockstep::new(&run, lattices);
        let ticks = Mutex::new((&mut tick, &mut runs));
        let fits = std::thread::scope(|s| {
            let threads: Vec<_> = first_evals
                .into_iter()
                .enumerate()
                .map(|(lattice, evals)| {
                    let (group, step1, ticks) = (&group, &step1, &ticks);
                    s.spawn(move || {
                        let member = Member { group, lattice };
                        let q = Problem {
                            runs: &member,
                            grade: p.grade.clone(),
                            ..*p
                        };
                        let tick = &mut |k| {
                            let mut t = ticks.lock().unwrap_or_else(|e| e.into_inner());
                            let (tick, runs) = &mut *t;
                            tick(k, runs)
                        };
                        fit_zones(&q, cfg, step1, evals, lattice, tick)
                    })
                })
                .collect();
            threads
                .into_iter()
                .map(|t| t.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
                .collect::<Vec<_>>()
        });
        if let Some(e) = group.error() {
            return Err(e);
        }
        let mut fits = fits.into_iter().collect::<Result<Vec<_>, _>>()?;
        profiles = std::mem::take(&mut fits[0].1);
        let fits: Vec<Joint> = fits.into_iter().map(|f| f.0).collect();
        let n = fits.len() as f64;
        for (k, z) in cfg.zones.iter().enumerate() {
            let mean = fits.iter().map(|f| f.theta[k]).sum::<f64>() / n;
            cal.frag_factor.insert(z.clone(), mean);
        }
        if fits.len() > 1 {
            lattice_values = (0..cfg.zones.len())
                .map(|k| fits.iter().map(|f| f.theta[k]).collect())
                .collect();
        }
        joint_fit = fits.into_iter().next();
    }

    // 3. Globals, zones fixed.
    type Global = (bool, &'static str, fn(&mut Calibration) -> &mut f64);
    let globals: [Global; 2] = [
        (cfg.fit_n1, "n1_factor", |c| &mut c.n1_factor),
        (cfg.fit_friction, "friction_factor", |c| {
            &mut c.friction_factor
        }),
    ];
    for (on, name, field) in globals {
        if !on {
            continue;
        }
        let cands: Vec<Calibration> = cfg
            .global
            .iter()
            .map(|&f| {
                let mut c = cal.clone();
                *field(&mut c) = f;
                c
            })
            .collect();
        let evals = p.eval_all(&cands, 0)?;
        tick(cands.len(), &mut runs);
        let prof: Profile = cfg
            .global
            .iter()
            .zip(&evals)
            .map(|(&f, e)| (f, e.all))
            .collect();
        *field(&mut cal) = argmin(&prof);
        profiles.insert(name.to_string(), prof);
    }

    // 4. The fitted values, run once more on each of TWINS twin lattices and at finer
    // markers (module docs, "Noise", "Lattice" and "Resolution").
    let trials: Vec<Trial> = std::iter::once((1.0, 0))
        .chain((1..=TWINS).map(|k| (1.0, k)))
        .chain(std::iter::once((CHECK_RESOLUTION, 0)))
        .map(|(finer, lattice)| Trial {
            calibration: cal.clone(),
            finer,
            lattice,
        })
        .collect();
    let finals = p.eval_trials(&trials)?;
    tick(finals.len(), &mut runs);
    let (after, twins, finer) = (&finals[0], &finals[1..=TWINS], &finals[TWINS + 1]);
    if after.all.1 == 0 {
        return Err(CalibrateError::Input(
            "no record matched a prediction: check drawpoint names and periods".into(),
        ));
    }
    // Each twin is √2 times the noise away from the fit's run: the noise is the RMS of
    // their differences over all twins, over √2.
    let diffs: Vec<f64> = twins
        .iter()
        .flat_map(|twin| {
            after
                .rows
                .iter()
                .filter_map(|(k, e)| twin.rows.get(k).map(|f| e - f))
        })
        .collect();
    let model_noise = if diffs.is_empty() {
        f64::NAN
    } else {
        (diffs.iter().map(|d| d * d).sum::<f64>() / (2.0 * diffs.len() as f64)).sqrt()
    };
    let records_noise = (rmse(after.all).powi(2) - model_noise.powi(2))
        .max(0.0)
        .sqrt();
    let shift = joint_fit.as_ref().and_then(|f| f.shift(after, finer));
    // Per zone: over several lattices, the standard error of the fits' mean; on one, the
    // RMS over the twins of the shift to each, over √2.
    let lattice = if !lattice_values.is_empty() {
        Some(DVector::from_iterator(
            lattice_values.len(),
            lattice_values.iter().map(|v| standard_error(v)),
        ))
    } else {
        joint_fit.as_ref().and_then(|f| {
            let shifts: Vec<DVector<f64>> =
                twins.iter().filter_map(|t| f.shift(after, t)).collect();
            (!shifts.is_empty()).then(|| {
                let n = shifts.len() as f64;
                shifts
                    .iter()
                    .fold(DVector::zeros(shifts[0].len()), |acc, d| {
                        acc + d.component_mul(d)
                    })
                    .map(|ms| (ms / (2.0 * n)).sqrt())
            })
        })
    };
    let cov = joint_fit.as_ref().and_then(|f| f.covariance(after));

    let mut parameters = Vec::new();
    for (name, prof) in &mut profiles {
        prof.sort_by(|a, b| a.0.total_cmp(&b.0));
        prof.dedup_by(|a, b| (a.0 - b.0).abs() < 1e-12);
        let zone = name.strip_prefix("frag_factor.");
        let (start_value, value, se, se_resolution, se_lattice, ci95) = match zone {
            Some(z) => {
                let k = cfg
                    .zones
                    .iter()
                    .position(|q| q == z)
                    .expect("a fitted zone");
                let value = cal.frag_factor[z];
                let res = shift.as_ref().map_or(f64::NAN, |d| d[k].abs());
                let lat = lattice.as_ref().map_or(f64::NAN, |d| d[k]);
                let stat = cov.as_ref().map_or(f64::NAN, |c| c[(k, k)].sqrt());
                let finite = |x: f64| if x.is_finite() { x } else { 0.0 };
                let se = stat.hypot(finite(res)).hypot(finite(lat));
                (
                    frag_factor(&start, z),
                    value,
                    se,
                    res,
                    lat,
                    [value - 1.96 * se, value + 1.96 * se],
                )
            }
            None => {
                let (value, se, ci95) = profile_fit(prof);
                let slot = if name == "n1_factor" {
                    (start.n1_factor, &mut cal.n1_factor)
                } else {
                    (start.friction_factor, &mut cal.friction_factor)
                };
                *slot.1 = value;
                (slot.0, value, se, f64::NAN, f64::NAN, ci95)
            }
        };
        let rows = zone.and_then(|z| zone_rows.get(z).cloned().flatten());
        parameters.push(Fitted {
            name: name.clone(),
            start: start_value,
            value,
            se,
            se_resolution,
            se_lattice,
            lattice_values: zone
                .and_then(|z| cfg.zones.iter().position(|q| q == z))
                .and_then(|k| lattice_values.get(k).cloned())
                .unwrap_or_default(),
            ci95,
            n: prof.first().map_or(0, |q| q.1 .1),
            profile: prof.iter().map(|&(t, e)| [t, rmse(e)]).collect(),
            rmse_before: rmse(before.of(rows.as_deref())),
            rmse_after: rmse(after.of(rows.as_deref())),
        });
    }
    let correlation = cov.as_ref().map(correlation).unwrap_or_default();
    Ok(CalibrationReport {
        grade: p.grade.clone(),
        parameters,
        correlation,
        rmse_before: rmse(before.all),
        rmse_after: rmse(after.all),
        model_noise,
        records_noise,
        resolution_adequate: model_noise < records_noise,
        n: after.all.1,
        runs,
        lowered: rmse(after.all) < rmse(before.all),
        calibration: cal,
    })
}

/// The runs of step 1 (the start and the coarse grid) and the rows each zone is judged on.
struct First<'a> {
    /// The start, then the coarse grid's values but the start.
    cals: &'a [Calibration],
    /// The coarse grid, every zone at one value.
    coarse: &'a [Calibration],
    /// Each zone's rows: those of the drawpoints whose zone it is (None: all rows).
    zone_rows: &'a BTreeMap<String, Option<String>>,
}

/// One lattice's fit's runner: its batches go out with the other lattices' fits' batches
/// of the same step ([`Lockstep`]). The fit is finished when it is dropped (also when its
/// thread panics), so the others never wait on it.
struct Member<'g, 'a> {
    group: &'g Lockstep<'a, Trial, DataFrame, CalibrateError>,
    lattice: usize,
}

impl Runs for Member<'_, '_> {
    fn predict(&self, _: &Problem, trials: &[Trial]) -> Result<Vec<DataFrame>, CalibrateError> {
        // A failed round's own error is returned by `calibrate` (`Lockstep::error`).
        self.group
            .ask(self.lattice, trials.to_vec())
            .ok_or_else(|| CalibrateError::Runs("a batch failed".into()))
    }
}

impl Drop for Member<'_, '_> {
    fn drop(&mut self) {
        self.group.finish();
    }
}

/// Steps 1–2 (module docs) on marker lattice `lattice`, from the runs of `first` made on
/// it (`evals`): the joint fit, and each zone's profile (its rows' errors at the coarse
/// grid and wherever its factor alone differed from a centre).
fn fit_zones(
    p: &Problem,
    cfg: &CalibrateConfig,
    first: &First,
    evals: Vec<Eval>,
    lattice: usize,
    tick: &mut dyn FnMut(usize),
) -> Result<(Joint, BTreeMap<String, Profile>), CalibrateError> {
    let start = &p.scenario.calibration;
    let rows_of = |z: &str| first.zone_rows[z].as_deref();
    let mut profiles: BTreeMap<String, Profile> = BTreeMap::new();
    let coarse: Vec<&Eval> = first
        .coarse
        .iter()
        .map(|c| {
            &evals[first
                .cals
                .iter()
                .position(|f| f == c)
                .expect("in the batch")]
        })
        .collect();
    for z in &cfg.zones {
        let prof = profiles.entry(format!("frag_factor.{z}")).or_default();
        prof.push((frag_factor(start, z), evals[0].of(rows_of(z))));
        for (f, e) in cfg.coarse.iter().zip(&coarse) {
            prof.push((*f, e.of(rows_of(z))));
        }
    }
    let best = |z: &str| argmin(&profiles[&format!("frag_factor.{z}")]);
    let mut theta: Vec<f64> = cfg.zones.iter().map(|z| best(z)).collect();
    let bounds = cfg
        .coarse
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &f| {
            (l.min(f), h.max(f))
        });
    let mut seen: Vec<(Vec<f64>, Eval)> = first
        .cals
        .iter()
        .zip(evals)
        .map(|(c, e)| {
            let t = cfg.zones.iter().map(|z| frag_factor(c, z));
            (t.collect(), e)
        })
        .collect();
    // Where a zone's factor was varied alone: its profile (below) is the runs on those
    // axes.
    let mut centres: Vec<Vec<f64>> = Vec::new();
    // 1b. Several zones: each zone over the grid with the others at their coarse best,
    // each taking its best on all rows (module docs).
    if cfg.zones.len() > 1 {
        centres.push(theta.clone());
        theta = one_at_a_time(p, &cfg.zones, &cfg.coarse, &theta, &mut seen, lattice, tick)?;
    }
    // 2. The zones jointly, from there.
    let fit = joint(p, &cfg.zones, bounds, theta, seen, lattice, tick)?;
    centres.extend(fit.centres.iter().cloned());
    for (k, z) in cfg.zones.iter().enumerate() {
        let prof = profiles
            .get_mut(&format!("frag_factor.{z}"))
            .expect("coarse made it");
        let on_axis = |t: &[f64]| {
            centres
                .iter()
                .any(|c| (0..t.len()).all(|j| j == k || t[j] == c[j]))
        };
        prof.extend(
            fit.points
                .iter()
                .filter(|(t, _)| on_axis(t))
                .map(|(t, e)| (t[k], e.of(rows_of(z)))),
        );
    }
    Ok((fit, profiles))
}

/// A global factor's θ̂, SE and 95% interval from its one-dimensional profile (module docs,
/// "Uncertainty"): the parabola through the points within 30% of the best, and the
/// profile interval.
fn profile_fit(prof: &Profile) -> (f64, f64, [f64; 2]) {
    let best = argmin(prof);
    // Bracket: within 30% of the best point (at least its two neighbours).
    let at = prof.iter().position(|q| q.0 == best).unwrap_or(0);
    let lo = prof[at.saturating_sub(1)].0.min(best / BRACKET);
    let hi = prof[(at + 1).min(prof.len() - 1)].0.max(best * BRACKET);
    let (value, se) = parabola(prof, (lo, hi)).unwrap_or((best, f64::NAN));
    // The profile interval: the evaluated values whose S is within χ²₁(95%) = 3.84 of the
    // best in units of σ̂², widened to the next evaluated value on each side (the crossing
    // lies somewhere between them).
    let (s_best, n) = prof[at].1;
    let limit = s_best * (1.0 + CHI2_95 / n.saturating_sub(1).max(1) as f64);
    let inside: Vec<usize> = (0..prof.len()).filter(|&k| prof[k].1 .0 <= limit).collect();
    let lo_k = inside.first().map_or(at, |&k| k.saturating_sub(1));
    let hi_k = inside.last().map_or(at, |&k| (k + 1).min(prof.len() - 1));
    let (p_lo, p_hi) = (prof[lo_k].0, prof[hi_k].0);
    let se = se.max((p_hi - p_lo) / (2.0 * 1.96));
    (
        value,
        se,
        [(value - 1.96 * se).min(p_lo), (value + 1.96 * se).max(p_hi)],
    )
}

/// Relative steps of the joint fit's probes, by iteration (the last one repeats): the
/// engine's response is ragged at the scale of single markers, so a step must move the
/// IMZs by much more than a marker's worth.
const FD_STEPS: [f64; 2] = [0.15, 0.1];
/// Iterations of the joint fit at most.
const MAX_ITERATIONS: usize = 3;
/// Runs per iteration of the joint fit: the centre and two probes per zone.
fn runs_per_iteration(zones: usize) -> usize {
    2 * zones + 1
}
/// Largest relative change of a factor in one step (a trust region for a Jacobian measured
/// on a ragged response).
const TRUST: f64 = 0.3;
/// The joint fit stops when no factor changes by more than this share in an iteration.
const CONVERGED: f64 = 0.01;
/// h and the marker spacing, as multiples of the fit's, of the run that checks the
/// resolution: 2^(−1/2), 2.8 times the markers (module docs, "Resolution").
const CHECK_RESOLUTION: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// Marker lattices the zones are fitted on by default ([`CalibrateConfig::lattices`]):
/// the scenario's and its first three twins, the lattices the fitted values are run on.
pub const LATTICES: usize = 1 + TWINS;

/// The standard error of the mean of `v`: its sample standard deviation over √n.
fn standard_error(v: &[f64]) -> f64 {
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let ss: f64 = v.iter().map(|x| (x - mean).powi(2)).sum();
    (ss / (n - 1.0) / n).sqrt()
}

/// Twin lattices the fitted values are run on, to measure the markers' sampling noise and
/// the fit's lean on its lattice (module docs, "Lattice" and "Noise"). One pair is one
/// draw of a difference: its size is often far below the spread it stands for.
const TWINS: usize = 3;

/// The joint fit of every zone's factor (module docs, step 2).
struct Joint {
    /// Fitted factors, in the order of the zones.
    theta: Vec<f64>,
    /// The residuals and Jacobian of the last iteration, keyed rows.
    lin: Linearised,
    /// The rows of `lin`.
    keys: Vec<(String, i64)>,
    /// Every evaluated point: factors and errors.
    points: Vec<(Vec<f64>, Eval)>,
    /// The centre of every iteration.
    centres: Vec<Vec<f64>>,
}

impl Joint {
    /// The residuals at `at` over `lin`'s rows (0 where `at` has none).
    fn residuals(&self, at: &Eval) -> DVector<f64> {
        DVector::from_iterator(
            self.keys.len(),
            self.keys
                .iter()
                .map(|k| at.rows.get(k).copied().unwrap_or(0.0)),
        )
    }

    /// Covariance at the fitted factors (residuals of the run `at` them): the larger of the
    /// plain and the cluster-robust variance (`least_squares`), element by element on the
    /// diagonal; the plain one off it.
    fn covariance(&self, at: &Eval) -> Option<DMatrix<f64>> {
        let (plain, robust) = self.lin.covariance(&self.residuals(at))?;
        let mut c = plain;
        for k in 0..c.nrows() {
            c[(k, k)] = c[(k, k)].max(robust[(k, k)]);
        }
        Some(c)
    }

    /// How far the factors would move had the fit been made with the markers of the run
    /// `other` (a finer run, or the twin lattice's): the Gauss–Newton step
    /// −A⁻¹ Jᵀ (e_other − e_fit) of the change in the predictions, on this fit's Jacobian
    /// (module docs, "Resolution" and "Lattice").
    fn shift(&self, fit: &Eval, other: &Eval) -> Option<DVector<f64>> {
        let d = DVector::from_iterator(
            self.keys.len(),
            self.keys
                .iter()
                .map(|k| match (other.rows.get(k), fit.rows.get(k)) {
                    (Some(a), Some(b)) => a - b,
                    _ => 0.0,
                }),
        );
        Some(-self.lin.inverse_normal()? * self.lin.j.transpose() * d)
    }
}

/// The correlation matrix of a covariance matrix.
fn correlation(c: &DMatrix<f64>) -> Vec<Vec<f64>> {
    let n = c.nrows();
    (0..n)
        .map(|i| {
            (0..n)
                .map(|j| c[(i, j)] / (c[(i, i)] * c[(j, j)]).sqrt())
                .collect()
        })
        .collect()
}

/// The runs of `cals` at the resolved resolution on marker lattice `lattice`.
fn trials_on(cals: &[Calibration], lattice: usize) -> impl Iterator<Item = Trial> + '_ {
    cals.iter().map(move |c| Trial {
        calibration: c.clone(),
        finer: 1.0,
        lattice,
    })
}

/// Zone `z`'s fragment factor in `c` (1 where `c` names none).
fn frag_factor(c: &Calibration, z: &str) -> f64 {
    c.frag_factor.get(z).copied().unwrap_or(1.0)
}

/// `start` with zone k's fragment factor at `t[k]`.
fn zones_to(start: &Calibration, zones: &[String], t: &[f64]) -> Calibration {
    let mut c = start.clone();
    for (z, &v) in zones.iter().zip(t) {
        c.frag_factor.insert(z.clone(), v);
    }
    c
}

/// Step 1b (module docs): each zone over `grid` with the others at `theta`, judged on all
/// rows; returns each zone's best. The runs join `seen`.
fn one_at_a_time(
    p: &Problem,
    zones: &[String],
    grid: &[f64],
    theta: &[f64],
    seen: &mut Vec<(Vec<f64>, Eval)>,
    lattice: usize,
    tick: &mut dyn FnMut(usize),
) -> Result<Vec<f64>, CalibrateError> {
    let cands: Vec<Vec<f64>> = std::iter::once(theta.to_vec())
        .chain((0..zones.len()).flat_map(|k| {
            grid.iter().filter(move |&&f| f != theta[k]).map(move |&f| {
                let mut t = theta.to_vec();
                t[k] = f;
                t
            })
        }))
        .filter(|t| !seen.iter().any(|(q, _)| q == t))
        .collect();
    let evals = p.eval_zones(zones, &cands, lattice)?;
    tick(cands.len());
    seen.extend(cands.into_iter().zip(evals));
    Ok((0..zones.len())
        .map(|k| {
            let on_axis = |q: &[f64]| (0..q.len()).all(|j| j == k || q[j] == theta[j]);
            seen.iter()
                .filter(|(q, _)| on_axis(q))
                .min_by(|a, b| rmse(a.1.all).total_cmp(&rmse(b.1.all)))
                .map_or(theta[k], |(q, _)| q[k])
        })
        .collect())
}

/// Points within this share of the centre on every factor make the regression.
const WINDOW: f64 = 0.2;

/// The residuals and Jacobian at `centre` from every evaluated point within [`WINDOW`] of
/// it: per row, the least-squares plane e = a + J (θ − centre) through those points
/// (module docs, step 2). None when the points do not span every factor.
fn regression(
    points: &[(Vec<f64>, Eval)],
    centre: &[f64],
) -> Option<(Linearised, Vec<(String, i64)>)> {
    let near: Vec<&(Vec<f64>, Eval)> = points
        .iter()
        .filter(|(t, _)| {
            t.iter()
                .zip(centre)
                .all(|(a, c)| (a - c).abs() <= WINDOW * c * (1.0 + 1e-9))
        })
        .collect();
    let k = centre.len();
    if near.len() <= k {
        return None;
    }
    let keys: Vec<(String, i64)> = near[0]
        .1
        .rows
        .keys()
        .filter(|key| near.iter().all(|(_, e)| e.rows.contains_key(*key)))
        .cloned()
        .collect();
    let x = DMatrix::from_fn(near.len(), k + 1, |p, c| {
        if c == 0 {
            1.0
        } else {
            near[p].0[c - 1] - centre[c - 1]
        }
    });
    // Coefficients of every row at once: (XᵀX)⁻¹ Xᵀ E, E one column per row.
    let solve = (x.transpose() * &x).try_inverse()? * x.transpose();
    let e = DMatrix::from_fn(near.len(), keys.len(), |p, r| near[p].1.rows[&keys[r]]);
    let coef = solve * e;
    let mut names: Vec<&str> = keys.iter().map(|q| q.0.as_str()).collect();
    names.sort_unstable();
    names.dedup();
    let lin = Linearised {
        e: DVector::from_iterator(keys.len(), coef.row(0).iter().copied()),
        j: DMatrix::from_fn(keys.len(), k, |r, c| coef[(c + 1, r)]),
        cluster: keys
            .iter()
            .map(|q| names.binary_search(&q.0.as_str()).expect("listed"))
            .collect(),
    };
    Some((lin, keys))
}

/// Fits the zones' factors together (module docs, step 2), from `theta`, each factor kept
/// within `bounds`; `points` are the runs already made (factors and errors).
fn joint(
    p: &Problem,
    zones: &[String],
    bounds: (f64, f64),
    mut theta: Vec<f64>,
    mut points: Vec<(Vec<f64>, Eval)>,
    lattice: usize,
    tick: &mut dyn FnMut(usize),
) -> Result<Joint, CalibrateError> {
    let mut last = None;
    let mut centres = Vec::new();
    for it in 0..MAX_ITERATIONS {
        centres.push(theta.clone());
        // The centre, and each zone at θ_k (1 ± h) with the others at the centre.
        let h = FD_STEPS[it.min(FD_STEPS.len() - 1)];
        let batch: Vec<Vec<f64>> = std::iter::once(theta.clone())
            .chain((0..zones.len()).flat_map(|k| {
                [1.0 - h, 1.0 + h].map(|m| {
                    let mut t = theta.clone();
                    t[k] *= m;
                    t
                })
            }))
            .collect();
        let evals = p.eval_zones(zones, &batch, lattice)?;
        tick(batch.len());
        points.extend(batch.into_iter().zip(evals));
        let Some(lin) = regression(&points, &theta) else {
            break;
        };
        // The Gauss–Newton step, within the trust region and the grid.
        let step = lin.0.step(0.0);
        last = Some(lin);
        let Some(d) = step else { break };
        let next: Vec<f64> = theta
            .iter()
            .zip(d.iter())
            .map(|(&t, &d)| (t + d.clamp(-TRUST * t, TRUST * t)).clamp(bounds.0, bounds.1))
            .collect();
        let moved = next
            .iter()
            .zip(&theta)
            .map(|(a, b)| ((a - b) / b).abs())
            .fold(0.0, f64::max);
        theta = next;
        if moved < CONVERGED {
            break;
        }
    }
    let (lin, keys) = last.expect("at least one iteration");
    Ok(Joint {
        theta,
        lin,
        keys,
        points,
        centres,
    })
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parabola_recovers_vertex_and_curvature() {
        // S(θ) = 4 + 50 (θ − 0.63)², n = 101: SE = √(4/100 / 50).
        let pts: Vec<(f64, (f64, usize))> = [0.5, 0.55, 0.6, 0.65, 0.7, 0.8]
            .iter()
            .map(|&t| (t, (4.0 + 50.0 * (t - 0.63f64).powi(2), 101)))
            .collect();
        let (v, se) = parabola(&pts, (0.5, 0.7)).unwrap();
        assert!((v - 0.63).abs() < 1e-9, "{v}");
        assert!((se - (0.04f64 / 50.0).sqrt()).abs() < 1e-9, "{se}");
        // A profile that opens downwards has no minimum to report.
        let down: Vec<(f64, (f64, usize))> =
            pts.iter().map(|&(t, (s, n))| (t, (10.0 - s, n))).collect();
        assert!(parabola(&down, (0.5, 0.7)).is_none());
    }
}
