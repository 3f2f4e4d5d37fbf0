//! Fits of measured points: a straight line (total least squares), a
//! least-squares circle and the minimum-zone circle pair (roundness as
//! ISO 12181 defines it: the smallest radial separation of two concentric
//! circles that hold every point).

use super::ProbeError;
use crate::geometry::{P2, V2};
use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};

/// A straight line fitted to points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LineFit {
    /// The centroid of the points (on the line).
    pub point: P2,
    /// Unit direction.
    pub dir: V2,
    /// Unit normal (`dir` turned left).
    pub normal: V2,
    /// Number of points.
    pub n: usize,
    /// Sum of squared positions along the line about the centroid (mm^2),
    /// for the uncertainty of the line's offset away from the centroid.
    pub sum_s2: f64,
    /// Peak-to-valley of the perpendicular residuals (mm): straightness.
    pub straightness_mm: f64,
}

impl LineFit {
    /// Signed distance of `p` from the line (positive on the normal's side).
    pub fn offset(&self, p: P2) -> f64 {
        (p - self.point).dot(&self.normal)
    }

    /// Standard deviation of the line's position at `p`, per unit point
    /// scatter: sqrt(1/n + s^2 / sum s_i^2) with s the position of `p`
    /// along the line.
    pub fn offset_sigma_factor(&self, p: P2) -> f64 {
        let s = (p - self.point).dot(&self.dir);
        (1.0 / self.n as f64 + if self.sum_s2 > 0.0 { s * s / self.sum_s2 } else { 0.0 }).sqrt()
    }
}

/// Fit a line minimising perpendicular distances.
pub fn line(points: &[P2]) -> Result<LineFit, ProbeError> {
    if points.len() < 2 {
        return Err(ProbeError::Fit(format!("a line needs 2 points, got {}", points.len())));
    }
    let n = points.len() as f64;
    let c = points.iter().fold(V2::zeros(), |a, p| a + p.coords) / n;
    let mut m = Matrix2::zeros();
    for p in points {
        let w = p.coords - c;
        m += w * w.transpose();
    }
    let e = m.symmetric_eigen();
    let i = if e.eigenvalues[0] >= e.eigenvalues[1] { 0 } else { 1 };
    let mut dir = V2::new(e.eigenvectors[(0, i)], e.eigenvectors[(1, i)]);
    if dir.norm() == 0.0 {
        return Err(ProbeError::Fit("the points for the line all coincide".into()));
    }
    dir /= dir.norm();
    // A stable sign: from the first point towards the last.
    if (points[points.len() - 1] - points[0]).dot(&dir) < 0.0 {
        dir = -dir;
    }
    let normal = V2::new(-dir.y, dir.x);
    let point = P2::from(c);
    let (mut lo, mut hi, mut s2) = (f64::INFINITY, f64::NEG_INFINITY, 0.0);
    for p in points {
        let r = (p - point).dot(&normal);
        lo = lo.min(r);
        hi = hi.max(r);
        s2 += (p - point).dot(&dir).powi(2);
    }
    if s2 == 0.0 {
        return Err(ProbeError::Fit("the points for the line all coincide".into()));
    }
    Ok(LineFit {
        point,
        dir,
        normal,
        n: points.len(),
        sum_s2: s2,
        straightness_mm: hi - lo,
    })
}

/// A least-squares circle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CircleFit {
    /// Centre.
    pub center: P2,
    /// Radius (mm).
    pub radius: f64,
    /// (J^T J)^-1 of the geometric fit, order (cx, cy, r): times the point
    /// variance it is the covariance of the fitted figures.
    pub cov_unit: Matrix3<f64>,
    /// Peak-to-valley of the radial residuals about this centre (mm).
    pub roundness_mm: f64,
}

/// Fit the circle that minimises the sum of squared radial distances
/// (algebraic start, then Gauss-Newton on the geometric residuals).
pub fn circle_lsq(points: &[P2]) -> Result<CircleFit, ProbeError> {
    if points.len() < 3 {
        return Err(ProbeError::Fit(format!(
            "a circle needs 3 points, got {}",
            points.len()
        )));
    }
    let n = points.len() as f64;
    let m = points.iter().fold(V2::zeros(), |a, p| a + p.coords) / n;
    // Algebraic (Kasa) start in centred coordinates: x^2+y^2 + D x + E y + F = 0.
    let mut a = Matrix3::zeros();
    let mut b = Vector3::zeros();
    for p in points {
        let w = p.coords - m;
        let row = Vector3::new(w.x, w.y, 1.0);
        a += row * row.transpose();
        b -= row * w.norm_squared();
    }
    let sol = a
        .lu()
        .solve(&b)
        .ok_or_else(|| ProbeError::Fit("the points for the circle are collinear".into()))?;
    let mut c = m + V2::new(-sol[0] / 2.0, -sol[1] / 2.0);
    let r2 = (sol[0] * sol[0] + sol[1] * sol[1]) / 4.0 - sol[2];
    if !(r2 > 0.0 && r2.is_finite()) {
        return Err(ProbeError::Fit("the points for the circle are collinear".into()));
    }
    let mut r = r2.sqrt();
    let mut jtj = Matrix3::zeros();
    for _ in 0..50 {
        jtj = Matrix3::zeros();
        let mut jtr = Vector3::zeros();
        for p in points {
            let w = p.coords - c;
            let d = w.norm();
            if d == 0.0 {
                return Err(ProbeError::Fit("a point lies at the circle's centre".into()));
            }
            let j = Vector3::new(-w.x / d, -w.y / d, -1.0);
            jtj += j * j.transpose();
            jtr += j * (d - r);
        }
        let step = jtj
            .lu()
            .solve(&(-jtr))
            .ok_or_else(|| ProbeError::Fit("the circle fit is singular".into()))?;
        c += V2::new(step[0], step[1]);
        r += step[2];
        if step.norm() <= 1e-15 * (1.0 + r) {
            break;
        }
    }
    let cov_unit = jtj
        .try_inverse()
        .ok_or_else(|| ProbeError::Fit("the circle fit is singular".into()))?;
    let (lo, hi) = radial_range(points, P2::from(c));
    Ok(CircleFit {
        center: P2::from(c),
        radius: r,
        cov_unit,
        roundness_mm: hi - lo,
    })
}

/// Smallest and largest distance of the points from `c`.
pub fn radial_range(points: &[P2], c: P2) -> (f64, f64) {
    points.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
        let d = (p - c).norm();
        (lo.min(d), hi.max(d))
    })
}

/// The minimum-zone circle pair.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ZoneFit {
    /// Common centre.
    pub center: P2,
    /// Inner circle radius (mm).
    pub r_in: f64,
    /// Outer circle radius (mm).
    pub r_out: f64,
}

impl ZoneFit {
    /// The roundness deviation: r_out - r_in (mm).
    pub fn zone(&self) -> f64 {
        self.r_out - self.r_in
    }
}

/// Where the perpendicular bisectors of (a, b) and (c, d) cross.
pub fn bisectors_cross(a: P2, b: P2, c: P2, d: P2) -> Option<P2> {
    let (u, v) = (b - a, d - c);
    let m = Matrix2::new(u.x, u.y, v.x, v.y);
    let rhs = Vector2::new(u.dot(&(a.coords + b.coords)) / 2.0, v.dot(&(c.coords + d.coords)) / 2.0);
    let det = m.determinant();
    if det.abs() <= 1e-14 * u.norm() * v.norm() {
        return None;
    }
    m.lu().solve(&rhs).map(P2::from)
}

/// The centre of the circle through three points.
pub fn circumcenter(a: P2, b: P2, c: P2) -> Option<P2> {
    bisectors_cross(a, b, b, c)
}

/// The minimum-zone circles (ISO 12181 roundness). The optimum centre is
/// equidistant from two outer and two inner points, or from three outer or
/// three inner ones; starting at the least-squares centre, candidates are
/// built from the points nearest the current zone's edges and the best
/// taken, until none improves the zone.
pub fn circle_min_zone(points: &[P2]) -> Result<ZoneFit, ProbeError> {
    let lsq = circle_lsq(points)?;
    let mut c = lsq.center;
    let (lo, hi) = radial_range(points, c);
    let mut best = (hi - lo, lo, hi);
    let m = points.len().min(8);
    for _ in 0..100 {
        let mut idx: Vec<usize> = (0..points.len()).collect();
        idx.sort_by(|&i, &j| {
            (points[i] - c)
                .norm()
                .total_cmp(&(points[j] - c).norm())
                .then(i.cmp(&j))
        });
        let inner = &idx[..m];
        let outer = &idx[idx.len() - m..];
        let mut cands = Vec::new();
        for (i, &a) in outer.iter().enumerate() {
            for &b in &outer[i + 1..] {
                for (k, &p) in inner.iter().enumerate() {
                    for &q in &inner[k + 1..] {
                        cands.extend(bisectors_cross(points[a], points[b], points[p], points[q]));
                    }
                }
            }
        }
        for set in [outer, inner] {
            for i in 0..m {
                for j in i + 1..m {
                    for k in j + 1..m {
                        cands.extend(circumcenter(points[set[i]], points[set[j]], points[set[k]]));
                    }
                }
            }
        }
        let mut improved = false;
        for q in cands {
            let (lo, hi) = radial_range(points, q);
            if hi - lo < best.0 - 1e-15 * hi {
                best = (hi - lo, lo, hi);
                c = q;
                improved = true;
            }
        }
        if !improved {
            break;
        }
    }
    Ok(ZoneFit {
        center: c,
        r_in: best.1,
        r_out: best.2,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_figures_fit_exactly() {
        let pts: Vec<P2> = (0..50)
            .map(|i| {
                let a = i as f64 * 0.37;
                P2::new(3.0 + 6.35 * a.cos(), -1.0 + 6.35 * a.sin())
            })
            .collect();
        let c = circle_lsq(&pts).unwrap();
        assert!((c.radius - 6.35).abs() < 1e-12 && (c.center - P2::new(3.0, -1.0)).norm() < 1e-12);
        let z = circle_min_zone(&pts).unwrap();
        assert!(z.zone() < 1e-12);
        let l = line(&[P2::new(0.0, 1.0), P2::new(1.0, 2.0), P2::new(2.0, 3.0)]).unwrap();
        assert!(l.offset(P2::new(0.0, 0.0)).abs() - 0.5f64.sqrt() < 1e-12);
        assert!(l.straightness_mm < 1e-12);
        assert!(circle_lsq(&[P2::new(0.0, 0.0), P2::new(1.0, 0.0), P2::new(2.0, 0.0)]).is_err());
    }

    #[test]
    fn min_zone_never_wider_than_the_least_squares_zone() {
        let mut rng = super::super::noise::Rng::new(3);
        for _ in 0..20 {
            let pts: Vec<P2> = (0..40)
                .map(|i| {
                    let a = i as f64 * std::f64::consts::TAU / 40.0;
                    let r = 5.0 + 0.01 * (3.0 * a).cos() + 0.002 * rng.normal();
                    P2::new(r * a.cos(), r * a.sin())
                })
                .collect();
            let l = circle_lsq(&pts).unwrap();
            let z = circle_min_zone(&pts).unwrap();
            assert!(z.zone() <= l.roundness_mm + 1e-15);
        }
    }
}
