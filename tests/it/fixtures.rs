//! Fixtures shared by the test modules: the command under test, the demo's `data/`, the small
//! valid scene of the input tests, a tiny box scene (and a study of it), the breakthrough
//! columns, runs and their comparison, Parquet files, and the check of a reported problem.

use std::collections::BTreeMap;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::Arc;

use arrow::array::{ArrayRef, RecordBatch};
use arrow::compute::concat_batches;
use arrow::datatypes::{Field, Schema};
use caveflow::engine::{Engine, RunOutput};
use caveflow::io::{Problem, Problems};
use caveflow::model::synthetic::UniformBox;
use caveflow::model::{Scenario, Scene};
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use parquet::arrow::ArrowWriter;
use tempfile::TempDir;

// ---------------------------------------------------------------------------------------
// The command and the demo.

/// The `caveflow` binary built for these tests.
pub fn caveflow() -> Command {
    Command::new(env!("CARGO_BIN_EXE_caveflow"))
}

/// Runs `caveflow args…` to completion.
pub fn caveflow_out(args: &[&str]) -> Output {
    caveflow().args(args).output().unwrap()
}

/// Runs `caveflow args…` in `cwd` to completion.
pub fn caveflow_in(args: &[&str], cwd: &Path) -> Output {
    caveflow().args(args).current_dir(cwd).output().unwrap()
}

/// A path in the repository (`schemas`, `tests/data/io`, …).
pub fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// The committed demo, `data/`.
pub fn demo_data() -> PathBuf {
    repo("data")
}

/// A copy of the demo's input tables and scenario file in a temporary folder.
pub fn demo_copy() -> TempDir {
    let data = demo_data();
    let tmp = TempDir::new().unwrap();
    for f in [
        "blocks.parquet",
        "drawpoints.csv",
        "periods.csv",
        "schedule.csv",
        "scenario.toml",
    ] {
        fs::copy(data.join(f), tmp.path().join(f)).unwrap();
    }
    tmp
}

// ---------------------------------------------------------------------------------------
// The small valid scene of the input tests: 8 blocks of 10 m, two drawpoints, two periods.

pub const BLOCKS: &str = "\
x,y,z,block_id,solids_density,porosity,max_porosity,friction_angle,frag_size,lithology,cu
5,5,5,1,2.7,0.3,0.45,38,0.2,ore,1.0
15,5,5,2,2.7,0.3,0.45,38,0.2,ore,1.1
5,15,5,3,2.7,0.3,0.45,38,0.2,ore,1.2
15,15,5,4,2.7,0.3,0.45,38,0.2,ore,1.3
5,5,15,5,2.5,0.35,0.5,36,0.5,waste,0.1
15,5,15,6,2.5,0.35,0.5,36,0.5,waste,0.1
5,15,15,7,2.5,0.35,0.5,36,0.5,waste,0.1
15,15,15,8,2.5,0.35,0.5,36,0.5,waste,0.1
";
pub const DRAWPOINTS_CSV: &str = "name,x,y,z,width\nDP1,5,5,0,4\nDP2,15,15,0,4\n";
pub const PERIODS_CSV: &str = "period,name,days\n1,Jan-09,31\n2,Feb-09,28\n";
pub const SCHEDULE_CSV: &str = "period,drawpoint,tonnes\n1,DP1,100\n1,DP2,100\n2,DP1,50\n";

/// The `[inputs]` section of a scenario file beside the small scene's files.
pub const SMALL_SCENE_INPUTS: &str = "[inputs]\nblocks = \"blocks.csv\"\ndrawpoints = \"drawpoints.csv\"\nperiods = \"periods.csv\"\nschedule = \"schedule.csv\"\n";

/// Writes the small scene's four tables into `dir`.
pub fn write_small_scene(dir: &Path) {
    for (name, text) in [
        ("blocks.csv", BLOCKS),
        ("drawpoints.csv", DRAWPOINTS_CSV),
        ("periods.csv", PERIODS_CSV),
        ("schedule.csv", SCHEDULE_CSV),
    ] {
        fs::write(dir.join(name), text).unwrap();
    }
}

/// Writes the small scene into `dir` and returns a default scenario naming its tables.
pub fn small_scene_in(dir: &Path) -> Scenario {
    write_small_scene(dir);
    let mut sc = Scenario::default();
    sc.inputs.blocks = dir.join("blocks.csv");
    sc.inputs.drawpoints = dir.join("drawpoints.csv");
    sc.inputs.periods = Some(dir.join("periods.csv"));
    sc.inputs.schedule = dir.join("schedule.csv");
    sc
}

/// Finds the problem with this file, row, column and rule, and checks that its Display names
/// all four; says what is wrong otherwise.
pub fn find<'a>(
    ps: &'a Problems,
    file: &str,
    row: Option<usize>,
    column: Option<&str>,
    rule: &str,
) -> Result<&'a Problem, String> {
    let p = ps
        .0
        .iter()
        .find(|p| p.file == file && p.row == row && p.column.as_deref() == column && p.rule == rule)
        .ok_or_else(|| format!("no {rule} problem at {file} {row:?} {column:?} in:\n{ps}"))?;
    let shown = p.to_string();
    let mut named =
        shown.starts_with(&format!("{file}: ")) && shown.contains(&format!("[{rule}] "));
    named &= match row {
        Some(0) => shown.contains("header"),
        Some(r) => shown.contains(&format!("row {r}")),
        None => !shown.contains(": row "),
    };
    if let Some(c) = column {
        named &= shown.contains(&format!("column {c}"));
    }
    if named {
        Ok(p)
    } else {
        Err(format!(
            "the problem does not name its place and rule: {shown}"
        ))
    }
}

/// Asserts that some problem has this file, row, column and rule, and that its Display
/// names all four. Returns it for further checks on the message.
pub fn expect<'a>(
    ps: &'a Problems,
    file: &str,
    row: Option<usize>,
    column: Option<&str>,
    rule: &str,
) -> &'a Problem {
    find(ps, file, row, column, rule).unwrap_or_else(|e| panic!("{e}"))
}

// ---------------------------------------------------------------------------------------
// Scenes and runs.

/// Two drawpoints drawing 6 kg from a 0.6 × 0.6 × 0.9 m box of Castro gravel in each of 3
/// periods (grade `elev`: the block's elevation; lithology `uniform`).
pub fn tiny() -> Scene {
    UniformBox {
        extent: [0.6, 0.6, 0.9],
        block: [0.05, 0.05, 0.05],
        drawpoints: vec![(-0.15, 0.0, 0.12), (0.15, 0.0, 0.12)],
        periods: 3,
        tonnes: 0.006,
        ..UniformBox::castro_isolated()
    }
    .scene()
}

/// Makes the ground of `scene` above elevation `z` never cave (cave period 1000).
pub fn never_cave_above(scene: &mut Scene, z: f64) {
    let bm = &mut scene.blocks;
    for k in 0..bm.len() {
        if bm.z[k] > z {
            bm.cave_period[k] = 1000;
        }
    }
}

/// Uniform Castro box of height `height`, `width` square, an isolated 120 mm drawpoint at
/// the centre drawing `tonnes` in each of `periods`: the columns the surface-cone and VTK
/// tests draw through breakthrough.
pub fn cone_column(width: f64, height: f64, periods: usize, tonnes: f64) -> Scene {
    UniformBox {
        extent: [width, width, height],
        drawpoints: vec![(0.0, 0.0, 0.12)],
        periods,
        tonnes,
        ..UniformBox::castro_isolated()
    }
    .scene()
}

/// The scenario of a [`cone_column`]: marker spacing `s`, disks 2 s thick, draw increment
/// `inc`, rilling on, the IMZ and the free surface at every period and the markers at the
/// last.
pub fn cone_scenario(periods: usize, s: f64, inc: f64) -> Scenario {
    let mut sc = scenario(2.0 * s, s, inc);
    sc.mechanisms.rilling = true;
    sc.outputs.imz_every_period = true;
    sc.outputs.surface_periods = (1..=periods as i64).collect();
    sc.outputs.marker_periods = vec![periods as i64];
    sc
}

/// The tiny scene's tables and scenario (charts off) in `dir`, plus `schedule_alt.csv`: the
/// same schedule at two thirds of the tonnes. What the study tests vary.
pub fn study_scene_files(dir: &Path) {
    let mut sc = Scenario::default();
    sc.outputs.charts = false;
    caveflow::output::inputs::write_scene(dir, &tiny(), &sc).unwrap();
    let mut alt = tiny();
    alt.schedule.tonnes.iter_mut().for_each(|t| *t *= 2.0 / 3.0);
    let other = dir.join("alt");
    caveflow::output::inputs::write_scene(&other, &alt, &sc).unwrap();
    fs::copy(other.join("schedule.csv"), dir.join("schedule_alt.csv")).unwrap();
}

/// A study of 4 variants of the tiny scene: two fragment factors × two schedules.
pub const STUDY_GRID_ALT: &str = r#"[grid]
"calibration.frag_factor.uniform" = [0.8, 1.0]
[alternatives.schedule]
base = {}
alt = { schedule = "schedule_alt.csv" }
"#;

/// Every file under `dir/dataset`, relative path → bytes.
pub fn dataset_files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    fn walk(root: &Path, d: &Path, out: &mut BTreeMap<String, Vec<u8>>) {
        for e in fs::read_dir(d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(root, &p, out);
            } else {
                let rel = p.strip_prefix(root).unwrap().display().to_string();
                out.insert(rel, fs::read(&p).unwrap());
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(&dir.join("dataset"), &dir.join("dataset"), &mut out);
    out
}

/// Asserts that two study outputs hold the same dataset byte for byte (every
/// `part-*.parquet` and `_SUCCESS`) and the same summary rows but for the run time.
/// Returns the number of Parquet files.
pub fn assert_same_study(a: &Path, b: &Path) -> usize {
    let (fa, fb) = (dataset_files(a), dataset_files(b));
    assert_eq!(
        fa.keys().collect::<Vec<_>>(),
        fb.keys().collect::<Vec<_>>(),
        "the same files"
    );
    let mut parquet = 0;
    for (k, x) in &fa {
        assert!(x == &fb[k], "{k} differs");
        parquet += usize::from(k.ends_with(".parquet"));
    }
    let (sa, sb) = (
        read_parquet(&a.join("summary.parquet")),
        read_parquet(&b.join("summary.parquet")),
    );
    assert_eq!(sa.schema(), sb.schema());
    assert_eq!(sa.num_rows(), sb.num_rows());
    for (i, f) in sa.schema().fields().iter().enumerate() {
        if f.name() != "wall_s" {
            assert_eq!(
                sa.column(i).to_data(),
                sb.column(i).to_data(),
                "summary column {}",
                f.name()
            );
        }
    }
    parquet
}

/// Writes `study.toml` (study `t` of `scenario.toml`) with `body` after the scenario line
/// into `dir`; returns its path.
pub fn study_file(dir: &Path, body: &str) -> PathBuf {
    let p = dir.join("study.toml");
    fs::write(
        &p,
        format!("name = \"t\"\nscenario = \"scenario.toml\"\n{body}"),
    )
    .unwrap();
    p
}

/// The tiny scene's files and a study of it with `body` ([`study_file`]) in a temporary
/// folder; the folder, and the study file's path.
pub fn tiny_study(body: &str) -> (TempDir, PathBuf) {
    let tmp = TempDir::new().unwrap();
    study_scene_files(tmp.path());
    let path = study_file(tmp.path(), body);
    (tmp, path)
}

/// Runs `scene` under `sc` to the end.
pub fn run(scene: &Scene, sc: &Scenario) -> RunOutput {
    Engine::new(scene, sc).unwrap().run(&mut |_, _| {})
}

/// Marker tonnes over scheduled tonnes of drawpoint `d` over the whole run (its extraction
/// rows).
pub fn marker_ratio(out: &RunOutput, d: usize) -> f64 {
    let ex = &out.extraction;
    let (m, s) = (0..ex.drawpoint.len())
        .filter(|&k| ex.drawpoint[k] as usize == d)
        .fold((0.0, 0.0), |a, k| {
            (a.0 + ex.marker_tonnes[k], a.1 + ex.scheduled_tonnes[k])
        });
    m / s
}

/// A scenario at an explicit resolution: disk thickness `h`, marker spacing `s`, draw
/// increment `inc` (t per drawpoint per step).
pub fn scenario(h: f64, s: f64, inc: f64) -> Scenario {
    let mut sc = Scenario::default();
    sc.resolution.layer_thickness = Some(h);
    sc.resolution.marker_spacing = Some(s);
    sc.resolution.draw_increment = Some(inc);
    sc
}

/// The bit patterns of `v`, to compare floats exactly.
pub fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// Every byte of a run's output, f64 bit for bit: bincode of the whole `RunOutput` with
/// its drawn table and end snapshot made whole (`RunOutput::with_tables`).
pub fn encoded(o: &RunOutput) -> Vec<u8> {
    bincode::serde::encode_to_vec(o.clone().with_tables(), bincode::config::standard()).unwrap()
}

/// Compares two runs field by field, f64 bitwise (the drawn table and the snapshots made
/// whole, `RunOutput::with_tables`).
pub fn assert_identical(a: &RunOutput, b: &RunOutput, what: &str) {
    let (a, b) = (&a.clone().with_tables(), &b.clone().with_tables());
    macro_rules! same {
        ($t:ident . $f:ident) => {
            assert_eq!(
                a.$t.$f,
                b.$t.$f,
                "{what}: {}.{} differ",
                stringify!($t),
                stringify!($f)
            );
        };
        (f $t:ident . $f:ident) => {
            assert_eq!(
                bits(&a.$t.$f),
                bits(&b.$t.$f),
                "{what}: {}.{} differ",
                stringify!($t),
                stringify!($f)
            );
        };
    }
    same!(extraction.drawpoint);
    same!(extraction.period);
    same!(f extraction.scheduled_tonnes);
    same!(f extraction.marker_tonnes);
    same!(f extraction.correction);
    same!(f extraction.tonnes);
    same!(f extraction.shortfall_tonnes);
    same!(f extraction.cum_tonnes);
    same!(extraction.markers);
    same!(f extraction.dilution);
    same!(f extraction.origin_z);
    same!(f extraction.hod);
    same!(f extraction.frag_size);
    same!(f extraction.fines_share);
    same!(f extraction.air_gap);
    same!(extraction.status);
    let g = |o: &RunOutput| {
        o.extraction
            .grades
            .iter()
            .chain(&o.extraction.lithology)
            .map(|c| bits(c))
            .collect::<Vec<_>>()
    };
    assert_eq!(g(a), g(b), "{what}: grades/lithology differ");
    same!(imz.drawpoint);
    same!(imz.period);
    same!(imz.disk);
    same!(f imz.z_base);
    same!(f imz.z_top);
    same!(f imz.radius);
    same!(drawn.marker_id);
    same!(drawn.drawpoint);
    same!(drawn.period);
    same!(f drawn.origin_x);
    same!(f drawn.origin_y);
    same!(f drawn.origin_z);
    same!(f drawn.mass);
    same!(drawn.block_id);
    same!(f drawn.frag_size);
    assert_eq!(a.snapshots.len(), b.snapshots.len());
    for (s, t) in a.snapshots.iter().zip(&b.snapshots) {
        assert_eq!(s.period, t.period);
        assert_eq!(s.marker_id, t.marker_id, "{what}: snapshot ids differ");
        for (u, v, f) in [
            (&s.x, &t.x, "x"),
            (&s.y, &t.y, "y"),
            (&s.z, &t.z, "z"),
            (&s.origin_x, &t.origin_x, "origin_x"),
            (&s.origin_y, &t.origin_y, "origin_y"),
            (&s.origin_z, &t.origin_z, "origin_z"),
            (&s.porosity, &t.porosity, "porosity"),
            (&s.mass, &t.mass, "mass"),
            (&s.frag_size, &t.frag_size, "frag_size"),
            (&s.shear_strain, &t.shear_strain, "shear_strain"),
            (&s.shear_work, &t.shear_work, "shear_work"),
        ] {
            assert_eq!(
                bits(u),
                bits(v),
                "{what}: snapshot {} {f} differs",
                s.period
            );
        }
        assert_eq!(s.block_id, t.block_id);
        assert_eq!(s.state, t.state);
        assert_eq!(s.drawpoint, t.drawpoint);
        assert_eq!(s.drawn_period, t.drawn_period);
    }
    assert_eq!(a.warnings, b.warnings, "{what}: warnings differ");
    assert_eq!(a.resolution, b.resolution);
    let mb = |o: &RunOutput| serde_json::to_string(&o.balance).unwrap();
    assert_eq!(mb(a), mb(b), "{what}: mass balance differs");
}

// ---------------------------------------------------------------------------------------
// Files.

/// A whole Parquet file as one batch, with the file's own Arrow schema (table-level metadata
/// included).
pub fn read_parquet(path: &Path) -> RecordBatch {
    let file = fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let builder = ParquetRecordBatchReaderBuilder::try_new(file).unwrap();
    let schema = builder.schema().clone();
    let batches: Vec<RecordBatch> = builder.build().unwrap().map(Result::unwrap).collect();
    concat_batches(&schema, &batches).unwrap()
}

/// Writes named columns as a Parquet file, every field nullable.
pub fn write_parquet(path: &Path, cols: Vec<(&str, ArrayRef)>) {
    let fields: Vec<Field> = cols
        .iter()
        .map(|(n, a)| Field::new(*n, a.data_type().clone(), true))
        .collect();
    let batch = RecordBatch::try_new(
        Arc::new(Schema::new(fields)),
        cols.into_iter().map(|c| c.1).collect(),
    )
    .unwrap();
    let mut w =
        ArrowWriter::try_new(fs::File::create(path).unwrap(), batch.schema(), None).unwrap();
    w.write(&batch).unwrap();
    w.close().unwrap();
}

/// Names of the entries of a directory, sorted.
pub fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

// ---------------------------------------------------------------------------------------
// Report pages in headless Chromium.

/// Renders the report `page` in headless Chromium (`tests/data/report/render.py`, driven
/// by Playwright from `CAVEFLOW_PY`) and asserts what an engineer's browser must show: the
/// title `title`, no console error or warning, no uncaught error, no request beyond the
/// file itself and its `data:` images, and a screenshot that is not blank (over 5% of the
/// pixels not white, over 200 colours). Returns the screenshot's size, or `None` after a
/// note when Python with Playwright or Chromium is not here (`.ci/run` provides both).
pub fn assert_renders(page: &Path, title: &str) -> Option<(u32, u32)> {
    let Some(python) = std::env::var_os("CAVEFLOW_PY") else {
        eprintln!(
            "note: {} not rendered: CAVEFLOW_PY is not set (`.ci/run` sets it)",
            page.display()
        );
        return None;
    };
    let chromium = std::env::var("CAVEFLOW_CHROMIUM").unwrap_or("/usr/bin/chromium".into());
    if !Path::new(&chromium).exists() {
        eprintln!(
            "note: {} not rendered: no Chromium at {chromium}",
            page.display()
        );
        return None;
    }
    let shot = page.with_extension("png");
    let out = Command::new(python)
        .arg(repo("tests/data/report/render.py"))
        .arg(page)
        .arg(&shot)
        .arg(&chromium)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "render.py failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let log: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let console: Vec<&serde_json::Value> = log["console"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|m| m[0] == "error" || m[0] == "warning")
        .collect();
    assert!(console.is_empty(), "console: {console:?}");
    assert_eq!(log["errors"].as_array().unwrap().len(), 0, "{log}");
    let url = format!("file://{}", page.canonicalize().unwrap().display());
    for r in log["requests"].as_array().unwrap() {
        let r = r.as_str().unwrap();
        assert!(r == url || r.starts_with("data:"), "the page requested {r}");
    }
    assert_eq!(log["title"], title);
    let (w, h, non_white, colours) = screenshot_stats(&shot);
    assert!(
        non_white > 0.05,
        "{:.1}% of the pixels are not white",
        100.0 * non_white
    );
    assert!(colours > 200, "{colours} colours");
    Some((w, h))
}

/// (width, height, share of pixels that are not white, distinct colours) of a PNG.
fn screenshot_stats(path: &Path) -> (u32, u32, f64, usize) {
    let decoder = png::Decoder::new(fs::File::open(path).unwrap());
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    let px = info.color_type.samples();
    let bytes = &buf[..info.buffer_size()];
    let mut colours = std::collections::HashSet::new();
    let mut non_white = 0usize;
    for p in bytes.chunks_exact(px) {
        let rgb = (p[0], p[1], p[2]);
        non_white += usize::from(rgb != (255, 255, 255));
        colours.insert(rgb);
    }
    let n = (bytes.len() / px).max(1);
    (
        info.width,
        info.height,
        non_white as f64 / n as f64,
        colours.len(),
    )
}
