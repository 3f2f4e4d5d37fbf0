//! An SVG preview of chains: closed chains blue, open chains red, a dot at
//! each chain's start and an arrow on its first segment showing the
//! direction of travel. Plain text, deterministic, viewable in any browser.

use crate::geometry::{P3, V3};
use crate::model::chain::{Chain, Segment};
use std::fmt::Write;

const CLOSED: &str = "#1565c0";
const OPEN: &str = "#d32f2f";
const POINT: &str = "#2e7d32";

fn n(x: f64) -> String {
    let s = format!("{:.6}", x);
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}

fn tangent_at_start(s: &Segment) -> V3 {
    match s {
        Segment::Line(l) => l.delta().xy().push(0.0),
        Segment::Arc(_) => s.start_tangent(),
    }
}

/// The whole preview as SVG text.
pub fn render(chains: impl Iterator<Item = Chain> + Clone) -> String {
    let mut lo = (f64::INFINITY, f64::INFINITY);
    let mut hi = (f64::NEG_INFINITY, f64::NEG_INFINITY);
    let mut grow = |p: &P3, r: f64| {
        lo = (lo.0.min(p.x - r), lo.1.min(p.y - r));
        hi = (hi.0.max(p.x + r), hi.1.max(p.y + r));
    };
    for c in chains.clone() {
        for s in &c.segments {
            grow(&s.start(), 0.0);
            grow(&s.end(), 0.0);
            if let Some(arc) = s.arc() {
                grow(&arc.center, arc.radius());
            }
        }
        for p in &c.points {
            grow(p, 0.0);
        }
    }
    if !lo.0.is_finite() {
        lo = (0.0, 0.0);
        hi = (1.0, 1.0);
    }
    let diag = ((hi.0 - lo.0).powi(2) + (hi.1 - lo.1).powi(2)).sqrt().max(1e-6);
    let pad = diag * 0.02;
    let (w, h) = (hi.0 - lo.0 + 2.0 * pad, hi.1 - lo.1 + 2.0 * pad);
    let dot = diag / 300.0;
    let arrow = diag / 80.0;
    let mut o = String::new();
    let _ = writeln!(
        o,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" viewBox=\"{} {} {} {}\" width=\"800\" height=\"{}\">",
        n(lo.0 - pad),
        n(-(hi.1 + pad)),
        n(w),
        n(h),
        n((800.0 * h / w).clamp(1.0, 8000.0))
    );
    let _ = writeln!(
        o,
        "<!-- microcam dxf2chains preview: closed chains {CLOSED}, open chains {OPEN}, points {POINT}; dot = start, arrow = direction -->"
    );
    // Y up, as in the drawing.
    // Stroke width in drawing units (a fixed fraction of the drawing), not
    // `vector-effect`, which not every renderer knows.
    let _ = writeln!(
        o,
        "<g transform=\"scale(1,-1)\" fill=\"none\" stroke-width=\"{}\">",
        n(diag / 1500.0)
    );
    for c in chains {
        let colour = if c.closed { CLOSED } else { OPEN };
        if let Some(first) = c.segments.first() {
            let mut d = format!("M{} {}", n(first.start().x), n(first.start().y));
            for s in &c.segments {
                match s {
                    Segment::Line(l) => {
                        let _ = write!(d, " L{} {}", n(l.end.x), n(l.end.y));
                    }
                    Segment::Arc(a) => {
                        let (start, end, center, ccw) = (a.start, a.end, a.center, a.ccw);
                        let (r, sw) = (a.radius(), a.sweep());
                        let flag = if ccw { 1 } else { 0 };
                        if start == end {
                            // SVG cannot draw a full circle as one arc: two halves.
                            let opp = P3::new(2.0 * center.x - start.x, 2.0 * center.y - start.y, 0.0);
                            for p in [opp, end] {
                                let _ = write!(d, " A{} {} 0 0 {} {} {}", n(r), n(r), flag, n(p.x), n(p.y));
                            }
                        } else {
                            let large = if sw.abs() > std::f64::consts::PI { 1 } else { 0 };
                            let _ = write!(d, " A{} {} 0 {} {} {} {}", n(r), n(r), large, flag, n(end.x), n(end.y));
                        }
                    }
                }
            }
            let _ = writeln!(o, "<path id=\"chain{}\" d=\"{d}\" stroke=\"{colour}\"/>", c.id);
            let p = first.start();
            let _ = writeln!(
                o,
                "<circle cx=\"{}\" cy=\"{}\" r=\"{}\" fill=\"{colour}\"/>",
                n(p.x),
                n(p.y),
                n(dot)
            );
            if let Some(t) = tangent_at_start(first).try_normalize(1e-300) {
                let len = first.length();
                let a = arrow.min(len * 0.3);
                let tip = p + t * a;
                let side = V3::new(-t.y, t.x, 0.0) * a * 0.35;
                let (l, r) = (p + side, p - side);
                let _ = writeln!(
                    o,
                    "<polygon points=\"{},{} {},{} {},{}\" fill=\"{colour}\"/>",
                    n(l.x),
                    n(l.y),
                    n(tip.x),
                    n(tip.y),
                    n(r.x),
                    n(r.y)
                );
            }
        }
        for p in &c.points {
            let _ = writeln!(
                o,
                "<circle cx=\"{}\" cy=\"{}\" r=\"{}\" fill=\"{POINT}\"/>",
                n(p.x),
                n(p.y),
                n(dot)
            );
        }
    }
    o.push_str("</g>\n</svg>\n");
    o
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colours_and_full_circle_halves() {
        let c = Chain {
            id: 1,
            closed: true,
            segments: vec![Segment::arc_xy(
                P3::new(1.0, 0.0, 0.0),
                P3::new(1.0, 0.0, 0.0),
                P3::origin(),
                true,
            )],
            ..Default::default()
        };
        let s = render([c].into_iter());
        assert!(s.contains(CLOSED));
        assert_eq!(s.matches(" A1 1 0 0 1 ").count(), 2);
        assert!(s.ends_with("</svg>\n"));
    }
}
