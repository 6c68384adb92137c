//! The scenario's `[calibration]`: multiplicative factors on block properties, for
//! back-analysis, and how they are checked and applied to a block model.

use serde::{Deserialize, Serialize};

use super::SettingError;
use crate::model::BlockModel;

/// Multiplicative adjustments of the block model's flow properties: what `calibrate` fits
/// to production records, and what a calibrated scenario carries so it can be run again.
///
/// ```toml
/// [calibration]
/// frag_factor = { urad = 0.65 }   # d̄ (and the Weibull scale β) of every `urad` block × 0.65
/// n1_factor = 1.0
/// friction_factor = 1.0
/// ```
///
/// or `--set calibration.frag_factor.urad=0.65`. Applied by [`Calibration::apply`] right
/// after the block model is read and checked (`model::load::load_scene`), so `run`,
/// `validate` and `sweep` all see the adjusted scene. The default is the identity, which
/// leaves every block, and so every output, bit-identical.
///
/// # Why factors, not values
/// Back-analysis asks "how much finer is this zone than we assumed?" (summary §8: 0.23 m
/// stated, 0.15 m matched). A factor keeps the block model's spatial variation within a
/// lithology and is one number to fit per zone.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct Calibration {
    /// Multiplicative factor on the mean primary fragment size d̄ (and the Weibull scale β) of every block of the named lithology.
    pub frag_factor: std::collections::BTreeMap<String, f64>,
    /// Multiplicative factor on the dilated porosity n1 of every block (1 = as given).
    pub n1_factor: f64,
    /// Multiplicative factor on the friction angle φ of every block (1 = as given).
    pub friction_factor: f64,
}

impl Default for Calibration {
    fn default() -> Self {
        Calibration {
            frag_factor: std::collections::BTreeMap::new(),
            n1_factor: 1.0,
            friction_factor: 1.0,
        }
    }
}

impl Calibration {
    /// True when applying it changes nothing.
    pub fn is_identity(&self) -> bool {
        self.n1_factor == 1.0
            && self.friction_factor == 1.0
            && self.frag_factor.values().all(|&f| f == 1.0)
    }

    /// Range checks that need no block model: every factor finite and positive.
    pub fn check(&self) -> Result<(), SettingError> {
        for (lith, &f) in &self.frag_factor {
            SettingError::positive(&format!("calibration.frag_factor.{lith}"), Some(f))?;
        }
        SettingError::positive("calibration.n1_factor", Some(self.n1_factor))?;
        SettingError::positive("calibration.friction_factor", Some(self.friction_factor))
    }

    /// Applies the factors to a checked block model, in place:
    /// - `frag_factor[lith]` multiplies `frag` (d̄) and `frag_scale` (β) of every block of
    ///   that lithology; the Weibull shape α is kept, so the sampled sizes scale by the
    ///   same factor;
    /// - `n1_factor` multiplies `n1` of every block; the result must stay at least n0 (the
    ///   block model's own `n1-below-n0` rule: n1 = n0 is ground already dilated) and
    ///   below 1;
    /// - `friction_factor` multiplies φ of every block; the result must stay in (0°, 90°).
    ///
    /// A factor of exactly 1 touches nothing. Errors (nothing is changed then): a factor
    /// that is not a positive number, a lithology the block model does not have (the
    /// message lists those it has), and the first block that a factor takes out of range
    /// (named by block id, with the count of such blocks).
    pub fn apply(&self, bm: &mut BlockModel) -> Result<(), String> {
        self.apply_located(bm).map_err(|e| e.message)
    }

    /// [`apply`](Self::apply), with where its error lies: the block row and the block
    /// model column (canonical name) it concerns, for the loader's problem report.
    pub fn apply_located(&self, bm: &mut BlockModel) -> Result<(), CalibrationError> {
        let whole = |e: SettingError| CalibrationError {
            block: None,
            column: None,
            message: e.to_string(),
        };
        self.check().map_err(whole)?;
        let mut lith_factor = vec![1.0; bm.lithology_names.len()];
        for (lith, &f) in &self.frag_factor {
            match bm.lithology_names.iter().position(|n| n == lith) {
                Some(k) => lith_factor[k] = f,
                None => {
                    return Err(CalibrationError {
                        block: None,
                        column: Some("lithology"),
                        message: format!(
                            "calibration.frag_factor names lithology `{lith}`, which the block model does not have; it has: {}",
                            bm.lithology_names
                                .iter()
                                .map(|n| format!("`{n}`"))
                                .collect::<Vec<_>>()
                                .join(", ")
                        ),
                    })
                }
            }
        }
        // The first block a factor takes out of range, and how many it does.
        let first_bad = |ok: &dyn Fn(usize) -> bool| {
            let mut bad = (0..bm.len()).filter(|&b| !ok(b));
            bad.next().map(|b| (b, 1 + bad.count()))
        };
        let f1 = self.n1_factor;
        if f1 != 1.0 {
            let ok = |b: usize| {
                let n = bm.n1[b] * f1;
                n >= bm.n0[b] && n < 1.0
            };
            if let Some((b, count)) = first_bad(&ok) {
                return Err(CalibrationError {
                    block: Some(b),
                    column: Some("max_porosity"),
                    message: format!(
                        "calibration.n1_factor = {f1} takes max_porosity n1 of block {} from {} to {}, outside [n0 = {}, 1) ({count} block(s) in all)",
                        bm.id[b],
                        bm.n1[b],
                        bm.n1[b] * f1,
                        bm.n0[b]
                    ),
                });
            }
        }
        let ff = self.friction_factor;
        if ff != 1.0 {
            let ok = |b: usize| {
                let p = bm.friction[b] * ff;
                p > 0.0 && p < 90.0
            };
            if let Some((b, count)) = first_bad(&ok) {
                return Err(CalibrationError {
                    block: Some(b),
                    column: Some("friction_angle"),
                    message: format!(
                        "calibration.friction_factor = {ff} takes the friction angle of block {} from {}° to {}°, outside (0°, 90°) ({count} block(s) in all)",
                        bm.id[b],
                        bm.friction[b],
                        bm.friction[b] * ff
                    ),
                });
            }
        }
        if lith_factor.iter().any(|&f| f != 1.0) {
            for b in 0..bm.len() {
                let f = lith_factor[bm.lithology[b] as usize];
                if f != 1.0 {
                    bm.frag[b] *= f;
                    if let Some(s) = bm.frag_scale.get_mut(b) {
                        *s *= f;
                    }
                }
            }
        }
        if f1 != 1.0 {
            bm.n1.iter_mut().for_each(|n| *n *= f1);
        }
        if ff != 1.0 {
            bm.friction.iter_mut().for_each(|p| *p *= ff);
        }
        Ok(())
    }
}

/// Why a [`Calibration`] cannot be applied to a block model.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationError {
    /// The block (row of the block model) it concerns, if one.
    pub block: Option<usize>,
    /// The block model column (canonical name) it concerns, if one.
    pub column: Option<&'static str>,
    /// What is wrong.
    pub message: String,
}
