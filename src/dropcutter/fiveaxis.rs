//! 5-axis cutter locations: a flat or torus end mill touching the surface
//! at a contact point (CC) with its axis along the surface normal, leaned
//! forward by a lead angle and sideways by a tilt angle. Each location is
//! written as the tool-tip centre (CL) and a second point on the tool axis
//! towards the holder: the layout of the 5-axis tool path in Singh 2014
//! (Annexure 2), which that thesis machined and verified in simulation.
//!
//! With surface normal n, feed direction f (the pass direction projected
//! into the tangent plane) and side s = n × f, the axis is
//! a = cos λ cos τ · n + sin λ · f + cos λ sin τ · s
//! (λ lead, τ tilt). The cutter's outward normal at the contact is −n, so
//! the contact lies on the tube (or the rim, for a flat end mill) on the
//! side w = unit(−(n − (n·a) a)) of the axis, and the tip centre is
//! CL = CC + rc·n − rc·a − (R − rc)·w. With λ = τ = 0 the flat bottom sits
//! on the tangent plane and CL = CC.
//!
//! Contacts are on the facet straight below each sampled (x, y), with
//! that facet's normal (the axis then turns in steps at facet edges, and
//! the location keeps that facet clear) or with a normal interpolated
//! across it ([`super::normals`]: the axis turns smoothly, and the tool,
//! tangent to the smooth surface rather than the facet, is then set down
//! on the mesh along its axis, [`super::gouge::GougeCheck::settle_one`]).
//! Either way [`super::gouge`] checks the whole tool against the mesh
//! afterwards.

use super::normals::SmoothNormals;
use super::{DropCutter, DropError};
use crate::cutter::Cutter;
use crate::geometry::{P2, P3, V3};

/// Orientation rule and output of a 5-axis pass.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FiveAxis {
    /// Lean of the axis towards the feed direction (radians).
    pub lead: f64,
    /// Lean of the axis to the left of the feed direction (radians).
    pub tilt: f64,
    /// Distance from the CL point to the second point on the axis (mm).
    pub axis_length: f64,
}

/// One 5-axis location: the tip centre and a point up the tool axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Location {
    /// The tool tip (the CL point), mm.
    pub cl: P3,
    /// The point `axis_length` up the tool axis from the tip, towards the
    /// holder, mm (Singh 2014's second point of a 5-axis row).
    pub axis_point: P3,
}

/// Where a 5-axis location touches the part: the contact point, the unit
/// surface normal there (the facet's, or a smoothed one), and the
/// direction of travel there (any length; zero for a single point).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    /// The contact point (CC), mm.
    pub cc: P3,
    /// Unit upward surface normal at the contact: its facet's, or
    /// interpolated across the facet ([`SmoothNormals`]).
    pub normal: V3,
    /// Unit upward normal of the facet the contact lies on.
    pub facet: V3,
    /// Direction of travel.
    pub feed: V3,
}

impl FiveAxis {
    /// Locations along one XY pass; points off the mesh end a run, so the
    /// result is one run per stretch of the pass that lies on the mesh.
    pub fn pass(&self, dc: &DropCutter, xy: &[P2]) -> Result<Vec<Vec<Location>>, DropError> {
        let (r, rc) = Self::radii(dc)?;
        Ok(Self::contacts(dc, xy)
            .iter()
            .map(|run| {
                run.iter()
                    .map(|c| self.location(c.cc, c.normal, c.feed, r, rc))
                    .collect()
            })
            .collect())
    }

    /// The cutter's radius and corner radius; a ball is refused.
    pub fn radii(dc: &DropCutter) -> Result<(f64, f64), DropError> {
        match dc.cutter() {
            Cutter::Flat { radius } => Ok((radius, 0.0)),
            Cutter::Torus { radius, corner } => Ok((radius, corner)),
            Cutter::Ball { .. } => Err(DropError::Option(
                "5-axis needs a flat or torus cutter (a ball's contact does not depend on its axis)".into(),
            )),
        }
    }

    /// The contacts along one XY pass, in runs as [`FiveAxis::pass`] has
    /// them: the highest mesh point below each sample, its facet's normal,
    /// and the travel direction from the neighbouring samples.
    pub fn contacts(dc: &DropCutter, xy: &[P2]) -> Vec<Vec<Contact>> {
        Self::contacts_with(dc, xy, None)
    }

    /// [`FiveAxis::contacts`] with the normal at each contact taken from
    /// `smooth` (interpolated across the facet) when given, else the
    /// facet's own.
    pub fn contacts_with(dc: &DropCutter, xy: &[P2], smooth: Option<&SmoothNormals>) -> Vec<Vec<Contact>> {
        let mut runs = Vec::new();
        let mut run: Vec<Contact> = Vec::new();
        for (i, p) in xy.iter().enumerate() {
            let Some((z, t)) = dc.surface_contact(p.x, p.y) else {
                if !run.is_empty() {
                    runs.push(std::mem::take(&mut run));
                }
                continue;
            };
            let cc = P3::new(p.x, p.y, z);
            let facet = {
                let n = dc.tris[t].n;
                V3::new(n[0], n[1], n[2])
            };
            let normal = match smooth {
                Some(s) => dc.smooth_normal_at(s, t, cc),
                None => facet,
            };
            let prev = xy[i.saturating_sub(1)];
            let next = xy[(i + 1).min(xy.len() - 1)];
            let d = next - prev;
            run.push(Contact {
                cc,
                normal,
                facet,
                feed: V3::new(d.x, d.y, 0.0),
            });
        }
        if !run.is_empty() {
            runs.push(run);
        }
        runs
    }

    /// The location for contact `cc` with unit surface normal `n`, travel
    /// direction `feed` (any length; zero for a single point).
    pub fn location(&self, cc: P3, n: V3, feed: V3, r: f64, rc: f64) -> Location {
        // Feed direction in the tangent plane; any tangent when there is none.
        let mut f = feed - n * feed.dot(&n);
        if f.norm() < 1e-12 {
            let helper = if n.x.abs() < 0.9 { V3::x() } else { V3::y() };
            f = helper - n * helper.dot(&n);
        }
        let f = f.normalize();
        let s = n.cross(&f);
        let (sl, cl) = self.lead.sin_cos();
        let (st, ct) = self.tilt.sin_cos();
        let a = (n * (cl * ct) + f * sl + s * (cl * st)).normalize();
        let radial = n - a * n.dot(&a);
        let tip = if radial.norm() < 1e-12 {
            // Axis along the normal: the flat bottom lies on the tangent
            // plane, centred on the contact.
            cc
        } else {
            let w = -radial.normalize();
            cc + n * rc - a * rc - w * (r - rc)
        };
        Location {
            cl: tip,
            axis_point: tip + a * self.axis_length,
        }
    }
}

impl Location {
    /// The unit tool axis, from the tip towards the holder.
    pub fn axis(&self) -> V3 {
        (self.axis_point - self.cl).normalize()
    }
}

/// The angle between two locations' tool axes (radians, 0 to pi).
pub fn axis_change(a: &Location, b: &Location) -> f64 {
    // atan2 of the cross and dot products: exact near 0, where acos of
    // the dot product loses half its digits.
    let (u, v) = (a.axis(), b.axis());
    u.cross(&v).norm().atan2(u.dot(&v))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A location at (x, 0, 0) whose axis leans `deg` degrees from +Z
    /// towards +X.
    pub(crate) fn leaning(x: f64, deg: f64) -> Location {
        let (s, c) = deg.to_radians().sin_cos();
        let cl = P3::new(x, 0.0, 0.0);
        Location {
            cl,
            axis_point: cl + V3::new(s, 0.0, c) * 10.0,
        }
    }

    #[test]
    fn axis_change_is_the_angle_between_the_axes() {
        for (a, b) in [(0.0, 0.0), (0.0, 1e-7), (-30.0, 30.0), (10.0, 95.0), (0.0, 180.0)] {
            let got = axis_change(&leaning(0.0, a), &leaning(1.0, b)).to_degrees();
            let want: f64 = (b - a).abs();
            assert!((got - want).abs() < 1e-9, "{a} -> {b}: {got}");
        }
    }

    #[test]
    fn the_tool_touches_the_contact_point_and_nothing_below_the_tangent_plane() {
        let n = V3::new(0.3, -0.2, 1.0).normalize();
        let cc = P3::new(1.0, 2.0, 3.0);
        for (lead, tilt) in [(0.0, 0.0), (0.1, 0.0), (0.2, -0.15), (0.0, 0.3)] {
            let fa = FiveAxis {
                lead,
                tilt,
                axis_length: 10.0,
            };
            let (r, rc) = (1.0, 0.25);
            let loc = fa.location(cc, n, V3::new(1.0, 0.0, 0.0), r, rc);
            let a = (loc.axis_point - loc.cl) / 10.0;
            assert!((a.norm() - 1.0).abs() < 1e-12);
            // Sample the torus surface: lowest point along n must be the
            // tangent plane (height 0 above it), reached at cc.
            let u = if a.x.abs() < 0.9 { V3::x() } else { V3::y() };
            let e1 = (u - a * u.dot(&a)).normalize();
            let e2 = a.cross(&e1);
            let mut lowest = f64::INFINITY;
            let mut at = P3::origin();
            for i in 0..720 {
                let phi = i as f64 / 720.0 * std::f64::consts::TAU;
                let radial = e1 * phi.cos() + e2 * phi.sin();
                for j in 0..=90 {
                    let th = j as f64 / 90.0 * std::f64::consts::FRAC_PI_2;
                    // tube from the bottom (th = 0) to the side (th = pi/2)
                    let p = loc.cl + a * rc + radial * (r - rc) + radial * (rc * th.sin()) - a * (rc * th.cos());
                    let h = (p - cc).dot(&n);
                    if h < lowest {
                        lowest = h;
                        at = p;
                    }
                }
            }
            assert!(lowest > -1e-4 && lowest < 1e-4, "{lead},{tilt}: {lowest}");
            if lead != 0.0 || tilt != 0.0 {
                assert!((at - cc).norm() < 2e-2, "{lead},{tilt}: {}", (at - cc).norm());
            }
        }
    }
}
