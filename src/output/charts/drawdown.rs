//! Drawdown sections of a run, built for [`section_chart`](super::section_chart): one
//! vertical section along x (Easting) through each row of drawpoints ([`run_sections`],
//! [`drawdown_section`]) with the deformed layers (`layers`), the free surface
//! (`free_surface`), the uncaved ground, the air gap, the IMZ and IEZ outlines and the
//! drawpoints' names with the mass drawn.
//!
//! # Reading a section
//! A layer is an initially horizontal line of material: the markers that start on one lattice
//! level of the section's lattice row. Their current positions, joined in the order of their
//! origins (a material line, so a layer never folds back on itself unless the material did),
//! show the drawdown. Stagnant ground is never materialised by the
//! engine, so where a layer was never mobilised it is drawn flat at its in-situ elevation;
//! where its markers were drawn the layer is broken (the material has left the model).

use std::collections::HashMap;

use super::free_surface::{below_surface, FreeSurface};
use super::layers::{layers, marker_spacing, SectionLattice};
use super::{fmt_mass, iez_outline, imz_outline, Section};
use crate::engine::result::RunOutput;
use crate::model::Scene;

/// Rows of the drawn table and of a marker snapshot a section reads at a time (the engine's
/// end tables are read from its markers in chunks, `engine::marker_tables`).
pub(super) const CHUNK: usize = 1 << 16;

/// Most drawdown sections [`run_sections`] makes at one moment; with more rows of drawpoints
/// it keeps the rows that drew the most tonnes.
pub const MAX_SECTIONS: usize = 4;

/// Aim for about this many initially horizontal layers over the model height (the summary's
/// Fig 13 shows 100 mm layers in a 3.3 m model: 33).
const TARGET_LAYERS: f64 = 30.0;

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::result::{Extraction, ResolvedResolution};
    use crate::model::synthetic::UniformBox;

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
    }
}
