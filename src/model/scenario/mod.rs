//! The scenario: what to run, at what resolution, with which mechanisms, writing what.
//!
//! Loaded from TOML; every key can also be set on the command line with
//! `--set section.key=value`. Unknown keys are errors, so a typo never silently falls back
//! to a default. Every default is documented here and in `docs::scenario`, with its reason.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

mod calibration;
mod draw_control;
mod read;

pub use calibration::{Calibration, CalibrationError};
pub use draw_control::{DrawControl, Economics, Strategy};
pub use read::{ScenarioError, SettingError};

/// A complete scenario.
#[derive(Debug, Clone, Serialize, Deserialize, Default, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct Scenario {
    /// Input tables.
    pub inputs: Inputs,
    /// Resolution knobs (None = chosen automatically from the scene).
    pub resolution: Resolution,
    /// IMZ and marker-motion parameters.
    pub flow: Flow,
    /// Optional mechanisms.
    pub mechanisms: Mechanisms,
    /// Cave advance, air gap and rilling settings.
    pub rilling: Rilling,
    /// Constants of secondary fragmentation (used when `mechanisms.fragmentation` is on).
    pub fragmentation: FragmentationParams,
    /// What counts as waste for the dilution share.
    pub dilution: Dilution,
    /// What to write.
    pub outputs: Outputs,
    /// Stress logic settings (used when `mechanisms.stress` is on).
    pub stress: StressSettings,
    /// Multiplicative adjustments of block properties, for back-analysis (default: none).
    pub calibration: Calibration,
    /// How each period's tonnes are decided (default: the schedule, as given).
    pub draw_control: DrawControl,
    /// What a tonne drawn is worth (optional: values and best heights of draw).
    pub economics: Option<Economics>,
    /// Seed of the run's random number generator.
    pub seed: u64,
}

/// Paths to the input tables (relative paths are relative to the scenario file).
#[derive(Debug, Clone, Serialize, Deserialize, Default, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct Inputs {
    /// Block model (Parquet, CSV or MassFlow CSV).
    pub blocks: PathBuf,
    /// Drawpoints.
    pub drawpoints: PathBuf,
    /// Drawbells (optional: gives drawpoint opening widths).
    pub drawbells: Option<PathBuf>,
    /// Schedule: long form (period, drawpoint, tonnes) or MassFlow wide form.
    pub schedule: PathBuf,
    /// Periods table (optional with the wide schedule, whose headers name the periods).
    pub periods: Option<PathBuf>,
    /// Trace points to follow through the draw (MassFlow's trace-marker file: `x y z`
    /// rows, no header; `io::TracePoints`). Optional; `--trace` sets it.
    pub trace: Option<PathBuf>,
}

/// Resolution knobs. Each has a measured cost and error (`docs::resolution`). The defaults are
/// stated once, in `engine::resolution` (the rule and why), which resolves them.
#[derive(Debug, Clone, Serialize, Deserialize, Default, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct Resolution {
    /// Disk (layer) thickness h, m. Unset: the scene default (`engine::resolution`).
    pub layer_thickness: Option<f64>,
    /// Marker lattice spacing, m. Unset: the scene default (`engine::resolution`).
    pub marker_spacing: Option<f64>,
    /// Draw increment: tonnes per drawpoint between marker updates. Unset: the scene
    /// default (`engine::resolution`).
    pub draw_increment: Option<f64>,
    /// The most a marker may move in one of its own steps, m: a marker slower than this per
    /// update steps once every 2^L updates by their summed motion (`engine::cadence`); 0
    /// makes every marker step every update. Unset: `engine::resolution::max_move_rule`.
    pub max_marker_move: Option<f64>,
    /// Accuracy target: the grade RMSE (relative, 0.01 = 1%) against a converged run that the
    /// resolution should reach. When set, the knobs left unset are chosen for it
    /// (`engine::resolution::resolve`): a tighter target gives a finer resolution, never a
    /// coarser one. Unset: the scene defaults above.
    pub target_grade_rmse: Option<f64>,
    /// Plan offset (x, y) of the marker lattice, as fractions of the spacing, each in
    /// [−0.5, 0.5). Another offset samples the same ground with other sites: it is as good
    /// a run, and the spread of the results between offsets is the markers' sampling noise
    /// (`docs::resolution`, "Sampling noise"). Default: none.
    pub lattice_offset: [f64; 2],
}

/// Plan offset, in fractions of the marker spacing, of a run's twin (added to its own
/// `lattice_offset`): half a spacing in x and a quarter in y, another sample of the ground
/// as far as a plan offset goes from the first. `sweep` runs its reference and check
/// twice, and `calibrate` its fit, to measure the markers' sampling noise.
pub const TWIN_OFFSET: [f64; 2] = [0.5, 0.25];

impl Resolution {
    /// The lattice offset of this resolution's k-th twin: moved by k × [`TWIN_OFFSET`],
    /// wrapped into [−0.5, 0.5) (k = 0 is its own lattice; the first three twins lie at
    /// (½, ¼), (0, ½) and (½, ¾) spacings from it, each another sample of the ground).
    pub fn nth_twin_offset(&self, k: usize) -> [f64; 2] {
        let o = self.lattice_offset;
        [0, 1].map(|a| (o[a] + k as f64 * TWIN_OFFSET[a] + 0.5).rem_euclid(1.0) - 0.5)
    }
}

/// IMZ growth and marker-motion parameters (summary §3.3).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct Flow {
    /// Exponent q of the r-law (summary default 3.5).
    pub q: f64,
    /// Shear band width w as a multiple of d̄ (summary §3.2: about 10).
    pub shear_band_factor: f64,
    /// Default drawpoint opening width when neither the drawpoint nor its drawbell gives
    /// one, m.
    pub default_opening_width: f64,
    /// Smallest porosity jump n1 − n0 that dilation can use. Below it the ground is
    /// already dilated: the disk widens for free to the edge of the dilated ground
    /// (see `engine::imz`).
    pub min_porosity_jump: f64,
    /// Refuse to run a scene where REBOP's method fails (`engine::stability`). false turns
    /// each refusal into a warning, kept in the run log and the manifest: for studies of
    /// the method itself, never for predictions.
    pub enforce_stability: bool,
}

impl Default for Flow {
    fn default() -> Self {
        Flow {
            q: 3.5,
            shear_band_factor: 10.0,
            default_opening_width: 4.0,
            min_porosity_jump: 0.005,
            enforce_stability: true,
        }
    }
}

/// Optional mechanisms: off by default, as in MassFlow.
#[derive(Debug, Clone, Serialize, Deserialize, Default, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct Mechanisms {
    /// Secondary fragmentation (Bridgwater attrition, summary §6.3).
    pub fragmentation: bool,
    /// Fines migration (percolation, summary §7.3).
    pub fines: bool,
    /// Free-surface rilling (summary §8).
    pub rilling: bool,
    /// Stress logic (summary §5.3).
    pub stress: bool,
}

/// Cave advance, air gap and free-surface rilling (summary §8, `engine::rilling`).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct Rilling {
    /// Rill after every this many draw steps as well as at the end of each period (0: at
    /// the end of each period only).
    pub every_steps: usize,
    /// A block counts as air once it holds less than this share of its in-situ mass
    /// (MassFlow: air once 0.75 empty, i.e. 0.25).
    pub air_fill: f64,
}

impl Default for Rilling {
    fn default() -> Self {
        Rilling {
            every_steps: 0,
            air_fill: 0.25,
        }
    }
}

/// Constants of Bridgwater's attrition law W = K_N (σ_N Γ^φ / σ_t)^β and of the
/// attrition-product size distribution (summary §6.3; see `engine::fragmentation`).
/// Bridgwater et al.'s published constants per particle shape were not at hand: every
/// default here is an ASSUMPTION, to be replaced by calibration.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct FragmentationParams {
    /// K_N (default 1.0, assumption).
    pub k_n: f64,
    /// β, exponent of the stress:strength ratio (default 1.0, assumption).
    pub beta: f64,
    /// φ, exponent of the shear strain (default 0.5, assumption).
    pub phi: f64,
    /// m in the attrition-product distribution (x/d0)^m, m = 3 − D (default 0.5: fractal
    /// dimension D = 2.5, assumption).
    pub product_exponent: f64,
}

impl Default for FragmentationParams {
    fn default() -> Self {
        FragmentationParams {
            k_n: 1.0,
            beta: 1.0,
            phi: 0.5,
            product_exponent: 0.5,
        }
    }
}

/// Waste definition for the dilution share.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct Dilution {
    /// Grade column that defines ore (default: the first grade column).
    pub grade: Option<String>,
    /// Material below this grade is waste, %.
    pub cutoff: f64,
    /// Lithologies that are waste whatever their grade.
    pub waste_lithologies: Vec<String>,
}

impl Default for Dilution {
    fn default() -> Self {
        Dilution {
            grade: None,
            cutoff: 0.0,
            waste_lithologies: Vec::new(),
        }
    }
}

/// Outputs.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct Outputs {
    /// Run directory (relative to the scenario file; `--out` overrides).
    pub dir: PathBuf,
    /// Periods at whose end marker states are written (empty: the last period only).
    pub marker_periods: Vec<i64>,
    /// Write IMZ geometry at the end of every period (true) or only the last (false).
    pub imz_every_period: bool,
    /// Write charts (PNG) into the run directory.
    pub charts: bool,
    /// Write `report.html`, the run report (`output::report::run`): the verdict, grade
    /// charts, plan maps, sections through the draw, the mass balance and the resolution,
    /// self-contained.
    pub report: bool,
    /// Fragments finer than this are fines, m.
    pub fines_cutoff: f64,
    /// Periods at whose end the free-surface height field is written (empty: the last).
    pub surface_periods: Vec<i64>,
    /// Periods at whose end the charts draw the sections (sections through time). Empty:
    /// about a quarter, a half and three quarters of the scheduled tonnes, and the last
    /// period (`Scene::moments`).
    pub section_periods: Vec<i64>,
    /// Also write extraction, imz, drawn, air_gap and surface (and draw control's and the
    /// value tables, when the run has them) as Hive-partitioned Parquet
    /// datasets under `<dir>/dataset/<table>/scenario=<name>/period=<N>/` for BI tools
    /// (`output::dataset`). Default true: BI tools read them as they are. They hold the
    /// same rows as the flat tables again; turn them off for mine-scale runs short of disk.
    pub hive: bool,
    /// Periods per dataset partition. 0 (default): automatic, one per period up to 400
    /// periods, else grouped into about 120 `period_group=` partitions (a daily mine-scale
    /// run would otherwise make thousands of tiny files per table).
    pub hive_periods_per_partition: usize,
    /// The `scenario=` value of the datasets. Default: the scenario file's stem (`run` when
    /// the tables are given on the command line).
    pub scenario_name: Option<String>,
    /// Also write MassFlow's report layouts under `<dir>/massflow/` (`output::massflow`):
    /// the period extraction report, the marker and trace reports and the daily trace CSV.
    /// The Parquet tables stay the primary output. `--massflow-reports` sets it.
    pub massflow: bool,
    /// Also write VTK XML files for ParaView under `<dir>/vtk/` (`output::vtk`): the IMZ
    /// disks, the markers at the marker periods, the free surface, the IEZ, the block model
    /// and the drawpoints, with `.pvd` collections that play the periods in order. Default
    /// false: they hold the markers again. `run --vtk` sets it.
    pub vtk: bool,
    /// Periods whose IMZ disks and free surface the VTK export writes (`output::vtk`; the
    /// markers follow `marker_periods`). Empty: the sections' moments (`section_periods`,
    /// `Scene::vtk_periods`). A period the schedule lacks is refused (`unknown-period`).
    pub vtk_periods: Vec<i64>,
}

impl Default for Outputs {
    fn default() -> Self {
        Outputs {
            dir: PathBuf::from("out"),
            marker_periods: Vec::new(),
            imz_every_period: true,
            charts: true,
            report: true,
            fines_cutoff: 0.01,
            surface_periods: Vec::new(),
            section_periods: Vec::new(),
            hive: true,
            hive_periods_per_partition: 0,
            scenario_name: None,
            massflow: false,
            vtk: false,
            vtk_periods: Vec::new(),
        }
    }
}

/// Lateral stress ratio K (horizontal over vertical stress) of the cave-scale Janssen slices.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "lowercase")]
pub enum LateralRatio {
    /// At rest, K0 = 1 − sin φ (Jaky): the stagnant caved column barely strains sideways.
    #[default]
    Jaky,
    /// Active, Ka = (1 − sin φ)/(1 + sin φ) (Rankine): the lower bound, walls yielding away.
    Rankine,
}

/// Stress logic (summary §5.3; see `engine::stress` for the physics and the choices).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct StressSettings {
    /// Periods at whose end stress is computed (empty: the last period only).
    pub periods: Vec<i64>,
    /// Stress grid cell and level spacing, m. Default: the IMZ disk thickness h, so each
    /// slice is one disk (summary §5.3: slices are analogous to the disks).
    pub cell: Option<f64>,
    /// Cohesion c of the caved rock, kPa. Default 0: caved rock (and the gravel of the
    /// physical models) is a cohesionless frictional assembly.
    pub cohesion_kpa: f64,
    /// K of the cave-scale Janssen slices. Default `jaky`.
    pub cave_k: LateralRatio,
    /// K inside IMZs (bin slices). Default 1: vertical and radial stresses inside an IMZ
    /// are about equal (summary §5.2).
    pub bin_k: f64,
    /// Friction angle between caved rock and the cave walls, degrees. Default (None): the
    /// caved rock's own φ (rough walls: slip happens inside the caved rock).
    pub wall_friction_deg: Option<f64>,
    /// Eastings of the N-S vertical sections, m. Default (None): one through the drawpoint
    /// axis nearest the centre of the drawpoints.
    pub ns_x: Option<Vec<f64>>,
    /// Northings of the E-W vertical sections, m. Default (None): as `ns_x`, across.
    pub ew_y: Option<Vec<f64>>,
    /// Elevations of the horizontal sections, m. Default (None): one at the mean mid-height
    /// of the IMZs.
    pub plan_z: Option<Vec<f64>>,
}

impl Default for StressSettings {
    fn default() -> Self {
        StressSettings {
            periods: Vec::new(),
            cell: None,
            cohesion_kpa: 0.0,
            cave_k: LateralRatio::Jaky,
            bin_k: 1.0,
            wall_friction_deg: None,
            ns_x: None,
            ew_y: None,
            plan_z: None,
        }
    }
}
