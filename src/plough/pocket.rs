//! An example pocket program, made here for the documentation, the tests
//! and the benchmark (the thesis's own programs are not available): a rectangular pocket cleared like a CAM
//! pocketing cycle (Bayesteh 2013 §5.3 machined five such pockets with a
//! 0.794 mm two-flute end mill). The cutter plunges on the pocket's long
//! centre line, cuts a full-immersion slot along it, then widens it in
//! stadium-shaped loops (straight sides, semicircular G3 ends) one
//! step-over apart, and finishes along the rectangle of the walls, which
//! also clears the corners the loops leave.

use crate::gcode::Dialect;
use crate::gcode::writer::{WriteOptions, write_string};
use crate::geometry::{P3, Plane};
use crate::model::toolpath::{ArcData, FeedUnit, Motion, MotionKind, Record};

/// The pocket and how it is cut.
#[derive(Debug, Clone, PartialEq)]
pub struct Pocket {
    /// Pocket centre, mm.
    pub center: (f64, f64),
    /// Pocket width (X), mm; at least the height.
    pub width: f64,
    /// Pocket height (Y), mm.
    pub height: f64,
    /// Cutter diameter, mm.
    pub tool_diameter: f64,
    /// Distance between loops, mm.
    pub step_over: f64,
    /// Feed, mm/s.
    pub feed_mm_s: f64,
    /// Spindle speed written into the program (S), rpm.
    pub rpm: f64,
}

impl Pocket {
    /// The example in the documentation: a 3 × 2 mm pocket centred in a 4 × 3 mm
    /// stock, 0.794 mm cutter, 0.3 mm step-over, 60,000 rpm.
    pub fn example(feed_mm_s: f64) -> Pocket {
        Pocket {
            center: (2.0, 1.5),
            width: 3.0,
            height: 2.0,
            tool_diameter: 0.794,
            step_over: 0.3,
            feed_mm_s,
            rpm: 60_000.0,
        }
    }

    /// The stock the example pocket is cut in: x0, y0, x1, y1, mm.
    pub const EXAMPLE_STOCK: [f64; 4] = [0.0, 0.0, 4.0, 3.0];

    /// The toolpath (feeds in mm/s).
    pub fn records(&self) -> Vec<Record> {
        let r = 0.5 * self.tool_diameter;
        let (cx, cy) = self.center;
        let half_len = 0.5 * (self.width - self.height).max(0.0);
        let (xl, xr) = (cx - half_len, cx + half_len);
        let dmax = (0.5 * self.height - r).max(0.0);
        let f = Some(self.feed_mm_s);
        let mut out = vec![Record::Spindle {
            rpm: self.rpm,
            block: None,
        }];
        let mv = |kind: MotionKind, x: f64, y: f64, z: f64, feed: Option<f64>| {
            Record::Move(Motion::bare(kind, P3::new(x, y, z), feed))
        };
        let ccw = |ox: f64, oy: f64| {
            MotionKind::Arc(ArcData {
                center: P3::new(ox, oy, -0.05),
                ccw: true,
                plane: Plane::Xy,
                extra_turns: 0,
            })
        };
        let z = -0.05;
        out.push(mv(MotionKind::Rapid, xl, cy, 1.0, None));
        out.push(mv(MotionKind::Line, xl, cy, z, f));
        out.push(mv(MotionKind::Line, xr, cy, z, f));
        let mut d = 0.0;
        while d < dmax - 1e-9 {
            d = (d + self.step_over).min(dmax);
            out.push(mv(MotionKind::Line, xr, cy - d, z, f));
            out.push(mv(ccw(xr, cy), xr, cy + d, z, f));
            out.push(mv(MotionKind::Line, xl, cy + d, z, f));
            out.push(mv(ccw(xl, cy), xl, cy - d, z, f));
            out.push(mv(MotionKind::Line, xr, cy - d, z, f));
        }
        // The walls: a rectangle at one radius from them.
        let (x0, x1) = (cx - 0.5 * self.width + r, cx + 0.5 * self.width - r);
        let (y0, y1) = (cy - dmax, cy + dmax);
        for (x, y) in [(x1, y0), (x1, y1), (x0, y1), (x0, y0), (xr, y0)] {
            out.push(mv(MotionKind::Line, x, y, z, f));
        }
        out.push(mv(MotionKind::Rapid, xr, y0, 1.0, None));
        out
    }

    /// The program in `dialect` (PMAC feeds in mm/s, ISO in mm/min).
    pub fn program(&self, dialect: Dialect) -> String {
        let mut opts = WriteOptions::for_dialect(dialect);
        opts.start = P3::new(self.center.0, self.center.1, 1.0);
        // Our own records are always well formed.
        write_string(opts, FeedUnit::MmPerS, &self.records()).unwrap_or_default()
    }
}
