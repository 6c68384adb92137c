//! Stress sections (summary Figs 24–25): a stress grid drawn as coloured cells on a section,
//! with IMZ outlines, drawpoints and red lines at the levels flagged for potential
//! stress-driven flow of stagnant ground (interactive draw).
//!
//! A child of [`charts`](super) so it shares the bundled font, the glyph-by-glyph text, the
//! axes, the legend and the atomic writer. The colour map is viridis (perceptually uniform,
//! readable in grey and by colour-blind readers), low stresses dark blue, high yellow; the
//! scale starts at 0 kPa so the low stresses inside IMZs read as such.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::section::equal_aspect_frame;
use super::{
    axis_title_style, draw_axes, ensure_font, finite_runs, nice_ticks, put_text, text, text_width,
    tick_style, widest_tick_label, write_chart, x_ticks, y_ticks, AxisLabels, ChartError,
    DrawError, Frame, Legend, LegendEntry, Pen, Render, Sample, FRAME_COLOUR, IMZ_COLOUR, MAX_SIDE,
    MIN_W, TICK, TICK_GAP, TITLE_H,
};
use super::{AXIS_COLOUR, AXIS_TITLE_W, DP_LINE, SEC_BOTTOM, SEC_RIGHT, SEC_TOP};

/// Flagged levels (potential interactive draw): red, as in the summary's Figs 24–25.
const FLAG_COLOUR: RGBColor = RGBColor(220, 20, 20);
/// Uncaved ground.
const UNCAVED_COLOUR: RGBColor = RGBColor(205, 205, 205);
/// Colour bar: gap from the plot (holding the flag marks), bar width, room for its labels;
/// px.
const BAR_GAP: u32 = 26;
const BAR_W: u32 = 18;
const BAR_LABELS: u32 = 70;
/// Drawpoint labels hang this far below the plot (under the tick labels); the strip they
/// take; px.
const DP_LABEL_Y: i32 = 28;
const DP_STRIP: u32 = DP_LABEL_Y as u32 + DP_LINE - 4;
/// Flag marks right of the plot: gap and length, px.
const FLAG_MARK: (i32, i32) = (3, 14);

/// Viridis at nine stops (matplotlib's table, every 32nd entry).
const VIRIDIS: [(u8, u8, u8); 9] = [
    (68, 1, 84),
    (71, 44, 122),
    (59, 81, 139),
    (44, 113, 142),
    (33, 144, 141),
    (39, 173, 129),
    (92, 200, 99),
    (170, 220, 50),
    (253, 231, 37),
];

/// Viridis colour of t in [0, 1] (clamped), linear between the stops.
pub fn viridis(t: f64) -> RGBColor {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let x = t * (VIRIDIS.len() - 1) as f64;
    let i = (x.floor() as usize).min(VIRIDIS.len() - 2);
    let f = x - i as f64;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    let mix = |p: u8, q: u8| (f64::from(p) + f * (f64::from(q) - f64::from(p))).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// A stress section to draw.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StressChart {
    /// Title.
    pub title: String,
    /// Horizontal axis label with unit.
    pub u_label: String,
    /// Vertical axis label with unit.
    pub v_label: String,
    /// Model extent along the axes, m.
    pub u_range: (f64, f64),
    /// Model extent along the axes, m.
    pub v_range: (f64, f64),
    /// Grid spacing, m: each point is drawn as a cell this size centred on it.
    pub cell: f64,
    /// Grid points (u, v), m.
    pub points: Vec<(f64, f64)>,
    /// Value per point, kPa (NaN: uncaved, drawn grey).
    pub values: Vec<f64>,
    /// IMZ outlines (closed polylines).
    pub outlines: Vec<Vec<(f64, f64)>>,
    /// Drawpoints (u, v, label); labels are set below the plot.
    pub drawpoints: Vec<(f64, f64, String)>,
    /// Elevations of flagged levels: each is marked red right of the plot, and each run of
    /// consecutive flagged levels (a band) is bounded by red lines across the section (one
    /// line per level would hatch over the stress when levels are a few pixels apart).
    pub flagged: Vec<f64>,
}

/// Draws a stress section to `path` (`.png` or `.svg`): 1 m across is 1 m up.
pub fn stress_chart(path: &Path, chart: &StressChart) -> Result<(), ChartError> {
    ensure_font(path)?;
    let input = |message: String| ChartError::Input {
        path: path.to_path_buf(),
        message,
    };
    let ok = |r: (f64, f64)| r.0.is_finite() && r.1.is_finite() && r.1 > r.0;
    if !(ok(chart.u_range) && ok(chart.v_range) && chart.cell > 0.0) {
        return Err(input(format!(
            "stress section ranges {:?} {:?} or cell {} cannot be drawn",
            chart.u_range, chart.v_range, chart.cell
        )));
    }
    if chart.points.len() != chart.values.len() {
        return Err(input(
            "stress section points and values differ in length".into(),
        ));
    }
    let plot = StressPlot::new(chart).map_err(|e| ChartError::Draw {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    write_chart(path, &plot)
}

/// A stress section laid out in pixels.
struct StressPlot<'a> {
    chart: &'a StressChart,
    size: (u32, u32),
    frame: Frame,
    y_label_w: u32,
    /// Colour scale top, kPa.
    vmax: f64,
    legend: Legend,
}

impl<'a> StressPlot<'a> {
    fn new(chart: &'a StressChart) -> Result<Self, DrawError> {
        let (u0, u1) = chart.u_range;
        let (v0, v1) = chart.v_range;
        let (du, dv) = (u1 - u0, v1 - v0);
        let finite_max = chart
            .values
            .iter()
            .copied()
            .filter(|v| v.is_finite())
            .fold(0.0f64, f64::max);
        let vmax = nice_ticks(0.0, finite_max.max(1e-9), 5)
            .values
            .last()
            .copied()
            .filter(|&t| t >= finite_max)
            .unwrap_or(finite_max * 1.05)
            .max(1e-9);
        let strip = if chart.drawpoints.iter().any(|d| !d.2.is_empty()) {
            DP_STRIP
        } else {
            0
        };
        let y_label_w = widest_tick_label(v0, v1)? + TICK_GAP as u32 + 6;
        let left = AXIS_TITLE_W + y_label_w;
        let right = BAR_GAP + BAR_W + BAR_LABELS + SEC_RIGHT;
        let mut entries = vec![LegendEntry {
            sample: Sample::Line(IMZ_COLOUR, 3),
            label: "IMZ".into(),
        }];
        if !chart.flagged.is_empty() {
            entries.push(LegendEntry {
                sample: Sample::Line(FLAG_COLOUR, 2),
                label: "Levels with potential stress-driven flow (interactive draw)".into(),
            });
        }
        entries.push(LegendEntry {
            sample: Sample::Line(UNCAVED_COLOUR, 8),
            label: "Uncaved".into(),
        });
        let legend_h = Legend::new(entries.clone(), MIN_W)?.height;
        let w_max = MAX_SIDE.saturating_sub(left + right).max(120);
        let h_max = MAX_SIDE
            .saturating_sub(TITLE_H + SEC_TOP + SEC_BOTTOM + strip + legend_h)
            .max(120);
        let scale = (f64::from(w_max - 1) / du).min(f64::from(h_max - 1) / dv);
        let plot_w = (du * scale).round() as u32 + 1;
        let plot_h = (dv * scale).round() as u32 + 1;
        let chart_w = left + plot_w + right;
        let title_w =
            text_width(&text(20.0, HPos::Center, VPos::Center), &chart.title)? as u32 + 40;
        let width = chart_w.max(MIN_W).max(title_w);
        let legend = Legend::new(entries, width)?;
        let height = TITLE_H + SEC_TOP + plot_h + strip + SEC_BOTTOM + legend.height;
        let frame = equal_aspect_frame(width, chart_w, left, (plot_w, plot_h), scale, (u0, v1));
        Ok(StressPlot {
            chart,
            size: (width, height),
            frame,
            y_label_w,
            vmax,
            legend,
        })
    }
}

impl Render for StressPlot<'_> {
    fn size(&self) -> (u32, u32) {
        self.size
    }

    fn title(&self) -> &str {
        &self.chart.title
    }

    fn draw_body<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        pen: Pen,
    ) -> Result<(), DrawError>
    where
        DB::ErrorType: 'static,
    {
        let (c, f) = (self.chart, &self.frame);
        let h = 0.5 * c.cell;
        for (&(u, v), &val) in c.points.iter().zip(&c.values) {
            let colour = if val.is_finite() {
                viridis(val / self.vmax)
            } else {
                UNCAVED_COLOUR
            };
            let a = f.px((u - h, v + h));
            let b = f.px((u + h, v - h));
            // One pixel of overlap: neighbours' shared edges may round apart.
            root.draw(&Rectangle::new([a, (b.0 + 1, b.1 + 1)], colour.filled()))?;
        }
        let extent = [
            f.px((c.u_range.0, c.v_range.1)),
            f.px((c.u_range.1, c.v_range.0)),
        ];
        root.draw(&Rectangle::new(extent, FRAME_COLOUR.stroke_width(1)))?;
        for (lo, hi) in flag_bands(&c.flagged, c.cell) {
            for z in [lo, hi] {
                let line = vec![f.px((c.u_range.0, z)), f.px((c.u_range.1, z))];
                root.draw(&PathElement::new(line, FLAG_COLOUR.stroke_width(2)))?;
            }
        }
        for &z in &c.flagged {
            let (a, b) = (f.px((c.u_range.1, z + h)), f.px((c.u_range.1, z - h)));
            let x = f.right() + FLAG_MARK.0;
            root.draw(&Rectangle::new(
                [(x, a.1), (x + FLAG_MARK.1, b.1.max(a.1 + 1))],
                FLAG_COLOUR.filled(),
            ))?;
        }
        // Outlines are clamped to the model extent (a mine-scale IMZ may be wider).
        let clamp = |(u, v): (f64, f64)| {
            (
                u.clamp(c.u_range.0, c.u_range.1),
                v.clamp(c.v_range.0, c.v_range.1),
            )
        };
        for run in c.outlines.iter().flat_map(|o| finite_runs(o)) {
            let run: Vec<(f64, f64)> = run.into_iter().map(clamp).collect();
            root.draw(&PathElement::new(f.path(&run), IMZ_COLOUR.stroke_width(3)))?;
        }
        let label_style = text(12.0, HPos::Center, VPos::Top);
        for (u, v, label) in &c.drawpoints {
            root.draw(&TriangleMarker::new(f.px((*u, *v)), 7, BLACK.filled()))?;
            if !label.is_empty() {
                let (lx, _) = f.px((*u, *v));
                put_text(
                    root,
                    label,
                    (lx, f.bottom() + DP_LABEL_Y),
                    &label_style,
                    pen,
                )?;
            }
        }
        let ticks = (x_ticks(f)?, y_ticks(f)?);
        draw_axes(
            root,
            f,
            (&ticks.0, &ticks.1),
            AxisLabels { x: true, y: true },
            pen,
        )?;
        let strip = if c.drawpoints.iter().any(|d| !d.2.is_empty()) {
            DP_STRIP as i32
        } else {
            0
        };
        let centre = (f.left + f.right()) / 2;
        let below = f.bottom() + strip + SEC_BOTTOM as i32 - 14;
        put_text(
            root,
            &c.u_label,
            (centre, below),
            &axis_title_style(false),
            pen,
        )?;
        let title_x = f.left - self.y_label_w as i32 - AXIS_TITLE_W as i32 / 2;
        let middle = (f.top + f.bottom()) / 2;
        put_text(
            root,
            &c.v_label,
            (title_x, middle),
            &axis_title_style(true),
            pen,
        )?;

        // Colour bar with its ticks, kPa.
        let bx = f.right() + BAR_GAP as i32;
        let (top, bottom) = (f.top, f.bottom());
        let span = (bottom - top).max(1);
        for y in top..=bottom {
            let t = f64::from(bottom - y) / f64::from(span);
            root.draw(&PathElement::new(
                vec![(bx, y), (bx + BAR_W as i32, y)],
                viridis(t),
            ))?;
        }
        root.draw(&Rectangle::new(
            [(bx, top), (bx + BAR_W as i32, bottom)],
            AXIS_COLOUR.stroke_width(1),
        ))?;
        let style = tick_style(HPos::Left, VPos::Center);
        let bar_ticks = nice_ticks(0.0, self.vmax, 6);
        for (&v, label) in bar_ticks.values.iter().zip(&bar_ticks.labels) {
            let y = bottom - (v / self.vmax * f64::from(span)).round() as i32;
            let x1 = bx + BAR_W as i32;
            root.draw(&PathElement::new(
                vec![(x1, y), (x1 + TICK, y)],
                AXIS_COLOUR,
            ))?;
            put_text(root, label, (x1 + TICK_GAP, y), &style, pen)?;
        }
        put_text(
            root,
            "kPa",
            (bx, top - 4),
            &text(12.0, HPos::Left, VPos::Bottom),
            pen,
        )?;
        self.legend
            .draw(root, (self.size.1 - self.legend.height) as i32, pen)
    }
}

/// Runs of consecutive flagged levels (no more than 1.5 cells apart) as (bottom, top) of the
/// slices they span, m.
fn flag_bands(levels: &[f64], cell: f64) -> Vec<(f64, f64)> {
    let mut sorted: Vec<f64> = levels.iter().copied().filter(|z| z.is_finite()).collect();
    sorted.sort_by(f64::total_cmp);
    let mut bands: Vec<(f64, f64)> = Vec::new();
    for z in sorted {
        match bands.last_mut() {
            Some(b) if z - (b.1 - 0.5 * cell) <= 1.5 * cell => b.1 = z + 0.5 * cell,
            _ => bands.push((z - 0.5 * cell, z + 0.5 * cell)),
        }
    }
    bands
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn viridis_ends_and_clamps() {
        assert_eq!(viridis(0.0), RGBColor(68, 1, 84));
        assert_eq!(viridis(1.0), RGBColor(253, 231, 37));
        assert_eq!(viridis(-3.0), viridis(0.0));
        assert_eq!(viridis(f64::NAN), viridis(0.0));
        assert_eq!(viridis(0.5), RGBColor(33, 144, 141));
    }

    #[test]
    fn flagged_levels_group_into_bands() {
        let b = flag_bands(&[0.3, 0.1, 0.2, 0.6, 0.7], 0.1);
        assert_eq!(b.len(), 2);
        assert!((b[0].0 - 0.05).abs() < 1e-12 && (b[0].1 - 0.35).abs() < 1e-12);
        assert!((b[1].0 - 0.55).abs() < 1e-12 && (b[1].1 - 0.75).abs() < 1e-12);
        assert!(flag_bands(&[], 0.1).is_empty());
    }
}
