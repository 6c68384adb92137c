//! The model's vertical walls as mirrors (method of images): how far from each wall the
//! IMZs' images reach ([`WallReach`]), and the images of the IMZs that a marker near a
//! wall is moved by.

use super::super::imz::ImzGeom;
use super::MotionField;
use crate::model::BlockModel;

/// How far from each of the model's vertical walls (x low, x high, y low, y high) the
/// IMZs' images reach, per band of height h from the lowest IMZ base: the most, over the
/// disks that overlap the band, of R_i less the distance from the IMZ's axis to the wall.
/// The image of a disk across a wall holds a point only if the point is within that of the
/// wall (the image lies as far beyond the wall as the axis lies inside it), so farther
/// markers skip the wall's images, and a corner's unless they are within reach of both
/// walls. In the lower half of the demo, where the disks are narrow, that is most markers.
#[derive(Debug, Clone, Default)]
pub struct WallReach {
    z0: f64,
    h: f64,
    bands: Vec<[f64; 4]>,
}

impl WallReach {
    /// The reach of the disks `geoms` in the walls of `bm`.
    pub fn new(geoms: &[ImzGeom], bm: &BlockModel) -> WallReach {
        let z0 = geoms.iter().map(|g| g.z0).fold(f64::INFINITY, f64::min);
        let h = geoms.iter().map(|g| g.h).fold(f64::INFINITY, f64::min);
        if !(z0.is_finite() && h > 0.0) {
            return WallReach::default();
        }
        let mut reach = WallReach {
            z0,
            h,
            bands: Vec::new(),
        };
        for g in geoms {
            reach.widen(g, bm);
        }
        reach
    }

    /// Widens the reach to cover the disks of `g` (one of the IMZs it was made for, whose
    /// base and disk height do not change). A disk's radius only grows, so the engine keeps
    /// one reach for the run and widens it by the IMZs that drew (`Engine::refresh_views`);
    /// were a disk to narrow, the kept reach would only be wider than needed, which makes a
    /// marker test images that hold it not, and moves nothing.
    pub fn widen(&mut self, g: &ImzGeom, bm: &BlockModel) {
        if !(self.h > 0.0) {
            return;
        }
        let (lo, hi) = (bm.origin, bm.max_corner());
        let dist = [g.x - lo[0], hi[0] - g.x, g.y - lo[1], hi[1] - g.y];
        for (i, &r) in g.radius.iter().enumerate() {
            let base = g.z0 + i as f64 * g.h - self.z0;
            let k0 = (base / self.h).floor().max(0.0) as usize;
            let k1 = ((base + g.h) / self.h).ceil() as usize;
            if self.bands.len() < k1 {
                self.bands.resize(k1, [f64::NEG_INFINITY; 4]);
            }
            for band in &mut self.bands[k0..k1] {
                for w in 0..4 {
                    band[w] = band[w].max(r - dist[w]);
                }
            }
        }
    }

    /// The reach of the band that holds height `z` (−∞ where no disk is).
    #[inline]
    pub fn at(&self, z: f64) -> [f64; 4] {
        let t = (z - self.z0) / self.h;
        if t >= 0.0 {
            if let Some(b) = self.bands.get(t as usize) {
                return *b;
            }
        }
        [f64::NEG_INFINITY; 4]
    }
}

impl MotionField<'_> {
    /// The model's vertical walls (method of images): an IMZ whose disk passes a wall
    /// also moves the marker as its mirror image across that wall would, so the flow
    /// along a wall has no component through it and a cut disk's flux stays whole in the
    /// model. The images of the IMZs of the cell at the wall nearest the mirrored point
    /// are the candidates, where the marker is within the images' reach of the wall
    /// ([`WallReach`]). Within reach of two walls, the images across both (the
    /// corner's) as well. Calls `f(at, q, sx, sy)` per image: the plan point whose grid
    /// cell lists the candidates, the marker's mirror `q`, and the signs (sx, sy) that map
    /// the image's plan moves to the marker's.
    #[inline]
    pub(super) fn images(&self, p: [f64; 3], mut f: impl FnMut([f64; 2], [f64; 3], f64, f64)) {
        let Some((bm, _)) = self.ground else { return };
        let (lo, hi) = (bm.origin, bm.max_corner());
        let reach = self.reach.at(p[2]);
        // Per axis, the two walls: (the wall, a point just inside it, its reach index).
        let walls = |a: usize| {
            [
                (lo[a], lo[a] + 1e-9, 2 * a),
                (hi[a], hi[a] - 1e-9, 2 * a + 1),
            ]
            .into_iter()
            .filter(move |&(wall, _, w)| (p[a] - wall).abs() <= reach[w])
        };
        for (wall, inside, _) in walls(0) {
            f([inside, p[1]], [2.0 * wall - p[0], p[1], p[2]], -1.0, 1.0);
        }
        for (wall, inside, _) in walls(1) {
            f([p[0], inside], [p[0], 2.0 * wall - p[1], p[2]], 1.0, -1.0);
        }
        for (wx, in_x, _) in walls(0) {
            for (wy, in_y, _) in walls(1) {
                f(
                    [in_x, in_y],
                    [2.0 * wx - p[0], 2.0 * wy - p[1], p[2]],
                    -1.0,
                    -1.0,
                );
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::super::imz::{DiskMotion, ImzGrid};
    use super::super::disk_moves::tests::still_disks;
    use super::super::prepare;
    use super::*;

    /// A marker beside a wall whose IMZ narrows below it never leaves the model: where it
    /// takes the image's transfer, which points beyond the wall, it ends at the mirror of
    /// where that move would carry it. The Castro box's wall x = −0.6 m, an IMZ 0.1 m from
    /// it with disks of 0.2 m below 0.3 m; points within 5 cm of the wall just above the
    /// disks' base, 16 keys each.
    #[test]
    fn an_images_transfer_never_carries_a_marker_through_its_wall() {
        let scene = crate::model::synthetic::UniformBox::castro_isolated().scene();
        let bm = &scene.blocks;
        let [wx, _, _] = bm.origin;
        let z0 = bm.origin[2];
        let motion = still_disks(&[0.2, 0.3, 0.3], |_| (0.004, 0.003), 0.05, 0.1);
        let geoms = vec![ImzGeom {
            x: wx + 0.1,
            y: 0.0,
            z0,
            h: 0.1,
            radius: vec![0.2, 0.3, 0.3],
        }];
        let grid = ImzGrid::build(&geoms, &[0], [wx, -0.6], [1.2, 1.2], 0.05);
        let motions: Vec<&[DiskMotion]> = vec![&motion[..]];
        let field = MotionField {
            geoms: &geoms,
            motion: &motions,
            grid: &grid,
            ground: Some((bm, 1)),
            reach: WallReach::new(&geoms, bm),
            seed: 1,
            window: false,
        };
        let (mut crossed, mut image) = (0, 0);
        for i in 0..10 {
            for j in -10..=10 {
                let p = [
                    wx + 0.005 * (i as f64 + 0.5),
                    0.02 * j as f64,
                    z0 + 0.1 + 1e-4,
                ];
                for id in 0..16 {
                    let st = field.step(p, id);
                    assert!(p[0] + st.dx >= wx, "{p:?}: {st:?}");
                    if p[2] + st.dz < z0 + 0.1 {
                        crossed += 1;
                        // The IMZ's own transfer pulls the marker off the wall (+x).
                        image += usize::from(st.dx < 0.0);
                    }
                }
            }
        }
        assert!(
            crossed > 1000 && image > 100,
            "{crossed} crossed, {image} by the image"
        );
    }

    /// [`WallReach`] never skips an image that holds the marker: over a grid of points in the
    /// Castro box and three IMZs of different widths and bases, wherever the mirror of a
    /// point across a wall lies in some IMZ's disk, the point is within the wall's reach
    /// at its height; and the reach does skip most of the points (it is a filter).
    #[test]
    fn wall_reach_never_skips_an_image_that_holds_the_marker() {
        let scene = crate::model::synthetic::UniformBox::castro_isolated().scene();
        let bm = &scene.blocks;
        let (lo, hi) = (bm.origin, bm.max_corner());
        let imz = |x: f64, y: f64, z0: f64, r: &[f64]| ImzGeom {
            x,
            y,
            z0,
            h: 0.1,
            radius: r.to_vec(),
        };
        let geoms = vec![
            imz(-0.45, 0.0, lo[2], &[0.06, 0.12, 0.2, 0.3, 0.4]),
            imz(0.3, 0.4, lo[2] + 0.05, &[0.06, 0.1, 0.15]),
            imz(0.0, -0.2, lo[2], &[0.06, 0.08]),
        ];
        let reach = WallReach::new(&geoms, bm);
        let (mut held, mut skipped, mut points) = (0, 0, 0);
        for i in 0..48 {
            for j in 0..48 {
                for k in 0..12 {
                    let p = [
                        lo[0] + (i as f64 + 0.5) * 0.025,
                        lo[1] + (j as f64 + 0.5) * 0.025,
                        lo[2] + (k as f64 + 0.5) * 0.05,
                    ];
                    let r = reach.at(p[2]);
                    for (w, (a, wall)) in [(0, lo[0]), (0, hi[0]), (1, lo[1]), (1, hi[1])]
                        .into_iter()
                        .enumerate()
                    {
                        let mut q = p;
                        q[a] = 2.0 * wall - p[a];
                        let near = (p[a] - wall).abs() <= r[w];
                        if geoms.iter().any(|g| g.disk_at(q).is_some()) {
                            held += 1;
                            assert!(near, "{p:?} wall {w}: reach {}", r[w]);
                        }
                        skipped += usize::from(!near);
                        points += 1;
                    }
                }
            }
        }
        assert!(held > 100, "{held}");
        assert!(skipped > points / 2, "{skipped} of {points}");
    }

    /// The model's walls mirror the IMZs (method of images): an IMZ whose disk passes a wall
    /// moves nothing through it, and the void it passes moves its whole volume of ground
    /// inside the model. The Castro box (1.2 m square, walls at x, y = ±0.6 m) with one IMZ
    /// 0.1 m from the wall x = −0.6 m, disks widened from 0.28 m to 0.3 m (cut by the wall
    /// over a fifth of their area, so their rings push the ground in on both sides of it)
    /// that take in 0.01 m³ of void and pass 0.009 m³ up, w = 0.05 m. At mid-height the
    /// void is 0.0095 m³; the flux is summed over a 2 mm grid inside the model, whose error
    /// on a 0.3 m disk is under 0.5%. Without the images the wall takes a radial push and
    /// the model holds four fifths of the flux. The same IMZ moved into the corner of the
    /// walls x, y = −0.6 m (0.1 m from both): without the corner's double image the ground
    /// at the walls moves through them (2 mm in x per 40 mm down).
    #[test]
    fn walls_mirror_the_imzs() {
        let scene = crate::model::synthetic::UniformBox::castro_isolated().scene();
        let bm = &scene.blocks;
        let [wx, wy, _] = bm.origin;
        let mut motion: Vec<DiskMotion> = (0..4)
            .map(|_| DiskMotion {
                r: 0.3,
                r_old: 0.28,
                dv: 0.01,
                dv_out: 0.009,
                w: 0.05,
                area_frac: 1.0,
                flow_frac: 1.0,
                ..Default::default()
            })
            .collect();
        prepare(&mut motion, 0.1);
        // A disk cut by the wall x = wx, then one in the corner of x = wx and y = wy.
        for (x, y) in [(wx + 0.1, 0.0), (wx + 0.1, wy + 0.1)] {
            let geom = ImzGeom {
                x,
                y,
                z0: bm.origin[2],
                h: 0.1,
                radius: vec![0.3; 4],
            };
            let geoms = vec![geom.clone()];
            let grid = ImzGrid::build(&geoms, &[0], [wx, wy], [1.2, 1.2], 0.05);
            let motion_ref: Vec<&[DiskMotion]> = vec![&motion[..]];
            let field = MotionField {
                geoms: &geoms,
                motion: &motion_ref,
                grid: &grid,
                ground: Some((bm, 1)),
                reach: WallReach::new(&geoms, bm),
                seed: 0,
                window: false,
            };
            let z = geom.z0 + 0.25;
            // Along each wall the disk reaches (1 nm inside it) nothing moves through it,
            // to the field's change over 2 nm.
            for k in 0..50 {
                let t = 0.011 * k as f64 - 0.27;
                let st = field.step([wx + 1e-9, y + t, z], k);
                assert!(st.dx.abs() < 1e-6 * st.dz.abs(), "({x}, {y}) t {t}: {st:?}");
                if y < wy + 0.3 && x + t > wx {
                    let st = field.step([x + t, wy + 1e-9, z], k);
                    assert!(st.dy.abs() < 1e-6 * st.dz.abs(), "({x}, {y}) t {t}: {st:?}");
                }
            }
            // The void moves its whole volume of ground inside the model.
            let cell = 0.002;
            let mut volume = 0.0;
            for i in 0..200 {
                for j in 0..300 {
                    let p = [
                        wx + (i as f64 + 0.5) * cell,
                        y - 0.3 + (j as f64 + 0.5) * cell,
                        z,
                    ];
                    if p[1] > wy {
                        volume -= field.step(p, 0).dz * cell * cell;
                    }
                }
            }
            assert!(
                (volume / 0.0095 - 1.0).abs() < 0.005,
                "({x}, {y}): {volume} m³ of 0.0095"
            );
        }
    }
}
