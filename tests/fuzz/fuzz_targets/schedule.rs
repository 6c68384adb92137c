//! A draw schedule from arbitrary text: the long form or the MassFlow wide form (period
//! headers as integers, months, Name%Days), any delimiter.
#![no_main]

use caveflow::io::{parse_period_header, read_schedule_bytes};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(s) = read_schedule_bytes("schedule.csv", data.to_vec()) {
        // What is accepted is finite.
        assert!(s.entries.iter().all(|e| e.tonnes.is_finite()));
        if let Some(p) = &s.periods {
            assert!(p.days.iter().all(|d| d.is_finite() && *d > 0.0));
        }
    }
    if let Ok(h) = std::str::from_utf8(data) {
        if let Ok((_, days)) = parse_period_header(h) {
            assert!(days.is_finite() && days > 0.0);
        }
    }
});
