//! Integration tests: the run plan (`engine::plan`). What `validate` accepts is what the
//! engine runs, and a resolution given to a plan is the one the engine uses.

use caveflow::engine::{Engine, EngineError, ResolvedResolution, RunPlan, WarningRule};
use caveflow::model::synthetic::UniformBox;
use caveflow::model::Scenario;

use crate::fixtures::{assert_identical, caveflow, demo_data, run, scenario};

/// A small isolated draw (3 periods of 0.02 t) at an explicit, coarse resolution.
fn small() -> (caveflow::model::Scene, Scenario) {
    let scene = UniformBox {
        periods: 3,
        ..UniformBox::castro_isolated()
    }
    .scene();
    (scene, scenario(0.05, 0.05, 0.002))
}

/// A plan made at a resolution runs at exactly that resolution, and gives the same run as
/// the scenario that states the same values.
#[test]
fn a_plan_runs_at_exactly_its_resolution() {
    let (scene, mut sc) = small();
    let res = ResolvedResolution {
        layer_thickness: 0.05,
        marker_spacing: 0.05,
        draw_increment: 0.002,
        max_marker_move: 0.02,
    };
    let plan = RunPlan::at(&scene, &sc, res).unwrap();
    assert_eq!(plan.resolution(), res);
    let by_plan = Engine::with_plan(&scene, &sc, plan).run(&mut |_, _| {});
    assert_eq!(by_plan.resolution, res);
    sc.resolution.max_marker_move = Some(0.02);
    let by_scenario = run(&scene, &sc);
    assert_eq!(by_scenario.resolution, res);
    assert_identical(&by_plan, &by_scenario, "plan against scenario");
}

/// Fines percolation is evaluated per update, so a plan with fines on steps every marker
/// every update; where it was given another `max_marker_move` it says so, where it
/// resolved one itself there is nothing to say.
#[test]
fn fines_step_every_marker_and_the_plan_says_when_it_changed_a_resolution() {
    let (scene, mut sc) = small();
    sc.mechanisms.fines = true;
    let res = ResolvedResolution {
        layer_thickness: 0.05,
        marker_spacing: 0.05,
        draw_increment: 0.002,
        max_marker_move: 0.03,
    };
    let plan = RunPlan::at(&scene, &sc, res).unwrap();
    assert_eq!(plan.resolution().max_marker_move, 0.0);
    let changed: Vec<_> = plan
        .warnings()
        .iter()
        .filter(|w| w.rule == WarningRule::Resolution)
        .collect();
    assert_eq!(changed.len(), 1, "{:?}", plan.warnings());
    assert!(
        changed[0]
            .message
            .contains("max_marker_move 0 instead of 0.03 m"),
        "{}",
        changed[0].message
    );
    let own = RunPlan::new(&scene, &sc).unwrap();
    assert_eq!(own.resolution().max_marker_move, 0.0);
    assert!(own
        .warnings()
        .iter()
        .all(|w| w.rule != WarningRule::Resolution));
}

/// A lattice too large for memory is refused by the plan, so `validate` refuses it too
/// (before, only `run` found it), with the key to change and exit code 1.
#[test]
fn a_lattice_too_large_is_refused_by_the_plan_and_by_validate() {
    let (scene, sc) = small();
    let res = ResolvedResolution {
        layer_thickness: 0.05,
        marker_spacing: 0.0005,
        draw_increment: 0.002,
        max_marker_move: 0.0,
    };
    match RunPlan::at(&scene, &sc, res) {
        Err(EngineError::TooManySites { sites, .. }) => assert!(sites > 2_000_000_000),
        other => panic!("expected TooManySites, got {other:?}"),
    }
    let out = caveflow()
        .arg("validate")
        .arg(demo_data().join("scenario.toml"))
        .args(["--set", "resolution.marker_spacing=0.01"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("lattice sites") && err.contains("resolution.marker_spacing"),
        "{err}"
    );
}
