//! The caps of the marker moves, counted on every run (summary §3.3; the moves are the
//! module's above). Where a disk's formula asks for more than one step can take, the
//! marker pass bounds the move, and what it leaves out is counted here and reported in
//! the run's `manifest.json` (`marker_caps`, `docs::validation`):
//!
//! - `push`: the ring's push between R_old and the new radius is at most half R_old
//!   (`radial`); only a disk that more than doubles its radius in a step asks for more.
//! - `squeeze`: inside R_old the squeeze is at most half the marker's radius a (`radial`).
//! - `lateral`: the lateral move is at most a quarter of R_old (`lateral`).
//! - `transfer_rim`: a cadence window's step split at a disk base (`MotionField::step`)
//!   may leave the marker beyond the rim of the disk whose base it reaches (other IMZs'
//!   plan moves carried it there); the transfer maps it as if it were at the rim, so it
//!   ends beyond the disk below by as much (`transfer`'s a ≤ R).
//! - `shape_modes`: the lateral move keeps the first `SHAPE_MODES` Fourier modes of the
//!   ring's dilation around the perimeter (`Stagnant::shape`). What the rest would move
//!   is not computed, so it is estimated: with σ² the dilation's variance beyond the kept
//!   modes (mean square over the perimeter's samples, `Stagnant::shape_rest`), the moves
//!   of the modes left out, averaged in square over the angle at the marker's radius a,
//!   are at most push √(2σ²) (a / R_old)^K inside R_old (mode k > K falls as
//!   (a/R_old)^(k−1)) and push √(2σ²) (R − a)/(R − R_old) beyond it. That RMS is counted
//!   as the dropped move; the share of the variance of w − 1 beyond the kept modes is
//!   reported beside it.
//!
//! What a cap drops is measured in tonne-metres: the marker's mass times the length of
//! the move the cap left out (summed over the disks and images that move it, each at its
//! share of a split step), against the mass times the length of every step made, so
//! `dropped_share` is the share of the moved material's displacement that the cap
//! dropped. A marker is the cell of in-situ ground around its lattice site, so in ground
//! of one density the mass weights are its volume's.
//!
//! The other bounds in the marker moves drop nothing: the radius after the radial move
//! and after a transfer is kept ≥ 0, which neither reaches (the squeeze and the push take
//! at most half of a and of R_old < a, and a transfer maps to a radius in the disk
//! below); a split step's share is kept in [0, 1] against rounding only; a move through
//! one of the model's walls is folded back to its mirror inside (the image's move, not a
//! cut); and a ray with no ring behind it is not pushed (the ring that would push is not
//! there: the physics, not a cap).
//!
//! The sums are kept in fixed point (integers of [`UNIT`]), so they add in any order: each
//! chunk of a parallel pass keeps its own [`CapTally`], reduced after the pass, and the
//! totals do not depend on how the pass was split.

use serde::{Deserialize, Serialize};

use super::motion::Step;

/// Number of caps counted.
pub const CAPS: usize = 5;
/// The ring's push beyond R_old.
pub const PUSH: usize = 0;
/// The squeeze inside R_old.
pub const SQUEEZE: usize = 1;
/// The lateral move.
pub const LATERAL: usize = 2;
/// A split step's transfer from beyond the disk's rim.
pub const RIM: usize = 3;
/// The lateral move's Fourier series, truncated (an estimate).
pub const MODES: usize = 4;

/// Fixed-point units per tonne-metre (and per tonne, for the variance sums).
pub const UNIT: f64 = 1e9;

/// What the caps left out of one marker step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Cut {
    /// Per cap (`PUSH`, `SQUEEZE`, `LATERAL`, `RIM`, `MODES`), the length of the move it dropped, summed
    /// over the disks that move the marker, m.
    pub dropped: [f64; CAPS],
    /// Over the disks whose lateral move moves the marker: the variance of their ring's
    /// dilation w − 1 beyond the kept modes, and all of it, summed.
    pub variance: [f64; 2],
}

impl Cut {
    /// Adds another part's cut.
    #[inline]
    pub fn add(&mut self, o: &Cut) {
        for c in 0..CAPS {
            self.dropped[c] += o.dropped[c];
        }
        self.variance[0] += o.variance[0];
        self.variance[1] += o.variance[1];
    }

    /// Scales it by the share `k` of the step made.
    #[inline]
    pub fn scale(&mut self, k: f64) {
        self.dropped.iter_mut().for_each(|d| *d *= k);
        self.variance.iter_mut().for_each(|v| *v *= k);
    }
}

/// `x` in fixed point ([`UNIT`]), rounded (x ≥ 0).
#[inline]
fn fixed(x: f64) -> u128 {
    (x * UNIT + 0.5) as u64 as u128
}

/// The caps' counts over marker steps: a pass's (one per chunk, reduced), or a run's.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct CapTally {
    /// Marker steps counted.
    pub moves: u64,
    /// Σ mass × |step|, in [`UNIT`]s of t·m.
    moved: u128,
    /// Per cap, the steps it cut.
    capped: [u64; CAPS],
    /// Per cap, Σ mass × |dropped|, in [`UNIT`]s of t·m.
    dropped: [u128; CAPS],
    /// Σ mass × the variance beyond the kept modes, and all of it ([`Cut::variance`]), in
    /// [`UNIT`]s of t.
    variance: [u128; 2],
}

impl CapTally {
    /// Counts a step `s` of a marker of mass `mass`, t.
    #[inline]
    pub fn add(&mut self, mass: f64, s: &Step) {
        self.moves += 1;
        let len = (s.dx * s.dx + s.dy * s.dy + s.dz * s.dz).sqrt();
        self.moved += fixed(mass * len);
        let cut = &s.cut;
        for c in 0..CAPS {
            if cut.dropped[c] > 0.0 {
                self.capped[c] += 1;
                self.dropped[c] += fixed(mass * cut.dropped[c]);
            }
        }
        if cut.variance[1] > 0.0 {
            self.variance[0] += fixed(mass * cut.variance[0]);
            self.variance[1] += fixed(mass * cut.variance[1]);
        }
    }

    /// Adds another tally.
    pub fn merge(mut self, o: CapTally) -> CapTally {
        self.moves += o.moves;
        self.moved += o.moved;
        for c in 0..CAPS {
            self.capped[c] += o.capped[c];
            self.dropped[c] += o.dropped[c];
        }
        self.variance[0] += o.variance[0];
        self.variance[1] += o.variance[1];
        self
    }

    /// The counts as the manifest reports them.
    pub fn report(&self) -> MarkerCaps {
        let share = |a: f64, b: f64| if b > 0.0 { a / b } else { 0.0 };
        let moved = self.moved as f64 / UNIT;
        let cap = |c: usize| {
            let dropped = self.dropped[c] as f64 / UNIT;
            CapCount {
                moves: self.capped[c],
                share: share(self.capped[c] as f64, self.moves as f64),
                dropped_tonne_metres: dropped,
                dropped_share: share(dropped, moved),
            }
        };
        MarkerCaps {
            moves: self.moves,
            moved_tonne_metres: moved,
            push: cap(PUSH),
            squeeze: cap(SQUEEZE),
            lateral: cap(LATERAL),
            transfer_rim: cap(RIM),
            shape_modes: cap(MODES),
            shape_variance_share: share(self.variance[0] as f64, self.variance[1] as f64),
        }
    }
}

/// One cap's count over a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct CapCount {
    /// Marker steps it cut.
    pub moves: u64,
    /// Their share of the marker steps.
    pub share: f64,
    /// Σ mass × the length of the move it dropped, t·m.
    pub dropped_tonne_metres: f64,
    /// That over Σ mass × the length of every step (`moved_tonne_metres`).
    pub dropped_share: f64,
}

/// The caps of the marker moves over a run (`manifest.json`, `marker_caps`; the module
/// docs above define each cap and the measure).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct MarkerCaps {
    /// Marker steps made.
    pub moves: u64,
    /// Σ mass × the length of every step, t·m.
    pub moved_tonne_metres: f64,
    /// The ring's push beyond R_old, at most R_old / 2.
    pub push: CapCount,
    /// The squeeze inside R_old, at most a / 2.
    pub squeeze: CapCount,
    /// The lateral move, at most R_old / 4.
    pub lateral: CapCount,
    /// A split step's transfer taken from beyond the disk's rim.
    pub transfer_rim: CapCount,
    /// The lateral move's Fourier modes beyond `SHAPE_MODES`: an estimate (RMS over the
    /// angle at the marker's radius).
    pub shape_modes: CapCount,
    /// The share of the ring dilation's variance beyond the kept modes, over the disks
    /// whose lateral move moves a marker, weighted by its mass.
    pub shape_variance_share: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The tally adds in any order to the same integers, and reports shares of the moved
    /// tonne-metres: a 10 t marker moved 3–4 m with 1 m of push dropped, and a 30 t one
    /// moved 0.5 m with nothing dropped.
    #[test]
    fn a_tally_reports_dropped_shares_in_any_order() {
        let mut capped = Step {
            dx: 3.0,
            dz: -4.0,
            ..Default::default()
        };
        capped.cut.dropped[PUSH] = 1.0;
        let free = Step {
            dy: 0.5,
            ..Default::default()
        };
        let (mut a, mut b) = (CapTally::default(), CapTally::default());
        a.add(10.0, &capped);
        b.add(30.0, &free);
        let (ab, ba) = (a.merge(b), b.merge(a));
        assert_eq!(ab, ba);
        let r = ab.report();
        assert_eq!((r.moves, r.push.moves, r.squeeze.moves), (2, 1, 0));
        assert_eq!(r.moved_tonne_metres, 65.0);
        assert_eq!(r.push.share, 0.5);
        assert_eq!(r.push.dropped_share, 10.0 / 65.0);
        assert_eq!(r.lateral.dropped_share, 0.0);
    }
}
