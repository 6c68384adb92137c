//! Back-analysis charts (summary §8): predicted against sampled grade as a scatter with the
//! 1:1 line, and the profiles of a calibration's fitted factors. The plan map of the error
//! per drawpoint is [`plan_map_chart`](super::plan_map_chart) on its diverging scale.
//!
//! A child of [`charts`](super) so it shares the bundled font, the glyph-by-glyph text, the
//! axes and the atomic writer.

use std::path::Path;

use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::{
    axis_title_style, draw_axes, draw_grid, ensure_font, put_text, series_colour, text,
    write_chart, x_ticks, y_ticks, AxisLabels, ChartError, DrawError, Frame, Pen, Render, Ticks,
    AXIS_COLOUR, TITLE_H,
};

const SIDE: u32 = 640;
const LEFT: i32 = 80;
const BOTTOM: i32 = 70;
const RIGHT: i32 = 150;

/// One drawpoint-period on the scatter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScatterPoint {
    /// Sampled grade.
    pub sampled: f64,
    /// Predicted grade.
    pub predicted: f64,
    /// Index into the zone names (the colour).
    pub zone: usize,
}

/// Predicted (up) against sampled (across) on equal axes with the 1:1 line, coloured by zone,
/// to `path` (`.png` or `.svg`), atomically. Non-finite points are left off.
pub fn scatter_chart(
    path: &Path,
    points: &[ScatterPoint],
    zones: &[String],
    title: &str,
    grade_label: &str,
) -> Result<(), ChartError> {
    ensure_font(path)?;
    let shown: Vec<ScatterPoint> = points
        .iter()
        .filter(|p| p.sampled.is_finite() && p.predicted.is_finite())
        .copied()
        .collect();
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for p in &shown {
        lo = lo.min(p.sampled.min(p.predicted));
        hi = hi.max(p.sampled.max(p.predicted));
    }
    if !(lo.is_finite() && hi > lo) {
        (lo, hi) = (0.0, 1.0);
    }
    let pad = 0.05 * (hi - lo);
    let range = ((lo - pad).max(0.0), hi + pad);
    write_chart(
        path,
        &Scatter {
            points: shown,
            zones: zones.to_vec(),
            frame: Frame {
                left: LEFT,
                top: TITLE_H as i32 + 10,
                size: (SIDE - LEFT as u32 - 20, SIDE - TITLE_H - 10 - BOTTOM as u32),
                x: range,
                y: range,
            },
            title: title.to_string(),
            grade_label: grade_label.to_string(),
        },
    )
}

struct Scatter {
    points: Vec<ScatterPoint>,
    zones: Vec<String>,
    frame: Frame,
    title: String,
    grade_label: String,
}

/// The grid of each frame; the ticks of the first frame.
pub(super) fn grids<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    frames: &[Frame],
) -> Result<(Ticks, Ticks), DrawError>
where
    DB::ErrorType: 'static,
{
    let mut first = None;
    for f in frames {
        let (xt, yt) = (x_ticks(f)?, y_ticks(f)?);
        draw_grid(root, f, (&xt, &yt))?;
        first.get_or_insert((xt, yt));
    }
    Ok(first.unwrap_or_else(|| (Ticks::empty(), Ticks::empty())))
}

impl Render for Scatter {
    fn size(&self) -> (u32, u32) {
        (SIDE + RIGHT as u32, SIDE)
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
        let (xt, yt) = grids(root, &[*f])?;
        root.draw(&PathElement::new(
            f.path(&[(f.x.0, f.y.0), (f.x.1, f.y.1)]),
            AXIS_COLOUR.stroke_width(1),
        ))?;
        put_text(
            root,
            "1:1",
            (f.right() - 24, f.top + 14),
            &text(12.0, HPos::Left, VPos::Center),
            pen,
        )?;
        for p in &self.points {
            root.draw(&Circle::new(
                f.px((p.sampled, p.predicted)),
                3,
                series_colour(p.zone).mix(0.7).filled(),
            ))?;
        }
        draw_axes(root, f, (&xt, &yt), AxisLabels { x: true, y: true }, pen)?;
        let mid_x = f.left + f.size.0 as i32 / 2;
        put_text(
            root,
            &format!("Sampled {}", self.grade_label),
            (mid_x, f.bottom() + 45),
            &axis_title_style(false),
            pen,
        )?;
        put_text(
            root,
            &format!("Predicted {}", self.grade_label),
            (20, f.top + f.size.1 as i32 / 2),
            &axis_title_style(true),
            pen,
        )?;
        let legend = text(13.0, HPos::Left, VPos::Center);
        let x0 = f.right() + 24;
        for (k, z) in self.zones.iter().enumerate() {
            let y = f.top + 10 + 22 * k as i32;
            root.draw(&Circle::new((x0, y), 5, series_colour(k).filled()))?;
            let name = if z.is_empty() { "(no zone)" } else { z };
            put_text(root, name, (x0 + 12, y), &legend, pen)?;
        }
        Ok(())
    }
}

/// One fitted parameter's error profile (calibration).
#[derive(Debug, Clone, PartialEq)]
pub struct Profile {
    /// Parameter name, the panel caption.
    pub name: String,
    /// (value, RMSE) evaluated, sorted by value.
    pub points: Vec<(f64, f64)>,
    /// Fitted value.
    pub fitted: f64,
    /// 95% interval of the fitted value (NaN ends: not drawn).
    pub ci95: (f64, f64),
    /// Value before calibration.
    pub start: f64,
}

const PANEL_W: u32 = 420;
const PANEL_H: u32 = 380;

/// Error profiles of a calibration, one panel per parameter side by side: RMSE against the
/// parameter, the fitted value (solid) with its 95% interval (shaded) and the starting
/// value (dashed), to `path`, atomically.
pub fn profile_chart(path: &Path, profiles: &[Profile], title: &str) -> Result<(), ChartError> {
    ensure_font(path)?;
    let frames = profiles
        .iter()
        .enumerate()
        .map(|(k, p)| {
            let (mut x, mut y) = (
                (p.start.min(p.fitted), p.start.max(p.fitted)),
                (f64::INFINITY, 0.0f64),
            );
            for &(v, e) in &p.points {
                if v.is_finite() && e.is_finite() {
                    x = (x.0.min(v), x.1.max(v));
                    y = (y.0.min(e), y.1.max(e));
                }
            }
            if !(y.0.is_finite() && y.1 > y.0) {
                y = (0.0, 1.0);
            }
            let (dx, dy) = (0.05 * (x.1 - x.0).max(1e-3), 0.08 * (y.1 - y.0));
            Frame {
                left: LEFT + (PANEL_W * k as u32) as i32,
                top: TITLE_H as i32 + 30,
                size: (PANEL_W - LEFT as u32 - 20, PANEL_H - 30 - BOTTOM as u32),
                x: (x.0 - dx, x.1 + dx),
                y: ((y.0 - dy).max(0.0), y.1 + dy),
            }
        })
        .collect();
    write_chart(
        path,
        &Profiles {
            profiles: profiles.to_vec(),
            frames,
            title: title.to_string(),
        },
    )
}

struct Profiles {
    profiles: Vec<Profile>,
    frames: Vec<Frame>,
    title: String,
}

impl Render for Profiles {
    fn size(&self) -> (u32, u32) {
        (
            PANEL_W * self.profiles.len().max(1) as u32,
            TITLE_H + PANEL_H,
        )
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
        grids(root, &self.frames)?;
        for (p, f) in self.profiles.iter().zip(&self.frames) {
            let (xt, yt) = (x_ticks(f)?, y_ticks(f)?);
            let (lo, hi) = p.ci95;
            if lo.is_finite() && hi.is_finite() {
                let (a, b) = (lo.max(f.x.0), hi.min(f.x.1));
                if b > a {
                    root.draw(&Rectangle::new(
                        [f.px((a, f.y.1)), f.px((b, f.y.0))],
                        series_colour(0).mix(0.15).filled(),
                    ))?;
                }
            }
            let vline = |v: f64| f.path(&[(v, f.y.0), (v, f.y.1)]);
            root.draw(&DashedPathElement::new(
                vline(p.start),
                5,
                4,
                AXIS_COLOUR.stroke_width(1),
            ))?;
            root.draw(&PathElement::new(
                vline(p.fitted),
                series_colour(0).stroke_width(2),
            ))?;
            let pts: Vec<(f64, f64)> = p
                .points
                .iter()
                .copied()
                .filter(|(v, e)| v.is_finite() && e.is_finite())
                .collect();
            root.draw(&PathElement::new(f.path(&pts), AXIS_COLOUR.stroke_width(1)))?;
            for &q in &pts {
                root.draw(&Circle::new(f.px(q), 4, series_colour(3).filled()))?;
            }
            draw_axes(root, f, (&xt, &yt), AxisLabels { x: true, y: true }, pen)?;
            put_text(
                root,
                &format!("{}: {:.3} (start {:.3})", p.name, p.fitted, p.start),
                (f.left + f.size.0 as i32 / 2, f.top - 14),
                &text(14.0, HPos::Center, VPos::Center),
                pen,
            )?;
            put_text(
                root,
                "RMSE (%)",
                (f.left - 60, f.top + f.size.1 as i32 / 2),
                &axis_title_style(true),
                pen,
            )?;
            put_text(
                root,
                "factor",
                (f.left + f.size.0 as i32 / 2, f.bottom() + 40),
                &axis_title_style(false),
                pen,
            )?;
        }
        Ok(())
    }
}
