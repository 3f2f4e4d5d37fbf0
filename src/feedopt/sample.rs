//! A pocket like the one Bayesteh 2013 optimised (ch. 3): contour-parallel
//! square passes from the centre outward, cut by a 0.794 mm two-flute end
//! mill at 60,000 rpm and 1 µm per tooth (2 mm/s). The tests, the benchmark
//! and the documentation use it; it is generated, not copied.

use crate::gcode::Dialect;

/// The sample pocket's parameters, mm.
#[derive(Debug, Clone, Copy)]
pub struct Pocket {
    /// Side of the square pocket.
    pub width: f64,
    /// Corner radius of the pocket (the tool-centre passes are its inward
    /// offsets: rounded while the offset radius stays positive, sharp
    /// further in, as a CAM system's contour-parallel passes are).
    pub corner: f64,
    /// Depth below the stock top (z = 0).
    pub depth: f64,
    /// Diameter of the flat end mill that cuts it.
    pub tool_diameter: f64,
    /// Distance between passes.
    pub stepover: f64,
}

impl Default for Pocket {
    fn default() -> Self {
        Pocket {
            width: 3.2,
            corner: 1.0,
            depth: 0.1,
            tool_diameter: 0.794,
            stepover: 0.25,
        }
    }
}

impl Pocket {
    /// Half-size and corner radius of each tool-centre pass, innermost
    /// first.
    pub fn rings(&self) -> Vec<(f64, f64)> {
        let r = 0.5 * self.tool_diameter;
        let outer = 0.5 * self.width - r;
        let mut h = Vec::new();
        let mut k = 0;
        loop {
            let d = self.stepover * k as f64;
            let v = outer - d;
            if v <= 0.05 {
                break;
            }
            h.push((v, (self.corner - r - d).max(0.0)));
            k += 1;
        }
        h.reverse();
        h
    }

    /// The program in `dialect`, at 1 µm per tooth (2 mm/s), with comments
    /// and (ISO) line numbers on some lines so preservation is tested.
    pub fn program(&self, dialect: Dialect) -> String {
        let iso = dialect == Dialect::Iso;
        let mut p = String::new();
        let (feed, plunge) = if iso { ("120", "60") } else { ("2", "1") };
        if iso {
            p.push_str("(sample pocket: 0.794 mm two-flute mill, 60000 rpm, 1 um/tooth)\n");
            p.push_str("N10 G21 G90 G17\nN20 S60000 M3\nN30 G0 Z1\nN40 G0 X0 Y0\n");
            p.push_str(&format!("N50 G1 Z{} F{plunge} (plunge)\n", num(-self.depth)));
        } else {
            p.push_str("; sample pocket: 0.794 mm two-flute mill, 60000 rpm, 1 um/tooth\n");
            p.push_str("OPEN PROG 1 CLEAR\nNORMAL K-1 ABS INC(R)\nRAPID Z1\nRAPID X0 Y0\n");
            p.push_str(&format!("LINEAR Z{} F{plunge} ; plunge\n", num(-self.depth)));
        }
        let line = |p: &mut String, x: f64, y: f64, f: Option<&str>, note: &str| {
            p.push_str(if iso { "G1" } else { "LINEAR" });
            p.push_str(&format!(" X{} Y{}", num(x), num(y)));
            if let Some(f) = f {
                p.push_str(" F");
                p.push_str(f);
            }
            if !note.is_empty() {
                p.push_str(&if iso {
                    format!(" ({note})")
                } else {
                    format!(" ; {note}")
                });
            }
            p.push('\n');
        };
        // A counter-clockwise quarter turn from (x0, y0) to (x, y) about
        // the centre (cx, cy); centres are relative to the start.
        let arc = |p: &mut String, (x0, y0): (f64, f64), (x, y): (f64, f64), (cx, cy): (f64, f64)| {
            p.push_str(if iso { "G3" } else { "CIRCLE2" });
            p.push_str(&format!(
                " X{} Y{} I{} J{}\n",
                num(x),
                num(y),
                num(cx - x0),
                num(cy - y0)
            ));
        };
        for (k, (h, c)) in self.rings().into_iter().enumerate() {
            let f = if k == 0 { Some(feed) } else { None };
            let a = h - c;
            line(&mut p, -a, -h, f, &format!("ring {}", k + 1));
            // Sides and corners, counter-clockwise from the bottom side.
            let corners = [(a, -a), (a, a), (-a, a), (-a, -a)];
            let sides = [
                ((a, -h), (h, -a)),
                ((h, a), (a, h)),
                ((-a, h), (-h, a)),
                ((-h, -a), (-a, -h)),
            ];
            for ((s_end, c_end), ctr) in sides.into_iter().zip(corners) {
                line(&mut p, s_end.0, s_end.1, None, "");
                if c > 0.0 {
                    arc(&mut p, s_end, c_end, ctr);
                }
            }
        }
        if iso {
            p.push_str("N900 G0 Z1\nN910 M5\nN920 M30\n");
        } else {
            p.push_str("RAPID Z1\nCLOSE\n");
        }
        p
    }
}

/// A coordinate to 0.0001 mm, trailing zeros dropped.
fn num(v: f64) -> String {
    let s = format!("{v:.4}");
    let s = s.trim_end_matches('0').trim_end_matches('.').to_string();
    if s == "-0" { "0".to_string() } else { s }
}
