//! The scenario: what to run, at what resolution, with which mechanisms, writing what.
//!
//! Loaded from TOML; every key can also be set on the command line with
//! `--set section.key=value`. Unknown keys are errors, so a typo never silently falls back
//! to a default. Every default is documented here and in the README, with its reason.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

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
    /// Also write extraction, imz, drawn, air_gap and surface as Hive-partitioned Parquet
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

/// Multiplicative adjustments of the block model's flow properties: what `calibrate` fits
/// to production records, and what a calibrated scenario carries so it can be run again.
///
/// ```toml
/// [calibration]
/// frag_factor = { urad = 0.65 }   # d̄ (and the Weibull scale β) of every `urad` block × 0.65
/// n1_factor = 1.0
/// friction_factor = 1.0
/// ```
///
/// or `--set calibration.frag_factor.urad=0.65`. Applied by [`Calibration::apply`] right
/// after the block model is read and checked (`model::load::load_scene`), so `run`,
/// `validate` and `sweep` all see the adjusted scene. The default is the identity, which
/// leaves every block, and so every output, bit-identical.
///
/// # Why factors, not values
/// Back-analysis asks "how much finer is this zone than we assumed?" (summary §8: 0.23 m
/// stated, 0.15 m matched). A factor keeps the block model's spatial variation within a
/// lithology and is one number to fit per zone.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct Calibration {
    /// Multiplicative factor on the mean primary fragment size d̄ (and the Weibull scale β) of every block of the named lithology.
    pub frag_factor: std::collections::BTreeMap<String, f64>,
    /// Multiplicative factor on the dilated porosity n1 of every block (1 = as given).
    pub n1_factor: f64,
    /// Multiplicative factor on the friction angle φ of every block (1 = as given).
    pub friction_factor: f64,
}

impl Default for Calibration {
    fn default() -> Self {
        Calibration {
            frag_factor: std::collections::BTreeMap::new(),
            n1_factor: 1.0,
            friction_factor: 1.0,
        }
    }
}

impl Calibration {
    /// True when applying it changes nothing.
    pub fn is_identity(&self) -> bool {
        self.n1_factor == 1.0
            && self.friction_factor == 1.0
            && self.frag_factor.values().all(|&f| f == 1.0)
    }

    /// Range checks that need no block model: every factor finite and positive.
    pub fn check(&self) -> Result<(), SettingError> {
        for (lith, &f) in &self.frag_factor {
            SettingError::positive(&format!("calibration.frag_factor.{lith}"), Some(f))?;
        }
        SettingError::positive("calibration.n1_factor", Some(self.n1_factor))?;
        SettingError::positive("calibration.friction_factor", Some(self.friction_factor))
    }

    /// Applies the factors to a checked block model, in place:
    /// - `frag_factor[lith]` multiplies `frag` (d̄) and `frag_scale` (β) of every block of
    ///   that lithology; the Weibull shape α is kept, so the sampled sizes scale by the
    ///   same factor;
    /// - `n1_factor` multiplies `n1` of every block; the result must stay at least n0 (the
    ///   block model's own `n1-below-n0` rule: n1 = n0 is ground already dilated) and
    ///   below 1;
    /// - `friction_factor` multiplies φ of every block; the result must stay in (0°, 90°).
    ///
    /// A factor of exactly 1 touches nothing. Errors (nothing is changed then): a factor
    /// that is not a positive number, a lithology the block model does not have (the
    /// message lists those it has), and the first block that a factor takes out of range
    /// (named by block id, with the count of such blocks).
    pub fn apply(&self, bm: &mut super::BlockModel) -> Result<(), String> {
        self.apply_located(bm).map_err(|e| e.message)
    }

    /// [`apply`](Self::apply), with where its error lies: the block row and the block
    /// model column (canonical name) it concerns, for the loader's problem report.
    pub fn apply_located(&self, bm: &mut super::BlockModel) -> Result<(), CalibrationError> {
        let whole = |e: SettingError| CalibrationError {
            block: None,
            column: None,
            message: e.to_string(),
        };
        self.check().map_err(whole)?;
        let mut lith_factor = vec![1.0; bm.lithology_names.len()];
        for (lith, &f) in &self.frag_factor {
            match bm.lithology_names.iter().position(|n| n == lith) {
                Some(k) => lith_factor[k] = f,
                None => {
                    return Err(CalibrationError {
                        block: None,
                        column: Some("lithology"),
                        message: format!(
                            "calibration.frag_factor names lithology `{lith}`, which the block model does not have; it has: {}",
                            bm.lithology_names
                                .iter()
                                .map(|n| format!("`{n}`"))
                                .collect::<Vec<_>>()
                                .join(", ")
                        ),
                    })
                }
            }
        }
        // The first block a factor takes out of range, and how many it does.
        let first_bad = |ok: &dyn Fn(usize) -> bool| {
            let mut bad = (0..bm.len()).filter(|&b| !ok(b));
            bad.next().map(|b| (b, 1 + bad.count()))
        };
        let f1 = self.n1_factor;
        if f1 != 1.0 {
            let ok = |b: usize| {
                let n = bm.n1[b] * f1;
                n >= bm.n0[b] && n < 1.0
            };
            if let Some((b, count)) = first_bad(&ok) {
                return Err(CalibrationError {
                    block: Some(b),
                    column: Some("max_porosity"),
                    message: format!(
                        "calibration.n1_factor = {f1} takes max_porosity n1 of block {} from {} to {}, outside [n0 = {}, 1) ({count} block(s) in all)",
                        bm.id[b],
                        bm.n1[b],
                        bm.n1[b] * f1,
                        bm.n0[b]
                    ),
                });
            }
        }
        let ff = self.friction_factor;
        if ff != 1.0 {
            let ok = |b: usize| {
                let p = bm.friction[b] * ff;
                p > 0.0 && p < 90.0
            };
            if let Some((b, count)) = first_bad(&ok) {
                return Err(CalibrationError {
                    block: Some(b),
                    column: Some("friction_angle"),
                    message: format!(
                        "calibration.friction_factor = {ff} takes the friction angle of block {} from {}° to {}°, outside (0°, 90°) ({count} block(s) in all)",
                        bm.id[b],
                        bm.friction[b],
                        bm.friction[b] * ff
                    ),
                });
            }
        }
        if lith_factor.iter().any(|&f| f != 1.0) {
            for b in 0..bm.len() {
                let f = lith_factor[bm.lithology[b] as usize];
                if f != 1.0 {
                    bm.frag[b] *= f;
                    if let Some(s) = bm.frag_scale.get_mut(b) {
                        *s *= f;
                    }
                }
            }
        }
        if f1 != 1.0 {
            bm.n1.iter_mut().for_each(|n| *n *= f1);
        }
        if ff != 1.0 {
            bm.friction.iter_mut().for_each(|p| *p *= ff);
        }
        Ok(())
    }
}

/// Why a [`Calibration`] cannot be applied to a block model.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationError {
    /// The block (row of the block model) it concerns, if one.
    pub block: Option<usize>,
    /// The block model column (canonical name) it concerns, if one.
    pub column: Option<&'static str>,
    /// What is wrong.
    pub message: String,
}

/// A setting outside its range (rule `setting-range`): the key, and what it must be.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{key} {must}")]
pub struct SettingError {
    /// The scenario key, e.g. `resolution.marker_spacing`.
    pub key: String,
    /// What the value must be, and what it is.
    pub must: String,
}

impl SettingError {
    /// A setting `key` that `must` be otherwise.
    pub fn new(key: &str, must: String) -> SettingError {
        SettingError {
            key: key.into(),
            must,
        }
    }

    /// Ok unless `value` is set and is not a positive number.
    pub fn positive(key: &str, value: Option<f64>) -> Result<(), SettingError> {
        match value {
            Some(x) if !(x.is_finite() && x > 0.0) => Err(SettingError::new(
                key,
                format!("must be a positive number, got {x}"),
            )),
            _ => Ok(()),
        }
    }
}

/// A problem with the scenario file or a `--set`. Displayed like an input
/// [`Problem`](crate::io::Problem): `scenario.toml: line 4, column 1: [unknown-key] …`.
///
/// Rules: `unreadable` (missing file, not UTF-8), `toml-syntax`, `unknown-key` (a typo
/// never falls back to a default), `wrong-type` (a string where a number belongs, …),
/// `bad-set` (a `--set` that is not `key=value`), `setting-range` (a value out of range).
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// Could not read the file.
    #[error("{}: [unreadable] cannot read the scenario: {source}", .path.display())]
    Read {
        /// File.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// TOML syntax or a key/type problem.
    #[error("{path}: {}[{rule}] {message}", at(.line))]
    Parse {
        /// File (or `--set`).
        path: String,
        /// 1-based line and column in the file, where known.
        line: Option<(usize, usize)>,
        /// Stable rule id (see the type's docs).
        rule: &'static str,
        /// What is wrong.
        message: String,
    },
}

impl ScenarioError {
    /// The rule id.
    pub fn rule(&self) -> &'static str {
        match self {
            ScenarioError::Read { .. } => "unreadable",
            ScenarioError::Parse { rule, .. } => rule,
        }
    }

    /// A problem not tied to a place in the file.
    fn at(path: &str, rule: &'static str, message: String) -> ScenarioError {
        ScenarioError::Parse {
            path: path.into(),
            line: None,
            rule,
            message,
        }
    }

    /// A TOML error, located in `text` when it has a span. `syntax`: the text did not
    /// parse at all; otherwise the rule is read from serde's wording.
    fn toml(path: &str, text: &str, e: &toml::de::Error, syntax: bool) -> ScenarioError {
        let message = e.message().trim().to_string();
        let rule = if syntax {
            "toml-syntax"
        } else if message.contains("unknown field") || message.contains("unknown variant") {
            "unknown-key"
        } else {
            "wrong-type"
        };
        let line = e.span().map(|r| {
            let before = text.get(..r.start).unwrap_or(text);
            let line = before.matches('\n').count() + 1;
            let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
            (line, col)
        });
        ScenarioError::Parse {
            path: path.into(),
            line,
            rule,
            message,
        }
    }
}

/// `line L, column C: ` or nothing.
fn at(line: &Option<(usize, usize)>) -> String {
    line.map_or(String::new(), |(l, c)| format!("line {l}, column {c}: "))
}

impl Scenario {
    /// Loads a scenario file, applies `--set key=value` overrides, and makes input paths
    /// absolute relative to the file's folder.
    pub fn load(path: &Path, sets: &[String]) -> Result<Scenario, ScenarioError> {
        let text = std::fs::read_to_string(path).map_err(|source| ScenarioError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        let base = path.parent().unwrap_or(Path::new("."));
        Self::from_toml(&text, &path.display().to_string(), sets, base)
    }

    /// Parses scenario text, applies overrides, resolves paths against `base`.
    pub fn from_toml(
        text: &str,
        origin: &str,
        sets: &[String],
        base: &Path,
    ) -> Result<Scenario, ScenarioError> {
        let mut value: toml::Table =
            toml::from_str(text).map_err(|e| ScenarioError::toml(origin, text, &e, true))?;
        // The file alone first, so that its key and type errors carry a line and column
        // (a `toml::Value` keeps no spans); then with the overrides, whose errors are theirs.
        toml::from_str::<Scenario>(text)
            .map_err(|e| ScenarioError::toml(origin, text, &e, false))?;
        for s in sets {
            apply_set(&mut value, s)?;
        }
        let mut sc: Scenario = Scenario::deserialize(toml::Value::Table(value))
            .map_err(|e| ScenarioError::toml("--set", "", &e, false))?;
        sc.resolve_paths(base);
        sc.check()
            .map_err(|e| ScenarioError::at(origin, "setting-range", e.to_string()))?;
        Ok(sc)
    }

    /// A scenario from defaults plus `--set` overrides (for runs given tables directly).
    pub fn from_sets(sets: &[String], base: &Path) -> Result<Scenario, ScenarioError> {
        Self::from_toml("", "--set", sets, base)
    }

    fn resolve_paths(&mut self, base: &Path) {
        let abs = |p: &mut PathBuf| {
            if !p.as_os_str().is_empty() && p.is_relative() {
                *p = base.join(&*p);
            }
        };
        abs(&mut self.inputs.blocks);
        abs(&mut self.inputs.drawpoints);
        abs(&mut self.inputs.schedule);
        if let Some(p) = self.inputs.drawbells.as_mut() {
            abs(p);
        }
        if let Some(p) = self.inputs.periods.as_mut() {
            abs(p);
        }
        if let Some(p) = self.inputs.trace.as_mut() {
            abs(p);
        }
        abs(&mut self.outputs.dir);
    }

    /// Range checks on the settings themselves: the first setting out of its range.
    pub fn check(&self) -> Result<(), SettingError> {
        let pos = SettingError::positive;
        let bad = |key: &str, must: String| Err(SettingError::new(key, must));
        let res = &self.resolution;
        pos("resolution.layer_thickness", res.layer_thickness)?;
        pos("resolution.marker_spacing", res.marker_spacing)?;
        pos("resolution.draw_increment", res.draw_increment)?;
        if let Some(x) = res.max_marker_move {
            if !(x.is_finite() && x >= 0.0) {
                return bad(
                    "resolution.max_marker_move",
                    format!("must be a number ≥ 0 (0: every marker steps every update), got {x}"),
                );
            }
        }
        pos("resolution.target_grade_rmse", res.target_grade_rmse)?;
        if let Some(x) = res
            .lattice_offset
            .iter()
            .find(|x| !(-0.5..0.5).contains(*x))
        {
            return bad(
                "resolution.lattice_offset",
                format!("each must lie in [-0.5, 0.5) (fractions of the marker spacing), got {x}"),
            );
        }
        pos("flow.q", Some(self.flow.q))?;
        pos("flow.shear_band_factor", Some(self.flow.shear_band_factor))?;
        pos(
            "flow.default_opening_width",
            Some(self.flow.default_opening_width),
        )?;
        pos("flow.min_porosity_jump", Some(self.flow.min_porosity_jump))?;
        pos("outputs.fines_cutoff", Some(self.outputs.fines_cutoff))?;
        let fill = self.rilling.air_fill;
        if !(fill > 0.0 && fill < 1.0) {
            return bad(
                "rilling.air_fill",
                format!("must lie strictly between 0 and 1, got {fill}"),
            );
        }
        let f = &self.fragmentation;
        if !(f.k_n.is_finite() && f.k_n >= 0.0) {
            return bad(
                "fragmentation.k_n",
                format!("must be a number >= 0, got {}", f.k_n),
            );
        }
        pos("fragmentation.beta", Some(f.beta))?;
        pos("fragmentation.phi", Some(f.phi))?;
        pos("fragmentation.product_exponent", Some(f.product_exponent))?;
        self.calibration.check()?;
        if let Some(n) = &self.outputs.scenario_name {
            let ok = |c: char| c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-');
            if n.is_empty() || !n.chars().all(ok) || n.starts_with('.') {
                return bad(
                    "outputs.scenario_name",
                    format!("`{n}` must be letters, digits, `.`, `_` and `-` (not starting with `.`): it names a directory"),
                );
            }
        }
        pos("stress.cell", self.stress.cell)?;
        pos("stress.bin_k", Some(self.stress.bin_k))?;
        let c = self.stress.cohesion_kpa;
        if !(c.is_finite() && c >= 0.0) {
            return bad(
                "stress.cohesion_kpa",
                format!("must be a number >= 0, got {c}"),
            );
        }
        if let Some(w) = self.stress.wall_friction_deg {
            if !(w > 0.0 && w < 90.0) {
                return bad(
                    "stress.wall_friction_deg",
                    format!("must be in (0, 90), got {w}"),
                );
            }
        }
        Ok(())
    }
}

/// Applies one `section.key=value` override. The value is parsed as TOML (number, bool,
/// string, array); a bare word that is not valid TOML is taken as a string.
fn apply_set(root: &mut toml::Table, set: &str) -> Result<(), ScenarioError> {
    let err = |message: String| ScenarioError::at("--set", "bad-set", message);
    let (key, raw) = set.split_once('=').ok_or_else(|| {
        err(format!(
            "`{set}`: expected key=value, e.g. resolution.layer_thickness=0.02"
        ))
    })?;
    let key = key.trim();
    let raw = raw.trim();
    let value = match format!("v = {raw}").parse::<toml::Table>() {
        Ok(mut t) if t.len() == 1 => t.remove("v"),
        _ => None,
    }
    .unwrap_or_else(|| toml::Value::String(raw.to_string()));
    let parts: Vec<&str> = key.split('.').collect();
    if parts.iter().any(|p| p.is_empty()) {
        return Err(err(format!("`{set}`: empty key segment")));
    }
    let mut table = root;
    for p in &parts[..parts.len() - 1] {
        table = table
            .entry(p.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()))
            .as_table_mut()
            .ok_or_else(|| err(format!("`{set}`: {p} is not a section")))?;
    }
    table.insert(parts[parts.len() - 1].to_string(), value);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The twin's offset is the lattice's moved by TWIN_OFFSET, wrapped into the range
    /// `check` accepts, so a twin of any valid scenario is valid.
    #[test]
    fn the_twin_lattice_is_moved_by_twin_offset_and_stays_in_range() {
        let twin = |o: [f64; 2]| {
            let mut sc = Scenario::default();
            sc.resolution.lattice_offset = o;
            let t = sc.resolution.nth_twin_offset(1);
            sc.resolution.lattice_offset = t;
            sc.check().unwrap();
            t
        };
        assert_eq!(twin([0.0, 0.0]), [-0.5, 0.25]);
        assert_eq!(twin([0.25, -0.5]), [-0.25, -0.25]);
        assert_eq!(twin([-0.5, 0.375]), [0.0, -0.375]);
        for k in 0..100 {
            let o = [k as f64 / 100.0 - 0.5, 0.49 - k as f64 / 101.0];
            let t = twin(o);
            for a in 0..2 {
                // Off by a whole number of spacings, to rounding.
                let r = (t[a] - o[a] - TWIN_OFFSET[a]).rem_euclid(1.0);
                assert!(r.min(1.0 - r) < 1e-12, "{o:?} → {t:?}");
            }
        }
    }

    /// A setting out of range is reported under its key, with what it must be; nested
    /// checks (the calibration's) name their own keys.
    #[test]
    fn a_setting_out_of_range_names_its_key() {
        let mut sc = Scenario::default();
        sc.resolution.marker_spacing = Some(-1.0);
        let e = sc.check().unwrap_err();
        assert_eq!(e.key, "resolution.marker_spacing");
        assert_eq!(
            e.to_string(),
            "resolution.marker_spacing must be a positive number, got -1"
        );
        let mut sc = Scenario::default();
        sc.calibration.frag_factor.insert("urad".into(), 0.0);
        assert_eq!(sc.check().unwrap_err().key, "calibration.frag_factor.urad");
        let mut sc = Scenario::default();
        sc.rilling.air_fill = 1.0;
        let e = sc.check().unwrap_err();
        assert_eq!(e.key, "rilling.air_fill");
        assert!(e.must.contains("strictly between 0 and 1"), "{e}");
        assert_eq!(Scenario::default().check(), Ok(()));
    }
}
