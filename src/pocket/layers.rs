//! Layered rough and finish cuts (the Iowa State grid-pocket thesis (1999)
//! §4.4): the same passes at every layer, each height clamped to
//! max(touching height, layer floor), roughing layers at the roughing
//! feed, the last layer at the finishing feed with its main path in the
//! chosen motion.
//!
//! Clamping keeps gouge safety: a chord between two clamped points lies
//! above the clamp of the chord, which lies above the clamped touching
//! height where the unclamped chord did.
//!
//! Links: the tool leaves a pass by a rapid straight up to the clearance
//! height, moves at clearance, and goes down at the plunge feed. Nothing
//! rapids downward below the clearance, so no rapid meets material (the
//! thesis' listing plunges with G0; this does not). When the next pass
//! starts where the tool is, there is no link; with `feed_links`, a pass
//! whose start the tool can reach by a straight move inside the
//! tool-centre region is reached by a feed move following the surface.

use super::contact::Contact;
use super::grid::Region;
use super::motion::{FitOptions, MotionMode, fit_run};
use super::passes::{Pass, PassKind, lift};
use crate::geometry::Segment;
use crate::geometry::{Line3, P2, P3};
use crate::model::toolpath::{ArcData, Motion, MotionKind, Record, Role};

/// Feeds (mm/s) and heights (mm) of the job.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Feeds {
    /// Feed of the roughing layers, mm/s.
    pub rough: f64,
    /// Feed of the final (finishing) layer, mm/s.
    pub finish: f64,
    /// Feed of the move down from clearance to a pass's start, mm/s.
    pub plunge: f64,
    /// Clearance height for links, mm; above the pocket's top.
    pub safe_z: f64,
}

/// The pocket's toolpath, with the pass kind of each record.
#[derive(Debug, Clone, Default)]
pub struct Program {
    /// The moves, in order (all `Record::Move`).
    pub records: Vec<Record>,
    /// The pass each record belongs to, index for index with `records`;
    /// `None` for links at clearance (retract, travel, plunge).
    pub kinds: Vec<Option<PassKind>>,
    /// Blocks of the final layer's main path.
    pub final_main_blocks: usize,
    pos: Option<P3>,
}

impl Program {
    fn push(&mut self, kind: MotionKind, to: P3, feed: Option<f64>, role: Role, pk: Option<PassKind>) {
        self.records.push(Record::Move(Motion {
            kind,
            to,
            feed,
            beam: true,
            beam_switch: None,
            role: Some(role),
            chain: None,
            block: None,
            tool: Default::default(),
        }));
        self.kinds.push(pk);
        self.pos = Some(to);
    }

    /// Where the tool is.
    pub fn pos(&self) -> Option<P3> {
        self.pos
    }

    /// Retract, travel at clearance and plunge to `to`.
    fn link(&mut self, to: P3, f: &Feeds) {
        match self.pos {
            Some(p) if (p - to).norm() <= 1e-9 => return,
            Some(p) => {
                if p.z < f.safe_z {
                    self.push(
                        MotionKind::Rapid,
                        P3::new(p.x, p.y, f.safe_z),
                        None,
                        Role::Retract,
                        None,
                    );
                }
                self.push(MotionKind::Rapid, P3::new(to.x, to.y, f.safe_z), None, Role::Link, None);
            }
            None => self.push(MotionKind::Rapid, P3::new(to.x, to.y, f.safe_z), None, Role::Link, None),
        }
        self.push(MotionKind::Line, to, Some(f.plunge), Role::Plunge, None);
    }

    fn feed_elems(&mut self, elems: &[Segment], feed: f64, pk: PassKind) {
        for e in elems {
            match e {
                Segment::Line(l) => self.push(MotionKind::Line, l.end, Some(feed), Role::Cut, Some(pk)),
                Segment::Arc(a) => self.push(
                    MotionKind::Arc(ArcData {
                        center: a.center,
                        ccw: a.ccw,
                        plane: a.plane,
                        extra_turns: 0,
                    }),
                    a.end,
                    Some(feed),
                    Role::Cut,
                    Some(pk),
                ),
            }
        }
    }

    /// End of the job: back to clearance.
    pub fn finish(&mut self, f: &Feeds) {
        if let Some(p) = self.pos
            && p.z < f.safe_z
        {
            self.push(
                MotionKind::Rapid,
                P3::new(p.x, p.y, f.safe_z),
                None,
                Role::Retract,
                None,
            );
        }
    }
}

/// Clamp a polyline to `floor` and drop points between collinear
/// neighbours (flat stretches at the floor become one move).
pub fn clamp(pts: &[P3], floor: f64) -> Vec<P3> {
    let mut out: Vec<P3> = Vec::with_capacity(pts.len());
    for p in pts {
        let q = P3::new(p.x, p.y, p.z.max(floor));
        if out.len() >= 2 {
            let (a, b) = (out[out.len() - 2], out[out.len() - 1]);
            let (u, v) = (b - a, q - b);
            if u.cross(&v).norm() <= 1e-12 * (1.0 + u.norm() * v.norm()) && u.dot(&v) > 0.0 {
                *out.last_mut().expect("len >= 2") = q;
                continue;
            }
        }
        if out.last().is_none_or(|l: &P3| (l - q).norm() > 1e-12) {
            out.push(q);
        }
    }
    out
}

fn polyline_elems(pts: &[P3]) -> Vec<Segment> {
    pts.windows(2)
        .filter(|w| (w[1] - w[0]).norm() > 1e-12)
        .map(|w| Segment::Line(Line3::new(w[0], w[1])))
        .collect()
}

/// What the layers are made of.
pub struct LayerPlan<'a> {
    /// The cutter on the bottom surface (for fits and gouge checks).
    pub contact: &'a Contact<'a>,
    /// The tool-centre region (for feed links).
    pub region: &'a Region,
    /// Floors of the roughing layers, highest first; the final layer follows.
    pub floors: Vec<f64>,
    /// Feeds and clearance height.
    pub feeds: Feeds,
    /// Passes cut in every layer, in order.
    pub every_layer: Vec<Pass>,
    /// Passes cut only in the final layer, after the others.
    pub final_only: Vec<Pass>,
    /// How the final layer's main passes are written.
    pub motion: MotionMode,
    /// Tolerances of those fits.
    pub fit: FitOptions,
    /// Sampling step (mm) of the gouge checks on curves.
    pub step: f64,
    /// Reach a pass's start by a feed move inside the region when possible.
    pub feed_links: bool,
}

/// The program of `plan`: layer by layer, every pass clamped to the
/// layer's floor, each reached by a link, the job ending at clearance.
pub fn build(plan: &LayerPlan) -> Program {
    let mut prog = Program::default();
    let f = &plan.feeds;
    let n_layers = plan.floors.len() + 1;
    for layer in 0..n_layers {
        let last = layer + 1 == n_layers;
        let floor = plan.floors.get(layer).copied().unwrap_or(f64::NEG_INFINITY);
        let feed = if last { f.finish } else { f.rough };
        let passes = plan
            .every_layer
            .iter()
            .chain(if last { plan.final_only.iter() } else { [].iter() });
        for pass in passes {
            let pts = clamp(&pass.pts, floor);
            let Some(&start) = pts.first() else { continue };
            let elems = if last && pass.kind == PassKind::Main && plan.motion != MotionMode::Lines {
                let e: Vec<Segment> = pass
                    .runs
                    .iter()
                    .flat_map(|r| fit_run(plan.contact, r, plan.motion, &plan.fit, plan.step))
                    .collect();
                prog.final_main_blocks += e.len();
                e
            } else {
                let e = polyline_elems(&pts);
                if last && pass.kind == PassKind::Main {
                    prog.final_main_blocks += e.len();
                }
                e
            };
            link_to(&mut prog, plan, start, floor, feed);
            prog.feed_elems(&elems, feed, pass.kind);
        }
    }
    prog.finish(f);
    prog
}

fn link_to(prog: &mut Program, plan: &LayerPlan, start: P3, floor: f64, feed: f64) {
    if let Some(p) = prog.pos()
        && plan.feed_links
        && (p - start).norm() > 1e-9
        && p.z < plan.feeds.safe_z
        && plan.region.segment_inside(P2::new(p.x, p.y), P2::new(start.x, start.y))
    {
        let pts = clamp(
            &lift(plan.contact, &[P2::new(p.x, p.y), P2::new(start.x, start.y)]),
            floor,
        );
        // The lifted link starts at the surface; the tool may sit higher
        // (clamped), so go from where it is.
        let mut e = polyline_elems(&pts);
        if let Some(Segment::Line(l)) = e.first_mut() {
            l.start = p;
        }
        if let Some(Segment::Line(l)) = e.last_mut() {
            l.end = start;
        }
        if (pts[0] - p).norm() <= 1e-9 {
            prog.feed_elems(&e, feed, PassKind::Link);
            return;
        }
    }
    prog.link(start, &plan.feeds);
}
