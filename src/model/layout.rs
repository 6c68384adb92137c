//! Drawpoints, periods and the draw schedule.

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
    /// Index of a drawpoint by name.
    pub fn find(&self, name: &str) -> Option<usize> {
        self.name.iter().position(|n| n == name)
    }
}

/// Periods, in order.
#[derive(Debug, Clone, Default)]
pub struct Periods {
    /// Period numbers, strictly increasing.
    pub id: Vec<i64>,
    /// Names.
    pub name: Vec<String>,
    /// Lengths, days.
    pub days: Vec<f64>,
    /// Start of each period, days since 1970-01-01 (from the periods table's optional
    /// `start_date` column); None when the periods have no calendar. Used to map dated
    /// production records to periods: period k covers [start_k, start_k + days_k).
    pub start: Option<Vec<f64>>,
}

impl Periods {
    /// Number of periods.
    pub fn len(&self) -> usize {
        self.id.len()
    }
    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.id.is_empty()
    }
    /// Index of a period by number.
    pub fn find(&self, id: i64) -> Option<usize> {
        self.id.binary_search(&id).ok()
    }
    /// Index of the period that holds `day` (days since 1970-01-01), when the periods have
    /// start dates; None before the first, after the last or in a gap between two.
    pub fn at_day(&self, day: f64) -> Option<usize> {
        let start = self.start.as_ref()?;
        let k = start.partition_point(|&s| s <= day).checked_sub(1)?;
        (day < start[k] + self.days[k]).then_some(k)
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
