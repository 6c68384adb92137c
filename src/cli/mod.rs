//! The command line: clap arguments become a validated scenario, then one of the commands
//! runs. Exit codes: 0 success, 1 invalid input (every problem listed), 2 any other error,
//! 3 a calibration whose fit did not lower the error.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand, ValueEnum};

use crate::engine::{Engine, EngineError, RunPlan};
use crate::model::demo::{self, DemoScale};
use crate::model::load::{load_scene, InputFile, LoadedScene};
use crate::model::scenario::ScenarioError;
use crate::model::{Scenario, Scene};
use crate::output;
use crate::output::run_dir::{write_run_dir, Checkpoints, RunDir};
use crate::schema;

#[cfg(feature = "analysis")]
mod backanalysis;
mod study;

/// caveflow: gravity flow of caved rock in block and panel caving mines (REBOP after
/// Pierce 2010). Give it a block model, drawpoints and a draw schedule; it predicts what
/// every drawpoint delivers, period by period.
#[derive(Debug, Parser)]
#[command(name = "caveflow", version, about, long_about = None)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Simulate draw: writes extraction.parquet, imz.parquet, drawn.parquet, markers/,
    /// charts/ and manifest.json into the output directory.
    Run(RunArgs),
    /// Check every input table and the scenario; list every problem with file, row, column
    /// and rule. Exits 1 if anything is wrong.
    Validate(InputArgs),
    /// Print the schema of a table (JSON: fields, types, units, descriptions), or write
    /// all of them.
    Schema(SchemaArgs),
    /// Write the synthetic Henderson-style demo panel (block model, drawpoints, periods,
    /// schedule, scenario.toml).
    Demo(DemoArgs),
    /// The speed–accuracy sweep: run one scene at a grid of resolutions around the default
    /// and a converged reference; write sweep.parquet and sweep.png (error against time).
    Sweep(SweepArgs),
    /// Run a scenario study: the variants of one scenario (grids over any key, swapped
    /// tables, seeds) in parallel into one Hive-partitioned dataset and summary.parquet;
    /// complete variants are skipped. --plan prints the variants as JSON.
    Study(study::StudyArgs),
    /// Compare a run's predictions with production records: write reconcile.parquet (bias,
    /// MAE, RMSE, correlation, tonnage-weighted error, dilution entry per drawpoint, zone
    /// and overall), reconcile_rows.parquet and report.html.
    #[cfg(feature = "analysis")]
    Reconcile(backanalysis::ReconcileArgs),
    /// Fit fragment-size factors per lithology (and optionally n1 and φ factors) to
    /// production records by running the engine many times; write calibration.json,
    /// calibrated.toml and profiles.svg.
    #[cfg(feature = "analysis")]
    Calibrate(backanalysis::CalibrateArgs),
}

/// Where the inputs come from: a scenario file, or the tables directly.
#[derive(Debug, Args)]
pub struct InputArgs {
    /// Scenario file (TOML). Optional when the tables are given with --blocks etc.
    pub scenario: Option<PathBuf>,
    /// Block model (Parquet, CSV or MassFlow CSV).
    #[arg(long)]
    pub blocks: Option<PathBuf>,
    /// Drawpoints (Parquet, CSV or MassFlow CSV).
    #[arg(long)]
    pub drawpoints: Option<PathBuf>,
    /// Drawbells (MassFlow BellName, DDWidth, DDHeight): opening widths.
    #[arg(long)]
    pub drawbells: Option<PathBuf>,
    /// Draw schedule: long (period, drawpoint, tonnes) or MassFlow wide.
    #[arg(long)]
    pub schedule: Option<PathBuf>,
    /// Periods table (period, name, days).
    #[arg(long)]
    pub periods: Option<PathBuf>,
    /// Trace points to follow through the draw (MassFlow's trace file: `x y z` rows, no
    /// header); each must lie inside the block model. `run` writes trace.parquet.
    #[arg(long)]
    pub trace: Option<PathBuf>,
    /// Override any scenario setting, e.g. --set resolution.layer_thickness=0.02
    /// (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub sets: Vec<String>,
}

/// `caveflow run`.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// Inputs.
    #[command(flatten)]
    pub input: InputArgs,
    /// Output directory (overrides outputs.dir).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Resume from the checkpoint in the output directory, if there is one made from the
    /// same inputs and scenario (otherwise start from the first period).
    #[arg(long)]
    pub resume: bool,
    /// Also write a checkpoint every N periods (0: only by time). It is removed once the
    /// outputs are written.
    #[arg(long, default_value_t = 0, value_name = "N")]
    pub checkpoint_every: usize,
    /// Write a checkpoint at the end of the first period that ends at least M minutes of
    /// wall time after the last one (0: never by time; default 5). A checkpoint of a large
    /// scene takes a fraction of a second, so by time it costs a few tenths of a percent of
    /// a run, whatever the length of the periods.
    #[arg(long, default_value_t = 5.0, value_name = "M")]
    pub checkpoint_minutes: f64,
    /// Run only the first N periods of the schedule (a trial run).
    #[arg(long, value_name = "N")]
    pub keep_periods: Option<usize>,
    /// Also write MassFlow's report layouts into massflow/ (outputs.massflow): the period
    /// extraction report, the marker and trace reports and the daily trace CSV.
    #[arg(long)]
    pub massflow_reports: bool,
    /// Also write VTK files for ParaView into vtk/ (outputs.vtk): IMZ disks, markers, free
    /// surface, IEZ and block model, with .pvd collections over the periods (the IMZ and the
    /// surface at outputs.vtk_periods, by default the sections' moments).
    #[arg(long)]
    pub vtk: bool,
    /// Print the run's account to stderr at the end: wall time per phase of the engine
    /// (IMZ growth, engulfing, grids, row selection, marker pass, crediting, mobilised
    /// sums, air gap, fill, period end) and of the outputs, and the work counters (updates,
    /// marker steps, candidate tests and hits, disk-cycles). Costs a counting pass per
    /// update; a run without it keeps no account.
    #[arg(long)]
    pub account: bool,
}

/// `caveflow schema`.
#[derive(Debug, Args)]
pub struct SchemaArgs {
    /// Table name (omit to list them).
    pub table: Option<String>,
    /// Write every schema as `<dir>/<table>.json` instead.
    #[arg(long, value_name = "DIR")]
    pub write: Option<PathBuf>,
}

/// Demo sizes.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum Scale {
    /// About 30 drawpoints, 24 monthly periods: seconds to run.
    Small,
    /// At least 400 drawpoints, 200 m columns, 10 years of daily draw: for benchmarks.
    Mine,
}

/// `caveflow demo`.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Size of the panel.
    #[arg(long, value_enum, default_value = "small")]
    pub scale: Scale,
    /// Directory to write into.
    #[arg(long, default_value = "demo")]
    pub out: PathBuf,
    /// Seed of the generator and of the scenario.
    #[arg(long, default_value_t = 42)]
    pub seed: u64,
    /// Also write synthetic production records (records.csv): a run of the demo with a
    /// hidden true Urad fragment size (0.15 m, not the stated 0.23 m) plus sampling noise.
    #[arg(long)]
    pub records: bool,
    /// Relative sampling noise σ of the records' grades and fragment sizes.
    #[arg(long, default_value_t = crate::analysis::records::DEMO_SIGMA, requires = "records")]
    pub records_sigma: f64,
    /// Seed of the records' sampling noise.
    #[arg(long, default_value_t = crate::analysis::records::DEMO_NOISE_SEED, requires = "records")]
    pub records_seed: u64,
}

/// `caveflow sweep`.
#[derive(Debug, Args)]
pub struct SweepArgs {
    /// Inputs (default: data/scenario.toml, the demo).
    #[command(flatten)]
    pub input: InputArgs,
    /// Output directory for sweep.parquet and sweep.png.
    #[arg(long, default_value = "sweep")]
    pub out: PathBuf,
    /// Keep only the first N periods of the schedule (a shorter scene for a quicker sweep).
    #[arg(long, value_name = "N")]
    pub keep_periods: Option<usize>,
    /// Multipliers of the default disk thickness h.
    #[arg(long, value_delimiter = ',', default_values_t = [2.0, 1.0, 0.5])]
    pub h: Vec<f64>,
    /// Multipliers of the default marker spacing.
    #[arg(long, value_delimiter = ',', default_values_t = [2.0, 1.0, 0.5])]
    pub spacing: Vec<f64>,
    /// Multipliers of the default draw increment.
    #[arg(long, value_delimiter = ',', default_values_t = [4.0, 1.0, 0.25])]
    pub increment: Vec<f64>,
    /// Multipliers h,spacing,increment of the converged reference run.
    #[arg(long, value_delimiter = ',', default_values_t = [0.5, 0.5, 0.25])]
    pub reference: Vec<f64>,
    /// Runs per point (the median wall time is kept).
    #[arg(long, default_value_t = 1)]
    pub repeats: usize,
    /// Accuracy target (grade RMSE, 0.01 = 1%): the automatic resolution for it is run too
    /// and marked on the chart (a target in the scenario comes first).
    #[arg(long, default_value_t = 0.01)]
    pub target: f64,
}

/// Arguments that cannot work together, or that the inputs contradict (invalid input
/// given on the command line: exit 1, like a bad table or a bad flag).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct UsageError(pub String);

/// Parses the command line and runs it.
pub fn main() -> Result<ExitCode> {
    // clap exits 2 on a bad flag; here invalid input, from the command line too, exits 1.
    // `--help` and `--version` are not errors: printed to stdout, exit 0.
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            e.print()?;
            return Ok(if e.use_stderr() {
                ExitCode::from(1)
            } else {
                ExitCode::SUCCESS
            });
        }
    };
    let r = match cli.command {
        Command::Run(a) => run(a),
        Command::Validate(a) => validate(a),
        Command::Schema(a) => schema_cmd(a),
        Command::Demo(a) => demo_cmd(a),
        Command::Sweep(a) => sweep_cmd(a),
        Command::Study(a) => study::study_cmd(a),
        #[cfg(feature = "analysis")]
        Command::Reconcile(a) => backanalysis::reconcile_cmd(a),
        #[cfg(feature = "analysis")]
        Command::Calibrate(a) => backanalysis::calibrate_cmd(a),
    };
    match r {
        // A bad scenario is invalid input, like a bad table: exit 1 (the problem names the
        // file, line, column and rule). So is a scene where the method fails (stability).
        Err(e)
            if e.downcast_ref::<ScenarioError>().is_some()
                || e.downcast_ref::<UsageError>().is_some()
                || e.downcast_ref::<crate::analysis::study::StudyProblems>()
                    .is_some()
                || matches!(e.downcast_ref(), Some(EngineError::Refused(_))) =>
        {
            eprintln!("error: {}", error_text(e.as_ref()));
            Ok(ExitCode::from(1))
        }
        r => r,
    }
}

pub use crate::analysis::error_text;

/// The scenario from the arguments: a file plus overrides, or defaults plus the tables
/// named on the command line.
pub fn scenario(a: &InputArgs) -> Result<Scenario> {
    let cwd = std::env::current_dir().context("current directory")?;
    let mut sc = match &a.scenario {
        Some(path) => Scenario::load(path, &a.sets)?,
        None => {
            if a.blocks.is_none() || a.drawpoints.is_none() || a.schedule.is_none() {
                return Err(UsageError(
                    "give a scenario file, or --blocks, --drawpoints and --schedule".into(),
                )
                .into());
            }
            Scenario::from_sets(&a.sets, &cwd)?
        }
    };
    let abs = |p: &PathBuf| {
        if p.is_relative() {
            cwd.join(p)
        } else {
            p.clone()
        }
    };
    if let Some(p) = &a.blocks {
        sc.inputs.blocks = abs(p);
    }
    if let Some(p) = &a.drawpoints {
        sc.inputs.drawpoints = abs(p);
    }
    if let Some(p) = &a.schedule {
        sc.inputs.schedule = abs(p);
    }
    if let Some(p) = &a.drawbells {
        sc.inputs.drawbells = Some(abs(p));
    }
    if let Some(p) = &a.periods {
        sc.inputs.periods = Some(abs(p));
    }
    if let Some(p) = &a.trace {
        sc.inputs.trace = Some(abs(p));
    }
    Ok(sc)
}

/// Applies `--keep-periods` (run, sweep, calibrate). Keeping 0 periods is invalid input:
/// prints why and returns false.
fn keep_periods(scene: &mut Scene, n: Option<usize>) -> bool {
    match n {
        Some(0) => {
            eprintln!("error: --keep-periods must be at least 1");
            false
        }
        Some(n) => {
            scene.keep_periods(n);
            true
        }
        None => true,
    }
}

/// Loads and validates; on problems prints them all and returns None.
fn load(sc: &Scenario) -> Option<LoadedScene> {
    match load_scene(sc) {
        Ok(l) => Some(l),
        Err(problems) => {
            eprintln!("{} problem(s) in the inputs:", problems.0.len());
            eprintln!("{problems}");
            None
        }
    }
}

fn validate(a: InputArgs) -> Result<ExitCode> {
    let sc = scenario(&a)?;
    let Some(l) = load(&sc) else {
        return Ok(ExitCode::from(1));
    };
    for w in &l.warnings {
        eprintln!("warning: {w}");
    }
    let s = &l.scene;
    match RunPlan::new(s, &sc) {
        Ok(plan) => plan
            .warnings()
            .iter()
            .for_each(|w| eprintln!("warning: {}", w.message)),
        Err(refused) => {
            eprintln!("error: {refused}");
            return Ok(ExitCode::from(1));
        }
    }
    println!(
        "ok: {} blocks ({} x {} x {} m), {} drawpoints, {} periods, {:.0} t scheduled{}",
        s.blocks.len(),
        s.blocks.size[0],
        s.blocks.size[1],
        s.blocks.size[2],
        s.drawpoints.len(),
        s.periods.len(),
        s.schedule.tonnes.iter().sum::<f64>(),
        match l.trace.len() {
            0 => String::new(),
            n => format!(", {n} trace points"),
        }
    );
    Ok(ExitCode::SUCCESS)
}

/// Runs `f` on a worker thread of rayon's global pool. The engine's parallel passes then
/// start from a worker, which takes its share of each pass, instead of from a thread that
/// waits while the pool's workers are woken for every pass: the mine scene's run takes
/// 0.97 times the wall time, with byte-identical outputs (`docs::resolution`, "Mine scale").
fn on_pool<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    rayon::join(f, || ()).0
}

fn run(a: RunArgs) -> Result<ExitCode> {
    let started = Instant::now();
    let mut sc = scenario(&a.input)?;
    if let Some(out) = &a.out {
        sc.outputs.dir = out.clone();
    }
    sc.outputs.massflow |= a.massflow_reports;
    sc.outputs.vtk |= a.vtk;
    if let Some(n) = a.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .context("thread pool")?;
    }
    let Some(mut loaded) = load(&sc) else {
        return Ok(ExitCode::from(1));
    };
    for w in &loaded.warnings {
        eprintln!("warning: {w}");
    }
    if !keep_periods(&mut loaded.scene, a.keep_periods) {
        return Ok(ExitCode::from(1));
    }
    if !(a.checkpoint_minutes.is_finite() && a.checkpoint_minutes >= 0.0) {
        eprintln!(
            "error: --checkpoint-minutes must be a number of minutes, 0 or more (got {})",
            a.checkpoint_minutes
        );
        return Ok(ExitCode::from(1));
    }
    let scene = &loaded.scene;
    let mut inputs = loaded.inputs.clone();
    if let Some(path) = &a.input.scenario {
        inputs
            .push(InputFile::new("scenario", path, 0).with_context(|| path.display().to_string())?);
    }
    let mut checkpoints = Checkpoints::new(
        &sc,
        &loaded.inputs,
        a.keep_periods,
        a.checkpoint_every,
        a.checkpoint_minutes,
    );
    let resumed = if a.resume {
        checkpoints
            .resume(scene, &sc)
            .with_context(|| checkpoints.path().display().to_string())?
    } else {
        None
    };
    let (engine, first) = match resumed {
        Some((e, next)) => {
            eprintln!("resuming at period {} of {}", next + 1, scene.periods.len());
            (e, next)
        }
        None => (Engine::new(scene, &sc)?.with_trace(&loaded.trace), 0),
    };
    let engine = if a.account {
        engine.keep_account()
    } else {
        engine
    };
    let engine_started = Instant::now();
    let bar = progress(scene.periods.len() as u64, "periods");
    bar.set_position(first as u64);
    let periods = scene.periods.len();
    let out = on_pool(|| {
        engine.run_from(
            first,
            &mut |done, _| bar.set_position(done as u64),
            &mut |e: &Engine, next: usize| checkpoints.after_period(e, next, periods),
        )
    })?;
    bar.finish_and_clear();
    let engine_wall = engine_started.elapsed();
    let account = out.account.clone();
    let b = out.balance.clone();
    for line in output::warnings::summary(&out.warnings) {
        eprintln!("warning: {line}");
    }
    let name = a
        .input
        .scenario
        .as_ref()
        .and_then(|p| p.file_stem())
        .map_or("run".to_string(), |s| s.to_string_lossy().into_owned());
    let dir = RunDir {
        scene,
        scenario: &sc,
        name: &name,
        command: std::env::args().collect::<Vec<_>>().join(" "),
        inputs,
        started,
    };
    let written = write_run_dir(dir, out)?;
    println!(
        "drew {:.0} t of {:.0} t scheduled ({} markers drawn of {} mobilised) in {:.1} s",
        b.credited_tonnes,
        b.scheduled_tonnes,
        b.markers_drawn,
        b.markers_mobilised,
        started.elapsed().as_secs_f64()
    );
    println!(
        "wrote {} files and {} charts to {}",
        written.files(),
        written.charts.len(),
        sc.outputs.dir.display()
    );
    if let Some(page) = &written.report {
        println!("report: {}", page.display());
    }
    if let Some(account) = account {
        let total = started.elapsed().as_secs_f64();
        eprint!("{}", account.report());
        let outputs = &written.timings;
        let written: f64 = outputs.iter().map(|o| o.1).sum();
        let each: Vec<String> = outputs
            .iter()
            .map(|(w, t)| format!("{w} {t:.2} s"))
            .collect();
        eprintln!(
            "run wall {total:.2} s: engine {:.2} s, outputs {written:.2} s ({}), set-up {:.2} s",
            engine_wall.as_secs_f64(),
            each.join(", "),
            total - engine_wall.as_secs_f64() - written,
        );
    }
    Ok(ExitCode::SUCCESS)
}

fn progress(n: u64, what: &str) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(n);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{elapsed_precise} [{bar:40}] {pos}/{len} {msg} (eta {eta})",
        )
        .expect("static template")
        .progress_chars("=> "),
    );
    bar.set_message(what.to_string());
    bar
}

fn schema_cmd(a: SchemaArgs) -> Result<ExitCode> {
    if let Some(dir) = &a.write {
        std::fs::create_dir_all(dir).with_context(|| dir.display().to_string())?;
        for t in schema::ALL {
            let path = dir.join(format!("{}.json", t.name));
            output::write_atomic(&path, schema_json(t).as_bytes())?;
        }
        println!("wrote {} schemas to {}", schema::ALL.len(), dir.display());
        return Ok(ExitCode::SUCCESS);
    }
    match &a.table {
        Some(name) => match schema::table(name) {
            Some(t) => print!("{}", schema_json(t)),
            None => {
                // An unknown table name is invalid input, like a bad flag: exit 1.
                eprintln!("error: no table `{name}`; tables: {}", table_names());
                return Ok(ExitCode::from(1));
            }
        },
        None => println!("{}", table_names()),
    }
    Ok(ExitCode::SUCCESS)
}

/// The JSON text of a table's schema, as committed in `schemas/`.
pub fn schema_json(t: &schema::TableSpec) -> String {
    let mut s = serde_json::to_string_pretty(&t.to_json()).expect("schema JSON");
    s.push('\n');
    s
}

fn table_names() -> String {
    schema::ALL
        .iter()
        .map(|t| t.name)
        .collect::<Vec<_>>()
        .join(", ")
}

fn demo_cmd(a: DemoArgs) -> Result<ExitCode> {
    let scale = match a.scale {
        Scale::Small => DemoScale::Small,
        Scale::Mine => DemoScale::Mine,
    };
    let scene = demo::henderson(scale, a.seed);
    let sc = demo::scenario(scale, a.seed);
    let files = output::inputs::write_scene(&a.out, &scene, &sc)?;
    println!(
        "wrote the synthetic Henderson-style demo ({} drawpoints, {} blocks, {} periods) to {}:",
        scene.drawpoints.len(),
        scene.blocks.len(),
        scene.periods.len(),
        a.out.display()
    );
    for f in files {
        println!("  {}", f.display());
    }
    let scenario_file = Path::new(&a.out).join("scenario.toml");
    if a.records {
        // Through the files just written, exactly as a user's run would read them.
        let sc = Scenario::load(&scenario_file, &[])?;
        let Some(l) = load(&sc) else {
            return Ok(ExitCode::from(1));
        };
        let cfg = crate::analysis::records::SyntheticRecords {
            sigma: a.records_sigma,
            frag_sigma: Some(a.records_sigma),
            seed: a.records_seed,
            ..Default::default()
        };
        let bar = progress(l.scene.periods.len() as u64, "periods (true fragmentation)");
        let recs =
            crate::analysis::records::synthetic_records(&l.scene, &sc, &cfg, &mut |p, _| {
                bar.set_position(p as u64)
            })?;
        bar.finish_and_clear();
        let path = Path::new(&a.out).join("records.csv");
        output::records::write_records(&path, &recs, &l.scene.drawpoints)?;
        println!(
            "  {} ({} synthetic records: true calibration {:?}, noise σ {}, seed {})",
            path.display(),
            recs.len(),
            cfg.truth.frag_factor,
            cfg.sigma,
            cfg.seed
        );
    }
    println!("run it with: caveflow run {}", scenario_file.display());
    Ok(ExitCode::SUCCESS)
}

fn sweep_cmd(mut a: SweepArgs) -> Result<ExitCode> {
    use crate::analysis::sweep::{self, SweepConfig};
    if a.input.scenario.is_none() && a.input.blocks.is_none() {
        a.input.scenario = Some(PathBuf::from("data/scenario.toml"));
    }
    let sc = scenario(&a.input)?;
    let Some(mut loaded) = load(&sc) else {
        return Ok(ExitCode::from(1));
    };
    if !keep_periods(&mut loaded.scene, a.keep_periods) {
        return Ok(ExitCode::from(1));
    }
    let Ok(reference) = <[f64; 3]>::try_from(a.reference.as_slice()) else {
        eprintln!(
            "--reference takes three multipliers, h,spacing,increment (e.g. 0.5,0.5,0.25); got {}",
            a.reference.len()
        );
        return Ok(ExitCode::from(1));
    };
    let cfg = SweepConfig {
        h: a.h,
        spacing: a.spacing,
        increment: a.increment,
        reference,
        repeats: a.repeats,
        target: Some(a.target),
    };
    // One line per run above a progress bar on a terminal; nothing on a non-terminal
    // (the summary below is printed either way).
    let bar = progress(0, "runs");
    let rows = sweep::sweep(&loaded.scene, &sc, &cfg, &mut |done, total, r| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
        bar.println(format!(
            "{done}/{total}: h×{} spacing×{} increment×{}: {:.2} s, {} markers, grade RMSE {:.3}% (second half {:.3}%), dilution entry {:.2}%, IMZ width {:.2}%, IEZ height {:.2}%{}",
            r.mult[0],
            r.mult[1],
            r.mult[2],
            r.wall_s,
            r.markers,
            100.0 * r.grade_rmse,
            100.0 * r.grade_rmse_late,
            100.0 * r.dilution_entry_error,
            100.0 * r.imz_width_error,
            100.0 * r.iez_height_error,
            if r.is_reference {
                " (reference: its own error, noise and bias)"
            } else if r.is_reference_check {
                " (check of the reference)"
            } else {
                ""
            }
        ))
    })?;
    bar.finish_and_clear();
    std::fs::create_dir_all(&a.out).with_context(|| a.out.display().to_string())?;
    let table = a.out.join("sweep.parquet");
    let chart = a.out.join("sweep.png");
    sweep::write_sweep(&table, &rows)?;
    let title = format!(
        "Speed and accuracy: {} drawpoints, {} periods",
        loaded.scene.drawpoints.len(),
        loaded.scene.periods.len()
    );
    sweep::write_sweep_chart(&chart, &rows, &title)?;
    println!("wrote {} and {}", table.display(), chart.display());
    Ok(ExitCode::SUCCESS)
}
