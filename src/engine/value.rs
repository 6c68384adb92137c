//! The value of what each drawpoint drew (`[economics]`), period by period, and its best
//! height of draw: the height (and tonnes) at which its cumulative value peaks, as the
//! flow model predicts the grades it delivers, not as a mixing rule does.
//!
//! A drawpoint-period's value is tonnes × (Σ_g price_g × grade_g × recovery − cost per
//! tonne) (`model::Economics::value`), with the grades of the extraction row (what the
//! drawpoint's markers carried over the period, `engine::crediting`). The cumulative value
//! rises while the drawpoint delivers ore worth more than its cost and falls once dilution
//! has brought the grade below the break-even grade; its peak is the best height of draw.

use super::result::{BestHod, Extraction, ValueTable};
use crate::model::Economics;

/// The values of the extraction rows `ex` (grade columns `names`) and each drawpoint's
/// best height of draw.
pub fn values(ex: &Extraction, names: &[String], e: &Economics) -> (ValueTable, BestHod) {
    let mut t = ValueTable::default();
    let n = ex
        .drawpoint
        .iter()
        .map(|&d| d as usize + 1)
        .max()
        .unwrap_or(0);
    let mut cum = vec![0.0; n];
    // Per drawpoint: (best value, its hod, tonnes, period), and the last hod.
    let mut best = vec![(0.0, 0.0, 0.0, -1i64); n];
    let mut last_hod = vec![f64::NAN; n];
    let mut grade = vec![0.0; names.len()];
    for k in 0..ex.drawpoint.len() {
        if !(ex.tonnes[k] > 0.0) {
            continue;
        }
        let d = ex.drawpoint[k] as usize;
        for (g, col) in grade.iter_mut().zip(&ex.grades) {
            *g = col[k];
        }
        let v = e.value(names, &grade, ex.tonnes[k]);
        cum[d] += v;
        t.drawpoint.push(d as u32);
        t.period.push(ex.period[k]);
        t.tonnes.push(ex.tonnes[k]);
        t.hod.push(ex.hod[k]);
        t.value.push(v);
        t.cum_value.push(cum[d]);
        last_hod[d] = ex.hod[k];
        if cum[d] > best[d].0 {
            best[d] = (cum[d], ex.hod[k], ex.cum_tonnes[k], ex.period[k]);
        }
    }
    let mut b = BestHod::default();
    for d in (0..n).filter(|&d| !last_hod[d].is_nan()) {
        let (v, h, tonnes, p) = best[d];
        b.drawpoint.push(d as u32);
        b.best_hod.push(h);
        b.best_tonnes.push(tonnes);
        b.best_value.push(v);
        b.best_period.push(p);
        b.final_hod.push(last_hod[d]);
        b.final_value.push(cum[d]);
    }
    (t, b)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A drawpoint whose grade falls below break-even peaks at the last period that
    /// paid: ore at 1% worth 40 a tonne after a cost of 10, then waste at 0.1%.
    #[test]
    fn the_best_height_of_draw_is_where_the_cumulative_value_peaks() {
        let grades = [1.0, 1.0, 0.5, 0.1, 0.1];
        let ex = Extraction {
            drawpoint: vec![0; 5],
            period: (1..=5).collect(),
            tonnes: vec![100.0; 5],
            cum_tonnes: (1..=5).map(|k| 100.0 * k as f64).collect(),
            hod: (1..=5).map(|k| 10.0 * k as f64).collect(),
            grades: vec![grades.to_vec()],
            ..Default::default()
        };
        let e = Economics {
            price: [("mo".to_string(), 50.0)].into(),
            recovery: 1.0,
            cost_per_tonne: 10.0,
        };
        let (t, b) = values(&ex, &["mo".to_string()], &e);
        assert_eq!(t.value, vec![4000.0, 4000.0, 1500.0, -500.0, -500.0]);
        assert_eq!(t.cum_value.last(), Some(&8500.0));
        assert_eq!(b.best_value, vec![9500.0]);
        assert_eq!(
            (b.best_hod[0], b.best_tonnes[0], b.best_period[0]),
            (30.0, 300.0, 3)
        );
        assert_eq!(b.final_hod, vec![50.0]);
    }
}
