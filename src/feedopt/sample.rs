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
    /// Depth below the stock top (z = 0).
    pub depth: f64,
    pub tool_diameter: f64,
    /// Distance between passes.
    pub stepover: f64,
}

impl Default for Pocket {
    fn default() -> Self {
        Pocket {
            width: 3.2,
            depth: 0.1,
            tool_diameter: 0.794,
            stepover: 0.25,
        }
    }
}

impl Pocket {
    /// Half-sizes of the tool-centre squares, innermost first.
    pub fn rings(&self) -> Vec<f64> {
        let outer = 0.5 * (self.width - self.tool_diameter);
        let mut h = Vec::new();
        let mut k = 0;
        loop {
            let v = outer - self.stepover * k as f64;
            if v <= 0.05 {
                break;
            }
            h.push(v);
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
        let num = |v: f64| {
            let s = format!("{v:.4}");
            let s = s.trim_end_matches('0').trim_end_matches('.').to_string();
            if s == "-0" { "0".to_string() } else { s }
        };
        let (feed, plunge) = if iso { ("120", "60") } else { ("2", "1") };
        if iso {
            p.push_str("(sample pocket: 0.794 mm two-flute mill, 60000 rpm, 1 um/tooth)\n");
            p.push_str("N10 G21 G90 G17\nN20 S60000 M3\nN30 G0 Z1\nN40 G0 X0 Y0\n");
            p.push_str(&format!("N50 G1 Z{} F{plunge} (plunge)\n", num(-self.depth)));
        } else {
            p.push_str("; sample pocket: 0.794 mm two-flute mill, 60000 rpm, 1 um/tooth\n");
            p.push_str("OPEN PROG 1 CLEAR\nNORMAL K-1 ABS\nRAPID Z1\nRAPID X0 Y0\n");
            p.push_str(&format!("LINEAR Z{} F{plunge} ; plunge\n", num(-self.depth)));
        }
        let mv = |p: &mut String, x: f64, y: f64, f: Option<&str>, note: &str| {
            p.push_str(if iso { "G1 X" } else { "X" });
            p.push_str(&num(x));
            p.push_str(" Y");
            p.push_str(&num(y));
            if let Some(f) = f {
                p.push_str(" F");
                p.push_str(f);
            }
            if !note.is_empty() {
                p.push_str(if iso { " (" } else { " ; " });
                p.push_str(note);
                if iso {
                    p.push(')');
                }
            }
            p.push('\n');
        };
        for (k, h) in self.rings().into_iter().enumerate() {
            let f = if k == 0 { Some(feed) } else { None };
            mv(&mut p, -h, -h, f, &format!("ring {}", k + 1));
            mv(&mut p, h, -h, None, "");
            mv(&mut p, h, h, None, "");
            mv(&mut p, -h, h, None, "");
            mv(&mut p, -h, -h, None, "");
        }
        if iso {
            p.push_str("N900 G0 Z1\nN910 M5\nN920 M30\n");
        } else {
            p.push_str("RAPID Z1\nCLOSE\n");
        }
        p
    }
}
