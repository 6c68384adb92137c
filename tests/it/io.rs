//! Integration tests: io (table readers, MassFlow formats) and model::load (validation).
//!
//! Good files live in `tests/data/io/`. Broken files are written at test time next to a
//! small, valid scene, one defect at a time, so that each test shows the defect it checks.

use std::fs;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use arrow::array::{ArrayRef, Float32Array, Float64Array, Int32Array, Int64Array, StringArray};
use caveflow::io::{
    parse_period_header, read_schedule, read_table, Problems, ScheduleForm, KEEP_PER_RULE,
};
use caveflow::model::load::{load_scene, LoadedScene};
use caveflow::model::Scenario;
use caveflow::schema::{BLOCK_MODEL, DRAWBELLS, DRAWPOINTS, PERIODS, SCHEDULE};
use sha2::{Digest, Sha256};
use tempfile::TempDir;

use crate::fixtures::{
    expect, find, repo, write_parquet, BLOCKS, DRAWPOINTS_CSV, PERIODS_CSV, SCHEDULE_CSV,
};

fn data(rel: &str) -> PathBuf {
    repo("tests/data/io").join(rel)
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * b.abs().max(1.0)
}

// ---------------------------------------------------------------------------------------
// The small valid scene of `fixtures`, edited one defect at a time.

/// The text of each input file of a test scene.
struct Files {
    blocks: String,
    drawpoints: String,
    drawbells: Option<String>,
    periods: Option<String>,
    schedule: String,
}

impl Default for Files {
    fn default() -> Files {
        Files {
            blocks: BLOCKS.into(),
            drawpoints: DRAWPOINTS_CSV.into(),
            drawbells: None,
            periods: Some(PERIODS_CSV.into()),
            schedule: SCHEDULE_CSV.into(),
        }
    }
}

/// Sets the cell of data row `row` (1-based) and column `column` of comma-separated text.
fn set(text: &mut String, row: usize, column: &str, value: &str) {
    let mut lines: Vec<Vec<String>> = text
        .lines()
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect();
    let c = lines[0]
        .iter()
        .position(|h| h == column)
        .unwrap_or_else(|| panic!("no column {column}"));
    lines[row][c] = value.to_string();
    *text = lines.iter().map(|l| l.join(",") + "\n").collect();
}

/// Removes a column from comma-separated text.
fn drop_column(text: &mut String, column: &str) {
    let c = text
        .lines()
        .next()
        .unwrap()
        .split(',')
        .position(|h| h == column)
        .unwrap();
    *text = text
        .lines()
        .map(|l| {
            let mut f: Vec<&str> = l.split(',').collect();
            f.remove(c);
            f.join(",") + "\n"
        })
        .collect();
}

/// Writes the files into a temporary folder and loads them.
fn load(files: Files) -> (TempDir, Result<LoadedScene, Problems>) {
    let dir = TempDir::new().unwrap();
    let mut sc = Scenario::default();
    let write = |name: &str, text: &str| {
        let p = dir.path().join(name);
        fs::write(&p, text).unwrap();
        p
    };
    sc.inputs.blocks = write("blocks.csv", &files.blocks);
    sc.inputs.drawpoints = write("drawpoints.csv", &files.drawpoints);
    sc.inputs.schedule = write("schedule.csv", &files.schedule);
    sc.inputs.drawbells = files
        .drawbells
        .as_deref()
        .map(|t| write("drawbells.csv", t));
    sc.inputs.periods = files.periods.as_deref().map(|t| write("periods.csv", t));
    let r = load_scene(&sc);
    (dir, r)
}

/// Loads files that must fail, returning the problems.
fn problems(files: Files) -> Problems {
    match load(files).1 {
        Ok(_) => panic!("the scene loaded but should not have"),
        Err(p) => p,
    }
}

fn edited(edit: impl FnOnce(&mut Files)) -> Problems {
    let mut f = Files::default();
    edit(&mut f);
    problems(f)
}

/// Reads bytes written to a temp file as a block model.
fn read_bytes(name: &str, bytes: &[u8]) -> Result<caveflow::io::Table, Problems> {
    let dir = TempDir::new().unwrap();
    let p = dir.path().join(name);
    fs::write(&p, bytes).unwrap();
    read_table(&p, &BLOCK_MODEL)
}

// ---------------------------------------------------------------------------------------
// Good files.

/// The CSV text with one more column: `header` on the header line, `value` on data line
/// `row` (1-based), empty elsewhere.
fn with_column(csv: &str, header: &str, row: usize, value: &str) -> String {
    csv.lines()
        .enumerate()
        .map(|(i, l)| {
            let cell = if i == 0 {
                header
            } else if i == row {
                value
            } else {
                ""
            };
            format!("{l},{cell}\n")
        })
        .collect()
}

#[test]
fn valid_scene_loads() {
    let (dir, r) = load(Files::default());
    let l = r.unwrap_or_else(|p| panic!("{p}"));
    let s = &l.scene;
    assert_eq!(s.blocks.len(), 8);
    assert_eq!(s.blocks.size, [10.0, 10.0, 10.0]);
    assert_eq!(s.blocks.origin, [0.0, 0.0, 0.0]);
    assert_eq!(s.blocks.dims, [2, 2, 2]);
    assert_eq!(s.blocks.locate([12.0, 3.0, 19.0]), Some(5));
    assert_eq!(s.blocks.lithology_names, ["ore", "waste"]);
    assert_eq!(s.blocks.lithology[4], 1);
    assert_eq!(s.blocks.grade_names, ["cu"]);
    assert_eq!(s.blocks.grades[0][3], 1.3);
    assert_eq!(s.blocks.cave_period, vec![0; 8]);
    assert_eq!(s.blocks.perc_k1[0], 11.0);
    assert_eq!(s.blocks.perc_k2[0], 4.5);
    assert_eq!(s.blocks.perc_vmr[0], 0.5);
    assert!(
        s.blocks.tensile[0].is_nan(),
        "no tensile strength and no UCS: NaN"
    );
    assert!(s.blocks.frag_shape[0].is_nan());
    assert_eq!(s.blocks.frag[4], 0.5);
    assert_eq!(s.drawpoints.name, ["DP1", "DP2"]);
    assert_eq!(s.periods.id, [1, 2]);
    assert_eq!(s.periods.days, [31.0, 28.0]);
    assert_eq!(s.schedule.period(0), [100.0, 100.0]);
    assert_eq!(s.schedule.period(1), [50.0, 0.0]);
    assert!(l.warnings.is_empty(), "{:?}", l.warnings);
    let roles: Vec<&str> = l.inputs.iter().map(|i| i.role.as_str()).collect();
    assert_eq!(roles, ["blocks", "drawpoints", "periods", "schedule"]);
    let blocks = &l.inputs[0];
    assert_eq!(blocks.rows, 8);
    let sha: String = Sha256::digest(fs::read(dir.path().join("blocks.csv")).unwrap())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    assert_eq!(blocks.sha256, sha);
    assert_eq!(blocks.sha256.len(), 64);
}

#[test]
fn csv_comma_reads_typed_columns_and_grades() {
    let t = read_table(&data("blocks.csv"), &BLOCK_MODEL).unwrap();
    assert_eq!(t.file, "blocks.csv");
    assert_eq!(t.len(), 8);
    assert_eq!(t.f64("x").unwrap()[1], 15.0);
    assert_eq!(t.i64("block_id").unwrap()[7], Some(8));
    assert_eq!(t.i64("cave_period").unwrap()[4], Some(1));
    assert_eq!(t.str("lithology").unwrap()[2], "porphyry");
    assert_eq!(t.f64("ucs").unwrap()[0], 100000.0);
    assert!(t.f64("frag_shape").is_none(), "absent optional column");
    let grades: Vec<&str> = t.extra.iter().map(|g| g.name.as_str()).collect();
    assert_eq!(grades, ["cu", "mo"]);
    assert_eq!(t.extra[1].values[3], 0.17);
    assert!(t.warnings.is_empty());
}

#[test]
fn csv_tab_with_aliases_reads_the_same() {
    let a = read_table(&data("blocks.csv"), &BLOCK_MODEL).unwrap();
    let b = read_table(&data("blocks.tsv"), &BLOCK_MODEL).unwrap();
    for c in ["x", "y", "z", "solids_density", "porosity", "frag_size"] {
        assert_eq!(a.f64(c), b.f64(c), "{c}");
    }
    assert_eq!(b.header("x"), "Easting");
    assert_eq!(b.header("block_id"), "BlockID");
    assert_eq!(a.i64("block_id"), b.i64("block_id"));
    assert_eq!(a.extra, b.extra);
}

#[test]
fn csv_semicolon_is_detected() {
    let text = BLOCKS.replace(',', ";");
    let t = read_bytes("blocks.csv", text.as_bytes()).unwrap();
    assert_eq!(t.f64("porosity").unwrap()[4], 0.35);
}

#[test]
fn csv_bom_and_quoted_numbers_and_padding() {
    let mut text = String::from("\u{feff}");
    text.push_str(
        &BLOCKS.replacen("2.7,0.3", "\" 2.7 \",\"0.3\"", 1).replacen(
            "15,5,5,2",
            "  15 , 5 ,5,2",
            1,
        ),
    );
    let t = read_bytes("blocks.csv", text.as_bytes()).unwrap_or_else(|p| panic!("{p}"));
    assert_eq!(
        t.header("x"),
        "x",
        "the BOM is not part of the first header"
    );
    assert_eq!(t.f64("solids_density").unwrap()[0], 2.7);
    assert_eq!(t.f64("porosity").unwrap()[0], 0.3);
    assert_eq!(t.f64("x").unwrap()[1], 15.0);
}

#[test]
fn csv_blank_rows_are_skipped_but_counted() {
    let mut lines: Vec<&str> = BLOCKS.lines().collect();
    lines.insert(3, ",,,,,,,,,,");
    lines.insert(4, "");
    let text = lines.join("\n");
    let dir = TempDir::new().unwrap();
    fs::write(dir.path().join("blocks.csv"), text).unwrap();
    let t = read_table(&dir.path().join("blocks.csv"), &BLOCK_MODEL).unwrap();
    assert_eq!(t.len(), 8);
    assert_eq!(t.warnings.len(), 1, "{:?}", t.warnings);
    assert!(
        t.warnings[0].rule == "empty-rows" && t.warnings[0].message.contains("skipped 1 empty row"),
        "{:?}",
        t.warnings
    );
    // The csv reader drops the truly empty line; the ",,,," line is data row 3 and skipped,
    // so the third block is data row 4.
    assert_eq!(t.row(2), 4);
}

#[test]
fn parquet_reads_and_casts() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("blocks.parquet");
    let n = 8;
    let xs: Vec<f32> = vec![5.5, 15.5, 5.5, 15.5, 5.5, 15.5, 5.5, 15.5];
    let ys: Vec<f64> = vec![5.0, 5.0, 15.0, 15.0, 5.0, 5.0, 15.0, 15.0];
    let zs: Vec<i32> = vec![5, 5, 5, 5, 15, 15, 15, 15];
    let ids: Vec<f64> = (1..=n).map(|i| i as f64).collect();
    let frag: Vec<Option<f64>> = vec![
        Some(0.2),
        None,
        Some(0.2),
        Some(0.2),
        Some(0.5),
        Some(0.5),
        Some(0.5),
        Some(0.5),
    ];
    let shape: Vec<Option<f64>> = vec![None, Some(2.0), None, None, None, None, None, None];
    let scale: Vec<Option<f64>> = vec![None, Some(0.3), None, None, None, None, None, None];
    let cols: Vec<(&str, ArrayRef)> = vec![
        ("Easting", Arc::new(Float32Array::from(xs))),
        ("Northing", Arc::new(Float64Array::from(ys))),
        ("Elevation", Arc::new(Int32Array::from(zs))),
        ("BlockID", Arc::new(Float64Array::from(ids))),
        (
            "CavePeriod",
            Arc::new(Int64Array::from(vec![
                Some(0),
                None,
                Some(2),
                Some(0),
                Some(0),
                Some(0),
                Some(0),
                Some(0),
            ])),
        ),
        ("SolidsDen", Arc::new(Float64Array::from(vec![2.7; n]))),
        ("InSituPor", Arc::new(Float64Array::from(vec![0.3; n]))),
        ("MaxPor", Arc::new(Float64Array::from(vec![0.5; n]))),
        ("FricAng", Arc::new(Int64Array::from(vec![40; n]))),
        ("frag_size", Arc::new(Float64Array::from(frag))),
        ("PriFragA", Arc::new(Float64Array::from(shape))),
        ("PriFragB", Arc::new(Float64Array::from(scale))),
        (
            "Lith",
            Arc::new(StringArray::from(vec![
                "a", "b", "a", "a", "c", "c", "c", "c",
            ])),
        ),
        ("Mo", Arc::new(Float32Array::from(vec![0.1f32; n]))),
        ("Au", Arc::new(StringArray::from(vec!["1.5"; n]))),
    ];
    write_parquet(&path, cols);
    let t = read_table(&path, &BLOCK_MODEL).unwrap_or_else(|p| panic!("{p}"));
    assert_eq!(t.f64("x").unwrap()[1], 15.5, "Float32 to f64");
    assert_eq!(t.f64("z").unwrap()[4], 15.0, "Int32 to f64");
    assert_eq!(
        t.i64("block_id").unwrap()[2],
        Some(3),
        "integral Float64 to i64"
    );
    assert_eq!(
        t.i64("cave_period").unwrap()[1],
        None,
        "null in an optional column"
    );
    assert!(t.f64("frag_size").unwrap()[1].is_nan());
    assert_eq!(t.str("lithology").unwrap()[4], "c");
    assert_eq!(t.extra[0].name, "Mo");
    assert_eq!(
        t.extra[0].values[0], 0.1,
        "Float32 reads through its decimal form, not as 0.10000000149"
    );
    assert_eq!(
        t.extra[1].values[0], 1.5,
        "numeric text in a Utf8 grade column"
    );

    // And as a whole scene, with the Weibull mean filling the missing frag_size.
    let mut sc = Scenario::default();
    sc.inputs.blocks = path.clone();
    sc.inputs.drawpoints = dir.path().join("dp.csv");
    fs::write(&sc.inputs.drawpoints, "name,x,y,z\nA,5,5,0\n").unwrap();
    sc.inputs.schedule = dir.path().join("schedule.csv");
    fs::write(
        &sc.inputs.schedule,
        SCHEDULE_CSV.replace("DP2", "A").replace("DP1", "A"),
    )
    .unwrap();
    let l = load_scene(&sc).unwrap_or_else(|p| panic!("{p}"));
    assert!(
        close(l.scene.blocks.frag[1], 0.3 * 0.886_226_925_452_758),
        "{}",
        l.scene.blocks.frag[1]
    );
    assert_eq!(l.scene.blocks.size, [10.0, 10.0, 10.0]);
    assert_eq!(
        l.scene.blocks.cave_period[1], 0,
        "missing cave period defaults to 0"
    );
    assert_eq!(l.scene.blocks.lithology_names, ["a", "b", "c"]);
    assert_eq!(l.scene.drawpoints.width, [4.0], "scenario default width");
    assert!(
        l.warnings.iter().any(|w| w.rule == "no-opening-width"),
        "{:?}",
        l.warnings
    );
    assert!(
        l.warnings.iter().any(|w| w.rule == "one-day-periods"),
        "{:?}",
        l.warnings
    );
    assert_eq!(l.scene.periods.days, [1.0, 1.0]);
    assert_eq!(l.scene.schedule.period(0), [200.0]);
    assert_eq!(l.inputs[0].rows, 8);
}

#[test]
fn parquet_type_problems() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("periods.pq");
    write_parquet(
        &path,
        vec![
            (
                "period",
                Arc::new(Float64Array::from(vec![Some(1.0), Some(2.5), None])) as ArrayRef,
            ),
            (
                "days",
                Arc::new(Float64Array::from(vec![30.0, f64::INFINITY, 31.0])),
            ),
            (
                "name",
                Arc::new(arrow::array::BooleanArray::from(vec![true, false, true])),
            ),
        ],
    );
    let p = read_table(&path, &PERIODS).unwrap_err();
    expect(&p, "periods.pq", Some(2), Some("period"), "mistyped");
    expect(&p, "periods.pq", Some(3), Some("period"), "missing-value");
    expect(&p, "periods.pq", Some(2), Some("days"), "not-finite");
    assert_eq!(p.0.len(), 3, "a boolean name column is read as text:\n{p}");

    let bad = dir.path().join("bad.parquet");
    fs::write(&bad, b"PAR1 this is not parquet at all PAR1").unwrap();
    let p = read_table(&bad, &PERIODS).unwrap_err();
    expect(&p, "bad.parquet", None, None, "unreadable");
}

/// Parquet as other tools write it: pandas, pyarrow, DuckDB, R's arrow and Spark compress
/// with Snappy by default, some with gzip, polars and caveflow with zstd. Each reads the
/// same table (a build without a codec refused the file as unreadable).
#[test]
fn parquet_reads_every_usual_compression() {
    use parquet::arrow::ArrowWriter;
    use parquet::basic::{Compression, GzipLevel, ZstdLevel};
    use parquet::file::properties::WriterProperties;
    let dir = TempDir::new().unwrap();
    let batch = arrow::record_batch::RecordBatch::try_from_iter([
        (
            "period",
            Arc::new(Int64Array::from(vec![1, 2, 3])) as ArrayRef,
        ),
        ("days", Arc::new(Float64Array::from(vec![30.0, 31.0, 28.5]))),
    ])
    .unwrap();
    for (name, c) in [
        ("snappy", Compression::SNAPPY),
        ("gzip", Compression::GZIP(GzipLevel::default())),
        ("zstd", Compression::ZSTD(ZstdLevel::default())),
        ("none", Compression::UNCOMPRESSED),
    ] {
        let path = dir.path().join(format!("periods_{name}.parquet"));
        let props = WriterProperties::builder().set_compression(c).build();
        let mut w = ArrowWriter::try_new(
            fs::File::create(&path).unwrap(),
            batch.schema(),
            Some(props),
        )
        .unwrap();
        w.write(&batch).unwrap();
        w.close().unwrap();
        let t = read_table(&path, &PERIODS).unwrap_or_else(|p| panic!("{name}: {p}"));
        assert_eq!(t.f64("days").unwrap(), [30.0, 31.0, 28.5], "{name}");
    }
}

#[test]
fn massflow_block_model_with_weibull_and_grades() {
    let t = read_table(&data("massflow/blocks.csv"), &BLOCK_MODEL).unwrap();
    assert_eq!(t.header("porosity"), "InSituPor");
    let grades: Vec<&str> = t.extra.iter().map(|g| g.name.as_str()).collect();
    assert_eq!(
        grades,
        ["Mo", "Cu"],
        "every column that is not a field is a grade"
    );

    let l = massflow_scene(data("massflow/schedule_wide.csv"));
    let b = &l.scene.blocks;
    assert_eq!(b.len(), 4);
    assert_eq!(
        b.size,
        [15.0, 15.0, 15.0],
        "one elevation: z takes the horizontal size"
    );
    assert!(
        l.warnings
            .iter()
            .any(|w| w.rule == "block-size-fallback" && w.message.contains("share one z centre")),
        "{:?}",
        l.warnings
    );
    assert!(close(b.frag[0], 0.23), "shape 1: the mean is the scale");
    assert!(
        close(b.frag[2], 0.04 * 0.886_226_925_452_758),
        "{}",
        b.frag[2]
    );
    assert_eq!(b.frag_shape[2], 2.0);
    assert!(
        close(b.tensile[0], 5000.0 * 0.886_226_925_452_758),
        "Weibull mean tensile strength"
    );
    assert!(close(b.tensile[2], 9000.0), "0.1 x UCS");
    assert!(b.tensile[3].is_nan(), "no tensile strength, no UCS");
    assert_eq!(b.perc_k1[..], [10.0, 10.0, 11.0, 11.0]);
    assert_eq!(b.perc_k2[..], [4.0, 4.0, 4.5, 4.5]);
    assert_eq!(b.perc_vmr[..], [0.5; 4]);
    assert_eq!(b.cave_period[3], 2);
    assert_eq!(b.grade_names, ["Mo", "Cu"]);
    assert_eq!(b.grades[0][1], 0.28);
    assert_eq!(b.lithology_names, ["default"]);
}

fn massflow_scene(schedule: PathBuf) -> LoadedScene {
    let mut sc = Scenario::default();
    sc.inputs.blocks = data("massflow/blocks.csv");
    sc.inputs.drawpoints = data("massflow/drawpoints.csv");
    sc.inputs.drawbells = Some(data("massflow/drawbells.csv"));
    sc.inputs.schedule = schedule;
    load_scene(&sc).unwrap_or_else(|p| panic!("{p}"))
}

#[test]
fn massflow_drawpoints_take_widths_from_drawbells() {
    let t = read_table(&data("massflow/drawpoints.csv"), &DRAWPOINTS).unwrap();
    assert_eq!(t.str("drawbell").unwrap()[0], "DB1");
    assert_eq!(t.str("bell_type").unwrap()[2], "", "empty optional text");
    let bells = read_table(&data("massflow/drawbells.csv"), &DRAWBELLS).unwrap();
    assert_eq!(bells.f64("height").unwrap()[1], 4.5);

    let l = massflow_scene(data("massflow/schedule_wide.csv"));
    let d = &l.scene.drawpoints;
    assert_eq!(d.name, ["P01", "P02", "P03"]);
    // P01: DBID DB1 is no bell, its DBType Standard is; P02: type Wide; P03: DBID DB3.
    assert_eq!(d.width, [4.2, 5.0, 3.8]);
    assert_eq!(d.z[0], 7690.0);
    assert!(
        !l.warnings.iter().any(|w| w.rule == "no-opening-width"),
        "{:?}",
        l.warnings
    );
}

#[test]
fn wide_schedule_with_every_header_form() {
    let s = read_schedule(&data("massflow/schedule_wide.csv")).unwrap();
    assert_eq!(s.form, ScheduleForm::Wide);
    let p = s.periods.as_ref().unwrap();
    assert_eq!(p.id, [1, 2, 3, 4, 5, 6]);
    assert_eq!(
        p.name,
        ["30", "Sept-08", "Feb-08", "Feb-09", "Jan-2009", "Q1"]
    );
    // Integer header = days; September 30; February 2008 is a leap month; 2009 is not.
    assert_eq!(p.days, [30.0, 30.0, 29.0, 28.0, 31.0, 90.5]);
    assert_eq!(s.rows, 3);

    let l = massflow_scene(data("massflow/schedule_wide.csv"));
    let sch = &l.scene.schedule;
    assert_eq!(l.scene.periods.len(), 6);
    assert_eq!(sch.period(0), [100.0, 0.0, 20.0]);
    assert_eq!(
        sch.period(2),
        [0.0, 75.0, 0.0],
        "empty cells are zero tonnes"
    );
    assert_eq!(sch.period(5), [1000.0, 900.5, 5.0]);
    assert_eq!(sch.total(0), 1360.0);
    assert!(!l.warnings.iter().any(|w| w.rule == "one-day-periods"));
}

#[test]
fn wide_schedule_tab_delimited() {
    let s = read_schedule(&data("massflow/schedule_wide.tsv")).unwrap();
    let p = s.periods.as_ref().unwrap();
    assert_eq!(p.name, ["Sep-08", "Oct-08"]);
    assert_eq!(p.days, [30.0, 31.0]);
    assert_eq!(s.entries.len(), 4);
    assert_eq!(s.drawpoint_column, "DPName");
}

#[test]
fn period_headers() {
    assert_eq!(parse_period_header("31"), Ok(("31".into(), 31.0)));
    assert_eq!(parse_period_header("Sept-08"), Ok(("Sept-08".into(), 30.0)));
    assert_eq!(parse_period_header("sep-08"), Ok(("sep-08".into(), 30.0)));
    assert_eq!(
        parse_period_header("Feb-2000"),
        Ok(("Feb-2000".into(), 29.0)),
        "400-year leap"
    );
    assert_eq!(
        parse_period_header("Feb-1900"),
        Ok(("Feb-1900".into(), 28.0)),
        "century, not leap"
    );
    assert_eq!(
        parse_period_header("Feb-96"),
        Ok(("Feb-96".into(), 29.0)),
        "96 is 1996"
    );
    assert_eq!(
        parse_period_header("February 2012"),
        Ok(("February 2012".into(), 29.0))
    );
    assert_eq!(parse_period_header("Dec/10"), Ok(("Dec/10".into(), 31.0)));
    assert_eq!(parse_period_header("Q1%90.5"), Ok(("Q1".into(), 90.5)));
    assert_eq!(parse_period_header("Week 3%7"), Ok(("Week 3".into(), 7.0)));
    for bad in [
        "0", "Q1%0", "Q1%-3", "%30", "Se-08", "Foo-08", "Jan-123", "abc", "", "1.5",
    ] {
        assert!(parse_period_header(bad).is_err(), "{bad}");
    }
}

#[test]
fn long_schedule_reads_from_csv() {
    let s = read_schedule(&data("schedule.csv")).unwrap();
    assert_eq!(s.form, ScheduleForm::Long);
    assert!(s.periods.is_none());
    assert_eq!(s.entries.len(), 4);
    assert_eq!(s.entries[3].row, 4);
    let t = read_table(&data("schedule.csv"), &SCHEDULE).unwrap();
    assert_eq!(t.f64("tonnes").unwrap()[1], 120.0);
}

#[test]
fn fixture_scene_sums_repeated_rows_and_reads_zones() {
    let mut sc = Scenario::default();
    sc.inputs.blocks = data("blocks.csv");
    sc.inputs.drawpoints = data("drawpoints.csv");
    sc.inputs.periods = Some(data("periods.csv"));
    sc.inputs.schedule = data("schedule.csv");
    sc.flow.default_opening_width = 3.0;
    let l = load_scene(&sc).unwrap_or_else(|p| panic!("{p}"));
    assert_eq!(l.scene.schedule.period(1), [75.0, 0.0]);
    assert!(
        l.warnings.iter().any(|w| w.rule == "summed-rows"),
        "{:?}",
        l.warnings
    );
    assert_eq!(l.scene.drawpoints.width, [4.5, 3.0]);
    assert_eq!(l.scene.drawpoints.zone, ["north", "south"]);
    assert_eq!(l.scene.periods.name, ["Jan-09", "Feb-09"]);
    assert_eq!(l.scene.blocks.cave_period[4], 1);
    assert_eq!(l.scene.blocks.lithology_names, ["ore", "porphyry", "waste"]);
}

#[test]
fn unknown_columns_of_fixed_tables_are_ignored_with_a_warning() {
    let (_d, r) = load(Files {
        drawpoints: "name,x,y,z,width,comment\nDP1,5,5,0,4,hi\nDP2,15,15,0,4,\n".into(),
        ..Files::default()
    });
    let l = r.unwrap_or_else(|p| panic!("{p}"));
    assert!(
        l.warnings.iter().any(|w| w.rule == "unknown-column"
            && w.file == "drawpoints.csv"
            && w.message.contains("`comment`")),
        "{:?}",
        l.warnings
    );
}

// ---------------------------------------------------------------------------------------
// Bad input as tables of cases. A case is one defect (an edit of the small valid scene, or
// bytes read alone as a block model) and the problem it must give: file, row, column, rule
// and fragments of its message. A table checks every case and then names each one that
// failed, with why.

/// What a case reads.
enum Given {
    /// The small valid scene with one edit, loaded whole by `load_scene`.
    Scene(fn(&mut Files)),
    /// Bytes read alone as the block model `blocks.csv` by `read_table`.
    Blocks(fn() -> Vec<u8>),
}
use Given::{Blocks, Scene};

/// One defect and the problem it must give.
struct Case {
    what: &'static str,
    given: Given,
    file: &'static str,
    row: Option<usize>,
    column: Option<&'static str>,
    rule: &'static str,
    /// Fragments the problem's message holds.
    says: &'static [&'static str],
    /// The whole Display of the problem, where a case pins it.
    shown: Option<&'static str>,
    /// Rules that must not be reported as well.
    without: &'static [&'static str],
    /// The problem is the only one reported.
    alone: bool,
    /// The problem is the only one of its rule.
    once: bool,
}

/// A case: `what` the defect is, what is read, and the file, row, column, rule and message
/// fragments of the problem it must give.
fn case(
    what: &'static str,
    given: Given,
    file: &'static str,
    row: Option<usize>,
    column: Option<&'static str>,
    rule: &'static str,
    says: &'static [&'static str],
) -> Case {
    Case {
        what,
        given,
        file,
        row,
        column,
        rule,
        says,
        shown: None,
        without: &[],
        alone: false,
        once: false,
    }
}

impl Case {
    fn shown(self, shown: &'static str) -> Case {
        Case {
            shown: Some(shown),
            ..self
        }
    }

    fn without(self, without: &'static [&'static str]) -> Case {
        Case { without, ..self }
    }

    fn alone(self) -> Case {
        Case {
            alone: true,
            ..self
        }
    }

    fn once(self) -> Case {
        Case { once: true, ..self }
    }

    fn problems(&self) -> Result<Problems, String> {
        match self.given {
            Scene(edit) => {
                let mut f = Files::default();
                edit(&mut f);
                match load(f).1 {
                    Ok(_) => Err("the scene loaded but should not have".into()),
                    Err(p) => Ok(p),
                }
            }
            Blocks(bytes) => match read_bytes("blocks.csv", &bytes()) {
                Ok(_) => Err("the table was read but should not have been".into()),
                Err(p) => Ok(p),
            },
        }
    }

    fn check(&self) -> Result<(), String> {
        let ps = self.problems()?;
        let p = find(&ps, self.file, self.row, self.column, self.rule)?;
        if let Some(s) = self.says.iter().find(|s| !p.message.contains(**s)) {
            return Err(format!("the message does not say `{s}`: {p}"));
        }
        if let Some(shown) = self.shown {
            if p.to_string() != shown {
                return Err(format!("shown as\n  {p}\nnot as\n  {shown}"));
            }
        }
        if let Some(r) = self.without.iter().find(|r| ps.has(r)) {
            return Err(format!("a {r} problem as well:\n{ps}"));
        }
        if self.alone && ps.0.len() != 1 {
            let n = ps.0.len();
            return Err(format!("{n} problems, not this one alone:\n{ps}"));
        }
        let of_rule = ps.with_rule(self.rule).count();
        if self.once && of_rule != 1 {
            return Err(format!("{of_rule} {} problems, not one:\n{ps}", self.rule));
        }
        Ok(())
    }
}

/// Checks every case, then fails naming each case that failed and why.
fn check_all(cases: Vec<Case>) {
    let failed: Vec<String> = cases
        .iter()
        .filter_map(|c| match catch_unwind(AssertUnwindSafe(|| c.check())) {
            Ok(Ok(())) => None,
            Ok(Err(why)) => Some(format!("{}: {why}", c.what)),
            Err(_) => Some(format!("{}: panicked (its message is above)", c.what)),
        })
        .collect();
    assert!(
        failed.is_empty(),
        "{} of {} cases failed:\n\n{}",
        failed.len(),
        cases.len(),
        failed.join("\n\n")
    );
}

/// Malformed files: none may panic; each gives its named rule.
#[rustfmt::skip]
#[test]
fn reader_rules() {
    check_all(vec![
        case("a row with one field too many",
             Blocks(|| BLOCKS.replacen("15,5,5,2,2.7", "15,5,5,2,2.7,9", 1).into()),
             "blocks.csv", Some(2), None, "ragged-row", &["12 fields", "11"]),
        case("an alias of a header already there",
             Blocks(|| BLOCKS.replacen("x,y,z,block_id", "x,y,z,Easting", 1).into()),
             "blocks.csv", Some(0), Some("Easting"), "duplicate-header", &["`x`", "Easting"]),
        case("a grade twice, in another case", Blocks(|| GRADE_TWICE.into()),
             "blocks.csv", Some(0), Some("CU"), "duplicate-header", &["more than once"]),
        case("a Latin-1 byte in a cell", Blocks(latin1_in_a_cell),
             "blocks.csv", Some(5), Some("lithology"), "not-utf8", &[]),
        // No bytes, blank lines, a header only, a BOM only.
        case("no bytes", Blocks(Vec::new),
             "blocks.csv", None, None, "empty-table", &[]),
        case("blank lines", Blocks(|| b"\n\n".to_vec()),
             "blocks.csv", None, None, "empty-table", &[]),
        case("a header only", Blocks(|| b"x,y,z\n".to_vec()),
             "blocks.csv", None, None, "empty-table", &[]),
        case("a BOM only", Blocks(|| "\u{feff}".into()),
             "blocks.csv", None, None, "empty-table", &[]),
        case("drawpoints: a header only", Scene(|f| f.drawpoints = "name,x,y,z\n".into()),
             "drawpoints.csv", None, None, "empty-table", &[]),
        case("wide schedule: a header only", Scene(|f| f.schedule = "DPName,Jan-09\n".into()),
             "schedule.csv", None, None, "empty-table", &[]),
        case("schedule: no bytes", Scene(|f| f.schedule = String::new()),
             "schedule.csv", None, None, "empty-table", &[]),
    ]);
}

const GRADE_TWICE: &str = "\
x,y,z,block_id,solids_density,porosity,max_porosity,friction_angle,frag_size,cu,CU
5,5,5,1,2.7,0.3,0.45,38,0.2,1,1
";

fn latin1_in_a_cell() -> Vec<u8> {
    let mut bytes = BLOCKS.as_bytes().to_vec();
    let at = BLOCKS.find("waste").unwrap();
    bytes[at + 1] = 0xE1; // Latin-1 á
    bytes
}

#[test]
fn non_utf8_header() {
    let mut bytes = BLOCKS.as_bytes().to_vec();
    bytes[1] = 0xFF;
    bytes.insert(1, b'x');
    let p = read_bytes("blocks.csv", &bytes).unwrap_err();
    assert!(p.has("not-utf8"), "{p}");
    assert_eq!(p.0[0].row, Some(0));
}

#[rustfmt::skip]
#[test]
fn cell_rules() {
    check_all(vec![
        case("porosity NaN", Scene(|f| set(&mut f.blocks, 2, "porosity", "NaN")),
             "blocks.csv", Some(2), Some("porosity"), "not-finite", &[]),
        case("a grade inf", Scene(|f| set(&mut f.blocks, 3, "cu", "inf")),
             "blocks.csv", Some(3), Some("cu"), "not-finite", &[]),
        case("tonnes -Infinity", Scene(|f| set(&mut f.schedule, 1, "tonnes", "-Infinity")),
             "schedule.csv", Some(1), Some("tonnes"), "not-finite", &[]),
        case("no density", Scene(|f| set(&mut f.blocks, 4, "solids_density", "")),
             "blocks.csv", Some(4), Some("solids_density"), "missing-value", &["required"]),
        case("no grade", Scene(|f| set(&mut f.blocks, 5, "cu", "")),
             "blocks.csv", Some(5), Some("cu"), "missing-value", &[]),
        case("no lithology", Scene(|f| set(&mut f.blocks, 6, "lithology", "")),
             "blocks.csv", Some(6), Some("lithology"), "missing-value", &[]),
        case("no fragment size", Scene(|f| set(&mut f.blocks, 7, "frag_size", "")),
             "blocks.csv", Some(7), Some("frag_size"), "missing-value", &["frag_shape"]),
        case("wide schedule: no drawpoint name", Scene(|f| f.schedule = "DPName,Jan-09\n,5\n".into()),
             "schedule.csv", Some(1), Some("DPName"), "missing-value", &[]),
        case("a word for an angle", Scene(|f| set(&mut f.blocks, 1, "friction_angle", "steep")),
             "blocks.csv", Some(1), Some("friction_angle"), "mistyped", &["`steep`"]),
        case("a fraction for an id", Scene(|f| set(&mut f.blocks, 2, "block_id", "2.5")),
             "blocks.csv", Some(2), Some("block_id"), "mistyped", &[]),
        case("a decimal comma in a semicolon file",
             Blocks(|| BLOCKS.replace(',', ";").replacen("5;15;5;3;2.7;0.3", "5;15;5;3;2.7;0,3", 1).into()),
             "blocks.csv", Some(3), Some("porosity"), "mistyped", &["decimal point"]),
        // A non-numeric extra column of the block model is not a grade.
        case("text in an extra column", Scene(|f| f.blocks = with_column(&f.blocks, "comment", 3, "check me")),
             "blocks.csv", Some(3), Some("comment"), "mistyped", &["grade"]),
        case("wide schedule: a word for tonnes", Scene(|f| f.schedule = "DPName,Jan-09\nDP1,lots\n".into()),
             "schedule.csv", Some(1), Some("Jan-09"), "mistyped", &[]),
        // The message lists the accepted headers.
        case("no density column", Scene(|f| drop_column(&mut f.blocks, "solids_density")),
             "blocks.csv", None, Some("solids_density"), "missing-column", &["SolidsDen"]),
        case("no fragment size column", Scene(|f| drop_column(&mut f.blocks, "frag_size")),
             "blocks.csv", None, Some("frag_size"), "missing-column", &["PriFragA"]),
        case("no drawpoint z", Scene(|f| drop_column(&mut f.drawpoints, "z")),
             "drawpoints.csv", None, Some("z"), "missing-column", &[]),
        case("wide schedule: no period", Scene(|f| f.schedule = "DPName\nDP1\n".into()),
             "schedule.csv", Some(0), None, "missing-column", &[]),
    ]);
}

#[rustfmt::skip]
#[test]
fn block_model_rules() {
    check_all(vec![
        case("density in kg/m³", Scene(|f| set(&mut f.blocks, 1, "solids_density", "2700")),
             "blocks.csv", Some(1), Some("solids_density"), "units-kg-m3", &["divide by 1000"]),
        case("zero density", Scene(|f| set(&mut f.blocks, 2, "solids_density", "0")),
             "blocks.csv", Some(2), Some("solids_density"), "not-positive", &[]),
        case("porosity above 1", Scene(|f| set(&mut f.blocks, 3, "porosity", "1.3")),
             "blocks.csv", Some(3), Some("porosity"), "porosity-range", &[])
            .shown("blocks.csv: row 3, column porosity: [porosity-range] porosity 1.3 is outside [0, 1)"),
        case("porosity in percent", Scene(|f| set(&mut f.blocks, 4, "max_porosity", "45")),
             "blocks.csv", Some(4), Some("max_porosity"), "units-percent", &["percentage", "0.45"]),
        case("negative porosity", Scene(|f| set(&mut f.blocks, 5, "porosity", "-0.1")),
             "blocks.csv", Some(5), Some("porosity"), "porosity-range", &[]),
        case("n1 below n0", Scene(|f| set(&mut f.blocks, 6, "max_porosity", "0.2")),
             "blocks.csv", Some(6), Some("max_porosity"), "n1-below-n0", &["0.2", "0.35"]),
        case("friction 0°", Scene(|f| set(&mut f.blocks, 7, "friction_angle", "0")),
             "blocks.csv", Some(7), Some("friction_angle"), "friction-range", &["(0, 90)"]),
        case("friction 90°", Scene(|f| set(&mut f.blocks, 7, "friction_angle", "90")),
             "blocks.csv", Some(7), Some("friction_angle"), "friction-range", &["(0, 90)"]),
        case("friction -5°", Scene(|f| set(&mut f.blocks, 7, "friction_angle", "-5")),
             "blocks.csv", Some(7), Some("friction_angle"), "friction-range", &["(0, 90)"]),
        case("friction 120°", Scene(|f| set(&mut f.blocks, 7, "friction_angle", "120")),
             "blocks.csv", Some(7), Some("friction_angle"), "friction-range", &["(0, 90)"]),
        case("negative fragment size", Scene(|f| set(&mut f.blocks, 8, "frag_size", "-0.2")),
             "blocks.csv", Some(8), Some("frag_size"), "not-positive", &[]),
        case("a Weibull fragment size of no finite mean", Scene(weibull_of_no_finite_mean),
             "blocks.csv", Some(1), Some("PriFragA"), "not-finite", &["Weibull"]),
        case("a negative UCS", Scene(negative_ucs),
             "blocks.csv", Some(2), Some("UCS"), "not-positive", &[]),
        case("a negative percolation factor", Scene(|f| f.blocks = with_column(&f.blocks, "PercK2", 2, "-1")),
             "blocks.csv", Some(2), Some("PercK2"), "negative", &[]),
        case("a negative grade", Scene(|f| set(&mut f.blocks, 2, "cu", "-0.5")),
             "blocks.csv", Some(2), Some("cu"), "negative", &["grade cu"]),
        case("a block id twice", Scene(|f| set(&mut f.blocks, 5, "block_id", "2")),
             "blocks.csv", Some(5), Some("block_id"), "duplicate-id", &["row 2"]),
        // Centres at x = 5, 15 and 22: the smallest spacing is 7 m, and 15 is not on that grid.
        case("centres 7 m apart", Scene(|f| set(&mut f.blocks, 2, "x", "22")),
             "blocks.csv", None, Some("x"), "mixed-block-size", &["5 and 15", "7 m"]),
        case("a centre off the 7 m grid", Scene(|f| set(&mut f.blocks, 2, "x", "22")),
             "blocks.csv", Some(4), Some("x"), "off-grid", &["x=15"]),
        case("two blocks in one cell", Scene(|f| {
                 set(&mut f.blocks, 8, "x", "5");
                 set(&mut f.blocks, 8, "y", "15");
             }),
             "blocks.csv", Some(8), None, "duplicate-cell", &["row 7"]),
        case("one block: no size",
             Scene(|f| f.blocks = BLOCKS.lines().take(2).collect::<Vec<_>>().join("\n")),
             "blocks.csv", None, None, "block-size", &[]),
        case("a stray coordinate", Scene(|f| set(&mut f.blocks, 8, "x", "1e9")),
             "blocks.csv", None, Some("x"), "grid-too-large", &["stray coordinate"]),
        case("65 537 lithologies", Scene(too_many_lithologies),
             "blocks.csv", Some(65_537), Some("lithology"), "too-many-lithologies", &[]),
    ]);
}

/// Block 1 without `frag_size`, given instead a Weibull shape so small that the mean is not
/// finite.
fn weibull_of_no_finite_mean(f: &mut Files) {
    set(&mut f.blocks, 1, "frag_size", "");
    let with_shape = with_column(&f.blocks, "PriFragA", 1, "0.001");
    f.blocks = with_column(&with_shape, "PriFragB", 1, "0.2");
}

/// A `UCS` column, 1000 everywhere but -5 on row 2.
fn negative_ucs(f: &mut Files) {
    f.blocks = f
        .blocks
        .lines()
        .enumerate()
        .map(|(i, l)| match i {
            0 => format!("{l},UCS\n"),
            2 => format!("{l},-5\n"),
            _ => format!("{l},1000\n"),
        })
        .collect();
}

/// A 256 × 257 block model with a lithology of its own for every block.
fn too_many_lithologies(f: &mut Files) {
    let mut text = String::from(
        "x,y,z,block_id,solids_density,porosity,max_porosity,friction_angle,frag_size,lithology\n",
    );
    for i in 0..65_537 {
        text.push_str(&format!(
            "{},{},5,{i},2.7,0.3,0.45,38,0.2,L{i}\n",
            5 + 10 * (i % 256),
            5 + 10 * (i / 256)
        ));
    }
    f.blocks = text;
}

#[rustfmt::skip]
#[test]
fn drawpoint_and_drawbell_rules() {
    check_all(vec![
        case("a drawpoint name twice", Scene(|f| set(&mut f.drawpoints, 2, "name", "DP1")),
             "drawpoints.csv", Some(2), Some("name"), "duplicate-id", &["`DP1`", "row 1"]),
        case("a zero width", Scene(|f| set(&mut f.drawpoints, 1, "width", "0")),
             "drawpoints.csv", Some(1), Some("width"), "not-positive", &[]),
        case("beside the model", Scene(|f| set(&mut f.drawpoints, 2, "x", "25")),
             "drawpoints.csv", Some(2), Some("x"), "outside-model", &["`DP2`"]),
        case("below the model", Scene(|f| set(&mut f.drawpoints, 1, "z", "-10.5")),
             "drawpoints.csv", Some(1), Some("z"), "outside-model", &["one block height"]),
        case("above the model", Scene(|f| set(&mut f.drawpoints, 1, "z", "31")),
             "drawpoints.csv", Some(1), Some("z"), "outside-model", &[]),
        // DP2 moved to 1 m from DP1: two 4 m openings would intersect.
        case("openings that overlap", Scene(|f| {
                 set(&mut f.drawpoints, 2, "x", "6");
                 set(&mut f.drawpoints, 2, "y", "5");
             }),
             "drawpoints.csv", Some(2), Some("x"), "overlapping-openings", &[
                 "drawpoint `DP2` (4 m wide) overlaps drawpoint `DP1` (4 m wide) at row 1",
                 "1.000 m apart, less than the 4.000 m",
             ])
            .once(),
        case("a drawbell that is not there", Scene(|f| belled(f, "BellName,DDWidth\nB1,4\n")),
             "drawpoints.csv", Some(2), Some("DBID"), "unknown-drawbell", &["`B9`", "`T9`"]),
        case("a drawbell of zero width", Scene(|f| belled(f, "BellName,DDWidth\nB1,0\nB9,4\nB1,4\n")),
             "drawbells.csv", Some(1), Some("DDWidth"), "not-positive", &[]),
        case("a drawbell name twice", Scene(|f| belled(f, "BellName,DDWidth\nB1,0\nB9,4\nB1,4\n")),
             "drawbells.csv", Some(3), Some("BellName"), "duplicate-id", &[]),
        // A broken drawbells file is reported once, without knock-on join errors.
        case("drawbells without widths", Scene(|f| belled(f, "BellName\nB1\n")),
             "drawbells.csv", None, Some("width"), "missing-column", &[])
            .without(&["unknown-drawbell"]),
    ]);
}

/// Drawpoints as MassFlow writes them, DP1 in drawbell B1, DP2 in B9 of type T9, over the
/// drawbells table `bells`.
fn belled(f: &mut Files, bells: &str) {
    f.drawpoints = "DPName,X,Y,Z,DBID,DBType\nDP1,5,5,0,B1,\nDP2,15,15,0,B9,T9\n".into();
    f.drawbells = Some(bells.into());
}

/// Exactly one block below the grid is still inside, and openings that touch (4 m apart)
/// or stand on another level do not overlap.
#[test]
fn drawpoints_at_the_limits_load() {
    let mut f = Files::default();
    set(&mut f.drawpoints, 1, "z", "-10");
    let mut scenes = vec![f];
    for (x, z) in [("9", "0"), ("5", "10")] {
        let mut f = Files::default();
        set(&mut f.drawpoints, 2, "x", x);
        set(&mut f.drawpoints, 2, "y", "5");
        set(&mut f.drawpoints, 2, "z", z);
        scenes.push(f);
    }
    for f in scenes {
        let (_d, r) = load(f);
        r.unwrap_or_else(|p| panic!("{p}"));
    }
}

#[rustfmt::skip]
#[test]
fn period_and_schedule_rules() {
    check_all(vec![
        case("a zero-day period", Scene(|f| set(f.periods.as_mut().unwrap(), 2, "days", "0")),
             "periods.csv", Some(2), Some("days"), "not-positive", &[]),
        case("a period twice", Scene(|f| set(f.periods.as_mut().unwrap(), 2, "period", "1")),
             "periods.csv", Some(2), Some("period"), "duplicate-id", &[]),
        case("periods out of order", Scene(|f| f.periods = Some("period,days\n2,30\n1,30\n".into())),
             "periods.csv", Some(2), Some("period"), "period-order", &["strictly increase"]),
        case("negative tonnes", Scene(|f| set(&mut f.schedule, 2, "tonnes", "-5")),
             "schedule.csv", Some(2), Some("tonnes"), "negative", &[]),
        case("an unknown drawpoint", Scene(|f| set(&mut f.schedule, 3, "drawpoint", "DP7")),
             "schedule.csv", Some(3), Some("drawpoint"), "unknown-drawpoint", &["`DP7`"]),
        case("an unknown period", Scene(|f| set(&mut f.schedule, 1, "period", "3")),
             "schedule.csv", Some(1), Some("period"), "unknown-period", &[]),
        // Wide form: the row is named once even if many periods draw from it.
        case("wide: an unknown drawpoint", Scene(wide_schedule_with_defects),
             "schedule.csv", Some(2), Some("DPName"), "unknown-drawpoint", &[])
            .once(),
        case("wide: negative tonnes", Scene(wide_schedule_with_defects),
             "schedule.csv", Some(1), Some("Mar-09"), "negative", &[]),
        case("wide: a period past the table", Scene(wide_schedule_with_defects),
             "schedule.csv", Some(1), Some("Mar-09"), "unknown-period", &[]),
        // Periods are positional: names may repeat.
        case("wide: a header that is no period", Scene(|f| {
                 f.periods = None;
                 f.schedule = "DPName,Jan-09,Next month,Jan-09\nDP1,1,2,3\n".into();
             }),
             "schedule.csv", Some(0), Some("Next month"), "period-header", &["Sept-08", "Name%Days"])
            .without(&["duplicate-header"]),
    ]);
}

/// A wide schedule of three periods over a periods table of two, negative tonnes in the
/// third, and a drawpoint that is not there.
fn wide_schedule_with_defects(f: &mut Files) {
    f.schedule = "DPName,Jan-09,Feb-09,Mar-09\nDP1,1,2,-3\nDPX,1,2,3\n".into();
}

#[test]
fn wide_schedule_with_periods_table_uses_the_table() {
    let (_d, r) = load(Files {
        schedule: "DPName,Jan-09,Feb-09\nDP1,10,20\nDP2,30,\n".into(),
        ..Files::default()
    });
    let l = r.unwrap_or_else(|p| panic!("{p}"));
    assert_eq!(l.scene.schedule.period(0), [10.0, 30.0]);
    assert_eq!(l.scene.schedule.period(1), [20.0, 0.0]);
    assert!(
        l.warnings.iter().any(|w| w.rule == "periods-table-wins"),
        "{:?}",
        l.warnings
    );
}

/// Files exported in a hurry (issue 9): one case per rule, each asserting its message.
#[rustfmt::skip]
#[test]
fn hurried_export_rules() {
    check_all(vec![
        // Pipes, colons and spaces are not delimiters caveflow reads; the one-field header
        // says what the file seems to use, and nothing else is reported.
        case("pipes", Blocks(|| BLOCKS.replace(',', "|").into()),
             "blocks.csv", Some(0), None, "wrong-delimiter", &["`|`", "comma-, tab- or semicolon"])
            .alone(),
        case("colons", Blocks(|| BLOCKS.replace(',', ":").into()),
             "blocks.csv", Some(0), None, "wrong-delimiter", &["`:`", "comma-, tab- or semicolon"])
            .alone(),
        case("spaces", Blocks(|| BLOCKS.replace(',', "  ").into()),
             "blocks.csv", Some(0), None, "wrong-delimiter", &["spaces", "comma-, tab- or semicolon"])
            .alone(),
        case("a wide schedule in pipes", Scene(|f| f.schedule = "DPName|Jan-09\nDP1|5\n".into()),
             "schedule.csv", Some(0), None, "wrong-delimiter", &[]),
        // A comma header over tab-separated rows: each row is one field, and the message
        // says why.
        case("a comma header over tab rows",
             Scene(|f| f.drawpoints = "name,x,y,z,width\nDP1\t5\t5\t0\t4\n".into()),
             "drawpoints.csv", Some(1), None, "ragged-row", &[
                 "1 fields but the header has 5",
                 "separated by a tab, the header by a comma",
             ]),
        // One rule per cell: radians are not also out of range.
        case("friction in radians", Scene(|f| set(&mut f.blocks, 3, "friction_angle", "0.66")),
             "blocks.csv", Some(3), Some("friction_angle"), "units-radians", &["looks like radians", "37.8°"])
            .without(&["friction-range"]),
        case("fragment size in mm", Scene(|f| set(&mut f.blocks, 2, "frag_size", "230")),
             "blocks.csv", Some(2), Some("frag_size"), "units-mm", &["looks like mm", "(0.23 m)"]),
        case("opening width in mm", Scene(|f| set(&mut f.drawpoints, 2, "width", "4000")),
             "drawpoints.csv", Some(2), Some("width"), "units-mm", &["opening width 4000 m", "(4 m)"]),
        case("drawbell width in mm", Scene(drawbell_width_in_mm),
             "drawbells.csv", Some(1), Some("DDWidth"), "units-mm", &["drawbell width 3800 m"]),
        // The test scene holds 8 blocks of 1000 m³: about 14 000 t in situ.
        case("tonnes in kg", Scene(|f| set(&mut f.schedule, 2, "tonnes", "100000")),
             "schedule.csv", Some(2), Some("tonnes"), "tonnes-exceed-model", &[
                 "100000 t is more than the whole block model holds",
                 "kg for t",
             ]),
        // Wide form: the column is the period's.
        case("wide: tonnes in kg", Scene(|f| f.schedule = "DPName,Jan-09,Feb-09\nDP1,5,2e9\n".into()),
             "schedule.csv", Some(1), Some("Feb-09"), "tonnes-exceed-model", &[]),
        // Finite but absurd numbers reach a rule, never the engine.
        case("a huge density", Scene(|f| set(&mut f.blocks, 1, "solids_density", "1e300")),
             "blocks.csv", Some(1), Some("solids_density"), "units-kg-m3", &[]),
        case("a huge fragment size", Scene(|f| set(&mut f.blocks, 1, "frag_size", "1e300")),
             "blocks.csv", Some(1), Some("frag_size"), "units-mm", &[]),
        case("a huge coordinate", Scene(|f| set(&mut f.blocks, 8, "x", "1e300")),
             "blocks.csv", Some(8), Some("x"), "coordinate-range", &["x = 1e300 m is farther than 1e9 m"])
            .without(&["duplicate-cell"]),
        case("huge tonnes", Scene(|f| set(&mut f.schedule, 1, "tonnes", "1e300")),
             "schedule.csv", Some(1), Some("tonnes"), "tonnes-exceed-model", &[]),
        case("a grade beyond f64", Scene(|f| set(&mut f.blocks, 1, "cu", "1e309")),
             "blocks.csv", Some(1), Some("cu"), "not-finite", &["inf is not a finite number"]),
        case("a huge block id", Scene(|f| set(&mut f.blocks, 1, "block_id", "1e30")),
             "blocks.csv", Some(1), Some("block_id"), "mistyped", &["whole number"]),
    ]);
}

/// Both drawpoints in drawbell B1, whose width is given in mm.
fn drawbell_width_in_mm(f: &mut Files) {
    f.drawpoints = "DPName,X,Y,Z,DBID\nDP1,5,5,0,B1\nDP2,15,15,0,B1\n".into();
    f.drawbells = Some("BellName,DDWidth\nB1,3800\n".into());
}

// ---------------------------------------------------------------------------------------
// Bad input that takes more than one edit or one problem to show.

#[test]
fn missing_files_and_inputs() {
    let mut sc = Scenario::default();
    sc.inputs.blocks = PathBuf::from("/nonexistent/blocks.csv");
    let p = load_scene(&sc).unwrap_err();
    let pr = expect(&p, "blocks.csv", None, None, "unreadable");
    assert!(pr.message.contains("/nonexistent/blocks.csv"), "{pr}");
    expect(&p, "scenario", None, None, "no-input");
    assert!(
        p.0.iter().any(|x| x.message.contains("inputs.drawpoints")),
        "{p}"
    );
    assert!(
        p.0.iter().any(|x| x.message.contains("inputs.schedule")),
        "{p}"
    );
}

#[test]
fn mangled_inputs_never_panic() {
    // Every truncation and a sweep of byte substitutions of a valid file, through every
    // reader: each must return, Ok or Err, without panicking.
    let dir = TempDir::new().unwrap();
    let csv = dir.path().join("t.csv");
    let wide = fs::read(data("massflow/schedule_wide.csv")).unwrap();
    let sources = [BLOCKS.as_bytes().to_vec(), wide];
    let specs = [BLOCK_MODEL, DRAWPOINTS, DRAWBELLS, PERIODS, SCHEDULE];
    for src in &sources {
        for cut in 0..src.len() {
            fs::write(&csv, &src[..cut]).unwrap();
            for spec in &specs {
                let _ = read_table(&csv, spec);
            }
            let _ = read_schedule(&csv);
        }
        for (i, b) in [b'"', b',', b'\n', b'\t', 0xFF, b'%', b'-', b'9']
            .iter()
            .cycle()
            .take(src.len())
            .enumerate()
        {
            let mut m = src.clone();
            m[i] = *b;
            fs::write(&csv, &m).unwrap();
            let _ = read_table(&csv, &BLOCK_MODEL);
            let _ = read_schedule(&csv);
        }
    }
    // A parquet file cut short.
    let pq = dir.path().join("t.parquet");
    write_parquet(
        &pq,
        vec![(
            "x",
            Arc::new(Float64Array::from(vec![1.0, 2.0])) as ArrayRef,
        )],
    );
    let full = fs::read(&pq).unwrap();
    for cut in (0..full.len()).step_by(7) {
        fs::write(&pq, &full[..cut]).unwrap();
        assert!(read_table(&pq, &BLOCK_MODEL).is_err());
    }
}

#[test]
fn problems_are_capped_per_rule() {
    let p = edited(|f| {
        let mut lines: Vec<String> = Vec::new();
        lines.push(BLOCKS.lines().next().unwrap().into());
        for i in 0..30 {
            lines.push(format!(
                "{},5,5,{},2700,0.3,0.45,38,0.2,ore,1.0",
                5 + 10 * i,
                i + 1
            ));
        }
        f.blocks = lines.join("\n");
    });
    let kept: Vec<_> = p.with_rule("units-kg-m3").collect();
    assert_eq!(kept.len(), KEEP_PER_RULE + 1, "{p}");
    let last = kept[KEEP_PER_RULE];
    assert_eq!(last.row, None);
    assert!(last.message.contains("10 more rows"), "{last}");
}

#[test]
fn every_file_is_checked_in_one_pass() {
    let p = edited(|f| {
        set(&mut f.blocks, 1, "porosity", "1.5");
        set(&mut f.drawpoints, 1, "width", "-1");
        set(f.periods.as_mut().unwrap(), 1, "days", "-1");
        set(&mut f.schedule, 1, "tonnes", "-1");
    });
    for rule in ["porosity-range", "not-positive", "negative"] {
        assert!(p.has(rule), "{p}");
    }
    assert_eq!(p.0.len(), 4, "{p}");
    assert_eq!(p.to_string().lines().count(), 4);
}

#[test]
fn reader_and_model_problems_come_together() {
    // A cell the reader cannot type does not hide the model rules of the other cells, and
    // is not reported a second time by them.
    let p = edited(|f| {
        set(&mut f.blocks, 1, "friction_angle", "steep");
        set(&mut f.blocks, 2, "porosity", "45");
        set(&mut f.blocks, 3, "frag_size", "fine");
        set(&mut f.blocks, 4, "cu", "n/a");
        set(&mut f.drawpoints, 1, "x", "far");
        set(&mut f.drawpoints, 2, "x", "-50");
    });
    expect(
        &p,
        "blocks.csv",
        Some(1),
        Some("friction_angle"),
        "mistyped",
    );
    expect(&p, "blocks.csv", Some(2), Some("porosity"), "units-percent");
    expect(&p, "blocks.csv", Some(3), Some("frag_size"), "mistyped");
    expect(&p, "blocks.csv", Some(4), Some("cu"), "mistyped");
    expect(&p, "drawpoints.csv", Some(1), Some("x"), "mistyped");
    expect(&p, "drawpoints.csv", Some(2), Some("x"), "outside-model");
    assert!(!p.has("missing-value"), "{p}");
    assert!(!p.has("friction-range"), "{p}");
    assert_eq!(p.0.len(), 6, "{p}");
}

#[test]
fn parquet_text_where_numbers_belong() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("drawbells.parquet");
    write_parquet(
        &path,
        vec![
            (
                "BellName",
                Arc::new(StringArray::from(vec!["B1", "B2"])) as ArrayRef,
            ),
            (
                "DDWidth",
                Arc::new(StringArray::from(vec!["4.0", "wide"])) as ArrayRef,
            ),
        ],
    );
    let p = read_table(&path, &DRAWBELLS).unwrap_err();
    let pr = expect(
        &p,
        "drawbells.parquet",
        Some(2),
        Some("DDWidth"),
        "mistyped",
    );
    assert!(pr.message.contains("`wide`"), "{pr}");
    // A nested type cannot be read at all: one problem for the column, not one per row.
    let list =
        arrow::array::ListArray::from_iter_primitive::<arrow::datatypes::Int32Type, _, _>(vec![
            Some(vec![Some(1)]),
            Some(vec![Some(2), Some(3)]),
        ]);
    let path = dir.path().join("bells2.parquet");
    write_parquet(
        &path,
        vec![
            (
                "BellName",
                Arc::new(StringArray::from(vec!["B1", "B2"])) as ArrayRef,
            ),
            ("DDWidth", Arc::new(list) as ArrayRef),
        ],
    );
    let p = read_table(&path, &DRAWBELLS).unwrap_err();
    let pr = expect(&p, "bells2.parquet", None, Some("DDWidth"), "mistyped");
    assert!(pr.message.contains("Arrow type List"), "{pr}");
}

// ---------------------------------------------------------------------------------------
// The scenario file: every rule located by line and column.

fn scenario_err(text: &str, sets: &[&str]) -> caveflow::model::scenario::ScenarioError {
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    match Scenario::from_toml(text, "scenario.toml", &sets, Path::new("/base")) {
        Ok(_) => panic!("the scenario loaded but should not have"),
        Err(e) => e,
    }
}

/// Scenario text and `--set` values, the rule they break, how the error begins and what
/// else it says; every failing case is named.
#[test]
fn scenario_rules() {
    type ScenarioCase = (
        &'static str,
        &'static str,
        &'static [&'static str],
        &'static str,
        &'static str,
        &'static [&'static str],
    );
    let cases: [ScenarioCase; 6] = [
        (
            "a misspelt key",
            "seed = 1\n[resolution]\nlayer_thicknes = 3.8\n",
            &[],
            "unknown-key",
            "scenario.toml: line 3, column 1: [unknown-key] unknown field `layer_thicknes`",
            &["layer_thickness"],
        ),
        (
            "a number in quotes",
            "[flow]\nq = \"3.5\"\n",
            &[],
            "wrong-type",
            "scenario.toml: line 2, column 5: [wrong-type] invalid type: string \"3.5\", expected f64",
            &[],
        ),
        (
            "an unclosed table header",
            "[flow\nq = 3.5\n",
            &[],
            "toml-syntax",
            "scenario.toml: line 1, column 6: [toml-syntax]",
            &[],
        ),
        ("--set without a value", "", &["flow.q"], "bad-set", "", &["expected key=value"]),
        (
            "--set of an unknown key",
            "",
            &["flow.nope=1"],
            "unknown-key",
            "--set: [unknown-key] unknown field `nope`",
            &[],
        ),
        (
            "a negative layer thickness",
            "[resolution]\nlayer_thickness = -1\n",
            &[],
            "setting-range",
            "",
            &["resolution.layer_thickness must be a positive number, got -1"],
        ),
    ];
    let mut failed = Vec::new();
    for (name, text, sets, rule, begins, says) in cases {
        let e = scenario_err(text, sets);
        let shown = e.to_string();
        if e.rule() != rule {
            failed.push(format!("{name}: rule {}, not {rule}: {shown}", e.rule()));
        } else if !shown.starts_with(begins) {
            failed.push(format!("{name}: does not begin `{begins}`: {shown}"));
        } else if let Some(s) = says.iter().find(|s| !shown.contains(**s)) {
            failed.push(format!("{name}: does not say `{s}`: {shown}"));
        }
    }
    assert!(failed.is_empty(), "{}", failed.join("\n"));
}

#[test]
fn scenario_files_that_cannot_be_read() {
    let dir = TempDir::new().unwrap();
    let missing = dir.path().join("nope.toml");
    let e = Scenario::load(&missing, &[]).unwrap_err();
    assert_eq!(e.rule(), "unreadable");
    assert!(
        e.to_string()
            .contains("nope.toml: [unreadable] cannot read the scenario"),
        "{e}"
    );
    let latin1 = dir.path().join("latin1.toml");
    fs::write(&latin1, b"# caf\xe9\nseed = 1\n").unwrap();
    let e = Scenario::load(&latin1, &[]).unwrap_err();
    assert_eq!(e.rule(), "unreadable");
    assert!(e.to_string().contains("valid UTF-8"), "{e}");
}

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
/// The coverage-guided runs are in the README; this keeps a short version in the suite.
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
