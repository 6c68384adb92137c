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
pub use scenario::{Economics, Scenario};

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
    /// Draw control's production target per period index, t, when a target table was
    /// given (`draw_control.target_table`); None: `draw_control.target_rate`.
    pub target: Option<Vec<f64>>,
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
        if let Some(t) = self.target.as_mut() {
            t.truncate(n);
        }
    }
}

/// Shares of the scheduled tonnes at which the charts show the draw by default: about a
/// quarter, a half and three quarters of the way, then the end.
pub const MOMENT_SHARES: [f64; 3] = [0.25, 0.5, 0.75];

impl Scene {
    /// The periods at whose end the charts show the draw (sections through time): `chosen`
    /// where given (`outputs.section_periods`; periods the schedule lacks are left out), else
    /// the first period by whose end the scene has scheduled [`MOMENT_SHARES`] of its tonnes,
    /// and the last period. Ascending, without repeats.
    pub fn moments(&self, chosen: &[i64]) -> Vec<i64> {
        let ids = &self.periods.id;
        let mut out: Vec<i64> = if chosen.is_empty() {
            let per: Vec<f64> = (0..ids.len())
                .map(|p| self.schedule.period(p).iter().sum())
                .collect();
            let total: f64 = per.iter().sum();
            let mut cum = 0.0;
            let mut next = MOMENT_SHARES.iter().peekable();
            let mut at = Vec::new();
            for (p, t) in per.iter().enumerate() {
                cum += t;
                while next
                    .next_if(|&&f| total > 0.0 && cum >= f * total)
                    .is_some()
                {
                    at.push(ids[p]);
                }
            }
            at.extend(ids.last());
            at
        } else {
            chosen.iter().copied().filter(|p| ids.contains(p)).collect()
        };
        out.sort_unstable();
        out.dedup();
        out
    }

    /// The periods the VTK export writes the IMZ disks and the free surface at
    /// (`output::vtk`): `outputs.vtk_periods` where given (periods the schedule lacks, as after
    /// `--keep-periods`, are left out; `model::load` refuses those of the full schedule), else
    /// the sections' moments, [`Scene::moments`] of `outputs.section_periods`. Ascending,
    /// without repeats.
    pub fn vtk_periods(&self, outputs: &scenario::Outputs) -> Vec<i64> {
        self.moments(if outputs.vtk_periods.is_empty() {
            &outputs.section_periods
        } else {
            &outputs.vtk_periods
        })
    }
}
