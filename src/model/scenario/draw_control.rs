//! Draw control (`[draw_control]`) and the value of what is drawn (`[economics]`): how
//! each period's production is shared among the drawpoints, when a drawpoint opens and
//! closes, and what a tonne drawn is worth. The engine applies them period by period
//! (`engine::draw_control`); here are the settings and their range checks.

use serde::{Deserialize, Serialize};

use super::SettingError;

/// How each period's tonnes are decided.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, Default, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Strategy {
    /// The schedule's tonnes, as given (the default).
    #[default]
    Schedule,
    /// A production target per period, shared among the open drawpoints under their
    /// rate limits, the uniformity rule and the closure rules. The schedule then says
    /// only which drawpoints exist; its tonnes are not read.
    Target,
}

/// `[draw_control]`. With `strategy = "schedule"` (the default) no other key may be set
/// and a run draws its schedule exactly as without the section.
#[derive(Debug, Clone, Serialize, Deserialize, Default, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct DrawControl {
    /// `schedule` or `target`.
    pub strategy: Strategy,
    /// The production target, t/day: a period's target is this times its days.
    pub target_rate: Option<f64>,
    /// The production target per period instead: a table (CSV or Parquet) of period and
    /// tonnes (schema `target`), relative to the scenario file.
    pub target_table: Option<std::path::PathBuf>,
    /// The most one drawpoint draws, t/day.
    pub max_rate: Option<f64>,
    /// The least an open drawpoint draws, t/day, when the target leaves enough (0: none).
    pub min_rate: f64,
    /// The draw-rate curve of a young drawpoint: points (share of its column drawn, share
    /// of `max_rate`), the shares increasing and in [0, 1]; piecewise linear between them
    /// and flat beyond the last. A drawpoint's column is the height from its brow to the
    /// top of the block model; the share drawn is its height of draw over that. Empty:
    /// the full rate from the start.
    pub rate_curve: Vec<[f64; 2]>,
    /// Uniform draw: a drawpoint whose height of draw exceeds the mean of its open
    /// neighbours' by more than this, m, draws only what the others cannot take.
    pub uniform_tolerance: Option<f64>,
    /// Neighbours for uniform draw: drawpoints within this distance in plan, m. Unset:
    /// 1.5 times the median distance from a drawpoint to its nearest neighbour.
    pub neighbour_radius: Option<f64>,
    /// Shut-off: the grade column named by `shutoff_column` below which a drawpoint
    /// closes, over `shutoff_periods` consecutive periods in which it drew.
    pub shutoff_grade: Option<f64>,
    /// The grade column of the shut-off rule (a block model grade column).
    pub shutoff_column: Option<String>,
    /// Consecutive periods below the shut-off grade that close a drawpoint (default 1).
    pub shutoff_periods: Option<usize>,
    /// A drawpoint closes once the waste share of what it drew in a period exceeds this
    /// (0–1).
    pub max_dilation: Option<f64>,
    /// A drawpoint closes once its height of draw reaches this, m.
    pub max_hod: Option<f64>,
    /// A drawpoint closes once a period's value (`[economics]`) is negative: its
    /// cumulative value has peaked, at its best height of draw.
    pub best_hod: bool,
}

impl DrawControl {
    /// Whether the schedule is replaced by a target.
    pub fn is_target(&self) -> bool {
        self.strategy == Strategy::Target
    }

    /// The rate curve's share of `max_rate` at `share` of the column drawn.
    pub fn rate_share(&self, share: f64) -> f64 {
        let c = &self.rate_curve;
        match c.iter().position(|p| p[0] > share) {
            None => c.last().map_or(1.0, |p| p[1]),
            Some(0) => c[0][1],
            Some(k) => {
                let ([x0, y0], [x1, y1]) = (c[k - 1], c[k]);
                y0 + (y1 - y0) * (share - x0) / (x1 - x0)
            }
        }
    }

    /// Range checks (rule `setting-range`), given whether `[economics]` is set and the
    /// grade columns it prices.
    pub fn check(&self, economics: Option<&Economics>) -> Result<(), SettingError> {
        let bad = |key: &str, must: String| Err(SettingError::new(key, must));
        let key = |k: &str| format!("draw_control.{k}");
        if !self.is_target() {
            let set = [
                ("target_rate", self.target_rate.is_some()),
                ("target_table", self.target_table.is_some()),
                ("max_rate", self.max_rate.is_some()),
                ("min_rate", self.min_rate != 0.0),
                ("rate_curve", !self.rate_curve.is_empty()),
                ("uniform_tolerance", self.uniform_tolerance.is_some()),
                ("neighbour_radius", self.neighbour_radius.is_some()),
                ("shutoff_grade", self.shutoff_grade.is_some()),
                ("shutoff_column", self.shutoff_column.is_some()),
                ("shutoff_periods", self.shutoff_periods.is_some()),
                ("max_dilation", self.max_dilation.is_some()),
                ("max_hod", self.max_hod.is_some()),
                ("best_hod", self.best_hod),
            ];
            if let Some((k, _)) = set.iter().find(|(_, s)| *s) {
                return bad(
                    &key(k),
                    "applies to strategy = \"target\" only (the schedule's tonnes are drawn as given)".into(),
                );
            }
            return Ok(());
        }
        match (self.target_rate, &self.target_table) {
            (None, None) => {
                return bad(
                    &key("target_rate"),
                    "or draw_control.target_table must be given with strategy = \"target\" (the production target)".into(),
                )
            }
            (Some(_), Some(_)) => {
                return bad(
                    &key("target_table"),
                    "and draw_control.target_rate are two ways to give the target: give one".into(),
                )
            }
            _ => {}
        }
        SettingError::positive(&key("target_rate"), self.target_rate)?;
        SettingError::positive(&key("max_rate"), self.max_rate)?;
        if !(self.min_rate.is_finite() && self.min_rate >= 0.0) {
            return bad(
                &key("min_rate"),
                format!("must be a number >= 0, got {}", self.min_rate),
            );
        }
        if let Some(m) = self.max_rate {
            if self.min_rate > m {
                return bad(
                    &key("min_rate"),
                    format!("must not exceed max_rate ({m}), got {}", self.min_rate),
                );
            }
        }
        if !self.rate_curve.is_empty() && self.max_rate.is_none() {
            return bad(
                &key("rate_curve"),
                "needs max_rate (the curve gives shares of it)".into(),
            );
        }
        for (k, p) in self.rate_curve.iter().enumerate() {
            if !p.iter().all(|x| (0.0..=1.0).contains(x)) {
                return bad(
                    &key("rate_curve"),
                    format!("point {} {p:?}: both shares must lie in [0, 1]", k + 1),
                );
            }
            if k > 0 && !(p[0] > self.rate_curve[k - 1][0]) {
                return bad(
                    &key("rate_curve"),
                    format!(
                        "point {} {p:?}: the share of the column drawn must increase",
                        k + 1
                    ),
                );
            }
        }
        SettingError::positive(&key("uniform_tolerance"), self.uniform_tolerance)?;
        SettingError::positive(&key("neighbour_radius"), self.neighbour_radius)?;
        if self.neighbour_radius.is_some() && self.uniform_tolerance.is_none() {
            return bad(
                &key("neighbour_radius"),
                "needs uniform_tolerance (the neighbours are uniform draw's)".into(),
            );
        }
        match (&self.shutoff_grade, &self.shutoff_column) {
            (Some(g), Some(_)) if !(g.is_finite() && *g >= 0.0) => {
                return bad(
                    &key("shutoff_grade"),
                    format!("must be a number >= 0, got {g}"),
                )
            }
            (Some(_), None) => {
                return bad(
                    &key("shutoff_column"),
                    "must name the grade column of shutoff_grade".into(),
                )
            }
            (None, Some(_)) => {
                return bad(
                    &key("shutoff_grade"),
                    "must be given with shutoff_column".into(),
                )
            }
            _ => {}
        }
        match self.shutoff_periods {
            Some(0) => return bad(&key("shutoff_periods"), "must be at least 1".into()),
            Some(_) if self.shutoff_grade.is_none() => {
                return bad(
                    &key("shutoff_periods"),
                    "needs shutoff_grade and shutoff_column".into(),
                )
            }
            _ => {}
        }
        if let Some(x) = self.max_dilation {
            if !(0.0..=1.0).contains(&x) {
                return bad(&key("max_dilation"), format!("must lie in [0, 1], got {x}"));
            }
        }
        SettingError::positive(&key("max_hod"), self.max_hod)?;
        if self.best_hod && economics.is_none() {
            return bad(
                &key("best_hod"),
                "needs [economics] (a period's value decides the best height of draw)".into(),
            );
        }
        Ok(())
    }
}

/// `[economics]`: what a tonne drawn is worth. A drawpoint-period's value is
/// Σ_g price_g × grade_g × recovery × tonnes − cost_per_tonne × tonnes, the grades those
/// of what it drew (in the block model's units, per tonne).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct Economics {
    /// Price per unit of grade and tonne, per grade column (e.g. `{ mo = 400.0 }` with
    /// grades in %: the value of a tonne at 1% Mo before recovery).
    pub price: std::collections::BTreeMap<String, f64>,
    /// Metallurgical recovery (0–1].
    pub recovery: f64,
    /// Cost per tonne drawn.
    pub cost_per_tonne: f64,
}

impl Default for Economics {
    fn default() -> Self {
        Economics {
            price: Default::default(),
            recovery: 1.0,
            cost_per_tonne: 0.0,
        }
    }
}

impl Economics {
    /// The value of `tonnes` drawn at `grade` (per grade column of `names`).
    pub fn value(&self, names: &[String], grade: &[f64], tonnes: f64) -> f64 {
        let metal: f64 = names
            .iter()
            .zip(grade)
            .filter_map(|(n, g)| self.price.get(n).map(|p| p * g))
            .sum();
        tonnes * (metal * self.recovery - self.cost_per_tonne)
    }

    /// Range checks (rule `setting-range`).
    pub fn check(&self) -> Result<(), SettingError> {
        let bad = |key: &str, must: String| Err(SettingError::new(key, must));
        if self.price.is_empty() {
            return bad(
                "economics.price",
                "must price at least one grade column".into(),
            );
        }
        for (g, p) in &self.price {
            if !(p.is_finite() && *p >= 0.0) {
                return bad(
                    &format!("economics.price.{g}"),
                    format!("must be a number >= 0, got {p}"),
                );
            }
        }
        if !(self.recovery > 0.0 && self.recovery <= 1.0) {
            return bad(
                "economics.recovery",
                format!("must lie in (0, 1], got {}", self.recovery),
            );
        }
        if !(self.cost_per_tonne.is_finite() && self.cost_per_tonne >= 0.0) {
            return bad(
                "economics.cost_per_tonne",
                format!("must be a number >= 0, got {}", self.cost_per_tonne),
            );
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn target() -> DrawControl {
        DrawControl {
            strategy: Strategy::Target,
            target_rate: Some(1000.0),
            max_rate: Some(100.0),
            ..Default::default()
        }
    }

    /// The curve is linear between its points and flat outside them.
    #[test]
    fn the_rate_curve_is_piecewise_linear_and_flat_beyond_its_ends() {
        let mut c = target();
        assert_eq!(c.rate_share(0.3), 1.0);
        c.rate_curve = vec![[0.1, 0.2], [0.3, 1.0]];
        assert_eq!(c.rate_share(0.0), 0.2);
        assert!((c.rate_share(0.2) - 0.6).abs() < 1e-12);
        assert_eq!(c.rate_share(0.3), 1.0);
        assert_eq!(c.rate_share(0.9), 1.0);
        c.check(None).unwrap();
    }

    /// Each bad setting names its key and the rule it breaks.
    #[test]
    fn bad_draw_control_settings_name_their_key() {
        let err = |c: DrawControl| c.check(None).unwrap_err();
        let e = err(DrawControl {
            max_rate: Some(5.0),
            ..Default::default()
        });
        assert_eq!(e.key, "draw_control.max_rate");
        assert!(e.must.contains("strategy = \"target\" only"), "{e}");
        let e = err(DrawControl {
            target_rate: None,
            ..target()
        });
        assert_eq!(e.key, "draw_control.target_rate");
        let e = err(DrawControl {
            max_rate: Some(-1.0),
            ..target()
        });
        assert_eq!(
            e.to_string(),
            "draw_control.max_rate must be a positive number, got -1"
        );
        let e = err(DrawControl {
            rate_curve: vec![[0.2, 0.5], [0.1, 1.0]],
            ..target()
        });
        assert!(e.must.contains("must increase"), "{e}");
        let e = err(DrawControl {
            rate_curve: vec![[0.2, 1.5]],
            ..target()
        });
        assert!(e.must.contains("[0, 1]"), "{e}");
        let e = err(DrawControl {
            shutoff_grade: Some(0.1),
            ..target()
        });
        assert_eq!(e.key, "draw_control.shutoff_column");
        let e = err(DrawControl {
            best_hod: true,
            ..target()
        });
        assert!(e.must.contains("[economics]"), "{e}");
        let e = err(DrawControl {
            min_rate: 200.0,
            ..target()
        });
        assert!(e.must.contains("must not exceed max_rate"), "{e}");
        let e = Economics::default().check().unwrap_err();
        assert_eq!(e.key, "economics.price");
        assert_eq!(DrawControl::default().check(None), Ok(()));
    }
}
