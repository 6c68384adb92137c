//! Property test (issue 9): random valid scenes through the engine. No panic, every output
//! value finite (NaN only in the per-tonne columns of rows that drew no marker, which the
//! extraction schema documents as null), the tonnes accounted for, no marker lost or
//! duplicated.
//!
//! # The generator
//! A small box of 50 mm blocks (0.3–0.6 m in plan, 0.5–0.8 m high) of Castro-like material
//! whose every block draws its own density (2.0–3.0 t/m³), porosity n0 (0.25–0.40), jump
//! (0.05–0.20), friction angle (32–48°) and fragment size (4–12 mm); one to three drawpoints
//! anywhere on the floor whose openings do not intersect, openings 80–160 mm; an upper slab that caves at period 1 or
//! later; two to four periods of 0–8 kg per drawpoint; h of 25 or 50 mm, markers at h/2 or h
//! (never coarser than the blocks), increments of 0.5–2 opening disks. Every scene is
//! inside the `engine::stability` valid region by construction (d̄/w 0.025–0.15, h/d̄
//! 2–12.5), so that a failure here is the engine's, not the method's.
//!
//! Delivery (the final shortfall of a drawpoint within the conservation test's 0.5%) is
//! checked where it is a property of the engine: draws of at least [`MIN_MARKERS`]
//! markers, whose IMZ never met uncaved ground. Smaller draws and air gaps end short by
//! design (MassFlow's bounded correction; the air gap), and the run reports it.
//! Markers are no coarser than a third of the narrowest opening: a first generator with
//! markers up to h = 50 mm in 80 mm openings failed delivery by 10% (the opening disk held
//! almost no marker); that is a resolution limit, noted in `docs::physics`.
//!
//! The suite runs [`SUITE_CASES`] cases; `CAVEFLOW_PROP_CASES=N` runs N (the long run in
//! `docs::validation` used it).

use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicUsize, Ordering};

use caveflow::engine::{Engine, MarkerState, RunOutput, WarningRule};
use caveflow::model::synthetic::UniformBox;
use caveflow::model::{Scenario, Scene};
use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};

/// Cases in the test suite (tiny scenes, a few seconds in all).
const SUITE_CASES: u32 = 12;

/// One random scene and its resolution, as plain numbers (shrinkable).
#[derive(Debug, Clone)]
struct Spec {
    plan: (usize, usize),
    height: usize,
    drawpoints: Vec<(f64, f64, f64)>,
    /// Per block: density, n0, jump, φ, d̄ (cycled over the blocks).
    blocks: Vec<(f64, f64, f64, f64, f64)>,
    /// Elevation (in blocks) of the slab that caves late, and its cave period.
    slab: (usize, i64),
    /// Tonnes per (period, drawpoint).
    tonnes: Vec<f64>,
    periods: usize,
    h: f64,
    fine_markers: bool,
    increment: f64,
}

/// A drawpoint (u, v, w) of the unit square placed on the floor of an nx × ny block box,
/// at least half an opening from the walls.
fn place(&(u, v, w): &(f64, f64, f64), nx: usize, ny: usize) -> (f64, f64, f64) {
    let (ex, ey) = (0.05 * nx as f64, 0.05 * ny as f64);
    let x = -0.5 * ex + 0.5 * w + u * (ex - w);
    let y = -0.5 * ey + 0.5 * w + v * (ey - w);
    (x, y, w)
}

fn spec() -> impl Strategy<Value = Spec> {
    (
        (6usize..=12, 6usize..=12, 10usize..=16),
        prop::collection::vec((0.0f64..1.0, 0.0f64..1.0, 0.08f64..0.16), 1..=3),
        prop::collection::vec(
            (
                2.0f64..3.0,
                0.25f64..0.40,
                0.05f64..0.20,
                32.0f64..48.0,
                0.004f64..0.012,
            ),
            1..=16,
        ),
        (4usize..=20, 1i64..=4),
        2usize..=4,
        prop::collection::vec(prop_oneof![Just(0.0), 0.0f64..0.008], 12),
        (prop::bool::ANY, prop::bool::ANY, 0.5f64..2.0),
    )
        // Openings that intersect are refused by the loader (`overlapping-openings`:
        // drawpoints are cut through pillars); the first long run found that the engine then
        // credits the shared material to one of them.
        .prop_filter("openings overlap", |t| {
            let dps: Vec<_> = t.1.iter().map(|d| place(d, t.0 .0, t.0 .1)).collect();
            dps.iter().enumerate().all(|(i, a)| {
                dps[i + 1..]
                    .iter()
                    .all(|b| (a.0 - b.0).hypot(a.1 - b.1) >= 0.5 * (a.2 + b.2))
            })
        })
        .prop_map(
            |(dims, dps, blocks, slab, periods, tonnes, (thin, fine_markers, increment))| {
                let (nx, ny, nz) = dims;
                // Drawpoints inside the floor, at least half an opening from the walls.
                let drawpoints = dps.iter().map(|d| place(d, nx, ny)).collect();
                Spec {
                    plan: (nx, ny),
                    height: nz,
                    drawpoints,
                    blocks,
                    slab: (slab.0.min(nz - 1), slab.1),
                    tonnes,
                    periods,
                    h: if thin { 0.025 } else { 0.05 },
                    fine_markers,
                    increment,
                }
            },
        )
}

/// The scene and scenario of a spec.
fn build(s: &Spec) -> (Scene, Scenario) {
    let b = UniformBox {
        extent: [
            0.05 * s.plan.0 as f64,
            0.05 * s.plan.1 as f64,
            0.05 * s.height as f64,
        ],
        block: [0.05; 3],
        drawpoints: s.drawpoints.clone(),
        periods: s.periods,
        ..UniformBox::castro_isolated()
    };
    let mut scene = b.scene();
    let bm = &mut scene.blocks;
    for k in 0..bm.len() {
        let (rho, n0, jump, phi, frag) = s.blocks[k % s.blocks.len()];
        bm.density[k] = rho;
        bm.n0[k] = n0;
        bm.n1[k] = n0 + jump;
        bm.friction[k] = phi;
        bm.frag[k] = frag;
        if bm.z[k] > 0.05 * s.slab.0 as f64 {
            bm.cave_period[k] = s.slab.1;
        }
    }
    let nd = s.drawpoints.len();
    scene.schedule.tonnes = (0..s.periods * nd)
        .map(|i| s.tonnes[i % s.tonnes.len()])
        .collect();
    let mut sc = Scenario::default();
    sc.resolution.layer_thickness = Some(s.h);
    // Markers at h/2 or h/4, never coarser than the blocks nor than a third of the narrowest
    // opening (see the module docs: coarser ones can leave an opening disk without markers).
    let w = s
        .drawpoints
        .iter()
        .map(|d| d.2)
        .fold(f64::INFINITY, f64::min);
    let spacing = if s.fine_markers {
        0.25 * s.h
    } else {
        0.5 * s.h
    };
    sc.resolution.marker_spacing = Some(spacing.min(0.05).min(w / 3.0));
    // The increment in opening disks of the narrowest opening at the mean dilated density.
    let w = s
        .drawpoints
        .iter()
        .map(|d| d.2)
        .fold(f64::INFINITY, f64::min);
    let disk = std::f64::consts::PI * 0.25 * w * w * s.h * 2.5 * (1.0 - 0.45);
    sc.resolution.draw_increment = Some(s.increment * disk);
    sc.outputs.marker_periods = scene.periods.id.clone();
    (scene, sc)
}

/// Drawpoints whose delivery (final shortfall ≤ 0.5%) was checked, over the run.
static DELIVERY_CHECKED: AtomicUsize = AtomicUsize::new(0);
/// Smallest draw, in markers, whose delivery is checked.
const MIN_MARKERS: f64 = 200.0;

/// Checks one run; Err names the first broken property. `marker_mass` is the heaviest
/// marker's mass, t.
fn check(scene: &Scene, out: &RunOutput, marker_mass: f64) -> Result<(), String> {
    let ex = &out.extraction;
    let bm = &scene.blocks;
    let nd = scene.drawpoints.len();
    // Finite everywhere; NaN only in per-tonne columns of rows with no marker drawn.
    for k in 0..ex.tonnes.len() {
        let always = [
            ("scheduled_tonnes", ex.scheduled_tonnes[k]),
            ("marker_tonnes", ex.marker_tonnes[k]),
            ("correction", ex.correction[k]),
            ("tonnes", ex.tonnes[k]),
            ("shortfall_tonnes", ex.shortfall_tonnes[k]),
            ("cum_tonnes", ex.cum_tonnes[k]),
            ("hod", ex.hod[k]),
            ("air_gap", ex.air_gap[k]),
        ];
        for (name, v) in always {
            if !v.is_finite() {
                return Err(format!("extraction row {k}: {name} = {v}"));
            }
        }
        if ex.markers[k] > 0 {
            let per_tonne = [
                ex.dilution[k],
                ex.origin_z[k],
                ex.frag_size[k],
                ex.fines_share[k],
            ]
            .into_iter()
            .chain(ex.grades.iter().map(|g| g[k]))
            .chain(ex.lithology.iter().map(|l| l[k]));
            if per_tonne.into_iter().any(|v| !v.is_finite()) {
                return Err(format!(
                    "extraction row {k}: a per-tonne value is not finite"
                ));
            }
        }
    }
    let t = &out.imz;
    if !t.radius.iter().all(|r| r.is_finite() && *r >= 0.0) {
        return Err("an IMZ radius is negative or not finite".into());
    }
    let d = out.drawn_table();
    for v in [&d.origin_x, &d.origin_y, &d.origin_z, &d.mass, &d.frag_size] {
        if !v.iter().all(|x| x.is_finite()) {
            return Err("a drawn-marker value is not finite".into());
        }
    }
    for s in &out.snapshot_tables() {
        for v in [
            &s.x,
            &s.y,
            &s.z,
            &s.mass,
            &s.porosity,
            &s.shear_strain,
            &s.shear_work,
        ] {
            if !v.iter().all(|x| x.is_finite()) {
                return Err(format!("period {}: a marker value is not finite", s.period));
            }
        }
    }
    // Tonnes: per drawpoint, credited + the final shortfall = scheduled (the carry makes it
    // an identity; 1e-9 relative for summation order), and the run totals agree.
    for dp in 0..nd {
        let rows: Vec<usize> = (0..ex.drawpoint.len())
            .filter(|&k| ex.drawpoint[k] as usize == dp)
            .collect();
        let sched: f64 = rows.iter().map(|&k| ex.scheduled_tonnes[k]).sum();
        let credited: f64 = rows.iter().map(|&k| ex.tonnes[k]).sum();
        let carry = rows.last().map_or(0.0, |&k| ex.shortfall_tonnes[k]);
        if (credited + carry - sched).abs() > 1e-9 * sched.max(1e-6) {
            return Err(format!(
                "drawpoint {dp}: credited {credited} + shortfall {carry} ≠ scheduled {sched}"
            ));
        }
        // And what was owed was delivered (the conservation test's 0.5%), unless the IMZ ran
        // into uncaved ground: then the void became an air gap and the shortfall is real,
        // reported in the rows and the warnings (a late-caving slab makes that happen).
        // Discrete markers make small draws lumpy: a drawpoint asked for a few dozen markers'
        // worth in its last period can saturate the bounded correction and end short (the
        // engine reports it). The 0.5% holds for draws of MIN_MARKERS markers or more, the
        // regime of the conservation test (~10³ markers per period).
        let air = rows.last().map_or(0.0, |&k| ex.air_gap[k]);
        let enough = sched >= MIN_MARKERS * marker_mass;
        if enough && air == 0.0 {
            DELIVERY_CHECKED.fetch_add(1, Ordering::Relaxed);
        }
        if enough && air == 0.0 && carry > 0.005 * sched {
            return Err(format!(
                "drawpoint {dp}: {carry} t of {sched} t still owed at the end"
            ));
        }
        let (bs, bc) = out.balance.per_drawpoint[dp];
        if (bs - sched).abs() > 1e-9 * sched.max(1e-6)
            || (bc - credited).abs() > 1e-9 * sched.max(1e-6)
        {
            return Err(format!(
                "drawpoint {dp}: balance ({bs}, {bc}) vs rows ({sched}, {credited})"
            ));
        }
    }
    // Markers: none lost or duplicated.
    let n_drawn: i64 = ex.markers.iter().sum();
    if d.marker_id.len() as i64 != n_drawn || out.balance.markers_drawn as i64 != n_drawn {
        return Err(format!(
            "{} drawn rows, {} in the balance, {n_drawn} in extraction",
            d.marker_id.len(),
            out.balance.markers_drawn
        ));
    }
    let ids: HashSet<i64> = d.marker_id.iter().cloned().collect();
    if ids.len() != d.marker_id.len() {
        return Err("a marker was drawn twice".into());
    }
    let block_mass: HashMap<i64, f64> = (0..bm.len())
        .map(|k| {
            (
                bm.id[k],
                bm.size.iter().product::<f64>() * bm.density[k] * (1.0 - bm.n0[k]),
            )
        })
        .collect();
    let mut last_drawn = 0;
    for s in &out.snapshot_tables() {
        if !s.marker_id.windows(2).all(|w| w[0] < w[1]) {
            return Err(format!("period {}: duplicated marker id", s.period));
        }
        let drawn_now = s.state.iter().filter(|&&x| x == MarkerState::Drawn).count();
        let rows: i64 = (0..ex.period.len())
            .filter(|&k| ex.period[k] <= s.period)
            .map(|k| ex.markers[k])
            .sum();
        if drawn_now < last_drawn || drawn_now as i64 != rows {
            return Err(format!(
                "period {}: {drawn_now} drawn markers, {rows} in extraction, {last_drawn} before",
                s.period
            ));
        }
        last_drawn = drawn_now;
        let mut per_block: HashMap<i64, f64> = HashMap::new();
        for k in 0..s.marker_id.len() {
            *per_block.entry(s.block_id[k]).or_default() += s.mass[k];
        }
        for (id, m) in per_block {
            let cap = block_mass[&id];
            if m > cap * (1.0 + 1e-9) {
                return Err(format!(
                    "period {}: block {id} mobilised {m} t > {cap} t",
                    s.period
                ));
            }
        }
    }
    Ok(())
}

#[test]
fn random_valid_scenes_run_finite_and_conserve() {
    let cases = std::env::var("CAVEFLOW_PROP_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(SUITE_CASES);
    let config = Config {
        cases,
        failure_persistence: None,
        ..Config::default()
    };
    let mut runner = TestRunner::new_with_rng(
        config,
        proptest::test_runner::TestRng::deterministic_rng(
            proptest::test_runner::RngAlgorithm::ChaCha,
        ),
    );
    let n = std::cell::Cell::new(0u32);
    let result = runner.run(&spec(), |s| {
        n.set(n.get() + 1);
        let (scene, sc) = build(&s);
        let engine = Engine::new(&scene, &sc).map_err(|e| TestCaseError::fail(e.to_string()))?;
        let out = engine.run(&mut |_, _| {});
        // Valid by construction: no stability warning.
        if let Some(w) = out
            .warnings
            .iter()
            .find(|w| w.rule == WarningRule::Stability)
        {
            return Err(TestCaseError::fail(w.message.clone()));
        }
        let bm = &scene.blocks;
        let s3 = sc.resolution.marker_spacing.unwrap_or(0.05).powi(3);
        let marker_mass = (0..bm.len())
            .map(|k| s3 * bm.density[k] * (1.0 - bm.n0[k]))
            .fold(0.0, f64::max);
        check(&scene, &out, marker_mass).map_err(TestCaseError::fail)
    });
    eprintln!(
        "{} random scenes run (shrinking included); delivery checked for {} drawpoints",
        n.get(),
        DELIVERY_CHECKED.load(Ordering::Relaxed)
    );
    if let Err(e) = result {
        panic!("{e}");
    }
    // The delivery rule must have been exercised, not skipped on every scene (too little
    // drawn for the markers to resolve it, or an air gap): all 12 of the suite's scenes
    // check a drawpoint's delivery today; a quarter is the floor.
    let checked = DELIVERY_CHECKED.load(Ordering::Relaxed);
    assert!(
        4 * checked >= n.get() as usize,
        "delivery checked for only {checked} drawpoints in {} scenes",
        n.get()
    );
}
