//! Plan maps: the drawpoints at their Easting and Northing on equal axes, each a disc
//! coloured by one value per drawpoint, with a colour bar.
//!
//! Two scales, for two kinds of value:
//! - [`MapScale::Diverging`], symmetric about 0 (blue below, white at 0, red above): errors
//!   such as reconcile's bias per drawpoint, where the eye must find the biased parts first;
//! - [`MapScale::Sequential`], from the smallest value to the largest (viridis: dark blue to
//!   yellow): quantities such as the run report's height of draw, dilution entry, drawn
//!   tonnes and air gap.
//!
//! A drawpoint without a value (NaN) is drawn hollow. Names are set beside the discs when
//! there are few enough drawpoints to read them ([`MAX_LABELS`]); the discs shrink to stay
//! apart on dense layouts.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::colors::colormaps::ViridisRGB;
use plotters::style::text_anchor::{HPos, VPos};

use super::reconcile::grids;
use super::{
    axis_titles, draw_axes, ensure_font, put_text, text, write_chart, AxisLabels, ChartError,
    DrawError, Frame, Pen, Render, AXIS_COLOUR, TITLE_H,
};

const SIDE: u32 = 640;
const LEFT: i32 = 80;
const BOTTOM: i32 = 70;
const RIGHT: i32 = 150;

/// Most drawpoints whose names are set on the map.
pub const MAX_LABELS: usize = 60;

/// One drawpoint on a plan map.
#[derive(Debug, Clone, PartialEq)]
pub struct MapPoint {
    /// Easting, m.
    pub x: f64,
    /// Northing, m.
    pub y: f64,
    /// The value coloured (e.g. the bias, predicted − sampled); NaN: drawn hollow.
    pub value: f64,
    /// Label set beside the point (the drawpoint name).
    pub label: String,
}

/// How values become colours.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MapScale {
    /// Symmetric about 0: −max|v| blue, 0 white, +max|v| red.
    Diverging,
    /// From the smallest value (dark blue) to the largest (yellow).
    Sequential,
}

/// Diverging colour of t in [−1, 1]: blue (−1), white (0), red (+1).
pub fn diverging(t: f64) -> RGBColor {
    let t = if t.is_finite() {
        t.clamp(-1.0, 1.0)
    } else {
        0.0
    };
    let (end, w) = if t < 0.0 {
        ((33.0, 102.0, 172.0), -t)
    } else {
        ((178.0, 24.0, 43.0), t)
    };
    let mix = |c: f64| (247.0 + w * (c - 247.0)).round() as u8;
    RGBColor(mix(end.0), mix(end.1), mix(end.2))
}

/// Plan map of `points` coloured by their value on `scale`, with a colour bar labelled
/// `value_label`, to `path` (`.png` or `.svg`), atomically.
pub fn plan_map_chart(
    path: &Path,
    points: &[MapPoint],
    title: &str,
    value_label: &str,
    scale: MapScale,
) -> Result<(), ChartError> {
    ensure_font(path)?;
    let (mut x, mut y) = (
        (f64::INFINITY, f64::NEG_INFINITY),
        (f64::INFINITY, f64::NEG_INFINITY),
    );
    let mut range = (f64::INFINITY, f64::NEG_INFINITY);
    for p in points {
        x = (x.0.min(p.x), x.1.max(p.x));
        y = (y.0.min(p.y), y.1.max(p.y));
        if p.value.is_finite() {
            range = (range.0.min(p.value), range.1.max(p.value));
        }
    }
    if !(x.0.is_finite() && y.0.is_finite()) {
        (x, y) = ((0.0, 1.0), (0.0, 1.0));
    }
    let range = match scale {
        _ if !range.0.is_finite() => (0.0, 1.0),
        MapScale::Diverging => {
            let m = range.0.abs().max(range.1.abs());
            let m = if m > 0.0 { m } else { 1.0 };
            (-m, m)
        }
        MapScale::Sequential if range.1 > range.0 => range,
        MapScale::Sequential => (range.0 - 0.5, range.0 + 0.5),
    };
    // Equal aspect: both spans padded to the larger one.
    let span = (x.1 - x.0).max(y.1 - y.0).max(1.0) * 1.1;
    let (cx, cy) = (0.5 * (x.0 + x.1), 0.5 * (y.0 + y.1));
    let side = SIDE - TITLE_H - 10 - BOTTOM as u32;
    // Disc radius: at most 8 px, and under half the closest spacing between drawpoints.
    let nearest = nearest_distance(points);
    let radius = if nearest.is_finite() {
        (0.45 * nearest / span * f64::from(side)).clamp(2.0, 8.0) as i32
    } else {
        8
    };
    write_chart(
        path,
        &PlanMap {
            points: points.to_vec(),
            scale,
            range,
            radius,
            frame: Frame {
                left: LEFT,
                top: TITLE_H as i32 + 10,
                size: (side, side),
                x: (cx - span / 2.0, cx + span / 2.0),
                y: (cy - span / 2.0, cy + span / 2.0),
            },
            title: title.to_string(),
            value_label: value_label.to_string(),
        },
    )
}

/// Smallest distance between two points, m (infinite with fewer than two).
fn nearest_distance(points: &[MapPoint]) -> f64 {
    let mut best = f64::INFINITY;
    for (i, a) in points.iter().enumerate() {
        for b in &points[i + 1..] {
            let d = (a.x - b.x).hypot(a.y - b.y);
            if d > 0.0 {
                best = best.min(d);
            }
        }
    }
    best
}

struct PlanMap {
    points: Vec<MapPoint>,
    scale: MapScale,
    /// Values at the bottom and the top of the colour bar.
    range: (f64, f64),
    radius: i32,
    frame: Frame,
    title: String,
    value_label: String,
}

impl PlanMap {
    /// Colour of `v`.
    fn colour(&self, v: f64) -> RGBColor {
        let t = (v - self.range.0) / (self.range.1 - self.range.0);
        match self.scale {
            MapScale::Diverging => diverging(2.0 * t - 1.0),
            MapScale::Sequential => ViridisRGB::get_color(t.clamp(0.0, 1.0)),
        }
    }
}

impl Render for PlanMap {
    fn size(&self) -> (u32, u32) {
        (LEFT as u32 + self.frame.size.0 + RIGHT as u32 + 20, SIDE)
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
        let small = text(10.0, HPos::Left, VPos::Center);
        let labelled = self.points.len() <= MAX_LABELS;
        for p in &self.points {
            let c = f.px((p.x, p.y));
            if p.value.is_finite() {
                root.draw(&Circle::new(c, self.radius, self.colour(p.value).filled()))?;
            }
            root.draw(&Circle::new(c, self.radius, AXIS_COLOUR.stroke_width(1)))?;
            if labelled {
                put_text(root, &p.label, (c.0 + self.radius + 2, c.1), &small, pen)?;
            }
        }
        draw_axes(root, f, (&xt, &yt), AxisLabels { x: true, y: true }, pen)?;
        axis_titles(root, f, ("Easting (m)", "Northing (m)"), 45, pen)?;
        // Colour bar: the top of the range at the top.
        let (bx, bw) = (f.right() + 40, 18);
        let (bt, bb) = (f.top + 20, f.bottom() - 20);
        let at = |py: i32| {
            let t = 1.0 - f64::from(py - bt) / f64::from(bb - bt);
            self.range.0 + t * (self.range.1 - self.range.0)
        };
        for py in bt..=bb {
            root.draw(&PathElement::new(
                vec![(bx, py), (bx + bw, py)],
                self.colour(at(py)),
            ))?;
        }
        root.draw(&Rectangle::new([(bx, bt), (bx + bw, bb)], AXIS_COLOUR))?;
        let label = text(12.0, HPos::Left, VPos::Center);
        for py in [bt, (bt + bb) / 2, bb] {
            let v = at(py);
            let shown = match self.scale {
                MapScale::Diverging => format!("{v:+.3}"),
                MapScale::Sequential => bar_label(v),
            };
            put_text(root, &shown, (bx + bw + 6, py), &label, pen)?;
        }
        put_text(
            root,
            &self.value_label,
            (bx - 2, bt - 12),
            &text(12.0, HPos::Left, VPos::Center),
            pen,
        )?;
        Ok(())
    }
}

/// A colour-bar value: whole numbers from 100 up, three significant digits below.
fn bar_label(v: f64) -> String {
    if v.abs() >= 100.0 {
        format!("{v:.0}")
    } else {
        format!("{v:.3}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output::charts::tests::out_dir;

    #[test]
    fn diverging_ends_and_middle() {
        assert_eq!(diverging(0.0), RGBColor(247, 247, 247));
        assert_eq!(diverging(-1.0), RGBColor(33, 102, 172));
        assert_eq!(diverging(1.0), RGBColor(178, 24, 43));
        assert_eq!(diverging(5.0), diverging(1.0));
        assert_eq!(diverging(f64::NAN), diverging(0.0));
    }

    /// A sequential map colours the smallest value dark and the largest light, and a
    /// drawpoint without a value is left hollow.
    #[test]
    fn sequential_scale_runs_from_the_smallest_to_the_largest_value() {
        let m = PlanMap {
            points: Vec::new(),
            scale: MapScale::Sequential,
            range: (10.0, 30.0),
            radius: 8,
            frame: Frame {
                left: 0,
                top: 0,
                size: (10, 10),
                x: (0.0, 1.0),
                y: (0.0, 1.0),
            },
            title: String::new(),
            value_label: String::new(),
        };
        let lum = |c: RGBColor| 0.3 * f64::from(c.0) + 0.6 * f64::from(c.1) + 0.1 * f64::from(c.2);
        assert!(lum(m.colour(10.0)) < lum(m.colour(20.0)));
        assert!(lum(m.colour(20.0)) < lum(m.colour(30.0)));
        let (_tmp, dir) = out_dir("plan_map");
        let points: Vec<MapPoint> = (0..4)
            .map(|k| MapPoint {
                x: 15.0 * f64::from(k),
                y: 0.0,
                value: if k == 3 { f64::NAN } else { f64::from(k) },
                label: format!("D{k}"),
            })
            .collect();
        let path = dir.join("map.svg");
        plan_map_chart(&path, &points, "Map", "HOD (m)", MapScale::Sequential).unwrap();
        let svg = std::fs::read_to_string(&path).unwrap();
        let names = svg.lines().filter(|l| l.starts_with('D')).count();
        assert_eq!(names, 4, "every drawpoint named");
    }
}
