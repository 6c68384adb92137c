//! Legends: the little sample drawn in front of each label ([`Sample`]), and a [`Legend`]
//! laid out in centred rows that fit the image width.

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::{put_text, text, text_width, DrawError, Pen, LAYER_COLOURS};

/// Legend: row height, sample width, gap between entries, padding; px.
pub(super) const LEGEND_ROW: u32 = 24;
pub(super) const SAMPLE_W: u32 = 30;
pub(super) const LEGEND_GAP: u32 = 26;
pub(super) const LEGEND_PAD: u32 = 6;

/// The little drawing in front of a legend label.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Sample {
    /// Two thin lines in the two layer colours.
    Layers,
    /// A solid line of a colour and width.
    Line(RGBColor, u32),
    /// A dashed line.
    Dashed(RGBColor),
    /// A filled dot.
    Dot(RGBColor),
    /// A filled upward triangle.
    Triangle(RGBColor),
}

/// One legend entry.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct LegendEntry {
    /// What the sample looks like.
    pub(super) sample: Sample,
    /// Its label.
    pub(super) label: std::borrow::Cow<'static, str>,
}

/// Legend text style.
pub(super) fn legend_style() -> TextStyle<'static> {
    text(14.0, HPos::Left, VPos::Center)
}

/// A legend laid out in centred rows.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Legend {
    /// Entries.
    pub(super) entries: Vec<LegendEntry>,
    /// Top-left corner of each entry, relative to the legend strip.
    pub(super) slots: Vec<(i32, i32)>,
    /// Strip height, px (0 without entries).
    pub(super) height: u32,
}

impl Legend {
    /// Lay out `entries` in centred rows that fit `width`.
    pub(super) fn new(entries: Vec<LegendEntry>, width: u32) -> Result<Self, DrawError> {
        if entries.is_empty() {
            return Ok(Legend {
                entries,
                slots: Vec::new(),
                height: 0,
            });
        }
        let style = legend_style();
        let widths = entries
            .iter()
            .map(|e| Ok(SAMPLE_W + 6 + text_width(&style, &e.label)? as u32))
            .collect::<Result<Vec<u32>, DrawError>>()?;
        let avail = width.saturating_sub(2 * LEGEND_PAD);
        let mut rows: Vec<(Vec<usize>, u32)> = vec![(Vec::new(), 0)];
        for (i, &w) in widths.iter().enumerate() {
            let (row, row_w) = rows.last_mut().expect("rows start non-empty");
            let need = if row.is_empty() {
                w
            } else {
                *row_w + LEGEND_GAP + w
            };
            if need > avail && !row.is_empty() {
                rows.push((vec![i], w));
            } else {
                row.push(i);
                *row_w = need;
            }
        }
        let mut slots = vec![(0, 0); entries.len()];
        for (r, (row, row_w)) in rows.iter().enumerate() {
            let mut x = (width.saturating_sub(*row_w) / 2) as i32;
            let y = (LEGEND_PAD + r as u32 * LEGEND_ROW) as i32;
            for &i in row {
                slots[i] = (x, y);
                x += (widths[i] + LEGEND_GAP) as i32;
            }
        }
        Ok(Legend {
            entries,
            slots,
            height: 2 * LEGEND_PAD + rows.len() as u32 * LEGEND_ROW,
        })
    }

    /// Draw the legend with its strip's top edge at `top`.
    pub(super) fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        top: i32,
        pen: Pen,
    ) -> Result<(), DrawError>
    where
        DB::ErrorType: 'static,
    {
        let sw = SAMPLE_W as i32;
        for (entry, &(x, y)) in self.entries.iter().zip(&self.slots) {
            let cy = top + y + LEGEND_ROW as i32 / 2;
            match entry.sample {
                Sample::Layers => {
                    for (k, colour) in LAYER_COLOURS.iter().enumerate() {
                        let ly = cy - 3 + 6 * k as i32;
                        root.draw(&PathElement::new(
                            vec![(x, ly), (x + sw, ly)],
                            colour.stroke_width(2),
                        ))?;
                    }
                }
                Sample::Line(colour, width) => {
                    root.draw(&PathElement::new(
                        vec![(x, cy), (x + sw, cy)],
                        colour.stroke_width(width),
                    ))?;
                }
                Sample::Dashed(colour) => {
                    for (a, b) in [(0, 10), (16, 26)] {
                        root.draw(&PathElement::new(
                            vec![(x + a, cy), (x + b, cy)],
                            colour.stroke_width(2),
                        ))?;
                    }
                }
                Sample::Dot(colour) => {
                    root.draw(&Circle::new((x + sw / 2, cy), 4, colour.filled()))?;
                }
                Sample::Triangle(colour) => {
                    root.draw(&TriangleMarker::new((x + sw / 2, cy), 7, colour.filled()))?;
                }
            }
            put_text(root, &entry.label, (x + sw + 6, cy), &legend_style(), pen)?;
        }
        Ok(())
    }
}

/// A mass for a drawpoint label: kg below 1 t (`"20.0 kg"`, `"412 kg"`), t below 10 kt
/// (`"1.23 t"`, `"412 t"`, `"4120 t"`), kt above (`"12.3 kt"`).
pub fn fmt_mass(tonnes: f64) -> String {
    if !tonnes.is_finite() {
        return "–".into();
    }
    let t = tonnes.max(0.0);
    if t < 1.0 {
        let kg = t * 1000.0;
        if kg < 100.0 {
            format!("{kg:.1} kg")
        } else {
            format!("{kg:.0} kg")
        }
    } else if t < 10.0 {
        format!("{t:.2} t")
    } else if t < 100.0 {
        format!("{t:.1} t")
    } else if t < 10_000.0 {
        format!("{t:.0} t")
    } else {
        format!("{:.1} kt", t / 1000.0)
    }
}
