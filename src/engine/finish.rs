//! The end of the run: what each extraction row drew, read from its drawpoint's stream
//! of drawn markers ([`crediting`]) with each marker's in-situ composition; the mass
//! balance and the end-of-run warnings; and the markers handed over to the tables
//! ([`marker_tables`]). Snapshots of the markers during the run are read here too.

use rayon::prelude::*;

use super::account::Phase;
use super::crediting::{self, Tally};
use super::fill;
use super::fragmentation::SizeDist;
use super::markers::Markers;
use super::{
    correction_stats, correction_warning, marker_tables, Engine, MarkerSnapshot, RunOutput,
    RunWarning, WarningRule,
};

/// Extraction rows whose drawn figures are worked out at a time (`Engine::read_streams`).
const READ_ROWS: usize = 1 << 16;

impl Engine<'_> {
    /// Marker states now: every moving and drawn marker, sorted by id.
    pub fn snapshot(&self, period: i64) -> MarkerSnapshot {
        let bm = &self.scene.blocks;
        let rows = marker_tables::MarkerRows {
            moving: &self.markers,
            drawn: &self.drawn,
            lattice: &self.lattice,
            block_id: &bm.id,
            porosity: &bm.n1,
        };
        rows.snapshot(period, &rows.snapshot_order())
    }

    /// What each extraction row drew, read from its drawpoint's stream over the row's
    /// scheduled interval (`crediting`), in place of the row's own markers.
    fn read_streams(&mut self) {
        let scene = self.scene;
        let bm = &scene.blocks;
        let at: std::collections::HashMap<i64, usize> = scene
            .periods
            .id
            .iter()
            .enumerate()
            .map(|(i, &p)| (p, i))
            .collect();
        // Per drawpoint, cumulative scheduled tonnes before each period.
        let n_dp = scene.drawpoints.len();
        let mut before = vec![vec![0.0; n_dp]; scene.periods.len() + 1];
        for p in 0..scene.periods.len() {
            let row = self.schedule.period(p);
            for d in 0..n_dp {
                before[p + 1][d] = before[p][d] + row[d];
            }
        }
        // A part of the rows at a time: at mine scale the rows' derived figures held
        // whole would be a few hundred megabytes at the run's peak of memory.
        let n = self.out.extraction.drawpoint.len();
        for start in (0..n).step_by(READ_ROWS) {
            let ex = &self.out.extraction;
            let derived: Vec<crediting::Derived> = (start..(start + READ_ROWS).min(n))
                .into_par_iter()
                .map(|k| {
                    let d = ex.drawpoint[k] as usize;
                    let p = at[&ex.period[k]];
                    let stream = &self.streams[d];
                    let (lo, hi) = (before[p][d], before[p + 1][d]);
                    let rows = stream.window(lo, hi, crediting::GRADE_MARKERS);
                    let mut t = Tally::new(bm.grades.len(), bm.lithology_names.len());
                    for r in rows {
                        self.contribute(&self.drawn.m, stream.row[r] as usize, &mut t);
                    }
                    t.derived()
                })
                .collect();
            for (k, dv) in derived.into_iter().enumerate() {
                dv.set(&mut self.out.extraction, start + k);
            }
        }
    }

    /// Completes the output: the mass balance, the warnings, and the markers handed over as
    /// they are ([`marker_tables::EndMarkers`]: the drawn table and the end snapshot).
    pub(super) fn finish(mut self) -> RunOutput {
        let mut clock = self.clock();
        // At mine scale the end of the run is where memory peaks: what is read no more is
        // let go as soon as it is not (the draw times are the streams', kept in `drawn`
        // for a resume only; the streams once read).
        self.drawn.tau = Vec::new();
        self.read_streams();
        self.streams = Vec::new();
        if let Some(e) = &self.scenario.economics {
            let names = &self.scene.blocks.grade_names;
            self.out.value = Some(super::value::values(&self.out.extraction, names, e));
        }
        self.rims = Vec::new();
        let dm = &self.drawn;
        let sched = &self.schedule;
        let n_dp = self.scene.drawpoints.len();
        let b = &mut self.out.balance;
        b.per_drawpoint = (0..n_dp).map(|d| (sched.total(d), self.cum[d])).collect();
        b.scheduled_tonnes = sched.tonnes.iter().sum();
        b.credited_tonnes = self.cum.iter().sum();
        b.marker_tonnes = self.out.extraction.marker_tonnes.iter().sum();
        b.final_shortfall_tonnes = self.carry.iter().sum();
        b.markers_drawn = dm.m.len() as u64;
        b.markers_mobilised = (dm.m.len() + self.markers.len()) as u64;
        b.correction = correction_stats(&self.out.extraction);
        if let Some(m) = correction_warning(&b.correction) {
            self.out
                .warnings
                .push(RunWarning::general(WarningRule::MassBalance, m));
        }
        for (d, &c) in self.carry.iter().enumerate() {
            if c > 1e-6 * sched.total(d).max(1.0) {
                let name = &self.scene.drawpoints.name[d];
                self.out.warnings.push(RunWarning {
                    rule: WarningRule::Short,
                    drawpoint: Some(name.clone()),
                    amount: c,
                    message: format!("drawpoint {name} could not deliver {c:.1} t of its schedule (IMZ blocked or nothing left to draw)"),
                });
            }
        }
        let lags = crediting::lagging(
            &self.out.extraction,
            n_dp,
            fill::EXHAUSTED_FILL,
            self.resolution.draw_increment,
        );
        for l in lags {
            let name = &self.scene.drawpoints.name[l.drawpoint];
            let excess = l.credited - l.markers;
            self.out.warnings.push(RunWarning {
                rule: WarningRule::Lagging,
                drawpoint: Some(name.clone()),
                amount: excess,
                message: format!(
                    "drawpoint {name}: its markers weigh {:.3} of the {} t credited while its lowest disks could feed its schedule ({} t behind, beyond their discreteness); credited in full",
                    l.ratio(),
                    significant(l.credited),
                    significant(excess)
                ),
            });
        }
        for imz in &self.imzs {
            if imz.air > 0.0 {
                let name = &self.scene.drawpoints.name[imz.id];
                self.out.warnings.push(RunWarning {
                    rule: WarningRule::AirGap,
                    drawpoint: Some(name.clone()),
                    amount: imz.air,
                    message: format!("drawpoint {name}: IMZ held under uncaved ground; {:.3e} m3 of void is still an air gap at the end of the run", imz.air),
                });
            }
        }
        let scene = self.scene;
        if let Some(&last) = scene.periods.id.last() {
            let wanted = &self.scenario.outputs.marker_periods;
            let snapshot = wanted.is_empty() || wanted.contains(&last);
            self.out.end = Some(marker_tables::EndMarkers::new(
                last,
                snapshot,
                std::mem::take(&mut self.markers),
                std::mem::take(&mut self.drawn),
                self.lattice,
                &scene.blocks,
            ));
        }
        self.charge(Phase::Finish, &mut clock);
        self.out.account = self.account.take().map(|a| *a);
        self.out
    }

    /// The in-situ composition of the cell of site `id`, whose centre lies in block `b`:
    /// the blocks the cell overlaps, each with its share of the cell's in-situ solids
    /// (`Lattice::cell_blocks`, weighted by ρ (1 − n0)); `[(b, 1)]` for a cell in one
    /// block. A marker stands for its whole cell, so where the cell straddles a block face
    /// its grade, lithology and waste share are the cell's mix, not its centre block's:
    /// taking the centre block's moved every block face's grade by up to s/2 and made the
    /// demo's whole-run grade error jump between 1.1 and 2.0% among spacings 1.05–1.52 m
    /// (`docs::resolution`, "Automatic resolution"). Size and fines stay the centre
    /// block's, as does the marker's mass (the lattice's, `Lattice::unit_masses`).
    fn composition(&self, id: usize, b: usize) -> Vec<(usize, f64)> {
        let bm = &self.scene.blocks;
        let mut cell = Vec::with_capacity(8);
        self.lattice.cell_blocks(bm, id, &mut cell);
        for (c, w) in cell.iter_mut() {
            *w *= bm.density[*c] * (1.0 - bm.n0[*c]);
        }
        let solids: f64 = cell.iter().map(|&(_, w)| w).sum();
        if cell.len() < 2 || solids <= 0.0 {
            return vec![(b, 1.0)];
        }
        cell.iter_mut().for_each(|(_, w)| *w /= solids);
        cell
    }

    /// Adds row `k` of the drawn markers `mk` to a tally.
    pub(super) fn contribute(&self, mk: &Markers, k: usize, t: &mut Tally) {
        let bm = &self.scene.blocks;
        let b = mk.block[k] as usize;
        let m = mk.mass[k];
        // The marker's size distribution and fines share: its own (primary size, attrited
        // fraction) when markers are sized, else its block's primary distribution.
        let (dist, fines) = if self.sized() {
            let dist = SizeDist::Attrited {
                d0: mk.frag0[k],
                w: mk.attrited[k],
                m: self.scenario.fragmentation.product_exponent,
            };
            (dist, dist.passing(self.scenario.outputs.fines_cutoff))
        } else {
            (SizeDist::of_block(bm, b), self.fines_frac[b])
        };
        let composition = self.composition(mk.id[k] as usize, b);
        t.mass += m;
        t.count += 1;
        for (g, col) in bm.grades.iter().enumerate() {
            t.grade[g] += m * composition.iter().map(|&(b, w)| w * col[b]).sum::<f64>();
        }
        let mut waste = 0.0;
        for &(b, w) in &composition {
            t.lith[bm.lithology[b] as usize] += m * w;
            if self.waste[b] {
                waste += w;
            }
        }
        t.origin_z += m * self.lattice.pos(mk.id[k] as usize)[2];
        t.frag += m * mk.frag[k];
        t.fines += m * fines;
        t.fines_z += m * fines * self.lattice.pos(mk.id[k] as usize)[2];
        t.sizes.push((dist, m));
        t.percolated += m * mk.percolated[k];
        if waste > 0.0 {
            t.waste += m * waste;
            t.fines_waste += m * fines * waste;
        }
        let rilled = mk.rill[k];
        if rilled > 0.0 {
            t.rilled += m;
            t.rill_dist += m * rilled;
        }
    }
}

/// `x` to four significant figures, without an exponent (tonnes from grams to megatonnes).
fn significant(x: f64) -> String {
    let digits = if x == 0.0 || !x.is_finite() {
        0
    } else {
        (3 - x.abs().log10().floor() as i32).max(0) as usize
    };
    format!("{x:.digits$}")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::synthetic::UniformBox;
    use crate::model::Scenario;

    /// The lattice holds the block model's metal where the density is uniform: Σ over
    /// every site of its mass times its cell's grade ([`Engine::composition`]) is Σ over
    /// the blocks of their in-situ solids times their grade, to rounding, on a lattice whose
    /// layers and columns straddle the block faces (35 mm on 50 mm blocks). Taking each
    /// site's centre block instead is 1.6% off here.
    #[test]
    fn the_lattice_carries_the_block_models_metal() {
        let mut scene = UniformBox {
            extent: [0.6, 0.55, 0.4],
            ..UniformBox::castro_isolated()
        }
        .scene();
        // A grade that is not linear in the blocks' coordinates, whose straddles would
        // cancel.
        scene.blocks.grades[0] = (0..scene.blocks.len())
            .map(|b| (scene.blocks.z[b] * 10.0).powi(2) + scene.blocks.x[b].abs())
            .collect();
        let bm = &scene.blocks;
        let in_situ: f64 = (0..bm.len())
            .map(|b| {
                bm.size.iter().product::<f64>() * bm.density[b] * (1.0 - bm.n0[b]) * bm.grades[0][b]
            })
            .sum();
        for offset in [[0.0, 0.0], [0.3, -0.5]] {
            let mut sc = Scenario::default();
            sc.resolution.marker_spacing = Some(0.035);
            sc.resolution.layer_thickness = Some(0.07);
            sc.resolution.lattice_offset = offset;
            let e = Engine::new(&scene, &sc).unwrap();
            let (mut cells, mut centres) = (0.0, 0.0);
            for id in 0..e.lattice.len() {
                let b = bm.locate(e.lattice.pos(id)).unwrap();
                let m = e.lattice.site_mass(bm, id, e.unit_mass[b]);
                let g: f64 = e
                    .composition(id, b)
                    .iter()
                    .map(|&(c, w)| w * bm.grades[0][c])
                    .sum();
                cells += m * g;
                centres += m * bm.grades[0][b];
            }
            assert!(
                (cells / in_situ - 1.0).abs() < 1e-9,
                "{offset:?}: {cells} {in_situ}"
            );
            let off = (centres / in_situ - 1.0).abs();
            eprintln!("{offset:?}: centre blocks' metal / in-situ − 1 = {off:.2e}");
            assert!(
                off > 1e-2,
                "{offset:?}: the centre blocks' metal is off by {off}"
            );
        }
    }
}
