//! The dilution entry of a drawpoint: the cumulative tonnes at which the waste share of its
//! periods first reaches [`DILUTION_ENTRY_SHARE`] (the `dilution` column of the extraction
//! report: the mass share of waste, by the scenario's waste rule, in the drawn material).
//! The run report marks it, the sweep measures its error and a study's summary averages it.

use crate::engine::result::RunOutput;

/// Waste share of a period at which the dilution entry is read.
pub const DILUTION_ENTRY_SHARE: f64 = 0.1;

/// Per drawpoint, the cumulative tonnes at which a period's waste share first reaches
/// [`DILUTION_ENTRY_SHARE`], interpolated between the midpoints of that period and the one
/// before (NaN where it never does).
pub fn dilution_entries(out: &RunOutput, n_dp: usize) -> Vec<f64> {
    let e = &out.extraction;
    let mut rows: Vec<usize> = (0..e.period.len()).filter(|&i| e.tonnes[i] > 0.0).collect();
    rows.sort_by_key(|&i| (e.drawpoint[i], e.period[i]));
    let mut entry = vec![f64::NAN; n_dp];
    let mut prev: Option<(u32, f64, f64)> = None; // (drawpoint, midpoint tonnes, share)
    for i in rows {
        let d = e.drawpoint[i];
        let (mid, share) = (e.cum_tonnes[i] - 0.5 * e.tonnes[i], e.dilution[i]);
        let slot = &mut entry[d as usize];
        if slot.is_nan() && share >= DILUTION_ENTRY_SHARE {
            *slot = match prev {
                Some((pd, pm, ps)) if pd == d && ps < DILUTION_ENTRY_SHARE => {
                    pm + (mid - pm) * (DILUTION_ENTRY_SHARE - ps) / (share - ps)
                }
                _ => mid,
            };
        }
        prev = Some((d, mid, share));
    }
    entry
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The dilution entry is read where a period's waste share first reaches 10%, between
    /// the midpoints of that period and the one before; a drawpoint that never reaches it
    /// has none.
    #[test]
    fn dilution_entry_interpolates_between_period_midpoints() {
        let mut out = RunOutput::default();
        let e = &mut out.extraction;
        // Drawpoint 0: 100 t a period, waste 0, 0.05, 0.25 (entry between the midpoints 150
        // and 250 t: 150 + 100 × 0.05 / 0.2 = 175 t). Drawpoint 1: 0.02 then 0.3 from its
        // first delivering period on, after an idle one (entry at that period's midpoint).
        // Drawpoint 2 never reaches 10%.
        for (d, p, t, w) in [
            (0, 1, 100.0, 0.0),
            (0, 2, 100.0, 0.05),
            (0, 3, 100.0, 0.25),
            (1, 1, 0.0, 0.0),
            (1, 2, 100.0, 0.3),
            (2, 1, 100.0, 0.09),
        ] {
            e.drawpoint.push(d);
            e.period.push(p);
            e.tonnes.push(t);
            e.dilution.push(w);
        }
        let mut cum = [0.0; 3];
        for i in 0..e.period.len() {
            cum[e.drawpoint[i] as usize] += e.tonnes[i];
            e.cum_tonnes.push(cum[e.drawpoint[i] as usize]);
        }
        let de = dilution_entries(&out, 3);
        assert!((de[0] - 175.0).abs() < 1e-9, "{de:?}");
        assert_eq!(de[1], 50.0);
        assert!(de[2].is_nan());
    }
}
