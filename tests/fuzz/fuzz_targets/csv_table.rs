//! Every table spec read from arbitrary delimited text (CSV, TSV, semicolons, MassFlow
//! names): the reader must return Ok or a list of problems, never panic.
#![no_main]

use caveflow::io::read_table_bytes;
use caveflow::schema::{BLOCK_MODEL, DRAWBELLS, DRAWPOINTS, PERIODS, SCHEDULE};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    for spec in [&BLOCK_MODEL, &DRAWPOINTS, &DRAWBELLS, &PERIODS, &SCHEDULE] {
        if let Err(p) = read_table_bytes("t.csv", data.to_vec(), spec) {
            // Every rejection names a rule.
            assert!(!p.0.is_empty() && p.0.iter().all(|p| !p.rule.is_empty()));
        }
    }
});
