//! Placing entities in the world: OCS, block insertion (nested, scaled,
//! mirrored, arrayed), units and user transforms, all as one affine map per
//! entity; curves leave here as exact lines and arcs.

use super::curves::{Conic, Curve, FitPoints, FitStats, Nurbs, fit_biarcs};
use super::entities::{Entity, EntityShape, Insert};
use super::ocs::Affine;
use super::reader::Pos;
use crate::geometry::tol::normalize_angle;
use crate::geometry::{P3, V3};
use crate::model::chain::Segment;
use std::collections::{BTreeMap, HashMap};
use std::f64::consts::TAU;

/// A block definition: entities drawn relative to a base point, placed
/// by INSERTs.
#[derive(Debug, Default)]
pub struct BlockDef {
    /// The base point (groups 10/20/30 of BLOCK), which an INSERT puts at
    /// its insertion point.
    pub base: P3,
    /// The block's entities as read (their own coordinates, nested
    /// INSERTs unexpanded).
    pub entities: Vec<Entity>,
}

/// Where expanded geometry goes, with what was counted on the way.
#[derive(Debug, Default)]
pub struct Sink {
    /// Segments with the index of their layer in `layers`.
    pub segments: Vec<(Segment, u32)>,
    /// POINT entities (mm, world) with the index of their layer.
    pub points: Vec<(P3, u32)>,
    /// Layer names in order of first use; the indices above point here.
    pub layers: Vec<String>,
    layer_ids: HashMap<String, u32>,
    /// The layer asked for last (drawings come in runs of one layer).
    last_layer: Option<u32>,
    /// Entities turned into geometry, by type.
    pub used: Tally,
    /// Warnings, by text, with counts.
    pub warnings: BTreeMap<String, u64>,
    /// Splines and ellipses fitted with biarcs.
    pub curves: u64,
    /// Arcs and lines those fits gave.
    pub curve_pieces: u64,
    /// Straight chords a polyline would need for the same curves within
    /// the same tolerance (for the summary's comparison).
    pub curve_chords: u64,
    /// The drawing expanded past `max_segments` segments or expanded
    /// entities: the result is incomplete and must not be used.
    pub overflow: bool,
    /// Entities visited so far, every copy of every insert counted: the
    /// work bound for inserts of empty or layer-filtered blocks.
    pub expanded: u64,
    /// Bad geometry (a coordinate beyond [`MAX_COORD`] after units and
    /// transforms): where the entity sits and what is wrong. The result
    /// must not be used.
    pub bad: Option<(Pos, String)>,
    /// Blocks being expanded, outermost first (the insert stack).
    stack: Vec<String>,
    /// The fit of the curve the entity being expanded draws, made ahead
    /// of its turn (set by `Expander::entity_prefitted`); used when it is
    /// what the fit in turn would give.
    prefit: Option<Prefit>,
    /// Curves whose fit made ahead was used.
    pub(crate) prefits_used: u64,
}

/// Counts by entity type. The types are a dozen literals, so a short list
/// matched by address (then by text, should one literal have two copies)
/// replaces a `BTreeMap`: its string comparisons, a `memcmp` call each, cost
/// about a twentieth of the placer's time on the mix benchmark drawing.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct Tally(Vec<(&'static str, u64)>);

impl Tally {
    /// Count one more `name`.
    pub fn add(&mut self, name: &'static str) {
        if let Some(e) = self.0.iter_mut().find(|e| std::ptr::eq(e.0, name)) {
            e.1 += 1;
        } else if let Some(e) = self.0.iter_mut().find(|e| e.0 == name) {
            e.1 += 1;
        } else {
            self.0.push((name, 1));
        }
    }

    /// The count of `name`, if any was counted.
    pub fn get(&self, name: &str) -> Option<&u64> {
        self.0.iter().find(|e| e.0 == name).map(|e| &e.1)
    }

    /// Nothing counted.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// The counts, by name in alphabetical order.
    pub fn iter(&self) -> impl Iterator<Item = (&'static str, u64)> {
        let mut v = self.0.clone();
        v.sort_unstable_by_key(|e| e.0);
        v.into_iter()
    }
}

/// `a == b`, compared in line: layer names are a few bytes, and `==` on
/// strings calls `memcmp` once the lengths agree, twice an entity.
#[inline]
fn same_name(a: &str, b: &str) -> bool {
    a.len() == b.len() && a.bytes().zip(b.bytes()).all(|(x, y)| x == y)
}

/// A curve fitted ahead of its turn.
#[derive(Debug)]
pub struct Prefit {
    /// The pieces, as [`fit_biarcs`] gives them.
    pub pieces: Vec<Segment>,
    /// What the fit counted.
    pub stats: FitStats,
}

/// What a SPLINE entity draws under a transform.
enum SplineCurve {
    Curve(Box<dyn Curve>),
    /// A control or fit point beyond [`MAX_COORD`].
    OutOfRange(P3),
    /// Fewer than two points: nothing to draw.
    TooFew,
}

/// The curve of a SPLINE's data under `t`.
fn spline_curve(t: &Affine, shape: &EntityShape) -> Option<SplineCurve> {
    let EntityShape::Spline {
        degree,
        knots,
        ctrl,
        weights,
        fit,
        ..
    } = shape
    else {
        return None;
    };
    let ctrl_w: Vec<P3> = ctrl.iter().map(|p| t.apply(p)).collect();
    let fit_w: Vec<P3> = fit.iter().map(|p| t.apply(p)).collect();
    // Far-out control points would make the fit subdivide for ever:
    // refuse them before fitting.
    if let Some(p) = ctrl_w.iter().chain(&fit_w).find(|p| !in_range(p)) {
        return Some(SplineCurve::OutOfRange(*p));
    }
    let curve: Option<Box<dyn Curve>> = if ctrl_w.len() >= 2 {
        Nurbs::new(*degree, knots.clone(), ctrl_w, weights.clone()).map(|n| Box::new(n) as Box<dyn Curve>)
    } else if fit.len() >= 2 {
        Some(Box::new(FitPoints { pts: fit_w }))
    } else {
        None
    };
    Some(curve.map_or(SplineCurve::TooFew, SplineCurve::Curve))
}

/// How to expand: tolerance and layer filter.
pub struct Expander<'a> {
    /// The drawing's blocks by upper-cased name.
    pub blocks: &'a HashMap<String, BlockDef>,
    /// Fitting tolerance for splines and ellipses (mm), also the distance
    /// within which a nearly straight arc with a far-out centre becomes
    /// its chord.
    pub arc_tol: f64,
    /// Empty: every layer.
    pub layers: &'a [String],
    /// Stop (and set [`Sink::overflow`]) past this many segments.
    pub max_segments: usize,
}

/// Blocks nested deeper than this are refused (each level is a stack frame
/// of the expansion); a block on its own insert stack is recursion, told
/// apart at any depth.
pub const MAX_NESTING: usize = 1000;
/// The default bound on the segments (and expanded entities) of one
/// drawing, a guard against block bombs (arrays of arrays of arrays...):
/// about 2 GB of geometry.
pub const MAX_SEGMENTS: usize = 20_000_000;
/// Coordinates (in mm, after units, inserts and user transforms) beyond
/// this are bad input: no machine travels a kilometre, and past this the
/// join tolerance is below the doubles' resolution.
pub const MAX_COORD: f64 = 1e9;

fn in_range(p: &P3) -> bool {
    // Written so that NaN fails too.
    p.x.abs() <= MAX_COORD && p.y.abs() <= MAX_COORD && p.z.abs() <= MAX_COORD
}

fn fmt_point(p: &P3) -> String {
    let f = |v: f64| {
        if v.abs() < 1e6 {
            format!("{v}")
        } else {
            format!("{v:e}")
        }
    };
    format!("({}, {}, {})", f(p.x), f(p.y), f(p.z))
}

impl Sink {
    fn layer_id(&mut self, name: &str) -> u32 {
        /// Up to this many layers, a name is looked up by comparing.
        const FEW_LAYERS: usize = 8;
        if let Some(i) = self.last_layer
            && self.layers.get(i as usize).is_some_and(|l| same_name(l, name))
        {
            return i;
        }
        // A few layers are compared by name, not hashed: drawings of a cut
        // layer and a mark layer switch between them entity by entity, and
        // SipHash cost more than the comparisons.
        let known = if self.layers.len() <= FEW_LAYERS {
            self.layers.iter().position(|l| same_name(l, name)).map(|i| i as u32)
        } else {
            self.layer_ids.get(name).copied()
        };
        if let Some(i) = known {
            self.last_layer = Some(i);
            return i;
        }
        let i = self.layers.len() as u32;
        self.layers.push(name.to_string());
        self.layer_ids.insert(name.to_string(), i);
        self.last_layer = Some(i);
        i
    }

    fn warn(&mut self, w: String) {
        *self.warnings.entry(w).or_default() += 1;
    }

    /// Set [`Sink::bad`] for `pos` unless it is set already.
    fn out_of_range(&mut self, pos: Pos, p: &P3) {
        if self.bad.is_none() {
            self.bad = Some((
                pos,
                format!(
                    "coordinate {} mm is beyond what a machine can mean (|x|, |y|, |z| at most {MAX_COORD:e} mm after units and transforms)",
                    fmt_point(p)
                ),
            ));
        }
    }

    /// Anything that must stop the expansion.
    pub fn stopped(&self) -> bool {
        self.overflow || self.bad.is_some()
    }
}

/// A nearly straight arc (a bulge of 1e-10, a fitted piece along a
/// straight stretch) has its centre far out although its ends are near:
/// when it lies within `tol` of its chord it becomes that chord, so no
/// coordinate of the output is out of range. Others are left for the range
/// check to refuse.
fn flatten_far_arc(s: &mut Segment, tol: f64) {
    let Segment::Arc(arc) = *s else {
        return;
    };
    let (start, end, center, ccw) = (arc.start, arc.end, arc.center, arc.ccw);
    if in_range(&center) || !in_range(&start) || !in_range(&end) {
        return;
    }
    let (a, b) = (start - center, end - center);
    let cross = a.x * b.y - a.y * b.x;
    if cross == 0.0 || (cross > 0.0) != ccw {
        // A full circle or a major arc: as far out as its centre.
        return;
    }
    let r = arc.radius();
    let half = 0.5 * (end - start).xy().norm();
    let sagitta = half * half / (r + (r * r - half * half).max(0.0).sqrt());
    if sagitta <= tol {
        *s = Segment::line(start, end);
    }
}

/// The first out-of-range point of a segment, if any.
fn first_out_of_range(s: &Segment) -> Option<P3> {
    match s {
        Segment::Line(l) => [l.start, l.end].into_iter().find(|p| !in_range(p)),
        Segment::Arc(a) => [a.start, a.end, a.center].into_iter().find(|p| !in_range(p)),
    }
}

impl Expander<'_> {
    /// The splines the top-level entities `batch` draw, each under every
    /// transform of `tops`, numbered `i * tops.len() + j` for entity `i`
    /// under transform `j` (layers the filter drops are left out).
    pub(super) fn spline_curves(&self, batch: &[Entity], tops: &[Affine]) -> Vec<(usize, Box<dyn Curve>)> {
        let mut curves = Vec::new();
        for (i, e) in batch.iter().enumerate() {
            if self.keeps(&e.layer) {
                for (j, t) in tops.iter().enumerate() {
                    if let Some(SplineCurve::Curve(c)) = spline_curve(t, &e.shape) {
                        curves.push((i * tops.len() + j, c));
                    }
                }
            }
        }
        curves
    }

    /// [`Expander::entity`] for a top-level entity, with the fit of the
    /// spline it draws made ahead, if any (used only when it is what the
    /// fit in turn would give).
    pub(super) fn entity_prefitted(&self, e: &Entity, t: &Affine, prefit: Option<Prefit>, sink: &mut Sink) {
        sink.prefit = prefit;
        self.entity(e, t, None, 0, sink);
        sink.prefit = None;
    }

    /// Whether the layer filter keeps `layer`.
    fn keeps(&self, layer: &str) -> bool {
        self.layers.is_empty() || self.layers.iter().any(|l| l == layer)
    }

    /// Expand one entity under transform `t`; `inherit` is the layer that
    /// replaces "0" inside blocks.
    pub fn entity(&self, e: &Entity, t: &Affine, inherit: Option<&str>, depth: usize, sink: &mut Sink) {
        let layer = match inherit {
            Some(l) if &*e.layer == "0" => l,
            _ => &e.layer,
        };
        if sink.stopped() {
            return;
        }
        sink.expanded += 1;
        if sink.segments.len() > self.max_segments || sink.expanded > self.max_segments as u64 {
            sink.overflow = true;
            return;
        }
        if let EntityShape::Insert(ins) = &e.shape {
            self.insert(ins, e.pos, t, layer, depth, sink);
            return;
        }
        if !self.keeps(layer) {
            return;
        }
        let lid = sink.layer_id(layer);
        let before = sink.segments.len();
        let name = match &e.shape {
            EntityShape::Line { a, b } => {
                sink.segments.push((Segment::line(t.apply(a), t.apply(b)), lid));
                "LINE"
            }
            EntityShape::Arc { c, r, a0, a1, ext } => {
                let t = t.with_ocs(ext);
                let a0r = a0.to_radians();
                // Counter-clockwise from a0 to a1; equal angles are a full circle.
                let mut sweep = normalize_angle((a1 - a0).to_radians());
                if sweep == 0.0 {
                    sweep = TAU;
                }
                self.conic(&t, c, *r, (a0r, sweep), lid, sink);
                "ARC"
            }
            EntityShape::Circle { c, r, ext } => {
                let t = t.with_ocs(ext);
                self.conic(&t, c, *r, (0.0, TAU), lid, sink);
                "CIRCLE"
            }
            EntityShape::Poly2 {
                verts,
                closed,
                elevation,
                ext,
                lw,
            } => {
                let t = t.with_ocs(ext);
                self.poly2(&t, verts, *closed, *elevation, lid, sink);
                if *lw { "LWPOLYLINE" } else { "POLYLINE" }
            }
            EntityShape::Poly3 { verts, closed } => {
                let n = verts.len();
                let pairs = if *closed && n > 2 { n } else { n.saturating_sub(1) };
                for i in 0..pairs {
                    sink.segments
                        .push((Segment::line(t.apply(&verts[i]), t.apply(&verts[(i + 1) % n])), lid));
                }
                "POLYLINE"
            }
            EntityShape::Ellipse {
                c,
                major,
                ratio,
                t0,
                t1,
                ext,
            } => {
                let n = ext.try_normalize(1e-12).unwrap_or(V3::z());
                let minor = n.cross(major) * *ratio;
                let mut sweep = normalize_angle(t1 - t0);
                if sweep < 1e-12 {
                    sweep = TAU;
                }
                let conic = Conic {
                    c: t.apply(c),
                    u: t.apply_vec(major),
                    v: t.apply_vec(&minor),
                    t0: *t0,
                    sweep,
                };
                if let Some(p) = conic_out_of_range(&conic) {
                    sink.out_of_range(e.pos, &p);
                    return;
                }
                self.place_conic(conic, lid, sink);
                "ELLIPSE"
            }
            EntityShape::Spline { .. } => {
                match spline_curve(t, &e.shape) {
                    Some(SplineCurve::Curve(c)) => self.fit(c.as_ref(), lid, sink),
                    Some(SplineCurve::OutOfRange(p)) => {
                        sink.out_of_range(e.pos, &p);
                        return;
                    }
                    _ => sink.warn("SPLINE with fewer than two points left out".into()),
                }
                "SPLINE"
            }
            EntityShape::Point { p } => {
                let q = t.apply(p);
                if !in_range(&q) {
                    sink.out_of_range(e.pos, &q);
                    return;
                }
                sink.points.push((q, lid));
                "POINT"
            }
            EntityShape::Insert(_) => "INSERT",
        };
        let flat = self.arc_tol.max(1e-9);
        for (s, _) in &mut sink.segments[before..] {
            flatten_far_arc(s, flat);
        }
        if let Some(p) = sink.segments[before..].iter().find_map(|(s, _)| first_out_of_range(s)) {
            sink.out_of_range(e.pos, &p);
            return;
        }
        // The entity that takes the drawing past the bound is the one
        // named, the last one in the file included (the check above only
        // looks before each entity).
        if sink.segments.len() > self.max_segments {
            sink.overflow = true;
        }
        if depth == 0 {
            sink.used.add(name);
        }
    }

    fn insert(&self, ins: &Insert, pos: Pos, t: &Affine, layer: &str, depth: usize, sink: &mut Sink) {
        if depth == 0 {
            sink.used.add("INSERT");
        }
        let Some(block) = self.blocks.get(&ins.block) else {
            sink.warn(format!("INSERT of undefined block '{}' left out", ins.block));
            return;
        };
        if let Some(k) = sink.stack.iter().position(|b| *b == ins.block) {
            // Recursion: the block is being expanded already. Its geometry
            // is drawn once, at the outermost level; the inner insert is
            // the cycle and is left out.
            let cycle: Vec<&str> = sink.stack[k..]
                .iter()
                .map(|s| s.as_str())
                .chain([ins.block.as_str()])
                .collect();
            sink.warn(format!(
                "block '{}' inserts itself ({}): the recursive INSERT left out",
                ins.block,
                cycle.join(" -> ")
            ));
            return;
        }
        if sink.stack.len() >= MAX_NESTING {
            if sink.bad.is_none() {
                sink.bad = Some((
                    pos,
                    format!(
                        "blocks nested more than {MAX_NESTING} levels deep (INSERT of '{}' inside '{}')",
                        ins.block,
                        sink.stack.last().map(|s| s.as_str()).unwrap_or("")
                    ),
                ));
            }
            return;
        }
        let place = t
            .then_after(&Affine::ocs(ins.ext))
            .then_after(&Affine::translate(ins.p.coords))
            .then_after(&Affine::rotate_z(ins.rotation_deg.to_radians()));
        let scale_base =
            Affine::scale(ins.scale.x, ins.scale.y, ins.scale.z).then_after(&Affine::translate(-block.base.coords));
        for row in 0..ins.rows {
            for col in 0..ins.cols {
                // Array spacing is in the rotated insert frame, not scaled.
                let offset = V3::new(col as f64 * ins.col_spacing, row as f64 * ins.row_spacing, 0.0);
                if sink.stopped() {
                    // Stop at every level at once, not copy by copy.
                    return;
                }
                let m = place.then_after(&Affine::translate(offset)).then_after(&scale_base);
                if !m.is_finite() {
                    sink.warn(format!(
                        "INSERT of '{}' with a non-finite transform left out",
                        ins.block
                    ));
                    return;
                }
                sink.stack.push(ins.block.clone());
                for e in &block.entities {
                    self.entity(e, &m, Some(layer), depth + 1, sink);
                }
                sink.stack.pop();
                // An empty block copied a billion times is work too.
                sink.expanded += 1;
                if sink.expanded > self.max_segments as u64 {
                    sink.overflow = true;
                }
            }
        }
    }

    /// `span` is (start angle, signed sweep) in radians.
    fn conic(&self, t: &Affine, c: &P3, r: f64, span: (f64, f64), lid: u32, sink: &mut Sink) {
        let (a0, sweep) = span;
        if !(r.is_finite() && r > 0.0) {
            // A point-sized circle or arc: let chaining count it as dropped.
            let p = t.apply(c);
            sink.segments.push((Segment::line(p, p), lid));
            return;
        }
        let conic = Conic {
            c: t.apply(c),
            u: t.apply_vec(&V3::new(r, 0.0, 0.0)),
            v: t.apply_vec(&V3::new(0.0, r, 0.0)),
            t0: a0,
            sweep,
        };
        self.place_conic(conic, lid, sink);
    }

    /// An elliptical arc in the world: an exact arc when its XY shadow is a
    /// circle (the usual case: arcs under rotation, uniform scale,
    /// mirroring), else biarcs.
    fn place_conic(&self, k: Conic, lid: u32, sink: &mut Sink) {
        let (ux, uy, vx, vy) = (k.u.x, k.u.y, k.v.x, k.v.y);
        let Shadow {
            lu,
            lv,
            cross,
            circular,
        } = Shadow::of(&k.u, &k.v);
        if circular {
            // The point at the angle of cosine `c` and sine `s`.
            let at_cos_sin = |c: f64, s: f64| P3::new(k.c.x + ux * c + vx * s, k.c.y + uy * c + vy * s, k.c.z);
            let at = |a: f64| at_cos_sin(a.cos(), a.sin());
            // A circle starts at angle 0, whose cosine and sine are 1 and 0
            // exactly: its point is made without the `sincos` call.
            let start = if k.t0.to_bits() == 0 {
                at_cos_sin(1.0, 0.0)
            } else {
                at(k.t0)
            };
            let full = k.sweep >= TAU - 1e-12;
            let end = if full { start } else { at(k.t0 + k.sweep) };
            sink.segments.push((
                Segment::arc_xy(
                    start,
                    end,
                    P3::new(k.c.x, k.c.y, k.c.z),
                    (k.sweep > 0.0) == (cross > 0.0),
                ),
                lid,
            ));
            return;
        }
        if cross.abs() <= 1e-12 * (lu * lv).max(1e-300) {
            // Seen edge-on: the shadow is a straight line, traced back and forth.
            sink.warn("arc or ellipse seen edge-on (extrusion in the XY plane) drawn as its chord".into());
            let a = k.point(0.0);
            let b = k.point(1.0);
            sink.segments.push((Segment::line(a, b), lid));
            return;
        }
        if let Some(p) = conic_out_of_range(&k) {
            // Reported by the caller, which knows the entity's position
            // (from this line's far end); never fit a curve this large.
            sink.segments.push((Segment::line(k.c, p), lid));
            return;
        }
        self.fit(&k, lid, sink);
    }

    fn fit(&self, c: &dyn Curve, lid: u32, sink: &mut Sink) {
        // One more piece than the bound leaves room for, so a curve that
        // does not fit overruns it by a piece and stops there; the check
        // at the end of `entity` then sees the drawing past the bound (the
        // one place that decides it).
        let left = self.max_segments.saturating_sub(sink.segments.len()).saturating_add(1);
        // A fit made ahead with at least this room that stayed short of
        // `left` pieces never met the bound: it is this fit, piece for
        // piece (the same curve, tolerance and step bound).
        let (segs, st) = match sink.prefit.take() {
            Some(p) if !p.stats.over_budget && p.pieces.len() < left => {
                sink.prefits_used += 1;
                (p.pieces, p.stats)
            }
            _ => {
                let mut segs = Vec::new();
                let st = fit_biarcs(c, self.arc_tol, left, &mut segs);
                (segs, st)
            }
        };
        if st.truncated {
            sink.warn(format!(
                "a curve needed more than {} fitting steps at --arc-tol {}: the rest of it drawn as chords (raise --arc-tol)",
                super::curves::MAX_STEPS,
                self.arc_tol
            ));
        }
        sink.curves += 1;
        sink.curve_pieces += st.pieces;
        sink.curve_chords += st.chords;
        sink.segments.extend(segs.into_iter().map(|s| (s, lid)));
    }

    fn poly2(&self, t: &Affine, verts: &[(f64, f64, f64)], closed: bool, z: f64, lid: u32, sink: &mut Sink) {
        let n = verts.len();
        let pairs = if closed && n > 1 { n } else { n.saturating_sub(1) };
        for i in 0..pairs {
            let (x0, y0, b) = verts[i];
            let (x1, y1, _) = verts[(i + 1) % n];
            let p0 = P3::new(x0, y0, z);
            let p1 = P3::new(x1, y1, z);
            if b == 0.0 || p0 == p1 {
                sink.segments.push((Segment::line(t.apply(&p0), t.apply(&p1)), lid));
                continue;
            }
            let (c, r, sweep) = bulge_circle(&p0, &p1, b);
            // Snap the ends to the vertices exactly: the arc maths is a
            // hair off, and consecutive pieces must share ends.
            if let Some(k) = circular_bulge(t, &c, r, sweep) {
                // The usual case, the shadow a circle: the arc is its centre,
                // turn and the two vertices, so its start angle and the
                // points at both ends (an `atan2` and two `sincos`, about a
                // tenth of the placer's time on the mix benchmark drawing)
                // would only be overwritten. Bit for bit what the general
                // path below gives (unit test).
                let mut s = Segment::arc_xy(k.center, k.center, k.center, k.ccw);
                s.set_start(t.apply(&p0));
                s.set_end(t.apply(&p1));
                sink.segments.push((s, lid));
                continue;
            }
            let a0 = (p0.y - c.y).atan2(p0.x - c.x);
            let before = sink.segments.len();
            self.conic(t, &c, r, (a0, sweep), lid, sink);
            if sink.segments.len() == before + 1
                && let Some((s @ Segment::Arc(_), _)) = sink.segments.get_mut(before)
            {
                s.set_start(t.apply(&p0));
                s.set_end(t.apply(&p1));
            }
        }
    }
}

/// The circle of a bulged polyline segment from `p0` to `p1` (OCS):
/// centre, radius and signed sweep (bulge = tan(sweep / 4), positive
/// counter-clockwise). `b` is not 0 and the points differ.
fn bulge_circle(p0: &P3, p1: &P3, b: f64) -> (P3, f64, f64) {
    let sweep = 4.0 * b.atan();
    let d = p1 - p0;
    let chord = d.xy().norm();
    let r = chord / (2.0 * (sweep / 2.0).sin().abs());
    let m = P3::from((p0.coords + p1.coords) * 0.5);
    let left = V3::new(-d.y, d.x, 0.0) / chord;
    let c = m + left * (chord / 2.0) * ((1.0 - b * b) / (2.0 * b));
    (c, r, sweep)
}

/// A bulge's arc in the world: centre and turn (see [`circular_bulge`]).
struct BulgeArc {
    center: P3,
    ccw: bool,
}

/// What [`Expander::conic`] and [`Expander::place_conic`] make of a bulge's
/// arc (OCS centre `c`, radius `r`, signed `sweep`) under `t` when they
/// make one exact arc: its world centre and turn, with the ends left for
/// the caller to set. `None` where they would do anything else (a radius
/// that is not positive, a shadow that is not a circle), so the caller
/// takes the general path.
fn circular_bulge(t: &Affine, c: &P3, r: f64, sweep: f64) -> Option<BulgeArc> {
    if !(r.is_finite() && r > 0.0) {
        return None;
    }
    let center = t.apply(c);
    let u = t.apply_vec(&V3::new(r, 0.0, 0.0));
    let v = t.apply_vec(&V3::new(0.0, r, 0.0));
    let shadow = Shadow::of(&u, &v);
    shadow.circular.then_some(BulgeArc {
        center,
        ccw: (sweep > 0.0) == (shadow.cross > 0.0),
    })
}

/// A conic's XY shadow, from its semi-diameters `u` and `v`.
struct Shadow {
    /// Lengths of `u` and `v` in XY.
    lu: f64,
    lv: f64,
    /// Their cross product: the sign of the turn.
    cross: f64,
    /// A circle: equal lengths, square to each other, within 1e-12 relative.
    circular: bool,
}

impl Shadow {
    fn of(u: &V3, v: &V3) -> Shadow {
        let (ux, uy, vx, vy) = (u.x, u.y, v.x, v.y);
        let lu = ux.hypot(uy);
        let lv = vx.hypot(vy);
        Shadow {
            lu,
            lv,
            cross: ux * vy - uy * vx,
            circular: lu > 0.0 && (lu - lv).abs() <= 1e-12 * lu && (ux * vx + uy * vy).abs() <= 1e-12 * lu * lu,
        }
    }
}

/// A point of the conic's bounding parallelogram beyond [`MAX_COORD`].
fn conic_out_of_range(k: &Conic) -> Option<P3> {
    [k.c, k.c + k.u + k.v, k.c - k.u - k.v, k.c + k.u - k.v, k.c - k.u + k.v]
        .into_iter()
        .find(|p| !in_range(p))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dxf::reader::Pos;

    fn ent(shape: EntityShape) -> Entity {
        Entity {
            layer: "0".into(),
            shape,
            pos: Pos::Line(1),
        }
    }

    fn expand(e: &Entity, blocks: &HashMap<String, BlockDef>) -> Sink {
        let x = Expander {
            blocks,
            arc_tol: 0.001,
            layers: &[],
            max_segments: MAX_SEGMENTS,
        };
        let mut sink = Sink::default();
        x.entity(e, &Affine::identity(), None, 0, &mut sink);
        sink
    }

    #[test]
    fn mirrored_ocs_arc_turns_clockwise() {
        let e = ent(EntityShape::Arc {
            c: P3::new(10.0, 0.0, 0.0),
            r: 1.0,
            a0: 0.0,
            a1: 90.0,
            ext: V3::new(0.0, 0.0, -1.0),
        });
        let s = expand(&e, &HashMap::new());
        let (Segment::Arc(a), _) = s.segments[0] else { panic!() };
        let (start, end, center, ccw) = (a.start, a.end, a.center, a.ccw);
        assert_eq!(center, P3::new(-10.0, 0.0, 0.0));
        assert!((start - P3::new(-11.0, 0.0, 0.0)).norm() < 1e-12);
        assert!((end - P3::new(-10.0, 1.0, 0.0)).norm() < 1e-12);
        assert!(!ccw);
    }

    /// The bulge arcs' shortcut gives bit for bit what the general path
    /// (start angle, conic, ends snapped) gives, under rotations, uniform
    /// and uneven scales, mirrors and tilted extrusions; uneven scales and
    /// tilts take the general path, the others the shortcut.
    #[test]
    fn bulge_arcs_shortcut_is_the_general_path_bit_for_bit() {
        let x = Expander {
            blocks: &HashMap::new(),
            arc_tol: 0.001,
            layers: &[],
            max_segments: MAX_SEGMENTS,
        };
        let mut next = crate::geometry::test_rng::unit_rng(0x2545_f491_4f6c_dd1d);
        let (mut shortcut, mut general) = (0, 0);
        for case in 0..4000 {
            let (sx, sy) = match case % 4 {
                0 => (1.0, 1.0),
                1 => {
                    let k = 0.01 + 100.0 * next();
                    (k, k)
                }
                2 => (-2.5, 2.5),
                _ => (0.5 + next(), 0.5 + next()),
            };
            let ext = if case % 7 == 0 {
                V3::new(next() - 0.5, next() - 0.5, 1.0)
            } else {
                V3::z()
            };
            let t = Affine::translate(V3::new(1e3 * (next() - 0.5), 1e3 * (next() - 0.5), next()))
                .then_after(&Affine::rotate_z(7.0 * next()))
                .then_after(&Affine::scale(sx, sy, 1.0))
                .with_ocs(&ext);
            let b = match case % 5 {
                0 => 1.0,
                1 => -1e-9,
                2 => 1e13,
                _ => 4.0 * (next() - 0.5),
            };
            let verts = [
                (1e3 * (next() - 0.5), 1e3 * (next() - 0.5), b),
                (1e3 * (next() - 0.5), next(), 0.0),
            ];
            let z = next();
            let mut fast = Sink::default();
            x.poly2(&t, &verts, false, z, 0, &mut fast);
            // The general path, as it was before the shortcut.
            let mut slow = Sink::default();
            let (p0, p1) = (P3::new(verts[0].0, verts[0].1, z), P3::new(verts[1].0, verts[1].1, z));
            let (c, r, sweep) = bulge_circle(&p0, &p1, b);
            let a0 = (p0.y - c.y).atan2(p0.x - c.x);
            x.conic(&t, &c, r, (a0, sweep), 0, &mut slow);
            if slow.segments.len() == 1
                && let Some((s @ Segment::Arc(_), _)) = slow.segments.get_mut(0)
            {
                s.set_start(t.apply(&p0));
                s.set_end(t.apply(&p1));
            }
            if circular_bulge(&t, &c, r, sweep).is_some() {
                shortcut += 1;
            } else {
                general += 1;
            }
            assert_eq!(
                format!("{:?}", fast.segments),
                format!("{:?}", slow.segments),
                "case {case}"
            );
        }
        assert!(shortcut > 2000 && general > 500, "{shortcut} {general}");
    }

    #[test]
    fn tally_counts_by_name_and_lists_them_in_order() {
        let mut t = Tally::default();
        assert!(t.is_empty());
        for n in ["LINE", "ARC", "LINE", "CIRCLE", "LINE", "ARC"] {
            t.add(n);
        }
        // A name from another copy of the text counts with the first.
        let line = String::from("LINE");
        t.add(Box::leak(line.into_boxed_str()));
        assert_eq!(t.get("LINE"), Some(&4));
        assert_eq!(t.get("ARC"), Some(&2));
        assert_eq!(t.get("SPLINE"), None);
        let listed: Vec<(&str, u64)> = t.iter().collect();
        assert_eq!(listed, [("ARC", 2), ("CIRCLE", 1), ("LINE", 4)]);
        assert!(same_name("CUT", "CUT") && !same_name("CUT", "CUTS") && !same_name("CUT", "CAT"));
    }

    #[test]
    fn bulge_semicircle() {
        let e = ent(EntityShape::Poly2 {
            verts: vec![(0.0, 0.0, 1.0), (2.0, 0.0, 0.0)],
            closed: false,
            elevation: 0.0,
            ext: V3::z(),
            lw: true,
        });
        let s = expand(&e, &HashMap::new());
        let (Segment::Arc(a), _) = s.segments[0] else { panic!() };
        let (center, ccw) = (a.center, a.ccw);
        assert!((center - P3::new(1.0, 0.0, 0.0)).norm() < 1e-12);
        assert!(ccw);
    }

    #[test]
    fn nested_mirrored_array_insert() {
        let mut blocks = HashMap::new();
        blocks.insert(
            "B".to_string(),
            BlockDef {
                base: P3::new(1.0, 0.0, 0.0),
                entities: vec![ent(EntityShape::Line {
                    a: P3::new(1.0, 0.0, 0.0),
                    b: P3::new(2.0, 0.0, 0.0),
                })],
            },
        );
        let ins = ent(EntityShape::Insert(Box::new(Insert {
            block: "B".into(),
            p: P3::new(10.0, 0.0, 0.0),
            scale: V3::new(-2.0, 1.0, 1.0),
            rotation_deg: 90.0,
            cols: 2,
            rows: 1,
            col_spacing: 5.0,
            row_spacing: 0.0,
            ext: V3::z(),
        })));
        let s = expand(&ins, &blocks);
        assert_eq!(s.segments.len(), 2);
        // Base (1,0) -> origin; (2,0) -> (1,0) -> scaled (-2,0) -> rotated (0,-2) -> (10,-2).
        let (Segment::Line(crate::geometry::Line3 { start, end }), _) = s.segments[0] else {
            panic!()
        };
        assert!((start - P3::new(10.0, 0.0, 0.0)).norm() < 1e-12);
        assert!((end - P3::new(10.0, -2.0, 0.0)).norm() < 1e-12);
        // Second column 5 along the rotated X axis: +5 in Y.
        let (Segment::Line(crate::geometry::Line3 { start, .. }), _) = s.segments[1] else {
            panic!()
        };
        assert!((start - P3::new(10.0, 5.0, 0.0)).norm() < 1e-12);
    }

    #[test]
    fn self_inserting_block_is_stopped() {
        let mut blocks = HashMap::new();
        let me = ent(EntityShape::Insert(Box::new(Insert {
            block: "A".into(),
            p: P3::origin(),
            scale: V3::new(1.0, 1.0, 1.0),
            rotation_deg: 0.0,
            cols: 1,
            rows: 1,
            col_spacing: 0.0,
            row_spacing: 0.0,
            ext: V3::z(),
        })));
        blocks.insert(
            "A".to_string(),
            BlockDef {
                base: P3::origin(),
                entities: vec![me.clone()],
            },
        );
        let s = expand(&me, &blocks);
        assert!(s.segments.is_empty());
        assert_eq!(s.warnings.len(), 1);
    }
}
