//! The block model table: its columns typed and checked, its defaults filled in and its
//! grid inferred.
//!
//! # Block model
//! - Every centre coordinate lies within 10⁹ m of the origin (`coordinate-range`).
//! - Block size per axis: the smallest positive spacing between distinct centre values.
//!   An axis with a single centre value (a one-block-thick model) takes the smallest size
//!   of the other axes. Every centre must sit a whole number of blocks from the lowest
//!   (`mixed-block-size` names the first that does not; `off-grid` names the rows).
//! - Defaults: `cave_period` 0; `perc_k1` 11, `perc_k2` 4.5 (summary §7.3), `perc_vmr`
//!   0.5 m (MassFlow's default; the summary's spread uses the bed's fragment size d_b).
//! - `cave_period` = `cave_period_dyn` (MassFlow CavePeriodDyn) where given, else
//!   `cave_period`; a warning counts the blocks where the two differ.
//! - `frag` = `frag_size` (MassFlow MeanDia) where the Weibull parameters are absent, else
//!   their mean `frag_scale · Γ(1 + 1/frag_shape)` (the engine draws primary sizes from
//!   them). A `frag_size` given with them is kept when it lies within
//!   [`FRAG_MEAN_TOLERANCE`] (10 %) of their mean; beyond it the Weibull mean is used, and
//!   one warning names the first such row and the count.
//! - `tensile` = `tensile_strength`, else the Weibull mean of `tensile_shape`/`tensile_scale`,
//!   else 0.1 × `ucs` (MassFlow's ratio), else NaN.
//! - Lithologies are numbered in order of first appearance (one lithology `default` when the
//!   column is absent). Every extra numeric column is a grade, in % by mass.

use std::collections::HashMap;

use super::Loader;
use crate::io::{InputWarning, Table};
use crate::model::block_model::MAX_FRAG_SIZE;
use crate::model::BlockModel;

/// Default percolation coefficient k1 (summary §7.3).
pub const DEFAULT_PERC_K1: f64 = 11.0;
/// Default percolation coefficient k2 (summary §7.3).
pub const DEFAULT_PERC_K2: f64 = 4.5;
/// Default percolation variance-to-mean ratio.
pub const DEFAULT_PERC_VMR: f64 = 0.5;
/// Tensile strength as a share of UCS when neither it nor its Weibull parameters are given
/// (MassFlow's default ratio).
pub const TENSILE_UCS_RATIO: f64 = 0.1;
/// Relative difference between a given mean fragment size (MassFlow MeanDia) and the mean
/// of the block's Weibull parameters beyond which the loader warns: 10 %, well above the
/// rounding of a size written to two or three figures, well below a size from another
/// fragmentation estimate.
pub const FRAG_MEAN_TOLERANCE: f64 = 0.1;
/// Largest block grid (cells) accepted. A grid this size already takes 1 GiB of index; a
/// larger one almost always means a stray coordinate.
pub const MAX_GRID_CELLS: usize = 1 << 28;

/// Friction angles below this many degrees are taken for radians (`units-radians`): π/2
/// rounded up. No caved rock has a friction angle under 1.6°, and every angle in radians
/// that a rock can have (20°–60° is 0.35–1.05 rad) lies below it.
pub const RADIANS_BELOW: f64 = 1.6;

/// Largest block-centre coordinate accepted, m. Mine grids (UTM northings included) stay
/// below 10⁷ m, and the Earth's circumference is 4 × 10⁷ m. Beyond 10⁹ m the block-size
/// inference's relative tolerance (10⁻⁹ of the largest coordinate) would pass a metre and
/// merge distinct blocks, so such a coordinate is reported as what it is.
pub const MAX_COORDINATE: f64 = 1e9;

/// Tonnes of solids in a block model: Σ block volume × ρ_s × (1 − n0). None when some
/// block's density or porosity broke a rule (already reported), so that the total is never
/// a guess.
pub(super) fn in_situ_tonnes(m: &BlockModel) -> Option<f64> {
    let v: f64 = m.size.iter().product();
    let ok =
        |b: usize| (m.density[b] > 0.0 && m.density[b] <= 20.0) && (0.0..1.0).contains(&m.n0[b]);
    (0..m.len())
        .map(|b| ok(b).then(|| v * m.density[b] * (1.0 - m.n0[b])))
        .sum::<Option<f64>>()
        .filter(|t| t.is_finite())
}

/// Whether `v` is a valid porosity (NaN: missing, already reported); otherwise the rule and
/// message.
fn porosity_problem(what: &str, v: f64) -> Option<(&'static str, String)> {
    if v.is_nan() || (0.0..1.0).contains(&v) {
        None
    } else if (2.0..=100.0).contains(&v) {
        // Values in (1, 2) would be porosities under 2 % as percentages, which caved rock
        // never has: they are reported as plainly out of range.
        Some((
            "units-percent",
            format!(
                "{what} {v} is outside [0, 1): it looks like a percentage; divide by 100 ({})",
                v / 100.0
            ),
        ))
    } else {
        Some(("porosity-range", format!("{what} {v} is outside [0, 1)")))
    }
}

/// Γ(x) for x ≥ 0.5 by the Lanczos approximation (g = 7, n = 9; relative error ~1e-15).
fn gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    let x = x - 1.0;
    let t = x + G + 0.5;
    let a = C
        .iter()
        .enumerate()
        .skip(1)
        .fold(C[0], |a, (i, c)| a + c / (x + i as f64));
    (2.0 * std::f64::consts::PI).sqrt() * t.powf(x + 0.5) * (-t).exp() * a
}

/// Mean of a Weibull distribution with shape α and scale β: β Γ(1 + 1/α).
fn weibull_mean(shape: f64, scale: f64) -> f64 {
    scale * gamma(1.0 + 1.0 / shape)
}

/// The block size along one axis: the smallest positive spacing of distinct centre
/// values. `Ok(None)` when the axis has a single value; `Err((a, b, size))` when centre `b`
/// is not a whole number of blocks from the lowest centre `a`.
fn axis_size(values: &[f64]) -> Result<Option<f64>, (f64, f64, f64)> {
    let mut v: Vec<f64> = values.to_vec();
    v.sort_by(f64::total_cmp);
    let (Some(&lo), Some(&hi)) = (v.first(), v.last()) else {
        return Ok(None);
    };
    let tol = 1e-9 * lo.abs().max(hi.abs()).max(1.0);
    v.dedup_by(|b, a| (*b - *a).abs() <= tol);
    let size = v
        .windows(2)
        .map(|w| w[1] - w[0])
        .fold(f64::INFINITY, f64::min);
    if !size.is_finite() {
        return Ok(None);
    }
    for &c in &v {
        let k = (c - lo) / size;
        if (k - k.round()).abs() > 1e-3 {
            return Err((lo, c, size));
        }
    }
    // The whole span over the block count is far more precise than one difference of
    // large mine coordinates; snap it to a micrometre when it is that close to one, so
    // 7.6 m blocks read as 7.6, not 7.599999999998545.
    let n = ((hi - lo) / size).round();
    let refined = (hi - lo) / n;
    let snapped = (refined * 1e6).round() / 1e6;
    Ok(Some(if (snapped - refined).abs() <= 1e-6 * refined {
        snapped
    } else {
        refined
    }))
}

impl Loader {
    /// The block model; None when no grid can be built (the other checks still run).
    pub(super) fn block_model(&mut self, t: &Table) -> Option<BlockModel> {
        let file = t.file.as_str();
        let n = t.len();
        let req = |name: &str| t.f64(name).filter(|v| v.len() == n);
        let (Some(x), Some(y), Some(z), Some(density), Some(n0), Some(n1), Some(phi), Some(ids)) = (
            req("x"),
            req("y"),
            req("z"),
            req("solids_density"),
            req("porosity"),
            req("max_porosity"),
            req("friction_angle"),
            t.i64("block_id").filter(|v| v.len() == n),
        ) else {
            return None;
        };
        let opt = |name: &str| t.f64(name).filter(|v| v.len() == n);
        let at = |i: usize| Some(t.row(i));
        let mut m = BlockModel {
            x: x.to_vec(),
            y: y.to_vec(),
            z: z.to_vec(),
            ..BlockModel::default()
        };

        let mut first_row: HashMap<i64, usize> = HashMap::with_capacity(n);
        for (i, id) in ids.iter().enumerate() {
            let Some(id) = *id else {
                m.id.push(0); // reported by the reader
                continue;
            };
            if let Some(&j) = first_row.get(&id) {
                self.problem(
                    file,
                    at(i),
                    Some(t.header("block_id")),
                    "duplicate-id",
                    format!("block_id {id} is already used at row {}", t.row(j)),
                );
            } else {
                first_row.insert(id, i);
            }
            m.id.push(id);
        }
        m.cave_period = match t.i64("cave_period") {
            Some(c) => c.iter().map(|c| c.unwrap_or(0)).collect(),
            None => vec![0; n],
        };
        // MassFlow's CavePeriodDyn starts as CavePeriod; where the two differ, the dynamic
        // value is the one MassFlow uses.
        if let Some(dynamic) = t.i64("cave_period_dyn").filter(|v| v.len() == n) {
            let mut differ = 0;
            for (c, d) in m.cave_period.iter_mut().zip(dynamic) {
                if let Some(d) = *d {
                    differ += usize::from(*c != d);
                    *c = d;
                }
            }
            if differ > 0 {
                self.warnings.push(InputWarning::new(
                    file,
                    "cave-period-dyn",
                    format!(
                        "{} differs from {} in {differ} block(s); the dynamic cave period is used",
                        t.header("cave_period_dyn"),
                        t.header("cave_period")
                    ),
                ));
            }
        }

        let (hd, h0, h1, hphi) = (
            t.header("solids_density"),
            t.header("porosity"),
            t.header("max_porosity"),
            t.header("friction_angle"),
        );
        for i in 0..n {
            let d = density[i];
            if d <= 0.0 {
                self.problem(
                    file,
                    at(i),
                    Some(hd),
                    "not-positive",
                    format!("solids density {d} t/m³ must be positive"),
                );
            } else if d > 20.0 {
                self.problem(file, at(i), Some(hd), "units-kg-m3", format!("solids density {d} t/m³ is not plausible: it looks like kg/m³; divide by 1000 ({} t/m³)", d / 1000.0));
            }
            let p0 = porosity_problem("porosity", n0[i]);
            let p1 = porosity_problem("max_porosity", n1[i]);
            let ok = p0.is_none() && p1.is_none();
            for (p, h) in [(p0, h0), (p1, h1)] {
                if let Some((rule, msg)) = p {
                    self.problem(file, at(i), Some(h), rule, msg);
                }
            }
            if ok && n1[i] < n0[i] {
                self.problem(file, at(i), Some(h1), "n1-below-n0", format!("max_porosity {} is below porosity {} (the dilated porosity n1 must be at least n0)", n1[i], n0[i]));
            }
            if phi[i] > 0.0 && phi[i] < RADIANS_BELOW {
                self.problem(
                    file,
                    at(i),
                    Some(hphi),
                    "units-radians",
                    format!(
                        "friction angle {}° is not plausible for caved rock: it looks like radians ({} rad = {:.1}°); give degrees",
                        phi[i],
                        phi[i],
                        phi[i].to_degrees()
                    ),
                );
            } else if phi[i] <= 0.0 || phi[i] >= 90.0 {
                self.problem(
                    file,
                    at(i),
                    Some(hphi),
                    "friction-range",
                    format!("friction angle {}° is outside (0, 90)", phi[i]),
                );
            }
        }
        m.density = density.to_vec();
        m.n0 = n0.to_vec();
        m.n1 = n1.to_vec();
        m.friction = phi.to_vec();

        // Positive-where-given columns.
        for name in [
            "frag_size",
            "frag_shape",
            "frag_scale",
            "tensile_strength",
            "tensile_shape",
            "tensile_scale",
            "ucs",
        ] {
            if let Some(v) = opt(name) {
                for (i, &x) in v.iter().enumerate() {
                    if x <= 0.0 {
                        self.problem(
                            file,
                            at(i),
                            Some(t.header(name)),
                            "not-positive",
                            format!("{name} {x} must be positive"),
                        );
                    }
                }
            }
        }
        let nan = vec![f64::NAN; n];
        let col = |name: &str| opt(name).unwrap_or(&nan);
        let (size, shape, scale) = (col("frag_size"), col("frag_shape"), col("frag_scale"));
        if !(t.has("frag_size") || (t.has("frag_shape") && t.has("frag_scale"))) {
            self.problem(file, None, Some("frag_size"), "missing-column", "the block model needs frag_size, or frag_shape and frag_scale (MassFlow PriFragA and PriFragB)".into());
        } else {
            // (first row, count, given, Weibull mean) of rows whose mean size disagrees with
            // their Weibull mean by more than FRAG_MEAN_TOLERANCE.
            let mut disagree: Option<(usize, usize, f64, f64)> = None;
            for i in 0..n {
                let weibull = !shape[i].is_nan() && !scale[i].is_nan();
                let f = if weibull {
                    // As in MassFlow, the Weibull parameters decide where given (the engine
                    // draws primary sizes from them); a mean size given with them is kept
                    // when it agrees with their mean (it is that mean, as written).
                    let mean = weibull_mean(shape[i], scale[i]);
                    let d = size[i];
                    let valid = shape[i] > 0.0 && scale[i] > 0.0 && mean.is_finite();
                    if !valid || d.is_nan() {
                        mean
                    } else if (d - mean).abs() > FRAG_MEAN_TOLERANCE * mean {
                        let e = disagree.get_or_insert((i, 0, d, mean));
                        e.1 += 1;
                        mean
                    } else {
                        d
                    }
                } else if !size[i].is_nan() {
                    size[i]
                } else if ["frag_size", "frag_shape", "frag_scale"]
                    .iter()
                    .any(|c| t.bad(c, i))
                {
                    f64::NAN // reported by the reader
                } else {
                    let h = t.header(if t.has("frag_size") {
                        "frag_size"
                    } else {
                        "frag_shape"
                    });
                    self.problem(
                        file,
                        at(i),
                        Some(h),
                        "missing-value",
                        "no fragment size: give frag_size, or both frag_shape and frag_scale"
                            .into(),
                    );
                    f64::NAN
                };
                if weibull && shape[i] > 0.0 && scale[i] > 0.0 && !f.is_finite() {
                    self.problem(
                        file,
                        at(i),
                        Some(t.header("frag_shape")),
                        "not-finite",
                        format!(
                            "the Weibull mean fragment size overflows for shape {}",
                            shape[i]
                        ),
                    );
                }
                if f.is_finite() && f > MAX_FRAG_SIZE {
                    let h = t.header(if weibull { "frag_scale" } else { "frag_size" });
                    self.problem(file, at(i), Some(h), "units-mm", format!(
                        "mean fragment size {f} m is not plausible (more than {MAX_FRAG_SIZE} m): it looks like mm; divide by 1000 ({} m)",
                        f / 1000.0
                    ));
                }
                m.frag.push(f);
            }
            if let Some((i, count, d, mean)) = disagree {
                self.warnings.push(InputWarning::new(file, "frag-mean", format!(
                    "{} disagrees with the Weibull mean of {}/{} by more than {:.0}% in {count} block(s), the first at row {} ({d} m against {mean:.4} m); the Weibull parameters are used",
                    t.header("frag_size"),
                    t.header("frag_shape"),
                    t.header("frag_scale"),
                    100.0 * FRAG_MEAN_TOLERANCE,
                    t.row(i)
                )));
            }
        }
        m.frag_shape = shape.to_vec();
        m.frag_scale = scale.to_vec();
        let (ts, tsh, tsc, ucs) = (
            col("tensile_strength"),
            col("tensile_shape"),
            col("tensile_scale"),
            col("ucs"),
        );
        m.tensile = (0..n)
            .map(|i| {
                if !ts[i].is_nan() {
                    ts[i]
                } else if !tsh[i].is_nan() && !tsc[i].is_nan() {
                    weibull_mean(tsh[i], tsc[i])
                } else {
                    TENSILE_UCS_RATIO * ucs[i]
                }
            })
            .collect();
        m.ucs = ucs.to_vec();
        let mut perc = |name: &str, default: f64| -> Vec<f64> {
            let v: Vec<f64> = col(name)
                .iter()
                .map(|&x| if x.is_nan() { default } else { x })
                .collect();
            for (i, &x) in v.iter().enumerate() {
                if x < 0.0 {
                    self.problem(
                        file,
                        at(i),
                        Some(t.header(name)),
                        "negative",
                        format!("{name} {x} must not be negative"),
                    );
                }
            }
            v
        };
        m.perc_k1 = perc("perc_k1", DEFAULT_PERC_K1);
        m.perc_k2 = perc("perc_k2", DEFAULT_PERC_K2);
        m.perc_vmr = perc("perc_vmr", DEFAULT_PERC_VMR);

        match t.str("lithology") {
            Some(lith) => {
                let mut code: HashMap<&str, u16> = HashMap::new();
                for (i, name) in lith.iter().enumerate() {
                    if name.is_empty() {
                        if !t.bad("lithology", i) {
                            self.problem(
                                file,
                                at(i),
                                Some(t.header("lithology")),
                                "missing-value",
                                "the lithology is empty".into(),
                            );
                        }
                        m.lithology.push(0);
                        continue;
                    }
                    let next = code.len();
                    let c = match code.get(name.as_str()) {
                        Some(&c) => c,
                        None => match u16::try_from(next) {
                            Ok(c) => {
                                code.insert(name.as_str(), c);
                                m.lithology_names.push(name.clone());
                                c
                            }
                            Err(_) => {
                                self.problem(
                                    file,
                                    at(i),
                                    Some(t.header("lithology")),
                                    "too-many-lithologies",
                                    format!(
                                        "more than {} distinct lithologies",
                                        u16::MAX as usize + 1
                                    ),
                                );
                                0
                            }
                        },
                    };
                    m.lithology.push(c);
                }
            }
            None => {
                m.lithology = vec![0; n];
                m.lithology_names = vec!["default".into()];
            }
        }

        for g in &t.extra {
            for (i, &v) in g.values.iter().enumerate() {
                if v.is_nan() && !t.bad(&g.name, i) {
                    self.problem(
                        file,
                        at(i),
                        Some(&g.name),
                        "missing-value",
                        format!("grade {} is empty", g.name),
                    );
                } else if v < 0.0 {
                    self.problem(
                        file,
                        at(i),
                        Some(&g.name),
                        "negative",
                        format!("grade {} {v} % must not be negative", g.name),
                    );
                }
            }
            m.grade_names.push(g.name.clone());
            m.grades.push(g.values.clone());
        }

        self.grid(t, &mut m).then_some(m)
    }

    /// Infers the block size and builds the grid index; false when no grid can be made.
    fn grid(&mut self, t: &Table, m: &mut BlockModel) -> bool {
        let file = t.file.as_str();
        let axes = ["x", "y", "z"];
        if [&m.x, &m.y, &m.z]
            .iter()
            .any(|v| v.iter().any(|c| c.is_nan()))
        {
            return false; // a centre the reader could not read: no grid to check against
        }
        let mut far = false;
        for (a, values) in [&m.x, &m.y, &m.z].into_iter().enumerate() {
            for (i, &c) in values.iter().enumerate() {
                if c.abs() > MAX_COORDINATE {
                    far = true;
                    self.problem(file, Some(t.row(i)), Some(t.header(axes[a])), "coordinate-range", format!(
                        "{} = {c:e} m is farther than {MAX_COORDINATE:e} m from the origin: no mine coordinate is (look for a stray value or a unit mistake)",
                        axes[a]
                    ));
                }
            }
        }
        if far {
            return false;
        }
        let mut size = [None; 3];
        for (a, values) in [&m.x, &m.y, &m.z].into_iter().enumerate() {
            match axis_size(values) {
                Ok(s) => size[a] = s,
                Err((lo, c, s)) => {
                    self.problem(file, None, Some(t.header(axes[a])), "mixed-block-size", format!(
                        "{} centres {lo} and {c} are {} m apart, not a whole number of {s} m blocks (the smallest spacing of distinct centres): blocks must all be one size per axis; regularise a sub-blocked model first",
                        axes[a], c - lo
                    ));
                    size[a] = Some(s);
                }
            }
        }
        let Some(fallback) = size.iter().flatten().copied().reduce(f64::min) else {
            self.problem(
                file,
                None,
                None,
                "block-size",
                "cannot infer the block size: every block has the same centre".into(),
            );
            return false;
        };
        for a in 0..3 {
            if size[a].is_none() {
                self.warnings.push(InputWarning::new(file, "block-size-fallback", format!("all blocks share one {} centre; the block size along {} is taken as {fallback} m", axes[a], axes[a])));
            }
            m.size[a] = size[a].unwrap_or(fallback);
        }
        let mut span = [0.0f64; 3];
        let mut range = [(0.0, 0.0); 3];
        for (a, values) in [&m.x, &m.y, &m.z].into_iter().enumerate() {
            let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            span[a] = ((hi - lo) / m.size[a]).round() + 1.0;
            range[a] = (lo, hi);
        }
        if span.iter().product::<f64>() > MAX_GRID_CELLS as f64 {
            let a = (0..3).fold(0, |best, a| if span[a] > span[best] { a } else { best });
            let (lo, hi) = range[a];
            self.problem(file, None, Some(t.header(axes[a])), "grid-too-large", format!(
                "the block grid would have {:.3e} cells, more than {MAX_GRID_CELLS} ({} spans {lo} to {hi} in {} m blocks): look for a stray coordinate",
                span.iter().product::<f64>(), axes[a], m.size[a]
            ));
            return false;
        }
        for (b, reason) in m.build_index() {
            // build_index words its reasons "block centre x=… is off the … grid" and
            // "… occupies the same cell as row …".
            let row = Some(t.row(b));
            if reason.contains("same cell") {
                self.problem(file, row, None, "duplicate-cell", reason);
            } else {
                let axis = axes
                    .iter()
                    .find(|a| reason.starts_with(&format!("block centre {a}=")))
                    .copied()
                    .unwrap_or("x");
                self.problem(file, row, Some(t.header(axis)), "off-grid", reason);
            }
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gamma_matches_known_values() {
        assert!((gamma(1.0) - 1.0).abs() < 1e-13);
        assert!((gamma(5.0) - 24.0).abs() < 1e-11);
        assert!((gamma(1.5) - std::f64::consts::PI.sqrt() / 2.0).abs() < 1e-13);
        assert!((gamma(0.5) - std::f64::consts::PI.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn weibull_mean_of_shape_one_is_the_scale() {
        // Shape 1 is the exponential distribution, whose mean is the scale.
        assert!((weibull_mean(1.0, 0.2) - 0.2).abs() < 1e-14);
        // Shape 2: β √π / 2.
        assert!((weibull_mean(2.0, 1.0) - std::f64::consts::PI.sqrt() / 2.0).abs() < 1e-13);
    }

    #[test]
    fn axis_size_finds_spacing_and_mixed_sizes() {
        assert_eq!(axis_size(&[5.0, 15.0, 10.0, 5.0, 30.0]), Ok(Some(5.0)));
        assert_eq!(axis_size(&[7.0, 7.0]), Ok(None));
        assert_eq!(axis_size(&[0.0, 5.0, 12.5]), Err((0.0, 12.5, 5.0)));
        assert_eq!(axis_size(&[]), Ok(None));
    }

    #[test]
    fn porosity_rules() {
        assert_eq!(porosity_problem("porosity", 0.4), None);
        assert_eq!(
            porosity_problem("porosity", 1.3).map(|p| p.0),
            Some("porosity-range")
        );
        assert_eq!(
            porosity_problem("porosity", 45.0).map(|p| p.0),
            Some("units-percent")
        );
        assert_eq!(
            porosity_problem("porosity", -0.1).map(|p| p.0),
            Some("porosity-range")
        );
        assert_eq!(
            porosity_problem("porosity", 1.0).map(|p| p.0),
            Some("porosity-range")
        );
    }
}
