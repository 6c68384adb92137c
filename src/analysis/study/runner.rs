//! Running variants into the study's layout: one variant ([`run_variant`], what a remote
//! task calls), or all of them on local worker threads ([`run_study`]), then the summary.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use anyhow::{Context, Result};

use super::plan::{Study, Variant};
use super::summary::{write_summary, SummaryRow};
use crate::engine::Engine;
use crate::output::dataset::{remove_leftovers, HiveLayout};
use crate::output::run::write_tables;
use crate::output::{write_atomic, Manifest};

/// The tables of every variant in the dataset.
pub use crate::output::run::DATASET_TABLES as TABLES;

/// The marker of a complete variant, in its state directory; it holds the variant's hash.
pub const SUCCESS: &str = "_SUCCESS";

/// Where a study writes, under its output directory `DIR`.
#[derive(Debug, Clone)]
pub struct Layout {
    /// `DIR`.
    pub dir: PathBuf,
    /// The `study=` value.
    pub study: String,
}

impl Layout {
    /// The layout of `study` under `dir`.
    pub fn new(dir: &Path, study: &Study) -> Layout {
        Layout {
            dir: dir.to_path_buf(),
            study: study.name.clone(),
        }
    }

    /// `DIR/dataset/<table>/study=<name>`: the root of a table's variants.
    pub fn table_root(&self, table: &str) -> PathBuf {
        self.dir
            .join("dataset")
            .join(table)
            .join(format!("study={}", self.study))
    }

    /// `DIR/variants/<variant>`: its `_SUCCESS`, `summary.json` and `manifest.json`.
    pub fn state(&self, variant: &str) -> PathBuf {
        self.dir.join("variants").join(variant)
    }

    /// `DIR/summary.parquet`.
    pub fn summary(&self) -> PathBuf {
        self.dir.join("summary.parquet")
    }

    /// The Parquet files of a variant's table in period order (by partition, then by file
    /// name), each with its period when its directory holds one period (`period=N`: the
    /// files have no `period` column) and `None` under `period_group=` (they do); none when
    /// the variant wrote no rows of it.
    pub fn partition_files(
        &self,
        table: &str,
        variant: &str,
    ) -> Result<Vec<(PathBuf, Option<i64>)>> {
        let dir = self.table_root(table).join(format!("scenario={variant}"));
        let Ok(entries) = std::fs::read_dir(&dir) else {
            return Ok(Vec::new());
        };
        let mut parts = Vec::new();
        for e in entries.flatten() {
            let n = e.file_name().to_string_lossy().into_owned();
            let (key, single) = match (n.strip_prefix("period="), n.strip_prefix("period_group=")) {
                (Some(k), _) => (k, true),
                (_, Some(k)) => (k, false),
                _ => continue,
            };
            let first: i64 = key
                .parse()
                .with_context(|| format!("{}: not a period partition", e.path().display()))?;
            parts.push((first, e.path(), single));
        }
        parts.sort_by_key(|p| p.0);
        let mut files = Vec::new();
        for (first, dir, single) in parts {
            let mut in_dir: Vec<PathBuf> = std::fs::read_dir(&dir)
                .with_context(|| dir.display().to_string())?
                .flatten()
                .map(|e| e.path())
                .filter(|f| f.extension().is_some_and(|x| x == "parquet"))
                .collect();
            in_dir.sort();
            files.extend(in_dir.into_iter().map(|f| (f, single.then_some(first))));
        }
        Ok(files)
    }

    /// Whether the variant is complete: its `_SUCCESS` holds its hash.
    pub fn is_complete(&self, v: &Variant) -> bool {
        std::fs::read_to_string(self.state(&v.name).join(SUCCESS)).is_ok_and(|h| h.trim() == v.hash)
    }
}

/// What became of a variant.
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome {
    /// Already complete (its `_SUCCESS` holds its hash): not run again.
    Skipped,
    /// Run now, in this many seconds of engine time.
    Ran(f64),
}

/// Runs one variant into the layout unless it is complete. The order makes a kill at any
/// point safe: the old `_SUCCESS` files go first, each table's partitions are swapped in
/// whole (`output::dataset`) and marked with a `_SUCCESS` of their own, and the variant's
/// `_SUCCESS` (with the hash), the one that counts, is written last, atomically, after
/// `summary.json` and `manifest.json`. `progress` gets (periods done, periods).
pub fn run_variant(
    layout: &Layout,
    v: &Variant,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Outcome> {
    if layout.is_complete(v) {
        return Ok(Outcome::Skipped);
    }
    let state = layout.state(&v.name);
    let success = state.join(SUCCESS);
    let partitions: Vec<PathBuf> = TABLES
        .iter()
        .map(|t| layout.table_root(t).join(format!("scenario={}", v.name)))
        .collect();
    for m in std::iter::once(success.clone()).chain(partitions.iter().map(|p| p.join(SUCCESS))) {
        if m.exists() {
            std::fs::remove_file(&m).with_context(|| m.display().to_string())?;
        }
    }
    let loaded = v
        .load()
        .map_err(|p| anyhow::anyhow!("variant {}: {}", v.name, p.join("\n")))?;
    let scene = &loaded.scene;
    let started = Instant::now();
    let mut out = Engine::with_plan(scene, &v.scenario, v.plan(scene)?)
        .with_trace(&loaded.trace)
        .run(progress);
    let wall_s = started.elapsed().as_secs_f64();
    let row = SummaryRow::new(
        &v.name,
        &v.hash,
        v.seed,
        v.values.clone(),
        scene,
        &out,
        wall_s,
    );
    let manifest = Manifest::new(
        format!("caveflow study --variant {}", v.name),
        &v.scenario,
        loaded.inputs.clone(),
        &out,
        rayon::current_num_threads(),
        wall_s,
    );
    let mut on = v.scenario.clone();
    on.outputs.hive = true;
    let hive = HiveLayout {
        scenario: v.name.clone(),
        ..HiveLayout::new(&on, &v.name, scene.periods.len()).expect("hive on")
    };
    for name in TABLES {
        remove_leftovers(&layout.table_root(name), &v.name)?;
    }
    write_tables(
        None,
        &|name: &str| layout.table_root(name),
        Some(&hive),
        scene,
        &mut out,
    )?;
    // Each table's partitions marked too, for readers that look for a `_SUCCESS` beside
    // them (Spark's convention; Parquet readers skip files named `_*`).
    for p in partitions.iter().filter(|p| p.is_dir()) {
        write_atomic(&p.join(SUCCESS), format!("{}\n", v.hash).as_bytes())?;
    }
    std::fs::create_dir_all(&state).with_context(|| state.display().to_string())?;
    write_atomic(
        &state.join("summary.json"),
        serde_json::to_string_pretty(&row)?.as_bytes(),
    )?;
    manifest.write(&state.join("manifest.json"))?;
    write_atomic(&success, format!("{}\n", v.hash).as_bytes())?;
    Ok(Outcome::Ran(wall_s))
}

/// What a study run did.
#[derive(Debug, Default)]
pub struct StudyReport {
    /// Variants run now, with their engine time (s).
    pub ran: Vec<(String, f64)>,
    /// Variants already complete.
    pub skipped: Vec<String>,
    /// Variants that failed, with why.
    pub failed: Vec<(String, String)>,
    /// The rows of `summary.parquet`: every complete variant.
    pub rows: Vec<SummaryRow>,
}

/// Events of a study run, for a progress display.
pub trait Progress: Sync {
    /// `n` more periods of some variant are done.
    fn periods(&self, n: u64);
    /// A variant is finished (`None`: it failed).
    fn finished(&self, name: &str, outcome: Option<&Outcome>);
}

/// The threads of each worker when `jobs` workers share the machine: max(1, cores / jobs).
pub fn default_threads(jobs: usize) -> usize {
    (std::thread::available_parallelism().map_or(1, |n| n.get()) / jobs.max(1)).max(1)
}

/// A rayon pool of `threads` threads: a worker's own cores, in which a variant's parallel
/// loops run (`pool.install`).
pub fn worker_pool(threads: usize) -> Result<rayon::ThreadPool> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads.max(1))
        .build()
        .context("thread pool")
}

/// Runs every variant that is not complete on `jobs` workers, each a thread that runs its
/// variants inside its own rayon pool of `threads` threads (so a worker is a fixed number
/// of cores, as a cluster task is), then writes `summary.parquet` from the complete
/// variants. A failed variant does not stop the others.
pub fn run_study(
    study: &Study,
    layout: &Layout,
    jobs: usize,
    threads: usize,
    progress: &dyn Progress,
) -> Result<StudyReport> {
    let next = AtomicUsize::new(0);
    let report = Mutex::new(StudyReport::default());
    let workers = jobs.max(1).min(study.variants.len().max(1));
    let pools = (0..workers)
        .map(|_| worker_pool(threads))
        .collect::<Result<Vec<_>>>()?;
    std::thread::scope(|s| {
        for pool in &pools {
            let (next, report) = (&next, &report);
            s.spawn(move || loop {
                let k = next.fetch_add(1, Ordering::SeqCst);
                let Some(v) = study.variants.get(k) else {
                    break;
                };
                let mut last = 0usize;
                let r = pool.install(|| {
                    run_variant(layout, v, &mut |done, _| {
                        progress.periods(done.saturating_sub(last) as u64);
                        last = done.max(last);
                    })
                });
                let mut rep = report.lock().expect("no worker panics holding it");
                match r {
                    Ok(o) => {
                        progress.finished(&v.name, Some(&o));
                        match o {
                            Outcome::Skipped => rep.skipped.push(v.name.clone()),
                            Outcome::Ran(t) => rep.ran.push((v.name.clone(), t)),
                        }
                    }
                    Err(e) => {
                        progress.finished(&v.name, None);
                        rep.failed
                            .push((v.name.clone(), crate::analysis::error_text(e.as_ref())));
                    }
                }
            });
        }
    });
    let mut report = report.into_inner().expect("workers done");
    report.rows = write_study_summary(study, layout)?;
    Ok(report)
}

/// The `scenario=` directories of the dataset that no variant of the study names (left by
/// an earlier version of the study file): they are kept, and a reader of the whole
/// dataset sees them, so the CLI names them.
pub fn stale_variants(study: &Study, layout: &Layout) -> Vec<String> {
    let mut stale = std::collections::BTreeSet::new();
    for t in TABLES {
        let Ok(entries) = std::fs::read_dir(layout.table_root(t)) else {
            continue;
        };
        for e in entries.flatten() {
            let n = e.file_name().to_string_lossy().into_owned();
            if let Some(v) = n.strip_prefix("scenario=") {
                if study.variant(v).is_none() {
                    stale.insert(v.to_string());
                }
            }
        }
    }
    stale.into_iter().collect()
}

/// Writes `summary.parquet` from the `summary.json` of every complete variant, in the
/// plan's order. Returns the rows.
pub fn write_study_summary(study: &Study, layout: &Layout) -> Result<Vec<SummaryRow>> {
    let mut rows = Vec::new();
    for v in study.variants.iter().filter(|v| layout.is_complete(v)) {
        let p = layout.state(&v.name).join("summary.json");
        let text = std::fs::read_to_string(&p).with_context(|| p.display().to_string())?;
        rows.push(serde_json::from_str(&text).with_context(|| p.display().to_string())?);
    }
    std::fs::create_dir_all(&layout.dir).with_context(|| layout.dir.display().to_string())?;
    write_summary(&layout.summary(), &study.columns, &rows)?;
    Ok(rows)
}
