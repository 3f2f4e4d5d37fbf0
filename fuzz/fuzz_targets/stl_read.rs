//! The STL reader must never panic: bad input is an error, not a crash.
//! Every mesh it accepts goes on through welding, the topology report,
//! the repairs and one section, which must not panic either.
#![no_main]

use libfuzzer_sys::fuzz_target;
use microcam::mesh::{Format, ReadOptions, read_bytes, topology};
use microcam::slice;

fuzz_target!(|data: &[u8]| {
    let opts = ReadOptions {
        format: Some(Format::Stl),
        ..Default::default()
    };
    if let Ok(m) = read_bytes(data, &opts)
        && m.mesh.triangles.len() < 4096
    {
        let p = topology::prepare(&m.mesh, 1e-6);
        let b = p.mesh.bbox();
        if !b.is_empty() {
            let z = 0.5 * (b.min.z + b.max.z);
            let _ = slice::section(&p.mesh, z, &slice::SliceOptions::default());
        }
    }
    // Content sniffing too.
    let _ = read_bytes(data, &ReadOptions::default());
});
