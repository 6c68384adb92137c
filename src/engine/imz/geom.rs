//! An IMZ's geometry as the other IMZs and the marker pass see it, and the plan grid that
//! lists the IMZs that may cover a point.

/// Geometry of one IMZ as seen by other IMZs and the marker pass.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct ImzGeom {
    /// Axis Easting, m.
    pub x: f64,
    /// Axis Northing, m.
    pub y: f64,
    /// Base elevation (drawpoint), m.
    pub z0: f64,
    /// Disk thickness h, m.
    pub h: f64,
    /// Disk radii R_i, m.
    pub radius: Vec<f64>,
}

impl ImzGeom {
    /// Largest disk radius.
    pub fn max_radius(&self) -> f64 {
        self.radius.iter().cloned().fold(0.0, f64::max)
    }
    /// Whether a point lies inside this IMZ.
    #[inline]
    pub fn contains(&self, p: [f64; 3]) -> bool {
        self.disk_at(p).is_some()
    }

    /// The disk that holds a point, if one does: its index i, the point's height in disk
    /// units above the IMZ's base (i ≤ t < i + 1), and its plan offset (dx, dy) from the
    /// axis with the squared distance dx² + dy².
    #[inline]
    pub fn disk_at(&self, p: [f64; 3]) -> Option<(usize, f64, [f64; 2], f64)> {
        let t = (p[2] - self.z0) / self.h;
        if !(t >= 0.0) {
            return None;
        }
        let i = t as usize;
        let (dx, dy) = (p[0] - self.x, p[1] - self.y);
        let a2 = dx * dx + dy * dy;
        self.radius
            .get(i)
            .is_some_and(|&r| a2 <= r * r)
            .then_some((i, t, [dx, dy], a2))
    }
}

/// A uniform 2-D grid over the footprint listing which IMZs may cover each cell.
#[derive(Debug, Clone, Default)]
pub struct ImzGrid {
    origin: [f64; 2],
    cell: f64,
    n: [usize; 2],
    start: Vec<u32>,
    ids: Vec<u32>,
}

impl ImzGrid {
    /// Builds the grid for the IMZs `which` (indices into `geoms`).
    pub fn build(
        geoms: &[ImzGeom],
        which: &[usize],
        origin: [f64; 2],
        extent: [f64; 2],
        cell: f64,
    ) -> ImzGrid {
        let n = [
            ((extent[0] / cell).ceil() as usize).max(1),
            ((extent[1] / cell).ceil() as usize).max(1),
        ];
        let mut counts = vec![0u32; n[0] * n[1] + 1];
        let ranges: Vec<_> = which
            .iter()
            .map(|&d| {
                let g = &geoms[d];
                let r = g.max_radius();
                let lo = |c: f64, o: f64, m: usize| {
                    (((c - r - o) / cell).floor().max(0.0) as usize).min(m - 1)
                };
                let hi = |c: f64, o: f64, m: usize| {
                    (((c + r - o) / cell).floor().max(0.0) as usize).min(m - 1)
                };
                (
                    d,
                    lo(g.x, origin[0], n[0]),
                    hi(g.x, origin[0], n[0]),
                    lo(g.y, origin[1], n[1]),
                    hi(g.y, origin[1], n[1]),
                )
            })
            .collect();
        for &(_, i0, i1, j0, j1) in &ranges {
            for j in j0..=j1 {
                for i in i0..=i1 {
                    counts[i + n[0] * j + 1] += 1;
                }
            }
        }
        for k in 1..counts.len() {
            counts[k] += counts[k - 1];
        }
        let mut fill = counts.clone();
        let mut ids = vec![0u32; *counts.last().unwrap() as usize];
        for &(d, i0, i1, j0, j1) in &ranges {
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let c = i + n[0] * j;
                    ids[fill[c] as usize] = d as u32;
                    fill[c] += 1;
                }
            }
        }
        ImzGrid {
            origin,
            cell,
            n,
            start: counts,
            ids,
        }
    }

    /// IMZ ids whose footprint may cover (x, y).
    #[inline]
    pub fn at(&self, x: f64, y: f64) -> &[u32] {
        let i = (x - self.origin[0]) / self.cell;
        let j = (y - self.origin[1]) / self.cell;
        if !(i >= 0.0 && j >= 0.0) {
            return &[];
        }
        let (i, j) = (i as usize, j as usize);
        if i >= self.n[0] || j >= self.n[1] {
            return &[];
        }
        let c = i + self.n[0] * j;
        &self.ids[self.start[c] as usize..self.start[c + 1] as usize]
    }
}
