//! SVG preview of a toolpath: beam-on cuts, beam-off feed moves, loops and
//! rapids in different colours, each pass's start marked and numbered in
//! cutting order, with an arrow showing the direction.

use super::setup::LaserSetup;
use crate::formats::push_num;
use crate::geometry::P3;
use crate::geometry::bbox::BBox3;
use crate::model::toolpath::{MotionKind, Record, Role};
use std::io::Write;

fn style(beam: bool, role: Option<Role>, rapid: bool) -> (&'static str, &'static str) {
    if rapid {
        return ("#9e9e9e", "stroke-dasharray=\"2 2\"");
    }
    match (beam, role) {
        (true, _) => ("#d32f2f", ""),
        (false, Some(Role::Loop)) => ("#1976d2", ""),
        (false, Some(Role::LeadIn | Role::LeadOut)) => ("#388e3c", ""),
        _ => ("#7b1fa2", ""),
    }
}

/// Write the preview. Y is flipped so the drawing reads as in CAD.
pub fn write_svg(out: &mut impl Write, records: &[Record], _m: &LaserSetup) -> std::io::Result<()> {
    let mut bb = BBox3::empty();
    for r in records {
        if let Some(m) = r.motion() {
            bb.extend(&m.to);
        }
    }
    if bb.is_empty() {
        bb.extend(&P3::origin());
    }
    let size = bb.size();
    let span = size.x.max(size.y).max(1e-6);
    let pad = 0.05 * span;
    let w = 1.0 / 600.0 * span; // stroke: ~1 px of a 600 px picture
    let mut s = String::new();
    // Round to 0.1 nm-ish so previews stay small and byte-identical.
    let num = |s: &mut String, v: f64| push_num(s, (v * 1e6).round() / 1e6);
    s.push_str("<svg xmlns=\"http://www.w3.org/2000/svg\" viewBox=\"");
    num(&mut s, bb.min.x - pad);
    s.push(' ');
    num(&mut s, -bb.max.y - pad);
    s.push(' ');
    num(&mut s, size.x + 2.0 * pad);
    s.push(' ');
    num(&mut s, size.y + 2.0 * pad);
    s.push_str("\" width=\"800\">\n");
    s.push_str(
        "<!-- red: beam on; green: lead-in/out; blue: corner loops; purple: other beam-off; grey dashed: rapids -->\n",
    );
    let mut pos = P3::origin();
    let mut order = 0u64;
    for r in records {
        let Some(m) = r.motion() else { continue };
        let (colour, extra) = style(m.beam, m.role, m.kind == MotionKind::Rapid);
        s.push_str("<path fill=\"none\" stroke=\"");
        s.push_str(colour);
        s.push_str("\" stroke-width=\"");
        num(&mut s, w);
        s.push_str("\" ");
        s.push_str(extra);
        s.push_str(" d=\"M");
        num(&mut s, pos.x);
        s.push(' ');
        num(&mut s, -pos.y);
        match m.kind {
            MotionKind::Arc(a) if a.plane == crate::geometry::Plane::Xy => {
                let r = (pos.xy() - a.center.xy()).norm();
                let arc = a.arc(pos, m.to);
                let sweep = arc.map_or(0.0, |x| x.sweep());
                // SVG cannot draw a full turn in one arc: go via the midpoint.
                let mid = arc.map_or(m.to, |x| x.point_at(0.5));
                for p in [mid, m.to] {
                    s.push_str(" A");
                    num(&mut s, r);
                    s.push(' ');
                    num(&mut s, r);
                    s.push_str(" 0 ");
                    s.push(if sweep.abs() / 2.0 > std::f64::consts::PI {
                        '1'
                    } else {
                        '0'
                    });
                    // Y is flipped, so counter-clockwise becomes sweep-flag 0.
                    s.push_str(if a.ccw { " 0 " } else { " 1 " });
                    num(&mut s, p.x);
                    s.push(' ');
                    num(&mut s, -p.y);
                }
            }
            _ => {
                s.push_str(" L");
                num(&mut s, m.to.x);
                s.push(' ');
                num(&mut s, -m.to.y);
            }
        }
        s.push_str("\"/>\n");
        if m.role == Some(Role::LeadIn) && !m.beam && m.kind == MotionKind::Line {
            // Start of a pass: dot, order number and direction arrow.
            order += 1;
            let d = (m.to - pos).xy();
            let d = if d.norm() > 0.0 { d.normalize() } else { d };
            let (x, y) = (m.to.x, -m.to.y);
            s.push_str("<circle fill=\"#000\" r=\"");
            num(&mut s, 2.5 * w);
            s.push_str("\" cx=\"");
            num(&mut s, x);
            s.push_str("\" cy=\"");
            num(&mut s, y);
            s.push_str("\"/>\n<text font-size=\"");
            num(&mut s, 12.0 * w);
            s.push_str("\" x=\"");
            num(&mut s, x + 3.0 * w);
            s.push_str("\" y=\"");
            num(&mut s, y - 3.0 * w);
            s.push_str("\">");
            s.push_str(&order.to_string());
            s.push_str("</text>\n<path fill=\"none\" stroke=\"#000\" stroke-width=\"");
            num(&mut s, w);
            s.push_str("\" d=\"M");
            let (tx, ty) = (x + 8.0 * w * d.x, y - 8.0 * w * d.y);
            num(&mut s, tx - 3.0 * w * (d.x - 0.6 * d.y));
            s.push(' ');
            num(&mut s, ty + 3.0 * w * (d.y + 0.6 * d.x));
            s.push_str(" L");
            num(&mut s, tx);
            s.push(' ');
            num(&mut s, ty);
            s.push_str(" L");
            num(&mut s, tx - 3.0 * w * (d.x + 0.6 * d.y));
            s.push(' ');
            num(&mut s, ty + 3.0 * w * (d.y - 0.6 * d.x));
            s.push_str("\"/>\n");
        }
        pos = m.to;
        if s.len() > 1 << 16 {
            out.write_all(s.as_bytes())?;
            s.clear();
        }
    }
    s.push_str("</svg>\n");
    out.write_all(s.as_bytes())
}
