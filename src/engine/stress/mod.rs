//! Stress logic: vertical and horizontal stress in and around IMZs without finite elements,
//! and the levels where stagnant ground between IMZs may yield and flow (interactive draw,
//! Heslop and Laubscher 1981). Summary §5 ("Interactive draw and the role of stress"), §5.3
//! (REBOP logic); DESIGN §4.4.
//!
//! [`compute`] is a pure function of the block model, the period and the IMZ geometries
//! ([`ImzGeom`]); the engine calls it at the end of the periods the scenario asks for
//! (`[stress] periods`), so it costs nothing when `mechanisms.stress` is off.
//!
//! # Slices (summary §5.3)
//! The caved volume is cut into horizontal levels `cell` apart (default: the IMZ disk
//! thickness h, so a slice is a disk). At each level there are three nested kinds of slice:
//! - **cave slice**: the flowable (caved) ground of the level, from the block model and the
//!   period (`BlockModel::flowable`);
//! - **bin slices**: an isolated IMZ disk, or a cluster of overlapping IMZ disks;
//! - **group slices**: bins whose elastic zones overlap (connected components).
//!
//! # Module map
//! The method is described in numbered sections, each in the docs of the file that
//! implements it:
//! - `janssen.rs`: §1 cave-average vertical stress (Janssen differential slices) and §2 bin
//!   stress inside the IMZs;
//! - `shaft.rs`: §3 plastic and elastic zones, the pressurised shaft around one bin
//!   (Mohr–Coulomb, Carranza-Torres 2002);
//! - `level.rs`: §4 several bins (superposition, yield cap, arching, force balance) and §5
//!   the interactive draw flags (pillars), one level at a time;
//! - `section.rs`: the N-S, E-W and plan sections written to Parquet and charted;
//! - `mod.rs` (here): the public result types ([`StressField`], [`StressLevels`], [`Zone`],
//!   [`StressParams`]) and [`compute`], which runs §1–5 over all levels.
//!
//! Everything public in the submodules is re-exported here (`engine::stress::…`).

use rayon::prelude::*;

use super::imz::ImzGeom;
use crate::model::scenario::{LateralRatio, StressSettings};
use crate::model::BlockModel;

mod janssen;
mod level;
mod section;
mod shaft;

pub use janssen::{
    janssen_closed_form, janssen_length, janssen_profile, janssen_step, lateral_ratio, JanssenSlice,
};
pub use level::{union_area_perimeter, PILLAR_SAMPLES};
pub use section::{Orientation, StressSection};
pub use shaft::{passive_coefficient, plastic_radius, stress_strength_ratio, Shaft, ShaftZone};

use level::{bins_at, cave_slice, disks_at, solve_level, Grid, Level, LevelRow};
use section::{decorate, section_rows, section_specs, SectionRows};

/// Gravitational acceleration, m/s²: t/m³ × g = kN/m³, so stresses come out in kPa.
pub const GRAVITY: f64 = 9.81;

// ---------------------------------------------------------------------------------------
// The field
// ---------------------------------------------------------------------------------------

/// What a point of a cave slice is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[repr(u8)]
pub enum Zone {
    /// Not caved (or outside the model): no stress computed.
    Uncaved = 0,
    /// Inside an IMZ (a bin).
    Imz = 1,
    /// Stagnant, in a plastic zone.
    Plastic = 2,
    /// Stagnant, in an elastic zone.
    Elastic = 3,
    /// Stagnant, outside every elastic zone (outside the draw area).
    Far = 4,
}

impl Zone {
    /// Name written to Parquet.
    pub fn name(self) -> &'static str {
        match self {
            Zone::Uncaved => "uncaved",
            Zone::Imz => "imz",
            Zone::Plastic => "plastic",
            Zone::Elastic => "elastic",
            Zone::Far => "far",
        }
    }
}

/// Per-level results (one row per level, bottom up).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StressLevels {
    /// Level elevation (slice mid-height), m.
    pub z: Vec<f64>,
    /// Cave slice area, m².
    pub cave_area: Vec<f64>,
    /// Cave slice perimeter, m.
    pub cave_perimeter: Vec<f64>,
    /// Janssen cave-average vertical stress σ̄, kPa (NaN without caved ground).
    pub sigma_v_cave: Vec<f64>,
    /// Area-weighted mean of the redistributed vertical stress over the cave slice, kPa.
    pub sigma_v_mean: Vec<f64>,
    /// Bin slices.
    pub bins: Vec<i64>,
    /// Group slices.
    pub groups: Vec<i64>,
    /// Pillars between bins of one group.
    pub pillars: Vec<i64>,
    /// Largest pillar minimum stress:strength ratio (NaN without pillars).
    pub pillar_ratio: Vec<f64>,
    /// Mean stress:strength ratio of the stagnant ground inside the elastic zones (NaN
    /// without IMZs).
    pub stagnant_ratio: Vec<f64>,
    /// Force arched onto the stagnant ground to keep the slice average (outside the draw
    /// area first), over the slice area, kPa; negative when taken back.
    pub arched: Vec<f64>,
    /// Potential stress-driven flow of stagnant ground (a pillar yields).
    pub flagged: Vec<bool>,
}

/// The stress logic's result at the end of one period.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StressField {
    /// Period number.
    pub period: i64,
    /// Grid cell and level spacing used, m.
    pub cell: f64,
    /// Per-level results.
    pub levels: StressLevels,
    /// Sections.
    pub sections: Vec<StressSection>,
    /// Cumulative tonnes drawn per drawpoint so far (labels; filled by the engine).
    pub drawn_tonnes: Vec<f64>,
}

/// Resolved parameters of one computation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StressParams {
    /// Grid cell and level spacing, m.
    pub cell: f64,
    /// Cohesion c, kPa.
    pub cohesion: f64,
    /// K of the cave slices.
    pub cave_k: LateralRatio,
    /// K inside IMZs.
    pub bin_k: f64,
    /// Wall friction angle, degrees (None: the caved rock's φ).
    pub wall_friction: Option<f64>,
}

impl StressParams {
    /// From the scenario's settings; `h` is the IMZ disk thickness (default cell).
    pub fn new(s: &StressSettings, h: f64) -> StressParams {
        StressParams {
            cell: s.cell.unwrap_or(h),
            cohesion: s.cohesion_kpa,
            cave_k: s.cave_k,
            bin_k: s.bin_k,
            wall_friction: s.wall_friction_deg,
        }
    }
}

/// Computes the stress field at the end of `period` for the IMZ geometries `geoms` (one per
/// drawpoint, in drawpoint order). See the module docs for the method.
pub fn compute(
    bm: &BlockModel,
    period: i64,
    geoms: &[ImzGeom],
    params: &StressParams,
    settings: &StressSettings,
) -> StressField {
    let cell = params.cell;
    let max = bm.max_corner();
    let n = [0, 1, 2].map(|a| (((max[a] - bm.origin[a]) / cell - 1e-9).ceil() as usize).max(1));
    let grid = Grid {
        origin: bm.origin,
        cell,
        n,
    };
    let mut levels: Vec<Level> = (0..n[2])
        .into_par_iter()
        .map(|k| {
            let z = grid.centre(2, k);
            Level::new(z, cave_slice(bm, period, &grid, z), disks_at(geoms, z))
        })
        .collect();

    // 1. Janssen cave average, top-down.
    let slices: Vec<JanssenSlice> = levels
        .iter()
        .rev()
        .map(|l| {
            let wall = params.wall_friction.unwrap_or(l.cave.phi);
            JanssenSlice {
                thickness: cell,
                area: l.cave.area,
                perimeter: l.cave.perimeter,
                unit_weight: l.cave.gamma,
                k: lateral_ratio(params.cave_k, l.cave.phi),
                mu: wall.to_radians().tan(),
            }
        })
        .collect();
    let profile = janssen_profile(&slices, 0.0);
    for (l, s) in levels.iter_mut().rev().zip(profile) {
        l.sigma = s;
    }

    // 2. Bins and their Janssen stress, top-down per IMZ.
    let mut state = vec![f64::NAN; geoms.len()];
    for l in levels.iter_mut().rev() {
        l.bins = bins_at(bm, &l.disks, l.z);
        let mut below = Vec::new();
        for bin in &mut l.bins {
            let lambda = janssen_length(
                bin.area,
                bin.perimeter,
                params.bin_k,
                bin.phi.to_radians().tan(),
            );
            let steady = bin.gamma * lambda;
            let (mut s, mut w) = (0.0, 0.0);
            for &m in &bin.members {
                let k = &l.disks[m];
                if state[k.imz].is_finite() {
                    s += state[k.imz] * k.r * k.r;
                    w += k.r * k.r;
                }
            }
            let top = if w > 0.0 { s / w } else { steady };
            let mid = janssen_step(top, bin.gamma, lambda, 0.5 * cell);
            let bottom = janssen_step(top, bin.gamma, lambda, cell);
            below.extend(bin.members.iter().map(|&m| (l.disks[m].imz, bottom)));
            bin.sigma = if l.sigma.is_finite() {
                mid.min(l.sigma)
            } else {
                mid
            };
        }
        for (imz, s) in below {
            state[imz] = s;
        }
    }

    // 3–5. Shafts, groups, the field, force balance, pillars and sections, per level.
    let specs = section_specs(bm, geoms, settings, &grid);
    let per_level: Vec<(LevelRow, Vec<SectionRows>)> = levels
        .par_iter_mut()
        .map(|l| {
            let row = solve_level(l, &grid, params);
            let rows = specs
                .iter()
                .map(|s| section_rows(l, s, &grid, params, geoms))
                .collect();
            (row, rows)
        })
        .collect();

    let mut out = StressField {
        period,
        cell,
        ..Default::default()
    };
    let lv = &mut out.levels;
    for (l, (row, _)) in levels.iter().zip(&per_level) {
        lv.z.push(l.z);
        lv.cave_area.push(l.cave.area);
        lv.cave_perimeter.push(l.cave.perimeter);
        lv.sigma_v_cave.push(l.sigma);
        lv.sigma_v_mean.push(row.mean);
        lv.bins.push(l.bins.len() as i64);
        lv.groups.push(l.groups as i64);
        lv.pillars.push(row.pillars as i64);
        lv.pillar_ratio.push(row.pillar_ratio);
        lv.stagnant_ratio.push(row.stagnant_ratio);
        lv.arched.push(l.arched);
        lv.flagged.push(row.flagged);
    }
    for (s, spec) in specs.iter().enumerate() {
        let mut sec = StressSection {
            orientation: Some(spec.orientation),
            at: spec.at,
            cell,
            ..Default::default()
        };
        for (_, rows) in &per_level {
            let r = &rows[s];
            sec.x.extend(&r.x);
            sec.y.extend(&r.y);
            sec.z.extend(&r.z);
            sec.sigma_v.extend(&r.sigma_v);
            sec.sigma_h.extend(&r.sigma_h);
            sec.ratio.extend(&r.ratio);
            sec.zone.extend(&r.zone);
        }
        let nu = spec.u.len();
        sec.shape = (nu, sec.x.len().checked_div(nu).unwrap_or(0));
        decorate(&mut sec, geoms);
        out.sections.push(sec);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::synthetic::UniformBox;

    fn rel(a: f64, b: f64) -> f64 {
        (a - b).abs() / b.abs().max(1e-300)
    }

    fn geom(x: f64, y: f64, radii: &[f64]) -> ImzGeom {
        ImzGeom {
            x,
            y,
            z0: 0.0,
            h: 0.05,
            radius: radii.to_vec(),
        }
    }

    /// Per level, the redistributed vertical stress averages to the Janssen cave average
    /// over the cave slice. The balance is imposed on the same raster it is checked on, so
    /// only rounding remains (sums of ~1e4 cells): 1e-9 relative.
    #[test]
    fn redistribution_keeps_the_cave_slice_average() {
        let scene = UniformBox {
            extent: [1.2, 1.0, 1.0],
            ..UniformBox::castro_isolated()
        }
        .scene();
        // Two IMZs 0.3 m apart, widening upward, and one cluster of two overlapping ones.
        let r: Vec<f64> = (0..16).map(|i| 0.06 + 0.006 * i as f64).collect();
        let geoms = vec![
            geom(-0.35, 0.0, &r),
            geom(-0.05, 0.0, &r),
            geom(0.3, 0.2, &r),
            geom(0.35, 0.25, &r),
        ];
        let settings = StressSettings::default();
        for c in [0.0, 2.0] {
            let params = StressParams {
                cell: 0.02,
                cohesion: c,
                ..StressParams::new(&settings, 0.05)
            };
            let f = compute(&scene.blocks, 1, &geoms, &params, &settings);
            let lv = &f.levels;
            let mut n = 0;
            for k in 0..lv.z.len() {
                assert!(
                    rel(lv.sigma_v_mean[k], lv.sigma_v_cave[k]) < 1e-9,
                    "z {} mean {} cave {}",
                    lv.z[k],
                    lv.sigma_v_mean[k],
                    lv.sigma_v_cave[k]
                );
                n += (lv.bins[k] > 0) as usize;
            }
            assert!(n >= 30, "levels with bins: {n}");
            // Bins: at least one cluster (two overlapping IMZs count once).
            assert!(lv.bins.contains(&3));
        }
    }
}
