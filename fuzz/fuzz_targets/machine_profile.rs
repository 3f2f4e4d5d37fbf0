//! Machine profiles are JSON a user writes by hand: any text must load or
//! give an error, and what loads must survive the derived figures every
//! tool asks of it.
#![no_main]

use libfuzzer_sys::fuzz_target;
use microcam::machine::Machine;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    if let Ok(m) = Machine::from_json(&text, "fuzz.json") {
        let shutter = m.shutter_or_instant();
        let _ = (shutter.open_latency_s(), shutter.close_latency_s(), m.block_time_s());
    }
});
