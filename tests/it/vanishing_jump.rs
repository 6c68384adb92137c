//! Integration tests: where the porosity jump n1 − n0 vanishes (ground a neighbour already
//! dilated, or ground at its dilated porosity), the IMZs stay finite and the markers weigh
//! the schedule.

use caveflow::engine::RunOutput;
use caveflow::model::synthetic::UniformBox;
use caveflow::model::Scene;

use crate::engine::disks;
use crate::fixtures::{marker_ratio, run, scenario};

// ---------------------------------------------------------------------------------------
// 6. Vanishing porosity jump
// ---------------------------------------------------------------------------------------

/// Everything a run wrote is finite (NaN is allowed only in the per-tonne columns of
/// extraction rows that drew nothing), and no radius exceeds the model's plan diagonal.
fn assert_finite(scene: &Scene, out: &RunOutput) {
    let ex = &out.extraction;
    for k in 0..ex.tonnes.len() {
        for (name, v) in [
            ("tonnes", ex.tonnes[k]),
            ("marker_tonnes", ex.marker_tonnes[k]),
            ("correction", ex.correction[k]),
            ("cum_tonnes", ex.cum_tonnes[k]),
            ("hod", ex.hod[k]),
            ("air_gap", ex.air_gap[k]),
        ] {
            assert!(v.is_finite(), "row {k}: {name} = {v}");
        }
        if ex.markers[k] > 0 {
            for v in [
                ex.origin_z[k],
                ex.frag_size[k],
                ex.dilution[k],
                ex.grades[0][k],
            ] {
                assert!(v.is_finite(), "row {k}: {v}");
            }
        }
    }
    let bm = &scene.blocks;
    let max = bm.max_corner();
    let diag = (max[0] - bm.origin[0]).hypot(max[1] - bm.origin[1]);
    assert!(
        out.imz
            .radius
            .iter()
            .all(|r| r.is_finite() && *r > 0.0 && *r <= diag),
        "radii: {:?}",
        out.imz.radius
    );
    for s in &out.snapshot_tables() {
        for v in [&s.x, &s.y, &s.z, &s.shear_strain, &s.shear_work] {
            assert!(v.iter().all(|x| x.is_finite()));
        }
    }
}

#[test]
fn vanishing_porosity_jump_stays_finite_and_conserves_mass() {
    let sc = scenario(0.05, 0.025, 0.001);
    // Wherever n1 − n0 → 0 the radius update R_i ← sqrt(R_i² + r v_i / (π h (n1 − n0)))
    // would divide by zero; the engine instead widens the disk for free across ground
    // already dilated (`engine::imz`). Two ways to get there:
    // (a) Successive draw beside a dilated IMZ: DP01 draws periods 1–3, then DP02, 0.3 m
    // away, draws periods 4–6 into ground DP01 already dilated (jump n1 − n1 = 0 on the
    // shared side).
    let b = UniformBox {
        extent: [1.2, 0.8, 1.5],
        drawpoints: vec![(-0.15, 0.0, 0.12), (0.15, 0.0, 0.12)],
        periods: 6,
        tonnes: 0.015,
        ..UniformBox::castro_isolated()
    };
    let mut scene = b.scene();
    for p in 0..6 {
        scene.schedule.tonnes[2 * p + usize::from(p < 3)] = 0.0;
    }
    // (b) Ground already at its dilated porosity: n0 = n1 above z = 0.6 m (say, the
    // broken remains of a level above), for one drawpoint.
    let b2 = UniformBox {
        extent: [1.0, 1.0, 1.5],
        periods: 4,
        tonnes: 0.015,
        ..UniformBox::castro_isolated()
    };
    let mut scene2 = b2.scene();
    for k in 0..scene2.blocks.len() {
        if scene2.blocks.z[k] > 0.6 {
            scene2.blocks.n0[k] = scene2.blocks.n1[k];
        }
    }
    for (name, scene) in [
        ("successive draw beside a dilated IMZ", &scene),
        ("n0 = n1 above 0.6 m", &scene2),
    ] {
        let out = run(scene, &sc);
        assert_finite(scene, &out);
        let nd = scene.drawpoints.len();
        let last = *scene.periods.id.last().unwrap();
        for (d, &(sched, credited)) in out.balance.per_drawpoint.iter().enumerate() {
            let rmax = disks(&out, d as u32, last)
                .iter()
                .map(|x| x.2)
                .fold(0.0, f64::max);
            let markers = marker_ratio(&out, d);
            eprintln!(
                "{name}: DP{:02} credited/scheduled {:.6}, markers/scheduled {:.4}, max R {rmax:.3} m",
                d + 1,
                credited / sched,
                markers
            );
            // Same 0.5% as the conservation test.
            assert!(
                (credited / sched - 1.0).abs() <= 0.005,
                "{name}: DP{:02}: {credited} of {sched}",
                d + 1
            );
            // The markers drawn weigh the schedule to 3%, the conservation test's tolerance
            // at ~10³ markers a period (measured 1.014, 1.022 and 1.025): ground widened
            // through for free is not drawn twice, nor is the void left empty.
            assert!(
                (markers - 1.0).abs() <= 0.03,
                "{name}: DP{:02}: markers {markers} of the schedule",
                d + 1
            );
        }
        let c = &out.extraction.correction;
        eprintln!(
            "{name}: corrections {:.3}–{:.3}; warnings {:?}",
            c.iter().cloned().fold(9.0, f64::min),
            c.iter().cloned().fold(0.0, f64::max),
            out.warnings
        );
        assert!(out.extraction.drawpoint.iter().all(|&d| (d as usize) < nd));
        let rmax = |d: u32| disks(&out, d, last).iter().map(|x| x.2).fold(0.0, f64::max);
        if nd == 2 {
            // Ground dilated by DP01 offers DP02 a smaller jump (DESIGN §4.3): after the
            // same 45 kg, DP02's IMZ ends wider than DP01's (measured 0.278 against 0.257 m).
            assert!(rmax(1) > rmax(0), "{} vs {}", rmax(1), rmax(0));
        } else {
            // With no jump at all the disks widen for free to the edge of the dilated
            // ground, here the model walls (half-width 0.5 m; measured R 0.709 m, where
            // the last perimeter point leaves the model), and no further.
            assert!(rmax(0) >= 0.5, "{}", rmax(0));
        }
    }
}
