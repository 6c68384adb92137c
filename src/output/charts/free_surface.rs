//! The free surface on the charts: the surface of one period by lattice row
//! ([`FreeSurface`]), as the drawdown sections and the VTK export read it, its elevation
//! along a section ([`surface_at`]), and the parts of an outline at or below it
//! ([`below_surface`]), where the sections cut the IMZ outlines.

use crate::engine::result::{RunOutput, SurfaceTable};

/// The free surface of one period as the sections and the VTK export read it: the rows of
/// `run.surface` at the period where it holds the period, else those of
/// `run.moment_surface` (the engine keeps the surface at the charts' moments and the VTK
/// periods there), grouped by lattice row.
#[derive(Debug, Clone, Default)]
pub struct FreeSurface {
    /// Per lattice row, Northing ascending: its Northing and its (Easting, elevation)
    /// points, Easting ascending.
    rows: Vec<(f64, Vec<(f64, f64)>)>,
}

impl FreeSurface {
    /// The surface table that holds `period` and its rows at `period` (none: the run did
    /// not keep the surface of that period).
    pub fn table(run: &RunOutput, period: i64) -> (&SurfaceTable, Vec<usize>) {
        let at = |t: &SurfaceTable| (0..t.z.len()).filter(|&k| t.period[k] == period).collect();
        let rows: Vec<usize> = at(&run.surface);
        if rows.is_empty() {
            (&run.moment_surface, at(&run.moment_surface))
        } else {
            (&run.surface, rows)
        }
    }

    /// The free surface of `period` in `run` ([`FreeSurface::table`]).
    pub fn of(run: &RunOutput, period: i64) -> FreeSurface {
        let (t, rows) = Self::table(run, period);
        let mut points: Vec<(f64, f64, f64)> = rows
            .iter()
            .map(|&k| (t.y[k], t.x[k], t.z[k]))
            .filter(|p| p.0.is_finite() && p.1.is_finite() && p.2.is_finite())
            .collect();
        // Stable: points of one Easting keep the table's order.
        points.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
        let mut out = FreeSurface::default();
        for (y, x, z) in points {
            match out.rows.last_mut() {
                Some((ry, line)) if *ry == y => line.push((x, z)),
                _ => out.rows.push((y, vec![(x, z)])),
            }
        }
        out
    }

    /// The surface along the lattice row nearest the Northing `y` (both rows where `y`
    /// lies halfway between two), Easting ascending: what a section at `y` draws and cuts
    /// the IMZ outlines at ([`below_surface`]). Empty without a surface.
    pub fn section(&self, y: f64) -> Vec<(f64, f64)> {
        let nearest = self
            .rows
            .iter()
            .map(|r| (r.0 - y).abs())
            .fold(f64::INFINITY, f64::min);
        let mut line: Vec<(f64, f64)> = self
            .rows
            .iter()
            .filter(|r| (r.0 - y).abs() <= nearest + 1e-9)
            .flat_map(|r| r.1.iter().copied())
            .collect();
        line.sort_by(|a, b| a.0.total_cmp(&b.0));
        line
    }

    /// The surface's elevation at (`x`, `y`), m: along each lattice row as on a section
    /// ([`surface_at`]: linear between the row's points, flat beyond its ends), and linear
    /// in Northing between the two rows about `y` (flat beyond the first and last row). On
    /// a lattice row it is that row's section surface. None without a surface or at a
    /// non-finite `y`.
    pub fn at(&self, x: f64, y: f64) -> Option<f64> {
        if !y.is_finite() {
            return None;
        }
        let (first, last) = (self.rows.first()?, self.rows.last()?);
        if y <= first.0 {
            return interpolate(&first.1, x);
        }
        if y >= last.0 {
            return interpolate(&last.1, x);
        }
        let i = self.rows.partition_point(|r| r.0 <= y);
        let (a, b) = (&self.rows[i - 1], &self.rows[i]);
        let (za, zb) = (interpolate(&a.1, x)?, interpolate(&b.1, x)?);
        Some(za + (zb - za) * (y - a.0) / (b.0 - a.0))
    }
}

/// The free surface's elevation at `x` on a section (linear between its points, flat
/// beyond its ends); None where it has no finite point.
pub fn surface_at(surface: &[(f64, f64)], x: f64) -> Option<f64> {
    interpolate(&finite_points(surface), x)
}

/// The finite points of a polyline.
fn finite_points(line: &[(f64, f64)]) -> Vec<(f64, f64)> {
    line.iter()
        .copied()
        .filter(|p| p.0.is_finite() && p.1.is_finite())
        .collect()
}

/// [`surface_at`] on the surface's finite points `pts`.
fn interpolate(pts: &[(f64, f64)], x: f64) -> Option<f64> {
    if !x.is_finite() {
        return None;
    }
    let (first, last) = (pts.first()?, pts.last()?);
    if x <= first.0 {
        return Some(first.1);
    }
    if x >= last.0 {
        return Some(last.1);
    }
    let i = pts.partition_point(|p| p.0 <= x);
    let (a, b) = (pts[i - 1], pts[i]);
    Some(if b.0 > a.0 {
        a.1 + (b.1 - a.1) * (x - a.0) / (b.0 - a.0)
    } else {
        a.1.min(b.1)
    })
}

/// The parts of a polyline at or below the free surface `surface` (as [`surface_at`] reads
/// it), broken by a non-finite point where it rises above: each segment is split where it
/// crosses the surface (between two of the surface's points both are straight, so the
/// crossing is exact). Without a surface the line is kept whole.
pub fn below_surface(line: &[(f64, f64)], surface: &[(f64, f64)]) -> Vec<(f64, f64)> {
    // The surface's finite points, once for every segment.
    let pts = finite_points(surface);
    let Some(&first) = pts.first() else {
        return line.to_vec();
    };
    let s = |x: f64| interpolate(&pts, x).unwrap_or(first.1);
    let lerp =
        |a: (f64, f64), b: (f64, f64), t: f64| (a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t);
    let mut out: Vec<(f64, f64)> = Vec::new();
    let add = |out: &mut Vec<(f64, f64)>, p: (f64, f64)| {
        if out.last() != Some(&p) {
            out.push(p);
        }
    };
    let cut = |out: &mut Vec<(f64, f64)>| {
        if out.last().is_some_and(|p| p.0.is_finite()) {
            out.push((f64::NAN, f64::NAN));
        }
    };
    for w in line.windows(2) {
        let (a, b) = (w[0], w[1]);
        if !(a.0.is_finite() && a.1.is_finite() && b.0.is_finite() && b.1.is_finite()) {
            cut(&mut out);
            continue;
        }
        // Pieces between the surface's points that fall inside the segment's span.
        let mut ts = vec![0.0, 1.0];
        if a.0 != b.0 {
            let (lo, hi) = (a.0.min(b.0), a.0.max(b.0));
            ts.extend(
                surface
                    .iter()
                    .filter(|p| p.0 > lo && p.0 < hi)
                    .map(|p| (p.0 - a.0) / (b.0 - a.0)),
            );
            ts.sort_by(f64::total_cmp);
        }
        for t in ts.windows(2) {
            let (p, q) = (lerp(a, b, t[0]), lerp(a, b, t[1]));
            let (dp, dq) = (p.1 - s(p.0), q.1 - s(q.0));
            match (dp <= 0.0, dq <= 0.0) {
                (true, true) => {
                    add(&mut out, p);
                    add(&mut out, q);
                }
                (true, false) => {
                    add(&mut out, p);
                    let c = lerp(p, q, dp / (dp - dq));
                    add(&mut out, (c.0, s(c.0).min(c.1)));
                    cut(&mut out);
                }
                (false, true) => {
                    cut(&mut out);
                    let c = lerp(p, q, dp / (dp - dq));
                    add(&mut out, (c.0, s(c.0).min(c.1)));
                    add(&mut out, q);
                }
                (false, false) => cut(&mut out),
            }
        }
    }
    if out.last().is_some_and(|p| !p.0.is_finite()) {
        out.pop();
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn free_surface_reads_each_row_as_a_section_and_is_linear_between_rows() {
        // Two lattice rows at y = 0 and y = 1 (a gap at x = 1 on the second), kept in the
        // moment table; a third period's row in the surface table.
        let mut run = RunOutput::default();
        let push = |t: &mut SurfaceTable, p: i64, x: f64, y: f64, z: f64| {
            t.period.push(p);
            t.x.push(x);
            t.y.push(y);
            t.z.push(z);
        };
        for (x, y, z) in [(0.0, 0.0, 10.0), (1.0, 0.0, 8.0), (2.0, 0.0, 6.0)] {
            push(&mut run.moment_surface, 4, x, y, z);
        }
        for (x, y, z) in [(0.0, 1.0, 12.0), (2.0, 1.0, 4.0)] {
            push(&mut run.moment_surface, 4, x, y, z);
        }
        push(&mut run.surface, 5, 0.0, 0.0, 3.0);
        let f = FreeSurface::of(&run, 4);
        // On a row: the section's surface at that row.
        for x in [-1.0, 0.0, 0.5, 1.0, 1.5, 2.0, 3.0] {
            for y in [0.0, 1.0] {
                assert_eq!(f.at(x, y), surface_at(&f.section(y), x), "({x}, {y})");
            }
        }
        assert_eq!(f.section(0.2), [(0.0, 10.0), (1.0, 8.0), (2.0, 6.0)]);
        assert_eq!(
            f.section(0.5).len(),
            5,
            "halfway: both rows, as the sections had it"
        );
        // Between rows: linear in y; beyond them: flat.
        assert_eq!(f.at(1.0, 0.25), Some(8.0));
        assert_eq!(f.at(0.0, 0.5), Some(11.0));
        assert_eq!(f.at(2.0, -5.0), Some(6.0));
        assert_eq!(f.at(2.0, 7.0), Some(4.0));
        assert_eq!(f.at(f64::NAN, 0.5), None);
        // The surface table first, then the moments; none for a period neither holds.
        assert_eq!(FreeSurface::of(&run, 5).at(9.0, 9.0), Some(3.0));
        assert_eq!(FreeSurface::table(&run, 5).1, [0]);
        assert_eq!(FreeSurface::of(&run, 6).at(0.0, 0.0), None);
        assert!(FreeSurface::of(&run, 6).section(0.0).is_empty());
    }
}
