//! The chains reader must never panic: bad input is an error, not a crash.
#![no_main]

use libfuzzer_sys::fuzz_target;
use microcam::formats::chains::ChainsReader;

fuzz_target!(|data: &[u8]| {
    if let Ok(reader) = ChainsReader::new(data) {
        for chain in reader {
            let _ = chain;
        }
    }
});
