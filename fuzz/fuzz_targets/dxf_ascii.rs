//! The DXF reader (ASCII form) must never panic, hang or run away in
//! memory: bad input is an error naming the line. What imports goes on
//! through chaining, orientation, the chains writer and the SVG preview,
//! which must not panic either.
#![no_main]

use libfuzzer_sys::fuzz_target;
use microcam::dxf::{ImportOptions, chain, import, svg};
use microcam::formats::chains::ChainsWriter;
use microcam::model::chain::ChainsHeader;
use std::io::Cursor;

fuzz_target!(|data: &[u8]| {
    // A bomb guard small enough that one input stays well under a second.
    let opts = ImportOptions {
        max_segments: 20_000,
        ..Default::default()
    };
    if let Ok(mut imp) = import(Box::new(Cursor::new(data.to_vec())), &opts) {
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
