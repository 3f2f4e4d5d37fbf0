//! The pocket's bottom surface, z = S(x, y): a bicubic Bezier patch from a
//! 4x4 net of Z control values over a rectangle (the Iowa State grid-pocket
//! thesis (1999) §3.1 models the bottom this way, Z control points on a
//! uniform XY net), measured grid points (the thesis' reverse-engineering
//! case, §4.5: probe or CMM points on a regular XY grid) interpolated
//! bilinearly or bicubically, or a flat floor.
//!
//! Outside its rectangle a surface keeps its edge values (the parameter is
//! clamped), so the cutter's footprint near a wall always has a height.

use super::PocketError;

/// Interpolation of measured grid points.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Interp {
    /// Piecewise bilinear: exact at the points, kinks between cells.
    Bilinear,
    /// Catmull-Rom bicubic: exact at the points, C1 between cells.
    Bicubic,
}

/// A bicubic Bezier patch: x = x0 + u·(x1 - x0), y = y0 + v·(y1 - y0),
/// z = Σ B_i(u) B_j(v) z\[j\]\[i\] (row j runs along X at v = j/3).
#[derive(Debug, Clone, PartialEq)]
pub struct BezierPatch {
    /// The rectangle's X range x0 < x1, mm.
    pub x: [f64; 2],
    /// The rectangle's Y range y0 < y1, mm.
    pub y: [f64; 2],
    /// Control heights, `z[j][i]`: row `j` (Y index), column `i` (X index).
    pub z: [[f64; 4]; 4],
}

/// Measured heights on a regular grid.
#[derive(Debug, Clone, PartialEq)]
pub struct GridSurface {
    /// The grid's X values, increasing, mm (at least two).
    pub xs: Vec<f64>,
    /// The grid's Y values, increasing, mm (at least two).
    pub ys: Vec<f64>,
    /// Row-major heights, `z[j * xs.len() + i]`.
    pub z: Vec<f64>,
    /// How heights between the points are found.
    pub interp: Interp,
}

/// The bottom of the pocket.
#[derive(Debug, Clone, PartialEq)]
pub enum Surface {
    /// A flat floor at this height.
    Flat(f64),
    /// A designed bottom: a bicubic Bezier patch.
    Bezier(BezierPatch),
    /// A measured bottom: heights on a regular grid.
    Grid(GridSurface),
}

fn bernstein(t: f64) -> [f64; 4] {
    let s = 1.0 - t;
    [s * s * s, 3.0 * t * s * s, 3.0 * t * t * s, t * t * t]
}

impl BezierPatch {
    /// A patch over `[x0,x1] × [y0,y1]` from 16 heights in rows of
    /// increasing Y, each row of increasing X.
    pub fn new(x: [f64; 2], y: [f64; 2], z16: &[f64]) -> Result<BezierPatch, PocketError> {
        if z16.len() != 16 || z16.iter().any(|v| !v.is_finite()) {
            return Err(PocketError::Input(format!(
                "a Bezier patch needs 16 finite control heights, got {}",
                z16.len()
            )));
        }
        if !(x[1] > x[0] && y[1] > y[0] && x.iter().chain(&y).all(|v| v.is_finite())) {
            return Err(PocketError::Input(
                "the patch rectangle needs x0 < x1 and y0 < y1".into(),
            ));
        }
        let mut z = [[0.0; 4]; 4];
        for (k, v) in z16.iter().enumerate() {
            z[k / 4][k % 4] = *v;
        }
        Ok(BezierPatch { x, y, z })
    }

    /// Height at (x, y), the parameters clamped to the patch.
    pub fn height(&self, x: f64, y: f64) -> f64 {
        let u = ((x - self.x[0]) / (self.x[1] - self.x[0])).clamp(0.0, 1.0);
        let v = ((y - self.y[0]) / (self.y[1] - self.y[0])).clamp(0.0, 1.0);
        let (bu, bv) = (bernstein(u), bernstein(v));
        let mut s = 0.0;
        for (w, zr) in bv.iter().zip(&self.z) {
            s += w * (bu[0] * zr[0] + bu[1] * zr[1] + bu[2] * zr[2] + bu[3] * zr[3]);
        }
        s
    }

    /// Parse `{"x":[x0,x1],"y":[y0,y1],"z":[16 numbers]}` (a `schema` field
    /// is allowed and ignored).
    pub fn from_json(text: &str) -> Result<BezierPatch, PocketError> {
        #[derive(serde::Deserialize)]
        struct J {
            x: [f64; 2],
            y: [f64; 2],
            z: Vec<f64>,
        }
        let j: J = serde_json::from_str(text).map_err(|e| PocketError::Input(format!("Bezier patch JSON: {e}")))?;
        BezierPatch::new(j.x, j.y, &j.z)
    }
}

/// Catmull-Rom weights of the four neighbours at fraction `t` of a cell.
fn catmull(t: f64) -> [f64; 4] {
    let (t2, t3) = (t * t, t * t * t);
    [
        0.5 * (-t3 + 2.0 * t2 - t),
        0.5 * (3.0 * t3 - 5.0 * t2 + 2.0),
        0.5 * (-3.0 * t3 + 4.0 * t2 + t),
        0.5 * (t3 - t2),
    ]
}

/// The cell index and fraction of `v` in sorted `axis`, clamped.
fn locate(axis: &[f64], v: f64) -> (usize, f64) {
    let n = axis.len();
    if v <= axis[0] {
        return (0, 0.0);
    }
    if v >= axis[n - 1] {
        return (n - 2, 1.0);
    }
    let i = axis.partition_point(|a| *a <= v).saturating_sub(1).min(n - 2);
    (i, (v - axis[i]) / (axis[i + 1] - axis[i]))
}

impl GridSurface {
    /// Points `x,y,z` (one per line; commas, spaces or tabs; `#` comments;
    /// a header line of words is skipped) that fill a regular grid: every
    /// combination of the distinct X and Y values exactly once.
    pub fn from_csv(text: &str, interp: Interp) -> Result<GridSurface, PocketError> {
        let mut pts = Vec::new();
        for (n, line) in text.lines().enumerate() {
            let line = line.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let f: Vec<&str> = line
                .split(|c: char| c == ',' || c.is_whitespace())
                .filter(|s| !s.is_empty())
                .collect();
            let nums: Option<Vec<f64>> = f
                .iter()
                .map(|s| s.parse::<f64>().ok().filter(|v| v.is_finite()))
                .collect();
            match nums {
                Some(v) if v.len() == 3 => pts.push((v[0], v[1], v[2])),
                None if pts.is_empty() && f.iter().all(|s| s.parse::<f64>().is_err()) => {}
                _ => {
                    return Err(PocketError::Input(format!(
                        "line {}: expected x,y,z as three finite numbers",
                        n + 1
                    )));
                }
            }
        }
        let axis = |sel: fn(&(f64, f64, f64)) -> f64| {
            let mut v: Vec<f64> = pts.iter().map(sel).collect();
            v.sort_by(f64::total_cmp);
            v.dedup_by(|a, b| (*a - *b).abs() <= 1e-9);
            v
        };
        let (xs, ys) = (axis(|p| p.0), axis(|p| p.1));
        if xs.len() < 2 || ys.len() < 2 {
            return Err(PocketError::Input(
                "grid points need at least two distinct X and two distinct Y".into(),
            ));
        }
        if xs.len() * ys.len() != pts.len() {
            return Err(PocketError::Input(format!(
                "{} points do not fill the {} x {} grid of their distinct X and Y values",
                pts.len(),
                xs.len(),
                ys.len()
            )));
        }
        let mut z = vec![f64::NAN; xs.len() * ys.len()];
        for p in &pts {
            let i = xs.partition_point(|a| *a < p.0 - 1e-9);
            let j = ys.partition_point(|a| *a < p.1 - 1e-9);
            let k = j * xs.len() + i;
            if !z[k].is_nan() {
                return Err(PocketError::Input(format!("grid point ({}, {}) given twice", p.0, p.1)));
            }
            z[k] = p.2;
        }
        Ok(GridSurface { xs, ys, z, interp })
    }

    fn at(&self, i: isize, j: isize) -> f64 {
        let i = i.clamp(0, self.xs.len() as isize - 1) as usize;
        let j = j.clamp(0, self.ys.len() as isize - 1) as usize;
        self.z[j * self.xs.len() + i]
    }

    /// Like `at`, one point beyond the grid extrapolated linearly (so the
    /// bicubic reproduces a plane up to the edge).
    fn at_ext(&self, i: isize, j: isize) -> f64 {
        let (nx, ny) = (self.xs.len() as isize, self.ys.len() as isize);
        let col = |j: isize| -> f64 {
            if i < 0 {
                2.0 * self.at(0, j) - self.at(1, j)
            } else if i >= nx {
                2.0 * self.at(nx - 1, j) - self.at(nx - 2, j)
            } else {
                self.at(i, j)
            }
        };
        if j < 0 {
            2.0 * col(0) - col(1)
        } else if j >= ny {
            2.0 * col(ny - 1) - col(ny - 2)
        } else {
            col(j)
        }
    }

    /// Interpolated height at (x, y), clamped to the grid.
    pub fn height(&self, x: f64, y: f64) -> f64 {
        let (i, s) = locate(&self.xs, x);
        let (j, t) = locate(&self.ys, y);
        let (i, j) = (i as isize, j as isize);
        match self.interp {
            Interp::Bilinear => {
                let a = self.at(i, j) * (1.0 - s) + self.at(i + 1, j) * s;
                let b = self.at(i, j + 1) * (1.0 - s) + self.at(i + 1, j + 1) * s;
                a * (1.0 - t) + b * t
            }
            Interp::Bicubic => {
                let (ws, wt) = (catmull(s), catmull(t));
                let mut z = 0.0;
                for (b, wb) in wt.iter().enumerate() {
                    let row: f64 = (0..4)
                        .map(|a| ws[a] * self.at_ext(i - 1 + a as isize, j - 1 + b as isize))
                        .sum();
                    z += wb * row;
                }
                z
            }
        }
    }
}

impl Surface {
    /// Height of the bottom at (x, y).
    pub fn height(&self, x: f64, y: f64) -> f64 {
        match self {
            Surface::Flat(z) => *z,
            Surface::Bezier(b) => b.height(x, y),
            Surface::Grid(g) => g.height(x, y),
        }
    }

    /// The lowest height of the surface's definition (control values or
    /// points bound a Bezier patch and the interpolants from below up to
    /// the Catmull-Rom overshoot, which the caller's sampling covers).
    pub fn min_height(&self) -> f64 {
        match self {
            Surface::Flat(z) => *z,
            Surface::Bezier(b) => b.z.iter().flatten().copied().fold(f64::INFINITY, f64::min),
            Surface::Grid(g) => g.z.iter().copied().fold(f64::INFINITY, f64::min),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bezier_patch_interpolates_its_corners_and_is_linear_for_a_planar_net() {
        let mut z = [0.0; 16];
        for (k, v) in z.iter_mut().enumerate() {
            // z = x + 2y on [0,3]^2: control heights of a plane are its values.
            *v = (k % 4) as f64 + 2.0 * (k / 4) as f64;
        }
        let p = BezierPatch::new([0.0, 3.0], [0.0, 3.0], &z).unwrap();
        for (x, y) in [(0.0, 0.0), (3.0, 3.0), (1.2, 2.7), (0.4, 0.1)] {
            assert!((p.height(x, y) - (x + 2.0 * y)).abs() < 1e-12);
        }
        // Clamped outside.
        assert!((p.height(-1.0, 0.0) - 0.0).abs() < 1e-12);
        assert!(BezierPatch::new([0.0, 1.0], [0.0, 1.0], &z[..15]).is_err());
    }

    #[test]
    fn grid_surface_reads_csv_and_interpolates_both_ways() {
        let mut csv = String::from("x,y,z\n");
        for j in 0..4 {
            for i in 0..5 {
                let (x, y) = (i as f64 * 0.5, j as f64 * 0.3);
                csv.push_str(&format!("{x} {y} {}\n", 2.0 * x - y));
            }
        }
        for interp in [Interp::Bilinear, Interp::Bicubic] {
            let g = GridSurface::from_csv(&csv, interp).unwrap();
            // A plane is reproduced exactly by both.
            for (x, y) in [(0.25, 0.1), (1.9, 0.85), (1.0, 0.3)] {
                assert!((g.height(x, y) - (2.0 * x - y)).abs() < 1e-12, "{interp:?}");
            }
        }
        assert!(GridSurface::from_csv("0 0 0\n1 0 0\n0 1 0\n", Interp::Bilinear).is_err());
        assert!(GridSurface::from_csv("0 0 0\n1 0 x\n", Interp::Bilinear).is_err());
    }
}
