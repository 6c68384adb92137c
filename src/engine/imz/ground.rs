//! The ground around a disk: the stagnant properties of its perimeter (sampled at
//! [`PERIMETER_POINTS`] points), the flowable share of its area and the dilation state of
//! its ring (which perimeter points already lie in another IMZ).

use std::f64::consts::PI;

use super::{
    ImzGeom, ImzGrid, ImzParams, AREA_RINGS, MAX_DILATION_POINTS, PERIMETER_POINTS, SHAPE_MODES,
    UNIT_CIRCLE,
};
use crate::model::BlockModel;

/// The ground around an IMZ: block model, current period and the other IMZs (a snapshot
/// taken at the start of the step, so parallel IMZ updates are deterministic).
pub struct Ground<'a> {
    /// Block model.
    pub blocks: &'a BlockModel,
    /// Current period number (flowability).
    pub period: i64,
    /// All IMZ geometries at the start of the step.
    pub geoms: &'a [ImzGeom],
    /// Grid over `geoms`.
    pub grid: &'a ImzGrid,
}

/// Stagnant properties of a disk (mean over its flowable perimeter points).
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
pub struct Stagnant {
    /// Mean current porosity (n1 where already dilated, else n0).
    pub n0: f64,
    /// Mean dilated porosity n1.
    pub n1: f64,
    /// Mean d̄, m.
    pub d: f64,
    /// Mean φ, degrees.
    pub phi: f64,
    /// Mean dilated bulk density ρ_s (1 − n1), t/m³.
    pub rho1: f64,
    /// Flowable share f of the perimeter points.
    pub flow_frac: f64,
    /// Flowable share A_f of the disk's area (equal-area rings of perimeter points).
    pub area_frac: f64,
    /// Radius at which these were sampled.
    pub sampled_at: f64,
    /// Radius at which the dilation state (which perimeter points lie inside another IMZ)
    /// was last sampled.
    pub dilation_at: f64,
    /// The shape of the ring's dilation around the perimeter: Fourier coefficients
    /// (α_k, β_k), k = 1 … [`SHAPE_MODES`], of w(θ) − 1, w the point's porosity jump over
    /// the mean over the flowable points (0 where already dilated, 1 all round in uniform
    /// ground). The marker pass reads it (`engine::markers::lateral`).
    pub shape: [f64; 2 * SHAPE_MODES],
    /// The variance of w − 1 over the perimeter's samples (mean square: its mean is 0)
    /// beyond the modes kept in `shape`, which the lateral move leaves out
    /// (`engine::markers::caps`); under 10⁻¹² (rounding) it is 0.
    pub shape_rest: f64,
    /// The variance of w − 1 over the perimeter's samples, all of it.
    pub shape_var: f64,
}

impl Stagnant {
    /// Porosity jump n1 − n0.
    pub fn jump(&self) -> f64 {
        self.n1 - self.n0
    }
}

impl Ground<'_> {
    /// Whether the ground at a point is flowable.
    pub fn flowable(&self, p: [f64; 3]) -> bool {
        self.flowable_block(p).is_some()
    }

    /// The block at a point, if there is one and it is flowable.
    #[inline]
    pub fn flowable_block(&self, p: [f64; 3]) -> Option<usize> {
        self.blocks
            .locate(p)
            .filter(|&b| self.blocks.flowable(b, self.period))
    }

    /// Reach of the flowable ground at level `z` from the axis (x, y): the largest distance
    /// from the axis to a point of a flowable block in that layer (0 if there is none). A
    /// disk wider than this covers every flowable point of its level, so it never grows
    /// past it: ground outside the model or not yet caved cannot be mobilised.
    pub fn reach(&self, x: f64, y: f64, z: f64) -> f64 {
        let bm = self.blocks;
        let Some([_, _, k]) = bm.cell([
            bm.origin[0] + 0.5 * bm.size[0],
            bm.origin[1] + 0.5 * bm.size[1],
            z,
        ]) else {
            return 0.0;
        };
        let mut far2: f64 = 0.0;
        for j in 0..bm.dims[1] {
            for i in 0..bm.dims[0] {
                let b = bm.index[i + bm.dims[0] * (j + bm.dims[1] * k)];
                if b == crate::model::block_model::NO_BLOCK || !bm.flowable(b as usize, self.period)
                {
                    continue;
                }
                let x0 = bm.origin[0] + i as f64 * bm.size[0];
                let y0 = bm.origin[1] + j as f64 * bm.size[1];
                let dx = (x - x0).abs().max((x - x0 - bm.size[0]).abs());
                let dy = (y - y0).abs().max((y - y0 - bm.size[1]).abs());
                far2 = far2.max(dx * dx + dy * dy);
            }
        }
        far2.sqrt()
    }

    /// Flowable share A_f of the area of a disk of radius `radius` at level `z`: the share
    /// of flowable points on four equal-area rings (radii R √((k + ½)/4)) of 24 points. A
    /// point beyond the model's walls counts as its mirror image inside (`BlockModel::mirror`):
    /// the marker pass moves ground across a wall by the IMZ's image, so a wall does not
    /// make the void fill a smaller area (uncaved ground does).
    pub fn area_fraction(&self, x: f64, y: f64, z: f64, radius: f64) -> f64 {
        let mut n = 0usize;
        for ring in 0..AREA_RINGS {
            let a = radius * ((ring as f64 + 0.5) / AREA_RINGS as f64).sqrt();
            for k in 0..PERIMETER_POINTS {
                let (c, si) = UNIT_CIRCLE[2 * k + ring];
                n += usize::from(self.flowable(self.blocks.mirror([x + a * c, y + a * si, z])));
            }
        }
        n as f64 / (AREA_RINGS * PERIMETER_POINTS) as f64
    }

    /// Stagnant properties of a disk of IMZ `me` at radius `radius` and mid-height `z`:
    /// the mean of 24 equally spaced perimeter points, and their dilation state
    /// ([`Ground::dilation`]).
    pub fn stagnant(&self, me: usize, [x, y, z]: [f64; 3], radius: f64, p: &ImzParams) -> Stagnant {
        let mut s = Stagnant {
            sampled_at: radius,
            ..Default::default()
        };
        let bm = self.blocks;
        let mut n = 0usize;
        for k in 0..PERIMETER_POINTS {
            let (c, si) = UNIT_CIRCLE[2 * k];
            let p = [x + radius * c, y + radius * si, z];
            let Some(b) = self.flowable_block(p) else {
                continue;
            };
            s.n1 += bm.n1[b];
            s.d += bm.frag[b];
            s.phi += bm.friction[b];
            s.rho1 += bm.density[b] * (1.0 - bm.n1[b]);
            n += 1;
        }
        if n > 0 {
            let k = n as f64;
            s.n1 /= k;
            s.d /= k;
            s.phi /= k;
            s.rho1 /= k;
        }
        s.flow_frac = n as f64 / PERIMETER_POINTS as f64;
        s.area_frac = self.area_fraction(x, y, z, radius);
        self.dilation(me, [x, y, z], radius, p, &mut s);
        s
    }

    /// Samples which perimeter points of a disk of IMZ `me` at radius `radius` lie inside
    /// another IMZ (already dilated: the jump there is 0) and sets the mean current
    /// porosity `n0` and the ring's dilation `shape` from it, keeping the block properties
    /// sampled before. Only the IMZ's own radius and its neighbours' growth change this, so
    /// it is resampled more often than the block properties.
    ///
    /// A point whose block's own jump n1 − n0 is below `p.min_jump` (`flow.min_porosity_jump`)
    /// counts as dilated too, so the mean is 0 exactly when no sampled point is stagnant
    /// ground: only then does the disk widen at no cost (`Imz::usable_jump`).
    pub fn dilation(
        &self,
        me: usize,
        [x, y, z]: [f64; 3],
        radius: f64,
        p: &ImzParams,
        s: &mut Stagnant,
    ) {
        let (spacing, min_jump) = (p.perimeter_spacing, p.min_jump);
        // Points at most `spacing` apart (so that a stagnant gap between a neighbour's
        // dilated ground and the next is seen once it is that wide), each with the jump of
        // its own block. Borrowing the jump of the nearest of the 24 block samples instead
        // counted points beyond a wall or the model's edge as stagnant ground wherever the
        // nearest sample lay inside: a ring that met the wall paid for ground that is not
        // there (on the demo, 0.988 of the schedule in markers at the median drawpoint with
        // it, 1.004 without, both spread alike).
        let n_pts = ((2.0 * PI * radius / spacing).ceil() as usize)
            .clamp(PERIMETER_POINTS, MAX_DILATION_POINTS);
        // Per mode m: Σ j cos mθ, Σ j sin mθ over the flowable points (j their jump now),
        // and Σ cos mθ, Σ sin mθ over the same points, so that the shape of w − 1 =
        // j / mean − 1 comes out of one pass.
        let (mut sum, mut sum2, mut n) = (0.0, 0.0, 0usize);
        let mut sj = [0.0; 2 * SHAPE_MODES];
        let mut s1 = [0.0; 2 * SHAPE_MODES];
        let (dc, ds) = (
            (2.0 * PI / n_pts as f64).cos(),
            (2.0 * PI / n_pts as f64).sin(),
        );
        let (mut c, mut si) = (1.0, 0.0);
        let bm = self.blocks;
        let mut last: Option<u32> = None;
        for _ in 0..n_pts {
            let (ck, sk) = (c, si);
            (c, si) = (c * dc - si * ds, c * ds + si * dc);
            let p = [x + radius * ck, y + radius * sk, z];
            let Some(b) = self.flowable_block(p) else {
                continue;
            };
            let pj = bm.n1[b] - bm.n0[b];
            // The IMZ that held the previous point is tried first: along the perimeter
            // one neighbour's IMZ usually holds a run of points. The same answer, sooner:
            // `contains` is the geometry's own test, and the grid lists every IMZ that can
            // hold the point, so `last` holding it means the scan below would find one.
            let holds = |e: u32| e as usize != me && self.geoms[e as usize].contains(p);
            let dilated = pj < min_jump
                || last.is_some_and(holds)
                || match self
                    .grid
                    .holding(p[0], p[1], p[2])
                    .find(|&e| Some(e) != last && holds(e))
                {
                    Some(e) => {
                        last = Some(e);
                        true
                    }
                    None => false,
                };
            let j = if dilated { 0.0 } else { pj };
            sum += j;
            sum2 += j * j;
            n += 1;
            let (mut cm, mut sm) = (ck, sk);
            for m in 0..SHAPE_MODES {
                sj[2 * m] += j * cm;
                sj[2 * m + 1] += j * sm;
                s1[2 * m] += cm;
                s1[2 * m + 1] += sm;
                (cm, sm) = (cm * ck - sm * sk, cm * sk + sm * ck);
            }
        }
        s.dilation_at = radius;
        s.shape = [0.0; 2 * SHAPE_MODES];
        (s.shape_rest, s.shape_var) = (0.0, 0.0);
        if n == 0 {
            s.n0 = s.n1;
            return;
        }
        let mean = sum / n as f64;
        s.n0 = s.n1 - mean;
        if mean > 1e-9 {
            let scale = 2.0 / n_pts as f64;
            for (a, (j, one)) in s.shape.iter_mut().zip(sj.iter().zip(&s1)) {
                *a = scale * (j / mean - one);
            }
            // w − 1 is j / mean − 1 at the flowable points and 0 elsewhere, of mean 0 over
            // the n_pts samples; its mean square is Σ j² / mean² − n over n_pts, and the
            // kept modes hold ½ Σ (α_k² + β_k²) of it (Parseval over the samples, k <
            // n_pts / 2).
            let var = ((sum2 / (mean * mean) - n as f64) / n_pts as f64).max(0.0);
            let kept = 0.5 * s.shape.iter().map(|c| c * c).sum::<f64>();
            let rest = var - kept;
            s.shape_var = var;
            s.shape_rest = if rest > 1e-12 { rest } else { 0.0 };
        }
    }
}
