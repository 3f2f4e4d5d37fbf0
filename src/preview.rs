//! SVG previews of a toolpath, seen from above (XY): rapids dashed grey,
//! beam-off feed moves blue, beam-on moves red, corner loops orange. Arcs
//! are drawn as exact SVG arcs, not tessellated, so a preview of a large
//! program stays small and sharp at any zoom.
//!
//! Arcs outside the XY plane are drawn as their chords' projection, which
//! is what a top view shows of them up to their bulge.
#![warn(missing_docs)]

use crate::formats::push_num;
use crate::geometry::{P3, Plane};
use crate::model::toolpath::{MotionKind, Record, Role};

/// Streaming SVG builder: add records one by one, then [`Preview::finish`].
pub struct Preview {
    body: String,
    pos: P3,
    min: (f64, f64),
    max: (f64, f64),
    moves: u64,
}

impl Preview {
    /// An empty preview with the machine at `start` (where the first move
    /// leaves from).
    pub fn new(start: P3) -> Self {
        Preview {
            body: String::new(),
            pos: start,
            min: (start.x, start.y),
            max: (start.x, start.y),
            moves: 0,
        }
    }

    fn grow(&mut self, x: f64, y: f64) {
        self.min = (self.min.0.min(x), self.min.1.min(y));
        self.max = (self.max.0.max(x), self.max.1.max(y));
    }

    /// Add one record.
    pub fn add(&mut self, r: &Record) {
        let Record::Move(m) = r else { return };
        self.moves += 1;
        let class = match (m.kind, m.beam, m.role) {
            (MotionKind::Rapid, _, _) => "rapid",
            (_, true, _) => "on",
            (_, false, Some(Role::Loop)) => "loop",
            _ => "off",
        };
        let b = &mut self.body;
        b.push_str("<path class=\"");
        b.push_str(class);
        b.push_str("\" d=\"M");
        push_num(b, self.pos.x);
        b.push(' ');
        push_num(b, -self.pos.y);
        // XY arcs are drawn exactly from one Arc3 (sweep and extents); a
        // degenerate arc, and arcs in other planes, as their chord.
        let arc = match m.kind {
            MotionKind::Arc(a) if a.plane == Plane::Xy => a.arc(self.pos, m.to),
            _ => None,
        };
        match arc {
            Some(arc) => {
                let (c, r, sweep) = (arc.center, arc.radius(), arc.sweep());
                // SVG cannot draw a full circle in one arc: split into
                // pieces of at most half a turn. In the flipped y of SVG, a
                // counter-clockwise arc has sweep-flag 0.
                let pieces = ((sweep.abs() / std::f64::consts::PI).ceil() as usize).max(1);
                let a0 = (self.pos.y - c.y).atan2(self.pos.x - c.x);
                for i in 1..=pieces {
                    let ang = a0 + sweep * i as f64 / pieces as f64;
                    let (x, y) = (c.x + r * ang.cos(), c.y + r * ang.sin());
                    b.push_str(" A");
                    push_num(b, r);
                    b.push(' ');
                    push_num(b, r);
                    b.push_str(if arc.ccw { " 0 0 0 " } else { " 0 0 1 " });
                    push_num(b, x);
                    b.push(' ');
                    push_num(b, -y);
                }
                let bb = arc.bbox();
                if !bb.is_empty() {
                    self.grow(bb.min.x, bb.min.y);
                    self.grow(bb.max.x, bb.max.y);
                }
            }
            None => {
                b.push_str(" L");
                push_num(b, m.to.x);
                b.push(' ');
                push_num(b, -m.to.y);
            }
        }
        self.body.push_str("\"/>\n");
        self.grow(self.pos.x, self.pos.y);
        self.grow(m.to.x, m.to.y);
        self.pos = m.to;
    }

    /// The SVG document. Stroke widths scale with the drawing so a 10 µm
    /// part and a 100 mm part both preview legibly.
    pub fn finish(self, title: &str) -> String {
        let w = (self.max.0 - self.min.0).max(1e-6);
        let h = (self.max.1 - self.min.1).max(1e-6);
        let pad = 0.05 * w.max(h);
        let stroke = 0.002 * w.max(h);
        let mut s = String::new();
        s.push_str("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<svg xmlns=\"http://www.w3.org/2000/svg\" viewBox=\"");
        push_num(&mut s, self.min.0 - pad);
        s.push(' ');
        push_num(&mut s, -self.max.1 - pad);
        s.push(' ');
        push_num(&mut s, w + 2.0 * pad);
        s.push(' ');
        push_num(&mut s, h + 2.0 * pad);
        s.push_str("\" width=\"800\" height=\"");
        push_num(
            &mut s,
            (800.0 * (h + 2.0 * pad) / (w + 2.0 * pad)).round().clamp(100.0, 4000.0),
        );
        s.push_str("\">\n<title>");
        s.push_str(&xml_escape(title));
        s.push_str("</title>\n<style>path{fill:none;stroke-linecap:round;stroke-width:");
        push_num(&mut s, stroke);
        s.push_str("}.rapid{stroke:#999;stroke-dasharray:");
        push_num(&mut s, 4.0 * stroke);
        s.push(' ');
        push_num(&mut s, 3.0 * stroke);
        s.push_str("}.off{stroke:#2b6cb0}.loop{stroke:#dd6b20}.on{stroke:#c53030;stroke-width:");
        push_num(&mut s, 2.0 * stroke);
        s.push_str("}</style>\n<rect x=\"");
        push_num(&mut s, self.min.0 - pad);
        s.push_str("\" y=\"");
        push_num(&mut s, -self.max.1 - pad);
        s.push_str("\" width=\"100%\" height=\"100%\" fill=\"white\"/>\n");
        s.push_str(&self.body);
        s.push_str("</svg>\n");
        s
    }
}

fn xml_escape(t: &str) -> String {
    t.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gcode::{ReadOptions, read_str};

    #[test]
    fn draws_every_move_with_its_class_and_exact_arcs() {
        let (_, recs) = read_str(
            "G0 X1\nM3\nG1 X2 F10\nG3 X2 Y0 I-1 J0\nM5\nG1 Y-1\n",
            &ReadOptions::default(),
        )
        .unwrap();
        let mut p = Preview::new(P3::origin());
        recs.iter().for_each(|r| p.add(r));
        let svg = p.finish("t<est>");
        assert_eq!(svg.matches("<path class=\"rapid\"").count(), 1);
        assert_eq!(svg.matches("<path class=\"on\"").count(), 2);
        assert_eq!(svg.matches("<path class=\"off\"").count(), 1);
        // The full circle is two half-turn SVG arcs, counter-clockwise.
        assert_eq!(svg.matches(" A1 1 0 0 0 ").count(), 2);
        assert!(svg.contains("<title>t&lt;est&gt;</title>"));
        // The view box holds the circle's left extreme at x = 0 and y = ±1.
        assert!(svg.contains("viewBox=\"-0.1 -1.1 2.2 2.2\""), "{}", &svg[..300]);
    }
}
