//! Integration tests: production records (model::records, output::records): reading,
//! every rule with its message, dates to periods, and the writer's round trip.

use std::fs;
use std::path::Path;

use caveflow::io::{Problem, Problems};
use caveflow::model::load::load_scene;
use caveflow::model::{load_records, Drawpoints, Periods, ProductionRecords};
use caveflow::output::records::write_records;
use tempfile::TempDir;

use crate::fixtures::small_scene_in;

/// Writes the io tests' small scene (drawpoints DP1 and DP2, grade `cu`) into `dir`, with
/// `periods` as its periods table, and loads it.
fn load_in(dir: &Path, periods: &str) -> Result<caveflow::model::load::LoadedScene, Problems> {
    let sc = small_scene_in(dir);
    fs::write(dir.join("periods.csv"), periods).unwrap();
    load_scene(&sc)
}

/// The small scene's drawpoints, periods and grade names.
fn scene(periods: &str) -> (Drawpoints, Periods, Vec<String>) {
    let dir = TempDir::new().unwrap();
    let s = load_in(dir.path(), periods)
        .unwrap_or_else(|p| panic!("{p}"))
        .scene;
    (s.drawpoints, s.periods, s.blocks.grade_names)
}

const DATED_PERIODS: &str = "period,name,days,start_date\n1,Jan-09,31,2009-01-01\n2,Feb-09,28,\n";
const UNDATED_PERIODS: &str = "period,name,days\n1,Jan-09,31\n2,Feb-09,28\n";

fn load(periods: &str, records: &str) -> Result<ProductionRecords, Problems> {
    let (d, p, g) = scene(periods);
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("records.csv");
    fs::write(&path, records).unwrap();
    load_records(&path, &d, &p, &g)
}

/// The records.csv problem at this row, column and rule, checking that its Display names
/// all four, the column just before the rule.
fn expect<'a>(ps: &'a Problems, row: Option<usize>, column: &str, rule: &str) -> &'a Problem {
    let p = crate::fixtures::expect(ps, "records.csv", row, Some(column), rule);
    let shown = p.to_string();
    assert!(
        shown.contains(&format!("column {column}: [{rule}] ")),
        "{shown}"
    );
    p
}

#[test]
fn records_read_with_periods_dates_and_gaps() {
    let r = load(
        DATED_PERIODS,
        "DPName,Period,Date,Tonnes,frag_size,Cu\n\
         DP1,1,,1000,0.2,1.1\n\
         DP2,,2009-02-10,500.5,,\n\
         DP1,2,2009-02-01T06:00:00,250,0.15,0.9\n",
    )
    .unwrap_or_else(|p| panic!("{p}"));
    assert_eq!(r.file, "records.csv");
    assert_eq!(r.row, [1, 2, 3]);
    assert_eq!(r.drawpoint, [0, 1, 0]);
    assert_eq!(
        r.period,
        [Some(1), Some(2), Some(2)],
        "the date maps to Feb-09"
    );
    assert_eq!(
        r.date,
        [None, Some("2009-02-10".into()), Some("2009-02-01".into())]
    );
    assert_eq!(r.tonnes, [1000.0, 500.5, 250.0]);
    assert_eq!(r.grade_names, ["cu"], "named as the block model names it");
    assert_eq!(r.grade("cu").unwrap()[0], 1.1);
    assert!(
        r.grades[0][1].is_nan(),
        "an empty grade cell is not sampled"
    );
    let f = r.frag.as_ref().unwrap();
    assert_eq!((f[0], f[2]), (0.2, 0.15));
    assert!(f[1].is_nan());
    // Without start dates a dated record keeps period None (matched later by tonnes).
    let r = load(
        UNDATED_PERIODS,
        "drawpoint,date,tonnes\nDP1,2009-02-10,10\n",
    )
    .unwrap();
    assert_eq!(r.period, [None]);
    assert_eq!(r.date, [Some("2009-02-10".into())]);
    assert!(r.frag.is_none() && r.grades.is_empty());
}

#[test]
fn records_rules_name_file_row_column_and_rule() {
    let p = load(
        DATED_PERIODS,
        "drawpoint,period,date,tonnes,frag_size,cu,zn\n\
         DP9,1,,10,,1,\n\
         DP1,7,,10,,1,\n\
         DP1,,2009-02-30,10,,1,\n\
         DP1,,,10,,1,\n\
         DP1,1,,-5,,1,\n\
         DP1,1,,NaN,,1,\n\
         DP1,1,,10,,NaN,\n\
         DP1,1,,10,,120,\n\
         DP1,,2010-05-01,10,,1,\n\
         DP1,1,2009-02-03,10,,1,\n\
         DP1,1,,10,-0.1,1,\n\
         DP1,1,,10,230,1,\n",
    )
    .unwrap_err();
    // (row, column, rule, the message or a part of it)
    let cases: [(usize, &str, &str, &str); 13] = [
        (0, "zn", "unknown-grade", "column `zn` is not a grade of the block model (it has: `cu`); rename it to the block model's grade or remove it"),
        (1, "drawpoint", "unknown-drawpoint", "drawpoint `DP9` is not in the drawpoints table"),
        (2, "period", "unknown-period", "period 7 is not one of the run's periods (1–2)"),
        (3, "date", "bad-date", "`2009-02-30` is not an ISO 8601 date (YYYY-MM-DD)"),
        (4, "period", "no-period", "the row has neither a period nor a date"),
        (5, "tonnes", "negative", "-5 tonnes must not be negative"),
        (6, "tonnes", "not-finite", "NaN is not a finite number"),
        (7, "cu", "not-finite", "NaN is not a finite number"),
        (8, "cu", "grade-range", "grade cu 120 % is outside [0, 100] %"),
        (9, "date", "unknown-period", "date 2010-05-01 falls in none of the run's periods (they run from 2009-01-01 to before 2009-03-01)"),
        (10, "date", "period-date-mismatch", "date 2009-02-03 lies in period 2, but the row gives period 1"),
        (11, "frag_size", "not-positive", "sampled fragment size -0.1 m must be positive"),
        (12, "frag_size", "units-mm", "sampled fragment size 230 m is not plausible (more than 10 m): it looks like mm; divide by 1000 (0.23 m)"),
    ];
    for (row, column, rule, message) in cases {
        let pr = expect(&p, Some(row), column, rule);
        assert_eq!(pr.message, message, "{pr}");
    }
    assert_eq!(p.0.len(), 13, "one problem per defect:\n{p}");
    // A file with neither a period nor a date column.
    let p = load(UNDATED_PERIODS, "drawpoint,tonnes\nDP1,10\n").unwrap_err();
    let pr = expect(&p, None, "period", "missing-column");
    assert!(
        pr.message
            .contains("a period column (Period) or a date column (Date)"),
        "{pr}"
    );
}

#[test]
fn periods_start_dates_rules() {
    let (_, p, _) = scene(DATED_PERIODS);
    let start = p.start.as_ref().unwrap();
    assert_eq!(start, &[14_245.0, 14_276.0]);
    assert_eq!(p.at_day(14_275.0), Some(0));
    assert_eq!(p.at_day(14_276.0), Some(1));
    assert_eq!(p.at_day(14_304.0), None, "March 2009 is after the run");
    assert_eq!(p.at_day(14_244.0), None);
    // Overlapping and unparseable starts.
    let dir = TempDir::new().unwrap();
    for (text, rule, message) in [
        (
            "period,name,days,start_date\n1,Jan-09,31,2009-01-01\n2,Feb-09,28,2009-01-20\n",
            "period-order",
            "period starts 2009-01-20 but the previous period runs to 2009-02-01 (its start plus its days): periods must not overlap",
        ),
        (
            "period,name,days,start_date\n1,Jan-09,31,Jan 2009\n2,Feb-09,28,\n",
            "bad-date",
            "`Jan 2009` is not an ISO 8601 date (YYYY-MM-DD)",
        ),
    ] {
        let p = load_in(dir.path(), text).unwrap_err();
        let pr = p.with_rule(rule).next().unwrap_or_else(|| panic!("{p}"));
        assert_eq!(pr.file, "periods.csv");
        assert_eq!(pr.column.as_deref(), Some("start_date"));
        assert_eq!(pr.message, message);
    }
}

#[test]
fn records_write_and_read_back() {
    let (d, p, g) = scene(DATED_PERIODS);
    let r = ProductionRecords {
        file: String::new(),
        row: vec![1, 2, 3],
        drawpoint: vec![0, 1, 1],
        period: vec![Some(1), Some(2), None],
        date: vec![None, Some("2009-02-10".into()), Some("2009-02-11".into())],
        tonnes: vec![1234.5, 0.1 + 0.2, 7.0],
        grade_names: vec!["cu".into()],
        grades: vec![vec![1.0 / 3.0, f64::NAN, 0.0]],
        frag: Some(vec![0.2, f64::NAN, 1e-3]),
    };
    let dir = TempDir::new().unwrap();
    for name in ["r.csv", "r.parquet"] {
        let path = dir.path().join(name);
        write_records(&path, &r, &d).unwrap();
        let back = load_records(&path, &d, &p, &g).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(back.drawpoint, r.drawpoint);
        assert_eq!(
            back.period,
            [Some(1), Some(2), Some(2)],
            "{name}: dated row mapped"
        );
        assert_eq!(back.date, r.date);
        assert_eq!(back.tonnes, r.tonnes, "{name}: bit for bit");
        assert_eq!(back.grades[0][0].to_bits(), r.grades[0][0].to_bits());
        assert!(back.grades[0][1].is_nan());
        assert_eq!(back.frag.as_ref().unwrap()[2], 1e-3);
        assert!(Path::new(&path).exists());
    }
    // Parquet carries the units of the production schema.
    let f = fs::File::open(dir.path().join("r.parquet")).unwrap();
    let b = parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder::try_new(f).unwrap();
    let schema = b.schema();
    let unit = |c: &str| schema.field_with_name(c).unwrap().metadata()["unit"].clone();
    assert_eq!(
        (unit("tonnes"), unit("cu"), unit("frag_size")),
        ("t".into(), "%".into(), "m".into())
    );
}
