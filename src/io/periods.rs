//! The periods of a draw schedule: number, name, length and, where known, start date.

/// Periods, in order.
#[derive(Debug, Clone, Default)]
pub struct Periods {
    /// Period numbers, strictly increasing.
    pub id: Vec<i64>,
    /// Names (they may repeat: periods are positional, as in MassFlow).
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
    /// The first and last period numbers, `1–24`, or `none`: what a message about a period
    /// that is not one of them shows.
    pub fn span(&self) -> String {
        match (self.id.first(), self.id.last()) {
            (Some(a), Some(b)) => format!("{a}–{b}"),
            _ => "none".to_string(),
        }
    }
    /// Index of the period that holds `day` (days since 1970-01-01), when the periods have
    /// start dates; None before the first, after the last or in a gap between two.
    pub fn at_day(&self, day: f64) -> Option<usize> {
        let start = self.start.as_ref()?;
        let k = start.partition_point(|&s| s <= day).checked_sub(1)?;
        (day < start[k] + self.days[k]).then_some(k)
    }
}
