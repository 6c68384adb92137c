//! 3D export for ParaView: VTK XML files and `.pvd` collections (`outputs.vtk`, `run --vtk`).
//!
//! With `outputs.vtk = true` (or `caveflow run --vtk`) a run also writes `<dir>/vtk/`:
//!
//! ```text
//! <dir>/vtk/imz.pvd              IMZ disks below the free surface, one file per VTK period
//! <dir>/vtk/imz/imz_<N>.vtp
//! <dir>/vtk/markers.pvd          marker states, one file per marker period (markers/period=N)
//! <dir>/vtk/markers/markers_<N>.vtp
//! <dir>/vtk/surface.pvd          the free surface, one file per VTK period
//! <dir>/vtk/surface/surface_<N>.vtp
//! <dir>/vtk/iez.vtp              the drawn markers' origins (the IEZ), every period in one file
//! <dir>/vtk/blocks.vtr           the block model on its regular grid
//! <dir>/vtk/drawpoints.vtp       the drawpoints
//! ```
//!
//! # Periods
//!
//! The IMZ and the surface are written at the **VTK periods**: `outputs.vtk_periods` where
//! given, else the moments of the sections through time (`outputs.section_periods`, by
//! default the first periods by whose end a quarter, a half and three quarters of the
//! scheduled tonnes are drawn, and the last period: `Scene::vtk_periods`). A separate key
//! rather than `section_periods` itself, so that ParaView can play many periods without
//! as many section charts; its default keeps the two views of a run at the same moments.
//! A period the schedule lacks is refused when the scene is loaded (`unknown-period`,
//! naming the key); under `--keep-periods` the periods beyond the kept ones are left out.
//! The markers are written at the periods of their snapshots (`outputs.marker_periods`,
//! the last by default), the only periods whose marker states a run keeps. To play the
//! whole draw, list every period in `outputs.vtk_periods`.
//!
//! Open a `.pvd` in ParaView and the time bar plays its periods in order: each file's
//! `timestep` is its period number (not days). The files are VTK XML (format version 1.0,
//! inline base64 binary, little endian, UInt64 headers, no compression) written by the
//! [`vtkio`] crate; the `.pvd` collections by quick-xml. Every coordinate is in metres in the
//! block model's own frame (the same as every other output), as Float64 so that mine
//! coordinates (Eastings of 10⁵–10⁶ m) keep millimetres.
//!
//! Points carry one vertex cell each (`Verts`), so ParaView draws them as they are; use the
//! "Point Gaussian" representation for round dots. Indices and codes:
//!
//! - `drawpoint`: the drawpoint's row in the drawpoints table, from 0, in input order (the
//!   order of `drawpoints.vtp`, whose `drawpoint` field is that row); -1 where there is none.
//! - `lithology`: the code of the lithology, from 0, in order of first appearance in the
//!   block model (`block_model` table); -1 where there is no block.
//! - `state`: 0 in situ, 1 moving, 2 drawn (`markers.state`).
//!
//! # Files and fields
//!
//! **`imz/imz_<N>.vtp`** (PolyData, one triangle strip per IMZ disk of `imz.parquet` at
//! period N: the disk's wall, a cylinder of the disk's radius from its base to its top,
//! drawn through [`SEGMENTS`] points of its rim around the drawpoint's axis, [`SEGMENTS`]
//! × 2 points). The wall is cut at the free surface of period N, as the sections cut the
//! IMZ outlines (`output::charts::below_surface`): above the surface a disk holds the air
//! that left the IMZ's top, not moving rock. At each rim point the wall rises from the
//! disk's base to its top or to the surface there, whichever is lower (the surface read by
//! `output::charts::FreeSurface::at`, which on a lattice row is the section's surface); a
//! disk whose base lies at or above the surface at every rim point is not written, and one
//! whose base the surface crosses is written as one strip per arc below the surface, each
//! ending where the surface meets the base (two points more per arc, and a cell per arc
//! with the disk's fields). No point lies above the surface; between rim points the wall's
//! top is straight, and may pass above a surface that dips between them. The ledges
//! between disks of different radii are not drawn. Cell data:
//!
//! | field | type | unit | what |
//! |---|---|---|---|
//! | `drawpoint` | Int32 | – | drawpoint row |
//! | `period` | Int64 | – | period number |
//! | `disk` | Int64 | – | disk index, 0 the lowest (`imz.disk`) |
//! | `z_base`, `z_top` | Float64 | m | the disk's base and top elevation |
//! | `radius` | Float64 | m | the disk's radius R_i |
//!
//! **`markers/markers_<N>.vtp`** (PolyData, one point per row of `markers/period=N`, at the
//! marker's position at the end of period N). Point data:
//!
//! | field | type | unit | what |
//! |---|---|---|---|
//! | `marker_id` | Int64 | – | marker id |
//! | `origin_z` | Float64 | m | elevation of its origin (its lattice site) |
//! | `mass` | Float64 | t | its mass |
//! | `state` | UInt8 | – | 0 in situ, 1 moving, 2 drawn |
//! | `lithology` | Int32 | – | lithology code of its origin block |
//! | `grade_<name>` | Float64 | % by mass | each block-model grade of its origin block |
//! | `frag_size` | Float64 | m | its fragment size |
//! | `porosity` | Float64 | – | its porosity |
//! | `drawpoint` | Int32 | – | drawpoint row that drew it, -1 if not drawn |
//! | `drawn_period` | Int64 | – | period it was drawn in, -1 if not drawn |
//!
//! **`surface/surface_<N>.vtp`** (PolyData, one point per lattice column with caved
//! material at period N: the top of the caved material, the rows of `surface.parquet` at N
//! where `outputs.surface_periods` holds N, else the surface the engine keeps for the
//! charts and this export, `RunOutput::moment_surface`). Point data: `z` (Float64, m, the
//! surface elevation, to colour by).
//!
//! **`iez.vtp`** (PolyData, one point per row of `drawn.parquet`, at the marker's origin: the
//! isolated extraction zones). Every period is in the one file: threshold on `period` to see
//! the IEZ at a moment. Point data: `drawpoint` (Int32), `period` (Int64, the period it was
//! drawn in), `marker_id` (Int64), `mass` (Float64, t), `frag_size` (Float64, m, when
//! drawn).
//!
//! **`blocks.vtr`** (RectilinearGrid: one cell per cell of the block grid, nx × ny × nz, x
//! fastest; the point coordinates are the block faces, m). Grid cells without a block hold
//! -1 in the integer fields and NaN in the others (threshold on `block_id` ≥ 0 to drop
//! them). Cell data: `block_id` (Int64), `cave_period` (Int64, the first period the block
//! flows in, 0 from the start), `lithology` (Int32), `density` (Float64, t/m³, solids),
//! `grade_<name>` (Float64, % by mass) per grade.
//!
//! **`drawpoints.vtp`** (PolyData, one point per drawpoint at its opening: x, y, z of the
//! drawpoints table). Point data: `drawpoint` (Int32, the row), `width` (Float64, m, the
//! opening width).
//!
//! **`<name>.pvd`** (ParaView collection): one `DataSet` per file, `timestep` the period
//! number, `file` relative to `vtk/`.
//!
//! # Why these formats
//!
//! ParaView, VisIt and the mine planning packages that read VTK all open XML VTK files and
//! `.pvd` collections. Polydata points are the lightest form of a marker cloud, and a
//! rectilinear grid keeps Float64 coordinates (image data holds only Float32 origins). The
//! writer is a maintained crate so the format is not ours to get wrong, and every file is
//! written atomically like every output (`output::parquet`).

use std::collections::{BTreeMap, BTreeSet, HashMap, HashSet};
use std::fs;
use std::path::{Path, PathBuf};

use quick_xml::events::{BytesDecl, Event};
use vtkio::model::{
    Attribute, Attributes, ByteOrder, Coordinates, DataSet, Extent, IOBuffer, PolyDataPiece,
    RectilinearGridPiece, Version, VertexNumbers, Vtk,
};

use super::charts::FreeSurface;
use super::parquet::{write_atomic, AtomicFile};
use super::OutputError;
use crate::engine::result::{DrawnTable, ImzTable, MarkerSnapshot, RunOutput, SurfaceTable};
use crate::model::block_model::{BlockModel, NO_BLOCK};
use crate::model::Scene;

/// Sides of the polygon that draws each IMZ disk's wall.
pub const SEGMENTS: usize = 24;

/// Writes the VTK files of a run into `dir` (usually `<run dir>/vtk`, created if needed) and
/// returns the files written, the collections after the files they list. The IMZ and
/// surface series hold `periods` (the VTK periods, `Scene::vtk_periods`), ascending, where
/// the run has them: the IMZ where `imz.parquet` holds the period, the surface where the
/// run kept it.
///
/// Each period's file is built and written before the next is built, so memory holds one
/// file's data at a time (a mine-scale IMZ series is hundreds of files). A series' files of
/// periods this run does not have (left by an earlier run into the same directory) are
/// removed, so that the directory holds what the collection lists.
pub fn write_vtk(
    dir: &Path,
    scene: &Scene,
    run: &RunOutput,
    periods: &[i64],
) -> Result<Vec<PathBuf>, OutputError> {
    mkdir(dir)?;
    let mut written = Vec::new();
    // Ascending, once each: the collections' order.
    let periods: BTreeSet<i64> = periods.iter().copied().collect();

    let mut disks = by_period(&run.imz.period);
    let imz = periods.iter().filter_map(|&p| {
        let rows = disks.remove(&p)?;
        Some((
            p,
            imz_data(scene, &run.imz, &rows, &FreeSurface::of(run, p)),
        ))
    });
    write_series(dir, "imz", imz, &mut written)?;

    let blocks = &scene.blocks;
    let row_of: HashMap<i64, usize> = blocks
        .id
        .iter()
        .enumerate()
        .map(|(b, &id)| (id, b))
        .collect();
    // One snapshot made whole at a time (the end one is read from the engine's markers).
    let markers = run.snapshot_periods().into_iter().filter_map(|p| {
        let s = run.snapshot(p)?;
        Some((p, marker_data(blocks, &row_of, &s)))
    });
    write_series(dir, "markers", markers, &mut written)?;

    let surface = periods.iter().filter_map(|&p| {
        let (t, rows) = FreeSurface::table(run, p);
        (!rows.is_empty()).then(|| (p, surface_data(t, &rows)))
    });
    write_series(dir, "surface", surface, &mut written)?;

    written.push(write_file(
        &dir.join("iez.vtp"),
        iez_data(&run.drawn_table()),
    )?);
    written.push(write_file(&dir.join("blocks.vtr"), block_data(blocks))?);
    written.push(write_file(
        &dir.join("drawpoints.vtp"),
        drawpoint_data(scene),
    )?);
    Ok(written)
}

/// Writes a time series: `<dir>/<name>/<name>_<period>.vtp` for each (period, data), built
/// one at a time as `files` yields them, then `<dir>/<name>.pvd` listing them; removes the
/// series' other `.vtp` files.
fn write_series(
    dir: &Path,
    name: &str,
    files: impl Iterator<Item = (i64, DataSet)>,
    written: &mut Vec<PathBuf>,
) -> Result<(), OutputError> {
    let sub = dir.join(name);
    mkdir(&sub)?;
    let mut entries = Vec::new();
    let mut names = HashSet::new();
    for (period, data) in files {
        let file = format!("{name}_{period}.vtp");
        written.push(write_file(&sub.join(&file), data)?);
        entries.push((period, format!("{name}/{file}")));
        names.insert(file);
    }
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| OutputError::Io { path, source }
    };
    for entry in fs::read_dir(&sub).map_err(io(&sub))? {
        let entry = entry.map_err(io(&sub))?;
        let file = entry.file_name().to_string_lossy().into_owned();
        if file.starts_with(&format!("{name}_")) && file.ends_with(".vtp") && !names.contains(&file)
        {
            fs::remove_file(entry.path()).map_err(io(&entry.path()))?;
        }
    }
    written.push(write_pvd(&dir.join(format!("{name}.pvd")), &entries)?);
    Ok(())
}

fn mkdir(dir: &Path) -> Result<(), OutputError> {
    fs::create_dir_all(dir).map_err(|source| OutputError::Io {
        path: dir.to_path_buf(),
        source,
    })
}

/// Rows of a table grouped by period, periods ascending, rows in table order.
fn by_period(period: &[i64]) -> BTreeMap<i64, Vec<usize>> {
    let mut groups: BTreeMap<i64, Vec<usize>> = BTreeMap::new();
    for (row, &p) in period.iter().enumerate() {
        groups.entry(p).or_default().push(row);
    }
    groups
}

/// Writes one VTK XML file atomically.
fn write_file(path: &Path, data: DataSet) -> Result<PathBuf, OutputError> {
    let vtk = Vtk {
        version: Version::new_xml(1, 0),
        byte_order: ByteOrder::LittleEndian,
        title: String::new(),
        file_path: None,
        data,
    };
    let mut file = AtomicFile::create(path)?;
    vtk.write_xml(&mut file).map_err(|e| OutputError::Encode {
        path: path.to_path_buf(),
        message: format!("cannot write VTK: {e}"),
    })?;
    file.commit()?;
    Ok(path.to_path_buf())
}

/// Writes a ParaView collection: one `DataSet` per (timestep, file relative to the
/// collection).
fn write_pvd(path: &Path, entries: &[(i64, String)]) -> Result<PathBuf, OutputError> {
    let mut w = quick_xml::Writer::new_with_indent(Vec::new(), b' ', 2);
    let xml = (|| -> Result<(), quick_xml::Error> {
        w.write_event(Event::Decl(BytesDecl::new("1.0", None, None)))?;
        w.create_element("VTKFile")
            .with_attributes([
                ("type", "Collection"),
                ("version", "0.1"),
                ("byte_order", "LittleEndian"),
            ])
            .write_inner_content(|w| {
                w.create_element("Collection").write_inner_content(|w| {
                    for (step, file) in entries {
                        let step = step.to_string();
                        w.create_element("DataSet")
                            .with_attributes([
                                ("timestep", step.as_str()),
                                ("group", ""),
                                ("part", "0"),
                                ("file", file.as_str()),
                            ])
                            .write_empty()?;
                    }
                    Ok::<(), quick_xml::Error>(())
                })?;
                Ok::<(), quick_xml::Error>(())
            })?;
        Ok(())
    })();
    xml.map_err(|e| OutputError::Encode {
        path: path.to_path_buf(),
        message: format!("cannot write the collection: {e}"),
    })?;
    let mut bytes = w.into_inner();
    bytes.push(b'\n');
    write_atomic(path, &bytes)?;
    Ok(path.to_path_buf())
}

/// A named one-component array.
fn field(name: &str, values: impl Into<IOBuffer>) -> Attribute {
    Attribute::generic(name, 1).with_data(values)
}

/// A drawpoint index as written: its row, or -1 (`u32::MAX` in the engine's tables).
fn drawpoint_code(d: u32) -> i32 {
    if d == u32::MAX {
        -1
    } else {
        d as i32
    }
}

/// One vertex cell per point, so ParaView draws the points as they are.
fn verts(n: usize) -> VertexNumbers {
    VertexNumbers::XML {
        connectivity: (0..n as u64).collect(),
        offsets: (1..=n as u64).collect(),
    }
}

/// Polydata of points with one vertex each and the given point data.
fn points(xyz: Vec<f64>, point: Vec<Attribute>) -> DataSet {
    let n = xyz.len() / 3;
    DataSet::inline(PolyDataPiece {
        points: xyz.into(),
        verts: Some(verts(n)),
        data: Attributes {
            point,
            cell: Vec::new(),
        },
        ..Default::default()
    })
}

/// Interleaves three coordinate columns, the rows `rows` of them.
fn interleave(x: &[f64], y: &[f64], z: &[f64], rows: impl Iterator<Item = usize>) -> Vec<f64> {
    rows.flat_map(|r| [x[r], y[r], z[r]]).collect()
}

/// The IMZ disks of the rows `rows` of the IMZ table below the free surface `surface` of
/// their period: a triangle strip per piece of a disk's wall ([`disk_wall`]).
fn imz_data(scene: &Scene, t: &ImzTable, rows: &[usize], surface: &FreeSurface) -> DataSet {
    let dps = &scene.drawpoints;
    let mut xyz = Vec::with_capacity(rows.len() * SEGMENTS * 6);
    let mut connectivity = Vec::with_capacity(rows.len() * (2 * SEGMENTS + 2));
    let mut offsets = Vec::with_capacity(rows.len());
    // The row of the IMZ table each cell draws.
    let mut cells = Vec::with_capacity(rows.len());
    for &r in rows {
        let d = t.drawpoint[r] as usize;
        let (z_base, z_top) = (t.z_base[r], t.z_top[r]);
        let disk = Disk {
            centre: (dps.x[d], dps.y[d]),
            radius: t.radius[r],
            z_base,
        };
        for (wall, closed) in disk_wall(&disk, surface) {
            let first = (xyz.len() / 3) as u64;
            for &(x, y, s) in &wall {
                xyz.extend_from_slice(&[x, y, z_base, x, y, z_top.min(s)]);
            }
            connectivity.extend(first..first + 2 * wall.len() as u64);
            if closed {
                // Close the wall: back to the first pair.
                connectivity.extend([first, first + 1]);
            }
            offsets.push(connectivity.len() as u64);
            cells.push(r);
        }
    }
    let pick_f = |v: &[f64]| cells.iter().map(|&r| v[r]).collect::<Vec<f64>>();
    let pick_i = |v: &[i64]| cells.iter().map(|&r| v[r]).collect::<Vec<i64>>();
    let cell = vec![
        field(
            "drawpoint",
            cells
                .iter()
                .map(|&r| drawpoint_code(t.drawpoint[r]))
                .collect::<IOBuffer>(),
        ),
        field("period", pick_i(&t.period)),
        field("disk", pick_i(&t.disk)),
        field("z_base", pick_f(&t.z_base)),
        field("z_top", pick_f(&t.z_top)),
        field("radius", pick_f(&t.radius)),
    ];
    DataSet::inline(PolyDataPiece {
        points: xyz.into(),
        strips: Some(VertexNumbers::XML {
            connectivity,
            offsets,
        }),
        data: Attributes {
            point: Vec::new(),
            cell,
        },
        ..Default::default()
    })
}

/// An IMZ disk as its wall needs it: axis (Easting, Northing), radius and base, m.
#[derive(Debug, Clone, Copy)]
struct Disk {
    /// The drawpoint's axis.
    centre: (f64, f64),
    /// R_i.
    radius: f64,
    /// The disk's base elevation.
    z_base: f64,
}

impl Disk {
    /// The point of the disk's rim at angle `a` (radians from the Easting axis).
    fn rim(&self, a: f64) -> (f64, f64) {
        (
            self.centre.0 + self.radius * a.cos(),
            self.centre.1 + self.radius * a.sin(),
        )
    }
}

/// A point of a disk's rim, (x, y), and the free surface's elevation there, m.
type RimPoint = (f64, f64, f64);

/// Halvings of the angle between a rim point below the surface and one above it that
/// place the wall's end where the surface meets the disk's base: 2π / SEGMENTS / 2⁴⁰ rad
/// is under a nanometre of rim on a 1 km disk.
const CROSSING_STEPS: usize = 40;

/// The parts of a disk's wall below the free surface `surface`, each with whether it is
/// the whole closed wall: per part, its rim points (x, y) in order of angle, each with the
/// surface's elevation there ([`FreeSurface::at`]; +∞ without a surface). The wall is
/// drawn at the [`SEGMENTS`] rim points at angles 2πk/SEGMENTS, from the disk's base up to
/// its top or the surface, whichever is lower. A rim point where the surface is at or
/// below the base has no wall: a run of such points cuts the wall into arcs, and each arc
/// ends where the surface meets the base, found by halving the angle to the point beyond
/// ([`CROSSING_STEPS`]) and kept on the side below the surface, so that no end rises
/// above it. A wall wholly below the surface is one closed strip, [`SEGMENTS`] points as
/// before the cut; one wholly above it is not drawn.
fn disk_wall(disk: &Disk, surface: &FreeSurface) -> Vec<(Vec<RimPoint>, bool)> {
    let angle = |k: f64| std::f64::consts::TAU * k / SEGMENTS as f64;
    let point = |a: f64| {
        let (x, y) = disk.rim(a);
        (x, y, surface.at(x, y).unwrap_or(f64::INFINITY))
    };
    let rim: Vec<RimPoint> = (0..SEGMENTS).map(|k| point(angle(k as f64))).collect();
    let below = |k: usize| rim[k].2 > disk.z_base;
    if (0..SEGMENTS).all(below) {
        return vec![(rim, true)];
    }
    // Where the surface meets the base between the rim angles `inside` (below the
    // surface) and `outside`.
    let crossing = |mut inside: f64, mut outside: f64| {
        for _ in 0..CROSSING_STEPS {
            let mid = 0.5 * (inside + outside);
            if point(mid).2 > disk.z_base {
                inside = mid;
            } else {
                outside = mid;
            }
        }
        point(inside)
    };
    let mut walls = Vec::new();
    for a in (0..SEGMENTS).filter(|&k| below(k) && !below((k + SEGMENTS - 1) % SEGMENTS)) {
        let mut wall = vec![crossing(angle(a as f64), angle(a as f64 - 1.0))];
        let mut k = a;
        while below(k % SEGMENTS) {
            wall.push(rim[k % SEGMENTS]);
            k += 1;
        }
        wall.push(crossing(angle((k - 1) as f64), angle(k as f64)));
        walls.push((wall, false));
    }
    walls
}

/// One marker snapshot at the markers' positions.
fn marker_data(bm: &BlockModel, row_of: &HashMap<i64, usize>, s: &MarkerSnapshot) -> DataSet {
    let n = s.marker_id.len();
    let block: Vec<Option<usize>> = s
        .block_id
        .iter()
        .map(|id| row_of.get(id).copied())
        .collect();
    let mut point = vec![
        field("marker_id", s.marker_id.clone()),
        field("origin_z", s.origin_z.clone()),
        field("mass", s.mass.clone()),
        field(
            "state",
            s.state.iter().map(|&st| st as u8).collect::<Vec<u8>>(),
        ),
        field(
            "lithology",
            block
                .iter()
                .map(|b| b.map_or(-1, |b| i32::from(bm.lithology[b])))
                .collect::<Vec<i32>>(),
        ),
    ];
    for (name, g) in bm.grade_names.iter().zip(&bm.grades) {
        point.push(field(
            &format!("grade_{name}"),
            block
                .iter()
                .map(|b| b.map_or(f64::NAN, |b| g[b]))
                .collect::<Vec<f64>>(),
        ));
    }
    point.extend([
        field("frag_size", s.frag_size.clone()),
        field("porosity", s.porosity.clone()),
        field(
            "drawpoint",
            s.drawpoint
                .iter()
                .map(|&d| drawpoint_code(d))
                .collect::<IOBuffer>(),
        ),
        field("drawn_period", s.drawn_period.clone()),
    ]);
    points(interleave(&s.x, &s.y, &s.z, 0..n), point)
}

/// The free surface at one period: the rows `rows` of the surface table.
fn surface_data(t: &SurfaceTable, rows: &[usize]) -> DataSet {
    let z: Vec<f64> = rows.iter().map(|&r| t.z[r]).collect();
    points(
        interleave(&t.x, &t.y, &t.z, rows.iter().copied()),
        vec![field("z", z)],
    )
}

/// The drawn markers at their origins.
fn iez_data(t: &DrawnTable) -> DataSet {
    let n = t.marker_id.len();
    points(
        interleave(&t.origin_x, &t.origin_y, &t.origin_z, 0..n),
        vec![
            field(
                "drawpoint",
                t.drawpoint
                    .iter()
                    .map(|&d| drawpoint_code(d))
                    .collect::<IOBuffer>(),
            ),
            field("period", t.period.clone()),
            field("marker_id", t.marker_id.clone()),
            field("mass", t.mass.clone()),
            field("frag_size", t.frag_size.clone()),
        ],
    )
}

/// The block model on its grid, a cell per grid cell.
fn block_data(bm: &BlockModel) -> DataSet {
    let axis = |a: usize| -> Vec<f64> {
        (0..=bm.dims[a])
            .map(|i| bm.origin[a] + bm.size[a] * i as f64)
            .collect()
    };
    let of = |b: u32| (b != NO_BLOCK).then_some(b as usize);
    let int = |v: &[i64]| -> Vec<i64> {
        bm.index
            .iter()
            .map(|&b| of(b).map_or(-1, |b| v[b]))
            .collect()
    };
    let float = |v: &[f64]| -> Vec<f64> {
        bm.index
            .iter()
            .map(|&b| of(b).map_or(f64::NAN, |b| v[b]))
            .collect()
    };
    let mut cell = vec![
        field("block_id", int(&bm.id)),
        field("cave_period", int(&bm.cave_period)),
        field(
            "lithology",
            bm.index
                .iter()
                .map(|&b| of(b).map_or(-1, |b| i32::from(bm.lithology[b])))
                .collect::<Vec<i32>>(),
        ),
        field("density", float(&bm.density)),
    ];
    for (name, g) in bm.grade_names.iter().zip(&bm.grades) {
        cell.push(field(&format!("grade_{name}"), float(g)));
    }
    let extent = Extent::Ranges(bm.dims.map(|n| 0..=n as i32));
    DataSet::inline(RectilinearGridPiece {
        extent,
        coords: Coordinates {
            x: axis(0).into(),
            y: axis(1).into(),
            z: axis(2).into(),
        },
        data: Attributes {
            point: Vec::new(),
            cell,
        },
    })
}

/// The drawpoints at their openings.
fn drawpoint_data(scene: &Scene) -> DataSet {
    let d = &scene.drawpoints;
    let n = d.len();
    points(
        interleave(&d.x, &d.y, &d.z, 0..n),
        vec![
            field("drawpoint", (0..n as i32).collect::<Vec<i32>>()),
            field("width", d.width.clone()),
        ],
    )
}
