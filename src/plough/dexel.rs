//! Dual-dexel stock (Bayesteh 2013 §5.1): two perpendicular families of
//! lines at spacing R over the W × H stock, each line holding the sorted,
//! disjoint intervals where material remains. Memory grows with the number
//! of lines, (W + H) / R, and with the cuts that cross them, never with
//! W × H cells. Positions along a line are exact (the cutter circle's
//! intersections), so the only discretisation is across the lines.

/// One family: lines parallel to one axis.
#[derive(Debug, Clone)]
pub struct Family {
    /// Coordinate (across the lines) of line 0's centre, mm.
    pub first: f64,
    /// Spacing between lines (the strip each line stands for), mm.
    pub spacing: f64,
    /// Material intervals along each line, sorted and disjoint, mm.
    pub lines: Vec<Vec<(f64, f64)>>,
}

/// A piece of material one cut took off one line: the strip
/// `[along0, along1] × [across − spacing/2, across + spacing/2]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Removed {
    /// Where the removed piece begins along the line, mm (in the stock's
    /// own axes: X for a line along X).
    pub along0: f64,
    /// Where it ends along the line, mm; `along1 > along0`.
    pub along1: f64,
    /// The line's coordinate across (its strip's centre), mm.
    pub across: f64,
}

impl Family {
    /// `n` lines spread evenly over `[lo, hi]` across, each full over
    /// `[a0, a1]` along.
    fn new(lo: f64, hi: f64, n: usize, a0: f64, a1: f64) -> Family {
        let spacing = (hi - lo) / n as f64;
        Family {
            first: lo + 0.5 * spacing,
            spacing,
            lines: vec![vec![(a0, a1)]; n],
        }
    }

    /// Coordinate across of line `j`.
    pub fn across(&self, j: usize) -> f64 {
        self.first + j as f64 * self.spacing
    }

    /// Remove the disc of radius `r` centred at (`along`, `across`) in this
    /// family's frame; push every removed piece to `out`. Returns the area
    /// removed, mm² (length × spacing).
    pub fn cut_disc(&mut self, along: f64, across: f64, r: f64, out: &mut Vec<Removed>) -> f64 {
        if self.lines.is_empty() {
            return 0.0;
        }
        let j0 = ((across - r - self.first) / self.spacing).ceil().max(0.0) as usize;
        let j1f = ((across + r - self.first) / self.spacing).floor();
        if j1f < 0.0 {
            return 0.0;
        }
        let j1 = (j1f as usize).min(self.lines.len() - 1);
        let mut len = 0.0;
        for j in j0..=j1 {
            let y = self.across(j);
            let d = y - across;
            let w2 = r * r - d * d;
            if w2 <= 0.0 {
                continue;
            }
            let w = w2.sqrt();
            len += subtract(&mut self.lines[j], along - w, along + w, y, out);
        }
        len * self.spacing
    }

    /// Material area this family holds, mm².
    pub fn area(&self) -> f64 {
        self.lines
            .iter()
            .map(|l| l.iter().map(|(a, b)| b - a).sum::<f64>())
            .sum::<f64>()
            * self.spacing
    }

    /// Intervals stored over all lines (memory use).
    pub fn intervals(&self) -> usize {
        self.lines.iter().map(Vec::len).sum()
    }
}

/// Remove `[lo, hi]` from the sorted intervals of one line; returns the
/// length removed.
fn subtract(line: &mut Vec<(f64, f64)>, lo: f64, hi: f64, across: f64, out: &mut Vec<Removed>) -> f64 {
    // First interval that ends after `lo`.
    let i0 = line.partition_point(|iv| iv.1 <= lo);
    let mut i1 = i0;
    while i1 < line.len() && line[i1].0 < hi {
        i1 += 1;
    }
    if i0 == i1 {
        return 0.0;
    }
    let mut len = 0.0;
    for &(a, b) in &line[i0..i1] {
        let (ra, rb) = (a.max(lo), b.min(hi));
        if rb > ra {
            len += rb - ra;
            out.push(Removed {
                along0: ra,
                along1: rb,
                across,
            });
        }
    }
    let (first, last) = (line[i0], line[i1 - 1]);
    let mut keep: Vec<(f64, f64)> = Vec::with_capacity(2);
    if first.0 < lo {
        keep.push((first.0, lo));
    }
    if last.1 > hi {
        keep.push((hi, last.1));
    }
    line.splice(i0..i1, keep);
    len
}

/// The stock as two dexel families: `x` holds lines along X (one per row
/// of width R in Y), `y` lines along Y.
#[derive(Debug, Clone)]
pub struct DualDexel {
    /// Stock outline: x0, y0, x1, y1, mm.
    pub bounds: [f64; 4],
    /// Lines along X, one per row of Y (they see a cut's extent in X).
    pub x: Family,
    /// Lines along Y, one per column of X.
    pub y: Family,
}

impl DualDexel {
    /// Stock `bounds` (x0, y0, x1, y1) at resolution `r` mm: at least one
    /// line per `r` across each side.
    pub fn new(bounds: [f64; 4], r: f64) -> DualDexel {
        let [x0, y0, x1, y1] = bounds;
        let ny = line_count(y1 - y0, r);
        let nx = line_count(x1 - x0, r);
        DualDexel {
            bounds,
            x: Family::new(y0, y1, ny, x0, x1),
            y: Family::new(x0, x1, nx, y0, y1),
        }
    }

    /// Remove the cutter disc at (`cx`, `cy`), radius `r`; the removed
    /// pieces of each family go to `rx`, `ry` (cleared first). Returns the
    /// area removed as each family sees it, mm².
    pub fn cut(&mut self, cx: f64, cy: f64, r: f64, rx: &mut Vec<Removed>, ry: &mut Vec<Removed>) -> (f64, f64) {
        rx.clear();
        ry.clear();
        let ax = self.x.cut_disc(cx, cy, r, rx);
        let ay = self.y.cut_disc(cy, cx, r, ry);
        (ax, ay)
    }
}

/// Lines needed to cover `side` at spacing at most `r`.
pub fn line_count(side: f64, r: f64) -> usize {
    ((side / r) - 1e-9).ceil().max(1.0) as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn subtract_splits_trims_and_drops() {
        let mut out = Vec::new();
        let mut l = vec![(0.0, 10.0)];
        assert_eq!(subtract(&mut l, 2.0, 3.0, 0.0, &mut out), 1.0);
        assert_eq!(l, vec![(0.0, 2.0), (3.0, 10.0)]);
        assert_eq!(subtract(&mut l, 1.0, 5.0, 0.0, &mut out), 3.0);
        assert_eq!(l, vec![(0.0, 1.0), (5.0, 10.0)]);
        assert_eq!(subtract(&mut l, -1.0, 11.0, 0.0, &mut out), 6.0);
        assert!(l.is_empty());
        assert_eq!(out.len(), 5);
        // Nothing left to remove.
        assert_eq!(subtract(&mut l, 0.0, 1.0, 0.0, &mut out), 0.0);
    }

    #[test]
    fn a_disc_in_fresh_stock_removes_its_area() {
        let mut s = DualDexel::new([0.0, 0.0, 4.0, 4.0], 0.01);
        let (mut rx, mut ry) = (Vec::new(), Vec::new());
        let (ax, ay) = s.cut(2.0, 2.0, 1.0, &mut rx, &mut ry);
        let pi = std::f64::consts::PI;
        assert!((ax - pi).abs() < 2e-3 * pi, "{ax}");
        assert!((ay - pi).abs() < 2e-3 * pi, "{ay}");
        assert!((s.x.area() - (16.0 - ax)).abs() < 1e-9);
        // The same disc again removes nothing.
        assert_eq!(s.cut(2.0, 2.0, 1.0, &mut rx, &mut ry), (0.0, 0.0));
        assert!(rx.is_empty() && ry.is_empty());
    }

    #[test]
    fn a_disc_half_outside_removes_half() {
        let mut s = DualDexel::new([0.0, 0.0, 4.0, 4.0], 0.005);
        let (mut rx, mut ry) = (Vec::new(), Vec::new());
        let (ax, _) = s.cut(4.0, 2.0, 1.0, &mut rx, &mut ry);
        let half = std::f64::consts::PI / 2.0;
        assert!((ax - half).abs() < 2e-3 * half, "{ax}");
    }
}
