//! What a plough2d run writes: the per-step CSV, the JSON summary, a plot
//! of both area series along the path (SVG) and a top view of the final
//! stock with the path (SVG, or PNG through the project's own encoder).
//! Areas are reported in µm² (a step's chip at these scales is thousands
//! of µm², millionths of a mm²).

use super::{Method, Params, Plough, Step};
use serde::Serialize;
use std::fmt::Write as _;
use std::io::{self, Write};

const UM2: f64 = 1e6;

/// Ploughing fraction of a step (0 when it cut nothing).
fn fraction(chip: f64, plough: f64) -> f64 {
    if chip > 0.0 { plough / chip } else { 0.0 }
}

/// Write the per-step series as CSV.
pub fn write_csv<W: Write>(w: &mut W, steps: &[Step], method: Method) -> io::Result<()> {
    let both = method == Method::Both;
    w.write_all(b"step,line,path_mm,x_mm,y_mm,chip_area_um2,plough_area_um2,plough_fraction")?;
    if both {
        w.write_all(b",exact_chip_area_um2,exact_plough_area_um2")?;
    }
    w.write_all(b"\n")?;
    let mut s = String::with_capacity(128);
    for (i, st) in steps.iter().enumerate() {
        s.clear();
        let line = st.line.map(|l| l.to_string()).unwrap_or_default();
        let _ = write!(
            s,
            "{i},{line},{:.6},{:.6},{:.6},{:.4},{:.4},{:.6}",
            st.path_mm,
            st.x_mm,
            st.y_mm,
            st.chip_mm2 * UM2,
            st.plough_mm2 * UM2,
            fraction(st.chip_mm2, st.plough_mm2)
        );
        if both {
            let (c, p) = st.exact_mm2.unwrap_or((0.0, 0.0));
            let _ = write!(s, ",{:.4},{:.4}", c * UM2, p * UM2);
        }
        s.push('\n');
        w.write_all(s.as_bytes())?;
    }
    Ok(())
}

/// Dexel against exact, over a run with `Method::Both`.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Comparison {
    /// The exact reference's total chip area, µm².
    pub exact_chip_area_um2: f64,
    /// The exact reference's total ploughing area, µm².
    pub exact_plough_area_um2: f64,
    /// Exact ploughing area over exact chip area.
    pub exact_plough_fraction: f64,
    /// |dexel − exact| / exact over the run's totals.
    pub chip_area_rel_diff: f64,
    /// The same for the ploughing area.
    pub plough_area_rel_diff: f64,
    /// Mean over steps of |dexel − exact| chip area, relative to the mean
    /// exact chip area of a step.
    pub step_chip_rel_diff: f64,
}

/// The run's totals (`microcam.plough2d/1`).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct PloughSummary {
    /// `microcam.plough2d/1`.
    pub schema: &'static str,
    /// Where the program came from (its toolpath header's `source`), when
    /// known.
    pub source: Option<String>,
    /// [`Method::name`] of the run.
    pub method: &'static str,
    /// Stock outline x0, y0, x1, y1, mm.
    pub stock_mm: [f64; 4],
    /// Dexel spacing R, µm.
    pub resolution_um: f64,
    /// Cutter diameter D, mm.
    pub tool_diameter_mm: f64,
    /// Cutter teeth N.
    pub teeth: u32,
    /// Scale factor SF on the feed per tooth.
    pub scale_factor: f64,
    /// Minimum chip thickness (scaled model), µm.
    pub min_chip_thickness_um: f64,
    /// Ploughing accuracy T_p, µm.
    pub accuracy_um: f64,
    /// Cutter steps, placings included.
    pub steps: usize,
    /// Steps that cut something.
    pub cutting_steps: usize,
    /// Feed path length at the last step, mm (XY).
    pub path_length_mm: f64,
    /// Total chip area, µm²: the dexel's, or the exact reference's for
    /// `Method::Exact`.
    pub chip_area_um2: f64,
    /// Total ploughing area, µm², from the same method.
    pub plough_area_um2: f64,
    /// Total ploughing area over total chip area.
    pub plough_fraction_of_total: f64,
    /// Mean over cutting steps of each step's ploughing fraction.
    pub mean_plough_fraction: f64,
    /// Largest chip area of one step, µm².
    pub max_chip_area_um2: f64,
    /// Stock area left at the end (dexel), mm².
    pub stock_left_mm2: Option<f64>,
    /// Memory the dexel stock holds at the end: lines and intervals.
    pub dexel_lines: Option<usize>,
    /// Material intervals stored over all dexel lines at the end.
    pub dexel_intervals: Option<usize>,
    /// Dexel against exact, for `Method::Both`.
    pub comparison: Option<Comparison>,
}

fn round(v: f64, digits: i32) -> f64 {
    let k = 10f64.powi(digits);
    (v * k).round() / k
}

/// Totals of a finished run.
pub fn summary(run: &Plough, source: Option<String>) -> PloughSummary {
    let p: &Params = run.params();
    let steps = &run.steps;
    let (mut chip, mut plough, mut fsum, mut cutting, mut max) = (0.0, 0.0, 0.0, 0, 0.0f64);
    for s in steps {
        chip += s.chip_mm2;
        plough += s.plough_mm2;
        max = max.max(s.chip_mm2);
        if s.chip_mm2 > 0.0 {
            cutting += 1;
            fsum += fraction(s.chip_mm2, s.plough_mm2);
        }
    }
    let comparison = (p.method == Method::Both).then(|| {
        let (mut ec, mut ep, mut d) = (0.0, 0.0, 0.0);
        for s in steps {
            let (c, pl) = s.exact_mm2.unwrap_or((0.0, 0.0));
            ec += c;
            ep += pl;
            d += (s.chip_mm2 - c).abs();
        }
        let rel = |a: f64, b: f64| if b > 0.0 { round((a - b).abs() / b, 6) } else { 0.0 };
        Comparison {
            exact_chip_area_um2: round(ec * UM2, 3),
            exact_plough_area_um2: round(ep * UM2, 3),
            exact_plough_fraction: round(fraction(ec, ep), 6),
            chip_area_rel_diff: rel(chip, ec),
            plough_area_rel_diff: rel(plough, ep),
            step_chip_rel_diff: if ec > 0.0 { round(d / ec, 6) } else { 0.0 },
        }
    });
    let stock = run.stock();
    PloughSummary {
        schema: "microcam.plough2d/1",
        source,
        method: p.method.name(),
        stock_mm: p.stock_mm,
        resolution_um: round(p.resolution_mm * 1e3, 6),
        tool_diameter_mm: p.diameter_mm,
        teeth: p.teeth,
        scale_factor: p.scale,
        min_chip_thickness_um: round(p.h_min_mm * 1e3, 6),
        accuracy_um: round(p.accuracy_mm * 1e3, 6),
        steps: steps.len(),
        cutting_steps: cutting,
        path_length_mm: round(steps.last().map_or(0.0, |s| s.path_mm), 6),
        chip_area_um2: round(chip * UM2, 3),
        plough_area_um2: round(plough * UM2, 3),
        plough_fraction_of_total: round(fraction(chip, plough), 6),
        mean_plough_fraction: if cutting > 0 {
            round(fsum / cutting as f64, 6)
        } else {
            0.0
        },
        max_chip_area_um2: round(max * UM2, 3),
        stock_left_mm2: stock.map(|s| round(0.5 * (s.x.area() + s.y.area()), 6)),
        dexel_lines: stock.map(|s| s.x.lines.len() + s.y.lines.len()),
        dexel_intervals: stock.map(|s| s.x.intervals() + s.y.intervals()),
        comparison,
    }
}

/// A plot of chip and ploughing area (µm²) against path position (mm).
pub fn plot_svg(steps: &[Step], title: &str) -> String {
    let (w, h, ml, mr, mt, mb) = (900.0, 360.0, 70.0, 20.0, 30.0, 45.0);
    let xmax = steps.last().map_or(1.0, |s| s.path_mm).max(1e-9);
    let ymax = steps.iter().map(|s| s.chip_mm2 * UM2).fold(0.0, f64::max).max(1e-9) * 1.05;
    let px = |x: f64| ml + x / xmax * (w - ml - mr);
    let py = |y: f64| h - mb - y / ymax * (h - mt - mb);
    let mut s = String::new();
    let _ = writeln!(
        s,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\" font-family=\"sans-serif\" font-size=\"12\">"
    );
    let _ = writeln!(s, "<rect width=\"{w}\" height=\"{h}\" fill=\"white\"/>");
    let _ = writeln!(s, "<text x=\"{ml}\" y=\"18\">{}</text>", xml(title));
    let _ = writeln!(
        s,
        "<path d=\"M{ml} {mt}V{}H{}\" fill=\"none\" stroke=\"black\"/>",
        h - mb,
        w - mr
    );
    for k in 0..=4 {
        let (xv, yv) = (xmax * k as f64 / 4.0, ymax * k as f64 / 4.0);
        let _ = writeln!(
            s,
            "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text>",
            px(xv),
            h - mb + 16.0,
            sig(xv)
        );
        let _ = writeln!(
            s,
            "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">{}</text>",
            ml - 6.0,
            py(yv) + 4.0,
            sig(yv)
        );
    }
    let _ = writeln!(
        s,
        "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">path position, mm</text>",
        (ml + w - mr) / 2.0,
        h - 8.0
    );
    let _ = writeln!(
        s,
        "<text x=\"14\" y=\"{:.1}\" transform=\"rotate(-90 14 {:.1})\" text-anchor=\"middle\">area per step, µm²</text>",
        h / 2.0,
        h / 2.0
    );
    // At most about two points per horizontal pixel and series: the
    // largest value of each bucket, so peaks survive.
    let buckets = 2 * (w - ml - mr) as usize;
    for (get, colour, name, ly) in [
        (0usize, "#1f5fbf", "chip area", 40.0),
        (1, "#d62728", "ploughing area", 56.0),
    ] {
        let mut d = String::new();
        let mut best: Option<(usize, f64, f64)> = None;
        let emit = |d: &mut String, x: f64, y: f64| {
            let _ = write!(d, "{}{:.1} {:.1}", if d.is_empty() { "M" } else { "L" }, px(x), py(y));
        };
        for st in steps {
            let v = if get == 0 { st.chip_mm2 } else { st.plough_mm2 } * UM2;
            let b = ((st.path_mm / xmax) * buckets as f64) as usize;
            match best {
                Some((bb, x, y)) if bb != b => {
                    emit(&mut d, x, y);
                    best = Some((b, st.path_mm, v));
                }
                Some((bb, x, y)) if v > y => best = Some((bb, st.path_mm.max(x), v)),
                None => best = Some((b, st.path_mm, v)),
                _ => {}
            }
        }
        if let Some((_, x, y)) = best {
            emit(&mut d, x, y);
        }
        let _ = writeln!(
            s,
            "<path d=\"{d}\" fill=\"none\" stroke=\"{colour}\" stroke-width=\"1\"/>"
        );
        let _ = writeln!(
            s,
            "<text x=\"{:.1}\" y=\"{ly}\" fill=\"{colour}\" text-anchor=\"end\">{name}</text>",
            w - mr - 4.0
        );
    }
    s.push_str("</svg>\n");
    s
}

fn sig(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if v.abs() >= 100.0 {
        format!("{v:.0}")
    } else if v.abs() >= 1.0 {
        format!("{v:.2}")
    } else {
        format!("{v:.3}")
    }
}

fn xml(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

/// Top view of the final stock (material grey, one stroke per dexel line
/// along X) with the feed moves red and rapids blue.
pub fn stock_svg(run: &Plough, title: &str) -> String {
    let [x0, y0, x1, y1] = run.params().stock_mm;
    let (w, h) = (x1 - x0, y1 - y0);
    let scale = 800.0 / w.max(h);
    let (pw, ph) = (w * scale, h * scale);
    let tx = |x: f64| (x - x0) * scale;
    let ty = |y: f64| (y1 - y) * scale;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{:.0}\" height=\"{:.0}\" viewBox=\"-10 -25 {:.1} {:.1}\" font-family=\"sans-serif\" font-size=\"12\">",
        pw + 20.0,
        ph + 35.0,
        pw + 20.0,
        ph + 35.0
    );
    let _ = writeln!(s, "<text x=\"0\" y=\"-8\">{}</text>", xml(title));
    let _ = writeln!(
        s,
        "<rect x=\"0\" y=\"0\" width=\"{pw:.2}\" height=\"{ph:.2}\" fill=\"white\" stroke=\"black\" stroke-width=\"0.5\"/>"
    );
    if let Some(st) = run.stock() {
        let sw = st.x.spacing * scale;
        let mut d = String::new();
        for (j, line) in st.x.lines.iter().enumerate() {
            let y = ty(st.x.across(j));
            for &(a, b) in line {
                let _ = write!(d, "M{:.2} {y:.2}H{:.2}", tx(a), tx(b));
            }
        }
        let _ = writeln!(
            s,
            "<path d=\"{d}\" stroke=\"#b0b0b0\" stroke-width=\"{:.3}\" fill=\"none\"/>",
            sw * 1.02
        );
    }
    for m in &run.drawn {
        let mut d = String::new();
        for (k, &(x, y)) in m.points.iter().enumerate() {
            let _ = write!(d, "{}{:.2} {:.2}", if k == 0 { "M" } else { "L" }, tx(x), ty(y));
        }
        let (c, dash) = if m.feed {
            ("#d62728", "")
        } else {
            ("#1f5fbf", " stroke-dasharray=\"4 3\"")
        };
        let _ = writeln!(
            s,
            "<path d=\"{d}\" stroke=\"{c}\" stroke-width=\"1\" fill=\"none\"{dash}/>"
        );
    }
    s.push_str("</svg>\n");
    s
}

/// Largest picture side, pixels.
pub const MAX_SIDE: usize = 4096;

/// Top view as RGB pixels (one pixel per dexel spacing, at most
/// [`MAX_SIDE`] on a side): material grey, cut white, path drawn over it.
pub fn stock_rgb(run: &Plough) -> (usize, usize, Vec<u8>) {
    let [x0, y0, x1, y1] = run.params().stock_mm;
    let (w, h) = (x1 - x0, y1 - y0);
    let px = (run.params().resolution_mm).max(w.max(h) / MAX_SIDE as f64);
    let (nw, nh) = (((w / px).ceil() as usize).max(1), ((h / px).ceil() as usize).max(1));
    let mut rgb = vec![255u8; nw * nh * 3];
    let put = |rgb: &mut [u8], i: usize, j: usize, c: [u8; 3]| {
        if i < nw && j < nh {
            let k = ((nh - 1 - j) * nw + i) * 3;
            rgb[k..k + 3].copy_from_slice(&c);
        }
    };
    if let Some(st) = run.stock() {
        for j in 0..nh {
            let y = y0 + (j as f64 + 0.5) * px;
            let l = (((y - st.x.first) / st.x.spacing).round().max(0.0) as usize).min(st.x.lines.len() - 1);
            for &(a, b) in &st.x.lines[l] {
                let i0 = ((a - x0) / px).round().max(0.0) as usize;
                let i1 = (((b - x0) / px).round().max(0.0) as usize).min(nw);
                for i in i0..i1 {
                    put(&mut rgb, i, j, [170, 170, 170]);
                }
            }
        }
    }
    for m in &run.drawn {
        let c = if m.feed { [214, 39, 40] } else { [31, 95, 191] };
        for w2 in m.points.windows(2) {
            let (a, b) = (w2[0], w2[1]);
            let (ax, ay) = ((a.0 - x0) / px, (a.1 - y0) / px);
            let (bx, by) = ((b.0 - x0) / px, (b.1 - y0) / px);
            let n = ((bx - ax).abs().max((by - ay).abs()).ceil() as usize).clamp(1, 1 << 16);
            for k in 0..=n {
                let t = k as f64 / n as f64;
                let (x, y) = (ax + (bx - ax) * t, ay + (by - ay) * t);
                if x >= 0.0 && y >= 0.0 {
                    put(&mut rgb, x as usize, y as usize, c);
                }
            }
        }
    }
    (nw, nh, rgb)
}
