//! Integration tests: the VTK export for ParaView (`output::vtk`), read back with vtkio's own
//! parser (and, where `.ci/run` has made its venv, VTK's readers from Python).

use std::collections::{BTreeMap, HashMap};
use std::fs;
use std::path::Path;

use caveflow::engine::{ImzTable, RunOutput};
use caveflow::model::{Scenario, Scene};
use caveflow::output::charts::FreeSurface;
use caveflow::output::vtk::{write_vtk, SEGMENTS};
use quick_xml::events::Event;
use vtkio::model::{
    Attribute, Attributes, DataSet, IOBuffer, PolyDataPiece, RectilinearGridPiece, VertexNumbers,
};
use vtkio::Vtk;

use crate::fixtures::{
    bits, caveflow_in, cone_column, cone_scenario, entries, run, small_scene_in, tiny,
    SMALL_SCENE_INPUTS,
};

/// The entries of `vtk/` after an export, in name order.
const EXPORT: [&str; 9] = [
    "blocks.vtr",
    "drawpoints.vtp",
    "iez.vtp",
    "imz",
    "imz.pvd",
    "markers",
    "markers.pvd",
    "surface",
    "surface.pvd",
];

/// The documented fields of each file, in order (`output::vtk`'s tables).
const IMZ_FIELDS: [&str; 6] = ["drawpoint", "period", "disk", "z_base", "z_top", "radius"];
const IEZ_FIELDS: [&str; 5] = ["drawpoint", "period", "marker_id", "mass", "frag_size"];

fn marker_fields(grades: &[String]) -> Vec<String> {
    let mut v: Vec<String> = ["marker_id", "origin_z", "mass", "state", "lithology"]
        .map(String::from)
        .to_vec();
    v.extend(grades.iter().map(|g| format!("grade_{g}")));
    v.extend(["frag_size", "porosity", "drawpoint", "drawn_period"].map(String::from));
    v
}

fn block_fields(grades: &[String]) -> Vec<String> {
    let mut v: Vec<String> = ["block_id", "cave_period", "lithology", "density"]
        .map(String::from)
        .to_vec();
    v.extend(grades.iter().map(|g| format!("grade_{g}")));
    v
}

/// A file read back with vtkio's parser.
fn import(path: &Path) -> DataSet {
    Vtk::import(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .data
}

fn poly(path: &Path) -> PolyDataPiece {
    PolyDataPiece::try_from(import(path)).unwrap_or_else(|e| panic!("{}: {e:?}", path.display()))
}

/// Names of attributes, in file order.
fn names(attrs: &[Attribute]) -> Vec<String> {
    attrs.iter().map(|a| a.name().to_string()).collect()
}

/// The buffer of the attribute `name`.
fn array<'a>(attrs: &'a [Attribute], name: &str) -> &'a IOBuffer {
    match attrs.iter().find(|a| a.name() == name) {
        Some(Attribute::DataArray(d)) => &d.data,
        _ => panic!("no array {name} in {:?}", names(attrs)),
    }
}

fn f64s(attrs: &[Attribute], name: &str) -> Vec<f64> {
    array(attrs, name).cast_into::<f64>().unwrap()
}

fn i64s(attrs: &[Attribute], name: &str) -> Vec<i64> {
    array(attrs, name).cast_into::<i64>().unwrap()
}

/// Cells of a vertex list: (connectivity length, number of cells).
fn cells(v: &Option<VertexNumbers>) -> (usize, usize) {
    v.as_ref()
        .map_or((0, 0), |v| (v.num_verts(), v.num_cells()))
}

/// Every array of `attrs` holds `n` values.
fn all_of_length(attrs: &Attributes, point: usize, cell: usize, what: &str) {
    for (set, n) in [(&attrs.point, point), (&attrs.cell, cell)] {
        for a in set {
            if let Attribute::DataArray(d) = a {
                assert_eq!(
                    d.data.len(),
                    n,
                    "{what}: {} has {} values",
                    d.name,
                    d.data.len()
                );
            }
        }
    }
}

/// (timestep, file) of each `DataSet` of a `.pvd`, in file order.
fn collection(path: &Path) -> Vec<(i64, String)> {
    let text = fs::read_to_string(path).unwrap();
    let mut r = quick_xml::Reader::from_str(&text);
    let mut out = Vec::new();
    let mut root = None;
    loop {
        match r.read_event().unwrap() {
            Event::Eof => break,
            Event::Start(e) | Event::Empty(e) => {
                let attr = |k: &str| {
                    e.try_get_attribute(k)
                        .unwrap()
                        .map(|a| a.unescape_value().unwrap().into_owned())
                };
                match e.name().as_ref() {
                    b"VTKFile" => root = attr("type"),
                    b"DataSet" => out.push((
                        attr("timestep").unwrap().parse().unwrap(),
                        attr("file").unwrap(),
                    )),
                    _ => {}
                }
            }
            _ => {}
        }
    }
    assert_eq!(root.as_deref(), Some("Collection"), "{}", path.display());
    out
}

/// Rows of a period column grouped by period.
fn by_period(period: &[i64]) -> BTreeMap<i64, Vec<usize>> {
    let mut m: BTreeMap<i64, Vec<usize>> = BTreeMap::new();
    for (r, &p) in period.iter().enumerate() {
        m.entry(p).or_default().push(r);
    }
    m
}

/// A folder holding the small scene of the input tests and its `scenario.toml`.
fn small_scene_dir() -> tempfile::TempDir {
    let tmp = tempfile::tempdir().unwrap();
    small_scene_in(tmp.path());
    fs::write(tmp.path().join("scenario.toml"), SMALL_SCENE_INPUTS).unwrap();
    tmp
}

/// `caveflow run scenario.toml --out OUT EXTRA…` in `d`, which must succeed: `d/OUT`.
fn run_in(d: &Path, out: &str, extra: &[&str]) -> std::path::PathBuf {
    let mut args = vec!["run", "scenario.toml", "--out", out];
    args.extend(extra);
    let o = caveflow_in(&args, d);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    d.join(out)
}

/// The Parquet tables of two run directories are byte-identical.
fn same_tables(a: &Path, b: &Path, what: &str) {
    for table in ["extraction", "imz", "drawn", "air_gap", "surface"] {
        let x = fs::read(a.join(format!("{table}.parquet"))).unwrap();
        let y = fs::read(b.join(format!("{table}.parquet"))).unwrap();
        assert!(x == y, "{table}.parquet differs {what}");
    }
}

/// The tiny scene run with markers and the surface at every period.
fn tiny_run() -> (Scene, RunOutput) {
    let scene = tiny();
    let mut sc = Scenario::default();
    sc.outputs.marker_periods = vec![1, 2, 3];
    sc.outputs.surface_periods = vec![1, 2, 3];
    let out = run(&scene, &sc);
    (scene, out)
}

/// The wall pieces the export must write for the IMZ disks `rows` under `surface`, derived
/// from the tables by `output::vtk`'s documented rule: at the SEGMENTS rim points of a
/// disk (angles 2πk/SEGMENTS), those where the surface lies above the disk's base carry a
/// wall; all of them make one closed strip, none nothing, and each run of them (around the
/// rim) a strip with two points more, its ends. Per piece: (IMZ row, points, closed).
fn expected_walls(
    scene: &Scene,
    imz: &ImzTable,
    rows: &[usize],
    surface: &FreeSurface,
) -> Vec<(usize, usize, bool)> {
    let mut out = Vec::new();
    for &r in rows {
        let d = imz.drawpoint[r] as usize;
        let (cx, cy, radius) = (scene.drawpoints.x[d], scene.drawpoints.y[d], imz.radius[r]);
        let below: Vec<bool> = (0..SEGMENTS)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / SEGMENTS as f64;
                let (x, y) = (cx + radius * a.cos(), cy + radius * a.sin());
                surface.at(x, y).is_none_or(|s| s > imz.z_base[r])
            })
            .collect();
        if below.iter().all(|&b| b) {
            out.push((r, 2 * SEGMENTS, true));
            continue;
        }
        for k in 0..SEGMENTS {
            if below[k] && !below[(k + SEGMENTS - 1) % SEGMENTS] {
                let n = (0..SEGMENTS)
                    .take_while(|j| below[(k + j) % SEGMENTS])
                    .count();
                out.push((r, 2 * (n + 2), false));
            }
        }
    }
    out
}

/// Checks one exported IMZ file against the disks `rows` of `imz` at period `p` and the
/// surface of that period: the pieces and their points as [`expected_walls`] derives them,
/// the cell fields those of each piece's disk, every point on its disk's rim, bases at the
/// disk's base and tops no higher than its top or the surface. Returns the pieces and the
/// points written.
fn check_imz_file(
    path: &Path,
    scene: &Scene,
    imz: &ImzTable,
    p: i64,
    rows: &[usize],
    surface: &FreeSurface,
) -> (usize, usize) {
    let piece = poly(path);
    let walls = expected_walls(scene, imz, rows, surface);
    let n = walls.len();
    let points: usize = walls.iter().map(|w| w.1).sum();
    let connectivity: usize = walls.iter().map(|w| w.1 + if w.2 { 2 } else { 0 }).sum();
    assert_eq!(piece.num_strips(), n, "period {p}: a strip per wall piece");
    assert_eq!(piece.num_cells(), n);
    assert_eq!(piece.num_points(), points, "period {p}");
    assert_eq!(cells(&piece.strips).0, connectivity);
    assert_eq!(names(&piece.data.cell), IMZ_FIELDS);
    assert!(piece.data.point.is_empty());
    all_of_length(&piece.data, 0, n, "imz");
    let pick = |v: &[f64]| bits(&walls.iter().map(|w| v[w.0]).collect::<Vec<_>>());
    assert_eq!(bits(&f64s(&piece.data.cell, "radius")), pick(&imz.radius));
    assert_eq!(bits(&f64s(&piece.data.cell, "z_base")), pick(&imz.z_base));
    assert_eq!(bits(&f64s(&piece.data.cell, "z_top")), pick(&imz.z_top));
    assert_eq!(i64s(&piece.data.cell, "period"), vec![p; n]);
    let dp = i64s(&piece.data.cell, "drawpoint");
    let disk = i64s(&piece.data.cell, "disk");
    let xyz = piece.points.cast_into::<f64>().unwrap();
    let (conn, offsets) = piece.strips.clone().unwrap().into_xml();
    let mut first = 0;
    for (i, &(r, m, closed)) in walls.iter().enumerate() {
        assert_eq!(dp[i], imz.drawpoint[r] as i64);
        assert_eq!(disk[i], imz.disk[r]);
        let start = if i == 0 { 0 } else { offsets[i - 1] as usize };
        let mut want: Vec<u64> = (first..first + m as u64).collect();
        if closed {
            want.extend([first, first + 1]);
        }
        assert_eq!(
            conn[start..offsets[i] as usize],
            want,
            "period {p}, piece {i}"
        );
        let d = imz.drawpoint[r] as usize;
        for k in 0..m {
            let q = &xyz[3 * (first as usize + k)..][..3];
            let rho = (q[0] - scene.drawpoints.x[d]).hypot(q[1] - scene.drawpoints.y[d]);
            assert!((rho - imz.radius[r]).abs() < 1e-9, "piece {i}: {rho}");
            if k % 2 == 0 {
                assert_eq!(q[2], imz.z_base[r], "period {p}, piece {i}: base");
            } else {
                let s = surface.at(q[0], q[1]).unwrap_or(f64::INFINITY);
                assert!(q[2] > imz.z_base[r] && q[2] <= imz.z_top[r].min(s));
            }
        }
        first += m as u64;
    }
    (n, points)
}

#[test]
fn every_vtk_file_reads_back_with_the_runs_counts_and_the_documented_fields() {
    let (scene, out) = tiny_run();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("vtk");
    let files = write_vtk(&dir, &scene, &out, &[1, 2, 3]).unwrap();
    assert_eq!(entries(&dir), EXPORT, "and no temporary file left");
    for f in &files {
        assert!(f.is_file(), "{} listed but absent", f.display());
    }
    let grades = &scene.blocks.grade_names;
    assert_eq!(grades, &["elev"]);

    // IMZ: at the VTK periods (by default the sections' moments, here every period), a
    // strip per piece of each disk's wall below the period's surface.
    let imz = &out.imz;
    let periods = by_period(&imz.period);
    assert_eq!(periods.keys().copied().collect::<Vec<_>>(), [1, 2, 3]);
    assert_eq!(scene.vtk_periods(&Scenario::default().outputs), [1, 2, 3]);
    let pvd = collection(&dir.join("imz.pvd"));
    assert_eq!(
        pvd,
        periods
            .keys()
            .map(|p| (*p, format!("imz/imz_{p}.vtp")))
            .collect::<Vec<_>>()
    );
    for (p, rows) in &periods {
        let path = dir.join(format!("imz/imz_{p}.vtp"));
        let surface = FreeSurface::of(&out, *p);
        let (n, points) = check_imz_file(&path, &scene, imz, *p, rows, &surface);
        eprintln!(
            "imz period {p}: {} disks, {n} wall pieces, {points} points",
            rows.len()
        );
        assert!(n >= 2, "period {p}: {n} pieces");
    }

    // Markers: one point (and one vertex) per marker of each snapshot.
    assert_eq!(
        collection(&dir.join("markers.pvd")),
        [1, 2, 3]
            .map(|p| (p, format!("markers/markers_{p}.vtp")))
            .to_vec()
    );
    assert_eq!(out.snapshot_periods().len(), 3);
    let row_of: HashMap<i64, usize> = scene
        .blocks
        .id
        .iter()
        .enumerate()
        .map(|(b, &id)| (id, b))
        .collect();
    for s in &out.snapshot_tables() {
        let piece = poly(&dir.join(format!("markers/markers_{}.vtp", s.period)));
        let n = s.marker_id.len();
        eprintln!("markers period {}: {n} markers", s.period);
        assert!(n > 100, "period {}: {n} markers", s.period);
        assert_eq!(piece.num_points(), n);
        assert_eq!(piece.num_verts(), n);
        assert_eq!(piece.num_cells(), n);
        assert_eq!(names(&piece.data.point), marker_fields(grades));
        all_of_length(&piece.data, n, 0, "markers");
        assert_eq!(i64s(&piece.data.point, "marker_id"), s.marker_id);
        assert_eq!(
            bits(&f64s(&piece.data.point, "origin_z")),
            bits(&s.origin_z)
        );
        assert_eq!(
            bits(&f64s(&piece.data.point, "frag_size")),
            bits(&s.frag_size)
        );
        assert_eq!(
            i64s(&piece.data.point, "state"),
            s.state.iter().map(|&x| x as i64).collect::<Vec<_>>()
        );
        // The grade is the origin block's: here its elevation.
        let elev: Vec<f64> = s
            .block_id
            .iter()
            .map(|id| scene.blocks.grades[0][row_of[id]])
            .collect();
        assert_eq!(bits(&f64s(&piece.data.point, "grade_elev")), bits(&elev));
        assert_eq!(i64s(&piece.data.point, "lithology"), vec![0; n]);
        let xyz = piece.points.cast_into::<f64>().unwrap();
        let z: Vec<f64> = xyz.iter().skip(2).step_by(3).copied().collect();
        assert_eq!(bits(&z), bits(&s.z), "positions at the period's end");
    }

    // Free surface: a point per lattice column of each chosen period.
    let surface = by_period(&out.surface.period);
    assert_eq!(surface.keys().copied().collect::<Vec<_>>(), [1, 2, 3]);
    assert_eq!(collection(&dir.join("surface.pvd")).len(), 3);
    for (p, rows) in &surface {
        let piece = poly(&dir.join(format!("surface/surface_{p}.vtp")));
        eprintln!("surface period {p}: {} columns", rows.len());
        assert_eq!(piece.num_points(), rows.len());
        assert_eq!(piece.num_verts(), rows.len());
        assert_eq!(names(&piece.data.point), ["z"]);
        let z: Vec<f64> = rows.iter().map(|&r| out.surface.z[r]).collect();
        assert_eq!(bits(&f64s(&piece.data.point, "z")), bits(&z));
    }

    // IEZ: a point per drawn marker, at its origin.
    let d = out.drawn_table();
    let piece = poly(&dir.join("iez.vtp"));
    eprintln!("iez: {} drawn markers", d.marker_id.len());
    assert!(d.marker_id.len() > 10);
    assert_eq!(piece.num_points(), d.marker_id.len());
    assert_eq!(piece.num_verts(), d.marker_id.len());
    assert_eq!(names(&piece.data.point), IEZ_FIELDS);
    all_of_length(&piece.data, d.marker_id.len(), 0, "iez");
    assert_eq!(i64s(&piece.data.point, "period"), d.period);
    assert_eq!(
        i64s(&piece.data.point, "drawpoint"),
        d.drawpoint.iter().map(|&x| x as i64).collect::<Vec<_>>()
    );
    let xyz = piece.points.cast_into::<f64>().unwrap();
    let z: Vec<f64> = xyz.iter().skip(2).step_by(3).copied().collect();
    assert_eq!(bits(&z), bits(&d.origin_z));

    // Block model: a cell per grid cell (the box is full: a cell per block).
    let bm = &scene.blocks;
    let grid = RectilinearGridPiece::try_from(import(&dir.join("blocks.vtr"))).unwrap();
    let cells_n: usize = bm.dims.iter().product();
    eprintln!(
        "blocks: {:?} = {cells_n} cells, {} blocks",
        bm.dims,
        bm.len()
    );
    assert_eq!(cells_n, bm.len());
    assert_eq!(
        grid.extent.clone().into_dims(),
        bm.dims.map(|n| n as u32 + 1)
    );
    assert_eq!(grid.coords.x.len(), bm.dims[0] + 1);
    assert_eq!(grid.coords.z.len(), bm.dims[2] + 1);
    assert_eq!(names(&grid.data.cell), block_fields(grades));
    all_of_length(&grid.data, 0, cells_n, "blocks");
    let order: Vec<usize> = bm.index.iter().map(|&b| b as usize).collect();
    let pick_i = |v: &[i64]| order.iter().map(|&b| v[b]).collect::<Vec<_>>();
    let pick_f = |v: &[f64]| bits(&order.iter().map(|&b| v[b]).collect::<Vec<_>>());
    assert_eq!(i64s(&grid.data.cell, "block_id"), pick_i(&bm.id));
    assert_eq!(
        i64s(&grid.data.cell, "cave_period"),
        pick_i(&bm.cave_period)
    );
    assert_eq!(
        bits(&f64s(&grid.data.cell, "grade_elev")),
        pick_f(&bm.grades[0])
    );
    let z0 = grid.coords.z.cast_into::<f64>().unwrap();
    assert_eq!(z0[0], bm.origin[2]);
    assert!((z0[bm.dims[2]] - bm.z_max()).abs() < 1e-12);

    // Drawpoints.
    let piece = poly(&dir.join("drawpoints.vtp"));
    assert_eq!(piece.num_points(), 2);
    assert_eq!(names(&piece.data.point), ["drawpoint", "width"]);
    assert_eq!(i64s(&piece.data.point, "drawpoint"), [0, 1]);
}

/// A grid cell without a block: -1 in the integer fields, NaN in the others.
#[test]
fn grid_cells_without_a_block_are_marked() {
    let (mut scene, out) = tiny_run();
    // Drop the block in the top corner cell from the grid (the run is already made).
    let bm = &mut scene.blocks;
    let last = bm.index.len() - 1;
    bm.index[last] = caveflow::model::block_model::NO_BLOCK;
    let tmp = tempfile::tempdir().unwrap();
    write_vtk(tmp.path(), &scene, &out, &[3]).unwrap();
    let grid = RectilinearGridPiece::try_from(import(&tmp.path().join("blocks.vtr"))).unwrap();
    let id = i64s(&grid.data.cell, "block_id");
    let cave = i64s(&grid.data.cell, "cave_period");
    let lith = i64s(&grid.data.cell, "lithology");
    let density = f64s(&grid.data.cell, "density");
    let grade = f64s(&grid.data.cell, "grade_elev");
    assert_eq!((id[last], cave[last], lith[last]), (-1, -1, -1));
    assert!(density[last].is_nan() && grade[last].is_nan());
    assert_eq!(id.iter().filter(|&&i| i < 0).count(), 1);
    assert!(density[..last].iter().all(|d| d.is_finite()));
}

/// `run --vtk` and `outputs.vtk = true` write `vtk/`; without either there is none, and the
/// Parquet tables are byte-identical either way.
#[test]
fn the_cli_writes_vtk_only_when_asked_and_changes_no_table() {
    let tmp = small_scene_dir();
    let d = tmp.path();
    let go = |out: &str, extra: &[&str]| {
        let mut args = vec!["--set", "outputs.charts=false"];
        args.extend(extra);
        run_in(d, out, &args)
    };
    let off = go("off", &[]);
    let flag = go("flag", &["--vtk"]);
    let key = go("key", &["--set", "outputs.vtk=true"]);
    assert!(!off.join("vtk").exists(), "off by default");
    for on in [&flag, &key] {
        assert_eq!(entries(&on.join("vtk")), EXPORT);
        for (_, file) in collection(&on.join("vtk/imz.pvd")) {
            let piece = poly(&on.join("vtk").join(file));
            assert!(piece.num_strips() > 0);
        }
        same_tables(&off, on, "with vtk on");
    }
}

/// VTK's own readers (the `vtk` package from PyPI, what ParaView reads with) open every file
/// with the same counts and fields. Runs where `.ci/run` set `CAVEFLOW_PY` to its venv's
/// Python; skipped with a note elsewhere.
#[test]
fn vtks_own_readers_open_every_file() {
    let Some(python) = std::env::var_os("CAVEFLOW_PY") else {
        eprintln!("CAVEFLOW_PY not set (`.ci/run` sets it): VTK's Python readers not tried");
        return;
    };
    let (scene, out) = tiny_run();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("vtk");
    write_vtk(&dir, &scene, &out, &[1, 2, 3]).unwrap();
    // What the script must find: file → (points, cells, point fields, cell fields).
    let mut expect = serde_json::Map::new();
    let mut put = |file: String, p: usize, c: usize, pf: Vec<String>, cf: Vec<String>| {
        expect.insert(file, serde_json::json!([p, c, pf, cf]));
    };
    let grades = &scene.blocks.grade_names;
    for (p, rows) in by_period(&out.imz.period) {
        let walls = expected_walls(&scene, &out.imz, &rows, &FreeSurface::of(&out, p));
        put(
            format!("imz/imz_{p}.vtp"),
            walls.iter().map(|w| w.1).sum(),
            walls.len(),
            vec![],
            IMZ_FIELDS.map(String::from).to_vec(),
        );
    }
    for s in &out.snapshot_tables() {
        let n = s.marker_id.len();
        put(
            format!("markers/markers_{}.vtp", s.period),
            n,
            n,
            marker_fields(grades),
            vec![],
        );
    }
    for (p, rows) in by_period(&out.surface.period) {
        let n = rows.len();
        put(
            format!("surface/surface_{p}.vtp"),
            n,
            n,
            vec!["z".into()],
            vec![],
        );
    }
    let n = out.drawn_len();
    put(
        "iez.vtp".into(),
        n,
        n,
        IEZ_FIELDS.map(String::from).to_vec(),
        vec![],
    );
    let d = scene.blocks.dims;
    put(
        "blocks.vtr".into(),
        (d[0] + 1) * (d[1] + 1) * (d[2] + 1),
        d.iter().product(),
        vec![],
        block_fields(grades),
    );
    let spec = tmp.path().join("expect.json");
    fs::write(&spec, serde_json::to_string(&expect).unwrap()).unwrap();
    let script = crate::fixtures::repo("tests/data/vtk/read_back.py");
    let o = std::process::Command::new(python)
        .arg(script)
        .arg(&dir)
        .arg(&spec)
        .output()
        .unwrap();
    let said = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    eprintln!("{said}");
    assert!(o.status.success(), "VTK's readers: {said}");
    assert!(
        said.contains(&format!("{} files read", expect.len())),
        "{said}"
    );
}

/// A second export into the same directory leaves only the files its collections list.
#[test]
fn a_second_export_leaves_only_what_its_collections_list() {
    let (scene, mut out) = tiny_run();
    let tmp = tempfile::tempdir().unwrap();
    write_vtk(tmp.path(), &scene, &out, &[1, 2, 3]).unwrap();
    assert_eq!(
        entries(&tmp.path().join("markers")),
        ["markers_1.vtp", "markers_2.vtp", "markers_3.vtp"]
    );
    out.snapshots.drain(..2);
    write_vtk(tmp.path(), &scene, &out, &[3, 1, 3]).unwrap();
    assert_eq!(entries(&tmp.path().join("markers")), ["markers_3.vtp"]);
    assert_eq!(
        collection(&tmp.path().join("markers.pvd")),
        [(3, "markers/markers_3.vtp".to_string())]
    );
    assert_eq!(entries(&tmp.path().join("imz")), ["imz_1.vtp", "imz_3.vtp"]);
    assert_eq!(
        collection(&tmp.path().join("imz.pvd")),
        [1, 3].map(|p| (p, format!("imz/imz_{p}.vtp")))
    );
    assert_eq!(
        entries(&tmp.path().join("surface")),
        ["surface_1.vtp", "surface_3.vtp"]
    );
}

/// `outputs.vtk_periods` chooses the periods of the IMZ and surface series, and their
/// collections list them in period order; by default they are the sections' moments. The
/// markers stay at their snapshots.
#[test]
fn the_period_key_chooses_the_files_and_the_collections_list_them_in_order() {
    let tmp = small_scene_dir();
    let d = tmp.path();
    let go = |out: &str, extra: &[&str]| {
        let mut args = vec!["--vtk"];
        args.extend(extra);
        run_in(d, out, &args).join("vtk")
    };
    let series = |vtk: &Path, name: &str| {
        let listed = collection(&vtk.join(format!("{name}.pvd")));
        let files: Vec<String> = entries(&vtk.join(name));
        let mut from_pvd: Vec<String> = listed
            .iter()
            .map(|(_, f)| f.trim_start_matches(&format!("{name}/")).to_string())
            .collect();
        from_pvd.sort();
        assert_eq!(files, from_pvd, "{name}: the files are those listed");
        listed.into_iter().map(|(p, _)| p).collect::<Vec<i64>>()
    };
    // The small scene's two periods draw 200 t and 50 t: the quarter, half and three
    // quarters all fall in period 1, so its moments are [1, 2], as the charts' are.
    let default = go("default", &[]);
    let charts: Vec<String> = entries(&d.join("default/charts"))
        .into_iter()
        .filter(|f| f.starts_with("section_1"))
        .collect();
    assert_eq!(charts, ["section_1.png", "section_1_p1.png"]);
    assert_eq!(series(&default, "imz"), [1, 2]);
    assert_eq!(series(&default, "surface"), [1, 2]);
    assert_eq!(series(&default, "markers"), [2]);
    // Chosen out of order and repeated: written once each, listed in period order.
    let chosen = go("chosen", &["--set", "outputs.vtk_periods=[2, 1, 2]"]);
    assert_eq!(series(&chosen, "imz"), [1, 2]);
    assert_eq!(series(&chosen, "surface"), [1, 2]);
    let one = go("one", &["--set", "outputs.vtk_periods=[2]"]);
    assert_eq!(series(&one, "imz"), [2]);
    assert_eq!(series(&one, "surface"), [2]);
    assert_eq!(
        series(&one, "markers"),
        [2],
        "the markers follow marker_periods"
    );
    // Without the key, the export follows the sections' periods.
    let sections = go("sections", &["--set", "outputs.section_periods=[1]"]);
    assert_eq!(
        series(&sections, "imz"),
        [1],
        "the default follows the sections"
    );
    // The tables are the same whichever periods the export writes.
    same_tables(&d.join("default"), &d.join("one"), "with other VTK periods");
}

/// A VTK period the schedule lacks is refused by `run` and `validate`, naming the key and
/// the rule, and the run writes nothing.
#[test]
fn a_vtk_period_outside_the_schedule_is_refused_with_its_key_and_rule() {
    let tmp = small_scene_dir();
    let d = tmp.path();
    let want = "scenario: [unknown-period] outputs.vtk_periods: period 5 is not one of the schedule's periods (1–2)";
    for args in [
        &["run", "scenario.toml", "--out", "bad", "--vtk"][..],
        &["validate", "scenario.toml"][..],
    ] {
        let mut args = args.to_vec();
        args.extend(["--set", "outputs.vtk_periods=[1, 5]"]);
        let o = caveflow_in(&args, d);
        let err = String::from_utf8_lossy(&o.stderr);
        eprintln!("{args:?}: {err}");
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
        assert!(
            !err.contains("period 1 "),
            "{args:?}: only the bad period: {err}"
        );
    }
    assert!(!d.join("bad").exists(), "nothing written");
    // A period of the full schedule that `--keep-periods` drops is left out, not refused.
    let kept = ["--vtk", "--keep-periods", "1"];
    run_in(
        d,
        "kept",
        &[&kept[..], &["--set", "outputs.vtk_periods=[1, 2]"]].concat(),
    );
    assert_eq!(
        collection(&d.join("kept/vtk/imz.pvd")),
        [(1, "imz/imz_1.vtp".to_string())]
    );
}

/// On a column drawn through breakthrough, the exported IMZ stops at the free surface of
/// each period: no point of any wall lies above it, and the cut acted (disks dropped or
/// cut, points on the surface). The surfaces come from the engine's moment surfaces (the
/// VTK periods are not surface periods here), as a run with `--vtk` has them.
///
/// Tolerance: none. Each point is read back as the Float64 the writer computed, and the
/// surface under it through the same `FreeSurface::at` (on a lattice row the sections'
/// `surface_at`, a unit test of `output::charts`), so a point above the surface by any
/// amount is one the export failed to cut.
#[test]
fn exported_imz_walls_stop_at_the_free_surface_of_their_period() {
    // The surface-cone near-field column (`surface_cone`), drawn in 12 periods of 2.5 kg:
    // breakthrough at about 5 kg.
    let periods = 12;
    let scene = cone_column(1.2, 0.5, periods, 0.0025);
    let mut sc = cone_scenario(periods, 0.0125, 0.0005);
    sc.outputs.surface_periods = vec![];
    sc.outputs.vtk_periods = (1..=periods as i64).collect();
    let t0 = std::time::Instant::now();
    let out = run(&scene, &sc);
    eprintln!("run: {:.1} s", t0.elapsed().as_secs_f64());
    assert!(out.surface.period.iter().all(|&p| p == periods as i64));
    let tmp = tempfile::tempdir().unwrap();
    let vtk_periods = scene.vtk_periods(&sc.outputs);
    write_vtk(tmp.path(), &scene, &out, &vtk_periods).unwrap();
    let imz = &out.imz;
    let top = scene.blocks.z_max();
    let (mut through, mut dropped, mut on, mut total) = (0, 0, 0, 0);
    for (p, rows) in by_period(&imz.period) {
        let surface = FreeSurface::of(&out, p);
        let axis = surface.at(0.0, 0.0).expect("a surface every period");
        let path = tmp.path().join(format!("imz/imz_{p}.vtp"));
        check_imz_file(&path, &scene, imz, p, &rows, &surface);
        let piece = poly(&path);
        let xyz = piece.points.cast_into::<f64>().unwrap();
        for q in xyz.chunks(3) {
            let s = surface.at(q[0], q[1]).unwrap();
            assert!(
                q[2] <= s,
                "period {p}: IMZ point {q:?} above the surface {s}"
            );
            on += usize::from(q[2] == s);
            total += 1;
        }
        let reached = rows.iter().any(|&r| imz.z_top[r] > axis);
        let written: std::collections::HashSet<i64> =
            i64s(&piece.data.cell, "disk").into_iter().collect();
        let gone = rows.len() - written.len();
        eprintln!(
            "period {p}: surface at the axis {axis:.3} m (top {top:.3}), {} disks, {gone} above the surface, {} points",
            rows.len(),
            xyz.len() / 3
        );
        through += usize::from(reached);
        dropped += gone;
    }
    eprintln!("{through} periods through the surface, {dropped} disks dropped, {on} of {total} points on the surface");
    assert!(through >= 3, "the IMZ breaks through in {through} periods");
    assert!(dropped > 0 && on > 0, "the cut acted");
}
