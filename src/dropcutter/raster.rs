//! Where to drop the cutter: raster passes over a rectangle, or points
//! along 2-D chains, as XY polylines ("passes"). Each pass is cut as one
//! continuous feed run; between passes the tool goes up to the safe Z.

use super::DropError;
use crate::geometry::P2;
use crate::model::chain::Chain;

/// Axis the raster lines run along.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// Lines along X, stepped over in Y.
    X,
    /// Lines along Y, stepped over in X.
    Y,
}

/// How consecutive raster lines are joined.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pattern {
    /// Alternate directions; each line joins the next by a feed move along
    /// the rectangle's edge (sampled and dropped like the lines), so the
    /// whole raster is one pass.
    Zigzag,
    /// Every line in the same direction, one pass each.
    OneWay,
}

/// A raster over an XY rectangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Raster {
    /// Largest distance between lines (mm).
    pub step_over: f64,
    /// Largest distance between points along a line (mm).
    pub step_forward: f64,
    /// Axis the lines run along.
    pub direction: Direction,
    /// How consecutive lines are joined.
    pub pattern: Pattern,
    /// The rectangle: min x, min y, max x, max y, mm.
    pub region: [f64; 4],
}

/// More points than this in one job are refused (about 2 GB of CL data).
pub const MAX_POINTS: f64 = 1.0e8;

fn check_step(name: &str, v: f64) -> Result<(), DropError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(DropError::Option(format!("--{name} must be positive, got {v}")))
    }
}

/// `n + 1` evenly spaced values from `a` to `b`, `n` the fewest steps of
/// at most `step` (a step longer by a rounding error, 1e-12 relative, still
/// counts as one step: a link exactly one step-over long gets no midpoint).
fn spaced(a: f64, b: f64, step: f64) -> impl Iterator<Item = f64> {
    let n = ((b - a).abs() / step * (1.0 - 1e-12)).ceil().max(1.0) as usize;
    (0..=n).map(move |i| if i == n { b } else { a + (b - a) * i as f64 / n as f64 })
}

impl Raster {
    /// The passes: lines evenly spaced at most `step_over` apart covering
    /// the region edge to edge, points at most `step_forward` apart.
    pub fn passes(&self) -> Result<Vec<Vec<P2>>, DropError> {
        check_step("step-over", self.step_over)?;
        check_step("step-forward", self.step_forward)?;
        let [x0, y0, x1, y1] = self.region;
        if !(x0.is_finite() && y0.is_finite() && x1.is_finite() && y1.is_finite() && x0 <= x1 && y0 <= y1) {
            return Err(DropError::Option(format!(
                "the region {x0},{y0},{x1},{y1} is not a rectangle (need xmin <= xmax, ymin <= ymax)"
            )));
        }
        // (along from, along to, across from, across to)
        let (a0, a1, c0, c1) = match self.direction {
            Direction::X => (x0, x1, y0, y1),
            Direction::Y => (y0, y1, x0, x1),
        };
        let lines = ((c1 - c0) / self.step_over).ceil() + 1.0;
        let per = ((a1 - a0) / self.step_forward).ceil() + 1.0;
        if lines * per > MAX_POINTS {
            return Err(DropError::Option(format!(
                "the raster would have {:.0} points (more than {MAX_POINTS:.0}); raise the steps",
                lines * per
            )));
        }
        let pt = |along: f64, across: f64| match self.direction {
            Direction::X => P2::new(along, across),
            Direction::Y => P2::new(across, along),
        };
        let mut passes: Vec<Vec<P2>> = Vec::new();
        for (k, c) in spaced(c0, c1, self.step_over).enumerate() {
            let reverse = self.pattern == Pattern::Zigzag && k % 2 == 1;
            let mut line: Vec<P2> = spaced(a0, a1, self.step_forward).map(|a| pt(a, c)).collect();
            if reverse {
                line.reverse();
            }
            match (self.pattern, passes.last_mut()) {
                (Pattern::Zigzag, Some(run)) => {
                    // The link along the edge, sampled like a line.
                    let from = *run.last().unwrap_or(&line[0]);
                    let to = line[0];
                    run.extend(sample_line(from, to, self.step_forward).into_iter().skip(1));
                    run.extend(line.into_iter().skip(1));
                }
                _ => passes.push(line),
            }
        }
        Ok(passes)
    }
}

/// Points from `a` to `b` (both included) at most `step` apart.
pub fn sample_line(a: P2, b: P2, step: f64) -> Vec<P2> {
    spaced(0.0, 1.0, step / (b - a).norm().max(f64::MIN_POSITIVE))
        .map(|t| a + (b - a) * t)
        .collect()
}

/// One pass per chain: its segments (lines and XY arcs; z ignored) sampled
/// at most `step` apart, every chain vertex kept.
pub fn chain_passes(chains: &[Chain], step: f64) -> Result<Vec<Vec<P2>>, DropError> {
    check_step("step-forward", step)?;
    let total: f64 = chains
        .iter()
        .flat_map(|c| &c.segments)
        .map(|s| s.length() / step + 1.0)
        .sum();
    if total > MAX_POINTS {
        return Err(DropError::Option(format!(
            "the chains would give {total:.0} points (more than {MAX_POINTS:.0}); raise --step-forward"
        )));
    }
    let mut passes = Vec::new();
    for c in chains {
        let mut pass: Vec<P2> = Vec::new();
        for s in &c.segments {
            let pts: Vec<P2> = match s.to_arc_xy() {
                None => sample_line(s.start().xy(), s.end().xy(), step),
                Some(arc) => {
                    let n = ((arc.radius * arc.sweep.abs()) / step).ceil().max(1.0) as usize;
                    (0..=n)
                        .map(|i| {
                            if i == n {
                                s.end().xy()
                            } else {
                                arc.point_at_angle(arc.start_angle + arc.sweep * i as f64 / n as f64)
                            }
                        })
                        .collect()
                }
            };
            let skip = usize::from(pass.last().is_some_and(|l| pts.first() == Some(l)));
            pass.extend(pts.into_iter().skip(skip));
        }
        if !pass.is_empty() {
            passes.push(pass);
        }
    }
    Ok(passes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::P3;
    use crate::model::chain::Segment;

    #[test]
    fn zigzag_is_one_pass_covering_the_region() {
        let r = Raster {
            step_over: 0.3,
            step_forward: 0.25,
            direction: Direction::X,
            pattern: Pattern::Zigzag,
            region: [0.0, 0.0, 1.0, 1.0],
        };
        let p = r.passes().unwrap();
        assert_eq!(p.len(), 1);
        // 5 lines at y = 0, 0.25, ..., 1 of 5 points each, joined by links.
        for w in p[0].windows(2) {
            let d = (w[1] - w[0]).norm();
            assert!(d <= 0.25 + 1e-12 && d > 0.0, "{d}");
        }
        assert_eq!(p[0][0], P2::new(0.0, 0.0));
        assert_eq!(*p[0].last().unwrap(), P2::new(1.0, 1.0));
        assert_eq!(p[0].len(), 25);
        let one = Raster {
            pattern: Pattern::OneWay,
            direction: Direction::Y,
            ..r
        };
        let p = one.passes().unwrap();
        assert_eq!(p.len(), 5);
        assert!(
            p.iter()
                .all(|l| l[0].y == 0.0 && l.last().unwrap().y == 1.0 && l.len() == 5)
        );
        assert!(Raster { step_over: 0.0, ..r }.passes().is_err());
        assert!(
            Raster {
                region: [1.0, 0.0, 0.0, 1.0],
                ..r
            }
            .passes()
            .is_err()
        );
    }

    #[test]
    fn chains_are_sampled_with_their_vertices() {
        let c = Chain {
            id: 1,
            closed: false,
            segments: vec![
                Segment::line(P3::new(0.0, 0.0, 0.0), P3::new(1.0, 0.0, 0.0)),
                Segment::arc_xy(
                    P3::new(1.0, 0.0, 0.0),
                    P3::new(1.0, 1.0, 0.0),
                    P3::new(1.0, 0.5, 0.0),
                    true,
                ),
            ],
            ..Default::default()
        };
        let p = chain_passes(&[c], 0.1).unwrap();
        assert_eq!(p.len(), 1);
        let pass = &p[0];
        assert_eq!(pass[0], P2::new(0.0, 0.0));
        assert!(pass.contains(&P2::new(1.0, 0.0)));
        assert_eq!(*pass.last().unwrap(), P2::new(1.0, 1.0));
        for w in pass.windows(2) {
            assert!((w[1] - w[0]).norm() <= 0.1 + 1e-12);
        }
        // The arc bulges to x = 1.5.
        assert!(pass.iter().any(|q| (q.x - 1.5).abs() < 1e-9));
    }
}
