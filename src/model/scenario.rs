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
    /// What counts as waste for the dilution share.
    pub dilution: Dilution,
    /// What to write.
    pub outputs: Outputs,
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
}

/// Resolution knobs. Each has a measured cost and error (see the README).
#[derive(Debug, Clone, Serialize, Deserialize, Default, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct Resolution {
    /// Disk (layer) thickness h, m. Default: min(0.5 × smallest block dimension,
    /// drawpoint opening width), MassFlow's 0.5 × block size unless the opening is finer.
    pub layer_thickness: Option<f64>,
    /// Marker lattice spacing, m. Default: 0.5 × h (MassFlow: 0.25 × block size with
    /// disks 0.5 × block size, the same ratio).
    pub marker_spacing: Option<f64>,
    /// Draw increment: tonnes per drawpoint between marker updates. Default: the tonnes
    /// of one opening disk, π (w/2)² h ρ_s (1 − n1) (see `engine::resolution`).
    pub draw_increment: Option<f64>,
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
    /// Fragments finer than this are fines, m.
    pub fines_cutoff: f64,
}

impl Default for Outputs {
    fn default() -> Self {
        Outputs {
            dir: PathBuf::from("out"),
            marker_periods: Vec::new(),
            imz_every_period: true,
            charts: true,
            fines_cutoff: 0.01,
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
            .map_err(|message| ScenarioError::at(origin, "setting-range", message))?;
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
        abs(&mut self.outputs.dir);
    }

    /// Range checks on the settings themselves.
    pub fn check(&self) -> Result<(), String> {
        let pos = |name: &str, v: Option<f64>| match v {
            Some(x) if !(x.is_finite() && x > 0.0) => {
                Err(format!("{name} must be a positive number, got {x}"))
            }
            _ => Ok(()),
        };
        pos(
            "resolution.layer_thickness",
            self.resolution.layer_thickness,
        )?;
        pos("resolution.marker_spacing", self.resolution.marker_spacing)?;
        pos("resolution.draw_increment", self.resolution.draw_increment)?;
        pos("flow.q", Some(self.flow.q))?;
        pos("flow.shear_band_factor", Some(self.flow.shear_band_factor))?;
        pos(
            "flow.default_opening_width",
            Some(self.flow.default_opening_width),
        )?;
        pos("flow.min_porosity_jump", Some(self.flow.min_porosity_jump))?;
        pos("outputs.fines_cutoff", Some(self.outputs.fines_cutoff))?;
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
