//! Engine throughput: the summary's Simulation 2 (isolated draw, Castro scale) at two
//! marker spacings, so the cost per mobilised marker can be compared across resolutions.

use caveflow::engine::Engine;
use caveflow::model::synthetic::UniformBox;
use caveflow::model::Scenario;
use criterion::{criterion_group, criterion_main, Criterion};

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

criterion_group!(benches, isolated_draw);
criterion_main!(benches);
