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
