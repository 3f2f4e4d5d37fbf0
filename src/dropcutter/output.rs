//! Drop-cutter results as CL data or as toolpath records (feed moves along
//! each pass, rapids at the safe Z between passes), which the G-code
//! writers turn into programs.

use super::fiveaxis::Location;
use crate::formats::cldata::ClWriter;
use crate::geometry::P3;
use crate::model::chain::Segment;
use crate::model::toolpath::{Motion, MotionKind, Record, Role};
use std::io::Write;

/// Feeds of the generated moves (mm/s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Feeds {
    /// Feed along the passes, mm/s.
    pub cut: f64,
    /// Feed of the move down from the safe Z to a pass's first point, mm/s.
    pub plunge: f64,
}

fn mv(kind: MotionKind, to: P3, feed: Option<f64>, role: Role) -> Record {
    Record::Move(Motion {
        kind,
        to,
        feed,
        beam: false,
        beam_switch: None,
        role: Some(role),
        chain: None,
        block: None,
        tool: Default::default(),
    })
}

/// Moves for the passes: for each pass a rapid at `safe_z` above its first
/// point, a plunge at the plunge feed, feed moves through its points, and a
/// rapid retract to `safe_z`.
pub fn toolpath_records(passes: &[Vec<P3>], safe_z: f64, feeds: Feeds) -> Vec<Record> {
    let mut recs = Vec::with_capacity(passes.iter().map(|p| p.len() + 3).sum());
    for pass in passes {
        let (Some(first), Some(last)) = (pass.first(), pass.last()) else {
            continue;
        };
        recs.push(mv(
            MotionKind::Rapid,
            P3::new(first.x, first.y, safe_z),
            None,
            Role::Link,
        ));
        recs.push(mv(MotionKind::Line, *first, Some(feeds.plunge), Role::Plunge));
        for p in &pass[1..] {
            recs.push(mv(MotionKind::Line, *p, Some(feeds.cut), Role::Cut));
        }
        recs.push(mv(
            MotionKind::Rapid,
            P3::new(last.x, last.y, safe_z),
            None,
            Role::Retract,
        ));
    }
    recs
}

/// [`toolpath_records`] of passes made of lines and arcs (waterline loops
/// with arcs fitted): the same rapids, plunge and retract, and one feed
/// move per piece, a G2/G3 for each arc.
pub fn toolpath_records_of_segments(passes: &[Vec<Segment>], safe_z: f64, feeds: Feeds) -> Vec<Record> {
    let mut recs = Vec::with_capacity(passes.iter().map(|p| p.len() + 3).sum());
    for pass in passes {
        let (Some(first), Some(last)) = (pass.first(), pass.last()) else {
            continue;
        };
        let (a, b) = (first.start(), last.end());
        recs.push(mv(MotionKind::Rapid, P3::new(a.x, a.y, safe_z), None, Role::Link));
        recs.push(mv(MotionKind::Line, a, Some(feeds.plunge), Role::Plunge));
        for s in pass {
            recs.push(mv(MotionKind::of_segment(s), s.end(), Some(feeds.cut), Role::Cut));
        }
        recs.push(mv(MotionKind::Rapid, P3::new(b.x, b.y, safe_z), None, Role::Retract));
    }
    recs
}

/// 3-axis CL data: each pass's points, joined by locations at the safe Z
/// above the end of one pass and the start of the next (so a verifier that
/// sweeps the tool from location to location lifts it between passes).
pub fn write_cldata<W: Write>(w: &mut ClWriter<W>, passes: &[Vec<P3>], safe_z: f64) -> std::io::Result<()> {
    let mut first = true;
    for pass in passes {
        let (Some(a), Some(b)) = (pass.first(), pass.last()) else {
            continue;
        };
        if !first {
            w.point(&P3::new(a.x, a.y, safe_z))?;
        }
        for p in pass {
            w.point(p)?;
        }
        if passes.len() > 1 {
            w.point(&P3::new(b.x, b.y, safe_z))?;
        }
        first = false;
    }
    Ok(())
}

/// 5-axis CL data: tip and axis point per location; between runs the tool
/// is drawn back along its axis to the safe Z and put down the same way.
pub fn write_cldata5<W: Write>(w: &mut ClWriter<W>, runs: &[Vec<Location>], safe_z: f64) -> std::io::Result<()> {
    let lifted = |l: &Location| {
        let a = l.axis_point - l.cl;
        // Along the axis until the tip reaches safe_z (straight up for a
        // level axis, which cannot happen for an upward normal).
        let t = if a.z > 1e-12 {
            ((safe_z - l.cl.z) / a.z).max(0.0)
        } else {
            0.0
        };
        Location {
            cl: l.cl + a * t,
            axis_point: l.axis_point + a * t,
        }
    };
    for (i, run) in runs.iter().enumerate() {
        let (Some(a), Some(b)) = (run.first(), run.last()) else {
            continue;
        };
        if i > 0 {
            let l = lifted(a);
            w.point5(&l.cl, &l.axis_point)?;
        }
        for l in run {
            w.point5(&l.cl, &l.axis_point)?;
        }
        if runs.len() > 1 {
            let l = lifted(b);
            w.point5(&l.cl, &l.axis_point)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passes_are_joined_at_the_safe_z() {
        let passes = vec![
            vec![P3::new(0.0, 0.0, 1.0), P3::new(1.0, 0.0, 1.5)],
            vec![P3::new(0.0, 1.0, 0.5)],
        ];
        let recs = toolpath_records(&passes, 5.0, Feeds { cut: 2.0, plunge: 1.0 });
        let to: Vec<P3> = recs.iter().map(|r| r.motion().unwrap().to).collect();
        assert_eq!(
            to,
            vec![
                P3::new(0.0, 0.0, 5.0),
                P3::new(0.0, 0.0, 1.0),
                P3::new(1.0, 0.0, 1.5),
                P3::new(1.0, 0.0, 5.0),
                P3::new(0.0, 1.0, 5.0),
                P3::new(0.0, 1.0, 0.5),
                P3::new(0.0, 1.0, 5.0),
            ]
        );
        let mut w = ClWriter::new(Vec::new());
        write_cldata(&mut w, &passes, 5.0).unwrap();
        let t = String::from_utf8(w.finish().unwrap()).unwrap();
        assert_eq!(t, "0 0 1\n1 0 1.5\n1 0 5\n0 1 5\n0 1 0.5\n0 1 5\n");
    }

    #[test]
    fn fitted_passes_move_piece_by_piece_with_arcs_as_arcs() {
        use crate::geometry::{Arc3, Plane};
        let z = 1.0;
        let line = Segment::line(P3::new(0.0, 0.0, z), P3::new(1.0, 0.0, z));
        let arc = Arc3::new(
            P3::new(1.0, 1.0, z),
            P3::new(1.0, 0.0, z),
            P3::new(2.0, 1.0, z),
            true,
            Plane::Xy,
            0,
        )
        .unwrap();
        let recs = toolpath_records_of_segments(
            &[vec![line, Segment::Arc(arc)], Vec::new()],
            5.0,
            Feeds { cut: 2.0, plunge: 1.0 },
        );
        let moves: Vec<&Motion> = recs.iter().filter_map(|r| r.motion()).collect();
        assert_eq!(
            moves.len(),
            5,
            "rapid, plunge, line, arc, retract; nothing for an empty pass"
        );
        let to: Vec<P3> = moves.iter().map(|m| m.to).collect();
        assert_eq!(
            to,
            vec![
                P3::new(0.0, 0.0, 5.0),
                P3::new(0.0, 0.0, z),
                P3::new(1.0, 0.0, z),
                P3::new(2.0, 1.0, z),
                P3::new(2.0, 1.0, 5.0)
            ]
        );
        assert_eq!(moves[2].kind, MotionKind::Line);
        assert_eq!(moves[3].arc(moves[2].to), Some(arc));
        assert_eq!((moves[1].feed, moves[3].feed), (Some(1.0), Some(2.0)));
        assert_eq!(moves[3].role, Some(Role::Cut));
    }
}
