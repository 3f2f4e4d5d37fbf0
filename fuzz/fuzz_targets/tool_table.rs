//! LinuxCNC tool tables (`--tool-table`) and cutter specs (`--tool
//! ball:2`): any text parses or is refused with its line, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let _ = microcam::gcode::tooltable::ToolTable::parse(&text, false);
    let _ = microcam::gcode::tooltable::ToolTable::parse(&text, true);
    for line in text.lines().take(64) {
        let _ = microcam::cutter::Cutter::parse(line);
    }
});
