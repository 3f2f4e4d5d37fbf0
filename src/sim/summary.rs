//! Path summary: lengths by kind, beam-on length, extents, counts.
//! One pass over the records, constant memory.

use crate::geometry::P3;
use crate::model::toolpath::{FeedUnit, MotionKind, Record};

/// Running totals over a toolpath.
#[derive(Debug, Clone, PartialEq)]
pub struct PathSummary {
    /// The unit of the toolpath's feeds (and of `min_feed`, `max_feed`).
    pub feed_unit: FeedUnit,
    /// Records seen, of every kind.
    pub records: u64,
    /// Rapid moves.
    pub rapids: u64,
    /// Straight feed moves.
    pub lines: u64,
    /// Arc moves.
    pub arcs: u64,
    /// Dwells.
    pub dwells: u64,
    /// Length of moves without a feed (rapids), mm.
    pub rapid_length_mm: f64,
    /// Length of moves with a feed, mm (arcs exactly, helix included).
    pub feed_length_mm: f64,
    /// Length of moves with the beam on, mm.
    pub beam_on_length_mm: f64,
    /// Dwell time, s.
    pub dwell_s: f64,
    /// Lowest programmed feed, in `feed_unit`.
    pub min_feed: Option<f64>,
    /// Highest programmed feed, in `feed_unit`.
    pub max_feed: Option<f64>,
    /// Extents of every end point and arc extreme (mm); `None` before the
    /// first move.
    pub bbox: Option<(P3, P3)>,
    pos: P3,
}

impl PathSummary {
    /// Empty totals for a toolpath starting at `start` (mm) with feeds in
    /// `feed_unit`.
    pub fn new(feed_unit: FeedUnit, start: P3) -> Self {
        PathSummary {
            feed_unit,
            records: 0,
            rapids: 0,
            lines: 0,
            arcs: 0,
            dwells: 0,
            rapid_length_mm: 0.0,
            feed_length_mm: 0.0,
            beam_on_length_mm: 0.0,
            dwell_s: 0.0,
            min_feed: None,
            max_feed: None,
            bbox: None,
            pos: start,
        }
    }

    fn grow(&mut self, p: &P3) {
        self.bbox = Some(match self.bbox {
            None => (*p, *p),
            Some((lo, hi)) => (lo.inf(p), hi.sup(p)),
        });
    }

    /// Add one record.
    pub fn add(&mut self, r: &Record) {
        self.records += 1;
        match r {
            Record::Move(m) => {
                if self.bbox.is_none() {
                    let p = self.pos;
                    self.grow(&p);
                }
                let len = match &m.kind {
                    MotionKind::Rapid => {
                        self.rapids += 1;
                        (m.to - self.pos).norm()
                    }
                    MotionKind::Line => {
                        self.lines += 1;
                        (m.to - self.pos).norm()
                    }
                    MotionKind::Arc(a) => {
                        self.arcs += 1;
                        // The geometry kernel's arc: exact length (helical
                        // rise included) and exact extents.
                        match a.arc(self.pos, m.to) {
                            Some(arc) => {
                                let bb = arc.bbox();
                                if !bb.is_empty() {
                                    self.grow(&bb.min);
                                    self.grow(&bb.max);
                                }
                                arc.length()
                            }
                            // Zero radius: readers refuse it; count the chord.
                            None => (m.to - self.pos).norm(),
                        }
                    }
                };
                if let Some(f) = m.feed {
                    self.feed_length_mm += len;
                    self.min_feed = Some(self.min_feed.map_or(f, |x| x.min(f)));
                    self.max_feed = Some(self.max_feed.map_or(f, |x| x.max(f)));
                } else {
                    self.rapid_length_mm += len;
                }
                if m.beam {
                    self.beam_on_length_mm += len;
                }
                self.pos = m.to;
                let p = m.to;
                self.grow(&p);
            }
            Record::Dwell { seconds, .. } => {
                self.dwells += 1;
                self.dwell_s += seconds;
            }
            _ => {}
        }
    }

    /// The summary as a JSON report (`microcam.summary/1`).
    pub fn to_json(&self, source: Option<&str>) -> String {
        use crate::formats::push_str_lit;
        let mut b = String::from("{\"schema\":\"microcam.summary/1\"");
        if let Some(s) = source {
            b.push_str(",\"source\":");
            push_str_lit(&mut b, s);
        }
        self.push_fields(&mut b);
        b.push('}');
        b
    }

    /// Append the summary's fields (`,"records":..`) to a JSON object, so
    /// bigger reports carry them under the same names.
    pub fn push_fields(&self, b: &mut String) {
        use crate::formats::{push_num, push_point3};
        let fields: [(&str, f64); 9] = [
            ("records", self.records as f64),
            ("rapids", self.rapids as f64),
            ("lines", self.lines as f64),
            ("arcs", self.arcs as f64),
            ("dwells", self.dwells as f64),
            ("rapid_length_mm", self.rapid_length_mm),
            ("feed_length_mm", self.feed_length_mm),
            ("beam_on_length_mm", self.beam_on_length_mm),
            ("dwell_s", self.dwell_s),
        ];
        for (k, v) in fields {
            b.push_str(",\"");
            b.push_str(k);
            b.push_str("\":");
            push_num(b, v);
        }
        let unit = match self.feed_unit {
            FeedUnit::MmPerS => "mm_per_s",
            FeedUnit::MmPerMin => "mm_per_min",
        };
        for (k, v) in [("min_feed", self.min_feed), ("max_feed", self.max_feed)] {
            if let Some(v) = v {
                b.push_str(&format!(",\"{k}_{unit}\":"));
                push_num(b, v);
            }
        }
        if let Some((lo, hi)) = self.bbox {
            b.push_str(",\"bbox_min_mm\":");
            push_point3(b, &lo);
            b.push_str(",\"bbox_max_mm\":");
            push_point3(b, &hi);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gcode::{ReadOptions, read_str};

    #[test]
    fn lengths_and_extents_of_a_small_program() {
        let (_, recs) = read_str(
            "G0 X1\nM3\nG1 X2 F10\nG3 X2 Y0 I-1 J0\nM5\nG4 P0.5\n",
            &ReadOptions::default(),
        )
        .unwrap();
        let mut s = PathSummary::new(FeedUnit::MmPerMin, P3::origin());
        recs.iter().for_each(|r| s.add(r));
        assert_eq!((s.rapids, s.lines, s.arcs, s.dwells), (1, 1, 1, 1));
        assert!((s.rapid_length_mm - 1.0).abs() < 1e-12);
        let circle = 2.0 * std::f64::consts::PI;
        assert!((s.feed_length_mm - (1.0 + circle)).abs() < 1e-9);
        assert!((s.beam_on_length_mm - (1.0 + circle)).abs() < 1e-9);
        let (lo, hi) = s.bbox.unwrap();
        assert!((lo - P3::new(0.0, -1.0, 0.0)).norm() < 1e-9);
        assert!((hi - P3::new(2.0, 1.0, 0.0)).norm() < 1e-9);
        assert_eq!(s.dwell_s, 0.5);
    }
}
