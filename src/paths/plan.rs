//! One cut path -> constant-velocity moves: lead-in, cut pieces with a
//! beam-off loop at every non-tangent corner, lead-out, and the shutter
//! commands moved earlier by its latencies so the shutter is fully open
//! exactly over the cut.

use super::dubins::corner_loop;
use super::elem::{Elem, MIN_PIECE};
use super::machine::Machine;
use crate::geometry::{P3, Plane, V2};
use crate::model::toolpath::{Motion, MotionKind, Record, Role};

/// A path whose pieces carry their role (cut, or a beam-off connection).
pub type Tagged = Vec<(Elem, Role)>;

/// One planned piece: geometry, why it is there, and the commanded beam.
#[derive(Debug, Clone, PartialEq)]
pub struct Piece {
    pub elem: Elem,
    pub role: Role,
    pub beam: bool,
}

/// Something the user should know about a planned path.
#[derive(Debug, Clone, PartialEq)]
pub enum Note {
    /// A cut shorter than the shutter's minimum exposure at V (mm).
    ShortCut { length: f64, min: f64 },
    /// A drawing arc tighter than V²/a: the stage cannot follow it at V
    /// within its acceleration (radius mm, demanded acceleration mm/s²).
    TightArc { radius: f64, demand: f64, count: usize },
    /// A corner between pieces whose turn could not be looped (the
    /// direction has no component in the loop plane).
    UnloopedCorner { at: P3 },
}

impl std::fmt::Display for Note {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Note::ShortCut { length, min } => write!(
                f,
                "cut of {length:.6} mm is shorter than the minimum exposure ({min:.6} mm at this feed)"
            ),
            Note::TightArc { radius, demand, count } => write!(
                f,
                "{count} arc(s) tighter than V²/a; the tightest, radius {radius:.6} mm, asks {demand:.3} mm/s² at this feed"
            ),
            Note::UnloopedCorner { at } => write!(f, "corner at ({}, {}, {}) could not be looped", at.x, at.y, at.z),
        }
    }
}

/// Plan one cut path. `path` is continuous; `closed` paths end where they
/// start (the seam gets a lead-out and the next pass its own lead-in).
pub fn plan_path(path: &[Elem], m: &Machine, notes: &mut Vec<Note>) -> Vec<Piece> {
    let tagged: Vec<(Elem, Role)> = path.iter().map(|e| (*e, Role::Cut)).collect();
    plan_tagged(&tagged, m, notes)
}

/// Plan a path whose pieces are cuts or beam-off connections the caller
/// already shaped (zigzag turnarounds: role `Loop` or `Link`, tangent to
/// their neighbours). Loops are added only between two cut pieces.
pub fn plan_tagged(path: &[(Elem, Role)], m: &Machine, notes: &mut Vec<Note>) -> Vec<Piece> {
    let path: Vec<(Elem, Role)> = path.iter().copied().filter(|e| e.0.length() > MIN_PIECE).collect();
    let (Some((first, _)), Some((last, _))) = (path.first(), path.last()) else {
        return Vec::new();
    };
    let r = m.min_radius();
    let cos_tol = m.tangent_cos();
    let mut out = Vec::with_capacity(path.len() + 2);
    // Count of drawing arcs tighter than V²/a and the tightest radius:
    // one note per path, not one per arc.
    let mut tight = (0usize, f64::INFINITY);
    let s0 = first.start();
    out.push(Piece {
        elem: Elem::line(s0 - first.dir_start() * m.lead_in(), s0),
        role: Role::LeadIn,
        beam: false,
    });
    for (i, (e, role)) in path.iter().enumerate() {
        if *role != Role::Cut {
            out.push(Piece {
                elem: *e,
                role: *role,
                beam: false,
            });
            continue;
        }
        if e.curvature_radius() < r * (1.0 - 1e-9) {
            tight.0 += 1;
            tight.1 = tight.1.min(e.curvature_radius());
        }
        out.push(Piece {
            elem: *e,
            role: Role::Cut,
            beam: true,
        });
        let Some((next, Role::Cut)) = path.get(i + 1) else {
            continue;
        };
        let (din, dout) = (e.dir_end(), next.dir_start());
        if din.dot(&dout) >= cos_tol {
            continue;
        }
        let plane = loop_plane(e, next);
        let (a, b, _) = plane.axes();
        let d2 = |v: crate::geometry::V3| V2::new(v[a], v[b]);
        let corner = e.end();
        let lp = (d2(din).norm() > 1e-9 && d2(dout).norm() > 1e-9)
            .then(|| {
                corner_loop(
                    corner,
                    d2(din).normalize(),
                    d2(dout).normalize(),
                    r,
                    m.shutter_window(),
                    plane,
                )
            })
            .flatten();
        match lp {
            Some(lp) => out.extend(lp.into_iter().map(|elem| Piece {
                elem,
                role: Role::Loop,
                beam: false,
            })),
            None => notes.push(Note::UnloopedCorner { at: corner }),
        }
    }
    if tight.0 > 0 {
        notes.push(Note::TightArc {
            radius: tight.1,
            demand: m.feed * m.feed / tight.1,
            count: tight.0,
        });
    }
    let e = last.end();
    out.push(Piece {
        elem: Elem::line(e, e + last.dir_end() * m.lead_out()),
        role: Role::LeadOut,
        beam: false,
    });
    time_shutter(out, m, notes)
}

/// Loops turn in the plane of the arcs around them, else XY.
fn loop_plane(a: &Elem, b: &Elem) -> Plane {
    match (a, b) {
        (Elem::Arc(x), _) => x.plane,
        (_, Elem::Arc(y)) => y.plane,
        _ => Plane::Xy,
    }
}

/// Commanded-on intervals along the path: each run of cut pieces
/// [s0, s1] becomes [s0 - open lead, s1 - close lead], so that the shutter,
/// commanded at V, is fully open from s0 and starts to close at s1.
fn time_shutter(pieces: Vec<Piece>, m: &Machine, notes: &mut Vec<Note>) -> Vec<Piece> {
    // Arc lengths cost an atan2 each; a million-segment job asks them once.
    let lens: Vec<f64> = pieces.iter().map(|p| p.elem.length()).collect();
    let mut on: Vec<(f64, f64)> = Vec::new();
    let mut s = 0.0;
    let mut run: Option<f64> = None;
    for (p, &len) in pieces.iter().zip(&lens) {
        match (p.role == Role::Cut, run) {
            (true, None) => run = Some(s),
            (false, Some(s0)) => {
                on.push((s0, s));
                run = None;
            }
            _ => {}
        }
        s += len;
    }
    if let Some(s0) = run {
        on.push((s0, s));
    }
    for &(a, b) in &on {
        if b - a < m.min_cut() {
            notes.push(Note::ShortCut {
                length: b - a,
                min: m.min_cut(),
            });
        }
    }
    let cmd: Vec<(f64, f64)> = on
        .iter()
        .map(|&(a, b)| (a - m.open_lead(), (b - m.close_lead()).max(a - m.open_lead())))
        .collect();
    let mut cuts: Vec<f64> = cmd.iter().flat_map(|&(a, b)| [a, b]).collect();
    cuts.sort_by(f64::total_cmp);
    // Intervals come in path order, so the one that may hold x is the last
    // starting before it (overlaps, if a loop were too short, are checked
    // one step back).
    let inside = |x: f64| {
        let k = cmd.partition_point(|&(a, _)| a < x);
        cmd[..k].iter().rev().take(2).any(|&(a, b)| x > a && x < b)
    };
    let mut out = Vec::with_capacity(pieces.len() + 2 * cmd.len());
    let mut s = 0.0;
    let mut k = 0;
    for (p, len) in pieces.into_iter().zip(lens) {
        let end = s + len;
        let mut rest = p.elem;
        let mut rest_s = s;
        while k < cuts.len() && cuts[k] <= s + MIN_PIECE {
            k += 1;
        }
        if k >= cuts.len() || cuts[k] >= end - MIN_PIECE {
            // No switching inside this piece: the common case.
            let beam = inside(s + 0.5 * len);
            out.push(Piece { beam, ..p });
            s = end;
            continue;
        }
        while k < cuts.len() && cuts[k] < end - MIN_PIECE {
            if let Some((a, b)) = rest.split_at_length(cuts[k] - rest_s) {
                let mid = rest_s + 0.5 * a.length();
                out.push(Piece {
                    elem: a,
                    role: p.role,
                    beam: inside(mid),
                });
                rest_s += a.length();
                rest = b;
            }
            k += 1;
        }
        let mid = rest_s + 0.5 * rest.length();
        out.push(Piece {
            elem: rest,
            role: p.role,
            beam: inside(mid),
        });
        s = end;
    }
    out
}

/// Turn planned pieces into toolpath moves at feed V, preceded by a rapid
/// link to the lead-in start.
pub fn to_records(pieces: &[Piece], feed: f64, chain: Option<u64>, out: &mut Vec<Record>) {
    let Some(first) = pieces.first() else { return };
    out.push(Record::Move(Motion {
        kind: MotionKind::Rapid,
        to: first.elem.start(),
        feed: None,
        beam: false,
        beam_switch: None,
        role: Some(Role::Link),
        chain,
        block: None,
    }));
    for p in pieces {
        out.push(Record::Move(Motion {
            kind: p.elem.motion_kind(),
            to: p.elem.end(),
            feed: Some(feed),
            beam: p.beam,
            beam_switch: None,
            role: Some(p.role),
            chain,
            block: None,
        }));
    }
}

/// The program's TA/TS, first in every generated job: the lead-in and
/// lead-out lengths assume these ramps, so the controller must not run
/// with whatever Isx87/Isx88 it happens to hold.
pub fn ramps_record(m: &Machine) -> Record {
    Record::Accel {
        ta_ms: Some(m.program_ta_ms()),
        ts_ms: Some(m.ts_ms),
        block: None,
    }
}

/// Plan several tagged paths in order, each with its own leads and shutter
/// timing, joined by rapids. Pattern generators use this.
pub fn plan_paths(paths: &[Vec<(Elem, Role)>], m: &Machine, chain: Option<u64>) -> (Vec<Record>, Vec<Note>) {
    let mut notes = Vec::new();
    let mut recs = vec![ramps_record(m)];
    for p in paths {
        let pieces = plan_tagged(p, m, &mut notes);
        to_records(&pieces, m.feed, chain, &mut recs);
    }
    (recs, notes)
}

/// Tag every piece of a path as a cut.
pub fn all_cut(path: Vec<Elem>) -> Vec<(Elem, Role)> {
    path.into_iter().map(|e| (e, Role::Cut)).collect()
}
