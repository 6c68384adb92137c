//! A run's checkpoint: `<dir>/checkpoint.bin`, the engine's state at the end of a period
//! (`engine::checkpoint`), written while the run goes so that a killed run can resume
//! (`caveflow run --resume`), and removed once the run directory is complete
//! ([`write_run_dir`](super::write_run_dir)).
//!
//! When: every `every` periods (0: never by count), and at the end of the first period that
//! ends at least `minutes` of wall time after the last checkpoint (0: never by time); never
//! after the last period. A checkpoint belongs to the inputs and the scenario it was made
//! from (its tag): a run resumes only from its own.

use std::fs;
use std::io::BufReader;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::engine::{Engine, EngineError};
use crate::io::sha256_hex;
use crate::model::load::InputFile;
use crate::model::{Scenario, Scene};
use crate::output::{write_atomic_with, OutputError};

/// Name of the checkpoint file in the output directory.
pub const CHECKPOINT_FILE: &str = "checkpoint.bin";

/// Where, when and for what a run writes its checkpoint.
#[derive(Debug, Clone)]
pub struct Checkpoints {
    dir: PathBuf,
    path: PathBuf,
    tag: String,
    every: usize,
    minutes: f64,
    last: Instant,
}

impl Checkpoints {
    /// The checkpoints of a run of `scenario` on the loaded `inputs` into
    /// `scenario.outputs.dir`, with `keep_periods` periods kept (part of the tag): every
    /// `every` periods and every `minutes` minutes (see the module docs). Time counts from
    /// now.
    pub fn new(
        scenario: &Scenario,
        inputs: &[InputFile],
        keep_periods: Option<usize>,
        every: usize,
        minutes: f64,
    ) -> Checkpoints {
        let mut text =
            serde_json::to_string(scenario).expect("a Scenario always serialises to JSON");
        for f in inputs {
            text.push_str(&f.sha256);
        }
        text.push_str(&format!("keep_periods={keep_periods:?}"));
        let dir = scenario.outputs.dir.clone();
        Checkpoints {
            path: dir.join(CHECKPOINT_FILE),
            dir,
            tag: sha256_hex(text.as_bytes()),
            every,
            minutes,
            last: Instant::now(),
        }
    }

    /// `<dir>/checkpoint.bin`.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The engine resumed from the checkpoint, with the first period it has to run; None
    /// when there is no checkpoint. A checkpoint of other inputs or another scenario is an
    /// error.
    pub fn resume<'a>(
        &self,
        scene: &'a Scene,
        scenario: &'a Scenario,
    ) -> Result<Option<(Engine<'a>, usize)>, EngineError> {
        let Ok(file) = fs::File::open(&self.path) else {
            return Ok(None);
        };
        Engine::resume_from(scene, scenario, BufReader::new(file), &self.tag).map(Some)
    }

    /// At the end of a period, `next` being the index of the next one of `periods`: writes
    /// the engine's checkpoint (atomically) when one is due.
    pub fn after_period(
        &mut self,
        engine: &Engine,
        next: usize,
        periods: usize,
    ) -> Result<(), OutputError> {
        let by_periods = self.every > 0 && next % self.every == 0;
        let by_time =
            self.minutes > 0.0 && self.last.elapsed().as_secs_f64() >= 60.0 * self.minutes;
        if (by_periods || by_time) && next < periods {
            fs::create_dir_all(&self.dir).map_err(|source| OutputError::Io {
                path: self.dir.clone(),
                source,
            })?;
            write_atomic_with(&self.path, |w| engine.write_checkpoint(w, next, &self.tag))?;
            self.last = Instant::now();
        }
        Ok(())
    }
}

/// Removes `<dir>/checkpoint.bin` if there is one: the outputs are complete.
pub fn remove_checkpoint(dir: &Path) -> Result<(), OutputError> {
    let path = dir.join(CHECKPOINT_FILE);
    if path.exists() {
        fs::remove_file(&path).map_err(|source| OutputError::Io { path, source })?;
    }
    Ok(())
}
