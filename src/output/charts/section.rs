//! Drawdown sections (summary Figs 13 and 16): the [`Section`] data, the IMZ and IEZ outlines
//! it draws ([`imz_outline`], [`iez_outline`]), and [`section_chart`], which lays a section
//! out ([`SectionPlot`]) and draws it.
//!
//! # Why equal aspect
//! A drawdown section is read as geometry: the IMZ base angle and the width of an IEZ only mean
//! something when one metre across is one metre up, so sections keep 1:1 within a pixel budget
//! ([`MAX_SIDE`]).

use std::collections::BTreeMap;
use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::{
    axis_title_style, draw_axes, ensure_font, finite_runs, put_text, text, text_width,
    widest_tick_label, write_chart, x_ticks, y_ticks, AxisLabels, ChartError, DrawError, Frame,
    IntoChartError, Legend, LegendEntry, Pen, Render, Sample, AIR_FILL, AXIS_TITLE_W, FRAME_COLOUR,
    IEZ_COLOUR, IMZ_COLOUR, LAYER_COLOURS, MAX_SIDE, MIN_W, MODEL_FILL, SURFACE_COLOUR, TICK_GAP,
    TITLE_H, TRACE_COLOUR, UNCAVED_FILL,
};

/// Layout failures: bad input, or a font measurement that failed.
enum LayoutError {
    /// The input cannot be drawn.
    Input(String),
    /// Text measurement failed.
    Draw(DrawError),
}

impl LayoutError {
    /// As a [`ChartError`] naming the path.
    fn into_chart_error(self, path: &Path) -> ChartError {
        match self {
            LayoutError::Input(message) => ChartError::Input {
                path: path.to_path_buf(),
                message,
            },
            LayoutError::Draw(e) => e.into_chart_error(path),
        }
    }
}

impl From<DrawError> for LayoutError {
    fn from(e: DrawError) -> Self {
        LayoutError::Draw(e)
    }
}

/// Section: x tick labels plus axis title below the plot, right margin, space above the plot;
/// px. The left margin follows the widest elevation label.
pub(super) const SEC_BOTTOM: u32 = 58;
pub(super) const SEC_RIGHT: u32 = 24;
pub(super) const SEC_TOP: u32 = 12;
/// Section: drawpoint labels hang this far below the model base, one row per line; px.
const DP_LABEL_TOP: u32 = 12;
pub(super) const DP_LINE: u32 = 16;
/// Section: most rows of drawpoint labels before labels may overlap.
const DP_MAX_ROWS: usize = 3;

/// A vertical drawdown section (summary Figs 13 and 16), as plain data in section coordinates:
/// the horizontal coordinate along the section (an Easting, a Northing or a distance) and the
/// elevation z, both in m.
///
/// The engine side fills it: marker positions per initial layer from a
/// [`MarkerSnapshot`](crate::engine::result::MarkerSnapshot), IMZ outlines from the
/// [`ImzTable`](crate::engine::result::ImzTable) through [`imz_outline`], IEZ outlines from the
/// [`DrawnTable`](crate::engine::result::DrawnTable) through [`iez_outline`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Section {
    /// Label of the horizontal axis, with its unit, e.g. `"Easting (m)"`.
    pub axis_label: String,
    /// Model extent along the section, m (low, high).
    pub x_range: (f64, f64),
    /// Model extent in elevation, m (low, high).
    pub z_range: (f64, f64),
    /// Current positions of the markers that started on one horizontal layer, one polyline per
    /// layer, sorted along the section. Drawn as thin lines in two alternating colours, so the
    /// drawdown shows as deformed, initially horizontal layers. Non-finite points break a line.
    pub layers: Vec<Vec<(f64, f64)>>,
    /// IMZ outline per drawpoint: closed polylines (see [`imz_outline`]).
    pub imz: Vec<Vec<(f64, f64)>>,
    /// IEZ outline per drawpoint: closed polylines (see [`iez_outline`]).
    pub iez: Vec<Vec<(f64, f64)>>,
    /// Drawpoints on the section: (horizontal, z, label), e.g. the name and the mass drawn.
    /// Labels are set below the model base, staggered over up to three rows when they crowd.
    pub drawpoints: Vec<(f64, f64, String)>,
    /// The free surface along the section (top of the caved material), a polyline; non-finite
    /// points break it (summary Fig. 33).
    pub surface: Vec<(f64, f64)>,
    /// Uncaved ground on the section: rectangles ((x0, z0), (x1, z1)).
    pub uncaved: Vec<((f64, f64), (f64, f64))>,
    /// The air gap on the section (air between the caved rock and the ground above it, or
    /// the model top): rectangles ((x0, z0), (x1, z1)).
    pub air: Vec<((f64, f64), (f64, f64))>,
    /// Paths of trace points (`engine::trace`), one polyline per point from its given
    /// position through its position at each period end; drawn with a dot at the start.
    pub traces: Vec<Vec<(f64, f64)>>,
}

/// Closed outline of an IMZ on a vertical section through its axis.
///
/// `disks` are (z_base, z_top, radius) in m, as in the IMZ table for one drawpoint and period,
/// in any order. The outline is the exact stair profile of the disk stack: up the right side
/// (`axis_x + R`) from the lowest disk, across the top, down the left side (`axis_x − R`), and
/// back to the first point. Disks with a zero, negative or non-finite radius (a new top disk not
/// yet dilated) are left out. No usable disk gives an empty outline.
pub fn imz_outline(disks: &[(f64, f64, f64)], axis_x: f64) -> Vec<(f64, f64)> {
    let mut stack: Vec<(f64, f64, f64)> = disks
        .iter()
        .copied()
        .filter(|&(b, t, r)| b.is_finite() && t.is_finite() && r.is_finite() && r > 0.0)
        .collect();
    stack.sort_by(|a, b| a.0.total_cmp(&b.0));
    stair_outline(&stack, axis_x)
}

/// Closed outline of an IEZ on a vertical section through a drawpoint axis.
///
/// `points` are the origins of the markers this drawpoint drew, as (horizontal coordinate
/// along the section, z) in m. Elevations are binned at multiples of `bin` (bin k covers
/// [k·bin, (k+1)·bin)); each bin's half-width is the largest |horizontal − `axis_x`| among its
/// points, and the outline is the symmetric stair profile of those half-widths, closed like
/// [`imz_outline`]. Bins without points are skipped (the outline joins across them). Non-finite
/// points are ignored; no points, or a `bin` that is not finite and positive, give an empty
/// outline.
pub fn iez_outline(points: &[(f64, f64)], axis_x: f64, bin: f64) -> Vec<(f64, f64)> {
    if !(bin.is_finite() && bin > 0.0 && axis_x.is_finite()) {
        return Vec::new();
    }
    let mut half_width: BTreeMap<i64, f64> = BTreeMap::new();
    for &(h, z) in points {
        if h.is_finite() && z.is_finite() {
            let w = (h - axis_x).abs();
            let k = (z / bin).floor() as i64;
            let entry = half_width.entry(k).or_insert(w);
            *entry = entry.max(w);
        }
    }
    let stack: Vec<(f64, f64, f64)> = half_width
        .into_iter()
        .map(|(k, w)| (k as f64 * bin, (k + 1) as f64 * bin, w))
        .collect();
    stair_outline(&stack, axis_x)
}

/// Stair profile of a stack of (z_base, z_top, half-width) sorted by z_base: right side up,
/// left side down, closed; consecutive duplicate points dropped.
fn stair_outline(stack: &[(f64, f64, f64)], axis_x: f64) -> Vec<(f64, f64)> {
    let mut out: Vec<(f64, f64)> = Vec::with_capacity(4 * stack.len() + 1);
    let mut push = |p: (f64, f64)| {
        if out.last() != Some(&p) {
            out.push(p);
        }
    };
    for &(b, t, r) in stack {
        push((axis_x + r, b));
        push((axis_x + r, t));
    }
    for &(b, t, r) in stack.iter().rev() {
        push((axis_x - r, t));
        push((axis_x - r, b));
    }
    if let Some(&first) = out.first() {
        out.push(first);
    }
    out
}

/// Draw a drawdown section (summary Figs 13 and 16) to `path` (`.png` or `.svg`).
///
/// One metre across is one metre up; the image fits in [`MAX_SIDE`] px. The plotted extent is
/// the model extent (shaded) grown to hold every finite point of the section, plus a strip
/// below for the drawpoint labels. A legend below the plot names what is drawn.
pub fn section_chart(path: &Path, section: &Section, title: &str) -> Result<(), ChartError> {
    ensure_font(path)?;
    let plot = SectionPlot::new(section, title).map_err(|e| e.into_chart_error(path))?;
    write_chart(path, &plot)
}

/// A section laid out in pixels.
struct SectionPlot<'a> {
    /// The data.
    section: &'a Section,
    /// The title.
    title: &'a str,
    /// Image size, px.
    size: (u32, u32),
    /// The plotting frame (equal aspect; its elevation range includes the label strip).
    frame: Frame,
    /// Space for the elevation tick labels left of the frame, px.
    y_label_w: u32,
    /// Elevation the drawpoint labels hang from (lowest model or data point), m.
    z_base: f64,
    /// Label row of each drawpoint.
    label_rows: Vec<usize>,
    /// The legend, below the plot.
    legend: Legend,
}

impl<'a> SectionPlot<'a> {
    /// Validate the section and lay it out.
    fn new(section: &'a Section, title: &'a str) -> Result<Self, LayoutError> {
        let (x_lo, x_hi) = section.x_range;
        let (z_lo, z_hi) = section.z_range;
        if !(x_lo.is_finite() && x_hi.is_finite() && x_hi > x_lo) {
            return Err(LayoutError::Input(format!(
                "section x range {:?} is not a finite, increasing interval",
                section.x_range
            )));
        }
        if !(z_lo.is_finite() && z_hi.is_finite() && z_hi > z_lo) {
            return Err(LayoutError::Input(format!(
                "section z range {:?} is not a finite, increasing interval",
                section.z_range
            )));
        }
        let (mut x0, mut x1, mut z0, mut z1) = (x_lo, x_hi, z_lo, z_hi);
        let polylines = section
            .layers
            .iter()
            .chain(&section.imz)
            .chain(&section.iez)
            .chain(&section.traces);
        let points = polylines
            .flatten()
            .copied()
            .chain(section.drawpoints.iter().map(|d| (d.0, d.1)));
        for (x, z) in points.filter(|p| p.0.is_finite() && p.1.is_finite()) {
            x0 = x0.min(x);
            x1 = x1.max(x);
            z0 = z0.min(z);
            z1 = z1.max(z);
        }
        let (dx, dz) = (x1 - x0, z1 - z0);

        // The label strip extends the elevation range down by a fraction of it at most.
        let y_label_w = widest_tick_label(z0 - 0.25 * dz, z1)? + TICK_GAP as u32 + 6;
        let left = AXIS_TITLE_W + y_label_w;
        let entries = section_legend(section);
        let legend_h_max = Legend::new(entries.clone(), MIN_W)?.height;
        let has_dps = !section.drawpoints.is_empty();
        let w_max = MAX_SIDE.saturating_sub(left + SEC_RIGHT).max(120);
        let h_max = MAX_SIDE
            .saturating_sub(
                TITLE_H + SEC_TOP + SEC_BOTTOM + legend_h_max + band_px(has_dps, DP_MAX_ROWS),
            )
            .max(120);
        let scale = (f64::from(w_max - 1) / dx).min(f64::from(h_max - 1) / dz);

        let (label_rows, rows_used) = label_rows(&section.drawpoints, x0, scale)?;
        let plot_w = (dx * scale).round() as u32 + 1;
        let plot_h = (dz * scale).round() as u32 + 1 + band_px(has_dps, rows_used);
        let chart_w = left + plot_w + SEC_RIGHT;
        let title_w = text_width(&text(20.0, HPos::Center, VPos::Center), title)? as u32 + 40;
        let width = chart_w.max(MIN_W).max(title_w);
        let legend = Legend::new(entries, width)?;
        let height = TITLE_H + SEC_TOP + plot_h + SEC_BOTTOM + legend.height;
        let frame = equal_aspect_frame(width, chart_w, left, (plot_w, plot_h), scale, (x0, z1));
        Ok(SectionPlot {
            section,
            title,
            size: (width, height),
            frame,
            y_label_w,
            z_base: z0,
            label_rows,
            legend,
        })
    }
}

/// Height of the drawpoint label strip with `rows` rows of labels, px (0 without drawpoints).
fn band_px(has_drawpoints: bool, rows: usize) -> u32 {
    if has_drawpoints {
        DP_LABEL_TOP + rows as u32 * DP_LINE + 4
    } else {
        0
    }
}

/// Drawpoint label text style.
fn dp_label_style() -> TextStyle<'static> {
    text(12.0, HPos::Center, VPos::Top)
}

/// Assign each drawpoint label to a row so that labels in one row do not overlap (greedy,
/// left to right; past [`DP_MAX_ROWS`] a label goes to the row with the most room). Returns the
/// row of each drawpoint and the number of rows used.
fn label_rows(
    drawpoints: &[(f64, f64, String)],
    x0: f64,
    scale: f64,
) -> Result<(Vec<usize>, usize), DrawError> {
    let style = dp_label_style();
    let mut order: Vec<usize> = (0..drawpoints.len()).collect();
    order.sort_by(|&a, &b| drawpoints[a].0.total_cmp(&drawpoints[b].0));
    let mut right_edge = [f64::NEG_INFINITY; DP_MAX_ROWS];
    let mut rows = vec![0; drawpoints.len()];
    let mut used = 0;
    for i in order {
        let (x, _, label) = &drawpoints[i];
        if label.is_empty() || !x.is_finite() {
            continue;
        }
        let half = f64::from(text_width(&style, label)?) / 2.0;
        let px = (x - x0) * scale;
        let row = (0..DP_MAX_ROWS)
            .find(|&r| right_edge[r] + 10.0 <= px - half)
            .unwrap_or_else(|| {
                (0..DP_MAX_ROWS)
                    .min_by(|&a, &b| right_edge[a].total_cmp(&right_edge[b]))
                    .unwrap_or(0)
            });
        right_edge[row] = px + half;
        rows[i] = row;
        used = used.max(row + 1);
    }
    Ok((rows, used))
}

/// Legend entries for what a section actually holds.
fn section_legend(section: &Section) -> Vec<LegendEntry> {
    let mut entries = Vec::new();
    if !section.layers.is_empty() {
        entries.push(LegendEntry {
            sample: Sample::Layers,
            label: "Marker layers (initially horizontal)".into(),
        });
    }
    if !section.imz.is_empty() {
        entries.push(LegendEntry {
            sample: Sample::Line(IMZ_COLOUR, 3),
            label: "IMZ (isolated movement zone)".into(),
        });
    }
    if !section.iez.is_empty() {
        entries.push(LegendEntry {
            sample: Sample::Line(IEZ_COLOUR, 3),
            label: "IEZ (origin of drawn material)".into(),
        });
    }
    if !section.surface.is_empty() {
        entries.push(LegendEntry {
            sample: Sample::Line(SURFACE_COLOUR, 3),
            label: "Free surface".into(),
        });
    }
    if !section.uncaved.is_empty() {
        entries.push(LegendEntry {
            sample: Sample::Line(UNCAVED_FILL, 8),
            label: "Uncaved ground".into(),
        });
    }
    if !section.air.is_empty() {
        entries.push(LegendEntry {
            sample: Sample::Line(AIR_FILL, 8),
            label: "Air gap".into(),
        });
    }
    if !section.traces.is_empty() {
        entries.push(LegendEntry {
            sample: Sample::Line(TRACE_COLOUR, 2),
            label: "Trace point paths (dot: given position)".into(),
        });
    }
    if !section.drawpoints.is_empty() {
        entries.push(LegendEntry {
            sample: Sample::Triangle(BLACK),
            label: "Drawpoint".into(),
        });
    }
    entries
}

/// The plot frame of an equal-aspect section (`scale` px per m on both axes): a chart
/// `chart_w` px wide centred on a page `width` wide, the plot `left` px into the chart and
/// `size` px, the data's top-left corner at `(x0, y1)`. A frame of n px spans n − 1 px
/// steps, so these ranges keep exactly `scale` px/m on both axes.
pub(super) fn equal_aspect_frame(
    width: u32,
    chart_w: u32,
    left: u32,
    size: (u32, u32),
    scale: f64,
    (x0, y1): (f64, f64),
) -> Frame {
    Frame {
        left: ((width - chart_w) / 2 + left) as i32,
        top: (TITLE_H + SEC_TOP) as i32,
        size,
        x: (x0, x0 + f64::from(size.0 - 1) / scale),
        y: (y1 - f64::from(size.1 - 1) / scale, y1),
    }
}

impl Render for SectionPlot<'_> {
    fn size(&self) -> (u32, u32) {
        self.size
    }

    fn title(&self) -> &str {
        self.title
    }

    fn draw_body<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        pen: Pen,
    ) -> Result<(), DrawError>
    where
        DB::ErrorType: 'static,
    {
        let (s, f) = (self.section, &self.frame);

        let extent = [
            f.px((s.x_range.0, s.z_range.1)),
            f.px((s.x_range.1, s.z_range.0)),
        ];
        root.draw(&Rectangle::new(extent, MODEL_FILL.filled()))?;
        root.draw(&Rectangle::new(extent, FRAME_COLOUR.stroke_width(1)))?;
        for (rects, fill) in [(&s.uncaved, UNCAVED_FILL), (&s.air, AIR_FILL)] {
            for &(a, b) in rects {
                let r = [f.px((a.0, b.1)), f.px((b.0, a.1))];
                root.draw(&Rectangle::new(r, fill.filled()))?;
            }
        }
        for (i, layer) in s.layers.iter().enumerate() {
            for run in finite_runs(layer) {
                root.draw(&PathElement::new(f.path(&run), LAYER_COLOURS[i % 2]))?;
            }
        }
        for (outlines, colour) in [(&s.imz, IMZ_COLOUR), (&s.iez, IEZ_COLOUR)] {
            for run in outlines.iter().flat_map(|o| finite_runs(o)) {
                root.draw(&PathElement::new(f.path(&run), colour.stroke_width(3)))?;
            }
        }
        for run in finite_runs(&s.surface) {
            root.draw(&PathElement::new(
                f.path(&run),
                SURFACE_COLOUR.stroke_width(3),
            ))?;
        }
        for path in &s.traces {
            for run in finite_runs(path) {
                root.draw(&PathElement::new(
                    f.path(&run),
                    TRACE_COLOUR.stroke_width(2),
                ))?;
            }
            if let Some(&start) = path.first().filter(|p| p.0.is_finite() && p.1.is_finite()) {
                root.draw(&Circle::new(f.px(start), 4, TRACE_COLOUR.filled()))?;
            }
        }
        let label_style = dp_label_style();
        for ((x, z, label), &row) in s.drawpoints.iter().zip(&self.label_rows) {
            if !(x.is_finite() && z.is_finite()) {
                continue;
            }
            root.draw(&TriangleMarker::new(f.px((*x, *z)), 7, BLACK.filled()))?;
            if !label.is_empty() {
                let (lx, ly) = f.px((*x, self.z_base));
                let dy = (DP_LABEL_TOP + row as u32 * DP_LINE) as i32;
                put_text(root, label, (lx, ly + dy), &label_style, pen)?;
            }
        }

        let ticks = (x_ticks(f)?, y_ticks(f)?);
        let labels = AxisLabels { x: true, y: true };
        draw_axes(root, f, (&ticks.0, &ticks.1), labels, pen)?;
        let centre = (f.left + f.right()) / 2;
        let below = f.bottom() + SEC_BOTTOM as i32 - 14;
        put_text(
            root,
            &s.axis_label,
            (centre, below),
            &axis_title_style(false),
            pen,
        )?;
        let title_x = f.left - self.y_label_w as i32 - AXIS_TITLE_W as i32 / 2;
        let middle = (f.top + f.bottom()) / 2;
        put_text(
            root,
            "Elevation (m)",
            (title_x, middle),
            &axis_title_style(true),
            pen,
        )?;
        self.legend
            .draw(root, (self.size.1 - self.legend.height) as i32, pen)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output::charts::font_ready;
    use crate::output::charts::tests::{
        blank_png_len, colour_bbox, colours_in, files_in, frame_rect, out_dir, png_dims, render_rgb,
    };

    /// A two-drawpoint physical-model scene at the scale of the summary's IN-T2 test (700 mm
    /// spacing, 3.3 m high): drawn-down layers, IMZs, IEZs and labelled drawpoints.
    fn sample_section() -> Section {
        let axes = [0.85, 1.55];
        let imz_top = 2.6;
        let drawdown = |x: f64, z: f64| -> f64 {
            axes.iter()
                .map(|&a| {
                    if z >= imz_top {
                        return 0.0;
                    }
                    let spread = 0.04 + 0.07 * z.sqrt();
                    let depth = 0.9 * (1.0 - z / imz_top).powf(0.7);
                    depth * (-(x - a).powi(2) / (2.0 * spread * spread)).exp()
                })
                .sum()
        };
        let layers = (1..33)
            .map(|k| {
                let z = k as f64 * 0.1;
                (0..=120)
                    .map(|i| {
                        let x = i as f64 * 0.02;
                        (x, (z - drawdown(x, z)).max(0.0))
                    })
                    .collect()
            })
            .collect();
        let imz = axes
            .iter()
            .map(|&a| {
                let disks: Vec<(f64, f64, f64)> = (0..52)
                    .map(|i| {
                        let zb = i as f64 * 0.05;
                        (zb, zb + 0.05, 0.06 + 0.1 * (zb + 0.025).sqrt())
                    })
                    .collect();
                imz_outline(&disks, a)
            })
            .collect();
        let iez = axes
            .iter()
            .map(|&a| {
                let origins: Vec<(f64, f64)> = (0..60)
                    .flat_map(|i| {
                        let z = i as f64 * 0.02;
                        let w = 0.05 + 0.06 * z.sqrt();
                        [(a - w, z), (a + w * 0.9, z)]
                    })
                    .collect();
                iez_outline(&origins, a, 0.1)
            })
            .collect();
        Section {
            axis_label: "Easting (m)".into(),
            x_range: (0.0, 2.4),
            z_range: (0.0, 3.3),
            layers,
            imz,
            iez,
            drawpoints: vec![
                (0.85, 0.0, "DP1: 0.412 t".into()),
                (1.55, 0.0, "DP2: 0.398 t".into()),
            ],
            surface: vec![(0.0, 3.3), (1.0, 3.3), (1.2, 3.0), (1.4, 3.3), (2.4, 3.3)],
            uncaved: vec![((1.8, 2.8), (2.4, 3.3))],
            air: vec![((1.8, 2.5), (2.4, 2.8))],
            traces: Vec::new(),
        }
    }

    #[test]
    fn imz_outline_of_two_disks_is_the_closed_stair() {
        let disks = [(1.0, 2.0, 1.0), (0.0, 1.0, 2.0)]; // unsorted on purpose
        let outline = imz_outline(&disks, 10.0);
        let expected = vec![
            (12.0, 0.0),
            (12.0, 1.0),
            (11.0, 1.0),
            (11.0, 2.0),
            (9.0, 2.0),
            (9.0, 1.0),
            (8.0, 1.0),
            (8.0, 0.0),
            (12.0, 0.0),
        ];
        assert_eq!(outline, expected);
    }

    #[test]
    fn imz_outline_skips_empty_disks_and_merges_equal_radii() {
        let disks = [
            (0.0, 1.0, 2.0),
            (1.0, 2.0, 2.0),
            (2.0, 3.0, 0.0),
            (3.0, 4.0, f64::NAN),
        ];
        let outline = imz_outline(&disks, 0.0);
        assert_eq!(
            outline,
            vec![
                (2.0, 0.0),
                (2.0, 1.0),
                (2.0, 2.0),
                (-2.0, 2.0),
                (-2.0, 1.0),
                (-2.0, 0.0),
                (2.0, 0.0)
            ]
        );
        assert!(imz_outline(&[(0.0, 1.0, 0.0)], 5.0).is_empty());
        assert!(imz_outline(&[], 5.0).is_empty());
    }

    #[test]
    fn iez_outline_of_symmetric_points_is_symmetric_and_closed() {
        let a = 5.0;
        let points = [
            (a - 1.0, 0.5),
            (a + 1.0, 0.2),
            (a + 0.5, 0.7),
            (a - 2.0, 1.5),
            (a + 2.0, 1.1),
            (f64::NAN, 1.0),
        ];
        let outline = iez_outline(&points, a, 1.0);
        let expected = vec![
            (6.0, 0.0),
            (6.0, 1.0),
            (7.0, 1.0),
            (7.0, 2.0),
            (3.0, 2.0),
            (3.0, 1.0),
            (4.0, 1.0),
            (4.0, 0.0),
            (6.0, 0.0),
        ];
        assert_eq!(outline, expected);
        // Mirror symmetry about the axis: every point has its mirror image on the outline.
        for &(x, z) in &outline {
            assert!(outline.contains(&(2.0 * a - x, z)));
        }
    }

    #[test]
    fn iez_outline_bins_at_multiples_of_bin_and_rejects_bad_bins() {
        // Bin 0.5 at z = -0.2 covers [-0.5, 0); a gap bin is joined across.
        let outline = iez_outline(&[(1.0, -0.2), (0.5, 1.2)], 0.0, 0.5);
        assert_eq!(
            outline,
            vec![
                (1.0, -0.5),
                (1.0, 0.0),
                (0.5, 1.0),
                (0.5, 1.5),
                (-0.5, 1.5),
                (-0.5, 1.0),
                (-1.0, 0.0),
                (-1.0, -0.5),
                (1.0, -0.5)
            ]
        );
        assert!(iez_outline(&[(1.0, 1.0)], 0.0, 0.0).is_empty());
        assert!(iez_outline(&[(1.0, 1.0)], 0.0, f64::NAN).is_empty());
        assert!(iez_outline(&[], 0.0, 1.0).is_empty());
    }

    #[test]
    fn section_chart_writes_png_and_svg() {
        let (_keep, dir) = out_dir("section");
        let section = sample_section();
        let title = "IN-T2: drawdown after 0.81 t drawn (synthetic)";
        let png = dir.join("section.png");
        let svg = dir.join("section.svg");
        section_chart(&png, &section, title).unwrap();
        section_chart(&svg, &section, title).unwrap();

        let layout = SectionPlot::new(&section, title).ok().unwrap();
        let bytes = std::fs::read(&png).unwrap();
        assert_eq!(png_dims(&bytes), layout.size);
        assert!(
            layout.size.0 <= MAX_SIDE && layout.size.1 <= MAX_SIDE,
            "{:?}",
            layout.size
        );
        assert!(bytes.len() as u64 > 3 * blank_png_len(&dir, layout.size));

        let svg_text = std::fs::read_to_string(&svg).unwrap();
        assert!(svg_text.starts_with("<svg"));
        assert!(svg_text.contains("Elevation (m)") && svg_text.contains("Easting (m)"));
        assert!(svg_text.contains("DP1: 0.412 t"));

        // No temporary file is left behind.
        let files = files_in(&dir);
        assert!(files.iter().all(|f| !f.contains(".tmp-")), "{files:?}");
    }

    #[test]
    fn section_plot_area_holds_the_drawing_at_equal_aspect() {
        assert!(font_ready());
        let section = sample_section();
        let layout = SectionPlot::new(&section, "t").ok().unwrap();
        let buf = render_rgb(&layout);
        let (w, _) = layout.size;
        let colours = colours_in(&buf, w, frame_rect(&layout.frame));
        for c in [
            IMZ_COLOUR,
            IEZ_COLOUR,
            LAYER_COLOURS[0],
            LAYER_COLOURS[1],
            MODEL_FILL,
        ] {
            assert!(colours.contains(&[c.0, c.1, c.2]), "plot area lacks {c:?}");
        }
        assert!(colours.len() > 10, "{} colours", colours.len());

        // A 10 m × 6 m rectangle as the only IMZ outline keeps its proportions in pixels.
        let rect = Section {
            axis_label: "Northing (m)".into(),
            x_range: (0.0, 40.0),
            z_range: (100.0, 130.0),
            imz: vec![vec![
                (15.0, 110.0),
                (25.0, 110.0),
                (25.0, 116.0),
                (15.0, 116.0),
                (15.0, 110.0),
            ]],
            ..Section::default()
        };
        let layout = SectionPlot::new(&rect, "aspect").ok().unwrap();
        let buf = render_rgb(&layout);
        let (x0, y0, x1, y1) = colour_bbox(&buf, layout.size.0, &layout.frame, IMZ_COLOUR).unwrap();
        let (bw, bh) = (f64::from(x1 - x0), f64::from(y1 - y0));
        // Both extents include the 3 px stroke once.
        let (mw, mh) = (bw - 2.0, bh - 2.0);
        assert!((mw / mh - 10.0 / 6.0).abs() < 0.03, "{bw} × {bh} px");
        // The 40 m wide, 30 m high model fills the width budget or the height budget.
        let f = layout.frame;
        assert!(f.size.0 > 600, "{f:?}");
        let per_m = (
            f64::from(f.size.0 - 1) / (f.x.1 - f.x.0),
            f64::from(f.size.1 - 1) / (f.y.1 - f.y.0),
        );
        assert!((per_m.0 - per_m.1).abs() < 1e-9, "{per_m:?}");
    }

    #[test]
    fn section_chart_rejects_bad_input_and_unknown_formats() {
        let (_keep, dir) = out_dir("section-errors");
        let mut section = sample_section();
        let err = section_chart(&dir.join("s.pdf"), &section, "t").unwrap_err();
        assert!(matches!(err, ChartError::Format { .. }), "{err}");
        section.z_range = (3.0, 3.0);
        let err = section_chart(&dir.join("s.png"), &section, "t").unwrap_err();
        assert!(matches!(err, ChartError::Input { .. }), "{err}");
        assert!(err.to_string().contains("s.png"), "{err}");

        // A missing directory fails with the path named and nothing left behind.
        let err = section_chart(&dir.join("missing/s.png"), &sample_section(), "t").unwrap_err();
        assert!(err.to_string().contains("missing"), "{err}");
        assert!(files_in(&dir).is_empty(), "{:?}", files_in(&dir));
    }
}
