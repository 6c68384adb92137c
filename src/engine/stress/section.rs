//! The sections: N-S, E-W and plan cuts through the stress field (summary Figs 24–25),
//! sampled on the stress grid level by level, with the IMZ outlines and drawpoints for the
//! charts (overview and module map in `stress`).

use super::level::{disks_at, Grid, Level};
use super::{StressParams, Zone};
use crate::engine::imz::ImzGeom;
use crate::model::scenario::StressSettings;
use crate::model::BlockModel;

/// Orientation of a section.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Orientation {
    /// Vertical, along Northing at a fixed Easting.
    NorthSouth,
    /// Vertical, along Easting at a fixed Northing.
    EastWest,
    /// Horizontal, at a fixed elevation.
    Plan,
}

impl Orientation {
    /// Name written to Parquet.
    pub fn name(self) -> &'static str {
        match self {
            Orientation::NorthSouth => "ns",
            Orientation::EastWest => "ew",
            Orientation::Plan => "plan",
        }
    }
}

/// One IMZ cut by a vertical section: its axis u along the section, and its disks cut by
/// the plane as (z_base, z_top, half chord).
pub type CutImz = (f64, Vec<(f64, f64, f64)>);

/// Stress on one section, on a regular grid of `shape.0` × `shape.1` points (u fastest):
/// (Northing, z) for N-S, (Easting, z) for E-W, (Easting, Northing) for plan.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StressSection {
    /// Orientation (None only in `Default`).
    pub orientation: Option<Orientation>,
    /// Easting (N-S), Northing (E-W) or elevation (plan) of the section, m.
    pub at: f64,
    /// Grid points (n_u, n_v).
    pub shape: (usize, usize),
    /// Grid spacing, m.
    pub cell: f64,
    /// Point coordinates, m.
    pub x: Vec<f64>,
    /// Point coordinates, m.
    pub y: Vec<f64>,
    /// Point coordinates, m.
    pub z: Vec<f64>,
    /// Vertical stress carried, kPa (NaN where uncaved).
    pub sigma_v: Vec<f64>,
    /// Horizontal (radial) stress, kPa (NaN where uncaved).
    pub sigma_h: Vec<f64>,
    /// Stress:strength ratio of stagnant ground (NaN in IMZs and uncaved ground).
    pub ratio: Vec<f64>,
    /// Zone of each point.
    pub zone: Vec<Zone>,
    /// Vertical sections: IMZ disks cut by the plane, per drawpoint. Plan sections: IMZ
    /// circles (x, y, r) in `circles`.
    pub imz: Vec<CutImz>,
    /// Plan sections: IMZ disks cut by the plane (x, y, r).
    pub circles: Vec<(f64, f64, f64)>,
    /// Drawpoints on (vertical) or under (plan) the section: (u, v, drawpoint index).
    pub drawpoints: Vec<(f64, f64, usize)>,
}

impl StressSection {
    /// Section name, e.g. `ns_x=0.000`.
    pub fn name(&self) -> String {
        match self.orientation {
            Some(Orientation::NorthSouth) => format!("ns_x={:.3}", self.at),
            Some(Orientation::EastWest) => format!("ew_y={:.3}", self.at),
            Some(Orientation::Plan) => format!("plan_z={:.3}", self.at),
            None => "section".into(),
        }
    }
}

/// Where a section is and the grid coordinates it samples.
#[derive(Debug, Clone)]
pub(super) struct SectionSpec {
    pub(super) orientation: Orientation,
    pub(super) at: f64,
    /// Along-section coordinates (y for N-S, x for E-W and plan).
    pub(super) u: Vec<f64>,
    /// Plan sections: Northings.
    v: Vec<f64>,
}

/// The sections asked for, defaults filled in (see `StressSettings`): N-S and E-W through the
/// drawpoint axis nearest the centre of the drawpoints (so the section cuts IMZs on their
/// axes, like the summary's Fig 24), and a plan at the mean mid-height of the IMZs.
pub(super) fn section_specs(
    bm: &BlockModel,
    geoms: &[ImzGeom],
    settings: &StressSettings,
    grid: &Grid,
) -> Vec<SectionSpec> {
    let max = bm.max_corner();
    let axis_near_centre = |coord: &dyn Fn(&ImzGeom) -> f64, a: usize| -> f64 {
        if geoms.is_empty() {
            return 0.5 * (bm.origin[a] + max[a]);
        }
        let lo = geoms.iter().map(coord).fold(f64::INFINITY, f64::min);
        let hi = geoms.iter().map(coord).fold(f64::NEG_INFINITY, f64::max);
        let c = 0.5 * (lo + hi);
        geoms
            .iter()
            .map(coord)
            .min_by(|p, q| (p - c).abs().total_cmp(&(q - c).abs()))
            .unwrap_or(c)
    };
    let ns = settings
        .ns_x
        .clone()
        .unwrap_or_else(|| vec![axis_near_centre(&|g| g.x, 0)]);
    let ew = settings
        .ew_y
        .clone()
        .unwrap_or_else(|| vec![axis_near_centre(&|g| g.y, 1)]);
    let plan = settings.plan_z.clone().unwrap_or_else(|| {
        let mids: Vec<f64> = geoms
            .iter()
            .filter_map(|g| {
                let top = g.radius.iter().rposition(|&r| r > 0.0)?;
                Some(g.z0 + 0.5 * (top + 1) as f64 * g.h)
            })
            .collect();
        if mids.is_empty() {
            vec![0.5 * (bm.origin[2] + max[2])]
        } else {
            vec![mids.iter().sum::<f64>() / mids.len() as f64]
        }
    });
    let xs: Vec<f64> = (0..grid.n[0]).map(|i| grid.centre(0, i)).collect();
    let ys: Vec<f64> = (0..grid.n[1]).map(|j| grid.centre(1, j)).collect();
    let mut specs = Vec::new();
    for at in ns {
        specs.push(SectionSpec {
            orientation: Orientation::NorthSouth,
            at,
            u: ys.clone(),
            v: Vec::new(),
        });
    }
    for at in ew {
        specs.push(SectionSpec {
            orientation: Orientation::EastWest,
            at,
            u: xs.clone(),
            v: Vec::new(),
        });
    }
    for at in plan {
        specs.push(SectionSpec {
            orientation: Orientation::Plan,
            at,
            u: xs.clone(),
            v: ys.clone(),
        });
    }
    specs
}

/// The points one level contributes to one section.
#[derive(Debug, Clone, Default)]
pub(super) struct SectionRows {
    pub(super) x: Vec<f64>,
    pub(super) y: Vec<f64>,
    pub(super) z: Vec<f64>,
    pub(super) sigma_v: Vec<f64>,
    pub(super) sigma_h: Vec<f64>,
    pub(super) ratio: Vec<f64>,
    pub(super) zone: Vec<Zone>,
}

pub(super) fn section_rows(
    l: &Level,
    spec: &SectionSpec,
    grid: &Grid,
    params: &StressParams,
    _geoms: &[ImzGeom],
) -> SectionRows {
    let points: Vec<(f64, f64)> = match spec.orientation {
        Orientation::NorthSouth => spec.u.iter().map(|&y| (spec.at, y)).collect(),
        Orientation::EastWest => spec.u.iter().map(|&x| (x, spec.at)).collect(),
        Orientation::Plan => {
            let h = 0.5 * grid.cell;
            if !(spec.at >= l.z - h && spec.at < l.z + h) {
                return SectionRows::default();
            }
            spec.v
                .iter()
                .flat_map(|&y| spec.u.iter().map(move |&x| (x, y)))
                .collect()
        }
    };
    let mut rows = SectionRows::default();
    for (x, y) in points {
        let i = ((x - grid.origin[0]) / grid.cell).floor();
        let j = ((y - grid.origin[1]) / grid.cell).floor();
        let inside = i >= 0.0 && j >= 0.0 && (i as usize) < grid.n[0] && (j as usize) < grid.n[1];
        let flow = inside
            && l.cave.area > 0.0
            && l.sigma.is_finite()
            && l.cave.flow[i as usize + grid.n[0] * j as usize];
        rows.x.push(x);
        rows.y.push(y);
        rows.z.push(l.z);
        if flow {
            let p = l.point(x, y, params);
            rows.sigma_v.push(p.sigma_v);
            rows.sigma_h.push(p.sigma_h);
            rows.ratio.push(p.ratio);
            rows.zone.push(p.zone);
        } else {
            rows.sigma_v.push(f64::NAN);
            rows.sigma_h.push(f64::NAN);
            rows.ratio.push(f64::NAN);
            rows.zone.push(Zone::Uncaved);
        }
    }
    rows
}

/// IMZ outlines and drawpoints for a section's charts.
pub(super) fn decorate(sec: &mut StressSection, geoms: &[ImzGeom]) {
    let half = 0.5 * sec.cell;
    for (d, g) in geoms.iter().enumerate() {
        match sec.orientation {
            Some(o @ (Orientation::NorthSouth | Orientation::EastWest)) => {
                let (off, axis) = if o == Orientation::NorthSouth {
                    (g.x - sec.at, g.y)
                } else {
                    (g.y - sec.at, g.x)
                };
                let stack: Vec<(f64, f64, f64)> = g
                    .radius
                    .iter()
                    .enumerate()
                    .filter(|(_, &r)| r > off.abs())
                    .map(|(i, &r)| {
                        let zb = g.z0 + i as f64 * g.h;
                        (zb, zb + g.h, (r * r - off * off).sqrt())
                    })
                    .collect();
                if !stack.is_empty() {
                    sec.imz.push((axis, stack));
                }
                if off.abs() <= half {
                    sec.drawpoints.push((axis, g.z0, d));
                }
            }
            Some(Orientation::Plan) => {
                sec.drawpoints.push((g.x, g.y, d));
            }
            None => {}
        }
    }
    if sec.orientation == Some(Orientation::Plan) {
        sec.circles = disks_at(geoms, sec.at)
            .into_iter()
            .map(|k| (k.x, k.y, k.r))
            .collect();
    }
}
