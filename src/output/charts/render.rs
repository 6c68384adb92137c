//! Laid-out charts and how they become files: the [`Render`] trait (size, title, body) that
//! any plotters backend can draw, the title strip, and [`write_chart`].
//!
//! Every chart is written atomically: it is rendered to a temporary file next to the target
//! (`<stem>.tmp-<pid>-<n>.<ext>`, since plotters writes to a path itself), then made final by
//! the same step as every other output file (`output::parquet::persist`: data synced, renamed
//! over the target, directory synced), so a reader never sees half a chart.

use std::fs::File;
use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use crate::output::parquet::{persist, tmp_tag};

use super::{put_text, text, ChartError, ChartFormat, DrawError, IntoChartError, Pen, TITLE_H};

/// A laid-out chart that any plotters backend can draw.
pub(super) trait Render {
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

/// Render `chart` to a temporary file next to `path`, sync it, then rename it onto `path`.
pub(super) fn write_chart<R: Render>(path: &Path, chart: &R) -> Result<(), ChartError> {
    let format = ChartFormat::from_path(path).ok_or_else(|| ChartError::Format {
        path: path.to_path_buf(),
    })?;
    let tmp = temp_path(path, format);
    let result = render_file(&tmp, format, chart)
        .map_err(|e| e.into_chart_error(path))
        .and_then(|()| {
            // Every failure names the chart, whichever file or directory it concerns.
            let io = |_: &Path, source| ChartError::Io {
                path: path.to_path_buf(),
                source,
            };
            let file = File::open(&tmp).map_err(|e| io(&tmp, e))?;
            persist(file, &tmp, path, io)
        });
    if result.is_err() {
        // The backend may have written a partial file before failing; it is ours to remove.
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Temporary sibling of `path`: `<stem>.tmp-<pid>-<n>.<ext>` (the tag of
/// `output::parquet::tmp_tag`). The extension stays last because the PNG encoder picks the
/// format from it.
pub(super) fn temp_path(path: &Path, format: ChartFormat) -> PathBuf {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "chart".into());
    path.with_file_name(format!("{stem}{}.{}", tmp_tag(), format.extension()))
}

/// Draw `chart` into the file `tmp` with the backend of `format`.
pub(super) fn render_file<R: Render>(
    tmp: &Path,
    format: ChartFormat,
    chart: &R,
) -> Result<(), DrawError> {
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

/// Draw the title, centred in the title strip.
pub(super) fn draw_title<DB: DrawingBackend>(
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
