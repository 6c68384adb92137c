//! Drawpoints, periods and the draw schedule.

// The periods are read by the schedule reader (a wide schedule's headers name them), so
// they are defined in `io`, which comes first.
pub use crate::io::Periods;

/// Drawpoints, column-wise.
#[derive(Debug, Clone, Default)]
pub struct Drawpoints {
    /// Unique names.
    pub name: Vec<String>,
    /// IMZ axis Easting, m.
    pub x: Vec<f64>,
    /// IMZ axis Northing, m.
    pub y: Vec<f64>,
    /// IMZ base elevation, m.
    pub z: Vec<f64>,
    /// Opening width (diameter of the lowest IMZ disk), m.
    pub width: Vec<f64>,
    /// Reporting zone ("" when not given).
    pub zone: Vec<String>,
    /// Under draw control, the first period in which the drawpoint may open (None: once
    /// its ground has caved). Empty when the table has no such column.
    pub open_period: Vec<Option<i64>>,
}

impl Drawpoints {
    /// Number of drawpoints.
    pub fn len(&self) -> usize {
        self.name.len()
    }
    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.name.is_empty()
    }
    /// The first period in which drawpoint `d` may open under draw control (None: no
    /// constraint beyond its ground having caved).
    pub fn opens_at(&self, d: usize) -> Option<i64> {
        self.open_period.get(d).copied().flatten()
    }
    /// Median over drawpoints of the distance in plan to the nearest other drawpoint, m
    /// (NaN with fewer than two).
    pub fn median_spacing(&self) -> f64 {
        let n = self.len();
        if n < 2 {
            return f64::NAN;
        }
        let mut near: Vec<f64> = (0..n)
            .map(|a| {
                (0..n)
                    .filter(|&b| b != a)
                    .map(|b| {
                        ((self.x[a] - self.x[b]).powi(2) + (self.y[a] - self.y[b]).powi(2)).sqrt()
                    })
                    .fold(f64::INFINITY, f64::min)
            })
            .collect();
        near.sort_by(f64::total_cmp);
        near[n / 2]
    }
    /// Index of a drawpoint by name.
    pub fn find(&self, name: &str) -> Option<usize> {
        self.name.iter().position(|n| n == name)
    }
}

/// Dense schedule: `tonnes[p * n_drawpoints + d]`.
#[derive(Debug, Clone, Default)]
pub struct Schedule {
    /// Number of drawpoints (row stride).
    pub n_drawpoints: usize,
    /// Tonnes per period and drawpoint.
    pub tonnes: Vec<f64>,
}

impl Schedule {
    /// Tonnes for period index `p` and drawpoint `d`.
    #[inline]
    pub fn get(&self, p: usize, d: usize) -> f64 {
        self.tonnes[p * self.n_drawpoints + d]
    }
    /// The row of period index `p`.
    pub fn period(&self, p: usize) -> &[f64] {
        &self.tonnes[p * self.n_drawpoints..(p + 1) * self.n_drawpoints]
    }
    /// Total scheduled tonnes of drawpoint `d`.
    pub fn total(&self, d: usize) -> f64 {
        self.tonnes
            .iter()
            .skip(d)
            .step_by(self.n_drawpoints.max(1))
            .sum()
    }
}
