//! Integration tests: the flow engine against conservation laws, closed forms and the
//! summary's published behaviour.

use caveflow::engine::{Engine, RunOutput};
use caveflow::model::synthetic::UniformBox;
use caveflow::model::{Scenario, Scene};

pub fn run(scene: &Scene, sc: &Scenario) -> RunOutput {
    Engine::new(scene, sc).unwrap().run(&mut |_, _| {})
}

/// Max radius and height of the IMZ of drawpoint 0 at the end.
fn imz_profile(out: &RunOutput) -> Vec<(f64, f64)> {
    let last = *out.imz.period.last().unwrap();
    (0..out.imz.radius.len())
        .filter(|&k| out.imz.period[k] == last && out.imz.drawpoint[k] == 0)
        .map(|k| (out.imz.z_top[k], out.imz.radius[k]))
        .collect()
}

#[test]
fn explore_isolated() {
    let mut b = UniformBox::castro_isolated();
    if let Ok(t) = std::env::var("T") { b.tonnes = t.parse().unwrap(); }
    let scene = b.scene();
    let sc = Scenario::default();
    let t = std::time::Instant::now();
    let mut e = Engine::new(&scene, &sc).unwrap();
    eprintln!("res {:?}", e.resolution);
    for p in 0..3 {
        e.run_period(p);
        let r: Vec<String> = e.imzs[0].geom.radius.iter().step_by(5).map(|r| format!("{r:.3}")).collect();
        eprintln!("period {p} t={:?} markers {} drawn {} disks {} air {} R {:?}", t.elapsed(), e.markers.len(), e.drawn.m.len(), e.imzs[0].disks(), e.imzs[0].air, r);
    }
    let out = run(&scene, &sc);
    eprintln!("res {:?} time {:?}", out.resolution, t.elapsed());
    eprintln!("balance {:?}", out.balance);
    for (z, r) in imz_profile(&out).iter().step_by(4) {
        eprintln!("z {z:.3} R {r:.4}");
    }
    let ex = &out.extraction;
    for k in 0..ex.tonnes.len() {
        eprintln!("p{} sched {:.4} marker {:.4} c {:.3} credited {:.4} short {:.4} n {} oz {:.3}", ex.period[k], ex.scheduled_tonnes[k], ex.marker_tonnes[k], ex.correction[k], ex.tonnes[k], ex.shortfall_tonnes[k], ex.markers[k], ex.origin_z[k]);
    }
    eprintln!("warnings {:?}", out.warnings);
}
