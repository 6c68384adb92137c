//! The charts of one run (DESIGN §5, "Report"): drawdown sections like the summary's Figs 13
//! and 16, and grade against cumulative tonnes like its Figs 31–32, built from a
//! [`RunOutput`] and drawn with [`charts`](crate::output::charts).
//!
//! [`write_run_charts`] writes them all into `<dir>/charts/`:
//!
//! ```text
//! <dir>/charts/section_<k>.png   one per row of drawpoints (at most MAX_SECTIONS), k = 1, 2, …
//!                                in order of increasing Northing, at the end of the run
//! <dir>/charts/section_<k>_p<N>.png
//!                                the same at the end of period N, for each earlier moment
//!                                of the draw (outputs.section_periods; by default a quarter,
//!                                a half and three quarters of the scheduled tonnes)
//! <dir>/charts/grade_<grade>.png predicted grade of the first grade column against
//!                                cumulative tonnes, one panel per drawpoint
//!                                (grade_<grade>-<k>.png when the panels fill several pages)
//! <dir>/charts/trace.png         the trace points' paths (only with trace points;
//!                                output::trace::trace_section)
//! <dir>/charts/stress_p<N>_<section>.png
//!                                the stress on each section (only with mechanisms.stress;
//!                                output::stress::write_stress_charts)
//! ```
//!
//! The pieces are in [`charts`](crate::output::charts), so that other commands can draw
//! them on their own: [`run_sections`] and
//! [`drawdown_section`](crate::output::charts::drawdown_section) build the sections,
//! [`grade_series`] builds the grade series (`reconcile` adds the sampled grades to them).
//! The choice of charts lives here, with the run directory, because it also draws the
//! trace and stress charts, which `output::trace` and `output::stress` build on `charts`.

use std::path::{Path, PathBuf};

use crate::engine::result::RunOutput;
use crate::model::Scene;
use crate::output::charts::{
    grade_series, grade_tonnage_chart, run_sections, section_chart, ChartError,
};
use crate::output::stress::write_stress_charts;
use crate::output::trace::trace_section;

/// Write the charts of a run into `dir/charts/` (created if missing) and return the paths
/// written, sections first.
///
/// - **Drawdown sections** ([`run_sections`]): one vertical section along x through each row
///   of drawpoints at the end of each of `moments` (sections through time; the engine
///   writes the free surface at them, `Scene::moments`), with the deformed layers every
///   `layer_spacing` m (None:
///   [`default_layer_spacing`](crate::output::charts::default_layer_spacing)) where a marker snapshot was taken,
///   the IMZ and IEZ outlines of the row's drawpoints, the free surface, the air gap, the
///   uncaved ground and the drawpoints' names with the mass drawn by then.
/// - **Grade against cumulative tonnes** ([`grade_series`]) of the first grade column of the
///   block model, with the uniform-drawdown block grade dashed; nothing when the block model
///   has no grade column or no drawpoint drew anything.
///
/// A run with no drawpoints, no marker snapshot and nothing drawn still gets its (empty)
/// sections, so a user sees the model extent rather than nothing.
pub fn write_run_charts(
    dir: &Path,
    scene: &Scene,
    run: &RunOutput,
    layer_spacing: Option<f64>,
    moments: &[i64],
) -> Result<Vec<PathBuf>, ChartError> {
    let out = dir.join("charts");
    std::fs::create_dir_all(&out).map_err(|source| ChartError::Io {
        path: out.clone(),
        source,
    })?;
    let mut written = Vec::new();
    let period_name = |p: i64| {
        scene
            .periods
            .id
            .iter()
            .position(|&id| id == p)
            .map(|i| scene.periods.name[i].clone())
    };
    let last = moments.last().copied();
    for &period in moments {
        let when = match period_name(period) {
            Some(name) if name != period.to_string() => {
                format!("end of period {period} ({name})")
            }
            _ => format!("end of period {period}"),
        };
        for (k, (section, y)) in run_sections(scene, run, layer_spacing, period)
            .into_iter()
            .enumerate()
        {
            let title = format!("Drawdown at Northing {} m, {when}", fmt_coord(y));
            let path = if Some(period) == last {
                out.join(format!("section_{}.png", k + 1))
            } else {
                out.join(format!("section_{}_p{period}.png", k + 1))
            };
            section_chart(&path, &section, &title)?;
            written.push(path);
        }
    }
    if let Some(name) = scene.blocks.grade_names.first() {
        let series = grade_series(scene, run, 0);
        if !series.is_empty() {
            let path = out.join(format!("grade_{}.png", file_safe(name)));
            let title = format!("{name}: predicted grade against cumulative tonnes");
            written.extend(grade_tonnage_chart(
                &path,
                &series,
                &title,
                &format!("{name} (%)"),
            )?);
        }
    }
    if let Some(section) = trace_section(scene, &run.trace) {
        let last = run.trace.period.iter().copied().max().unwrap_or(0);
        let title =
            format!("Trace points to the end of period {last} (Easting–elevation projection)");
        let path = out.join("trace.png");
        section_chart(&path, &section, &title)?;
        written.push(path);
    }
    written.extend(write_stress_charts(&out, scene, &run.stress)?);
    Ok(written)
}

/// A Northing for a title: up to three decimals, trailing zeros dropped.
fn fmt_coord(v: f64) -> String {
    let s = format!("{v:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".into()
    } else {
        s.into()
    }
}

/// A name as part of a file name: ASCII letters, digits, `-`, `_` and `.` kept, anything
/// else `_`.
fn file_safe(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.') {
                c
            } else {
                '_'
            }
        })
        .collect();
    if s.is_empty() {
        "grade".into()
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::Engine;
    use crate::model::synthetic::UniformBox;
    use crate::model::Scenario;
    use crate::output::charts::tests::out_dir;

    fn two_drawpoints() -> UniformBox {
        UniformBox {
            extent: [0.8, 0.4, 0.8],
            block: [0.05, 0.05, 0.05],
            drawpoints: vec![(-0.2, 0.0, 0.1), (0.2, 0.0, 0.1)],
            periods: 3,
            tonnes: 0.02,
            ..UniformBox::castro_isolated()
        }
    }

    fn run(scene: &Scene, h: f64, s: f64) -> RunOutput {
        let mut scenario = Scenario::default();
        scenario.resolution.layer_thickness = Some(h);
        scenario.resolution.marker_spacing = Some(s);
        Engine::new(scene, &scenario).unwrap().run(&mut |_, _| {})
    }

    #[test]
    fn run_charts_are_written_as_png() {
        let scene = two_drawpoints().scene();
        let out = run(&scene, 0.05, 0.025);
        assert!(!out.snapshot_periods().is_empty());
        let (_keep, dir) = out_dir("figures-two-dp");
        let written = write_run_charts(&dir, &scene, &out, None, &[3]).unwrap();
        let names: Vec<String> = written
            .iter()
            .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names, ["section_1.png", "grade_elev.png"]);
        for p in &written {
            assert_eq!(p.parent().unwrap(), dir.join("charts"));
            let bytes = std::fs::read(p).unwrap();
            assert!(
                bytes.len() > 1000,
                "{} is {} bytes",
                p.display(),
                bytes.len()
            );
            assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{}", p.display());
        }

        // The one section holds both drawpoints, both outlines and deformed layers.
        let sections = run_sections(&scene, &out, None, 3);
        assert_eq!(sections.len(), 1);
        let (section, y) = &sections[0];
        assert_eq!(*y, 0.0);
        assert_eq!(section.drawpoints.len(), 2);
        assert!(
            section.drawpoints[0].2.starts_with("DP01: ")
                && section.drawpoints[0].2.ends_with(" kg")
        );
        assert_eq!(section.imz.len(), 2);
        assert_eq!(section.iez.len(), 2);
        // 0.8 m high → 0.02 m neat spacing is below the marker spacing: 0.025 m layers, 32.
        assert_eq!(section.layers.len(), 32);
        let dipped = section
            .layers
            .iter()
            .flatten()
            .filter(|p| p.1.is_finite())
            .filter(|p| {
                let level = ((p.1 - 0.0125) / 0.025).round() * 0.025 + 0.0125;
                (p.1 - level).abs() > 1e-9
            })
            .count();
        assert!(dipped > 0, "no marker moved off its layer");
    }

    /// The project's own Figs 13 and 16 (DESIGN §7): Castro's isolated draw and IN-T2 at
    /// the summary's scale. Slow; run with `--ignored` and `CAVEFLOW_CHART_DIR` set to look.
    #[test]
    #[ignore]
    fn reference_scenes_render() {
        let castro = UniformBox::castro_isolated();
        let in_t2 = UniformBox {
            extent: [1.4, 0.7, 3.3],
            drawpoints: vec![(-0.35, 0.0, 0.12), (0.35, 0.0, 0.12)],
            periods: 10,
            tonnes: 0.003,
            ..UniformBox::castro_isolated()
        };
        for (name, scene) in [("castro", castro.scene()), ("in-t2", in_t2.scene())] {
            let t = std::time::Instant::now();
            let out = Engine::new(&scene, &Scenario::default())
                .unwrap()
                .run(&mut |_, _| {});
            let ran = t.elapsed();
            let (_keep, dir) = out_dir(name);
            let moments = scene.moments(&[]);
            let written = write_run_charts(&dir, &scene, &out, None, &moments).unwrap();
            eprintln!(
                "{name}: run {ran:?}, charts {:?}, resolution {:?}, warnings {:?}",
                t.elapsed() - ran,
                out.resolution,
                out.warnings
            );
            assert!(!written.is_empty());
        }
    }

    #[test]
    fn titles_and_file_names_read_well() {
        assert_eq!(fmt_coord(0.35), "0.35");
        assert_eq!(fmt_coord(-0.0), "0");
        assert_eq!(fmt_coord(5120.0), "5120");
        assert_eq!(file_safe("Mo %"), "Mo__");
    }
}
