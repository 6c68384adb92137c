//! Does the model explain the records? (module docs, "Diagnosis".)
//!
//! The standard errors measure noise. A model that differs from the process in the same way
//! at every drawpoint of a zone moves all of them alike: the zone's factor absorbs the
//! difference, the scatter of the residuals stays small, and the interval is narrow about
//! a wrong value. What the absorbed difference leaves behind is structure in the residuals
//! at θ̂, which noise does not make. Three checks look for it, per zone (the drawpoints'
//! `zone`) and, where there are several zones, over every drawpoint together ([`ALL`]):
//!
//! - **Held-out skill.** Each drawpoint in turn is left out of the fit: the factors are
//!   refitted without its rows on the fit's linearisation (residuals e at θ̂, Jacobian J of
//!   the joint fit's last iteration, A = JᵀJ):
//!   Δ₋g = −(A − J_gᵀJ_g)⁻¹ (Jᵀe − J_gᵀe_g), and its rows predicted with them,
//!   e_g + J_g Δ₋g. The held-out RMSE against the in-fit one (every drawpoint in,
//!   e + J Δ, Δ = −A⁻¹Jᵀe) says how far the fit leans on the drawpoints it was given;
//!   against the RMSE before calibration, whether it predicts drawpoints it has not seen
//!   better than the start: skill = 1 − held-out² / before². The refit is linear, so it
//!   costs no run; it says nothing where the linearisation does not hold.
//! - **Shape along the draw.** Each drawpoint's rows fall into [`STRETCHES`] stretches of
//!   its draw by cumulative tonnes (edges at the quantiles of every matched row's); each
//!   drawpoint's mean residual in each stretch, and across the zone's drawpoints each
//!   stretch's mean and its t. Drawpoints that share a shape (too rich early and too lean
//!   late, say) give a t far from zero. Its reference is a sign-flip test: with no shared
//!   shape a drawpoint's residuals are as likely one sign as the other, so flipping whole
//!   drawpoints' signs at random ([`FLIPS`] times, a seeded generator) gives the
//!   distribution of the largest |t| over the stretches under noise alone, with each
//!   drawpoint's own correlation along its draw and the number of stretches accounted
//!   for. A zone has a shape when its largest |t| passes that distribution's 1 − 0.05 / Z
//!   quantile (Z zones tested: 5% over all of them); the stretches past it are named.
//! - **Autocorrelation along the draw.** The lag-one autocorrelation of each drawpoint's
//!   residuals in period order, averaged over the zone's drawpoints, against what the
//!   model's own noise gives. The twin lattices' runs differ from the fit's run by √2 times
//!   the model's noise; their differences have its autocorrelation ρ_m (the markers drawn
//!   in one period spread into the next) and its variance σ_m². Residuals that are that
//!   noise plus white records' noise would show ρ_m σ_m² / RMSE². A zone whose mean
//!   exceeds that by more than three standard errors of the mean (its drawpoints' spread
//!   over √G) is autocorrelated beyond the noise.
//!
//! A zone with a shape or that autocorrelation is structure: the fit reports that the model
//! does not explain the records ([`Diagnosis::explained`] false, and a warning that names
//! the zones and the stretches of the draw), and its intervals are the noise's alone, not
//! the model's distance from the process.

use std::collections::BTreeMap;

use nalgebra::{DMatrix, DVector};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::fit::Joint;
use super::problem::Eval;

/// Stretches of the draw the shape is read over.
pub const STRETCHES: usize = 4;
/// Sign flips of the shape's reference distribution.
pub const FLIPS: usize = 999;
/// The shape's family-wise level over every zone tested.
const LEVEL: f64 = 0.05;
/// Standard errors past the noise's autocorrelation that make a zone's autocorrelated.
const AUTOCORRELATION_SE: f64 = 3.0;
/// Fewest drawpoints a zone's shape and autocorrelation are read on: fewer cannot tell a
/// shared shape from one drawpoint's.
const MIN_DRAWPOINTS: usize = 3;
/// The zone of drawpoints that name none.
pub const NO_ZONE: &str = "(none)";
/// Every drawpoint together, read beside the zones when there are several: a difference
/// between model and process that every zone shares (a mechanism, not a zone's input) is
/// seen best there.
pub const ALL: &str = "(all)";

/// What the residuals at the fitted values say of the model (module docs).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Diagnosis {
    /// Edges of the stretches of the draw, a drawpoint's cumulative tonnes (t): stretch s
    /// runs from `stretches[s]` to `stretches[s + 1]`.
    pub stretches: Vec<f64>,
    /// Per zone of the drawpoints, in name order.
    pub zones: Vec<ZoneDiagnosis>,
    /// No zone has a shape or an autocorrelation beyond the noise.
    pub explained: bool,
}

/// One zone's diagnosis. RMSEs in the grade's unit.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ZoneDiagnosis {
    /// The drawpoints' zone ([`NO_ZONE`] for those without).
    pub zone: String,
    /// Drawpoints with matched rows.
    pub drawpoints: usize,
    /// Matched rows.
    pub n: usize,
    /// RMSE before calibration, over the rows the held-out skill is read on.
    pub rmse_before: f64,
    /// RMSE of the linearised fit with every drawpoint in, same rows.
    pub rmse_fit: f64,
    /// RMSE of each drawpoint's rows predicted by the fit without it, same rows (NaN
    /// without a joint fit of zones).
    pub rmse_held_out: f64,
    /// 1 − held-out² / before²: above 0, the fit predicts drawpoints it has not seen
    /// better than the start.
    pub skill: f64,
    /// The drawpoints' mean residual in each stretch (NaN where fewer than 3 have rows).
    pub shape: Vec<f64>,
    /// Its t per stretch (mean over its standard error across the drawpoints).
    pub shape_t: Vec<f64>,
    /// The |t| that noise alone passes with probability 0.05 / Z (the sign flips').
    pub shape_limit: f64,
    /// The sign-flip p-value of the largest |t| (NaN when not tested).
    pub shape_p: f64,
    /// Stretches whose |t| passes `shape_limit`.
    pub shaped: Vec<usize>,
    /// Mean lag-one autocorrelation of the drawpoints' residuals along their draw.
    pub autocorrelation: f64,
    /// What the model's own noise gives (module docs).
    pub autocorrelation_noise: f64,
    /// Standard error of `autocorrelation` (the drawpoints' spread over √G).
    pub autocorrelation_se: f64,
    /// Autocorrelated beyond the noise.
    pub autocorrelated: bool,
}

impl ZoneDiagnosis {
    /// Whether the zone's residuals are structure rather than noise.
    pub fn structured(&self) -> bool {
        !self.shaped.is_empty() || self.autocorrelated
    }
}

/// Rows keyed (drawpoint, period) → value, grouped by drawpoint in period order.
type Rows = BTreeMap<(String, i64), f64>;

/// The diagnosis of the residuals of `after` (the run at θ̂): `before` the run at the
/// start, `twins` the runs at θ̂ on the twin lattices, `joint` the zones' fit (None when
/// only global factors were fitted), `zone_of` each drawpoint's zone.
pub(super) fn diagnose(
    after: &Eval,
    before: &Eval,
    twins: &[Eval],
    joint: Option<&Joint>,
    zone_of: &BTreeMap<String, String>,
) -> Diagnosis {
    let zone = |d: &str| zone_of.get(d).map_or(NO_ZONE, String::as_str).to_string();
    let stretches = edges(after.drawn.values().copied().collect());
    let held = joint
        .map(|j| held_out(&j.keys, &j.lin.j, &after.rows))
        .unwrap_or_default();
    // Per zone: its drawpoints' rows.
    let mut by_zone: BTreeMap<String, Vec<&str>> = BTreeMap::new();
    for d in drawpoints(&after.rows) {
        by_zone.entry(zone(d)).or_default().push(d);
    }
    if by_zone.len() > 1 {
        by_zone.insert(ALL.to_string(), drawpoints(&after.rows));
    }
    let tested = by_zone
        .values()
        .filter(|dps| dps.len() >= MIN_DRAWPOINTS)
        .count()
        .max(1);
    let quantile = 1.0 - LEVEL / tested as f64;
    let zones: Vec<ZoneDiagnosis> = by_zone
        .iter()
        .enumerate()
        .map(|(k, (name, dps))| {
            let rows: Vec<Vec<f64>> = dps.iter().map(|d| series(&after.rows, d)).collect();
            let n = rows.iter().map(Vec::len).sum();
            let (rmse_before, rmse_fit, rmse_held_out) = skill_rows(dps, &held, before);
            // Shape: each drawpoint's mean residual per stretch.
            let means: Vec<Vec<Option<f64>>> = dps
                .iter()
                .map(|d| stretch_means(&after.rows, &after.drawn, d, &stretches))
                .collect();
            let shape = (0..STRETCHES)
                .map(|s| stretch_t(&means, s, None))
                .collect::<Vec<_>>();
            let (shape_limit, shape_p) = if dps.len() >= MIN_DRAWPOINTS {
                sign_flips(&means, quantile, 0x5eed ^ k as u64)
            } else {
                (f64::NAN, f64::NAN)
            };
            let shaped = (0..STRETCHES)
                .filter(|&s| shape[s].1.abs() >= shape_limit)
                .collect();
            // Autocorrelation: the residuals' and the noise's.
            let r1: Vec<f64> = rows.iter().filter_map(|e| lag_one(e)).collect();
            let (autocorrelation, autocorrelation_se) = mean_se(&r1);
            let noise = noise_autocorrelation(after, twins, dps);
            let rmse2 = rows.iter().flatten().map(|e| e * e).sum::<f64>() / n as f64;
            let autocorrelation_noise = noise.0 * (noise.1 / rmse2).min(1.0);
            let autocorrelated = r1.len() >= MIN_DRAWPOINTS
                && autocorrelation - autocorrelation_noise
                    > AUTOCORRELATION_SE * autocorrelation_se;
            ZoneDiagnosis {
                zone: name.clone(),
                drawpoints: dps.len(),
                n,
                rmse_before,
                rmse_fit,
                rmse_held_out,
                skill: 1.0 - (rmse_held_out / rmse_before).powi(2),
                shape: shape.iter().map(|s| s.0).collect(),
                shape_t: shape.iter().map(|s| s.1).collect(),
                shape_limit,
                shape_p,
                shaped,
                autocorrelation,
                autocorrelation_noise,
                autocorrelation_se,
                autocorrelated,
            }
        })
        .collect();
    Diagnosis {
        stretches,
        explained: !zones.iter().any(ZoneDiagnosis::structured),
        zones,
    }
}

/// The drawpoints of `rows`, in order.
fn drawpoints(rows: &Rows) -> Vec<&str> {
    let mut out: Vec<&str> = rows.keys().map(|k| k.0.as_str()).collect();
    out.dedup();
    out
}

/// Drawpoint `d`'s entries of `rows` (keyed by drawpoint and period), in period order.
fn of<'a, V>(
    rows: &'a BTreeMap<(String, i64), V>,
    d: &str,
) -> std::collections::btree_map::Range<'a, (String, i64), V> {
    rows.range((d.to_string(), i64::MIN)..=(d.to_string(), i64::MAX))
}

/// Drawpoint `d`'s values in period order.
fn series(rows: &Rows, d: &str) -> Vec<f64> {
    of(rows, d).map(|(_, &e)| e).collect()
}

/// The edges of [`STRETCHES`] stretches with equal shares of `drawn`.
fn edges(mut drawn: Vec<f64>) -> Vec<f64> {
    drawn.retain(|x| x.is_finite());
    drawn.sort_by(f64::total_cmp);
    if drawn.is_empty() {
        return Vec::new();
    }
    (0..=STRETCHES)
        .map(|s| drawn[(s * (drawn.len() - 1)) / STRETCHES])
        .collect()
}

/// Drawpoint `d`'s mean residual in each stretch of `edges` (None where it has no row).
fn stretch_means(rows: &Rows, drawn: &Rows, d: &str, edges: &[f64]) -> Vec<Option<f64>> {
    let mut sum = [(0.0, 0usize); STRETCHES];
    for (key, &e) in of(rows, d) {
        let Some(&t) = drawn.get(key) else { continue };
        let s = (1..STRETCHES)
            .take_while(|&s| edges.get(s).is_some_and(|&x| t > x))
            .count();
        sum[s].0 += e;
        sum[s].1 += 1;
    }
    sum.iter()
        .map(|&(s, n)| (n > 0).then(|| s / n as f64))
        .collect()
}

/// Stretch `s`'s mean over the drawpoints that have it and its t, each drawpoint's value
/// times its sign in `signs` (all +1 for None); NaNs with fewer than 3 drawpoints.
fn stretch_t(means: &[Vec<Option<f64>>], s: usize, signs: Option<&[f64]>) -> (f64, f64) {
    let v: Vec<f64> = means
        .iter()
        .enumerate()
        .filter_map(|(g, m)| m[s].map(|x| x * signs.map_or(1.0, |f| f[g])))
        .collect();
    if v.len() < MIN_DRAWPOINTS {
        return (f64::NAN, f64::NAN);
    }
    let (mean, se) = mean_se(&v);
    (mean, if se > 0.0 { mean / se } else { f64::NAN })
}

/// The largest |t| over the stretches (NaNs ignored).
fn max_t(means: &[Vec<Option<f64>>], signs: Option<&[f64]>) -> f64 {
    (0..STRETCHES)
        .map(|s| stretch_t(means, s, signs).1.abs())
        .filter(|t| t.is_finite())
        .fold(0.0, f64::max)
}

/// The sign-flip reference of the largest |t| (module docs): its `quantile` and the
/// p-value of the observed one.
fn sign_flips(means: &[Vec<Option<f64>>], quantile: f64, seed: u64) -> (f64, f64) {
    let observed = max_t(means, None);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut flipped: Vec<f64> = (0..FLIPS)
        .map(|_| {
            let signs: Vec<f64> = means
                .iter()
                .map(|_| if rng.random::<bool>() { 1.0 } else { -1.0 })
                .collect();
            max_t(means, Some(&signs))
        })
        .collect();
    flipped.sort_by(f64::total_cmp);
    let at = ((quantile * FLIPS as f64).ceil() as usize).clamp(1, FLIPS) - 1;
    let beyond = flipped.iter().filter(|&&t| t >= observed).count();
    (flipped[at], (1 + beyond) as f64 / (1 + FLIPS) as f64)
}

/// The mean of `v` and its standard error, the sample standard deviation over √n (NaN
/// for fewer than 2 values).
pub(super) fn mean_se(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    if v.len() < 2 {
        return (mean, f64::NAN);
    }
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

/// The lag-one autocorrelation Σ e_t e_t+1 / Σ e_t² of a series of at least 4 values
/// (None otherwise, or with no variance).
fn lag_one(e: &[f64]) -> Option<f64> {
    let ss: f64 = e.iter().map(|x| x * x).sum();
    (e.len() >= 4 && ss > 0.0).then(|| e.windows(2).map(|w| w[0] * w[1]).sum::<f64>() / ss)
}

/// The model's noise over drawpoints `dps` (module docs): the mean lag-one autocorrelation
/// of the twins' differences from `after`, and the noise's variance σ_m², the differences'
/// mean square over 2.
fn noise_autocorrelation(after: &Eval, twins: &[Eval], dps: &[&str]) -> (f64, f64) {
    let mut r1 = Vec::new();
    let (mut ss, mut n) = (0.0, 0usize);
    for twin in twins {
        for d in dps {
            let diff: Vec<f64> = of(&after.rows, d)
                .filter_map(|(k, e)| twin.rows.get(k).map(|f| f - e))
                .collect();
            ss += diff.iter().map(|x| x * x).sum::<f64>();
            n += diff.len();
            r1.extend(lag_one(&diff));
        }
    }
    if r1.is_empty() || n == 0 {
        return (0.0, 0.0);
    }
    (mean_se(&r1).0, ss / (2.0 * n as f64))
}

/// Per row of `keys` that `rows` has (the residuals e at θ̂; `j` the Jacobian, one row per
/// key, keys grouped by drawpoint): (residual of the linearised fit with every drawpoint
/// in, residual of the fit without the row's drawpoint), keyed as the rows (module docs,
/// "Held-out skill"). A drawpoint whose removal leaves the normal matrix singular (a zone
/// no other drawpoint informs) is left out.
fn held_out(
    keys: &[(String, i64)],
    j: &DMatrix<f64>,
    rows: &Rows,
) -> BTreeMap<(String, i64), (f64, f64)> {
    let at: Vec<usize> = (0..keys.len())
        .filter(|&r| rows.contains_key(&keys[r]))
        .collect();
    let j = DMatrix::from_fn(at.len(), j.ncols(), |r, c| j[(at[r], c)]);
    let e = DVector::from_iterator(at.len(), at.iter().map(|&r| rows[&keys[r]]));
    let a = j.transpose() * &j;
    let g = j.transpose() * &e;
    let Some(full) = a.clone().cholesky().map(|c| -c.solve(&g)) else {
        return BTreeMap::new();
    };
    let fitted = &e + &j * full;
    let mut out = BTreeMap::new();
    let mut start = 0;
    while start < at.len() {
        let d = &keys[at[start]].0;
        let end = start + at[start..].iter().take_while(|&&r| &keys[r].0 == d).count();
        let jg = j.rows(start, end - start);
        let eg = e.rows(start, end - start);
        let a_g = &a - jg.transpose() * jg;
        let g_g = &g - jg.transpose() * eg;
        if let Some(c) = a_g.cholesky() {
            let held = eg + jg * (-c.solve(&g_g));
            for (i, r) in (start..end).enumerate() {
                out.insert(keys[at[r]].clone(), (fitted[r], held[i]));
            }
        }
        start = end;
    }
    out
}

/// RMSE before, of the fit, and held out, over the rows of drawpoints `dps` that the
/// held-out refit covers (all NaN when it covers none).
fn skill_rows(
    dps: &[&str],
    held: &BTreeMap<(String, i64), (f64, f64)>,
    before: &Eval,
) -> (f64, f64, f64) {
    let (mut b, mut f, mut h, mut n) = (0.0, 0.0, 0.0, 0usize);
    for d in dps {
        for (key, &(fit, out)) in of(held, d) {
            let Some(e0) = before.rows.get(key) else {
                continue;
            };
            b += e0 * e0;
            f += fit * fit;
            h += out * out;
            n += 1;
        }
    }
    let rms = |s: f64| {
        if n == 0 {
            f64::NAN
        } else {
            (s / n as f64).sqrt()
        }
    };
    (rms(b), rms(f), rms(h))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A shape shared by every drawpoint passes the sign-flip limit; the same residuals
    /// with signs that alternate between drawpoints (no shared shape) do not.
    #[test]
    fn a_shared_shape_passes_the_sign_flip_limit_and_noise_does_not() {
        let shared: Vec<Vec<Option<f64>>> = (0..12)
            .map(|g| {
                let wobble = 0.1 * ((g * 7 % 5) as f64 - 2.0);
                vec![
                    Some(-1.0 + wobble),
                    Some(0.0),
                    Some(0.3 - wobble),
                    Some(1.0 + wobble),
                ]
            })
            .collect();
        let (limit, p) = sign_flips(&shared, 0.95, 1);
        assert!(max_t(&shared, None) > limit && p < 0.01, "{limit} {p}");
        let alternating: Vec<Vec<Option<f64>>> = shared
            .iter()
            .enumerate()
            .map(|(g, m)| {
                let s = if g % 2 == 0 { 1.0 } else { -1.0 };
                m.iter().map(|x| x.map(|v| v * s)).collect()
            })
            .collect();
        let (limit, p) = sign_flips(&alternating, 0.95, 1);
        assert!(max_t(&alternating, None) < limit && p > 0.05, "{limit} {p}");
    }

    /// The held-out residuals are those of a least-squares refit made without the
    /// drawpoint's rows, and the in-fit ones those of the refit with every row.
    #[test]
    fn held_out_residuals_are_those_of_a_refit_without_the_drawpoint() {
        let keys: Vec<(String, i64)> = (0..12).map(|r| (format!("d{}", r / 3), r)).collect();
        let j = DMatrix::from_fn(12, 2, |r, c| ((r * 7 + c * 3) % 5) as f64 - 1.5 + c as f64);
        let rows: Rows = keys
            .iter()
            .enumerate()
            .map(|(r, k)| (k.clone(), ((r * 11) % 7) as f64 - 3.0))
            .collect();
        let held = held_out(&keys, &j, &rows);
        let e = DVector::from_iterator(12, keys.iter().map(|k| rows[k]));
        let refit = |keep: &dyn Fn(usize) -> bool| {
            let idx: Vec<usize> = (0..12).filter(|&r| keep(r)).collect();
            let jk = DMatrix::from_fn(idx.len(), 2, |r, c| j[(idx[r], c)]);
            let ek = DVector::from_iterator(idx.len(), idx.iter().map(|&r| e[r]));
            let delta = (jk.transpose() * &jk).try_inverse().unwrap() * jk.transpose() * ek;
            &e - &j * delta
        };
        let all = refit(&|_| true);
        for g in 0..4 {
            let without = refit(&|r| r / 3 != g);
            for r in 3 * g..3 * g + 3 {
                let (f, h) = held[&keys[r]];
                assert!((f - all[r]).abs() < 1e-9 && (h - without[r]).abs() < 1e-9);
            }
        }
    }

    /// The lag-one autocorrelation of a slow wave is near 1, of an alternating series −1.
    #[test]
    fn lag_one_reads_a_wave_and_an_alternation() {
        let wave: Vec<f64> = (0..40).map(|t| (t as f64 / 10.0).sin()).collect();
        assert!(lag_one(&wave).unwrap() > 0.9);
        let alt: Vec<f64> = (0..40)
            .map(|t| if t % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        assert!((lag_one(&alt).unwrap() + 0.975).abs() < 1e-12);
        assert!(lag_one(&[1.0, 2.0, 3.0]).is_none());
    }
}
