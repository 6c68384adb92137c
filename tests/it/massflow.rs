//! Integration tests: MassFlow projects load as MassFlow reads them (issue 19). The scenes
//! are built from the MassFlow manual's own example rows, in comma form and in the tab form
//! of MassFlow's example projects (a `Delimiter: …;` line ahead of the header).

use std::fs;
use std::time::Instant;

use caveflow::engine::{resolution, stability, Engine};
use caveflow::io::{read_schedule, read_table, InputWarning, Problems};
use caveflow::model::load::{load_scene, LoadedScene};
use caveflow::model::Scenario;
use caveflow::schema::{BLOCK_MODEL, DRAWBELLS, DRAWPOINTS};
use tempfile::TempDir;

use crate::fixtures::expect;

/// The block model header: the DESIGN's MassFlow names, then one grade.
const BLOCK_HEADER: &str = "Easting,Northing,Elevation,CavePeriod,BlockID,SolidsDen,InSituPor,MaxPor,FricAng,PriFragA,PriFragB,TenStrA,TenStrB,UCS,PercK1,PercK2,PercVMR,Cu";
/// The manual's example block row (InSituPor 0: intact ground, caved from CavePeriod on).
const BLOCK_ROW: &str = "1405,-1598,225,1,1,2.6,0,0.2,42,0.86,0.45,2.3803,3803,60000,11,4.5,0.5,9";
const DRAWPOINTS_CSV: &str = "DPName,X,Y,Z,DBID,DBType\nDP1,1500.7,-1552.7,228.4,1,cone%1\n";
const DRAWBELLS_CSV: &str = "BellName,DDWidth,DDHeight,BellHeight,SideAngle,EndAngle,DFZDepth,DFZWidth,DFZHeight,SideHoleAngle,CrossCutSpacing,SublevelSpacing,Burden,RetreatAz\ncone%1,4.5,4.5,13,70,80,0,0,0,0,0,0,0,0\n";
const SCHEDULE_CSV: &str = "DPName,7,7,7,7\nDP1,2000,2000,2000,2000\n";

/// The manual's block row and, around it, 10 m blocks of the same ground reaching the
/// drawpoint: 11 × 6 × 4 blocks, the manual's row first (BlockID 1).
fn blocks_csv(header: &str, extra: impl Fn(usize) -> String) -> String {
    let mut text = format!("{header}\n");
    let rest = BLOCK_ROW.splitn(6, ',').nth(5).unwrap();
    let mut id = 0;
    for k in 0..4 {
        for j in 0..6 {
            for i in 0..11 {
                id += 1;
                let (x, y, z) = (1405 + 10 * i, -1598 + 10 * j, 225 + 10 * k);
                text.push_str(&format!("{x},{y},{z},1,{id},{rest}{}\n", extra(id)));
            }
        }
    }
    assert!(text.lines().nth(1).unwrap().starts_with(BLOCK_ROW));
    text
}

/// Comma-separated text as MassFlow's tab-delimited example projects write it.
fn tab_form(csv: &str) -> String {
    format!("Delimiter: r;\n{}", csv.replace(',', "\t"))
}

/// The input files of a scene.
struct Files {
    blocks: String,
    drawpoints: String,
    drawbells: String,
    schedule: String,
    ext: &'static str,
}

impl Files {
    fn manual() -> Files {
        Files {
            blocks: blocks_csv(BLOCK_HEADER, |_| String::new()),
            drawpoints: DRAWPOINTS_CSV.into(),
            drawbells: DRAWBELLS_CSV.into(),
            schedule: SCHEDULE_CSV.into(),
            ext: "csv",
        }
    }

    fn tab(self) -> Files {
        Files {
            blocks: tab_form(&self.blocks),
            drawpoints: tab_form(&self.drawpoints),
            drawbells: tab_form(&self.drawbells),
            schedule: tab_form(&self.schedule),
            ext: "txt",
        }
    }

    /// Writes the files into a temporary folder and loads them as `caveflow validate` does.
    fn load(&self) -> (TempDir, Scenario, Result<LoadedScene, Problems>) {
        let dir = TempDir::new().unwrap();
        let write = |name: &str, text: &str| {
            let p = dir.path().join(format!("{name}.{}", self.ext));
            fs::write(&p, text).unwrap();
            p
        };
        let mut sc = Scenario::default();
        sc.inputs.blocks = write("blocks", &self.blocks);
        sc.inputs.drawpoints = write("drawpoints", &self.drawpoints);
        sc.inputs.drawbells = Some(write("drawbells", &self.drawbells));
        sc.inputs.schedule = write("schedule", &self.schedule);
        let r = load_scene(&sc);
        (dir, sc, r)
    }

    fn problems(&self) -> Problems {
        match self.load().2 {
            Ok(_) => panic!("the scene loaded but should not have"),
            Err(p) => p,
        }
    }
}

/// Loads and validates (load_scene, then the stability assessment, as `caveflow validate`).
fn validated(files: &Files) -> (TempDir, Scenario, LoadedScene) {
    let (dir, sc, r) = files.load();
    let l = r.unwrap_or_else(|p| panic!("{p}"));
    stability::assess(&l.scene, &sc, &resolution::resolve(&l.scene, &sc))
        .unwrap_or_else(|e| panic!("refused: {e}"));
    (dir, sc, l)
}

fn has_warning(l: &LoadedScene, needle: &str) -> bool {
    l.warnings.iter().any(|w| w.to_string().contains(needle))
}

#[test]
fn manual_example_loads_and_validates_in_comma_and_tab_form() {
    for files in [Files::manual(), Files::manual().tab()] {
        let (_dir, _sc, l) = validated(&files);
        let s = &l.scene;
        let b = &s.blocks;
        assert_eq!(b.len(), 264);
        assert_eq!(b.size, [10.0, 10.0, 10.0]);
        assert_eq!(
            (b.x[0], b.y[0], b.z[0], b.id[0]),
            (1405.0, -1598.0, 225.0, 1)
        );
        assert_eq!(b.n0[0], 0.0, "InSituPor 0 (intact ground) is accepted");
        assert_eq!(b.n1[0], 0.2);
        assert_eq!(b.cave_period[0], 1);
        assert!(
            (b.frag[0] - 0.486).abs() < 2e-3,
            "Weibull mean {}",
            b.frag[0]
        );
        assert_eq!(b.grade_names, ["Cu"]);
        assert_eq!(b.grades[0][0], 9.0);
        assert_eq!(s.drawpoints.name, ["DP1"]);
        assert_eq!(s.drawpoints.width, [4.5], "DBType cone%1 joins BellName");
        assert_eq!(s.periods.id, [1, 2, 3, 4]);
        assert_eq!(s.periods.name, ["7", "7", "7", "7"]);
        assert_eq!(s.periods.days, [7.0; 4]);
        assert_eq!(s.schedule.period(3), [2000.0]);
        // The 14-column drawbell file: no warning per column, one line for the lot.
        assert!(
            !has_warning(&l, "not a drawbells column"),
            "{:?}",
            l.warnings
        );
        let unused: Vec<&InputWarning> = l
            .warnings
            .iter()
            .filter(|w| w.rule == "massflow-unused")
            .collect();
        assert_eq!(unused.len(), 1, "{:?}", l.warnings);
        assert!(
            unused[0].message.contains("BellHeight") && unused[0].message.contains("RetreatAz"),
            "{}",
            unused[0]
        );
        assert_eq!(l.warnings.len(), 1, "{:?}", l.warnings);
    }
}

#[test]
fn manual_example_runs() {
    let (_dir, sc, l) = validated(&Files::manual().tab());
    let started = Instant::now();
    let out = Engine::new(&l.scene, &sc).unwrap().run(&mut |_, _| {});
    let e = &out.extraction;
    assert_eq!(
        e.period,
        [1, 2, 3, 4],
        "one drawpoint, four periods by number"
    );
    assert_eq!(e.grades.len(), 1, "Cu is the only grade");
    assert!(e.tonnes.iter().sum::<f64>() > 0.0);
    let secs = started.elapsed().as_secs_f64();
    assert!(secs < 30.0, "the manual's scene took {secs} s");
}

#[test]
fn repeated_period_names_are_positional() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("schedule.csv");
    fs::write(&path, SCHEDULE_CSV).unwrap();
    let s = read_schedule(&path).unwrap_or_else(|p| panic!("{p}"));
    let p = s.periods.as_ref().unwrap();
    assert_eq!(p.id, [1, 2, 3, 4]);
    assert_eq!(p.name, ["7", "7", "7", "7"]);
    assert_eq!(p.days, [7.0; 4]);
    let cells: Vec<(i64, f64)> = s.entries.iter().map(|e| (e.period, e.tonnes)).collect();
    assert_eq!(cells, [(1, 2000.0), (2, 2000.0), (3, 2000.0), (4, 2000.0)]);

    // The periods table written from the scene keeps number and name, and reads back.
    let (dir, _sc, l) = validated(&Files::manual());
    let path = dir.path().join("periods_out.csv");
    caveflow::output::inputs::write_periods(&path, &l.scene.periods).unwrap();
    let text = fs::read_to_string(&path).unwrap();
    assert_eq!(
        text,
        "period,name,days\n1,7,7.0\n2,7,7.0\n3,7,7.0\n4,7,7.0\n"
    );
    let mut files = Files::manual();
    files.schedule = "period,drawpoint,tonnes\n1,DP1,10\n4,DP1,20\n".into();
    let (_d, mut sc, _) = files.load();
    sc.inputs.periods = Some(path);
    let l = load_scene(&sc).unwrap_or_else(|p| panic!("{p}"));
    assert_eq!(l.scene.periods.name, ["7", "7", "7", "7"]);
    assert_eq!(l.scene.schedule.period(3), [20.0]);
}

#[test]
fn delimiter_line_rule() {
    // The preamble is accepted in every delimited table, also ahead of a comma header.
    let mut files = Files::manual();
    files.drawpoints = format!("Delimiter: ,;\n{DRAWPOINTS_CSV}");
    validated(&files);

    for (bad, table) in [
        ("Delimiter r", "blocks"),
        ("Delimiter: r", "schedule"),
        ("delimiter r;", "drawbells"),
    ] {
        let mut files = Files::manual().tab();
        let text = match table {
            "blocks" => &mut files.blocks,
            "schedule" => &mut files.schedule,
            _ => &mut files.drawbells,
        };
        *text = text.replacen("Delimiter: r;", bad, 1);
        let p = files.problems();
        let pr = expect(&p, &format!("{table}.txt"), None, None, "delimiter-line");
        assert!(
            pr.message.contains(&format!("`{bad}`")) && pr.message.contains("Delimiter: <"),
            "{pr}"
        );
        assert_eq!(p.0.len(), 1, "the file is not read further:\n{p}");
    }
}

#[test]
fn drawpoints_with_unfamiliar_headers_are_read_by_position() {
    let mut files = Files::manual();
    files.drawpoints = "Name,East,North,Elev,Bell,Type\nDP1,1500.7,-1552.7,228.4,1,cone%1\n".into();
    let (_dir, _sc, l) = validated(&files);
    assert_eq!(l.scene.drawpoints.x, [1500.7]);
    assert_eq!(l.scene.drawpoints.width, [4.5], "Type read as DBType");
    assert!(
        has_warning(
            &l,
            "drawpoints.csv: [positional-columns] the headers `Name`, `East`, `North`, `Elev`, `Bell`, `Type` are not all MassFlow's; as MassFlow does, the 6 columns are read by position as DPName, X, Y, Z, DBID, DBType"
        ),
        "{:?}",
        l.warnings
    );

    // Headers that name the documented columns in another order are read by name.
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("drawpoints.csv");
    fs::write(&path, "name,x,y,z,width,comment\nDP1,1,2,3,4,hi\n").unwrap();
    let t = read_table(&path, &DRAWPOINTS).unwrap();
    assert_eq!(t.f64("width").unwrap(), [4.0]);
    assert!(t
        .warnings
        .iter()
        .any(|w| w.rule == "unknown-column" && w.message.contains("`comment`")));

    // A schedule row for a drawpoint the positional file does not have.
    files.schedule = "DPName,7,7,7,7\nDP1,2000,2000,2000,2000\nDP9,1,1,1,1\n".into();
    let p = files.problems();
    let pr = expect(
        &p,
        "schedule.csv",
        Some(2),
        Some("DPName"),
        "unknown-drawpoint",
    );
    assert!(
        pr.message.contains("`DP9` is not in the drawpoints table"),
        "{pr}"
    );
}

#[test]
fn drawbells_with_unfamiliar_headers_are_read_by_position() {
    let mut files = Files::manual().tab();
    let header: Vec<String> = (1..=14).map(|i| format!("c{i}")).collect();
    files.drawbells = format!(
        "Delimiter: r;\n{}\ncone%1\t4.5\t4.5\t13\t70\t80\t0\t0\t0\t0\t0\t0\t0\t0\n",
        header.join("\t")
    );
    let (dir, _sc, l) = validated(&files);
    assert_eq!(l.scene.drawpoints.width, [4.5]);
    assert!(
        has_warning(
            &l,
            "read by position as BellName, DDWidth, DDHeight, BellHeight"
        ),
        "{:?}",
        l.warnings
    );
    let t = read_table(&dir.path().join("drawbells.txt"), &DRAWBELLS).unwrap();
    assert_eq!(
        t.header("width"),
        "c2",
        "messages name the header as written"
    );
}

#[test]
fn massflow_computed_block_columns_are_not_grades() {
    let header = format!("{BLOCK_HEADER},MeanDia,MeanDiaDyn,CavePeriodDyn,SDDia,Pmin,Kexp");
    let mut files = Files::manual();
    // MeanDia agrees with the Weibull mean (0.4866 m); CavePeriodDyn moves block 2 to period 3.
    files.blocks = blocks_csv(&header, |id| {
        let dynamic = if id == 2 { 3 } else { 1 };
        format!(",0.49,0.3,{dynamic},0.1,0.01,2")
    });
    let (dir, sc, l) = validated(&files);
    let b = &l.scene.blocks;
    assert_eq!(b.grade_names, ["Cu"], "{:?}", l.warnings);
    assert_eq!(
        b.cave_period[..3],
        [1, 3, 1],
        "the dynamic cave period wins"
    );
    assert!(has_warning(
        &l,
        "blocks.csv: [cave-period-dyn] CavePeriodDyn differs from CavePeriod in 1 block(s); the dynamic cave period is used"
    ));
    assert!(
        has_warning(
            &l,
            "blocks.csv: [massflow-unused] MassFlow column(s) MeanDiaDyn, SDDia, Pmin, Kexp recognised but not used by caveflow (ignored)"
        ),
        "{:?}",
        l.warnings
    );
    assert!(!has_warning(&l, "MeanDia disagrees"), "{:?}", l.warnings);
    let out = Engine::new(&l.scene, &sc).unwrap().run(&mut |_, _| {});
    assert_eq!(out.extraction.grades.len(), 1, "one grade column: Cu");

    // Without the Weibull parameters, MeanDia is the mean fragment size.
    let t = read_table(&dir.path().join("blocks.csv"), &BLOCK_MODEL).unwrap();
    assert_eq!(t.header("frag_size"), "MeanDia");
    let mut files = Files::manual();
    files.blocks = blocks_csv(&header, |_| ",0.3,0.3,1,0.1,0.01,2.0".to_string())
        .replace(",0.86,0.45,", ",,,");
    let (_d, _sc, l) = validated(&files);
    assert_eq!(l.scene.blocks.frag[0], 0.3);
    assert!(l.scene.blocks.frag_shape[0].is_nan());
}

#[test]
fn mean_dia_disagreeing_with_weibull_warns() {
    let header = format!("{BLOCK_HEADER},MeanDia");
    let mut files = Files::manual();
    files.blocks = blocks_csv(&header, |id| {
        if id % 2 == 0 {
            ",0.7".into()
        } else {
            ",0.5".into()
        }
    });
    let (_dir, _sc, l) = validated(&files);
    let w: Vec<String> = l
        .warnings
        .iter()
        .filter(|w| w.rule == "frag-mean")
        .map(|w| w.to_string())
        .collect();
    assert_eq!(
        w,
        ["blocks.csv: [frag-mean] MeanDia disagrees with the Weibull mean of PriFragA/PriFragB by more than 10% in 132 block(s), the first at row 2 (0.7 m against 0.4861 m); the Weibull parameters are used"],
        "{:?}",
        l.warnings
    );
    assert!((l.scene.blocks.frag[1] - 0.486).abs() < 2e-3);
}
