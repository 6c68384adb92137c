//! Multi-rate marker updates: each marker steps as often as its own speed needs.
//!
//! REBOP moves every mobilised marker at every update (summary §3.3), and the update
//! interval is set by the fastest ground, the opening disk, where one interval moves markers
//! about a disk height h. High in a wide IMZ the plug velocity v ∝ Δv / (π R_i²) is
//! hundreds of times smaller: a marker there moves a few centimetres an update, and in a
//! mine-scale run (daily draw, merged funnels) these slow markers are nearly all of them.
//!
//! So a marker has a level L: it steps once every 2^L updates, by the motion of those 2^L
//! updates summed. The motion of an IMZ is linear in the void Δv_i passed through each disk,
//! and the radial move depends on R_i^old and R_i only, so the summed motion of a window is
//! one [`DiskMotion`](super::imz::DiskMotion) with Δv_i the window's void and R_i^old the
//! radius at its start ([`Window`], kept per level by every IMZ). The windows of level L
//! are aligned: they end at the updates u that are multiples of 2^L, so one set of sums per
//! level serves every marker of that level.
//!
//! After each of its steps a marker takes the highest level at which its last move, scaled
//! to the new window, stays within `resolution.max_marker_move`: a CFL-like bound, like the
//! bound on the draw increment itself. It climbs at most one level a step (a marker whose
//! surroundings start moving is never far behind), may drop any number at once, and may
//! only take a level whose window starts now (L ≤ the number of trailing zeros of u).
//! Markers near a drawpoint keep level 0 and step every update, as before; markers are
//! drawn from there, so the extraction tables keep the update interval's resolution.
//!
//! A window's step is split at the disk bases it reaches (`MotionField::step`): below a
//! base the rest of the window moves the marker in the motion there, as the window's
//! updates would have, where carrying the summed move on by one IMZ's transfer over-drew
//! in the overlaps of IMZs, in proportion to the window's move.
//!
//! Between its steps a marker of level L lags its true position by at most one window's
//! move (≤ `max_marker_move`). Whatever reads marker positions exactly (rilling, marker
//! snapshots, the free surface, the end of the run) first brings every marker up to date:
//! `Engine::catch_up` (each steps by its level's partial window). The air gap and the
//! mobilised disk properties (per period) read the lagged positions; they are block- and
//! disk-scale sums, coarser than the lag. Fines percolation is evaluated per update
//! (`engine::fines`), so with fines on every marker steps every update.

use serde::{Deserialize, Serialize};

/// Highest level: a marker steps at least once every 2^MAX_LEVEL updates.
pub const MAX_LEVEL: u8 = 6;

/// Void passed into and out of a disk over a level's window, and the disk's radius when it
/// began.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Window {
    /// Δv_i summed over the window, m³.
    pub dv: f64,
    /// Void passed out through the disk's top, summed over the window, m³.
    pub dv_out: f64,
    /// R_i at the start of the window, m (0 for a disk opened since).
    pub r_old: f64,
}

/// The cadence rule for one run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cadence {
    /// The most a marker may move in one of its own steps, m (`resolution.max_marker_move`).
    pub max_move: f64,
    /// Highest level in use (0: every marker steps every update).
    pub max_level: u8,
}

impl Cadence {
    /// The rule for a largest move `max_move` (m; 0 or less turns multi-rate off).
    pub fn new(max_move: f64) -> Cadence {
        Cadence {
            max_move,
            max_level: if max_move > 0.0 { MAX_LEVEL } else { 0 },
        }
    }

    /// Highest level whose window ends at update `u` (≥ 1): the levels due then are 0 up to
    /// this one.
    pub fn due(&self, u: u64) -> u8 {
        (u.trailing_zeros() as u8).min(self.max_level)
    }

    /// The level a marker of level `level` takes after moving `moved` (m) in a step that
    /// ends at update `u`.
    #[inline]
    pub fn next_level(&self, level: u8, moved: f64, u: u64) -> u8 {
        let per_update = moved / (1u64 << level) as f64;
        let mut fit = 0u8;
        while fit < self.max_level && per_update * (2u64 << fit) as f64 <= self.max_move {
            fit += 1;
        }
        fit.min(level + 1).min(self.due(u))
    }
}

/// The rows whose level is at most `top` and for which `keep(row)` holds, ascending (in
/// parallel). Most rows are of higher levels than an update's due ones, so the levels are
/// read eight at a time and a word holding none at most `top` is passed over whole.
pub fn rows_due(level: &[u8], top: u8, keep: impl Fn(usize) -> bool + Sync) -> Vec<u32> {
    use rayon::prelude::*;
    const CHUNK: usize = 1 << 14;
    let below = u64::from(top) + 1;
    let ones = u64::from_le_bytes([1; 8]);
    let highs = u64::from_le_bytes([0x80; 8]);
    let chunks: Vec<Vec<u32>> = level
        .par_chunks(CHUNK)
        .enumerate()
        .map(|(c, chunk)| {
            let mut out = Vec::new();
            let mut take = |k: usize| {
                if chunk[k] <= top && keep(c * CHUNK + k) {
                    out.push((c * CHUNK + k) as u32);
                }
            };
            let words = chunk.chunks_exact(8);
            let tail = words.remainder().len();
            for (w, word) in words.enumerate() {
                let x = u64::from_le_bytes(word.try_into().expect("eight bytes"));
                // Some byte of x is below `below` (≤ 7, so the borrow trick holds).
                if x.wrapping_sub(ones * below) & !x & highs != 0 {
                    (8 * w..8 * w + 8).for_each(&mut take);
                }
            }
            (chunk.len() - tail..chunk.len()).for_each(take);
            out
        })
        .collect();
    chunks.concat()
}

/// Adds one update's void per disk (in and out, `dv`) to each level's windows, opening
/// windows for new disks (they began at radius 0).
pub fn accumulate(windows: &mut [Vec<Window>], dv: impl Iterator<Item = (f64, f64)> + Clone) {
    for w in windows.iter_mut() {
        for (i, (v, out)) in dv.clone().enumerate() {
            if i == w.len() {
                w.push(Window::default());
            }
            w[i].dv += v;
            w[i].dv_out += out;
        }
    }
}

/// Starts a new window: no void yet, radii as they are now.
pub fn restart(window: &mut Vec<Window>, radius: &[f64]) {
    window.clear();
    window.extend(radius.iter().map(|&r| Window {
        r_old: r,
        ..Window::default()
    }));
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The word-at-a-time scan finds exactly the rows a plain filter finds, in order.
    #[test]
    fn rows_due_are_the_filters_rows() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for n in [0, 5, 8, 13, 40_000, 70_001] {
            let level: Vec<u8> = (0..n)
                .map(|_| {
                    if rng.random_bool(0.9) {
                        6
                    } else {
                        rng.random_range(0..=6)
                    }
                })
                .collect();
            for top in 0..=MAX_LEVEL {
                let keep = |k: usize| k % 3 != 1;
                let want: Vec<u32> = (0..n as u32)
                    .filter(|&k| level[k as usize] <= top && keep(k as usize))
                    .collect();
                assert_eq!(rows_due(&level, top, keep), want, "n {n}, top {top}");
            }
        }
    }

    #[test]
    fn due_levels_follow_the_trailing_zeros() {
        let c = Cadence::new(0.5);
        assert_eq!(c.due(1), 0);
        assert_eq!(c.due(2), 1);
        assert_eq!(c.due(12), 2);
        assert_eq!(c.due(1 << 20), MAX_LEVEL);
        assert_eq!(Cadence::new(0.0).due(1 << 20), 0);
    }

    #[test]
    fn levels_climb_one_at_a_time_drop_at_once_and_stay_aligned() {
        let c = Cadence::new(0.5);
        // Still: climbs one level a step, up to what the window start allows.
        assert_eq!(c.next_level(0, 0.0, 64), 1);
        assert_eq!(c.next_level(3, 0.0, 64), 4);
        assert_eq!(c.next_level(3, 0.0, 8), 3);
        assert_eq!(c.next_level(MAX_LEVEL, 0.0, 64), MAX_LEVEL);
        // 0.1 m an update: a window of 4 updates moves 0.4 m ≤ 0.5, of 8 would move 0.8.
        assert_eq!(c.next_level(2, 0.4, 64), 2);
        assert_eq!(c.next_level(1, 0.2, 64), 2);
        // Fast: back to every update at once.
        assert_eq!(c.next_level(5, 32.0, 64), 0);
        // Off: always 0.
        assert_eq!(Cadence::new(0.0).next_level(0, 0.0, 64), 0);
    }

    #[test]
    fn windows_sum_the_void_and_keep_the_starting_radius() {
        let mut w = vec![Vec::new(), Vec::new()];
        restart(&mut w[0], &[2.0]);
        restart(&mut w[1], &[2.0]);
        accumulate(&mut w, [(1.0, 0.5), (0.5, 0.0)].into_iter());
        accumulate(&mut w, [(1.0, 0.5), (0.5, 0.0)].into_iter());
        assert_eq!(
            w[0],
            vec![
                Window {
                    dv: 2.0,
                    dv_out: 1.0,
                    r_old: 2.0
                },
                Window {
                    dv: 1.0,
                    dv_out: 0.0,
                    r_old: 0.0
                }
            ]
        );
        restart(&mut w[0], &[2.5, 1.0]);
        assert_eq!(
            w[0][1],
            Window {
                dv: 0.0,
                dv_out: 0.0,
                r_old: 1.0
            }
        );
        assert_eq!(w[1][0].dv, 2.0);
    }
}
