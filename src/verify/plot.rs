//! Pictures of a comparison: the deviation map (one cell per ray, red for
//! gouges, blue for excess material, green inside the band, darker the
//! farther from zero, grey where nothing was compared) as SVG or RGB for
//! PNG, and the profiles as an SVG plot of deviation against x.

use super::compare::Sample;

const GOUGE: [u8; 3] = [214, 39, 40];
const EXCESS: [u8; 3] = [31, 119, 180];
const GREY: [u8; 3] = [190, 190, 190];

/// Colour of one deviation against ±band.
pub fn colour(d: Option<f64>, band: f64) -> [u8; 3] {
    let Some(d) = d.filter(|d| d.is_finite()) else {
        return GREY;
    };
    if d < -band {
        GOUGE
    } else if d > band {
        EXCESS
    } else {
        // Light green at zero, darker towards the band's edge.
        let f = if band > 0.0 { (d.abs() / band).min(1.0) } else { 0.0 };
        let l = |a: f64, b: f64| (a + (b - a) * f) as u8;
        [l(200.0, 60.0), l(240.0, 160.0), l(200.0, 60.0)]
    }
}

fn hex(c: [u8; 3]) -> String {
    format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])
}

/// Pixels per grid cell so the map is about 800 pixels on its long side.
fn scale(nx: usize, ny: usize) -> usize {
    (800 / nx.max(ny).max(1)).clamp(1, 40)
}

/// RGB pixels of the map (`nx` × `ny` samples, row-major, y up) and a
/// legend strip below: (width, height, rgb).
pub fn map_rgb(samples: &[Sample], nx: usize, ny: usize, band: f64) -> (usize, usize, Vec<u8>) {
    let s = scale(nx, ny);
    let (w, h) = (nx * s, ny * s + 3 * s.max(8));
    let mut rgb = vec![255u8; w * h * 3];
    for (k, p) in samples.iter().enumerate() {
        let (i, j) = (k % nx, k / nx);
        let c = colour(p.deviation(), band);
        for py in 0..s {
            let row = (ny - 1 - j) * s + py;
            for px in 0..s {
                let o = (row * w + i * s + px) * 3;
                rgb[o..o + 3].copy_from_slice(&c);
            }
        }
    }
    // Legend: gouge, in band (from -band to +band), excess, as bars.
    let y0 = ny * s + s.max(8) / 2;
    let bar = 2 * s.max(8);
    for x in 0..w {
        let f = x as f64 / w.max(1) as f64;
        let d = -1.5 * band + 3.0 * band * f;
        let c = colour(Some(d), band);
        for y in y0..(y0 + bar).min(h) {
            let o = (y * w + x) * 3;
            rgb[o..o + 3].copy_from_slice(&c);
        }
    }
    (w, h, rgb)
}

/// The map as SVG with a labelled legend.
pub fn map_svg(samples: &[Sample], xs: &[f64], ys: &[f64], band: f64, title: &str) -> String {
    let (nx, ny) = (xs.len(), ys.len());
    let s = scale(nx, ny) as f64;
    let (w, h) = (nx as f64 * s, ny as f64 * s);
    let mut o = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{}\" height=\"{}\" font-family=\"sans-serif\" font-size=\"12\">\n<title>{}</title>\n",
        w + 20.0,
        h + 110.0,
        xml(title)
    );
    for (k, p) in samples.iter().enumerate() {
        let (i, j) = (k % nx, k / nx);
        let d = p.deviation();
        o.push_str(&format!(
            "<rect x=\"{}\" y=\"{}\" width=\"{s}\" height=\"{s}\" fill=\"{}\"><title>x {:.3} y {:.3} dev {}</title></rect>\n",
            10.0 + i as f64 * s,
            10.0 + (ny - 1 - j) as f64 * s,
            hex(colour(d, band)),
            p.x,
            p.y,
            d.map_or("n/a".to_string(), |d| format!("{d:.4} mm"))
        ));
    }
    let ly = h + 30.0;
    let items = [
        (GOUGE, format!("gouge (over-cut) < -{band} mm")),
        (colour(Some(0.0), band), format!("within ±{band} mm")),
        (EXCESS, format!("excess (under-cut) > +{band} mm")),
        (GREY, "not compared".to_string()),
    ];
    for (k, (c, label)) in items.iter().enumerate() {
        let y = ly + 18.0 * k as f64;
        o.push_str(&format!(
            "<rect x=\"10\" y=\"{y}\" width=\"14\" height=\"14\" fill=\"{}\"/><text x=\"30\" y=\"{}\">{}</text>\n",
            hex(*c),
            y + 12.0,
            xml(label)
        ));
    }
    o.push_str(&format!(
        "<text x=\"10\" y=\"{}\">x {:.3}..{:.3} mm, y {:.3}..{:.3} mm</text>\n</svg>\n",
        h + 22.0,
        xs.first().copied().unwrap_or(0.0),
        xs.last().copied().unwrap_or(0.0),
        ys.first().copied().unwrap_or(0.0),
        ys.last().copied().unwrap_or(0.0)
    ));
    o
}

/// Deviation against x for each profile line, with the band drawn.
pub fn profiles_svg(profiles: &[(f64, Vec<Sample>)], band: f64) -> String {
    let (w, h, m) = (700.0, 360.0, 50.0);
    let pts = profiles.iter().flat_map(|(_, v)| v.iter());
    let (mut x0, mut x1, mut d0, mut d1) = (f64::INFINITY, f64::NEG_INFINITY, -band, band);
    for p in pts {
        x0 = x0.min(p.x);
        x1 = x1.max(p.x);
        if let Some(d) = p.deviation().filter(|d| d.is_finite()) {
            d0 = d0.min(d);
            d1 = d1.max(d);
        }
    }
    if x0.partial_cmp(&x1) != Some(std::cmp::Ordering::Less) {
        x1 = x0 + 1.0;
    }
    let pad = 0.1 * (d1 - d0).max(1e-6);
    let (d0, d1) = (d0 - pad, d1 + pad);
    let sx = |x: f64| m + (x - x0) / (x1 - x0) * (w - 2.0 * m);
    let sy = |d: f64| h - m - (d - d0) / (d1 - d0) * (h - 2.0 * m);
    let mut o = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"{w}\" height=\"{h}\" fill=\"white\"/>\n"
    );
    for (d, dash) in [(band, "4 3"), (-band, "4 3"), (0.0, "")] {
        o.push_str(&format!(
            "<line x1=\"{m}\" x2=\"{}\" y1=\"{y:.2}\" y2=\"{y:.2}\" stroke=\"#888\" stroke-dasharray=\"{dash}\"/><text x=\"{}\" y=\"{:.2}\">{d:+} mm</text>\n",
            w - m,
            w - m + 4.0,
            sy(d) + 4.0,
            y = sy(d)
        ));
    }
    let palette = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b"];
    for (k, (y, v)) in profiles.iter().enumerate() {
        let c = palette[k % palette.len()];
        let mut path = String::new();
        let mut pen = false;
        for p in v {
            match p.deviation().filter(|d| d.is_finite()) {
                Some(d) => {
                    path.push_str(&format!("{}{:.2},{:.2} ", if pen { "L" } else { "M" }, sx(p.x), sy(d)));
                    pen = true;
                }
                None => pen = false,
            }
        }
        o.push_str(&format!(
            "<path d=\"{path}\" fill=\"none\" stroke=\"{c}\"/>\n<text x=\"{}\" y=\"{}\" fill=\"{c}\">y = {y} mm</text>\n",
            m + 10.0 + 110.0 * k as f64,
            20
        ));
    }
    o.push_str(&format!(
        "<text x=\"{}\" y=\"{}\">x, mm ({x0:.3}..{x1:.3})</text>\n<text x=\"4\" y=\"{}\">machined - design, mm</text>\n</svg>\n",
        w / 2.0 - 40.0,
        h - 12.0,
        m - 12.0
    ));
    o
}

fn xml(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colours_and_picture_size() {
        assert_eq!(colour(Some(-0.2), 0.1), GOUGE);
        assert_eq!(colour(Some(0.2), 0.1), EXCESS);
        assert_eq!(colour(None, 0.1), GREY);
        assert_eq!(colour(Some(0.0), 0.1), [200, 240, 200]);
        let p = Sample {
            x: 0.0,
            y: 0.0,
            design_z: Some(0.0),
            machined_z: 0.5,
        };
        let (w, h, rgb) = map_rgb(&[p, p], 2, 1, 0.1);
        assert_eq!(rgb.len(), w * h * 3);
        assert_eq!(&rgb[0..3], &EXCESS);
        let svg = map_svg(&[p, p], &[0.0, 1.0], &[0.0], 0.1, "t");
        assert!(svg.contains("excess") && svg.ends_with("</svg>\n"));
        assert!(profiles_svg(&[(1.0, vec![p, p])], 0.1).contains("y = 1 mm"));
    }
}
