//! Free surface, air gap and rilling (summary §§1, 3.1 and 8; DESIGN §4.7).
//!
//! # Free surface
//! The top of the caved material, as a height field H over the lattice columns (one
//! column per marker-lattice site in plan, spacing s): the highest of the moving markers in
//! the column (their centre + half their height at n1, below) and the in-situ caved ground
//! (the highest flowable lattice site that no IMZ has engulfed, + s/2). Draw lowers it where an IMZ reaches it,
//! and the marker motion then leaves a surface cone above the drawpoint (summary §3.1).
//!
//! # Rilling
//! Loose material on the surface cannot stand steeper than the angle of repose
//! β = 12° + φ/2 (DESIGN §4.7, φ the friction angle of the material that would move).
//! Slopes are measured between rilling cells of `CELL` × `CELL` lattice columns, whose
//! height is the mean of their columns' surfaces: a rilling step moves the top parcel
//! (marker) of a cell's highest column to the lowest column of the neighbouring cell down
//! which the slope is steepest, wherever H_q − H_n > tan β · |q − n|, and repeats until no
//! slope between neighbouring cells is steeper than repose.
//!
//! Resolution: a marker stands for s³ of ground at n0, so in situ a parcel is s thick in
//! its column; moving, or rilled, it is dilated to n1 and s (1 − n0)/(1 − n1) thick (its
//! solids at n1 over the column's area s²; the top of a column is its top marker's centre
//! plus half that). A single column's height changes by whole parcels: one parcel between
//! neighbouring columns is already a 45° slope, steeper than repose. A cell's mean height
//! changes by about s / CELL² per parcel, so slopes between cells (3 s apart) are resolved
//! to 1/27 ≈ 2° at CELL = 3. A move must also bring the parcel's centre down by at least
//! s/2 (with a parcel s thick at both ends, source top − destination top ≥ 1.5 s), so every
//! move lowers the pile and the step ends.
//! - Mass: markers are moved, never made or lost; in-situ caved ground at the top of a
//!   column is mobilised (engulfed) first, as the IMZs do.
//! - Uncaved ground: a parcel only lands in flowable ground. It may travel laterally under
//!   uncaved ground (into an air gap beneath the cave back), as at Henderson's southeast
//!   boundary (summary §8).
//! - Each marker carries the horizontal distance it has rilled, so the extraction report
//!   gives per drawpoint the share of material that arrived by rilling and from how far.
//!
//! # Air gap
//! A block counts as air once it holds less than a quarter of its in-situ mass
//! (`air_fill`, MassFlow's 0.75 empty). The air-gap height of a block column is the height
//! of its air blocks; it forms when draw outpaces cave advance (the IMZ cannot grow into
//! uncaved ground, so its void stays at its top), and closes when the cave catches up (the
//! IMZ then grows into the newly caved ground and passes the stored void up into it).

use super::markers::{Lattice, Markers};
use crate::model::BlockModel;

/// Free-surface height H of every lattice column (i + n_x j), m; −∞ for a column with no
/// caved material.
pub fn surface(
    lat: &Lattice,
    bm: &BlockModel,
    period: i64,
    engulfed: &[bool],
    mk: &Markers,
) -> Vec<f64> {
    let (nx, ny, nz) = (lat.n[0], lat.n[1], lat.n[2]);
    let mut h = vec![f64::NEG_INFINITY; nx * ny];
    for j in 0..ny {
        for i in 0..nx {
            h[i + nx * j] = in_situ_top(lat, bm, period, engulfed, i, j, nz);
        }
    }
    for k in 0..mk.len() {
        if let Some(c) = column(lat, mk.x[k], mk.y[k]) {
            h[c] = h[c].max(mk.z[k] + marker_half(bm, mk, k, lat.s));
        }
    }
    h
}

/// Top (+ s/2) of the highest flowable, not yet engulfed lattice site of column (i, j).
fn in_situ_top(
    lat: &Lattice,
    bm: &BlockModel,
    period: i64,
    engulfed: &[bool],
    i: usize,
    j: usize,
    nz: usize,
) -> f64 {
    for k in (0..nz).rev() {
        let id = lat.id(i, j, k);
        if engulfed[id] {
            continue;
        }
        let p = lat.pos(id);
        if bm.locate(p).is_some_and(|b| bm.flowable(b, period)) {
            return p[2] + 0.5 * lat.s;
        }
    }
    f64::NEG_INFINITY
}

/// Lattice column of a plan position, or None outside the lattice.
#[inline]
pub fn column(lat: &Lattice, x: f64, y: f64) -> Option<usize> {
    let i = (x - lat.origin[0]) / lat.s;
    let j = (y - lat.origin[1]) / lat.s;
    if !(i >= 0.0 && j >= 0.0) {
        return None;
    }
    let (i, j) = (i as usize, j as usize);
    (i < lat.n[0] && j < lat.n[1]).then_some(i + lat.n[0] * j)
}

/// Where a parcel dropped on a column whose surface is at `h` comes to rest: its centre
/// `half` its height above the surface (the floor of the lattice for an empty column).
#[inline]
fn landing(lat: &Lattice, h: f64, half: f64) -> f64 {
    h.max(lat.origin[2]) + half
}

/// Half the height a marker of block `b` and mass `mass` stands for in its column: its
/// solids at the block's dilated porosity, m / (ρ_s (1 − n1)), over the column's area s².
/// Moving ground is at n1 (the IMZ's balance), and so is a parcel that rills: stacked s
/// apart, as the lattice holds them in situ, rilled parcels would lie at n0, and the demo
/// with rilling on drew 1.05–1.15× its schedule in markers over its last five periods.
#[inline]
fn half_height(bm: &BlockModel, b: usize, mass: f64, s: f64) -> f64 {
    0.5 * mass / (bm.density[b] * (1.0 - bm.n1[b]) * s * s)
}

/// [`half_height`] of marker `k`.
#[inline]
fn marker_half(bm: &BlockModel, mk: &Markers, k: usize, s: f64) -> f64 {
    half_height(bm, mk.block[k] as usize, mk.mass[k], s)
}

/// Rilling cells are CELL × CELL lattice columns (see the module docs).
pub const CELL: i64 = 3;

/// What a rilling step did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RillStats {
    /// Parcels moved.
    pub moves: u64,
    /// Mass moved, t.
    pub mass: f64,
    /// Sites of in-situ caved ground mobilised to rill.
    pub mobilised: u64,
}

/// The state a rilling step reads and changes (borrowed from the engine).
pub struct RillState<'a> {
    /// Marker lattice.
    pub lattice: &'a Lattice,
    /// Block model.
    pub blocks: &'a BlockModel,
    /// Period (flowability).
    pub period: i64,
    /// Engulfed lattice sites.
    pub engulfed: &'a mut [bool],
    /// Engulfed in-situ mass per block, t.
    pub engulfed_mass: &'a mut [f64],
    /// Marker mass of each block at an interior lattice site, t (`Lattice::unit_masses`).
    pub unit_mass: &'a [f64],
    /// Moving markers.
    pub markers: &'a mut Markers,
    /// Primary fragment size of a newly mobilised site: (block, site id) → d0, m.
    pub size: &'a dyn Fn(usize, u64) -> f64,
}

/// tan(12° + φ/2): the slope of repose of material with friction angle φ (degrees).
#[inline]
pub fn tan_repose(phi: f64) -> f64 {
    (12.0 + 0.5 * phi).to_radians().tan()
}

/// One rilling step: moves surface parcels downslope until no slope between neighbouring
/// cells is steeper than repose. Deterministic: cells are visited in index order and ties
/// go to the lowest index.
pub fn rill(st: &mut RillState) -> RillStats {
    let lat = *st.lattice;
    let bm = st.blocks;
    let (nx, ny) = (lat.n[0], lat.n[1]);
    let s = lat.s;
    let cell = CELL as usize;
    let (cx, cy) = (nx.div_ceil(cell), ny.div_ceil(cell));
    let mut stats = RillStats::default();
    // Moving markers per column, sorted by height (top last).
    let mut stacks: Vec<Vec<usize>> = vec![Vec::new(); nx * ny];
    for k in 0..st.markers.len() {
        if let Some(c) = column(&lat, st.markers.x[k], st.markers.y[k]) {
            stacks[c].push(k);
        }
    }
    let mk = &*st.markers;
    for v in &mut stacks {
        v.sort_by(|&a, &b| mk.z[a].total_cmp(&mk.z[b]).then(mk.id[a].cmp(&mk.id[b])));
    }
    let mut in_situ: Vec<f64> = (0..nx * ny)
        .map(|c| in_situ_top(&lat, bm, st.period, st.engulfed, c % nx, c / nx, lat.n[2]))
        .collect();
    let top = |stacks: &[Vec<usize>], in_situ: &[f64], mk: &Markers, c: usize| -> f64 {
        let m = stacks[c]
            .last()
            .map_or(f64::NEG_INFINITY, |&k| mk.z[k] + marker_half(bm, mk, k, s));
        m.max(in_situ[c])
    };
    let columns = |q: usize| {
        let (qi, qj) = (q % cx * cell, q / cx * cell);
        (qj..(qj + cell).min(ny))
            .flat_map(move |j| (qi..(qi + cell).min(nx)).map(move |i| i + nx * j))
    };
    // Mean surface height of a cell over its columns that hold material.
    let mean = |stacks: &[Vec<usize>], in_situ: &[f64], mk: &Markers, q: usize| -> f64 {
        let (mut sum, mut n) = (0.0, 0usize);
        for c in columns(q) {
            let h = top(stacks, in_situ, mk, c);
            if h.is_finite() {
                sum += h;
                n += 1;
            }
        }
        if n == 0 {
            f64::NEG_INFINITY
        } else {
            sum / n as f64
        }
    };
    let mut queue: std::collections::VecDeque<usize> = (0..cx * cy).collect();
    let mut queued = vec![true; cx * cy];
    // Each move lowers a parcel by at least s/2; the bound only guards against a bug.
    let max_moves = 64 * (nx * ny * lat.n[2]) as u64;
    while let Some(q) = queue.pop_front() {
        queued[q] = false;
        let h_q = mean(&stacks, &in_situ, st.markers, q);
        if !h_q.is_finite() {
            continue;
        }
        // The parcel that would move: the top of the cell's highest column.
        // Columns by the height of their tops; ties go to the lower index either way.
        let height = |k: usize| top(&stacks, &in_situ, st.markers, k);
        let Some(c) = columns(q).max_by(|&a, &b| height(a).total_cmp(&height(b)).then(b.cmp(&a)))
        else {
            continue;
        };
        let h_c = height(c);
        let from_site = stacks[c]
            .last()
            .is_none_or(|&k| st.markers.z[k] + marker_half(bm, st.markers, k, s) < in_situ[c]);
        let site = |h: f64| {
            let k = ((h - 0.5 * s - lat.origin[2]) / s - 0.5).round().max(0.0) as usize;
            lat.id(c % nx, c / nx, k.min(lat.n[2] - 1))
        };
        let phi = if from_site {
            bm.locate(lat.pos(site(in_situ[c])))
                .map_or(f64::NAN, |b| bm.friction[b])
        } else {
            bm.friction[st.markers.block[*stacks[c].last().unwrap()] as usize]
        };
        let tan_b = tan_repose(phi);
        // Half the height the parcel stands for where it is, and where it lands.
        let half_here = if from_site {
            0.5 * s
        } else {
            marker_half(bm, st.markers, *stacks[c].last().unwrap(), s)
        };
        let half = if from_site {
            let id = site(in_situ[c]);
            bm.locate(lat.pos(id)).map_or(0.5 * s, |b| {
                half_height(bm, b, lat.site_mass(bm, id, st.unit_mass[b]), s)
            })
        } else {
            half_here
        };
        let (qi, qj) = ((q % cx) as i64, (q / cx) as i64);
        let mut best: Option<(f64, usize)> = None;
        for dj in -1i64..=1 {
            for di in -1i64..=1 {
                let (ni, nj) = (qi + di, qj + dj);
                if (di == 0 && dj == 0) || ni < 0 || nj < 0 || ni >= cx as i64 || nj >= cy as i64 {
                    continue;
                }
                let nq = ni as usize + cx * nj as usize;
                let dist = CELL as f64 * s * ((di * di + dj * dj) as f64).sqrt();
                let h_n = mean(&stacks, &in_situ, st.markers, nq);
                if !(h_q - h_n > tan_b * dist) {
                    continue;
                }
                // The parcel goes to the lowest column of the cell, and must come to rest
                // with its centre at least s/2 lower, in flowable ground.
                let Some(n) =
                    columns(nq).min_by(|&a, &b| height(a).total_cmp(&height(b)).then(a.cmp(&b)))
                else {
                    continue;
                };
                let h_low = height(n);
                if h_c - h_low < half_here + half + 0.5 * s {
                    continue;
                }
                let p = [
                    lat.centre(0, n % nx),
                    lat.centre(1, n / nx),
                    landing(&lat, h_low, half),
                ];
                if !bm.locate(p).is_some_and(|b| bm.flowable(b, st.period)) {
                    continue;
                }
                let excess = (h_q - h_n) / dist;
                if best.is_none_or(|b| excess > b.0) {
                    best = Some((excess, n));
                }
            }
        }
        let Some((_, n)) = best else { continue };
        if stats.moves >= max_moves {
            break;
        }
        // Mobilise the in-situ parcel on top if that is what moves.
        let k = if from_site {
            let id = site(in_situ[c]);
            let p = lat.pos(id);
            let Some(b) = bm.locate(p) else { continue };
            st.engulfed[id] = true;
            let m = lat.site_mass(bm, id, st.unit_mass[b]);
            st.engulfed_mass[b] += m;
            let d0 = (st.size)(b, id as u64);
            st.markers.push(id as u64, p, m, b as u32, d0);
            stats.mobilised += 1;
            in_situ[c] = in_situ_top(&lat, bm, st.period, st.engulfed, c % nx, c / nx, lat.n[2]);
            st.markers.len() - 1
        } else {
            stacks[c].pop().unwrap()
        };
        let h_low = top(&stacks, &in_situ, st.markers, n);
        let m = &mut *st.markers;
        let dx = ((n % nx) as f64 - (c % nx) as f64) * s;
        let dy = ((n / nx) as f64 - (c / nx) as f64) * s;
        m.x[k] += dx;
        m.y[k] += dy;
        m.z[k] = landing(&lat, h_low, half);
        m.rill[k] += dx.hypot(dy);
        stacks[n].push(k);
        stats.moves += 1;
        stats.mass += m.mass[k];
        // The cells around the source may now be steep towards it, and the destination
        // towards its own neighbours.
        let nq = (n % nx) / cell + cx * ((n / nx) / cell);
        for r in [q, nq] {
            let (ri, rj) = ((r % cx) as i64, (r / cx) as i64);
            for dj in -1i64..=1 {
                for di in -1i64..=1 {
                    let (ni, nj) = (ri + di, rj + dj);
                    if ni >= 0 && nj >= 0 && ni < cx as i64 && nj < cy as i64 {
                        let w = ni as usize + cx * nj as usize;
                        if !queued[w] {
                            queued[w] = true;
                            queue.push_back(w);
                        }
                    }
                }
            }
        }
    }
    stats
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn repose_is_12_plus_half_phi() {
        assert!((tan_repose(40.0) - 32f64.to_radians().tan()).abs() < 1e-15);
        assert!((tan_repose(36.0) - 30f64.to_radians().tan()).abs() < 1e-15);
    }
}
