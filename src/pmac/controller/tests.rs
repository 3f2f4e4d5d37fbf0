use super::*;

fn ctl() -> (Emulator, Session) {
    let cfg = Config {
        memory_words: 100,
        ..Config::default()
    };
    (Emulator::new(cfg, Clock::Manual(0.0), None), Session::default())
}

fn ok(c: &mut Emulator, s: &mut Session, l: &str) -> Vec<String> {
    c.command_line(s, l).unwrap_or_else(|e| panic!("{l}: ERR{e:03}"))
}

#[test]
fn download_run_and_status() {
    let (mut c, mut s) = ctl();
    assert_eq!(ok(&mut c, &mut s, "i6=1 i3=2 ver"), vec!["1.945  "]);
    assert_eq!(ok(&mut c, &mut s, "cid"), vec!["603382"]);
    ok(&mut c, &mut s, "CLOSE DELETE GATHER");
    ok(&mut c, &mut s, "OPEN PROG 1 CLEAR");
    assert_eq!(ok(&mut c, &mut s, "SIZE"), vec!["-100"]);
    assert_eq!(c.command_line(&mut s, "OPEN PROG 2"), Err(err::IN_USE));
    ok(&mut c, &mut s, "LINEAR X1 F1 P400=1");
    ok(&mut c, &mut s, "M33==1 X2 P400=2");
    ok(&mut c, &mut s, "M33=0 CLOSE");
    assert_eq!(ok(&mut c, &mut s, "SIZE"), vec!["86"]);
    assert_eq!(c.command_line(&mut s, "&1R"), Err(err::BAD_POINTER));
    ok(&mut c, &mut s, "&1B1R");
    let st = ok(&mut c, &mut s, "&1??");
    assert_eq!(parse_status(&st[0]), Some((true, false)));
    assert_eq!(c.command_line(&mut s, "OPEN PROG 1 CLEAR"), Err(err::RUNNING));
    c.set_time(1.5);
    // P400=2 is a plain assignment: it ran when look-ahead calculated
    // the second line, ahead of its motion.
    assert_eq!(ok(&mut c, &mut s, "P400"), vec!["2"]);
    assert_eq!(ok(&mut c, &mut s, "M33"), vec!["1"]);
    c.set_time(2.5);
    // The immediate `M33=0` after the last move ran at calculation
    // time, before `M33==1` took effect: the shutter stays open. This
    // is why pmac-send closes it synchronously and after every stop.
    assert_eq!(ok(&mut c, &mut s, "M33"), vec!["1"]);
    assert_eq!(parse_status(&ok(&mut c, &mut s, "&1??")[0]), Some((false, true)));
}

#[test]
fn memory_and_error_codes() {
    let (mut c, mut s) = ctl();
    assert_eq!(c.command_line(&mut s, "LINEAR X1"), Err(err::NEEDS_OPEN_BUFFER));
    assert_eq!(c.command_line(&mut s, "HELLO"), Err(err::DATA));
    ok(&mut c, &mut s, "OPEN PROG 1 CLEAR");
    let mut stored = 0;
    let e = loop {
        match c.command_line(&mut s, "X1 Y2 Z3 F4 P5=6") {
            Ok(_) => stored += 1,
            Err(e) => break e,
        }
        assert!(stored < 100);
    };
    assert_eq!(e, err::NO_ROOM);
    assert_eq!(stored, 100 / 7);
    ok(&mut c, &mut s, "CLOSE");
    assert_eq!(c.command_line(&mut s, "&2B1R"), Err(err::NO_MOTORS));
}

#[test]
fn rotary_idles_when_dry_and_logs_it() {
    let (mut c, mut s) = ctl();
    ok(&mut c, &mut s, "&1 DEFINE ROT 50");
    ok(&mut c, &mut s, "&1 B0");
    ok(&mut c, &mut s, "OPEN ROT");
    ok(&mut c, &mut s, "LINEAR X1 F1");
    assert_eq!(ok(&mut c, &mut s, "PR"), vec!["1"]);
    ok(&mut c, &mut s, "&1R");
    assert_eq!(ok(&mut c, &mut s, "PR"), vec!["0"]);
    c.set_time(3.0);
    ok(&mut c, &mut s, "X2");
    c.set_time(10.0);
    assert!(c.running());
    assert!(c.in_position());
    ok(&mut c, &mut s, "CLOSE");
    ok(&mut c, &mut s, "&1Q");
    assert!(!c.running());
    assert_eq!(c.pos.x, 2.0);
}

#[test]
fn synchronous_counter_follows_motion_and_mflush_clears_leftovers() {
    let (mut c, mut s) = ctl();
    ok(&mut c, &mut s, "M7400->L:$6190");
    assert_eq!(ok(&mut c, &mut s, "M7400->"), vec!["L:$6190"]);
    ok(&mut c, &mut s, "OPEN PROG 1 CLEAR");
    ok(&mut c, &mut s, "LINEAR F1 X1 M7400==1");
    ok(&mut c, &mut s, "M33==1 X2 M7400==2");
    ok(&mut c, &mut s, "X3 M7400==3");
    ok(&mut c, &mut s, "M33==0 X4 M7400==4");
    ok(&mut c, &mut s, "CLOSE &1B1R");
    c.set_time(0.5);
    // The counter (through M7400, in P400) is set where the next move
    // starts: still 0 in move 1.
    assert_eq!(ok(&mut c, &mut s, "P400"), vec!["0"]);
    assert_eq!(ok(&mut c, &mut s, "#1P"), vec!["5000"]);
    c.set_time(1.5);
    assert_eq!(ok(&mut c, &mut s, "P400 M7400 M33"), vec!["1", "1", "1"]);
    c.set_time(2.25);
    ok(&mut c, &mut s, "&1A");
    assert_eq!(ok(&mut c, &mut s, "#1P #2P #1->"), vec!["22500", "0", "10000X"]);
    assert!(!c.running() && c.in_position());
    // Queued `==` assignments of dropped look-ahead (M33==0, counters)
    // stay queued: the next move would run them. MFLUSH clears them.
    assert!(!c.sync_left.is_empty());
    ok(&mut c, &mut s, "&1 MFLUSH");
    assert!(c.sync_left.is_empty());
    assert_eq!(c.position().x, 2.25);
}

#[test]
fn dry_rotary_program_is_suspended_not_finished() {
    let (mut c, mut s) = ctl();
    ok(&mut c, &mut s, "&1 DEFINE ROT 50");
    ok(&mut c, &mut s, "&1 B0");
    ok(&mut c, &mut s, "OPEN ROT");
    ok(&mut c, &mut s, "LINEAR X1 F1");
    ok(&mut c, &mut s, "&1R");
    ok(&mut c, &mut s, "CLOSE");
    c.set_time(5.0);
    let st = ok(&mut c, &mut s, "&1??");
    assert_eq!(parse_status(&st[0]), Some((true, true)), "running and in position");
    ok(&mut c, &mut s, "&1Q");
    assert_eq!(parse_status(&ok(&mut c, &mut s, "&1??")[0]), Some((false, true)));
}

#[test]
fn no_panic_on_garbage() {
    let (mut c, mut s) = ctl();
    for l in [
        "",
        "&",
        "&99",
        "B",
        "P99999",
        "P1=",
        "P1=$",
        "OPEN PROG",
        "DEFINE ROT 99999999999",
        "\u{e9}",
        "M33=1e999",
        "?",
    ] {
        let _ = c.command_line(&mut s, l);
    }
    ok(&mut c, &mut s, "OPEN PROG 3");
    for l in ["CIRCLE1 X1", "X(", "))))", "LINEAR X1 Y1 F0"] {
        let _ = c.command_line(&mut s, l);
    }
    ok(&mut c, &mut s, "CLOSE &1B3R");
    c.set_time(100.0);
    c.advance();
    assert!(!c.running());
}
