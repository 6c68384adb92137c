//! Integration tests: the input rules. Bad input as tables of cases: each case is one
//! defect (an edit of the small valid scene of `fixtures`, or bytes read alone as a block
//! model) and the problem it must give, with file, row, column, rule and message.

use std::fs;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;
use std::sync::Arc;

use arrow::array::{ArrayRef, Float64Array, StringArray};
use caveflow::io::{read_schedule, read_table, Problems, KEEP_PER_RULE};
use caveflow::model::load::load_scene;
use caveflow::model::Scenario;
use caveflow::schema::{BLOCK_MODEL, DRAWBELLS, DRAWPOINTS, PERIODS, SCHEDULE};
use tempfile::TempDir;

use crate::fixtures::{expect, find, write_parquet, BLOCKS};

use crate::io::{data, drop_column, edited, load, read_bytes, set, with_column, Files};

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
