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
//!   is not computed, so it is estimated per disk and update ([`CapTally::add_disks`]):
//!   with σ² the dilation's variance beyond the kept modes (`Stagnant::shape_rest`), the
//!   move of the modes left out, in mean square over the angle at radius a, is at most
//!   (push √(2σ²) (a / R_old)^K)² inside R_old (mode k > K falls as (a/R_old)^(k−1)) and
//!   (push √(2σ²) (R − a)/(R − R_old))² beyond it; that RMS, integrated over the disk at
//!   its markers' bulk density ρ_s (1 − n1), is the estimate. By Cauchy–Schwarz it bounds
//!   the mean length of that move; on a dilation that drops to 0 over a 40° arc it is
//!   1.7 times the move itself (`tests::the_estimate_of_…`). It also takes every disk as
//!   full of material at n1, which a column being drawn out is not, so it is an upper
//!   estimate.
//!
//! What a cap drops is measured in tonne-metres: the marker's mass times the length of
//! the move the cap left out (summed over the disks and images that move it, each at its
//! share of a split step), against the mass times the length of every step made, so
//! `dropped_share` is the share of the moved material's displacement that the cap
//! dropped. A marker is the cell of in-situ ground around its lattice site, so in ground
//! of one density the mass weights are its volume's. The first four caps are counted
//! marker by marker where they bind, in the disks whose bounds let one bind at all
//! (`PerDisk::may_cap`; the others cost the pass one test); counting the fifth so would
//! cost a term per disk and marker, so it is counted per disk.
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

use super::super::imz::{DiskMotion, Stagnant, SHAPE_MODES};

/// Number of caps counted marker by marker.
pub const CAPS: usize = 4;
/// The ring's push beyond R_old.
pub const PUSH: usize = 0;
/// The squeeze inside R_old.
pub const SQUEEZE: usize = 1;
/// The lateral move.
pub const LATERAL: usize = 2;
/// A split step's transfer from beyond the disk's rim.
pub const RIM: usize = 3;

/// Fixed-point units per tonne-metre (and per tonne, for the variance sums): a step's
/// term is rounded to 10⁻¹² t·m (a lab-scale marker of 10 g moved 0.1 mm is 10⁻⁹ t·m) and
/// may reach 1.8 × 10⁷ t·m (a 1000 t marker moved 18 km); a run's sums, in u128, do not
/// overflow.
pub const UNIT: f64 = 1e12;

/// What the caps left out of one marker step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Cut {
    /// Per cap (`PUSH`, `SQUEEZE`, `LATERAL`, `RIM`), the length of the move it dropped,
    /// summed over the disks that move the marker, m.
    pub dropped: [f64; CAPS],
}

impl Cut {
    /// Whether a cap dropped anything.
    #[inline]
    pub fn any(&self) -> bool {
        let d = &self.dropped;
        d[0] + d[1] + d[2] + d[3] > 0.0
    }

    /// Adds another part's cut.
    #[inline]
    pub fn add(&mut self, o: &Cut) {
        for c in 0..CAPS {
            self.dropped[c] += o.dropped[c];
        }
    }

    /// Scales it by the share `k` of the step made.
    #[inline]
    pub fn scale(&mut self, k: f64) {
        self.dropped.iter_mut().for_each(|d| *d *= k);
    }
}

/// `x` in fixed point ([`UNIT`]), rounded (x ≥ 0).
#[inline]
fn fixed(x: f64) -> u128 {
    (x * UNIT + 0.5) as u64 as u128
}

/// The caps' counts: a pass's (one per chunk, reduced), or a run's.
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
    /// Disk updates with a lateral move, whose Fourier series is truncated.
    lateral_disks: u64,
    /// The estimate of what the modes left out would move, in [`UNIT`]s of t·m.
    modes: u128,
    /// Σ weight × the dilation's variance beyond the kept modes, and all of it
    /// ([`CapTally::add_disks`]), in [`UNIT`]s of t·m.
    variance: [u128; 2],
}

impl CapTally {
    /// Counts a step `s` of a marker of mass `mass`, t, that the caps cut by `cut`.
    #[inline]
    pub fn add(&mut self, mass: f64, s: &super::Step, cut: &Cut) {
        let len = (s.dx * s.dx + s.dy * s.dy + s.dz * s.dz).sqrt();
        self.add_moved(mass, len, cut);
    }

    /// Counts a step of length `len`, m, of a marker of mass `mass`, t, that the caps cut
    /// by `cut`. Each step's term is fixed on its own, so the sums do not depend on the
    /// order of the rows either (`Markers::permute`).
    #[inline]
    pub fn add_moved(&mut self, mass: f64, len: f64, cut: &Cut) {
        self.moves += 1;
        self.moved += fixed(mass * len);
        if cut.any() {
            self.count_cut(mass, cut);
        }
    }

    /// Counts what the caps cut from a step of a marker of mass `mass`, t.
    #[cold]
    fn count_cut(&mut self, mass: f64, cut: &Cut) {
        for c in 0..CAPS {
            if cut.dropped[c] > 0.0 {
                self.capped[c] += 1;
                self.dropped[c] += fixed(mass * cut.dropped[c]);
            }
        }
    }

    /// Counts the Fourier modes the lateral moves of an IMZ's disks (thickness `h`, m)
    /// left out over one update: per disk with a lateral move, the estimate of the module
    /// docs, push √(2σ²) ρ h A_f (2π R_old² / (K + 2) + π (R − R_old)(R + 2 R_old) / 3)
    /// (the RMS integrated over the disk's flowable area, inside R_old and in the ring
    /// beyond it), ρ the ring's dilated bulk density (`Stagnant::rho1`); and its
    /// variance beyond the kept modes and in all, weighted by push ρ h A_f π R².
    pub fn add_disks(&mut self, motion: &[DiskMotion], stagnant: &[Stagnant], h: f64) {
        use std::f64::consts::PI;
        for (m, st) in motion.iter().zip(stagnant) {
            let p = &m.per_disk;
            if !p.lateral {
                continue;
            }
            self.lateral_disks += 1;
            let (r, r0) = (m.r, m.r_old);
            let mass = st.rho1 * h * m.area_frac;
            let area = 2.0 * PI * r0 * r0 / (SHAPE_MODES as f64 + 2.0)
                + PI * (r - r0) * (r + 2.0 * r0) / 3.0;
            self.modes += fixed(p.tail * mass * area);
            let w = p.push * mass * PI * r * r;
            self.variance[0] += fixed(w * m.shape_rest);
            self.variance[1] += fixed(w * m.shape_var);
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
        self.lateral_disks += o.lateral_disks;
        self.modes += o.modes;
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
        let modes = self.modes as f64 / UNIT;
        MarkerCaps {
            moves: self.moves,
            moved_tonne_metres: moved,
            push: cap(PUSH),
            squeeze: cap(SQUEEZE),
            lateral: cap(LATERAL),
            transfer_rim: cap(RIM),
            shape_modes: ModesCount {
                disk_updates: self.lateral_disks,
                dropped_tonne_metres: modes,
                dropped_share: share(modes, moved),
                variance_share: share(self.variance[0] as f64, self.variance[1] as f64),
            },
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

/// The Fourier modes the lateral moves left out, over a run (an estimate).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct ModesCount {
    /// Disk updates with a lateral move (every one keeps `SHAPE_MODES` modes).
    pub disk_updates: u64,
    /// The estimate of Σ mass × the length of the move of the modes left out, t·m.
    pub dropped_tonne_metres: f64,
    /// That over the moved tonne-metres.
    pub dropped_share: f64,
    /// The share of the ring dilation's variance beyond the kept modes (per disk update,
    /// weighted by its push times its mass).
    pub variance_share: f64,
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
    /// The lateral move's Fourier modes beyond `SHAPE_MODES` (an estimate).
    pub shape_modes: ModesCount,
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use super::super::super::imz::{ImzGeom, ImzGrid};
    use super::super::{lateral, prepare, MotionField, Step, WallReach};
    use super::*;

    /// One disk of radius 3 m (h = 1 m, shear band 0.5 m) in open ground that widened from
    /// `r_old`, its ring taking `take` m² of plan area from the interior, its dilation
    /// lopsided by `alpha` (mode 1), prepared.
    fn disk(r_old: f64, take: f64, alpha: f64) -> DiskMotion {
        let mut shape = [0.0; 2 * SHAPE_MODES];
        shape[0] = alpha;
        let mut m = [DiskMotion {
            r: 3.0,
            r_old,
            dv: take,
            w: 0.5,
            area_frac: 1.0,
            flow_frac: 1.0,
            shape,
            ..Default::default()
        }];
        prepare(&mut m, 1.0);
        m[0]
    }

    /// The step of a marker at `p` in the one disk `m` (its IMZ's axis at the origin), and
    /// what the caps cut from it.
    fn step(m: DiskMotion, p: [f64; 3]) -> (Step, Cut) {
        let geoms = vec![ImzGeom {
            x: 0.0,
            y: 0.0,
            z0: 0.0,
            h: 1.0,
            radius: vec![3.0],
        }];
        let grid = ImzGrid::build(&geoms, &[0], [-4.0, -4.0], [8.0, 8.0], 1.0);
        let one = [m];
        let motion: Vec<&[DiskMotion]> = vec![&one[..]];
        let field = MotionField {
            geoms: &geoms,
            motion: &motion,
            grid: &grid,
            ground: None,
            reach: WallReach::default(),
            seed: 0,
            window: false,
        };
        let mut cut = Cut::default();
        (field.step_cut(p, 0, &mut cut), cut)
    }

    /// The tally of 2 t markers on a 0.2 m grid over the disk, at mid-height.
    fn tally(m: DiskMotion) -> CapTally {
        let mut t = CapTally::default();
        for i in -15..=15 {
            for j in -15..=15 {
                let p = [0.2 * i as f64 + 0.01, 0.2 * j as f64, 0.5];
                if p[0].hypot(p[1]) < 3.0 {
                    let (s, cut) = step(m, p);
                    t.add(2.0, &s, &cut);
                }
            }
        }
        t
    }

    /// The tally adds in any order to the same integers, and reports shares of the moved
    /// tonne-metres: a 10 t marker moved 5 m with 1 m of push dropped, and a 30 t one
    /// moved 0.5 m with nothing dropped.
    #[test]
    fn a_tally_reports_dropped_shares_in_any_order() {
        let capped = Step {
            dx: 3.0,
            dz: -4.0,
            ..Default::default()
        };
        let mut cut = Cut::default();
        cut.dropped[PUSH] = 1.0;
        let free = Step {
            dy: 0.5,
            ..Default::default()
        };
        let (mut a, mut b) = (CapTally::default(), CapTally::default());
        a.add(10.0, &capped, &cut);
        b.add(30.0, &free, &Cut::default());
        let (ab, ba) = (a.merge(b), b.merge(a));
        assert_eq!(ab, ba);
        let r = ab.report();
        assert_eq!((r.moves, r.push.moves, r.squeeze.moves), (2, 1, 0));
        assert_eq!(r.moved_tonne_metres, 65.0);
        assert_eq!(r.push.share, 0.5);
        assert_eq!(r.push.dropped_share, 10.0 / 65.0);
        assert_eq!(r.lateral.dropped_share, 0.0);
    }

    /// A disk that widens from 1.2 m to 3 m in one step, absorbing a void far beyond what
    /// the step can move: the push beyond R_old asks for 1.4 m (cap 0.6 m), the squeeze
    /// inside it for more than half of each marker's radius, the lateral move (mode 1 at
    /// 0.5) for 0.7 m (cap 0.3 m). Each cap drops exactly the move asked for past it, and
    /// the tally counts every marker step it cut.
    #[test]
    fn a_disk_more_than_doubling_its_radius_is_capped_and_counted() {
        let m = disk(1.2, 60.0, 0.5);
        let (pd, cap) = (m.per_disk, 0.6);
        assert!(pd.push > 2.0 * cap, "{}", pd.push);
        let fall = |a: f64| 1.0 - (a - m.r_old) / (m.r - m.r_old);
        let (_, c) = step(m, [2.0, 0.0, 0.5]);
        let want = (pd.push - cap) * fall(2.0);
        assert!((c.dropped[PUSH] - want).abs() < 1e-12, "{c:?}");
        let a = 0.6;
        let u = pd.take * pd.profile.flux_inside(a) / (2.0 * PI * a);
        let (_, c) = step(m, [0.0, a, 0.5]);
        assert!((c.dropped[SQUEEZE] - (u - 0.5 * a)).abs() < 1e-12, "{c:?}");
        assert!(c.dropped[LATERAL] > 0.0, "{c:?}");
        let r = tally(m).report();
        eprintln!("{r:?}");
        for c in [r.push, r.squeeze, r.lateral] {
            assert!(c.moves > 50 && c.dropped_share > 0.0, "{r:?}");
        }
        assert_eq!(
            r.push.moves + r.squeeze.moves,
            r.moves,
            "every marker is pushed"
        );
        assert_eq!(r.transfer_rim.moves, 0, "no base crossed");
    }

    /// A disk that widens from 2.9 m to 3 m by a small void: no cap binds, and the tally
    /// reports zeros against the moved tonne-metres.
    #[test]
    fn a_disk_widening_a_little_cuts_nothing() {
        let r = tally(disk(2.9, 0.3, 0.2)).report();
        assert!(r.moves > 500 && r.moved_tonne_metres > 0.0, "{r:?}");
        for c in [r.push, r.squeeze, r.lateral, r.transfer_rim] {
            assert_eq!(c, CapCount::default(), "{r:?}");
        }
    }

    /// The estimate of what the Fourier modes left out would move ([`CapTally::add_disks`])
    /// against the move of those modes, summed over markers on a 2 cm grid over a disk that
    /// widened from 2 m to 3 m. The ring's dilation is 0 on a 40° arc (a neighbour's IMZ)
    /// and the jump elsewhere, sampled at 360 points: its spectrum falls as 1/k, the shape
    /// of the dilations the lateral move reads. The estimate bounds the move of modes K+1
    /// … 179 (Cauchy–Schwarz, and (a/R_old)^K bounds each mode's fall inside R_old), and
    /// is within 3 times it.
    #[test]
    fn the_estimate_of_the_modes_left_out_bounds_their_move() {
        let n = 360;
        let w: Vec<f64> = (0..n)
            .map(|i| {
                if i < 40 {
                    0.0
                } else {
                    n as f64 / (n - 40) as f64
                }
            })
            .collect();
        let theta = |i: usize| 2.0 * PI * i as f64 / n as f64;
        let coef = |k: usize| {
            let (mut c, mut s) = (0.0, 0.0);
            for (i, wi) in w.iter().enumerate() {
                c += (wi - 1.0) * (k as f64 * theta(i)).cos();
                s += (wi - 1.0) * (k as f64 * theta(i)).sin();
            }
            [2.0 * c / n as f64, 2.0 * s / n as f64]
        };
        let all: Vec<[f64; 2]> = (1..n / 2).map(coef).collect();
        let var = w.iter().map(|x| (x - 1.0).powi(2)).sum::<f64>() / n as f64;
        let mut m = disk(2.0, 1.0, 0.0);
        for (k, c) in all[..SHAPE_MODES].iter().enumerate() {
            (m.shape[2 * k], m.shape[2 * k + 1]) = (c[0], c[1]);
        }
        let kept: f64 = all[..SHAPE_MODES]
            .iter()
            .map(|c| 0.5 * (c[0] * c[0] + c[1] * c[1]))
            .sum();
        (m.shape_rest, m.shape_var) = (var - kept, var);
        prepare(std::slice::from_mut(&mut m), 1.0);
        let st = Stagnant {
            rho1: 2.0,
            ..Default::default()
        };
        let mut t = CapTally::default();
        t.add_disks(&[m], &[st], 1.0);
        let estimate = t.modes as f64 / UNIT;
        // The modes left out, marker by marker: every mode's W' less the kept ones'
        // (`lateral`), at 2 t/m³ over 1 m of height.
        let (push, g) = (m.per_disk.push, 0.02);
        let mut moved = 0.0;
        for i in -150..150 {
            for j in -150..150 {
                let (ex, ey) = ((i as f64 + 0.5) * g, (j as f64 + 0.5) * g);
                let a = ex.hypot(ey);
                if a >= m.r {
                    continue;
                }
                let u = [ex / a, ey / a];
                let (scale, tx, ty) = if a <= m.r_old {
                    (-push, ex / m.r_old, ey / m.r_old)
                } else {
                    (-push * (m.r - a) / (m.r - m.r_old), u[0], u[1])
                };
                let (mut wr, mut wi, mut pr, mut pi) = (0.0, 0.0, 1.0, 0.0);
                for c in &all {
                    wr += c[0] * pr + c[1] * pi;
                    wi += c[0] * pi - c[1] * pr;
                    (pr, pi) = (pr * tx - pi * ty, pr * ty + pi * tx);
                }
                let (kx, ky) = lateral(&m, ex, ey, a, u);
                moved += 2.0 * g * g * (scale * wr - kx).hypot(-scale * wi - ky);
            }
        }
        let r = t.report().shape_modes;
        eprintln!("modes left out: moved {moved:.4e} t·m, estimate {estimate:.4e}; {r:?}");
        assert_eq!(r.disk_updates, 1);
        assert!(
            (r.variance_share - (var - kept) / var).abs() < 1e-9,
            "{r:?}"
        );
        assert!(
            moved <= estimate && estimate <= 3.0 * moved,
            "{moved} vs {estimate}"
        );
    }
}
