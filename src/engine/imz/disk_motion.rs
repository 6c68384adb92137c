//! What the marker pass reads of each disk after an update: its motion ([`DiskMotion`])
//! and the constants worked out from it once per disk ([`PerDisk`]).

use super::SHAPE_MODES;

/// Per-disk state that the marker pass reads, accumulated since the last marker update.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
pub struct DiskMotion {
    /// R_i now, m.
    pub r: f64,
    /// R_i at the last marker update (R_i^old), m.
    pub r_old: f64,
    /// Δv_i: void passed up into this disk since the last marker update, m³.
    pub dv: f64,
    /// Void passed out through this disk's top since the last marker update, m³: Δv_{i+1}
    /// for a disk below another (less the air a new disk above took in), or the void that
    /// left the IMZ for the free surface or an air gap. Δv_i − this is the void the disk's
    /// ring absorbed by dilating.
    pub dv_out: f64,
    /// Shear band width w_i = factor × d̄, m.
    pub w: f64,
    /// Janssen normal stress σ_n = ρ_s (1 − n1) g R / (2 tan φ), kPa.
    pub sigma_n: f64,
    /// Flowable share A_f of the disk's area: the void spreads over the material that
    /// exists, so vertical moves are divided by it (1 for a disk in open ground).
    pub area_frac: f64,
    /// Flowable share f of the disk's perimeter: the rays on which a ring dilates and
    /// pushes the interior in.
    pub flow_frac: f64,
    /// Mean fragment size d̄ of the disk, m.
    pub d: f64,
    /// The ring's dilation around the perimeter ([`Stagnant::shape`](super::Stagnant::shape)).
    pub shape: [f64; 2 * SHAPE_MODES],
    /// The marker pass's constants of this disk, the same for every marker it moves
    /// (`engine::markers::prepare`; zero until then).
    pub per_disk: PerDisk,
}

/// A disk's constants of the marker pass, worked out once per disk and update
/// (`engine::markers::prepare`) instead of once per marker in it.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
pub struct PerDisk {
    /// Plan area the dilating ring takes from the interior, (Δv_i − Δv_out) / (h f), m².
    pub take: f64,
    /// The ring's inward push at R^old, take F(R^old) / (2π R^old), m (0 where the disk
    /// did not widen).
    pub push: f64,
    /// Whether the ring's dilation differs around the perimeter (a lateral move).
    pub lateral: bool,
}
