//! Calibration: fit inputs to production records by running the engine many times in
//! parallel (rayon over runs) and reconciling each run (DESIGN §6; summary §8, where the
//! Primos fragment size was found by trying 0.23 m and 0.04 m by hand).
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
//! rows of [`reconcile`](super::reconcile)). The fragment factor of lithology z is judged on
//! the rows of the drawpoints whose `zone` is z (all rows when no drawpoint names it), so
//! that one run serves every zone at once:
//!
//! 1. **coarse**: one run per value of the coarse grid, every fitted zone set to that value;
//!    each zone takes its own best value;
//! 2. **refine**: runs at ±8% and ±15% around each zone's best (each run sets every zone
//!    to its own k-th step), so each zone's profile is sampled finely near its minimum;
//! 3. **globals** (when asked): n1 then φ factors, each on a grid around 1 with the zones
//!    fixed, judged on all rows;
//! 4. a last run at the fitted values gives the error after.
//!
//! # Uncertainty
//! Near its minimum each profile is a parabola, S(θ) ≈ S_min + a (θ − θ̂)², fitted by least
//! squares to the evaluated points within 30% of the best one. As in nonlinear least
//! squares, a = Σ (∂e/∂θ)² and the residual variance is σ̂² = S_min / (n − 1), so the noise
//! gives θ̂ a standard error σ̂ / √a. The engine's response is ragged at the scale of single
//! markers, so the points scatter about the parabola; the vertex's spread under that
//! scatter (the regression's covariance) is added in quadrature.
//!
//! Where the profile has a flat valley rather than a parabola's bottom, the curvature says
//! too little. So the profile interval is taken too: the evaluated values whose S lies
//! within χ²₁(95%) = 3.84 σ̂² of the best, widened to the next evaluated value on each side.
//! The reported SE is the larger of the curvature's and the interval's half-width / 1.96;
//! the 95% interval covers both. The profile
//! points themselves are reported too (the error surface around the optimum), so a flat or
//! two-valleyed profile is seen, not hidden behind one number.

use std::collections::BTreeMap;
use std::path::Path;

use polars::prelude::*;
use rayon::prelude::*;

use super::reconcile::{
    floats, predicted_frame, reconcile, strings, Frames, ReconcileError, Settings,
};
use crate::engine::{Engine, EngineError};
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
    /// Coarse grid of fragment-size factors.
    pub coarse: Vec<f64>,
    /// Relative steps around each zone's coarse best (multipliers).
    pub refine: Vec<f64>,
    /// Grid of n1 and φ factors.
    pub global: Vec<f64>,
}

impl Default for CalibrateConfig {
    fn default() -> Self {
        CalibrateConfig {
            zones: Vec::new(),
            fit_n1: false,
            fit_friction: false,
            coarse: vec![0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.15, 1.3, 1.5],
            refine: vec![0.85, 0.92, 1.08, 1.15],
            global: vec![0.9, 0.95, 1.0, 1.05, 1.1],
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
    /// Standard error of θ̂: the larger of the curvature's and the profile interval's (see
    /// the module docs; NaN when the profile has no minimum).
    pub se: f64,
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
    /// Overall RMSE before (at the scenario's own calibration).
    pub rmse_before: f64,
    /// Overall RMSE after (at the fitted values).
    pub rmse_after: f64,
    /// Rows compared.
    pub n: usize,
    /// Engine runs made.
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

/// Errors of one run: Σ e² and n per zone and overall.
#[derive(Debug, Clone)]
struct Eval {
    zones: BTreeMap<String, (f64, usize)>,
    all: (f64, usize),
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

/// The calibration problem: a scene loaded without calibration, the scenario, the records.
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
}

impl Problem<'_> {
    /// Runs the engine with `cal` and reconciles it.
    fn eval(&self, cal: &Calibration) -> Result<Eval, CalibrateError> {
        let mut scene = self.scene.clone();
        cal.apply(&mut scene.blocks)
            .map_err(CalibrateError::Apply)?;
        let mut sc = self.scenario.clone();
        sc.calibration = cal.clone();
        let out = Engine::new(&scene, &sc)
            .map_err(|source| CalibrateError::Engine {
                calibration: describe(cal),
                source,
            })?
            .run(&mut |_, _| {});
        let frames = Frames {
            predicted: predicted_frame(&out.extraction, &scene)?,
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
        Ok(Eval { zones, all })
    }

    fn eval_all(&self, cals: &[Calibration]) -> Result<Vec<Eval>, CalibrateError> {
        cals.par_iter().map(|c| self.eval(c)).collect()
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

/// `start` with every zone's fragment factor set to `value(zone)`.
fn zones_at(start: &Calibration, zones: &[String], value: impl Fn(&str) -> f64) -> Calibration {
    let mut c = start.clone();
    for z in zones {
        c.frag_factor.insert(z.clone(), value(z));
    }
    c
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
    progress: &mut dyn FnMut(usize, usize),
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
            .map(|&f| zones_at(&start, &cfg.zones, |_| f))
            .collect()
    };
    let first: Vec<Calibration> = std::iter::once(start.clone())
        .chain(coarse.iter().filter(|c| **c != start).cloned())
        .collect();
    let total = first.len()
        + usize::from(!cfg.zones.is_empty()) * cfg.refine.len()
        + usize::from(cfg.fit_n1) * cfg.global.len()
        + usize::from(cfg.fit_friction) * cfg.global.len()
        + 1;
    let mut runs = 0;
    let mut tick = |k: usize, runs: &mut usize| {
        *runs += k;
        progress(*runs, total);
    };
    let first_evals = p.eval_all(&first)?;
    tick(first.len(), &mut runs);
    let before = first_evals[0].clone();
    let mut cal = start.clone();
    let mut profiles: BTreeMap<String, Profile> = BTreeMap::new();
    let start_of = |z: &str| start.frag_factor.get(z).copied().unwrap_or(1.0);

    if !cfg.zones.is_empty() {
        let evals: Vec<&Eval> = coarse
            .iter()
            .map(|c| &first_evals[first.iter().position(|f| f == c).expect("in the batch")])
            .collect();
        for z in &cfg.zones {
            let prof = profiles.entry(format!("frag_factor.{z}")).or_default();
            prof.push((start_of(z), before.of(zone_rows[z].as_deref())));
            for (f, e) in cfg.coarse.iter().zip(&evals) {
                prof.push((*f, e.of(zone_rows[z].as_deref())));
            }
        }
        let best = |z: &str, profiles: &BTreeMap<String, Profile>| {
            argmin(&profiles[&format!("frag_factor.{z}")])
        };
        // 2. Refine around each zone's own best.
        let centre: BTreeMap<String, f64> = cfg
            .zones
            .iter()
            .map(|z| (z.clone(), best(z, &profiles)))
            .collect();
        let cands: Vec<Calibration> = cfg
            .refine
            .iter()
            .map(|&m| zones_at(&start, &cfg.zones, |z| centre[z] * m))
            .collect();
        let evals = p.eval_all(&cands)?;
        tick(cands.len(), &mut runs);
        for z in &cfg.zones {
            let prof = profiles
                .get_mut(&format!("frag_factor.{z}"))
                .expect("coarse made it");
            for (m, e) in cfg.refine.iter().zip(&evals) {
                prof.push((centre[z] * m, e.of(zone_rows[z].as_deref())));
            }
            cal.frag_factor.insert(z.clone(), best(z, &profiles));
        }
    }

    // 3. Globals, zones fixed.
    let globals: [(bool, &str, fn(&mut Calibration) -> &mut f64); 2] = [
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
        let evals = p.eval_all(&cands)?;
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

    // Sub-grid optimum and SE of each parameter from its profile.
    let mut parameters = Vec::new();
    for (name, prof) in &mut profiles {
        prof.sort_by(|a, b| a.0.total_cmp(&b.0));
        prof.dedup_by(|a, b| (a.0 - b.0).abs() < 1e-12);
        let best = argmin(prof);
        // Bracket: within 30% of the best point (at least its two neighbours).
        let at = prof.iter().position(|q| q.0 == best).unwrap_or(0);
        let lo = prof[at.saturating_sub(1)].0.min(best / BRACKET);
        let hi = prof[(at + 1).min(prof.len() - 1)].0.max(best * BRACKET);
        let (value, se) = match parabola(prof, (lo, hi)) {
            Some((v, se)) => (v, se),
            None => (best, f64::NAN),
        };
        // The profile interval: the evaluated values whose S is within χ²₁(95%) = 3.84 of
        // the best in units of σ̂², widened to the next evaluated value on each side
        // (the crossing lies somewhere between them).
        let (s_best, n) = prof[at].1;
        let limit = s_best * (1.0 + CHI2_95 / n.saturating_sub(1).max(1) as f64);
        let inside: Vec<usize> = (0..prof.len()).filter(|&k| prof[k].1 .0 <= limit).collect();
        let lo_k = inside.first().map_or(at, |&k| k.saturating_sub(1));
        let hi_k = inside.last().map_or(at, |&k| (k + 1).min(prof.len() - 1));
        let (p_lo, p_hi) = (prof[lo_k].0, prof[hi_k].0);
        let se = se.max((p_hi - p_lo) / (2.0 * 1.96));
        let ci95 = [(value - 1.96 * se).min(p_lo), (value + 1.96 * se).max(p_hi)];
        let (start_value, slot) = if let Some(z) = name.strip_prefix("frag_factor.") {
            (start_of(z), cal.frag_factor.get_mut(z))
        } else if name == "n1_factor" {
            (start.n1_factor, Some(&mut cal.n1_factor))
        } else {
            (start.friction_factor, Some(&mut cal.friction_factor))
        };
        if let Some(slot) = slot {
            *slot = value;
        }
        parameters.push(Fitted {
            name: name.clone(),
            start: start_value,
            value,
            se,
            ci95,
            n: prof.first().map_or(0, |q| q.1 .1),
            profile: prof.iter().map(|&(t, e)| [t, rmse(e)]).collect(),
            rmse_before: f64::NAN,
            rmse_after: f64::NAN,
        });
    }

    // 4. The fitted values, run once more.
    let after = p.eval(&cal)?;
    tick(1, &mut runs);
    for f in &mut parameters {
        let zone = f
            .name
            .strip_prefix("frag_factor.")
            .and_then(|z| zone_rows.get(z).cloned().flatten());
        f.rmse_before = rmse(before.of(zone.as_deref()));
        f.rmse_after = rmse(after.of(zone.as_deref()));
    }
    if after.all.1 == 0 {
        return Err(CalibrateError::Input(
            "no record matched a prediction: check drawpoint names and periods".into(),
        ));
    }
    Ok(CalibrationReport {
        grade: p.grade.clone(),
        parameters,
        rmse_before: rmse(before.all),
        rmse_after: rmse(after.all),
        n: after.all.1,
        runs,
        lowered: rmse(after.all) < rmse(before.all),
        calibration: cal,
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
