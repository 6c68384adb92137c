//! Integration tests: the same inputs and seed give identical outputs, across repeats,
//! thread counts and resumes from a checkpoint.

use caveflow::engine::{Engine, EngineError};
use caveflow::model::synthetic::UniformBox;

use crate::engine::{caving_scenario, caving_scene};
use crate::fixtures::{assert_identical, encoded, run};

// ---------------------------------------------------------------------------------------
// 2. Determinism
// ---------------------------------------------------------------------------------------

#[test]
fn runs_are_deterministic_across_repeats_and_thread_counts() {
    // The conservation scene: overlapping IMZs (superposition in the parallel marker
    // pass), an air gap, late caving and a blocked drawpoint.
    let scene = caving_scene();
    let sc = caving_scenario();
    let a = run(&scene, &sc);
    let b = run(&scene, &sc);
    assert_identical(&a, &b, "two runs");
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let c = pool.install(|| run(&scene, &sc));
        assert_identical(&a, &c, &format!("{threads}-thread pool"));
    }
    eprintln!(
        "{} extraction rows, {} IMZ rows, {} drawn markers identical",
        a.extraction.tonnes.len(),
        a.imz.radius.len(),
        a.drawn_len()
    );
}

#[test]
fn a_run_resumed_from_any_checkpoint_is_identical() {
    // The conservation scene again: resuming must restore overlapping IMZs, an air gap,
    // ground that caves between two listed periods and a blocked drawpoint's carry.
    let scene = caving_scene();
    let sc = caving_scenario();
    // With every mechanism on as well, resumed once mid-run: the percolation draws are
    // keyed by the marker-update count, which the checkpoint must carry.
    let mut all_on = caving_scenario();
    all_on.mechanisms.fragmentation = true;
    all_on.mechanisms.fines = true;
    all_on.mechanisms.rilling = true;
    all_on.mechanisms.stress = true;
    let expected = encoded(&run(&scene, &all_on));
    let mut mid = None;
    let _ = Engine::new(&scene, &all_on).unwrap().run_from(
        0,
        &mut |_, _| {},
        &mut |e: &Engine, next: usize| {
            if next == 3 {
                mid = Some(e.checkpoint(next, "tag"));
            }
            Ok::<(), ()>(())
        },
    );
    let (e, at) = Engine::resume(&scene, &all_on, &mid.unwrap(), "tag").unwrap();
    let resumed = e
        .run_from(at, &mut |_, _| {}, &mut |_: &Engine, _: usize| {
            Ok::<(), ()>(())
        })
        .unwrap();
    assert!(
        encoded(&resumed) == expected,
        "mechanisms on: resumed outputs differ"
    );

    let whole = encoded(&run(&scene, &sc));
    let mut checkpoints = Vec::new();
    let out = Engine::new(&scene, &sc)
        .unwrap()
        .run_from(0, &mut |_, _| {}, &mut |e: &Engine, next: usize| {
            checkpoints.push((next, e.checkpoint(next, "tag")));
            Ok::<(), ()>(())
        })
        .unwrap();
    assert_eq!(encoded(&out), whole, "checkpointing changed the run");
    assert_eq!(checkpoints.len(), scene.periods.len());
    for (next, bytes) in &checkpoints {
        let (e, at) = Engine::resume(&scene, &sc, bytes, "tag").unwrap();
        assert_eq!(at, *next);
        let resumed = e
            .run_from(at, &mut |_, _| {}, &mut |_: &Engine, _: usize| {
                Ok::<(), ()>(())
            })
            .unwrap();
        assert!(
            encoded(&resumed) == whole,
            "resumed at period index {at}: outputs differ"
        );
    }
    // A checkpoint of other inputs, or a torn one, is refused with a reason.
    let bytes = &checkpoints[2].1;
    let err = |r: Result<(Engine, usize), EngineError>| r.err().map(|e| e.to_string()).unwrap();
    assert!(err(Engine::resume(&scene, &sc, bytes, "other")).contains("other inputs"));
    assert!(err(Engine::resume(
        &scene,
        &sc,
        &bytes[..bytes.len() / 2],
        "tag"
    ))
    .contains("unreadable"));
    let other = UniformBox::castro_isolated().scene();
    assert!(err(Engine::resume(&other, &sc, bytes, "tag")).contains("does not fit"));
    eprintln!(
        "{} checkpoints ({} bytes at period index 2) resume to identical outputs",
        checkpoints.len(),
        bytes.len()
    );
}
