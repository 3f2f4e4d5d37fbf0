//! A top-view picture of the simulated stock with the toolpath drawn over
//! it, as PNG (no image crate: stored deflate blocks are enough for a
//! picture a person looks at once).
//!
//! One pixel per stock cell, at most [`MAX_SIDE`] on a side (coarser cells
//! are sampled). Height is shaded light (top) to dark (bottom) with a
//! hill-shade from the north-west so shallow cuts show; feed moves are drawn
//! red, rapids blue, into an overlay as the simulation runs, so memory does
//! not grow with the program.

use super::stock::Stock;
use crate::geometry::P3;
use std::io::{self, Write};

/// Largest picture side, pixels.
pub const MAX_SIDE: usize = 4096;

/// The path overlay, drawn while moves are simulated.
pub struct Overlay {
    w: usize,
    h: usize,
    x0: f64,
    y0: f64,
    /// mm per pixel.
    px: f64,
    /// 0 nothing, 1 rapid, 2 feed.
    ink: Vec<u8>,
}

impl Overlay {
    /// An empty overlay with the picture's pixels over `s`: one per cell,
    /// or per block of cells when the stock is wider than [`MAX_SIDE`].
    pub fn for_stock(s: &Stock) -> Overlay {
        let step = s.nx.max(s.ny).div_ceil(MAX_SIDE).max(1);
        let (w, h) = (s.nx.div_ceil(step), s.ny.div_ceil(step));
        Overlay {
            w,
            h,
            x0: s.x0,
            y0: s.y0,
            px: s.cell * step as f64,
            ink: vec![0; w * h],
        }
    }

    /// Draw a straight move (arcs come as chords).
    pub fn line(&mut self, a: &P3, b: &P3, feed: bool) {
        let (ax, ay) = ((a.x - self.x0) / self.px, (a.y - self.y0) / self.px);
        let (bx, by) = ((b.x - self.x0) / self.px, (b.y - self.y0) / self.px);
        let n = ((bx - ax).abs().max((by - ay).abs()).ceil() as usize).clamp(1, 1 << 16);
        let v = if feed { 2 } else { 1 };
        for k in 0..=n {
            let t = k as f64 / n as f64;
            let (x, y) = (ax + (bx - ax) * t, ay + (by - ay) * t);
            if x >= 0.0 && y >= 0.0 && (x as usize) < self.w && (y as usize) < self.h {
                let i = (self.h - 1 - y as usize) * self.w + x as usize;
                // Feed moves win over rapids where both pass.
                self.ink[i] = self.ink[i].max(v);
            }
        }
    }

    /// RGB pixels, rows top (north) first.
    pub fn render(&self, s: &Stock) -> (usize, usize, Vec<u8>) {
        let step = s.nx.max(s.ny).div_ceil(MAX_SIDE).max(1);
        let span = (s.top - s.bottom).max(1e-12);
        let z = |i: usize, j: usize| s.z[j.min(s.ny - 1) * s.nx + i.min(s.nx - 1)];
        let mut rgb = Vec::with_capacity(self.w * self.h * 3);
        for row in 0..self.h {
            let j = (self.h - 1 - row) * step;
            for col in 0..self.w {
                let i = col * step;
                let ink = self.ink[row * self.w + col];
                let px = match ink {
                    2 => [220, 30, 30],
                    1 => [40, 90, 230],
                    _ => {
                        let zc = z(i, j);
                        let level = (zc - s.bottom) / span;
                        // Slope towards a light in the north-west, in units
                        // of the stock depth per cell, so cuts of any depth
                        // show their walls.
                        let gx = z(i + step, j) - z(i.saturating_sub(step), j);
                        let gy = z(i, j + step) - z(i, j.saturating_sub(step));
                        let shade = ((-gx + gy) / span * 4.0).clamp(-0.3, 0.3);
                        let g = ((0.25 + 0.65 * level + shade).clamp(0.0, 1.0) * 255.0) as u8;
                        [g, g, g]
                    }
                };
                rgb.extend_from_slice(&px);
            }
        }
        (self.w, self.h, rgb)
    }
}

fn crc32(data: &[u8], mut c: u32) -> u32 {
    c = !c;
    for &b in data {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
        }
    }
    !c
}

fn chunk<W: Write>(w: &mut W, kind: &[u8; 4], data: &[u8]) -> io::Result<()> {
    w.write_all(&(data.len() as u32).to_be_bytes())?;
    w.write_all(kind)?;
    w.write_all(data)?;
    let c = crc32(data, crc32(kind, 0));
    w.write_all(&c.to_be_bytes())
}

/// Write an 8-bit RGB PNG with uncompressed (stored) deflate blocks.
pub fn write_png<W: Write>(w: &mut W, width: usize, height: usize, rgb: &[u8]) -> io::Result<()> {
    w.write_all(b"\x89PNG\r\n\x1a\n")?;
    let mut ihdr = Vec::with_capacity(13);
    ihdr.extend_from_slice(&(width as u32).to_be_bytes());
    ihdr.extend_from_slice(&(height as u32).to_be_bytes());
    ihdr.extend_from_slice(&[8, 2, 0, 0, 0]);
    chunk(w, b"IHDR", &ihdr)?;
    // Scanlines with filter byte 0.
    let mut raw = Vec::with_capacity(height * (width * 3 + 1));
    for row in rgb.chunks(width * 3) {
        raw.push(0);
        raw.extend_from_slice(row);
    }
    let mut z = vec![0x78, 0x01];
    let mut blocks = raw.chunks(65_535).peekable();
    if blocks.peek().is_none() {
        z.extend_from_slice(&[1, 0, 0, 0xff, 0xff]);
    }
    while let Some(b) = blocks.next() {
        z.push(u8::from(blocks.peek().is_none()));
        let n = b.len() as u16;
        z.extend_from_slice(&n.to_le_bytes());
        z.extend_from_slice(&(!n).to_le_bytes());
        z.extend_from_slice(b);
    }
    let (mut s1, mut s2) = (1u32, 0u32);
    for &b in &raw {
        s1 = (s1 + b as u32) % 65_521;
        s2 = (s2 + s1) % 65_521;
    }
    z.extend_from_slice(&((s2 << 16) | s1).to_be_bytes());
    chunk(w, b"IDAT", &z)?;
    chunk(w, b"IEND", &[])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cutter::Cutter;

    #[test]
    fn png_structure_and_checksums() {
        // The CRC of "IEND" with no data is a well-known constant.
        assert_eq!(crc32(b"IEND", 0), 0xAE42_6082);
        let mut out = Vec::new();
        write_png(&mut out, 2, 1, &[255, 0, 0, 0, 0, 255]).unwrap();
        assert_eq!(&out[..8], b"\x89PNG\r\n\x1a\n");
        assert_eq!(&out[out.len() - 12..], b"\0\0\0\0IEND\xaeB`\x82");
        // IDAT: zlib header, one final stored block of 7 bytes, Adler-32.
        let idat = &out[33..];
        assert_eq!(&idat[4..8], b"IDAT");
        assert_eq!(&idat[8..15], &[0x78, 0x01, 1, 7, 0, 0xf8, 0xff]);
        assert_eq!(&idat[15..22], &[0, 255, 0, 0, 0, 0, 255]);
    }

    #[test]
    fn the_picture_shows_the_cut_and_the_path() {
        let mut s = Stock::new(P3::new(0.0, 0.0, -1.0), P3::new(4.0, 2.0, 0.0), 0.1).unwrap();
        let mut o = Overlay::for_stock(&s);
        let (a, b) = (P3::new(0.5, 1.0, -0.5), P3::new(3.5, 1.0, -0.5));
        s.cut_line(&a, &b, &Cutter::Flat { radius: 0.4 });
        o.line(&a, &b, true);
        o.line(&P3::new(0.0, 0.2, 1.0), &P3::new(4.0, 0.2, 1.0), false);
        let (w, h, rgb) = o.render(&s);
        assert_eq!((w, h), (40, 20));
        let px = |x: usize, y: usize| &rgb[(y * w + x) * 3..(y * w + x) * 3 + 3];
        // The path row, a rapid near the bottom edge (rows count from the
        // top, north up), uncut stock light, the slot beside the path dark.
        let row = |y_mm: f64| h - 1 - (y_mm / 0.1) as usize;
        assert_eq!(px(20, row(1.0)), [220, 30, 30]);
        assert_eq!(px(20, row(0.2)), [40, 90, 230]);
        let (top, slot) = (px(20, 3)[0], px(20, 12)[0]);
        assert!(top > slot + 60, "{top} vs {slot}");
    }
}
