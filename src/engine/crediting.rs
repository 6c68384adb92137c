//! Crediting a drawpoint's draw: the tonnes of each period, and the material they stand for.
//!
//! Markers are discrete. A default marker on mine-scale blocks weighs about as much as one
//! or two drawpoint-days, so crediting each period with the markers it happened to draw
//! leaves many days with no marker (no grade, a shortfall carried to the next day) and the
//! next with two. The summary is silent on crediting; MassFlow scales each period's marker
//! tonnes by a bounded factor. We credit the schedule, and read what was drawn from the
//! drawpoint's stream.
//!
//! # The stream
//! A drawpoint's drawn markers, in the order drawn, each at its draw time τ: the
//! drawpoint's cumulative scheduled tonnes at the middle of the step that drew it. Period p
//! stands for the scheduled interval [S_{p−1}, S_p] of that stream.
//!
//! # Tonnes
//! A period is credited by the state of its drawpoint's lowest disks (`engine::fill`).
//! While they can feed its schedule (their fill is at least `fill::EXHAUSTED_FILL`, or its
//! IMZ is too young to judge) it is credited its scheduled tonnes, whatever its markers
//! did: a period's markers are lumpy (a default marker on mine-scale blocks weighs half a
//! drawpoint-day), and a column that holds the material delivers it. A drawpoint whose
//! markers nevertheless run behind its credits over those periods by more than their
//! discreteness, [`FLOWING_SIGMAS`] √N markers and a draw step ([`lagging`]), is named in
//! the run's warnings with the ratio, and is not made short.
//!
//! Where the fill is lower, its column is running out (drawn out, with the ground around
//! it standing where rilling is off, or drained into the air gap under uncaved ground),
//! and the markers decide. It is credited its schedule while it is flowing: over the last
//! `max(TRAIL_MARKERS` markers' mass, the period's schedule) of scheduled tonnes, its
//! markers weigh what was scheduled to within their discreteness ([`FLOWING_SIGMAS`]), or
//! the draw has not yet reached that much. A trailing window of N markers sees a deficit
//! δ only once δ > 3/√N, so a drawpoint can draw a steady share short of its schedule and
//! pass every window (on the mine scene at 1.65 m markers, drawpoints under uncaved ground
//! drew 0.80 of their schedule in markers for over a year); so the credits are also held
//! to a budget over the drawpoint's whole draw: they run ahead of its markers' mass by at
//! most their discreteness, [`FLOWING_SIGMAS`] √N markers over the N its schedule stands
//! for so far, and a draw step. A period that is not flowing is credited the marker tonnes
//! it drew, and one that would overrun the budget up to it: `short`, `exhausted` or
//! `blocked` (`fill::short_reason`). A drawpoint whose ground has not caved draws nothing
//! and is `short`, `uncaved`. What a period could not deliver is reported as
//! `shortfall_tonnes` (the running total) and is not credited later. Over a run the
//! credited tonnes are the schedule less those shortfalls, exactly.
//!
//! On the mine scene (`caveflow demo --scale mine --out mine`, `caveflow run
//! mine/scenario.toml`) crediting by the state, against crediting every period by its
//! markers as above, credits 8.0 kt more of 40.6 Mt scheduled (the seeds 42, 43 and 44 of
//! the latter differ by up to 10.0 kt), moves 24 drawpoints' tonnes by 126 t rms (the
//! seeds: 130 drawpoints, 623–682 t rms) and their metal by 0.16% rms (the seeds: 0.95–
//! 1.04%), and has 8155 short days at 113 drawpoints instead of 8225 at 124 (the seeds:
//! 8150–8339 at 116–124); the grades of the days are the same. No drawpoint lags at the
//! default resolution. At 1.65 m markers (`--set resolution.marker_spacing=1.65`) it
//! credits 10.4 kt more, 867 days that the markers alone would leave short are credited
//! in full, and 19 drawpoints lag, at 0.94–0.97 of their credits (51 kt in all). On the
//! demo (`caveflow run data/scenario.toml`) it credits 4.4 kt more of 2.33 Mt (seeds 42
//! and 43 of the latter: 1.8 kt apart), and 35 drawpoint-months are short instead of 40:
//! three drawpoints beside its drawn-out southeast corner, whose columns drain in their
//! last months to fills of 0.61–0.76, are credited in full while their markers weigh
//! 0.96–0.97 of their schedule, within their discreteness over the whole draw and so not
//! named (`tests/it/balance.rs`, the demo's whole draw).
//!
//! # What was drawn
//! A period's grades, dilution, origin elevation, fragment sizes, fines and lithology shares
//! are the mass-weighted means over the markers of its interval, or, where the interval
//! holds fewer than [`GRADE_MARKERS`], over the [`GRADE_MARKERS`] markers nearest its
//! middle. So a period always has a grade when its drawpoint drew anything, a marker counts
//! in every short period around the one that drew it, and monthly periods (hundreds of
//! markers each) read exactly their own markers. `marker_tonnes` and `markers` stay the
//! period's own (the discreteness the crediting smooths), and `correction` is credited over
//! marker tonnes, a diagnostic.

use std::ops::Range;

use super::fragmentation::{self, SizeDist};
use super::result::Extraction;

/// Markers whose mass sets the trailing window over which a drawpoint is judged flowing.
pub const TRAIL_MARKERS: f64 = 60.0;

/// How far below its schedule, in standard deviations of the markers' discreteness, a
/// drawpoint's markers may weigh over the trailing window and it still count as flowing.
/// A window of N markers' worth of schedule draws a count of markers that scatters by
/// about √N (the demo's monthly periods of ~250 markers scatter by 0.06 of their schedule,
/// 1/√250 = 0.063), so a flowing drawpoint falls below 1 − 3/√N in about one window in a
/// thousand: 0.61 of the schedule at the shortest window (60 markers), 0.81 over a monthly
/// period of the demo. A drawpoint below it draws air: its column is drawn out (and, with
/// rilling off, the ground around it stands and does not feed it), or it is held under
/// uncaved ground. A fixed half credited the demo's southeast drawpoints whose columns were
/// drawn out their schedule while their markers weighed 0.61–0.74 of it.
pub const FLOWING_SIGMAS: f64 = 3.0;

/// Fewest markers a period's grades are read from. On the mine scene's daily schedule (the
/// default resolution's 3.4 m markers weigh about half a drawpoint-day) the relative Mo
/// grade RMSE per drawpoint-day over the first 400 days, against a run at 1.4 m markers,
/// is 0.89% at 6, 0.76% at 10 and 0.69% at 16; per 91 days it is 0.33%, 0.34% and 0.37%:
/// wider windows blur the grade's changes. 10 keeps the quarterly error of the
/// period-by-period markers (0.34%).
pub const GRADE_MARKERS: usize = 10;

/// One drawpoint's stream (see the module docs): draw time τ, row in the drawn markers and
/// running mass, in the order drawn (τ never decreases).
#[derive(Debug, Clone, Default)]
pub struct Stream {
    /// Draw time τ: cumulative scheduled tonnes, t.
    pub tau: Vec<f64>,
    /// Row in `DrawnMarkers`.
    pub row: Vec<u32>,
    /// Running sums of the markers' mass, t (the mass over any stretch is two look-ups).
    cum: Vec<f64>,
}

impl Stream {
    /// Appends a marker drawn at `tau`.
    pub fn push(&mut self, tau: f64, mass: f64, row: usize) {
        debug_assert!(self.tau.last().is_none_or(|&t| t <= tau));
        self.tau.push(tau);
        self.row.push(row as u32);
        self.cum.push(self.total() + mass);
    }

    /// Mass drawn so far, t.
    fn total(&self) -> f64 {
        self.cum.last().copied().unwrap_or(0.0)
    }

    /// Mean marker mass, if any was drawn.
    pub fn mean_mass(&self) -> Option<f64> {
        (!self.tau.is_empty()).then(|| self.total() / self.tau.len() as f64)
    }

    /// Marker mass drawn at τ in (from, to].
    pub fn mass_in(&self, from: f64, to: f64) -> f64 {
        let upto = |n: usize| if n == 0 { 0.0 } else { self.cum[n - 1] };
        let a = self.tau.partition_point(|&t| t <= from);
        let b = self.tau.partition_point(|&t| t <= to);
        upto(b) - upto(a)
    }

    /// Whether the drawpoint is flowing when its schedule has reached `s_end`: over the
    /// trailing `window` of scheduled tonnes its markers (of mean mass `marker`) weigh at
    /// least 1 − [`FLOWING_SIGMAS`] / √N of them, N = window / marker, less `step`, the
    /// tonnes of one draw step (a step's markers share one τ, so the window's edges cut the
    /// draw by whole steps: at four times the default increment a fixed share made
    /// drawpoints of the sweep's scene short). Before the schedule has reached one window
    /// it is taken as flowing.
    pub fn flowing(&self, s_end: f64, window: f64, marker: f64, step: f64) -> bool {
        let share = (1.0 - FLOWING_SIGMAS / (window / marker).sqrt()).max(0.0);
        s_end < window || self.mass_in(s_end - window, s_end) >= share * window - step
    }

    /// The tonnes a period of `scheduled` tonnes that drew `mass` in markers is credited,
    /// the drawpoint having been credited `credited_before` over its earlier periods, its
    /// schedule reaching `s_end` with this period (see the module docs, "Tonnes"): its
    /// schedule while it is [`flowing`](Self::flowing) over the trailing `window` and its
    /// credits stay within the budget, at most what brings the credits to the budget when
    /// not, and what it drew when it is not flowing.
    ///
    /// The budget: the drawpoint's credits may run ahead of its markers' mass by their
    /// discreteness over its whole draw, [`FLOWING_SIGMAS`] √N markers (N the markers its
    /// schedule stands for so far, at least [`TRAIL_MARKERS`]) plus one draw `step`; the
    /// module docs say why the trailing window alone is not enough.
    pub fn credit(
        &self,
        s_end: f64,
        scheduled: f64,
        mass: f64,
        credited_before: f64,
        (window, marker, step): (f64, f64, f64),
    ) -> f64 {
        let drew = mass.min(scheduled);
        if !self.flowing(s_end, window, marker, step) {
            return drew;
        }
        let n = (s_end / marker).max(TRAIL_MARKERS);
        let budget = FLOWING_SIGMAS * n.sqrt() * marker + step;
        let ahead = credited_before - (self.total() - mass);
        (budget - ahead + mass).clamp(drew, scheduled)
    }

    /// The markers that stand for the scheduled interval [lo, hi]: those drawn in it, or,
    /// where fewer than `k`, the `k` nearest its middle (all of them if there are fewer).
    pub fn window(&self, lo: f64, hi: f64, k: usize) -> Range<usize> {
        let n = self.tau.len();
        let (mut a, mut b) = (
            self.tau.partition_point(|&t| t < lo),
            self.tau.partition_point(|&t| t <= hi),
        );
        if n <= k {
            return 0..n;
        }
        let mid = 0.5 * (lo + hi);
        while b - a < k {
            let left = (a > 0).then(|| mid - self.tau[a - 1]);
            let right = (b < n).then(|| self.tau[b] - mid);
            match (left, right) {
                (Some(l), Some(r)) if l <= r => a -= 1,
                (Some(_), None) => a -= 1,
                _ => b += 1,
            }
        }
        a..b
    }
}

/// What a drawpoint's markers weighed against its credits over the periods in which its
/// lowest disks could feed its schedule ([`lagging`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lag {
    /// The drawpoint.
    pub drawpoint: usize,
    /// Tonnes credited in those periods.
    pub credited: f64,
    /// Marker tonnes drawn in those periods.
    pub markers: f64,
    /// Markers drawn in those periods.
    pub count: i64,
}

impl Lag {
    /// The markers' mass over the credits.
    pub fn ratio(&self) -> f64 {
        self.markers / self.credited
    }
}

/// The drawpoints whose markers ran behind their credits by more than their discreteness
/// while their lowest disks could feed their schedule: over the extraction rows of `ex`
/// credited by the state (scheduled, caved, and a fill not below `exhausted_fill`, or not
/// yet judged), the credits exceed the markers' mass by more than [`FLOWING_SIGMAS`] √N
/// markers and a draw `step`, N the markers the credits stand for. Such a drawpoint is
/// credited its schedule regardless (the module docs, "Tonnes"); this says by how much
/// its markers did not follow, for the run's warnings.
pub fn lagging(ex: &Extraction, drawpoints: usize, exhausted_fill: f64, step: f64) -> Vec<Lag> {
    let mut lags: Vec<Lag> = (0..drawpoints)
        .map(|d| Lag {
            drawpoint: d,
            credited: 0.0,
            markers: 0.0,
            count: 0,
        })
        .collect();
    for k in 0..ex.drawpoint.len() {
        let fed = ex.scheduled_tonnes[k] > 0.0
            && ex.short_reason[k] != "uncaved"
            && !(ex.fill[k] < exhausted_fill);
        if fed {
            let l = &mut lags[ex.drawpoint[k] as usize];
            l.credited += ex.tonnes[k];
            l.markers += ex.marker_tonnes[k];
            l.count += ex.markers[k];
        }
    }
    lags.retain(|l| {
        if l.count == 0 {
            return l.credited > step;
        }
        let marker = l.markers / l.count as f64;
        let n = l.credited / marker;
        l.credited - l.markers > FLOWING_SIGMAS * n.sqrt() * marker + step
    });
    lags
}

/// Mass-weighted sums over a set of drawn markers (a period's, or a window of a stream).
#[derive(Debug, Clone, Default)]
pub struct Tally {
    /// Σ mass, t.
    pub mass: f64,
    /// Markers.
    pub count: i64,
    /// Σ mass × grade, per grade.
    pub grade: Vec<f64>,
    /// Σ mass per lithology.
    pub lith: Vec<f64>,
    /// Σ mass × origin elevation.
    pub origin_z: f64,
    /// Σ mass × fragment size.
    pub frag: f64,
    /// Σ mass × fines share.
    pub fines: f64,
    /// Waste mass.
    pub waste: f64,
    /// Rilled mass.
    pub rilled: f64,
    /// Σ rilled mass × distance rilled.
    pub rill_dist: f64,
    /// Size distribution and mass of each marker.
    pub sizes: Vec<(SizeDist, f64)>,
    /// Σ fines mass × origin elevation.
    pub fines_z: f64,
    /// Fines mass that is waste.
    pub fines_waste: f64,
    /// Σ mass × accumulated percolation distance.
    pub percolated: f64,
}

impl Tally {
    /// An empty tally for `grades` grades and `liths` lithologies.
    pub fn new(grades: usize, liths: usize) -> Tally {
        Tally {
            grade: vec![0.0; grades],
            lith: vec![0.0; liths],
            ..Default::default()
        }
    }

    /// The extraction columns that describe what the markers were (NaN where none).
    pub fn derived(&mut self) -> Derived {
        let per = |x: f64| {
            if self.mass > 0.0 {
                x / self.mass
            } else {
                f64::NAN
            }
        };
        let per_fines = |x: f64| {
            if self.fines > 0.0 {
                x / self.fines
            } else {
                f64::NAN
            }
        };
        Derived {
            dilution: per(self.waste),
            origin_z: per(self.origin_z),
            frag_size: per(self.frag),
            fines_share: per(self.fines),
            frag_p: fragmentation::p20_p50_p80(&mut self.sizes),
            fines_origin_z: per_fines(self.fines_z),
            fines_waste_share: per_fines(self.fines_waste),
            percolation: per(self.percolated),
            rilled_share: per(self.rilled),
            rill_distance: if self.rilled > 0.0 {
                self.rill_dist / self.rilled
            } else {
                f64::NAN
            },
            grades: self.grade.iter().map(|&v| per(v)).collect(),
            lith: self.lith.iter().map(|&v| per(v)).collect(),
        }
    }
}

/// The columns of an extraction row that say what was drawn ([`Tally::derived`]).
#[derive(Debug, Clone)]
pub struct Derived {
    dilution: f64,
    origin_z: f64,
    frag_size: f64,
    fines_share: f64,
    frag_p: [f64; 3],
    fines_origin_z: f64,
    fines_waste_share: f64,
    percolation: f64,
    rilled_share: f64,
    rill_distance: f64,
    grades: Vec<f64>,
    lith: Vec<f64>,
}

impl Derived {
    /// Appends these to a new row of `ex`.
    pub fn push(self, ex: &mut Extraction) {
        ex.dilution.push(self.dilution);
        ex.origin_z.push(self.origin_z);
        ex.frag_size.push(self.frag_size);
        ex.fines_share.push(self.fines_share);
        ex.frag_p20.push(self.frag_p[0]);
        ex.frag_p50.push(self.frag_p[1]);
        ex.frag_p80.push(self.frag_p[2]);
        ex.fines_origin_z.push(self.fines_origin_z);
        ex.fines_waste_share.push(self.fines_waste_share);
        ex.percolation.push(self.percolation);
        ex.rilled_share.push(self.rilled_share);
        ex.rill_distance.push(self.rill_distance);
        for (g, v) in self.grades.into_iter().enumerate() {
            ex.grades[g].push(v);
        }
        for (l, v) in self.lith.into_iter().enumerate() {
            ex.lithology[l].push(v);
        }
    }

    /// Sets these in row `k` of `ex`.
    pub fn set(self, ex: &mut Extraction, k: usize) {
        ex.dilution[k] = self.dilution;
        ex.origin_z[k] = self.origin_z;
        ex.frag_size[k] = self.frag_size;
        ex.fines_share[k] = self.fines_share;
        [ex.frag_p20[k], ex.frag_p50[k], ex.frag_p80[k]] = self.frag_p;
        ex.fines_origin_z[k] = self.fines_origin_z;
        ex.fines_waste_share[k] = self.fines_waste_share;
        ex.percolation[k] = self.percolation;
        ex.rilled_share[k] = self.rilled_share;
        ex.rill_distance[k] = self.rill_distance;
        for (g, v) in self.grades.into_iter().enumerate() {
            ex.grades[g][k] = v;
        }
        for (l, v) in self.lith.into_iter().enumerate() {
            ex.lithology[l][k] = v;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stream(tau: &[f64]) -> Stream {
        let mut s = Stream::default();
        for (k, &t) in tau.iter().enumerate() {
            s.push(t, 10.0, k);
        }
        s
    }

    #[test]
    fn windows_take_the_interval_or_the_nearest_markers() {
        let s = stream(&[5.0, 15.0, 25.0, 35.0, 45.0, 55.0, 65.0, 75.0]);
        // Enough markers in the interval: exactly those.
        assert_eq!(s.window(10.0, 60.0, 3), 1..6);
        // Too few: widened to the k nearest the middle (30): 25, 35, then 15 (tie → left).
        assert_eq!(s.window(28.0, 32.0, 3), 1..4);
        // An interval with none, at the end of the stream: the last k.
        assert_eq!(s.window(80.0, 90.0, 2), 6..8);
        // Fewer markers than k: all of them.
        assert_eq!(stream(&[1.0, 2.0]).window(0.0, 1.0, 5), 0..2);
        assert_eq!(Stream::default().window(0.0, 1.0, 5), 0..0);
    }

    /// Credits period by period (10 t each, a 5 t step) of a drawpoint whose markers of
    /// 10 t arrive at `rate` of its schedule; returns (credited, marker mass, short periods).
    fn credit_run(rate: f64, periods: usize) -> (f64, f64, usize) {
        let mut s = Stream::default();
        let (mut credited, mut drawn, mut short, mut next) = (0.0, 0.0, 0, 0.0);
        for p in 1..=periods {
            let s_end = 10.0 * p as f64;
            let before = s.total();
            while next + 10.0 <= s_end * rate {
                next += 10.0;
                s.push(next / rate, 10.0, 0);
            }
            let mass = s.total() - before;
            let window = (TRAIL_MARKERS * 10.0).max(10.0);
            let c = s.credit(s_end, 10.0, mass, credited, (window, 10.0, 5.0));
            short += usize::from(c < 10.0);
            (credited, drawn) = (credited + c, drawn + mass);
        }
        (credited, drawn, short)
    }

    #[test]
    fn credits_run_ahead_of_the_markers_by_their_discreteness_only() {
        // Markers at the schedule: every period credited in full.
        let (credited, drawn, short) = credit_run(1.0, 2000);
        assert_eq!((credited, short), (20_000.0, 0));
        assert_eq!(drawn, 20_000.0);
        // Markers at 0.8 of it pass every 60-marker window (1 − 3/√60 = 0.61), but the
        // credits never run further ahead of them than 3 √N markers and a step (N = 2000
        // periods' worth: 134 markers, 1347 t). Once they are that far ahead, a period
        // that draws its marker is credited in full and one that draws none is short: a
        // fifth of the periods.
        let (credited, drawn, short) = credit_run(0.8, 2000);
        let budget = 3.0 * 2000f64.sqrt() * 10.0 + 5.0;
        assert!(credited - drawn <= budget + 1e-9, "{credited} {drawn}");
        assert!(credited - drawn > 0.9 * budget, "{credited} {drawn}");
        assert!((300..=400).contains(&short), "{short}");
    }

    /// Rows of one drawpoint, 10 t credited each, drawing `rate` × 10 t in markers of 1 t
    /// with a fill of `fill`.
    fn rows(
        ex: &mut Extraction,
        d: u32,
        periods: usize,
        rate: f64,
        fill: f64,
        reason: &'static str,
    ) {
        for _ in 0..periods {
            ex.drawpoint.push(d);
            ex.scheduled_tonnes.push(10.0);
            ex.tonnes.push(10.0);
            ex.marker_tonnes.push(10.0 * rate);
            ex.markers.push((10.0 * rate).round() as i64);
            ex.fill.push(fill);
            ex.short_reason.push(reason);
        }
    }

    #[test]
    fn lagging_names_the_drawpoints_whose_markers_fall_behind_while_fed() {
        let mut ex = Extraction::default();
        // 2000 t credited: the discreteness allowed is 3 √2000 markers of 1 t and a step
        // of 1 t, 135 t. At 0.9 of the credits the markers are 200 t behind: named.
        rows(&mut ex, 0, 200, 0.9, 0.95, "");
        // At 0.95, 100 t behind: within the discreteness.
        rows(&mut ex, 1, 200, 0.95, 0.95, "");
        // Behind by as much, but the fill says its column is running out (credited by its
        // markers, not by the state), or the ground has not caved: not counted.
        rows(&mut ex, 2, 200, 0.9, 0.5, "");
        rows(&mut ex, 3, 200, 0.0, f64::NAN, "uncaved");
        // A young IMZ's fill is not judged: fed.
        rows(&mut ex, 4, 200, 0.8, f64::NAN, "");
        let got = lagging(&ex, 5, 0.726, 1.0);
        let named: Vec<usize> = got.iter().map(|l| l.drawpoint).collect();
        assert_eq!(named, vec![0, 4]);
        assert!((got[0].ratio() - 0.9).abs() < 1e-12);
        assert_eq!((got[0].credited, got[0].count), (2000.0, 1800));
    }

    #[test]
    fn flowing_needs_the_trailing_schedule_in_markers_to_within_three_sigmas() {
        // 100 markers of 10 t, one every 10 t of schedule.
        let tau: Vec<f64> = (0..100).map(|k| 10.0 * k as f64 + 5.0).collect();
        let s = stream(&tau);
        assert_eq!(s.mass_in(100.0, 350.0), 250.0);
        assert_eq!(s.mean_mass(), Some(10.0));
        // A window of 1000 t: N = 100 markers, flowing down to 1 − 3/10 = 0.7 of it.
        assert!(s.flowing(1000.0, 1000.0, 10.0, 0.0));
        // Up to 1300 the last 1000 t drew 700 t (τ 305 … 995); up to 1310, 690 t.
        assert!(s.flowing(1300.0, 1000.0, 10.0, 0.0));
        assert!(!s.flowing(1310.0, 1000.0, 10.0, 0.0));
        // Too early to judge.
        assert!(Stream::default().flowing(30.0, 40.0, 10.0, 0.0));
    }
}
