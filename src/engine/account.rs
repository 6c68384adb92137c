//! The engine's account of its own work: wall time per phase of a run and the counters
//! that say how much work each phase did (`caveflow run --account`, `benches/engine.rs`).
//!
//! A run keeps no account unless asked ([`Engine::keep_account`](super::Engine)): the
//! clocks (wall time and the process's CPU time, summed over its threads) are then read at
//! each phase boundary of an update, a few dozen times per update,
//! and the candidate count of the marker pass is a second, counting pass over the same
//! rows (charged to its own phase, `counting`, so it does not inflate the marker pass).
//! Without an account the engine reads no clock and counts nothing but the updates and
//! marker steps it keeps anyway.

use std::time::{Duration, Instant};

use cpu_time::ProcessTime;

/// The phases of a run, in the order of an update.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// IMZ growth by the r-law, the drawing IMZs in parallel (`Imz::draw`), including the
    /// perimeters' stagnant properties and dilation state.
    Growth,
    /// Stagnant lattice sites covered by the grown disks turned into moving markers.
    Engulf,
    /// The step's read-only views: IMZ geometry, plan grids, the walls' reach, the cadence
    /// windows' motions.
    Grids,
    /// Which marker rows step in this update.
    Rows,
    /// The marker pass (`markers::move_rows`).
    MarkerPass,
    /// After the pass: the bins, attrition, the drawn markers taken out and tallied.
    Crediting,
    /// The disks' mobilised properties refreshed from their markers.
    Mobilised,
    /// The air gap per block column.
    AirGap,
    /// The fill of the drawing drawpoints' lowest disks (`engine::fill`).
    Fill,
    /// The rest of a period's end: catching lagging markers up, extraction rows, IMZ rows,
    /// surface, snapshots, the rows' sort.
    PeriodEnd,
    /// The end of the run: the streams read into the extraction table, the drawn table.
    Finish,
    /// Draw control's plan and review of each period (`engine::draw_control`).
    Control,
    /// The account's own counting pass (not part of a normal run).
    Counting,
}

/// Every phase, in order.
pub const PHASES: [Phase; 13] = [
    Phase::Growth,
    Phase::Engulf,
    Phase::Grids,
    Phase::Rows,
    Phase::MarkerPass,
    Phase::Crediting,
    Phase::Mobilised,
    Phase::AirGap,
    Phase::Fill,
    Phase::PeriodEnd,
    Phase::Finish,
    Phase::Control,
    Phase::Counting,
];

impl Phase {
    /// Short name, as printed.
    pub fn name(self) -> &'static str {
        match self {
            Phase::Growth => "IMZ growth",
            Phase::Engulf => "engulfing",
            Phase::Grids => "grids and motions",
            Phase::Rows => "row selection",
            Phase::MarkerPass => "marker pass",
            Phase::Crediting => "crediting",
            Phase::Mobilised => "mobilised sums",
            Phase::AirGap => "air gap",
            Phase::Fill => "lowest disks' fill",
            Phase::PeriodEnd => "period end",
            Phase::Finish => "finish",
            Phase::Control => "draw control",
            Phase::Counting => "counting (account only)",
        }
    }
}

/// Work counters of a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counters {
    /// Marker updates (draw increments).
    pub updates: u64,
    /// Marker steps: the rows stepped, summed over the updates.
    pub marker_steps: u64,
    /// IMZs a stepped marker's plan cell listed and whose disk at its height was tested,
    /// images across the walls included.
    pub candidate_tests: u64,
    /// Candidates whose disk held the marker.
    pub hits: u64,
    /// Disk-cycles of IMZ growth: the disks a cycle of void passed through, summed.
    pub disk_cycles: u64,
    /// Of them, those a disk took in one step with the draw's other cycles
    /// (`Imz::pass_all`).
    pub merged_cycles: u64,
    /// IMZ draws (one per drawing IMZ and update).
    pub imz_draws: u64,
    /// Markers engulfed.
    pub engulfed: u64,
    /// Markers drawn.
    pub drawn: u64,
}

/// A reading of both clocks: wall time and the process's CPU time.
#[derive(Debug, Clone, Copy)]
pub struct Mark {
    wall: Instant,
    cpu: ProcessTime,
}

impl Mark {
    /// Both clocks now.
    pub fn now() -> Mark {
        Mark {
            wall: Instant::now(),
            cpu: ProcessTime::now(),
        }
    }
}

/// Wall and CPU time per phase and the work counters.
#[derive(Debug, Clone, Default)]
pub struct Account {
    time: [Duration; PHASES.len()],
    cpu: [Duration; PHASES.len()],
    /// Counters.
    pub counters: Counters,
}

impl Account {
    /// Adds the time since `*t` to `phase` and restarts `*t`.
    #[inline]
    pub fn charge(&mut self, phase: Phase, t: &mut Mark) {
        let now = Mark::now();
        self.time[phase as usize] += now.wall - t.wall;
        self.cpu[phase as usize] += now.cpu.duration_since(t.cpu);
        *t = now;
    }

    /// Wall time of `phase`.
    pub fn time(&self, phase: Phase) -> Duration {
        self.time[phase as usize]
    }

    /// CPU time of `phase`, summed over the threads.
    pub fn cpu(&self, phase: Phase) -> Duration {
        self.cpu[phase as usize]
    }

    /// Wall time of every phase but the account's own counting.
    pub fn engine_time(&self) -> Duration {
        PHASES
            .iter()
            .filter(|&&p| p != Phase::Counting)
            .map(|&p| self.time(p))
            .sum()
    }

    /// CPU time of every phase but the account's own counting.
    pub fn engine_cpu(&self) -> Duration {
        PHASES
            .iter()
            .filter(|&&p| p != Phase::Counting)
            .map(|&p| self.cpu(p))
            .sum()
    }

    /// The account as a text table: phase, wall seconds, share of the engine's wall time,
    /// CPU seconds and CPU over wall (how many threads the phase kept busy), then the
    /// counters and the ratios that read off them.
    pub fn report(&self) -> String {
        let total = self.engine_time().as_secs_f64().max(1e-12);
        let mut s = String::from("phase                      wall s   share    cpu s  cpu/wall\n");
        let line = |name: &str, t: f64, share: String, c: f64| {
            format!(
                "{name:<24} {t:>8.2} {share:>7} {c:>8.2} {:>8.2}\n",
                c / t.max(1e-12)
            )
        };
        for p in PHASES {
            let (t, c) = (self.time(p).as_secs_f64(), self.cpu(p).as_secs_f64());
            let share = if p == Phase::Counting {
                String::new()
            } else {
                format!("{:.1}%", 100.0 * t / total)
            };
            s.push_str(&line(p.name(), t, share, c));
        }
        let c = self.engine_cpu().as_secs_f64();
        s.push_str(&line("engine total", total, String::new(), c));
        let c = &self.counters;
        let per = |a: u64, b: u64| a as f64 / (b.max(1)) as f64;
        s.push_str(&format!(
            "updates {}; marker steps {} ({:.0} an update); candidate tests {} ({:.1} a step), hits {} ({:.1} a step); \
             IMZ draws {}, disk-cycles {} ({:.0} a draw, {:.0}% taken together); markers engulfed {}, drawn {}\n",
            c.updates,
            c.marker_steps,
            per(c.marker_steps, c.updates),
            c.candidate_tests,
            per(c.candidate_tests, c.marker_steps),
            c.hits,
            per(c.hits, c.marker_steps),
            c.imz_draws,
            c.disk_cycles,
            per(c.disk_cycles, c.imz_draws),
            100.0 * per(c.merged_cycles, c.disk_cycles),
            c.engulfed,
            c.drawn,
        ));
        s
    }
}
