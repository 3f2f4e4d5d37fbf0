//! The CL-data reader (`formats::cldata::read_cldata`: the rows of pathgen
//! dropcutter and stlverify's 3-/5-axis locations) and the conversion to
//! tool locations must turn any bytes into data or an error naming the
//! line, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(d) = microcam::formats::cldata::read_cldata(data) {
        let _ = microcam::verify::cl::locations(&d);
    }
});
