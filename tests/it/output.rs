//! Integration tests: output (atomic writes, run tables, manifest, input tables) and the demo
//! generator.

use std::fs;
use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, UNIX_EPOCH};

use arrow::array::{ArrayRef, AsArray, Float64Array, RecordBatch};
use arrow::datatypes::{Float64Type, Int64Type, Schema};
use caveflow::engine::result::{
    AirGapTable, CorrectionStats, DrawnTable, Extraction, ImzTable, MarkerSnapshot, MarkerState,
    MassBalance, ResolvedResolution, RunOutput, RunWarning, SurfaceTable, WarningRule,
};
use caveflow::model::demo::{self, DemoScale};
use caveflow::model::Scene;
use caveflow::output::manifest::rfc3339_utc;
use caveflow::output::{write_atomic, write_parquet, write_run, AtomicFile, InputFile, Manifest};
use caveflow::schema::{self, TableSpec};
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;

use crate::fixtures::{entries, read_parquet};

pub(crate) fn f64_col(batch: &RecordBatch, name: &str) -> Vec<f64> {
    batch
        .column_by_name(name)
        .unwrap()
        .as_primitive::<Float64Type>()
        .values()
        .to_vec()
}

pub(crate) fn i64_col(batch: &RecordBatch, name: &str) -> Vec<i64> {
    batch
        .column_by_name(name)
        .unwrap()
        .as_primitive::<Int64Type>()
        .values()
        .to_vec()
}

pub(crate) fn str_col(batch: &RecordBatch, name: &str) -> Vec<String> {
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
pub(crate) fn assert_schema(batch: &RecordBatch, expected: &Schema) {
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

pub(crate) fn spec_schema(spec: &TableSpec, extra: &[String]) -> Arc<Schema> {
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
        fill: vec![0.95, 0.3, f64::NAN, 1.02, 0.9, 0.2],
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
        marker_caps: {
            // One 10 t marker moved 5 m, 0.5 m of its ring's push cut.
            use caveflow::engine::markers::{CapTally, Cut, Step};
            let s = Step {
                dx: 3.0,
                dz: -4.0,
                ..Default::default()
            };
            let mut cut = Cut::default();
            cut.dropped[0] = 0.5;
            let mut t = CapTally::default();
            t.add(10.0, &s, &cut);
            t
        },
        counterflow: Default::default(),
        stress: Vec::new(),
        trace: Default::default(),
        control: None,
        value: None,
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
    let caps = &m["marker_caps"];
    assert_eq!(
        (caps["moves"].as_u64(), caps["moved_tonne_metres"].as_f64()),
        (Some(1), Some(50.0))
    );
    let push = &caps["push"];
    assert_eq!(
        (push["moves"].as_u64(), push["share"].as_f64()),
        (Some(1), Some(1.0))
    );
    assert_eq!(
        (
            push["dropped_tonne_metres"].as_f64(),
            push["dropped_share"].as_f64()
        ),
        (Some(5.0), Some(0.1))
    );
    assert_eq!(caps["lateral"]["dropped_share"].as_f64(), Some(0.0));
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
