//! Integration tests: the demo scenes (`model::demo`): deterministic for a seed, the small
//! panel and the mine-scale scene as they are documented, written as input tables that the
//! readers take back.

use arrow::datatypes::DataType;
use caveflow::model::demo::{self, DemoScale, BLOCK_HEIGHT, EXTRACTION_LEVEL_Z};
use caveflow::model::{Scenario, Scene};
use caveflow::output::inputs::write_scene;
use caveflow::schema::{self};

use crate::fixtures::{entries, read_parquet};
use crate::output::{assert_schema, f64_col, i64_col, spec_schema, str_col};

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
