//! The deformed layers of a drawdown section ([`drawdown_section`](super::drawdown_section)):
//! the lattice row of markers nearest the section ([`SectionLattice`]), the marker spacing
//! when the run does not state it ([`marker_spacing`]), and each layer's polyline from a
//! marker snapshot ([`layers`]).

use std::borrow::Cow;
use std::collections::HashMap;

use super::drawdown::CHUNK;
use crate::engine::result::{MarkerSnapshot, MarkerState, RunOutput};
use crate::model::BlockModel;

/// The regular marker lattice as far as a section needs it: spacing `s` and, per axis, the
/// coordinate of site 0 and the number of sites over the block grid.
#[derive(Debug, Clone, Copy)]
pub(super) struct SectionLattice {
    pub(super) s: f64,
    start: [f64; 3],
    n: [i64; 3],
}

impl SectionLattice {
    /// Sites are `start + i s`. The phase comes from an observed marker origin when there is
    /// one (so it matches the engine whatever its convention), else the engine's
    /// `origin + (i + ½) s`; sites cover the block grid.
    pub(super) fn new(bm: &BlockModel, run: &RunOutput, snap: Option<i64>, s: f64) -> Self {
        let max = bm.max_corner();
        let first = |x: &[f64], y: &[f64], z: &[f64]| (!x.is_empty()).then(|| [x[0], y[0], z[0]]);
        let seen = snap
            .and_then(|p| run.snapshot_chunks(p, 1)?.next())
            .and_then(|m| first(&m.origin_x, &m.origin_y, &m.origin_z))
            .or_else(|| {
                let t = run.drawn_chunks(1).next()?;
                first(&t.origin_x, &t.origin_y, &t.origin_z)
            });
        let mut start = [0.0; 3];
        let mut n = [0i64; 3];
        for a in 0..3 {
            start[a] = match seen {
                Some(p) => p[a] - s * ((p[a] - bm.origin[a]) / s).floor(),
                None => bm.origin[a] + 0.5 * s,
            };
            n[a] = (((max[a] - start[a]) / s).ceil() as i64).max(1);
        }
        SectionLattice { s, start, n }
    }

    /// Index of the lattice site nearest to `v` along axis `a` (not clamped).
    pub(super) fn index(&self, a: usize, v: f64) -> i64 {
        ((v - self.start[a]) / self.s).round() as i64
    }

    /// Coordinate of site `i` along axis `a`.
    fn coord(&self, a: usize, i: i64) -> f64 {
        self.start[a] + i as f64 * self.s
    }
}

/// Marker spacing: the run's resolved spacing when set, else the smallest gap between
/// distinct origin coordinates (any axis) of the snapshot's markers and the drawn markers.
pub(super) fn marker_spacing(run: &RunOutput, snap: Option<i64>) -> Option<f64> {
    let s = run.resolution.marker_spacing;
    if s.is_finite() && s > 0.0 {
        return Some(s);
    }
    let mut best = f64::INFINITY;
    let mut axes: Vec<Vec<f64>> = vec![Vec::new(); 3];
    for t in run.drawn_chunks(CHUNK) {
        for (a, v) in axes.iter_mut().zip([&t.origin_x, &t.origin_y, &t.origin_z]) {
            a.extend_from_slice(v);
        }
    }
    if let Some(chunks) = snap.and_then(|p| run.snapshot_chunks(p, CHUNK)) {
        let mut snap_axes: Vec<Vec<f64>> = vec![Vec::new(); 3];
        for m in chunks {
            for (a, v) in snap_axes
                .iter_mut()
                .zip([&m.origin_x, &m.origin_y, &m.origin_z])
            {
                a.extend_from_slice(v);
            }
        }
        axes.extend(snap_axes);
    }
    for values in axes {
        let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
        v.sort_by(f64::total_cmp);
        let tol = 1e-9 * v.last().map_or(1.0, |x| x.abs().max(1.0));
        for w in v.windows(2) {
            let gap = w[1] - w[0];
            if gap > tol {
                best = best.min(gap);
            }
        }
    }
    best.is_finite().then_some(best)
}

/// What a section knows about one lattice site of its row.
#[derive(Debug, Clone, Copy)]
enum Site {
    /// A mobilised marker still in the model, at its current (x, z).
    Moving(f64, f64),
    /// A marker that was drawn.
    Drawn,
}

/// The deformed layers on the lattice row nearest to `y` (see [`drawdown_section`](super::drawdown_section)).
pub(super) fn layers<'r>(
    lat: &SectionLattice,
    snapshot: impl Iterator<Item = Cow<'r, MarkerSnapshot>>,
    y: f64,
    spacing: f64,
) -> Vec<Vec<(f64, f64)>> {
    let j = lat.index(1, y).clamp(0, lat.n[1] - 1);
    let mut sites: HashMap<(i64, i64), Site> = HashMap::new();
    for snap in snapshot {
        for m in 0..snap.marker_id.len() {
            if lat.index(1, snap.origin_y[m]) != j {
                continue;
            }
            let key = (
                lat.index(0, snap.origin_x[m]),
                lat.index(2, snap.origin_z[m]),
            );
            let site = match snap.state[m] {
                MarkerState::Drawn => Site::Drawn,
                _ => Site::Moving(snap.x[m], snap.z[m]),
            };
            sites.insert(key, site);
        }
    }
    let base = lat.start[2] - 0.5 * lat.s;
    let top = lat.coord(2, lat.n[2] - 1) + 0.5 * lat.s;
    let mut levels: Vec<i64> = Vec::new();
    let mut k = 1;
    loop {
        let z = base + (k as f64 - 0.5) * spacing;
        if z > top + 1e-9 * top.abs().max(1.0) {
            break;
        }
        let level = lat.index(2, z).clamp(0, lat.n[2] - 1);
        if levels.last() != Some(&level) {
            levels.push(level);
        }
        k += 1;
    }
    levels
        .into_iter()
        .map(|kz| layer_line(lat, &sites, kz))
        .filter(|line| line.iter().any(|p| p.0.is_finite()))
        .collect()
}

/// One layer: lattice columns in order, in-situ runs reduced to their ends, drawn markers as
/// a single NaN break between pieces.
fn layer_line(lat: &SectionLattice, sites: &HashMap<(i64, i64), Site>, kz: i64) -> Vec<(f64, f64)> {
    let z0 = lat.coord(2, kz);
    let nan = (f64::NAN, f64::NAN);
    let mut line: Vec<(f64, f64)> = Vec::new();
    // Index in `line` where the current run of in-situ points started.
    let mut flat_from: Option<usize> = None;
    for i in 0..lat.n[0] {
        match sites.get(&(i, kz)) {
            None => {
                let p = (lat.coord(0, i), z0);
                match flat_from {
                    // Keep the first and the latest point of a flat run.
                    Some(start) if line.len() - start >= 2 => *line.last_mut().unwrap() = p,
                    Some(_) => line.push(p),
                    None => {
                        flat_from = Some(line.len());
                        line.push(p);
                    }
                }
            }
            Some(Site::Moving(x, z)) => {
                flat_from = None;
                line.push((*x, *z));
            }
            Some(Site::Drawn) => {
                flat_from = None;
                if line.last().is_some_and(|p| p.0.is_finite()) {
                    line.push(nan);
                }
            }
        }
    }
    if line.last().is_some_and(|p| !p.0.is_finite()) {
        line.pop();
    }
    line
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layer_lines_are_flat_outside_the_mobilised_markers_and_break_where_drawn() {
        let lat = SectionLattice {
            s: 1.0,
            start: [0.5, 0.5, 0.5],
            n: [8, 1, 4],
        };
        let mut sites = HashMap::new();
        sites.insert((2, 1), Site::Moving(2.6, 1.2));
        sites.insert((3, 1), Site::Drawn);
        sites.insert((4, 1), Site::Drawn);
        sites.insert((5, 1), Site::Moving(5.4, 1.1));
        let line = layer_line(&lat, &sites, 1);
        let z = 1.5;
        assert_eq!(line.len(), 7);
        assert_eq!(&line[..3], &[(0.5, z), (1.5, z), (2.6, 1.2)]);
        assert!(line[3].0.is_nan());
        assert_eq!(&line[4..], &[(5.4, 1.1), (6.5, z), (7.5, z)]);
        // A layer never mobilised is its two ends.
        assert_eq!(layer_line(&lat, &sites, 2), vec![(0.5, 2.5), (7.5, 2.5)]);
    }

    #[test]
    fn spacing_is_inferred_from_origins_without_a_resolution() {
        let snap = MarkerSnapshot {
            origin_x: vec![0.125, 0.175, 0.125],
            origin_y: vec![0.0, 0.0, 0.0],
            origin_z: vec![1.025, 1.025, 1.075],
            ..MarkerSnapshot::default()
        };
        let out = RunOutput {
            snapshots: vec![snap],
            ..RunOutput::default()
        };
        let s = marker_spacing(&out, Some(0)).unwrap();
        assert!((s - 0.05).abs() < 1e-12, "{s}");
        assert!(marker_spacing(&RunOutput::default(), None).is_none());
    }
}
