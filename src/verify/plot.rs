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

/// Millimetres covered by the map along X and Y: the samples are the
/// centres of cells `dx` × `dy` (the grid steps), so the map spans
/// `nx·dx` × `ny·dy`. A single row or column takes the other axis' step
/// (or 1 mm when both are single).
pub fn extent_mm(xs: &[f64], ys: &[f64]) -> (f64, f64) {
    let step = |v: &[f64]| {
        (v.len() > 1)
            .then(|| (v[v.len() - 1] - v[0]) / (v.len() - 1) as f64)
            .filter(|d| d.is_finite() && *d > 0.0)
    };
    let (dx, dy) = match (step(xs), step(ys)) {
        (Some(a), Some(b)) => (a, b),
        (Some(a), None) => (a, a),
        (None, Some(b)) => (b, b),
        (None, None) => (1.0, 1.0),
    };
    (xs.len().max(1) as f64 * dx, ys.len().max(1) as f64 * dy)
}

/// Pixels per millimetre: about 800 pixels on the long side, at least one
/// pixel per sample along each axis when that needs more, at most 4000
/// pixels on the long side. The same scale on both axes, so the picture's
/// aspect is the region's in millimetres whatever the steps.
fn pixels_per_mm(nx: usize, ny: usize, wx: f64, wy: f64) -> f64 {
    let long = wx.max(wy);
    let want = (800.0 / long).max(nx as f64 / wx).max(ny as f64 / wy);
    want.min(4000.0 / long)
}

/// The map's size in pixels: (width, height, pixels per mm).
fn map_size(xs: &[f64], ys: &[f64]) -> (usize, usize, f64) {
    let (wx, wy) = extent_mm(xs, ys);
    let ppm = pixels_per_mm(xs.len(), ys.len(), wx, wy);
    (
        ((wx * ppm).round() as usize).max(1),
        ((wy * ppm).round() as usize).max(1),
        ppm,
    )
}

/// RGB pixels of the map (`xs.len()` × `ys.len()` samples, row-major, y
/// up, at the grid `xs` × `ys`) scaled by millimetres, not samples, and a
/// legend strip below: (width, height, rgb). Each pixel shows the sample
/// whose cell holds the pixel's centre.
pub fn map_rgb(samples: &[Sample], xs: &[f64], ys: &[f64], band: f64) -> (usize, usize, Vec<u8>) {
    let (nx, ny) = (xs.len(), ys.len());
    let (w, hm, _) = map_size(xs, ys);
    let bar = 16;
    let h = hm + 2 * 8 + bar;
    let mut rgb = vec![255u8; w * h * 3];
    if nx > 0 && ny > 0 {
        let cols: Vec<usize> = (0..w)
            .map(|px| (((px as f64 + 0.5) / w as f64 * nx as f64) as usize).min(nx - 1))
            .collect();
        for row in 0..hm {
            // Row 0 is the top: the last sample row.
            let j = ny - 1 - (((row as f64 + 0.5) / hm as f64 * ny as f64) as usize).min(ny - 1);
            for (px, &i) in cols.iter().enumerate() {
                let c = samples.get(j * nx + i).map_or(GREY, |p| colour(p.deviation(), band));
                let o = (row * w + px) * 3;
                rgb[o..o + 3].copy_from_slice(&c);
            }
        }
    }
    // Legend: gouge, in band (from -band to +band), excess, as bars.
    let y0 = hm + 8;
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

/// The map as SVG with a labelled legend, scaled by millimetres like
/// [`map_rgb`].
pub fn map_svg(samples: &[Sample], xs: &[f64], ys: &[f64], band: f64, title: &str) -> String {
    let (nx, ny) = (xs.len(), ys.len());
    let (wpx, hpx, _) = map_size(xs, ys);
    let (w, h) = (wpx as f64, hpx as f64);
    let (sx, sy) = (w / nx.max(1) as f64, h / ny.max(1) as f64);
    let mut o = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{}\" height=\"{}\" font-family=\"sans-serif\" font-size=\"12\">\n<title>{}</title>\n",
        w + 20.0,
        h + 110.0,
        xml(title)
    );
    for (k, p) in samples.iter().enumerate() {
        let (i, j) = (k % nx.max(1), k / nx.max(1));
        let d = p.deviation();
        o.push_str(&format!(
            "<rect x=\"{:.3}\" y=\"{:.3}\" width=\"{sx:.3}\" height=\"{sy:.3}\" fill=\"{}\"><title>x {:.3} y {:.3} dev {}</title></rect>\n",
            10.0 + i as f64 * sx,
            10.0 + (ny.saturating_sub(1 + j)) as f64 * sy,
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
        let (w, h, rgb) = map_rgb(&[p, p], &[0.0, 1.0], &[0.0], 0.1);
        assert_eq!(rgb.len(), w * h * 3);
        assert_eq!(&rgb[0..3], &EXCESS);
        let svg = map_svg(&[p, p], &[0.0, 1.0], &[0.0], 0.1, "t");
        assert!(svg.contains("excess") && svg.ends_with("</svg>\n"));
        assert!(profiles_svg(&[(1.0, vec![p, p])], 0.1).contains("y = 1 mm"));
    }

    /// Decode an 8-bit RGB PNG of stored deflate blocks (what
    /// `write_png` writes): (width, height, pixels).
    fn decode_png(b: &[u8]) -> (usize, usize, Vec<u8>) {
        assert_eq!(&b[..8], b"\x89PNG\r\n\x1a\n");
        let (mut i, mut w, mut h, mut z) = (8, 0, 0, Vec::new());
        while i < b.len() {
            let n = u32::from_be_bytes(b[i..i + 4].try_into().unwrap()) as usize;
            let data = &b[i + 8..i + 8 + n];
            match &b[i + 4..i + 8] {
                b"IHDR" => {
                    w = u32::from_be_bytes(data[0..4].try_into().unwrap()) as usize;
                    h = u32::from_be_bytes(data[4..8].try_into().unwrap()) as usize;
                    assert_eq!(&data[8..], &[8, 2, 0, 0, 0]);
                }
                b"IDAT" => z.extend_from_slice(data),
                _ => {}
            }
            i += 12 + n;
        }
        let (mut k, mut raw) = (2, Vec::new());
        loop {
            let fin = z[k] & 1;
            assert_eq!(z[k] >> 1 & 3, 0, "stored blocks");
            let n = u16::from_le_bytes([z[k + 1], z[k + 2]]) as usize;
            raw.extend_from_slice(&z[k + 5..k + 5 + n]);
            k += 5 + n;
            if fin == 1 {
                break;
            }
        }
        assert_eq!(raw.len(), h * (3 * w + 1));
        let rgb = raw.chunks(3 * w + 1).flat_map(|r| r[1..].to_vec()).collect();
        (w, h, rgb)
    }

    /// The map's rows: from the top down to the first all-white row (the
    /// gap above the legend).
    fn map_rows(w: usize, h: usize, rgb: &[u8]) -> usize {
        (0..h)
            .find(|&r| rgb[r * w * 3..(r + 1) * w * 3].iter().all(|&c| c == 255))
            .unwrap_or(h)
    }

    #[test]
    fn the_png_map_follows_millimetres_not_samples() {
        // The thesis' grid: 0.1 mm along X over 0..4, 0.25 mm along Y over
        // 10..30: 41 × 81 samples on a 4.1 × 20.25 mm map. Scaled per sample
        // it came out 41:81 (about 1:2), in millimetres it is about 1:5.
        for (xs, ys) in [
            (
                crate::verify::compare::steps(0.0, 4.0, 0.1),
                crate::verify::compare::steps(10.0, 30.0, 0.25),
            ),
            (
                crate::verify::compare::steps(0.0, 30.0, 0.5),
                crate::verify::compare::steps(0.0, 2.0, 0.01),
            ),
            (
                crate::verify::compare::steps(0.0, 5.0, 0.05),
                crate::verify::compare::steps(0.0, 5.0, 0.5),
            ),
        ] {
            let samples: Vec<Sample> = ys
                .iter()
                .flat_map(|&y| {
                    xs.iter().map(move |&x| Sample {
                        x,
                        y,
                        // Gouges left of x = 1 mm, in band elsewhere.
                        design_z: Some(0.0),
                        machined_z: if x < 1.0 { -0.5 } else { 0.0 },
                    })
                })
                .collect();
            let (w, h, rgb) = map_rgb(&samples, &xs, &ys, 0.1);
            let mut png = Vec::new();
            crate::sim::picture::write_png(&mut png, w, h, &rgb).unwrap();
            let (pw, ph, px) = decode_png(&png);
            assert_eq!((pw, ph), (w, h));
            let rows = map_rows(pw, ph, &px);
            let (wx, wy) = extent_mm(&xs, &ys);
            let want = wx / wy;
            let got = pw as f64 / rows as f64;
            // Within a pixel of rounding on either side.
            let slack = want * (1.0 / pw as f64 + 1.0 / rows as f64);
            assert!((got - want).abs() <= slack, "{got} vs {want} ({pw} x {rows} px)");
            // The gouge stripe (x < 1 mm, ~10 samples) is 1 mm wide in pixels.
            let ppm = pw as f64 / wx;
            let red = (0..pw).filter(|&x| px[x * 3..x * 3 + 3] == GOUGE).count() as f64;
            let gouge_mm = (xs.iter().filter(|&&x| x < 1.0).count() as f64) * wx / xs.len() as f64;
            assert!(
                (red / ppm - gouge_mm).abs() <= 1.0 / ppm + 1e-9,
                "{red} px at {ppm} px/mm"
            );
        }
    }
}
