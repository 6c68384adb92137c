//! Integration tests: the Hive-partitioned datasets of a run (output::dataset), read back
//! with the parquet crate.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use arrow::array::{Array, ArrayRef, AsArray, Int64Array, UInt32Array};
use arrow::compute::{concat_batches, take_record_batch};
use arrow::datatypes::Int64Type;
use arrow::record_batch::RecordBatch;
use caveflow::engine::Engine;
use caveflow::model::{Scenario, Scene};
use caveflow::output::dataset::HiveLayout;
use caveflow::output::{write_run_with, Manifest};

use crate::fixtures::{entries, read_parquet, tiny};

/// Runs `scene` and writes the run into `dir` with `sc`'s dataset layout.
fn run_into(dir: &Path, scene: &Scene, sc: &Scenario) -> Vec<PathBuf> {
    let out = Engine::new(scene, sc).unwrap().run(&mut |_, _| {});
    let manifest = Manifest::new("test".into(), sc, Vec::new(), &out, 1, 0.0);
    let hive = HiveLayout::new(sc, "tiny", scene.periods.len());
    write_run_with(dir, scene, out, &manifest, hive.as_ref()).unwrap()
}

/// The flat table's rows in stable period order.
fn by_period(flat: &RecordBatch) -> RecordBatch {
    let p = flat
        .column_by_name("period")
        .unwrap()
        .as_primitive::<Int64Type>();
    let mut idx: Vec<u32> = (0..flat.num_rows() as u32).collect();
    idx.sort_by_key(|&i| p.value(i as usize));
    take_record_batch(flat, &UInt32Array::from(idx)).unwrap()
}

#[test]
fn hive_datasets_match_the_flat_tables() {
    let scene = tiny();
    let sc = Scenario::default();
    assert!(sc.outputs.hive, "on by default");
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("run");
    let files = run_into(&dir, &scene, &sc);
    assert_eq!(
        entries(&dir.join("dataset")),
        ["air_gap", "drawn", "extraction", "imz", "surface"]
    );
    let mut checked = 0;
    for table in ["extraction", "imz", "drawn", "air_gap", "surface"] {
        let flat = read_parquet(&dir.join(format!("{table}.parquet")));
        let root = dir.join("dataset").join(table);
        if flat.num_rows() == 0 {
            assert!(
                !root.join("scenario=tiny").exists(),
                "{table}: no rows, no partitions"
            );
            continue;
        }
        assert_eq!(entries(&root), ["scenario=tiny"], "{table}");
        let parts = entries(&root.join("scenario=tiny"));
        // One partition per period that has rows, named period=<N>.
        let mut periods: Vec<i64> = parts
            .iter()
            .map(|p| p.strip_prefix("period=").unwrap().parse().unwrap())
            .collect();
        periods.sort();
        let mut flat_periods: Vec<i64> = flat
            .column_by_name("period")
            .unwrap()
            .as_primitive::<Int64Type>()
            .values()
            .to_vec();
        flat_periods.dedup();
        flat_periods.sort();
        flat_periods.dedup();
        assert_eq!(periods, flat_periods, "{table}");
        // Each part: the flat columns less `period` (it is the directory), same names,
        // same unit metadata; with `period` added back from the directory, the union of
        // the parts is the flat table.
        let mut batches = Vec::new();
        for p in &periods {
            let file = root
                .join("scenario=tiny")
                .join(format!("period={p}"))
                .join("part-0.parquet");
            assert!(files.contains(&file), "{} not listed", file.display());
            let part = read_parquet(&file);
            let schema = part.schema();
            assert!(schema.field_with_name("period").is_err(), "{table}");
            for f in flat
                .schema()
                .fields()
                .iter()
                .filter(|f| f.name() != "period")
            {
                let g = schema.field_with_name(f.name()).unwrap();
                assert_eq!(g.data_type(), f.data_type(), "{table}.{}", f.name());
                assert_eq!(g.metadata(), f.metadata(), "{table}.{}", f.name());
                assert!(g.metadata().contains_key("unit"), "{table}.{}", f.name());
            }
            // Rebuild the flat layout: `period` back at its place.
            let at = flat.schema().index_of("period").unwrap();
            let mut cols: Vec<ArrayRef> = part.columns().to_vec();
            cols.insert(at, Arc::new(Int64Array::from(vec![*p; part.num_rows()])));
            batches.push(RecordBatch::try_new(flat.schema(), cols).unwrap());
        }
        let union = concat_batches(&flat.schema(), &batches).unwrap();
        let want = by_period(&flat);
        assert_eq!(union.num_rows(), want.num_rows(), "{table}");
        for c in 0..want.num_columns() {
            assert_eq!(
                union.column(c).to_data(),
                want.column(c).to_data(),
                "{table}.{}",
                want.schema().field(c).name()
            );
        }
        checked += 1;
    }
    assert!(checked >= 3, "extraction, imz and drawn have rows");
    // No temporary directory is left beside the partitions.
    for table in entries(&dir.join("dataset")) {
        for e in entries(&dir.join("dataset").join(&table)) {
            assert!(!e.starts_with('.'), "left behind: {table}/{e}");
        }
    }
}

#[test]
fn hive_grouped_partitions_and_reruns_replace_stale_ones() {
    let scene = tiny();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("run");
    // Two periods per partition: period_group=1 (periods 1 and 2) and period_group=3, with
    // `period` kept in the files.
    let mut sc = Scenario::default();
    sc.outputs.hive_periods_per_partition = 2;
    run_into(&dir, &scene, &sc);
    let root = dir.join("dataset/extraction/scenario=tiny");
    assert_eq!(entries(&root), ["period_group=1", "period_group=3"]);
    let g1 = read_parquet(&root.join("period_group=1/part-0.parquet"));
    let p: Vec<i64> = g1
        .column_by_name("period")
        .unwrap()
        .as_primitive::<Int64Type>()
        .values()
        .to_vec();
    assert!(p.contains(&1) && p.contains(&2) && !p.contains(&3), "{p:?}");
    // A rerun into the same directory, per period, replaces the grouped partitions.
    run_into(&dir, &scene, &Scenario::default());
    assert_eq!(entries(&root), ["period=1", "period=2", "period=3"]);
    // hive = false writes no dataset; a named scenario names its partition.
    let mut off = Scenario::default();
    off.outputs.hive = false;
    assert!(HiveLayout::new(&off, "tiny", 3).is_none());
    let mut named = Scenario::default();
    named.outputs.scenario_name = Some("base-case".into());
    assert_eq!(
        HiveLayout::new(&named, "tiny", 3).unwrap().scenario,
        "base-case"
    );
    // Automatic grouping at mine scale: 3650 daily periods in partitions of 31.
    let auto = HiveLayout::new(&Scenario::default(), "mine", 3650).unwrap();
    assert_eq!(auto.periods_per_partition, 31);
    assert_eq!(
        HiveLayout::new(&Scenario::default(), "a b/c", 24)
            .unwrap()
            .scenario,
        "a_b_c"
    );
    // A scenario name that cannot be a directory is refused.
    let sets = ["outputs.scenario_name=\"../x\"".to_string()];
    let e = Scenario::from_toml("", "scenario.toml", &sets, Path::new("/")).unwrap_err();
    assert_eq!(e.rule(), "setting-range");
    assert!(
        e.to_string()
            .contains("outputs.scenario_name `../x` must be letters"),
        "{e}"
    );
}
