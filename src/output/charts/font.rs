//! The bundled font and how text is set: DejaVu Sans registered with plotters once, its
//! metrics read from the font file ([`FontMetrics`]), and [`put_text`], which every piece of
//! chart text goes through.
//!
//! # Why text is set glyph by glyph
//! plotters 0.3.7 rasterises ab_glyph text with each glyph's ink at the pen position, dropping
//! the glyph's left side bearing, so PNG text comes out unevenly spaced ("0.41 2 t"). Its
//! backend traits are not re-exported, so the fix cannot live in a wrapping backend without a
//! new dependency. Instead every piece of text goes through one function that, on bitmaps, sets
//! it glyph by glyph with the bearings read from the bundled font (`FontMetrics`); tick
//! marks, tick labels and frames are drawn by the charts too (see `axes`), so that they use
//! it. SVG text is one `<text>` element per label, laid out by the viewer.

use std::path::Path;
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::FontStyle;

use super::{ChartError, DrawError};

/// Font family name the bundled font is registered under.
pub(super) const FONT: &str = "sans-serif";
/// DejaVu Sans 2.37 (Bitstream Vera licence, see `src/output/fonts/LICENSE-DejaVu.txt`).
pub(super) const FONT_TTF: &[u8] = include_bytes!("../fonts/DejaVuSans.ttf");

/// How text is set on a backend.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Pen {
    /// Glyph by glyph, with the font's left side bearings (bitmaps; see [`FontMetrics`]).
    Glyphs,
    /// One text element per label (SVG: the viewer lays it out).
    Whole,
}

/// Registers the bundled font with plotters once; false if it failed to parse.
pub(super) fn font_ready() -> bool {
    static READY: OnceLock<bool> = OnceLock::new();
    *READY.get_or_init(|| plotters::style::register_font(FONT, FontStyle::Normal, FONT_TTF).is_ok())
}

/// [`font_ready`], as a [`ChartError`] naming the path.
pub(super) fn ensure_font(path: &Path) -> Result<(), ChartError> {
    if font_ready() {
        Ok(())
    } else {
        Err(ChartError::Draw {
            path: path.to_path_buf(),
            message: "the bundled font DejaVuSans.ttf could not be loaded".into(),
        })
    }
}

/// Text style of the bundled font at `size` px, anchored at `h`, `v`.
pub(super) fn text(size: f64, h: HPos, v: VPos) -> TextStyle<'static> {
    TextStyle::from((FONT, size).into_font()).pos(Pos::new(h, v))
}

/// Width of `s` in `style` along its baseline, px.
pub(super) fn text_width(style: &TextStyle, s: &str) -> Result<i32, DrawError> {
    let ((x0, _), (x1, _)) = style.font.layout_box(s)?;
    Ok(x1 - x0)
}

/// Big-endian reads from font tables; `None` past the end.
pub(super) fn be_u16(data: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_be_bytes(data.get(at..at + 2)?.try_into().ok()?))
}

/// See [`be_u16`].
pub(super) fn be_u32(data: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_be_bytes(data.get(at..at + 4)?.try_into().ok()?))
}

/// Left side bearings and cap height of the bundled font, read from its `hhea`, `hmtx`,
/// `cmap` (format 4), `head`, `loca` and `glyf` tables.
///
/// # Why
/// plotters 0.3.7 draws an ab_glyph glyph with its ink box at the pen position, so the left
/// side bearing (the blank between the pen and the ink) is lost and letter spacing wobbles by
/// a pixel or two; it also ignores where the anchor asks the baseline to be. With the bearings
/// and the cap height known, [`put_text`] places each glyph where it belongs. ab_glyph scales
/// font units by `size / (ascent − descent)`, with both from `hhea`.
#[derive(Debug)]
pub(super) struct FontMetrics {
    /// The font file.
    data: &'static [u8],
    /// Offset of the `cmap` format 4 subtable.
    cmap4: usize,
    /// Offset of the `hmtx` table.
    hmtx: usize,
    /// Number of (advance, bearing) pairs in `hmtx`.
    n_hmetrics: usize,
    /// ascent − descent, font units.
    height_units: f64,
    /// Cap height (top of 'H'), font units.
    cap_units: f64,
}

impl FontMetrics {
    /// Read the tables; `None` if the font lacks one of them.
    fn parse(data: &'static [u8]) -> Option<Self> {
        let n_tables = usize::from(be_u16(data, 4)?);
        let table = |tag: &[u8]| {
            (0..n_tables)
                .map(|i| 12 + 16 * i)
                .find(|&rec| data.get(rec..rec + 4) == Some(tag))
                .and_then(|rec| be_u32(data, rec + 8))
                .map(|offset| offset as usize)
        };
        let (hhea, hmtx, cmap) = (table(b"hhea")?, table(b"hmtx")?, table(b"cmap")?);
        let ascent = be_u16(data, hhea + 4)? as i16;
        let descent = be_u16(data, hhea + 6)? as i16;
        let n_hmetrics = usize::from(be_u16(data, hhea + 34)?);
        let n_subtables = usize::from(be_u16(data, cmap + 2)?);
        let cmap4 = (0..n_subtables).find_map(|i| {
            let rec = cmap + 4 + 8 * i;
            let (platform, encoding) = (be_u16(data, rec)?, be_u16(data, rec + 2)?);
            let sub = cmap + be_u32(data, rec + 4)? as usize;
            let unicode = platform == 0 || (platform == 3 && encoding == 1);
            (unicode && be_u16(data, sub)? == 4).then_some(sub)
        })?;
        let height_units = f64::from(ascent) - f64::from(descent);
        let mut metrics = FontMetrics {
            data,
            cmap4,
            hmtx,
            n_hmetrics,
            height_units,
            cap_units: 0.0,
        };
        // Cap height from the bounding box of 'H' in `glyf` (located through `loca`, whose
        // offsets are u16 halves or u32 bytes as `head.indexToLocFormat` says).
        let (head, loca, glyf) = (table(b"head")?, table(b"loca")?, table(b"glyf")?);
        let h = metrics.glyph('H')?;
        let offset = match be_u16(data, head + 50)? {
            0 => 2 * usize::from(be_u16(data, loca + 2 * h)?),
            _ => be_u32(data, loca + 4 * h)? as usize,
        };
        metrics.cap_units = f64::from(be_u16(data, glyf + offset + 8)? as i16);
        (n_hmetrics > 0 && height_units > 0.0 && metrics.cap_units > 0.0).then_some(metrics)
    }

    /// Glyph id of a character (basic multilingual plane), if the font maps it.
    fn glyph(&self, c: char) -> Option<usize> {
        let c = u16::try_from(u32::from(c)).ok()?;
        let (d, sub) = (self.data, self.cmap4);
        let seg_x2 = usize::from(be_u16(d, sub + 6)?);
        let ends = sub + 14;
        let starts = ends + seg_x2 + 2;
        let deltas = starts + seg_x2;
        let ranges = deltas + seg_x2;
        let seg = (0..seg_x2 / 2).find(|&i| be_u16(d, ends + 2 * i).is_some_and(|end| end >= c))?;
        let start = be_u16(d, starts + 2 * seg)?;
        if start > c {
            return None;
        }
        let delta = be_u16(d, deltas + 2 * seg)?;
        let range = usize::from(be_u16(d, ranges + 2 * seg)?);
        let id = if range == 0 {
            c.wrapping_add(delta)
        } else {
            let at = ranges + 2 * seg + range + 2 * usize::from(c - start);
            match be_u16(d, at)? {
                0 => return None,
                g => g.wrapping_add(delta),
            }
        };
        Some(usize::from(id))
    }

    /// Left side bearing of a character at `size` px, rounded down as ab_glyph rounds the ink
    /// box; 0 for characters the font does not map.
    fn bearing_px(&self, c: char, size: f64) -> i32 {
        let n = self.n_hmetrics;
        self.glyph(c)
            .and_then(|g| {
                let at = if g < n {
                    self.hmtx + 4 * g + 2
                } else {
                    self.hmtx + 4 * n + 2 * (g - n)
                };
                be_u16(self.data, at)
            })
            .map_or(0, |lsb| {
                (f64::from(lsb as i16) * size / self.height_units).floor() as i32
            })
    }

    /// Cap height at `size` px.
    fn cap_px(&self, size: f64) -> i32 {
        (self.cap_units * size / self.height_units).round() as i32
    }
}

/// The bundled font's metrics, parsed once.
pub(super) fn font_metrics() -> Option<&'static FontMetrics> {
    static METRICS: OnceLock<Option<FontMetrics>> = OnceLock::new();
    METRICS
        .get_or_init(|| FontMetrics::parse(FONT_TTF))
        .as_ref()
}

/// Draw `s` at `pos` (anchored as `style` says) on `root`.
///
/// With [`Pen::Glyphs`] each glyph is drawn on its own at pen position plus left side bearing,
/// and the baseline is put where the anchor means it: the cap height below the anchor for
/// `VPos::Top`, half of it for `VPos::Center`, on the anchor for `VPos::Bottom` (plotters'
/// ab_glyph path puts it half the font size below the anchor's box top, whatever the anchor).
/// Rotated styles advance along their rotated baseline. Sizes should be even whole pixels:
/// plotters truncates half the size per glyph, and an odd size makes glyphs hop by a pixel.
pub(super) fn put_text<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    s: &str,
    pos: (i32, i32),
    style: &TextStyle<'static>,
    pen: Pen,
) -> Result<(), DrawError>
where
    DB::ErrorType: 'static,
{
    let metrics = match (pen, font_metrics()) {
        (Pen::Glyphs, Some(m)) => m,
        _ => {
            root.draw(&Text::new(s.to_string(), pos, style.clone()))?;
            return Ok(());
        }
    };
    let dx = match style.pos.h_pos {
        HPos::Left => 0,
        HPos::Center => -text_width(style, s)? / 2,
        HPos::Right => -text_width(style, s)?,
    };
    let glyph_style = style.pos(Pos::new(HPos::Left, style.pos.v_pos));
    let transform = style.font.get_transform();
    let size = style.font.get_size();
    // plotters: box height `size / 1.24`, baseline `size / 2` below the box top.
    let box_h = (size / 1.24) as i32;
    let cap = metrics.cap_px(size);
    let (box_top, baseline) = match style.pos.v_pos {
        VPos::Top => (0, cap),
        VPos::Center => (-box_h / 2, cap / 2),
        VPos::Bottom => (-box_h, 0),
    };
    let down = baseline - box_top - (size / 2.0) as i32;
    for (i, c) in s.char_indices().filter(|(_, c)| !c.is_whitespace()) {
        let end = i + c.len_utf8();
        // Pen position of this glyph: the advance of everything before it, kerning included.
        let advance = text_width(style, &s[..end])? - text_width(style, &s[i..end])?;
        let (ox, oy) = transform.transform(dx + advance + metrics.bearing_px(c, size), down);
        root.draw(&Text::new(
            &s[i..end],
            (pos.0 + ox, pos.1 + oy),
            glyph_style.clone(),
        ))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn font_metrics_match_ab_glyph_advances() {
        assert!(font_ready());
        let m = font_metrics().expect("bundled font parses");
        // Each glyph's hmtx advance, scaled as assumed, is plotters' own layout width: this
        // checks the scale (ascent − descent) and the cmap lookup together. At 1000 px the
        // layout's rounding to whole pixels is below 0.1 %.
        let style = text(1000.0, HPos::Left, VPos::Top);
        for c in "IN-T2: drawdown after 0.412 t (IMZ) Mo %".chars() {
            let g = m.glyph(c).expect("mapped");
            let at = m.hmtx + 4 * g.min(m.n_hmetrics - 1);
            let advance = f64::from(be_u16(m.data, at).unwrap()) * 1000.0 / m.height_units;
            let width = f64::from(text_width(&style, &c.to_string()).unwrap());
            assert!(
                (advance - width).abs() <= 1.0,
                "{c:?}: {advance} vs {width}"
            );
        }
        // '1' sits well right of its pen position; 'j' hangs left of it.
        assert!(m.bearing_px('1', 40.0) >= 3, "{}", m.bearing_px('1', 40.0));
        assert!(m.bearing_px('j', 40.0) < 0);
        assert_eq!(m.bearing_px('\u{10000}', 40.0), 0);
    }

    /// Ink bounding box (x0, y0, x1, y1) of `s` drawn at (20, 40) on white.
    fn ink_box(s: &str, v: VPos, pen: Pen) -> (u32, u32, u32, u32) {
        let (w, h) = (240u32, 120u32);
        let mut buf = vec![255u8; (w * h * 3) as usize];
        {
            let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
            put_text(&root, s, (20, 40), &text(40.0, HPos::Left, v), pen).unwrap();
            root.present().unwrap();
        }
        let ink = buf
            .chunks_exact(3)
            .enumerate()
            .filter(|(_, px)| px[0] < 128)
            .map(|(i, _)| (i as u32 % w, i as u32 / w));
        ink.fold((u32::MAX, u32::MAX, 0, 0), |(a, b, c, d), (x, y)| {
            (a.min(x), b.min(y), c.max(x), d.max(y))
        })
    }

    #[test]
    fn glyphs_are_set_at_their_bearing_and_baseline() {
        assert!(font_ready());
        let bearing = font_metrics().unwrap().bearing_px('1', 40.0) as u32;
        // plotters alone puts the ink at the pen; glyph by glyph it starts a bearing later.
        assert!(bearing >= 3);
        let whole = ink_box("1", VPos::Top, Pen::Whole);
        assert!((20..=21).contains(&whole.0), "{whole:?}");
        assert_eq!(ink_box("1", VPos::Top, Pen::Glyphs).0, whole.0 + bearing);
        // Capitals hang from a top anchor, centre on a centre anchor, stand on a bottom one.
        let top = ink_box("H", VPos::Top, Pen::Glyphs);
        assert!(top.1.abs_diff(40) <= 1, "{top:?}");
        let centre = ink_box("H", VPos::Center, Pen::Glyphs);
        assert!((centre.1 + centre.3).abs_diff(80) <= 2, "{centre:?}");
        let bottom = ink_box("H", VPos::Bottom, Pen::Glyphs);
        assert!(bottom.3.abs_diff(39) <= 1, "{bottom:?}");
        // The period of "0.5" sits on the digits' baseline.
        let (digit, dot) = (
            ink_box("0", VPos::Top, Pen::Glyphs),
            ink_box(".", VPos::Top, Pen::Glyphs),
        );
        assert!(digit.3.abs_diff(dot.3) <= 1, "{digit:?} {dot:?}");
    }
}
