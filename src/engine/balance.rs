//! The mass balance of a run: how far the tonnes credited to the drawpoints sit from the
//! mass of the markers they drew (the correction), as a distribution and a warning.

use super::{CorrectionStats, Extraction};

/// MassFlow's bounds of its mass-correction factor: the rows beyond them are counted.
pub const CORRECTION_BOUNDS: (f64, f64) = (0.1, 2.0);

/// How far the median over the drawpoints of credited over marker tonnes may sit from 1
/// before a run warns: the markers' discreteness averages out over a drawpoint's run.
pub const CORRECTION_MEDIAN_TOLERANCE: f64 = 0.03;

/// The warning of a run whose drawpoints' median ratio of credited over marker tonnes
/// leaves 1 ± [`CORRECTION_MEDIAN_TOLERANCE`], over the run or over either half of the
/// drawpoints' tonnes (a bias that changes sign over the run can leave the run's median at
/// 1).
pub fn correction_warning(c: &CorrectionStats) -> Option<String> {
    let off = |m: f64| (m - 1.0).abs() > CORRECTION_MEDIAN_TOLERANCE;
    let [first, second] = c.halves_median;
    (c.rows > 0 && (off(c.drawpoint_median) || off(first) || off(second))).then(|| format!(
        "mass balance: the drawpoints' median ratio of credited over marker tonnes is {:.3} ({first:.3} over the first half of each drawpoint's tonnes, {second:.3} over the second), beyond 1 ± {CORRECTION_MEDIAN_TOLERANCE}: the markers drawn carry a bias, not only their discreteness (per drawpoint-period: median {:.3}, p10 {:.3}, p90 {:.3} over {} rows); see manifest.json mass_balance.correction",
        c.drawpoint_median, c.median, c.p10, c.p90, c.rows
    ))
}

/// Nearest-rank quantile `p` of sorted values (NaN if none).
fn quantile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((p * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len()) - 1]
}

/// The distribution of the correction factor in an extraction table: quantiles over the
/// `ok` rows that drew markers, the rows beyond MassFlow's bounds over every row with
/// markers, and the median over the drawpoints of their ratio over the run.
pub fn correction_stats(ex: &Extraction) -> CorrectionStats {
    let ok = |k: usize| ex.status[k] == "ok" && ex.marker_tonnes[k] > 0.0;
    let mut c: Vec<f64> = (0..ex.correction.len())
        .filter(|&k| ok(k))
        .map(|k| ex.correction[k])
        .collect();
    c.sort_unstable_by(f64::total_cmp);
    // Per drawpoint over the run, and over each half of its credited tonnes (a row falls in
    // the half that holds its middle): every ok row, those that drew no marker too.
    let rows = || (0..ex.correction.len()).filter(|&k| ex.status[k] == "ok");
    let mut total: std::collections::BTreeMap<u32, f64> = Default::default();
    for k in rows() {
        *total.entry(ex.drawpoint[k]).or_default() += ex.tonnes[k];
    }
    // (credited, marker) tonnes per drawpoint: over the run, the first half, the second.
    let mut per_dp: std::collections::BTreeMap<u32, [(f64, f64); 3]> = Default::default();
    for k in rows() {
        let e = per_dp.entry(ex.drawpoint[k]).or_default();
        let half = if e[0].0 + 0.5 * ex.tonnes[k] <= 0.5 * total[&ex.drawpoint[k]] {
            1
        } else {
            2
        };
        for i in [0, half] {
            e[i].0 += ex.tonnes[k];
            e[i].1 += ex.marker_tonnes[k];
        }
    }
    let median_of = |i: usize| {
        let mut r: Vec<f64> = per_dp
            .values()
            .filter(|e| e[i].1 > 0.0)
            .map(|e| e[i].0 / e[i].1)
            .collect();
        r.sort_unstable_by(f64::total_cmp);
        quantile(&r, 0.5)
    };
    let beyond = |outside: fn(f64) -> bool| {
        (0..ex.correction.len())
            .filter(|&k| ex.marker_tonnes[k] > 0.0 && outside(ex.correction[k]))
            .count() as u64
    };
    CorrectionStats {
        rows: c.len() as u64,
        median: quantile(&c, 0.5),
        p10: quantile(&c, 0.1),
        p90: quantile(&c, 0.9),
        at_lower_bound: beyond(|x| x <= CORRECTION_BOUNDS.0),
        at_upper_bound: beyond(|x| x >= CORRECTION_BOUNDS.1),
        drawpoint_median: median_of(0),
        halves_median: [median_of(1), median_of(2)],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn correction_stats_and_warning() {
        let mut ex = Extraction::default();
        for (k, (c, m, st)) in [
            (0.9, 10.0, "ok"),
            (1.0, 10.0, "ok"),
            (1.02, 10.0, "ok"),
            (1.1, 10.0, "ok"),
            (2.0, 10.0, "short"),
            (1.0, 0.0, "ok"),
        ]
        .into_iter()
        .enumerate()
        {
            ex.drawpoint.push((k % 2) as u32);
            ex.correction.push(c);
            ex.marker_tonnes.push(m);
            ex.tonnes.push(if m > 0.0 { c * m } else { 5.0 });
            ex.status.push(st);
        }
        let s = correction_stats(&ex);
        // Quantiles over the four ok rows that drew markers; bounds over every row.
        assert_eq!((s.rows, s.p10, s.median, s.p90), (4, 0.9, 1.0, 1.1));
        assert_eq!((s.at_lower_bound, s.at_upper_bound), (0, 1));
        // Drawpoint 0: (9 + 10.2) / 20 = 0.96; drawpoint 1: (10 + 11 + 5) / 20 = 1.3, its ok
        // row that drew no marker counting with its 5 t credited.
        assert!(
            (s.drawpoint_median - 0.96).abs() < 1e-12,
            "{}",
            s.drawpoint_median
        );
        let mut one = ex.clone();
        one.status[0] = "short";
        one.status[2] = "short";
        assert!((correction_stats(&one).drawpoint_median - 1.3).abs() < 1e-12);
        assert!(correction_warning(&s)
            .unwrap()
            .contains("median ratio of credited over marker tonnes is 0.960"));
        // Halves: drawpoint 0's 9 t row is its first half (0.9), its 10.2 t row its second
        // (1.02); drawpoint 1's 10 t row its first (1.0), the 11 t and 5 t rows its second
        // (16 / 10). Nearest-rank medians of two values take the lower.
        assert_eq!(
            s.halves_median.map(|m| (m * 1e9).round() / 1e9),
            [0.9, 1.02]
        );
        let fair = CorrectionStats {
            drawpoint_median: 1.02,
            halves_median: [1.0, 1.02],
            ..s
        };
        assert!(correction_warning(&fair).is_none());
        // A bias that changes sign over the run leaves the run's median at 1.
        let trend = CorrectionStats {
            drawpoint_median: 1.0,
            halves_median: [0.96, 1.05],
            ..s
        };
        assert!(correction_warning(&trend).unwrap().contains(
            "(0.960 over the first half of each drawpoint's tonnes, 1.050 over the second)"
        ));
        assert!(correction_warning(&CorrectionStats::default()).is_none());
    }
}
