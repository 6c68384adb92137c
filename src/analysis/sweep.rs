//! The speed–accuracy sweep (DESIGN §9): one scene run at a grid of resolutions around the
//! default, each timed and compared with a converged reference run.
//!
//! A resolution is given as multipliers of the default one ([`resolution::resolve`]): of the
//! disk thickness h, of the marker spacing and of the draw increment. Each point of the full
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
//! # The reference's own error
//! REBOP has no closed form to compare against, so the reference is a fine run, and the
//! errors are distances to it. How far the reference itself is from the converged limit is
//! estimated, not assumed: a check run at twice the reference's h and spacing (same
//! increment, every marker every update) is compared with it, and, if the error falls as
//! the spacing to the power p, the reference's own error is the check's divided by
//! 2^p − 1 (Richardson). p is [`REFERENCE_ORDER`], the order of a sampling error. Where the
//! error is noise rather than bias the estimate is high (two independent noises add in
//! quadrature: the check's distance would then be √(2^(2p) + 1) times the reference's own
//! error, not 2^p − 1), so it is an upper bound. The reference row of the table carries these
//! estimates in its error columns; the check run is a row of its own (`is_reference_check`).
//!
//! Every run is made with `flow.enforce_stability = false`: the coarse and fine corners of the
//! grid are studies of the method, never predictions, and may fall outside where it holds.

use std::collections::HashMap;
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

/// The resolution `mult` times `default`; `max_marker_move` follows h and the spacing as
/// the default rule does (`resolution::max_move_rule`), in proportion to the default's.
fn times(default: &ResolvedResolution, mult: [f64; 3]) -> ResolvedResolution {
    let (h, s) = (
        default.layer_thickness * mult[0],
        default.marker_spacing * mult[1],
    );
    let rule = |s: f64, h: f64| crate::engine::resolution::max_move_rule(s, h);
    ResolvedResolution {
        layer_thickness: h,
        marker_spacing: s,
        draw_increment: default.draw_increment * mult[2],
        max_marker_move: default.max_marker_move * rule(s, h)
            / rule(default.marker_spacing, default.layer_thickness),
    }
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
    let t = &out.drawn;
    for i in 0..t.drawpoint.len() {
        let d = t.drawpoint[i] as usize;
        if d < n_dp {
            heights[d].push(t.origin_z[i] - scene.drawpoints.z[d]);
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

/// Order p of the error in the resolution, for the reference's own error (module docs): a
/// drawpoint-period's grade is the mean of N ∝ s⁻³ markers, so its sampling error goes as
/// s^(3/2).
pub const REFERENCE_ORDER: f64 = 1.5;

/// Relative RMSE of the first grade over the drawpoint-periods both runs drew from.
pub fn grade_rmse(out: &RunOutput, reference: &RunOutput) -> f64 {
    grade_rmse_from(out, reference, i64::MIN)
}

/// [`grade_rmse`] over the periods from `first` on.
fn grade_rmse_from(out: &RunOutput, reference: &RunOutput, first: i64) -> f64 {
    let (Some(g), Some(gr)) = (
        out.extraction.grades.first(),
        reference.extraction.grades.first(),
    ) else {
        return f64::NAN;
    };
    let key = |e: &crate::engine::result::Extraction, i: usize| (e.drawpoint[i], e.period[i]);
    let rows: HashMap<(u32, i64), usize> = (0..out.extraction.period.len())
        .map(|i| (key(&out.extraction, i), i))
        .collect();
    let (mut sq, mut sum, mut n) = (0.0, 0.0, 0usize);
    for (j, &grj) in gr.iter().enumerate() {
        if reference.extraction.period[j] < first {
            continue;
        }
        let Some(&i) = rows.get(&key(&reference.extraction, j)) else {
            continue;
        };
        if g[i].is_finite() && grj.is_finite() {
            sq += (g[i] - grj).powi(2);
            sum += grj;
            n += 1;
        }
    }
    if n == 0 || sum == 0.0 {
        return f64::NAN;
    }
    (sq / n as f64).sqrt() / (sum / n as f64).abs()
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
    let mut res: Vec<ResolvedResolution> = grid.iter().map(|&m| times(&default, m)).collect();
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
    let n_dp = scene.drawpoints.len();
    // The check of the reference's own error: twice its h and spacing, its increment, every
    // marker every update.
    let check_mult = [
        2.0 * cfg.reference[0],
        2.0 * cfg.reference[1],
        cfg.reference[2],
    ];
    let check_res = ResolvedResolution {
        max_marker_move: 0.0,
        ..times(&default, check_mult)
    };
    let total = grid.len() + 1;
    let (reference, ref_wall) = run_at(scene, base, &res[0], cfg.reference, cfg.repeats)?;
    // The second half of the schedule's periods.
    let ids = &scene.periods.id;
    let late = ids.get(ids.len() / 2).copied().unwrap_or(i64::MAX);
    let (ref_de, ref_w, ref_h) = (
        dilution_entries(&reference, n_dp),
        imz_widths(&reference, n_dp),
        iez_heights(&reference, scene),
    );
    let errors = |out: &RunOutput| Errors {
        grade: grade_rmse(out, &reference),
        grade_late: grade_rmse_from(out, &reference, late),
        de: mean_relative(&dilution_entries(out, n_dp), &ref_de),
        w: mean_relative(&imz_widths(out, n_dp), &ref_w),
        h: mean_relative(&iez_heights(out, scene), &ref_h),
    };
    let (check, check_wall) = run_at(scene, base, &check_res, check_mult, cfg.repeats)?;
    let check_errors = errors(&check);
    // Richardson: the error of the reference, if it falls as spacing^p.
    let own = check_errors.scaled(1.0 / (2f64.powf(REFERENCE_ORDER) - 1.0));
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
    /// Every error times `k`.
    fn scaled(&self, k: f64) -> Errors {
        Errors {
            grade: k * self.grade,
            grade_late: k * self.grade_late,
            de: k * self.de,
            w: k * self.w,
            h: k * self.h,
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
