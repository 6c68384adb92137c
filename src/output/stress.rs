//! The stress logic's outputs (summary §5.3, Figs 24–25; `engine::stress`).
//!
//! ```text
//! <dir>/stress_levels.parquet     one row per level per chosen period: Janssen cave average,
//!                                 bins, groups, pillar ratio and the interactive-draw flag
//! <dir>/stress_sections.parquet   one row per grid point per section per chosen period
//! <dir>/charts/stress_p<N>_<section>.png   vertical stress on each section (kPa), IMZ
//!                                 outlines, flagged levels as red lines (vertical sections)
//! ```

use std::path::{Path, PathBuf};
use std::sync::Arc;

use arrow::array::{ArrayRef, StringArray};

use super::charts::stress::{stress_chart, StressChart};
use super::charts::{fmt_mass, imz_outline, ChartError};
use super::columns::{f64s, f64s_or_null, i64s, write_table};
use super::OutputError;
use crate::engine::stress::{Orientation, StressField};
use crate::model::Scene;
use crate::schema::{STRESS_LEVELS, STRESS_SECTIONS};

fn strings(v: Vec<String>) -> ArrayRef {
    Arc::new(StringArray::from(v))
}

/// Writes `stress_levels.parquet` and `stress_sections.parquet` into `dir`; returns the paths.
pub fn write_stress(dir: &Path, fields: Vec<StressField>) -> Result<Vec<PathBuf>, OutputError> {
    let mut period: Vec<i64> = Vec::new();
    // z, cave area, cave perimeter, σv at the cave, mean σv.
    let mut lv: [Vec<f64>; 5] = Default::default();
    let mut counts: (Vec<i64>, Vec<i64>, Vec<i64>) = Default::default();
    let mut ratios: (Vec<f64>, Vec<f64>, Vec<f64>, Vec<i64>) = Default::default();
    let mut sec = SectionColumns::default();
    for f in fields {
        let l = f.levels;
        period.extend(std::iter::repeat_n(f.period, l.z.len()));
        lv[0].extend(l.z);
        lv[1].extend(l.cave_area);
        lv[2].extend(l.cave_perimeter);
        lv[3].extend(l.sigma_v_cave);
        lv[4].extend(l.sigma_v_mean);
        counts.0.extend(l.bins);
        counts.1.extend(l.groups);
        counts.2.extend(l.pillars);
        ratios.0.extend(l.pillar_ratio);
        ratios.1.extend(l.stagnant_ratio);
        ratios.2.extend(l.arched);
        ratios.3.extend(l.flagged.iter().map(|&b| b as i64));
        for s in f.sections {
            let n = s.x.len();
            sec.period.extend(std::iter::repeat_n(f.period, n));
            sec.section.extend(std::iter::repeat_n(s.name(), n));
            let o = s.orientation.map_or("", Orientation::name).to_string();
            sec.orientation.extend(std::iter::repeat_n(o, n));
            sec.x.extend(s.x);
            sec.y.extend(s.y);
            sec.z.extend(s.z);
            sec.sigma_v.extend(s.sigma_v);
            sec.sigma_h.extend(s.sigma_h);
            sec.ratio.extend(s.ratio);
            sec.zone.extend(s.zone.iter().map(|z| z.name().to_string()));
        }
    }
    let levels = dir.join("stress_levels.parquet");
    let [z, cave_area, cave_perimeter, sigma_v_cave, sigma_v_mean] = lv;
    let fixed = vec![
        ("period", i64s(period)),
        ("z", f64s(z)),
        ("cave_area", f64s(cave_area)),
        ("cave_perimeter", f64s(cave_perimeter)),
        ("sigma_v_cave", f64s_or_null(sigma_v_cave)),
        ("sigma_v_mean", f64s_or_null(sigma_v_mean)),
        ("bins", i64s(counts.0)),
        ("groups", i64s(counts.1)),
        ("pillars", i64s(counts.2)),
        ("pillar_ratio", f64s_or_null(ratios.0)),
        ("stagnant_ratio", f64s_or_null(ratios.1)),
        ("arched", f64s(ratios.2)),
        ("flagged", i64s(ratios.3)),
    ];
    write_table(&levels, &STRESS_LEVELS, fixed, Vec::new())?;
    let sections = dir.join("stress_sections.parquet");
    let fixed = vec![
        ("period", i64s(sec.period)),
        ("section", strings(sec.section)),
        ("orientation", strings(sec.orientation)),
        ("x", f64s(sec.x)),
        ("y", f64s(sec.y)),
        ("z", f64s(sec.z)),
        ("sigma_v", f64s_or_null(sec.sigma_v)),
        ("sigma_h", f64s_or_null(sec.sigma_h)),
        ("ratio", f64s_or_null(sec.ratio)),
        ("zone", strings(sec.zone)),
    ];
    write_table(&sections, &STRESS_SECTIONS, fixed, Vec::new())?;
    Ok(vec![levels, sections])
}

/// Columns of `stress_sections` being gathered.
#[derive(Default)]
struct SectionColumns {
    period: Vec<i64>,
    section: Vec<String>,
    orientation: Vec<String>,
    x: Vec<f64>,
    y: Vec<f64>,
    z: Vec<f64>,
    sigma_v: Vec<f64>,
    sigma_h: Vec<f64>,
    ratio: Vec<f64>,
    zone: Vec<String>,
}

/// Draws the vertical stress on every section of every field into `dir` (created if
/// missing) as `stress_p<period>_<section>.png`; returns the paths. Vertical sections carry
/// the IMZ outlines, the drawpoints with the mass each has drawn, and a red line at every
/// flagged level (potential interactive draw), like the summary's Figs 24–25.
pub fn write_stress_charts(
    dir: &Path,
    scene: &Scene,
    fields: &[StressField],
) -> Result<Vec<PathBuf>, ChartError> {
    if fields.is_empty() {
        return Ok(Vec::new());
    }
    std::fs::create_dir_all(dir).map_err(|source| ChartError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let bm = &scene.blocks;
    let max = bm.max_corner();
    let mut written = Vec::new();
    for f in fields {
        let flagged: Vec<f64> = (0..f.levels.z.len())
            .filter(|&k| f.levels.flagged[k])
            .map(|k| f.levels.z[k])
            .collect();
        for s in &f.sections {
            let Some(o) = s.orientation else { continue };
            let (u_axis, v_axis, u_range, v_range, what) = match o {
                Orientation::NorthSouth => (
                    "Northing (m)",
                    "Elevation (m)",
                    (bm.origin[1], max[1]),
                    (bm.origin[2], max[2]),
                    format!("N-S section at Easting {:.3} m", s.at),
                ),
                Orientation::EastWest => (
                    "Easting (m)",
                    "Elevation (m)",
                    (bm.origin[0], max[0]),
                    (bm.origin[2], max[2]),
                    format!("E-W section at Northing {:.3} m", s.at),
                ),
                Orientation::Plan => (
                    "Easting (m)",
                    "Northing (m)",
                    (bm.origin[0], max[0]),
                    (bm.origin[1], max[1]),
                    format!("plan at elevation {:.3} m", s.at),
                ),
            };
            let vertical = o != Orientation::Plan;
            let label = |d: usize| {
                let name = scene.drawpoints.name.get(d).cloned().unwrap_or_default();
                match f.drawn_tonnes.get(d) {
                    Some(&t) => format!("{name} {}", fmt_mass(t)),
                    None => name,
                }
            };
            let plan_flag = o == Orientation::Plan
                && f.levels
                    .z
                    .iter()
                    .zip(&f.levels.flagged)
                    .any(|(&z, &fl)| fl && (s.at - z).abs() <= 0.5 * f.cell);
            let chart = StressChart {
                title: format!(
                    "Vertical stress (kPa), {what}, end of period {}{}",
                    f.period,
                    if plan_flag {
                        " (level flagged: potential interactive draw)"
                    } else {
                        ""
                    }
                ),
                u_label: u_axis.to_string(),
                v_label: v_axis.to_string(),
                u_range,
                v_range,
                cell: s.cell,
                points: match o {
                    Orientation::NorthSouth => {
                        s.y.iter().copied().zip(s.z.iter().copied()).collect()
                    }
                    Orientation::EastWest => s.x.iter().copied().zip(s.z.iter().copied()).collect(),
                    Orientation::Plan => s.x.iter().copied().zip(s.y.iter().copied()).collect(),
                },
                values: s.sigma_v.clone(),
                outlines: if vertical {
                    s.imz
                        .iter()
                        .map(|(axis, st)| imz_outline(st, *axis))
                        .collect()
                } else {
                    s.circles.iter().map(|&(x, y, r)| circle(x, y, r)).collect()
                },
                drawpoints: s
                    .drawpoints
                    .iter()
                    .map(|&(u, v, d)| (u, v, if vertical { label(d) } else { String::new() }))
                    .collect(),
                flagged: if vertical {
                    flagged.clone()
                } else {
                    Vec::new()
                },
            };
            let path = dir.join(format!(
                "stress_p{}_{}.png",
                f.period,
                s.name().replace('=', "_")
            ));
            stress_chart(&path, &chart)?;
            written.push(path);
        }
    }
    Ok(written)
}

/// A closed circle polyline.
fn circle(x: f64, y: f64, r: f64) -> Vec<(f64, f64)> {
    (0..=72)
        .map(|k| {
            let t = k as f64 * std::f64::consts::TAU / 72.0;
            (x + r * t.cos(), y + r * t.sin())
        })
        .collect()
}
