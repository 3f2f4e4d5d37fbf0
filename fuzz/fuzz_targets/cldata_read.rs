//! Both CL-data readers (the `microcam.cl` rows of pathgen dropcutter and
//! stlverify's 3-/5-axis locations) must turn any bytes into data or an
//! error naming the line, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = microcam::formats::cldata::read_cldata(data);
    let _ = microcam::verify::cl::read_cl(data);
});
