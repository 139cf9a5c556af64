//! The PLY (ASCII and binary) reader on arbitrary bytes: it may refuse them, never panic,
//! hang or allocate beyond what the input can describe.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let _ = voltrack::io::read_ply(Path::new("fuzz.ply"), data);
});
