//! G-code readers must never panic: any bytes, any dialect, errors allowed.
#![no_main]

use libfuzzer_sys::fuzz_target;
use microcam::gcode::{Dialect, ReadOptions, read_str};

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    for dialect in [None, Some(Dialect::Iso), Some(Dialect::Pmac)] {
        let opts = ReadOptions {
            dialect,
            // A loop whose condition never changes is stopped by this
            // bound; at the default (1,000,000 iterations, seconds of
            // work) every mutation of such a loop is a libFuzzer timeout
            // and ends the run. 1,000 runs the same code, bound included;
            // at 10,000 the few inputs with long loops took 90 % of the
            // fuzzer's time (up to 0.8 s each).
            max_loop_iterations: 1_000,
            ..ReadOptions::default()
        };
        let _ = read_str(&text, &opts);
    }
});
