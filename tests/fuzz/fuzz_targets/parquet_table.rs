//! Arbitrary bytes as a Parquet block model and schedule. The parquet crate panics on some
//! corrupt files; caveflow must catch that and report `unreadable`, never crash.
#![no_main]

use std::io::Write;

use caveflow::io::{read_schedule, read_table};
use caveflow::schema::BLOCK_MODEL;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut f = tempfile::Builder::new()
        .suffix(".parquet")
        .tempfile()
        .expect("temp file");
    f.write_all(data).expect("write");
    let _ = read_table(f.path(), &BLOCK_MODEL);
    let _ = read_schedule(f.path());
});
