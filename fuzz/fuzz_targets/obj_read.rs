//! The OBJ reader must never panic: bad input is an error, not a crash.
#![no_main]

use libfuzzer_sys::fuzz_target;
use microcam::mesh::{Format, ReadOptions, read_bytes, topology};

fuzz_target!(|data: &[u8]| {
    let opts = ReadOptions {
        format: Some(Format::Obj),
        ..Default::default()
    };
    if let Ok(m) = read_bytes(data, &opts)
        && m.mesh.triangles.len() < 4096
    {
        let _ = topology::prepare(&m.mesh, 1e-6);
    }
});
