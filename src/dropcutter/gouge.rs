//! The 5-axis gouge check: does the tool, placed at a 5-axis location,
//! cut into the part anywhere other than at its contact point?
//!
//! A 5-axis location ([`super::fiveaxis`]) is made from one contact point
//! and one facet's normal, so nothing in its construction keeps the rest
//! of the cutter out of the part: on a concave region tighter than the
//! tool (a fillet, a trough, the foot of a wall) the flat bottom or the
//! corner of the cutter sits inside the neighbouring facets. The check
//! asks, for each location, how far the cutter must move up its own axis
//! until it only touches the mesh, and that is exactly a drop-cutter
//! question in the tool's frame: turn the mesh so the axis is vertical,
//! drop the same cutter on the same triangles at the axis, and the CL
//! height found above the tip is the depth of the gouge. The contact
//! formulas are the 3-axis ones ([`super::cutter_vs_triangle`]), so the
//! answer is exact against every vertex, edge and facet, not sampled.
//!
//! What counts as the tool: the cutter's profile from its tip up to
//! `length` along the axis (pathgen's `--axis-length`, the second point of
//! Singh 2014's 5-axis row), with the cutter's radius all the way up, and,
//! when given ([`Holder`]), a wider cylinder from the holder's height up
//! (several for a stepped holder: a collet nut, the holder's body, the
//! spindle nose, each from its own height up).
//! Triangles are cut at `length`, so a part of the mesh beyond it (the
//! far wall of a bowl across the axis) is not a gouge. The holder's
//! clearance is a drop too: a flat cutter of the holder's radius dropped
//! on the same turned triangles finds the highest point within that
//! radius, and the holder's face must rise above it.
//!
//! A gouging location is either lifted along its axis by the depth found
//! (the tool then touches the part and leaves material, which the
//! verification shows as an undercut, instead of cutting into it) or left
//! as it is and only reported ([`GougeRule`]); [`super::tilt`] first
//! tries other orientations for the same contact.
//!
//! A location oriented by a smoothed normal ([`super::normals`]) is not
//! tangent to its facet: it touches its contact but dips into the facets
//! round it. Such locations are first set down on the mesh along their
//! axes ([`GougeCheck::settle_one`], the same drop), and what counts as a
//! gouge is then the rise beyond the dip into the contact facet's own
//! plane ([`Placement::SetDown`]): the question the facet rule asks.

use super::DropCutter;
use super::cutter_vs_triangle::{ContactCutter, Tri, drop_on};
use super::fiveaxis::{Contact, Location};
use crate::geometry::{P3, V3};
use crate::mesh::bvh::Bvh;
use crate::mesh::{Mesh, Triangle};
use rayon::prelude::*;

/// Depths up to this are the round-off of the contact itself, not gouges
/// (mm): a location's cutter touches its own facet at a height of about
/// 1e-15 of the coordinates above or below the tip.
pub const GOUGE_TOL: f64 = 1e-6;

/// What to do with a location whose tool cuts into the part.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GougeRule {
    /// Move the tool up its axis until it only touches the part.
    Lift,
    /// Leave the location as it is; only count it.
    Report,
}

/// What the check found over a set of locations.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct GougeReport {
    /// Locations checked.
    pub checked: usize,
    /// Locations whose tool cut into the part by more than [`GOUGE_TOL`].
    pub gouging: usize,
    /// The deepest gouge, along the tool axis (mm); 0 when none.
    pub deepest: f64,
    /// The tool tip of the deepest gouge, as it was before any lift.
    pub deepest_at: Option<P3>,
}

impl GougeReport {
    /// Count one checked location whose tool is `depth` into the part;
    /// true when that is a gouge.
    pub(super) fn record(&mut self, l: &Location, depth: f64) -> bool {
        self.checked += 1;
        if depth <= GOUGE_TOL {
            return false;
        }
        self.gouging += 1;
        if depth > self.deepest {
            self.deepest = depth;
            self.deepest_at = Some(l.cl);
        }
        true
    }
}

/// How a 5-axis location sits on the part before the gouge check judges
/// it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Placement {
    /// Tangent to its contact's facet, as made (facet normals): the check
    /// measures how far it is in the part.
    Tangent,
    /// Set down on the mesh along its axis first (smoothed normals,
    /// [`GougeCheck::settle_one`]): the check measures how far it had to
    /// rise beyond its own facet's plane.
    SetDown,
}

/// What [`GougeCheck::check_settling`] did in setting the locations down.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SettleReport {
    /// Locations set down on the part.
    pub settled: usize,
    /// Locations with no part within reach below (left as they were).
    pub nothing_below: usize,
    /// Locations moved up by more than [`GOUGE_TOL`].
    pub raised: usize,
    /// The largest move up (mm; 0 when none).
    pub highest: f64,
}

/// One location set down on the part ([`GougeCheck::settle_one`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settled {
    /// Where the tool rests.
    pub location: Location,
    /// How far it moved up its axis to get there; `None` when nothing of
    /// the part was within reach (it stays where it was).
    pub raise: Option<f64>,
    /// How deep it was in the part beyond its own facet's plane (or its
    /// holder's clearance, when more): a gouge when above [`GOUGE_TOL`].
    pub depth: f64,
    /// How far its holder still has to rise to clear the part (0 without
    /// a holder).
    pub holder: f64,
}

impl SettleReport {
    pub(super) fn record(&mut self, s: &Settled) {
        let Some(m) = s.raise else {
            self.nothing_below += 1;
            return;
        };
        self.settled += 1;
        self.raised += (m > GOUGE_TOL) as usize;
        self.highest = self.highest.max(m);
    }
}

/// `f` on every location of `runs` with its contact, in parallel; the
/// results by run, in order.
pub(super) fn map_located<T: Send>(
    contacts: &[Vec<Contact>],
    runs: &[Vec<Location>],
    f: impl Fn(&Location, &Contact) -> T + Sync,
) -> Vec<Vec<T>> {
    runs.par_iter()
        .zip(contacts.par_iter())
        .map(|(run, cs)| run.par_iter().zip(cs.par_iter()).map(|(l, c)| f(l, c)).collect())
        .collect()
}

/// `l` moved `depth` up its own axis.
pub(super) fn lifted(l: &Location, depth: f64) -> Location {
    let a = (l.axis_point - l.cl).normalize();
    Location {
        cl: l.cl + a * depth,
        axis_point: l.axis_point + a * depth,
    }
}

/// A mesh and cutter prepared for gouge checks: the drop-cutter's
/// triangles and cutter, and a 3-D tree over the triangles for the
/// capsule queries (built once here, before any parallel work: a tree
/// built lazily inside rayon tasks could steal one of those tasks while it
/// builds and wait on itself).
pub struct GougeCheck<'a> {
    dc: &'a DropCutter,
    bvh: Bvh,
    /// The holder's cylinders (more than one for a stepped holder), each
    /// with a flat cutter of its radius to drop.
    holder: Vec<(Holder, ContactCutter)>,
}

/// A tool holder (or a shank wider than the cutter): a cylinder about the
/// tool axis from `height` above the tip up to the checked length. Below
/// it the tool is the cutter, its radius all the way up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Holder {
    /// Radius (mm), at least the cutter's.
    pub radius: f64,
    /// Distance from the tool tip up the axis to the holder's face (mm):
    /// the tool's stick-out.
    pub height: f64,
}

impl Holder {
    /// Whether this holder can hold a cutter of `cutter_radius` (mm): at
    /// least as wide, its face above the tip, both finite.
    pub fn fits(&self, cutter_radius: f64) -> Result<(), super::DropError> {
        if self.radius.is_finite() && self.radius >= cutter_radius && self.height.is_finite() && self.height > 0.0 {
            return Ok(());
        }
        Err(super::DropError::Option(format!(
            "holder of radius {} at {} mm up the tool: needs a radius of at least the cutter's ({cutter_radius} mm) and a height above 0",
            self.radius, self.height
        )))
    }
}

impl<'a> GougeCheck<'a> {
    /// Prepare checks of `dc`'s cutter against its mesh.
    pub fn new(dc: &'a DropCutter) -> GougeCheck<'a> {
        let tris: Vec<Triangle> = dc
            .tris
            .iter()
            .map(|t| {
                let [a, b, c] = t.v.map(|p| P3::new(p[0], p[1], p[2]));
                Triangle::new(a, b, c)
            })
            .collect();
        GougeCheck {
            dc,
            bvh: Bvh::new(&Mesh::from_triangles(&tris)),
            holder: Vec::new(),
        }
    }

    /// Check the holder too: the tool is the cutter up to `h.height` and a
    /// cylinder of `h.radius` above. Called again, a further cylinder: a
    /// stepped holder is the union of its cylinders, each from its own
    /// height up to the checked length. A cylinder narrower than the
    /// cutter, or not above the tip, is refused.
    pub fn with_holder(mut self, h: Holder) -> Result<Self, super::DropError> {
        h.fits(self.dc.shape.r)?;
        let flat = ContactCutter::new(crate::cutter::Cutter::Flat { radius: h.radius });
        self.holder.push((h, flat));
        Ok(self)
    }

    /// The drop-cutter (mesh and cutter) the checks run against.
    pub(super) fn drop_cutter(&self) -> &DropCutter {
        self.dc
    }

    /// How far the cutter with its tip at `tip` and its axis along `axis`
    /// (towards the holder; any length) must move up that axis so that,
    /// from the tip to `length` up the axis, it meets the mesh only on its
    /// surface: 0 when it is clear already (or touches only), else the
    /// depth of the deepest penetration measured along the axis.
    pub fn clearance(&self, tip: P3, axis: V3, length: f64) -> f64 {
        self.depth_until(tip, axis, length, f64::INFINITY)
    }

    /// Whether the tool clears the part within `tol`: the same answer as
    /// `clearance(tip, axis, length) <= tol`, found sooner where it does
    /// not (the search stops at the first contact deeper than `tol`). The
    /// tilt search asks this of every turn it tries, and most of the
    /// turns it tries at a location that stays lifted cut in.
    pub fn clears(&self, tip: P3, axis: V3, length: f64, tol: f64) -> bool {
        self.depth_until(tip, axis, length, tol) <= tol
    }

    /// [`GougeCheck::clearance`], exact where it is at most `stop`; above
    /// that, some depth above `stop` (the search stops there).
    fn depth_until(&self, tip: P3, axis: V3, length: f64, stop: f64) -> f64 {
        let n = axis.norm();
        let usable = n.is_finite() && n > 0.0 && length > 0.0 && tip.coords.iter().all(|c| c.is_finite());
        if !usable {
            return 0.0;
        }
        let frame = ToolFrame::new(tip, axis / n, length);
        let mut worst = self.drop_in_until(&frame, &self.dc.shape, 0.0, 0.0, stop);
        // Each of the holder's faces must rise above the highest point
        // within its radius (a flat cutter of that radius, dropped): by
        // that height less the face's.
        for (h, flat) in self.holder.iter().filter(|(h, _)| h.height < length) {
            if worst > stop {
                break;
            }
            worst = worst.max(self.drop_in_until(&frame, flat, h.height, worst + h.height, stop + h.height) - h.height);
        }
        worst
    }

    /// How far the cutter with its tip at `tip` and its axis along `axis`
    /// must move along that axis (up positive, down negative) to rest on
    /// the mesh: touching it, nowhere in it, from the tip to `length` up
    /// the axis. Contacts down to at least `below` mm under the tip are
    /// found; `None` when there is none. The cutter only: the holder is
    /// the gouge check's.
    pub fn rest_height(&self, tip: P3, axis: V3, length: f64, below: f64) -> Option<f64> {
        let n = axis.norm();
        let usable = n.is_finite()
            && n > 0.0
            && length > 0.0
            && below >= 0.0
            && below.is_finite()
            && tip.coords.iter().all(|c| c.is_finite());
        if !usable {
            return None;
        }
        let a = axis / n;
        let frame = ToolFrame::new(tip - a * below, a, length + below);
        let h = self.drop_in(&frame, &self.dc.shape, 0.0, f64::NEG_INFINITY);
        (h > f64::NEG_INFINITY).then_some(h - below)
    }

    /// A 5-axis location made tangent to a smoothed surface
    /// ([`super::normals`]) rather than to its facet, set down on the
    /// mesh along its own axis ([`GougeCheck::rest_height`], searched
    /// from the cutter's radius below its tip). Such a tool touches its
    /// contact point but dips into the facets round it; where the part is
    /// tighter than the tool it also cuts in as any location does. Both
    /// are lifted out here, so the tool rests on the mesh; the depth
    /// reported is the second only: how much higher the tool had to rise
    /// than out of its own facet's plane (or the holder's clearance, when
    /// that is more). `c` is the location's contact.
    pub fn settle_one(&self, l: &Location, c: &Contact, length: f64) -> Settled {
        let axis = l.axis_point - l.cl;
        let raise = self.rest_height(l.cl, axis, length, self.dc.shape.r);
        let location = lifted(l, raise.unwrap_or(0.0));
        let own = self.plane_rise(l, c.cc, c.facet);
        let holder = if !self.holder.is_empty() {
            self.clearance(location.cl, axis, length)
        } else {
            0.0
        };
        Settled {
            location,
            raise,
            depth: (raise.unwrap_or(0.0) - own).max(holder),
            holder,
        }
    }

    /// How far the tool of `l` must move up its axis to clear the plane
    /// through `p` with unit normal `n` (the side it points to is
    /// outside): the lowest point of its cutter towards the plane, raised
    /// onto it. 0 where the axis does not rise away from the plane (no
    /// move along it clears the plane).
    pub(super) fn plane_rise(&self, l: &Location, p: P3, n: V3) -> f64 {
        let a = (l.axis_point - l.cl).normalize();
        let rise_per_mm = a.dot(&n);
        // (NaN from a degenerate axis falls here too.)
        if rise_per_mm.is_nan() || rise_per_mm <= 1e-9 {
            return 0.0;
        }
        // The cutter's underside is its flat disc (radius R - rc, at rc up
        // the axis) grown by the corner radius rc: its lowest point
        // towards the plane is the disc's rim point farthest along -n's
        // part across the axis, then rc along -n.
        let s = &self.dc.shape;
        let down = -n;
        let across = down - a * down.dot(&a);
        let rim = if across.norm() > 1e-12 {
            across.normalize() * s.a
        } else {
            V3::zeros()
        };
        let lowest = l.cl + a * s.rc + rim + down * s.rc;
        ((p - lowest).dot(&n) / rise_per_mm).max(0.0)
    }

    /// [`GougeCheck::settle_one`] for every location of `runs` (with
    /// their `contacts`), in parallel, counted on the progress meter.
    pub(super) fn settle_all(
        &self,
        contacts: &[Vec<Contact>],
        runs: &[Vec<Location>],
        length: f64,
    ) -> Vec<Vec<Settled>> {
        map_located(contacts, runs, |l, c| {
            crate::progress::advance(1);
            self.settle_one(l, c, length)
        })
    }

    /// Set every location of `runs` (with their `contacts`) down on the
    /// part ([`GougeCheck::settle_one`]), in parallel, and check them: the
    /// report counts the locations that had to rise beyond their own
    /// facets (or whose holder meets the part). With
    /// [`GougeRule::Lift`] a location whose holder meets the part is
    /// lifted further until it clears; with [`GougeRule::Report`] it is
    /// left set down on the part, its holder in it.
    pub fn check_settling(
        &self,
        contacts: &[Vec<Contact>],
        runs: &mut [Vec<Location>],
        length: f64,
        rule: GougeRule,
    ) -> (GougeReport, SettleReport) {
        let settled = self.settle_all(contacts, runs, length);
        let (mut gouges, mut settling) = (GougeReport::default(), SettleReport::default());
        for (run, settled) in runs.iter_mut().zip(settled) {
            for (l, s) in run.iter_mut().zip(settled) {
                settling.record(&s);
                let gouging = gouges.record(l, s.depth);
                *l = if gouging && rule == GougeRule::Lift && s.holder > GOUGE_TOL {
                    lifted(&s.location, s.holder)
                } else {
                    s.location
                };
            }
        }
        (gouges, settling)
    }

    /// The height, in the tool's frame, at which `shape` dropped down the
    /// axis rests on the mesh's triangles from `from` up the axis to the
    /// frame's length (cut there); `floor` when that is higher. The
    /// candidates come from a capsule query on the mesh's 3-D tree along
    /// the stretch of the axis that can reach the mesh.
    fn drop_in(&self, f: &ToolFrame, shape: &ContactCutter, from: f64, floor: f64) -> f64 {
        self.drop_in_until(f, shape, from, floor, f64::INFINITY)
    }

    /// [`GougeCheck::drop_in`], stopping as soon as a contact is above
    /// `stop`: the result is then some height above `stop`, not the
    /// highest; at or below `stop` it is exact.
    fn drop_in_until(&self, f: &ToolFrame, shape: &ContactCutter, from: f64, floor: f64, stop: f64) -> f64 {
        let (r, length) = (shape.r, f.length);
        let Some((s0, s1)) = self.dc.bbox.clip_line(&f.tip, &f.a, (from, length), r) else {
            return floor;
        };
        let mut best = floor;
        self.bvh
            .try_for_each_near_segment(f.tip + f.a * s0, f.tip + f.a * s1, r, |_, c| {
                let [p, q, w] = [f.local(&c[0]), f.local(&c[1]), f.local(&c[2])];
                // Wholly beyond the checked length, or wholly below the
                // highest contact found: nothing to add.
                if p.z.min(q.z).min(w.z) > length || p.z.max(q.z).max(w.z) <= best {
                    return std::ops::ControlFlow::Continue(());
                }
                let (count, parts) = clip_below(Triangle::new(p, q, w), length);
                for tri in &parts[..count] {
                    let tri = Tri::new(tri);
                    if tri.zmax > best && tri.near(0.0, 0.0, r) {
                        drop_on(shape, 0.0, 0.0, &tri, &mut best);
                    }
                }
                if best > stop {
                    std::ops::ControlFlow::Break(())
                } else {
                    std::ops::ControlFlow::Continue(())
                }
            });
        best
    }

    /// Check every location of `runs` (tools `length` long), lifting the
    /// gouging ones along their axes when `rule` says so; in parallel, and the
    /// same result whatever the thread count.
    pub fn check(&self, runs: &mut [Vec<Location>], length: f64, rule: GougeRule) -> GougeReport {
        let depths: Vec<Vec<f64>> = runs
            .par_iter()
            .map(|run| {
                run.par_iter()
                    .map(|l| {
                        let d = self.clearance(l.cl, l.axis_point - l.cl, length);
                        crate::progress::advance(1);
                        d
                    })
                    .collect()
            })
            .collect();
        let mut report = GougeReport::default();
        for (run, depths) in runs.iter_mut().zip(&depths) {
            for (l, &d) in run.iter_mut().zip(depths) {
                if report.record(l, d) && rule == GougeRule::Lift {
                    *l = lifted(l, d);
                }
            }
        }
        report
    }
}

/// A tool's frame: the tip at the origin, the unit axis `a` as z, and the
/// length of tool checked.
struct ToolFrame {
    tip: P3,
    a: V3,
    e1: V3,
    e2: V3,
    length: f64,
}

impl ToolFrame {
    fn new(tip: P3, a: V3, length: f64) -> ToolFrame {
        let helper = if a.x.abs() < 0.9 { V3::x() } else { V3::y() };
        let e1 = (helper - a * helper.dot(&a)).normalize();
        let e2 = a.cross(&e1);
        ToolFrame { tip, a, e1, e2, length }
    }

    /// `p` in the frame.
    fn local(&self, p: &P3) -> P3 {
        let d = p - self.tip;
        P3::new(d.dot(&self.e1), d.dot(&self.e2), d.dot(&self.a))
    }
}

/// The part of triangle `t` at or below height `h` (z), as up to two
/// triangles (the count, then the triangles).
fn clip_below(t: Triangle, h: f64) -> (usize, [Triangle; 2]) {
    let v = [t.a, t.b, t.c];
    if v.iter().all(|p| p.z <= h) {
        return (1, [t, t]);
    }
    let mut poly = [P3::origin(); 4];
    let mut n = 0;
    for i in 0..3 {
        let (p, q) = (v[i], v[(i + 1) % 3]);
        if p.z <= h {
            poly[n] = p;
            n += 1;
        }
        if (p.z <= h) != (q.z <= h) {
            let s = (h - p.z) / (q.z - p.z);
            let mut x = p + (q - p) * s;
            x.z = h;
            poly[n] = x;
            n += 1;
        }
    }
    let first = Triangle::new(poly[0], poly[1], poly[2]);
    match n {
        3 => (1, [first, first]),
        4 => (2, [first, Triangle::new(poly[0], poly[2], poly[3])]),
        _ => (0, [first, first]),
    }
}

#[cfg(test)]
#[path = "gouge_tests.rs"]
pub(crate) mod tests;
