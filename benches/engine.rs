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
//! - `mine_mid_run`: 60 daily periods (1500 to 1559) of the mine-scale scene (416
//!   drawpoints) from the state at day 1500, where the caves are tall and most markers are
//!   moving: the expensive phase of the run, which the first days do not show. The state
//!   is made once (15–20 s of draw) and kept as a checkpoint under the target directory
//!   (`bench-cache/`), made again when absent or when the engine refuses it (another
//!   checkpoint format or another scene); each iteration resumes from it outside the
//!   timing. Once per bench run the engine's account of those 60 days
//!   (`engine::account`, time per phase and work counters) is printed to stderr.
//!
//! `cargo bench --bench engine -- mine_mid_run` runs the last alone.

use std::path::{Path, PathBuf};
use std::time::Duration;

use caveflow::engine::markers::move_rows;
use caveflow::engine::Engine;
use caveflow::model::demo::{self, DemoScale};
use caveflow::model::synthetic::UniformBox;
use caveflow::model::{Scenario, Scene};
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

/// Period index of the mid-run state `mine_mid_run` starts from, and how many periods it
/// draws from there.
const MID_RUN: usize = 1500;
const MID_RUN_DAYS: usize = 60;

/// The checkpoint tag of the mine scene: a hash of the scenario and of the scene's
/// defining columns, so a cached state made from another scene is refused.
fn scene_tag(scene: &Scene, sc: &Scenario) -> String {
    let mut text = serde_json::to_string(sc).expect("scenario as JSON");
    let bm = &scene.blocks;
    text.push_str(&format!(
        "{:?} {:?} {:?} {} {}",
        bm.dims,
        bm.origin,
        bm.size,
        scene.drawpoints.len(),
        scene.periods.len()
    ));
    let mut bytes = text.into_bytes();
    for col in [
        &bm.density,
        &bm.n0,
        &bm.n1,
        &bm.frag,
        &scene.schedule.tonnes,
    ]
    .into_iter()
    .chain(&bm.grades)
    {
        bytes.extend(col.iter().flat_map(|x| x.to_le_bytes()));
    }
    bytes.extend(bm.cave_period.iter().flat_map(|x| x.to_le_bytes()));
    caveflow::io::sha256_hex(&bytes)
}

/// Where the cached mid-run state lives: `<target>/bench-cache/`, the target directory
/// being `CARGO_TARGET_DIR` or the one this bench was built into (`<target>/release/deps/`).
fn cache_dir() -> PathBuf {
    if let Some(dir) = std::env::var_os("CARGO_TARGET_DIR") {
        return PathBuf::from(dir).join("bench-cache");
    }
    let exe = std::env::current_exe().expect("the bench's own path");
    exe.ancestors()
        .nth(3)
        .map_or_else(|| PathBuf::from("target"), Path::to_path_buf)
        .join("bench-cache")
}

/// The mine scene's state at day [`MID_RUN`] as checkpoint bytes: read from the cache when
/// the engine accepts it, else drawn from day 0 and cached.
fn mid_run_state(scene: &Scene, sc: &Scenario, tag: &str) -> Vec<u8> {
    let dir = cache_dir();
    let path = dir.join(format!("mine-{MID_RUN}-{}.bin", &tag[..12]));
    if let Ok(bytes) = std::fs::read(&path) {
        match Engine::resume(scene, sc, &bytes, tag) {
            Ok((_, next)) if next == MID_RUN => return bytes,
            Ok(_) => eprintln!("{}: another day; made again", path.display()),
            Err(e) => eprintln!("{}: {e}; made again", path.display()),
        }
    }
    eprintln!(
        "mine_mid_run: drawing days 0..{MID_RUN} once (cached in {})",
        path.display()
    );
    let mut e = Engine::new(scene, sc).expect("mine scene");
    for p in 0..MID_RUN {
        e.run_period(p);
    }
    std::fs::create_dir_all(&dir).expect("bench cache directory");
    let bytes = e.checkpoint(MID_RUN, tag);
    caveflow::output::write_atomic(&path, &bytes).expect("cached state written");
    bytes
}

fn mine_mid_run(c: &mut Criterion) {
    let mut g = c.benchmark_group("mine_mid_run");
    g.sample_size(10);
    g.warm_up_time(Duration::from_secs(1));
    g.measurement_time(Duration::from_secs(20));
    // Everything is made inside the routine, so a filter that leaves this bench out costs
    // nothing.
    let mut made: Option<(Scene, Scenario)> = None;
    let mut state: Option<Vec<u8>> = None;
    g.bench_function(format!("{MID_RUN_DAYS}_days"), |bench| {
        let (scene, sc) = made.get_or_insert_with(|| {
            (
                demo::henderson(DemoScale::Mine, 42),
                demo::scenario(DemoScale::Mine, 42),
            )
        });
        let tag = scene_tag(scene, sc);
        let state = state.get_or_insert_with(|| {
            let bytes = mid_run_state(scene, sc, &tag);
            // The account of the same days, once.
            let (e, next) = Engine::resume(scene, sc, &bytes, &tag).expect("mid-run state");
            let mut e = e.keep_account();
            for p in next..next + MID_RUN_DAYS {
                e.run_period(p);
            }
            let account = e.account().expect("an account").report();
            eprintln!(
                "mine_mid_run: days {next}..{} ({} moving markers at the end)\n{account}",
                next + MID_RUN_DAYS,
                e.markers.len()
            );
            bytes
        });
        bench.iter_batched(
            || {
                Engine::resume(scene, sc, state, &tag)
                    .expect("mid-run state")
                    .0
            },
            |mut e| {
                for p in MID_RUN..MID_RUN + MID_RUN_DAYS {
                    e.run_period(p);
                }
                // Dropped outside the timing.
                e
            },
            BatchSize::PerIteration,
        )
    });
    g.finish();
}

criterion_group!(benches, isolated_draw, marker_pass, demo_run, mine_mid_run);
criterion_main!(benches);
