//! Setting up an [`Engine`]: the marker lattice, one IMZ per drawpoint at the run's
//! resolution, the IMZ parameters read from the scenario, and the per-block and
//! per-drawpoint tables the run reads (waste, fines shares, block columns); and the
//! options set before the first period (an account, trace points).

use super::account::Account;
use super::cadence::{self, Cadence};
use super::height_of_draw::tributary;
use super::imz::{Imz, ImzGeom, ImzParams, Listing};
use super::markers::{Bins, DrawnMarkers, Lattice, Markers, WallReach};
use super::{
    crediting, draw_control, trace, Engine, EngineError, RunOutput, RunPlan, RunWarning,
    WarningRule,
};
use crate::model::{Scenario, Scene};

impl<'a> Engine<'a> {
    /// Sets up the lattice and one IMZ per drawpoint, at the scenario's own plan
    /// ([`RunPlan::new`]).
    pub fn new(scene: &'a Scene, scenario: &'a Scenario) -> Result<Engine<'a>, EngineError> {
        Ok(Engine::with_plan(
            scene,
            scenario,
            RunPlan::new(scene, scenario)?,
        ))
    }

    /// Sets up the lattice and one IMZ per drawpoint, at a plan already made and checked
    /// ([`RunPlan`]).
    pub fn with_plan(scene: &'a Scene, scenario: &'a Scenario, plan: RunPlan) -> Engine<'a> {
        let bm = &scene.blocks;
        let res = plan.resolution();
        let lattice = Lattice::new(bm, res.marker_spacing)
            .with_offset(bm, scenario.resolution.lattice_offset);
        let unit_mass = lattice.unit_masses(bm);
        let max = bm.max_corner();
        let diag = ((max[0] - bm.origin[0]).powi(2) + (max[1] - bm.origin[1]).powi(2)).sqrt();
        // The IMZs sample the ground around them at the marker spacing, but never finer
        // than half their disk thickness (`engine::imz`): markers finer than that sample
        // the grades better and leave the IMZs' geometry alone.
        let ground = res.marker_spacing.max(0.5 * res.layer_thickness);
        let params = ImzParams {
            q: scenario.flow.q,
            shear_band_factor: scenario.flow.shear_band_factor,
            min_jump: scenario.flow.min_porosity_jump,
            resample: 0.5 * ground,
            redilate: 0.05 * ground,
            perimeter_spacing: ground,
            r_cap: diag,
        };
        let dp = &scene.drawpoints;
        let cadence = Cadence::new(res.max_marker_move);
        let imzs = (0..dp.len())
            .map(|d| {
                let h = res.layer_thickness;
                let mut m = Imz::new(d, dp.x[d], dp.y[d], dp.z[d], h, dp.width[d]);
                m.windows = vec![Vec::new(); cadence.max_level as usize];
                for w in &mut m.windows {
                    cadence::restart(w, &m.geom.radius);
                }
                m
            })
            .collect::<Vec<Imz>>();
        let imz_geoms: Vec<ImzGeom> = imzs.iter().map(|m| m.geom.clone()).collect();
        let n_dp = dp.len();
        let mut out = RunOutput {
            resolution: res,
            ..Default::default()
        };
        out.warnings = plan.into_warnings();
        let dc = &scenario.draw_control;
        out.control = dc.is_target().then(|| super::result::ControlRecord {
            closed: vec![None; dp.len()],
            low: vec![0; dp.len()],
            running_out: vec![None; dp.len()],
            neighbour_radius: dc.neighbour_radius,
            ..Default::default()
        });
        out.extraction.grades = vec![Vec::new(); bm.grades.len()];
        out.extraction.lithology = vec![Vec::new(); bm.lithology_names.len()];
        if scenario.mechanisms.fragmentation {
            let weak = bm.tensile.iter().filter(|t| !(**t > 0.0)).count();
            if weak > 0 {
                out.warnings.push(RunWarning::general(WarningRule::Input, format!(
                    "secondary fragmentation is on but {weak} blocks have no tensile strength or UCS; they do not break"
                )));
            }
        }
        Engine {
            scene,
            scenario,
            resolution: res,
            params,
            lattice,
            lattice_mass: lattice.block_masses(bm, &unit_mass),
            unit_mass,
            engulfed: vec![false; lattice.len()],
            engulfed_mass: vec![0.0; bm.len()],
            imzs,
            rims: vec![Vec::new(); n_dp],
            markers: Markers::default(),
            drawn: DrawnMarkers::default(),
            carry: vec![0.0; n_dp],
            cum: vec![0.0; n_dp],
            sched_cum: vec![0.0; n_dp],
            schedule: if dc.is_target() {
                std::borrow::Cow::Owned(crate::model::Schedule {
                    n_drawpoints: n_dp,
                    tonnes: vec![0.0; scene.schedule.tonnes.len()],
                })
            } else {
                std::borrow::Cow::Borrowed(&scene.schedule)
            },
            control: dc
                .is_target()
                .then(|| draw_control::Layout::new(scene, dc.neighbour_radius)),
            at: (0, 0.0),
            streams: vec![crediting::Stream::default(); n_dp],
            tally: vec![(0.0, 0); n_dp],
            hod_density_area: tributary(scene),
            drawpoint_block: (0..n_dp)
                .map(|d| {
                    let dp = &scene.drawpoints;
                    bm.locate([dp.x[d], dp.y[d], dp.z[d] + 0.5 * res.layer_thickness])
                        .unwrap_or(0)
                })
                .collect(),
            waste: waste_blocks(scene, scenario),
            fines_frac: fines_fractions(scene, scenario.outputs.fines_cutoff),
            extent: (
                [bm.origin[0], bm.origin[1]],
                [max[0] - bm.origin[0], max[1] - bm.origin[1]],
            ),
            out,
            steps_done: 0,
            marker_steps: 0,
            bins: Bins::new(
                [bm.origin[0], bm.origin[1]],
                [max[0] - bm.origin[0], max[1] - bm.origin[1]],
                grid_cell(bm, res.marker_spacing),
            ),
            rows: Vec::new(),
            geoms: vec![ImzGeom::default(); n_dp],
            listings: vec![Listing::new(); n_dp],
            viewed_at: vec![u64::MAX; n_dp],
            reach: WallReach::new(&imz_geoms, bm),
            dirty_cols: vec![true; bm.dims[0] * bm.dims[1]],
            all_moved: true,
            fixed_mass: vec![0; bm.len()],
            block_col: block_columns(bm),
            air_col: vec![0.0; bm.dims[0] * bm.dims[1]],
            cadence,
            trace: trace::Trace::default(),
            moments: {
                let o = &scenario.outputs;
                let mut m = scene.moments(&o.section_periods);
                m.extend(scene.vtk_periods(o));
                m
            },
            account: None,
        }
    }

    /// Keeps an account of the run's time per phase and its work counters
    /// ([`account`](super::account)), returned in [`RunOutput::account`].
    pub fn keep_account(mut self) -> Self {
        self.account = Some(Box::default());
        self
    }

    /// The account kept so far ([`Engine::keep_account`]), if one is kept.
    pub fn account(&self) -> Option<&Account> {
        self.account.as_deref()
    }

    /// Follows `points` through the draw ([`trace`]); they must lie inside the block model
    /// (`model::load` checks it). Call before the first period.
    pub fn with_trace(mut self, points: &[[f64; 3]]) -> Self {
        self.trace = trace::Trace::new(points);
        self
    }
}

/// Per block, its column i + n_x j in the block model's grid.
fn block_columns(bm: &crate::model::BlockModel) -> Vec<u32> {
    let mut col = vec![0; bm.len()];
    for (c, &b) in bm.index.iter().enumerate() {
        if b != crate::model::block_model::NO_BLOCK {
            col[b as usize] = (c % (bm.dims[0] * bm.dims[1])) as u32;
        }
    }
    col
}

/// Cell of the plan grids over the IMZs and the marker bins: the smaller block side, or the
/// marker spacing when coarser.
pub(super) fn grid_cell(bm: &crate::model::BlockModel, spacing: f64) -> f64 {
    bm.size[0].min(bm.size[1]).max(spacing)
}

/// Which blocks are waste under the scenario's dilution rule.
fn waste_blocks(scene: &Scene, sc: &Scenario) -> Vec<bool> {
    let bm = &scene.blocks;
    let g = match &sc.dilution.grade {
        Some(name) => bm.grade_names.iter().position(|n| n == name),
        None => (!bm.grades.is_empty()).then_some(0),
    };
    let waste_lith: Vec<bool> = bm
        .lithology_names
        .iter()
        .map(|n| sc.dilution.waste_lithologies.iter().any(|w| w == n))
        .collect();
    (0..bm.len())
        .map(|b| {
            waste_lith[bm.lithology[b] as usize]
                || g.is_some_and(|g| bm.grades[g][b] < sc.dilution.cutoff)
        })
        .collect()
}

/// Mass share of each block's primary fragmentation finer than `cut`: the Weibull CDF
/// 1 − exp(−(cut/β)^α) where α, β are given, else 1 or 0 by the mean size.
fn fines_fractions(scene: &Scene, cut: f64) -> Vec<f64> {
    let bm = &scene.blocks;
    (0..bm.len())
        .map(|b| {
            let (a, s) = (bm.frag_shape[b], bm.frag_scale[b]);
            if a.is_finite() && s.is_finite() && a > 0.0 && s > 0.0 {
                1.0 - (-(cut / s).powf(a)).exp()
            } else if bm.frag[b] < cut {
                1.0
            } else {
                0.0
            }
        })
        .collect()
}
