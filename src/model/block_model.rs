//! The regular block grid with O(1) point lookup.

/// Largest plausible mean fragment size, m. Caved fragmentation runs from centimetres to
/// about 2 m (Henderson: 0.04–0.23 m; coarse primary caving d50 of 1–2 m); a mean above
/// 10 m is almost always millimetres (`units-mm`, in the block model and the production
/// records alike).
pub const MAX_FRAG_SIZE: f64 = 10.0;

/// Sentinel for "no block here" in [`BlockModel::index`].
pub const NO_BLOCK: u32 = u32::MAX;

/// A regular, axis-aligned block model held column-wise.
///
/// Blocks have one size, which may differ per axis (`size`). Grid cells without a block are
/// outside the cave: nothing there flows. Every per-block property is a plain column indexed
/// by block row.
#[derive(Debug, Clone, Default)]
pub struct BlockModel {
    /// Minimum corner of the grid (x, y, z), m.
    pub origin: [f64; 3],
    /// Block dimensions (dx, dy, dz), m.
    pub size: [f64; 3],
    /// Number of grid cells per axis.
    pub dims: [usize; 3],
    /// Grid cell (i + nx (j + ny k)) → block row, or [`NO_BLOCK`].
    pub index: Vec<u32>,
    /// Block centres, m.
    pub x: Vec<f64>,
    /// Block centres, m.
    pub y: Vec<f64>,
    /// Block centres, m.
    pub z: Vec<f64>,
    /// Block ids.
    pub id: Vec<i64>,
    /// First period in which the block is flowable (0 = from the start).
    pub cave_period: Vec<i64>,
    /// Solids density ρ_s, t/m³.
    pub density: Vec<f64>,
    /// In-situ porosity n0.
    pub n0: Vec<f64>,
    /// Dilated porosity n1.
    pub n1: Vec<f64>,
    /// Friction angle φ, degrees.
    pub friction: Vec<f64>,
    /// Mean primary fragment diameter d̄, m (from `frag_size`, or the Weibull mean
    /// β Γ(1 + 1/α) when only the Weibull parameters are given).
    pub frag: Vec<f64>,
    /// Weibull shape α of primary fragmentation (NaN when not given).
    pub frag_shape: Vec<f64>,
    /// Weibull scale β of primary fragmentation, m (NaN when not given).
    pub frag_scale: Vec<f64>,
    /// Tensile strength σ_t, kPa (defaults to 0.1 × UCS; NaN when neither is given).
    pub tensile: Vec<f64>,
    /// UCS, kPa (NaN when not given).
    pub ucs: Vec<f64>,
    /// Percolation coefficient k1 (default 11).
    pub perc_k1: Vec<f64>,
    /// Percolation coefficient k2 (default 4.5).
    pub perc_k2: Vec<f64>,
    /// Percolation variance-to-mean ratio (default 0.5).
    pub perc_vmr: Vec<f64>,
    /// Lithology code index into `lithology_names`.
    pub lithology: Vec<u16>,
    /// Distinct lithology names, in order of first appearance.
    pub lithology_names: Vec<String>,
    /// Grade column names, in input order.
    pub grade_names: Vec<String>,
    /// Grades, `grades[g][block]`, % by mass.
    pub grades: Vec<Vec<f64>>,
}

impl BlockModel {
    /// Number of blocks.
    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// True when there are no blocks.
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// Grid cell index along axis `a` of the coordinate `x`, or None outside the grid.
    #[inline]
    pub fn axis_cell(&self, a: usize, x: f64) -> Option<usize> {
        let t = (x - self.origin[a]) / self.size[a];
        (t >= 0.0 && t < self.dims[a] as f64).then_some(t as usize)
    }

    /// Grid cell indices of a point, or None outside the grid.
    #[inline]
    pub fn cell(&self, p: [f64; 3]) -> Option<[usize; 3]> {
        Some([
            self.axis_cell(0, p[0])?,
            self.axis_cell(1, p[1])?,
            self.axis_cell(2, p[2])?,
        ])
    }

    /// Row of the block containing a point, in O(1); None outside the grid or in a missing
    /// block.
    #[inline]
    pub fn locate(&self, p: [f64; 3]) -> Option<usize> {
        self.at_cell(self.cell(p)?)
    }

    /// Row of the block in grid cell `c`, or None in a missing block.
    #[inline]
    pub fn at_cell(&self, c: [usize; 3]) -> Option<usize> {
        let b = self.index[c[0] + self.dims[0] * (c[1] + self.dims[1] * c[2])];
        (b != NO_BLOCK).then_some(b as usize)
    }

    /// Whether block `b` is caved (free to flow) during period `period`.
    #[inline]
    pub fn flowable(&self, b: usize, period: i64) -> bool {
        self.cave_period[b] <= period
    }

    /// Top of the grid, m.
    pub fn z_max(&self) -> f64 {
        self.origin[2] + self.size[2] * self.dims[2] as f64
    }

    /// Grid extent (max corner), m.
    pub fn max_corner(&self) -> [f64; 3] {
        [0, 1, 2].map(|a| self.origin[a] + self.size[a] * self.dims[a] as f64)
    }

    /// A point beyond the grid's plan bounds reflected back across the sides it is beyond:
    /// its image in the model's vertical wall, or, off a corner, across both walls.
    #[inline]
    pub fn mirror(&self, p: [f64; 3]) -> [f64; 3] {
        let hi = self.max_corner();
        let image = |a: usize| {
            if p[a] < self.origin[a] {
                Some(2.0 * self.origin[a] - p[a])
            } else if p[a] > hi[a] {
                Some(2.0 * hi[a] - p[a])
            } else {
                None
            }
        };
        match (image(0), image(1)) {
            (Some(x), None) => [x, p[1], p[2]],
            (None, Some(y)) => [p[0], y, p[2]],
            (Some(x), Some(y)) => [x, y, p[2]],
            _ => p,
        }
    }

    /// Builds the grid index from block centres and a block size. Returns the rows of
    /// blocks that share a cell with an earlier block, and the rows off the grid, as
    /// errors for the validator: (row, reason).
    pub fn build_index(&mut self) -> Vec<(usize, String)> {
        let mut problems = Vec::new();
        if self.x.is_empty() {
            return problems;
        }
        let cols = [&self.x, &self.y, &self.z];
        for (a, col) in cols.iter().enumerate() {
            let min = col.iter().cloned().fold(f64::INFINITY, f64::min);
            let max = col.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
            self.origin[a] = min - 0.5 * self.size[a];
            self.dims[a] = ((max - min) / self.size[a]).round() as usize + 1;
        }
        self.index = vec![NO_BLOCK; self.dims.iter().product()];
        let axis = ["x", "y", "z"];
        for b in 0..self.x.len() {
            let p = [self.x[b], self.y[b], self.z[b]];
            let mut c = [0usize; 3];
            let mut off = false;
            for a in 0..3 {
                let t = (p[a] - self.origin[a]) / self.size[a] - 0.5;
                let r = t.round();
                if (t - r).abs() > 1e-3 {
                    problems.push((
                        b,
                        format!(
                            "block centre {}={} is off the {} m grid that starts at {} (blocks must be regular)",
                            axis[a], p[a], self.size[a], self.origin[a] + 0.5 * self.size[a]
                        ),
                    ));
                    off = true;
                    break;
                }
                c[a] = r as usize;
            }
            if off {
                continue;
            }
            let cell = c[0] + self.dims[0] * (c[1] + self.dims[1] * c[2]);
            if self.index[cell] != NO_BLOCK {
                problems.push((
                    b,
                    format!(
                        "block at ({}, {}, {}) occupies the same cell as row {}",
                        p[0],
                        p[1],
                        p[2],
                        self.index[cell] as usize + 1
                    ),
                ));
                continue;
            }
            self.index[cell] = b as u32;
        }
        problems
    }
}
