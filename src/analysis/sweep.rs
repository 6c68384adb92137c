//! The speed–accuracy sweep (DESIGN §9): one scene run at a grid of resolutions around the
//! default, each timed and compared with a converged reference run.
//!
//! A resolution is given as multipliers of the default one ([`resolution::resolve`]): of the
//! disk thickness h, of the marker spacing and of the draw increment, applied by
//! [`resolution::scaled`]. Each point of the full
//! factorial grid is run once (or `repeats` times, keeping the median wall time), and so is
//! the reference. The sweep runs the scene's whole schedule (`--keep-periods` shortens it):
//! the early periods, before waste reaches any drawpoint, hide most of the error. The errors
//! against the reference are:
//!
//! - **grade RMSE**: the root mean square difference of the first grade over every
//!   drawpoint-period that both runs drew from, divided by the reference's mean grade over the
//!   same rows (a relative error: 0.01 is 1%);
//! - **late grade RMSE**: the same over the second half of the schedule's periods, where
//!   ore and waste mix;
//! - **dilution entry**: per drawpoint, the cumulative tonnes at which the waste share of a
//!   period first reaches [`DILUTION_ENTRY_SHARE`](crate::output::dilution::DILUTION_ENTRY_SHARE) (interpolated between the midpoints of
//!   that period and the one before); the mean relative difference over the drawpoints
//!   where both runs reach it;
//! - **IMZ width**: per drawpoint, the widest disk (2 R) at the last period; the mean relative
//!   difference over drawpoints;
//! - **IEZ height**: per drawpoint, the 95th percentile of the drawn markers' origin heights
//!   above the drawpoint (the extent of the isolated extraction zone); the mean relative
//!   difference over drawpoints.
//!
//! # The reference and its own error
//! REBOP has no closed form to compare against, so the reference is a fine run, and the
//! errors are distances to it. Its error is the markers' sampling noise and its bias
//! (`docs::resolution`, "Sampling noise"); for the noise the reference is run twice, on
//! the lattice and on its twin, moved in plan by
//! [`TWIN_OFFSET`](crate::model::scenario::TWIN_OFFSET) (`resolution.lattice_offset`): two
//! equally good samples of the same ground. The errors are distances to their mean (per
//! drawpoint-period for the grades, per drawpoint for the rest). Half the distance between
//! the two is the noise ν of that mean (two independent noises σ lie √2 σ apart; their
//! mean is σ/√2 from the limit). One pair is a rough sample of the noise: at the demo's
//! default resolution, pairs of lattice offsets lie 1.3–1.9% apart over √2
//! (`docs::resolution`, "Sampling noise").
//!
//! What noise does not explain is bias. A check at twice the reference's h and spacing
//! (same increment, every marker every update), also run twice the same way, has its mean
//! at d_c from the reference, and that mean's own noise is ν_c (half the distance between
//! its two runs). The part of d_c that neither noise explains, b = √(max(0, d_c² − ν_c² −
//! ν²)), is the bias between the check and the reference; if the bias falls at least as the
//! resolution (first order), the reference's own bias is at most b. The reference row holds
//! its own error √(ν² + b²), per measure; the check row holds d_c (`is_reference_check`).
//!
//! Every run is made with `flow.enforce_stability = false`: the coarse and fine corners of the
//! grid are studies of the method, never predictions, and may fall outside where it holds.

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

use crate::engine::result::{ResolvedResolution, RunOutput};
use crate::engine::{resolution, Engine, EngineError, RunPlan};
use crate::model::{Scenario, Scene};
use crate::output::charts::{sweep_chart, ChartError, SweepPoint};
use crate::output::columns::{f64s, i64s, write_table};
use crate::output::dilution::dilution_entries;
use crate::output::OutputError;
use crate::schema::SWEEP;

/// Which resolutions to run.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepConfig {
    /// Multipliers of the default disk thickness h.
    pub h: Vec<f64>,
    /// Multipliers of the default marker spacing.
    pub spacing: Vec<f64>,
    /// Multipliers of the default draw increment.
    pub increment: Vec<f64>,
    /// Multipliers (h, spacing, increment) of the converged reference.
    pub reference: [f64; 3],
    /// Runs per point; the median wall time is kept (the outputs are deterministic).
    pub repeats: usize,
    /// Accuracy target (grade RMSE, 0.01 = 1%) for which the automatic resolution
    /// ([`resolution::resolve`] with `resolution.target_grade_rmse`) is run and marked too;
    /// the scenario's own target, when it sets one, comes first. None: not run.
    pub target: Option<f64>,
}

impl Default for SweepConfig {
    fn default() -> Self {
        SweepConfig {
            h: vec![2.0, 1.0, 0.5],
            spacing: vec![2.0, 1.0, 0.5],
            increment: vec![4.0, 1.0, 0.25],
            reference: [0.5, 0.5, 0.25],
            repeats: 1,
            target: None,
        }
    }
}

/// One run of the sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepRow {
    /// Multipliers of the default (h, spacing, increment).
    pub mult: [f64; 3],
    /// The resolution run.
    pub resolution: ResolvedResolution,
    /// Median wall time, s.
    pub wall_s: f64,
    /// Markers mobilised.
    pub markers: u64,
    /// Relative grade RMSE over drawpoint-periods (0.01 = 1%).
    pub grade_rmse: f64,
    /// Relative grade RMSE over the drawpoint-periods of the second half of the schedule.
    pub grade_rmse_late: f64,
    /// Mean relative error of the dilution entry per drawpoint.
    pub dilution_entry_error: f64,
    /// Mean relative error of the widest IMZ disk per drawpoint.
    pub imz_width_error: f64,
    /// Mean relative error of the IEZ height (95th percentile origin height) per drawpoint.
    pub iez_height_error: f64,
    /// Credited / scheduled tonnes.
    pub delivered: f64,
    /// This is the default resolution.
    pub is_default: bool,
    /// This is the reference run (its error columns hold its own estimated error).
    pub is_reference: bool,
    /// This is the check run of the reference's own error (twice its h and spacing).
    pub is_reference_check: bool,
    /// This is the automatic resolution for the sweep's accuracy target.
    pub is_auto: bool,
    /// On the Pareto front of wall time against grade RMSE.
    pub pareto: bool,
}

/// Errors of a sweep.
#[derive(Debug, thiserror::Error)]
pub enum SweepError {
    /// A run could not start.
    #[error("run at multipliers {mult:?}: {source}")]
    Engine {
        /// Multipliers of the run.
        mult: [f64; 3],
        /// Cause.
        source: EngineError,
    },
    /// Writing the table failed.
    #[error(transparent)]
    Output(#[from] OutputError),
    /// Drawing the chart failed.
    #[error(transparent)]
    Chart(#[from] ChartError),
}

/// Runs the scene at resolution `res` (`mult` times the default), `repeats` times; returns
/// the output of the last run and the median wall time.
fn run_at(
    scene: &Scene,
    base: &Scenario,
    res: &ResolvedResolution,
    mult: [f64; 3],
    repeats: usize,
) -> Result<(RunOutput, f64), SweepError> {
    let mut sc = base.clone();
    sc.flow.enforce_stability = false;
    let plan =
        RunPlan::at(scene, &sc, *res).map_err(|source| SweepError::Engine { mult, source })?;
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..repeats.max(1) {
        let t = Instant::now();
        let out = Engine::with_plan(scene, &sc, plan.clone()).run(&mut |_, _| {});
        times.push(t.elapsed().as_secs_f64());
        last = Some(out);
    }
    times.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    Ok((last.expect("at least one run"), median))
}

/// Per drawpoint, the widest disk (2 R) at the last period in the IMZ table.
fn imz_widths(out: &RunOutput, n_dp: usize) -> Vec<f64> {
    let t = &out.imz;
    let last = t.period.iter().copied().max().unwrap_or(0);
    let mut w = vec![0.0f64; n_dp];
    for i in 0..t.period.len() {
        if t.period[i] == last {
            let d = t.drawpoint[i] as usize;
            w[d] = w[d].max(2.0 * t.radius[i]);
        }
    }
    w
}

/// Per drawpoint, the 95th percentile of drawn origin heights above the drawpoint (NaN if
/// it drew nothing).
fn iez_heights(out: &RunOutput, scene: &Scene) -> Vec<f64> {
    let n_dp = scene.drawpoints.len();
    let mut heights = vec![Vec::new(); n_dp];
    for t in out.drawn_chunks(crate::engine::marker_tables::CHUNK_ROWS) {
        for i in 0..t.drawpoint.len() {
            let d = t.drawpoint[i] as usize;
            if d < n_dp {
                heights[d].push(t.origin_z[i] - scene.drawpoints.z[d]);
            }
        }
    }
    heights
        .into_iter()
        .map(|mut v| {
            if v.is_empty() {
                return f64::NAN;
            }
            v.sort_by(f64::total_cmp);
            v[((v.len() - 1) as f64 * 0.95).round() as usize]
        })
        .collect()
}

/// Mean of |a − r| / |r| over the pairs where both are finite and r is not zero.
fn mean_relative(a: &[f64], r: &[f64]) -> f64 {
    let (sum, n) = a
        .iter()
        .zip(r)
        .filter(|(a, r)| a.is_finite() && r.is_finite() && **r != 0.0)
        .fold((0.0, 0usize), |(s, n), (a, r)| {
            (s + ((a - r) / r).abs(), n + 1)
        });
    if n == 0 {
        f64::NAN
    } else {
        sum / n as f64
    }
}

/// Relative RMSE of the first grade over the drawpoint-periods both runs drew from.
pub fn grade_rmse(out: &RunOutput, reference: &RunOutput) -> f64 {
    rmse_from(&grades(out), &grades(reference), i64::MIN)
}

/// The first grade per (drawpoint, period), where finite.
fn grades(out: &RunOutput) -> BTreeMap<(u32, i64), f64> {
    let e = &out.extraction;
    let Some(g) = e.grades.first() else {
        return BTreeMap::new();
    };
    (0..e.period.len())
        .filter(|&i| g[i].is_finite())
        .map(|i| ((e.drawpoint[i], e.period[i]), g[i]))
        .collect()
}

/// Root mean square of g − r over the keys both hold, from period `first` on, over the
/// mean of r there.
fn rmse_from(g: &BTreeMap<(u32, i64), f64>, r: &BTreeMap<(u32, i64), f64>, first: i64) -> f64 {
    let (mut sq, mut sum, mut n) = (0.0, 0.0, 0usize);
    for (k, &rk) in r.iter().filter(|(k, _)| k.1 >= first) {
        if let Some(&gk) = g.get(k) {
            sq += (gk - rk).powi(2);
            sum += rk;
            n += 1;
        }
    }
    if n == 0 || sum == 0.0 {
        return f64::NAN;
    }
    (sq / n as f64).sqrt() / (sum / n as f64).abs()
}

/// What the errors compare, of one run or the mean of two (module docs).
struct Measures {
    /// First grade per (drawpoint, period).
    grade: BTreeMap<(u32, i64), f64>,
    /// Per drawpoint: dilution entry, widest disk, IEZ height.
    de: Vec<f64>,
    w: Vec<f64>,
    h: Vec<f64>,
}

impl Measures {
    fn of(out: &RunOutput, scene: &Scene) -> Measures {
        let n_dp = scene.drawpoints.len();
        Measures {
            grade: grades(out),
            de: dilution_entries(out, n_dp),
            w: imz_widths(out, n_dp),
            h: iez_heights(out, scene),
        }
    }

    /// The mean of two runs' measures (NaN where either has none).
    fn mean(&self, o: &Measures) -> Measures {
        let mid = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| 0.5 * (x + y)).collect();
        Measures {
            grade: self
                .grade
                .iter()
                .filter_map(|(k, &g)| o.grade.get(k).map(|&go| (*k, 0.5 * (g + go))))
                .collect(),
            de: mid(&self.de, &o.de),
            w: mid(&self.w, &o.w),
            h: mid(&self.h, &o.h),
        }
    }

    /// Errors of these measures against `r`; `late` is the first period of the second half.
    fn errors(&self, r: &Measures, late: i64) -> Errors {
        Errors {
            grade: rmse_from(&self.grade, &r.grade, i64::MIN),
            grade_late: rmse_from(&self.grade, &r.grade, late),
            de: mean_relative(&self.de, &r.de),
            w: mean_relative(&self.w, &r.w),
            h: mean_relative(&self.h, &r.h),
        }
    }
}

/// Marks the rows on the Pareto front of wall time against grade RMSE: no other row is both
/// faster and more accurate. The reference (whose errors are its own estimate) is left off.
fn mark_pareto(rows: &mut [SweepRow]) {
    let mut order: Vec<usize> = (0..rows.len())
        .filter(|&i| !rows[i].is_reference && rows[i].grade_rmse.is_finite())
        .collect();
    order.sort_by(|&a, &b| {
        rows[a]
            .wall_s
            .total_cmp(&rows[b].wall_s)
            .then(rows[a].grade_rmse.total_cmp(&rows[b].grade_rmse))
    });
    let mut best = f64::INFINITY;
    for i in order {
        rows[i].pareto = rows[i].grade_rmse < best;
        best = best.min(rows[i].grade_rmse);
    }
}

/// Runs the sweep. `progress(done, total, row)` is called after each run.
pub fn sweep(
    scene: &Scene,
    base: &Scenario,
    cfg: &SweepConfig,
    progress: &mut dyn FnMut(usize, usize, &SweepRow),
) -> Result<Vec<SweepRow>, SweepError> {
    let mut plain = base.clone();
    plain.resolution.target_grade_rmse = None;
    let default = resolution::resolve(scene, &plain);
    let mut grid: Vec<[f64; 3]> = vec![cfg.reference];
    for &h in &cfg.h {
        for &s in &cfg.spacing {
            for &i in &cfg.increment {
                let m = [h, s, i];
                if !grid.contains(&m) {
                    grid.push(m);
                }
            }
        }
    }
    if !grid.contains(&[1.0; 3]) {
        grid.push([1.0; 3]);
    }
    let mut res: Vec<ResolvedResolution> = grid
        .iter()
        .map(|&m| resolution::scaled(&default, m))
        .collect();
    // The reference moves every marker at every update (no multi-rate cadence).
    res[0].max_marker_move = 0.0;
    // The automatic resolution, run as chosen (its multipliers are for the table).
    let auto_at = base
        .resolution
        .target_grade_rmse
        .or(cfg.target)
        .map(|target| {
            let mut sc = base.clone();
            sc.resolution.target_grade_rmse = Some(target);
            let auto = resolution::resolve(scene, &sc);
            grid.push([
                auto.layer_thickness / default.layer_thickness,
                auto.marker_spacing / default.marker_spacing,
                auto.draw_increment / default.draw_increment,
            ]);
            res.push(auto);
            grid.len() - 1
        });
    // The check of the reference's own error: twice its h and spacing, its increment, every
    // marker every update.
    let check_mult = [
        2.0 * cfg.reference[0],
        2.0 * cfg.reference[1],
        cfg.reference[2],
    ];
    let check_res = ResolvedResolution {
        max_marker_move: 0.0,
        ..resolution::scaled(&default, check_mult)
    };
    let total = grid.len() + 1;
    // The reference and its check, each run on the lattice and on its twin.
    let mut twin = base.clone();
    twin.resolution.lattice_offset = base.resolution.nth_twin_offset(1);
    // The second half of the schedule's periods.
    let ids = &scene.periods.id;
    let late = ids.get(ids.len() / 2).copied().unwrap_or(i64::MAX);
    let pair = |res: &ResolvedResolution, mult| -> Result<_, SweepError> {
        let (a, wall) = run_at(scene, base, res, mult, cfg.repeats)?;
        let (b, _) = run_at(scene, &twin, res, mult, 1)?;
        let (ma, mb) = (Measures::of(&a, scene), Measures::of(&b, scene));
        Ok((a, wall, ma.mean(&mb), ma.errors(&mb, late)))
    };
    let (reference, ref_wall, ref_mean, ref_apart) = pair(&res[0], cfg.reference)?;
    let errors = |out: &RunOutput| Measures::of(out, scene).errors(&ref_mean, late);
    let (check, check_wall, check_mean, check_apart) = pair(&check_res, check_mult)?;
    let check_errors = check_mean.errors(&ref_mean, late);
    let own = Errors::own(&ref_apart, &check_apart, &check_errors);
    let mut rows = Vec::with_capacity(total);
    for row in [
        SweepRow {
            is_reference: true,
            ..row_of(cfg.reference, &reference, ref_wall, &own)
        },
        SweepRow {
            is_reference_check: true,
            is_default: false,
            ..row_of(check_mult, &check, check_wall, &check_errors)
        },
    ] {
        progress(rows.len() + 1, total, &row);
        rows.push(row);
    }
    for (k, &mult) in grid.iter().enumerate().skip(1) {
        let (out, wall) = run_at(scene, base, &res[k], mult, cfg.repeats)?;
        let row = row_of(mult, &out, wall, &errors(&out));
        let row = SweepRow {
            is_auto: auto_at == Some(k),
            is_default: row.is_default && auto_at != Some(k),
            ..row
        };
        progress(rows.len() + 1, total, &row);
        rows.push(row);
    }
    mark_pareto(&mut rows);
    Ok(rows)
}

/// A run's errors against the reference (module docs).
struct Errors {
    grade: f64,
    grade_late: f64,
    de: f64,
    w: f64,
    h: f64,
}

impl Errors {
    /// The reference's own error (module docs), per measure: its noise ν (half the
    /// distance `apart` between its two runs) and the bias b that the distance `check`
    /// of the check's mean leaves unexplained by ν and the check's own noise ν_c (half
    /// the distance `check_apart` between its two runs).
    fn own(apart: &Errors, check_apart: &Errors, check: &Errors) -> Errors {
        let f = |apart: f64, check_apart: f64, check: f64| {
            let (nu, nu_c) = (0.5 * apart, 0.5 * check_apart);
            let b2 = (check * check - nu_c * nu_c - nu * nu).max(0.0);
            (nu * nu + b2).sqrt()
        };
        Errors {
            grade: f(apart.grade, check_apart.grade, check.grade),
            grade_late: f(apart.grade_late, check_apart.grade_late, check.grade_late),
            de: f(apart.de, check_apart.de, check.de),
            w: f(apart.w, check_apart.w, check.w),
            h: f(apart.h, check_apart.h, check.h),
        }
    }
}

fn row_of(mult: [f64; 3], out: &RunOutput, wall_s: f64, e: &Errors) -> SweepRow {
    let b = &out.balance;
    SweepRow {
        mult,
        resolution: out.resolution,
        wall_s,
        markers: b.markers_mobilised,
        grade_rmse: e.grade,
        grade_rmse_late: e.grade_late,
        dilution_entry_error: e.de,
        imz_width_error: e.w,
        iez_height_error: e.h,
        delivered: if b.scheduled_tonnes > 0.0 {
            b.credited_tonnes / b.scheduled_tonnes
        } else {
            f64::NAN
        },
        is_default: mult == [1.0; 3],
        is_reference: false,
        is_reference_check: false,
        is_auto: false,
        pareto: false,
    }
}

/// Writes the sweep table (`schemas/sweep.json`) to `path` (Parquet, atomically).
pub fn write_sweep(path: &Path, rows: &[SweepRow]) -> Result<(), OutputError> {
    let col = |f: &dyn Fn(&SweepRow) -> f64| f64s(rows.iter().map(f).collect());
    let flag = |f: &dyn Fn(&SweepRow) -> bool| i64s(rows.iter().map(|r| f(r) as i64).collect());
    let fixed = vec![
        ("h_mult", col(&|r| r.mult[0])),
        ("spacing_mult", col(&|r| r.mult[1])),
        ("increment_mult", col(&|r| r.mult[2])),
        ("layer_thickness", col(&|r| r.resolution.layer_thickness)),
        ("marker_spacing", col(&|r| r.resolution.marker_spacing)),
        ("draw_increment", col(&|r| r.resolution.draw_increment)),
        ("max_marker_move", col(&|r| r.resolution.max_marker_move)),
        ("wall_s", col(&|r| r.wall_s)),
        (
            "markers",
            i64s(rows.iter().map(|r| r.markers as i64).collect()),
        ),
        ("grade_rmse", col(&|r| r.grade_rmse)),
        ("grade_rmse_late", col(&|r| r.grade_rmse_late)),
        ("dilution_entry_error", col(&|r| r.dilution_entry_error)),
        ("imz_width_error", col(&|r| r.imz_width_error)),
        ("iez_height_error", col(&|r| r.iez_height_error)),
        ("delivered", col(&|r| r.delivered)),
        ("is_default", flag(&|r| r.is_default)),
        ("is_reference", flag(&|r| r.is_reference)),
        ("is_reference_check", flag(&|r| r.is_reference_check)),
        ("pareto", flag(&|r| r.pareto)),
        ("is_auto", flag(&|r| r.is_auto)),
    ];
    write_table(path, &SWEEP, fixed, Vec::new())
}

/// Draws error against time (`.png` or `.svg`), atomically.
pub fn write_sweep_chart(path: &Path, rows: &[SweepRow], title: &str) -> Result<(), ChartError> {
    let points: Vec<SweepPoint> = rows
        .iter()
        .filter(|r| !r.is_reference)
        .map(|r| SweepPoint {
            wall_s: r.wall_s,
            error: r.grade_rmse,
            label: r
                .mult
                .map(|m| format!("{}", (m * 100.0).round() / 100.0))
                .join("/"),
            pareto: r.pareto,
            is_default: r.is_default,
            is_auto: r.is_auto,
        })
        .collect();
    let ref_wall = rows
        .iter()
        .find(|r| r.is_reference)
        .map_or(f64::NAN, |r| r.wall_s);
    sweep_chart(path, &points, ref_wall, title)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(wall_s: f64, grade_rmse: f64) -> SweepRow {
        SweepRow {
            mult: [1.0; 3],
            resolution: ResolvedResolution::default(),
            wall_s,
            markers: 0,
            grade_rmse,
            grade_rmse_late: 0.0,
            dilution_entry_error: 0.0,
            imz_width_error: 0.0,
            iez_height_error: 0.0,
            delivered: 1.0,
            is_default: false,
            is_reference: false,
            is_reference_check: false,
            is_auto: false,
            pareto: false,
        }
    }

    #[test]
    fn pareto_front_keeps_runs_no_other_run_beats_in_both() {
        let mut rows = vec![
            row(1.0, 0.05),
            row(2.0, 0.06), // slower and worse than the first: off
            row(3.0, 0.01),
            row(0.5, 0.2),
            row(3.0, 0.02), // as slow as a better run: off
            SweepRow {
                is_reference: true,
                ..row(10.0, 0.0)
            },
        ];
        mark_pareto(&mut rows);
        let front: Vec<bool> = rows.iter().map(|r| r.pareto).collect();
        assert_eq!(front, [true, false, true, true, false, false]);
    }

    #[test]
    fn relative_errors_skip_missing_values() {
        let e = mean_relative(&[1.1, f64::NAN, 2.0], &[1.0, 5.0, 2.0]);
        assert!((e - 0.05).abs() < 1e-12, "{e}");
        assert!(mean_relative(&[f64::NAN], &[1.0]).is_nan());
    }
}
