//! Top-view SVG of a pocket program coloured by pass kind, as the Iowa
//! State grid-pocket thesis (1999) draws its case study (Figs. 25-28):
//! main path red, wall green, X zigzag blue, Y zigzag dark green; offset
//! loops orange, feed links purple, moves at clearance grey dashed. The
//! boundary is drawn in black. Arcs are drawn by their end points (the
//! final layer's arcs lie in vertical planes, so from above they are
//! straight).

use super::layers::Program;
use super::passes::PassKind;
use crate::formats::push_num;
use crate::geometry::P2;
use std::io::Write;

fn colour(k: Option<PassKind>) -> &'static str {
    match k {
        Some(PassKind::Main) => "#d32f2f",
        Some(PassKind::Wall) => "#388e3c",
        Some(PassKind::XZigzag) => "#1976d2",
        Some(PassKind::YZigzag) => "#1b5e20",
        Some(PassKind::Offset) => "#ef6c00",
        Some(PassKind::Link) => "#7b1fa2",
        None => "#9e9e9e",
    }
}

/// Write the preview; with `only`, just the moves of that pass kind (and
/// the boundary).
pub fn write_svg(out: &mut impl Write, prog: &Program, boundary: &[P2], only: Option<PassKind>) -> std::io::Result<()> {
    let (mut lo, mut hi) = (
        P2::new(f64::INFINITY, f64::INFINITY),
        P2::new(f64::NEG_INFINITY, f64::NEG_INFINITY),
    );
    for p in boundary {
        lo = P2::new(lo.x.min(p.x), lo.y.min(p.y));
        hi = P2::new(hi.x.max(p.x), hi.y.max(p.y));
    }
    if !lo.x.is_finite() {
        (lo, hi) = (P2::origin(), P2::new(1.0, 1.0));
    }
    let span = (hi.x - lo.x).max(hi.y - lo.y).max(1e-6);
    let pad = 0.05 * span;
    let w = span / 500.0;
    let mut s = String::new();
    let num = |s: &mut String, v: f64| push_num(s, (v * 1e6).round() / 1e6);
    s.push_str("<svg xmlns=\"http://www.w3.org/2000/svg\" viewBox=\"");
    num(&mut s, lo.x - pad);
    s.push(' ');
    num(&mut s, -hi.y - pad);
    s.push(' ');
    num(&mut s, hi.x - lo.x + 2.0 * pad);
    s.push(' ');
    num(&mut s, hi.y - lo.y + 2.0 * pad);
    s.push_str("\" width=\"800\" height=\"");
    num(
        &mut s,
        (800.0 * (hi.y - lo.y + 2.0 * pad) / (hi.x - lo.x + 2.0 * pad)).round(),
    );
    s.push_str("\">\n");
    s.push_str("<!-- red: main; green: wall; blue: X zigzag; dark green: Y zigzag; orange: offset loops; purple: feed links; grey dashed: at clearance; black: boundary -->\n");
    s.push_str("<polygon fill=\"none\" stroke=\"#000\" stroke-width=\"");
    num(&mut s, 2.0 * w);
    s.push_str("\" points=\"");
    for p in boundary {
        num(&mut s, p.x);
        s.push(',');
        num(&mut s, -p.y);
        s.push(' ');
    }
    s.push_str("\"/>\n");
    let mut pos: Option<P2> = None;
    // Consecutive moves of one kind become one path element.
    let mut cur: Option<(Option<PassKind>, String)> = None;
    let flush = |s: &mut String, cur: &mut Option<(Option<PassKind>, String)>| {
        if let Some((k, d)) = cur.take() {
            s.push_str("<path fill=\"none\" stroke=\"");
            s.push_str(colour(k));
            s.push_str("\" stroke-width=\"");
            num(s, w);
            s.push('"');
            if k.is_none() {
                s.push_str(" stroke-dasharray=\"");
                num(s, 4.0 * w);
                s.push('"');
            }
            s.push_str(" d=\"");
            s.push_str(&d);
            s.push_str("\"/>\n");
        }
    };
    for (r, k) in prog.records.iter().zip(&prog.kinds) {
        let Some(m) = r.motion() else { continue };
        let to = P2::new(m.to.x, m.to.y);
        let show = only.is_none_or(|o| *k == Some(o));
        if let (Some(p), true) = (pos, show) {
            if cur.as_ref().is_none_or(|(ck, _)| ck != k) {
                flush(&mut s, &mut cur);
                let mut d = String::from("M");
                num(&mut d, p.x);
                d.push(',');
                num(&mut d, -p.y);
                cur = Some((*k, d));
            }
            if (to - p).norm() > 0.0
                && let Some((_, d)) = cur.as_mut()
            {
                d.push('L');
                num(d, to.x);
                d.push(',');
                num(d, -to.y);
            }
        } else {
            flush(&mut s, &mut cur);
        }
        pos = Some(to);
    }
    flush(&mut s, &mut cur);
    s.push_str("</svg>\n");
    out.write_all(s.as_bytes())
}
