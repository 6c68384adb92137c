//! Engine throughput (DESIGN §9), measured with criterion, never asserted on:
//!
//! - `isolated_draw_60kg`: the summary's Simulation 2 (isolated draw, Castro scale) at two
//!   disk thicknesses, so the cost per mobilised marker can be compared across resolutions;
//! - `marker_pass`: one marker update over the markers mobilised by a Castro isolated draw,
//!   at three marker spacings (each ×8 markers) and on 1 and 2 threads, as the engine runs it
//!   (`markers::move_rows` over the active rows, here every row). The throughput is reported in markers (criterion's "elements"), so
//!   marker-updates per second read straight off the report;
//! - `demo_small_6_periods`: the first 6 monthly periods of the small demo panel, end to end
//!   (32 drawpoints, 0.4 Mt drawn);
//! - `mine_200_days`: the first 200 daily periods of the mine-scale scene (416 drawpoints),
//!   with the multi-rate cadence (the default) and with every marker stepping every update
//!   (`max_marker_move = 0`), so the cadence's gain reads as a ratio.

use caveflow::engine::markers::move_rows;
use caveflow::engine::Engine;
use caveflow::model::demo::{self, DemoScale};
use caveflow::model::synthetic::UniformBox;
use caveflow::model::Scenario;
use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};

fn isolated_draw(c: &mut Criterion) {
    let mut b = UniformBox::castro_isolated();
    b.periods = 3;
    let scene = b.scene();
    let mut g = c.benchmark_group("isolated_draw_60kg");
    g.sample_size(10);
    for h in [0.05, 0.025] {
        let mut sc = Scenario::default();
        sc.resolution.layer_thickness = Some(h);
        g.bench_function(format!("h={h}"), |bench| {
            bench.iter(|| Engine::new(&scene, &sc).unwrap().run(&mut |_, _| {}))
        });
    }
    g.finish();
}

fn marker_pass(c: &mut Criterion) {
    let mut b = UniformBox::castro_isolated();
    b.periods = 3;
    let scene = b.scene();
    let mut g = c.benchmark_group("marker_pass");
    g.sample_size(20);
    for spacing in [0.025, 0.0125, 0.00625] {
        let mut sc = Scenario::default();
        sc.resolution.marker_spacing = Some(spacing);
        // Draw 3 periods; the IMZ keeps the motion of its last interval.
        let mut e = Engine::new(&scene, &sc).unwrap();
        for p in 0..scene.periods.len() {
            e.run_period(p);
        }
        let n = e.markers.len();
        let rows: Vec<u32> = (0..n as u32).collect();
        g.throughput(Throughput::Elements(n as u64));
        e.with_last_field(|field| {
            for threads in [1, 2] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                g.bench_function(format!("{n}_markers/{threads}_threads"), |bench| {
                    bench.iter_batched_ref(
                        || e.markers.clone(),
                        |mk| {
                            pool.install(|| {
                                move_rows(mk, std::slice::from_ref(field), None, &rows, None)
                            })
                        },
                        BatchSize::LargeInput,
                    )
                });
            }
        });
    }
    g.finish();
}

fn demo_run(c: &mut Criterion) {
    let mut scene = demo::henderson(DemoScale::Small, 42);
    scene.keep_periods(6);
    let sc = demo::scenario(DemoScale::Small, 42);
    let mut g = c.benchmark_group("demo_small_6_periods");
    g.sample_size(10);
    g.bench_function("run", |bench| {
        bench.iter(|| Engine::new(&scene, &sc).unwrap().run(&mut |_, _| {}))
    });
    g.finish();
}

fn mine_run(c: &mut Criterion) {
    let mut scene = demo::henderson(DemoScale::Mine, 42);
    scene.keep_periods(200);
    let mut g = c.benchmark_group("mine_200_days");
    g.sample_size(10);
    for (name, max_move) in [("cadence", None), ("every_update", Some(0.0))] {
        let mut sc = demo::scenario(DemoScale::Mine, 42);
        sc.resolution.max_marker_move = max_move;
        g.bench_function(name, |bench| {
            bench.iter(|| Engine::new(&scene, &sc).unwrap().run(&mut |_, _| {}))
        });
    }
    g.finish();
}

criterion_group!(benches, isolated_draw, marker_pass, demo_run, mine_run);
criterion_main!(benches);
