//! Rays on a grid: the design's and the machined part's top surface at
//! each point, and what the differences say (Singh 2014: rays cast along
//! Z over a region at a step forward and a step over, excess material
//! and gouges judged against a ±band).

use super::Simulation;
use crate::geometry::{P3, V3};
use crate::mesh::parallel::{Lattice, ParallelRays};

/// One comparison point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Where the ray was cast, mm.
    pub x: f64,
    /// Where the ray was cast, mm.
    pub y: f64,
    /// Top of the design (`None`: the ray misses it).
    pub design_z: Option<f64>,
    /// Top of the machined part.
    pub machined_z: f64,
}

impl Sample {
    /// Machined minus design: positive is excess material (under-cut),
    /// negative a gouge (over-cut).
    pub fn deviation(&self) -> Option<f64> {
        self.design_z.map(|d| self.machined_z - d)
    }
}

/// The design mesh ready for vertical rays: the same hits as the BVH, a
/// grid of rays at a time by rasterising the design onto it
/// ([`ParallelRays::first_depths_lattice`]), single rays through a 2-D
/// grid over the plan view (docs/mesh.md).
pub struct Design {
    rays: ParallelRays,
    top: f64,
}

impl Design {
    /// Index `mesh` for rays.
    pub fn new(mesh: &crate::mesh::Mesh) -> Design {
        let b = mesh.bbox();
        Design {
            rays: ParallelRays::new(mesh, -V3::z()),
            top: if b.max.z.is_finite() { b.max.z } else { 0.0 },
        }
    }

    /// Top of the design over (x, y): the first hit of a ray cast down.
    pub fn top_at(&self, x: f64, y: f64) -> Option<f64> {
        let z0 = self.top + 1.0;
        self.rays.first_hit(&P3::new(x, y, z0)).map(|h| z0 - h.t)
    }

    /// [`Design::top_at`] at every `(xs[i], ys[j])`, in the order
    /// `j * xs.len() + i`, bit for bit the same values (the rays'
    /// origins are the same points).
    pub fn tops(&self, xs: &[f64], ys: &[f64]) -> Vec<Option<f64>> {
        let z0 = self.top + 1.0;
        let l = Lattice {
            base: P3::new(0.0, 0.0, z0),
            eu: V3::x(),
            ev: V3::y(),
            us: xs,
            vs: ys,
        };
        self.rays
            .first_depths_lattice(&l)
            .into_iter()
            .map(|t| (t != f64::INFINITY).then_some(z0 - t))
            .collect()
    }
}

/// Points `x0, x0 + step, ...` up to `x1` (inclusive within rounding).
pub fn steps(x0: f64, x1: f64, step: f64) -> Vec<f64> {
    let n = ((x1 - x0) / step + 1e-9).floor().max(0.0) as usize;
    (0..=n).map(|k| x0 + k as f64 * step).collect()
}

/// Sample every point of the grid (row by row, y outer, x inner).
pub fn sample(sim: &Simulation, design: &Design, xs: &[f64], ys: &[f64]) -> Vec<Sample> {
    let tops = design.tops(xs, ys);
    let nx = xs.len().max(1);
    let points: Vec<(f64, f64)> = (0..tops.len()).map(|k| (xs[k % nx], ys[k / nx])).collect();
    let machined = sim.tops_at(&points);
    points
        .iter()
        .zip(tops)
        .zip(machined)
        .map(|((&(x, y), design_z), m)| Sample {
            x,
            y,
            design_z,
            machined_z: m.unwrap_or(f64::NAN),
        })
        .collect()
}

/// What the comparison found.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Stats {
    /// Half-width of the tolerance band, mm.
    pub band_mm: f64,
    /// Points compared or not.
    pub points: usize,
    /// Points where the design or the stock has no surface.
    pub not_compared: usize,
    /// Points within the band.
    pub in_band: usize,
    /// Points above the band (excess material, under-cut).
    pub excess: usize,
    /// Points below the band (gouge, over-cut).
    pub gouge: usize,
    /// Largest excess and gouge (both ≥ 0), mm.
    pub max_excess_mm: f64,
    /// See `max_excess_mm`.
    pub max_gouge_mm: f64,
    /// Root mean square of the deviations, mm.
    pub rms_mm: f64,
    /// Mean deviation (machined minus design), mm.
    pub mean_mm: f64,
}

impl Stats {
    /// Tally `samples` against `±band`.
    pub fn of(samples: &[Sample], band: f64) -> Stats {
        let mut s = Stats {
            band_mm: band,
            points: samples.len(),
            ..Stats::default()
        };
        let (mut sum, mut sum2, mut n) = (0.0, 0.0, 0usize);
        for p in samples {
            let Some(d) = p.deviation().filter(|d| d.is_finite()) else {
                s.not_compared += 1;
                continue;
            };
            n += 1;
            sum += d;
            sum2 += d * d;
            if d > band {
                s.excess += 1;
            } else if d < -band {
                s.gouge += 1;
            } else {
                s.in_band += 1;
            }
            s.max_excess_mm = s.max_excess_mm.max(d);
            s.max_gouge_mm = s.max_gouge_mm.max(-d);
        }
        if n > 0 {
            s.mean_mm = sum / n as f64;
            s.rms_mm = (sum2 / n as f64).sqrt();
        }
        s
    }

    /// True when no compared point is outside the band.
    pub fn passed(&self) -> bool {
        self.excess == 0 && self.gouge == 0
    }
}

/// Profiles as CSV: `y_mm,x_mm,design_z_mm,machined_z_mm,deviation_mm`.
pub fn profiles_csv(profiles: &[(f64, Vec<Sample>)]) -> String {
    let mut s = String::from("y_mm,x_mm,design_z_mm,machined_z_mm,deviation_mm\n");
    let f = |v: Option<f64>| v.filter(|v| v.is_finite()).map_or(String::new(), |v| format!("{v:.6}"));
    for (y, pts) in profiles {
        for p in pts {
            s.push_str(&format!(
                "{y:.6},{:.6},{},{},{}\n",
                p.x,
                f(p.design_z),
                f(Some(p.machined_z)),
                f(p.deviation())
            ));
        }
    }
    s
}

/// Grid rays as CSV: `x_mm,y_mm,design_z_mm,machined_z_mm,deviation_mm`.
pub fn points_csv(samples: &[Sample]) -> String {
    let mut s = String::from("x_mm,y_mm,design_z_mm,machined_z_mm,deviation_mm\n");
    let f = |v: Option<f64>| v.filter(|v| v.is_finite()).map_or(String::new(), |v| format!("{v:.6}"));
    for p in samples {
        s.push_str(&format!(
            "{:.6},{:.6},{},{},{}\n",
            p.x,
            p.y,
            f(p.design_z),
            f(Some(p.machined_z)),
            f(p.deviation())
        ));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn design_tops_on_a_grid_are_its_single_rays() {
        let m = crate::mesh::solids::sphere(P3::new(1.0, 0.5, -2.0), 2.0, 40, 20);
        let d = Design::new(&m);
        let xs = steps(-1.5, 3.5, 0.05);
        let ys = steps(-2.0, 3.0, 0.07);
        let tops = d.tops(&xs, &ys);
        let mut hits = 0;
        for (j, &y) in ys.iter().enumerate() {
            for (i, &x) in xs.iter().enumerate() {
                let want = d.top_at(x, y);
                assert_eq!(
                    tops[j * xs.len() + i].map(f64::to_bits),
                    want.map(f64::to_bits),
                    "({x}, {y})"
                );
                hits += want.is_some() as usize;
            }
        }
        assert!(hits > 1000 && hits < tops.len(), "{hits}");
    }

    #[test]
    fn stats_classify_and_measure() {
        let mk = |d: f64| Sample {
            x: 0.0,
            y: 0.0,
            design_z: Some(1.0),
            machined_z: 1.0 + d,
        };
        let v = [
            mk(0.05),
            mk(-0.05),
            mk(0.2),
            mk(-0.3),
            Sample {
                design_z: None,
                ..mk(0.0)
            },
        ];
        let s = Stats::of(&v, 0.1);
        assert_eq!((s.in_band, s.excess, s.gouge, s.not_compared), (2, 1, 1, 1));
        assert!((s.max_gouge_mm - 0.3).abs() < 1e-12 && (s.max_excess_mm - 0.2).abs() < 1e-12);
        let want = ((0.0025 + 0.0025 + 0.04 + 0.09) / 4.0f64).sqrt();
        assert!((s.rms_mm - want).abs() < 1e-12);
        assert!(!s.passed());
        assert_eq!(steps(0.0, 4.0, 0.1).len(), 41);
    }
}
