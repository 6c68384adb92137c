//! Scenario studies: one base scenario, many variants, one dataset (`caveflow study`).
//!
//! # The study file
//!
//! ```toml
//! name = "demo"                  # the `study=` partition (default: the file's stem)
//! scenario = "scenario.toml"     # the base scenario, relative to this file
//! set = ["outputs.charts=false"] # overrides of every variant, as `run --set`
//! seeds = [1, 2]                 # repeats: the scenario's `seed` (default: its own only)
//! keep_periods = 12              # only the first N periods, as `run --keep-periods`
//!
//! [grid]                         # any scenario key: the values to run
//! "calibration.frag_factor.urad" = [0.6, 1.0]
//! flow.q = [3.0, 3.5]            # dotted keys as nested tables work too
//!
//! [alternatives.schedule]        # a named dimension of alternatives that swap tables
//! base = {}                      # the scenario's own tables
//! slow = { schedule = "schedule_slow.csv" }  # role = path, relative to this file
//!
//! [cases]                        # named variants, each its own overrides
//! coarse = ["resolution.marker_spacing=3.8"]
//! fine = ["resolution.marker_spacing=1.9", "flow.q=3.0"]
//! exact = ["flow.q=3.0"]
//!
//! [case_resolution.exact]        # a case's resolution, run as given (not resolved)
//! layer_thickness = 2.7
//! marker_spacing = 1.35
//! draw_increment = 68.4
//! max_marker_move = 1.9
//! ```
//!
//! The variants are the cartesian product of the grids (in key order), the alternative
//! dimensions (in name order), the cases (in name order: a list of variants where no grid's
//! product fits, as `caveflow calibrate`'s runs, `analysis::calibrate_runs`) and the seeds,
//! the first dimension varying slowest. Each
//! grid value and each alternative becomes a `key=value` override of the base scenario,
//! applied by `Scenario::load`, the very code of `run --set`: the same keys, the same
//! types, the same range checks (a map entry such as `calibration.frag_factor.urad` too).
//! An alternative's roles are the scenario's `inputs`: blocks, drawpoints, drawbells,
//! schedule, periods, trace. A variant's name joins its choices' labels with `_`:
//! `urad-0.6_schedule-slow_seed-1` (the key's last segment, or the whole key when two
//! grids share it; a case's own name; `base` with no dimension at all). The summary has a
//! column per grid key and per alternative dimension, and `case` for the cases.
//!
//! A case may carry its resolution as numbers (`[case_resolution.<case>]`: h, marker
//! spacing, draw increment and `max_marker_move`): the variant then runs at exactly that
//! resolution ([`Variant::plan`]) instead of the one its scenario resolves to, as
//! `caveflow calibrate`'s finer check does. The resolution is part of the variant's hash.
//!
//! # Identity
//!
//! A variant is a pure function of its resolved scenario (and the resolution it carries,
//! if any), its input files, its seed, the periods kept and the caveflow that runs it, and
//! [`plan::variant_hash`] hashes exactly those: the scenario's JSON with input paths
//! replaced by their roles and the output placement left out, the resolution carried,
//! each input file's SHA-256 (as the run manifest and the checkpoint tag of `run` hash
//! them), the seed, `keep_periods` when given, and caveflow's version
//! (`CARGO_PKG_VERSION`, [`plan::VERSION`]): a binary of another version runs every variant
//! again rather than skip one an older binary computed. The same tables at another path
//! give the same hash; one changed byte gives another.
//!
//! # Layout
//!
//! ```text
//! DIR/dataset/<table>/study=<study>/scenario=<variant>/period=<N>/part-0.parquet
//! DIR/dataset/<table>/study=<study>/scenario=<variant>/_SUCCESS   the hash, once all are in
//! DIR/variants/<variant>/_SUCCESS        the variant's hash: complete
//! DIR/variants/<variant>/summary.json    its summary row
//! DIR/variants/<variant>/manifest.json   its run manifest (inputs, resolution, balance)
//! DIR/summary.parquet                    one row per complete variant (schemas/study_summary.json)
//! DIR/report.html, DIR/charts/*.svg       the variants side by side (report::write_study_report)
//! ```
//!
//! for the tables extraction, imz, drawn, air_gap and surface (and draw control's and the
//! value tables of the variants that have them), written by
//! `output::dataset` exactly as `run` writes its own (`period_group=` beyond 400
//! periods). A reader of the whole dataset while a study runs, or after one was killed,
//! also sees the partitions of incomplete variants: keep to the variants of
//! `summary.parquet`, or to partitions with a `_SUCCESS`. Marker snapshots, stress and trace tables, charts and the flat tables are not
//! written for a study's variants.
//!
//! # Killed at any point
//!
//! [`runner::run_variant`] first removes the variant's `_SUCCESS`, then swaps each table's
//! partitions in whole (a hidden temporary directory renamed into place), then writes
//! `summary.json` and `manifest.json`, and `_SUCCESS` last, each atomically. A variant is
//! complete when its `_SUCCESS` holds its hash, and only then skipped; anything else
//! (no `_SUCCESS`, another hash because a table or the scenario changed, a temporary
//! directory a killed writer left, which is removed) is run again and replaces what was
//! there. So a study killed at any point and run again loses nothing and runs nothing
//! twice. Different variants may be written by different processes at once (their
//! directories are disjoint); one variant must have one writer at a time (a writer
//! removes the temporary directories its variant's killed writers left).
//!
//! # In parallel, here and elsewhere
//!
//! `--jobs N --threads T` runs N workers, each a thread that runs one variant at a time
//! inside its own rayon pool of T threads (default max(1, cores / N)): a worker is a fixed
//! number of cores, as a Ray task of `num_cpus = T` is (the Ray driver passes its tasks'
//! CPUs as `--threads`). The engine is deterministic, so the dataset is the same byte for
//! byte at any N and T. Measured on this project's shared 2-core machine, the 8 demo
//! variants of `data/study.toml` × `flow.q = [3.0, 3.5]`, alternating, `uptime`'s load
//! before each run: one worker (`--jobs 1 --threads 1`) 72.3, 77.4, 64.6 and 64.2 s; two
//! (`--jobs 2 --threads 1`) 37.0, 63.5, 35.2 and 32.2 s: 1.95×, 1.83× and 1.99× where the
//! two workers had both cores (182–196 % CPU; load 0.9–4.8), 1.22× in the one run where
//! another engineer's build held a core (107 % CPU). A worker of one thread on a core of
//! its own leaves nothing idle, where one variant's run keeps two cores only 1.3–1.75
//! busy. Memory: 130–150 MB at one worker, 190–250 MB at two. More workers than cores
//! only adds memory.
//!
//! `caveflow study --plan STUDY.toml` prints the expanded study as JSON (each variant's
//! name, hash, `--set` list, input paths and hashes, seed, swept values): the one place the
//! expansion lives. It checks the study file (keys, values, that the tables exist) but
//! not each variant's tables, which that variant's run checks (exit 1): a driver then runs
//! the good variants and reports the bad. `caveflow study STUDY.toml --variant NAME --out DIR
//! [--threads T]` runs one variant into the layout in a pool of T threads (default every
//! core; what a task of a cluster driver calls, with T its CPUs), and `caveflow study STUDY.toml
//! --out DIR --summary-only` run after every task writes the summary from the complete
//! variants and runs none (exit 1, naming them, when some are not complete).
//! `src/python/caveflow_ray/` is such a driver: one Ray task per variant, with retries
//! (its README; figures in `docs::resolution`, "Studies").
//!
//! # Bad study files
//!
//! Refused before any run, every problem listed as `file: [rule] key: message`, exit 1
//! ([`spec::StudyError`] has the rules). `caveflow study` checks every variant's tables
//! first; `--plan` the study file only, and `--variant` that variant's tables.

pub mod plan;
pub mod report;
pub mod runner;
pub mod spec;
pub mod summary;

pub use plan::{Study, Variant};
pub use report::write_study_report;
pub use runner::{run_study, run_variant, Layout, Outcome};
pub use spec::{StudyError, StudyProblems};
pub use summary::SummaryRow;
