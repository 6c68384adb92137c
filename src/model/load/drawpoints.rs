//! The drawbells and drawpoints tables: opening widths, positions against the block grid
//! and overlapping openings.
//!
//! # Drawpoints
//! Two openings must not intersect (`overlapping-openings`). Opening width = the
//! drawpoint's `width`, else that of its drawbell (its `drawbell` id,
//! else its `bell_type`, joined to `drawbells.name`), else `flow.default_opening_width`.

use std::collections::HashMap;

use super::Loader;
use crate::io::{InputWarning, Table};
use crate::model::{BlockModel, Drawpoints};

/// Largest plausible opening (drawpoint or drawbell) width, m. Drawpoints are 3–6 m wide and
/// drawbells up to about 20 m; a width above 100 m is almost always millimetres
/// (`units-mm`).
pub const MAX_OPENING_WIDTH: f64 = 100.0;

/// The `units-mm` message for an opening width.
fn width_in_mm(what: &str, w: f64) -> String {
    format!(
        "{what} width {w} m is not plausible (more than {MAX_OPENING_WIDTH} m): it looks like mm; divide by 1000 ({} m)",
        w / 1000.0
    )
}

impl Loader {
    /// Drawbell name → width; None when the name or width column is missing.
    pub(super) fn drawbells(&mut self, t: &Table) -> Option<HashMap<String, f64>> {
        let mut widths = HashMap::new();
        let (names, width) = (t.str("name")?, t.f64("width")?);
        for (i, (name, &w)) in names.iter().zip(width).enumerate() {
            if w <= 0.0 {
                self.problem(
                    &t.file,
                    Some(t.row(i)),
                    Some(t.header("width")),
                    "not-positive",
                    format!("drawbell width {w} m must be positive"),
                );
            } else if w > MAX_OPENING_WIDTH {
                self.problem(
                    &t.file,
                    Some(t.row(i)),
                    Some(t.header("width")),
                    "units-mm",
                    width_in_mm("drawbell", w),
                );
            }
            if !name.is_empty() && widths.insert(name.clone(), w).is_some() {
                self.problem(
                    &t.file,
                    Some(t.row(i)),
                    Some(t.header("name")),
                    "duplicate-id",
                    format!("drawbell `{name}` appears more than once"),
                );
            }
        }
        Some(widths)
    }

    /// Drawpoints with their opening widths; None when a required column is missing.
    /// `bells_broken`: a drawbells table was given but could not be read, so drawbell joins
    /// are not checked.
    pub(super) fn drawpoints(
        &mut self,
        t: &Table,
        bells: Option<&HashMap<String, f64>>,
        bells_broken: bool,
        blocks: Option<&BlockModel>,
        default_width: f64,
    ) -> Option<Drawpoints> {
        let file = t.file.as_str();
        let mut d = Drawpoints::default();
        let (names, x, y, z) = (t.str("name")?, t.f64("x")?, t.f64("y")?, t.f64("z")?);
        let empty = vec![String::new(); t.len()];
        let nan = vec![f64::NAN; t.len()];
        let width = t.f64("width").unwrap_or(&nan);
        let (bell, bell_type) = (
            t.str("drawbell").unwrap_or(&empty),
            t.str("bell_type").unwrap_or(&empty),
        );
        let zone = t.str("zone").unwrap_or(&empty);
        let open = t.i64("open_period");
        let mut seen: HashMap<&str, usize> = HashMap::new();
        let mut defaulted = 0;
        for i in 0..names.len().min(x.len()).min(y.len()).min(z.len()) {
            let row = Some(t.row(i));
            let name = names[i].as_str();
            if name.is_empty() {
                // Reported by the reader.
            } else if let Some(&j) = seen.get(name) {
                self.problem(
                    file,
                    row,
                    Some(t.header("name")),
                    "duplicate-id",
                    format!("drawpoint `{name}` is already defined at row {}", t.row(j)),
                );
            } else {
                seen.insert(name, i);
            }
            let keys = [(bell.get(i), "drawbell"), (bell_type.get(i), "bell_type")];
            let keys: Vec<(&str, &str)> = keys
                .iter()
                .filter_map(|(k, c)| k.filter(|k| !k.is_empty()).map(|k| (k.as_str(), *c)))
                .collect();
            let w = match width
                .get(i)
                .copied()
                .filter(|w| !w.is_nan() || t.bad("width", i))
            {
                Some(w) => {
                    if w <= 0.0 {
                        self.problem(
                            file,
                            row,
                            Some(t.header("width")),
                            "not-positive",
                            format!("opening width {w} m must be positive"),
                        );
                    } else if w > MAX_OPENING_WIDTH {
                        self.problem(
                            file,
                            row,
                            Some(t.header("width")),
                            "units-mm",
                            width_in_mm("opening", w),
                        );
                    }
                    w
                }
                None => match bells {
                    Some(b) if !keys.is_empty() => match keys.iter().find_map(|(k, _)| b.get(*k)) {
                        Some(&w) => w,
                        None => {
                            let named: Vec<String> = keys
                                .iter()
                                .map(|(k, c)| format!("{} `{k}`", t.header(c)))
                                .collect();
                            let column = t.header(keys.first().map_or("drawbell", |k| k.1));
                            self.problem(
                                file,
                                row,
                                Some(column),
                                "unknown-drawbell",
                                format!("{} is not in the drawbells table", named.join(" / ")),
                            );
                            default_width
                        }
                    },
                    _ => {
                        if !bells_broken {
                            defaulted += 1;
                        }
                        default_width
                    }
                },
            };
            let located = !(x[i].is_nan() || y[i].is_nan() || z[i].is_nan());
            if let Some(b) = blocks.filter(|b| located && !b.index.is_empty()) {
                let (lo, hi) = (b.origin, b.max_corner());
                let dz = b.size[2];
                if !(x[i] >= lo[0] && x[i] <= hi[0] && y[i] >= lo[1] && y[i] <= hi[1]) {
                    self.problem(file, row, Some(t.header("x")), "outside-model", format!(
                        "drawpoint `{name}` at ({}, {}) lies outside the block grid, which spans x {}..{} and y {}..{}",
                        x[i], y[i], lo[0], hi[0], lo[1], hi[1]
                    ));
                } else if z[i] < lo[2] - dz || z[i] > hi[2] + dz {
                    self.problem(file, row, Some(t.header("z")), "outside-model", format!(
                        "drawpoint `{name}` at z {} is more than one block height ({dz} m) outside the block grid, which spans z {}..{}",
                        z[i], lo[2], hi[2]
                    ));
                }
            }
            d.name.push(name.to_string());
            d.x.push(x[i]);
            d.y.push(y[i]);
            d.z.push(z[i]);
            d.width.push(w);
            d.zone.push(zone.get(i).cloned().unwrap_or_default());
            if let Some(open) = open {
                d.open_period.push(open.get(i).copied().flatten());
            }
        }
        self.overlapping_openings(t, &d);
        if defaulted > 0 {
            self.warnings.push(InputWarning::new(file, "no-opening-width", format!("{defaulted} drawpoint(s) have no opening width (no width column value and no drawbell width); they use flow.default_opening_width = {default_width} m")));
        }
        Some(d)
    }

    /// `overlapping-openings`: two drawpoints whose openings intersect (centres closer than
    /// the mean of their widths, horizontally and vertically). Drawpoints are cut through
    /// pillars; one opening inside another is a duplicated or mistyped row, and the engine
    /// would give all the material to one of them. Each pair is reported once, at the later
    /// row. Drawpoints are swept in x order, so the check is O(n log n) on real layouts.
    fn overlapping_openings(&mut self, t: &Table, d: &Drawpoints) {
        let mut order: Vec<usize> = (0..d.len())
            .filter(|&i| d.x[i].is_finite() && d.y[i].is_finite() && d.z[i].is_finite())
            .filter(|&i| d.width[i].is_finite() && d.width[i] > 0.0)
            .collect();
        order.sort_by(|&a, &b| d.x[a].total_cmp(&d.x[b]));
        let widest = order.iter().map(|&i| d.width[i]).fold(0.0, f64::max);
        for (k, &a) in order.iter().enumerate() {
            for &b in &order[k + 1..] {
                if d.x[b] - d.x[a] >= widest {
                    break;
                }
                let need = 0.5 * (d.width[a] + d.width[b]);
                let apart = (d.x[b] - d.x[a]).hypot(d.y[b] - d.y[a]);
                if apart < need && (d.z[b] - d.z[a]).abs() < need {
                    let (first, later) = if a < b { (a, b) } else { (b, a) };
                    self.problem(&t.file, Some(t.row(later)), Some(t.header("x")), "overlapping-openings", format!(
                        "drawpoint `{}` ({} m wide) overlaps drawpoint `{}` ({} m wide) at row {}: their centres are {apart:.3} m apart, less than the {need:.3} m their openings need",
                        d.name[later], d.width[later], d.name[first], d.width[first], t.row(first)
                    ));
                }
            }
        }
    }
}
