//! What comes back from a controller (or a proxy that lies) over the
//! Ethernet protocol: any bytes are a reply, "not yet complete" or an
//! error, never a panic in pmac-send.
#![no_main]

use libfuzzer_sys::fuzz_target;
use microcam::pmac::protocol::{parse_reply, parse_writebuffer_status};

fuzz_target!(|data: &[u8]| {
    let _ = parse_reply(data);
    let _ = parse_writebuffer_status(data);
    let _ = microcam::pmac::controller::parse_status(&String::from_utf8_lossy(data));
});
