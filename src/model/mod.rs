//! Typed views over the input tables: the block grid, drawpoints, periods and schedule,
//! and the scenario. Everything here is validated; the engine trusts it.

pub mod block_model;
pub mod demo;
pub mod layout;
pub mod load;
pub mod records;
pub mod scenario;
pub mod synthetic;

pub use block_model::BlockModel;
pub use layout::{Drawpoints, Periods, Schedule};
pub use records::{load_records, ProductionRecords};
pub use scenario::Scenario;

/// A fully loaded, validated scene: what the engine runs.
#[derive(Debug, Clone)]
pub struct Scene {
    /// The block model.
    pub blocks: BlockModel,
    /// The drawpoints.
    pub drawpoints: Drawpoints,
    /// The periods, in order.
    pub periods: Periods,
    /// Tonnes per period per drawpoint.
    pub schedule: Schedule,
}

impl Scene {
    /// Keeps only the first `n` periods (a shorter scene: a quicker sweep, calibration or
    /// trial run).
    pub fn keep_periods(&mut self, n: usize) {
        let n = n.min(self.periods.len());
        self.periods.id.truncate(n);
        self.periods.name.truncate(n);
        self.periods.days.truncate(n);
        if let Some(s) = self.periods.start.as_mut() {
            s.truncate(n);
        }
        let nd = self.schedule.n_drawpoints;
        self.schedule.tonnes.truncate(n * nd);
    }
}
