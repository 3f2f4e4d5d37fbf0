//! Shortest paths of bounded curvature between two poses (Dubins, 1957):
//! the optimum is one of six words of at most three pieces, turns of the
//! minimum radius (L left, R right) and a straight (S). A corner loop at
//! constant speed V under acceleration a is exactly this problem with radius
//! V²/a, from the corner with the incoming heading back to the corner with
//! the outgoing heading.

use super::elem::MIN_PIECE;
use crate::geometry::Segment;
use crate::geometry::arc::Arc3;
use crate::geometry::{P2, P3, Plane, V2};
use std::f64::consts::TAU;

/// The six candidate shapes of a Dubins path: L a left turn, R a right
/// turn (both of the minimum radius), S a straight.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Word {
    /// Left, straight, left.
    Lsl,
    /// Right, straight, right.
    Rsr,
    /// Left, straight, right.
    Lsr,
    /// Right, straight, left.
    Rsl,
    /// Right, left, right (three turns, for close poses).
    Rlr,
    /// Left, right, left (three turns, for close poses).
    Lrl,
}

impl Word {
    /// Every word, in the order they are tried (ties go to the first).
    pub const ALL: [Word; 6] = [Word::Lsl, Word::Rsr, Word::Lsr, Word::Rsl, Word::Rlr, Word::Lrl];

    /// The three piece types: 'L', 'S' or 'R'.
    pub fn letters(self) -> [u8; 3] {
        match self {
            Word::Lsl => *b"LSL",
            Word::Rsr => *b"RSR",
            Word::Lsr => *b"LSR",
            Word::Rsl => *b"RSL",
            Word::Rlr => *b"RLR",
            Word::Lrl => *b"LRL",
        }
    }
}

/// A Dubins path: the word and its three piece lengths in units of the
/// radius (angles in radians for turns).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dubins {
    /// Which shape.
    pub word: Word,
    /// The three pieces' lengths divided by the radius (a turn's is its
    /// angle in radians).
    pub params: [f64; 3],
    /// The turning radius (mm).
    pub radius: f64,
}

impl Dubins {
    /// Total length of the path (mm).
    pub fn length(&self) -> f64 {
        self.radius * (self.params[0] + self.params[1] + self.params[2])
    }
}

fn m2pi(a: f64) -> f64 {
    // Already in range: `rem_euclid` would return it unchanged, after a
    // software `fmod` (a tenth of a corner loop's search).
    if (0.0..TAU).contains(&a) { a } else { a.rem_euclid(TAU) }
}

/// The start and goal headings `a`, `b` in the goal frame with the sines
/// and cosines every word's closed form uses: worked out once per path,
/// not once per word (a corner loop's search asks for thousands of paths).
#[derive(Debug, Clone, Copy)]
struct Headings {
    a: f64,
    b: f64,
    sa: f64,
    ca: f64,
    sb: f64,
    cb: f64,
    /// cos(a - b).
    cab: f64,
}

impl Headings {
    fn new(a: f64, b: f64) -> Headings {
        Headings {
            a,
            b,
            sa: a.sin(),
            ca: a.cos(),
            sb: b.sin(),
            cb: b.cos(),
            cab: (a - b).cos(),
        }
    }
}

/// Piece lengths (normalised) of one word, `None` when the word has no
/// solution. Standard closed forms in the frame where the goal lies on +x
/// at distance `d` (in radii), `a`/`b` the start/goal headings in that frame.
/// Also `None` when the word's middle piece alone, times `r`, is at least
/// `limit`: its length `r (t + p + q)` cannot be below that (the pieces are
/// not negative, and rounding keeps the order), so the caller, which keeps
/// only paths shorter than `limit`, loses nothing and skips the angles.
fn word_params(w: Word, d: f64, h: &Headings, r: f64, limit: f64) -> Option<[f64; 3]> {
    let Headings {
        a,
        b,
        sa,
        ca,
        sb,
        cb,
        cab,
    } = *h;
    match w {
        Word::Lsl => {
            let p2 = 2.0 + d * d - 2.0 * cab + 2.0 * d * (sa - sb);
            if p2 < 0.0 {
                return None;
            }
            let p = p2.sqrt();
            if r * p >= limit {
                return None;
            }
            let t1 = (cb - ca).atan2(d + sa - sb);
            Some([m2pi(-a + t1), p, m2pi(b - t1)])
        }
        Word::Rsr => {
            let p2 = 2.0 + d * d - 2.0 * cab + 2.0 * d * (sb - sa);
            if p2 < 0.0 {
                return None;
            }
            let p = p2.sqrt();
            if r * p >= limit {
                return None;
            }
            let t1 = (ca - cb).atan2(d - sa + sb);
            Some([m2pi(a - t1), p, m2pi(-b + t1)])
        }
        Word::Lsr => {
            let p2 = -2.0 + d * d + 2.0 * cab + 2.0 * d * (sa + sb);
            if p2 < 0.0 {
                return None;
            }
            let p = p2.sqrt();
            if r * p >= limit {
                return None;
            }
            let t2 = (-ca - cb).atan2(d + sa + sb) - (-2.0f64).atan2(p);
            Some([m2pi(-a + t2), p, m2pi(-m2pi(b) + t2)])
        }
        Word::Rsl => {
            let p2 = -2.0 + d * d + 2.0 * cab - 2.0 * d * (sa + sb);
            if p2 < 0.0 {
                return None;
            }
            let p = p2.sqrt();
            if r * p >= limit {
                return None;
            }
            let t2 = (ca + cb).atan2(d - sa - sb) - 2.0f64.atan2(p);
            Some([m2pi(a - t2), p, m2pi(b - t2)])
        }
        Word::Rlr => {
            let tmp = (6.0 - d * d + 2.0 * cab + 2.0 * d * (sa - sb)) / 8.0;
            if tmp.abs() > 1.0 {
                return None;
            }
            let p = m2pi(TAU - tmp.acos());
            if r * p >= limit {
                return None;
            }
            let t = m2pi(a - (ca - cb).atan2(d - sa + sb) + p / 2.0);
            Some([t, p, m2pi(a - b - t + p)])
        }
        Word::Lrl => {
            let tmp = (6.0 - d * d + 2.0 * cab + 2.0 * d * (sb - sa)) / 8.0;
            if tmp.abs() > 1.0 {
                return None;
            }
            let p = m2pi(TAU - tmp.acos());
            if r * p >= limit {
                return None;
            }
            let t = m2pi(-a - (ca - cb).atan2(d + sa - sb) + p / 2.0);
            Some([t, p, m2pi(m2pi(b) - a - t + p)])
        }
    }
}

/// The shortest path of radius `r` from `p0` heading `h0` to `p1` heading
/// `h1` (headings in radians). Ties go to the earlier word, so the answer is
/// deterministic.
pub fn shortest(p0: P2, h0: f64, p1: P2, h1: f64, r: f64) -> Option<Dubins> {
    shortest_where(p0, h0, p1, h1, r, |_| true)
}

/// The shortest path among those `accept` lets through.
pub fn shortest_where(p0: P2, h0: f64, p1: P2, h1: f64, r: f64, accept: impl Fn(&Dubins) -> bool) -> Option<Dubins> {
    if !(r.is_finite() && r > 0.0) {
        return None;
    }
    let v = (p1 - p0) / r;
    let d = v.norm();
    let theta = if d > 1e-12 { m2pi(v.y.atan2(v.x)) } else { 0.0 };
    let a = m2pi(h0 - theta);
    let b = m2pi(h1 - theta);
    let h = Headings::new(a, b);
    let mut best: Option<Dubins> = None;
    for w in Word::ALL {
        // Only a path shorter than the best by 1e-12 replaces it.
        let limit = best.map_or(f64::INFINITY, |b| b.length() - 1e-12);
        if let Some(params) = word_params(w, d, &h, r, limit) {
            let cand = Dubins {
                word: w,
                params,
                radius: r,
            };
            if accept(&cand) && best.is_none_or(|b| cand.length() < b.length() - 1e-12) {
                best = Some(cand);
            }
        }
    }
    best
}

/// Walk a Dubins path from `p0`/`h0` and return its pieces in `plane` at the
/// normal coordinate `nz`. The last point is snapped to `goal`, so chained
/// pieces meet exactly.
pub fn to_elems(dp: &Dubins, p0: P2, h0: f64, goal: P2, plane: Plane, nz: f64) -> Vec<Segment> {
    let r = dp.radius;
    let mut pos = p0;
    let mut h = h0;
    let mut out = Vec::with_capacity(3);
    let lift = |q: &P2| plane.lift(q, nz);
    for (i, &c) in dp.word.letters().iter().enumerate() {
        let amount = dp.params[i];
        let len = amount * r;
        let (next, nh) = match c {
            b'S' => (pos + V2::new(h.cos(), h.sin()) * len, h),
            b'L' => {
                let ctr = pos + V2::new(-h.sin(), h.cos()) * r;
                let nh = h + amount;
                (ctr + V2::new(nh.sin(), -nh.cos()) * r, nh)
            }
            _ => {
                let ctr = pos + V2::new(h.sin(), -h.cos()) * r;
                let nh = h - amount;
                (ctr + V2::new(-nh.sin(), nh.cos()) * r, nh)
            }
        };
        let next = if i == 2 { goal } else { next };
        if len > MIN_PIECE {
            let (a, b) = (lift(&pos), lift(&next));
            match c {
                b'S' => out.push(Segment::line(a, b)),
                b'L' | b'R' => {
                    let left = c == b'L';
                    let ctr = if left {
                        pos + V2::new(-h.sin(), h.cos()) * r
                    } else {
                        pos + V2::new(h.sin(), -h.cos()) * r
                    };
                    // A turn of (nearly) a full circle has start == end; Arc3
                    // reads that as the full turn, which is what it is.
                    if let Some(arc) = Arc3::new(lift(&ctr), a, b, left, plane, 0) {
                        out.push(Segment::Arc(arc));
                    }
                }
                _ => unreachable!("Dubins words hold only L, S and R"),
            }
        }
        pos = next;
        h = nh;
    }
    out
}

/// A beam-off corner loop of radius `r` at `corner`: leaves along the
/// incoming direction `din`, returns through the corner along `dout`, and is
/// at least `min_len` long (so the shutter has time to close and reopen),
/// with no piece shorter than `min_piece` and a last piece of at least
/// `tail` (see [`connect`]).
pub fn corner_loop(
    corner: P3,
    din: V2,
    dout: V2,
    r: f64,
    shape: ConnectionLimits,
    plane: Plane,
) -> Option<Vec<Segment>> {
    connect(corner, din, corner, dout, r, shape, plane)
}

/// What a connection must be besides shortest.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConnectionLimits {
    /// Least total length.
    pub min_len: f64,
    /// Least length of any piece.
    pub min_piece: f64,
    /// Least length of its last piece (room for a shutter switch).
    pub tail: f64,
}

/// Most candidate paths tried while looking for one without a sliver.
const SLIVER_TRIES: usize = 64;

/// The shortest path of radius `r` in `plane` from `from` heading `din` to
/// `to` heading `dout`, at least `min_len` long. When the shortest is
/// shorter, both ends are extended straight along their headings by the
/// least amount that makes it long enough: curvature stays at the limit
/// and only straight travel is added. `to` must share `from`'s normal
/// coordinate.
///
/// No piece is shorter than `shape.min_piece` (a sliver would be a block
/// shorter than the controller's least acceleration time, which it would
/// run slower than V): among paths of a sliver-free word, the shortest is
/// taken, and if none exists the straight extensions grow in steps of
/// `min_piece` until one does. The last piece is at least `shape.tail`
/// long (room for the shutter's open command): the path's own last turn
/// when it is long enough, else an end straight of that length.
pub fn connect(
    from: P3,
    din: V2,
    to: P3,
    dout: V2,
    r: f64,
    shape: ConnectionLimits,
    plane: Plane,
) -> Option<Vec<Segment>> {
    let ConnectionLimits {
        min_len,
        min_piece,
        tail,
    } = shape;
    let a2 = plane.project(&from);
    let b2 = plane.project(&to);
    let nz = plane.normal_coord(&from);
    let (h0, h1) = (din.y.atan2(din.x), dout.y.atan2(dout.x));
    let (u0, u1) = (V2::new(h0.cos(), h0.sin()), V2::new(h1.cos(), h1.sin()));
    let clean = |dp: &Dubins| dp.params.iter().all(|&p| p * r <= MIN_PIECE || p * r >= min_piece);
    // The last piece: the end straight if there is one, else the Dubins
    // path's last turn or straight.
    let last_piece = |end: f64, dp: &Dubins| {
        if end > MIN_PIECE {
            end
        } else {
            dp.params
                .iter()
                .rev()
                .map(|p| p * r)
                .find(|&l| l > MIN_PIECE)
                .unwrap_or(0.0)
        }
    };
    // Two shapes: symmetric straight extensions e (the last piece may be
    // long enough by itself), or an end straight of at least `tail`.
    // (total, e, path, whether it is the unconstrained optimum)
    let search = |forced: bool| -> Option<(f64, f64, Dubins, bool)> {
        let end_ext = |e: f64| if forced { e.max(tail) } else { e };
        let total = |e: f64| -> Option<f64> {
            let dp = shortest(a2 + u0 * e, h0, b2 - u1 * end_ext(e), h1, r)?;
            Some(e + end_ext(e) + dp.length())
        };
        let mut e = 0.0;
        if total(0.0)? < min_len {
            // 2e alone reaches min_len at e = min_len/2; bisect for the least e.
            let (mut lo, mut hi) = (0.0, 0.5 * min_len);
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if total(mid)? >= min_len { hi = mid } else { lo = mid }
            }
            e = hi;
        }
        if e > MIN_PIECE && e < min_piece {
            e = min_piece;
        }
        // Scan longer extensions for the shortest acceptable total, stopping
        // once the straights alone are longer than the best found.
        let mut best: Option<(f64, f64, Dubins)> = None;
        for k in 0..=SLIVER_TRIES {
            let ek = if k == 0 {
                e
            } else {
                e.max(min_piece) + (k - 1) as f64 * min_piece
            };
            let straights = ek + end_ext(ek);
            if best.as_ref().is_some_and(|b| straights >= b.0) {
                break;
            }
            let (s, g) = (a2 + u0 * ek, b2 - u1 * end_ext(ek));
            let ok = |dp: &Dubins| clean(dp) && last_piece(end_ext(ek), dp) >= tail - 1e-12;
            if k == 0
                && let Some(plain) = shortest(s, h0, g, h1, r)
                && ok(&plain)
            {
                // The usual case: the shortest path is acceptable as it is.
                return Some((straights + plain.length(), ek, plain, true));
            }
            if let Some(cand) = shortest_where(s, h0, g, h1, r, ok) {
                let len = straights + cand.length();
                if best.as_ref().is_none_or(|b| len < b.0 - 1e-12) {
                    best = Some((len, ek, cand));
                }
            }
        }
        // The grid step is coarse: refine around the best grid point.
        if let Some((_, eb, _)) = best
            && eb > 0.0
        {
            for j in 1..32 {
                let ek = (eb - min_piece + 2.0 * min_piece * j as f64 / 32.0).max(e);
                if ek > MIN_PIECE && ek < min_piece {
                    continue;
                }
                let (s, g) = (a2 + u0 * ek, b2 - u1 * end_ext(ek));
                let ok = |dp: &Dubins| clean(dp) && last_piece(end_ext(ek), dp) >= tail - 1e-12;
                if let Some(cand) = shortest_where(s, h0, g, h1, r, ok) {
                    let len = ek + end_ext(ek) + cand.length();
                    if best.as_ref().is_none_or(|b| len < b.0 - 1e-12) {
                        best = Some((len, ek, cand));
                    }
                }
            }
        }
        best.map(|(l, e, d)| (l, e, d, false))
    };
    let free = search(false);
    let found = match free {
        // Nothing constrained it: no other shape can be shorter.
        Some(a) if a.3 => Some((a, false)),
        _ => match (free, if tail > 0.0 { search(true) } else { None }) {
            (Some(a), Some(b)) => Some(if b.0 < a.0 - 1e-12 { (b, true) } else { (a, false) }),
            (Some(a), None) => Some((a, false)),
            (None, Some(b)) => Some((b, true)),
            (None, None) => None,
        },
    };
    // Nothing acceptable within the tries: the plain shortest path.
    let ((_, e, dp, _), forced) = match found {
        Some(f) => f,
        None => ((0.0, 0.0, shortest(a2, h0, b2, h1, r)?, false), false),
    };
    let end_ext = |e: f64| if forced { e.max(tail) } else { e };
    let (ext0, ext1) = (e > MIN_PIECE, end_ext(e) > MIN_PIECE);
    let s2 = if ext0 { a2 + u0 * e } else { a2 };
    let g2 = if ext1 { b2 - u1 * end_ext(e) } else { b2 };
    let mut out = Vec::with_capacity(5);
    if ext0 {
        out.push(Segment::line(from, plane.lift(&s2, nz)));
    }
    let mut mid = to_elems(&dp, s2, h0, g2, plane, nz);
    // Snap unextended ends exactly onto the given points.
    if !ext0 && let Some(first) = mid.first_mut() {
        first.set_start(from);
    }
    if !ext1 && let Some(last) = mid.last_mut() {
        last.set_end(to);
    }
    out.append(&mut mid);
    if ext1 {
        out.push(Segment::line(plane.lift(&g2, nz), to));
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn end_pose(dp: &Dubins, p0: P2, h0: f64) -> (P2, f64) {
        // Integrate analytically instead of trusting to_elems' snapping.
        let mut pos = p0;
        let mut h = h0;
        let r = dp.radius;
        for (i, &c) in dp.word.letters().iter().enumerate() {
            let a = dp.params[i];
            match c {
                b'S' => pos += V2::new(h.cos(), h.sin()) * a * r,
                b'L' => {
                    let ctr = pos + V2::new(-h.sin(), h.cos()) * r;
                    h += a;
                    pos = ctr + V2::new(h.sin(), -h.cos()) * r;
                }
                _ => {
                    let ctr = pos + V2::new(h.sin(), -h.cos()) * r;
                    h -= a;
                    pos = ctr + V2::new(-h.sin(), h.cos()) * r;
                }
            }
        }
        (pos, h)
    }

    proptest! {
        #[test]
        fn reaches_the_goal_pose(x in -3.0..3.0f64, y in -3.0..3.0f64, h0 in 0.0..TAU, h1 in 0.0..TAU, r in 0.1..2.0f64) {
            let p0 = P2::new(0.5, -0.2);
            let p1 = P2::new(x, y);
            let dp = shortest(p0, h0, p1, h1, r).expect("a Dubins path always exists");
            let (pe, he) = end_pose(&dp, p0, h0);
            prop_assert!((pe - p1).norm() < 1e-8 * (1.0 + r), "{dp:?} ends at {pe:?}");
            prop_assert!(m2pi(he - h1).min(TAU - m2pi(he - h1)) < 1e-8);
            // No word is shorter than the straight-line distance.
            prop_assert!(dp.length() >= (p1 - p0).norm() - 1e-9);
        }

        #[test]
        fn corner_loops_close_with_bounded_curvature(turn in 0.02..3.1f64, left in any::<bool>(), min_len in 0.0..5.0f64) {
            let corner = P3::new(1.0, 2.0, 0.5);
            let hin = 0.3f64;
            let hout = if left { hin + turn } else { hin - turn };
            let r = 0.2;
            let shape = ConnectionLimits { min_len, min_piece: 0.002, tail: if left { 0.03 } else { 0.0 } };
            let els = corner_loop(corner, V2::new(hin.cos(), hin.sin()), V2::new(hout.cos(), hout.sin()), r, shape, Plane::Xy).unwrap();
            prop_assert_eq!(els.first().unwrap().start(), corner);
            prop_assert!((els.last().unwrap().end() - corner).norm() < 1e-9);
            let d0 = els[0].start_tangent();
            prop_assert!((d0.x - hin.cos()).abs() < 1e-9 && (d0.y - hin.sin()).abs() < 1e-9);
            let d1 = els.last().unwrap().end_tangent();
            prop_assert!((d1.x - hout.cos()).abs() < 1e-6 && (d1.y - hout.sin()).abs() < 1e-6, "{d1:?} vs {hout}");
            for w in els.windows(2) {
                prop_assert!((w[0].end() - w[1].start()).norm() < 1e-9);
                prop_assert!(w[0].end_tangent().dot(&w[1].start_tangent()) > 1.0 - 1e-9, "loop not tangent-continuous");
            }
            for e in &els {
                prop_assert!(e.curvature_radius() >= r - 1e-9);
            }
            let len: f64 = els.iter().map(Segment::length).sum();
            prop_assert!(len >= min_len - 1e-9);
            for e in &els {
                prop_assert!(e.length() >= 0.002 - 1e-9, "a sliver of {} mm", e.length());
            }
            if shape.tail > 0.0 {
                let last = els.last().unwrap();
                prop_assert!(last.length() >= shape.tail - 1e-9, "last piece {} < tail", last.length());
            }
        }
    }

    #[test]
    fn a_reversal_is_the_teardrop() {
        // Heading +x in, -x out through the same point: the teardrop RLR
        // of 60° + 300° + 60°, 7π/3 radii long.
        let dp = shortest(P2::origin(), 0.0, P2::origin(), std::f64::consts::PI, 1.0).unwrap();
        assert_eq!(dp.word, Word::Rlr);
        assert!((dp.length() - 7.0 * std::f64::consts::PI / 3.0).abs() < 1e-9);
    }
}
