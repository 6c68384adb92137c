//! What a run produces, column-wise, before it is written.

/// Marker states (`markers.state`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[repr(u8)]
pub enum MarkerState {
    /// Never mobilised: at its lattice origin.
    InSitu = 0,
    /// Inside an IMZ (dilated, moving).
    Moving = 1,
    /// Left the lowest disk of an IMZ.
    Drawn = 2,
}

impl MarkerState {
    /// Name written to Parquet.
    pub fn name(self) -> &'static str {
        match self {
            MarkerState::InSitu => "in_situ",
            MarkerState::Moving => "moving",
            MarkerState::Drawn => "drawn",
        }
    }
}

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
    /// Why a `short` row could not deliver (`engine::crediting`): uncaved | blocked |
    /// exhausted; empty for the other rows.
    #[serde(default, deserialize_with = "static_reasons")]
    pub short_reason: Vec<&'static str>,
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

/// Drawn markers (IEZ).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DrawnTable {
    /// Marker id.
    pub marker_id: Vec<i64>,
    /// Drawpoint index.
    pub drawpoint: Vec<u32>,
    /// Period number.
    pub period: Vec<i64>,
    /// Origin.
    pub origin_x: Vec<f64>,
    /// Origin.
    pub origin_y: Vec<f64>,
    /// Origin.
    pub origin_z: Vec<f64>,
    /// Mass, t.
    pub mass: Vec<f64>,
    /// Block id.
    pub block_id: Vec<i64>,
    /// Horizontal distance rilled on the free surface, m.
    pub rill_distance: Vec<f64>,
    /// Fragment size when drawn, m.
    pub frag_size: Vec<f64>,
}

/// Marker states at the end of one period.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MarkerSnapshot {
    /// Period number.
    pub period: i64,
    /// Marker id.
    pub marker_id: Vec<i64>,
    /// Position.
    pub x: Vec<f64>,
    /// Position.
    pub y: Vec<f64>,
    /// Position.
    pub z: Vec<f64>,
    /// Origin.
    pub origin_x: Vec<f64>,
    /// Origin.
    pub origin_y: Vec<f64>,
    /// Origin.
    pub origin_z: Vec<f64>,
    /// Mass, t.
    pub mass: Vec<f64>,
    /// Block id.
    pub block_id: Vec<i64>,
    /// State.
    pub state: Vec<MarkerState>,
    /// Porosity.
    pub porosity: Vec<f64>,
    /// Fragment size, m.
    pub frag_size: Vec<f64>,
    /// Accumulated shear strain Γ.
    pub shear_strain: Vec<f64>,
    /// Accumulated shear work Γσ_n, kPa.
    pub shear_work: Vec<f64>,
    /// Primary fragment size d0, m.
    pub primary_frag_size: Vec<f64>,
    /// Attrited mass fraction W.
    pub attrited: Vec<f64>,
    /// Accumulated percolation distance, m.
    pub percolated: Vec<f64>,
    /// Drawpoint index that drew it (u32::MAX if not drawn).
    pub drawpoint: Vec<u32>,
    /// Period drawn (-1 if not drawn).
    pub drawn_period: Vec<i64>,
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
    /// Drawn markers.
    pub drawn: DrawnTable,
    /// Marker snapshots.
    pub snapshots: Vec<MarkerSnapshot>,
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
    /// Resolution used.
    pub resolution: ResolvedResolution,
    /// Stress fields at the chosen periods (empty unless `mechanisms.stress` is on).
    pub stress: Vec<super::stress::StressField>,
    /// Trace points at the end of every period (empty without trace points).
    pub trace: TraceTable,
    /// Time per phase and work counters, when the engine kept an account
    /// (`Engine::keep_account`).
    #[serde(skip)]
    pub account: Option<super::account::Account>,
}

/// Row statuses of the extraction report.
pub const STATUSES: [&str; 3] = ["ok", "short", "idle"];

/// Why a short row could not deliver: the ground above the drawpoint has not caved; its
/// IMZ is held under uncaved ground and has drained into the air gap; its column is
/// exhausted.
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
