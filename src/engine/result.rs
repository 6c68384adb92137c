//! What a run produces, column-wise, before it is written.

use std::borrow::Cow;
use std::ops::Range;

use super::marker_tables::EndMarkers;
pub use super::marker_tables::{DrawnTable, MarkerSnapshot, MarkerState};

/// Extraction report rows (drawpoint-major within period order).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Extraction {
    /// Drawpoint index.
    pub drawpoint: Vec<u32>,
    /// Period number.
    pub period: Vec<i64>,
    /// Scheduled tonnes.
    pub scheduled_tonnes: Vec<f64>,
    /// Mass of markers drawn.
    pub marker_tonnes: Vec<f64>,
    /// Correction factor in [0.1, 2] (1 when nothing was drawn).
    pub correction: Vec<f64>,
    /// Credited tonnes.
    pub tonnes: Vec<f64>,
    /// Shortfall carried to the next period.
    pub shortfall_tonnes: Vec<f64>,
    /// Cumulative credited tonnes.
    pub cum_tonnes: Vec<f64>,
    /// Markers drawn.
    pub markers: Vec<i64>,
    /// Waste share.
    pub dilution: Vec<f64>,
    /// Mean origin elevation.
    pub origin_z: Vec<f64>,
    /// Height of draw.
    pub hod: Vec<f64>,
    /// Mean fragment size.
    pub frag_size: Vec<f64>,
    /// Fines share.
    pub fines_share: Vec<f64>,
    /// Size passed by 20 % of the drawn mass, m.
    pub frag_p20: Vec<f64>,
    /// Size passed by 50 % of the drawn mass, m.
    pub frag_p50: Vec<f64>,
    /// Size passed by 80 % of the drawn mass, m.
    pub frag_p80: Vec<f64>,
    /// Fines-mass-weighted mean origin elevation of the drawn fines, m.
    pub fines_origin_z: Vec<f64>,
    /// Waste share of the drawn fines.
    pub fines_waste_share: Vec<f64>,
    /// Mass-weighted mean distance the drawn material percolated on its way, m.
    pub percolation: Vec<f64>,
    /// Air gap volume above the drawpoint so far.
    pub air_gap: Vec<f64>,
    /// Mass share of the drawn material that rilled on the free surface.
    pub rilled_share: Vec<f64>,
    /// Mass-weighted mean horizontal distance the rilled material rilled, m (NaN if none).
    pub rill_distance: Vec<f64>,
    /// ok | short | idle.
    #[serde(deserialize_with = "static_statuses")]
    pub status: Vec<&'static str>,
    /// Why a `short` row could not deliver, from the state of its drawpoint's lowest
    /// disks (`engine::fill`): uncaved | blocked | exhausted; empty for the other rows.
    #[serde(default, deserialize_with = "static_reasons")]
    pub short_reason: Vec<&'static str>,
    /// Fill of the drawpoint's lowest disks at the end of the period (`engine::fill`):
    /// the markers' volume at n1 over the disks'; NaN where it did not draw (uncaved, or
    /// nothing scheduled) or its IMZ is still smaller than the volume the fill is read
    /// over.
    #[serde(default)]
    pub fill: Vec<f64>,
    /// `grades[g][row]`.
    pub grades: Vec<Vec<f64>>,
    /// `lithology[l][row]` mass shares.
    pub lithology: Vec<Vec<f64>>,
}

impl Extraction {
    /// Metal of grade column `g` (Σ tonnes × grade) and the tonnes it is counted over: the
    /// rows that drew tonnes and have a grade. Their ratio is the tonnage-weighted mean
    /// grade (NaN when no row counts).
    pub fn grade_metal(&self, g: usize) -> (f64, f64) {
        let (mut metal, mut t) = (0.0, 0.0);
        if let Some(col) = self.grades.get(g) {
            for (i, &x) in col.iter().enumerate() {
                if self.tonnes[i] > 0.0 && x.is_finite() {
                    metal += self.tonnes[i] * x;
                    t += self.tonnes[i];
                }
            }
        }
        (metal, t)
    }
}

/// IMZ geometry rows.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ImzTable {
    /// Drawpoint index.
    pub drawpoint: Vec<u32>,
    /// Period number.
    pub period: Vec<i64>,
    /// Disk index.
    pub disk: Vec<i64>,
    /// Disk base, m.
    pub z_base: Vec<f64>,
    /// Disk top, m.
    pub z_top: Vec<f64>,
    /// Radius R_i, m.
    pub radius: Vec<f64>,
}

/// What a run warning is about (the rule it reports).
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
pub enum WarningRule {
    /// The method is degraded for the scene (`engine::stability`), one per rule.
    Stability,
    /// The run plan changed a resolution it was given, for a physical rule
    /// (`engine::plan`).
    Resolution,
    /// A mechanism is on but some of its inputs are missing.
    Input,
    /// A drawpoint is scheduled in a period while the ground above it has not caved:
    /// nothing is drawn (amount: the tonnes scheduled).
    Uncaved,
    /// A drawpoint could not deliver all of its schedule (amount: the tonnes it still
    /// owes at the end).
    Short,
    /// A drawpoint's markers ran behind its credits by more than their discreteness while
    /// its lowest disks could feed its schedule (`crediting::lagging`; amount: the credits'
    /// excess over its markers' mass, t).
    Lagging,
    /// A drawpoint's IMZ ends the run held under uncaved ground (amount: the air gap, m³).
    AirGap,
    /// The median mass correction leaves 1 ± 0.03: a bias, not discreteness.
    MassBalance,
}

/// A warning of a run: its rule, the drawpoint it concerns, how much it concerns, and
/// the sentence that says it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RunWarning {
    /// The rule.
    pub rule: WarningRule,
    /// The drawpoint, where there is one.
    pub drawpoint: Option<String>,
    /// Its size, in the rule's unit (see [`WarningRule`]); 0 where it has none.
    pub amount: f64,
    /// The warning in words.
    pub message: String,
}

impl RunWarning {
    /// A warning of `rule` that concerns no drawpoint in particular.
    pub fn general(rule: WarningRule, message: String) -> RunWarning {
        RunWarning {
            rule,
            drawpoint: None,
            amount: 0.0,
            message,
        }
    }
}

/// Mass balance of a run.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MassBalance {
    /// Total scheduled, t.
    pub scheduled_tonnes: f64,
    /// Total credited, t.
    pub credited_tonnes: f64,
    /// Total marker mass drawn, t.
    pub marker_tonnes: f64,
    /// Shortfall left at the end, t.
    pub final_shortfall_tonnes: f64,
    /// Markers created (mobilised at least once).
    pub markers_mobilised: u64,
    /// Markers drawn.
    pub markers_drawn: u64,
    /// Per drawpoint: (scheduled, credited).
    pub per_drawpoint: Vec<(f64, f64)>,
    /// Distribution of the mass-correction factor over the drawpoint-periods that drew
    /// markers and are `ok`.
    pub correction: CorrectionStats,
}

/// Distribution of the correction factor c = credited / marker tonnes (`engine::crediting`):
/// how far the markers each drawpoint-period drew are from the tonnes credited. It is the
/// discreteness of markers alone when the kinematics conserve mass, so the per-drawpoint
/// ratio over a run is 1 to within a few markers; `Engine` warns when the median of that
/// ratio over the drawpoints leaves 1 ± 0.03.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CorrectionStats {
    /// Drawpoint-periods counted (status `ok`, marker tonnes > 0).
    pub rows: u64,
    /// Median of c.
    pub median: f64,
    /// 10th percentile of c.
    pub p10: f64,
    /// 90th percentile of c.
    pub p90: f64,
    /// Rows of the whole table (any status, with markers) whose c is at or below
    /// MassFlow's lower bound 0.1.
    pub at_lower_bound: u64,
    /// Rows of the whole table (any status, with markers) whose c is at or above
    /// MassFlow's upper bound 2.
    pub at_upper_bound: u64,
    /// Median over the drawpoints of their credited over marker tonnes in `ok` rows over
    /// the run.
    #[serde(default)]
    pub drawpoint_median: f64,
    /// The same median over the first and over the second half of each drawpoint's
    /// credited tonnes in `ok` rows (a row counts in the half that holds its middle).
    #[serde(default)]
    pub halves_median: [f64; 2],
}

/// Trace rows (`engine::trace`): one per trace point per period, at the period's end.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TraceTable {
    /// Trace id: the point's place in the trace file (1, 2, …).
    pub trace_id: Vec<i64>,
    /// Period number.
    pub period: Vec<i64>,
    /// Position at the period's end, m.
    pub x: Vec<f64>,
    /// Position at the period's end, m.
    pub y: Vec<f64>,
    /// Position at the period's end, m.
    pub z: Vec<f64>,
    /// Given position, m.
    pub origin_x: Vec<f64>,
    /// Given position, m.
    pub origin_y: Vec<f64>,
    /// Given position, m.
    pub origin_z: Vec<f64>,
    /// State at the period's end.
    pub state: Vec<MarkerState>,
    /// Drawpoint index that drew it (u32::MAX if not drawn).
    pub drawpoint: Vec<u32>,
    /// Period in which it was drawn (-1 if not drawn).
    pub drawn_period: Vec<i64>,
    /// Accumulated shear strain Γ.
    pub shear_strain: Vec<f64>,
    /// Accumulated shear work Γσ_n, kPa.
    pub shear_work: Vec<f64>,
}

/// Resolution actually used.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ResolvedResolution {
    /// Disk thickness h, m.
    pub layer_thickness: f64,
    /// Marker lattice spacing, m.
    pub marker_spacing: f64,
    /// Draw increment, t per drawpoint per step.
    pub draw_increment: f64,
    /// The most a marker moves in one of its own steps, m (0: every marker steps every
    /// update; `engine::cadence`).
    #[serde(default)]
    pub max_marker_move: f64,
}

/// Air gap per block column and period (rows only where there is air).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AirGapTable {
    /// Period number.
    pub period: Vec<i64>,
    /// Block column centre.
    pub x: Vec<f64>,
    /// Block column centre.
    pub y: Vec<f64>,
    /// Height of the column's air blocks, m.
    pub air_gap: Vec<f64>,
}

/// Free-surface height per lattice column at chosen periods.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SurfaceTable {
    /// Period number.
    pub period: Vec<i64>,
    /// Column centre.
    pub x: Vec<f64>,
    /// Column centre.
    pub y: Vec<f64>,
    /// Top of the caved material, m.
    pub z: Vec<f64>,
}

/// Everything a run produces.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct RunOutput {
    /// Extraction report.
    pub extraction: Extraction,
    /// IMZ geometry.
    pub imz: ImzTable,
    /// Drawn markers, held whole: a run made by hand. The engine leaves this empty and
    /// hands the drawn markers over in [`end`](RunOutput::end); read the table through
    /// [`RunOutput::drawn_chunks`] or [`RunOutput::drawn_table`], which read either.
    pub drawn: DrawnTable,
    /// Marker snapshots held whole: the engine's of the periods before the last
    /// (`outputs.marker_periods`); the end snapshot is read from
    /// [`end`](RunOutput::end). Read them through [`RunOutput::snapshot_periods`] and
    /// [`RunOutput::snapshot_chunks`], which read both.
    pub snapshots: Vec<MarkerSnapshot>,
    /// The markers as the run left them, read as the drawn table and the end snapshot a
    /// range of rows at a time (`engine::marker_tables`); None for a run made by hand or a
    /// run not finished (a checkpoint).
    #[serde(skip)]
    pub end: Option<EndMarkers>,
    /// Air gap per block column and period.
    pub air_gap: AirGapTable,
    /// Free surface at the chosen periods.
    pub surface: SurfaceTable,
    /// Free surface at the charts' moments (`Scene::moments`) and the VTK export's periods
    /// (`Scene::vtk_periods`) that `surface` does not hold, for the sections through time
    /// and the VTK files only (not written as a table). Read without bringing
    /// the lagging markers up to date (`engine::cadence`), so it is within
    /// `max_marker_move` of the exact surface, and charting a moment never changes a run.
    pub moment_surface: SurfaceTable,
    /// Warnings (degraded validity, blocked drawpoints, ...), in the order raised.
    pub warnings: Vec<RunWarning>,
    /// Mass balance.
    pub balance: MassBalance,
    /// The caps of the marker moves, counted over every marker step
    /// (`engine::markers::caps`; `manifest.json`'s `marker_caps`).
    pub marker_caps: super::markers::CapTally,
    /// What fines percolation moved across the IMZs' disk bases and what the bulk's
    /// counterflow returned (`engine::fines`; `manifest.json`'s `percolation`).
    pub counterflow: super::fines::Counterflow,
    /// Resolution used.
    pub resolution: ResolvedResolution,
    /// Stress fields at the chosen periods (empty unless `mechanisms.stress` is on).
    pub stress: Vec<super::stress::StressField>,
    /// Trace points at the end of every period (empty without trace points).
    pub trace: TraceTable,
    /// Draw control's realised schedule, closures and production against target (None
    /// without `[draw_control]`'s target strategy).
    pub control: Option<ControlRecord>,
    /// Each drawpoint-period's value and each drawpoint's best height of draw (None
    /// without `[economics]`).
    pub value: Option<(ValueTable, BestHod)>,
    /// Time per phase and work counters, when the engine kept an account
    /// (`Engine::keep_account`).
    #[serde(skip)]
    pub account: Option<super::account::Account>,
}

/// Row statuses of the extraction report.
pub const STATUSES: [&str; 3] = ["ok", "short", "idle"];

/// Why a short row could not deliver (`engine::fill`): the ground above the drawpoint has
/// not caved; its column has drained into the air gap under uncaved ground; its column is
/// drawn out.
pub const SHORT_REASONS: [&str; 4] = ["", "uncaved", "blocked", "exhausted"];

/// Reads `Extraction::status` back from a checkpoint as the static names.
fn static_statuses<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Vec<&'static str>, D::Error> {
    static_names(d, &STATUSES, "row status")
}

/// Reads `Extraction::short_reason` back from a checkpoint as the static names.
fn static_reasons<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Vec<&'static str>, D::Error> {
    static_names(d, &SHORT_REASONS, "short reason")
}

fn static_names<'de, D: serde::Deserializer<'de>>(
    d: D,
    known: &[&'static str],
    what: &str,
) -> Result<Vec<&'static str>, D::Error> {
    let names: Vec<String> = serde::Deserialize::deserialize(d)?;
    names
        .iter()
        .map(|n| {
            known
                .iter()
                .find(|s| *s == n)
                .copied()
                .ok_or_else(|| serde::de::Error::custom(format!("unknown {what} {n:?}")))
        })
        .collect()
}

// The marker tables of a run, wherever they are held (`engine::marker_tables`).

/// Consecutive ranges of at most `rows` rows over `0..n`; one empty range when `n` is 0,
/// so that an empty table still comes as one (empty) chunk.
fn ranges(n: usize, rows: usize) -> impl Iterator<Item = Range<usize>> {
    let rows = rows.max(1);
    (0..n.max(1))
        .step_by(rows)
        .map(move |a| a.min(n)..(a + rows).min(n))
}

impl RunOutput {
    /// The periods of the run's marker snapshots, ascending: those of
    /// [`snapshots`](RunOutput::snapshots), then the end's.
    pub fn snapshot_periods(&self) -> Vec<i64> {
        let mut p: Vec<i64> = self.snapshots.iter().map(|s| s.period).collect();
        p.extend(self.end.as_ref().and_then(EndMarkers::snapshot_period));
        p
    }

    /// The marker snapshot of `period` as chunks of at most `rows` rows in marker-id order
    /// (a snapshot held whole comes as one chunk); None when the run kept no snapshot of
    /// `period`.
    pub fn snapshot_chunks(
        &self,
        period: i64,
        rows: usize,
    ) -> Option<Box<dyn Iterator<Item = Cow<'_, MarkerSnapshot>> + '_>> {
        if let Some(s) = self.snapshots.iter().find(|s| s.period == period) {
            return Some(Box::new(std::iter::once(Cow::Borrowed(s))));
        }
        let end = self.end.as_ref()?;
        (end.snapshot_period() == Some(period)).then(|| {
            let chunks =
                ranges(end.snapshot_len(), rows).map(move |r| Cow::Owned(end.snapshot_range(r)));
            Box::new(chunks) as Box<dyn Iterator<Item = _>>
        })
    }

    /// The marker snapshot of `period`, whole (None: the run kept none). At mine scale the
    /// end snapshot is large; read it with [`RunOutput::snapshot_chunks`] where memory
    /// matters.
    pub fn snapshot(&self, period: i64) -> Option<Cow<'_, MarkerSnapshot>> {
        if let Some(s) = self.snapshots.iter().find(|s| s.period == period) {
            return Some(Cow::Borrowed(s));
        }
        let end = self.end.as_ref()?;
        (end.snapshot_period() == Some(period))
            .then(|| Cow::Owned(end.snapshot_range(0..end.snapshot_len())))
    }

    /// Every marker snapshot, whole, in period order ([`RunOutput::snapshot`]).
    pub fn snapshot_tables(&self) -> Vec<Cow<'_, MarkerSnapshot>> {
        self.snapshot_periods()
            .into_iter()
            .filter_map(|p| self.snapshot(p))
            .collect()
    }

    /// The run with its drawn table and end snapshot made whole, in
    /// [`drawn`](RunOutput::drawn) and [`snapshots`](RunOutput::snapshots), as a run made
    /// by hand holds them, and the end markers let go: plain tables for a small run (at
    /// mine scale they are large).
    pub fn with_tables(mut self) -> RunOutput {
        if let Some(end) = self.end.take() {
            self.drawn = end.drawn_range(0..end.drawn_len());
            if end.snapshot_period().is_some() {
                self.snapshots
                    .push(end.snapshot_range(0..end.snapshot_len()));
            }
        }
        self
    }

    /// Rows of the drawn table.
    pub fn drawn_len(&self) -> usize {
        match &self.end {
            Some(end) => end.drawn_len(),
            None => self.drawn.marker_id.len(),
        }
    }

    /// The drawn table as chunks of at most `rows` rows in marker-id order (a table held
    /// whole in [`drawn`](RunOutput::drawn) comes as one chunk).
    pub fn drawn_chunks(&self, rows: usize) -> Box<dyn Iterator<Item = Cow<'_, DrawnTable>> + '_> {
        match &self.end {
            Some(end) => {
                Box::new(ranges(end.drawn_len(), rows).map(move |r| Cow::Owned(end.drawn_range(r))))
            }
            None => Box::new(std::iter::once(Cow::Borrowed(&self.drawn))),
        }
    }

    /// The drawn table, whole. At mine scale it is large; read it with
    /// [`RunOutput::drawn_chunks`] where memory matters.
    pub fn drawn_table(&self) -> Cow<'_, DrawnTable> {
        match &self.end {
            Some(end) => Cow::Owned(end.drawn_range(0..end.drawn_len())),
            None => Cow::Borrowed(&self.drawn),
        }
    }
}

/// Draw control's state and record (`engine::draw_control`), carried in the run's output
/// (so a checkpoint holds it).
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct ControlRecord {
    /// The realised tonnes, period by period (drawpoint-major rows, as `Schedule`).
    pub realised: Vec<f64>,
    /// `draw_control.neighbour_radius` as set (None: the default), so that what reads
    /// the record finds the control's own neighbours (`draw_control::Layout::new`).
    pub neighbour_radius: Option<f64>,
    /// Per drawpoint, the index of the period in which it closed.
    pub closed: Vec<Option<usize>>,
    /// Per drawpoint, consecutive periods it drew below the shut-off grade.
    pub low: Vec<usize>,
    /// Per drawpoint running out of material (`exhausted`), the rate it delivered then,
    /// t/day: its limit until its lowest disks can feed it again.
    pub running_out: Vec<Option<f64>>,
    /// The closures, in order.
    pub closures: Closures,
    /// Production against target per period.
    pub production: Production,
}

/// The `closures` table: one row per closed drawpoint.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct Closures {
    /// Drawpoint index.
    pub drawpoint: Vec<u32>,
    /// Period in which it closed.
    pub period: Vec<i64>,
    /// Which rule closed it (`draw_control::CLOSURE_REASONS`).
    pub reason: Vec<String>,
    /// Tonnes it drew in all, t.
    pub cum_tonnes: Vec<f64>,
    /// Height of draw at closure, m.
    pub hod: Vec<f64>,
    /// Grade of what it drew in the closing period (the shut-off column, else the first
    /// grade column).
    pub grade: Vec<f64>,
}

/// The `production` table: target against realised tonnes per period.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct Production {
    /// Period number.
    pub period: Vec<i64>,
    /// Target, t.
    pub target_tonnes: Vec<f64>,
    /// Tonnes shared among the open drawpoints, t.
    pub planned_tonnes: Vec<f64>,
    /// Tonnes credited, t (below planned where a drawpoint could not deliver).
    pub tonnes: Vec<f64>,
    /// Target the open drawpoints could not take, t.
    pub shortfall_tonnes: Vec<f64>,
    /// Open drawpoints.
    pub open: Vec<u32>,
    /// Drawpoints held under an air gap (not open).
    pub held: Vec<u32>,
    /// Drawpoints closed so far.
    pub closed: Vec<u32>,
}

/// The `value` table (`engine::value`): one row per extraction row that drew.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct ValueTable {
    /// Drawpoint index.
    pub drawpoint: Vec<u32>,
    /// Period number.
    pub period: Vec<i64>,
    /// Credited tonnes, t.
    pub tonnes: Vec<f64>,
    /// Height of draw at the period's end, m.
    pub hod: Vec<f64>,
    /// The period's value.
    pub value: Vec<f64>,
    /// The drawpoint's cumulative value at the period's end.
    pub cum_value: Vec<f64>,
}

/// The `best_hod` table: one row per drawpoint that drew.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct BestHod {
    /// Drawpoint index.
    pub drawpoint: Vec<u32>,
    /// Height of draw at which the cumulative value peaks, m (0 when it never rises above
    /// zero).
    pub best_hod: Vec<f64>,
    /// Tonnes drawn by then, t.
    pub best_tonnes: Vec<f64>,
    /// The peak cumulative value.
    pub best_value: Vec<f64>,
    /// Period in which the peak was reached (-1 when it never rose above zero).
    pub best_period: Vec<i64>,
    /// Height of draw at the end of the run, m.
    pub final_hod: Vec<f64>,
    /// Cumulative value at the end of the run.
    pub final_value: Vec<f64>,
}
