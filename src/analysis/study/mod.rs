//! Scenario studies: one base scenario, many variants, one dataset (`caveflow study`).
//!
//! # The study file
//!
//! ```toml
//! name = "demo"                  # the `study=` partition (default: the file's stem)
//! scenario = "scenario.toml"     # the base scenario, relative to this file
//! set = ["outputs.charts=false"] # overrides of every variant, as `run --set`
//! seeds = [1, 2]                 # repeats: the scenario's `seed` (default: its own only)
//!
//! [grid]                         # any scenario key: the values to run
//! "calibration.frag_factor.urad" = [0.6, 1.0]
//! flow.q = [3.0, 3.5]            # dotted keys as nested tables work too
//!
//! [alternatives.schedule]        # a named dimension of alternatives that swap tables
//! base = {}                      # the scenario's own tables
//! slow = { schedule = "schedule_slow.csv" }  # role = path, relative to this file
//! ```
//!
//! The variants are the cartesian product of the grids (in key order), the alternative
//! dimensions (in name order) and the seeds, the first dimension varying slowest. Each
//! grid value and each alternative becomes a `key=value` override of the base scenario,
//! applied by `Scenario::load`, the very code of `run --set`: the same keys, the same
//! types, the same range checks (a map entry such as `calibration.frag_factor.urad` too).
//! An alternative's roles are the scenario's `inputs`: blocks, drawpoints, drawbells,
//! schedule, periods, trace. A variant's name joins its choices' labels with `_`:
//! `urad-0.6_schedule-slow_seed-1` (the key's last segment, or the whole key when two
//! grids share it; `base` with no dimension at all).
//!
//! # Identity
//!
//! A variant is a pure function of its resolved scenario, its input files and its seed,
//! and [`plan::variant_hash`] hashes exactly those: the scenario's JSON with input paths
//! replaced by their roles and the output placement left out, each input file's SHA-256
//! (as the run manifest and the checkpoint tag of `run` hash them) and the seed. The same
//! tables at another path give the same hash; one changed byte gives another.
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
//! for the tables extraction, imz, drawn, air_gap and surface, written by
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
//! `--jobs N` runs N variants at once on worker threads. Each run's own parallel loops use
//! rayon's one global pool (as many threads as cores), so N runs share the cores rather
//! than multiply threads; a second run fills the serial stretches of the first (loading,
//! IMZ growth between marker updates, writing). A lone demo run keeps 2 cores only about
//! 1.3–1.75 busy (`time`: 127–175 % CPU), so the default is 2: measured on this project's
//! shared 2-core machine, the 4-variant `data/study.toml` took 27.6 s with `--jobs 1`
//! (127 % CPU) and 19.2 s with `--jobs 2` (187 %), 1.44× (best of three each; while another
//! engineer's build held a core, both took 34–38 s). Memory: 133 MB at one job, 240 MB at
//! two. More jobs than cores only adds memory.
//!
//! `caveflow study --plan STUDY.toml` prints the expanded study as JSON (each variant's
//! name, hash, `--set` list, input paths and hashes, seed, swept values): the one place the
//! expansion lives. It checks the study file (keys, values, that the tables exist) but
//! not each variant's tables, which that variant's run checks (exit 1): a driver then runs
//! the good variants and reports the bad. `caveflow study STUDY.toml --variant NAME --out DIR` runs one variant
//! into the layout (what a task of a cluster driver calls), and `caveflow study STUDY.toml
//! --out DIR --summary-only` run after every task writes the summary from the complete
//! variants and runs none (exit 1, naming them, when some are not complete).
//! `src/python/caveflow_ray/` is such a driver: one Ray task per variant, with retries
//! (its README; figures in `docs::performance`, "Studies").
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
