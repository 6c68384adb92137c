//! The fit (module docs, steps 1–3): each zone's profile over the coarse grid, one zone at
//! a time, the zones jointly by Gauss–Newton on a regression over the runs near the
//! centre, each made whole on every marker lattice at once; then the global factors on
//! their grids.

use std::collections::BTreeMap;
use std::sync::Mutex;

use nalgebra::{DMatrix, DVector};
use polars::prelude::*;

use super::problem::{frag_factor, rmse, Eval, Problem, Runs, Trial};
use super::{CalibrateConfig, CalibrateError};
use crate::analysis::least_squares::Linearised;
use crate::analysis::lockstep::Lockstep;
use crate::model::scenario::Calibration;

/// A parameter's profile: (value, (Σ e², n)) per run.
pub(super) type Profile = Vec<(f64, (f64, usize))>;

/// The value with the least Σ e² (1 for an empty profile).
pub(super) fn argmin(prof: &Profile) -> f64 {
    prof.iter()
        .min_by(|a, b| a.1 .0.total_cmp(&b.1 .0))
        .map_or(1.0, |p| p.0)
}

/// The runs of step 1 (the start and the coarse grid) and the rows each zone is judged on.
pub(super) struct First<'a> {
    /// The start, then the coarse grid's values but the start.
    pub(super) cals: &'a [Calibration],
    /// The coarse grid, every zone at one value.
    pub(super) coarse: &'a [Calibration],
    /// Each zone's rows: those of the drawpoints whose zone it is (None: all rows).
    pub(super) zone_rows: &'a BTreeMap<String, Option<String>>,
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

/// The zones fitted on every marker lattice (steps 1–2).
pub(super) struct Zones {
    /// Each zone's factor: the mean of its fits on the lattices.
    pub(super) means: Vec<f64>,
    /// The fit on the scenario's lattice.
    pub(super) joint: Joint,
    /// The profiles of the scenario's lattice's fit.
    pub(super) profiles: BTreeMap<String, Profile>,
    /// Per zone, its fit on each lattice (with more than one; empty otherwise).
    pub(super) lattice_values: Vec<Vec<f64>>,
}

/// Steps 1–2 on each lattice, each on its own thread, their batches made together
/// ([`Lockstep`]), from the runs of `first` on every lattice (`first_evals`, one list per
/// lattice, the scenario's first).
pub(super) fn on_lattices(
    p: &Problem,
    cfg: &CalibrateConfig,
    first: &First,
    first_evals: Vec<Vec<Eval>>,
    tick: &mut (dyn FnMut(usize) + Send),
) -> Result<Zones, CalibrateError> {
    let run = |trials: Vec<Trial>| p.runs.predict(p, &trials);
    let group = Lockstep::new(&run, first_evals.len());
    let ticks = Mutex::new(tick);
    let fits = std::thread::scope(|s| {
        let threads: Vec<_> = first_evals
            .into_iter()
            .enumerate()
            .map(|(lattice, evals)| {
                let (group, ticks) = (&group, &ticks);
                s.spawn(move || {
                    let member = Member { group, lattice };
                    let q = Problem {
                        runs: &member,
                        grade: p.grade.clone(),
                        ..*p
                    };
                    let tick = &mut |k| (ticks.lock().unwrap_or_else(|e| e.into_inner()))(k);
                    fit_zones(&q, cfg, first, evals, lattice, tick)
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
    let profiles = std::mem::take(&mut fits[0].1);
    let fits: Vec<Joint> = fits.into_iter().map(|f| f.0).collect();
    let n = fits.len() as f64;
    let means = (0..cfg.zones.len())
        .map(|k| fits.iter().map(|f| f.theta[k]).sum::<f64>() / n)
        .collect();
    let lattice_values = if fits.len() > 1 {
        (0..cfg.zones.len())
            .map(|k| fits.iter().map(|f| f.theta[k]).collect())
            .collect()
    } else {
        Vec::new()
    };
    Ok(Zones {
        means,
        joint: fits.into_iter().next().expect("one lattice at least"),
        profiles,
        lattice_values,
    })
}

/// Step 3: the n1 then the φ factor (those `cfg` fits), each over `cfg.global` with the
/// rest of `cal` fixed, judged on all rows; each takes its profile's best run into `cal`
/// and its profile into `profiles`.
pub(super) fn globals(
    p: &Problem,
    cfg: &CalibrateConfig,
    cal: &mut Calibration,
    profiles: &mut BTreeMap<String, Profile>,
    tick: &mut dyn FnMut(usize),
) -> Result<(), CalibrateError> {
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
        tick(cands.len());
        let prof: Profile = cfg
            .global
            .iter()
            .zip(&evals)
            .map(|(&f, e)| (f, e.all))
            .collect();
        *field(cal) = argmin(&prof);
        profiles.insert(name.to_string(), prof);
    }
    Ok(())
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

/// Relative steps of the joint fit's probes, by iteration (the last one repeats): the
/// engine's response is ragged at the scale of single markers, so a step must move the
/// IMZs by much more than a marker's worth.
const FD_STEPS: [f64; 2] = [0.15, 0.1];
/// Iterations of the joint fit at most.
pub(super) const MAX_ITERATIONS: usize = 3;
/// Runs per iteration of the joint fit: the centre and two probes per zone.
pub(super) fn runs_per_iteration(zones: usize) -> usize {
    2 * zones + 1
}
/// Largest relative change of a factor in one step (a trust region for a Jacobian measured
/// on a ragged response).
const TRUST: f64 = 0.3;
/// The joint fit stops when no factor changes by more than this share in an iteration.
const CONVERGED: f64 = 0.01;

/// The joint fit of every zone's factor (module docs, step 2).
pub(super) struct Joint {
    /// Fitted factors, in the order of the zones.
    pub(super) theta: Vec<f64>,
    /// The residuals and Jacobian of the last iteration, keyed rows.
    pub(super) lin: Linearised,
    /// The rows of `lin`.
    pub(super) keys: Vec<(String, i64)>,
    /// Every evaluated point: factors and errors.
    points: Vec<(Vec<f64>, Eval)>,
    /// The centre of every iteration.
    centres: Vec<Vec<f64>>,
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
