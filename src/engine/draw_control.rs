//! Draw control (`[draw_control]`, `model::scenario::DrawControl`): each period's tonnes
//! decided from the state of the draw, as a mine's draw control decides them, instead of
//! read from a fixed schedule.
//!
//! At the start of a period the production target (`target_rate` × the period's days, or
//! the period's row of the target table, `draw_control.target_table`) is
//! shared among the **open** drawpoints: a drawpoint opens once the ground above its brow
//! has caved (the block model's cave period, as a scheduled drawpoint is drawn) and, where
//! the drawpoints table gives one, its `open_period` has come (a drawbell opened before
//! the cave reaches it would draw nothing), and stays open until a closure rule closes it.
//! A drawpoint whose IMZ holds an air gap under ground that has not caved
//! (`imz::Imz::under_air_gap`) is **held**: a mine does not draw under an air gap (an
//! air blast), and the drawpoint would give nothing but the void. Once the ground above
//! caves it is open again, and its next draw closes the gap.
//!
//! A drawpoint that runs out of material in a period (`exhausted`: its lowest disks'
//! fill below `fill::EXHAUSTED_FILL` with no air gap) may take no more, per day, than it
//! delivered then, until a period's end finds its lowest disks full enough to feed it
//! again: what it cannot give goes to the others, as a mine's draw control moves a short
//! drawpoint's tonnes. One that delivered nothing is drawn out, and closes (`exhausted`).
//!
//! Each open drawpoint may take at most its rate limit: `max_rate` × days × the draw-rate
//! curve's share at its height of draw over its column (the height from its brow to the
//! top of the block model). First every open drawpoint takes its minimum (`min_rate` ×
//! days, within its limit, the target shared in proportion when it is smaller than the
//! minima); the rest is shared in proportion to what each can still take (equal shares
//! when no rate limit is set), first among the drawpoints that are not ahead of their
//! neighbours, then among those that are. A drawpoint is ahead when its height of draw
//! exceeds the mean of its open neighbours' (drawpoints within `neighbour_radius` in plan)
//! by more than `uniform_tolerance`: it draws only what the others cannot take, so the
//! heights of draw stay within the tolerance and neighbouring IMZs keep interacting
//! (summary §5, interactive draw). What no open drawpoint can take is the period's
//! production shortfall.
//!
//! At the end of the period each drawpoint that drew is reviewed against the closure
//! rules, with what it drew in the period as known then (the markers drawn up to the
//! period's end, `crediting::Stream::window`): a shut-off grade over consecutive periods,
//! a dilution limit, a height-of-draw limit, or, with `[economics]`, a negative period
//! value (its cumulative value has peaked: the best height of draw). A drawpoint closes in
//! the period its rule is first met and draws nothing after it.
//!
//! The realised draw is the engine's schedule from then on: crediting, the streams and the
//! extraction rows read it as they read a fixed schedule, so a controlled run's realised
//! schedule (`schedule_realised`), run as a fixed schedule, draws the same.

use rayon::prelude::*;

use super::crediting::{self, Tally};
use super::fill;
use super::height_of_draw::hod;
use super::Engine;
use crate::model::{Economics, Scene};

/// Why a drawpoint closed.
pub const CLOSURE_REASONS: [&str; 5] = [
    "shutoff_grade",
    "dilution",
    "hod_limit",
    "best_hod",
    "exhausted",
];

/// What the control derives from the scene once: each drawpoint's column height and
/// its neighbours.
#[derive(Debug, Clone, Default)]
pub struct Layout {
    /// Height from each drawpoint's brow to the top of the block model, m.
    pub column: Vec<f64>,
    /// Per drawpoint, the drawpoints within the neighbour radius in plan.
    pub neighbours: Vec<Vec<usize>>,
    /// The neighbour radius used, m.
    pub radius: f64,
}

impl Layout {
    /// The layout of `scene`'s drawpoints, neighbours within `radius` (None: 1.5 times
    /// the median distance to the nearest drawpoint).
    pub fn new(scene: &Scene, radius: Option<f64>) -> Layout {
        let dp = &scene.drawpoints;
        let n = dp.len();
        let dist = |a: usize, b: usize| (dp.x[a] - dp.x[b]).hypot(dp.y[a] - dp.y[b]);
        let radius = radius.unwrap_or_else(|| {
            let s = dp.median_spacing();
            if s.is_nan() {
                0.0
            } else {
                1.5 * s
            }
        });
        let top = scene.blocks.z_max();
        Layout {
            column: (0..n).map(|d| (top - dp.z[d]).max(0.0)).collect(),
            neighbours: (0..n)
                .map(|a| (0..n).filter(|&b| b != a && dist(a, b) <= radius).collect())
                .collect(),
            radius,
        }
    }
}

/// Shares `total` among drawpoints with room `room` (their limits less what they have):
/// in proportion to the room, or in equal shares where any room is unlimited; never more
/// than a drawpoint's room. Returns the shares.
fn share(total: f64, room: &[f64]) -> Vec<f64> {
    if room.is_empty() || !(total > 0.0) {
        return vec![0.0; room.len()];
    }
    if room.iter().any(|r| r.is_infinite()) {
        let each = total / room.len() as f64;
        return vec![each; room.len()];
    }
    let sum: f64 = room.iter().sum();
    if sum <= total {
        return room.to_vec();
    }
    let k = total / sum;
    room.iter().map(|r| r * k).collect()
}

/// One period's plan: the tonnes of each drawpoint, given which are open, each one's
/// limit and minimum (t) and whether it is ahead of its neighbours; and the target's
/// shortfall.
pub fn plan(
    target: f64,
    open: &[bool],
    limit: &[f64],
    min: &[f64],
    ahead: &[bool],
) -> (Vec<f64>, f64) {
    let n = open.len();
    let mut row = vec![0.0; n];
    let ids: Vec<usize> = (0..n).filter(|&d| open[d]).collect();
    // The minima, within each limit, shared in proportion when the target is smaller.
    let mins: Vec<f64> = ids.iter().map(|&d| min[d].min(limit[d])).collect();
    for (&d, x) in ids.iter().zip(share(target, &mins)) {
        row[d] = x;
    }
    let mut left = target - row.iter().sum::<f64>();
    for tier in [false, true] {
        let members: Vec<usize> = ids.iter().copied().filter(|&d| ahead[d] == tier).collect();
        let room: Vec<f64> = members.iter().map(|&d| limit[d] - row[d]).collect();
        for (&d, x) in members.iter().zip(share(left, &room)) {
            row[d] += x;
        }
        left = target - row.iter().sum::<f64>();
    }
    (row, left.max(0.0))
}

impl Engine<'_> {
    /// The control's tonnes for period index `p` (strategy `target`), set as the
    /// engine's schedule row; recorded with the period's production.
    pub(super) fn control_plan(&mut self, p: usize) {
        let (Some(layout), Some(rec)) = (self.control.as_ref(), self.out.control.as_mut()) else {
            return;
        };
        let dc = &self.scenario.draw_control;
        let scene = self.scene;
        let (bm, period) = (&scene.blocks, scene.periods.id[p]);
        let days = scene.periods.days[p];
        let n = scene.drawpoints.len();
        let hod: Vec<f64> = (0..n)
            .map(|d| hod(self.cum[d], self.hod_density_area[d]))
            .collect();
        let dp = &scene.drawpoints;
        let held: Vec<bool> = (0..n)
            .map(|d| self.imzs[d].under_air_gap(bm, period))
            .collect();
        let open: Vec<bool> = (0..n)
            .map(|d| {
                rec.closed[d].is_none()
                    && dp.opens_at(d).is_none_or(|o| period >= o)
                    && bm.flowable(self.drawpoint_block[d], period)
                    && !held[d]
            })
            .collect();
        let limit: Vec<f64> = (0..n)
            .map(|d| {
                let rate = match dc.max_rate {
                    Some(m) => {
                        let share = hod[d] / layout.column[d].max(1e-12);
                        m * days * dc.rate_share(share)
                    }
                    None => f64::INFINITY,
                };
                rate.min(rec.running_out[d].map_or(f64::INFINITY, |r| r * days))
            })
            .collect();
        let min = vec![dc.min_rate * days; n];
        let ahead: Vec<bool> = (0..n)
            .map(|d| {
                let Some(tol) = dc.uniform_tolerance else {
                    return false;
                };
                let near: Vec<f64> = layout.neighbours[d]
                    .iter()
                    .filter(|&&e| open[e])
                    .map(|&e| hod[e])
                    .collect();
                !near.is_empty() && hod[d] - near.iter().sum::<f64>() / near.len() as f64 > tol
            })
            .collect();
        let target = match &scene.target {
            Some(t) => t[p],
            None => dc.target_rate.unwrap_or(0.0) * days,
        };
        let (row, shortfall) = plan(target, &open, &limit, &min, &ahead);
        rec.realised.extend_from_slice(&row);
        let pr = &mut rec.production;
        pr.period.push(period);
        pr.target_tonnes.push(target);
        pr.planned_tonnes.push(row.iter().sum());
        pr.tonnes.push(0.0);
        pr.shortfall_tonnes.push(shortfall);
        pr.open.push(open.iter().filter(|&&o| o).count() as u32);
        pr.held.push(held.iter().filter(|&&h| h).count() as u32);
        pr.closed
            .push(rec.closed.iter().filter(|c| c.is_some()).count() as u32);
        let s = self.schedule.to_mut();
        s.tonnes[p * n..(p + 1) * n].copy_from_slice(&row);
    }

    /// Reviews every drawpoint that drew in period index `p` against the closure rules
    /// (after the period's extraction rows are written), and records the period's credited
    /// tonnes.
    pub(super) fn control_review(&mut self, p: usize, first_row: usize) {
        let Some(mut rec) = self.out.control.take() else {
            return;
        };
        let dc = &self.scenario.draw_control;
        let scene = self.scene;
        let bm = &scene.blocks;
        let ex = &self.out.extraction;
        let credited: f64 = ex.tonnes[first_row..].iter().sum();
        if let Some(t) = rec.production.tonnes.last_mut() {
            *t = credited;
        }
        // A drawpoint running out is held to the rate it delivered, until its lowest disks
        // can feed it again (`fill`).
        let days = scene.periods.days[p];
        let mut drawn_out = Vec::new();
        for k in first_row..ex.drawpoint.len() {
            let d = ex.drawpoint[k] as usize;
            if ex.short_reason[k] == "exhausted" {
                rec.running_out[d] = Some(ex.tonnes[k] / days);
                if !(ex.tonnes[k] > 0.0) {
                    drawn_out.push(d);
                }
            } else if ex.fill[k] >= fill::EXHAUSTED_FILL {
                rec.running_out[d] = None;
            }
        }
        let shut_col = dc
            .shutoff_column
            .as_ref()
            .and_then(|c| bm.grade_names.iter().position(|g| g == c));
        let row = self.schedule.period(p);
        let graded = shut_col.is_some() || dc.max_dilation.is_some() || dc.best_hod;
        let height = |d: usize| hod(self.cum[d], self.hod_density_area[d]);
        let reviewed = |d: usize| row[d] > 0.0 && rec.closed[d].is_none();
        // What each reviewed drawpoint drew in the period, as known at its end: its grades
        // and waste share (read only where a rule or a closure needs them; the drawpoints
        // in parallel).
        let drawn: Vec<Option<(Vec<f64>, f64)>> = (0..row.len())
            .into_par_iter()
            .map(|d| {
                let high = dc.max_hod.is_some_and(|m| height(d) >= m);
                if !reviewed(d) || !(graded || high) {
                    return None;
                }
                let stream = &self.streams[d];
                let (lo, hi) = (self.sched_cum[d], self.sched_cum[d] + row[d]);
                let mut t = Tally::new(bm.grades.len(), bm.lithology_names.len());
                for r in stream.window(lo, hi, crediting::GRADE_MARKERS) {
                    self.contribute(&self.drawn.m, stream.row[r] as usize, &mut t);
                }
                (t.mass > 0.0).then(|| {
                    let grade: Vec<f64> = t.grade.iter().map(|g| g / t.mass).collect();
                    (grade, t.waste / t.mass)
                })
            })
            .collect();
        let mut closing = Vec::new();
        for (d, read) in drawn.into_iter().enumerate() {
            if !reviewed(d) {
                continue;
            }
            let (drew, hod) = (row[d], height(d));
            let high = dc.max_hod.is_some_and(|m| hod >= m);
            // No marker drawn: nothing to grade (the height-of-draw limit still closes).
            let (grade, dilution) = match read {
                Some(g) => g,
                None if high => (vec![f64::NAN; bm.grades.len()], f64::NAN),
                None => continue,
            };
            let low = shut_col.is_some_and(|g| grade[g] < dc.shutoff_grade.unwrap_or(0.0));
            rec.low[d] = if low { rec.low[d] + 1 } else { 0 };
            let value = |e: &Economics| e.value(&bm.grade_names, &grade, drew);
            let reason = if rec.low[d] >= dc.shutoff_periods.unwrap_or(1) && shut_col.is_some() {
                Some(0)
            } else if dc.max_dilation.is_some_and(|m| dilution > m) {
                Some(1)
            } else if high {
                Some(2)
            } else if dc.best_hod
                && self
                    .scenario
                    .economics
                    .as_ref()
                    .is_some_and(|e| value(e) < 0.0)
            {
                Some(3)
            } else {
                None
            };
            if let Some(k) = reason {
                let g = shut_col.unwrap_or(0);
                closing.push((d, k, hod, grade.get(g).copied().unwrap_or(f64::NAN)));
            }
        }
        // A drawpoint that ran out and delivered nothing is drawn out: closed.
        for d in drawn_out {
            if rec.closed[d].is_none() && closing.iter().all(|c| c.0 != d) {
                closing.push((d, 4, height(d), f64::NAN));
            }
        }
        let period = scene.periods.id[p];
        for (d, k, hod, grade) in closing {
            rec.closed[d] = Some(p);
            let c = &mut rec.closures;
            c.drawpoint.push(d as u32);
            c.period.push(period);
            c.reason.push(CLOSURE_REASONS[k].to_string());
            c.cum_tonnes.push(self.cum[d]);
            c.hod.push(hod);
            c.grade.push(grade);
        }
        self.out.control = Some(rec);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The target is shared within the limits, the drawpoints behind their neighbours
    /// first, and what nobody can take is the shortfall.
    #[test]
    fn a_period_shares_its_target_within_the_limits_behind_first() {
        let open = [true, true, true, false];
        let limit = [100.0, 50.0, 100.0, 100.0];
        let min = [0.0; 4];
        let level = [false; 4];
        let (row, short) = plan(120.0, &open, &limit, &min, &level);
        // In proportion to the room: 120 × (100, 50, 100) / 250.
        assert_eq!(row, vec![48.0, 24.0, 48.0, 0.0]);
        assert_eq!(short, 0.0);
        let (row, short) = plan(400.0, &open, &limit, &min, &level);
        assert_eq!(row, vec![100.0, 50.0, 100.0, 0.0]);
        assert_eq!(short, 150.0);
        // Drawpoint 0 ahead: the others take what they can first.
        let ahead = [true, false, false, false];
        let (row, short) = plan(120.0, &open, &limit, &min, &ahead);
        assert_eq!(row, vec![0.0, 40.0, 80.0, 0.0]);
        assert_eq!(short, 0.0);
        let (row, _) = plan(200.0, &open, &limit, &min, &ahead);
        assert_eq!(row[..3], [50.0, 50.0, 100.0]);
        // Minima first, within each limit; no limit: equal shares.
        let (row, _) = plan(90.0, &open, &[f64::INFINITY; 4], &[20.0; 4], &level);
        assert_eq!(row, vec![30.0, 30.0, 30.0, 0.0]);
        let (row, _) = plan(30.0, &open, &limit, &[20.0; 4], &level);
        assert_eq!(row, vec![10.0, 10.0, 10.0, 0.0]);
    }
}
