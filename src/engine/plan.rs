//! The run plan: what a run will do, worked out once and checked before it starts.
//!
//! A scene and a scenario leave the resolution partly open (the scenario's
//! `resolution.*` keys default to rules of the scene, [`super::resolution`]) and say
//! nothing directly of whether REBOP's method holds at that resolution
//! ([`super::stability`]). [`RunPlan`] settles both, once: `validate`, `run`, `sweep` and
//! `calibrate` all build one and hand it to [`Engine::with_plan`](super::Engine::with_plan),
//! so what `validate` accepts is what `run` runs, and a sweep or a calibration runs at
//! exactly the resolution it chose: the chosen numbers go to [`RunPlan::at`], in memory or
//! through a study's case (`analysis::study`, `case_resolution`), never into the
//! scenario's `resolution` keys to be resolved again.
//!
//! The defaults themselves are stated in one place, [`super::resolution`]; the scenario's
//! keys point there.

use super::{
    resolution, stability, EngineError, ResolvedResolution, RunWarning, WarningRule, MAX_SITES,
};
use crate::model::{Scenario, Scene};

/// One validated run: the resolution the engine runs at and the stability findings that
/// did not refuse it. Made only by [`RunPlan::new`] and [`RunPlan::at`], so an engine never
/// runs an unchecked plan.
#[derive(Debug, Clone, PartialEq)]
pub struct RunPlan {
    resolution: ResolvedResolution,
    warnings: Vec<RunWarning>,
}

impl RunPlan {
    /// The plan of a scene run as its scenario says: the resolution resolved from both
    /// ([`resolution::resolve`]), then checked ([`RunPlan::at`]).
    pub fn new(scene: &Scene, sc: &Scenario) -> Result<RunPlan, EngineError> {
        RunPlan::at(scene, sc, resolution::resolve(scene, sc))
    }

    /// The plan at a resolution chosen by the caller (a sweep's grid point, a
    /// calibration's finer check), used as given but for one physical rule: fines
    /// percolation is evaluated per update, so with `mechanisms.fines` on every marker
    /// steps every update (`max_marker_move` 0), and a plan that asked for another value
    /// says so in its warnings. Refused, with every reason, when the lattice would not fit
    /// in memory or the scene lies where the method fails ([`stability::assess`]; a
    /// refusal is a warning instead where `flow.enforce_stability = false`).
    pub fn at(
        scene: &Scene,
        sc: &Scenario,
        mut res: ResolvedResolution,
    ) -> Result<RunPlan, EngineError> {
        let mut warnings = Vec::new();
        if sc.mechanisms.fines && res.max_marker_move != 0.0 {
            warnings.push(RunWarning::general(
                WarningRule::Resolution,
                format!(
                    "fines percolation steps every marker every update: max_marker_move 0 instead of {} m",
                    res.max_marker_move
                ),
            ));
            res.max_marker_move = 0.0;
        }
        let sites = super::markers::Lattice::new(&scene.blocks, res.marker_spacing).len();
        if sites > MAX_SITES {
            return Err(EngineError::TooManySites {
                spacing: res.marker_spacing,
                sites,
                limit: MAX_SITES,
            });
        }
        let stability = stability::assess(scene, sc, &res).map_err(EngineError::Refused)?;
        warnings.extend(
            stability
                .into_iter()
                .map(|m| RunWarning::general(WarningRule::Stability, m)),
        );
        Ok(RunPlan {
            resolution: res,
            warnings,
        })
    }

    /// h, marker spacing, draw increment and `max_marker_move`, as the engine uses them.
    pub fn resolution(&self) -> ResolvedResolution {
        self.resolution
    }

    /// The degraded findings of [`stability::assess`] (and the refused ones, where
    /// `flow.enforce_stability = false`), one per rule, and a resolution the plan had to
    /// change; the run log and the manifest repeat them.
    pub fn warnings(&self) -> &[RunWarning] {
        &self.warnings
    }

    /// [`RunPlan::warnings`], taken.
    pub fn into_warnings(self) -> Vec<RunWarning> {
        self.warnings
    }
}
