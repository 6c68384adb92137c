//! A study expanded into its variants: names, `--set` lists, input files and content
//! hashes (`caveflow study --plan` prints it).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use serde_json::json;

use super::spec::{StudyError, StudyFile, StudyProblems};
use crate::engine::{EngineError, ResolvedResolution, RunPlan};
use crate::model::load::{load_scene, LoadedScene};
use crate::model::scenario::ScenarioError;
use crate::model::{Scenario, Scene};
use crate::output::dataset::partition_value;

/// The input roles an alternative may swap, as `inputs.<role>` of the scenario.
pub const INPUT_ROLES: [&str; 6] = [
    "blocks",
    "drawpoints",
    "drawbells",
    "schedule",
    "periods",
    "trace",
];

/// One swept value of a variant, for the summary table.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(untagged)]
pub enum Swept {
    /// A number (grids of integers and floats).
    Number(f64),
    /// Anything else, as text (an alternative's name, a string or boolean grid value).
    Text(String),
}

/// One variant: the base scenario with its `--set` list, its seed and its content hash.
#[derive(Debug, Clone)]
pub struct Variant {
    /// Name, unique in the study: the `scenario=` partition value.
    pub name: String,
    /// Content hash (SHA-256, hex) of the resolved scenario (input paths and output
    /// settings that only place files left out), each input file's SHA-256, the seed, the
    /// periods kept and caveflow's version ([`variant_hash`]).
    pub hash: String,
    /// The overrides on the base scenario, in `run --set` form.
    pub sets: Vec<String>,
    /// The seed.
    pub seed: u64,
    /// The swept values: one per dimension (summary column name → value).
    pub values: Vec<(String, Swept)>,
    /// The resolved scenario.
    pub scenario: Scenario,
    /// The resolution the variant runs at, as given (a case's `case_resolution`); None:
    /// the one its scenario resolves to.
    pub resolution: Option<ResolvedResolution>,
    /// Input role → (path, SHA-256).
    pub inputs: BTreeMap<String, (PathBuf, String)>,
    /// Only the first N periods (the study's `keep_periods`).
    pub keep_periods: Option<usize>,
}

/// A study expanded: its variants in order (the first dimension varies slowest).
#[derive(Debug, Clone)]
pub struct Study {
    /// The study file.
    pub file: PathBuf,
    /// The `study=` partition value.
    pub name: String,
    /// The base scenario file.
    pub scenario: PathBuf,
    /// The summary columns of the swept dimensions, in order.
    pub columns: Vec<String>,
    /// The variants.
    pub variants: Vec<Variant>,
}

/// One option of a dimension: its label in variant names, its overrides, its value and
/// its resolution (a case's, when the study gives one).
struct Choice {
    label: String,
    sets: Vec<String>,
    value: Swept,
    resolution: Option<ResolvedResolution>,
}

/// Flattens `[grid]` into dotted keys; the leaves must be arrays.
fn flatten(prefix: &str, t: &toml::Table, out: &mut Vec<(String, toml::Value)>) {
    for (k, v) in t {
        let key = if prefix.is_empty() {
            k.clone()
        } else {
            format!("{prefix}.{k}")
        };
        match v {
            toml::Value::Table(inner) => flatten(&key, inner, out),
            v => out.push((key, v.clone())),
        }
    }
}

/// A value as it appears in a variant name.
fn label_value(v: &toml::Value) -> String {
    match v {
        toml::Value::String(s) => s.clone(),
        v => v.to_string(),
    }
}

/// A scenario problem caused by a `--set` the study made (the base scenario alone has been
/// checked), attributed to the study key.
fn scenario_problem(file: &Path, key: &str, e: ScenarioError) -> StudyError {
    match e {
        ScenarioError::Parse { rule, message, .. } => StudyError::new(file, key, rule, message),
        e => StudyError::new(file, key, e.rule(), e.to_string()),
    }
}

impl Study {
    /// Reads a study file and expands it: every grid value and every variant is checked by
    /// the scenario's own machinery (`Scenario::load` with the variant's `--set` list), and
    /// every input file is hashed. The tables themselves are not read here (see
    /// [`Study::validate`]). Every problem is returned.
    pub fn expand(file: &Path) -> Result<Study, StudyProblems> {
        let spec = StudyFile::read(file)?;
        // Absolute, so that the plan's paths hold from any working directory.
        let dir = match file.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        let dir = &std::path::absolute(dir).unwrap_or(dir.to_path_buf());
        let mut problems = Vec::new();
        let name = spec.name.clone().unwrap_or_else(|| {
            file.file_stem()
                .map_or("study".into(), |s| s.to_string_lossy().into_owned())
        });
        if partition_value(&name) != name || name.starts_with('.') {
            problems.push(StudyError::new(
                file,
                "name",
                "bad-name",
                format!("`{name}` must be letters, digits, `.`, `_` and `-` (not starting with `.`): it names a directory"),
            ));
        }
        let scenario = dir.join(&spec.scenario);
        // The base scenario alone, then with the fixed overrides.
        if let Err(e) = Scenario::load(&scenario, &[]) {
            problems.push(StudyError::new(file, "scenario", e.rule(), e.to_string()));
            return Err(StudyProblems(problems));
        }
        if let Err(e) = Scenario::load(&scenario, &spec.set) {
            problems.push(scenario_problem(file, "set", e));
            return Err(StudyProblems(problems));
        }

        let mut dims: Vec<(String, Vec<Choice>)> = Vec::new();
        // Grids.
        let mut grid = Vec::new();
        flatten("", &spec.grid, &mut grid);
        let last = |k: &str| k.rsplit('.').next().unwrap_or(k).to_string();
        for (key, values) in &grid {
            let skey = format!("grid.{key}");
            let toml::Value::Array(values) = values else {
                problems.push(StudyError::new(
                    file,
                    &skey,
                    "grid-not-array",
                    format!(
                        "a grid is an array of the values to run, e.g. [0.6, 0.8]; got {values}"
                    ),
                ));
                continue;
            };
            if values.is_empty() {
                problems.push(StudyError::new(
                    file,
                    &skey,
                    "empty-grid",
                    "the grid has no values: give at least one",
                ));
                continue;
            }
            // The short name (last segment) labels variants unless two grids share it.
            let short = if grid.iter().filter(|(k, _)| last(k) == last(key)).count() > 1 {
                key.clone()
            } else {
                last(key)
            };
            let mut choices = Vec::new();
            for v in values {
                let set = format!("{key}={v}");
                let mut sets = spec.set.clone();
                sets.push(set.clone());
                match Scenario::load(&scenario, &sets) {
                    Ok(_) => choices.push(Choice {
                        label: format!("{short}-{}", label_value(v)),
                        sets: vec![set],
                        value: match v {
                            toml::Value::Integer(i) => Swept::Number(*i as f64),
                            toml::Value::Float(x) => Swept::Number(*x),
                            v => Swept::Text(label_value(v)),
                        },
                        resolution: None,
                    }),
                    Err(e) => problems.push(scenario_problem(file, &format!("{skey} = {v}"), e)),
                }
            }
            dims.push((key.clone(), choices));
        }
        // Named alternatives.
        for (dim, alts) in &spec.alternatives {
            let akey = format!("alternatives.{dim}");
            if alts.is_empty() {
                problems.push(StudyError::new(
                    file,
                    &akey,
                    "empty-grid",
                    "no alternatives: give at least one (`base = {}` keeps the scenario's tables)",
                ));
                continue;
            }
            let mut choices = Vec::new();
            for (alt, roles) in alts {
                let mut sets = Vec::new();
                for (role, path) in roles {
                    let key = format!("{akey}.{alt}.{role}");
                    if !INPUT_ROLES.contains(&role.as_str()) {
                        problems.push(StudyError::new(
                            file,
                            &key,
                            "unknown-key",
                            format!(
                                "an alternative swaps input tables; `{role}` is not one of: {}",
                                INPUT_ROLES.join(", ")
                            ),
                        ));
                        continue;
                    }
                    // Absolute: the scenario resolves a relative path against its own folder.
                    let path = dir.join(path);
                    if !path.is_file() {
                        problems.push(StudyError::new(
                            file,
                            &key,
                            "missing-table",
                            format!("{} does not exist", path.display()),
                        ));
                        continue;
                    }
                    let p = toml::Value::String(path.display().to_string());
                    sets.push(format!("inputs.{role}={p}"));
                }
                choices.push(Choice {
                    label: format!("{dim}-{alt}"),
                    sets,
                    value: Swept::Text(alt.clone()),
                    resolution: None,
                });
            }
            dims.push((dim.clone(), choices));
        }
        // Cases: explicit variants, each its own overrides.
        if let Some(cases) = spec.cases.as_ref().filter(|c| !c.is_empty()) {
            let mut choices = Vec::new();
            for (case, sets) in cases {
                let ckey = format!("cases.{case}");
                if partition_value(case) != *case || case.starts_with('.') {
                    problems.push(StudyError::new(
                        file,
                        &ckey,
                        "bad-name",
                        format!("`{case}` must be letters, digits, `.`, `_` and `-` (not starting with `.`): it names variants"),
                    ));
                    continue;
                }
                let all: Vec<String> = spec.set.iter().chain(sets).cloned().collect();
                match Scenario::load(&scenario, &all) {
                    Ok(_) => choices.push(Choice {
                        label: case.clone(),
                        sets: sets.clone(),
                        value: Swept::Text(case.clone()),
                        resolution: spec.case_resolution.get(case).copied(),
                    }),
                    Err(e) => problems.push(scenario_problem(file, &ckey, e)),
                }
            }
            dims.push(("case".into(), choices));
        } else if spec.cases.is_some() {
            problems.push(StudyError::new(
                file,
                "cases",
                "empty-grid",
                "no cases: give at least one, or leave `[cases]` out",
            ));
        }
        problems.extend(case_resolution_problems(file, &spec));
        if spec.keep_periods == Some(0) {
            problems.push(StudyError::new(
                file,
                "keep_periods",
                "setting-range",
                "keep_periods must be at least 1 (the periods of every variant kept)",
            ));
        }
        // Seeds.
        if let Some(seeds) = &spec.seeds {
            if seeds.is_empty() {
                problems.push(StudyError::new(
                    file,
                    "seeds",
                    "empty-grid",
                    "no seeds: give at least one, or leave `seeds` out to run the scenario's own",
                ));
            } else {
                let choices = seeds
                    .iter()
                    .map(|s| Choice {
                        label: format!("seed-{s}"),
                        sets: vec![format!("seed={s}")],
                        value: Swept::Number(*s as f64),
                        resolution: None,
                    })
                    .collect();
                dims.push(("seed".into(), choices));
            }
        }
        if !problems.is_empty() {
            return Err(StudyProblems(problems));
        }

        // The cartesian product, first dimension slowest.
        let mut columns: Vec<String> = dims.iter().map(|(k, _)| k.clone()).collect();
        columns.retain(|c| c != "seed");
        let total: usize = dims.iter().map(|(_, c)| c.len()).product();
        let mut variants = Vec::with_capacity(total);
        let mut names = BTreeSet::new();
        for n in 0..total {
            let mut rest = n;
            let mut pick = vec![0; dims.len()];
            for (d, (_, choices)) in dims.iter().enumerate().rev() {
                pick[d] = rest % choices.len();
                rest /= choices.len();
            }
            let mut sets = spec.set.clone();
            let mut labels = Vec::new();
            let mut values = Vec::new();
            let mut resolution = None;
            for (d, (key, choices)) in dims.iter().enumerate() {
                let c = &choices[pick[d]];
                sets.extend(c.sets.iter().cloned());
                resolution = resolution.or(c.resolution);
                labels.push(c.label.clone());
                if key != "seed" {
                    values.push((key.clone(), c.value.clone()));
                }
            }
            let name = if labels.is_empty() {
                "base".to_string()
            } else {
                partition_value(&labels.join("_"))
            };
            let sc = match Scenario::load(&scenario, &sets) {
                Ok(sc) => sc,
                Err(e) => {
                    problems.push(scenario_problem(file, &format!("variant {name}"), e));
                    continue;
                }
            };
            if !names.insert(name.clone()) {
                problems.push(StudyError::new(
                    file,
                    format!("variant {name}"),
                    "bad-name",
                    "two variants have this name (values that differ only in characters a directory name cannot hold)",
                ));
                continue;
            }
            let mut inputs = BTreeMap::new();
            for (role, path) in input_paths(&sc) {
                match std::fs::read(&path) {
                    Ok(bytes) => {
                        inputs.insert(role.to_string(), (path, crate::io::sha256_hex(&bytes)));
                    }
                    Err(e) => problems.push(StudyError::new(
                        file,
                        format!("variant {name}: inputs.{role}"),
                        "missing-table",
                        format!("{}: {e}", path.display()),
                    )),
                }
            }
            let hash = variant_hash(
                &sc,
                resolution.as_ref(),
                &inputs,
                spec.keep_periods,
                VERSION,
            );
            variants.push(Variant {
                name,
                hash,
                sets,
                seed: sc.seed,
                values,
                scenario: sc,
                resolution,
                inputs,
                keep_periods: spec.keep_periods,
            });
        }
        // Identical problems of many variants (a base table missing) once.
        let mut seen = BTreeSet::new();
        problems.retain(|p| seen.insert((p.rule, p.message.clone())));
        if !problems.is_empty() {
            return Err(StudyProblems(problems));
        }
        Ok(Study {
            file: file.to_path_buf(),
            name,
            scenario,
            columns,
            variants,
        })
    }

    /// The variant of this name.
    pub fn variant(&self, name: &str) -> Option<&Variant> {
        self.variants.iter().find(|v| v.name == name)
    }

    /// Reads and checks every table of the named variants (all when `only` is None) and
    /// whether the method holds for each scene (`RunPlan`), as `caveflow validate` would;
    /// returns every problem, each under the variant's name.
    pub fn validate(&self, only: Option<&str>) -> Result<(), StudyProblems> {
        let mut problems = Vec::new();
        let mut seen = BTreeSet::new();
        for v in self
            .variants
            .iter()
            .filter(|v| only.is_none_or(|n| n == v.name))
        {
            if let Err(e) = v.load() {
                for message in e {
                    if seen.insert(message.clone()) {
                        problems.push(StudyError::new(
                            &self.file,
                            format!("variant {}", v.name),
                            "bad-variant",
                            message,
                        ));
                    }
                }
            }
        }
        if problems.is_empty() {
            Ok(())
        } else {
            Err(StudyProblems(problems))
        }
    }

    /// The plan as JSON: what `caveflow study --plan` prints, and all a driver needs to run
    /// the variants elsewhere (`caveflow study STUDY.toml --variant NAME` per variant).
    pub fn plan_json(&self) -> serde_json::Value {
        let variants: Vec<_> = self
            .variants
            .iter()
            .map(|v| {
                json!({
                    "name": v.name,
                    "hash": v.hash,
                    "sets": v.sets,
                    "seed": v.seed,
                    "resolution": v.resolution,
                    "values": v.values.iter().map(|(k, x)| (k.clone(), json!(x))).collect::<serde_json::Map<_, _>>(),
                    "inputs": v.inputs.iter().map(|(r, (p, _))| (r.clone(), json!(p))).collect::<serde_json::Map<_, _>>(),
                    "input_sha256": v.inputs.iter().map(|(r, (_, h))| (r.clone(), json!(h))).collect::<serde_json::Map<_, _>>(),
                })
            })
            .collect();
        json!({
            "study": self.name,
            "file": self.file,
            "keep_periods": self.variants.first().and_then(|v| v.keep_periods),
            "scenario": self.scenario,
            "columns": self.columns,
            "variants": variants,
        })
    }
}

impl Variant {
    /// Loads the variant's scene and checks that the method holds for it; the problems as
    /// text otherwise. The input files must still be the ones hashed.
    pub fn load(&self) -> Result<LoadedScene, Vec<String>> {
        let mut loaded = load_scene(&self.scenario)
            .map_err(|p| p.0.iter().map(|p| p.to_string()).collect::<Vec<_>>())?;
        if let Some(n) = self.keep_periods {
            loaded.scene.keep_periods(n);
        }
        for f in &loaded.inputs {
            if self
                .inputs
                .get(&f.role)
                .is_some_and(|(_, h)| *h != f.sha256)
            {
                return Err(vec![format!(
                    "{}: changed since the study was expanded (hash {} now)",
                    f.path.display(),
                    f.sha256
                )]);
            }
        }
        self.plan(&loaded.scene).map_err(|e| vec![e.to_string()])?;
        Ok(loaded)
    }

    /// The variant's run plan on its loaded `scene`: at its own resolution when it carries
    /// one ([`RunPlan::at`]), else at the one its scenario resolves to ([`RunPlan::new`]).
    pub fn plan(&self, scene: &Scene) -> Result<RunPlan, EngineError> {
        match self.resolution {
            Some(r) => RunPlan::at(scene, &self.scenario, r),
            None => RunPlan::new(scene, &self.scenario),
        }
    }
}

/// The scenario's input files by role.
fn input_paths(sc: &Scenario) -> Vec<(&'static str, PathBuf)> {
    let i = &sc.inputs;
    let mut v = vec![
        ("blocks", i.blocks.clone()),
        ("drawpoints", i.drawpoints.clone()),
        ("schedule", i.schedule.clone()),
    ];
    for (role, p) in [
        ("drawbells", &i.drawbells),
        ("periods", &i.periods),
        ("trace", &i.trace),
    ] {
        if let Some(p) = p {
            v.push((role, p.clone()));
        }
    }
    v
}

/// caveflow's version, which every variant's hash covers ([`variant_hash`]).
pub const VERSION: &str = env!("CARGO_PKG_VERSION");

/// The content hash of a variant: SHA-256 of the resolved scenario's JSON with the input
/// paths replaced by their roles and the output directory and scenario name left out (they
/// place files, they change no result), then the resolution it carries (when it carries
/// one, [`Variant::resolution`]), each input role's SHA-256, the seed, the
/// periods kept (when not all) and `version`, caveflow's ([`VERSION`]): another version may
/// compute another result, so a variant is never skipped for one an older binary made.
/// The same tables under another path, or the study moved, give the same hash; one
/// changed byte in a table gives another.
pub fn variant_hash(
    sc: &Scenario,
    resolution: Option<&ResolvedResolution>,
    inputs: &BTreeMap<String, (PathBuf, String)>,
    keep_periods: Option<usize>,
    version: &str,
) -> String {
    let mut s = sc.clone();
    s.inputs.blocks = "blocks".into();
    s.inputs.drawpoints = "drawpoints".into();
    s.inputs.schedule = "schedule".into();
    s.inputs.drawbells = s.inputs.drawbells.as_ref().map(|_| "drawbells".into());
    s.inputs.periods = s.inputs.periods.as_ref().map(|_| "periods".into());
    s.inputs.trace = s.inputs.trace.as_ref().map(|_| "trace".into());
    s.outputs.dir = PathBuf::new();
    s.outputs.scenario_name = None;
    s.outputs.charts = false;
    let mut text = serde_json::to_string(&s).expect("a scenario serialises");
    if let Some(r) = resolution {
        let r = serde_json::to_string(r).expect("a resolution serialises");
        text.push_str(&format!("\nresolution={r}"));
    }
    for (role, (_, sha)) in inputs {
        text.push_str(&format!("\n{role}={sha}"));
    }
    text.push_str(&format!("\nseed={}", sc.seed));
    if let Some(n) = keep_periods {
        text.push_str(&format!("\nkeep_periods={n}"));
    }
    text.push_str(&format!("\ncaveflow={version}"));
    crate::io::sha256_hex(text.as_bytes())
}

/// The problems of `case_resolution`: an entry that names no case (`unknown-key`), a value
/// that is not finite, h, spacing or increment not above 0, or `max_marker_move` below 0
/// (`setting-range`).
fn case_resolution_problems(file: &Path, spec: &StudyFile) -> Vec<StudyError> {
    let mut problems = Vec::new();
    for (case, r) in &spec.case_resolution {
        let key = format!("case_resolution.{case}");
        if !spec.cases.as_ref().is_some_and(|c| c.contains_key(case)) {
            problems.push(StudyError::new(
                file,
                &key,
                "unknown-key",
                format!("`{case}` is not a case of `[cases]`: a resolution is given to a case"),
            ));
        }
        for (name, v, least) in [
            ("layer_thickness", r.layer_thickness, None),
            ("marker_spacing", r.marker_spacing, None),
            ("draw_increment", r.draw_increment, None),
            ("max_marker_move", r.max_marker_move, Some(0.0)),
        ] {
            let ok = v.is_finite() && least.map_or(v > 0.0, |l| v >= l);
            if !ok {
                let rule = if least.is_some() {
                    "at least 0"
                } else {
                    "above 0"
                };
                problems.push(StudyError::new(
                    file,
                    format!("{key}.{name}"),
                    "setting-range",
                    format!("{v} must be finite and {rule}"),
                ));
            }
        }
    }
    problems
}
