//! A histogram: how a quantity is distributed over many rows (the run report's mass-balance
//! correction per drawpoint-period), as bars on a linear axis with labelled vertical guide
//! lines (for the correction: 1, and the 1 ± 0.03 band the run warns outside).
//!
//! The axis spans the 1st to the 99th percentile of the values, widened to hold the guides,
//! in [`BINS`] equal bins; the few values beyond it are counted in the caption rather than
//! stretching the axis until the bulk of the distribution is one bar.

use std::path::Path;

use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::{
    axis_titles, draw_axes, draw_grid, ensure_font, put_text, text, write_chart, x_ticks, y_ticks,
    AxisLabels, ChartError, DrawError, Frame, Pen, Render, AXIS_COLOUR, PREDICTED_COLOUR,
    SAMPLED_COLOUR, TITLE_H,
};

/// Bars on the axis.
pub const BINS: usize = 40;

const WIDTH: u32 = 760;
const HEIGHT: u32 = 460;
const LEFT: i32 = 80;
const RIGHT: i32 = 30;
const BOTTOM: i32 = 90;

/// Draws the histogram of the finite `values` to `path` (`.png` or `.svg`), atomically, with a
/// dashed vertical line and its label at each of `guides`.
pub fn histogram_chart(
    path: &Path,
    values: &[f64],
    title: &str,
    value_label: &str,
    guides: &[(f64, &str)],
) -> Result<(), ChartError> {
    ensure_font(path)?;
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    let q = |p: f64| v[((v.len() - 1) as f64 * p).round() as usize];
    let (mut lo, mut hi) = if v.is_empty() {
        (0.0, 1.0)
    } else {
        (q(0.01), q(0.99))
    };
    for &(g, _) in guides {
        (lo, hi) = (lo.min(g), hi.max(g));
    }
    if hi <= lo {
        (lo, hi) = (lo - 0.5, hi + 0.5);
    }
    let pad = 0.04 * (hi - lo);
    (lo, hi) = (lo - pad, hi + pad);
    let width = (hi - lo) / BINS as f64;
    let mut counts = vec![0u64; BINS];
    let (mut below, mut above) = (0, 0);
    for &x in &v {
        if x < lo {
            below += 1;
        } else if x >= hi {
            above += 1;
        } else {
            counts[(((x - lo) / width) as usize).min(BINS - 1)] += 1;
        }
    }
    let top = counts.iter().copied().max().unwrap_or(0).max(1) as f64 * 1.1;
    write_chart(
        path,
        &Histogram {
            counts,
            edges: (lo, hi),
            outside: (below, above),
            total: v.len(),
            guides: guides.iter().map(|&(g, l)| (g, l.to_string())).collect(),
            frame: Frame {
                left: LEFT,
                top: TITLE_H as i32 + 30,
                size: (
                    WIDTH - LEFT as u32 - RIGHT as u32,
                    HEIGHT - TITLE_H - 30 - BOTTOM as u32,
                ),
                x: (lo, hi),
                y: (0.0, top),
            },
            title: title.to_string(),
            value_label: value_label.to_string(),
        },
    )
}

struct Histogram {
    counts: Vec<u64>,
    edges: (f64, f64),
    /// Values below and above the axis.
    outside: (usize, usize),
    total: usize,
    guides: Vec<(f64, String)>,
    frame: Frame,
    title: String,
    value_label: String,
}

impl Render for Histogram {
    fn size(&self) -> (u32, u32) {
        (WIDTH, HEIGHT)
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
        let f = &self.frame;
        let (xt, yt) = (x_ticks(f)?, y_ticks(f)?);
        draw_grid(root, f, (&xt, &yt))?;
        let w = (self.edges.1 - self.edges.0) / self.counts.len() as f64;
        for (k, &n) in self.counts.iter().enumerate() {
            if n == 0 {
                continue;
            }
            let x0 = self.edges.0 + k as f64 * w;
            let (a, b) = (f.px((x0, 0.0)), f.px((x0 + w, n as f64)));
            root.draw(&Rectangle::new(
                [(a.0, b.1), (b.0 - 1, a.1)],
                PREDICTED_COLOUR.filled(),
            ))?;
        }
        let label = text(12.0, HPos::Center, VPos::Bottom);
        for (k, (g, name)) in self.guides.iter().enumerate() {
            let (a, b) = (f.px((*g, f.y.0)), f.px((*g, f.y.1)));
            root.draw(&DashedPathElement::new(
                vec![a, b],
                5,
                4,
                SAMPLED_COLOUR.stroke_width(2),
            ))?;
            // Alternate heights so that close guides keep their labels apart.
            put_text(
                root,
                name,
                (a.0, b.1 - 4 - 14 * (k as i32 % 2)),
                &label,
                pen,
            )?;
        }
        draw_axes(root, f, (&xt, &yt), AxisLabels { x: true, y: true }, pen)?;
        axis_titles(root, f, (&self.value_label, "Rows"), 40, pen)?;
        let caption = format!(
            "{} rows; {} below the axis, {} above it",
            self.total, self.outside.0, self.outside.1
        );
        put_text(
            root,
            &caption,
            (f.left, f.bottom() + 70),
            &text(12.0, HPos::Left, VPos::Center),
            pen,
        )?;
        root.draw(&Rectangle::new(
            [(f.left, f.top), (f.right(), f.bottom())],
            AXIS_COLOUR,
        ))?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output::charts::tests::out_dir;

    /// Values beyond the 1st–99th percentile axis are counted, not drawn, and every finite
    /// value is either in a bar or counted outside.
    #[test]
    fn values_are_binned_or_counted_outside() {
        let (_tmp, dir) = out_dir("histogram");
        let mut values: Vec<f64> = (0..1000)
            .map(|k| 0.9 + 0.2 * f64::from(k) / 999.0)
            .collect();
        values.extend([0.1, 2.0, f64::NAN]);
        let path = dir.join("h.svg");
        histogram_chart(&path, &values, "c", "correction", &[(1.0, "1")]).unwrap();
        let svg = std::fs::read_to_string(&path).unwrap();
        // Axis 0.894–1.106 (1st and 99th percentiles, 0.902 and 1.098, padded by 4%).
        assert!(
            svg.contains("1002 rows; 1 below the axis, 1 above it"),
            "caption missing"
        );
    }
}
