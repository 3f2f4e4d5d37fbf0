//! feedopt's report (`microcam.feedopt/1` JSON), the per-step CSV and an
//! SVG of the chip-volume and feed profiles along the path (the plots of
//! Bayesteh 2013 Figs. 3-10 and 3-21).

use super::force::Coefficients;
use super::schedule::{Band, By};
use super::{Mode, SeriesRow, Target};
use crate::formats::{push_num, push_str_lit, push_uint};
use crate::gcode::Dialect;

/// The report's schema name.
pub const SCHEMA: &str = "microcam.feedopt/1";

/// Mean, extremes and spread of a series.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Stats {
    /// Values in the series.
    pub count: u64,
    /// Their mean.
    pub mean: f64,
    /// The smallest value.
    pub min: f64,
    /// The largest value.
    pub max: f64,
    /// Standard deviation.
    pub std: f64,
}

impl Stats {
    /// Figures of `values` (all zero when empty).
    pub fn of(values: impl Iterator<Item = f64>) -> Stats {
        let (mut n, mut sum, mut sq, mut lo, mut hi) = (0u64, 0.0, 0.0, f64::INFINITY, f64::NEG_INFINITY);
        for v in values {
            n += 1;
            sum += v;
            sq += v * v;
            lo = lo.min(v);
            hi = hi.max(v);
        }
        if n == 0 {
            return Stats::default();
        }
        let mean = sum / n as f64;
        Stats {
            count: n,
            mean,
            min: lo,
            max: hi,
            std: (sq / n as f64 - mean * mean).max(0.0).sqrt(),
        }
    }
}

/// Cutting-force figures, before and after.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceFigures {
    /// The coefficients the figures were computed with.
    pub coefficients: Coefficients,
    /// Mean force over the cutting steps, weighted by their machining time,
    /// at the programmed feeds, N.
    pub mean_before_n: f64,
    /// The same at the written feeds, N.
    pub mean_after_n: f64,
    /// Largest one-tooth peak force of a cutting step at the programmed
    /// feeds, N.
    pub peak_before_n: f64,
    /// The same at the written feeds, N.
    pub peak_after_n: f64,
}

/// Everything feedopt reports.
#[derive(Debug, Clone)]
pub struct FeedoptReport {
    /// The mode asked for.
    pub mode: Mode,
    /// The mode whose program was written (split falls back to per-block
    /// when it cannot win).
    pub mode_used: Mode,
    /// What the schedule held constant.
    pub target: Target,
    /// How a block's feed was taken from its steps.
    pub by: By,
    /// The program's dialect (the output keeps it).
    pub dialect: Dialect,
    /// The machine profile's name.
    pub machine: String,
    /// The shortest sub-block split mode allows, s.
    pub min_block_s: f64,
    /// Feed per tooth at the largest chip, mm (reported in µm).
    pub fz_min_mm: f64,
    /// Feed per tooth at the smallest chip, mm (reported in µm).
    pub fz_max_mm: f64,
    /// Teeth of the cutter.
    pub flutes: u32,
    /// Simulation step along the path, mm.
    pub step_mm: f64,
    /// Height-field cell size, mm.
    pub cell_mm: f64,
    /// Moving-average window, mm of path.
    pub window_mm: f64,
    /// Smallest and largest chip cross-section of the cutting steps.
    pub band: Band,
    /// Largest chip volume per tooth allowed: the largest chip at f_min.
    pub chip_cap_mm3: f64,
    /// Predicted cycle time of the input program (gsim's time model), s.
    pub cycle_time_before_s: f64,
    /// Predicted cycle time of the program written, s.
    pub cycle_time_after_s: f64,
    /// Predicted cycle time with one feed per block, s: what split mode
    /// has to beat.
    pub per_block_cycle_time_s: f64,
    /// Chip volume per tooth over the cutting steps at the programmed
    /// feeds, mm³.
    pub chip_before: Stats,
    /// The same at the written feeds, mm³.
    pub chip_after: Stats,
    /// Cutting-force figures, when a force model was given.
    pub force: Option<ForceFigures>,
    /// Feed moves (lines and arcs) in the program.
    pub feed_moves: u64,
    /// Source lines whose text changed (a new F word).
    pub blocks_changed: u64,
    /// Sub-block lines inserted (split and naive modes).
    pub blocks_added: u64,
    /// Things the user should know: rapids that cut, a split that lost,
    /// blocks not split.
    pub notes: Vec<String>,
}

fn field(b: &mut String, k: &str, v: f64) {
    b.push_str(",\"");
    b.push_str(k);
    b.push_str("\":");
    push_num(b, v);
}

fn stats(b: &mut String, k: &str, s: &Stats) {
    b.push_str(",\"");
    b.push_str(k);
    b.push_str("\":{\"steps\":");
    push_uint(b, s.count);
    field(b, "mean_mm3", s.mean);
    field(b, "min_mm3", s.min);
    field(b, "max_mm3", s.max);
    field(b, "spread_mm3", s.max - s.min);
    field(b, "std_mm3", s.std);
    b.push('}');
}

impl FeedoptReport {
    /// Relative change of the predicted cycle time, % (negative = shorter).
    pub fn cycle_time_change_pct(&self) -> f64 {
        if self.cycle_time_before_s > 0.0 {
            100.0 * (self.cycle_time_after_s / self.cycle_time_before_s - 1.0)
        } else {
            0.0
        }
    }

    /// The report as one JSON object.
    pub fn to_json(&self, source: Option<&str>) -> String {
        let mut b = format!("{{\"schema\":\"{SCHEMA}\"");
        if let Some(s) = source {
            b.push_str(",\"source\":");
            push_str_lit(&mut b, s);
        }
        for (k, v) in [
            ("mode", self.mode.name()),
            ("mode_used", self.mode_used.name()),
            (
                "target",
                match self.target {
                    Target::Chip => "chip",
                    Target::Force => "force",
                },
            ),
            (
                "by",
                match self.by {
                    By::Mean => "mean",
                    By::Max => "max",
                },
            ),
            ("dialect", self.dialect.name()),
        ] {
            b.push_str(",\"");
            b.push_str(k);
            b.push_str("\":\"");
            b.push_str(v);
            b.push('"');
        }
        b.push_str(",\"machine\":");
        push_str_lit(&mut b, &self.machine);
        field(&mut b, "min_block_time_s", self.min_block_s);
        field(&mut b, "fz_min_um", self.fz_min_mm * 1e3);
        field(&mut b, "fz_max_um", self.fz_max_mm * 1e3);
        field(&mut b, "flutes", self.flutes as f64);
        field(&mut b, "step_mm", self.step_mm);
        field(&mut b, "cell_mm", self.cell_mm);
        field(&mut b, "window_mm", self.window_mm);
        field(&mut b, "chip_area_min_mm2", self.band.area_min_mm2);
        field(&mut b, "chip_area_max_mm2", self.band.area_max_mm2);
        field(&mut b, "chip_cap_mm3", self.chip_cap_mm3);
        field(&mut b, "cycle_time_before_s", self.cycle_time_before_s);
        field(&mut b, "cycle_time_after_s", self.cycle_time_after_s);
        field(&mut b, "cycle_time_change_pct", self.cycle_time_change_pct());
        field(&mut b, "per_block_cycle_time_s", self.per_block_cycle_time_s);
        stats(&mut b, "chip_volume_per_tooth_before", &self.chip_before);
        stats(&mut b, "chip_volume_per_tooth_after", &self.chip_after);
        if let Some(f) = &self.force {
            b.push_str(",\"force\":{\"model\":\"mechanistic mean over a revolution\"");
            field(&mut b, "ktc_n_mm2", f.coefficients.ktc_n_mm2);
            field(&mut b, "krc_n_mm2", f.coefficients.krc_n_mm2);
            field(&mut b, "kte_n_mm", f.coefficients.kte_n_mm);
            field(&mut b, "kre_n_mm", f.coefficients.kre_n_mm);
            field(&mut b, "mean_before_n", f.mean_before_n);
            field(&mut b, "mean_after_n", f.mean_after_n);
            field(&mut b, "peak_before_n", f.peak_before_n);
            field(&mut b, "peak_after_n", f.peak_after_n);
            b.push('}');
        }
        field(&mut b, "feed_moves", self.feed_moves as f64);
        field(&mut b, "blocks_changed", self.blocks_changed as f64);
        field(&mut b, "blocks_added", self.blocks_added as f64);
        b.push_str(",\"notes\":[");
        for (i, n) in self.notes.iter().enumerate() {
            if i > 0 {
                b.push(',');
            }
            push_str_lit(&mut b, n);
        }
        b.push_str("]}");
        b
    }
}

/// The per-step series as CSV.
pub fn series_csv(rows: &[SeriesRow]) -> String {
    let mut b = String::from(
        "line,x_mm,y_mm,z_mm,path_mm,chip_area_mm2,cutting,fz_before_um,fz_after_um,chip_before_mm3,chip_after_mm3,force_before_n,force_after_n\n",
    );
    for r in rows {
        if let Some(l) = r.line {
            push_uint(&mut b, l);
        }
        for v in [r.end.x, r.end.y, r.end.z, r.s_mm, r.area_mm2] {
            b.push(',');
            push_num(&mut b, v);
        }
        b.push_str(if r.cutting { ",1" } else { ",0" });
        for v in [
            r.fz_before_mm * 1e3,
            r.fz_after_mm * 1e3,
            r.area_mm2 * r.fz_before_mm,
            r.area_mm2 * r.fz_after_mm,
        ] {
            b.push(',');
            push_num(&mut b, v);
        }
        for v in [r.force_before_n, r.force_after_n] {
            b.push(',');
            if let Some(v) = v {
                push_num(&mut b, v);
            }
        }
        b.push('\n');
    }
    b
}

/// Two stacked plots along the path: chip volume per tooth before and
/// after, and feed per tooth before and after.
pub fn profiles_svg(rows: &[SeriesRow], title: &str) -> String {
    let (w, h, pad) = (900.0, 260.0, 40.0);
    let s_max = rows.last().map_or(1.0, |r| r.s_mm).max(1e-9);
    let chip = |r: &SeriesRow, after: bool| r.area_mm2 * if after { r.fz_after_mm } else { r.fz_before_mm };
    let v_max = rows
        .iter()
        .map(|r| chip(r, false).max(chip(r, true)))
        .fold(0.0, f64::max)
        .max(1e-30);
    let f_max = rows
        .iter()
        .map(|r| r.fz_before_mm.max(r.fz_after_mm))
        .fold(0.0, f64::max)
        .max(1e-30);
    let mut b = String::new();
    b.push_str(&format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{}\" viewBox=\"0 0 {w} {}\" font-family=\"sans-serif\" font-size=\"12\">\n",
        2.0 * h,
        2.0 * h
    ));
    b.push_str("<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n");
    let mut esc = String::new();
    push_str_lit(&mut esc, title);
    let esc = esc.trim_matches('"').replace('&', "&amp;").replace('<', "&lt;");
    for (panel, label, top, vmax) in [
        (0, "chip volume per tooth, mm³", 0.0, v_max),
        (1, "feed per tooth, µm", h, f_max * 1e3),
    ] {
        b.push_str(&format!(
            "<text x=\"{pad}\" y=\"{}\">{esc}: {label} (grey before, blue after; max {:.3e}) vs path length 0..{:.3} mm</text>\n",
            top + 16.0,
            vmax,
            s_max
        ));
        b.push_str(&format!(
            "<rect x=\"{pad}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"none\" stroke=\"black\"/>\n",
            top + 24.0,
            w - 2.0 * pad,
            h - 48.0
        ));
        for (after, colour) in [(false, "#999"), (true, "#1f5fbf")] {
            b.push_str(&format!(
                "<polyline fill=\"none\" stroke=\"{colour}\" stroke-width=\"1\" points=\""
            ));
            // At most one point per horizontal pixel pair keeps the file small.
            let stride = (rows.len() / 2000).max(1);
            for r in rows.iter().step_by(stride) {
                let v = if panel == 0 {
                    chip(r, after)
                } else if after {
                    r.fz_after_mm * 1e3
                } else {
                    r.fz_before_mm * 1e3
                };
                let x = pad + (w - 2.0 * pad) * r.s_mm / s_max;
                let y = top + h - 24.0 - (h - 48.0) * (v / vmax).clamp(0.0, 1.0);
                b.push_str(&format!("{x:.1},{y:.1} "));
            }
            b.push_str("\"/>\n");
        }
    }
    b.push_str("</svg>\n");
    b
}

/// Size of the profile picture, pixels: two stacked panels.
pub const PNG_WIDTH: usize = 900;
/// Height of the profile picture, pixels.
pub const PNG_HEIGHT: usize = 520;
/// Colour of the program before in the profile picture (grey), RGB; the
/// background is white.
pub const PNG_BEFORE: [u8; 3] = [150, 150, 150];
/// Colour of the program after (blue), RGB.
pub const PNG_AFTER: [u8; 3] = [31, 95, 191];
/// Colour of the panel frames (black), RGB.
pub const PNG_FRAME: [u8; 3] = [0, 0, 0];

/// The same two profiles as [`profiles_svg`] as RGB pixels (rows top
/// first, [`PNG_WIDTH`] × [`PNG_HEIGHT`]): chip volume per tooth along the
/// path in the upper panel, feed per tooth in the lower one, each scaled to
/// its largest value before or after, path length 0 at the left. Write it
/// with [`crate::sim::picture::write_png`].
///
/// Each series is drawn column by column (the span of its values in the
/// column, joined to the previous column), so the cost is linear in the
/// steps however long the path.
pub fn profiles_rgb(rows: &[SeriesRow]) -> (usize, usize, Vec<u8>) {
    let (w, h) = (PNG_WIDTH, PNG_HEIGHT);
    let (pad, panel) = (40usize, h / 2);
    let mut rgb = vec![255u8; w * h * 3];
    let put = |rgb: &mut [u8], x: usize, y: usize, c: [u8; 3]| {
        if x < w && y < h {
            let k = (y * w + x) * 3;
            rgb[k..k + 3].copy_from_slice(&c);
        }
    };
    let s_max = rows.last().map_or(1.0, |r| r.s_mm).max(1e-9);
    let chip = |r: &SeriesRow, after: bool| r.area_mm2 * if after { r.fz_after_mm } else { r.fz_before_mm };
    let feed = |r: &SeriesRow, after: bool| if after { r.fz_after_mm } else { r.fz_before_mm };
    let (x0, x1) = (pad, w - pad - 1);
    for p in 0..2 {
        let (y0, y1) = (p * panel + 24, p * panel + panel - 24);
        for x in x0..=x1 {
            put(&mut rgb, x, y0, PNG_FRAME);
            put(&mut rgb, x, y1, PNG_FRAME);
        }
        for y in y0..=y1 {
            put(&mut rgb, x0, y, PNG_FRAME);
            put(&mut rgb, x1, y, PNG_FRAME);
        }
        let value = |r: &SeriesRow, after: bool| if p == 0 { chip(r, after) } else { feed(r, after) };
        let vmax = rows
            .iter()
            .map(|r| value(r, false).max(value(r, true)))
            .filter(|v| v.is_finite())
            .fold(0.0, f64::max)
            .max(1e-30);
        // Inside the frame: columns x0+1..x1, rows y0+1..y1 (bottom = 0).
        let (cols, span) = ((x1 - x0 - 1) as f64, (y1 - y0 - 2) as f64);
        for (after, colour) in [(false, PNG_BEFORE), (true, PNG_AFTER)] {
            // Per column: the lowest and highest pixel row of the series.
            let mut lo = vec![usize::MAX; w];
            let mut hi = vec![0usize; w];
            let mut prev: Option<(usize, usize)> = None;
            for r in rows {
                let v = value(r, after);
                let v = if v.is_finite() { (v / vmax).clamp(0.0, 1.0) } else { 0.0 };
                let x = x0 + 1 + (cols * (r.s_mm / s_max).clamp(0.0, 1.0)).round() as usize;
                let y = y1 - 1 - (span * v).round() as usize;
                let x = x.min(x1 - 1);
                // Join to the previous point: its row counts in this column.
                let from = prev.map_or(y, |(px, py)| if px + 1 >= x { py } else { y });
                if let Some((px, py)) = prev.filter(|&(px, _)| px + 1 < x) {
                    // A gap of several columns: a straight line across it.
                    for (c, (l, u)) in lo.iter_mut().zip(hi.iter_mut()).enumerate().take(x).skip(px + 1) {
                        let t = (c - px) as f64 / (x - px) as f64;
                        let yc = (py as f64 + (y as f64 - py as f64) * t).round() as usize;
                        *l = (*l).min(yc);
                        *u = (*u).max(yc);
                    }
                }
                lo[x] = lo[x].min(y.min(from));
                hi[x] = hi[x].max(y.max(from));
                prev = Some((x, y));
            }
            for (x, (&a, &b)) in lo.iter().zip(&hi).enumerate() {
                for y in a..=b {
                    put(&mut rgb, x, y, colour);
                }
            }
        }
    }
    (w, h, rgb)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::P3;

    fn row(s: f64, area: f64, before: f64, after: f64) -> SeriesRow {
        SeriesRow {
            line: Some(1),
            end: P3::origin(),
            s_mm: s,
            area_mm2: area,
            cutting: true,
            fz_before_mm: before,
            fz_after_mm: after,
            force_before_n: None,
            force_after_n: None,
        }
    }

    #[test]
    fn the_picture_draws_both_profiles_in_both_panels() {
        // A chip that rises along the path; the feed after falls with it.
        let rows: Vec<SeriesRow> = (0..=1000)
            .map(|k| {
                let t = k as f64 / 1000.0;
                row(t * 5.0, 0.01 + 0.02 * t, 0.001, 0.0015 - 0.0005 * t)
            })
            .collect();
        let (w, h, rgb) = profiles_rgb(&rows);
        assert_eq!((w, h, rgb.len()), (PNG_WIDTH, PNG_HEIGHT, PNG_WIDTH * PNG_HEIGHT * 3));
        let px = |x: usize, y: usize| [rgb[(y * w + x) * 3], rgb[(y * w + x) * 3 + 1], rgb[(y * w + x) * 3 + 2]];
        let column =
            |x: usize, y0: usize, y1: usize, c: [u8; 3]| (y0..y1).filter(|&y| px(x, y) == c).collect::<Vec<_>>();
        // Feed panel: before is flat at 1 µm (2/3 of the 1.5 µm top), after
        // falls from the top at the left to meet it at the right.
        let (left, right) = (45, w - 45);
        let before_l = column(left, h / 2, h, PNG_BEFORE);
        let after_l = column(left, h / 2, h, PNG_AFTER);
        let after_r = column(right, h / 2, h, PNG_AFTER);
        assert!(!before_l.is_empty() && !after_l.is_empty() && !after_r.is_empty());
        assert!(after_l[0] < before_l[0], "after above before at the start");
        assert!(after_r[0] > after_l[0] + 50, "after falls along the path");
        // Chip panel: both rise left to right.
        let top = |x: usize, c: [u8; 3]| column(x, 0, h / 2, c).first().copied().unwrap_or(0);
        assert!(top(right, PNG_BEFORE) + 50 < top(left, PNG_BEFORE));
        assert!(top(right, PNG_AFTER) < top(left, PNG_AFTER));
        // Frames, and white outside them.
        assert_eq!(px(40, 100), PNG_FRAME);
        assert_eq!(px(5, 5), [255, 255, 255]);
        // No rows draws frames only; never panics.
        let (_, _, empty) = profiles_rgb(&[]);
        assert!(!empty.chunks(3).any(|c| c == PNG_AFTER));
    }
}
