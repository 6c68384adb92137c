//! Curves overlaid on one pair of linear axes, one colour per series with a legend: the
//! study report's grade–tonnage and recovery–dilution curves, a variant per series.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use super::{
    axis_titles, draw_axes, draw_grid, ensure_font, finite_runs, series_colour, write_chart,
    x_ticks, y_ticks, AxisLabels, ChartError, DrawError, Frame, IntoChartError, Legend,
    LegendEntry, Pen, Render, Sample, AXIS_COLOUR, TITLE_H,
};

/// One curve.
#[derive(Debug, Clone, PartialEq)]
pub struct LineSeries {
    /// Legend label.
    pub name: String,
    /// (x, y) in drawing order; a non-finite point breaks the line.
    pub points: Vec<(f64, f64)>,
}

const WIDTH: u32 = 680;
const PLOT_H: u32 = 380;
const LEFT: i32 = 80;
const RIGHT: i32 = 30;
const BOTTOM: i32 = 60;

/// Draws `series` on shared axes that hold every finite point, to `path` (`.png` or
/// `.svg`), atomically.
pub fn line_chart(
    path: &Path,
    series: &[LineSeries],
    title: &str,
    x_label: &str,
    y_label: &str,
) -> Result<(), ChartError> {
    ensure_font(path)?;
    let (mut x, mut y) = (
        (f64::INFINITY, f64::NEG_INFINITY),
        (f64::INFINITY, f64::NEG_INFINITY),
    );
    for &(px, py) in series.iter().flat_map(|s| &s.points) {
        if px.is_finite() && py.is_finite() {
            x = (x.0.min(px), x.1.max(px));
            y = (y.0.min(py), y.1.max(py));
        }
    }
    let pad = |(lo, hi): (f64, f64)| {
        if !lo.is_finite() {
            (0.0, 1.0)
        } else if hi > lo {
            (lo - 0.03 * (hi - lo), hi + 0.03 * (hi - lo))
        } else {
            (lo - 0.5, hi + 0.5)
        }
    };
    let entries: Vec<LegendEntry> = series
        .iter()
        .enumerate()
        .map(|(k, s)| LegendEntry {
            sample: Sample::Line(series_colour(k), 2),
            label: s.name.clone().into(),
        })
        .collect();
    let legend = Legend::new(entries, WIDTH).map_err(|e| e.into_chart_error(path))?;
    let top = TITLE_H as i32 + legend.height as i32 + 10;
    write_chart(
        path,
        &Lines {
            series: series.to_vec(),
            frame: Frame {
                left: LEFT,
                top,
                size: (WIDTH - LEFT as u32 - RIGHT as u32, PLOT_H),
                x: pad(x),
                y: pad(y),
            },
            legend,
            title: title.to_string(),
            labels: (x_label.to_string(), y_label.to_string()),
        },
    )
}

struct Lines {
    series: Vec<LineSeries>,
    frame: Frame,
    legend: Legend,
    title: String,
    labels: (String, String),
}

impl Render for Lines {
    fn size(&self) -> (u32, u32) {
        (WIDTH, self.frame.bottom() as u32 + BOTTOM as u32)
    }

    fn title(&self) -> &str {
        &self.title
    }

    fn draw_body<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        pen: Pen,
    ) -> Result<(), DrawError>
    where
        DB::ErrorType: 'static,
    {
        self.legend.draw(root, TITLE_H as i32, pen)?;
        let f = &self.frame;
        let (xt, yt) = (x_ticks(f)?, y_ticks(f)?);
        draw_grid(root, f, (&xt, &yt))?;
        for (k, s) in self.series.iter().enumerate() {
            let colour = series_colour(k);
            for run in finite_runs(&s.points) {
                root.draw(&PathElement::new(f.path(&run), colour.stroke_width(2)))?;
            }
        }
        draw_axes(root, f, (&xt, &yt), AxisLabels { x: true, y: true }, pen)?;
        root.draw(&Rectangle::new(
            [(f.left, f.top), (f.right(), f.bottom())],
            AXIS_COLOUR,
        ))?;
        axis_titles(root, f, (&self.labels.0, &self.labels.1), 42, pen)?;
        Ok(())
    }
}
