//! Round trip toolpath -> G-code -> toolpath, both dialects: what the
//! writer prints, the readers must turn back into the same model within the
//! output precision (6 decimals here, so 1e-6 mm).
//!
//! Random toolpaths of rapids, lines, arcs in all three planes (helical,
//! full circles, extra turns), dwells and beam changes are written with
//! `microcam::gcode::writer` and read back with `microcam::gcode::read_str`.
//!
//! (The tests were written before the readers existed; they now run.)

use microcam::gcode::writer::{WriteOptions, write_string};
use microcam::gcode::{Dialect, ReadOptions, read_str};
use microcam::geometry::{P2, P3, Plane};
use microcam::model::toolpath::{ArcData, FeedUnit, Motion, MotionKind, Record};
use proptest::prelude::*;
use std::f64::consts::{PI, TAU};

/// Decimals written; the tolerance below follows from it (half a unit of
/// rounding plus parsing noise).
const DECIMALS: u8 = 6;
const TOL: f64 = 1e-6;
/// PMAC has no turn count: the writer splits an arc with extra turns into
/// full circles and shares the helix's normal travel by sweep angle
/// computed from the *rounded* points, so the intermediate normal
/// coordinates of small-radius helices differ from the exact split by a
/// little more than the rounding.
const SPLIT_TOL: f64 = 2e-5;

#[derive(Debug, Clone)]
enum Op {
    Rapid([f64; 3]),
    Line {
        d: [f64; 3],
        feed: f64,
        beam: bool,
    },
    Arc {
        plane: Plane,
        radius: f64,
        /// Direction from the start point to the centre.
        phi: f64,
        sweep: f64,
        full: bool,
        ccw: bool,
        /// Travel along the plane normal (helix).
        dn: f64,
        turns: u32,
        feed: f64,
        beam: bool,
    },
    Dwell(f64),
    Var {
        name: String,
        value: f64,
        sync: bool,
    },
}

fn coord(range: f64) -> impl Strategy<Value = f64> {
    -range..range
}

fn op(with_vars: bool) -> impl Strategy<Value = Op> {
    let plane = prop_oneof![Just(Plane::Xy), Just(Plane::Xz), Just(Plane::Yz)];
    let feed = 0.1f64..100.0;
    let rapid = [coord(20.0), coord(20.0), coord(5.0)].prop_map(Op::Rapid);
    let line = ([coord(5.0), coord(5.0), coord(1.0)], feed.clone(), any::<bool>())
        .prop_map(|(d, feed, beam)| Op::Line { d, feed, beam });
    let arc = (
        plane,
        0.05f64..10.0,
        0.0..TAU,
        0.2..(TAU - 0.2),
        prop::bool::weighted(0.25),
        any::<bool>(),
        prop_oneof![Just(0.0), coord(2.0)],
        prop_oneof![4 => Just(0u32), 1 => 1u32..3],
        feed,
        any::<bool>(),
    )
        .prop_map(
            |(plane, radius, phi, sweep, full, ccw, dn, turns, feed, beam)| Op::Arc {
                plane,
                radius,
                phi,
                sweep,
                full,
                ccw,
                dn,
                turns,
                feed,
                beam,
            },
        );
    let dwell = (0.0f64..2.0).prop_map(Op::Dwell);
    let var = (
        prop_oneof![Just("P"), Just("Q"), Just("M")],
        1u32..399,
        coord(1000.0),
        any::<bool>(),
    )
        .prop_filter("not the shutter", |(l, n, _, _)| !(*l == "M" && *n == 33))
        .prop_map(|(l, n, value, sync)| Op::Var {
            name: format!("{l}{n}"),
            value,
            // Synchronous assignment exists for M-variables only.
            sync: sync && l == "M",
        });
    if with_vars {
        prop_oneof![2 => rapid, 5 => line, 5 => arc, 1 => dwell, 2 => var].boxed()
    } else {
        prop_oneof![2 => rapid, 5 => line, 5 => arc, 1 => dwell].boxed()
    }
}

fn motion(kind: MotionKind, to: P3, feed: Option<f64>, beam: bool) -> Record {
    Record::Move(Motion {
        kind,
        to,
        feed,
        beam,
        beam_switch: None,
        role: None,
        chain: None,
        block: None,
        tool: Default::default(),
    })
}

/// The toolpath the ops describe, starting at the origin.
fn build(ops: &[Op]) -> Vec<Record> {
    let mut pos = P3::origin();
    let mut out = Vec::with_capacity(ops.len());
    for op in ops {
        match op {
            Op::Rapid(p) => {
                pos = P3::new(p[0], p[1], p[2]);
                out.push(motion(MotionKind::Rapid, pos, None, false));
            }
            Op::Line { d, feed, beam } => {
                pos = P3::new(pos.x + d[0], pos.y + d[1], pos.z + d[2]);
                out.push(motion(MotionKind::Line, pos, Some(*feed), *beam));
            }
            &Op::Arc {
                plane,
                radius,
                phi,
                sweep,
                full,
                ccw,
                dn,
                turns,
                feed,
                beam,
            } => {
                let s = plane.project(&pos);
                let c = s + radius * nalgebra::Vector2::new(phi.cos(), phi.sin());
                let a0 = phi + PI;
                let a1 = if ccw { a0 + sweep } else { a0 - sweep };
                let e = if full {
                    s
                } else {
                    c + radius * nalgebra::Vector2::new(a1.cos(), a1.sin())
                };
                let n0 = plane.normal_coord(&pos);
                let to = plane.lift(&e, n0 + dn);
                let arc = ArcData {
                    center: plane.lift(&c, n0),
                    ccw,
                    plane,
                    extra_turns: turns,
                };
                pos = to;
                out.push(motion(MotionKind::Arc(arc), to, Some(feed), beam));
            }
            Op::Dwell(s) => out.push(Record::Dwell {
                seconds: *s,
                block: None,
            }),
            Op::Var { name, value, sync } => out.push(Record::Var {
                name: name.clone(),
                value: *value,
                sync: *sync,
                block: None,
            }),
        }
    }
    out
}

/// What the reader should give back: feeds in the dialect's unit; for PMAC,
/// arcs with extra turns as full circles plus the remainder, and a
/// `DWELL 0` at the end when the last move left the shutter open. Each
/// record comes with its position tolerance.
fn expected(recs: &[Record], unit: FeedUnit, d: Dialect) -> Vec<(Record, f64)> {
    let out_unit = d.feed_unit();
    let mut pos = P3::origin();
    let mut beam = false;
    let mut out = Vec::new();
    for r in recs {
        let Record::Move(m) = r else {
            out.push((r.clone(), TOL));
            continue;
        };
        let mut m = m.clone();
        m.feed = m.feed.map(|f| unit.convert(f, out_unit));
        beam = m.beam;
        match m.kind {
            MotionKind::Arc(a) if d == Dialect::Pmac && a.extra_turns > 0 => {
                let (s, e, c) = (
                    a.plane.project(&pos),
                    a.plane.project(&m.to),
                    a.plane.project(&a.center),
                );
                let base = sweep(&c, &s, &e, a.ccw);
                let total = base + TAU * f64::from(a.extra_turns);
                let n0 = a.plane.normal_coord(&pos);
                let dn = a.plane.normal_coord(&m.to) - n0;
                for k in 1..=a.extra_turns {
                    let mut full = m.clone();
                    full.to = a.plane.lift(&s, n0 + dn * TAU * f64::from(k) / total);
                    full.kind = MotionKind::Arc(ArcData {
                        center: a.plane.lift(&c, a.plane.normal_coord(&full.to) - dn * TAU / total),
                        extra_turns: 0,
                        ..a
                    });
                    out.push((Record::Move(full), SPLIT_TOL));
                }
                let mut rest = m.clone();
                rest.kind = MotionKind::Arc(ArcData {
                    center: a.plane.lift(&c, n0 + dn * TAU * f64::from(a.extra_turns) / total),
                    extra_turns: 0,
                    ..a
                });
                out.push((Record::Move(rest), SPLIT_TOL));
            }
            _ => out.push((Record::Move(m.clone()), TOL)),
        }
        pos = m.to;
    }
    if d == Dialect::Pmac && beam {
        out.push((
            Record::Dwell {
                seconds: 0.0,
                block: None,
            },
            TOL,
        ));
    }
    out
}

/// Unsigned sweep of a partial arc (full circle when start == end).
fn sweep(c: &P2, s: &P2, e: &P2, ccw: bool) -> f64 {
    if (e - s).norm() < 1e-12 {
        return TAU;
    }
    let a0 = (s - c).y.atan2((s - c).x);
    let a1 = (e - c).y.atan2((e - c).x);
    let d = if ccw { a1 - a0 } else { a0 - a1 };
    d.rem_euclid(TAU)
}

fn close(a: &P3, b: &P3, tol: f64) -> bool {
    (0..3).all(|i| (a[i] - b[i]).abs() <= tol)
}

fn compare(want: &[(Record, f64)], got: &[Record], text: &str) -> Result<(), TestCaseError> {
    prop_assert_eq!(
        want.len(),
        got.len(),
        "record count differs\nwant {:#?}\ngot {:#?}\n{}",
        want,
        got,
        text
    );
    for (i, ((w, tol), g)) in want.iter().zip(got).enumerate() {
        let ctx = || format!("record {i}: want {w:?}\ngot {g:?}\nprogram:\n{text}");
        match (w, g) {
            (Record::Move(w), Record::Move(g)) => {
                prop_assert!(close(&w.to, &g.to, *tol), "end point: {}", ctx());
                prop_assert_eq!(w.beam, g.beam, "beam: {}", ctx());
                match (w.kind, g.kind) {
                    (MotionKind::Rapid, MotionKind::Rapid) => {}
                    (MotionKind::Line, MotionKind::Line) => {
                        prop_assert!(feed_close(w.feed, g.feed), "feed: {}", ctx());
                    }
                    (MotionKind::Arc(wa), MotionKind::Arc(ga)) => {
                        prop_assert!(feed_close(w.feed, g.feed), "feed: {}", ctx());
                        prop_assert!(close(&wa.center, &ga.center, *tol), "centre: {}", ctx());
                        prop_assert_eq!(wa.ccw, ga.ccw, "ccw: {}", ctx());
                        prop_assert_eq!(wa.plane, ga.plane, "plane: {}", ctx());
                        prop_assert_eq!(wa.extra_turns, ga.extra_turns, "turns: {}", ctx());
                    }
                    _ => prop_assert!(false, "kind: {}", ctx()),
                }
            }
            (Record::Dwell { seconds: w, .. }, Record::Dwell { seconds: g, .. }) => {
                prop_assert!((w - g).abs() <= TOL, "dwell: {}", ctx());
            }
            (
                Record::Var {
                    name: wn,
                    value: wv,
                    sync: ws,
                    ..
                },
                Record::Var {
                    name: gn,
                    value: gv,
                    sync: gs,
                    ..
                },
            ) => {
                prop_assert!(wn.eq_ignore_ascii_case(gn), "name: {}", ctx());
                prop_assert!((wv - gv).abs() <= TOL, "value: {}", ctx());
                prop_assert_eq!(ws, gs, "sync: {}", ctx());
            }
            _ => prop_assert!(false, "record type: {}", ctx()),
        }
    }
    Ok(())
}

fn feed_close(w: Option<f64>, g: Option<f64>) -> bool {
    match (w, g) {
        (Some(w), Some(g)) => (w - g).abs() <= TOL,
        (None, None) => true,
        _ => false,
    }
}

fn round_trip(ops: &[Op], unit: FeedUnit, d: Dialect) -> Result<(), TestCaseError> {
    let recs = build(ops);
    let mut opts = WriteOptions::for_dialect(d);
    opts.decimals = DECIMALS;
    let text = write_string(opts, unit, &recs).map_err(|e| TestCaseError::fail(format!("write: {e}")))?;
    let read_opts = ReadOptions {
        dialect: Some(d),
        ..Default::default()
    };
    let (rd, got) = read_str(&text, &read_opts).map_err(|e| TestCaseError::fail(format!("read: {e}\n{text}")))?;
    prop_assert_eq!(rd, d);
    compare(&expected(&recs, unit, d), &got, &text)
}

fn unit() -> impl Strategy<Value = FeedUnit> {
    prop_oneof![Just(FeedUnit::MmPerS), Just(FeedUnit::MmPerMin)]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]

    fn iso_round_trip(ops in prop::collection::vec(op(false), 0..40), unit in unit()) {
        round_trip(&ops, unit, Dialect::Iso)?;
    }

    #[test]
    fn pmac_round_trip(ops in prop::collection::vec(op(false), 0..40), unit in unit()) {
        round_trip(&ops, unit, Dialect::Pmac)?;
    }

    // PMAC variables other than the shutter and the line counter are
    // carried as `Var` records. Needs the PMAC reader.
    #[test]
    fn pmac_variables_round_trip(ops in prop::collection::vec(op(true), 0..40), unit in unit()) {
        round_trip(&ops, unit, Dialect::Pmac)?;
    }
}

/// The generator and the expectation builder themselves, so the ignored
/// tests are not broken in ways only the readers would reveal: every
/// generated toolpath writes without error in both dialects.
#[test]
fn generated_toolpaths_write_in_both_dialects() {
    use proptest::strategy::ValueTree;
    use proptest::test_runner::{Config, TestRunner};
    let mut runner = TestRunner::new(Config::default());
    let strat = (prop::collection::vec(op(true), 0..40), unit());
    for _ in 0..200 {
        let (ops, unit) = strat.new_tree(&mut runner).expect("tree").current();
        let recs = build(&ops);
        for d in [Dialect::Iso, Dialect::Pmac] {
            let mut opts = WriteOptions::for_dialect(d);
            opts.decimals = DECIMALS;
            let text = write_string(opts, unit, &recs).unwrap_or_else(|e| panic!("{e}\n{ops:#?}"));
            let want = expected(&recs, unit, d);
            let moves = want.iter().filter(|(r, _)| matches!(r, Record::Move(_))).count();
            if d == Dialect::Pmac {
                // One counter per motion line, the last one equal to the count.
                assert_eq!(text.matches(" P400=").count(), moves, "{text}");
            }
        }
    }
}
