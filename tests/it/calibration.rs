//! Integration tests: the scenario's `[calibration]` section (model::scenario::Calibration),
//! applied by `load_scene` to the block model.

use std::path::Path;

use caveflow::io::Problems;
use caveflow::model::load::{load_scene, LoadedScene};
use caveflow::model::scenario::Calibration;
use caveflow::model::Scenario;
use tempfile::TempDir;

use crate::fixtures::{bits, tiny, write_small_scene, SMALL_SCENE_INPUTS};

/// Loads the io tests' small scene (lithologies `ore` and `waste`) under a scenario made of
/// `toml` and `sets`.
fn load_with(toml: &str, sets: &[&str]) -> (TempDir, Result<LoadedScene, Problems>) {
    let dir = TempDir::new().unwrap();
    write_small_scene(dir.path());
    let text = format!("{SMALL_SCENE_INPUTS}{toml}");
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    let sc = Scenario::from_toml(&text, "scenario.toml", &sets, dir.path())
        .unwrap_or_else(|e| panic!("{e}"));
    let r = load_scene(&sc);
    (dir, r)
}

#[test]
fn calibration_scales_the_named_lithology_n1_and_phi() {
    let (_d, base) = load_with("", &[]);
    let base = base.unwrap_or_else(|p| panic!("{p}")).scene.blocks;
    let (_d, r) = load_with(
        "[calibration]\nfrag_factor = { ore = 0.5 }\nn1_factor = 1.1\nfriction_factor = 0.9\n",
        &[],
    );
    let b = r.unwrap_or_else(|p| panic!("{p}")).scene.blocks;
    for i in 0..b.len() {
        let ore = b.lithology_names[b.lithology[i] as usize] == "ore";
        let f = if ore { 0.5 } else { 1.0 };
        assert_eq!(b.frag[i], base.frag[i] * f, "block {i}");
        assert_eq!(b.n1[i], base.n1[i] * 1.1);
        assert_eq!(b.friction[i], base.friction[i] * 0.9);
        assert_eq!(b.n0[i], base.n0[i]);
    }
    assert_eq!(b.frag[0], 0.1);
    assert_eq!(b.frag[4], 0.5, "waste is not scaled");
    // The same through --set, as the lead's calibrate writes it.
    let (_d, r) = load_with("", &["calibration.frag_factor.ore=0.5"]);
    let s = r.unwrap_or_else(|p| panic!("{p}")).scene.blocks;
    assert_eq!(
        bits(&s.frag),
        bits(&{
            let mut v = base.frag.clone();
            v[..4].iter_mut().for_each(|x| *x *= 0.5);
            v
        })
    );
}

#[test]
fn calibration_weibull_scale_and_direct_apply() {
    // Apply on a block model in memory: d̄ and the Weibull scale β scale, the shape does not.
    let mut bm = caveflow::model::BlockModel {
        id: vec![1, 2],
        n0: vec![0.3, 0.3],
        n1: vec![0.45, 0.5],
        friction: vec![38.0, 40.0],
        frag: vec![0.23, 0.04],
        frag_shape: vec![1.5, 1.5],
        frag_scale: vec![0.23 / 0.9027, 0.04 / 0.9027],
        lithology: vec![0, 1],
        lithology_names: vec!["urad".into(), "primos".into()],
        x: vec![0.0, 1.0],
        ..Default::default()
    };
    let before = bm.clone();
    let mut c = Calibration::default();
    c.frag_factor.insert("urad".into(), 0.15 / 0.23);
    c.apply(&mut bm).unwrap();
    assert!((bm.frag[0] - 0.15).abs() < 1e-15);
    assert_eq!(bm.frag_scale[0], before.frag_scale[0] * (0.15 / 0.23));
    assert_eq!(bm.frag_shape, before.frag_shape);
    assert_eq!(bits(&bm.frag[1..]), bits(&before.frag[1..]));
}

/// An identity calibration, written out in full, leaves every block column bit-identical
/// (so the engine, which reads only the scene, gives bit-identical outputs).
#[test]
fn calibration_identity_is_a_no_op() {
    assert!(Calibration::default().is_identity());
    let (_d, a) = load_with("", &[]);
    let (_d, b) = load_with(
        "[calibration]\nfrag_factor = { ore = 1.0, waste = 1.0 }\nn1_factor = 1.0\nfriction_factor = 1.0\n",
        &[],
    );
    let (a, b) = (a.unwrap().scene.blocks, b.unwrap().scene.blocks);
    for (x, y) in [
        (&a.frag, &b.frag),
        (&a.frag_scale, &b.frag_scale),
        (&a.n0, &b.n0),
        (&a.n1, &b.n1),
        (&a.friction, &b.friction),
        (&a.density, &b.density),
    ] {
        assert_eq!(bits(x), bits(y));
    }
    // A default scenario serialises its calibration, and reads it back unchanged.
    let sc = Scenario::default();
    let text = toml::to_string(&sc).unwrap();
    assert!(text.contains("[calibration]"), "{text}");
    let back = Scenario::from_toml(&text, "t", &[], Path::new("/")).unwrap();
    assert_eq!(back.calibration, Calibration::default());
}

fn scenario_err(text: &str, sets: &[&str]) -> String {
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    match Scenario::from_toml(text, "scenario.toml", &sets, Path::new("/base")) {
        Ok(_) => panic!("the scenario loaded but should not have"),
        Err(e) => {
            assert_eq!(e.rule(), "setting-range", "{e}");
            e.to_string()
        }
    }
}

#[test]
fn calibration_bad_factors_are_setting_range() {
    let e = scenario_err("[calibration]\nn1_factor = 0\n", &[]);
    assert!(
        e.starts_with(
            "scenario.toml: [setting-range] calibration.n1_factor must be a positive number, got 0"
        ),
        "{e}"
    );
    let e = scenario_err("[calibration]\nfriction_factor = nan\n", &[]);
    assert!(
        e.contains("calibration.friction_factor must be a positive number, got NaN"),
        "{e}"
    );
    let e = scenario_err("", &["calibration.frag_factor.urad=-0.5"]);
    assert!(
        e.contains("calibration.frag_factor.urad must be a positive number, got -0.5"),
        "{e}"
    );
    // A typo in the section is an unknown key, like everywhere else.
    let sets = ["calibration.n1_factr=1.1".to_string()];
    let e = Scenario::from_toml("", "scenario.toml", &sets, Path::new("/")).unwrap_err();
    assert_eq!(e.rule(), "unknown-key", "{e}");
}

/// The one problem of a load that must fail.
fn only_problem(toml: &str) -> caveflow::io::Problem {
    let (_d, r) = load_with(toml, &[]);
    let p = match r {
        Ok(_) => panic!("the scene loaded but should not have"),
        Err(p) => p,
    };
    assert_eq!(p.0.len(), 1, "{p}");
    p.0[0].clone()
}

#[test]
fn calibration_out_of_range_blocks_are_named() {
    // n1 0.45 × 2.5 = 1.125: block 1 (row 1) first, all 8 blocks in all.
    let p = only_problem("[calibration]\nn1_factor = 2.5\n");
    assert_eq!(
        p.to_string(),
        "blocks.csv: row 1, column max_porosity: [calibration-range] calibration.n1_factor = 2.5 takes max_porosity n1 of block 1 from 0.45 to 1.125, outside [n0 = 0.3, 1) (8 block(s) in all)"
    );
    // n1 0.45 × 0.6 = 0.27 < n0 0.3 for the ore; waste 0.5 × 0.6 = 0.3 < 0.35 too.
    let p = only_problem("[calibration]\nn1_factor = 0.6\n");
    assert_eq!(p.rule, "calibration-range");
    assert_eq!(p.row, Some(1));
    assert!(p.message.contains("outside [n0 = 0.3, 1)"), "{p}");
    // φ 38° × 2.5 = 95°.
    let p = only_problem("[calibration]\nfriction_factor = 2.5\n");
    assert_eq!(
        p.to_string(),
        "blocks.csv: row 1, column friction_angle: [calibration-range] calibration.friction_factor = 2.5 takes the friction angle of block 1 from 38° to 95°, outside (0°, 90°) (8 block(s) in all)"
    );
    // A lithology the block model does not have: named, with the ones it has.
    let p = only_problem("[calibration]\nfrag_factor = { urad = 0.65 }\n");
    assert_eq!(
        p.to_string(),
        "blocks.csv: column lithology: [calibration-range] calibration.frag_factor names lithology `urad`, which the block model does not have; it has: `ore`, `waste`"
    );
}

/// End to end: an identity calibration gives a bit-identical run, and a factor changes it.
#[test]
fn calibration_identity_gives_a_bit_identical_run() {
    let scene = tiny();
    let sc = Scenario::default();
    let run = |c: &Calibration| {
        let mut s = scene.clone();
        c.apply(&mut s.blocks).unwrap();
        let out = caveflow::engine::Engine::new(&s, &sc)
            .unwrap()
            .run(&mut |_, _| {});
        // JSON keeps every float exactly (shortest round trip), NaN as null.
        (
            serde_json::to_string(&out.extraction).unwrap(),
            serde_json::to_string(&out.imz).unwrap(),
        )
    };
    let base = run(&Calibration::default());
    let mut identity = Calibration::default();
    identity.frag_factor.insert("uniform".into(), 1.0);
    assert_eq!(run(&identity), base);
    let mut finer = Calibration::default();
    finer.frag_factor.insert("uniform".into(), 0.65);
    assert_ne!(run(&finer).1, base.1, "a finer d̄ changes the IMZs");
}
