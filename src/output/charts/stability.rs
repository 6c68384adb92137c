//! The stability chart: where REBOP's method is valid, degraded or refused, one band per
//! swept quantity (see [`crate::engine::stability`]), with the outcome of the tiny runs
//! that checked it drawn as dots on the bands.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::{
    ensure_font, put_text, text, write_chart, ChartError, DrawError, Pen, Render, AXIS_COLOUR,
    TICK, TICK_GAP, TITLE_H,
};
use crate::engine::stability::Validity;

/// One swept quantity.
#[derive(Debug, Clone, PartialEq)]
pub struct RegionBand {
    /// Label with its unit, e.g. `"d̄ / opening width"`.
    pub label: String,
    /// Swept range (low, high); drawn on a log axis when `log`.
    pub range: (f64, f64),
    /// Log axis (decades) or linear.
    pub log: bool,
    /// Classification along the range: (from, to, verdict) spans, covering the range.
    pub spans: Vec<(f64, f64, Validity)>,
    /// Checked points: (value, whether the tiny run there stayed physical).
    pub checks: Vec<(f64, bool)>,
}

/// Fill colours of the three regions.
fn fill(v: Validity) -> RGBColor {
    match v {
        Validity::Valid => RGBColor(166, 217, 160),
        Validity::Degraded => RGBColor(253, 208, 120),
        Validity::Refused => RGBColor(239, 130, 120),
    }
}

const LABEL_W: u32 = 250;
const BAND_H: u32 = 34;
const ROW_H: u32 = 84;
const RIGHT: u32 = 36;
const WIDTH: u32 = 1000;
const LEGEND_H: u32 = 40;

/// Draws the region chart to `path` (`.png` or `.svg`), atomically.
pub fn stability_chart(path: &Path, bands: &[RegionBand], title: &str) -> Result<(), ChartError> {
    ensure_font(path)?;
    write_chart(
        path,
        &StabilityPlot {
            bands,
            title: title.to_string(),
        },
    )
}

struct StabilityPlot<'a> {
    bands: &'a [RegionBand],
    title: String,
}

/// Position of a value along a band, 0–1.
fn frac(b: &RegionBand, v: f64) -> f64 {
    let (lo, hi) = b.range;
    let t = if b.log {
        (v.ln() - lo.ln()) / (hi.ln() - lo.ln())
    } else {
        (v - lo) / (hi - lo)
    };
    t.clamp(0.0, 1.0)
}

/// Ticks of a log axis over [lo, hi]: the decades and their 2 and 5.
pub(super) fn log_ticks(lo: f64, hi: f64) -> Vec<(f64, String)> {
    let mut out = Vec::new();
    let mut k = lo.log10().floor() as i32;
    while 10f64.powi(k) <= hi * (1.0 + 1e-9) {
        for m in [1.0, 2.0, 5.0] {
            let v = m * 10f64.powi(k);
            if v >= lo * (1.0 - 1e-9) && v <= hi * (1.0 + 1e-9) {
                out.push((v, format!("{}", (v * 1e6).round() / 1e6)));
            }
        }
        k += 1;
    }
    out
}

/// Tick values of a band: decades and their 2 and 5 on a log axis, ~8 on a linear one.
fn ticks(b: &RegionBand) -> Vec<(f64, String)> {
    let (lo, hi) = b.range;
    let mut out = Vec::new();
    if b.log {
        out = log_ticks(lo, hi);
    } else {
        // 1, 2 or 5 × 10^k, about ten ticks.
        let raw = (hi - lo) / 10.0;
        let mag = 10f64.powf(raw.log10().floor());
        let step = [1.0, 2.0, 5.0, 10.0]
            .iter()
            .map(|m| m * mag)
            .find(|&s| s >= raw)
            .unwrap_or(10.0 * mag);
        let mut k = (lo / step).ceil();
        while k * step <= hi * (1.0 + 1e-9) {
            let v = k * step;
            out.push((v, format!("{}", (v * 1e6).round() / 1e6)));
            k += 1.0;
        }
    }
    out
}

impl Render for StabilityPlot<'_> {
    fn size(&self) -> (u32, u32) {
        (
            WIDTH,
            TITLE_H + ROW_H * self.bands.len() as u32 + LEGEND_H + 10,
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
        let (l, r) = (LABEL_W as i32, (WIDTH - RIGHT) as i32);
        let px = |b: &RegionBand, v: f64| l + (frac(b, v) * f64::from(r - l)).round() as i32;
        for (k, b) in self.bands.iter().enumerate() {
            let top = (TITLE_H + 10 + ROW_H * k as u32) as i32;
            let bottom = top + BAND_H as i32;
            let label = text(15.0, HPos::Right, VPos::Center);
            put_text(
                root,
                &b.label,
                (l - 12, top + BAND_H as i32 / 2),
                &label,
                pen,
            )?;
            for &(from, to, v) in &b.spans {
                root.draw(&Rectangle::new(
                    [(px(b, from), top), (px(b, to), bottom)],
                    fill(v).filled(),
                ))?;
            }
            for &(v, ok) in &b.checks {
                let c = (px(b, v), top + BAND_H as i32 / 2);
                if ok {
                    root.draw(&Circle::new(c, 5, BLACK.filled()))?;
                } else {
                    root.draw(&Cross::new(c, 6, BLACK.stroke_width(3)))?;
                }
            }
            root.draw(&Rectangle::new([(l, top), (r, bottom)], AXIS_COLOUR))?;
            let style = text(12.0, HPos::Center, VPos::Top);
            for (v, s) in ticks(b) {
                let x = px(b, v);
                root.draw(&PathElement::new(
                    vec![(x, bottom), (x, bottom + TICK)],
                    AXIS_COLOUR,
                ))?;
                put_text(root, &s, (x, bottom + TICK_GAP), &style, pen)?;
            }
        }
        // Legend.
        let y = (TITLE_H + 10 + ROW_H * self.bands.len() as u32 + LEGEND_H / 2) as i32;
        let style = text(14.0, HPos::Left, VPos::Center);
        let mut x = 40;
        for (v, name) in [
            (Validity::Valid, "valid"),
            (Validity::Degraded, "degraded (warned)"),
            (Validity::Refused, "refused (error)"),
        ] {
            root.draw(&Rectangle::new(
                [(x, y - 8), (x + 28, y + 8)],
                fill(v).filled(),
            ))?;
            put_text(root, name, (x + 36, y), &style, pen)?;
            x += 200;
        }
        root.draw(&Circle::new((x + 10, y), 5, BLACK.filled()))?;
        put_text(root, "tiny run physical", (x + 22, y), &style, pen)?;
        root.draw(&Cross::new((x + 170, y), 6, BLACK.stroke_width(3)))?;
        put_text(root, "tiny run not physical", (x + 182, y), &style, pen)?;
        Ok(())
    }
}
