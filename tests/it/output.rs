//! Integration tests: output (atomic writes, run tables, manifest, input tables) and the demo
//! generator.

use std::fs;
use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, UNIX_EPOCH};

use arrow::array::{ArrayRef, AsArray, Float64Array, RecordBatch};
use arrow::datatypes::{DataType, Float64Type, Int64Type, Schema};
use caveflow::engine::result::{
    AirGapTable, CorrectionStats, DrawnTable, Extraction, ImzTable, MarkerSnapshot, MarkerState,
    MassBalance, ResolvedResolution, RunOutput, RunWarning, SurfaceTable, WarningRule,
};
use caveflow::model::demo::{self, DemoScale, BLOCK_HEIGHT, EXTRACTION_LEVEL_Z};
use caveflow::model::{Scenario, Scene};
use caveflow::output::inputs::write_scene;
use caveflow::output::manifest::rfc3339_utc;
use caveflow::output::{write_atomic, write_parquet, write_run, AtomicFile, InputFile, Manifest};
use caveflow::schema::{self, TableSpec};
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;

use crate::fixtures::{entries, read_parquet};

fn f64_col(batch: &RecordBatch, name: &str) -> Vec<f64> {
    batch
        .column_by_name(name)
        .unwrap()
        .as_primitive::<Float64Type>()
        .values()
        .to_vec()
}

fn i64_col(batch: &RecordBatch, name: &str) -> Vec<i64> {
    batch
        .column_by_name(name)
        .unwrap()
        .as_primitive::<Int64Type>()
        .values()
        .to_vec()
}

fn str_col(batch: &RecordBatch, name: &str) -> Vec<String> {
    batch
        .column_by_name(name)
        .unwrap()
        .as_string::<i32>()
        .iter()
        .map(|s| s.unwrap().to_string())
        .collect()
}

/// The file's schema has exactly the expected fields: names, order, types, and each
/// field's `unit` and `description` metadata.
fn assert_schema(batch: &RecordBatch, expected: &Schema) {
    let got = batch.schema();
    let names = |s: &Schema| {
        s.fields()
            .iter()
            .map(|f| f.name().clone())
            .collect::<Vec<_>>()
    };
    assert_eq!(names(&got), names(expected));
    for (g, e) in got.fields().iter().zip(expected.fields()) {
        assert_eq!(g.data_type(), e.data_type(), "{}", e.name());
        assert_eq!(g.metadata(), e.metadata(), "{}", e.name());
        assert!(!g.metadata()["unit"].is_empty() && !g.metadata()["description"].is_empty());
    }
    assert_eq!(
        got.metadata().get("description"),
        expected.metadata().get("description")
    );
}

fn spec_schema(spec: &TableSpec, extra: &[String]) -> Arc<Schema> {
    spec.arrow_schema(&spec.field_names(), extra)
}

// ---------------------------------------------------------------- atomic writes

#[test]
fn write_atomic_replaces_and_leaves_only_the_target() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("a.json");
    write_atomic(&path, b"old").unwrap();
    write_atomic(&path, b"new").unwrap();
    assert_eq!(fs::read(&path).unwrap(), b"new");
    assert_eq!(entries(dir.path()), ["a.json"]);
}

#[test]
fn dropped_writer_leaves_the_old_file_intact() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("extraction.parquet");
    write_atomic(&path, b"old contents").unwrap();

    let mut w = AtomicFile::create(&path).unwrap();
    w.write_all(b"half a new fi").unwrap();
    w.flush().unwrap();
    let tmp = w.tmp_path().to_path_buf();
    assert_eq!(
        tmp.parent(),
        path.parent(),
        "temporary file must sit beside the target"
    );
    assert!(tmp
        .file_name()
        .unwrap()
        .to_string_lossy()
        .starts_with("extraction.parquet.tmp-"));
    assert_eq!(fs::read(&tmp).unwrap(), b"half a new fi");
    assert_eq!(
        fs::read(&path).unwrap(),
        b"old contents",
        "target untouched while writing"
    );
    drop(w); // interrupted: never committed

    assert_eq!(fs::read(&path).unwrap(), b"old contents");
    assert_eq!(
        entries(dir.path()),
        ["extraction.parquet"],
        "temporary file removed"
    );
}

#[test]
fn dropped_writer_of_a_new_file_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("new.parquet");
    let mut w = AtomicFile::create(&path).unwrap();
    w.write_all(b"partial").unwrap();
    drop(w);
    assert!(entries(dir.path()).is_empty());
}

#[test]
fn failed_rename_keeps_the_target_and_cleans_up() {
    let dir = tempfile::tempdir().unwrap();
    // The target is a non-empty directory, so the final rename fails.
    let target = dir.path().join("imz.parquet");
    fs::create_dir(&target).unwrap();
    fs::write(target.join("keep"), b"x").unwrap();

    let schema = spec_schema(&schema::IMZ, &[]);
    let cols: Vec<ArrayRef> = vec![
        Arc::new(arrow::array::StringArray::from(vec!["D1"])),
        Arc::new(arrow::array::Int64Array::from(vec![1])),
        Arc::new(arrow::array::Int64Array::from(vec![0])),
        Arc::new(Float64Array::from(vec![0.0])),
        Arc::new(Float64Array::from(vec![1.0])),
        Arc::new(Float64Array::from(vec![2.0])),
    ];
    let err = write_parquet(&target, schema, cols).unwrap_err();
    assert!(
        err.to_string().contains(&target.display().to_string()),
        "{err}"
    );
    assert!(target.is_dir());
    assert_eq!(fs::read(target.join("keep")).unwrap(), b"x");
    assert_eq!(
        entries(dir.path()),
        ["imz.parquet"],
        "no temporary file left"
    );
}

#[test]
fn errors_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("missing_dir").join("manifest.json");
    let err = write_atomic(&path, b"{}").unwrap_err();
    assert!(err.to_string().contains("missing_dir"), "{err}");

    // Columns that do not fit the schema are refused before anything is written.
    let path = dir.path().join("imz.parquet");
    let err = write_parquet(&path, spec_schema(&schema::IMZ, &[]), vec![]).unwrap_err();
    assert!(err.to_string().contains("imz.parquet"), "{err}");
    assert!(entries(dir.path()).is_empty());
}

// ---------------------------------------------------------------- run tables

/// A small fabricated run over the demo scene: 2 drawpoints × 3 periods.
fn fake_run(scene: &Scene) -> RunOutput {
    let rows = 6;
    let v = |k: f64| {
        (0..rows)
            .map(|i| k * (i as f64 + 1.0) / 3.0)
            .collect::<Vec<f64>>()
    };
    let n_lith = scene.blocks.lithology_names.len();
    let extraction = Extraction {
        drawpoint: vec![0, 1, 0, 1, 0, 1],
        period: vec![1, 1, 2, 2, 3, 3],
        scheduled_tonnes: v(1000.0),
        marker_tonnes: v(990.0),
        correction: v(0.3),
        tonnes: v(1001.0),
        shortfall_tonnes: v(0.1),
        cum_tonnes: v(5000.0),
        markers: (0..rows as i64).map(|i| 100 + i).collect(),
        dilution: v(0.01),
        origin_z: v(2400.0),
        hod: v(10.0),
        frag_size: v(0.2),
        fines_share: v(0.001),
        frag_p20: v(0.05),
        frag_p50: v(0.15),
        frag_p80: v(0.3),
        fines_origin_z: v(2450.0),
        fines_waste_share: v(0.2),
        percolation: v(0.02),
        air_gap: v(0.0),
        rilled_share: v(0.05),
        rill_distance: v(3.0),
        status: vec!["ok", "short", "idle", "ok", "ok", "short"],
        short_reason: vec!["", "blocked", "", "", "", "exhausted"],
        grades: vec![v(0.25)],
        lithology: (0..n_lith).map(|l| v(0.1 * l as f64)).collect(),
    };
    let imz = ImzTable {
        drawpoint: vec![0, 0, 1],
        period: vec![3, 3, 3],
        disk: vec![0, 1, 0],
        z_base: vec![2347.0, 2354.6, 2347.0],
        z_top: vec![2354.6, 2362.2, 2354.6],
        radius: vec![2.0, 2.5, 2.1],
    };
    let drawn = DrawnTable {
        marker_id: vec![7, 9],
        drawpoint: vec![1, 0],
        period: vec![1, 2],
        origin_x: vec![10_001.0, 10_002.5],
        origin_y: vec![5_001.0, 5_003.5],
        origin_z: vec![2350.0, 2351.25],
        mass: vec![12.5, 13.0],
        block_id: vec![1, 2],
        frag_size: vec![0.23, 0.04],
        rill_distance: vec![0.0, 7.6],
    };
    let snapshot = |period: i64| MarkerSnapshot {
        period,
        marker_id: vec![7, 8, 9],
        x: vec![1.0, 2.0, 3.0],
        y: vec![4.0, 5.0, 6.0],
        z: vec![7.0, 8.0, 9.0],
        origin_x: vec![1.5, 2.5, 3.5],
        origin_y: vec![4.5, 5.5, 6.5],
        origin_z: vec![7.5, 8.5, 9.5],
        mass: vec![12.5, 12.5, 13.0],
        block_id: vec![1, 1, 2],
        state: vec![MarkerState::Drawn, MarkerState::Moving, MarkerState::InSitu],
        porosity: vec![0.45, 0.44, 0.30],
        frag_size: vec![0.23, 0.22, 0.04],
        shear_strain: vec![0.5, 0.1, 0.0],
        shear_work: vec![100.0, 10.0, 0.0],
        primary_frag_size: vec![0.25, 0.22, 0.04],
        attrited: vec![0.1, 0.0, 0.0],
        percolated: vec![0.0, 1.5, 0.0],
        drawpoint: vec![1, u32::MAX, u32::MAX],
        drawn_period: vec![1, -1, -1],
    };
    RunOutput {
        extraction,
        imz,
        drawn,
        snapshots: vec![snapshot(2), snapshot(3)],
        air_gap: AirGapTable {
            period: vec![2, 3],
            x: vec![10_003.8, 10_003.8],
            y: vec![5_003.8, 5_003.8],
            air_gap: vec![15.2, 30.4],
        },
        surface: SurfaceTable {
            period: vec![3, 3],
            x: vec![10_000.95, 10_002.85],
            y: vec![5_000.95, 5_000.95],
            z: vec![2_510.0, 2_505.5],
        },
        moment_surface: SurfaceTable::default(),
        warnings: vec![RunWarning {
            rule: WarningRule::Short,
            drawpoint: Some("D01-02".into()),
            amount: 0.5,
            message: "drawpoint D01-02 short in period 1".into(),
        }],
        balance: MassBalance {
            scheduled_tonnes: 21_000.0,
            credited_tonnes: 20_999.5,
            marker_tonnes: 20_800.0,
            final_shortfall_tonnes: 0.5,
            markers_mobilised: 3,
            markers_drawn: 2,
            per_drawpoint: vec![(10_500.0, 10_500.0), (10_500.0, 10_499.5)],
            correction: CorrectionStats {
                rows: 2,
                median: 0.99,
                p10: 0.98,
                p90: 1.0,
                at_lower_bound: 0,
                at_upper_bound: 1,
                drawpoint_median: 1.01,
                halves_median: [1.0, 1.02],
            },
        },
        resolution: ResolvedResolution {
            layer_thickness: 3.8,
            marker_spacing: 1.9,
            draw_increment: 250.0,
            max_marker_move: 0.95,
        },
        stress: Vec::new(),
        trace: Default::default(),
        account: None,
        end: None,
    }
}

fn run_dir() -> (tempfile::TempDir, Scene, RunOutput, Vec<PathBuf>) {
    let tmp = tempfile::tempdir().unwrap();
    let scene = demo::henderson(DemoScale::Small, 7);
    let run = fake_run(&scene);
    let input = tmp.path().join("schedule.csv");
    fs::write(&input, b"abc").unwrap();
    let scenario = demo::scenario(DemoScale::Small, 7);
    let inputs = vec![InputFile::new("schedule", &input, 3).unwrap()];
    let manifest = Manifest::new(
        "caveflow run scenario.toml".into(),
        &scenario,
        inputs,
        &run,
        2,
        1.25,
    );
    let files = write_run(&tmp.path().join("run"), &scene, run.clone(), &manifest).unwrap();
    (tmp, scene, run, files)
}

#[test]
fn run_directory_layout() {
    let (tmp, _, _, files) = run_dir();
    let dir = tmp.path().join("run");
    let expected: Vec<PathBuf> = [
        "extraction.parquet",
        "imz.parquet",
        "drawn.parquet",
        "air_gap.parquet",
        "surface.parquet",
        "markers/period=2/part-0.parquet",
        "markers/period=3/part-0.parquet",
        "manifest.json",
    ]
    .iter()
    .map(|f| dir.join(f))
    .collect();
    assert_eq!(files, expected);
    assert_eq!(
        entries(&dir),
        [
            "air_gap.parquet",
            "drawn.parquet",
            "extraction.parquet",
            "imz.parquet",
            "manifest.json",
            "markers",
            "surface.parquet"
        ]
    );
    assert_eq!(entries(&dir.join("markers")), ["period=2", "period=3"]);
    assert_eq!(entries(&dir.join("markers/period=3")), ["part-0.parquet"]);
}

#[test]
fn extraction_round_trip() {
    let (tmp, scene, run, _) = run_dir();
    let batch = read_parquet(&tmp.path().join("run/extraction.parquet"));
    let t = run.extraction;

    let mut extra = vec!["mo".to_string()];
    extra.extend(
        scene
            .blocks
            .lithology_names
            .iter()
            .map(|l| format!("lith_{l}")),
    );
    assert_eq!(extra.len(), 5, "mo + four lithologies");
    assert_schema(&batch, &spec_schema(&schema::EXTRACTION, &extra));
    let lith_field = batch.schema().field_with_name("lith_urad").unwrap().clone();
    assert_eq!(lith_field.metadata()["unit"], "-");
    assert_eq!(
        batch.schema().field_with_name("mo").unwrap().metadata()["unit"],
        "%"
    );

    let names: Vec<String> = t
        .drawpoint
        .iter()
        .map(|&d| scene.drawpoints.name[d as usize].clone())
        .collect();
    assert_eq!(str_col(&batch, "drawpoint"), names);
    assert_eq!(i64_col(&batch, "period"), t.period);
    assert_eq!(f64_col(&batch, "scheduled_tonnes"), t.scheduled_tonnes);
    assert_eq!(f64_col(&batch, "marker_tonnes"), t.marker_tonnes);
    assert_eq!(f64_col(&batch, "correction"), t.correction);
    assert_eq!(f64_col(&batch, "tonnes"), t.tonnes);
    assert_eq!(f64_col(&batch, "shortfall_tonnes"), t.shortfall_tonnes);
    assert_eq!(f64_col(&batch, "cum_tonnes"), t.cum_tonnes);
    assert_eq!(i64_col(&batch, "markers"), t.markers);
    assert_eq!(f64_col(&batch, "dilution"), t.dilution);
    assert_eq!(f64_col(&batch, "origin_z"), t.origin_z);
    assert_eq!(f64_col(&batch, "hod"), t.hod);
    assert_eq!(f64_col(&batch, "frag_size"), t.frag_size);
    assert_eq!(f64_col(&batch, "fines_share"), t.fines_share);
    assert_eq!(f64_col(&batch, "frag_p20"), t.frag_p20);
    assert_eq!(f64_col(&batch, "frag_p50"), t.frag_p50);
    assert_eq!(f64_col(&batch, "frag_p80"), t.frag_p80);
    assert_eq!(f64_col(&batch, "fines_origin_z"), t.fines_origin_z);
    assert_eq!(f64_col(&batch, "fines_waste_share"), t.fines_waste_share);
    assert_eq!(f64_col(&batch, "percolation"), t.percolation);
    assert_eq!(f64_col(&batch, "air_gap"), t.air_gap);
    assert_eq!(str_col(&batch, "status"), t.status);
    assert_eq!(f64_col(&batch, "mo"), t.grades[0]);
    for (l, name) in scene.blocks.lithology_names.iter().enumerate() {
        assert_eq!(f64_col(&batch, &format!("lith_{name}")), t.lithology[l]);
    }
}

#[test]
fn imz_and_drawn_round_trip() {
    let (tmp, scene, run, _) = run_dir();
    let name = |d: &[u32]| {
        d.iter()
            .map(|&d| scene.drawpoints.name[d as usize].clone())
            .collect::<Vec<_>>()
    };

    let batch = read_parquet(&tmp.path().join("run/imz.parquet"));
    assert_schema(&batch, &spec_schema(&schema::IMZ, &[]));
    let t = run.imz;
    assert_eq!(str_col(&batch, "drawpoint"), name(&t.drawpoint));
    assert_eq!(i64_col(&batch, "period"), t.period);
    assert_eq!(i64_col(&batch, "disk"), t.disk);
    assert_eq!(f64_col(&batch, "z_base"), t.z_base);
    assert_eq!(f64_col(&batch, "z_top"), t.z_top);
    assert_eq!(f64_col(&batch, "radius"), t.radius);

    let batch = read_parquet(&tmp.path().join("run/drawn.parquet"));
    assert_schema(&batch, &spec_schema(&schema::DRAWN, &[]));
    let t = run.drawn;
    assert_eq!(i64_col(&batch, "marker_id"), t.marker_id);
    assert_eq!(str_col(&batch, "drawpoint"), name(&t.drawpoint));
    assert_eq!(i64_col(&batch, "period"), t.period);
    assert_eq!(f64_col(&batch, "origin_x"), t.origin_x);
    assert_eq!(f64_col(&batch, "origin_y"), t.origin_y);
    assert_eq!(f64_col(&batch, "origin_z"), t.origin_z);
    assert_eq!(f64_col(&batch, "mass"), t.mass);
    assert_eq!(i64_col(&batch, "block_id"), t.block_id);
    assert_eq!(f64_col(&batch, "frag_size"), t.frag_size);
}

#[test]
fn marker_partitions_round_trip() {
    let (tmp, scene, run, _) = run_dir();
    for s in &run.snapshots {
        let batch = read_parquet(
            &tmp.path()
                .join(format!("run/markers/period={}/part-0.parquet", s.period)),
        );
        assert_schema(&batch, &spec_schema(&schema::MARKERS, &[]));
        assert_eq!(i64_col(&batch, "period"), vec![s.period; 3]);
        assert_eq!(i64_col(&batch, "marker_id"), s.marker_id);
        assert_eq!(f64_col(&batch, "x"), s.x);
        assert_eq!(f64_col(&batch, "origin_z"), s.origin_z);
        assert_eq!(f64_col(&batch, "shear_work"), s.shear_work);
        assert_eq!(f64_col(&batch, "primary_frag_size"), s.primary_frag_size);
        assert_eq!(f64_col(&batch, "attrited"), s.attrited);
        assert_eq!(f64_col(&batch, "percolated"), s.percolated);
        assert_eq!(str_col(&batch, "state"), ["drawn", "moving", "in_situ"]);
        assert_eq!(
            str_col(&batch, "drawpoint"),
            [scene.drawpoints.name[1].as_str(), "", ""]
        );
        assert_eq!(i64_col(&batch, "drawn_period"), s.drawn_period);
    }
}

#[test]
fn parquet_files_are_zstd_with_statistics() {
    let (tmp, _, _, _) = run_dir();
    let file = fs::File::open(tmp.path().join("run/extraction.parquet")).unwrap();
    let builder = ParquetRecordBatchReaderBuilder::try_new(file).unwrap();
    let meta = builder.metadata();
    assert_eq!(meta.num_row_groups(), 1);
    for col in meta.row_group(0).columns() {
        assert!(
            matches!(col.compression(), parquet::basic::Compression::ZSTD(_)),
            "{:?}",
            col.column_path()
        );
        assert!(col.statistics().is_some(), "{:?}", col.column_path());
    }
}

#[test]
fn manifest_records_the_run() {
    let (tmp, _, run, _) = run_dir();
    let text = fs::read_to_string(tmp.path().join("run/manifest.json")).unwrap();
    let m: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(m["caveflow_version"], env!("CARGO_PKG_VERSION"));
    assert_eq!(m["command"], "caveflow run scenario.toml");
    assert_eq!(m["seed"], 7);
    assert_eq!(m["threads"], 2);
    assert_eq!(m["wall_time_s"], 1.25);
    let input = &m["inputs"][0];
    assert_eq!(input["role"], "schedule");
    assert_eq!(input["rows"], 3);
    assert_eq!(
        input["sha256"],
        "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
    );
    assert!(input["path"].as_str().unwrap().ends_with("schedule.csv"));
    assert_eq!(
        m["mass_balance"]["scheduled_tonnes"],
        run.balance.scheduled_tonnes
    );
    assert_eq!(
        m["mass_balance"]["credited_tonnes"],
        run.balance.credited_tonnes
    );
    assert_eq!(m["mass_balance"]["per_drawpoint"][1][1], 10_499.5);
    let c = &m["mass_balance"]["correction"];
    assert_eq!(
        (c["rows"].as_u64(), c["median"].as_f64()),
        (Some(2), Some(0.99))
    );
    assert_eq!(
        (c["p10"].as_f64(), c["p90"].as_f64()),
        (Some(0.98), Some(1.0))
    );
    assert_eq!(c["at_upper_bound"], 1);
    assert_eq!(m["resolution"]["layer_thickness"], 3.8);
    assert_eq!(m["warnings"][0], run.warnings[0].message);
    assert_eq!(m["scenario"]["dilution"]["grade"], "mo");
    assert_eq!(m["scenario"]["seed"], 7);
    let created = m["created_utc"].as_str().unwrap();
    assert_eq!(created.len(), 20, "{created}");
    assert!(
        created.starts_with("20") && created.ends_with('Z') && &created[10..11] == "T",
        "{created}"
    );
}

#[test]
fn rfc3339_formats_utc() {
    let at = |s: u64| rfc3339_utc(UNIX_EPOCH + Duration::from_secs(s));
    assert_eq!(at(0), "1970-01-01T00:00:00Z");
    assert_eq!(at(951_782_400), "2000-02-29T00:00:00Z");
    assert_eq!(at(951_868_799), "2000-02-29T23:59:59Z");
    assert_eq!(at(951_868_800), "2000-03-01T00:00:00Z");
    assert_eq!(at(1_700_000_000), "2023-11-14T22:13:20Z");
    assert_eq!(at(4_107_542_400), "2100-03-01T00:00:00Z"); // 2100 is not a leap year
}

#[test]
fn sha256_of_a_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("empty");
    fs::write(&path, b"").unwrap();
    assert_eq!(
        InputFile::new("x", &path, 0).unwrap().sha256,
        "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855"
    );
}

// ---------------------------------------------------------------- demo and input tables

/// Debug text captures every column of the scene.
fn fingerprint(s: &Scene) -> String {
    format!("{s:?}")
}

#[test]
fn demo_is_deterministic_for_a_seed() {
    let a = demo::henderson(DemoScale::Small, 42);
    let b = demo::henderson(DemoScale::Small, 42);
    assert_eq!(fingerprint(&a), fingerprint(&b));
    let c = demo::henderson(DemoScale::Small, 43);
    assert_ne!(fingerprint(&a), fingerprint(&c));

    let a = demo::henderson(DemoScale::Mine, 42);
    let b = demo::henderson(DemoScale::Mine, 42);
    assert_eq!(a.schedule.tonnes, b.schedule.tonnes);
    assert_eq!(a.blocks.grades, b.blocks.grades);
    assert_eq!(a.blocks.lithology, b.blocks.lithology);
}

/// Every drawpoint sits at the base of a full column of blocks.
fn assert_drawpoints_over_blocks(s: &Scene) {
    let b = &s.blocks;
    for d in 0..s.drawpoints.len() {
        let (x, y, z) = (s.drawpoints.x[d], s.drawpoints.y[d], s.drawpoints.z[d]);
        assert!(
            (z - b.origin[2]).abs() < 1e-6,
            "{} at z {z}, grid base {}",
            s.drawpoints.name[d],
            b.origin[2]
        );
        for k in 0..8 {
            let p = [x, y, z + (k as f64 + 0.5) * b.size[2]];
            assert!(
                b.locate(p).is_some(),
                "{} layer {k}: no block",
                s.drawpoints.name[d]
            );
        }
    }
}

#[test]
fn demo_small_panel() {
    let s = demo::henderson(DemoScale::Small, 1);
    let b = &s.blocks;
    assert_eq!(b.size, [7.6, 7.6, 15.2]);
    assert_eq!(b.grade_names, ["mo"]);
    let mut liths = b.lithology_names.clone();
    liths.sort();
    assert_eq!(liths, ["8100_broken", "contact", "primos", "urad"]);
    assert!(
        (24..=40).contains(&s.drawpoints.len()),
        "{}",
        s.drawpoints.len()
    );
    assert!((b.origin[2] - EXTRACTION_LEVEL_Z).abs() < 1e-6);
    let column = b.z_max() - EXTRACTION_LEVEL_Z;
    assert!((150.0..=180.0).contains(&column), "{column}");
    let extent = b.max_corner();
    for (a, (hi, lo)) in extent.iter().zip(b.origin).take(2).enumerate() {
        let span = hi - lo;
        assert!((90.0..=115.0).contains(&span), "axis {a}: {span} m");
    }
    assert_drawpoints_over_blocks(&s);

    // Properties per lithology.
    let lith = |name: &str| b.lithology_names.iter().position(|l| l == name).unwrap() as u16;
    let (urad, primos, contact, broken) = (
        lith("urad"),
        lith("primos"),
        lith("contact"),
        lith("8100_broken"),
    );
    let gamma_5_3 = 0.902_745_292_950_933_6;
    for i in 0..b.len() {
        let expected = match b.lithology[i] {
            l if l == urad => 0.23,
            l if l == primos => 0.04,
            l if l == contact => 0.13,
            _ => 0.10,
        };
        assert_eq!(b.frag[i], expected);
        assert!((b.frag_scale[i] * gamma_5_3 - b.frag[i]).abs() < 1e-12);
        assert_eq!(b.frag_shape[i], 1.5);
        assert!((0.29..=0.31).contains(&b.n0[i]) && (0.44..=0.46).contains(&b.n1[i]));
        assert!((38.0..=42.0).contains(&b.friction[i]));
        assert!((100_000.0..=150_000.0).contains(&b.ucs[i]));
        assert!((2.5..=2.7).contains(&b.density[i]));
        let mo = b.grades[0][i];
        if b.lithology[i] == broken {
            assert!((0.03..=0.07).contains(&mo), "{mo}");
            assert!(b.z[i] > EXTRACTION_LEVEL_Z + 120.0);
        } else {
            assert!((0.2..=0.35).contains(&mo), "{mo}");
        }
    }

    // Urad in the west, Primos in the east (bottom layer).
    let mean_x = |l: u16| {
        let xs: Vec<f64> = (0..b.len())
            .filter(|&i| b.lithology[i] == l)
            .map(|i| b.x[i])
            .collect();
        xs.iter().sum::<f64>() / xs.len() as f64
    };
    assert!(mean_x(urad) < mean_x(contact) && mean_x(contact) < mean_x(primos));

    // Higher grade to the north.
    let ore: Vec<usize> = (0..b.len()).filter(|&i| b.lithology[i] != broken).collect();
    let y_mid = 0.5 * (b.origin[1] + extent[1]);
    let mean_mo = |north: bool| {
        let v: Vec<f64> = ore
            .iter()
            .filter(|&&i| (b.y[i] > y_mid) == north)
            .map(|&i| b.grades[0][i])
            .collect();
        v.iter().sum::<f64>() / v.len() as f64
    };
    assert!(mean_mo(true) > mean_mo(false) + 0.02);

    // The southeast corner: no broken material over it, late caving at its top.
    let (x_se, y_se) = (extent[0] - 1.0, b.origin[1] + 1.0);
    let top = |x: f64, y: f64| {
        (0..20)
            .filter(|&k| {
                b.locate([x, y, b.origin[2] + (k as f64 + 0.5) * BLOCK_HEIGHT])
                    .is_some()
            })
            .count()
    };
    assert_eq!(top(x_se, y_se), 8, "SE column stops at the ore");
    assert_eq!(
        top(b.origin[0] + 1.0, extent[1] - 1.0),
        11,
        "NW column has broken material on top"
    );
    let se_top = b
        .locate([x_se, y_se, b.origin[2] + 7.5 * BLOCK_HEIGHT])
        .unwrap();
    assert!(b.cave_period[se_top] > 1);
    let se_bottom = b
        .locate([x_se, y_se, b.origin[2] + 0.5 * BLOCK_HEIGHT])
        .unwrap();
    assert_eq!(b.cave_period[se_bottom], 0);

    // Drawpoint zones are the lithology they sit in.
    for d in 0..s.drawpoints.len() {
        let at = b
            .locate([
                s.drawpoints.x[d],
                s.drawpoints.y[d],
                s.drawpoints.z[d] + 1.0,
            ])
            .unwrap();
        assert_eq!(
            s.drawpoints.zone[d],
            b.lithology_names[b.lithology[at] as usize]
        );
        assert_eq!(s.drawpoints.width[d], 4.0);
    }

    // Monthly periods from Jan-09.
    assert_eq!(s.periods.len(), 24);
    assert_eq!(s.periods.name[0], "Jan-09");
    assert_eq!(s.periods.name[23], "Dec-10");
    assert_eq!(s.periods.days[1], 28.0);
    assert_eq!(s.periods.days.iter().sum::<f64>(), 730.0);

    // Schedule: west starts no later than east; steady months of 3000–6000 t.
    let n = s.drawpoints.len();
    assert_eq!(s.schedule.n_drawpoints, n);
    let first = |d: usize| {
        (0..s.periods.len())
            .find(|&p| s.schedule.get(p, d) > 0.0)
            .unwrap()
    };
    let west = (0..n)
        .min_by(|&a, &c| s.drawpoints.x[a].total_cmp(&s.drawpoints.x[c]))
        .unwrap();
    let east = (0..n)
        .max_by(|&a, &c| s.drawpoints.x[a].total_cmp(&s.drawpoints.x[c]))
        .unwrap();
    assert_eq!(first(west), 0);
    assert!(first(east) >= 6, "east starts in month {}", first(east) + 1);
    for d in 0..n {
        let f = first(d);
        assert!(
            s.schedule.get(f, d) < s.schedule.get(f + 3, d),
            "ramp-up of {}",
            s.drawpoints.name[d]
        );
        let steady = s.schedule.get(f + 4, d);
        assert!((2500.0..=6500.0).contains(&steady), "{steady}");
    }
    assert!(s
        .schedule
        .tonnes
        .iter()
        .all(|&t| (0.0..=6500.0).contains(&t)));
}

#[test]
fn demo_mine_scale() {
    let s = demo::henderson(DemoScale::Mine, 3);
    assert!(s.drawpoints.len() >= 400, "{}", s.drawpoints.len());
    assert!(s.blocks.z_max() - EXTRACTION_LEVEL_Z >= 200.0);
    assert_eq!(s.periods.len(), 3650);
    assert!(s.periods.days.iter().all(|&d| d == 1.0));
    assert_eq!(s.periods.name[0], "1");
    assert_eq!(s.periods.name[3649], "3650");
    assert_eq!(s.schedule.tonnes.len(), 3650 * s.drawpoints.len());
    assert_drawpoints_over_blocks(&s);
    // Every drawpoint draws, and none draws more than its column holds.
    for d in 0..s.drawpoints.len() {
        let total = s.schedule.total(d);
        assert!(
            total > 50_000.0 && total < 130_000.0,
            "{}: {total} t",
            s.drawpoints.name[d]
        );
    }
}

#[test]
fn scene_written_as_input_tables() {
    let dir = tempfile::tempdir().unwrap();
    let scene = demo::henderson(DemoScale::Small, 5);
    let files = write_scene(dir.path(), &scene, &demo::scenario(DemoScale::Small, 5)).unwrap();
    let names: Vec<String> = files
        .iter()
        .map(|f| f.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        [
            "blocks.parquet",
            "drawpoints.csv",
            "periods.csv",
            "schedule.csv",
            "scenario.toml"
        ]
    );
    assert_eq!(
        entries(dir.path()),
        [
            "blocks.parquet",
            "drawpoints.csv",
            "periods.csv",
            "scenario.toml",
            "schedule.csv"
        ]
    );

    // The scenario file loads and points at the tables.
    let sc = Scenario::load(&dir.path().join("scenario.toml"), &[]).unwrap();
    assert_eq!(sc.seed, 5);
    assert_eq!(sc.dilution.waste_lithologies, ["8100_broken"]);
    for p in [
        &sc.inputs.blocks,
        &sc.inputs.drawpoints,
        &sc.inputs.schedule,
        sc.inputs.periods.as_ref().unwrap(),
    ] {
        assert!(p.is_file(), "{}", p.display());
    }

    // Block model: canonical names, metadata, values.
    let b = &scene.blocks;
    let batch = read_parquet(&sc.inputs.blocks);
    let fixed: Vec<&str> = schema::BLOCK_MODEL
        .field_names()
        .into_iter()
        // Resolved values are written: the tensile strength, the cave period in use.
        .filter(|f| !["tensile_shape", "tensile_scale", "cave_period_dyn"].contains(f))
        .collect();
    assert_schema(
        &batch,
        &schema::BLOCK_MODEL.arrow_schema(&fixed, &["mo".to_string()]),
    );
    assert_eq!(
        batch
            .schema()
            .field_with_name("lithology")
            .unwrap()
            .data_type(),
        &DataType::Utf8
    );
    assert_eq!(f64_col(&batch, "x"), b.x);
    assert_eq!(f64_col(&batch, "z"), b.z);
    assert_eq!(i64_col(&batch, "block_id"), b.id);
    assert_eq!(i64_col(&batch, "cave_period"), b.cave_period);
    assert_eq!(f64_col(&batch, "max_porosity"), b.n1);
    assert_eq!(f64_col(&batch, "frag_scale"), b.frag_scale);
    assert_eq!(f64_col(&batch, "mo"), b.grades[0]);
    let lith: Vec<String> = b
        .lithology
        .iter()
        .map(|&l| b.lithology_names[l as usize].clone())
        .collect();
    assert_eq!(str_col(&batch, "lithology"), lith);

    // CSV tables.
    let mut rd = csv::Reader::from_path(&sc.inputs.drawpoints).unwrap();
    assert_eq!(
        rd.headers().unwrap(),
        vec!["name", "x", "y", "z", "width", "zone"]
    );
    let rows: Vec<csv::StringRecord> = rd.records().map(Result::unwrap).collect();
    assert_eq!(rows.len(), scene.drawpoints.len());
    assert_eq!(&rows[3][0], scene.drawpoints.name[3]);
    assert_eq!(rows[3][1].parse::<f64>().unwrap(), scene.drawpoints.x[3]);
    assert_eq!(&rows[3][5], scene.drawpoints.zone[3]);

    let mut rd = csv::Reader::from_path(sc.inputs.periods.as_ref().unwrap()).unwrap();
    assert_eq!(rd.headers().unwrap(), vec!["period", "name", "days"]);
    let rows: Vec<csv::StringRecord> = rd.records().map(Result::unwrap).collect();
    assert_eq!(rows.len(), 24);
    assert_eq!(
        (&rows[0][0], &rows[0][1], rows[0][2].parse::<f64>().unwrap()),
        ("1", "Jan-09", 31.0)
    );

    let mut rd = csv::Reader::from_path(&sc.inputs.schedule).unwrap();
    assert_eq!(rd.headers().unwrap(), vec!["period", "drawpoint", "tonnes"]);
    let mut total = 0.0;
    let mut rows = 0;
    for r in rd.records() {
        let r = r.unwrap();
        let t: f64 = r[2].parse().unwrap();
        assert!(t > 0.0);
        let p = r[0].parse::<usize>().unwrap() - 1;
        assert_eq!(
            scene.schedule.get(p, scene.drawpoints.find(&r[1]).unwrap()),
            t
        );
        total += t;
        rows += 1;
    }
    assert_eq!(
        rows,
        scene.schedule.tonnes.iter().filter(|&&t| t > 0.0).count()
    );
    assert_eq!(total, scene.schedule.tonnes.iter().sum::<f64>());
}

#[test]
fn mine_scale_schedule_is_parquet() {
    let dir = tempfile::tempdir().unwrap();
    let scene = demo::henderson(DemoScale::Mine, 5);
    let files = write_scene(dir.path(), &scene, &demo::scenario(DemoScale::Mine, 5)).unwrap();
    assert!(files.iter().any(|f| f.ends_with("schedule.parquet")));
    let sc = Scenario::load(&dir.path().join("scenario.toml"), &[]).unwrap();
    assert!(!sc.outputs.imz_every_period);
    let batch = read_parquet(&sc.inputs.schedule);
    assert_schema(&batch, &spec_schema(&schema::SCHEDULE, &[]));
    let nonzero: Vec<f64> = scene
        .schedule
        .tonnes
        .iter()
        .copied()
        .filter(|&t| t > 0.0)
        .collect();
    assert_eq!(batch.num_rows(), nonzero.len());
    assert!(nonzero.len() > 200_000);
    let periods = i64_col(&batch, "period");
    assert!(periods.windows(2).all(|w| w[0] <= w[1]), "period-major");
    assert_eq!(
        f64_col(&batch, "tonnes").iter().sum::<f64>(),
        nonzero.iter().sum::<f64>()
    );
}

/// Read → write → read through caveflow's own writers and readers: the demo scene written
/// as input tables loads back with identical values (block size snapped to the grid).
#[test]
fn scene_round_trip_through_the_readers() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = demo::henderson(DemoScale::Small, 3);
    let scenario = demo::scenario(DemoScale::Small, 3);
    caveflow::output::inputs::write_scene(tmp.path(), &scene, &scenario).unwrap();
    let sc = caveflow::model::Scenario::load(&tmp.path().join("scenario.toml"), &[]).unwrap();
    let back = caveflow::model::load::load_scene(&sc).unwrap().scene;
    let (a, b) = (&scene.blocks, &back.blocks);
    assert_eq!(a.size, b.size);
    assert_eq!(a.dims, b.dims);
    assert_eq!(a.index, b.index);
    assert_eq!(
        (&a.x, &a.y, &a.z, &a.id, &a.cave_period),
        (&b.x, &b.y, &b.z, &b.id, &b.cave_period)
    );
    assert_eq!(
        (&a.density, &a.n0, &a.n1, &a.friction, &a.frag),
        (&b.density, &b.n0, &b.n1, &b.friction, &b.frag)
    );
    assert_eq!((&a.grade_names, &a.grades), (&b.grade_names, &b.grades));
    assert_eq!(
        (&a.lithology, &a.lithology_names),
        (&b.lithology, &b.lithology_names)
    );
    let (p, q) = (&scene.drawpoints, &back.drawpoints);
    assert_eq!(
        (&p.name, &p.x, &p.y, &p.z, &p.width),
        (&q.name, &q.x, &q.y, &q.z, &q.width)
    );
    assert_eq!(
        (&scene.periods.id, &scene.periods.name, &scene.periods.days),
        (&back.periods.id, &back.periods.name, &back.periods.days)
    );
    assert_eq!(scene.schedule.tonnes, back.schedule.tonnes);
}
