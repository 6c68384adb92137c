//! Integration tests: the intersection of the IMZ and the surface cone in the near and far
//! field (summary §3.1). Castro material (d̄ = 8.3 mm, φ = 40°) in uniform boxes
//! at one resolution, an isolated drawpoint drawing under a free surface with rilling on.
//! Each test prints what it measured (`-- --nocapture`); with `CAVEFLOW_DOCS=dir` the two
//! sections are copied there (`tests/figures/surface_cone_{near,far}_field.png`).

use std::path::Path;

use caveflow::engine::imz::r_law;
use caveflow::engine::{Engine, RunOutput};
use caveflow::model::{Scenario, Scene};
use caveflow::output::charts::{drawdown_section, surface_at};

use crate::fixtures::{cone_column as column, cone_scenario as scenario};

/// Lattice spacing s, m (h = 2 s).
const S: f64 = 0.0125;

/// One period's measurement.
#[derive(Debug, Clone, Copy)]
struct Row {
    /// Cumulative tonnes drawn.
    drawn: f64,
    /// Whether the IMZ had reached the surface.
    through: bool,
    /// Crater rim radius: outer edge of the outermost ring (width s about the axis) whose
    /// mean surface drop exceeds s / 2, m.
    rim: f64,
    /// IMZ radius at the surface: the radius of the widest disk that lies at least partly
    /// below the surface over its own perimeter (where the IMZ limit meets the cone), m.
    r_meet: f64,
    /// Crater depth at the axis, m.
    depth: f64,
}

/// Azimuthal mean of f over rings of width s about the axis: (ring outer radius, mean).
fn rings(pts: &[(f64, f64)], n: usize) -> Vec<(f64, f64)> {
    let mut sum = vec![(0.0, 0usize); n];
    for &(a, v) in pts {
        let k = (a / S) as usize;
        if k < n {
            sum[k].0 += v;
            sum[k].1 += 1;
        }
    }
    sum.iter()
        .enumerate()
        .filter(|(_, s)| s.1 > 0)
        .map(|(k, s)| ((k + 1) as f64 * S, s.0 / s.1 as f64))
        .collect()
}

fn measure(scene: &Scene, sc: &Scenario, top: f64) -> (Vec<Row>, RunOutput) {
    let out = Engine::new(scene, sc).unwrap().run(&mut |_, _| {});
    let tonnes = scene.schedule.tonnes[0];
    let mut rows = Vec::new();
    for &p in &scene.periods.id {
        let sf = &out.surface;
        let pts: Vec<(f64, f64)> = (0..sf.z.len())
            .filter(|&k| sf.period[k] == p)
            .map(|k| (sf.x[k].hypot(sf.y[k]), top - sf.z[k]))
            .collect();
        let prof = rings(&pts, 200);
        let rim = prof
            .iter()
            .filter(|r| r.1 > 0.5 * S)
            .map(|r| r.0)
            .fold(0.0, f64::max);
        let depth = prof.first().map_or(0.0, |r| r.1);
        // Surface height at radius a (ring mean).
        let surf = |a: f64| {
            let k = ((a / S) as usize).min(prof.len() - 1);
            top - prof[k].1
        };
        let t = &out.imz;
        let disks: Vec<(f64, f64)> = (0..t.radius.len())
            .filter(|&k| t.period[k] == p)
            .map(|k| (t.z_base[k], t.radius[k]))
            .collect();
        let through = disks.iter().map(|d| d.0).fold(0.0, f64::max) + 2.0 * S >= top - 1e-9;
        // The highest disk still (partly) under the surface at its own perimeter.
        let r_meet = disks
            .iter()
            .filter(|&&(zb, r)| zb < surf(r))
            .max_by(|a, b| a.0.total_cmp(&b.0))
            .map_or(0.0, |d| d.1);
        rows.push(Row {
            drawn: p as f64 * tonnes,
            through,
            rim,
            r_meet,
            depth,
        });
    }
    (rows, out)
}

/// One column drawn through breakthrough: its rows, the draw at breakthrough m_b (first
/// period whose IMZ reaches the top), and the row nearest each multiple of m_b.
struct Field {
    scene: Scene,
    out: RunOutput,
    rows: Vec<Row>,
    m_b: f64,
}

impl Field {
    fn run(width: f64, height: f64, periods: usize, tonnes: f64, inc: f64) -> Field {
        let scene = column(width, height, periods, tonnes);
        let (rows, out) = measure(&scene, &scenario(periods, S, inc), height);
        let m_b = rows
            .iter()
            .find(|r| r.through)
            .expect("no breakthrough")
            .drawn;
        Field {
            scene,
            out,
            rows,
            m_b,
        }
    }

    /// Share of a void entering the lowest disk that the r-law passes through every disk to
    /// the surface, Π (1 − r_i), in the IMZ of the period nearest k × m_b.
    fn pass_through(&self, k: f64) -> f64 {
        let p = self.at(k).drawn / self.scene.schedule.tonnes[0];
        let t = &self.out.imz;
        let mut disks: Vec<(f64, f64)> = (0..t.radius.len())
            .filter(|&j| t.period[j] as f64 == p.round())
            .map(|j| (t.z_base[j], t.radius[j]))
            .collect();
        disks.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (d, phi) = (0.0083, 40.0);
        (1..disks.len())
            .map(|i| 1.0 - r_law(d, 2.0 * S, disks[i].1, disks[i - 1].1, phi, 3.5))
            .product()
    }

    /// The draw at which the crater first overflows the IMZ's footprint: the first period
    /// after breakthrough whose rim lies beyond the IMZ radius at the surface.
    fn overflow(&self) -> f64 {
        self.rows
            .iter()
            .find(|r| r.through && r.rim > r.r_meet)
            .expect("the crater never overflows the IMZ")
            .drawn
    }

    /// Growth rates (m per unit of m_b drawn) of the rim and of the IMZ radius at the
    /// surface over the window from the overflow to `span` × m_b later.
    fn rates_after_overflow(&self, span: f64) -> (f64, f64) {
        let m_o = self.overflow();
        let near = |m: f64| {
            *self
                .rows
                .iter()
                .min_by(|a, b| (a.drawn - m).abs().total_cmp(&(b.drawn - m).abs()))
                .unwrap()
        };
        let (a, b) = (near(m_o), near(m_o + span * self.m_b));
        let dm = (b.drawn - a.drawn) / self.m_b;
        ((b.rim - a.rim) / dm, (b.r_meet - a.r_meet) / dm)
    }

    /// The row at a draw of k × m_b.
    fn at(&self, k: f64) -> Row {
        *self
            .rows
            .iter()
            .min_by(|a, b| {
                (a.drawn - k * self.m_b)
                    .abs()
                    .total_cmp(&(b.drawn - k * self.m_b).abs())
            })
            .unwrap()
    }
}

#[test]
fn the_surface_cone_overflows_the_imz_and_outruns_it_in_the_far_field() {
    // Summary §3.1: in the far field (heights > 100–200 d̄) the surface cone grows well
    // beyond the IMZ (a sharply convex intersection); in the near field the cone rim and the
    // IMZ limit grow outward at more similar rates (a concave intersection near the rim).
    //
    // Near field: a 0.5 m column (H/d̄ = 60); far field: 2.0 m (H/d̄ = 241). Same material,
    // same h = 25 mm, s = 12.5 mm and rilling cell (3 s), so the comparison is at matched
    // resolution; the far-field box is wider (2.4 m) so its crater stays off the walls. The
    // two are compared at matched stages of the draw after breakthrough: k × m_b, the draw
    // at breakthrough (5 kg and 80 kg, which scale as the IMZ volume). Comparing at the same
    // absolute draw (kg) instead favours the smaller column: its crater starts from zero
    // just as fast (rim ∝ V^{1/3}) on a smaller IMZ.
    let near = Field::run(1.2, 0.5, 60, 0.0005, 0.0005);
    let far = Field::run(2.4, 2.0, 90, 0.005, 0.0025);
    // The sections through time cut the IMZ at the free surface (above it the disks hold
    // the air that left the IMZ's top, not moving rock): no outline point lies above the
    // surface in any period, and after breakthrough some lie on it (the cut acted).
    for (name, f) in [("near", &near), ("far", &far)] {
        let (mut points, mut on) = (0, 0);
        for (&p, row) in f.scene.periods.id.iter().zip(&f.rows) {
            let sec = drawdown_section(&f.scene, &f.out, &[0], 0.0, Some(0.05), p);
            for &(x, z) in sec.imz.iter().flatten().filter(|p| p.0.is_finite()) {
                let s = surface_at(&sec.surface, x).expect("a surface every period");
                assert!(
                    z <= s + 1e-9,
                    "{name}, period {p}: IMZ at z {z} above the surface {s}"
                );
                points += 1;
                on += usize::from(row.through && (z - s).abs() <= 1e-9);
            }
        }
        eprintln!(
            "  {name}: {points} IMZ outline points, {on} cut at the surface after breakthrough"
        );
        assert!(on > 0, "{name}: the IMZ never reached the surface");
    }
    let keep = std::env::var_os("CAVEFLOW_DOCS");
    let tmp = tempfile::tempdir().unwrap();
    for (name, f) in [("near", &near), ("far", &far)] {
        let h_d = f.scene.blocks.z_max() / 0.0083;
        eprintln!(
            "{name} field: H/d̄ {h_d:.0}, breakthrough at {:.1} kg",
            1000.0 * f.m_b
        );
        for k in [1.0, 2.0, 3.0, 4.0, 5.0] {
            let r = f.at(k);
            eprintln!(
                "  {k}× m_b ({:5.1} kg): rim {:.3} m, IMZ at the surface {:.3} m, rim/IMZ {:.2}, crater depth {:.3} m",
                1000.0 * r.drawn,
                r.rim,
                r.r_meet,
                r.rim / r.r_meet,
                r.depth
            );
        }
        // Not asserted, measured and documented (`docs::validation`): how fast rim and IMZ
        // grow once the crater overflows the IMZ's footprint, over the same span of draw in
        // units of m_b in both columns, and the share of the void that reaches the surface.
        let (rim_rate, imz_rate) = f.rates_after_overflow(2.0);
        eprintln!(
            "  overflow at {:.2}× m_b; over the next 2 m_b the rim grew {rim_rate:.4} m and the IMZ at the surface {imz_rate:.4} m per m_b ({:.1}×); void reaching the surface {:.0}% (3×), {:.0}% (5×)",
            f.overflow() / f.m_b,
            rim_rate / imz_rate,
            100.0 * f.pass_through(3.0),
            100.0 * f.pass_through(5.0)
        );
        // The section (like Fig. 33): surface cone, IMZ and IEZ outlines, marker layers.
        let last = f.rows.last().unwrap();
        let period = *f.scene.periods.id.last().unwrap();
        let sec = drawdown_section(&f.scene, &f.out, &[0], 0.0, Some(0.05), period);
        let file = format!("surface_cone_{name}_field.png");
        let png = tmp.path().join(&file);
        let title = format!(
            "{} field, H/d̄ = {h_d:.0}: {:.0} kg drawn ({:.0}× breakthrough), rim / IMZ at surface = {:.2}",
            if name == "near" { "Near" } else { "Far" },
            1000.0 * last.drawn,
            last.drawn / f.m_b,
            last.rim / last.r_meet
        );
        caveflow::output::charts::section_chart(&png, &sec, &title).unwrap();
        assert!(std::fs::read(&png).unwrap().starts_with(b"\x89PNG"));
        if let Some(dir) = &keep {
            std::fs::copy(&png, Path::new(dir).join(&file)).unwrap();
        }
    }
    for k in [3.0, 5.0] {
        let (n, f) = (near.at(k), far.at(k));
        let (rn, rf) = (n.rim / n.r_meet, f.rim / f.r_meet);
        eprintln!(
            "{k}× m_b: rim/IMZ near {rn:.2}, far {rf:.2}, far/near {:.2}; rim beyond the IMZ near {:.3} m, far {:.3} m",
            rf / rn,
            n.rim - n.r_meet,
            f.rim - f.r_meet
        );
    }
    // In both columns the crater overflows the IMZ's footprint within 2 m_b of the draw at
    // breakthrough (measured 1.80× near, 1.31× far).
    for (name, f) in [("near", &near), ("far", &far)] {
        assert!(
            f.overflow() <= 2.0 * f.m_b,
            "{name}: overflow at {}",
            f.overflow()
        );
    }
    // Far field (summary §3.1): the surface cone grows well beyond the IMZ, a sharply
    // convex intersection. At 5× m_b rim/IMZ is 1.65 and the rim lies 0.25 m (20 s) beyond
    // the IMZ; bounds 1.4 and 0.15 m leave room for the ±6% to which the rim is read.
    let f = far.at(5.0);
    assert!(
        f.rim / f.r_meet >= 1.4,
        "far-field rim/IMZ {}",
        f.rim / f.r_meet
    );
    assert!(
        f.rim - f.r_meet > 0.15,
        "far-field rim {} vs IMZ {}",
        f.rim,
        f.r_meet
    );
    // Not reproduced, and so not asserted: the near field's intersection lying closer to the
    // rim. Since void vented through the top disk moves its markers (`engine::markers`), the
    // near-field crater is as wide relative to the IMZ as the far field's (rim/IMZ 1.38 and
    // 1.64 at 3× and 5× m_b, against 1.46 and 1.65), and its rim outgrows the IMZ faster
    // after the overflow (5.5 against 2.6 times the IMZ's rate). See `docs::validation`.
}
