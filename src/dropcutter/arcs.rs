//! 3-axis passes as lines and arcs: a pass of CL points is cut into its
//! planar stretches, each fitted with tangent-continuous arcs in its own
//! plane ([`crate::laser::arcfit::fit_points`], polyline mode: within the
//! tolerance of the points' chords both ways).
//!
//! Why: a micro-milling controller runs each block for at least its least
//! block time, so a finishing pass of CL points a few hundredths of a
//! millimetre apart runs far below its feed; an arc spans dozens of them.
//! The planes are the ones G-code can name: a raster pass along X lies in
//! a plane of constant Y (G18, the ZX plane), along Y in one of constant X
//! (G19), a zigzag's link along the region's edge in the other, and a
//! level stretch in one of constant Z (G17). Chords that leave every such
//! plane (a pass along a drawn chain) stay lines. (Waterline loops, level
//! throughout, are fitted in XY directly.)

use crate::geometry::arc::Arc3;
use crate::geometry::{P2, P3, Plane, Segment};
use crate::laser::arcfit::fit_points;

/// The plane of constant coordinate that holds both `a` and `b`, if any:
/// constant Y, then constant X, then constant Z (a level move along X lies
/// in two; the pass's vertical plane goes on past the level stretch).
fn plane_of(a: &P3, b: &P3) -> Option<Plane> {
    [Plane::Xz, Plane::Yz, Plane::Xy]
        .into_iter()
        .find(|pl| pl.normal_coord(a) == pl.normal_coord(b))
}

/// A piece fitted in `plane`'s own coordinates (`fit_points` lifts them as
/// if the plane were XY, at `h`) put back into the plane.
fn into_plane(s: Segment, plane: Plane) -> Segment {
    if plane == Plane::Xy {
        return s;
    }
    let back = |p: &P3| plane.lift(&P2::new(p.x, p.y), p.z);
    match s {
        Segment::Line(l) => Segment::line(back(&l.start), back(&l.end)),
        // `project` orders a plane's axes so that first x second is its
        // normal: counter-clockwise in the fit's frame is counter-clockwise
        // about the plane normal, as G2/G3 count it in G18 and G19.
        Segment::Arc(a) => match Arc3::new(back(&a.center), back(&a.start), back(&a.end), a.ccw, plane, 0) {
            Some(arc) => Segment::Arc(arc),
            None => Segment::line(back(&a.start), back(&a.end)),
        },
    }
}

/// Below this fraction of the tolerance an arc's sagitta makes it a line.
const FLAT_ARC: f64 = 0.01;

/// `s` as a line when it is an arc that bows from its chord by less than
/// `FLAT_ARC` of `tol`: the biarc fit gives a straight stretch of points
/// (a flat floor) radii of hundreds of metres where its end tangents lean
/// a little, which a controller then computes through a far-away centre.
/// The line is within `FLAT_ARC · tol` of the arc, so the piece stays
/// within the tolerance of the chords, and the tangent breaks by a few
/// microradians.
pub fn straightened(s: Segment, tol: f64) -> Segment {
    let Segment::Arc(a) = s else { return s };
    let half = (0.5 * a.sweep().abs()).min(std::f64::consts::FRAC_PI_2);
    if a.radius() * (1.0 - half.cos()) < FLAT_ARC * tol {
        Segment::line(a.start, a.end)
    } else {
        s
    }
}

/// A waterline loop (CL points at one Z) as lines and arcs in its level
/// plane, within `tol` of its chords, the flat arcs straightened.
pub fn fit_loop(points: &[P3], tol: f64) -> Vec<Segment> {
    let pts: Vec<P2> = points.iter().map(|p| P2::new(p.x, p.y)).collect();
    fit_points(&pts, tol, points.first().map_or(0.0, |p| p.z), true)
        .into_iter()
        .map(|s| straightened(s, tol))
        .collect()
}

/// `pass` (CL points in order) as lines and arcs within `tol` of its
/// chords: each maximal stretch of points in one plane of constant X, Y or
/// Z is fitted in that plane; a chord in none of them is a line. The
/// pieces run from the first point to the last, end to start, through
/// every point where the stretches meet.
pub fn fit_pass(pass: &[P3], tol: f64) -> Vec<Segment> {
    let mut out = Vec::new();
    let mut i = 0;
    while i + 1 < pass.len() {
        let Some(plane) = plane_of(&pass[i], &pass[i + 1]) else {
            out.push(Segment::line(pass[i], pass[i + 1]));
            i += 1;
            continue;
        };
        let h = plane.normal_coord(&pass[i]);
        let mut j = i + 1;
        while j + 1 < pass.len() && plane.normal_coord(&pass[j + 1]) == h {
            j += 1;
        }
        let pts: Vec<P2> = pass[i..=j].iter().map(|p| plane.project(p)).collect();
        out.extend(
            fit_points(&pts, tol, h, true)
                .into_iter()
                .map(|s| into_plane(straightened(s, tol), plane)),
        );
        i = j;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The largest distance from points sampled along `fit` to the
    /// polyline `pass` (in 3-D), and from `pass`'s points to the fit.
    fn deviation(fit: &[Segment], pass: &[P3]) -> f64 {
        let to_chords = |q: &P3| {
            pass.windows(2)
                .map(|w| {
                    let (d, n) = (w[1] - w[0], q - w[0]);
                    let t = (n.dot(&d) / d.norm_squared().max(1e-300)).clamp(0.0, 1.0);
                    (n - d * t).norm()
                })
                .fold(f64::INFINITY, f64::min)
        };
        let mut worst = 0.0f64;
        for s in fit {
            for k in 0..=64 {
                worst = worst.max(to_chords(&s.point_at(k as f64 / 64.0)));
            }
        }
        worst
    }

    /// A zigzag over a dome: passes along X at constant Y joined by links
    /// along the edge at constant X. Each stretch is fitted in its own
    /// plane (G18 arcs along the passes), the pieces join end to start
    /// from the first point to the last, and every sample of every piece
    /// lies within the tolerance of the points' chords.
    #[test]
    fn a_zigzag_over_a_dome_becomes_arcs_in_its_planes() {
        let z = |x: f64, y: f64| (25.0 - x * x - y * y).max(0.0).sqrt();
        let mut pass: Vec<P3> = Vec::new();
        for (k, y) in [-1.0, -0.5, 0.0, 0.5].into_iter().enumerate() {
            let mut line: Vec<P3> = (0..=80)
                .map(|i| -4.0 + i as f64 * 0.1)
                .map(|x| P3::new(x, y, z(x, y)))
                .collect();
            if k % 2 == 1 {
                line.reverse();
            }
            if let Some(last) = pass.last().copied() {
                // The link along the edge, in the plane x = const.
                let to = line[0];
                for s in 1..5 {
                    let yy = last.y + (to.y - last.y) * s as f64 / 5.0;
                    pass.push(P3::new(last.x, yy, z(last.x, yy)));
                }
            }
            pass.extend(line.into_iter().skip(usize::from(!pass.is_empty())));
        }
        let tol = 0.001;
        let fit = fit_pass(&pass, tol);
        let arcs: Vec<&Arc3> = fit
            .iter()
            .filter_map(|s| match s {
                Segment::Arc(a) => Some(a),
                Segment::Line(_) => None,
            })
            .collect();
        assert!(
            fit.len() * 4 < pass.len(),
            "{} pieces for {} points",
            fit.len(),
            pass.len()
        );
        assert!(arcs.len() >= 4, "{} arcs", arcs.len());
        assert!(arcs.iter().any(|a| a.plane == Plane::Xz));
        for a in &arcs {
            // An arc along a pass keeps its Y; one along a link its X.
            assert!(a.plane != Plane::Xy);
            let h = a.plane.normal_coord(&a.start);
            assert_eq!(a.plane.normal_coord(&a.end), h);
        }
        assert_eq!(fit[0].start(), pass[0]);
        assert_eq!(fit.last().unwrap().end(), *pass.last().unwrap());
        for w in fit.windows(2) {
            assert!((w[0].end() - w[1].start()).norm() < 1e-9);
        }
        let dev = deviation(&fit, &pass);
        assert!(dev <= tol * 1.0001, "{dev}");
        // Every point of the pass within the tolerance of the fit.
        for p in &pass {
            let d = fit.iter().filter_map(|s| s.distance(p)).fold(f64::INFINITY, f64::min);
            assert!(d <= tol * 1.0001, "{p:?}: {d}");
        }
    }

    /// A flat floor between two slopes: the fit's near-straight arcs there
    /// become lines; the curved arcs stay.
    #[test]
    fn flat_stretches_are_lines() {
        let z = |x: f64| {
            if x.abs() <= 2.0 {
                -3.0
            } else {
                -3.0 + (x.abs() - 2.0).powi(2)
            }
        };
        let pass: Vec<P3> = (0..=80)
            .map(|i| -4.0 + i as f64 * 0.1)
            .map(|x| P3::new(x, 0.5, z(x)))
            .collect();
        let tol = 0.001;
        let fit = fit_pass(&pass, tol);
        let floor: Vec<&Segment> = fit.iter().filter(|s| s.start().x >= -2.0 && s.end().x <= 2.0).collect();
        assert!(!floor.is_empty());
        for s in &floor {
            assert!(matches!(s, Segment::Line(_)), "{s:?}");
        }
        assert!(fit.iter().any(|s| matches!(s, Segment::Arc(_))));
        for s in &fit {
            if let Segment::Arc(a) = s {
                assert!(a.radius() < 1e3, "{a:?}");
            }
        }
        // Straightening keeps what bows by more and turns what bows by less.
        let arc = |r: f64| {
            let (c, half) = (P3::new(0.0, 0.0, -r), 0.01f64);
            let at = |t: f64| P3::new(r * t.sin(), 0.0, -r + r * t.cos());
            Segment::Arc(Arc3::new(c, at(-half), at(half), true, Plane::Xz, 0).unwrap())
        };
        // Sagitta r (1 - cos 0.01) = 5e-5 r (the short way, counter-
        // clockwise about +Y from -0.01 to 0.01 rad off +Z).
        assert!((arc(1.0).length() - 0.02).abs() < 1e-12);
        assert!(matches!(straightened(arc(0.1), tol), Segment::Line(_)));
        assert!(matches!(straightened(arc(1.0), tol), Segment::Arc(_)));
    }

    /// A pass in no plane of constant coordinate stays lines, one a chord;
    /// a straight level pass is one line; one or no point gives nothing.
    #[test]
    fn off_plane_chords_stay_lines() {
        let pass: Vec<P3> = (0..20)
            .map(|i| {
                let t = i as f64 * 0.1;
                P3::new(t, t * 0.5, t.sin())
            })
            .collect();
        let fit = fit_pass(&pass, 0.01);
        assert_eq!(fit.len(), pass.len() - 1);
        assert!(fit.iter().all(|s| matches!(s, Segment::Line(_))));
        let level: Vec<P3> = (0..50).map(|i| P3::new(i as f64 * 0.1, 1.0, 2.0)).collect();
        let fit = fit_pass(&level, 0.01);
        assert_eq!(fit.len(), 1);
        assert_eq!((fit[0].start(), fit[0].end()), (level[0], level[49]));
        assert!(fit_pass(&pass[..1], 0.01).is_empty());
        assert!(fit_pass(&[], 0.01).is_empty());
    }
}
