//! The fit's uncertainty (module docs, step 4 and "Uncertainty"): the runs at the fitted
//! values on the twin lattices and at a finer resolution; the zones' statistical
//! covariance (plain and clustered by drawpoint), their resolution and lattice terms, the
//! model's and the records' noise; the global factors' SE from their profiles' parabolas.

use std::collections::BTreeMap;

use nalgebra::{DMatrix, DVector};

use super::diagnosis::mean_se;
use super::fit::{argmin, Joint, Profile};
use super::problem::{frag_factor, rmse, Eval, Problem, Trial};
use super::{CalibrateConfig, CalibrateError, Fitted};
use crate::model::scenario::Calibration;

/// The profile points within this factor of the best one make the parabola's fit.
const BRACKET: f64 = 1.3;
/// The 95% point of χ² with one degree of freedom.
const CHI2_95: f64 = 3.84;

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

/// Twin lattices the fitted values are run on, to measure the markers' sampling noise and
/// the fit's lean on its lattice (module docs, "Lattice" and "Noise"). One pair is one
/// draw of a difference: its size is often far below the spread it stands for.
pub(super) const TWINS: usize = 3;

/// h and the marker spacing, as multiples of the fit's, of the run that checks the
/// resolution: 2^(−1/2), 2.8 times the markers (module docs, "Resolution").
const CHECK_RESOLUTION: f64 = std::f64::consts::FRAC_1_SQRT_2;

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
pub(super) fn correlation(c: &DMatrix<f64>) -> Vec<Vec<f64>> {
    let n = c.nrows();
    (0..n)
        .map(|i| {
            (0..n)
                .map(|j| c[(i, j)] / (c[(i, i)] * c[(j, j)]).sqrt())
                .collect()
        })
        .collect()
}

/// The runs at the fitted values (module docs, step 4) and what they say of the fit.
pub(super) struct Check {
    /// The errors of the run at the fitted values.
    pub(super) after: Eval,
    /// The errors of the same run on each twin lattice.
    pub(super) twins: Vec<Eval>,
    /// The model's own noise (module docs, "Noise").
    pub(super) model_noise: f64,
    /// The records' noise beside it.
    pub(super) records_noise: f64,
    /// Per zone, how far its factor would move at the finer resolution.
    shift: Option<DVector<f64>>,
    /// Per zone, its lattice part of the SE.
    lattice: Option<DVector<f64>>,
    /// The zones' statistical covariance.
    pub(super) covariance: Option<DMatrix<f64>>,
}

impl Check {
    /// Runs `cal` once more on the scenario's lattice, on each of [`TWINS`] twin lattices
    /// and at finer markers (module docs, "Noise", "Lattice" and "Resolution"), as one
    /// batch, and measures the uncertainty: `joint` is the zones' fit on the scenario's
    /// lattice (None without zones), `lattice_values` each zone's fit on each lattice
    /// (empty with one lattice).
    pub(super) fn run(
        p: &Problem,
        cal: &Calibration,
        joint: Option<&Joint>,
        lattice_values: &[Vec<f64>],
        tick: &mut dyn FnMut(usize),
    ) -> Result<Check, CalibrateError> {
        let trials: Vec<Trial> = std::iter::once((1.0, 0))
            .chain((1..=TWINS).map(|k| (1.0, k)))
            .chain(std::iter::once((CHECK_RESOLUTION, 0)))
            .map(|(finer, lattice)| Trial {
                calibration: cal.clone(),
                finer,
                lattice,
            })
            .collect();
        let mut finals = p.eval_trials(&trials)?;
        tick(finals.len());
        let finer = finals.pop().expect("the finer run");
        let after = finals.remove(0);
        let twins = finals;
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
        let shift = joint.and_then(|f| f.shift(&after, &finer));
        // Per zone: over several lattices, the standard error of the fits' mean; on one,
        // the RMS over the twins of the shift to each, over √2.
        let lattice = if !lattice_values.is_empty() {
            Some(DVector::from_iterator(
                lattice_values.len(),
                lattice_values.iter().map(|v| mean_se(v).1),
            ))
        } else {
            joint.and_then(|f| {
                let shifts: Vec<DVector<f64>> =
                    twins.iter().filter_map(|t| f.shift(&after, t)).collect();
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
        let covariance = joint.and_then(|f| f.covariance(&after));
        Ok(Check {
            after,
            twins,
            model_noise,
            records_noise,
            shift,
            lattice,
            covariance,
        })
    }
}

/// Every parameter's fit, in the order of `profiles` (sorted and deduplicated here): a
/// zone's value is `cal`'s, its SE the statistical one, `check`'s resolution and lattice
/// terms in quadrature; a global factor's value and SE come from its profile
/// ([`profile_fit`]), and its value is set in `cal`. `start` is the calibration before,
/// `zone_rows` each zone's rows, `before` the errors of the run at `start`.
#[allow(clippy::too_many_arguments)]
pub(super) fn fitted(
    cfg: &CalibrateConfig,
    start: &Calibration,
    cal: &mut Calibration,
    profiles: &mut BTreeMap<String, Profile>,
    zone_rows: &BTreeMap<String, Option<String>>,
    lattice_values: &[Vec<f64>],
    check: &Check,
    before: &Eval,
) -> Vec<Fitted> {
    let mut parameters = Vec::new();
    for (name, prof) in profiles.iter_mut() {
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
                let res = check.shift.as_ref().map_or(f64::NAN, |d| d[k].abs());
                let lat = check.lattice.as_ref().map_or(f64::NAN, |d| d[k]);
                let stat = check
                    .covariance
                    .as_ref()
                    .map_or(f64::NAN, |c| c[(k, k)].sqrt());
                let finite = |x: f64| if x.is_finite() { x } else { 0.0 };
                let se = stat.hypot(finite(res)).hypot(finite(lat));
                (
                    frag_factor(start, z),
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
            rmse_after: rmse(check.after.of(rows.as_deref())),
        });
    }
    parameters
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
