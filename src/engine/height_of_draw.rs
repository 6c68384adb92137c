//! The footprint behind the height of draw: each drawpoint's tributary plan area, from which
//! tonnes drawn become metres of column (HOD = tonnes / (footprint × bulk density)).

use rayon::prelude::*;

use crate::model::Scene;

/// Largest plan cell of the tributary areas, m (see [`tributary`]).
const TRIBUTARY_CELL: f64 = 1.0;

/// Tributary footprint × in-situ bulk density per drawpoint (t per m of height of draw):
/// each block-grid column is split into square sub-cells of at most [`TRIBUTARY_CELL`], and
/// each sub-cell belongs to its nearest drawpoint. Whole columns would leave a drawpoint
/// with no footprint (and an infinite height of draw) wherever drawpoints are closer
/// together than a block is wide, as at mine scale (15.2 m blocks, 12.2 m spacing).
pub(super) fn tributary(scene: &Scene) -> Vec<f64> {
    let bm = &scene.blocks;
    let dp = &scene.drawpoints;
    let mut out = vec![0.0; dp.len()];
    if dp.is_empty() {
        return out;
    }
    let sub = [0, 1].map(|a| ((bm.size[a] / TRIBUTARY_CELL).ceil() as usize).max(1));
    let area = bm.size[0] * bm.size[1] / (sub[0] * sub[1]) as f64;
    // Per block column (in parallel: a mine's 10⁴ columns × 10² sub-cells × 10² drawpoints),
    // its share per sub-cell and each sub-cell's nearest drawpoint; summed afterwards in
    // column order, so the footprints do not depend on the threads.
    let columns: Vec<(f64, Vec<usize>)> = (0..bm.dims[0] * bm.dims[1])
        .into_par_iter()
        .map(|c| {
            let (i, j) = (c % bm.dims[0], c / bm.dims[0]);
            let (mut rho, mut n) = (0.0, 0usize);
            for k in 0..bm.dims[2] {
                let b = bm.index[i + bm.dims[0] * (j + bm.dims[1] * k)];
                if b != crate::model::block_model::NO_BLOCK {
                    let b = b as usize;
                    rho += bm.density[b] * (1.0 - bm.n0[b]);
                    n += 1;
                }
            }
            if n == 0 {
                return (0.0, Vec::new());
            }
            let mut near = Vec::with_capacity(sub[0] * sub[1]);
            for sj in 0..sub[1] {
                for si in 0..sub[0] {
                    let x =
                        bm.origin[0] + (i as f64 + (si as f64 + 0.5) / sub[0] as f64) * bm.size[0];
                    let y =
                        bm.origin[1] + (j as f64 + (sj as f64 + 0.5) / sub[1] as f64) * bm.size[1];
                    near.push(
                        (0..dp.len())
                            .min_by(|&a, &b| {
                                let da = (dp.x[a] - x).powi(2) + (dp.y[a] - y).powi(2);
                                let db = (dp.x[b] - x).powi(2) + (dp.y[b] - y).powi(2);
                                da.total_cmp(&db)
                            })
                            .unwrap_or(0),
                    );
                }
            }
            (area * rho / n as f64, near)
        })
        .collect();
    for (share, near) in columns {
        for d in near {
            out[d] += share;
        }
    }
    out
}

/// The height of draw of `tonnes` credited over a footprint × bulk density of
/// `density_area` (t per m, [`tributary`]), m.
pub(super) fn hod(tonnes: f64, density_area: f64) -> f64 {
    tonnes / density_area.max(1e-12)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::demo::{henderson, DemoScale};

    /// At mine scale the drawpoints (12.2 m apart along a drift) are closer together than a
    /// block is wide (15.2 m): every drawpoint still has a footprint near its share of the
    /// panel (its heights of draw are finite), and the footprints add up to the panel's.
    #[test]
    fn every_drawpoint_has_a_tributary_footprint() {
        for scale in [DemoScale::Small, DemoScale::Mine] {
            let scene = henderson(scale, 1);
            let bm = &scene.blocks;
            let t = tributary(&scene);
            let mut whole = 0.0;
            for j in 0..bm.dims[1] {
                for i in 0..bm.dims[0] {
                    let col: Vec<usize> = (0..bm.dims[2])
                        .map(|k| bm.index[i + bm.dims[0] * (j + bm.dims[1] * k)])
                        .filter(|&b| b != crate::model::block_model::NO_BLOCK)
                        .map(|b| b as usize)
                        .collect();
                    if !col.is_empty() {
                        let rho: f64 = col.iter().map(|&b| bm.density[b] * (1.0 - bm.n0[b])).sum();
                        whole += bm.size[0] * bm.size[1] * rho / col.len() as f64;
                    }
                }
            }
            let sum: f64 = t.iter().sum();
            assert!(
                (sum - whole).abs() <= 1e-9 * whole,
                "{scale:?}: {sum} vs {whole}"
            );
            let mut sorted = t.clone();
            sorted.sort_by(f64::total_cmp);
            let median = sorted[t.len() / 2];
            // Interior drawpoints share the footprint evenly; those on the panel's edge take
            // the ground beyond it too, so only a floor is asserted.
            assert!(
                sorted[0] > 0.5 * median,
                "{scale:?}: smallest {} vs median {median}",
                sorted[0]
            );
        }
    }
}
