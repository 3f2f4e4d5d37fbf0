//! The small files tools read beside their main input: feedopt's force
//! coefficients (`--force-model`), pathgen pocket's floor surfaces (a
//! Bezier patch as JSON, a grid of points as CSV), pathgen arcfit's point
//! lists, and pmac-send's resume state. Any text parses or is refused with
//! a message, never a panic; what parses is used once (heights sampled,
//! points fitted, the resume point taken).
#![no_main]

use libfuzzer_sys::fuzz_target;
use microcam::pmac::send::{Mode, State};
use microcam::pocket::surface::{BezierPatch, GridSurface, Interp};

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let _ = microcam::feedopt::force::Coefficients::from_json(&text, "fuzz");
    let probes = [(0.0, 0.0), (1.5, -2.5), (-1e9, 1e9), (f64::NAN, 0.5)];
    if let Ok(b) = BezierPatch::from_json(&text) {
        for (x, y) in probes {
            let _ = b.height(x, y);
        }
    }
    for interp in [Interp::Bilinear, Interp::Bicubic] {
        if let Ok(g) = GridSurface::from_csv(&text, interp) {
            for (x, y) in probes {
                let _ = g.height(x, y);
            }
        }
    }
    if let Ok(pts) = microcam::laser::arcfit::parse_points(&text)
        && pts.len() <= 64
    {
        let _ = microcam::laser::arcfit::fit_points(&pts, 0.01, 0.0, false);
        let _ = microcam::laser::arcfit::fit_points(&pts, 0.01, 0.0, true);
    }
    if let Ok(s) = State::from_json(&text, "fuzz") {
        let _ = s.resume_point();
        let _ = s.check_resume("0", Mode::Rotary, std::path::Path::new("fuzz"));
    }
});
