//! Grade against cumulative tonnes of a run, built for
//! [`grade_tonnage_chart`](super::grade_tonnage_chart): per drawpoint the predicted grade,
//! the grade perfectly uniform drawdown would give ([`block_grade`]) and the dilution entry
//! ([`grade_series`]).

use super::GradeSeries;
use crate::engine::result::RunOutput;
use crate::model::block_model::NO_BLOCK;
use crate::model::{BlockModel, Scene};
use crate::output::dilution::dilution_entries;

/// Grade against cumulative tonnes of grade column `g`, one series per drawpoint that drew
/// something, for [`grade_tonnage_chart`](super::grade_tonnage_chart).
///
/// - **Predicted**: per period, the extraction report's grade at the period's cumulative
///   tonnes, over the rows where markers were drawn (`markers > 0`) and the grade is finite
///   (NaN means nothing drawn).
/// - **Block grade** (the summary's dashed line, "grades that would be achieved under
///   perfectly uniform drawdown"): per period whose height of draw grew, the grade of the
///   in-situ slice that perfectly uniform drawdown of the column directly above the
///   drawpoint would deliver in that period: [`block_grade`] of the block-grid column
///   containing the drawpoint's (x, y), between `z + HOD_prev` and `z + HOD`, where z is the
///   drawpoint's elevation, HOD the extraction report's height of draw at the end of the
///   period (cumulative tonnes over tributary area × in-situ bulk density, see the engine)
///   and HOD_prev the one at the end of the drawpoint's previous row (0 before its first).
///   Plotted at the period's cumulative tonnes; slices with no block (above the model, or a
///   missing block) give no point.
/// - **Dilution entry** ([`dilution_entries`]), where the drawpoint reaches it.
///
/// Series are named after the drawpoints and carry no sampled grades.
pub fn grade_series(scene: &Scene, run: &RunOutput, g: usize) -> Vec<GradeSeries> {
    let ex = &run.extraction;
    let dp = &scene.drawpoints;
    let Some(grades) = ex.grades.get(g) else {
        return Vec::new();
    };
    let entries = dilution_entries(run, dp.len());
    let mut series: Vec<GradeSeries> = dp
        .name
        .iter()
        .zip(entries)
        .map(|(name, entry)| GradeSeries {
            name: name.clone(),
            block_grade: Some(Vec::new()),
            dilution_entry: entry.is_finite().then_some(entry),
            ..GradeSeries::default()
        })
        .collect();
    let mut hod_prev = vec![0.0; dp.len()];
    for (i, &d) in ex.drawpoint.iter().enumerate() {
        let d = d as usize;
        let Some(s) = series.get_mut(d) else { continue };
        let cum = ex.cum_tonnes[i];
        if ex.markers[i] > 0 && grades[i].is_finite() && cum.is_finite() {
            s.cum_tonnes.push(cum);
            s.predicted.push(grades[i]);
        }
        let hod = ex.hod[i];
        if hod.is_finite() && hod > hod_prev[d] {
            let v = block_grade(
                &scene.blocks,
                g,
                dp.x[d],
                dp.y[d],
                dp.z[d] + hod_prev[d],
                dp.z[d] + hod,
            );
            if v.is_finite() && cum.is_finite() {
                s.block_grade.as_mut().unwrap().push((cum, v));
            }
            hod_prev[d] = hod;
        }
    }
    series.retain(|s| !s.predicted.is_empty());
    series
}

/// Uniform-drawdown grade of a slice: the mass-weighted mean of grade column `g` over the
/// blocks of the block-grid column containing (`x`, `y`) between elevations `z_lo` and
/// `z_hi`.
///
/// Each block weighs its in-situ mass inside the slice: the length of [`z_lo`, `z_hi`]
/// inside the block × solids density × (1 − n0) (the footprint is the same for every block
/// of a column, so it cancels). Blocks missing from the grid are skipped. NaN when (x, y) is
/// off the grid, the slice is empty or reversed, or no block overlaps it.
pub fn block_grade(bm: &BlockModel, g: usize, x: f64, y: f64, z_lo: f64, z_hi: f64) -> f64 {
    let Some(col) = bm.grades.get(g) else {
        return f64::NAN;
    };
    // Written so that NaN bounds also give NaN.
    if z_hi.partial_cmp(&z_lo) != Some(std::cmp::Ordering::Greater) || bm.index.is_empty() {
        return f64::NAN;
    }
    let cell = |v: f64, a: usize| {
        let t = (v - bm.origin[a]) / bm.size[a];
        (t >= 0.0 && t < bm.dims[a] as f64).then_some(t as usize)
    };
    let (Some(i), Some(j)) = (cell(x, 0), cell(y, 1)) else {
        return f64::NAN;
    };
    let dz = bm.size[2];
    let k0 = ((z_lo - bm.origin[2]) / dz).floor().max(0.0) as usize;
    let k1 = (((z_hi - bm.origin[2]) / dz).ceil().max(0.0) as usize).min(bm.dims[2]);
    let (mut mass, mut sum) = (0.0, 0.0);
    for k in k0..k1 {
        let b = bm.index[i + bm.dims[0] * (j + bm.dims[1] * k)];
        if b == NO_BLOCK {
            continue;
        }
        let b = b as usize;
        let lo = bm.origin[2] + k as f64 * dz;
        let overlap = (z_hi.min(lo + dz) - z_lo.max(lo)).max(0.0);
        let w = overlap * bm.density[b] * (1.0 - bm.n0[b]);
        if w > 0.0 && col[b].is_finite() {
            mass += w;
            sum += w * col[b];
        }
    }
    if mass > 0.0 {
        sum / mass
    } else {
        f64::NAN
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::result::Extraction;
    use crate::model::synthetic::UniformBox;

    #[test]
    fn block_grade_is_the_mean_elevation_of_the_drawn_slice() {
        // Grade `elev` = block centre elevation, 0.05 m blocks from z = 0.
        let scene = UniformBox {
            extent: [0.2, 0.2, 1.0],
            ..UniformBox::castro_isolated()
        }
        .scene();
        let bm = &scene.blocks;
        let at = |lo: f64, hi: f64| block_grade(bm, 0, 0.01, -0.03, lo, hi);
        // A slice of whole blocks: the mean of their centres is the slice's mean elevation.
        assert!((at(0.0, 0.1) - 0.05).abs() < 1e-12);
        assert!((at(0.2, 0.5) - 0.35).abs() < 1e-12);
        // Part blocks weigh by their length inside the slice:
        // [0.04, 0.12] → 0.01 of 0.025, 0.05 of 0.075, 0.02 of 0.125.
        let expected = (0.01 * 0.025 + 0.05 * 0.075 + 0.02 * 0.125) / 0.08;
        assert!((at(0.04, 0.12) - expected).abs() < 1e-12);
        // Inside one block: that block's grade.
        assert!((at(0.51, 0.52) - 0.525).abs() < 1e-12);
        // Above the model, empty, reversed or off the grid: no grade.
        assert!(at(1.1, 1.2).is_nan());
        assert!(at(0.3, 0.3).is_nan());
        assert!(at(0.3, 0.2).is_nan());
        assert!(block_grade(bm, 0, 5.0, 0.0, 0.0, 0.1).is_nan());
        assert!(block_grade(bm, 1, 0.0, 0.0, 0.0, 0.1).is_nan());
        // Straddling the top: only the part inside the model counts.
        assert!((at(0.95, 1.5) - 0.975).abs() < 1e-12);
    }

    #[test]
    fn block_grade_weighs_in_situ_mass() {
        let mut scene = UniformBox {
            extent: [0.1, 0.1, 0.1],
            ..UniformBox::castro_isolated()
        }
        .scene();
        let bm = &mut scene.blocks;
        let lower = bm.locate([0.0, 0.0, 0.025]).unwrap();
        // The lower blocks hold twice the solids per metre of the upper ones.
        for b in 0..bm.len() {
            if bm.z[b] < 0.05 {
                bm.density[b] = 2.0;
                bm.n0[b] = 0.0;
            } else {
                bm.density[b] = 2.0;
                bm.n0[b] = 0.5;
            }
        }
        assert!(bm.z[lower] < 0.05);
        let v = block_grade(bm, 0, 0.0, 0.0, 0.0, 0.1);
        assert!((v - (2.0 * 0.025 + 0.075) / 3.0).abs() < 1e-12, "{v}");
    }

    #[test]
    fn grade_series_follows_the_extraction_rows() {
        let scene = UniformBox {
            extent: [0.2, 0.2, 1.0],
            drawpoints: vec![(-0.05, 0.0, 0.1), (0.05, 0.0, 0.1)],
            ..UniformBox::castro_isolated()
        }
        .scene();
        // Period-major rows; DP02 draws nothing in period 1 and is idle in period 2.
        let ex = Extraction {
            drawpoint: vec![0, 1, 0, 1, 0, 1],
            period: vec![1, 1, 2, 2, 3, 3],
            cum_tonnes: vec![0.01, 0.0, 0.02, 0.0, 0.03, 0.01],
            tonnes: vec![0.01, 0.0, 0.01, 0.0, 0.01, 0.01],
            dilution: vec![0.0, f64::NAN, 0.0, f64::NAN, 0.2, 0.0],
            markers: vec![5, 0, 4, 0, 6, 3],
            hod: vec![0.1, 0.0, 0.2, 0.0, 0.35, 0.1],
            grades: vec![vec![0.4, f64::NAN, 0.5, f64::NAN, 0.6, 0.3]],
            ..Extraction::default()
        };
        let out = RunOutput {
            extraction: ex,
            ..RunOutput::default()
        };
        let series = grade_series(&scene, &out, 0);
        assert_eq!(series.len(), 2);
        let a = &series[0];
        assert_eq!(a.name, "DP01");
        assert_eq!(a.cum_tonnes, [0.01, 0.02, 0.03]);
        assert_eq!(a.predicted, [0.4, 0.5, 0.6]);
        // 10% waste between the midpoints of periods 2 (0.015 t, none) and 3 (0.025 t, 20%).
        assert!((a.dilution_entry.unwrap() - 0.02).abs() < 1e-12);
        assert_eq!(series[1].dilution_entry, None);
        let blocks = a.block_grade.as_ref().unwrap();
        let want = [(0.01, 0.05), (0.02, 0.15), (0.03, 0.275)];
        assert_eq!(blocks.len(), 3);
        for (got, want) in blocks.iter().zip(want) {
            assert_eq!(got.0, want.0);
            assert!((got.1 - want.1).abs() < 1e-12, "{got:?} vs {want:?}");
        }
        let b = &series[1];
        assert_eq!(b.cum_tonnes, [0.01]);
        let blocks = b.block_grade.as_ref().unwrap();
        assert_eq!(blocks.len(), 1);
        assert!((blocks[0].1 - 0.05).abs() < 1e-12);
        assert!(grade_series(&scene, &out, 1).is_empty());
    }
}
