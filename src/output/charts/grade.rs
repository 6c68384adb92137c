//! Grade against cumulative tonnes per drawpoint (summary Figs 31–32): the [`GradeSeries`]
//! data and [`grade_tonnage_chart`], which sorts the series, pages them and draws each page
//! ([`GradePage`]) as a grid of small panels.
//!
//! # Why small multiples
//! Grade curves are compared between drawpoints, so many drawpoints share one pair of axes
//! across a grid of small panels instead of a tangle of lines on one plot.

use std::cmp::Ordering;
use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::{
    axis_title_style, draw_axes, draw_grid, ensure_font, finite_runs, put_text, text, text_width,
    widest_tick_label, write_chart, x_ticks, y_ticks, AxisLabels, ChartError, DrawError, Frame,
    IntoChartError, Legend, LegendEntry, Pen, Render, Sample, Ticks, AXIS_TITLE_W, BLOCK_COLOUR,
    DILUTION_COLOUR, MAX_SIDE, MIN_W, PREDICTED_COLOUR, SAMPLED_COLOUR, TICK_GAP, TITLE_H,
};

/// Most panels on one grade-tonnage image; more series are split over several pages.
pub const MAX_PANELS: usize = 36;

/// Grade grid: right margin, x tick label strip, x title strip, gaps between panels, panel
/// caption height; px. The y tick label strip follows the widest grade label.
const G_RIGHT: u32 = 28;
const G_XL: u32 = 26;
const G_XTITLE: u32 = 30;
const G_GAP_X: u32 = 22;
const G_GAP_Y: u32 = 14;
const G_CAPTION: u32 = 20;

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
    /// Dilution entry (`output::dilution`), t: drawn as a dotted vertical line.
    pub dilution_entry: Option<f64>,
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
        if let Some(t) = s.dilution_entry.filter(|t| t.is_finite()) {
            let x = t / ax.tonnes_per_unit;
            root.draw(&DashedPathElement::new(
                f.path(&[(x, ax.y.0), (x, ax.y.1)]),
                2,
                3,
                DILUTION_COLOUR.stroke_width(2),
            ))?;
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
        label: "Predicted".into(),
    }];
    if series
        .iter()
        .any(|s| s.sampled.as_ref().is_some_and(|v| !v.is_empty()))
    {
        entries.push(LegendEntry {
            sample: Sample::Dot(SAMPLED_COLOUR),
            label: "Sampled".into(),
        });
    }
    if series
        .iter()
        .any(|s| s.block_grade.as_ref().is_some_and(|v| !v.is_empty()))
    {
        entries.push(LegendEntry {
            sample: Sample::Dashed(BLOCK_COLOUR),
            label: "Block grade (uniform drawdown)".into(),
        });
    }
    if series.iter().any(|s| s.dilution_entry.is_some()) {
        entries.push(LegendEntry {
            sample: Sample::Dashed(DILUTION_COLOUR),
            label: "Dilution entry (10% waste)".into(),
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
mod tests {
    use super::*;
    use crate::output::charts::tests::{
        blank_png_len, colours_in, files_in, frame_rect, out_dir, png_dims, render_rgb,
    };
    use std::collections::HashSet;

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
                    dilution_entry: (d % 3 == 0).then_some(entry),
                }
            })
            .collect();
        out.reverse();
        out.swap(0, n / 2);
        out
    }

    #[test]
    fn natural_order_compares_numbers_as_numbers() {
        let mut names = vec!["DP10", "DP2", "DP1", "B1", "DP02", "DP1a"];
        names.sort_by(|a, b| natural_cmp(a, b).then_with(|| a.cmp(b)));
        assert_eq!(names, vec!["B1", "DP1", "DP1a", "DP02", "DP2", "DP10"]);
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
}
