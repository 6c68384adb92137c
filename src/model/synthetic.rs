//! Uniform synthetic scenes for physics tests, property tests and benchmarks: a box of one
//! material, drawpoints anywhere on its floor, a constant schedule.
//!
//! The scene carries one grade column, `elev`, equal to each block's centre elevation, so
//! the grade reporting to a drawpoint is the mean origin elevation of what it drew.

use super::block_model::BlockModel;
use super::layout::{Drawpoints, Periods, Schedule};
use super::Scene;

/// A box of uniform caved material.
#[derive(Debug, Clone)]
pub struct UniformBox {
    /// Box size (x, y, z), m; the floor is at z = 0 and the box is centred on x = y = 0.
    pub extent: [f64; 3],
    /// Block size, m.
    pub block: [f64; 3],
    /// Solids density, t/m³.
    pub density: f64,
    /// In-situ porosity n0.
    pub n0: f64,
    /// Dilated porosity n1.
    pub n1: f64,
    /// Friction angle, degrees.
    pub friction: f64,
    /// Mean fragment size d̄, m.
    pub frag: f64,
    /// Drawpoints: (x, y, opening width).
    pub drawpoints: Vec<(f64, f64, f64)>,
    /// Number of periods.
    pub periods: usize,
    /// Tonnes per drawpoint per period.
    pub tonnes: f64,
}

impl UniformBox {
    /// The summary's Simulation 2 (Castro 2006 isolated draw): 8.3 mm fragments, a 120 mm
    /// drawpoint, a 3.3 m high model (here 1.2 m × 1.2 m in plan, 50 mm blocks).
    pub fn castro_isolated() -> UniformBox {
        UniformBox {
            extent: [1.2, 1.2, 3.3],
            block: [0.05, 0.05, 0.05],
            density: 2.6,
            n0: 0.35,
            n1: 0.45,
            friction: 40.0,
            frag: 0.0083,
            drawpoints: vec![(0.0, 0.0, 0.12)],
            periods: 10,
            tonnes: 0.02,
        }
    }

    /// Builds the scene.
    pub fn scene(&self) -> Scene {
        let n = [0, 1, 2].map(|a| ((self.extent[a] / self.block[a]).round() as usize).max(1));
        let mut bm = BlockModel {
            size: self.block,
            ..Default::default()
        };
        let mut id = 0i64;
        for k in 0..n[2] {
            for j in 0..n[1] {
                for i in 0..n[0] {
                    bm.x.push(-0.5 * self.extent[0] + (i as f64 + 0.5) * self.block[0]);
                    bm.y.push(-0.5 * self.extent[1] + (j as f64 + 0.5) * self.block[1]);
                    bm.z.push((k as f64 + 0.5) * self.block[2]);
                    bm.id.push(id);
                    id += 1;
                }
            }
        }
        let nb = bm.x.len();
        bm.cave_period = vec![0; nb];
        bm.density = vec![self.density; nb];
        bm.n0 = vec![self.n0; nb];
        bm.n1 = vec![self.n1; nb];
        bm.friction = vec![self.friction; nb];
        bm.frag = vec![self.frag; nb];
        bm.frag_shape = vec![f64::NAN; nb];
        bm.frag_scale = vec![f64::NAN; nb];
        bm.tensile = vec![f64::NAN; nb];
        bm.ucs = vec![f64::NAN; nb];
        bm.perc_k1 = vec![11.0; nb];
        bm.perc_k2 = vec![4.5; nb];
        bm.perc_vmr = vec![0.5; nb];
        bm.lithology = vec![0; nb];
        bm.lithology_names = vec!["uniform".into()];
        bm.grade_names = vec!["elev".into()];
        bm.grades = vec![bm.z.clone()];
        let problems = bm.build_index();
        debug_assert!(problems.is_empty());
        let nd = self.drawpoints.len();
        let drawpoints = Drawpoints {
            name: (0..nd).map(|d| format!("DP{:02}", d + 1)).collect(),
            x: self.drawpoints.iter().map(|d| d.0).collect(),
            y: self.drawpoints.iter().map(|d| d.1).collect(),
            z: vec![0.0; nd],
            width: self.drawpoints.iter().map(|d| d.2).collect(),
            zone: vec![String::new(); nd],
            open_period: Vec::new(),
        };
        let periods = Periods {
            id: (1..=self.periods as i64).collect(),
            name: (1..=self.periods).map(|p| p.to_string()).collect(),
            days: vec![1.0; self.periods],
            start: None,
        };
        let schedule = Schedule {
            n_drawpoints: nd,
            tonnes: vec![self.tonnes; nd * self.periods],
        };
        Scene {
            blocks: bm,
            drawpoints,
            periods,
            schedule,
            target: None,
        }
    }
}
