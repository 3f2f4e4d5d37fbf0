//! A top view of a scan: the design contour, the probe path, the contacts,
//! and the deviation from the design exaggerated along the design normal,
//! with a scale bar giving the exaggerated length.

use super::job::Outcome;
use super::part::{Part, Prim};
use super::scan::MoveKind;
use crate::geometry::P2;
use std::fmt::Write;

/// Render the scan. `exaggerate` multiplies deviations (None: chosen so
/// the largest deviation draws as a twentieth of the picture).
pub fn render(design: &Part, out: &Outcome, re: f64, exaggerate: Option<f64>) -> String {
    let mut pts: Vec<P2> = Vec::new();
    for p in &design.prims {
        pts.extend(sample(p));
    }
    for m in &out.scan.path {
        pts.push(m.from);
        pts.push(m.to);
    }
    let (mut lo, mut hi) = (
        P2::new(f64::INFINITY, f64::INFINITY),
        P2::new(f64::NEG_INFINITY, f64::NEG_INFINITY),
    );
    for p in &pts {
        lo = P2::new(lo.x.min(p.x), lo.y.min(p.y));
        hi = P2::new(hi.x.max(p.x), hi.y.max(p.y));
    }
    if !lo.x.is_finite() {
        lo = P2::new(0.0, 0.0);
        hi = P2::new(1.0, 1.0);
    }
    let size = (hi.x - lo.x).max(hi.y - lo.y).max(1e-6);
    let margin = 0.08 * size;
    let (w, h) = (hi.x - lo.x + 2.0 * margin, hi.y - lo.y + 2.0 * margin + 0.1 * size);
    let px = 800.0 / w.max(h);
    let tx = |p: P2| ((p.x - lo.x + margin) * px, (hi.y - p.y + margin) * px);
    let stroke = 1.0;
    let max_dev = out.deviations.iter().map(|d| d.deviation_mm.abs()).fold(0.0, f64::max);
    let k = exaggerate.unwrap_or(if max_dev > 1e-12 { 0.05 * size / max_dev } else { 1.0 });
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{:.0}" height="{:.0}" viewBox="0 0 {:.1} {:.1}" font-family="sans-serif" font-size="12">"#,
        w * px,
        h * px,
        w * px,
        h * px
    );
    let _ = writeln!(s, r#"<rect width="100%" height="100%" fill="white"/>"#);
    // Design.
    for p in &design.prims {
        let _ = writeln!(
            s,
            r##"<polyline fill="none" stroke="#000" stroke-width="{stroke}" points="{}"/>"##,
            poly(&sample(p), &tx)
        );
    }
    // Path.
    for m in &out.scan.path {
        let (color, dash) = match m.kind {
            MoveKind::Approach => ("#1f6fd1", ""),
            MoveKind::Search => ("#e07b00", ""),
            MoveKind::Travel => ("#999", r#" stroke-dasharray="6 4""#),
            MoveKind::Retract | MoveKind::Reposition => ("#aaa", r#" stroke-dasharray="2 2""#),
        };
        let (a, b) = (tx(m.from), tx(m.to));
        let _ = writeln!(
            s,
            r#"<line x1="{:.2}" y1="{:.2}" x2="{:.2}" y2="{:.2}" stroke="{color}" stroke-width="0.6"{dash}/>"#,
            a.0, a.1, b.0, b.1
        );
    }
    // Contacts (probe centres) and the probe's size at the first one.
    for c in &out.scan.contacts {
        let a = tx(c.center);
        let _ = writeln!(
            s,
            r##"<circle cx="{:.2}" cy="{:.2}" r="1.6" fill="#1f6fd1"/>"##,
            a.0, a.1
        );
    }
    if let Some(c) = out.scan.contacts.first() {
        let a = tx(c.center);
        let _ = writeln!(
            s,
            r##"<circle cx="{:.2}" cy="{:.2}" r="{:.2}" fill="none" stroke="#1f6fd1" stroke-width="0.5"/>"##,
            a.0,
            a.1,
            re * px
        );
    }
    // Exaggerated deviation: each surface point moved off the design by k
    // times its deviation.
    let dev: Vec<P2> = out
        .deviations
        .iter()
        .map(|d| {
            let foot = design.prims[d.prim].nearest(d.surface);
            foot + design_free_normal(design, d.prim, foot) * (d.deviation_mm * k)
        })
        .collect();
    if !dev.is_empty() {
        let _ = writeln!(
            s,
            r##"<polyline fill="none" stroke="#d12f1f" stroke-width="1.2" points="{}"/>"##,
            poly(&dev, &tx)
        );
    }
    // Scale bar: a round deviation, drawn exaggerated.
    let bar_dev = nice(0.1 * size / k);
    let bar = bar_dev * k * px;
    let (x0, y0) = (10.0, h * px - 12.0);
    let _ = writeln!(
        s,
        r##"<line x1="{x0:.1}" y1="{y0:.1}" x2="{:.1}" y2="{y0:.1}" stroke="#d12f1f" stroke-width="3"/>"##,
        x0 + bar
    );
    let _ = writeln!(
        s,
        r##"<text x="{:.1}" y="{:.1}">deviation {} um (x{}) · contacts {} · stop: {}</text>"##,
        x0 + bar + 8.0,
        y0 + 4.0,
        fmt_g(bar_dev * 1000.0),
        fmt_g(k),
        out.scan.contacts.len(),
        out.scan.stop.code()
    );
    s.push_str("</svg>\n");
    s
}

fn design_free_normal(design: &Part, prim: usize, q: P2) -> crate::geometry::V2 {
    let p = design.prims[prim];
    let t = match p {
        Prim::Line { a, b } => (b - a) / (b - a).norm(),
        Prim::Arc { c, .. } => {
            let r = q - c;
            crate::geometry::V2::new(-r.y, r.x) / r.norm().max(1e-300)
        }
    };
    let n = crate::geometry::V2::new(-t.y, t.x);
    if design.in_material(q + n * 1e-7) { -n } else { n }
}

fn sample(p: &Prim) -> Vec<P2> {
    match *p {
        Prim::Line { a, b } => vec![a, b],
        Prim::Arc { r, sweep, .. } => {
            let n = ((sweep.abs() / 0.05).ceil() as usize).clamp(2, 400);
            let len = r * sweep.abs();
            (0..=n).map(|i| p.at(len * i as f64 / n as f64)).collect()
        }
    }
}

fn poly(pts: &[P2], tx: &impl Fn(P2) -> (f64, f64)) -> String {
    let mut s = String::new();
    for p in pts {
        let (x, y) = tx(*p);
        let _ = write!(s, "{x:.2},{y:.2} ");
    }
    s.pop();
    s
}

/// The largest of 1, 2, 5 times a power of ten not above `x`.
fn nice(x: f64) -> f64 {
    if !(x > 0.0 && x.is_finite()) {
        return 1.0;
    }
    let e = 10f64.powf(x.log10().floor());
    [5.0, 2.0, 1.0]
        .into_iter()
        .map(|m| m * e)
        .find(|&v| v <= x)
        .unwrap_or(e)
}

/// A short decimal for labels.
fn fmt_g(x: f64) -> String {
    let s = format!("{:.6}", x);
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if x >= 100.0 { format!("{x:.0}") } else { s.to_string() }
}
