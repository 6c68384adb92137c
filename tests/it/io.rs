//! Integration tests: io (table readers, MassFlow formats) and model::load (validation).
//!
//! Good files live in `tests/data/io/`. Broken files are written at test time next to a
//! small, valid scene, one defect at a time, so that each test shows the defect it checks.

use std::fs;
use std::path::PathBuf;
use std::sync::Arc;

use arrow::array::{ArrayRef, Float32Array, Float64Array, Int32Array, Int64Array, StringArray};
use caveflow::io::{parse_period_header, read_schedule, read_table, Problems, ScheduleForm};
use caveflow::model::load::{load_scene, LoadedScene};
use caveflow::model::Scenario;
use caveflow::schema::{BLOCK_MODEL, DRAWBELLS, DRAWPOINTS, PERIODS, SCHEDULE};
use sha2::{Digest, Sha256};
use tempfile::TempDir;

use crate::fixtures::{
    expect, repo, write_parquet, BLOCKS, DRAWPOINTS_CSV, PERIODS_CSV, SCHEDULE_CSV,
};

pub(crate) fn data(rel: &str) -> PathBuf {
    repo("tests/data/io").join(rel)
}

pub(crate) fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * b.abs().max(1.0)
}

// ---------------------------------------------------------------------------------------
// The small valid scene of `fixtures`, edited one defect at a time.

/// The text of each input file of a test scene.
pub(crate) struct Files {
    pub(crate) blocks: String,
    pub(crate) drawpoints: String,
    pub(crate) drawbells: Option<String>,
    pub(crate) periods: Option<String>,
    pub(crate) schedule: String,
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
pub(crate) fn set(text: &mut String, row: usize, column: &str, value: &str) {
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
pub(crate) fn drop_column(text: &mut String, column: &str) {
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
pub(crate) fn load(files: Files) -> (TempDir, Result<LoadedScene, Problems>) {
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
pub(crate) fn problems(files: Files) -> Problems {
    match load(files).1 {
        Ok(_) => panic!("the scene loaded but should not have"),
        Err(p) => p,
    }
}

pub(crate) fn edited(edit: impl FnOnce(&mut Files)) -> Problems {
    let mut f = Files::default();
    edit(&mut f);
    problems(f)
}

/// Reads bytes written to a temp file as a block model.
pub(crate) fn read_bytes(name: &str, bytes: &[u8]) -> Result<caveflow::io::Table, Problems> {
    let dir = TempDir::new().unwrap();
    let p = dir.path().join(name);
    fs::write(&p, bytes).unwrap();
    read_table(&p, &BLOCK_MODEL)
}

// ---------------------------------------------------------------------------------------
// Good files.

/// The CSV text with one more column: `header` on the header line, `value` on data line
/// `row` (1-based), empty elsewhere.
pub(crate) fn with_column(csv: &str, header: &str, row: usize, value: &str) -> String {
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
