//! The end of a period: the period's extraction rows credited from its drawn markers
//! ([`crediting`]), the IMZ, air-gap, surface, snapshot and stress tables of the periods
//! that ask for them; and, before the next period draws, the mobilised means of the
//! drawing IMZs' disks refreshed from the markers inside them.

use rayon::prelude::*;

use super::account::Phase;
use super::crediting::{self, Tally};
use super::fill::{self, Fill};
use super::height_of_draw::hod;
use super::imz::{ImzGeom, Mobilised};
use super::markers::Lattice;
use super::{rilling, stress, Engine, SurfaceTable};

impl Engine<'_> {
    /// Recomputes the mobilised properties (means) of the disks of the IMZs `which` (those
    /// drawing this period) from the markers inside them, in parallel over the IMZs. Each
    /// IMZ visits only the markers binned in the cells its bounding box covers, and sums
    /// them in the order of their ids, whatever the rows' order; the other IMZs' sums
    /// are not read until they draw, and are refreshed then.
    pub(super) fn refresh_mobilised(&mut self, which: &[usize]) {
        if which.is_empty() {
            return;
        }
        let bm = &self.scene.blocks;
        let mut wanted = vec![false; self.imzs.len()];
        which.iter().for_each(|&d| wanted[d] = true);
        let (mk, bins) = (&self.markers, &self.bins);
        self.imzs
            .par_iter_mut()
            .filter(|imz| wanted[imz.id])
            .for_each(|imz| {
                imz.mobilised
                    .iter_mut()
                    .for_each(|m| *m = Mobilised::default());
                // A marker inside the IMZ lies in its plan bounding box, so in these cells.
                let g = &imz.geom;
                let r = g.max_radius();
                let mut cells = Vec::new();
                bins.cells_in([g.x - r, g.x + r], [g.y - r, g.y + r], 0, &mut cells);
                // The markers inside, keyed by id: the sums run in the order of the ids.
                let mut inside: Vec<(u64, u32)> = cells
                    .iter()
                    .flat_map(|&c| bins.list(c).iter().copied())
                    .filter(|&k| {
                        let k = k as usize;
                        g.contains([mk.x[k], mk.y[k], mk.z[k]])
                    })
                    .map(|k| (mk.id[k as usize], k))
                    .collect();
                inside.sort_unstable();
                for (_, k) in inside {
                    let k = k as usize;
                    let b = mk.block[k] as usize;
                    let i = ((mk.z[k] - g.z0) / g.h) as usize;
                    let m = &mut imz.mobilised[i];
                    m.d += mk.frag[k];
                    m.phi += bm.friction[b];
                    m.rho1 += bm.density[b] * (1.0 - bm.n1[b]);
                    m.rho_s += bm.density[b];
                    m.count += 1;
                }
                for m in imz.mobilised.iter_mut().filter(|m| m.count > 0) {
                    let k = m.count as f64;
                    (m.d, m.phi, m.rho1, m.rho_s) = (m.d / k, m.phi / k, m.rho1 / k, m.rho_s / k);
                }
            });
    }

    /// The model's plan box ([x0, x1], [y0, y1]).
    fn plan_box(&self) -> [[f64; 2]; 2] {
        let (o, e) = self.extent;
        [[o[0], o[0] + e[0]], [o[1], o[1] + e[1]]]
    }

    /// The fill of the lowest disks (`fill`) of each drawpoint that drew this period
    /// (`caved`, and a schedule in `row`), the default (no volume, not judged) for the
    /// others.
    fn fills(&self, row: &[f64], caved: &[bool]) -> Vec<Fill> {
        let bm = &self.scene.blocks;
        let which: Vec<(usize, f64)> = (0..row.len())
            .filter(|&d| caved[d] && row[d] > 0.0)
            .map(|d| {
                let b = self.drawpoint_block[d];
                let rho1 = bm.density[b] * (1.0 - bm.n1[b]);
                (d, row[d].max(fill::FILL_MARKERS * self.unit_mass[b]) / rho1)
            })
            .collect();
        let got = fill::fills(
            &self.imzs,
            &which,
            self.plan_box(),
            &self.markers,
            &self.bins,
            bm,
        );
        let mut all = vec![Fill::default(); row.len()];
        for (&(d, _), f) in which.iter().zip(got) {
            all[d] = f;
        }
        all
    }

    /// Writes the period's extraction rows and snapshots, and applies the correction.
    pub(super) fn close_period(&mut self, p: usize, period: i64, drawing: &[usize]) {
        let mut t = self.clock();
        let scene = self.scene;
        let last = p + 1 == scene.periods.len();
        let surface = &self.scenario.outputs.surface_periods;
        let snapshot = &self.scenario.outputs.marker_periods;
        let moment = self.moments.contains(&period);
        if last || surface.contains(&period) || snapshot.contains(&period) {
            // Positions are read exactly: every marker up to date (`engine::cadence`),
            // before the period's tallies are written.
            self.catch_up(period);
        }
        let row = self.schedule.period(p).to_vec();
        let mut caved = vec![false; row.len()];
        drawing.iter().for_each(|&d| caved[d] = true);
        let bm = &scene.blocks;
        self.charge(Phase::PeriodEnd, &mut t);
        let fills = self.fills(&row, &caved);
        self.charge(Phase::Fill, &mut t);
        let ex = &mut self.out.extraction;
        for d in 0..row.len() {
            let (mass, count) = std::mem::take(&mut self.tally[d]);
            let scheduled = row[d];
            if scheduled <= 0.0 && count == 0 {
                continue;
            }
            // Credited the schedule while its lowest disks can feed it, else by its
            // markers (`crediting`).
            let s_end = self.sched_cum[d] + scheduled;
            let stream = &self.streams[d];
            let marker = stream
                .mean_mass()
                .unwrap_or(self.unit_mass[self.drawpoint_block[d]]);
            let trail = (crediting::TRAIL_MARKERS * marker).max(scheduled);
            let step = self.resolution.draw_increment;
            let running_out = fills[d].value().is_some_and(|f| f < fill::EXHAUSTED_FILL);
            let credited = if !caved[d] {
                mass.min(scheduled)
            } else if running_out {
                stream.credit(s_end, scheduled, mass, self.cum[d], (trail, marker, step))
            } else {
                scheduled
            };
            let c = if mass > 0.0 {
                credited / mass
            } else {
                f64::NAN
            };
            self.carry[d] += scheduled - credited;
            self.cum[d] += credited;
            ex.drawpoint.push(d as u32);
            ex.period.push(period);
            ex.scheduled_tonnes.push(scheduled);
            ex.marker_tonnes.push(mass);
            ex.correction.push(c);
            ex.tonnes.push(credited);
            ex.shortfall_tonnes.push(self.carry[d]);
            ex.cum_tonnes.push(self.cum[d]);
            ex.markers.push(count);
            ex.hod.push(hod(self.cum[d], self.hod_density_area[d]));
            ex.air_gap.push(self.imzs[d].air);
            // What was drawn is read from the stream at the end (`read_streams`).
            Tally::new(bm.grades.len(), bm.lithology_names.len())
                .derived()
                .push(ex);
            let imz = &self.imzs[d];
            let short = credited < scheduled;
            ex.status.push(if scheduled <= 0.0 {
                "idle"
            } else if short {
                "short"
            } else {
                "ok"
            });
            ex.fill.push(fills[d].value().unwrap_or(f64::NAN));
            ex.short_reason.push(if short {
                fill::short_reason(caved[d], &fills[d], imz)
            } else {
                ""
            });
        }
        if self.scenario.outputs.imz_every_period || last {
            let imz = &mut self.out.imz;
            for m in &self.imzs {
                for (i, &r) in m.geom.radius.iter().enumerate() {
                    imz.drawpoint.push(m.id as u32);
                    imz.period.push(period);
                    imz.disk.push(i as i64);
                    imz.z_base.push(m.geom.z0 + i as f64 * m.geom.h);
                    imz.z_top.push(m.geom.z0 + (i + 1) as f64 * m.geom.h);
                    imz.radius.push(r);
                }
            }
        }
        self.charge(Phase::PeriodEnd, &mut t);
        self.record_air_gap(period);
        self.charge(Phase::AirGap, &mut t);
        self.trace.record(period, &mut self.out.trace);
        let wanted = &self.scenario.outputs.surface_periods;
        let written = wanted.contains(&period) || (wanted.is_empty() && last);
        if written || moment {
            let h = self.free_surface(period);
            let table = if written {
                &mut self.out.surface
            } else {
                &mut self.out.moment_surface
            };
            surface_rows(&self.lattice, period, &h, table);
        }
        // The end snapshot is read from the markers as `finish` leaves them
        // (`marker_tables`), not made here.
        let wanted = &self.scenario.outputs.marker_periods;
        if wanted.contains(&period) && !last {
            let snap = self.snapshot(period);
            self.out.snapshots.push(snap);
        }
        let stress = &self.scenario.stress;
        if self.scenario.mechanisms.stress
            && (stress.periods.contains(&period) || (stress.periods.is_empty() && last))
        {
            let geoms: Vec<ImzGeom> = self.imzs.iter().map(|m| m.geom.clone()).collect();
            let params = stress::StressParams::new(stress, self.resolution.layer_thickness);
            let mut field = stress::compute(&scene.blocks, period, &geoms, &params, stress);
            field.drawn_tonnes = self.cum.clone();
            self.out.stress.push(field);
        }
        self.charge(Phase::PeriodEnd, &mut t);
    }

    /// Free-surface height of every lattice column (i + n_x j) now, m (`rilling::surface`):
    /// the top of the highest marker, or of the highest site never engulfed.
    pub fn free_surface(&self, period: i64) -> Vec<f64> {
        rilling::surface(
            &self.lattice,
            &self.scene.blocks,
            period,
            &self.engulfed,
            &self.markers,
        )
    }
}

/// Appends a free-surface height field (`Engine::free_surface`) to a surface table, one row
/// per lattice column that has a surface.
fn surface_rows(lat: &Lattice, period: i64, h: &[f64], t: &mut SurfaceTable) {
    for (c, &z) in h.iter().enumerate() {
        if z.is_finite() {
            t.period.push(period);
            t.x.push(lat.centre(0, c % lat.n[0]));
            t.y.push(lat.centre(1, c / lat.n[0]));
            t.z.push(z);
        }
    }
}
