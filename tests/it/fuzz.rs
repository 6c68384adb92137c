//! Integration tests: the fuzz harness's findings, and a short fuzz run over every reader.

use std::fs;
use std::path::Path;

use caveflow::io::{read_schedule, read_table};
use caveflow::schema::{BLOCK_MODEL, DRAWBELLS, DRAWPOINTS, PERIODS, SCHEDULE};

use crate::fixtures::{expect, BLOCKS, DRAWPOINTS_CSV, PERIODS_CSV, SCHEDULE_CSV};

use crate::io::data;

// ---------------------------------------------------------------------------------------
// The fuzz harness's findings, and a short fuzz run in the suite.

/// Each input that crashed a fuzz target (tests/fuzz/README.md) is kept in
/// `tests/data/io/fuzz/` and must now be reported, never panic.
#[test]
fn fuzz_regressions() {
    // The parquet crate panics in `ColumnChunkMetaData::byte_range` on a column chunk whose
    // start or length is negative (libFuzzer, parquet_table target, 82 472 runs in). The
    // panic is caught, silently, and reported with its message.
    let crash = data("fuzz/negative_column_start.parquet");
    let p = read_schedule(&crash).unwrap_err();
    let pr = expect(
        &p,
        "negative_column_start.parquet",
        None,
        None,
        "unreadable",
    );
    assert!(
        pr.message
            .contains("column start and length should not be negative"),
        "{pr}"
    );
    let _ = read_table(&crash, &BLOCK_MODEL).unwrap_err();
}

/// Every readable seed of the fuzz corpus, and a few hundred proptest-generated mutations
/// of the test scene's files (random bytes spliced in, cut, duplicated), through every
/// text reader and `load_scene`: each returns, Ok or a list of problems each with a rule.
/// The coverage-guided runs are in `tests/fuzz/README.md`; this keeps a short version in the suite.
#[test]
fn random_bytes_through_every_reader() {
    use proptest::prelude::*;
    use proptest::test_runner::{Config, TestRunner};
    let seeds = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz/corpus-seed");
    let mut inputs: Vec<Vec<u8>> = Vec::new();
    for dir in ["csv_table", "schedule"] {
        for e in fs::read_dir(seeds.join(dir)).unwrap() {
            inputs.push(fs::read(e.unwrap().path()).unwrap());
        }
    }
    inputs
        .extend([BLOCKS, DRAWPOINTS_CSV, PERIODS_CSV, SCHEDULE_CSV].map(|s| s.as_bytes().to_vec()));
    let all_specs = [BLOCK_MODEL, DRAWPOINTS, DRAWBELLS, PERIODS, SCHEDULE];
    let read_all = |bytes: &[u8]| {
        for spec in &all_specs {
            if let Err(p) = caveflow::io::read_table_bytes("t.csv", bytes.to_vec(), spec) {
                assert!(!p.0.is_empty());
            }
        }
        let _ = caveflow::io::read_schedule_bytes("t.csv", bytes.to_vec());
    };
    for i in &inputs {
        read_all(i);
    }
    // Mutations: (which input, position, replacement bytes, cut length).
    let alphabet: Vec<u8> = b",;\t\n\r\"% -.0123456789eE+xyzNaInf\xEF\xBB\xBF\xFF\x00".to_vec();
    let strategy = (
        0..inputs.len(),
        any::<prop::sample::Index>(),
        prop::collection::vec(prop::sample::select(alphabet), 0..12),
        0usize..8,
    );
    let mut runner = TestRunner::new_with_rng(
        Config {
            cases: 400,
            failure_persistence: None,
            ..Config::default()
        },
        proptest::test_runner::TestRng::deterministic_rng(
            proptest::test_runner::RngAlgorithm::ChaCha,
        ),
    );
    runner
        .run(&strategy, |(k, at, insert, cut)| {
            let mut b = inputs[k].clone();
            let at = at.index(b.len() + 1);
            let end = (at + cut).min(b.len());
            b.splice(at..end, insert);
            read_all(&b);
            Ok(())
        })
        .unwrap();
}
