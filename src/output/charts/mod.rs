//! Charts for people (DESIGN §5): drawdown sections with IMZ and IEZ outlines, like the
//! summary's Figs 13 and 16, and grade against cumulative tonnes per drawpoint, like its
//! Figs 31–32; and the analysis charts (reconciliation, stability, stress, sweeps).
//!
//! Charts are PNG (plotters' `BitMapBackend`) or SVG (`SVGBackend`); the file extension picks
//! the [`ChartFormat`]. Text is set in DejaVu Sans, bundled in `src/output/fonts/` (licence
//! next to it) and registered with plotters once, so no system font library is needed. Every
//! chart is written atomically (see `render`), so a reader never sees half a chart.
//!
//! The inputs, [`Section`] and [`GradeSeries`], are plain data. [`run_sections`] and
//! [`grade_series`] fill them from a run's outputs; [`imz_outline`] and [`iez_outline`] turn
//! the IMZ disk table and the drawn markers' origins into the closed outlines a section
//! draws. Which charts a run writes is `output::run_dir::charts`.
//!
//! One concept per file:
//! - `font`: the bundled font, its metrics (`FontMetrics`) and glyph-by-glyph text;
//! - `axes`: plotting frames, ticks, tick labels, grid lines and axis titles;
//! - `legend`: legend entries and their layout;
//! - `render`: the `Render` trait every laid-out chart implements, the title, and rendering
//!   to a file atomically;
//! - `section`: drawdown sections ([`Section`], [`imz_outline`], [`iez_outline`],
//!   [`section_chart`]);
//! - `drawdown`: a run's drawdown sections, one per row of drawpoints ([`run_sections`],
//!   [`drawdown_section`]);
//! - `layers`: the deformed layers of a section, from a marker snapshot;
//! - `free_surface`: the free surface by lattice row ([`FreeSurface`]) and the outlines cut
//!   at it ([`below_surface`]);
//! - `grade`: grade against cumulative tonnes in small multiples ([`GradeSeries`],
//!   [`grade_tonnage_chart`]);
//! - `grade_series`: a run's grade series and the uniform-drawdown block grade
//!   ([`grade_series`], [`block_grade`]);
//! - `plan_map`: drawpoints on a plan coloured by a value ([`plan_map_chart`]);
//! - `histogram`: a distribution as bars with guide lines ([`histogram_chart`]);
//! - `lines`: curves overlaid on shared axes with a legend ([`line_chart`]);
//! - `reconcile`, `stability`, `stress`, `sweep`: the analysis charts.
//!
//! This file holds what they share: [`ChartFormat`], [`ChartError`], the palette and the
//! page layout sizes.

mod axes;
mod drawdown;
mod font;
mod free_surface;
mod grade;
mod grade_series;
mod histogram;
mod layers;
mod legend;
mod lines;
mod plan_map;
mod reconcile;
mod render;
mod section;
mod stability;
pub mod stress;
mod sweep;

pub use self::drawdown::{
    default_layer_spacing, drawdown_section, drawpoint_rows, run_sections, MAX_SECTIONS,
};
pub use self::free_surface::{below_surface, surface_at, FreeSurface};
pub use self::grade::{grade_tonnage_chart, GradeSeries, MAX_PANELS};
pub use self::grade_series::{block_grade, grade_series};
pub use self::histogram::histogram_chart;
pub use self::legend::fmt_mass;
pub use self::lines::{line_chart, LineSeries};
pub use self::plan_map::{diverging, plan_map_chart, MapPoint, MapScale, MAX_LABELS};
pub use self::reconcile::{profile_chart, scatter_chart, Profile, ScatterPoint};
pub use self::section::{iez_outline, imz_outline, section_chart, Section};
pub use self::stability::{stability_chart, RegionBand};
pub use self::sweep::{sweep_chart, SweepPoint};

// What the chart modules share, importable as `super::…` from each of them.
use self::axes::*;
use self::font::*;
use self::legend::*;
use self::render::*;
use self::section::{DP_LINE, SEC_BOTTOM, SEC_RIGHT, SEC_TOP};

use std::error::Error as StdError;
use std::path::{Path, PathBuf};

use plotters::prelude::*;

/// Largest side of a chart image, px (sections and grade grids both fit inside it).
pub const MAX_SIDE: u32 = 1200;

/// Marker layers alternate these two colours, like the coloured layers of a physical model.
const LAYER_COLOURS: [RGBColor; 2] = [RGBColor(45, 95, 170), RGBColor(140, 140, 140)];
/// IMZ outline (yellow-orange).
const IMZ_COLOUR: RGBColor = RGBColor(245, 165, 0);
/// IEZ outline (magenta).
const IEZ_COLOUR: RGBColor = RGBColor(200, 0, 160);
/// Free surface (summary Fig. 33).
const SURFACE_COLOUR: RGBColor = RGBColor(120, 70, 20);
/// Trace point paths (green).
const TRACE_COLOUR: RGBColor = RGBColor(0, 150, 70);
/// Uncaved ground.
const UNCAVED_FILL: RGBColor = RGBColor(190, 190, 190);
/// The air gap (light blue).
const AIR_FILL: RGBColor = RGBColor(190, 225, 250);
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
/// Dilution entry, a dotted vertical line on grade panels.
const DILUTION_COLOUR: RGBColor = RGBColor(200, 0, 160);
/// Block grade (uniform drawdown) dashed line.
const BLOCK_COLOUR: RGBColor = RGBColor(70, 70, 70);

/// Colours of series told apart by colour alone (zones, study variants): Tableau 10,
/// repeated when there are more.
const SERIES_COLOURS: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// The colour of series `k`.
fn series_colour(k: usize) -> RGBColor {
    SERIES_COLOURS[k % SERIES_COLOURS.len()]
}

/// Height of the title strip, px.
const TITLE_H: u32 = 44;
/// Narrowest image, px (room for the title and the legend).
const MIN_W: u32 = 720;
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

/// Split a polyline at non-finite points into runs of finite points.
fn finite_runs(points: &[(f64, f64)]) -> Vec<Vec<(f64, f64)>> {
    points
        .split(|p| !(p.0.is_finite() && p.1.is_finite()))
        .filter(|run| !run.is_empty())
        .map(<[_]>::to_vec)
        .collect()
}

#[cfg(test)]
pub(crate) mod tests {
    //! Helpers shared by the chart tests. Set `CAVEFLOW_CHART_DIR` to keep the rendered test
    //! charts there for a look.

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
    pub(super) fn png_dims(bytes: &[u8]) -> (u32, u32) {
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "PNG signature");
        assert_eq!(&bytes[12..16], b"IHDR");
        let w = u32::from_be_bytes(bytes[16..20].try_into().unwrap());
        let h = u32::from_be_bytes(bytes[20..24].try_into().unwrap());
        (w, h)
    }

    /// Size of an all-white PNG of the given dimensions.
    pub(super) fn blank_png_len(dir: &Path, size: (u32, u32)) -> u64 {
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
    pub(super) fn render_rgb<R: Render>(chart: &R) -> Vec<u8> {
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
    pub(super) fn colours_in(
        buf: &[u8],
        width: u32,
        rect: (u32, u32, u32, u32),
    ) -> HashSet<[u8; 3]> {
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
    pub(super) fn frame_rect(f: &Frame) -> (u32, u32, u32, u32) {
        (f.left as u32, f.top as u32, f.size.0, f.size.1)
    }

    /// Bounding box (x0, y0, x1, y1) of the pixels of one exact colour inside a frame.
    pub(super) fn colour_bbox(
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
    pub(super) fn files_in(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
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
}
