//! The fill of a drawpoint's lowest disks: how much of the material it can draw now is
//! there, and why a short period could not deliver.
//!
//! An IMZ's material is at the dilated porosity n1 (`imz`, the volume balance), so a disk
//! full of ground holds markers whose volume at n1, mass / (ρ_s (1 − n1)), adds up to the
//! disk's own, π R² h, up to their discreteness. The void a draw opens at the drawpoint
//! takes the material at its base, so a drawpoint delivers in markers about its schedule
//! times the fill there. Where the column has been drawn out (the free surface, or under
//! uncaved ground the air gap, come down towards the drawpoint) its lowest disks hold
//! less, and what they hold is what it can still draw. The **fill** is the markers' volume
//! at n1 over the disks' volume, over the lowest disks that hold at least the period's
//! schedule and [`FILL_MARKERS`] markers at n1 (the fewest disks from the base up whose
//! volume reaches that). An IMZ whose disks do not yet hold that much has not been drawn
//! long enough to run out, and its fill is not judged (null): a fill over fewer markers is
//! their discreteness (an IMZ of a few tonnes may hold no marker at all).
//!
//! A disk's volume is the share of it where markers can be: inside the model's plan box
//! (a wall cuts it; the marker pass mirrors the flux, but no marker lies beyond) and in
//! flowable ground (its flowable area share A_f, `Stagnant::area_frac`). The markers are
//! read where they are at the end of the period, lagging by at most `max_marker_move`
//! (`engine::cadence`), from the plan cells the disks cover (`markers::Bins`): each cell
//! once for all the drawpoints whose disks cover it, rejecting by height the markers
//! above them. The fill is computed for every drawpoint that drew, at the end of each
//! period (the mine scene's account: 4–5% of the engine's time, `docs::performance`).
//!
//! # Crediting and short reasons
//! A drawpoint whose fill is at least [`EXHAUSTED_FILL`] (or not yet judged) can feed its
//! schedule and is credited it (`crediting`, "Tonnes"); one whose fill is lower is
//! running out, and is credited by its markers. So a period is `short` for one of these:
//! - `uncaved`: the ground above the drawpoint has not caved; nothing is drawn.
//! - `blocked`: the fill is below [`EXHAUSTED_FILL`] and the IMZ is held under uncaved
//!   ground with an air gap above it: its column has drained into the air gap.
//! - `exhausted`: the fill is below [`EXHAUSTED_FILL`] with no air gap: its column is drawn
//!   out (to the free surface, or to what the ground around it feeds).
//!
//! A drawpoint whose markers run behind its credits while its column is full enough is
//! not short: the run's warnings name it with the ratio (`crediting::lagging`).
//!
//! # The volume and the threshold
//! On the mine scene (`caveflow demo --scale mine --out mine`, `caveflow run
//! mine/scenario.toml`, 3.4 m markers) the fill of full columns (days of drawpoints that
//! are never short, past the first tenth and before the half of their draw) is 0.97 on
//! average and scatters by about 0.8/√K over K markers: 0.127 at 40, 0.093 at 80, 0.070
//! at 120. It is below 1 because the base's markers are drawn as soon as they cross it,
//! which leaves the lowest half-spacing half empty. A short period's lowest disks are
//! often emptier than the column above them by chance (the markers that did not come
//! down are the ones missing there: on the mine scene, D05-17's markers lagged by their
//! discreteness over days 1820–1839, at a mean fill of 0.41 over 10 markers and of 1.10
//! over 80), so the fill is
//! read over two trailing windows of the crediting ([`FILL_MARKERS`] = 120 markers), and
//! [`EXHAUSTED_FILL`] = 1 − 3/√120 = 0.726 is three standard deviations of their
//! discreteness below a full column, as the crediting's trailing window is
//! (`crediting::FLOWING_SIGMAS`): 0.06% of the full columns' days are below it. The fills
//! measured by reason are in `docs::outputs`.

use std::f64::consts::PI;

use rayon::prelude::*;

use super::crediting::TRAIL_MARKERS;
use super::imz::Imz;
use super::markers::{Bins, Markers};
use crate::model::BlockModel;

/// Fewest markers' volume at n1 the fill is measured over: the markers of two trailing
/// windows of the crediting (see the module docs).
pub const FILL_MARKERS: f64 = 2.0 * TRAIL_MARKERS;

/// Fill of the lowest disks below which a drawpoint cannot feed its schedule: its column
/// is running out: 1 − 3/√[`FILL_MARKERS`] (= 0.726), three standard deviations of the
/// markers' discreteness.
pub const EXHAUSTED_FILL: f64 = 0.7261387212474169;

/// Fixed-point units of the fill (2⁴⁰ a full disk stack): a marker's share is rounded
/// to 10⁻¹² of the disks' volume, and the sums are exact.
const FILL_UNITS: f64 = 1_099_511_627_776.0;

/// Strips over which the share of a disk inside the model's plan box is integrated.
const STRIPS: usize = 64;

/// What a drawpoint's lowest disks hold: their volume where markers can be, m³, and the
/// volume at n1 of the markers inside them, m³.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Fill {
    /// Σ π R_i² h × (share inside the model) × A_f over the lowest disks, m³.
    pub volume: f64,
    /// Σ mass / (ρ_s (1 − n1)) over the markers inside them, m³ (each rounded to
    /// 2⁻⁴⁰ of `volume`).
    pub markers: f64,
    /// Disks counted, from the base up.
    pub disks: usize,
    /// Whether the disks counted hold the volume asked for (else they are all the IMZ's).
    pub judged: bool,
}

impl Fill {
    /// The fill, markers' volume over the disks', where it is judged (see the module
    /// docs).
    pub fn value(&self) -> Option<f64> {
        (self.judged && self.volume > 0.0).then(|| self.markers / self.volume)
    }
}

/// Why a short period of a drawpoint could not deliver (see the module docs): `caved`
/// whether the ground above it has caved, `fill` its lowest disks' fill at the end of the
/// period, `imz` its IMZ. A drawpoint on caved ground is credited its schedule unless its
/// fill is below [`EXHAUSTED_FILL`] (`crediting`), so a short one's column is running out:
/// into the air gap under uncaved ground (`blocked`), or drawn out (`exhausted`).
pub fn short_reason(caved: bool, fill: &Fill, imz: &Imz) -> &'static str {
    if !caved {
        return "uncaved";
    }
    debug_assert!(fill.value().is_some_and(|f| f < EXHAUSTED_FILL), "{fill:?}");
    if imz.blocked && imz.air > 0.0 {
        "blocked"
    } else {
        "exhausted"
    }
}

/// The lowest disks of `imz` whose volume where markers can be reaches `need` m³ (all the
/// disks if they do not), with each disk's volume; `plan` is the model's plan box
/// ([x0, x1], [y0, y1]).
pub fn lowest_disks(imz: &Imz, need: f64, plan: [[f64; 2]; 2]) -> Vec<f64> {
    let g = &imz.geom;
    let mut out = Vec::new();
    let mut total = 0.0;
    for (i, &r) in g.radius.iter().enumerate() {
        if total >= need {
            break;
        }
        let a_f = imz.stagnant[i].area_frac.max(1.0 / 96.0);
        let v = PI * r * r * g.h * inside_share([g.x, g.y], r, plan) * a_f;
        out.push(v);
        total += v;
    }
    out
}

/// The fills of the lowest disks of the IMZs `which` (index, volume `need` m³ each; see
/// the module docs), in the order of `which`, read from the markers binned in `bins`.
///
/// All at once: each plan cell that some of the lowest disks cover is read once, in
/// parallel, for all of them (neighbouring drawpoints share cells), and its markers above
/// every one of those disks are rejected by their height alone. Each marker's share of
/// the disks' volume is summed in fixed point (`FILL_UNITS`), exactly, so the fill does
/// not depend on the order in which the markers are read.
pub fn fills(
    imzs: &[Imz],
    which: &[(usize, f64)],
    plan: [[f64; 2]; 2],
    mk: &Markers,
    bins: &Bins,
    bm: &BlockModel,
) -> Vec<Fill> {
    // Per IMZ asked for: its lowest disks' volumes, their sum and the top of the last one.
    let lows: Vec<(Vec<f64>, f64, f64)> = which
        .iter()
        .map(|&(d, need)| {
            let v = lowest_disks(&imzs[d], need, plan);
            let g = &imzs[d].geom;
            let top = g.z0 + v.len() as f64 * g.h;
            let volume = v.iter().sum();
            (v, volume, top)
        })
        .collect();
    // (cell, asked-for index) pairs, grouped by cell.
    let mut pairs: Vec<(usize, u32)> = Vec::new();
    let mut cells = Vec::new();
    for (j, &(d, _)) in which.iter().enumerate() {
        let g = &imzs[d].geom;
        let r = g.radius[..lows[j].0.len()]
            .iter()
            .copied()
            .fold(0.0, f64::max);
        cells.clear();
        bins.cells_in([g.x - r, g.x + r], [g.y - r, g.y + r], 0, &mut cells);
        pairs.extend(cells.iter().map(|&c| (c, j as u32)));
    }
    pairs.sort_unstable();
    let groups: Vec<&[(usize, u32)]> = pairs.chunk_by(|a, b| a.0 == b.0).collect();
    // Per group, (asked-for index, fill in FILL_UNITS) of the markers in its cell.
    let parts: Vec<Vec<(u32, i64)>> = groups
        .par_iter()
        .map(|group| {
            let top = group
                .iter()
                .map(|p| lows[p.1 as usize].2)
                .fold(f64::MIN, f64::max);
            let mut sums: Vec<(u32, i64)> = group.iter().map(|p| (p.1, 0)).collect();
            for &row in bins.list(group[0].0) {
                let row = row as usize;
                let z = mk.z[row];
                if z >= top {
                    continue;
                }
                let p = [mk.x[row], mk.y[row], z];
                for (j, sum) in sums.iter_mut() {
                    let (volumes, volume, top) = &lows[*j as usize];
                    if z >= *top {
                        continue;
                    }
                    let g = &imzs[which[*j as usize].0].geom;
                    if g.disk_at(p).is_some_and(|(i, ..)| i < volumes.len()) {
                        let v = mk.volume_at_n1(row, bm);
                        *sum += (v / volume * FILL_UNITS).round() as i64;
                    }
                }
            }
            sums
        })
        .collect();
    let mut units = vec![0i64; which.len()];
    for (j, u) in parts.into_iter().flatten() {
        units[j as usize] += u;
    }
    which
        .iter()
        .zip(&lows)
        .zip(units)
        .map(|((&(_, need), (volumes, volume, _)), u)| Fill {
            volume: *volume,
            markers: u as f64 / FILL_UNITS * volume,
            disks: volumes.len(),
            judged: *volume >= need,
        })
        .collect()
}

/// The share of the disk of radius `r` centred on `c` that lies inside the plan box
/// `plan`: 1 where it does not cross a wall, else integrated over `STRIPS` strips.
pub fn inside_share(c: [f64; 2], r: f64, plan: [[f64; 2]; 2]) -> f64 {
    let [[x0, x1], [y0, y1]] = plan;
    if r <= 0.0 {
        return 1.0;
    }
    if c[0] - r >= x0 && c[0] + r <= x1 && c[1] - r >= y0 && c[1] + r <= y1 {
        return 1.0;
    }
    let dx = 2.0 * r / STRIPS as f64;
    let mut area = 0.0;
    for s in 0..STRIPS {
        let x = c[0] - r + (s as f64 + 0.5) * dx;
        if x < x0 || x > x1 {
            continue;
        }
        let half = (r * r - (x - c[0]).powi(2)).max(0.0).sqrt();
        let len = ((c[1] + half).min(y1) - (c[1] - half).max(y0)).max(0.0);
        area += len * dx;
    }
    // The strips' own circle, so that a disk inside the box gives 1 to rounding.
    let whole: f64 = (0..STRIPS)
        .map(|s| {
            let x = -r + (s as f64 + 0.5) * dx;
            2.0 * (r * r - x * x).max(0.0).sqrt() * dx
        })
        .sum();
    area / whole
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::crediting::FLOWING_SIGMAS;

    #[test]
    fn the_threshold_is_three_sigmas_and_the_schema_says_so() {
        let want = 1.0 - FLOWING_SIGMAS / FILL_MARKERS.sqrt();
        assert!((EXHAUSTED_FILL - want).abs() < 1e-15, "{want}");
        // The extraction table's descriptions quote both.
        let field = |name: &str| {
            crate::schema::EXTRACTION
                .fields
                .iter()
                .find(|f| f.name == name)
                .unwrap()
                .description
        };
        let t = format!("{EXHAUSTED_FILL:.3}");
        assert!(field("short_reason").contains(&t));
        assert!(field("fill").contains(&t));
        assert!(field("fill").contains(&format!("{FILL_MARKERS} markers")));
    }

    #[test]
    fn a_wall_through_the_centre_halves_the_disk() {
        let plan = [[0.0, 100.0], [0.0, 100.0]];
        assert_eq!(inside_share([50.0, 50.0], 5.0, plan), 1.0);
        assert!((inside_share([0.0, 50.0], 5.0, plan) - 0.5).abs() < 1e-12);
        // A corner: a quarter.
        assert!((inside_share([0.0, 0.0], 5.0, plan) - 0.25).abs() < 1e-12);
        // A wall at half the radius: the segment beyond it is (π/3 − √3/4) r² of π r².
        let beyond = (PI / 3.0 - 3f64.sqrt() / 4.0) / PI;
        let got = inside_share([2.5, 50.0], 5.0, plan);
        assert!((got - (1.0 - beyond)).abs() < 2e-3, "{got}");
    }
}
