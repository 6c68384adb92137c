//! Synthetic production records: what a mine would have sampled if the ground were the
//! "true" one, for back-analysis to recover (DESIGN §8).
//!
//! The scene is run with a hidden true [`Calibration`] (applied on top of the scene as
//! given), and every drawpoint-period that delivered material becomes one record:
//! - `tonnes`: the run's credited tonnes (what the mine would have weighed);
//! - each grade: the run's predicted grade × (1 + ε), ε ~ Normal(0, σ), clamped to
//!   [0, 100] %: sampling and assay noise, relative, as assay error is;
//! - `frag_size` (optional): the run's mean fragment size × (1 + ε_f), ε_f ~ Normal(0, σ_f);
//!   a size the noise would make zero or negative is left unsampled.
//!
//! The noise comes from one [`ChaCha8Rng`] seeded with `seed`, drawn in record order (period,
//! then drawpoint; for each record its grades in order, then its size), so a seed gives the
//! same records on every machine. The demo's records (`data/records.csv`) are made by
//! `caveflow demo --records` with [`SyntheticRecords::default`].
//!
//! # Why the thesis' 0.15 m
//! The summary's §8 found Urad drawpoints matched at d̄ 0.23 m and others at 0.15 m. The demo
//! states 0.23 m for Urad; its records come from a run at 0.15 m, so calibration has a
//! factor of 0.15/0.23 = 0.652 to find.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use crate::engine::{Engine, EngineError};
use crate::model::scenario::Calibration;
use crate::model::{ProductionRecords, Scenario, Scene};

/// The hidden truth of the demo's records: Urad's d̄ is 0.15 m, not the stated 0.23 m.
pub const DEMO_TRUE_URAD_FACTOR: f64 = 0.15 / 0.23;
/// Relative sampling noise σ of the demo's grades (and sizes).
pub const DEMO_SIGMA: f64 = 0.05;
/// Seed of the demo's sampling noise.
pub const DEMO_NOISE_SEED: u64 = 7;

/// How to make synthetic records.
#[derive(Debug, Clone, PartialEq)]
pub struct SyntheticRecords {
    /// The hidden true calibration, applied on top of the scene as given.
    pub truth: Calibration,
    /// Relative noise σ of the sampled grades.
    pub sigma: f64,
    /// Relative noise σ of the sampled mean fragment size; None: no size column.
    pub frag_sigma: Option<f64>,
    /// Seed of the noise.
    pub seed: u64,
}

impl Default for SyntheticRecords {
    /// The demo's: Urad d̄ × 0.15/0.23, σ = 0.05 on grades and sizes, seed 7.
    fn default() -> Self {
        let mut truth = Calibration::default();
        truth
            .frag_factor
            .insert("urad".to_string(), DEMO_TRUE_URAD_FACTOR);
        SyntheticRecords {
            truth,
            sigma: DEMO_SIGMA,
            frag_sigma: Some(DEMO_SIGMA),
            seed: DEMO_NOISE_SEED,
        }
    }
}

/// Why synthetic records could not be made.
#[derive(Debug, thiserror::Error)]
pub enum SyntheticError {
    /// The truth does not fit the scene (an unknown lithology, a factor out of range).
    #[error("the true calibration does not fit the scene: {0}")]
    Truth(String),
    /// A noise σ that is not a finite number ≥ 0.
    #[error("the sampling noise σ must be a finite number >= 0, got {0}")]
    Sigma(f64),
    /// The engine refused the scene.
    #[error(transparent)]
    Engine(#[from] EngineError),
}

/// Runs `scene` under `scenario` with the hidden truth and samples the result (see the
/// module docs). `progress(period, periods)` is called as the run goes.
pub fn synthetic_records(
    scene: &Scene,
    scenario: &Scenario,
    cfg: &SyntheticRecords,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<ProductionRecords, SyntheticError> {
    for s in std::iter::once(cfg.sigma).chain(cfg.frag_sigma) {
        if !(s.is_finite() && s >= 0.0) {
            return Err(SyntheticError::Sigma(s));
        }
    }
    let mut truth = scene.clone();
    cfg.truth
        .apply(&mut truth.blocks)
        .map_err(SyntheticError::Truth)?;
    let out = Engine::new(&truth, scenario)?.run(progress);
    Ok(sample(
        &out.extraction,
        &truth.blocks.grade_names,
        cfg.sigma,
        cfg.frag_sigma,
        cfg.seed,
    ))
}

/// Samples an extraction report: one record per row that drew material (see the module
/// docs).
pub fn sample(
    x: &crate::engine::result::Extraction,
    grade_names: &[String],
    sigma: f64,
    frag_sigma: Option<f64>,
    seed: u64,
) -> ProductionRecords {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    // σ = 0 is a valid Normal; a σ that is not was refused by the caller.
    let noise = Normal::new(0.0, sigma).expect("σ checked");
    let frag_noise = frag_sigma.map(|s| Normal::new(0.0, s).expect("σ checked"));
    let mut r = ProductionRecords {
        grade_names: grade_names.to_vec(),
        grades: vec![Vec::new(); grade_names.len()],
        frag: frag_sigma.map(|_| Vec::new()),
        ..ProductionRecords::default()
    };
    for i in 0..x.tonnes.len() {
        if !(x.tonnes[i] > 0.0 && x.markers[i] > 0) {
            continue;
        }
        for (g, out) in r.grades.iter_mut().enumerate() {
            let e = noise.sample(&mut rng);
            let v = x.grades[g][i];
            out.push(if v.is_nan() {
                f64::NAN
            } else {
                (v * (1.0 + e)).clamp(0.0, 100.0)
            });
        }
        if let (Some(n), Some(out)) = (frag_noise.as_ref(), r.frag.as_mut()) {
            let e = n.sample(&mut rng);
            let v = x.frag_size[i] * (1.0 + e);
            out.push(if v > 0.0 { v } else { f64::NAN });
        }
        r.row.push(r.row.len() + 1);
        r.drawpoint.push(x.drawpoint[i] as usize);
        r.period.push(Some(x.period[i]));
        r.date.push(None);
        r.tonnes.push(x.tonnes[i]);
    }
    r
}
