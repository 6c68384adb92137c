//! Calibration: fit inputs to production records by running the engine many times, a
//! batch of independent runs at a time, and reconciling each run (DESIGN §6; summary §8,
//! where the Primos fragment size was found by trying 0.23 m and 0.04 m by hand). Where a
//! batch runs is the [`Runs`] given: [`InProcess`] (rayon over the runs), or a study
//! ([`calibrate_runs`](super::calibrate_runs), what `caveflow calibrate` uses), with the
//! same results.
//!
//! The code by concept: [`problem`] (a run of the calibration, where runs are made, a
//! run's errors), [`fit`] (steps 1–3 below), [`uncertainty`] (step 4 and the standard
//! errors) and [`command`] (`caveflow calibrate`'s work around the fit: its defaults, its
//! files and warnings). What the fit gives on the demo and on the
//! tests' three-zone truth is in `docs::validation`, "Back-analysis".
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
//!    This finds the right valley where the first pass has two.
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
//!    ragged surface the lowest of many runs is the one whose markers happened to fall
//!    best. J's off-diagonal terms are how the zones' influence on one another enters.
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
//! spacing × 2^(−1/2) (2.8 times the markers, twice as many disks; the increment and
//! `max_marker_move` as resolved) measures it: the Gauss–Newton step −A⁻¹ Jᵀ (e_finer −
//! e_fit) is how far the factors would move had the fit been made at the finer resolution.
//! Its size is each factor's `se_resolution`, added in quadrature to the statistical SE.
//! It is a lower bound of the resolution's error (a run converged in resolution would move
//! the factors further).
//!
//! **Lattice.** The markers sample the ground at their lattice's sites, and a fit made with
//! one lattice leans on that sample's noise in the same way in every trial run (the same
//! markers fall the same way), so it is biased by it, beyond what the residuals' scatter
//! shows. The zones are therefore fitted whole on K lattices, each another sample of the
//! same ground, and each factor is the K fits' mean; its `se_lattice` is the standard
//! error of that mean (the fits' sample standard deviation over √K), added in quadrature.
//! It has K − 1 degrees of freedom, so with the default 4 it is itself uncertain by about
//! 40%. A single fit's own estimate of its lattice part (K = 1, below) reads the other
//! lattices through the fit's own Jacobian, and on a surface ragged at the scale of single
//! markers that Jacobian does not say where another lattice's fit lands: it can fall far
//! short of the spread of whole fits.
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
//! the RMS of e_twin − e_fit over the rows of all three, over √2 (the finer run would not
//! do: its own noise is smaller, and two unequal noises are not √2 one of them apart). The
//! records' noise is what is left beside it, √(RMSE² − model²): when the model's noise is
//! not below the records', the fit cannot resolve what the records say, and `calibrate`
//! says so. A drawpoint's errors are correlated over its periods, so one pair is a rough
//! sample of the noise.
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
//!
//! # Diagnosis
//! The standard errors measure noise, and a model that differs from the process alike at
//! every drawpoint of a zone hides inside its factor. [`diagnosis`] reads the residuals at
//! θ̂ for what noise does not make, per zone: the skill of the fit on each drawpoint held
//! out of it (a linearised refit), a shape along the draw that the zone's drawpoints share
//! (a sign-flip test), and an autocorrelation along each drawpoint's draw beyond the model's
//! own noise's. Where it finds structure, the report says the model does not explain the
//! records, naming the zones and the stretches of the draw, and the intervals are not to be
//! read as the distance to the truth.

use std::collections::BTreeMap;

use polars::prelude::*;

use super::reconcile::ReconcileError;
use crate::engine::EngineError;
use crate::model::scenario::Calibration;

pub mod command;
pub mod diagnosis;
pub mod fit;
pub mod problem;
pub mod uncertainty;

pub use command::{write_calibration, Command, Outcome};
pub use diagnosis::{Diagnosis, ZoneDiagnosis};
pub use problem::{describe, InProcess, Problem, Runs, Trial};

use fit::First;
use problem::{rmse, trials_on, zones_to, Eval};
use uncertainty::TWINS;

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
    /// Whether the model explains the records: held-out skill, and structure in the
    /// residuals at the fitted values (module docs, "Diagnosis").
    pub diagnosis: Diagnosis,
    /// The fitted calibration.
    #[serde(skip)]
    pub calibration: Calibration,
}

/// Marker lattices the zones are fitted on by default ([`CalibrateConfig::lattices`]):
/// the scenario's and its first three twins, the lattices the fitted values are run on.
pub const LATTICES: usize = 1 + TWINS;

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
                * fit::MAX_ITERATIONS
                * fit::runs_per_iteration(cfg.zones.len()))
        + usize::from(cfg.fit_n1) * cfg.global.len()
        + usize::from(cfg.fit_friction) * cfg.global.len()
        + 2;
    let mut runs = 0;
    let mut tick = |k: usize| {
        runs += k;
        progress(runs, total);
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
    tick(trials.len());
    let before = first_evals[0][0].clone();
    let mut cal = start.clone();
    // 1–2. The zones on every lattice, each zone's factor the mean of its fits.
    let zones = if cfg.zones.is_empty() {
        None
    } else {
        let step1 = First {
            cals: &first,
            coarse: &coarse,
            zone_rows: &zone_rows,
        };
        let zones = fit::on_lattices(p, cfg, &step1, first_evals, &mut tick)?;
        for (z, &mean) in cfg.zones.iter().zip(&zones.means) {
            cal.frag_factor.insert(z.clone(), mean);
        }
        Some(zones)
    };
    let (mut profiles, joint, lattice_values) = match zones {
        Some(z) => (z.profiles, Some(z.joint), z.lattice_values),
        None => (BTreeMap::new(), None, Vec::new()),
    };
    // 3. Globals, zones fixed.
    fit::globals(p, cfg, &mut cal, &mut profiles, &mut tick)?;
    // 4. The fitted values' runs, and the uncertainty they give.
    let check = uncertainty::Check::run(p, &cal, joint.as_ref(), &lattice_values, &mut tick)?;
    let after = &check.after;
    let parameters = uncertainty::fitted(
        cfg,
        &start,
        &mut cal,
        &mut profiles,
        &zone_rows,
        &lattice_values,
        &check,
        &before,
    );
    let zone_of: BTreeMap<String, String> = {
        let names = p.drawpoints.column("drawpoint")?.str()?.clone();
        let zones = p.drawpoints.column("zone")?.str()?.clone();
        names
            .iter()
            .zip(zones.iter())
            .filter_map(|(d, z)| Some((d?.to_string(), z?.to_string())))
            .collect()
    };
    let diagnosis = diagnosis::diagnose(after, &before, &check.twins, joint.as_ref(), &zone_of);
    let correlation = check
        .covariance
        .as_ref()
        .map(uncertainty::correlation)
        .unwrap_or_default();
    Ok(CalibrationReport {
        grade: p.grade.clone(),
        parameters,
        correlation,
        rmse_before: rmse(before.all),
        rmse_after: rmse(after.all),
        model_noise: check.model_noise,
        records_noise: check.records_noise,
        resolution_adequate: check.model_noise < check.records_noise,
        n: after.all.1,
        runs,
        lowered: rmse(after.all) < rmse(before.all),
        diagnosis,
        calibration: cal,
    })
}
