//! Charts for people (DESIGN §5): drawdown sections with IMZ and IEZ outlines, like the
//! summary's Figs 13 and 16, and grade against cumulative tonnes per drawpoint, like its
//! Figs 31–32.
//!
//! Charts are PNG (plotters' `BitMapBackend`) or SVG (`SVGBackend`); the file extension picks
//! the [`ChartFormat`]. Text is set in DejaVu Sans, bundled in `src/output/fonts/` (licence
//! next to it) and registered with plotters once, so no system font library is needed. Every
//! chart is written atomically: it is rendered to a temporary file next to the target
//! (`<stem>.tmp-<pid>-<n>.<ext>`) and renamed over it, so a reader never sees half a chart.
//!
//! The inputs, [`Section`] and [`GradeSeries`], are plain data. The engine-side callers fill
//! them from the run outputs; [`imz_outline`] and [`iez_outline`] turn the IMZ disk table and
//! the drawn markers' origins into the closed outlines a section draws.
//!
//! # Why text and axes are drawn here, not by plotters' mesh
//! plotters 0.3.7 rasterises ab_glyph text with each glyph's ink at the pen position, dropping
//! the glyph's left side bearing, so PNG text comes out unevenly spaced ("0.41 2 t"). Its
//! backend traits are not re-exported, so the fix cannot live in a wrapping backend without a
//! new dependency. Instead every piece of text goes through one function that, on bitmaps, sets
//! it glyph by glyph with the bearings read from the bundled font (`FontMetrics`); tick
//! marks, tick labels and frames are drawn here too, so that they use it. SVG text is one
//! `<text>` element per label, laid out by the viewer.
//!
//! # Why equal aspect and small multiples
//! A drawdown section is read as geometry: the IMZ base angle and the width of an IEZ only mean
//! something when one metre across is one metre up, so sections keep 1:1 within a pixel budget
//! ([`MAX_SIDE`]). Grade curves are compared between drawpoints, so many drawpoints share one
//! pair of axes across a grid of small panels instead of a tangle of lines on one plot.

mod reconcile;
mod stability;
mod sweep;

pub use self::reconcile::{
    diverging, error_map_chart, profile_chart, scatter_chart, MapPoint, Profile, ScatterPoint,
};
pub use self::stability::{stability_chart, RegionBand};
pub use self::sweep::{sweep_chart, SweepPoint};

use std::cmp::Ordering;
use std::collections::BTreeMap;
use std::error::Error as StdError;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering as AtomicOrdering};
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::{FontStyle, FontTransform};

pub mod stress;

/// Largest side of a chart image, px (sections and grade grids both fit inside it).
pub const MAX_SIDE: u32 = 1200;

/// Most panels on one grade-tonnage image; more series are split over several pages.
pub const MAX_PANELS: usize = 36;

/// Font family name the bundled font is registered under.
const FONT: &str = "sans-serif";
/// DejaVu Sans 2.37 (Bitstream Vera licence, see `fonts/LICENSE-DejaVu.txt`).
const FONT_TTF: &[u8] = include_bytes!("fonts/DejaVuSans.ttf");

/// Marker layers alternate these two colours, like the coloured layers of a physical model.
const LAYER_COLOURS: [RGBColor; 2] = [RGBColor(45, 95, 170), RGBColor(140, 140, 140)];
/// IMZ outline (yellow-orange).
const IMZ_COLOUR: RGBColor = RGBColor(245, 165, 0);
/// IEZ outline (magenta).
const IEZ_COLOUR: RGBColor = RGBColor(200, 0, 160);
/// Free surface (summary Fig. 33).
const SURFACE_COLOUR: RGBColor = RGBColor(120, 70, 20);
/// Uncaved ground.
const UNCAVED_FILL: RGBColor = RGBColor(190, 190, 190);
/// Fill of the model extent on a section.
const MODEL_FILL: RGBColor = RGBColor(250, 247, 238);
/// Edge of the model extent.
const FRAME_COLOUR: RGBColor = RGBColor(150, 150, 150);
/// Plot frames and tick marks.
const AXIS_COLOUR: RGBColor = RGBColor(60, 60, 60);
/// Light grid lines of grade panels.
const GRID_COLOUR: RGBColor = RGBColor(228, 228, 228);
/// Predicted grade line.
const PREDICTED_COLOUR: RGBColor = RGBColor(31, 119, 180);
/// Sampled grade points.
const SAMPLED_COLOUR: RGBColor = RGBColor(214, 39, 40);
/// Block grade (uniform drawdown) dashed line.
const BLOCK_COLOUR: RGBColor = RGBColor(70, 70, 70);

/// Height of the title strip, px.
const TITLE_H: u32 = 44;
/// Narrowest image, px (room for the title and the legend).
const MIN_W: u32 = 720;
/// Legend: row height, sample width, gap between entries, padding; px.
const LEGEND_ROW: u32 = 24;
const SAMPLE_W: u32 = 30;
const LEGEND_GAP: u32 = 26;
const LEGEND_PAD: u32 = 6;

/// Tick marks and the gap between a tick mark and its label; px.
const TICK: i32 = 5;
const TICK_GAP: i32 = 8;
/// Strip holding a rotated axis title, px.
const AXIS_TITLE_W: u32 = 28;

/// Section: x tick labels plus axis title below the plot, right margin, space above the plot;
/// px. The left margin follows the widest elevation label.
const SEC_BOTTOM: u32 = 58;
const SEC_RIGHT: u32 = 24;
const SEC_TOP: u32 = 12;
/// Section: drawpoint labels hang this far below the model base, one row per line; px.
const DP_LABEL_TOP: u32 = 12;
const DP_LINE: u32 = 16;
/// Section: most rows of drawpoint labels before labels may overlap.
const DP_MAX_ROWS: usize = 3;

/// Grade grid: right margin, x tick label strip, x title strip, gaps between panels, panel
/// caption height; px. The y tick label strip follows the widest grade label.
const G_RIGHT: u32 = 28;
const G_XL: u32 = 26;
const G_XTITLE: u32 = 30;
const G_GAP_X: u32 = 22;
const G_GAP_Y: u32 = 14;
const G_CAPTION: u32 = 20;

/// Errors while drawing or writing a chart. Every variant names the target path.
#[derive(Debug, thiserror::Error)]
pub enum ChartError {
    /// The path's extension names no supported format.
    #[error("chart {}: unsupported format (use .png or .svg)", path.display())]
    Format {
        /// Target path.
        path: PathBuf,
    },
    /// The chart's input cannot be drawn (empty, inconsistent or non-finite).
    #[error("chart {}: {message}", path.display())]
    Input {
        /// Target path.
        path: PathBuf,
        /// What is wrong with the input.
        message: String,
    },
    /// plotters failed (font, backend or encoder; a missing directory shows up here too).
    #[error("chart {}: drawing failed: {message}", path.display())]
    Draw {
        /// Target path.
        path: PathBuf,
        /// plotters' error, as text.
        message: String,
    },
    /// Syncing the finished temporary file or renaming it onto the target failed.
    #[error("chart {}: {source}", path.display())]
    Io {
        /// Target path.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
}

/// Image format of a chart, chosen from the file extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ChartFormat {
    /// Raster PNG (plotters' `BitMapBackend`).
    Png,
    /// Vector SVG (plotters' `SVGBackend`); text stays text, in the viewer's sans-serif.
    Svg,
}

impl ChartFormat {
    /// The format named by a path's extension (`png` or `svg`, any case), if any.
    pub fn from_path(path: &Path) -> Option<Self> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "png" => Some(ChartFormat::Png),
            "svg" => Some(ChartFormat::Svg),
            _ => None,
        }
    }

    /// File extension, without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            ChartFormat::Png => "png",
            ChartFormat::Svg => "svg",
        }
    }
}

/// A vertical drawdown section (summary Figs 13 and 16), as plain data in section coordinates:
/// the horizontal coordinate along the section (an Easting, a Northing or a distance) and the
/// elevation z, both in m.
///
/// The engine side fills it: marker positions per initial layer from a
/// [`MarkerSnapshot`](crate::engine::result::MarkerSnapshot), IMZ outlines from the
/// [`ImzTable`](crate::engine::result::ImzTable) through [`imz_outline`], IEZ outlines from the
/// [`DrawnTable`](crate::engine::result::DrawnTable) through [`iez_outline`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Section {
    /// Label of the horizontal axis, with its unit, e.g. `"Easting (m)"`.
    pub axis_label: String,
    /// Model extent along the section, m (low, high).
    pub x_range: (f64, f64),
    /// Model extent in elevation, m (low, high).
    pub z_range: (f64, f64),
    /// Current positions of the markers that started on one horizontal layer, one polyline per
    /// layer, sorted along the section. Drawn as thin lines in two alternating colours, so the
    /// drawdown shows as deformed, initially horizontal layers. Non-finite points break a line.
    pub layers: Vec<Vec<(f64, f64)>>,
    /// IMZ outline per drawpoint: closed polylines (see [`imz_outline`]).
    pub imz: Vec<Vec<(f64, f64)>>,
    /// IEZ outline per drawpoint: closed polylines (see [`iez_outline`]).
    pub iez: Vec<Vec<(f64, f64)>>,
    /// Drawpoints on the section: (horizontal, z, label), e.g. the name and the mass drawn.
    /// Labels are set below the model base, staggered over up to three rows when they crowd.
    pub drawpoints: Vec<(f64, f64, String)>,
    /// The free surface along the section (top of the caved material), a polyline; non-finite
    /// points break it (summary Fig. 33).
    pub surface: Vec<(f64, f64)>,
    /// Uncaved ground on the section at the end of the run: rectangles ((x0, z0), (x1, z1)).
    pub uncaved: Vec<((f64, f64), (f64, f64))>,
}

/// Grade against cumulative tonnes for one drawpoint (summary Figs 31–32).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GradeSeries {
    /// Drawpoint name: the panel caption and the sort key (natural order, so DP2 < DP10).
    pub name: String,
    /// Cumulative tonnes at the end of each period, t.
    pub cum_tonnes: Vec<f64>,
    /// Predicted grade of each period, same length as `cum_tonnes`.
    pub predicted: Vec<f64>,
    /// Sampled grades as (cumulative tonnes, grade), drawn as points (back-analysis).
    pub sampled: Option<Vec<(f64, f64)>>,
    /// Block grade under uniform drawdown as (cumulative tonnes, grade), drawn dashed.
    pub block_grade: Option<Vec<(f64, f64)>>,
}

/// Closed outline of an IMZ on a vertical section through its axis.
///
/// `disks` are (z_base, z_top, radius) in m, as in the IMZ table for one drawpoint and period,
/// in any order. The outline is the exact stair profile of the disk stack: up the right side
/// (`axis_x + R`) from the lowest disk, across the top, down the left side (`axis_x − R`), and
/// back to the first point. Disks with a zero, negative or non-finite radius (a new top disk not
/// yet dilated) are left out. No usable disk gives an empty outline.
pub fn imz_outline(disks: &[(f64, f64, f64)], axis_x: f64) -> Vec<(f64, f64)> {
    let mut stack: Vec<(f64, f64, f64)> = disks
        .iter()
        .copied()
        .filter(|&(b, t, r)| b.is_finite() && t.is_finite() && r.is_finite() && r > 0.0)
        .collect();
    stack.sort_by(|a, b| a.0.total_cmp(&b.0));
    stair_outline(&stack, axis_x)
}

/// Closed outline of an IEZ on a vertical section through a drawpoint axis.
///
/// `points` are the origins of the markers this drawpoint drew, as (horizontal coordinate
/// along the section, z) in m. Elevations are binned at multiples of `bin` (bin k covers
/// [k·bin, (k+1)·bin)); each bin's half-width is the largest |horizontal − `axis_x`| among its
/// points, and the outline is the symmetric stair profile of those half-widths, closed like
/// [`imz_outline`]. Bins without points are skipped (the outline joins across them). Non-finite
/// points are ignored; no points, or a `bin` that is not finite and positive, give an empty
/// outline.
pub fn iez_outline(points: &[(f64, f64)], axis_x: f64, bin: f64) -> Vec<(f64, f64)> {
    if !(bin.is_finite() && bin > 0.0 && axis_x.is_finite()) {
        return Vec::new();
    }
    let mut half_width: BTreeMap<i64, f64> = BTreeMap::new();
    for &(h, z) in points {
        if h.is_finite() && z.is_finite() {
            let w = (h - axis_x).abs();
            let k = (z / bin).floor() as i64;
            let entry = half_width.entry(k).or_insert(w);
            *entry = entry.max(w);
        }
    }
    let stack: Vec<(f64, f64, f64)> = half_width
        .into_iter()
        .map(|(k, w)| (k as f64 * bin, (k + 1) as f64 * bin, w))
        .collect();
    stair_outline(&stack, axis_x)
}

/// Stair profile of a stack of (z_base, z_top, half-width) sorted by z_base: right side up,
/// left side down, closed; consecutive duplicate points dropped.
fn stair_outline(stack: &[(f64, f64, f64)], axis_x: f64) -> Vec<(f64, f64)> {
    let mut out: Vec<(f64, f64)> = Vec::with_capacity(4 * stack.len() + 1);
    let mut push = |p: (f64, f64)| {
        if out.last() != Some(&p) {
            out.push(p);
        }
    };
    for &(b, t, r) in stack {
        push((axis_x + r, b));
        push((axis_x + r, t));
    }
    for &(b, t, r) in stack.iter().rev() {
        push((axis_x - r, t));
        push((axis_x - r, b));
    }
    if let Some(&first) = out.first() {
        out.push(first);
    }
    out
}

/// Draw a drawdown section (summary Figs 13 and 16) to `path` (`.png` or `.svg`).
///
/// One metre across is one metre up; the image fits in [`MAX_SIDE`] px. The plotted extent is
/// the model extent (shaded) grown to hold every finite point of the section, plus a strip
/// below for the drawpoint labels. A legend below the plot names what is drawn.
pub fn section_chart(path: &Path, section: &Section, title: &str) -> Result<(), ChartError> {
    ensure_font(path)?;
    let plot = SectionPlot::new(section, title).map_err(|e| e.into_chart_error(path))?;
    write_chart(path, &plot)
}

/// Draw grade against cumulative tonnes, one small panel per drawpoint, to `path` (`.png` or
/// `.svg`); returns the files written.
///
/// Panels are sorted by name in natural order and share both axes (tonnes from 0, grade from
/// 0 or below), so drawpoints compare at a glance. Up to [`MAX_PANELS`] panels go on one image,
/// written to `path`. More series are spread evenly over several pages, written to
/// `<stem>-<k>.<ext>` (k from 1, zero-padded) instead of `path`. Tonnes are shown in t, kt or
/// Mt by their size. `grade_label` names the grade and its unit, e.g. `"Mo (%)"`.
pub fn grade_tonnage_chart(
    path: &Path,
    series: &[GradeSeries],
    title: &str,
    grade_label: &str,
) -> Result<Vec<PathBuf>, ChartError> {
    ensure_font(path)?;
    let input = |message: String| ChartError::Input {
        path: path.to_path_buf(),
        message,
    };
    if series.is_empty() {
        return Err(input("no grade series to chart".into()));
    }
    if let Some(s) = series
        .iter()
        .find(|s| s.cum_tonnes.len() != s.predicted.len())
    {
        return Err(input(format!(
            "series {:?} has {} cumulative tonnes but {} predicted grades",
            s.name,
            s.cum_tonnes.len(),
            s.predicted.len()
        )));
    }
    let axes = GradeAxes::new(series);
    let pages = paginate(series);
    let paths = page_paths(path, pages.len());
    for (k, (page, page_path)) in pages.iter().zip(&paths).enumerate() {
        let page_title = if pages.len() > 1 {
            format!("{title} ({}/{})", k + 1, pages.len())
        } else {
            title.to_string()
        };
        let chart = GradePage::new(page, page_title, grade_label, &axes)
            .map_err(|e| e.into_chart_error(page_path))?;
        write_chart(page_path, &chart)?;
    }
    Ok(paths)
}

/// Errors inside rendering: plotters' drawing and font errors, boxed.
type DrawError = Box<dyn StdError>;

/// Turns a [`DrawError`] into a [`ChartError::Draw`] naming the path.
trait IntoChartError {
    /// The error as a [`ChartError::Draw`].
    fn into_chart_error(self, path: &Path) -> ChartError;
}

impl IntoChartError for DrawError {
    fn into_chart_error(self, path: &Path) -> ChartError {
        ChartError::Draw {
            path: path.to_path_buf(),
            message: self.to_string(),
        }
    }
}

/// How text is set on a backend.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Pen {
    /// Glyph by glyph, with the font's left side bearings (bitmaps; see [`FontMetrics`]).
    Glyphs,
    /// One text element per label (SVG: the viewer lays it out).
    Whole,
}

/// A laid-out chart that any plotters backend can draw.
trait Render {
    /// Image size, px.
    fn size(&self) -> (u32, u32);
    /// The title, set centred over the top of the image.
    fn title(&self) -> &str;
    /// Draw everything below the title onto `root`, setting text with `pen`.
    fn draw_body<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        pen: Pen,
    ) -> Result<(), DrawError>
    where
        DB::ErrorType: 'static;
    /// Draw the whole image: a white page, the title, the body.
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        pen: Pen,
    ) -> Result<(), DrawError>
    where
        DB::ErrorType: 'static,
    {
        root.fill(&WHITE)?;
        draw_title(root, self.title(), self.size().0, pen)?;
        self.draw_body(root, pen)
    }
}

/// Registers the bundled font with plotters once; false if it failed to parse.
fn font_ready() -> bool {
    static READY: OnceLock<bool> = OnceLock::new();
    *READY.get_or_init(|| plotters::style::register_font(FONT, FontStyle::Normal, FONT_TTF).is_ok())
}

/// [`font_ready`], as a [`ChartError`] naming the path.
fn ensure_font(path: &Path) -> Result<(), ChartError> {
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
fn text(size: f64, h: HPos, v: VPos) -> TextStyle<'static> {
    TextStyle::from((FONT, size).into_font()).pos(Pos::new(h, v))
}

/// Width of `s` in `style` along its baseline, px.
fn text_width(style: &TextStyle, s: &str) -> Result<i32, DrawError> {
    let ((x0, _), (x1, _)) = style.font.layout_box(s)?;
    Ok(x1 - x0)
}

/// Big-endian reads from font tables; `None` past the end.
fn be_u16(data: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_be_bytes(data.get(at..at + 2)?.try_into().ok()?))
}

/// See [`be_u16`].
fn be_u32(data: &[u8], at: usize) -> Option<u32> {
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
struct FontMetrics {
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
fn font_metrics() -> Option<&'static FontMetrics> {
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
fn put_text<DB: DrawingBackend>(
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

/// Render `chart` to a temporary file next to `path`, sync it, then rename it onto `path`.
fn write_chart<R: Render>(path: &Path, chart: &R) -> Result<(), ChartError> {
    let format = ChartFormat::from_path(path).ok_or_else(|| ChartError::Format {
        path: path.to_path_buf(),
    })?;
    let tmp = temp_path(path, format);
    let result = render_file(&tmp, format, chart)
        .map_err(|e| e.into_chart_error(path))
        .and_then(|()| {
            let io = |source| ChartError::Io {
                path: path.to_path_buf(),
                source,
            };
            // Synced before the rename and the directory after it, like every other output
            // file (see `output::parquet`).
            std::fs::File::open(&tmp)
                .and_then(|f| f.sync_all())
                .map_err(io)?;
            std::fs::rename(&tmp, path).map_err(io)?;
            super::parquet::sync_parent(path).map_err(io)
        });
    if result.is_err() {
        // The backend may have written a partial file before failing; it is ours to remove.
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Temporary sibling of `path`: `<stem>.tmp-<pid>-<n>.<ext>`. The extension stays last
/// because the PNG encoder picks the format from it; `n` keeps threads apart.
fn temp_path(path: &Path, format: ChartFormat) -> PathBuf {
    static SEQ: AtomicU64 = AtomicU64::new(0);
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "chart".into());
    let n = SEQ.fetch_add(1, AtomicOrdering::Relaxed);
    path.with_file_name(format!(
        "{stem}.tmp-{}-{n}.{}",
        std::process::id(),
        format.extension()
    ))
}

/// Draw `chart` into the file `tmp` with the backend of `format`.
fn render_file<R: Render>(tmp: &Path, format: ChartFormat, chart: &R) -> Result<(), DrawError> {
    match format {
        ChartFormat::Png => {
            let root = BitMapBackend::new(tmp, chart.size()).into_drawing_area();
            chart.draw(&root, Pen::Glyphs)?;
            root.present()?;
        }
        ChartFormat::Svg => {
            let root = SVGBackend::new(tmp, chart.size()).into_drawing_area();
            chart.draw(&root, Pen::Whole)?;
            root.present()?;
        }
    }
    Ok(())
}

/// Split a polyline at non-finite points into runs of finite points.
fn finite_runs(points: &[(f64, f64)]) -> Vec<Vec<(f64, f64)>> {
    points
        .split(|p| !(p.0.is_finite() && p.1.is_finite()))
        .filter(|run| !run.is_empty())
        .map(<[_]>::to_vec)
        .collect()
}

/// Draw the title, centred in the title strip.
fn draw_title<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    width: u32,
    pen: Pen,
) -> Result<(), DrawError>
where
    DB::ErrorType: 'static,
{
    let style = text(20.0, HPos::Center, VPos::Center);
    put_text(
        root,
        title,
        (width as i32 / 2, TITLE_H as i32 / 2),
        &style,
        pen,
    )
}

/// A plotting frame: a pixel rectangle on the root area and the data ranges it spans.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Frame {
    /// Left and top pixel.
    left: i32,
    top: i32,
    /// Width and height, px.
    size: (u32, u32),
    /// Horizontal and vertical data ranges (low, high).
    x: (f64, f64),
    y: (f64, f64),
}

impl Frame {
    /// Right pixel column.
    fn right(&self) -> i32 {
        self.left + self.size.0 as i32 - 1
    }

    /// Bottom pixel row.
    fn bottom(&self) -> i32 {
        self.top + self.size.1 as i32 - 1
    }

    /// Pixel of a data point (y up).
    fn px(&self, (x, y): (f64, f64)) -> (i32, i32) {
        let fx = (x - self.x.0) / (self.x.1 - self.x.0) * f64::from(self.size.0 - 1);
        let fy = (y - self.y.0) / (self.y.1 - self.y.0) * f64::from(self.size.1 - 1);
        (
            self.left + fx.round() as i32,
            self.bottom() - fy.round() as i32,
        )
    }

    /// Pixels of a polyline.
    fn path(&self, points: &[(f64, f64)]) -> Vec<(i32, i32)> {
        points.iter().map(|&p| self.px(p)).collect()
    }
}

/// Tick values and their labels along one axis.
#[derive(Debug, Clone, PartialEq)]
struct Ticks {
    /// Values, increasing.
    values: Vec<f64>,
    /// Labels, one per value.
    labels: Vec<String>,
}

impl Ticks {
    /// No ticks.
    fn empty() -> Ticks {
        Ticks {
            values: Vec::new(),
            labels: Vec::new(),
        }
    }
}

/// Ticks at 1, 2 or 5 × 10^k inside [lo, hi], about `max` of them at most.
fn nice_ticks(lo: f64, hi: f64, max: usize) -> Ticks {
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
fn fit_ticks(
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
fn tick_style(h: HPos, v: VPos) -> TextStyle<'static> {
    text(12.0, h, v)
}

/// Ticks for a horizontal axis of a frame.
fn x_ticks(frame: &Frame) -> Result<Ticks, DrawError> {
    let style = tick_style(HPos::Center, VPos::Top);
    fit_ticks(frame.x, frame.size.0, 70, |s| text_width(&style, s))
}

/// Ticks for a vertical axis of a frame.
fn y_ticks(frame: &Frame) -> Result<Ticks, DrawError> {
    let height = tick_style(HPos::Right, VPos::Center).font.get_size() as i32;
    fit_ticks(frame.y, frame.size.1, 36, |_| Ok(height))
}

/// Widest label of ticks over [lo, hi], px (sizes the margin left of a frame).
fn widest_tick_label(lo: f64, hi: f64) -> Result<u32, DrawError> {
    let style = tick_style(HPos::Right, VPos::Center);
    let mut widest = 0;
    for label in nice_ticks(lo, hi, 10).labels {
        widest = widest.max(text_width(&style, &label)?);
    }
    Ok(widest as u32)
}

/// Which sides of a frame [`draw_axes`] labels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct AxisLabels {
    /// Tick marks and labels below the frame.
    x: bool,
    /// Tick marks and labels left of the frame.
    y: bool,
}

/// Draw light grid lines at a frame's ticks (under the data: call first).
fn draw_grid<DB: DrawingBackend>(
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
fn draw_axes<DB: DrawingBackend>(
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
fn axis_title_style(vertical: bool) -> TextStyle<'static> {
    let style = text(16.0, HPos::Center, VPos::Center);
    if vertical {
        style.transform(FontTransform::Rotate270)
    } else {
        style
    }
}

/// The little drawing in front of a legend label.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Sample {
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
struct LegendEntry {
    /// What the sample looks like.
    sample: Sample,
    /// Its label.
    label: &'static str,
}

/// Legend text style.
fn legend_style() -> TextStyle<'static> {
    text(14.0, HPos::Left, VPos::Center)
}

/// A legend laid out in centred rows.
#[derive(Debug, Clone, PartialEq)]
struct Legend {
    /// Entries.
    entries: Vec<LegendEntry>,
    /// Top-left corner of each entry, relative to the legend strip.
    slots: Vec<(i32, i32)>,
    /// Strip height, px (0 without entries).
    height: u32,
}

impl Legend {
    /// Lay out `entries` in centred rows that fit `width`.
    fn new(entries: Vec<LegendEntry>, width: u32) -> Result<Self, DrawError> {
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
            .map(|e| Ok(SAMPLE_W + 6 + text_width(&style, e.label)? as u32))
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
    fn draw<DB: DrawingBackend>(
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
            put_text(root, entry.label, (x + sw + 6, cy), &legend_style(), pen)?;
        }
        Ok(())
    }
}

/// Layout failures: bad input, or a font measurement that failed.
enum LayoutError {
    /// The input cannot be drawn.
    Input(String),
    /// Text measurement failed.
    Draw(DrawError),
}

impl LayoutError {
    /// As a [`ChartError`] naming the path.
    fn into_chart_error(self, path: &Path) -> ChartError {
        match self {
            LayoutError::Input(message) => ChartError::Input {
                path: path.to_path_buf(),
                message,
            },
            LayoutError::Draw(e) => e.into_chart_error(path),
        }
    }
}

impl From<DrawError> for LayoutError {
    fn from(e: DrawError) -> Self {
        LayoutError::Draw(e)
    }
}

/// A section laid out in pixels.
struct SectionPlot<'a> {
    /// The data.
    section: &'a Section,
    /// The title.
    title: &'a str,
    /// Image size, px.
    size: (u32, u32),
    /// The plotting frame (equal aspect; its elevation range includes the label strip).
    frame: Frame,
    /// Space for the elevation tick labels left of the frame, px.
    y_label_w: u32,
    /// Elevation the drawpoint labels hang from (lowest model or data point), m.
    z_base: f64,
    /// Label row of each drawpoint.
    label_rows: Vec<usize>,
    /// The legend, below the plot.
    legend: Legend,
}

impl<'a> SectionPlot<'a> {
    /// Validate the section and lay it out.
    fn new(section: &'a Section, title: &'a str) -> Result<Self, LayoutError> {
        let (x_lo, x_hi) = section.x_range;
        let (z_lo, z_hi) = section.z_range;
        if !(x_lo.is_finite() && x_hi.is_finite() && x_hi > x_lo) {
            return Err(LayoutError::Input(format!(
                "section x range {:?} is not a finite, increasing interval",
                section.x_range
            )));
        }
        if !(z_lo.is_finite() && z_hi.is_finite() && z_hi > z_lo) {
            return Err(LayoutError::Input(format!(
                "section z range {:?} is not a finite, increasing interval",
                section.z_range
            )));
        }
        let (mut x0, mut x1, mut z0, mut z1) = (x_lo, x_hi, z_lo, z_hi);
        let polylines = section
            .layers
            .iter()
            .chain(&section.imz)
            .chain(&section.iez);
        let points = polylines
            .flatten()
            .copied()
            .chain(section.drawpoints.iter().map(|d| (d.0, d.1)));
        for (x, z) in points.filter(|p| p.0.is_finite() && p.1.is_finite()) {
            x0 = x0.min(x);
            x1 = x1.max(x);
            z0 = z0.min(z);
            z1 = z1.max(z);
        }
        let (dx, dz) = (x1 - x0, z1 - z0);

        // The label strip extends the elevation range down by a fraction of it at most.
        let y_label_w = widest_tick_label(z0 - 0.25 * dz, z1)? + TICK_GAP as u32 + 6;
        let left = AXIS_TITLE_W + y_label_w;
        let entries = section_legend(section);
        let legend_h_max = Legend::new(entries.clone(), MIN_W)?.height;
        let has_dps = !section.drawpoints.is_empty();
        let w_max = MAX_SIDE.saturating_sub(left + SEC_RIGHT).max(120);
        let h_max = MAX_SIDE
            .saturating_sub(
                TITLE_H + SEC_TOP + SEC_BOTTOM + legend_h_max + band_px(has_dps, DP_MAX_ROWS),
            )
            .max(120);
        let scale = (f64::from(w_max - 1) / dx).min(f64::from(h_max - 1) / dz);

        let (label_rows, rows_used) = label_rows(&section.drawpoints, x0, scale)?;
        let plot_w = (dx * scale).round() as u32 + 1;
        let plot_h = (dz * scale).round() as u32 + 1 + band_px(has_dps, rows_used);
        let chart_w = left + plot_w + SEC_RIGHT;
        let title_w = text_width(&text(20.0, HPos::Center, VPos::Center), title)? as u32 + 40;
        let width = chart_w.max(MIN_W).max(title_w);
        let legend = Legend::new(entries, width)?;
        let height = TITLE_H + SEC_TOP + plot_h + SEC_BOTTOM + legend.height;
        // A frame of n px spans n − 1 px steps, so these ranges keep exactly `scale` px/m on
        // both axes.
        let frame = Frame {
            left: ((width - chart_w) / 2 + left) as i32,
            top: (TITLE_H + SEC_TOP) as i32,
            size: (plot_w, plot_h),
            x: (x0, x0 + f64::from(plot_w - 1) / scale),
            y: (z1 - f64::from(plot_h - 1) / scale, z1),
        };
        Ok(SectionPlot {
            section,
            title,
            size: (width, height),
            frame,
            y_label_w,
            z_base: z0,
            label_rows,
            legend,
        })
    }
}

/// Height of the drawpoint label strip with `rows` rows of labels, px (0 without drawpoints).
fn band_px(has_drawpoints: bool, rows: usize) -> u32 {
    if has_drawpoints {
        DP_LABEL_TOP + rows as u32 * DP_LINE + 4
    } else {
        0
    }
}

/// Drawpoint label text style.
fn dp_label_style() -> TextStyle<'static> {
    text(12.0, HPos::Center, VPos::Top)
}

/// Assign each drawpoint label to a row so that labels in one row do not overlap (greedy,
/// left to right; past [`DP_MAX_ROWS`] a label goes to the row with the most room). Returns the
/// row of each drawpoint and the number of rows used.
fn label_rows(
    drawpoints: &[(f64, f64, String)],
    x0: f64,
    scale: f64,
) -> Result<(Vec<usize>, usize), DrawError> {
    let style = dp_label_style();
    let mut order: Vec<usize> = (0..drawpoints.len()).collect();
    order.sort_by(|&a, &b| drawpoints[a].0.total_cmp(&drawpoints[b].0));
    let mut right_edge = [f64::NEG_INFINITY; DP_MAX_ROWS];
    let mut rows = vec![0; drawpoints.len()];
    let mut used = 0;
    for i in order {
        let (x, _, label) = &drawpoints[i];
        if label.is_empty() || !x.is_finite() {
            continue;
        }
        let half = f64::from(text_width(&style, label)?) / 2.0;
        let px = (x - x0) * scale;
        let row = (0..DP_MAX_ROWS)
            .find(|&r| right_edge[r] + 10.0 <= px - half)
            .unwrap_or_else(|| {
                (0..DP_MAX_ROWS)
                    .min_by(|&a, &b| right_edge[a].total_cmp(&right_edge[b]))
                    .unwrap_or(0)
            });
        right_edge[row] = px + half;
        rows[i] = row;
        used = used.max(row + 1);
    }
    Ok((rows, used))
}

/// Legend entries for what a section actually holds.
fn section_legend(section: &Section) -> Vec<LegendEntry> {
    let mut entries = Vec::new();
    if !section.layers.is_empty() {
        entries.push(LegendEntry {
            sample: Sample::Layers,
            label: "Marker layers (initially horizontal)",
        });
    }
    if !section.imz.is_empty() {
        entries.push(LegendEntry {
            sample: Sample::Line(IMZ_COLOUR, 3),
            label: "IMZ (isolated movement zone)",
        });
    }
    if !section.iez.is_empty() {
        entries.push(LegendEntry {
            sample: Sample::Line(IEZ_COLOUR, 3),
            label: "IEZ (origin of drawn material)",
        });
    }
    if !section.surface.is_empty() {
        entries.push(LegendEntry {
            sample: Sample::Line(SURFACE_COLOUR, 3),
            label: "Free surface",
        });
    }
    if !section.uncaved.is_empty() {
        entries.push(LegendEntry {
            sample: Sample::Line(UNCAVED_FILL, 8),
            label: "Uncaved ground",
        });
    }
    if !section.drawpoints.is_empty() {
        entries.push(LegendEntry {
            sample: Sample::Triangle(BLACK),
            label: "Drawpoint",
        });
    }
    entries
}

impl Render for SectionPlot<'_> {
    fn size(&self) -> (u32, u32) {
        self.size
    }

    fn title(&self) -> &str {
        self.title
    }

    fn draw_body<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        pen: Pen,
    ) -> Result<(), DrawError>
    where
        DB::ErrorType: 'static,
    {
        let (s, f) = (self.section, &self.frame);

        let extent = [
            f.px((s.x_range.0, s.z_range.1)),
            f.px((s.x_range.1, s.z_range.0)),
        ];
        root.draw(&Rectangle::new(extent, MODEL_FILL.filled()))?;
        root.draw(&Rectangle::new(extent, FRAME_COLOUR.stroke_width(1)))?;
        for &(a, b) in &s.uncaved {
            let r = [f.px((a.0, b.1)), f.px((b.0, a.1))];
            root.draw(&Rectangle::new(r, UNCAVED_FILL.filled()))?;
        }
        for (i, layer) in s.layers.iter().enumerate() {
            for run in finite_runs(layer) {
                root.draw(&PathElement::new(f.path(&run), LAYER_COLOURS[i % 2]))?;
            }
        }
        for (outlines, colour) in [(&s.imz, IMZ_COLOUR), (&s.iez, IEZ_COLOUR)] {
            for run in outlines.iter().flat_map(|o| finite_runs(o)) {
                root.draw(&PathElement::new(f.path(&run), colour.stroke_width(3)))?;
            }
        }
        for run in finite_runs(&s.surface) {
            root.draw(&PathElement::new(
                f.path(&run),
                SURFACE_COLOUR.stroke_width(3),
            ))?;
        }
        let label_style = dp_label_style();
        for ((x, z, label), &row) in s.drawpoints.iter().zip(&self.label_rows) {
            if !(x.is_finite() && z.is_finite()) {
                continue;
            }
            root.draw(&TriangleMarker::new(f.px((*x, *z)), 7, BLACK.filled()))?;
            if !label.is_empty() {
                let (lx, ly) = f.px((*x, self.z_base));
                let dy = (DP_LABEL_TOP + row as u32 * DP_LINE) as i32;
                put_text(root, label, (lx, ly + dy), &label_style, pen)?;
            }
        }

        let ticks = (x_ticks(f)?, y_ticks(f)?);
        let labels = AxisLabels { x: true, y: true };
        draw_axes(root, f, (&ticks.0, &ticks.1), labels, pen)?;
        let centre = (f.left + f.right()) / 2;
        let below = f.bottom() + SEC_BOTTOM as i32 - 14;
        put_text(
            root,
            &s.axis_label,
            (centre, below),
            &axis_title_style(false),
            pen,
        )?;
        let title_x = f.left - self.y_label_w as i32 - AXIS_TITLE_W as i32 / 2;
        let middle = (f.top + f.bottom()) / 2;
        put_text(
            root,
            "Elevation (m)",
            (title_x, middle),
            &axis_title_style(true),
            pen,
        )?;
        self.legend
            .draw(root, (self.size.1 - self.legend.height) as i32, pen)
    }
}

/// Shared axes of all grade panels (over every page).
struct GradeAxes {
    /// Tonnes per displayed unit (1, 1e3 or 1e6).
    tonnes_per_unit: f64,
    /// Displayed tonnage unit.
    unit: &'static str,
    /// Tonnage axis end, displayed units (the axis starts at 0).
    x_max: f64,
    /// Grade axis range.
    y: (f64, f64),
}

impl GradeAxes {
    /// Axes that hold every finite point of every series.
    fn new(series: &[GradeSeries]) -> Self {
        let mut t_max = 0.0f64;
        let (mut g_lo, mut g_hi) = (0.0f64, f64::NEG_INFINITY);
        for s in series {
            let pairs = s
                .cum_tonnes
                .iter()
                .copied()
                .zip(s.predicted.iter().copied());
            let extra = s.sampled.iter().chain(&s.block_grade).flatten().copied();
            for (t, g) in pairs.chain(extra) {
                if t.is_finite() && g.is_finite() {
                    t_max = t_max.max(t);
                    g_lo = g_lo.min(g);
                    g_hi = g_hi.max(g);
                }
            }
        }
        let (tonnes_per_unit, unit) = if t_max >= 2e6 {
            (1e6, "Mt")
        } else if t_max >= 2e4 {
            (1e3, "kt")
        } else {
            (1.0, "t")
        };
        let x_max = if t_max > 0.0 {
            t_max / tonnes_per_unit * 1.02
        } else {
            1.0
        };
        let y_hi = if g_hi > g_lo {
            g_hi + 0.08 * (g_hi - g_lo)
        } else {
            g_lo + 1.0
        };
        GradeAxes {
            tonnes_per_unit,
            unit,
            x_max,
            y: (g_lo, y_hi),
        }
    }

    /// (tonnes, grade) points in display units.
    fn scale(&self, points: impl Iterator<Item = (f64, f64)>) -> Vec<(f64, f64)> {
        points.map(|(t, g)| (t / self.tonnes_per_unit, g)).collect()
    }
}

/// Series sorted by name in natural order, split evenly into pages of at most [`MAX_PANELS`].
fn paginate(series: &[GradeSeries]) -> Vec<Vec<&GradeSeries>> {
    let mut sorted: Vec<&GradeSeries> = series.iter().collect();
    sorted.sort_by(|a, b| natural_cmp(&a.name, &b.name).then_with(|| a.name.cmp(&b.name)));
    let n_pages = sorted.len().div_ceil(MAX_PANELS);
    let per_page = sorted.len().div_ceil(n_pages.max(1));
    sorted.chunks(per_page.max(1)).map(<[_]>::to_vec).collect()
}

/// Output paths: `path` for one page, `<stem>-<k>.<ext>` for several.
fn page_paths(path: &Path, n_pages: usize) -> Vec<PathBuf> {
    if n_pages <= 1 {
        return vec![path.to_path_buf()];
    }
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().into_owned())
        .unwrap_or_default();
    let digits = n_pages.to_string().len();
    (1..=n_pages)
        .map(|k| path.with_file_name(format!("{stem}-{k:0digits$}.{ext}")))
        .collect()
}

/// Natural order: runs of ASCII digits compare as numbers, everything else by character.
fn natural_cmp(a: &str, b: &str) -> Ordering {
    let (mut a, mut b) = (a, b);
    loop {
        match (a.chars().next(), b.chars().next()) {
            (None, None) => return Ordering::Equal,
            (None, Some(_)) => return Ordering::Less,
            (Some(_), None) => return Ordering::Greater,
            (Some(ca), Some(cb)) if ca.is_ascii_digit() && cb.is_ascii_digit() => {
                let na = a.find(|c: char| !c.is_ascii_digit()).unwrap_or(a.len());
                let nb = b.find(|c: char| !c.is_ascii_digit()).unwrap_or(b.len());
                let da = a[..na].trim_start_matches('0');
                let db = b[..nb].trim_start_matches('0');
                let ord = da.len().cmp(&db.len()).then_with(|| da.cmp(db));
                if ord != Ordering::Equal {
                    return ord;
                }
                a = &a[na..];
                b = &b[nb..];
            }
            (Some(ca), Some(cb)) => {
                if ca != cb {
                    return ca.cmp(&cb);
                }
                a = &a[ca.len_utf8()..];
                b = &b[cb.len_utf8()..];
            }
        }
    }
}

/// One page of grade panels laid out in pixels.
struct GradePage<'a> {
    /// Series on this page, in panel order.
    series: &'a [&'a GradeSeries],
    /// Title.
    title: String,
    /// Grade axis label.
    grade_label: &'a str,
    /// Shared axes.
    axes: &'a GradeAxes,
    /// Grid columns and rows.
    cols: usize,
    rows: usize,
    /// Space for the y tick labels left of the first column, px.
    y_label_w: u32,
    /// One plotting area, px.
    plot: (u32, u32),
    /// Left edge of the first column's plotting area, px.
    grid_left: u32,
    /// Image size, px.
    size: (u32, u32),
    /// The legend, below the title.
    legend: Legend,
}

impl<'a> GradePage<'a> {
    /// Lay out a page.
    fn new(
        series: &'a [&'a GradeSeries],
        title: String,
        grade_label: &'a str,
        axes: &'a GradeAxes,
    ) -> Result<Self, DrawError> {
        let n = series.len().max(1);
        let cols = (n as f64).sqrt().ceil() as usize;
        let rows = n.div_ceil(cols);
        let (cols_u, rows_u) = (cols as u32, rows as u32);
        let y_label_w = widest_tick_label(axes.y.0, axes.y.1)? + TICK_GAP as u32 + 4;
        let left = AXIS_TITLE_W + y_label_w;
        let plot_w = if n == 1 {
            820
        } else {
            let fixed = left + G_RIGHT + (cols_u - 1) * G_GAP_X;
            (MAX_SIDE.saturating_sub(fixed) / cols_u).clamp(60, 380)
        };
        let grid_w = cols_u * plot_w + (cols_u - 1) * G_GAP_X;
        let title_w = text_width(&text(20.0, HPos::Center, VPos::Center), &title)? as u32 + 40;
        let width = (left + grid_w + G_RIGHT).max(MIN_W).max(title_w);
        let legend = Legend::new(grade_legend(series), width)?;
        let fixed_h = TITLE_H + legend.height + G_XL + G_XTITLE + rows_u * (G_CAPTION + G_GAP_Y);
        let plot_h = if n == 1 {
            480
        } else {
            ((f64::from(plot_w) * 0.62) as u32).min(MAX_SIDE.saturating_sub(fixed_h) / rows_u)
        };
        let height = TITLE_H
            + legend.height
            + rows_u * (G_CAPTION + plot_h)
            + (rows_u - 1) * G_GAP_Y
            + G_XL
            + G_XTITLE;
        Ok(GradePage {
            series,
            title,
            grade_label,
            axes,
            cols,
            rows,
            y_label_w,
            plot: (plot_w, plot_h),
            grid_left: left + (width - (left + grid_w + G_RIGHT)) / 2,
            size: (width, height),
            legend,
        })
    }

    /// Plotting frame of panel `idx`.
    fn frame(&self, idx: usize) -> Frame {
        let (r, c) = ((idx / self.cols) as u32, (idx % self.cols) as u32);
        let top =
            TITLE_H + self.legend.height + r * (G_CAPTION + self.plot.1 + G_GAP_Y) + G_CAPTION;
        Frame {
            left: (self.grid_left + c * (self.plot.0 + G_GAP_X)) as i32,
            top: top as i32,
            size: self.plot,
            x: (0.0, self.axes.x_max),
            y: self.axes.y,
        }
    }

    /// Draw panel `idx` with the shared ticks.
    fn draw_panel<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        idx: usize,
        ticks: (&Ticks, &Ticks),
        pen: Pen,
    ) -> Result<(), DrawError>
    where
        DB::ErrorType: 'static,
    {
        let (s, f, ax) = (self.series[idx], self.frame(idx), self.axes);
        let caption = text(14.0, HPos::Left, VPos::Bottom);
        put_text(root, &s.name, (f.left, f.top - 4), &caption, pen)?;
        draw_grid(root, &f, ticks)?;
        if let Some(block) = &s.block_grade {
            for run in finite_runs(&ax.scale(block.iter().copied())) {
                root.draw(&DashedPathElement::new(
                    f.path(&run),
                    6,
                    4,
                    BLOCK_COLOUR.stroke_width(2),
                ))?;
            }
        }
        let predicted = ax.scale(
            s.cum_tonnes
                .iter()
                .copied()
                .zip(s.predicted.iter().copied()),
        );
        for run in finite_runs(&predicted) {
            root.draw(&PathElement::new(
                f.path(&run),
                PREDICTED_COLOUR.stroke_width(2),
            ))?;
        }
        if let Some(sampled) = &s.sampled {
            for p in ax.scale(sampled.iter().copied()) {
                if p.0.is_finite() && p.1.is_finite() {
                    root.draw(&Circle::new(f.px(p), 3, SAMPLED_COLOUR.filled()))?;
                }
            }
        }
        // Tick labels only on the outer panels: y on the first column, x where no panel is
        // below. Every frame has the same size either way, so the panels compare.
        let labels = AxisLabels {
            x: idx + self.cols >= self.series.len(),
            y: idx % self.cols == 0,
        };
        draw_axes(root, &f, ticks, labels, pen)
    }
}

/// Legend entries for what a page holds.
fn grade_legend(series: &[&GradeSeries]) -> Vec<LegendEntry> {
    let mut entries = vec![LegendEntry {
        sample: Sample::Line(PREDICTED_COLOUR, 2),
        label: "Predicted",
    }];
    if series
        .iter()
        .any(|s| s.sampled.as_ref().is_some_and(|v| !v.is_empty()))
    {
        entries.push(LegendEntry {
            sample: Sample::Dot(SAMPLED_COLOUR),
            label: "Sampled",
        });
    }
    if series
        .iter()
        .any(|s| s.block_grade.as_ref().is_some_and(|v| !v.is_empty()))
    {
        entries.push(LegendEntry {
            sample: Sample::Dashed(BLOCK_COLOUR),
            label: "Block grade (uniform drawdown)",
        });
    }
    entries
}

impl Render for GradePage<'_> {
    fn size(&self) -> (u32, u32) {
        self.size
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
        let first = self.frame(0);
        let ticks = (x_ticks(&first)?, y_ticks(&first)?);
        for idx in 0..self.series.len() {
            self.draw_panel(root, idx, (&ticks.0, &ticks.1), pen)?;
        }

        // Shared axis titles, centred on the grid.
        let last = self.frame(self.cols * self.rows - 1);
        let grid_top = first.top - G_CAPTION as i32;
        let centre_x = (first.left + last.right()) / 2;
        let centre_y = (grid_top + last.bottom()) / 2;
        let x_title = format!("Cumulative tonnes ({})", self.axes.unit);
        let below = self.size.1 as i32 - G_XTITLE as i32 / 2 - 2;
        put_text(
            root,
            &x_title,
            (centre_x, below),
            &axis_title_style(false),
            pen,
        )?;
        let title_x = first.left - self.y_label_w as i32 - AXIS_TITLE_W as i32 / 2;
        put_text(
            root,
            self.grade_label,
            (title_x, centre_y),
            &axis_title_style(true),
            pen,
        )
    }
}

#[cfg(test)]
pub(crate) mod tests {
    //! Set `CAVEFLOW_CHART_DIR` to keep the rendered test charts there for a look.

    use super::*;
    use std::collections::HashSet;

    /// A directory for test charts: `CAVEFLOW_CHART_DIR` if set, else a fresh temporary one.
    pub(crate) fn out_dir(name: &str) -> (Option<tempfile::TempDir>, PathBuf) {
        match std::env::var_os("CAVEFLOW_CHART_DIR") {
            Some(dir) => {
                let dir = PathBuf::from(dir).join(name);
                std::fs::create_dir_all(&dir).unwrap();
                (None, dir)
            }
            None => {
                let tmp = tempfile::tempdir().unwrap();
                let dir = tmp.path().to_path_buf();
                (Some(tmp), dir)
            }
        }
    }

    /// Width and height from a PNG's IHDR chunk.
    fn png_dims(bytes: &[u8]) -> (u32, u32) {
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "PNG signature");
        assert_eq!(&bytes[12..16], b"IHDR");
        let w = u32::from_be_bytes(bytes[16..20].try_into().unwrap());
        let h = u32::from_be_bytes(bytes[20..24].try_into().unwrap());
        (w, h)
    }

    /// Size of an all-white PNG of the given dimensions.
    fn blank_png_len(dir: &Path, size: (u32, u32)) -> u64 {
        let path = dir.join("blank-reference.png");
        {
            let root = BitMapBackend::new(&path, size).into_drawing_area();
            root.fill(&WHITE).unwrap();
            root.present().unwrap();
        }
        let len = std::fs::metadata(&path).unwrap().len();
        std::fs::remove_file(&path).unwrap();
        len
    }

    /// Render a laid-out chart into an RGB buffer.
    fn render_rgb<R: Render>(chart: &R) -> Vec<u8> {
        let (w, h) = chart.size();
        let mut buf = vec![0u8; (w * h * 3) as usize];
        {
            let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
            chart.draw(&root, Pen::Glyphs).unwrap();
            root.present().unwrap();
        }
        buf
    }

    /// Distinct colours inside a pixel rectangle (x, y, w, h) of an RGB buffer `width` wide.
    fn colours_in(buf: &[u8], width: u32, rect: (u32, u32, u32, u32)) -> HashSet<[u8; 3]> {
        let (x0, y0, w, h) = rect;
        let mut set = HashSet::new();
        for y in y0..y0 + h {
            for x in x0..x0 + w {
                let i = ((y * width + x) * 3) as usize;
                set.insert([buf[i], buf[i + 1], buf[i + 2]]);
            }
        }
        set
    }

    /// Pixel rectangle (x, y, w, h) of a frame.
    fn frame_rect(f: &Frame) -> (u32, u32, u32, u32) {
        (f.left as u32, f.top as u32, f.size.0, f.size.1)
    }

    /// Bounding box (x0, y0, x1, y1) of the pixels of one exact colour inside a frame.
    fn colour_bbox(
        buf: &[u8],
        width: u32,
        f: &Frame,
        colour: RGBColor,
    ) -> Option<(u32, u32, u32, u32)> {
        let mut bbox: Option<(u32, u32, u32, u32)> = None;
        for (i, px) in buf.chunks_exact(3).enumerate() {
            let (x, y) = (i as u32 % width, i as u32 / width);
            let inside = (f.left..=f.right()).contains(&(x as i32))
                && (f.top..=f.bottom()).contains(&(y as i32));
            if inside && px == [colour.0, colour.1, colour.2] {
                bbox = Some(match bbox {
                    None => (x, y, x, y),
                    Some((a, b, c, d)) => (a.min(x), b.min(y), c.max(x), d.max(y)),
                });
            }
        }
        bbox
    }

    /// Files in a directory, sorted.
    fn files_in(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    /// A two-drawpoint physical-model scene at the scale of the summary's IN-T2 test (700 mm
    /// spacing, 3.3 m high): drawn-down layers, IMZs, IEZs and labelled drawpoints.
    fn sample_section() -> Section {
        let axes = [0.85, 1.55];
        let imz_top = 2.6;
        let drawdown = |x: f64, z: f64| -> f64 {
            axes.iter()
                .map(|&a| {
                    if z >= imz_top {
                        return 0.0;
                    }
                    let spread = 0.04 + 0.07 * z.sqrt();
                    let depth = 0.9 * (1.0 - z / imz_top).powf(0.7);
                    depth * (-(x - a).powi(2) / (2.0 * spread * spread)).exp()
                })
                .sum()
        };
        let layers = (1..33)
            .map(|k| {
                let z = k as f64 * 0.1;
                (0..=120)
                    .map(|i| {
                        let x = i as f64 * 0.02;
                        (x, (z - drawdown(x, z)).max(0.0))
                    })
                    .collect()
            })
            .collect();
        let imz = axes
            .iter()
            .map(|&a| {
                let disks: Vec<(f64, f64, f64)> = (0..52)
                    .map(|i| {
                        let zb = i as f64 * 0.05;
                        (zb, zb + 0.05, 0.06 + 0.1 * (zb + 0.025).sqrt())
                    })
                    .collect();
                imz_outline(&disks, a)
            })
            .collect();
        let iez = axes
            .iter()
            .map(|&a| {
                let origins: Vec<(f64, f64)> = (0..60)
                    .flat_map(|i| {
                        let z = i as f64 * 0.02;
                        let w = 0.05 + 0.06 * z.sqrt();
                        [(a - w, z), (a + w * 0.9, z)]
                    })
                    .collect();
                iez_outline(&origins, a, 0.1)
            })
            .collect();
        Section {
            axis_label: "Easting (m)".into(),
            x_range: (0.0, 2.4),
            z_range: (0.0, 3.3),
            layers,
            imz,
            iez,
            drawpoints: vec![
                (0.85, 0.0, "DP1: 0.412 t".into()),
                (1.55, 0.0, "DP2: 0.398 t".into()),
            ],
            surface: vec![(0.0, 3.3), (1.0, 3.3), (1.2, 3.0), (1.4, 3.3), (2.4, 3.3)],
            uncaved: vec![((1.8, 2.8), (2.4, 3.3))],
        }
    }

    /// A deterministic pseudo-random value in [-1, 1).
    fn noise(i: usize, j: usize) -> f64 {
        let mut x = (i as u64 * 0x9E37_79B9_7F4A_7C15) ^ (j as u64 * 0xBF58_476D_1CE4_E5B9);
        x ^= x >> 31;
        x = x.wrapping_mul(0x94D0_49BB_1331_11EB);
        x ^= x >> 29;
        (x % 2000) as f64 / 1000.0 - 1.0
    }

    /// `n` drawpoints named DP1..DPn (given in shuffled order), with Henderson-like grade
    /// curves: ore grade until dilution entry, then a fall towards the waste above.
    fn sample_series(n: usize) -> Vec<GradeSeries> {
        let mut out: Vec<GradeSeries> = (1..=n)
            .map(|d| {
                let entry = 60_000.0 + 8_000.0 * noise(d, 0);
                let ore = 0.22 + 0.05 * noise(d, 1);
                let grade = |t: f64| ore * (1.0 - 0.8 / (1.0 + (-(t - entry) / 9_000.0).exp()));
                let cum: Vec<f64> = (1..=24).map(|p| p as f64 * 5_000.0).collect();
                let predicted: Vec<f64> = cum.iter().map(|&t| grade(t)).collect();
                let sampled = cum
                    .iter()
                    .step_by(2)
                    .enumerate()
                    .map(|(k, &t)| (t, (grade(t) + 0.02 * noise(d, k + 2)).max(0.0)))
                    .collect();
                let block = cum
                    .iter()
                    .map(|&t| (t, if t < 75_000.0 { ore * 0.95 } else { ore * 0.2 }))
                    .collect();
                GradeSeries {
                    name: format!("DP{d}"),
                    cum_tonnes: cum,
                    predicted,
                    sampled: Some(sampled),
                    block_grade: (d % 2 == 0).then_some(block),
                }
            })
            .collect();
        out.reverse();
        out.swap(0, n / 2);
        out
    }

    #[test]
    fn imz_outline_of_two_disks_is_the_closed_stair() {
        let disks = [(1.0, 2.0, 1.0), (0.0, 1.0, 2.0)]; // unsorted on purpose
        let outline = imz_outline(&disks, 10.0);
        let expected = vec![
            (12.0, 0.0),
            (12.0, 1.0),
            (11.0, 1.0),
            (11.0, 2.0),
            (9.0, 2.0),
            (9.0, 1.0),
            (8.0, 1.0),
            (8.0, 0.0),
            (12.0, 0.0),
        ];
        assert_eq!(outline, expected);
    }

    #[test]
    fn imz_outline_skips_empty_disks_and_merges_equal_radii() {
        let disks = [
            (0.0, 1.0, 2.0),
            (1.0, 2.0, 2.0),
            (2.0, 3.0, 0.0),
            (3.0, 4.0, f64::NAN),
        ];
        let outline = imz_outline(&disks, 0.0);
        assert_eq!(
            outline,
            vec![
                (2.0, 0.0),
                (2.0, 1.0),
                (2.0, 2.0),
                (-2.0, 2.0),
                (-2.0, 1.0),
                (-2.0, 0.0),
                (2.0, 0.0)
            ]
        );
        assert!(imz_outline(&[(0.0, 1.0, 0.0)], 5.0).is_empty());
        assert!(imz_outline(&[], 5.0).is_empty());
    }

    #[test]
    fn iez_outline_of_symmetric_points_is_symmetric_and_closed() {
        let a = 5.0;
        let points = [
            (a - 1.0, 0.5),
            (a + 1.0, 0.2),
            (a + 0.5, 0.7),
            (a - 2.0, 1.5),
            (a + 2.0, 1.1),
            (f64::NAN, 1.0),
        ];
        let outline = iez_outline(&points, a, 1.0);
        let expected = vec![
            (6.0, 0.0),
            (6.0, 1.0),
            (7.0, 1.0),
            (7.0, 2.0),
            (3.0, 2.0),
            (3.0, 1.0),
            (4.0, 1.0),
            (4.0, 0.0),
            (6.0, 0.0),
        ];
        assert_eq!(outline, expected);
        // Mirror symmetry about the axis: every point has its mirror image on the outline.
        for &(x, z) in &outline {
            assert!(outline.contains(&(2.0 * a - x, z)));
        }
    }

    #[test]
    fn iez_outline_bins_at_multiples_of_bin_and_rejects_bad_bins() {
        // Bin 0.5 at z = -0.2 covers [-0.5, 0); a gap bin is joined across.
        let outline = iez_outline(&[(1.0, -0.2), (0.5, 1.2)], 0.0, 0.5);
        assert_eq!(
            outline,
            vec![
                (1.0, -0.5),
                (1.0, 0.0),
                (0.5, 1.0),
                (0.5, 1.5),
                (-0.5, 1.5),
                (-0.5, 1.0),
                (-1.0, 0.0),
                (-1.0, -0.5),
                (1.0, -0.5)
            ]
        );
        assert!(iez_outline(&[(1.0, 1.0)], 0.0, 0.0).is_empty());
        assert!(iez_outline(&[(1.0, 1.0)], 0.0, f64::NAN).is_empty());
        assert!(iez_outline(&[], 0.0, 1.0).is_empty());
    }

    #[test]
    fn format_follows_the_extension() {
        assert_eq!(
            ChartFormat::from_path(Path::new("a/b.PNG")),
            Some(ChartFormat::Png)
        );
        assert_eq!(
            ChartFormat::from_path(Path::new("b.svg")),
            Some(ChartFormat::Svg)
        );
        assert_eq!(ChartFormat::from_path(Path::new("b.pdf")), None);
        assert_eq!(ChartFormat::from_path(Path::new("b")), None);
        assert_eq!(ChartFormat::Svg.extension(), "svg");
    }

    #[test]
    fn natural_order_compares_numbers_as_numbers() {
        let mut names = vec!["DP10", "DP2", "DP1", "B1", "DP02", "DP1a"];
        names.sort_by(|a, b| natural_cmp(a, b).then_with(|| a.cmp(b)));
        assert_eq!(names, vec!["B1", "DP1", "DP1a", "DP02", "DP2", "DP10"]);
    }

    #[test]
    fn section_chart_writes_png_and_svg() {
        let (_keep, dir) = out_dir("section");
        let section = sample_section();
        let title = "IN-T2: drawdown after 0.81 t drawn (synthetic)";
        let png = dir.join("section.png");
        let svg = dir.join("section.svg");
        section_chart(&png, &section, title).unwrap();
        section_chart(&svg, &section, title).unwrap();

        let layout = SectionPlot::new(&section, title).ok().unwrap();
        let bytes = std::fs::read(&png).unwrap();
        assert_eq!(png_dims(&bytes), layout.size);
        assert!(
            layout.size.0 <= MAX_SIDE && layout.size.1 <= MAX_SIDE,
            "{:?}",
            layout.size
        );
        assert!(bytes.len() as u64 > 3 * blank_png_len(&dir, layout.size));

        let svg_text = std::fs::read_to_string(&svg).unwrap();
        assert!(svg_text.starts_with("<svg"));
        assert!(svg_text.contains("Elevation (m)") && svg_text.contains("Easting (m)"));
        assert!(svg_text.contains("DP1: 0.412 t"));

        // No temporary file is left behind.
        let files = files_in(&dir);
        assert!(files.iter().all(|f| !f.contains(".tmp-")), "{files:?}");
    }

    #[test]
    fn section_plot_area_holds_the_drawing_at_equal_aspect() {
        assert!(font_ready());
        let section = sample_section();
        let layout = SectionPlot::new(&section, "t").ok().unwrap();
        let buf = render_rgb(&layout);
        let (w, _) = layout.size;
        let colours = colours_in(&buf, w, frame_rect(&layout.frame));
        for c in [
            IMZ_COLOUR,
            IEZ_COLOUR,
            LAYER_COLOURS[0],
            LAYER_COLOURS[1],
            MODEL_FILL,
        ] {
            assert!(colours.contains(&[c.0, c.1, c.2]), "plot area lacks {c:?}");
        }
        assert!(colours.len() > 10, "{} colours", colours.len());

        // A 10 m × 6 m rectangle as the only IMZ outline keeps its proportions in pixels.
        let rect = Section {
            axis_label: "Northing (m)".into(),
            x_range: (0.0, 40.0),
            z_range: (100.0, 130.0),
            imz: vec![vec![
                (15.0, 110.0),
                (25.0, 110.0),
                (25.0, 116.0),
                (15.0, 116.0),
                (15.0, 110.0),
            ]],
            ..Section::default()
        };
        let layout = SectionPlot::new(&rect, "aspect").ok().unwrap();
        let buf = render_rgb(&layout);
        let (x0, y0, x1, y1) = colour_bbox(&buf, layout.size.0, &layout.frame, IMZ_COLOUR).unwrap();
        let (bw, bh) = (f64::from(x1 - x0), f64::from(y1 - y0));
        // Both extents include the 3 px stroke once.
        let (mw, mh) = (bw - 2.0, bh - 2.0);
        assert!((mw / mh - 10.0 / 6.0).abs() < 0.03, "{bw} × {bh} px");
        // The 40 m wide, 30 m high model fills the width budget or the height budget.
        let f = layout.frame;
        assert!(f.size.0 > 600, "{f:?}");
        let per_m = (
            f64::from(f.size.0 - 1) / (f.x.1 - f.x.0),
            f64::from(f.size.1 - 1) / (f.y.1 - f.y.0),
        );
        assert!((per_m.0 - per_m.1).abs() < 1e-9, "{per_m:?}");
    }

    #[test]
    fn section_chart_rejects_bad_input_and_unknown_formats() {
        let (_keep, dir) = out_dir("section-errors");
        let mut section = sample_section();
        let err = section_chart(&dir.join("s.pdf"), &section, "t").unwrap_err();
        assert!(matches!(err, ChartError::Format { .. }), "{err}");
        section.z_range = (3.0, 3.0);
        let err = section_chart(&dir.join("s.png"), &section, "t").unwrap_err();
        assert!(matches!(err, ChartError::Input { .. }), "{err}");
        assert!(err.to_string().contains("s.png"), "{err}");

        // A missing directory fails with the path named and nothing left behind.
        let err = section_chart(&dir.join("missing/s.png"), &sample_section(), "t").unwrap_err();
        assert!(err.to_string().contains("missing"), "{err}");
        assert!(files_in(&dir).is_empty(), "{:?}", files_in(&dir));
    }

    #[test]
    fn grade_chart_writes_png_and_svg() {
        let (_keep, dir) = out_dir("grade");
        let series = sample_series(12);
        let png = dir.join("grade.png");
        let written =
            grade_tonnage_chart(&png, &series, "Grade against tonnes (synthetic)", "Mo (%)")
                .unwrap();
        assert_eq!(written, vec![png.clone()]);
        let svg = dir.join("grade.svg");
        grade_tonnage_chart(&svg, &series, "Grade against tonnes (synthetic)", "Mo (%)").unwrap();

        let axes = GradeAxes::new(&series);
        assert_eq!(axes.unit, "kt");
        let pages = paginate(&series);
        assert_eq!(pages.len(), 1);
        let names: Vec<&str> = pages[0].iter().map(|s| s.name.as_str()).collect();
        let expected: Vec<String> = (1..=12).map(|d| format!("DP{d}")).collect();
        assert_eq!(names, expected);
        let page = GradePage::new(&pages[0], "g".into(), "Mo (%)", &axes).unwrap();
        assert_eq!((page.cols, page.rows), (4, 3));

        let bytes = std::fs::read(&png).unwrap();
        let size = png_dims(&bytes);
        assert!(size.0 <= MAX_SIDE && size.1 <= MAX_SIDE, "{size:?}");
        assert!(bytes.len() as u64 > 3 * blank_png_len(&dir, size));
        let svg_text = std::fs::read_to_string(&svg).unwrap();
        assert!(svg_text.contains("Cumulative tonnes (kt)") && svg_text.contains("DP12"));

        // Every panel's plot area shows the predicted line, and the sampled points somewhere.
        let buf = render_rgb(&page);
        let mut all = HashSet::new();
        for idx in 0..12 {
            let colours = colours_in(&buf, page.size.0, frame_rect(&page.frame(idx)));
            let p = PREDICTED_COLOUR;
            assert!(colours.contains(&[p.0, p.1, p.2]), "panel {idx}");
            all.extend(colours);
        }
        let s = SAMPLED_COLOUR;
        assert!(all.contains(&[s.0, s.1, s.2]));
        let b = BLOCK_COLOUR;
        assert!(all.contains(&[b.0, b.1, b.2]));
        assert!(files_in(&dir).iter().all(|f| !f.contains(".tmp-")));
    }

    #[test]
    fn one_series_gets_one_large_panel() {
        let (_keep, dir) = out_dir("grade-single");
        let mut series = sample_series(1);
        series[0].block_grade = None;
        let png = dir.join("dp1.png");
        grade_tonnage_chart(&png, &series, "DP1 (synthetic)", "Mo (%)").unwrap();
        let bytes = std::fs::read(&png).unwrap();
        let (w, h) = png_dims(&bytes);
        assert!(
            w > 800 && h > 500 && w <= MAX_SIDE && h <= MAX_SIDE,
            "{w} × {h}"
        );
        let svg = dir.join("dp1.svg");
        grade_tonnage_chart(&svg, &series, "DP1 (synthetic)", "Mo (%)").unwrap();
        let svg_text = std::fs::read_to_string(&svg).unwrap();
        assert!(svg_text.contains("Sampled") && !svg_text.contains("Block grade"));
    }

    #[test]
    fn many_series_are_split_over_even_pages() {
        let (_keep, dir) = out_dir("grade-pages");
        let series = sample_series(40);
        let written = grade_tonnage_chart(&dir.join("all.png"), &series, "All", "Mo (%)").unwrap();
        assert_eq!(written, vec![dir.join("all-1.png"), dir.join("all-2.png")]);
        for p in &written {
            let (w, h) = png_dims(&std::fs::read(p).unwrap());
            assert!(w <= MAX_SIDE && h <= MAX_SIDE, "{w} × {h}");
        }
        assert_eq!(files_in(&dir), vec!["all-1.png", "all-2.png"]);
        let pages = paginate(&series);
        assert_eq!(pages.iter().map(Vec::len).collect::<Vec<_>>(), vec![20, 20]);
        assert_eq!(pages[1][0].name, "DP21");
        assert_eq!(
            page_paths(Path::new("x/g.svg"), 12)[0],
            Path::new("x/g-01.svg")
        );
    }

    #[test]
    fn grade_chart_rejects_bad_input() {
        let (_keep, dir) = out_dir("grade-errors");
        let path = dir.join("g.png");
        let err = grade_tonnage_chart(&path, &[], "t", "Mo (%)").unwrap_err();
        assert!(matches!(err, ChartError::Input { .. }), "{err}");
        let bad = GradeSeries {
            name: "DP1".into(),
            cum_tonnes: vec![1.0, 2.0],
            predicted: vec![0.1],
            ..GradeSeries::default()
        };
        let err = grade_tonnage_chart(&path, &[bad], "t", "Mo (%)").unwrap_err();
        assert!(err.to_string().contains("DP1"), "{err}");
        assert!(files_in(&dir).is_empty());
    }

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
