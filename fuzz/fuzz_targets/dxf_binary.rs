//! The DXF reader (binary form) must never panic, hang or run away in
//! memory: bad input is an error naming the line. What imports goes on
//! through chaining, orientation, the chains writer and the SVG preview,
//! which must not panic either.
#![no_main]

use libfuzzer_sys::fuzz_target;
use microcam::dxf::{ImportOptions, chain, import, svg};
use microcam::formats::chains::ChainsWriter;
use microcam::model::chain::ChainsHeader;
use std::io::Cursor;

/// Every input is read as binary DXF: the sentinel is prepended unless the
/// input starts with it already.
const SENTINEL: &[u8] = b"AutoCAD Binary DXF\r\n\x1a\0";

fuzz_target!(|data: &[u8]| {
    let bytes = if data.starts_with(SENTINEL) {
        data.to_vec()
    } else {
        [SENTINEL, data].concat()
    };
    // A bomb guard small enough that one input stays cheap. Binary
    // doubles make wild spline control points easy to mutate into, and the
    // fuzzer grows its corpus towards inputs that fit as many arcs as the
    // guard allows (each loop count a new coverage feature): at 20,000 a
    // grown corpus ran at 200 executions a second a core, nearly all of it
    // in the biarc fit. At 2,000, the fit bounded by what is left of it,
    // every code path is still reached (the guard itself included), at a
    // tenth of the work per input; sizes past it are unit-tested.
    let opts = ImportOptions {
        max_segments: 2_000,
        ..Default::default()
    };
    if let Ok(mut imp) = import(Box::new(Cursor::new(bytes)), &opts) {
        let segs = std::mem::take(&mut imp.sink.segments);
        let (chains, _) = chain::build(segs, &imp.sink.points, &imp.sink.layers, 0.001);
        // Written out as dxf2chains does, and previewed.
        let mut w = ChainsWriter::new(Vec::new());
        w.header(&ChainsHeader { source: None }).unwrap();
        for c in chains.iter() {
            w.chain(&c).unwrap();
        }
        w.finish().unwrap();
        let _ = svg::render(chains.iter());
    }
});
