//! The automatic resolution: h, marker spacing and draw increment from the scene.
//!
//! Defaults follow MassFlow's ratios and are refined by the scene:
//! - h = min(0.5 × smallest block dimension, smallest opening width): MassFlow's disks are
//!   0.5 × block size; a disk thicker than the opening cannot resolve the base angle.
//! - marker spacing = 0.5 h (MassFlow: markers 0.25 × block size with 0.5 × block disks).
//! - draw increment = the tonnes of the smallest opening disk (π (w/2)² h) at dilated
//!   density. The increment is the marker-update interval: the IMZ itself grows in cycles
//!   of at most a quarter of its lowest disk (`Imz::draw`), and markers then move by the
//!   void passed "since the last marker update" (summary §3.3). The axial marker of a cone
//!   profile moves up to 3 disks per update at this size; a third of it keeps it within
//!   one disk at three times the cost (see the speed–accuracy sweep in the README).

use crate::engine::ResolvedResolution;
use crate::model::{Scenario, Scene};

/// Fills the unset resolution knobs from the scene.
pub fn resolve(scene: &Scene, sc: &Scenario) -> ResolvedResolution {
    let bm = &scene.blocks;
    let min_block = bm.size.iter().cloned().fold(f64::INFINITY, f64::min);
    let min_open = scene
        .drawpoints
        .width
        .iter()
        .cloned()
        .fold(f64::INFINITY, f64::min);
    let h = sc
        .resolution
        .layer_thickness
        .unwrap_or_else(|| (0.5 * min_block).min(min_open));
    let s = sc.resolution.marker_spacing.unwrap_or(0.5 * h);
    let rho1 = if bm.is_empty() {
        1.0
    } else {
        (0..bm.len())
            .map(|b| bm.density[b] * (1.0 - bm.n1[b]))
            .sum::<f64>()
            / bm.len() as f64
    };
    let r = 0.5 * min_open;
    let inc = sc
        .resolution
        .draw_increment
        .unwrap_or(std::f64::consts::PI * r * r * h * rho1);
    ResolvedResolution {
        layer_thickness: h,
        marker_spacing: s,
        draw_increment: inc,
    }
}
