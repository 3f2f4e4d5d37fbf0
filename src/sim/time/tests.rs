use super::*;

fn machine(controller: Controller) -> Machine {
    let mut m = Machine::builtin("lookahead");
    m.controller = controller;
    m.accel_mm_s2 = 100.0;
    m.junction_deviation_mm = 0.01;
    m.max_feed_mm_s = 1000.0;
    m.block_rate_hz = 0.0;
    m.ta_ms = 133.0;
    m.ts_ms = 0.0;
    m
}

fn run(m: &Machine, blocks: &[MotionBlock]) -> Vec<TimedBlock> {
    let mut tm = TimeModel::new(m);
    for b in blocks {
        tm.push_move(b.clone());
    }
    drain(tm)
}

/// Finish the model and collect its timed blocks.
fn drain(mut tm: TimeModel) -> Vec<TimedBlock> {
    tm.finish();
    let mut v = Vec::new();
    while let Some(e) = tm.pop() {
        if let Event::Block(b) = e {
            v.push(b);
        }
    }
    v
}

fn line(dx: f64, dy: f64, f: f64) -> MotionBlock {
    MotionBlock::straight(MoveClass::Line, V3::new(dx, dy, 0.0), f)
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

/// Every block's pieces cover its length, blocks follow each other in
/// time without gaps, and speeds are continuous across boundaries.
fn check_consistent(t: &[TimedBlock]) {
    let mut now = 0.0;
    let mut v_prev = 0.0;
    for b in t {
        let d: f64 = b.pieces().iter().map(|p| p.distance()).sum();
        assert!(close(d, b.block.length_mm, 1e-9), "{d} vs {}", b.block.length_mm);
        assert!(close(b.t_start_s, now, 1e-9));
        let dt: f64 = b.pieces().iter().map(|p| p.dt).sum();
        assert!(close(dt, b.time_s, 1e-12));
        if let Some(p) = b.pieces().first() {
            assert!(close(p.v0, v_prev, 1e-9), "speed jumps {v_prev} -> {}", p.v0);
            v_prev = b.pieces()[b.n_pieces - 1].v1;
        }
        now += b.time_s;
    }
    assert!(close(v_prev, 0.0, 1e-12), "ends moving");
}

#[test]
fn one_trapezoid() {
    // 10 mm at 10 mm/s, 100 mm/s²: 0.1 s up, 0.1 s down (0.5 mm each),
    // 9 mm cruise in 0.9 s.
    let t = run(&machine(Controller::Lookahead), &[line(10.0, 0.0, 10.0)]);
    check_consistent(&t);
    assert!(close(t[0].time_s, 1.1, 1e-12), "{}", t[0].time_s);
    assert_eq!(t[0].achieved_feed_mm_s, 10.0);
    assert_eq!(t[0].limited_by, Limit::None);
    assert_eq!(t[0].n_pieces, 3);
}

#[test]
fn triangle_profile() {
    // 0.5 mm cannot reach 10 mm/s: peak sqrt(a·L), time 2·peak/a.
    let t = run(&machine(Controller::Lookahead), &[line(0.5, 0.0, 10.0)]);
    check_consistent(&t);
    let vp = 50.0_f64.sqrt();
    assert!(close(t[0].achieved_feed_mm_s, vp, 1e-12));
    assert!(close(t[0].time_s, 2.0 * vp / 100.0, 1e-12));
    assert_eq!(t[0].limited_by, Limit::Acceleration);
}

#[test]
fn junction_at_90_degrees() {
    // sin(θ/2) = √½ for a right angle: v² = a·δ·√½/(1−√½).
    let s = 0.5_f64.sqrt();
    let vj = (100.0 * 0.01 * s / (1.0 - s)).sqrt();
    assert!(close(junction_speed(100.0, 0.01, &V3::x(), &V3::y()), vj, 1e-12));
    assert_eq!(junction_speed(100.0, 0.01, &V3::x(), &V3::x()), f64::INFINITY);
    assert_eq!(junction_speed(100.0, 0.01, &V3::x(), &-V3::x()), 0.0);
    let t = run(
        &machine(Controller::Lookahead),
        &[line(0.5, 0.0, 10.0), line(0.0, 0.5, 10.0)],
    );
    check_consistent(&t);
    let corner = t[0].pieces()[t[0].n_pieces - 1].v1;
    assert!(close(corner, vj, 1e-12), "{corner} vs {vj}");
    // Up from rest, down to the corner speed: v_p² = a·L + v_j²/2.
    let vp = (50.0 + 0.5 * vj * vj).sqrt();
    assert!(close(t[0].achieved_feed_mm_s, vp, 1e-12));
    assert!(close(t[0].time_s, vp / 100.0 + (vp - vj) / 100.0, 1e-12));
    assert_eq!(t[0].limited_by, Limit::Junction);
    assert_eq!(t[1].limited_by, Limit::Junction);
    // Straight on, the same two lengths run as one 1 mm move.
    let t2 = run(
        &machine(Controller::Lookahead),
        &[line(0.5, 0.0, 10.0), line(0.5, 0.0, 10.0)],
    );
    let one = run(&machine(Controller::Lookahead), &[line(1.0, 0.0, 10.0)]);
    assert!(close(t2[0].time_s + t2[1].time_s, one[0].time_s, 1e-12));
}

#[test]
fn planner_buffer_must_be_able_to_stop() {
    // With one block of view, every block stops at its end.
    let mut m = machine(Controller::Lookahead);
    m.lookahead_blocks = 1;
    let t = run(&m, &[line(10.0, 0.0, 10.0), line(10.0, 0.0, 10.0)]);
    check_consistent(&t);
    assert!(close(t[0].time_s, 1.1, 1e-12) && close(t[1].time_s, 1.1, 1e-12));
    m.lookahead_blocks = 2;
    let t = run(&m, &[line(10.0, 0.0, 10.0), line(10.0, 0.0, 10.0)]);
    assert!(close(t[0].time_s + t[1].time_s, 2.1, 1e-12));
}

#[test]
fn pmac_stretched_move() {
    // 0.1 mm at 3 mm/s would take 33 ms; TA = 133 ms stretches it, so
    // the plateau is 0.1/0.133 mm/s and from rest to rest it takes 2·TA.
    let m = machine(Controller::Pmac);
    let t = run(&m, &[line(0.1, 0.0, 3.0)]);
    check_consistent(&t);
    assert!(close(t[0].achieved_feed_mm_s, 0.1 / 0.133, 1e-12));
    assert!(close(t[0].time_s, 0.266, 1e-12));
    assert_eq!(t[0].limited_by, Limit::Ta);
    // A long move reaches F and takes L/F + TA.
    let t = run(&m, &[line(1.0, 0.0, 3.0)]);
    assert!(close(t[0].time_s, 1.0 / 3.0 + 0.133, 1e-12));
    assert_eq!((t[0].achieved_feed_mm_s, t[0].limited_by), (3.0, Limit::None));
}

#[test]
fn pmac_blends_corners_without_slowing() {
    let m = machine(Controller::Pmac);
    let t = run(&m, &[line(1.0, 0.0, 3.0), line(0.0, 1.0, 3.0)]);
    check_consistent(&t);
    assert!(close(t[0].time_s + t[1].time_s, 2.0 / 3.0 + 0.133, 1e-12));
    // Equal speeds: the boundary is the middle of a flat "ramp".
    assert!(close(t[0].time_s, 1.0 / 3.0 + 0.133 / 2.0, 1e-12));
}

#[test]
fn pmac_blend_takes_the_incoming_moves_ta() {
    // 1 mm from rest at TA 133, then TA 6 and 0.03 mm: the second move
    // is not stretched (10 ms >= 6 ms), and the blend into it (at one
    // speed, so flat) starts 3 ms before its nominal start: that is
    // where an M33== on it acts.
    let m = machine(Controller::Pmac);
    let mut tm = TimeModel::new(&m);
    tm.push_move(line(1.0, 0.0, 3.0));
    tm.set_accel(Some(6.0), Some(0.0));
    tm.push_move(line(0.03, 0.0, 3.0));
    let t = drain(tm);
    check_consistent(&t);
    assert_eq!(t[1].limited_by, Limit::None);
    assert!(close(t[1].achieved_feed_mm_s, 3.0, 1e-12));
    assert!(close(t[1].t_start_s - t[1].exec_start_s, 0.003, 1e-12));
    // The other way round the blend is clamped to what the shorter
    // move before it has left, so the curve stays consistent.
    let mut tm = TimeModel::new(&m);
    tm.set_accel(Some(6.0), Some(0.0));
    tm.push_move(line(0.03, 0.0, 3.0));
    tm.set_accel(Some(133.0), Some(0.0));
    tm.push_move(line(1.0, 0.0, 3.0));
    check_consistent(&drain(tm));
}

#[test]
fn pmac_s_curve_time_and_block_rate() {
    let mut m = machine(Controller::Pmac);
    m.ta_ms = 10.0;
    m.ts_ms = 50.0;
    let t = run(&m, &[line(0.01, 0.0, 3.0)]);
    assert!(close(t[0].time_s, 0.2, 1e-12), "2·TS wins over TA");
    let mut tm = TimeModel::new(&m);
    tm.set_accel(Some(20.0), Some(0.0));
    tm.push_move(line(0.01, 0.0, 3.0));
    tm.finish();
    let Some(Event::Block(b)) = tm.pop() else { panic!() };
    assert!(close(b.time_s, 0.04, 1e-12), "TA/TS from the program");
    // TA0 is TA1 on a Turbo PMAC (whole ms, at least 1): the block
    // lasts the block-rate time plus the half ramps at its ends.
    m.ta_ms = 0.0;
    m.ts_ms = 0.0;
    m.block_rate_hz = 100.0;
    let t = run(&m, &[line(0.01, 0.0, 3.0)]);
    assert_eq!(t[0].limited_by, Limit::BlockRate);
    assert!(close(t[0].time_s, 0.011, 1e-12), "{}", t[0].time_s);
}

#[test]
fn rotary_moves_take_the_rotary_axes_time() {
    for c in [Controller::Pmac, Controller::Lookahead] {
        let mut m = machine(c);
        m.rotary = Some(crate::machine::Rotary {
            max_deg_s: 30.0,
            rapid_deg_s: 90.0,
            accel_deg_s2: 300.0,
        });
        // Indexing: 90 degrees at F 60 deg/s capped to 30, 0.1 s ramps.
        let mut index = MotionBlock::straight(MoveClass::Line, V3::zeros(), 60.0);
        index.rotary_deg = 90.0;
        // Rapid indexing: 9 degrees cannot reach 90 deg/s: a triangle.
        let mut rapid = MotionBlock::straight(MoveClass::Rapid, V3::zeros(), 0.0);
        rapid.rotary_deg = 9.0;
        // Both: 1 mm at 3 mm/s while turning 60 degrees: the rotary
        // maximum (30 deg/s) holds the feed to 0.5 mm/s.
        let mut both = line(1.0, 0.0, 3.0);
        both.rotary_deg = 60.0;
        let t = run(&m, &[line(1.0, 0.0, 3.0), index, rapid, both]);
        check_consistent(&t);
        assert!(close(t[1].time_s, 3.0 + 0.1, 1e-12), "{c:?}: {}", t[1].time_s);
        assert!(close(t[2].time_s, 2.0 * (9.0f64 / 300.0).sqrt(), 1e-12), "{c:?}");
        assert!(close(t[2].t_start_s, t[1].t_start_s + t[1].time_s, 1e-12), "{c:?}");
        assert!(close(t[3].block.feed_mm_s, 0.5, 1e-12), "{c:?}");
        assert!(t[3].time_s >= 2.0 - 1e-12, "{c:?}: {}", t[3].time_s);
    }
    // Without a rotary section the linear figures count, as degrees.
    let m = machine(Controller::Pmac);
    let r = m.rotary_or_linear();
    assert_eq!((r.max_deg_s, r.rapid_deg_s), (m.max_feed_mm_s, m.rapid_mm_s));
}

#[test]
fn pmac_rapid_runs_each_axis_and_stops() {
    let mut m = machine(Controller::Pmac);
    m.rapid_mm_s = 10.0;
    m.rapid_accel_mm_s2 = 100.0;
    let rapid = MotionBlock::straight(MoveClass::Rapid, V3::new(10.0, 0.5, 0.0), 0.0);
    let t = run(&m, &[line(1.0, 0.0, 3.0), rapid, line(1.0, 0.0, 3.0)]);
    check_consistent(&t);
    // X: 10 mm at 10 mm/s with 0.1 s ramps = 1.1 s; Y is faster.
    assert!(close(t[1].time_s, 1.1, 1e-12));
    assert!(close(t[0].time_s, 1.0 / 3.0 + 0.133, 1e-12), "stops before the rapid");
}

/// Bayesteh (2013) Fig. 3-20: a straight path at 3 mm/s in equal segments on
/// the micro mill's PMAC (TA ≈ 133 ms): the achieved feed grows
/// linearly with segment length and reaches 3 mm/s at about 0.4 mm.
#[test]
fn fig_3_20_achieved_feed_grows_linearly_with_segment_length() {
    let m = Machine::builtin("micro-mill");
    let ta = crate::machine::pmac::accel_time_s(m.ta_ms, m.ts_ms);
    let mut reached = None;
    for i in 1..=16 {
        let s = 0.05 * i as f64;
        let blocks: Vec<MotionBlock> = (0..40).map(|_| line(s, 0.0, 3.0)).collect();
        let t = run(&m, &blocks);
        check_consistent(&t);
        let mid = &t[20];
        let want = (s / ta).min(3.0);
        assert!(
            close(mid.achieved_feed_mm_s, want, 1e-9),
            "{s}: {}",
            mid.achieved_feed_mm_s
        );
        if s < 0.39 {
            assert_eq!(mid.limited_by, Limit::Ta);
            // Linear: feed per length is the same for every short segment.
            assert!(close(mid.achieved_feed_mm_s / s, 1.0 / ta, 1e-9));
        }
        if reached.is_none() && mid.achieved_feed_mm_s >= 3.0 - 1e-9 {
            reached = Some(s);
        }
    }
    let s = reached.unwrap();
    assert!((0.39..=0.45).contains(&s), "reaches 3 mm/s at {s} mm");
}

#[test]
fn arcs_are_held_to_centripetal_acceleration() {
    let m = machine(Controller::Lookahead);
    let mut b = line(10.0, 0.0, 10.0);
    b.class = MoveClass::Arc;
    b.radius_mm = 0.25;
    let t = run(&m, &[b]);
    // v = sqrt(a·r) = 5 mm/s.
    assert!(close(t[0].achieved_feed_mm_s, 5.0, 1e-12));
    assert_eq!(t[0].limited_by, Limit::Centripetal);
}

mod props {
    use super::*;
    use proptest::prelude::*;

    /// (kind, length, heading, feed, radius): kind 0-4 line, 5 rapid,
    /// 6-7 arc, 8 dwell, 9 TA change.
    fn step() -> impl Strategy<Value = (u8, f64, f64, f64, f64)> {
        (
            0u8..10,
            prop_oneof![Just(0.0), 0.0..3.0f64],
            0.0..6.3f64,
            0.1..50.0f64,
            0.05..5.0f64,
        )
    }

    fn check_stream(m: &Machine, steps: &[(u8, f64, f64, f64, f64)]) {
        let mut tm = TimeModel::new(m);
        let mut dir = V3::x();
        for &(k, l, h, f, r) in steps {
            let d = V3::new(h.cos(), h.sin(), 0.0);
            match k {
                8 => tm.push_dwell(l * 0.01, None),
                // A PMAC with zero acceleration time jumps in speed; not tested.
                9 => tm.set_accel(Some(1.0 + l * 50.0), Some(l * 10.0)),
                5 => tm.push_move(MotionBlock::straight(MoveClass::Rapid, d * l, 0.0)),
                6 | 7 => {
                    // An arc turning by up to a right angle.
                    let mut b = MotionBlock::straight(MoveClass::Arc, d * l, f);
                    b.dir_in = dir;
                    b.dir_out = d;
                    b.radius_mm = r;
                    if l == 0.0 {
                        b.dir_in = V3::zeros();
                        b.dir_out = V3::zeros();
                    }
                    tm.push_move(b);
                }
                _ => tm.push_move(MotionBlock::straight(MoveClass::Line, d * l, f)),
            }
            if l > 0.0 && k != 8 && k != 9 {
                dir = d;
            }
        }
        tm.finish();
        let (mut now, mut v) = (0.0_f64, 0.0_f64);
        while let Some(e) = tm.pop() {
            match e {
                Event::Dwell { t_start_s, seconds, .. } => {
                    assert!(close(t_start_s, now, 1e-9) && v.abs() < 1e-9, "dwell while moving");
                    now += seconds;
                }
                Event::Block(b) => {
                    assert!(close(b.t_start_s, now, 1e-9));
                    let dist: f64 = b.pieces().iter().map(|p| p.distance()).sum();
                    assert!(close(dist, b.block.length_mm, 1e-9 * (1.0 + b.block.length_mm)));
                    assert!(b.time_s >= 0.0 && b.time_s.is_finite());
                    for p in b.pieces() {
                        assert!(close(p.v0, v, 1e-9 * (1.0 + v)), "speed jumps {v} -> {}", p.v0);
                        assert!(p.v0 >= -1e-12 && p.v1 >= -1e-12 && p.dt > 0.0);
                        if m.controller == Controller::Lookahead {
                            let acc = (p.v1 - p.v0).abs() / p.dt;
                            assert!(acc <= m.accel_mm_s2 * (1.0 + 1e-6), "accel {acc}");
                        }
                        v = p.v1;
                    }
                    // A zero-length block only passes on the speed around it.
                    if b.block.class != MoveClass::Rapid && b.block.length_mm > 0.0 {
                        let cap = b.commanded_feed_mm_s.min(m.max_feed_mm_s);
                        assert!(
                            b.achieved_feed_mm_s <= cap * (1.0 + 1e-9),
                            "{} > {cap}",
                            b.achieved_feed_mm_s
                        );
                        let reached = b.achieved_feed_mm_s >= b.commanded_feed_mm_s * (1.0 - 1e-9);
                        assert!((b.limited_by == Limit::None) == reached, "{b:?}");
                    }
                    now += b.time_s;
                }
            }
        }
        assert!(v.abs() < 1e-9, "ends moving at {v}");
        assert!(close(now, tm.now_s(), 1e-9));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        #[test]
        fn lookahead_streams_are_consistent(steps in prop::collection::vec(step(), 1..40)) {
            let mut m = machine(Controller::Lookahead);
            m.max_feed_mm_s = 30.0;
            m.block_rate_hz = 200.0;
            m.lookahead_blocks = 4;
            check_stream(&m, &steps);
        }

        #[test]
        fn pmac_streams_are_consistent(steps in prop::collection::vec(step(), 1..40)) {
            let mut m = machine(Controller::Pmac);
            m.max_feed_mm_s = 30.0;
            check_stream(&m, &steps);
        }
    }
}
