//! The run manifest: what was run, on what, how, and how the mass balanced.
//!
//! Written as pretty JSON (`manifest.json`) last in a run directory, so a directory with a
//! manifest is a complete run. The fields follow the `manifest` table spec in
//! [`crate::schema::MANIFEST`].

use std::path::Path;
use std::time::{SystemTime, UNIX_EPOCH};

use serde::Serialize;

use super::{write_atomic, OutputError};
use crate::engine::fines::Counterflow;
use crate::engine::markers::MarkerCaps;
use crate::engine::result::{MassBalance, ResolvedResolution, RunOutput};
use crate::model::load::InputFile;
use crate::model::Scenario;

/// The run manifest (`manifest.json`).
#[derive(Debug, Clone, Serialize)]
pub struct Manifest {
    /// Crate version that produced the run.
    pub caveflow_version: String,
    /// When the manifest was made, RFC 3339 UTC (`2024-05-01T12:34:56Z`).
    pub created_utc: String,
    /// The command line.
    pub command: String,
    /// Input files with their hashes.
    pub inputs: Vec<InputFile>,
    /// The resolved scenario: every setting, defaults filled in.
    pub scenario: serde_json::Value,
    /// Resolution actually used (automatic choices resolved).
    pub resolution: ResolvedResolution,
    /// Random seed.
    pub seed: u64,
    /// Worker threads.
    pub threads: usize,
    /// Wall time of the run, s.
    pub wall_time_s: f64,
    /// Scheduled, credited and shortfall tonnes, overall and per drawpoint.
    pub mass_balance: MassBalance,
    /// The caps of the marker moves: per cap, the marker steps it cut and the share of the
    /// moved tonne-metres it dropped (`engine::markers::caps`).
    pub marker_caps: MarkerCaps,
    /// Fines percolation's volume across the IMZs' disk bases and the bulk's counterflow
    /// (`engine::fines`; zeros with `mechanisms.fines` off).
    pub percolation: Counterflow,
    /// Warnings raised during the run.
    pub warnings: Vec<String>,
}

impl Manifest {
    /// The manifest of a finished run, stamped with the current time. The seed is the
    /// scenario's.
    pub fn new(
        command: String,
        scenario: &Scenario,
        inputs: Vec<InputFile>,
        run: &RunOutput,
        threads: usize,
        wall_time_s: f64,
    ) -> Manifest {
        Manifest {
            caveflow_version: env!("CARGO_PKG_VERSION").to_string(),
            created_utc: rfc3339_utc(SystemTime::now()),
            command,
            inputs,
            scenario: serde_json::to_value(scenario).expect("a Scenario always serialises to JSON"),
            resolution: run.resolution,
            seed: scenario.seed,
            threads,
            wall_time_s,
            mass_balance: run.balance.clone(),
            marker_caps: run.marker_caps.report(),
            percolation: run.counterflow,
            warnings: run.warnings.iter().map(|w| w.message.clone()).collect(),
        }
    }

    /// Writes the manifest atomically as pretty JSON.
    pub fn write(&self, path: &Path) -> Result<(), OutputError> {
        let mut json = serde_json::to_vec_pretty(self).map_err(|e| OutputError::Encode {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        json.push(b'\n');
        write_atomic(path, &json)
    }
}

/// Formats a time as RFC 3339 UTC to the second, e.g. `2000-02-29T00:00:00Z`. Times before
/// 1970 are clamped to the epoch.
pub fn rfc3339_utc(t: SystemTime) -> String {
    let secs = t.duration_since(UNIX_EPOCH).map_or(0, |d| d.as_secs());
    let (days, rem) = ((secs / 86_400) as i64, secs % 86_400);
    let (y, m, d) = civil_from_days(days);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z",
        rem / 3600,
        rem / 60 % 60,
        rem % 60
    )
}

/// Proleptic Gregorian (year, month, day) of a day count since 1970-01-01
/// (H. Hinnant's `civil_from_days`).
fn civil_from_days(z: i64) -> (i64, u32, u32) {
    let z = z + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097); // day of era, [0, 146096]
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365; // [0, 399]
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100); // [0, 365], from March 1
    let mp = (5 * doy + 2) / 153; // [0, 11], March = 0
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = (if mp < 10 { mp + 3 } else { mp - 9 }) as u32;
    let y = yoe + era * 400 + i64::from(m <= 2);
    (y, m, d)
}
