//! Where REBOP's method holds, where it degrades, and where it fails.
//!
//! REBOP (summary §3.3) is an empirical rule, calibrated and checked over a range of
//! conditions; outside that range it still produces numbers. The summary itself names its
//! weak spots: IMZ widths are over-predicted at small ratios of fragment size to drawpoint
//! width, and hang-up is not modelled (§3.4); the near field (IMZ heights below 100–200 d̄,
//! §3.1) is represented less well than the far field (§9). caveflow classifies every run
//! before it starts, per drawpoint, on five dimensionless numbers, and says so rather than
//! silently producing numbers:
//!
//! - **valid**: inside the range the method was checked against;
//! - **degraded**: the run goes ahead, with a warning in the run log and the manifest;
//! - **refused**: the run stops with an error ([`EngineError::Refused`](super::EngineError)),
//!   unless `flow.enforce_stability = false`, which runs it with the refusal as a warning
//!   (for studies of the method itself, such as the sweep that measured these regions).
//!
//! | quantity | refused | degraded | valid | degraded | refused |
//! |---|---|---|---|---|---|
//! | d̄/w (fragment / opening width) | — | < 0.01 | 0.01–0.2 | 0.2–0.5 | ≥ 0.5 |
//! | n1 − n0 (porosity jump) | < `flow.min_porosity_jump` (0.005) | < 0.02 | 0.02–0.35 | > 0.35 | — |
//! | h/d̄ (disk thickness / fragment) | < 0.1 | < 1 | 1–200 | > 200 | — |
//! | increment / opening disk | — | — | ≤ 4 | 4–30 | > 30, or > 10⁸ steps |
//! | φ (friction angle) | < 20° | 20°–30° | 30°–50° | 50°–60° | > 60° |
//!
//! The resolution itself is degraded where the marker spacing is over half the opening
//! width (`marker-to-opening`, at [`MARKER_TO_OPENING_HIGH`]). Two more refusals concern
//! the resolution alone: a marker spacing wider than the smallest block dimension
//! (`marker-spacing`: blocks between lattice sites carry no marker, so their tonnes vanish;
//! found by the sweep below, where it halved the credited tonnes), and a schedule that
//! needs more than 10⁸ draw steps (`increment`).
//!
//! Each threshold's reason is at its constant below. The sweep that charts these regions
//! and checks them against tiny isolated-draw runs is `tests/it/stability.rs`; its chart is
//! in `docs::physics`.
//!
//! The numbers are read per drawpoint from the block just above its opening (the material
//! whose near field the rules are about), with the drawpoint's own opening width; the
//! worst drawpoint of each rule is named in the message, with the count of the others.

use crate::engine::ResolvedResolution;
use crate::model::{Scenario, Scene};

/// Below this d̄/w the IMZ is over-predicted in width (summary §3.4). The smallest ratio
/// the summary shows REBOP matching is Henderson's Primos porphyry: d̄ 0.04 m through
/// 4 m drawpoints (§8), d̄/w = 0.01.
pub const FRAG_TO_WIDTH_LOW: f64 = 0.01;
/// Above this d̄/w the opening is less than five mean fragments wide, where hang-ups
/// become likely (the usual free-flow rule of thumb); REBOP has no hang-up logic (§3.4
/// leaves it to further work), so it predicts flow that may not happen.
pub const FRAG_TO_WIDTH_HIGH: f64 = 0.2;
/// At or above this d̄/w the opening is less than two fragments wide: two fragments arch
/// across it and nothing flows. REBOP would still pass void up; refused.
pub const FRAG_TO_WIDTH_REFUSED: f64 = 0.5;
/// Below this porosity jump the IMZ grows wide through dilation of very little void
/// (R² grows as 1/(n1 − n0)): at 0.02 the IMZ is √5 ≈ 2.2 times as wide as at Castro's
/// 0.1, and dilated ground from a neighbour is indistinguishable from fresh ground.
/// Caved rock has n0 ≈ 0.3–0.4 and n1 ≈ 0.45–0.55 (DESIGN §2), jumps of 0.05–0.25.
pub const JUMP_LOW: f64 = 0.02;
/// Above this jump n0 is below 0.2 for any n1 up to 0.55: intact or barely broken rock,
/// the cave back rather than caved rock, which REBOP's flow rules do not describe.
pub const JUMP_HIGH: f64 = 0.35;
/// Below this h/d̄ a disk is thinner than one fragment: the r-law's 10 d̄ h / (π R²)
/// averages over a disk that holds no whole fragment, outside what REBOP was checked
/// against. The draw itself hardly moves (`tests/it/stability.rs`, 18 kg of Castro
/// isolated draw): against h = 3 d̄, the drawn material's mean origin is 0.9% low at
/// h = d̄ (1.4% at 6 d̄), 2.3% at 0.6 d̄ and 1.1% at 0.3 d̄.
pub const LAYER_TO_FRAG_LOW: f64 = 1.0;
/// Below this h/d̄ a disk is a tenth of a fragment (markers a twentieth): refused, as far
/// below the r-law's scale as the method is taken (not run: the cost grows as 1/h).
pub const LAYER_TO_FRAG_REFUSED: f64 = 0.1;
/// Above this h/d̄ the first disk is taller than the whole near field (100–200 d̄,
/// summary §3.1), whose ellipsoidal shape is then not resolved at all.
pub const LAYER_TO_FRAG_HIGH: f64 = 200.0;
/// Above this many opening disks per marker update, the axial marker of a cone profile
/// moves about 3 disks per opening disk drawn (`engine::resolution`), so more than 12
/// disks between updates, each crossing transferred in turn (§3.3), while the IMZ grows
/// within the update and the markers move by its end state. Measured
/// (`tests/it/stability.rs`, 50 kg of Castro isolated draw): against 0.3 disks per update,
/// the mean origin elevation of the drawn material is unchanged at 1 disk, 0.9% low at 4,
/// 2.6% low at 15.
pub const INCREMENT_HIGH: f64 = 4.0;
/// Above this many opening disks per update the drawn material comes from 4.3% (40 disks)
/// to 6.6% (120 disks) lower than it should, with 5–6% fewer markers drawn than the
/// schedule needs (made up by the correction): more than the model's own grade noise at
/// the default resolution. Refused.
pub const INCREMENT_REFUSED: f64 = 30.0;
/// More draw steps than this over the run: a hang, not a result (the increment is far
/// below what the resolution needs). Refused.
pub const MAX_STEPS: f64 = 1e8;
/// Above this marker spacing over the opening width an opening disk holds fewer than
/// about two markers across, and drawpoints run short of markers late in their draw: on
/// the mine scene (`caveflow demo --scale mine`, 4 m openings) the markers of the
/// drawpoints never short, over the last 5% of their tonnes, weigh a median 0.948 of the
/// schedule at 3.4 m markers (0.85 of the opening) against 0.964 at 1.65 m (0.41), and
/// small draws at markers over about a third of the opening end short
/// (`tests/it/props.rs`). The demo's default, 1.9 m markers in 4 m openings (0.475), draws
/// its schedule in markers at a median of 0.994.
pub const MARKER_TO_OPENING_HIGH: f64 = 0.5;
/// The friction angles of caved rock are 35–50° (DESIGN §2); REBOP's checks (Castro's
/// gravel, Henderson) lie within 30–50°.
pub const FRICTION_VALID: (f64, f64) = (30.0, 50.0);
/// Outside 20–60° the base-angle limit 45 + φ/2 (55°–75°) leaves the range of granular
/// rock: refused.
pub const FRICTION_REFUSED: (f64, f64) = (20.0, 60.0);

/// The dimensionless numbers of one drawpoint that the rules look at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Conditions {
    /// Mean fragment size over opening width, d̄/w.
    pub frag_to_width: f64,
    /// Porosity jump n1 − n0.
    pub porosity_jump: f64,
    /// Disk thickness over mean fragment size, h/d̄.
    pub layer_to_frag: f64,
    /// Tonnes drawn per step (the draw increment, or less where a period draws less; see
    /// [`step_tonnes`]) over the tonnes of one opening disk, π (w/2)² h ρ_s (1 − n1).
    pub increment_to_disk: f64,
    /// Friction angle φ, degrees.
    pub friction: f64,
}

/// A region of validity.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Validity {
    /// Inside the checked range.
    Valid,
    /// Runs, with a warning.
    Degraded,
    /// Does not run.
    Refused,
}

/// One rule's verdict.
#[derive(Debug, Clone, PartialEq)]
pub struct Finding {
    /// Stable rule id: `frag-to-width`, `porosity-jump`, `layer-to-frag`, `increment`,
    /// `friction`.
    pub rule: &'static str,
    /// The verdict.
    pub validity: Validity,
    /// Why, with the summary's reason (empty when valid).
    pub reason: String,
}

/// The worst verdict of a list (valid when empty).
pub fn worst(findings: &[Finding]) -> Validity {
    findings
        .iter()
        .map(|f| f.validity)
        .max()
        .unwrap_or(Validity::Valid)
}

/// Classifies one set of conditions, one finding per rule, in the order of the module
/// table. `min_jump` is `flow.min_porosity_jump`.
pub fn classify(c: &Conditions, min_jump: f64) -> Vec<Finding> {
    use Validity::*;
    let f = |rule, validity, reason: String| Finding {
        rule,
        validity,
        reason,
    };
    let dw = c.frag_to_width;
    // A relative tolerance on the boundaries, so that Henderson's Primos (0.04 / 4.0) reads
    // as the 0.01 it is.
    let below = |x: f64, t: f64| x < t * (1.0 - 1e-9);
    let above = |x: f64, t: f64| x > t * (1.0 + 1e-9);
    let frag = if !below(dw, FRAG_TO_WIDTH_REFUSED) {
        f("frag-to-width", Refused, format!(
            "d̄/w = {dw:.3}: the opening is less than two mean fragments wide, so fragments arch across it; REBOP has no hang-up logic (summary §3.4)"
        ))
    } else if above(dw, FRAG_TO_WIDTH_HIGH) {
        f("frag-to-width", Degraded, format!(
            "d̄/w = {dw:.3} > {FRAG_TO_WIDTH_HIGH}: the opening is under five fragments wide, hang-ups are likely and REBOP does not model them (summary §3.4)"
        ))
    } else if below(dw, FRAG_TO_WIDTH_LOW) {
        f("frag-to-width", Degraded, format!(
            "d̄/w = {dw:.4} < {FRAG_TO_WIDTH_LOW}: REBOP over-predicts IMZ widths at small fragment-to-drawpoint-width ratios (summary §3.4)"
        ))
    } else {
        f("frag-to-width", Valid, String::new())
    };
    let j = c.porosity_jump;
    let jump = if below(j, min_jump) {
        f("porosity-jump", Refused, format!(
            "n1 − n0 = {j:.4} < flow.min_porosity_jump = {min_jump}: the ground at the drawpoint is already dilated, and the r-law's radius update divides by the jump (summary §3.3), so nothing but the model walls bounds the IMZ"
        ))
    } else if below(j, JUMP_LOW) {
        f("porosity-jump", Degraded, format!(
            "n1 − n0 = {j:.4} < {JUMP_LOW}: the IMZ widens as 1/√(n1 − n0) (summary §3.3) and is very wide; check n0 and n1"
        ))
    } else if above(j, JUMP_HIGH) {
        f(
            "porosity-jump",
            Degraded,
            format!("n1 − n0 = {j:.3} > {JUMP_HIGH}: n0 this low is intact rock, not caved rock"),
        )
    } else {
        f("porosity-jump", Valid, String::new())
    };
    let hd = c.layer_to_frag;
    let layer = if below(hd, LAYER_TO_FRAG_REFUSED) {
        f("layer-to-frag", Refused, format!(
            "h/d̄ = {hd:.3} < {LAYER_TO_FRAG_REFUSED}: disks a tenth of a fragment thick; raise resolution.layer_thickness"
        ))
    } else if below(hd, LAYER_TO_FRAG_LOW) {
        f("layer-to-frag", Degraded, format!(
            "h/d̄ = {hd:.3} < {LAYER_TO_FRAG_LOW}: disks thinner than one fragment, below the scale of the r-law (summary §3.3)"
        ))
    } else if above(hd, LAYER_TO_FRAG_HIGH) {
        f("layer-to-frag", Degraded, format!(
            "h/d̄ = {hd:.0} > {LAYER_TO_FRAG_HIGH}: the first disk is taller than the near field (100–200 d̄, summary §3.1), which is not resolved; lower resolution.layer_thickness"
        ))
    } else {
        f("layer-to-frag", Valid, String::new())
    };
    let inc = c.increment_to_disk;
    let increment = if above(inc, INCREMENT_REFUSED) {
        f("increment", Refused, format!(
            "the draw increment is {inc:.0} opening disks (> {INCREMENT_REFUSED}): markers jump many disks between updates (summary §3.3), half the markers needed are drawn and the drawn material comes from 15–25% too low; lower resolution.draw_increment"
        ))
    } else if above(inc, INCREMENT_HIGH) {
        f("increment", Degraded, format!(
            "the draw increment is {inc:.1} opening disks (> {INCREMENT_HIGH}): markers skip disks between updates (summary §3.3), and the drawn material comes from a few % too low; lower resolution.draw_increment"
        ))
    } else {
        f("increment", Valid, String::new())
    };
    let phi = c.friction;
    let (lo, hi) = FRICTION_VALID;
    let (rlo, rhi) = FRICTION_REFUSED;
    let friction = if below(phi, rlo) || above(phi, rhi) {
        f("friction", Refused, format!(
            "φ = {phi}° is outside {rlo}°–{rhi}°: the base angle 45 + φ/2 (summary §3.1) is outside the range of granular rock"
        ))
    } else if below(phi, lo) || above(phi, hi) {
        f("friction", Degraded, format!(
            "φ = {phi}° is outside {lo}°–{hi}°, the friction angles REBOP was checked at (summary §3.4, §8)"
        ))
    } else {
        f("friction", Valid, String::new())
    };
    vec![frag, jump, layer, increment, friction]
}

/// The conditions of every drawpoint of a scene at a resolution (None for a drawpoint whose
/// opening lies outside the block model, which the engine reports itself).
pub fn scene_conditions(scene: &Scene, res: &ResolvedResolution) -> Vec<Option<Conditions>> {
    let bm = &scene.blocks;
    let dp = &scene.drawpoints;
    let h = res.layer_thickness;
    let step = step_tonnes(scene, res);
    (0..dp.len())
        .map(|d| {
            let b = bm.locate([dp.x[d], dp.y[d], dp.z[d] + 0.5 * h])?;
            let w = dp.width[d];
            let disk = std::f64::consts::PI * 0.25 * w * w * h * bm.density[b] * (1.0 - bm.n1[b]);
            Some(Conditions {
                frag_to_width: bm.frag[b] / w,
                porosity_jump: bm.n1[b] - bm.n0[b],
                layer_to_frag: h / bm.frag[b],
                increment_to_disk: step / disk,
                friction: bm.friction[b],
            })
        })
        .collect()
}

/// The largest tonnes one drawpoint draws in one step: the increment, or less where a
/// period's largest cell is smaller (`Engine::run_period` splits each period into
/// ⌈largest cell / increment⌉ equal steps).
pub fn step_tonnes(scene: &Scene, res: &ResolvedResolution) -> f64 {
    (0..scene.periods.len())
        .map(|p| {
            let max_t = scene.schedule.period(p).iter().cloned().fold(0.0, f64::max);
            max_t / (max_t / res.draw_increment).ceil().max(1.0)
        })
        .fold(0.0, f64::max)
}

/// Draw steps the run will take: per period, the largest scheduled cell over the increment,
/// rounded up (as `Engine::run_period` does).
pub fn steps(scene: &Scene, res: &ResolvedResolution) -> f64 {
    (0..scene.periods.len())
        .map(|p| {
            let max_t = scene.schedule.period(p).iter().cloned().fold(0.0, f64::max);
            (max_t / res.draw_increment).ceil()
        })
        .sum()
}

/// Checks a scene before it runs: the degraded findings as warnings (worst drawpoint of
/// each rule named, with the count of the others), or every refusal as one error message.
pub fn assess(
    scene: &Scene,
    sc: &Scenario,
    res: &ResolvedResolution,
) -> Result<Vec<String>, String> {
    let conditions = scene_conditions(scene, res);
    // Per rule: (verdict, count of drawpoints, reason of the first drawpoint at that verdict).
    let mut by_rule: Vec<(&'static str, Validity, usize, String)> = Vec::new();
    for (d, c) in conditions.iter().enumerate() {
        let Some(c) = c else { continue };
        for f in classify(c, sc.flow.min_porosity_jump) {
            if f.validity == Validity::Valid {
                continue;
            }
            let named = format!("drawpoint {}: {}", scene.drawpoints.name[d], f.reason);
            match by_rule.iter_mut().find(|r| r.0 == f.rule) {
                Some(r) if f.validity > r.1 => *r = (f.rule, f.validity, 1, named),
                Some(r) if f.validity == r.1 => r.2 += 1,
                Some(_) => {}
                None => by_rule.push((f.rule, f.validity, 1, named)),
            }
        }
    }
    let block = scene
        .blocks
        .size
        .iter()
        .cloned()
        .fold(f64::INFINITY, f64::min);
    if res.marker_spacing > block * (1.0 + 1e-9) {
        by_rule.push((
            "marker-spacing",
            Validity::Refused,
            1,
            format!(
                "marker spacing {} m is wider than the smallest block dimension {block} m: blocks between lattice sites carry no marker, and their tonnes vanish from the draw; lower resolution.marker_spacing",
                res.marker_spacing
            ),
        ));
    }
    let dp = &scene.drawpoints;
    let coarse: Vec<usize> = (0..dp.len())
        .filter(|&d| res.marker_spacing > MARKER_TO_OPENING_HIGH * dp.width[d] * (1.0 + 1e-9))
        .collect();
    let narrowest = coarse
        .iter()
        .min_by(|&&a, &&b| dp.width[a].total_cmp(&dp.width[b]));
    if let Some(&d) = narrowest {
        let (s, w) = (res.marker_spacing, dp.width[d]);
        by_rule.push((
            "marker-to-opening",
            Validity::Degraded,
            coarse.len(),
            format!(
                "drawpoint {}: marker spacing {s:.3} m is {:.2} of its {w} m opening (> {MARKER_TO_OPENING_HIGH}): the opening disk holds too few markers across, and drawpoints run short of markers late in their draw (the tonnes are credited, the grades come from fewer markers); lower resolution.marker_spacing",
                dp.name[d],
                s / w
            ),
        ));
    }
    let steps = steps(scene, res);
    if steps > MAX_STEPS {
        by_rule.push((
            "increment",
            Validity::Refused,
            1,
            format!(
                "the schedule needs {steps:.2e} draw steps of {} t (more than {MAX_STEPS:.0e}): raise resolution.draw_increment",
                res.draw_increment
            ),
        ));
    }
    let say = |(rule, v, n, reason): &(&str, Validity, usize, String)| {
        let more = if *n > 1 {
            format!(" (and {} more drawpoint(s))", n - 1)
        } else {
            String::new()
        };
        let what = if *v == Validity::Refused {
            "refused"
        } else {
            "degraded"
        };
        format!("stability [{rule}] {what}: {reason}{more}")
    };
    let refused: Vec<String> = by_rule
        .iter()
        .filter(|r| r.1 == Validity::Refused)
        .map(say)
        .collect();
    if refused.is_empty() {
        Ok(by_rule.iter().map(say).collect())
    } else if !sc.flow.enforce_stability {
        Ok(by_rule
            .iter()
            .map(|r| match r.1 {
                Validity::Refused => format!(
                    "{} (run anyway: flow.enforce_stability = false; these results are not REBOP's)",
                    say(r)
                ),
                _ => say(r),
            })
            .collect())
    } else {
        Err(format!(
            "{}\n(the scene lies where REBOP's method fails: see \"Where the method holds\" in the crate's docs, caveflow::docs::physics)",
            refused.join("\n")
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn castro() -> Conditions {
        // Castro's isolated draw (summary §3.4): 8.3 mm in a 120 mm opening, h = 25 mm.
        Conditions {
            frag_to_width: 0.0083 / 0.12,
            porosity_jump: 0.1,
            layer_to_frag: 0.025 / 0.0083,
            increment_to_disk: 1.0,
            friction: 40.0,
        }
    }

    #[test]
    fn the_validated_scenes_are_valid() {
        assert_eq!(worst(&classify(&castro(), 0.005)), Validity::Valid);
        // Henderson Primos (summary §8): 0.04 m in 4 m drawpoints, h = 4 m.
        let primos = Conditions {
            frag_to_width: 0.04 / 4.0,
            layer_to_frag: 4.0 / 0.04,
            porosity_jump: 0.15,
            ..castro()
        };
        assert_eq!(worst(&classify(&primos, 0.005)), Validity::Valid);
    }

    /// The baseline with one rule's quantity set to `v`.
    fn with(rule: &str, v: f64) -> Conditions {
        let mut c = castro();
        match rule {
            "frag-to-width" => c.frag_to_width = v,
            "porosity-jump" => c.porosity_jump = v,
            "layer-to-frag" => c.layer_to_frag = v,
            "increment" => c.increment_to_disk = v,
            _ => c.friction = v,
        }
        c
    }

    #[test]
    fn each_rule_degrades_and_refuses_on_its_own() {
        use Validity::{Degraded as D, Refused as R};
        let cases = [
            ("frag-to-width", 0.005, D),
            ("frag-to-width", 0.3, D),
            ("frag-to-width", 0.5, R),
            ("porosity-jump", 0.01, D),
            ("porosity-jump", 0.001, R),
            ("layer-to-frag", 0.5, D),
            ("layer-to-frag", 0.05, R),
            ("layer-to-frag", 500.0, D),
            ("increment", 10.0, D),
            ("increment", 50.0, R),
            ("friction", 25.0, D),
            ("friction", 65.0, R),
        ];
        for (rule, v, want) in cases {
            for f in &classify(&with(rule, v), 0.005) {
                let expect = if f.rule == rule {
                    want
                } else {
                    Validity::Valid
                };
                assert_eq!(f.validity, expect, "{rule} = {v}: {f:?}");
                assert_eq!(f.reason.is_empty(), expect == Validity::Valid, "{f:?}");
            }
        }
    }
}
