//! Arbitrary scenario TOML: parsed, checked and resolved, or refused with a message.
#![no_main]

use std::path::Path;

use caveflow::model::Scenario;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let _ = Scenario::from_toml(text, "scenario.toml", &[], Path::new("/base"));
});
