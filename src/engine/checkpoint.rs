//! Checkpoints: the engine's state between two periods, so a run killed at any moment
//! resumes and produces exactly the outputs of an uninterrupted run: no work is lost.
//!
//! A checkpoint holds everything [`Engine`] changes as it draws: the IMZs, the moving and
//! drawn markers, the engulfed lattice sites, the mass-balance carries, the trace points
//! and the output accumulated so far. What the engine derives from the scene (lattice,
//! marker masses, waste rule, …) is derived again on resume. The encoding is bincode, so every f64
//! (NaN included) comes back bit for bit, and the outputs of a resumed run are
//! byte-identical to those of an uninterrupted one.
//!
//! A checkpoint carries a `tag` chosen by the caller (the CLI hashes the scenario and the
//! input files into it); resuming with another tag is refused, so a checkpoint is never
//! applied to inputs it was not made from.
//!
//! A checkpoint is encoded straight into its writer and decoded straight from its reader
//! ([`Engine::write_checkpoint`], [`Engine::resume_from`]): at mine scale the state is
//! hundreds of megabytes, and a second copy of it as bytes would be as large again.

use serde::{Deserialize, Serialize};

use super::imz::Imz;
use super::markers::{DrawnMarkers, Markers};
use super::trace::Trace;
use super::{Engine, EngineError, RunOutput};
use crate::model::{Scenario, Scene};

/// Format version: bump when the state's layout changes.
const VERSION: u32 = 14;

#[derive(Serialize, Deserialize)]
struct State {
    version: u32,
    tag: String,
    /// Index of the next period to draw.
    next: usize,
    imzs: Vec<Imz>,
    markers: Markers,
    drawn: DrawnMarkers,
    engulfed: Vec<bool>,
    engulfed_mass: Vec<f64>,
    steps_done: u64,
    carry: Vec<f64>,
    cum: Vec<f64>,
    trace: Trace,
    out: RunOutput,
}

/// Borrowed twin of [`State`] for writing without cloning the markers.
#[derive(Serialize)]
struct StateRef<'e> {
    version: u32,
    tag: &'e str,
    next: usize,
    imzs: &'e [Imz],
    markers: &'e Markers,
    drawn: &'e DrawnMarkers,
    engulfed: &'e [bool],
    engulfed_mass: &'e [f64],
    steps_done: u64,
    carry: &'e [f64],
    cum: &'e [f64],
    trace: &'e Trace,
    out: &'e RunOutput,
}

fn config() -> bincode::config::Configuration {
    bincode::config::standard()
}

impl<'a> Engine<'a> {
    /// The state after period index `next − 1`, ready to resume at `next`, as bytes (what
    /// [`Engine::write_checkpoint`] writes).
    pub fn checkpoint(&self, next: usize, tag: &str) -> Vec<u8> {
        let mut bytes = Vec::new();
        // Writing into a Vec cannot fail.
        self.write_checkpoint(&mut bytes, next, tag)
            .expect("checkpoint encoding");
        bytes
    }

    /// Writes the state after period index `next − 1`, ready to resume at `next`, to `w` as
    /// it is encoded. Nothing of the state is copied first, so a mine-scale checkpoint
    /// costs the engine no second copy of its markers in memory; give it a buffered
    /// writer (`output::write_atomic_with`).
    pub fn write_checkpoint(
        &self,
        w: &mut impl std::io::Write,
        next: usize,
        tag: &str,
    ) -> std::io::Result<()> {
        let s = StateRef {
            version: VERSION,
            tag,
            next,
            imzs: &self.imzs,
            markers: &self.markers,
            drawn: &self.drawn,
            engulfed: &self.engulfed,
            engulfed_mass: &self.engulfed_mass,
            steps_done: self.steps_done,
            carry: &self.carry,
            cum: &self.cum,
            trace: &self.trace,
            out: &self.out,
        };
        match bincode::serde::encode_into_std_write(&s, w, config()) {
            Ok(_) => Ok(()),
            Err(bincode::error::EncodeError::Io { inner, .. }) => Err(inner),
            // Plain data has no other way to fail; say what happened if it ever does.
            Err(e) => Err(std::io::Error::other(format!("checkpoint encoding: {e}"))),
        }
    }

    /// An engine restored from a checkpoint of the same scene and scenario, and the index
    /// of the period to resume at.
    pub fn resume(
        scene: &'a Scene,
        scenario: &'a Scenario,
        bytes: &[u8],
        tag: &str,
    ) -> Result<(Engine<'a>, usize), EngineError> {
        Engine::resume_from(scene, scenario, bytes, tag)
    }

    /// [`Engine::resume`] from a checkpoint read from `r` as it is decoded, so the file's
    /// bytes are never held in memory beside the state (give it a buffered reader).
    pub fn resume_from(
        scene: &'a Scene,
        scenario: &'a Scenario,
        mut r: impl std::io::Read,
        tag: &str,
    ) -> Result<(Engine<'a>, usize), EngineError> {
        let bad = |why: String| EngineError::Checkpoint(why);
        let s: State = bincode::serde::decode_from_std_read(&mut r, config())
            .map_err(|e| bad(format!("unreadable ({e})")))?;
        if s.version != VERSION {
            return Err(bad(format!(
                "format version {} (this build reads {VERSION})",
                s.version
            )));
        }
        if s.tag != tag {
            return Err(bad("made from other inputs or another scenario".into()));
        }
        let mut e = Engine::new(scene, scenario)?;
        let n_dp = scene.drawpoints.len();
        if s.imzs.len() != n_dp
            || s.carry.len() != n_dp
            || s.cum.len() != n_dp
            || s.engulfed.len() != e.engulfed.len()
            || s.engulfed_mass.len() != e.engulfed_mass.len()
            || s.next > scene.periods.len()
            || !s.markers.is_consistent()
            || !s.drawn.m.is_consistent()
            || !s.trace.is_consistent()
        {
            return Err(bad("does not fit this scene".into()));
        }
        e.imzs = s.imzs;
        e.markers = s.markers;
        e.drawn = s.drawn;
        e.engulfed = s.engulfed;
        e.engulfed_mass = s.engulfed_mass;
        e.steps_done = s.steps_done;
        e.carry = s.carry;
        e.cum = s.cum;
        e.trace = s.trace;
        e.out = s.out;
        // The marker bins, the streams and the scheduled tonnes so far are derived state.
        e.bins.sync(&e.markers);
        e.count_all();
        let d = &e.drawn;
        if d.tau.len() != d.m.len() {
            return Err(bad("does not fit this scene".into()));
        }
        for k in 0..d.m.len() {
            e.streams[d.drawpoint[k] as usize].push(d.tau[k], d.m.mass[k], k);
        }
        if let Some(rec) = &e.out.control {
            // The realised rows so far are the schedule drawn (`engine::draw_control`).
            let n = rec.realised.len();
            if n != s.next * n_dp {
                return Err(bad("does not fit this scene".into()));
            }
            e.schedule.to_mut().tonnes[..n].copy_from_slice(&rec.realised);
        }
        for p in 0..s.next {
            let row = e.schedule.period(p);
            e.sched_cum.iter_mut().zip(row).for_each(|(c, t)| *c += t);
        }
        Ok((e, s.next))
    }
}
