//! Markers (summary §3.3, DESIGN §4.2): tracked parcels of material, held column-wise.
//!
//! Markers start on a regular lattice of spacing `s` over the block grid. A lattice site
//! stands for the cube of side s around it at its block's in-situ density, ρ (1 − n0) s³
//! (the cells of the last sites along an axis run to the grid's face), so the marker field
//! is as dense as the ground everywhere and its mass adds up to the block model's where the
//! density is uniform; a block's own mass is exact where s divides it. A drawn marker
//! reports its cell's grade, lithology and waste share: the mean over the blocks the cell
//! overlaps, weighted by their in-situ solids there (`Lattice::cell_blocks`), so the
//! lattice carries the block model's metal where the density is uniform, whatever the
//! spacing (its size and fines are its site's block's). Stagnant ground is
//! never materialised: a site becomes a marker (row of [`Markers`]) only when an IMZ
//! engulfs it, and the marker id is the site index. So stagnant ground costs nothing per increment, and the lattice itself
//! is the spatial index of the stagnant markers.
//!
//! # Motion of a marker at radius a_m in disk i (per IMZ, summed by superposition)
//! - Vertical, cone (R_i ≤ w_i): Δz = −3 Δv_i (1 − a_m/R_i) / (π R_i²).
//! - Vertical, frustum (R_i > w_i, plug radius R_p = R_i − w_i):
//!   plug Δz = −3 Δv_i / (π (R_i² + R_i R_p + R_p²)); annulus the same × (1 − (a_m − R_p)/w_i).
//!   Each disk's profile ([`Profile`](crate::engine::imz::Profile)) and the other constants of
//!   this list are worked out once per disk and update ([`prepare`]), so a marker's moves
//!   multiply where these formulas divide.
//! - Radial, from disk expansion ΔR_i = R_i − R_i^old. The ring R_i^old → R_i is stagnant
//!   ground at n0 that dilates to n1 (`engine::imz`, the volume balance): it swells inward
//!   by the void the disk absorbed, v_a = Δv_i − Δv_out (the void in through its base less
//!   the void out through its top), over the flowable share f of the perimeter (rays with
//!   no ring are not pushed), and squeezes the interior by as much. The squeeze follows the
//!   vertical move's profile, streamtube by streamtube: the area inside radius a ≤ R_old
//!   loses the share F(a) of v_a / (h f) that the profile passes inside a ([`radial`]);
//!   beyond R_old the move falls linearly to zero at the new radius. To first order the
//!   peak, at R_old, is ΔR_i (n1 − n0)/(1 − n1), the thickness the ring gains. The summary
//!   prints the factor inverted, (1 − n1)/(n1 − n0); taken literally that moves a marker of
//!   a new disk (R^old = 0) by ~3.7 R across the axis, and diverges as the porosity jump
//!   vanishes, so we use the volume-balance form
//!   (`disk_moves::tests::radial_move_is_the_ring_dilation`).
//!   Ground widened into for free (already dilated by a neighbour) absorbs no void and is
//!   not pushed. A new disk (R^old = 0) has no interior to push; its ring dilates by the
//!   vertical move alone.
//! - Lateral, where the ring's dilation differs around the perimeter (part of it inside a
//!   neighbour, already at n1): the radial move pushes the same on every ray, so the part
//!   inside the neighbour would dilate past n1 and the stagnant part stop short of it. A
//!   potential flow inside R_old carries the difference across the disk, from the side
//!   that must dilate to the side that must not ([`lateral`]); it changes no volume inside
//!   the disk. Two drawpoints 8 m apart (4 m openings, 15 m blocks, 2.5 m markers) draw
//!   1.001 of their schedule in markers with it and 0.973–0.976 without; 15 m apart, 0.996
//!   and 0.978–0.982 (an isolated one, 0.981: markers still on their way).
//! - The vertical move interpolates the void linearly from Δv_i at the disk's base to
//!   Δv_out at its top, so it stretches the disk's material by v_a, the volume the radial
//!   move took from the interior: the interior stays at n1 and the ring reaches n1. Void
//!   that leaves the top disk (to the free surface, or into an air gap under uncaved
//!   ground) moves the top disk's markers down by it, so the surface subsides by the void
//!   that left and an air gap opens above the markers, not inside them.
//! - Transfer into the disk below: a marker that crosses a disk's base keeps its
//!   streamtube (`transfer`); under overlap, it takes one IMZ's transfer, drawn with that
//!   IMZ's share of its vertical move, on crossings decided by the summed move
//!   ([`MotionField::step`]). Between two cones this is the summary's Δa′ = −(1 −
//!   R_{i−1}/R_i) a_m and Δz′ = −p (R_i² − R_{i−1}²)/R_{i−1}², p the depth reached below the
//!   disk base z_i (the summary's Δz′ with its Δz cancelled); between profiles of other
//!   shapes it is the volume-conserving form of the same idea. A move that reaches past
//!   the next base down as well (a step near a narrow opening, disks thinner than the
//!   move) is transferred base by base, each from where the one above left it. Applying
//!   the first base's transfer only lost volume: in Castro isolated draw at 40 opening
//!   disks per update the drawn material came from 15% too low (4.3% now), at h = 0.3 d̄
//!   8.4% (1.1% now), and an isolated demo drawpoint at h = s/2 delivered 0.985 of its
//!   schedule in markers (1.000 now; `tests/it/stability.rs`, `docs::validation`).
//! - Walls (method of images): an IMZ whose disk passes one of the model's vertical walls
//!   also moves each marker as its mirror image across that wall would, plan components
//!   mirrored ([`MotionField::step`]). Along the wall the two cancel through it, so nothing
//!   crosses, and the disk's flux, which the wall would cut, stays whole inside the model
//!   (`walls::tests::walls_mirror_the_imzs`). Dividing the moves by the flowable share A_f
//!   instead keeps the volume but not where it goes: the transfers map each ray by the uncut
//!   disk's shares, so the rays towards a wall let out more than they take in. On the
//!   demo, whose IMZs widen across the whole model, the drawpoints next to the walls then
//!   drew 0.85–0.95 of their schedule in markers and the row inside them 1.09–1.21; with
//!   images, 0.92–1.03 (never-short drawpoints, p10 0.931, p90 1.014). Past a corner, the
//!   IMZ's double image (mirrored across both walls, both plan components mirrored) moves
//!   the marker too: without it the demo's two corner drawpoints that are never short drew
//!   0.971 of their schedule, with it 0.988 and 0.991. A marker visits a wall's images
//!   only where it is within their reach at its height ([`WallReach`]): the demo's IMZs
//!   all reach the walls near the top, and visiting every wall's images wherever the
//!   widest disk reached cost 1.21× the run against that. Nothing measurable at mine scale.
//!   A move that would still carry a marker through a wall (an image's transfer, which
//!   points beyond it) ends at its mirror inside: the image's move beyond the wall is the
//!   mirror of the IMZ's own move of the marker's mirror.
//! - Shear strain in the shear annulus: Γ = |Δz| / min(R, w); shear work Γ σ_n with the
//!   Janssen σ_n = ρ_s (1 − n1) g R / (2 tan φ) (summary §6.3).
//!
//! A marker that leaves the lowest disk is drawn, credited to the IMZ that moved it most.

mod bins;
mod caps;
mod disk_moves;
mod lattice;
mod motion;
mod walls;

use rayon::prelude::*;

use super::cadence::Cadence;

pub use bins::Bins;
pub use caps::{CapCount, CapTally, Cut, MarkerCaps, ModesCount};
pub use disk_moves::{lateral, prepare, radial};
pub use lattice::{Lattice, Rim};
pub use motion::{MotionField, Step};
pub use walls::WallReach;

/// Calls the macro `$m` with the names of every column of [`Markers`], so that what is done
/// to each column (reorder, append, move a row) is written once and cannot miss one.
macro_rules! columns {
    ($m:ident) => {
        $m!(
            id, x, y, z, mass, block, frag, strain, work, rill, frag0, attrited, percolated, level,
            at
        )
    };
}

/// Mobilised markers, struct of arrays. `id` is the stable identity (the lattice site);
/// row order changes no result (every sum over markers is taken in the order of their ids,
/// or exactly), so [`Bins::tidy`] may reorder the rows for the cache.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct Markers {
    /// Marker id (lattice site index).
    pub id: Vec<u64>,
    /// Current position.
    pub x: Vec<f64>,
    /// Current position.
    pub y: Vec<f64>,
    /// Current position.
    pub z: Vec<f64>,
    /// Mass, t.
    pub mass: Vec<f64>,
    /// Block of origin (row in the block model).
    pub block: Vec<u32>,
    /// Representative fragment size, m.
    pub frag: Vec<f64>,
    /// Accumulated shear strain Γ.
    pub strain: Vec<f64>,
    /// Accumulated shear work Γ σ_n, kPa.
    pub work: Vec<f64>,
    /// Horizontal distance rilled on the free surface so far, m (`engine::rilling`).
    pub rill: Vec<f64>,
    /// Primary fragment size d0, m (`engine::fragmentation`).
    pub frag0: Vec<f64>,
    /// Attrited mass fraction W (`engine::fragmentation`).
    pub attrited: Vec<f64>,
    /// Accumulated percolation distance, m (`engine::fines`).
    pub percolated: Vec<f64>,
    /// Cadence level L: the marker steps once every 2^L updates (`engine::cadence`).
    pub level: Vec<u8>,
    /// The block the marker lies in now (row in the block model; `u32::MAX` outside every
    /// block), as the air gap's block masses last counted it (`engine::air_gap`).
    pub at: Vec<u32>,
}

/// Drawn markers: the moving columns plus who drew them and when.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct DrawnMarkers {
    /// The markers as they were when drawn.
    pub m: Markers,
    /// Drawpoint that drew each.
    pub drawpoint: Vec<u32>,
    /// Period number in which each was drawn.
    pub period: Vec<i64>,
    /// Draw time τ of each: its drawpoint's cumulative scheduled tonnes at the middle of the
    /// step that drew it, t (`engine::crediting`).
    #[serde(default)]
    pub tau: Vec<f64>,
}

impl Markers {
    /// Number of markers.
    pub fn len(&self) -> usize {
        self.id.len()
    }

    /// The volume marker row `k` fills in flowing ground: its mass at its block's n1, m³.
    pub fn volume_at_n1(&self, k: usize, bm: &crate::model::BlockModel) -> f64 {
        let b = self.block[k] as usize;
        self.mass[k] / (bm.density[b] * (1.0 - bm.n1[b]))
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.id.is_empty()
    }

    /// Whether every column has one value per marker (a decoded checkpoint may not).
    pub fn is_consistent(&self) -> bool {
        let n = self.id.len();
        macro_rules! same_length {
            ($($c:ident),*) => { true $(&& self.$c.len() == n)* };
        }
        columns!(same_length)
    }

    /// Reorders the rows: row k takes the old row `perm[k]` (`perm` a permutation of the
    /// rows).
    pub fn permute(&mut self, perm: &[u32]) {
        fn gather<T: Copy + Send + Sync>(v: &mut Vec<T>, perm: &[u32]) {
            let new: Vec<T> = if perm.len() < 1 << 14 {
                perm.iter().map(|&k| v[k as usize]).collect()
            } else {
                perm.par_iter().map(|&k| v[k as usize]).collect()
            };
            *v = new;
        }
        macro_rules! gather_all {
            ($($c:ident),*) => { $(gather(&mut self.$c, perm);)* };
        }
        columns!(gather_all);
    }

    /// Moves every row of `other` to the end of these.
    pub fn append(&mut self, other: &mut Markers) {
        macro_rules! append_all {
            ($($c:ident),*) => { $(self.$c.append(&mut other.$c);)* };
        }
        columns!(append_all);
    }

    /// Appends a marker, lying in its block of origin.
    pub fn push(&mut self, id: u64, p: [f64; 3], mass: f64, block: u32, frag: f64) {
        self.id.push(id);
        self.x.push(p[0]);
        self.y.push(p[1]);
        self.z.push(p[2]);
        self.mass.push(mass);
        self.block.push(block);
        self.frag.push(frag);
        self.strain.push(0.0);
        self.work.push(0.0);
        self.rill.push(0.0);
        self.frag0.push(frag);
        self.attrited.push(0.0);
        self.percolated.push(0.0);
        self.level.push(0);
        self.at.push(block);
    }

    /// Moves row `k` out (swap-remove) and appends it to `to`.
    pub fn take_into(&mut self, k: usize, to: &mut Markers) {
        macro_rules! take_all {
            ($($c:ident),*) => { $(to.$c.push(self.$c.swap_remove(k));)* };
        }
        columns!(take_all);
    }
}

/// What a mechanism adds to the marker pass before any step is applied (fines percolation).
pub trait StepExtra: Sync {
    /// Adds to the step `st` of marker row `k`. Pure per marker, like the step itself.
    fn step(&self, mk: &Markers, k: usize, st: &mut Step);

    /// Amends the pass's steps once all are known: `steps[j]` is row `rows[j]`'s (row `j`'s
    /// where `rows` is `None`). Its result must not depend on the rows' order.
    fn settle(&self, _mk: &Markers, _rows: Option<&[u32]>, _steps: &mut [Step]) {}
}

impl<F: Fn(&Markers, usize, &mut Step) + Sync> StepExtra for F {
    fn step(&self, mk: &Markers, k: usize, st: &mut Step) {
        self(mk, k, st)
    }
}

/// A mechanism's part of the marker pass ([`StepExtra`]).
pub type StepHook<'a> = &'a dyn StepExtra;

/// Moves every marker once (parallel, pure per marker, so the result does not depend on
/// the number of threads). Returns the rows drawn, in row order, with their drawpoint,
/// and the caps' counts over the steps (`caps`). `extra` may add to each marker's step
/// before it is applied (fines percolation); it must be pure per marker too.
pub fn move_markers(
    mk: &mut Markers,
    field: &MotionField,
    extra: Option<StepHook>,
) -> (Vec<(usize, u32)>, CapTally) {
    let Some(extra) = extra else {
        // No hook reads the markers: step and apply in one pass. A marker's step depends
        // on its own position only, so this is the two-pass result bit for bit, without the
        // per-update array of steps (72 bytes a marker, fresh pages every update).
        let none = || (Vec::new(), CapTally::default());
        return (
            mk.x.par_iter_mut(),
            mk.y.par_iter_mut(),
            mk.z.par_iter_mut(),
            mk.strain.par_iter_mut(),
            mk.work.par_iter_mut(),
            (mk.id.par_iter(), mk.mass.par_iter()),
        )
            .into_par_iter()
            .enumerate()
            .fold(
                none,
                |(mut drawn, mut tally), (k, (x, y, z, g, w, (&id, &m)))| {
                    let mut cut = Cut::default();
                    let s = field.step_cut([*x, *y, *z], id, &mut cut);
                    *x += s.dx;
                    *y += s.dy;
                    *z += s.dz;
                    *g += s.strain;
                    *w += s.work;
                    tally.add(m, &s, &cut);
                    if s.drawn_by != u32::MAX {
                        drawn.push((k, s.drawn_by));
                    }
                    (drawn, tally)
                },
            )
            .reduce(none, |(mut a, ta), (mut b, tb)| {
                a.append(&mut b);
                (a, ta.merge(tb))
            });
    };
    let (mut steps, cuts): (Vec<Step>, Vec<Cut>) = (0..mk.len())
        .into_par_iter()
        .map(|k| {
            let mut cut = Cut::default();
            let mut s = field.step_cut([mk.x[k], mk.y[k], mk.z[k]], mk.id[k], &mut cut);
            extra.step(mk, k, &mut s);
            (s, cut)
        })
        .unzip();
    extra.settle(mk, None, &mut steps);
    (
        mk.x.par_iter_mut(),
        mk.y.par_iter_mut(),
        mk.z.par_iter_mut(),
        mk.strain.par_iter_mut(),
        mk.work.par_iter_mut(),
        &steps,
    )
        .into_par_iter()
        .for_each(|(x, y, z, g, w, s)| {
            *x += s.dx;
            *y += s.dy;
            *z += s.dz;
            *g += s.strain;
            *w += s.work;
        });
    mk.percolated
        .par_iter_mut()
        .zip(&steps)
        .for_each(|(l, s)| *l += s.perc);
    let tally = (&mk.mass, (&steps, &cuts))
        .into_par_iter()
        .fold(CapTally::default, |mut t, (&m, (s, cut))| {
            t.add(m, s, cut);
            t
        })
        .reduce(CapTally::default, CapTally::merge);
    let drawn = steps
        .iter()
        .enumerate()
        .filter(|(_, s)| s.drawn_by != u32::MAX)
        .map(|(k, s)| (k, s.drawn_by))
        .collect();
    (drawn, tally)
}

/// Moves the marker rows `rows` (ascending, distinct) once: [`move_markers`] restricted to
/// the markers that a drawing IMZ can reach (the rows of the active cells of [`Bins`]).
/// Every other marker would take a zero step, so the result is [`move_markers`]'s bit for
/// bit. Parallel over chunks of rows, each writing its own window of the columns.
///
/// `fields[L]` is the motion of cadence level L (`engine::cadence`). Without a cadence
/// every row steps by `fields[0]`; with `(cadence, u)` each row steps by its own level's
/// field and then takes its next level for update `u`. Each chunk counts the caps over
/// its steps (`caps`), and the chunks' counts are added after the pass.
pub fn move_rows(
    mk: &mut Markers,
    fields: &[MotionField],
    extra: Option<StepHook>,
    rows: &[u32],
    cadence: Option<(&Cadence, u64)>,
) -> (Vec<(usize, u32)>, CapTally) {
    if rows.is_empty() {
        return (Vec::new(), CapTally::default());
    }
    debug_assert!(rows.windows(2).all(|w| w[0] < w[1]));
    let chunk = (rows.len() / (16 * rayon::current_num_threads())).max(256);
    let chunks: Vec<&[u32]> = rows.chunks(chunk).collect();
    let spans: Vec<(usize, usize)> = chunks
        .iter()
        .map(|c| (c[0] as usize, c[c.len() - 1] as usize + 1))
        .collect();
    let (steps, cuts): (Vec<Step>, Vec<Cut>) = match extra {
        Some(extra) => {
            let (mut steps, cuts): (Vec<Step>, Vec<Cut>) = rows
                .par_iter()
                .map(|&k| {
                    let k = k as usize;
                    let mut cut = Cut::default();
                    let p = [mk.x[k], mk.y[k], mk.z[k]];
                    let mut s = fields[0].step_cut(p, mk.id[k], &mut cut);
                    extra.step(mk, k, &mut s);
                    (s, cut)
                })
                .unzip();
            extra.settle(mk, Some(rows), &mut steps);
            (steps, cuts)
        }
        None => (Vec::new(), Vec::new()),
    };
    let (hooked, steps, cuts) = (extra.is_some(), &steps[..], &cuts[..]);
    let (ids, mass) = (&mk.id, &mk.mass);
    let firsts: Vec<usize> = (0..chunks.len()).map(|c| c * chunk).collect();
    let drawn: Vec<(Vec<(usize, u32)>, CapTally)> = (
        (chunks, spans.clone(), firsts),
        windows(&mut mk.x, &spans),
        windows(&mut mk.y, &spans),
        windows(&mut mk.z, &spans),
        windows(&mut mk.strain, &spans),
        windows(&mut mk.work, &spans),
        windows(&mut mk.percolated, &spans),
        windows(&mut mk.level, &spans),
    )
        .into_par_iter()
        .map(|((rows, (lo, _), first), x, y, z, g, w, l, lv)| {
            let (mut drawn, mut tally) = (Vec::new(), CapTally::default());
            for (n, &k) in rows.iter().enumerate() {
                let i = k as usize - lo;
                let (s, cut) = if hooked {
                    (steps[first + n], cuts[first + n])
                } else {
                    let level = if cadence.is_some() { lv[i] } else { 0 };
                    let mut cut = Cut::default();
                    let p = [x[i], y[i], z[i]];
                    (
                        fields[level as usize].step_cut(p, ids[k as usize], &mut cut),
                        cut,
                    )
                };
                x[i] += s.dx;
                y[i] += s.dy;
                z[i] += s.dz;
                g[i] += s.strain;
                w[i] += s.work;
                if hooked {
                    l[i] += s.perc;
                }
                let moved = (s.dx * s.dx + s.dy * s.dy + s.dz * s.dz).sqrt();
                tally.add_moved(mass[k as usize], moved, &cut);
                if let Some((c, u)) = cadence {
                    lv[i] = c.next_level(lv[i], moved, u);
                }
                if s.drawn_by != u32::MAX {
                    drawn.push((k as usize, s.drawn_by));
                }
            }
            (drawn, tally)
        })
        .collect();
    let tally = drawn.iter().fold(CapTally::default(), |t, d| t.merge(d.1));
    (drawn.into_iter().flat_map(|d| d.0).collect(), tally)
}

/// The candidate tests and hits of a marker pass over `rows` (`engine::account`), each row
/// at its own cadence level's field (level 0 where there is one field).
pub fn count_candidates(mk: &Markers, fields: &[MotionField], rows: &[u32]) -> (u64, u64) {
    rows.par_iter()
        .map(|&k| {
            let k = k as usize;
            let level = if fields.len() > 1 {
                mk.level[k] as usize
            } else {
                0
            };
            fields[level].candidates([mk.x[k], mk.y[k], mk.z[k]])
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
}

/// Disjoint windows `col[lo..hi]` for ascending, non-overlapping spans.
fn windows<'a, T>(mut col: &'a mut [T], spans: &[(usize, usize)]) -> Vec<&'a mut [T]> {
    let mut out = Vec::with_capacity(spans.len());
    let mut at = 0;
    for &(lo, hi) in spans {
        let (_, rest) = std::mem::take(&mut col).split_at_mut(lo - at);
        let (w, rest) = rest.split_at_mut(hi - lo);
        out.push(w);
        col = rest;
        at = hi;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `columns!` names every field of `Markers`, so the row operations written with it
    /// keep every column the same length: two markers, reordered, appended to each other
    /// and one row moved out.
    #[test]
    fn the_column_list_holds_every_column() {
        macro_rules! names {
            ($($c:ident),*) => { vec![$(stringify!($c)),*] };
        }
        let listed: Vec<&str> = columns!(names);
        let json = serde_json::to_value(Markers::default()).unwrap();
        let mut fields: Vec<&str> = json
            .as_object()
            .unwrap()
            .keys()
            .map(String::as_str)
            .collect();
        let mut sorted = listed.clone();
        fields.sort_unstable();
        sorted.sort_unstable();
        assert_eq!(fields, sorted);

        let mut a = Markers::default();
        a.push(7, [1.0, 2.0, 3.0], 10.0, 4, 0.5);
        a.push(9, [4.0, 5.0, 6.0], 20.0, 5, 0.7);
        a.permute(&[1, 0]);
        assert_eq!((a.id.clone(), a.z.clone()), (vec![9, 7], vec![6.0, 3.0]));
        let mut b = a.clone();
        a.append(&mut b);
        assert!(a.is_consistent() && a.len() == 4 && b.is_empty() && b.is_consistent());
        a.take_into(0, &mut b);
        assert!(a.is_consistent() && b.is_consistent());
        assert_eq!(
            (a.id.clone(), b.id.clone(), b.mass.clone()),
            (vec![7, 7, 9], vec![9], vec![20.0])
        );
        a.level.pop();
        assert!(!a.is_consistent());
    }
}
