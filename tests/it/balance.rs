//! Integration tests: mass-consistent kinematics (`engine::imz`, the volume balance). The
//! IMZ's material is at n1, the stagnant ground at n0, and the marker field carries the
//! mass that geometry implies, so the mass correction corrects discreteness only. Each test
//! prints what it measured (`cargo test ... balance:: -- --nocapture`).

use std::f64::consts::PI;

use caveflow::engine::imz::dilation;
use caveflow::engine::markers::Lattice;
use caveflow::engine::{Engine, RunOutput, WarningRule};
use caveflow::model::synthetic::UniformBox;
use caveflow::model::{Scenario, Scene};

use crate::fixtures::{marker_ratio, never_cave_above, run, scenario};

/// Median of the correction factor over the `ok` rows of `periods` that drew markers.
fn median_correction(out: &RunOutput, periods: &[i64]) -> f64 {
    let ex = &out.extraction;
    let mut c: Vec<f64> = (0..ex.correction.len())
        .filter(|&k| ex.status[k] == "ok" && ex.marker_tonnes[k] > 0.0)
        .filter(|&k| periods.contains(&ex.period[k]))
        .map(|k| ex.correction[k])
        .collect();
    assert!(!c.is_empty());
    c.sort_unstable_by(f64::total_cmp);
    c[c.len() / 2]
}

/// The median correction of the first and the second half of the periods lie within
/// 1 ± `tol`: no bias, and no trend over the run.
fn assert_unbiased(name: &str, scene: &Scene, out: &RunOutput, tol: f64) {
    let ids = &scene.periods.id;
    let (first, second) = ids.split_at(ids.len() / 2);
    let (m1, m2) = (
        median_correction(out, first),
        median_correction(out, second),
    );
    let c = &out.balance.correction;
    eprintln!(
        "{name}: median correction {:.4} (p10 {:.4}, p90 {:.4}, {} rows); first half {m1:.4}, second half {m2:.4}; marker / scheduled tonnes {:.4}",
        c.median,
        c.p10,
        c.p90,
        c.rows,
        out.balance.marker_tonnes / out.balance.scheduled_tonnes
    );
    for (half, m) in [("first", m1), ("second", m2)] {
        assert!(
            (m - 1.0).abs() <= tol,
            "{name}: {half}-half median correction {m}"
        );
    }
    assert!(!out
        .warnings
        .iter()
        .any(|w| w.rule == WarningRule::MassBalance));
}

/// Castro's isolated draw (summary §3.4, Simulation 2), 10 kg a period for ten periods.
fn castro_10kg() -> Scene {
    UniformBox {
        tonnes: 0.01,
        ..UniformBox::castro_isolated()
    }
    .scene()
}

/// Isolated draw at physical-model scale (summary §3.4, Simulation 2: 8.3 mm fragments, a
/// 120 mm drawpoint, a 3.3 m high model), 10 kg a period for ten periods, at the automatic
/// resolution: the markers drawn weigh what the schedule asks. Before the balance was made
/// consistent this median was ~0.90.
///
/// Tolerance 0.02 (the issue's): a period draws ~10 kg, about 400 markers at the automatic
/// 15 mm spacing (26 g each), so one period's marker tonnes scatter by a few percent about
/// the schedule; the median over five periods is within 0.01 of 1 when unbiased.
#[test]
fn isolated_draw_draws_the_scheduled_marker_mass() {
    let scene = castro_10kg();
    let out = run(&scene, &Scenario::default());
    assert_unbiased("isolated draw", &scene, &out, 0.02);
}

/// A lattice moved in plan (`resolution.lattice_offset`) is another sample of the same
/// ground, as good as the default one: isolated draw as above is as unbiased (same
/// tolerance), from other sites (every drawn marker's origin sits 0.3 and −0.45 spacings
/// off the default lattice in x and y), and delivers the same tonnes.
#[test]
fn an_offset_lattice_samples_the_same_draw_from_other_sites() {
    let scene = castro_10kg();
    let mut sc = Scenario::default();
    sc.resolution.lattice_offset = [0.3, -0.45];
    let out = run(&scene, &sc);
    assert_unbiased("isolated draw, offset lattice", &scene, &out, 0.02);
    let s = out.resolution.marker_spacing;
    let o = scene.blocks.origin;
    let phase = |x: f64, o: f64| ((x - o) / s - 0.5).rem_euclid(1.0);
    let t = out.drawn_table();
    assert!(!t.origin_x.is_empty());
    for k in 0..t.origin_x.len() {
        assert!((phase(t.origin_x[k], o[0]) - 0.3).abs() < 1e-6);
        assert!((phase(t.origin_y[k], o[1]) - 0.55).abs() < 1e-6);
    }
    let plain = run(&scene, &Scenario::default());
    assert_eq!(out.balance.credited_tonnes, plain.balance.credited_tonnes);
}

/// A drawpoint near a wall draws the same marker mass whether or not the lattice's offset
/// puts a column of sites on that wall: the demo's D01-01, 6.1 m from the west wall,
/// drawing its schedule alone, at offsets (0, 0) and (−0.5, 0). At −0.5 the first sites'
/// cells are half cells on the wall. Sites on the regular lattice sat on the wall itself,
/// where the walls' images carry a marker along the wall but never off it: 0.923 of the
/// schedule in markers against 0.990. At their cells' middles (`Lattice::centre`):
/// 0.983 against 0.990.
///
/// Tolerance 0.02 between the two: a drawpoint's marker tonnes over the run (79 kt, some
/// 6000 markers) move by 0.44% (median standard deviation) between lattice offsets, and
/// both must be within 0.02 of 1 as isolated draw is.
#[test]
fn a_lattice_with_sites_on_a_wall_draws_beside_it_as_the_default_one() {
    use caveflow::model::demo::{henderson, scenario, DemoScale};
    let mut scene = henderson(DemoScale::Small, 42);
    let d = scene
        .drawpoints
        .name
        .iter()
        .position(|n| n == "D01-01")
        .unwrap();
    let nd = scene.schedule.n_drawpoints;
    for (k, t) in scene.schedule.tonnes.iter_mut().enumerate() {
        if k % nd != d {
            *t = 0.0;
        }
    }
    let ratio = |offset: [f64; 2]| {
        let mut sc = scenario(DemoScale::Small, 42);
        sc.resolution.lattice_offset = offset;
        marker_ratio(&run(&scene, &sc), d)
    };
    let (plain, on_wall) = (ratio([0.0, 0.0]), ratio([-0.5, 0.0]));
    eprintln!("D01-01 alone, marker tonnes over scheduled: {plain:.4} at (0, 0), {on_wall:.4} at (-0.5, 0)");
    assert!((plain - 1.0).abs() <= 0.02 && (on_wall - 1.0).abs() <= 0.02);
    assert!((on_wall - plain).abs() <= 0.02);
}

/// IN-T2 (summary §4: two drawpoints 0.7 m apart), 25 kg a drawpoint a period for eight
/// periods at the automatic resolution: the overlap (ground already dilated by the
/// neighbour widens a disk for free, with no void and no radial push) keeps the balance.
/// Tolerance as for isolated draw.
#[test]
fn in_t2_pair_draws_the_scheduled_marker_mass() {
    let spacing = 0.7;
    let scene = UniformBox {
        extent: [1.4, 1.0, 3.3],
        drawpoints: vec![(-0.5 * spacing, 0.0, 0.12), (0.5 * spacing, 0.0, 0.12)],
        periods: 8,
        tonnes: 0.025,
        ..UniformBox::castro_isolated()
    }
    .scene();
    let out = run(&scene, &Scenario::default());
    assert_unbiased("IN-T2", &scene, &out, 0.02);
}

/// A closed volume: an isolated IMZ that never reaches the top of its box. Solids are
/// conserved between the IMZ's bulk at n1, the stagnant ground at n0 and the solids drawn,
/// with the IMZ taken from the geometry and the drawn solids from the markers (before any
/// correction):
///
/// V_imz (1 − n1) ρ_s + (V_box − V_imz)(1 − n0) ρ_s + drawn = V_box (1 − n0) ρ_s.
///
/// V_imz leaves out the core of the opening disk (radius w/2), which is mobilised from the
/// start, is never dilated by the balance and so stays at n0 (its π r² h Δn ρ_s of solids
/// is 0.2% of what is drawn here). Tolerance 1.5% of the drawn solids: 100 kg are drawn
/// as ~3000 markers of 33 g (12.5 mm spacing), and the lattice sites a disk engulfs differ
/// from its area by the sites on its rim.
///
/// The marker field must also fill the IMZ at n1: the markers inside the final IMZ weigh
/// V_imz (1 − n1) ρ_s to 3% (the lattice count of a curved boundary).
#[test]
fn a_closed_volume_conserves_solids_between_the_imz_the_stagnant_ground_and_the_draw() {
    let b = UniformBox {
        periods: 10,
        tonnes: 0.01,
        ..UniformBox::castro_isolated()
    };
    let scene = b.scene();
    let (h, s) = (0.025, 0.0125);
    let mut sc = scenario(h, s, 0.0004);
    sc.outputs.marker_periods = vec![10];
    let out = run(&scene, &sc);
    let last = 10;
    let t = &out.imz;
    let disks: Vec<(f64, f64)> = (0..t.radius.len())
        .filter(|&k| t.period[k] == last)
        .map(|k| (t.z_base[k], t.radius[k]))
        .collect();
    let top = disks.iter().map(|d| d.0 + h).fold(0.0, f64::max);
    assert!(
        top < scene.blocks.z_max() - 0.5,
        "the IMZ reached the top: {top}"
    );
    let r_open = 0.06;
    let v_imz: f64 =
        disks.iter().map(|d| PI * h * d.1 * d.1).sum::<f64>() - PI * h * r_open * r_open;
    let v_box: f64 = b.extent.iter().product();
    let rho = b.density;
    let initial = v_box * (1.0 - b.n0) * rho;
    let drawn = out.balance.marker_tonnes;
    let now = v_imz * (1.0 - b.n1) * rho + (v_box - v_imz) * (1.0 - b.n0) * rho + drawn;
    eprintln!(
        "closed volume: IMZ {:.4} m³ up to {top:.2} m; drawn {:.2} kg of markers ({:.2} kg scheduled); solids now − initially {:+.3} kg ({:+.2}% of drawn)",
        v_imz,
        1000.0 * drawn,
        1000.0 * out.balance.scheduled_tonnes,
        1000.0 * (now - initial),
        100.0 * (now - initial) / drawn
    );

    // The markers inside the IMZ at the end weigh the IMZ's bulk at n1.
    let snaps = out.snapshot_tables();
    let snap = snaps.last().unwrap();
    let inside: f64 = (0..snap.marker_id.len())
        .filter(|&k| snap.drawpoint[k] == u32::MAX)
        .filter(|&k| {
            let i = (snap.z[k] / h) as usize;
            disks
                .get(i)
                .is_some_and(|d| snap.x[k].hypot(snap.y[k]) <= d.1)
        })
        .map(|k| snap.mass[k])
        .sum();
    let at_n1 = (v_imz + PI * h * r_open * r_open) * (1.0 - b.n1) * rho;
    eprintln!(
        "markers in the IMZ {:.2} kg; its bulk at n1 holds {:.2} kg ({:+.2}%)",
        1000.0 * inside,
        1000.0 * at_n1,
        100.0 * (inside / at_n1 - 1.0)
    );
    assert!((inside / at_n1 - 1.0).abs() <= 0.03);
    assert!((now - initial).abs() <= 0.015 * drawn);
}

/// An isolated 120 mm drawpoint in a 1.2 m box of Castro material whose ground above
/// `cap` never caves (`None`: the box's top is a free surface), 1 kg a period for 12
/// periods.
fn capped_box(height: f64, cap: Option<f64>) -> (UniformBox, Scene) {
    let b = UniformBox {
        extent: [1.2, 1.2, height],
        periods: 12,
        tonnes: 0.001,
        ..UniformBox::castro_isolated()
    };
    let mut scene = b.scene();
    if let Some(z) = cap {
        never_cave_above(&mut scene, z);
    }
    (b, scene)
}

/// Resolution of the void tests: h = 25 mm, s = 12.5 mm, 0.2 kg increments.
const S: f64 = 0.0125;

/// The engine after every period of `scene`.
fn draw_all<'a>(scene: &'a Scene, sc: &'a Scenario) -> Engine<'a> {
    let mut e = Engine::new(scene, sc).unwrap();
    for p in 0..scene.periods.len() {
        e.run_period(p);
    }
    e
}

/// Void balance of the IMZ of [`draw_to_the_top`]: the void drawn (tonnes / ρ_s (1 − n1))
/// is the void the rings absorbed (ε π h Σ (R_i² − R_i,0²)) plus what left through the top
/// (vented to the free surface, or held as air under uncaved ground), to 1e-9: none is lost.
fn assert_no_void_lost(b: &UniformBox, e: &Engine) {
    let (imz, h, r_open) = (&e.imzs[0], 2.0 * S, 0.06);
    let eps = dilation(b.n1 - b.n0, b.n1);
    let absorbed: f64 = imz
        .geom
        .radius
        .iter()
        .enumerate()
        .map(|(i, &r)| eps * PI * h * (r * r - if i == 0 { r_open * r_open } else { 0.0 }))
        .sum();
    let drawn_void = (b.periods as f64 * b.tonnes) / (b.density * (1.0 - b.n1));
    eprintln!(
        "void drawn {drawn_void:.5} m³ = absorbed {absorbed:.5} + vented {:.5} + air {:.5}",
        imz.vented, imz.air
    );
    assert!((absorbed + imz.vented + imz.air - drawn_void).abs() <= 1e-9 * drawn_void);
}

/// The volume by which the sheet of markers that started in lattice layer `layer` sank: in
/// plan cells of 2 s, the mean drop of those markers now in a cell times the cell's area,
/// summed. The sheet is the top of the flowing ground (nothing flows above it), so this is
/// the crater under the free surface or the air gap under a cap; cells holding none of its
/// markers are ground the IMZ never reached (no drop).
fn sheet_drop(b: &UniformBox, lat: &Lattice, e: &Engine, layer: usize) -> f64 {
    let mk = &e.markers;
    let cell = 2.0 * S;
    let n = (b.extent[0] / cell).ceil() as usize;
    let mut drop = vec![(0.0, 0usize); n * n];
    for k in 0..mk.len() {
        let id = mk.id[k] as usize;
        if id / (lat.n[0] * lat.n[1]) != layer {
            continue;
        }
        let i = ((mk.x[k] + 0.5 * b.extent[0]) / cell) as usize;
        let j = ((mk.y[k] + 0.5 * b.extent[1]) / cell) as usize;
        let c = &mut drop[i.min(n - 1) + n * j.min(n - 1)];
        c.0 += lat.pos(id)[2] - mk.z[k];
        c.1 += 1;
    }
    drop.iter()
        .filter(|c| c.1 > 0)
        .map(|c| c.0 / c.1 as f64 * cell * cell)
        .sum()
}

/// Lattice layers on disk boundaries: the drawpoint lies level with the lattice's origin,
/// so at h = s/2 every layer of sites lies exactly on a disk base, and at h = 1.5 s every
/// third. Each such site belongs to the disk `ImzGeom::disk_at` puts it in and is engulfed
/// by that disk's growth, so after the draw every site inside the IMZ is a marker (moving
/// or drawn). Before, a site on a boundary could fall in neither disk's range of layers
/// and was never engulfed: 932 of the 13 708 sites inside the IMZ here at h = s/2 and 488
/// at 1.5 s, and an isolated demo drawpoint delivered 0.59 (h = s/2) and 0.93 (1.5 s) of
/// its schedule in markers (1.000 and 1.002 now). At 1.5 s the markers drawn weigh the
/// schedule to 2%, as in isolated draw (~3600 markers of 3.3 g; 0.987 measured). At
/// h = s/2 they weigh 0.953, and less with smaller increments (0.897 at a quarter of
/// this one), while at 0.45 s and 0.55 s, with few sites on a base, they weigh 0.98 and
/// 1.00 at a quarter: markers that start exactly on a disk base still lose volume, where
/// they are engulfed in the IMZ's upper part (`docs::validation`), not fixed yet, so no
/// tolerance is claimed at h = s/2.
#[test]
fn lattice_layers_on_disk_boundaries_are_engulfed() {
    let (b, scene) = capped_box(0.5, None);
    let lat = Lattice::new(&scene.blocks, S);
    for h in [0.5 * S, 1.5 * S] {
        let sc = scenario(h, S, 0.0002);
        let e = draw_all(&scene, &sc);
        let g = &e.imzs[0].geom;
        let mut marker = vec![false; lat.len()];
        for &id in e.markers.id.iter().chain(&e.drawn.m.id) {
            marker[id as usize] = true;
        }
        let inside: Vec<usize> = (0..lat.len())
            .filter(|&id| g.disk_at(lat.pos(id)).is_some())
            .collect();
        let on_base = inside
            .iter()
            .filter(|&&id| g.height(lat.pos(id)[2]).fract() == 0.0)
            .count();
        let missed = inside.iter().filter(|&&id| !marker[id]).count();
        let drawn: f64 = e.drawn.m.mass.iter().sum();
        let ratio = drawn / (b.periods as f64 * b.tonnes);
        eprintln!(
            "h {h}: {} sites inside the IMZ ({on_base} on a disk base), {missed} not engulfed; \
             drawn markers {ratio:.4} of the schedule",
            inside.len()
        );
        assert!(on_base > 0, "h {h}: no layer lies on a disk base");
        assert_eq!(missed, 0, "h {h}: sites inside the IMZ never engulfed");
        if h > S {
            assert!((ratio - 1.0).abs() <= 0.02, "h {h}: {ratio}");
        }
    }
}

/// A broken-through isolated IMZ: a 0.5 m column drawn to about four times its
/// breakthrough draw, no rilling. Void that leaves the top disk moves the top disk's
/// markers, so the crater the surface markers make is the void vented through the IMZ's
/// top. Tolerance 5%: the sheet is read from ~500 markers in cells of 2 s, and a marker's
/// drop is its centre's while the surface is its top (a dilated marker is ~0.1 s taller);
/// with the top disk's markers held at the top (the void interpolated to zero there, as
/// before) the crater came out 34% short.
#[test]
fn a_broken_through_imz_subsides_the_surface_by_the_void_that_left() {
    let (b, scene) = capped_box(0.5, None);
    let sc = scenario(2.0 * S, S, 0.0002);
    let e = draw_all(&scene, &sc);
    let imz = &e.imzs[0];
    assert!(
        imz.vented > 0.0 && imz.air == 0.0,
        "the IMZ did not break through"
    );
    assert_no_void_lost(&b, &e);
    let lat = Lattice::new(&scene.blocks, S);
    let crater = sheet_drop(&b, &lat, &e, lat.n[2] - 1);
    eprintln!(
        "crater under the surface markers {crater:.5} m³; vented {:.5} m³ ({:+.1}%)",
        imz.vented,
        100.0 * (crater / imz.vented - 1.0)
    );
    assert!((crater / imz.vented - 1.0).abs() <= 0.05);
}

/// The same draw under ground that never caves above 0.5 m: the IMZ is held there, its
/// void is an air gap, and the gap opens above the IMZ's markers: the sheet of markers
/// that started just under the cap sank by the air held (tolerance as for the crater).
#[test]
fn under_uncaved_ground_the_air_gap_opens_above_the_markers() {
    let (b, scene) = capped_box(1.0, Some(0.5));
    let sc = scenario(2.0 * S, S, 0.0002);
    let e = draw_all(&scene, &sc);
    let imz = &e.imzs[0];
    assert!(imz.blocked && imz.air > 0.0 && imz.vented == 0.0);
    assert_no_void_lost(&b, &e);
    // The last lattice layer whose centre lies under the cap.
    let lat = Lattice::new(&scene.blocks, S);
    let layer = (0..lat.n[2])
        .rev()
        .find(|&k| lat.pos(lat.id(0, 0, k))[2] < 0.5)
        .unwrap();
    let sheet_drawn = (0..e.drawn.m.len())
        .filter(|&k| e.drawn.m.id[k] as usize / (lat.n[0] * lat.n[1]) == layer)
        .count();
    assert_eq!(sheet_drawn, 0, "the sheet under the cap was drawn");
    let gap = sheet_drop(&b, &lat, &e, layer);
    eprintln!(
        "sheet under the cap sank by {gap:.5} m³; air held {:.5} m³ ({:+.1}%)",
        imz.air,
        100.0 * (gap / imz.air - 1.0)
    );
    assert!((gap / imz.air - 1.0).abs() <= 0.05);
}

/// Two drawpoints 0.5 m apart in Castro material, one drawing twice as much as the other,
/// so the leader's IMZ spreads over ground its neighbour later draws: each drawpoint's
/// marker tonnes stay within 3% of its schedule (the sum within 1%).
#[test]
fn unequal_draw_from_overlapping_imzs_keeps_each_drawpoints_balance() {
    let mut scene = UniformBox {
        extent: [1.4, 1.0, 3.3],
        drawpoints: vec![(-0.25, 0.0, 0.12), (0.25, 0.0, 0.12)],
        periods: 8,
        tonnes: 0.03,
        ..UniformBox::castro_isolated()
    }
    .scene();
    for p in 0..8 {
        scene.schedule.tonnes[2 * p] = 0.04;
        scene.schedule.tonnes[2 * p + 1] = 0.02;
    }
    let out = run(&scene, &scenario(0.025, 0.0125, 0.001));
    let (a, b) = (marker_ratio(&out, 0), marker_ratio(&out, 1));
    eprintln!(
        "unequal draw: marker / scheduled tonnes, leader {a:.4}, follower {b:.4}; sum {:.4}",
        out.balance.marker_tonnes / out.balance.scheduled_tonnes
    );
    assert!((a - 1.0).abs() <= 0.03 && (b - 1.0).abs() <= 0.03);
}

/// The demo's scene with nine drawpoints of its west interior drawn evenly, 2 kt a period
/// each, and the others idle; the nine's indices.
fn evenly_drawn_panel() -> (Scene, Vec<usize>) {
    use caveflow::model::demo::{henderson, DemoScale};
    let mut scene = henderson(DemoScale::Small, 42);
    let panel: Vec<usize> = [
        "D02-01", "D02-02", "D02-03", "D03-01", "D03-02", "D03-03", "D03-04", "D04-02", "D04-03",
    ]
    .iter()
    .map(|n| scene.drawpoints.name.iter().position(|m| m == n).unwrap())
    .collect();
    let nd = scene.schedule.n_drawpoints;
    for (k, t) in scene.schedule.tonnes.iter_mut().enumerate() {
        *t = if panel.contains(&(k % nd)) {
            2000.0
        } else {
            0.0
        };
    }
    (scene, panel)
}

/// Nine drawpoints of the demo's panel (its west interior, 13.6–17.3 m apart, whose IMZs
/// overlap from their lower disks up), drawn evenly, 2 kt a period each for the 24
/// periods (48 kt, short of exhausting their columns): each draws its schedule in markers
/// to 2%. Measured 0.987–1.008 (standard deviation 0.59%). While a marker under two IMZs
/// took each one's transfer at its share, the lenses where the lower disks overlap kept
/// markers the transfers could not carry into either disk below: 6 of the 9 were within
/// 2%, 0.956–1.007 (`markers::MotionField::step`).
#[test]
fn a_panel_drawn_evenly_draws_each_drawpoints_schedule_in_markers() {
    use caveflow::model::demo::{scenario, DemoScale};
    let (scene, panel) = evenly_drawn_panel();
    let out = run(&scene, &scenario(DemoScale::Small, 42));
    let ratios: Vec<f64> = panel.iter().map(|&d| marker_ratio(&out, d)).collect();
    eprintln!("panel drawn evenly: marker / scheduled tonnes {ratios:.4?}");
    assert!(ratios.iter().all(|r| (r - 1.0).abs() <= 0.02), "{ratios:?}");
}

/// The same nine drawpoints drawn evenly with each mechanism that moves or changes the
/// markers on, and with every marker stepping every update: fines migration (fines
/// percolate down through the bed, which the counterflow slows, and out of the IMZs, which
/// refill from above), secondary fragmentation (sizes and the disks' d̄ change as the
/// markers shear) and free-surface rilling (the surface's markers slide into the craters).
/// Each drawpoint still draws its schedule in markers to 3%. Measured: fines 0.988–1.021,
/// fragmentation 0.986–1.009, rilling 0.986–1.007, every marker every update 0.989–1.010;
/// without the counterflow, fines drew 0.944–0.974 (`docs::validation`, "Fines migration").
#[test]
fn a_panel_drawn_evenly_with_each_mechanism_on_draws_its_schedule_in_markers() {
    use caveflow::model::demo::{scenario, DemoScale};
    let (scene, panel) = evenly_drawn_panel();
    for mechanism in [
        "fines",
        "fragmentation",
        "rilling",
        "every marker stepping every update",
    ] {
        let mut sc = scenario(DemoScale::Small, 42);
        let m = &mut sc.mechanisms;
        match mechanism {
            "fines" => m.fines = true,
            "fragmentation" => m.fragmentation = true,
            "rilling" => m.rilling = true,
            _ => sc.resolution.max_marker_move = Some(0.0),
        }
        let out = run(&scene, &sc);
        let ratios: Vec<f64> = panel.iter().map(|&d| marker_ratio(&out, d)).collect();
        eprintln!(
            "panel drawn evenly, with {mechanism}: marker / scheduled tonnes {ratios:.4?}; percolation {:?}",
            out.counterflow
        );
        assert!(
            ratios.iter().all(|r| (r - 1.0).abs() <= 0.03),
            "{mechanism}: {ratios:?}"
        );
    }
}

/// A daily schedule on mine-scale blocks (9 drawpoints 15 m apart on 15 m blocks, 150 t a
/// day each for 300 days, at the automatic resolution): markers of 96 t cross the opening a
/// layer of four at a time, so 1205 of the 2700 drawpoint-days draw none. Every day is
/// credited from its drawpoint's stream (`engine::crediting`): every drawpoint-day has a
/// grade, every day of a flowing drawpoint its 150 t. Under the bounded per-period
/// correction, 1450 of the 2700 drawpoint-days had no grade and 1702 were short. No day is
/// short: each drawpoint's markers weigh 0.970–1.032 of its schedule (1.000 in all). While
/// a marker under two IMZs took each one's transfer at its share, the central drawpoint's
/// markers weighed 0.77 of its schedule (the markers the averaged transfers stranded
/// between the IMZs' lower disks, `markers::MotionField::step`) and it was short 66 days;
/// a short day must still be the central drawpoint's, `exhausted`.
#[test]
fn a_daily_schedule_gives_every_drawpoint_day_its_tonnes_and_a_grade() {
    let dps: Vec<(f64, f64, f64)> = (0..9)
        .map(|k| {
            (
                15.0 * (k % 3) as f64 - 15.0,
                15.0 * (k / 3) as f64 - 15.0,
                4.0,
            )
        })
        .collect();
    let scene = UniformBox {
        extent: [90.0, 90.0, 120.0],
        block: [15.0, 15.0, 15.0],
        n0: 0.30,
        n1: 0.45,
        frag: 0.2,
        drawpoints: dps,
        periods: 300,
        tonnes: 150.0,
        ..UniformBox::castro_isolated()
    }
    .scene();
    let out = run(&scene, &Scenario::default());
    let ex = &out.extraction;
    let rows = ex.drawpoint.len();
    let short: Vec<usize> = (0..rows).filter(|&k| ex.status[k] == "short").collect();
    let no_grade = (0..rows).filter(|&k| ex.grades[0][k].is_nan()).count();
    let no_marker = (0..rows).filter(|&k| ex.markers[k] == 0).count();
    eprintln!(
        "daily scene: {rows} drawpoint-days, {no_marker} drew no marker, {no_grade} have no grade, {} short; marker / scheduled tonnes {:.4}",
        short.len(),
        out.balance.marker_tonnes / out.balance.scheduled_tonnes
    );
    let mut per = [(0usize, 0.0f64, 0.0f64); 9];
    for k in 0..rows {
        let d = ex.drawpoint[k] as usize;
        per[d].0 += (ex.status[k] == "short") as usize;
        per[d].1 += ex.marker_tonnes[k];
        per[d].2 += ex.scheduled_tonnes[k];
    }
    eprintln!(
        "per drawpoint (short days, marker / scheduled): {:?}",
        per.iter()
            .map(|p| (p.0, (p.1 / p.2 * 1000.0).round() / 1000.0))
            .collect::<Vec<_>>()
    );
    assert_eq!(rows, 2700);
    assert!(
        no_marker > 1000,
        "the scene is not discrete enough to test: {no_marker}"
    );
    assert_eq!(no_grade, 0);
    for k in 0..rows {
        if ex.status[k] == "ok" {
            assert_eq!(ex.tonnes[k], 150.0, "row {k}");
        } else {
            assert_eq!(
                (ex.status[k], ex.drawpoint[k], ex.short_reason[k]),
                ("short", 4, "exhausted")
            );
            assert!(ex.tonnes[k] < 150.0);
        }
    }
    assert!(short.len() <= 80, "{} short days", short.len());
    let b = &out.balance;
    assert!((b.credited_tonnes + b.final_shortfall_tonnes - b.scheduled_tonnes).abs() <= 1e-6);
}

/// A marker stands for the ground around its site, not for a share of its block: where the
/// spacing does not divide the blocks (50 mm blocks, 17.5 mm markers: columns of 2 and of 3
/// sites per block along each axis), isolated draw over a block column of either kind draws
/// the scheduled mass. Were a block's mass shared among its sites, the ground of a column of
/// 2 × 2 sites would be (3/2)² = 2.25× as heavy, as markers, as that of one of 3 × 3; the
/// drawpoint over it then drew 1.052× the schedule, and the one over 3 × 3 sites (next to
/// columns of 2) 1.036×.
///
/// Tolerance 0.03: 10 kg a period for ten periods is ~4000 markers of 25 g; the lattice
/// sites a disk engulfs differ from its area by the sites on its rim.
#[test]
fn markers_weigh_the_ground_they_stand_for_whatever_the_block_boundaries() {
    let b = UniformBox::castro_isolated();
    let s = 0.0175;
    let lat = Lattice::new(&b.scene().blocks, s);
    // Sites per block along x in the block whose centre is `x`.
    let sites = |x: f64| {
        lat.range(0, x - 0.5 * b.block[0], x + 0.5 * b.block[0])
            .map_or(0, |(i0, i1)| i1 - i0 + 1)
    };
    // The block nearest the centre of the box with `n` sites along each plan axis.
    let near = |n: usize| {
        (0..24)
            .map(|j| -0.575 + 0.05 * j as f64)
            .filter(|&x| sites(x) == n)
            .min_by(|a, c| a.abs().total_cmp(&c.abs()))
            .unwrap()
    };
    let mut ratio = Vec::new();
    for n in [2, 3] {
        let x = near(n);
        let scene = UniformBox {
            drawpoints: vec![(x, x, 0.12)],
            tonnes: 0.01,
            ..b.clone()
        }
        .scene();
        let out = run(&scene, &scenario(0.025, s, 0.0004));
        let r = out.balance.marker_tonnes / out.balance.scheduled_tonnes;
        eprintln!("drawpoint over a block column of {n} × {n} sites at ({x:.3}, {x:.3}): marker / scheduled tonnes {r:.4}");
        ratio.push(r);
    }
    for r in &ratio {
        assert!((r - 1.0).abs() <= 0.03, "{ratio:?}");
    }
}

/// The demo (`data/`, seed 42) over its whole draw at the automatic resolution: the
/// markers drawn weigh what the schedule asks, without a bias and without a trend. The
/// drawpoints' median of credited over marker tonnes lies within 1 ± 0.03 over the run and
/// over each half of their tonnes (the run's own warning rule). The drawpoints whose
/// columns do not run out (22 of 32: never short, and their lowest disks' fill at the end
/// at least 0.8, a full column's first percentile, `engine::fill`; the southeast corner's
/// are short by design, `model::demo`, and three beside them drain in their last months
/// to fills of 0.61–0.76, credited in full while their markers weigh 0.96–0.97 of their
/// schedule) draw a median of their schedule in markers within 1 ± 0.01 (measured 0.994),
/// each within 3%, and at least 16 within 2% (measured 19: a drawpoint's ratio moves by
/// 0.44%, median standard deviation, with the lattice's phase alone, `docs::resolution`,
/// "Sampling noise", so one near the line may cross it). A marker under several IMZs takes
/// one IMZ's transfer, and a cadence window's step is split at the bases it crosses
/// (`markers::MotionField::step`): averaged transfers stranded markers between the IMZs'
/// lower disks (median 0.988), and windows moved in one piece over-drew in the IMZs'
/// overlaps (median 1.010).
#[test]
fn the_demo_draws_its_schedule_in_markers_over_the_whole_draw() {
    use caveflow::model::demo::{henderson, scenario, DemoScale};
    let scene = henderson(DemoScale::Small, 42);
    let out = run(&scene, &scenario(DemoScale::Small, 42));
    let c = &out.balance.correction;
    let ex = &out.extraction;
    let n = scene.drawpoints.len();
    let (mut marker, mut sched, mut short) = (vec![0.0; n], vec![0.0; n], vec![false; n]);
    // Each drawpoint's last judged fill (the rows are in period order).
    let mut last_fill = vec![f64::NAN; n];
    for k in 0..ex.drawpoint.len() {
        let d = ex.drawpoint[k] as usize;
        marker[d] += ex.marker_tonnes[k];
        sched[d] += ex.scheduled_tonnes[k];
        short[d] |= ex.status[k] == "short";
        if ex.fill[k].is_finite() {
            last_fill[d] = ex.fill[k];
        }
    }
    let ratios: Vec<(String, f64)> = (0..n)
        .filter(|&d| !short[d] && last_fill[d] >= 0.8)
        .map(|d| (scene.drawpoints.name[d].clone(), marker[d] / sched[d]))
        .collect();
    let within = |t: f64| ratios.iter().filter(|r| (r.1 - 1.0).abs() <= t).count();
    eprintln!(
        "demo: credited over marker tonnes, drawpoints' median {:.4} (halves {:.4}, {:.4}); {} columns not run out, {} within 2%, {} within 3% of their schedule in markers",
        c.drawpoint_median,
        c.halves_median[0],
        c.halves_median[1],
        ratios.len(),
        within(0.02),
        within(0.03)
    );
    for m in [c.drawpoint_median, c.halves_median[0], c.halves_median[1]] {
        assert!((m - 1.0).abs() <= 0.03, "{c:?}");
    }
    assert!(!out
        .warnings
        .iter()
        .any(|w| w.rule == WarningRule::MassBalance));
    assert!(ratios.len() >= 20, "{} columns not run out", ratios.len());
    let mut sorted: Vec<f64> = ratios.iter().map(|r| r.1).collect();
    sorted.sort_by(f64::total_cmp);
    let median = 0.5 * (sorted[(sorted.len() - 1) / 2] + sorted[sorted.len() / 2]);
    eprintln!("demo: those drawpoints' median marker / scheduled tonnes {median:.4}");
    assert!((median - 1.0).abs() <= 0.01, "{median}");
    assert_eq!(within(0.03), ratios.len(), "{ratios:?}");
    assert!(within(0.02) >= 16, "{ratios:?}");
}
