//! `caveflow study`: expand a study, run its variants (all, or one), write the summary.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::Args;

use crate::analysis::study::runner::{
    default_threads, run_variant, stale_variants, worker_pool, write_study_summary, Progress,
};
use crate::analysis::study::{run_study, write_study_report, Layout, Outcome, Study};

/// `caveflow study`.
#[derive(Debug, Args)]
pub struct StudyArgs {
    /// The study file (TOML; see `analysis::study`).
    pub study: PathBuf,
    /// Output directory: `dataset/`, `variants/` and `summary.parquet`.
    #[arg(long, default_value = "study")]
    pub out: PathBuf,
    /// Workers: variants run at once (`analysis::study`, "In parallel").
    #[arg(long, default_value_t = 2, value_name = "N")]
    pub jobs: usize,
    /// Threads of each worker: each variant runs in its own pool of T threads (default:
    /// max(1, cores / N); with --variant, every core).
    #[arg(long, value_name = "T")]
    pub threads: Option<usize>,
    /// Print the expanded study as JSON (name, hash, --set list, inputs, seed of every
    /// variant) and run nothing. The study file is checked, not each variant's tables.
    #[arg(long)]
    pub plan: bool,
    /// Run only this variant into the layout (what a cluster task calls); no summary.
    #[arg(long, value_name = "NAME", conflicts_with = "plan")]
    pub variant: Option<String>,
    /// Write `summary.parquet` from the complete variants and run none; exit 1, listing
    /// them, when some are not complete (what a cluster driver calls after its tasks).
    #[arg(long, conflicts_with_all = ["plan", "variant"])]
    pub summary_only: bool,
}

/// The progress bar (on a terminal only) and one line per finished variant.
struct Bar {
    bar: indicatif::ProgressBar,
    terminal: bool,
}

impl Progress for Bar {
    fn periods(&self, n: u64) {
        self.bar.inc(n);
    }
    fn finished(&self, name: &str, outcome: Option<&Outcome>) {
        let line = match outcome {
            Some(Outcome::Skipped) => format!("{name}: complete, skipped"),
            Some(Outcome::Ran(s)) => format!("{name}: ran in {s:.1} s"),
            None => format!("{name}: failed"),
        };
        if self.terminal {
            self.bar.println(line);
        } else {
            eprintln!("{line}");
        }
    }
}

/// Runs `caveflow study`.
pub fn study_cmd(a: StudyArgs) -> Result<ExitCode> {
    let study = Study::expand(&a.study)?;
    if a.jobs == 0 {
        return Err(super::UsageError("--jobs must be at least 1".into()).into());
    }
    if a.threads == Some(0) {
        return Err(super::UsageError("--threads must be at least 1".into()).into());
    }
    if a.summary_only {
        return summary_only(&a, &study);
    }
    if a.plan {
        // The expansion only (the study file's keys, values and tables): each variant's
        // tables are checked by its own run (exit 1), so that a driver runs the good ones.
        println!("{}", serde_json::to_string_pretty(&study.plan_json())?);
        return Ok(ExitCode::SUCCESS);
    }
    study.validate(a.variant.as_deref())?;
    let layout = Layout::new(&a.out, &study);
    if let Some(name) = &a.variant {
        let Some(v) = study.variant(name) else {
            let names: Vec<_> = study.variants.iter().map(|v| v.name.as_str()).collect();
            return Err(super::UsageError(format!(
                "no variant `{name}` in {}; variants: {}",
                a.study.display(),
                names.join(", ")
            ))
            .into());
        };
        let threads = a.threads.unwrap_or_else(|| default_threads(1));
        match worker_pool(threads)?.install(|| run_variant(&layout, v, &mut |_, _| {}))? {
            Outcome::Skipped => println!("{name}: complete ({}), skipped", v.hash),
            Outcome::Ran(s) => println!("{name}: ran in {s:.1} s ({})", v.hash),
        }
        return Ok(ExitCode::SUCCESS);
    }
    let terminal = std::io::stderr().is_terminal();
    let total = study
        .variants
        .iter()
        .filter(|v| !layout.is_complete(v))
        .count();
    let threads = a.threads.unwrap_or_else(|| default_threads(a.jobs));
    eprintln!(
        "study {}: {} variant(s), {} to run, {} worker(s) of {} thread(s)",
        study.name,
        study.variants.len(),
        total,
        a.jobs,
        threads
    );
    let bar = if terminal {
        // Periods of the variants to run; a variant's periods are known once it loads, so
        // the bar counts variants × the base scene's periods, close enough to pace it.
        let periods = study
            .variants
            .first()
            .map_or(0, |v| v.load().map_or(0, |l| l.scene.periods.len() as u64));
        super::progress(total as u64 * periods, "periods")
    } else {
        indicatif::ProgressBar::hidden()
    };
    let progress = Bar { bar, terminal };
    let report = run_study(&study, &layout, a.jobs, threads, &progress)?;
    progress.bar.finish_and_clear();
    let page = write_study_report(&study, &layout, &report.rows)?;
    println!(
        "{} ran, {} complete already, {} failed; wrote {} ({} rows), {} and {}",
        report.ran.len(),
        report.skipped.len(),
        report.failed.len(),
        layout.summary().display(),
        report.rows.len(),
        page.display(),
        layout.dir.join("dataset").display()
    );
    warn_stale(&study, &layout);
    if report.failed.is_empty() {
        Ok(ExitCode::SUCCESS)
    } else {
        for (name, why) in &report.failed {
            eprintln!("error: variant {name}: {why}");
        }
        Ok(ExitCode::from(2))
    }
}

/// Names the dataset's variants that the study no longer has (left by an earlier version
/// of the study file): kept, and seen by a reader of the whole dataset.
fn warn_stale(study: &Study, layout: &Layout) {
    let stale = stale_variants(study, layout);
    if !stale.is_empty() {
        eprintln!(
            "warning: {} holds variants this study no longer has (kept; remove them by hand if unwanted): {}",
            layout.dir.join("dataset").display(),
            stale.join(", ")
        );
    }
}

/// `caveflow study --summary-only`: the summary of the complete variants; none is run, so
/// a driver whose tasks missed a variant never runs it here by accident. Exit 1 (the
/// variants not complete listed) unless every variant is complete.
fn summary_only(a: &StudyArgs, study: &Study) -> Result<ExitCode> {
    let layout = Layout::new(&a.out, study);
    let missing: Vec<&str> = study
        .variants
        .iter()
        .filter(|v| !layout.is_complete(v))
        .map(|v| v.name.as_str())
        .collect();
    let rows = write_study_summary(study, &layout)?;
    let page = write_study_report(study, &layout, &rows)?;
    println!(
        "{} of {} variant(s) complete; wrote {} and {}",
        rows.len(),
        study.variants.len(),
        layout.summary().display(),
        page.display()
    );
    warn_stale(study, &layout);
    if missing.is_empty() {
        return Ok(ExitCode::SUCCESS);
    }
    eprintln!(
        "error: {} variant(s) not complete (no `_SUCCESS` with their hash in {}): {}",
        missing.len(),
        layout.dir.join("variants").display(),
        missing.join(", ")
    );
    Ok(ExitCode::from(1))
}
