//! Integration tests: why a short period could not deliver, read from the state of its
//! drawpoint's lowest disks (`engine::fill`): a drawpoint is short only where its column is
//! running out (its fill is low), `exhausted` or `blocked`; where the material is there and
//! only its markers ran behind, it is credited its schedule, and a steady lag is a
//! warning. Each test prints the rows it judged
//! (`cargo test ... short_reasons:: -- --nocapture`).

use caveflow::engine::fill::EXHAUSTED_FILL;
use caveflow::engine::{RunOutput, WarningRule};
use caveflow::model::synthetic::UniformBox;
use caveflow::model::Scene;

use crate::fixtures::{never_cave_above, run, scenario};

/// Resolution of the drawn-out columns: h = 25 mm, s = 12.5 mm, 0.2 kg increments.
const S: f64 = 0.0125;

/// An isolated 120 mm drawpoint in Castro material in a 0.6 m × 0.6 m × 0.6 m box, 4 kg a
/// period for 40 periods: 160 kg, while its IMZ, wider than the box at its top, holds
/// about 100 kg. With `cap`, the ground above that height never caves.
fn short_column(cap: Option<f64>) -> Scene {
    let b = UniformBox {
        extent: [0.6, 0.6, 0.6],
        periods: 40,
        tonnes: 0.004,
        ..UniformBox::castro_isolated()
    };
    let mut scene = b.scene();
    if let Some(z) = cap {
        never_cave_above(&mut scene, z);
    }
    scene
}

/// The short rows of drawpoint 0: (period, marker tonnes, reason, fill, air gap).
fn short_rows(out: &RunOutput) -> Vec<(i64, f64, &'static str, f64, f64)> {
    let ex = &out.extraction;
    let rows: Vec<_> = (0..ex.drawpoint.len())
        .filter(|&k| ex.status[k] == "short")
        .map(|k| {
            (
                ex.period[k],
                ex.marker_tonnes[k],
                ex.short_reason[k],
                ex.fill[k],
                ex.air_gap[k],
            )
        })
        .collect();
    for w in &out.warnings {
        eprintln!("warning: {}", w.message);
    }
    for r in &rows {
        eprintln!(
            "period {}: drew {:.2} kg, {} (fill {:.3}, air gap {:.4} m³)",
            r.0,
            1000.0 * r.1,
            r.2,
            r.3,
            r.4
        );
    }
    rows
}

/// Every short row's column is running out: its fill is below [`EXHAUSTED_FILL`].
fn assert_running_out(rows: &[(i64, f64, &str, f64, f64)]) {
    for r in rows {
        assert!(
            r.3 < EXHAUSTED_FILL,
            "period {}: {} at fill {}",
            r.0,
            r.2,
            r.3
        );
    }
}

/// A drawpoint that draws its column out to the free surface (rilling off: the ground
/// around the crater stands). From the 11th period its markers fall behind; while its
/// lowest disks (here those that hold one period's schedule) still hold at least
/// [`EXHAUSTED_FILL`] of their volume it is credited its schedule, and once they hold less
/// it is credited by its markers and is short, `exhausted`: 25 of the last 28 periods, at
/// fills of 0.43–0.69 (the last 18 at a mean of 0.51), drawing 0.1–0.6 of the schedule.
/// Its first short periods drew 0.45–0.77 of it in markers at fills of 0.73–0.97 (the
/// column drains from the top, so its lowest disks empty last) and were credited in
/// full: the run warns that its markers ran behind its credits (0.86 of them over the
/// periods credited by the state).
#[test]
fn a_column_drawn_out_to_the_free_surface_is_exhausted_at_a_low_fill() {
    let scene = short_column(None);
    let out = run(&scene, &scenario(2.0 * S, S, 0.0002));
    let rows = short_rows(&out);
    assert_running_out(&rows);
    assert!(rows.iter().all(|r| r.4 == 0.0 && r.2 == "exhausted"));
    let last: Vec<_> = rows.iter().filter(|r| r.0 > 22).collect();
    assert_eq!(
        last.len(),
        18,
        "the column's last periods are not all short"
    );
    let mean = last.iter().map(|r| r.3).sum::<f64>() / last.len() as f64;
    assert!(mean < 0.55, "mean fill {mean}");
    let lag = out
        .warnings
        .iter()
        .find(|w| w.rule == WarningRule::Lagging)
        .expect("no warning of lagging");
    assert!(lag.message.contains("weigh 0.8"), "{}", lag.message);
}

/// The same draw under ground that never caves above 0.3 m: the void is held as an air gap
/// above the IMZ, and the column drains into it. From the 3rd period on, every period is
/// short and `blocked`, at fills falling from 0.69 to 0.15.
#[test]
fn a_column_under_uncaved_ground_drains_into_the_air_gap_blocked() {
    let scene = short_column(Some(0.3));
    let out = run(&scene, &scenario(2.0 * S, S, 0.0002));
    let rows = short_rows(&out);
    assert_running_out(&rows);
    assert_eq!(rows.len(), 38, "periods 3 to 40 are not all short");
    for r in &rows {
        assert_eq!(r.2, "blocked", "period {}", r.0);
        assert!(r.4 > 0.0, "period {}: {r:?}", r.0);
    }
    assert!(rows.last().unwrap().3 < 0.25);
}

/// A drawpoint that draws a small part of a tall column (Castro's 3.3 m, 4 kg a period for
/// 60 periods) at markers of 50 mm over its 120 mm opening: a period's schedule is about
/// 20 markers, and on a few periods too few of them cross the opening (six periods that
/// the markers alone would credit short: `crediting`'s trailing window). Its column is
/// full (fills of 1.08–1.39 on those periods: the markers that did not come are still in
/// the lowest disks), so every period is credited its schedule, none is short, and its
/// markers follow its credits to within their discreteness: no warning of lagging.
#[test]
fn a_full_column_whose_markers_lag_by_their_discreteness_is_credited_in_full() {
    let b = UniformBox {
        periods: 60,
        tonnes: 0.004,
        ..UniformBox::castro_isolated()
    };
    let out = run(&b.scene(), &scenario(0.025, 0.05, 0.0004));
    assert!(short_rows(&out).is_empty());
    let ex = &out.extraction;
    let lagged = (0..ex.drawpoint.len())
        .filter(|&k| ex.marker_tonnes[k] < 0.5 * ex.scheduled_tonnes[k])
        .count();
    eprintln!("{lagged} periods drew under half their schedule in markers");
    assert!(lagged >= 3, "too few lagging periods to test: {lagged}");
    assert_eq!(out.balance.credited_tonnes, out.balance.scheduled_tonnes);
    assert!(out.warnings.iter().all(|w| w.rule != WarningRule::Lagging));
}
