//! The speed–accuracy chart: grade error against wall time for every run of a sweep, on log
//! axes, with the Pareto front joined, the default marked, the 1% target and the reference
//! run's time (and a tenth of it) drawn as guides.

use std::path::Path;

use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::stability::log_ticks;
use super::{
    axis_title_style, ensure_font, put_text, text, write_chart, ChartError, DrawError, Pen, Render,
    AXIS_COLOUR, GRID_COLOUR, PREDICTED_COLOUR, SAMPLED_COLOUR, TICK, TICK_GAP, TITLE_H,
};

/// One run on the chart.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepPoint {
    /// Wall time, s.
    pub wall_s: f64,
    /// Relative error (0.01 = 1%).
    pub error: f64,
    /// Short label (the multipliers).
    pub label: String,
    /// On the Pareto front.
    pub pareto: bool,
    /// The default resolution.
    pub is_default: bool,
    /// The automatic resolution for the accuracy target (`engine::resolution`).
    pub is_auto: bool,
}

const WIDTH: u32 = 960;
const HEIGHT: u32 = 680;
const LEFT: i32 = 100;
const RIGHT: i32 = 30;
const BOTTOM: i32 = 120;
/// Grey of the runs off the front.
const OFF_FRONT: RGBColor = RGBColor(150, 150, 150);

/// Draws the chart to `path` (`.png` or `.svg`), atomically. `ref_wall` is the reference run's
/// wall time (NaN: not drawn). Points with a non-positive or non-finite error or time are
/// left off (a log axis cannot show them).
pub fn sweep_chart(
    path: &Path,
    points: &[SweepPoint],
    ref_wall: f64,
    title: &str,
) -> Result<(), ChartError> {
    ensure_font(path)?;
    let shown: Vec<SweepPoint> = points
        .iter()
        .filter(|p| p.wall_s > 0.0 && p.error > 0.0 && p.wall_s.is_finite() && p.error.is_finite())
        .cloned()
        .collect();
    let mut x = (f64::INFINITY, f64::NEG_INFINITY);
    let mut y = (0.01f64, 0.01f64);
    for p in &shown {
        x = (x.0.min(p.wall_s), x.1.max(p.wall_s));
        y = (y.0.min(p.error), y.1.max(p.error));
    }
    if ref_wall.is_finite() && ref_wall > 0.0 {
        x = (x.0.min(ref_wall / 10.0), x.1.max(ref_wall));
    }
    if !x.0.is_finite() {
        x = (0.1, 10.0);
    }
    write_chart(
        path,
        &SweepPlot {
            points: shown,
            ref_wall,
            x: (x.0 / 1.5, x.1 * 1.5),
            y: (y.0 / 1.5, y.1 * 1.5),
            title: title.to_string(),
        },
    )
}

struct SweepPlot {
    points: Vec<SweepPoint>,
    ref_wall: f64,
    x: (f64, f64),
    y: (f64, f64),
    title: String,
}

impl SweepPlot {
    fn px(&self, (vx, vy): (f64, f64)) -> (i32, i32) {
        let (l, r) = (LEFT, WIDTH as i32 - RIGHT);
        let (t, b) = (TITLE_H as i32 + 10, HEIGHT as i32 - BOTTOM);
        let fx = (vx.ln() - self.x.0.ln()) / (self.x.1.ln() - self.x.0.ln());
        let fy = (vy.ln() - self.y.0.ln()) / (self.y.1.ln() - self.y.0.ln());
        (
            l + (fx * f64::from(r - l)).round() as i32,
            b - (fy * f64::from(b - t)).round() as i32,
        )
    }
}

impl Render for SweepPlot {
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
        let (l, r) = (LEFT, WIDTH as i32 - RIGHT);
        let (t, b) = (TITLE_H as i32 + 10, HEIGHT as i32 - BOTTOM);
        let xt = log_ticks(self.x.0, self.x.1);
        let yt = log_ticks(self.y.0, self.y.1);
        for (v, _) in &xt {
            let px = self.px((*v, self.y.0)).0;
            root.draw(&PathElement::new(vec![(px, t), (px, b)], GRID_COLOUR))?;
        }
        for (v, _) in &yt {
            let py = self.px((self.x.0, *v)).1;
            root.draw(&PathElement::new(vec![(l, py), (r, py)], GRID_COLOUR))?;
        }
        // Guides: the 1% target, the reference's time and a tenth of it.
        let label = text(12.0, HPos::Left, VPos::Bottom);
        let py = self.px((self.x.0, 0.01)).1;
        root.draw(&DashedPathElement::new(
            vec![(l, py), (r, py)],
            6,
            4,
            SAMPLED_COLOUR.stroke_width(1),
        ))?;
        put_text(root, "1% grade RMSE", (l + 6, py - 3), &label, pen)?;
        if self.ref_wall.is_finite() && self.ref_wall > 0.0 {
            for (v, name) in [
                (self.ref_wall, "reference run"),
                (self.ref_wall / 10.0, "reference / 10"),
            ] {
                let px = self.px((v, self.y.0)).0;
                root.draw(&DashedPathElement::new(
                    vec![(px, t), (px, b)],
                    6,
                    4,
                    AXIS_COLOUR.stroke_width(1),
                ))?;
                put_text(root, name, (px + 4, t + 14), &label, pen)?;
            }
        }
        // The Pareto front, joined in order of time.
        let mut front: Vec<&SweepPoint> = self.points.iter().filter(|p| p.pareto).collect();
        front.sort_by(|a, b| a.wall_s.total_cmp(&b.wall_s));
        root.draw(&PathElement::new(
            front
                .iter()
                .map(|p| self.px((p.wall_s, p.error)))
                .collect::<Vec<_>>(),
            PREDICTED_COLOUR.stroke_width(2),
        ))?;
        let small = text(11.0, HPos::Left, VPos::Center);
        for p in &self.points {
            let c = self.px((p.wall_s, p.error));
            if p.pareto {
                root.draw(&Circle::new(c, 5, PREDICTED_COLOUR.filled()))?;
                put_text(root, &p.label, (c.0 + 8, c.1 - 8), &small, pen)?;
            } else {
                root.draw(&Circle::new(c, 4, OFF_FRONT.filled()))?;
            }
            if p.is_auto {
                let d = 10;
                root.draw(&PathElement::new(
                    vec![
                        (c.0, c.1 - d),
                        (c.0 + d, c.1),
                        (c.0, c.1 + d),
                        (c.0 - d, c.1),
                        (c.0, c.1 - d),
                    ],
                    AXIS_COLOUR.stroke_width(3),
                ))?;
                put_text(
                    root,
                    "automatic",
                    (c.0 + 12, c.1 - 12),
                    &text(14.0, HPos::Left, VPos::Center),
                    pen,
                )?;
            }
            if p.is_default {
                root.draw(&Circle::new(c, 9, SAMPLED_COLOUR.stroke_width(3)))?;
                put_text(
                    root,
                    "default",
                    (c.0 + 12, c.1 + 10),
                    &text(14.0, HPos::Left, VPos::Center),
                    pen,
                )?;
            }
        }
        // Axes.
        root.draw(&Rectangle::new([(l, t), (r, b)], AXIS_COLOUR))?;
        let xs = text(12.0, HPos::Center, VPos::Top);
        for (v, s) in &xt {
            let px = self.px((*v, self.y.0)).0;
            root.draw(&PathElement::new(
                vec![(px, b), (px, b + TICK)],
                AXIS_COLOUR,
            ))?;
            put_text(root, s, (px, b + TICK_GAP), &xs, pen)?;
        }
        let ys = text(12.0, HPos::Right, VPos::Center);
        for (v, _) in &yt {
            let py = self.px((self.x.0, *v)).1;
            root.draw(&PathElement::new(
                vec![(l - TICK, py), (l, py)],
                AXIS_COLOUR,
            ))?;
            let pct = format!("{}%", (v * 100.0 * 1e6).round() / 1e6);
            put_text(root, &pct, (l - TICK_GAP, py), &ys, pen)?;
        }
        put_text(
            root,
            "wall time, s (log)",
            ((l + r) / 2, b + 40),
            &axis_title_style(false),
            pen,
        )?;
        put_text(
            root,
            "grade RMSE against the reference (log)",
            (22, (t + b) / 2),
            &axis_title_style(true),
            pen,
        )?;
        // Legend.
        let y = b + 80;
        let style = text(14.0, HPos::Left, VPos::Center);
        root.draw(&Circle::new((l + 10, y), 5, PREDICTED_COLOUR.filled()))?;
        put_text(
            root,
            "Pareto front (h / spacing / increment × default)",
            (l + 22, y),
            &style,
            pen,
        )?;
        root.draw(&Circle::new((l + 430, y), 4, OFF_FRONT.filled()))?;
        put_text(root, "other runs", (l + 442, y), &style, pen)?;
        root.draw(&Circle::new(
            (l + 570, y),
            9,
            SAMPLED_COLOUR.stroke_width(3),
        ))?;
        put_text(root, "default resolution", (l + 586, y), &style, pen)?;
        let (ax, ay, d) = (l + 10, y + 24, 8);
        root.draw(&PathElement::new(
            vec![
                (ax, ay - d),
                (ax + d, ay),
                (ax, ay + d),
                (ax - d, ay),
                (ax, ay - d),
            ],
            AXIS_COLOUR.stroke_width(3),
        ))?;
        put_text(
            root,
            "automatic resolution for the accuracy target (resolution.target_grade_rmse)",
            (l + 22, ay),
            &style,
            pen,
        )?;
        Ok(())
    }
}
