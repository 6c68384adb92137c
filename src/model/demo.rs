//! The demo scene: a SYNTHETIC Henderson-style panel.
//!
//! Henderson Mine's own block model and production data are not public. This scene is made
//! up; only its broad facts follow what is published (summary §8):
//!
//! - a molybdenum porphyry, grades in % Mo (column `mo`);
//! - a 7700-level panel (extraction level at 2347 m, i.e. 7700 ft) under the exhausted 8100
//!   level about 120 m above. The 8100 level's broken low-grade and waste material
//!   (lithology `8100_broken`, about 0.05 % Mo) sits on top of the ore column;
//! - Urad porphyry (`urad`, d̄ 0.23 m) in the west and north, Primos porphyry (`primos`,
//!   d̄ 0.04 m) in the east, and a `contact` zone at 0.13 m between them;
//! - a southeast boundary area beyond the limit of the level above: there is no 8100 broken
//!   material over the SE corner, and the top of its ore column caves late, so the engine's
//!   rilling can bring high grades in from the north (summary §8);
//! - blocks 15.2 m high.
//!
//! Everything is drawn from one seeded [`ChaCha8Rng`], so a seed gives the same scene on every
//! machine. Generation is cheap: the mine scale (400+ drawpoints, 3650 daily periods) takes
//! well under a second.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::block_model::BlockModel;
use super::layout::{Drawpoints, Periods, Schedule};
use super::scenario::{Dilution, Scenario};
use super::Scene;

/// How big a demo to make.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DemoScale {
    /// One panel of 32 drawpoints (about 106 m × 99 m), blocks 7.6 × 7.6 × 15.2 m, a 167 m
    /// column (121.6 m of ore, 45.6 m of 8100 broken material), 24 monthly periods from
    /// `Jan-09`. Small enough to ship in `data/` and run in seconds.
    Small,
    /// A mine-scale panel for benchmarks: 416 drawpoints, blocks 15.2 m on every axis, a
    /// 212.8 m column (121.6 m of ore, 91.2 m of broken material), 3650 daily periods
    /// (ten years; period names are day numbers).
    Mine,
}

/// Extraction (7700) level elevation, m: 7700 ft. Drawpoints and the base of the block
/// model sit here.
pub const EXTRACTION_LEVEL_Z: f64 = 2347.0;
/// Block height, m (50 ft).
pub const BLOCK_HEIGHT: f64 = 15.2;
/// Spacing of the (east–west) extraction drifts, m (80 ft).
pub const DRIFT_SPACING: f64 = 24.4;
/// Spacing of drawpoints along a drift, m (40 ft).
pub const DRAWPOINT_SPACING: f64 = 12.2;
/// Drawpoint opening width, m.
pub const OPENING_WIDTH: f64 = 4.0;

/// Ore layers between the 7700 and the 8100 level: 8 × 15.2 = 121.6 m (400 ft = 121.9 m).
const ORE_LAYERS: usize = 8;
/// Ore layers at the top of the SE column that cave late.
const SE_LATE_LAYERS: usize = 2;
/// Distance of a drawpoint from its drift's centre line (alternating sides), m.
const SIDE_OFFSET: f64 = 6.1;
/// South-west corner of the panel (mine coordinates), m.
const ORIGIN: [f64; 2] = [10_000.0, 5_000.0];
/// Γ(1 + 1/1.5): the Weibull mean is scale × this for shape 1.5.
const GAMMA_5_3: f64 = 0.902_745_292_950_933_6;
/// Weibull shape of the primary fragmentation.
const FRAG_SHAPE: f64 = 1.5;
/// Grade of the 8100 broken material, % Mo.
const BROKEN_GRADE: f64 = 0.05;

/// The lithologies: name, mean fragment size d̄ (m), solids density (t/m³), UCS range (kPa).
/// The 8100 broken material's d̄ is an assumption: rock already comminuted by the draw of
/// the level above, finer than the Urad it mostly came from.
const LITHS: [(&str, f64, f64, [f64; 2]); 4] = [
    ("urad", 0.23, 2.60, [100_000.0, 130_000.0]),
    ("contact", 0.13, 2.61, [110_000.0, 140_000.0]),
    ("primos", 0.04, 2.63, [120_000.0, 150_000.0]),
    ("8100_broken", 0.10, 2.58, [100_000.0, 120_000.0]),
];
const URAD: u16 = 0;
const CONTACT: u16 = 1;
const PRIMOS: u16 = 2;
const BROKEN: u16 = 3;

/// Sizes of one scale.
struct Layout {
    /// Horizontal block size, m.
    block_xy: f64,
    /// Extraction drifts.
    drifts: usize,
    /// Drawpoints per drift.
    per_drift: usize,
    /// Layers of 8100 broken material over the ore.
    broken_layers: usize,
}

impl DemoScale {
    fn layout(self) -> Layout {
        match self {
            DemoScale::Small => Layout {
                block_xy: 7.6,
                drifts: 4,
                per_drift: 8,
                broken_layers: 3,
            },
            DemoScale::Mine => Layout {
                block_xy: 15.2,
                drifts: 16,
                per_drift: 26,
                broken_layers: 6,
            },
        }
    }
}

/// A smooth random field in [0, 1]: three plane waves of random direction, wavelength
/// (60–200 m) and phase.
struct Field([(f64, [f64; 3], f64); 3]);

impl Field {
    fn new(rng: &mut ChaCha8Rng) -> Field {
        Field(std::array::from_fn(|_| {
            let k = std::f64::consts::TAU / rng.random_range(60.0..200.0);
            let azimuth = rng.random_range(0.0..std::f64::consts::TAU);
            let dip = rng.random_range(-0.5..0.5f64);
            let dir = [
                azimuth.cos() * dip.cos(),
                azimuth.sin() * dip.cos(),
                dip.sin(),
            ]
            .map(|c| c * k);
            (
                rng.random_range(0.5..1.0),
                dir,
                rng.random_range(0.0..std::f64::consts::TAU),
            )
        }))
    }

    fn at(&self, p: [f64; 3]) -> f64 {
        let total: f64 = self.0.iter().map(|w| w.0).sum();
        let sum: f64 = self
            .0
            .iter()
            .map(|(a, k, phase)| a * (k[0] * p[0] + k[1] * p[1] + k[2] * p[2] + phase).cos())
            .sum();
        0.5 * (sum / total + 1.0)
    }
}

/// Whether a point at panel fractions (u east, v north) lies in the southeast boundary area,
/// beyond the limit of the 8100 level.
fn southeast(u: f64, v: f64) -> bool {
    u - v > 0.45
}

/// The synthetic Henderson-style panel at `scale`, deterministic from `seed`.
///
/// Layout: east–west extraction drifts [`DRIFT_SPACING`] apart with drawpoints every
/// [`DRAWPOINT_SPACING`] along them, on alternating sides of the drift and shifted by half a
/// spacing on every other drift (an offset herringbone). Drawpoints are named
/// `D<drift>-<n>`, drifts numbered from the south and drawpoints from the west; their `zone`
/// is the lithology they sit in.
///
/// Schedule: the panel advances west to east, so drawpoints start in sequence by easting
/// (over the first 10 months, or 8 years at mine scale), ramp up over 3 months (90 days),
/// then draw steadily at a per-drawpoint rate of 3200–5200 t a month (±10 % per period;
/// ±20 % per day at mine scale), until they have drawn 90 % of their column's in-situ
/// tonnes. Every block is caved before the first period except the late top of the SE
/// column, which caves a third of the way through the schedule.
pub fn henderson(scale: DemoScale, seed: u64) -> Scene {
    let lay = scale.layout();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let grade_field = Field::new(&mut rng);
    let contact_field = Field::new(&mut rng);

    let periods = match scale {
        DemoScale::Small => monthly(2009, 1, 24),
        DemoScale::Mine => Periods {
            id: (1..=3650).collect(),
            name: (1..=3650).map(|d: i64| d.to_string()).collect(),
            days: vec![1.0; 3650],
            start: None,
        },
    };
    let late_period = periods.id[periods.len() / 3];

    // Drawpoints (before the blocks: the panel extent follows from them).
    let mut dp = Drawpoints::default();
    for j in 0..lay.drifts {
        let drift_y = ORIGIN[1] + 0.5 * DRIFT_SPACING + j as f64 * DRIFT_SPACING;
        let shift = if j % 2 == 1 {
            0.5 * DRAWPOINT_SPACING
        } else {
            0.0
        };
        for i in 0..lay.per_drift {
            let side = if i % 2 == 0 {
                SIDE_OFFSET
            } else {
                -SIDE_OFFSET
            };
            dp.name.push(format!("D{:02}-{:02}", j + 1, i + 1));
            dp.x.push(ORIGIN[0] + 0.5 * DRAWPOINT_SPACING + i as f64 * DRAWPOINT_SPACING + shift);
            dp.y.push(drift_y + side);
            dp.z.push(EXTRACTION_LEVEL_Z);
            dp.width.push(OPENING_WIDTH);
        }
    }
    let b = lay.block_xy;
    let nx = ((dp.x.iter().cloned().fold(0.0, f64::max) - ORIGIN[0] + 0.5 * DRAWPOINT_SPACING) / b)
        .ceil() as usize;
    let ny = (lay.drifts as f64 * DRIFT_SPACING / b).ceil() as usize;
    let (width, depth) = (nx as f64 * b, ny as f64 * b);
    let nz = ORE_LAYERS + lay.broken_layers;

    // Blocks, bottom layer first, then south to north, west to east.
    let mut bm = BlockModel {
        size: [b, b, BLOCK_HEIGHT],
        ..BlockModel::default()
    };
    let mut lith_code = Vec::new();
    let mut mo_col = Vec::new();
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let p = [
                    ORIGIN[0] + (i as f64 + 0.5) * b,
                    ORIGIN[1] + (j as f64 + 0.5) * b,
                    EXTRACTION_LEVEL_Z + (k as f64 + 0.5) * BLOCK_HEIGHT,
                ];
                let (u, v) = ((p[0] - ORIGIN[0]) / width, (p[1] - ORIGIN[1]) / depth);
                let w = (k as f64 + 0.5) / ORE_LAYERS as f64;
                let se = southeast(u, v);
                if se && k >= ORE_LAYERS {
                    continue; // beyond the limit of the 8100 level: nothing broken above
                }
                let (lith, mo) = if k >= ORE_LAYERS {
                    (BROKEN, BROKEN_GRADE + rng.random_range(-0.015..0.015))
                } else {
                    // Urad to the west and north, Primos to the east; the contact dips
                    // gently east and wanders with a smooth field.
                    let c = (u - 0.55) - 0.25 * (v - 0.5)
                        + 0.08 * (w - 0.5)
                        + 0.1 * (contact_field.at(p) - 0.5);
                    let lith = if c < -0.07 {
                        URAD
                    } else if c > 0.07 {
                        PRIMOS
                    } else {
                        CONTACT
                    };
                    // 0.20–0.35 % Mo, higher to the north, smooth, with a little block noise.
                    let s = 0.6 * v + 0.4 * grade_field.at(p) + rng.random_range(-0.03..0.03);
                    (lith, 0.20 + 0.15 * s.clamp(0.0, 1.0))
                };
                let (_, dbar, density, ucs) = LITHS[lith as usize];
                let ucs = rng.random_range(ucs[0]..ucs[1]);
                bm.x.push(p[0]);
                bm.y.push(p[1]);
                bm.z.push(p[2]);
                bm.id.push(bm.id.len() as i64 + 1);
                bm.cave_period
                    .push(if se && k >= ORE_LAYERS - SE_LATE_LAYERS {
                        late_period
                    } else {
                        0
                    });
                bm.density.push(density + rng.random_range(-0.02..0.02));
                bm.n0.push(0.30 + rng.random_range(-0.01..0.01));
                bm.n1.push(0.45 + rng.random_range(-0.01..0.01));
                bm.friction.push(rng.random_range(38.0..42.0));
                bm.frag.push(dbar);
                bm.frag_shape.push(FRAG_SHAPE);
                bm.frag_scale.push(dbar / GAMMA_5_3);
                bm.tensile.push(0.1 * ucs);
                bm.ucs.push(ucs);
                bm.perc_k1.push(11.0);
                bm.perc_k2.push(4.5);
                bm.perc_vmr.push(0.5);
                lith_code.push(lith);
                mo_col.push(mo);
            }
        }
    }
    set_lithologies(&mut bm, &lith_code);
    bm.grade_names = vec!["mo".to_string()];
    bm.grades = vec![mo_col];
    let problems = bm.build_index();
    debug_assert!(problems.is_empty(), "demo grid is irregular: {problems:?}");

    for d in 0..dp.len() {
        let at = bm
            .locate([dp.x[d], dp.y[d], dp.z[d] + 0.5 * BLOCK_HEIGHT])
            .expect("drawpoint over the panel");
        dp.zone
            .push(bm.lithology_names[bm.lithology[at] as usize].clone());
    }

    let schedule = schedule(
        scale,
        &dp,
        &periods,
        width,
        depth,
        lay.broken_layers,
        &mut rng,
    );
    Scene {
        blocks: bm,
        drawpoints: dp,
        periods,
        schedule,
        target: None,
    }
}

/// Sets the lithology columns from demo codes, naming them in order of first appearance as
/// a reader of the written table would.
fn set_lithologies(bm: &mut BlockModel, codes: &[u16]) {
    let mut remap = [u16::MAX; LITHS.len()];
    for &c in codes {
        if remap[c as usize] == u16::MAX {
            remap[c as usize] = bm.lithology_names.len() as u16;
            bm.lithology_names.push(LITHS[c as usize].0.to_string());
        }
    }
    bm.lithology = codes.iter().map(|&c| remap[c as usize]).collect();
}

/// `count` monthly periods from `year`-`month`, named like `Jan-09`, with their days.
fn monthly(year: i32, month: usize, count: usize) -> Periods {
    const NAMES: [&str; 12] = [
        "Jan", "Feb", "Mar", "Apr", "May", "Jun", "Jul", "Aug", "Sep", "Oct", "Nov", "Dec",
    ];
    const DAYS: [u32; 12] = [31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31];
    let mut p = Periods::default();
    for n in 0..count {
        let m = (month - 1 + n) % 12;
        let y = year + ((month - 1 + n) / 12) as i32;
        let leap = y % 4 == 0 && (y % 100 != 0 || y % 400 == 0);
        p.id.push(n as i64 + 1);
        p.name.push(format!("{}-{:02}", NAMES[m], y % 100));
        p.days.push(f64::from(DAYS[m] + u32::from(m == 1 && leap)));
    }
    p
}

/// The draw schedule: west-to-east start, ramp-up, steady draw with noise, stop at 90 % of
/// the column's in-situ tonnes.
fn schedule(
    scale: DemoScale,
    dp: &Drawpoints,
    periods: &Periods,
    width: f64,
    depth: f64,
    broken_layers: usize,
    rng: &mut ChaCha8Rng,
) -> Schedule {
    // (start spread, ramp length, noise) in periods.
    let (advance, ramp, noise) = match scale {
        DemoScale::Small => (10.0, 3.0, 0.10),
        DemoScale::Mine => (2900.0, 90.0, 0.20),
    };
    // In-situ tonnes per m of column height over one drawpoint's share of the panel
    // (nominal density 2.6 t/m³, n0 0.30).
    let tonnes_per_m = DRIFT_SPACING * DRAWPOINT_SPACING * 2.6 * 0.7;
    let n = dp.len();
    let mut tonnes = vec![0.0; periods.len() * n];
    for d in 0..n {
        let (u, v) = ((dp.x[d] - ORIGIN[0]) / width, (dp.y[d] - ORIGIN[1]) / depth);
        let start = (u * advance) as usize;
        let rate_per_day = rng.random_range(3200.0..5200.0) / 30.44;
        let layers = if southeast(u, v) {
            ORE_LAYERS
        } else {
            ORE_LAYERS + broken_layers
        };
        let mut left = (0.9 * tonnes_per_m * layers as f64 * BLOCK_HEIGHT).round();
        for p in start..periods.len() {
            let ramp_factor = ((p - start + 1) as f64 / ramp).min(1.0);
            let t = (rate_per_day
                * periods.days[p]
                * ramp_factor
                * (1.0 + rng.random_range(-noise..noise)))
            .round()
            .min(left);
            tonnes[p * n + d] = t;
            left -= t;
            if left <= 0.0 {
                break;
            }
        }
    }
    Schedule {
        n_drawpoints: n,
        tonnes,
    }
}

/// The scenario that goes with the demo: `mo` decides ore, material under 0.1 % Mo or from
/// the 8100 level is waste for the dilution share. At mine scale IMZ geometry is kept for
/// the last period only (every day for 400 drawpoints would dwarf the other outputs).
pub fn scenario(scale: DemoScale, seed: u64) -> Scenario {
    let mut sc = Scenario {
        seed,
        dilution: Dilution {
            grade: Some("mo".to_string()),
            cutoff: 0.1,
            waste_lithologies: vec![LITHS[BROKEN as usize].0.to_string()],
        },
        ..Scenario::default()
    };
    sc.outputs.imz_every_period = scale == DemoScale::Small;
    sc
}
