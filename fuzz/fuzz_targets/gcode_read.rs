//! G-code readers must never panic: any bytes, any dialect, errors allowed.
#![no_main]

use libfuzzer_sys::fuzz_target;
use microcam::gcode::{Dialect, ReadOptions, read_str};

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    for dialect in [None, Some(Dialect::Iso), Some(Dialect::Pmac)] {
        let opts = ReadOptions {
            dialect,
            ..ReadOptions::default()
        };
        let _ = read_str(&text, &opts);
    }
});
