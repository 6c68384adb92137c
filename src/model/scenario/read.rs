//! Reading a scenario: the TOML file, `--set key=value` overrides, the range checks, and
//! the problems each can have.

use std::path::{Path, PathBuf};

use serde::Deserialize;

use super::Scenario;

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
        if let Some(p) = self.draw_control.target_table.as_mut() {
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
        if let Some(e) = &self.economics {
            e.check()?;
        }
        self.draw_control.check(self.economics.as_ref())?;
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
    use super::super::TWIN_OFFSET;
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
