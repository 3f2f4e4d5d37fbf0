//! The toolpath reader must never panic: bad input is an error, not a crash.
#![no_main]

use libfuzzer_sys::fuzz_target;
use microcam::formats::toolpath::ToolpathReader;

fuzz_target!(|data: &[u8]| {
    if let Ok(reader) = ToolpathReader::new(data) {
        for rec in reader {
            // Keep reading past errors: each call must stay panic-free
            // whatever state the previous one left behind.
            let _ = rec;
        }
    }
});
