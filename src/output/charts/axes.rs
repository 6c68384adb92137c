//! Axes drawn by hand rather than by plotters' mesh (so tick labels are set by
//! [`put_text`](super::font::put_text)): plotting [`Frame`]s, round [`Ticks`] that fit their
//! axis, grid lines, frame borders with tick marks and labels, and axis titles.

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};
use plotters::style::FontTransform;

use super::{put_text, text, text_width, DrawError, Pen, AXIS_COLOUR, GRID_COLOUR};

/// Tick marks and the gap between a tick mark and its label; px.
pub(super) const TICK: i32 = 5;
pub(super) const TICK_GAP: i32 = 8;
/// Strip holding a rotated axis title, px.
pub(super) const AXIS_TITLE_W: u32 = 28;

/// A plotting frame: a pixel rectangle on the root area and the data ranges it spans.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Frame {
    /// Left and top pixel.
    pub(super) left: i32,
    pub(super) top: i32,
    /// Width and height, px.
    pub(super) size: (u32, u32),
    /// Horizontal and vertical data ranges (low, high).
    pub(super) x: (f64, f64),
    pub(super) y: (f64, f64),
}

impl Frame {
    /// Right pixel column.
    pub(super) fn right(&self) -> i32 {
        self.left + self.size.0 as i32 - 1
    }

    /// Bottom pixel row.
    pub(super) fn bottom(&self) -> i32 {
        self.top + self.size.1 as i32 - 1
    }

    /// Pixel of a data point (y up).
    pub(super) fn px(&self, (x, y): (f64, f64)) -> (i32, i32) {
        let fx = (x - self.x.0) / (self.x.1 - self.x.0) * f64::from(self.size.0 - 1);
        let fy = (y - self.y.0) / (self.y.1 - self.y.0) * f64::from(self.size.1 - 1);
        (
            self.left + fx.round() as i32,
            self.bottom() - fy.round() as i32,
        )
    }

    /// Pixels of a polyline.
    pub(super) fn path(&self, points: &[(f64, f64)]) -> Vec<(i32, i32)> {
        points.iter().map(|&p| self.px(p)).collect()
    }
}

/// Tick values and their labels along one axis.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Ticks {
    /// Values, increasing.
    pub(super) values: Vec<f64>,
    /// Labels, one per value.
    pub(super) labels: Vec<String>,
}

impl Ticks {
    /// No ticks.
    pub(super) fn empty() -> Ticks {
        Ticks {
            values: Vec::new(),
            labels: Vec::new(),
        }
    }
}

/// Ticks at 1, 2 or 5 × 10^k inside [lo, hi], about `max` of them at most.
pub(super) fn nice_ticks(lo: f64, hi: f64, max: usize) -> Ticks {
    let raw = (hi - lo) / max.max(1) as f64;
    if !(raw.is_finite() && raw > 0.0) {
        return Ticks::empty();
    }
    let magnitude = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * magnitude)
        .find(|&s| s >= raw * (1.0 - 1e-9))
        .unwrap_or(10.0 * magnitude);
    let decimals = (-(step.log10() + 1e-9).floor()).max(0.0) as usize;
    let (first, last) = ((lo / step - 1e-9).ceil(), (hi / step + 1e-9).floor());
    let values: Vec<f64> = (first as i64..=last as i64)
        .map(|k| k as f64 * step)
        .collect();
    let labels = values
        .iter()
        .map(|v| {
            let s = format!("{v:.decimals$}");
            // "-0" and "-0.0" read as zero.
            if s.trim_start_matches('-')
                .chars()
                .all(|c| c == '0' || c == '.')
            {
                s.trim_start_matches('-').to_string()
            } else {
                s
            }
        })
        .collect();
    Ticks { values, labels }
}

/// Ticks at most about every `every_px` pixels along an axis of `len_px` pixels (2 to 10),
/// fewer if labels would touch (labels are `along` px long in the axis direction: their width
/// on a horizontal axis, their height on a vertical one).
pub(super) fn fit_ticks(
    (lo, hi): (f64, f64),
    len_px: u32,
    every_px: u32,
    along: impl Fn(&str) -> Result<i32, DrawError>,
) -> Result<Ticks, DrawError> {
    let mut max = (len_px.div_ceil(every_px) + 1).clamp(2, 10) as usize;
    loop {
        let ticks = nice_ticks(lo, hi, max);
        let spacing = match ticks.values.as_slice() {
            [a, b, ..] => (b - a) / (hi - lo) * f64::from(len_px),
            _ => f64::INFINITY,
        };
        let mut longest = 0;
        for label in &ticks.labels {
            longest = longest.max(along(label)?);
        }
        if max <= 2 || f64::from(longest + 12) <= spacing {
            return Ok(ticks);
        }
        max -= 1;
    }
}

/// Tick label style.
pub(super) fn tick_style(h: HPos, v: VPos) -> TextStyle<'static> {
    text(12.0, h, v)
}

/// Ticks for a horizontal axis of a frame.
pub(super) fn x_ticks(frame: &Frame) -> Result<Ticks, DrawError> {
    let style = tick_style(HPos::Center, VPos::Top);
    fit_ticks(frame.x, frame.size.0, 70, |s| text_width(&style, s))
}

/// Ticks for a vertical axis of a frame.
pub(super) fn y_ticks(frame: &Frame) -> Result<Ticks, DrawError> {
    let height = tick_style(HPos::Right, VPos::Center).font.get_size() as i32;
    fit_ticks(frame.y, frame.size.1, 36, |_| Ok(height))
}

/// Widest label of ticks over [lo, hi], px (sizes the margin left of a frame).
pub(super) fn widest_tick_label(lo: f64, hi: f64) -> Result<u32, DrawError> {
    let style = tick_style(HPos::Right, VPos::Center);
    let mut widest = 0;
    for label in nice_ticks(lo, hi, 10).labels {
        widest = widest.max(text_width(&style, &label)?);
    }
    Ok(widest as u32)
}

/// Which sides of a frame [`draw_axes`] labels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct AxisLabels {
    /// Tick marks and labels below the frame.
    pub(super) x: bool,
    /// Tick marks and labels left of the frame.
    pub(super) y: bool,
}

/// Draw light grid lines at a frame's ticks (under the data: call first).
pub(super) fn draw_grid<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    frame: &Frame,
    (xt, yt): (&Ticks, &Ticks),
) -> Result<(), DrawError>
where
    DB::ErrorType: 'static,
{
    let (l, t, r, b) = (frame.left, frame.top, frame.right(), frame.bottom());
    for &v in &xt.values {
        let x = frame.px((v, frame.y.0)).0;
        root.draw(&PathElement::new(vec![(x, t), (x, b)], GRID_COLOUR))?;
    }
    for &v in &yt.values {
        let y = frame.px((frame.x.0, v)).1;
        root.draw(&PathElement::new(vec![(l, y), (r, y)], GRID_COLOUR))?;
    }
    Ok(())
}

/// Draw a frame's border and, on the sides `labels` asks for, tick marks and tick labels
/// (over the data: call last).
pub(super) fn draw_axes<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    frame: &Frame,
    (xt, yt): (&Ticks, &Ticks),
    labels: AxisLabels,
    pen: Pen,
) -> Result<(), DrawError>
where
    DB::ErrorType: 'static,
{
    let (l, t, r, b) = (frame.left, frame.top, frame.right(), frame.bottom());
    root.draw(&Rectangle::new(
        [(l, t), (r, b)],
        AXIS_COLOUR.stroke_width(1),
    ))?;
    if labels.x {
        let style = tick_style(HPos::Center, VPos::Top);
        for (&v, label) in xt.values.iter().zip(&xt.labels) {
            let x = frame.px((v, frame.y.0)).0;
            root.draw(&PathElement::new(vec![(x, b), (x, b + TICK)], AXIS_COLOUR))?;
            put_text(root, label, (x, b + TICK_GAP), &style, pen)?;
        }
    }
    if labels.y {
        let style = tick_style(HPos::Right, VPos::Center);
        for (&v, label) in yt.values.iter().zip(&yt.labels) {
            let y = frame.px((frame.x.0, v)).1;
            root.draw(&PathElement::new(vec![(l - TICK, y), (l, y)], AXIS_COLOUR))?;
            put_text(root, label, (l - TICK_GAP, y), &style, pen)?;
        }
    }
    Ok(())
}

/// Axis title style (rotated for a vertical axis).
pub(super) fn axis_title_style(vertical: bool) -> TextStyle<'static> {
    let style = text(16.0, HPos::Center, VPos::Center);
    if vertical {
        style.transform(FontTransform::Rotate270)
    } else {
        style
    }
}

/// The axis titles of frame `f`: `x` centred `below` px under it, `y` rotated, centred on
/// its height, 18 px from the image's left edge.
pub(super) fn axis_titles<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    f: &Frame,
    (x, y): (&str, &str),
    below: i32,
    pen: Pen,
) -> Result<(), DrawError>
where
    DB::ErrorType: 'static,
{
    let at_x = (f.left + f.size.0 as i32 / 2, f.bottom() + below);
    put_text(root, x, at_x, &axis_title_style(false), pen)?;
    let at_y = (18, f.top + f.size.1 as i32 / 2);
    put_text(root, y, at_y, &axis_title_style(true), pen)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nice_ticks_use_round_steps() {
        let t = nice_ticks(0.0, 3.3, 8);
        assert_eq!(t.labels, ["0.0", "0.5", "1.0", "1.5", "2.0", "2.5", "3.0"]);
        let t = nice_ticks(7690.0, 7905.0, 5);
        assert_eq!(t.labels, ["7700", "7750", "7800", "7850", "7900"]);
        let t = nice_ticks(-0.12, 0.3, 5);
        assert_eq!(t.labels, ["-0.1", "0.0", "0.1", "0.2", "0.3"]);
        assert!(nice_ticks(1.0, 1.0, 5).values.is_empty());
    }
}
