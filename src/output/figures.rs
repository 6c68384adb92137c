//! The charts of one run (DESIGN §5, "Report"): drawdown sections like the summary's Figs 13
//! and 16, and grade against cumulative tonnes like its Figs 31–32, built from a
//! [`RunOutput`] and drawn with [`charts`](super::charts).
//!
//! [`write_run_charts`] writes them all into `<dir>/charts/`:
//!
//! ```text
//! <dir>/charts/section_<k>.png   one per row of drawpoints (at most MAX_SECTIONS), k = 1, 2, …
//!                                in order of increasing Northing, at the end of the run
//! <dir>/charts/section_<k>_p<N>.png
//!                                the same at the end of period N, for each earlier moment
//!                                of the draw (outputs.section_periods; by default a quarter,
//!                                a half and three quarters of the scheduled tonnes)
//! <dir>/charts/grade_<grade>.png predicted grade of the first grade column against
//!                                cumulative tonnes, one panel per drawpoint
//!                                (grade_<grade>-<k>.png when the panels fill several pages)
//! <dir>/charts/trace.png         the trace points' paths (only with trace points;
//!                                output::trace::trace_section)
//! ```
//!
//! The pieces are public so that other commands can draw them on their own: [`run_sections`]
//! and [`drawdown_section`] build the [`Section`]s, [`grade_series`] builds the
//! [`GradeSeries`] (`reconcile` adds the sampled grades to them), and [`block_grade`] is the
//! uniform-drawdown grade of one slice of a block column.
//!
//! # Reading a section
//! A layer is an initially horizontal line of material: the markers that start on one lattice
//! level of the section's lattice row. Their current positions, joined in the order of their
//! origins (a material line, so a layer never folds back on itself unless the material did),
//! show the drawdown. Stagnant ground is never materialised by the
//! engine, so where a layer was never mobilised it is drawn flat at its in-situ elevation;
//! where its markers were drawn the layer is broken (the material has left the model).

use std::borrow::Cow;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

use super::charts::{
    fmt_mass, grade_tonnage_chart, iez_outline, imz_outline, section_chart, ChartError,
    GradeSeries, Section,
};
use super::dilution::dilution_entries;
use crate::engine::result::{MarkerSnapshot, MarkerState, RunOutput, SurfaceTable};
use crate::model::block_model::NO_BLOCK;
use crate::model::{BlockModel, Scene};

/// Rows of the drawn table and of a marker snapshot a section reads at a time (the engine's
/// end tables are read from its markers in chunks, `engine::marker_tables`).
const CHUNK: usize = 1 << 16;

/// Most drawdown sections [`write_run_charts`] draws; with more rows of drawpoints it keeps
/// the rows that drew the most tonnes.
pub const MAX_SECTIONS: usize = 4;

/// Aim for about this many initially horizontal layers over the model height (the summary's
/// Fig 13 shows 100 mm layers in a 3.3 m model: 33).
const TARGET_LAYERS: f64 = 30.0;

/// Write the charts of a run into `dir/charts/` (created if missing) and return the paths
/// written, sections first.
///
/// - **Drawdown sections** ([`run_sections`]): one vertical section along x through each row
///   of drawpoints at the end of each of `moments` (sections through time; the engine
///   writes the free surface at them, `Scene::moments`), with the deformed layers every
///   `layer_spacing` m (None: [`default_layer_spacing`]) where a marker snapshot was taken,
///   the IMZ and IEZ outlines of the row's drawpoints, the free surface, the air gap, the
///   uncaved ground and the drawpoints' names with the mass drawn by then.
/// - **Grade against cumulative tonnes** ([`grade_series`]) of the first grade column of the
///   block model, with the uniform-drawdown block grade dashed; nothing when the block model
///   has no grade column or no drawpoint drew anything.
///
/// A run with no drawpoints, no marker snapshot and nothing drawn still gets its (empty)
/// sections, so a user sees the model extent rather than nothing.
pub fn write_run_charts(
    dir: &Path,
    scene: &Scene,
    run: &RunOutput,
    layer_spacing: Option<f64>,
    moments: &[i64],
) -> Result<Vec<PathBuf>, ChartError> {
    let out = dir.join("charts");
    std::fs::create_dir_all(&out).map_err(|source| ChartError::Io {
        path: out.clone(),
        source,
    })?;
    let mut written = Vec::new();
    let period_name = |p: i64| {
        scene
            .periods
            .id
            .iter()
            .position(|&id| id == p)
            .map(|i| scene.periods.name[i].clone())
    };
    let last = moments.last().copied();
    for &period in moments {
        let when = match period_name(period) {
            Some(name) if name != period.to_string() => {
                format!("end of period {period} ({name})")
            }
            _ => format!("end of period {period}"),
        };
        for (k, (section, y)) in run_sections(scene, run, layer_spacing, period)
            .into_iter()
            .enumerate()
        {
            let title = format!("Drawdown at Northing {} m, {when}", fmt_coord(y));
            let path = if Some(period) == last {
                out.join(format!("section_{}.png", k + 1))
            } else {
                out.join(format!("section_{}_p{period}.png", k + 1))
            };
            section_chart(&path, &section, &title)?;
            written.push(path);
        }
    }
    if let Some(name) = scene.blocks.grade_names.first() {
        let series = grade_series(scene, run, 0);
        if !series.is_empty() {
            let path = out.join(format!("grade_{}.png", file_safe(name)));
            let title = format!("{name}: predicted grade against cumulative tonnes");
            written.extend(grade_tonnage_chart(
                &path,
                &series,
                &title,
                &format!("{name} (%)"),
            )?);
        }
    }
    if let Some(section) = super::trace::trace_section(scene, &run.trace) {
        let last = run.trace.period.iter().copied().max().unwrap_or(0);
        let title =
            format!("Trace points to the end of period {last} (Easting–elevation projection)");
        let path = out.join("trace.png");
        section_chart(&path, &section, &title)?;
        written.push(path);
    }
    written.extend(super::stress::write_stress_charts(
        &out,
        scene,
        &run.stress,
    )?);
    Ok(written)
}

/// Default spacing of the initially horizontal layers on a section, m: the neat number (1, 2
/// or 5 × 10^k) nearest to a thirtieth of the model height, and at least the marker spacing
/// (a layer is one lattice level, so finer layers would repeat levels).
///
/// A thirtieth gives the 0.1 m layers of the summary's Fig 13 for its 3.3 m physical model,
/// and 10 m layers in a 300 m column: close enough to follow the funnel, far enough apart to
/// stay distinct lines at 1:1 aspect.
pub fn default_layer_spacing(model_height: f64, marker_spacing: f64) -> f64 {
    let target = model_height / TARGET_LAYERS;
    let neat = if target.is_finite() && target > 0.0 {
        let e = target.log10().floor();
        let base = 10f64.powf(e);
        [1.0, 2.0, 5.0, 10.0]
            .into_iter()
            .map(|m| m * base)
            .min_by(|a, b| (a / target).ln().abs().total_cmp(&(b / target).ln().abs()))
            .unwrap_or(target)
    } else {
        1.0
    };
    if marker_spacing.is_finite() && marker_spacing > 0.0 {
        neat.max(marker_spacing)
    } else {
        neat
    }
}

/// Rows of drawpoints: drawpoints whose Northings lie within half a block (`bm.size[1] / 2`)
/// of the first (southernmost) drawpoint of their row, in order of increasing Northing; each
/// row lists its drawpoint indices in order of increasing Easting.
pub fn drawpoint_rows(scene: &Scene) -> Vec<Vec<usize>> {
    let dp = &scene.drawpoints;
    let tol = 0.5 * scene.blocks.size[1];
    let mut order: Vec<usize> = (0..dp.len()).filter(|&d| dp.y[d].is_finite()).collect();
    order.sort_by(|&a, &b| dp.y[a].total_cmp(&dp.y[b]).then(a.cmp(&b)));
    let mut rows: Vec<Vec<usize>> = Vec::new();
    for d in order {
        match rows.last_mut() {
            Some(row) if dp.y[d] - dp.y[row[0]] <= tol => row.push(d),
            _ => rows.push(vec![d]),
        }
    }
    for row in &mut rows {
        row.sort_by(|&a, &b| dp.x[a].total_cmp(&dp.x[b]).then(a.cmp(&b)));
    }
    rows
}

/// The drawdown sections of a run at the end of `period`, with the Northing of each
/// ([`drawdown_section`]).
///
/// One section per row of drawpoints ([`drawpoint_rows`]), through the mean Northing of the
/// row. With more than [`MAX_SECTIONS`] rows, only the rows with the most tonnes drawn over
/// the run are kept (the same rows at every moment), still in order of Northing.
pub fn run_sections(
    scene: &Scene,
    run: &RunOutput,
    layer_spacing: Option<f64>,
    period: i64,
) -> Vec<(Section, f64)> {
    let dp = &scene.drawpoints;
    let drawn = tonnes_by(run, dp.len(), i64::MAX);
    let mut rows = drawpoint_rows(scene);
    if rows.len() > MAX_SECTIONS {
        let tonnes = |row: &Vec<usize>| row.iter().map(|&d| drawn[d]).sum::<f64>();
        let mut ranked: Vec<usize> = (0..rows.len()).collect();
        ranked.sort_by(|&a, &b| {
            tonnes(&rows[b])
                .total_cmp(&tonnes(&rows[a]))
                .then(a.cmp(&b))
        });
        ranked.truncate(MAX_SECTIONS);
        ranked.sort_unstable();
        rows = ranked.into_iter().map(|i| rows[i].clone()).collect();
    }
    rows.iter()
        .map(|row| {
            let y = row.iter().map(|&d| dp.y[d]).sum::<f64>() / row.len() as f64;
            let section = drawdown_section(scene, run, row, y, layer_spacing, period);
            (section, y)
        })
        .collect()
}

/// One drawdown section along x (Easting) through the Northing `y`, for the drawpoints `row`,
/// at the end of `period`.
///
/// - **Layers.** From the marker snapshot of `period` ([`RunOutput::snapshot_chunks`]), if
///   there is one (`outputs.marker_periods`; the last period by default). The section is
///   the lattice row of markers nearest to `y` (its origins lie within half a marker spacing
///   of `y`; when `y` falls exactly between two rows the southern one is used). Layers are
///   the lattice levels nearest to the model base + (k − ½) × `layer_spacing` (k = 1, 2, …
///   up to the model top, so each is the middle of a band `layer_spacing` thick; None:
///   [`default_layer_spacing`]).
///   Each layer is a polyline along the lattice columns in order of origin Easting: a moving
///   marker at its current (x, z), a column never mobilised at its in-situ (x, z), and a
///   drawn marker as a break. Runs of in-situ columns are reduced to their two ends.
/// - **Free surface** of `period` (`run.surface`, or `run.moment_surface`) along the
///   lattice row nearest the section, the ground still **uncaved** at the end of `period`,
///   and the **air gap** of `period` (`run.air_gap`): per block column on the section, the
///   air from the top of its highest caved stretch down by the gap.
/// - **IMZ outlines.** The disks of `period` in `run.imz` of each drawpoint of `row`,
///   through [`imz_outline`] about the drawpoint's Easting, cut at the free surface: above
///   it the disks hold air (void that left the top of the IMZ), not moving rock.
/// - **IEZ outlines.** The origins of the markers each drawpoint of `row` drew by the end of
///   `period` ([`RunOutput::drawn_chunks`]) that lie on the section's lattice row, so the
///   outline is the IEZ cut by the section plane (not the projection of the whole IEZ),
///   consistent with the breaks in the layers; binned every marker spacing in elevation by
///   [`iez_outline`].
/// - **Drawpoints.** Name and cumulative mass drawn by the end of `period` ([`fmt_mass`]).
///
/// The marker spacing is `run.resolution.marker_spacing` when set, else inferred from the
/// distinct origin coordinates of the snapshot and the drawn table (their smallest gap).
/// Without either the section has outlines and drawpoints but no layers.
pub fn drawdown_section(
    scene: &Scene,
    run: &RunOutput,
    row: &[usize],
    y: f64,
    layer_spacing: Option<f64>,
    period: i64,
) -> Section {
    let bm = &scene.blocks;
    let dp = &scene.drawpoints;
    let max = bm.max_corner();
    let mut section = Section {
        axis_label: "Easting (m)".into(),
        x_range: (bm.origin[0], max[0]),
        z_range: (bm.origin[2], max[2]),
        ..Section::default()
    };
    let snapshots = run.snapshot_periods();
    let snapshot = snapshots.contains(&period).then_some(period);
    let any_snapshot = snapshot.or_else(|| snapshots.iter().max().copied());
    let lattice =
        marker_spacing(run, any_snapshot).map(|s| SectionLattice::new(bm, run, any_snapshot, s));

    if let (Some(lat), Some(chunks)) = (
        &lattice,
        snapshot.and_then(|p| run.snapshot_chunks(p, CHUNK)),
    ) {
        let spacing = layer_spacing
            .filter(|l| l.is_finite() && *l > 0.0)
            .unwrap_or_else(|| default_layer_spacing(max[2] - bm.origin[2], lat.s));
        section.layers = layers(lat, chunks, y, spacing);
    }

    // The free surface of the period along the lattice row nearest the section.
    section.surface = FreeSurface::of(run, period).section(y);
    if let Some([_, j, _]) = bm.cell([bm.origin[0], y, bm.origin[2]]) {
        let block = |i: usize, k: usize| {
            let b = bm.index[i + bm.dims[0] * (j + bm.dims[1] * k)];
            (b != crate::model::block_model::NO_BLOCK).then_some(b as usize)
        };
        for k in 0..bm.dims[2] {
            for i in 0..bm.dims[0] {
                if block(i, k).is_some_and(|b| !bm.flowable(b, period)) {
                    let x0 = bm.origin[0] + i as f64 * bm.size[0];
                    let z0 = bm.origin[2] + k as f64 * bm.size[2];
                    section
                        .uncaved
                        .push(((x0, z0), (x0 + bm.size[0], z0 + bm.size[2])));
                }
            }
        }
        // The air gap of each block column on the section, from the top of its highest
        // caved stretch down (as `engine::air_gap` counts it).
        let yc = bm.origin[1] + (j as f64 + 0.5) * bm.size[1];
        let t = &run.air_gap;
        for k in (0..t.air_gap.len()).filter(|&k| t.period[k] == period) {
            if (t.y[k] - yc).abs() > 1e-6 * bm.size[1] {
                continue;
            }
            let Some([i, _, _]) = bm.cell([t.x[k], yc, bm.origin[2]]) else {
                continue;
            };
            let top = (0..bm.dims[2])
                .rev()
                .find(|&k| block(i, k).is_some_and(|b| bm.flowable(b, period)))
                .map(|k| bm.origin[2] + (k + 1) as f64 * bm.size[2]);
            if let Some(top) = top {
                let x0 = bm.origin[0] + i as f64 * bm.size[0];
                section
                    .air
                    .push(((x0, top - t.air_gap[k]), (x0 + bm.size[0], top)));
            }
        }
    }

    let imz = &run.imz;
    let drawn = tonnes_by(run, dp.len(), period);
    // The origins of what each drawpoint of the row drew by the end of `period`, on the
    // section's lattice row: one pass over the drawn table.
    let mut iez: HashMap<usize, Vec<(f64, f64)>> = row.iter().map(|&d| (d, Vec::new())).collect();
    if let Some(lat) = &lattice {
        let j = lat.index(1, y);
        for t in run.drawn_chunks(CHUNK) {
            for i in 0..t.drawpoint.len() {
                if t.period[i] <= period && lat.index(1, t.origin_y[i]) == j {
                    if let Some(points) = iez.get_mut(&(t.drawpoint[i] as usize)) {
                        points.push((t.origin_x[i], t.origin_z[i]));
                    }
                }
            }
        }
    }
    for &d in row {
        let disks: Vec<(f64, f64, f64)> = (0..imz.period.len())
            .filter(|&i| imz.period[i] == period && imz.drawpoint[i] as usize == d)
            .map(|i| (imz.z_base[i], imz.z_top[i], imz.radius[i]))
            .collect();
        // A disk may be wider than the ground it covers (it spans every flowable point of
        // its level, see `engine::imz`); the section shows it within the model, and below
        // the free surface.
        let outline: Vec<(f64, f64)> = imz_outline(&disks, dp.x[d])
            .into_iter()
            .map(|(x, z)| (x.clamp(bm.origin[0], max[0]), z))
            .collect();
        let outline = below_surface(&outline, &section.surface);
        if outline.iter().any(|p| p.0.is_finite()) {
            section.imz.push(outline);
        }
        if let Some(lat) = &lattice {
            let points = &iez[&d];
            // The outline is symmetric about the axis; material rilled in from one side
            // would mirror past the model's edge on the other, so it is clipped to the model.
            let outline: Vec<(f64, f64)> = iez_outline(points, dp.x[d], lat.s)
                .into_iter()
                .map(|(x, z)| (x.clamp(bm.origin[0], max[0]), z))
                .collect();
            if !outline.is_empty() {
                section.iez.push(outline);
            }
        }
        section.drawpoints.push((
            dp.x[d],
            dp.z[d],
            format!("{}: {}", dp.name[d], fmt_mass(drawn[d])),
        ));
    }
    section
}

/// The free surface of one period as the sections and the VTK export read it: the rows of
/// `run.surface` at the period where it holds the period, else those of
/// `run.moment_surface` (the engine keeps the surface at the charts' moments and the VTK
/// periods there), grouped by lattice row.
#[derive(Debug, Clone, Default)]
pub struct FreeSurface {
    /// Per lattice row, Northing ascending: its Northing and its (Easting, elevation)
    /// points, Easting ascending.
    rows: Vec<(f64, Vec<(f64, f64)>)>,
}

impl FreeSurface {
    /// The surface table that holds `period` and its rows at `period` (none: the run did
    /// not keep the surface of that period).
    pub fn table(run: &RunOutput, period: i64) -> (&SurfaceTable, Vec<usize>) {
        let at = |t: &SurfaceTable| (0..t.z.len()).filter(|&k| t.period[k] == period).collect();
        let rows: Vec<usize> = at(&run.surface);
        if rows.is_empty() {
            (&run.moment_surface, at(&run.moment_surface))
        } else {
            (&run.surface, rows)
        }
    }

    /// The free surface of `period` in `run` ([`FreeSurface::table`]).
    pub fn of(run: &RunOutput, period: i64) -> FreeSurface {
        let (t, rows) = Self::table(run, period);
        let mut points: Vec<(f64, f64, f64)> = rows
            .iter()
            .map(|&k| (t.y[k], t.x[k], t.z[k]))
            .filter(|p| p.0.is_finite() && p.1.is_finite() && p.2.is_finite())
            .collect();
        // Stable: points of one Easting keep the table's order.
        points.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
        let mut out = FreeSurface::default();
        for (y, x, z) in points {
            match out.rows.last_mut() {
                Some((ry, line)) if *ry == y => line.push((x, z)),
                _ => out.rows.push((y, vec![(x, z)])),
            }
        }
        out
    }

    /// The surface along the lattice row nearest the Northing `y` (both rows where `y`
    /// lies halfway between two), Easting ascending: what a section at `y` draws and cuts
    /// the IMZ outlines at ([`below_surface`]). Empty without a surface.
    pub fn section(&self, y: f64) -> Vec<(f64, f64)> {
        let nearest = self
            .rows
            .iter()
            .map(|r| (r.0 - y).abs())
            .fold(f64::INFINITY, f64::min);
        let mut line: Vec<(f64, f64)> = self
            .rows
            .iter()
            .filter(|r| (r.0 - y).abs() <= nearest + 1e-9)
            .flat_map(|r| r.1.iter().copied())
            .collect();
        line.sort_by(|a, b| a.0.total_cmp(&b.0));
        line
    }

    /// The surface's elevation at (`x`, `y`), m: along each lattice row as on a section
    /// ([`surface_at`]: linear between the row's points, flat beyond its ends), and linear
    /// in Northing between the two rows about `y` (flat beyond the first and last row). On
    /// a lattice row it is that row's section surface. None without a surface or at a
    /// non-finite `y`.
    pub fn at(&self, x: f64, y: f64) -> Option<f64> {
        if !y.is_finite() {
            return None;
        }
        let (first, last) = (self.rows.first()?, self.rows.last()?);
        if y <= first.0 {
            return interpolate(&first.1, x);
        }
        if y >= last.0 {
            return interpolate(&last.1, x);
        }
        let i = self.rows.partition_point(|r| r.0 <= y);
        let (a, b) = (&self.rows[i - 1], &self.rows[i]);
        let (za, zb) = (interpolate(&a.1, x)?, interpolate(&b.1, x)?);
        Some(za + (zb - za) * (y - a.0) / (b.0 - a.0))
    }
}

/// The free surface's elevation at `x` on a section (linear between its points, flat
/// beyond its ends); None where it has no finite point.
pub fn surface_at(surface: &[(f64, f64)], x: f64) -> Option<f64> {
    interpolate(&finite_points(surface), x)
}

/// The finite points of a polyline.
fn finite_points(line: &[(f64, f64)]) -> Vec<(f64, f64)> {
    line.iter()
        .copied()
        .filter(|p| p.0.is_finite() && p.1.is_finite())
        .collect()
}

/// [`surface_at`] on the surface's finite points `pts`.
fn interpolate(pts: &[(f64, f64)], x: f64) -> Option<f64> {
    if !x.is_finite() {
        return None;
    }
    let (first, last) = (pts.first()?, pts.last()?);
    if x <= first.0 {
        return Some(first.1);
    }
    if x >= last.0 {
        return Some(last.1);
    }
    let i = pts.partition_point(|p| p.0 <= x);
    let (a, b) = (pts[i - 1], pts[i]);
    Some(if b.0 > a.0 {
        a.1 + (b.1 - a.1) * (x - a.0) / (b.0 - a.0)
    } else {
        a.1.min(b.1)
    })
}

/// The parts of a polyline at or below the free surface `surface` (as [`surface_at`] reads
/// it), broken by a non-finite point where it rises above: each segment is split where it
/// crosses the surface (between two of the surface's points both are straight, so the
/// crossing is exact). Without a surface the line is kept whole.
pub fn below_surface(line: &[(f64, f64)], surface: &[(f64, f64)]) -> Vec<(f64, f64)> {
    // The surface's finite points, once for every segment.
    let pts = finite_points(surface);
    let Some(&first) = pts.first() else {
        return line.to_vec();
    };
    let s = |x: f64| interpolate(&pts, x).unwrap_or(first.1);
    let lerp =
        |a: (f64, f64), b: (f64, f64), t: f64| (a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t);
    let mut out: Vec<(f64, f64)> = Vec::new();
    let add = |out: &mut Vec<(f64, f64)>, p: (f64, f64)| {
        if out.last() != Some(&p) {
            out.push(p);
        }
    };
    let cut = |out: &mut Vec<(f64, f64)>| {
        if out.last().is_some_and(|p| p.0.is_finite()) {
            out.push((f64::NAN, f64::NAN));
        }
    };
    for w in line.windows(2) {
        let (a, b) = (w[0], w[1]);
        if !(a.0.is_finite() && a.1.is_finite() && b.0.is_finite() && b.1.is_finite()) {
            cut(&mut out);
            continue;
        }
        // Pieces between the surface's points that fall inside the segment's span.
        let mut ts = vec![0.0, 1.0];
        if a.0 != b.0 {
            let (lo, hi) = (a.0.min(b.0), a.0.max(b.0));
            ts.extend(
                surface
                    .iter()
                    .filter(|p| p.0 > lo && p.0 < hi)
                    .map(|p| (p.0 - a.0) / (b.0 - a.0)),
            );
            ts.sort_by(f64::total_cmp);
        }
        for t in ts.windows(2) {
            let (p, q) = (lerp(a, b, t[0]), lerp(a, b, t[1]));
            let (dp, dq) = (p.1 - s(p.0), q.1 - s(q.0));
            match (dp <= 0.0, dq <= 0.0) {
                (true, true) => {
                    add(&mut out, p);
                    add(&mut out, q);
                }
                (true, false) => {
                    add(&mut out, p);
                    let c = lerp(p, q, dp / (dp - dq));
                    add(&mut out, (c.0, s(c.0).min(c.1)));
                    cut(&mut out);
                }
                (false, true) => {
                    cut(&mut out);
                    let c = lerp(p, q, dp / (dp - dq));
                    add(&mut out, (c.0, s(c.0).min(c.1)));
                    add(&mut out, q);
                }
                (false, false) => cut(&mut out),
            }
        }
    }
    if out.last().is_some_and(|p| !p.0.is_finite()) {
        out.pop();
    }
    out
}

/// The regular marker lattice as far as a section needs it: spacing `s` and, per axis, the
/// coordinate of site 0 and the number of sites over the block grid.
#[derive(Debug, Clone, Copy)]
struct SectionLattice {
    s: f64,
    start: [f64; 3],
    n: [i64; 3],
}

impl SectionLattice {
    /// Sites are `start + i s`. The phase comes from an observed marker origin when there is
    /// one (so it matches the engine whatever its convention), else the engine's
    /// `origin + (i + ½) s`; sites cover the block grid.
    fn new(bm: &BlockModel, run: &RunOutput, snap: Option<i64>, s: f64) -> Self {
        let max = bm.max_corner();
        let first = |x: &[f64], y: &[f64], z: &[f64]| (!x.is_empty()).then(|| [x[0], y[0], z[0]]);
        let seen = snap
            .and_then(|p| run.snapshot_chunks(p, 1)?.next())
            .and_then(|m| first(&m.origin_x, &m.origin_y, &m.origin_z))
            .or_else(|| {
                let t = run.drawn_chunks(1).next()?;
                first(&t.origin_x, &t.origin_y, &t.origin_z)
            });
        let mut start = [0.0; 3];
        let mut n = [0i64; 3];
        for a in 0..3 {
            start[a] = match seen {
                Some(p) => p[a] - s * ((p[a] - bm.origin[a]) / s).floor(),
                None => bm.origin[a] + 0.5 * s,
            };
            n[a] = (((max[a] - start[a]) / s).ceil() as i64).max(1);
        }
        SectionLattice { s, start, n }
    }

    /// Index of the lattice site nearest to `v` along axis `a` (not clamped).
    fn index(&self, a: usize, v: f64) -> i64 {
        ((v - self.start[a]) / self.s).round() as i64
    }

    /// Coordinate of site `i` along axis `a`.
    fn coord(&self, a: usize, i: i64) -> f64 {
        self.start[a] + i as f64 * self.s
    }
}

/// Marker spacing: the run's resolved spacing when set, else the smallest gap between
/// distinct origin coordinates (any axis) of the snapshot's markers and the drawn markers.
fn marker_spacing(run: &RunOutput, snap: Option<i64>) -> Option<f64> {
    let s = run.resolution.marker_spacing;
    if s.is_finite() && s > 0.0 {
        return Some(s);
    }
    let mut best = f64::INFINITY;
    let mut axes: Vec<Vec<f64>> = vec![Vec::new(); 3];
    for t in run.drawn_chunks(CHUNK) {
        for (a, v) in axes.iter_mut().zip([&t.origin_x, &t.origin_y, &t.origin_z]) {
            a.extend_from_slice(v);
        }
    }
    if let Some(chunks) = snap.and_then(|p| run.snapshot_chunks(p, CHUNK)) {
        let mut snap_axes: Vec<Vec<f64>> = vec![Vec::new(); 3];
        for m in chunks {
            for (a, v) in snap_axes
                .iter_mut()
                .zip([&m.origin_x, &m.origin_y, &m.origin_z])
            {
                a.extend_from_slice(v);
            }
        }
        axes.extend(snap_axes);
    }
    for values in axes {
        let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
        v.sort_by(f64::total_cmp);
        let tol = 1e-9 * v.last().map_or(1.0, |x| x.abs().max(1.0));
        for w in v.windows(2) {
            let gap = w[1] - w[0];
            if gap > tol {
                best = best.min(gap);
            }
        }
    }
    best.is_finite().then_some(best)
}

/// What a section knows about one lattice site of its row.
#[derive(Debug, Clone, Copy)]
enum Site {
    /// A mobilised marker still in the model, at its current (x, z).
    Moving(f64, f64),
    /// A marker that was drawn.
    Drawn,
}

/// The deformed layers on the lattice row nearest to `y` (see [`drawdown_section`]).
fn layers<'r>(
    lat: &SectionLattice,
    snapshot: impl Iterator<Item = Cow<'r, MarkerSnapshot>>,
    y: f64,
    spacing: f64,
) -> Vec<Vec<(f64, f64)>> {
    let j = lat.index(1, y).clamp(0, lat.n[1] - 1);
    let mut sites: HashMap<(i64, i64), Site> = HashMap::new();
    for snap in snapshot {
        for m in 0..snap.marker_id.len() {
            if lat.index(1, snap.origin_y[m]) != j {
                continue;
            }
            let key = (
                lat.index(0, snap.origin_x[m]),
                lat.index(2, snap.origin_z[m]),
            );
            let site = match snap.state[m] {
                MarkerState::Drawn => Site::Drawn,
                _ => Site::Moving(snap.x[m], snap.z[m]),
            };
            sites.insert(key, site);
        }
    }
    let base = lat.start[2] - 0.5 * lat.s;
    let top = lat.coord(2, lat.n[2] - 1) + 0.5 * lat.s;
    let mut levels: Vec<i64> = Vec::new();
    let mut k = 1;
    loop {
        let z = base + (k as f64 - 0.5) * spacing;
        if z > top + 1e-9 * top.abs().max(1.0) {
            break;
        }
        let level = lat.index(2, z).clamp(0, lat.n[2] - 1);
        if levels.last() != Some(&level) {
            levels.push(level);
        }
        k += 1;
    }
    levels
        .into_iter()
        .map(|kz| layer_line(lat, &sites, kz))
        .filter(|line| line.iter().any(|p| p.0.is_finite()))
        .collect()
}

/// One layer: lattice columns in order, in-situ runs reduced to their ends, drawn markers as
/// a single NaN break between pieces.
fn layer_line(lat: &SectionLattice, sites: &HashMap<(i64, i64), Site>, kz: i64) -> Vec<(f64, f64)> {
    let z0 = lat.coord(2, kz);
    let nan = (f64::NAN, f64::NAN);
    let mut line: Vec<(f64, f64)> = Vec::new();
    // Index in `line` where the current run of in-situ points started.
    let mut flat_from: Option<usize> = None;
    for i in 0..lat.n[0] {
        match sites.get(&(i, kz)) {
            None => {
                let p = (lat.coord(0, i), z0);
                match flat_from {
                    // Keep the first and the latest point of a flat run.
                    Some(start) if line.len() - start >= 2 => *line.last_mut().unwrap() = p,
                    Some(_) => line.push(p),
                    None => {
                        flat_from = Some(line.len());
                        line.push(p);
                    }
                }
            }
            Some(Site::Moving(x, z)) => {
                flat_from = None;
                line.push((*x, *z));
            }
            Some(Site::Drawn) => {
                flat_from = None;
                if line.last().is_some_and(|p| p.0.is_finite()) {
                    line.push(nan);
                }
            }
        }
    }
    if line.last().is_some_and(|p| !p.0.is_finite()) {
        line.pop();
    }
    line
}

/// Cumulative credited tonnes per drawpoint by the end of `period` (0 for drawpoints
/// without rows by then).
fn tonnes_by(run: &RunOutput, n: usize, period: i64) -> Vec<f64> {
    let ex = &run.extraction;
    let mut out = vec![0.0; n];
    for (i, &d) in ex.drawpoint.iter().enumerate() {
        if let Some(slot) = out.get_mut(d as usize) {
            let c = ex.cum_tonnes[i];
            if ex.period[i] <= period && c.is_finite() && c > *slot {
                *slot = c;
            }
        }
    }
    out
}

/// Grade against cumulative tonnes of grade column `g`, one series per drawpoint that drew
/// something, for [`grade_tonnage_chart`].
///
/// - **Predicted**: per period, the extraction report's grade at the period's cumulative
///   tonnes, over the rows where markers were drawn (`markers > 0`) and the grade is finite
///   (NaN means nothing drawn).
/// - **Block grade** (the summary's dashed line, "grades that would be achieved under
///   perfectly uniform drawdown"): per period whose height of draw grew, the grade of the
///   in-situ slice that perfectly uniform drawdown of the column directly above the
///   drawpoint would deliver in that period: [`block_grade`] of the block-grid column
///   containing the drawpoint's (x, y), between `z + HOD_prev` and `z + HOD`, where z is the
///   drawpoint's elevation, HOD the extraction report's height of draw at the end of the
///   period (cumulative tonnes over tributary area × in-situ bulk density, see the engine)
///   and HOD_prev the one at the end of the drawpoint's previous row (0 before its first).
///   Plotted at the period's cumulative tonnes; slices with no block (above the model, or a
///   missing block) give no point.
/// - **Dilution entry** ([`dilution_entries`]), where the drawpoint reaches it.
///
/// Series are named after the drawpoints and carry no sampled grades.
pub fn grade_series(scene: &Scene, run: &RunOutput, g: usize) -> Vec<GradeSeries> {
    let ex = &run.extraction;
    let dp = &scene.drawpoints;
    let Some(grades) = ex.grades.get(g) else {
        return Vec::new();
    };
    let entries = dilution_entries(run, dp.len());
    let mut series: Vec<GradeSeries> = dp
        .name
        .iter()
        .zip(entries)
        .map(|(name, entry)| GradeSeries {
            name: name.clone(),
            block_grade: Some(Vec::new()),
            dilution_entry: entry.is_finite().then_some(entry),
            ..GradeSeries::default()
        })
        .collect();
    let mut hod_prev = vec![0.0; dp.len()];
    for (i, &d) in ex.drawpoint.iter().enumerate() {
        let d = d as usize;
        let Some(s) = series.get_mut(d) else { continue };
        let cum = ex.cum_tonnes[i];
        if ex.markers[i] > 0 && grades[i].is_finite() && cum.is_finite() {
            s.cum_tonnes.push(cum);
            s.predicted.push(grades[i]);
        }
        let hod = ex.hod[i];
        if hod.is_finite() && hod > hod_prev[d] {
            let v = block_grade(
                &scene.blocks,
                g,
                dp.x[d],
                dp.y[d],
                dp.z[d] + hod_prev[d],
                dp.z[d] + hod,
            );
            if v.is_finite() && cum.is_finite() {
                s.block_grade.as_mut().unwrap().push((cum, v));
            }
            hod_prev[d] = hod;
        }
    }
    series.retain(|s| !s.predicted.is_empty());
    series
}

/// Uniform-drawdown grade of a slice: the mass-weighted mean of grade column `g` over the
/// blocks of the block-grid column containing (`x`, `y`) between elevations `z_lo` and
/// `z_hi`.
///
/// Each block weighs its in-situ mass inside the slice: the length of [`z_lo`, `z_hi`]
/// inside the block × solids density × (1 − n0) (the footprint is the same for every block
/// of a column, so it cancels). Blocks missing from the grid are skipped. NaN when (x, y) is
/// off the grid, the slice is empty or reversed, or no block overlaps it.
pub fn block_grade(bm: &BlockModel, g: usize, x: f64, y: f64, z_lo: f64, z_hi: f64) -> f64 {
    let Some(col) = bm.grades.get(g) else {
        return f64::NAN;
    };
    // Written so that NaN bounds also give NaN.
    if z_hi.partial_cmp(&z_lo) != Some(std::cmp::Ordering::Greater) || bm.index.is_empty() {
        return f64::NAN;
    }
    let cell = |v: f64, a: usize| {
        let t = (v - bm.origin[a]) / bm.size[a];
        (t >= 0.0 && t < bm.dims[a] as f64).then_some(t as usize)
    };
    let (Some(i), Some(j)) = (cell(x, 0), cell(y, 1)) else {
        return f64::NAN;
    };
    let dz = bm.size[2];
    let k0 = ((z_lo - bm.origin[2]) / dz).floor().max(0.0) as usize;
    let k1 = (((z_hi - bm.origin[2]) / dz).ceil().max(0.0) as usize).min(bm.dims[2]);
    let (mut mass, mut sum) = (0.0, 0.0);
    for k in k0..k1 {
        let b = bm.index[i + bm.dims[0] * (j + bm.dims[1] * k)];
        if b == NO_BLOCK {
            continue;
        }
        let b = b as usize;
        let lo = bm.origin[2] + k as f64 * dz;
        let overlap = (z_hi.min(lo + dz) - z_lo.max(lo)).max(0.0);
        let w = overlap * bm.density[b] * (1.0 - bm.n0[b]);
        if w > 0.0 && col[b].is_finite() {
            mass += w;
            sum += w * col[b];
        }
    }
    if mass > 0.0 {
        sum / mass
    } else {
        f64::NAN
    }
}

/// A Northing for a title: up to three decimals, trailing zeros dropped.
fn fmt_coord(v: f64) -> String {
    let s = format!("{v:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".into()
    } else {
        s.into()
    }
}

/// A name as part of a file name: ASCII letters, digits, `-`, `_` and `.` kept, anything
/// else `_`.
fn file_safe(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.') {
                c
            } else {
                '_'
            }
        })
        .collect();
    if s.is_empty() {
        "grade".into()
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::result::{Extraction, ResolvedResolution};
    use crate::engine::Engine;
    use crate::model::synthetic::UniformBox;
    use crate::model::Scenario;

    use crate::output::charts::tests::out_dir;

    fn two_drawpoints() -> UniformBox {
        UniformBox {
            extent: [0.8, 0.4, 0.8],
            block: [0.05, 0.05, 0.05],
            drawpoints: vec![(-0.2, 0.0, 0.1), (0.2, 0.0, 0.1)],
            periods: 3,
            tonnes: 0.02,
            ..UniformBox::castro_isolated()
        }
    }

    fn run(scene: &Scene, h: f64, s: f64) -> RunOutput {
        let mut scenario = Scenario::default();
        scenario.resolution.layer_thickness = Some(h);
        scenario.resolution.marker_spacing = Some(s);
        Engine::new(scene, &scenario).unwrap().run(&mut |_, _| {})
    }

    #[test]
    fn run_charts_are_written_as_png() {
        let scene = two_drawpoints().scene();
        let out = run(&scene, 0.05, 0.025);
        assert!(!out.snapshot_periods().is_empty());
        let (_keep, dir) = out_dir("figures-two-dp");
        let written = write_run_charts(&dir, &scene, &out, None, &[3]).unwrap();
        let names: Vec<String> = written
            .iter()
            .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names, ["section_1.png", "grade_elev.png"]);
        for p in &written {
            assert_eq!(p.parent().unwrap(), dir.join("charts"));
            let bytes = std::fs::read(p).unwrap();
            assert!(
                bytes.len() > 1000,
                "{} is {} bytes",
                p.display(),
                bytes.len()
            );
            assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{}", p.display());
        }

        // The one section holds both drawpoints, both outlines and deformed layers.
        let sections = run_sections(&scene, &out, None, 3);
        assert_eq!(sections.len(), 1);
        let (section, y) = &sections[0];
        assert_eq!(*y, 0.0);
        assert_eq!(section.drawpoints.len(), 2);
        assert!(
            section.drawpoints[0].2.starts_with("DP01: ")
                && section.drawpoints[0].2.ends_with(" kg")
        );
        assert_eq!(section.imz.len(), 2);
        assert_eq!(section.iez.len(), 2);
        // 0.8 m high → 0.02 m neat spacing is below the marker spacing: 0.025 m layers, 32.
        assert_eq!(section.layers.len(), 32);
        let dipped = section
            .layers
            .iter()
            .flatten()
            .filter(|p| p.1.is_finite())
            .filter(|p| {
                let level = ((p.1 - 0.0125) / 0.025).round() * 0.025 + 0.0125;
                (p.1 - level).abs() > 1e-9
            })
            .count();
        assert!(dipped > 0, "no marker moved off its layer");
    }

    /// The project's own Figs 13 and 16 (DESIGN §7): Castro's isolated draw and IN-T2 at
    /// the summary's scale. Slow; run with `--ignored` and `CAVEFLOW_CHART_DIR` set to look.
    #[test]
    #[ignore]
    fn reference_scenes_render() {
        let castro = UniformBox::castro_isolated();
        let in_t2 = UniformBox {
            extent: [1.4, 0.7, 3.3],
            drawpoints: vec![(-0.35, 0.0, 0.12), (0.35, 0.0, 0.12)],
            periods: 10,
            tonnes: 0.003,
            ..UniformBox::castro_isolated()
        };
        for (name, scene) in [("castro", castro.scene()), ("in-t2", in_t2.scene())] {
            let t = std::time::Instant::now();
            let out = Engine::new(&scene, &Scenario::default())
                .unwrap()
                .run(&mut |_, _| {});
            let ran = t.elapsed();
            let (_keep, dir) = out_dir(name);
            let moments = scene.moments(&[]);
            let written = write_run_charts(&dir, &scene, &out, None, &moments).unwrap();
            eprintln!(
                "{name}: run {ran:?}, charts {:?}, resolution {:?}, warnings {:?}",
                t.elapsed() - ran,
                out.resolution,
                out.warnings
            );
            assert!(!written.is_empty());
        }
    }

    #[test]
    fn block_grade_is_the_mean_elevation_of_the_drawn_slice() {
        // Grade `elev` = block centre elevation, 0.05 m blocks from z = 0.
        let scene = UniformBox {
            extent: [0.2, 0.2, 1.0],
            ..UniformBox::castro_isolated()
        }
        .scene();
        let bm = &scene.blocks;
        let at = |lo: f64, hi: f64| block_grade(bm, 0, 0.01, -0.03, lo, hi);
        // A slice of whole blocks: the mean of their centres is the slice's mean elevation.
        assert!((at(0.0, 0.1) - 0.05).abs() < 1e-12);
        assert!((at(0.2, 0.5) - 0.35).abs() < 1e-12);
        // Part blocks weigh by their length inside the slice:
        // [0.04, 0.12] → 0.01 of 0.025, 0.05 of 0.075, 0.02 of 0.125.
        let expected = (0.01 * 0.025 + 0.05 * 0.075 + 0.02 * 0.125) / 0.08;
        assert!((at(0.04, 0.12) - expected).abs() < 1e-12);
        // Inside one block: that block's grade.
        assert!((at(0.51, 0.52) - 0.525).abs() < 1e-12);
        // Above the model, empty, reversed or off the grid: no grade.
        assert!(at(1.1, 1.2).is_nan());
        assert!(at(0.3, 0.3).is_nan());
        assert!(at(0.3, 0.2).is_nan());
        assert!(block_grade(bm, 0, 5.0, 0.0, 0.0, 0.1).is_nan());
        assert!(block_grade(bm, 1, 0.0, 0.0, 0.0, 0.1).is_nan());
        // Straddling the top: only the part inside the model counts.
        assert!((at(0.95, 1.5) - 0.975).abs() < 1e-12);
    }

    #[test]
    fn block_grade_weighs_in_situ_mass() {
        let mut scene = UniformBox {
            extent: [0.1, 0.1, 0.1],
            ..UniformBox::castro_isolated()
        }
        .scene();
        let bm = &mut scene.blocks;
        let lower = bm.locate([0.0, 0.0, 0.025]).unwrap();
        // The lower blocks hold twice the solids per metre of the upper ones.
        for b in 0..bm.len() {
            if bm.z[b] < 0.05 {
                bm.density[b] = 2.0;
                bm.n0[b] = 0.0;
            } else {
                bm.density[b] = 2.0;
                bm.n0[b] = 0.5;
            }
        }
        assert!(bm.z[lower] < 0.05);
        let v = block_grade(bm, 0, 0.0, 0.0, 0.0, 0.1);
        assert!((v - (2.0 * 0.025 + 0.075) / 3.0).abs() < 1e-12, "{v}");
    }

    #[test]
    fn grade_series_follows_the_extraction_rows() {
        let scene = UniformBox {
            extent: [0.2, 0.2, 1.0],
            drawpoints: vec![(-0.05, 0.0, 0.1), (0.05, 0.0, 0.1)],
            ..UniformBox::castro_isolated()
        }
        .scene();
        // Period-major rows; DP02 draws nothing in period 1 and is idle in period 2.
        let ex = Extraction {
            drawpoint: vec![0, 1, 0, 1, 0, 1],
            period: vec![1, 1, 2, 2, 3, 3],
            cum_tonnes: vec![0.01, 0.0, 0.02, 0.0, 0.03, 0.01],
            tonnes: vec![0.01, 0.0, 0.01, 0.0, 0.01, 0.01],
            dilution: vec![0.0, f64::NAN, 0.0, f64::NAN, 0.2, 0.0],
            markers: vec![5, 0, 4, 0, 6, 3],
            hod: vec![0.1, 0.0, 0.2, 0.0, 0.35, 0.1],
            grades: vec![vec![0.4, f64::NAN, 0.5, f64::NAN, 0.6, 0.3]],
            ..Extraction::default()
        };
        let out = RunOutput {
            extraction: ex,
            ..RunOutput::default()
        };
        let series = grade_series(&scene, &out, 0);
        assert_eq!(series.len(), 2);
        let a = &series[0];
        assert_eq!(a.name, "DP01");
        assert_eq!(a.cum_tonnes, [0.01, 0.02, 0.03]);
        assert_eq!(a.predicted, [0.4, 0.5, 0.6]);
        // 10% waste between the midpoints of periods 2 (0.015 t, none) and 3 (0.025 t, 20%).
        assert!((a.dilution_entry.unwrap() - 0.02).abs() < 1e-12);
        assert_eq!(series[1].dilution_entry, None);
        let blocks = a.block_grade.as_ref().unwrap();
        let want = [(0.01, 0.05), (0.02, 0.15), (0.03, 0.275)];
        assert_eq!(blocks.len(), 3);
        for (got, want) in blocks.iter().zip(want) {
            assert_eq!(got.0, want.0);
            assert!((got.1 - want.1).abs() < 1e-12, "{got:?} vs {want:?}");
        }
        let b = &series[1];
        assert_eq!(b.cum_tonnes, [0.01]);
        let blocks = b.block_grade.as_ref().unwrap();
        assert_eq!(blocks.len(), 1);
        assert!((blocks[0].1 - 0.05).abs() < 1e-12);
        assert!(grade_series(&scene, &out, 1).is_empty());
    }

    #[test]
    fn rows_group_drawpoints_within_half_a_block() {
        let scene = UniformBox {
            extent: [2.0, 2.0, 0.5],
            block: [0.1, 0.1, 0.1],
            drawpoints: vec![
                (0.5, 0.52, 0.1),
                (-0.5, 0.0, 0.1),
                (0.5, 0.0, 0.1),
                (0.0, 0.5, 0.1),
                (0.0, 0.03, 0.1),
            ],
            ..UniformBox::castro_isolated()
        }
        .scene();
        assert_eq!(drawpoint_rows(&scene), vec![vec![1, 4, 2], vec![3, 0]]);
    }

    #[test]
    fn many_rows_keep_the_rows_that_drew_most() {
        let scene = UniformBox {
            extent: [1.0, 1.2, 0.5],
            block: [0.1, 0.1, 0.1],
            drawpoints: (0..6).map(|j| (0.0, -0.5 + 0.2 * j as f64, 0.1)).collect(),
            ..UniformBox::castro_isolated()
        }
        .scene();
        let ex = Extraction {
            drawpoint: (0..6).collect(),
            period: vec![1; 6],
            cum_tonnes: vec![5.0, 1.0, 4.0, 3.0, 2.0, 6.0],
            markers: vec![1; 6],
            hod: vec![0.0; 6],
            grades: vec![vec![0.0; 6]],
            ..Extraction::default()
        };
        let out = RunOutput {
            extraction: ex,
            resolution: ResolvedResolution {
                marker_spacing: 0.05,
                ..ResolvedResolution::default()
            },
            ..RunOutput::default()
        };
        let sections = run_sections(&scene, &out, None, 6);
        let ys: Vec<f64> = sections
            .iter()
            .map(|s| (s.1 * 10.0).round() / 10.0)
            .collect();
        assert_eq!(ys, [-0.5, -0.1, 0.1, 0.5]);
        // Without snapshots: no layers, but labels with the mass drawn.
        assert!(sections.iter().all(|s| s.0.layers.is_empty()));
        assert_eq!(sections[3].0.drawpoints[0].2, "DP06: 6.00 t");
    }

    #[test]
    fn layer_lines_are_flat_outside_the_mobilised_markers_and_break_where_drawn() {
        let lat = SectionLattice {
            s: 1.0,
            start: [0.5, 0.5, 0.5],
            n: [8, 1, 4],
        };
        let mut sites = HashMap::new();
        sites.insert((2, 1), Site::Moving(2.6, 1.2));
        sites.insert((3, 1), Site::Drawn);
        sites.insert((4, 1), Site::Drawn);
        sites.insert((5, 1), Site::Moving(5.4, 1.1));
        let line = layer_line(&lat, &sites, 1);
        let z = 1.5;
        assert_eq!(line.len(), 7);
        assert_eq!(&line[..3], &[(0.5, z), (1.5, z), (2.6, 1.2)]);
        assert!(line[3].0.is_nan());
        assert_eq!(&line[4..], &[(5.4, 1.1), (6.5, z), (7.5, z)]);
        // A layer never mobilised is its two ends.
        assert_eq!(layer_line(&lat, &sites, 2), vec![(0.5, 2.5), (7.5, 2.5)]);
    }

    #[test]
    fn spacing_is_inferred_from_origins_without_a_resolution() {
        let snap = MarkerSnapshot {
            origin_x: vec![0.125, 0.175, 0.125],
            origin_y: vec![0.0, 0.0, 0.0],
            origin_z: vec![1.025, 1.025, 1.075],
            ..MarkerSnapshot::default()
        };
        let out = RunOutput {
            snapshots: vec![snap],
            ..RunOutput::default()
        };
        let s = marker_spacing(&out, Some(0)).unwrap();
        assert!((s - 0.05).abs() < 1e-12, "{s}");
        assert!(marker_spacing(&RunOutput::default(), None).is_none());
    }

    #[test]
    fn default_layers_and_masses_read_well() {
        assert_eq!(default_layer_spacing(3.3, 0.004), 0.1);
        assert_eq!(default_layer_spacing(300.0, 1.0), 10.0);
        assert_eq!(default_layer_spacing(0.8, 0.025), 0.025);
        assert_eq!(default_layer_spacing(150.0, 1.0), 5.0);
        assert_eq!(fmt_mass(0.02), "20.0 kg");
        assert_eq!(fmt_mass(0.4123), "412 kg");
        assert_eq!(fmt_mass(1.234), "1.23 t");
        assert_eq!(fmt_mass(4120.0), "4120 t");
        assert_eq!(fmt_mass(12_345.0), "12.3 kt");
        assert_eq!(fmt_coord(0.35), "0.35");
        assert_eq!(fmt_coord(-0.0), "0");
        assert_eq!(fmt_coord(5120.0), "5120");
        assert_eq!(file_safe("Mo %"), "Mo__");
    }

    #[test]
    fn free_surface_reads_each_row_as_a_section_and_is_linear_between_rows() {
        // Two lattice rows at y = 0 and y = 1 (a gap at x = 1 on the second), kept in the
        // moment table; a third period's row in the surface table.
        let mut run = RunOutput::default();
        let push = |t: &mut SurfaceTable, p: i64, x: f64, y: f64, z: f64| {
            t.period.push(p);
            t.x.push(x);
            t.y.push(y);
            t.z.push(z);
        };
        for (x, y, z) in [(0.0, 0.0, 10.0), (1.0, 0.0, 8.0), (2.0, 0.0, 6.0)] {
            push(&mut run.moment_surface, 4, x, y, z);
        }
        for (x, y, z) in [(0.0, 1.0, 12.0), (2.0, 1.0, 4.0)] {
            push(&mut run.moment_surface, 4, x, y, z);
        }
        push(&mut run.surface, 5, 0.0, 0.0, 3.0);
        let f = FreeSurface::of(&run, 4);
        // On a row: the section's surface at that row.
        for x in [-1.0, 0.0, 0.5, 1.0, 1.5, 2.0, 3.0] {
            for y in [0.0, 1.0] {
                assert_eq!(f.at(x, y), surface_at(&f.section(y), x), "({x}, {y})");
            }
        }
        assert_eq!(f.section(0.2), [(0.0, 10.0), (1.0, 8.0), (2.0, 6.0)]);
        assert_eq!(
            f.section(0.5).len(),
            5,
            "halfway: both rows, as the sections had it"
        );
        // Between rows: linear in y; beyond them: flat.
        assert_eq!(f.at(1.0, 0.25), Some(8.0));
        assert_eq!(f.at(0.0, 0.5), Some(11.0));
        assert_eq!(f.at(2.0, -5.0), Some(6.0));
        assert_eq!(f.at(2.0, 7.0), Some(4.0));
        assert_eq!(f.at(f64::NAN, 0.5), None);
        // The surface table first, then the moments; none for a period neither holds.
        assert_eq!(FreeSurface::of(&run, 5).at(9.0, 9.0), Some(3.0));
        assert_eq!(FreeSurface::table(&run, 5).1, [0]);
        assert_eq!(FreeSurface::of(&run, 6).at(0.0, 0.0), None);
        assert!(FreeSurface::of(&run, 6).section(0.0).is_empty());
    }
}
