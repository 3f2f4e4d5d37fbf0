//! End to end: pmac-send (the binary) against the emulator (in-process, on
//! 127.0.0.1:0), checked through the emulator's event log: the moves the
//! stage executed and the shutter state during each must equal the
//! program's, with no line lost or run twice, in every mode and after
//! faults and --resume.

use microcam::gcode::{ReadOptions, read_str};
use microcam::geometry::P3;
use microcam::model::toolpath::Record;
use microcam::pmac::controller::{Clock, Config, Emulator};
use microcam::pmac::server::{Faults, Server};
use microcam::pmac::upload_plan::{Names, UploadPlan};
use serde_json::Value;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

type Move = (f64, f64, f64, bool);

/// A job of `n` cut squares: beam-off rapid and lead-in, a beam-on square
/// with an arc, beam-off lead-out.
fn program(n: usize) -> String {
    let mut s = String::from("OPEN PROG 1 CLEAR\nABS\nM33=0\n");
    for k in 0..n {
        let x = (k % 10) as f64 * 2.0;
        let y = (k / 10) as f64 * 2.0;
        s += &format!("RAPID X{x} Y{y}\n");
        s += &format!("LINEAR X{} Y{y} F5\n", x + 0.2);
        s += &format!("M33==1 X{} Y{y}\n", x + 1.2);
        s += &format!("Y{}\n", y + 1.0);
        s += &format!("CIRCLE2 X{} Y{} I-0.5 J0\n", x + 0.2, y + 1.0);
        s += &format!("LINEAR Y{}\n", y + 0.2);
        s += &format!("M33==0 Y{y}\n");
        s += &format!("X{} Y{}\n", x, y - 0.2);
    }
    s += "M33=0\nCLOSE\n";
    s
}

fn expected(text: &str) -> Vec<Move> {
    let (_, recs) = read_str(text, &ReadOptions::default()).unwrap();
    recs.iter()
        .filter_map(|r| match r {
            Record::Move(m) => Some((m.to.x, m.to.y, m.to.z, m.beam)),
            _ => None,
        })
        .collect()
}

struct Emu {
    server: Server,
    log: PathBuf,
    dir: tempfile::TempDir,
}

fn emu(cfg: Config, faults: Faults, scale: f64) -> Emu {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("events.jsonl");
    let f = std::fs::File::create(&log).unwrap();
    let ctl = Emulator::new(cfg, Clock::scaled(scale), Some(Box::new(f)));
    let server = Server::start("127.0.0.1:0".parse::<SocketAddr>().unwrap(), ctl, faults).unwrap();
    let e = Emu { server, log, dir };
    std::fs::write(e.dir.path().join("job.pmac"), program(30)).unwrap();
    e
}

struct Outcome {
    code: i32,
    summary: Value,
    stderr: String,
}

/// pmac-send on `job.pmac` in `dir` against the controller at `port`,
/// polling fast, with `extra` flags (a `--timeout-ms` there wins).
fn spawn_send(dir: &Path, port: u16, extra: &[&str], stdout: Stdio) -> std::process::Child {
    let host = format!("127.0.0.1:{port}");
    let mut args = vec!["job.pmac", "--host", &host, "--poll-ms", "5", "--stall-s", "10"];
    if !extra.contains(&"--timeout-ms") {
        args.extend_from_slice(&["--timeout-ms", "2000"]);
    }
    args.extend_from_slice(extra);
    Command::new(env!("CARGO_BIN_EXE_pmac-send"))
        .args(&args)
        .current_dir(dir)
        .stdout(stdout)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

fn send(e: &Emu, extra: &[&str]) -> Outcome {
    let mut child = spawn_send(e.dir.path(), e.server.addr().port(), extra, Stdio::piped());
    // Bounded: no test run may hang.
    let deadline = Instant::now() + Duration::from_secs(60);
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("pmac-send did not finish in 60 s");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let out = child.wait_with_output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout).to_string();
    Outcome {
        code: out.status.code().unwrap_or(-1),
        summary: serde_json::from_str(stdout.trim()).unwrap_or(Value::Null),
        stderr: String::from_utf8_lossy(&out.stderr).to_string(),
    }
}

fn events(log: &Path) -> Vec<Value> {
    let text = std::fs::read_to_string(log).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let mut out = Vec::new();
    for (i, l) in lines.iter().enumerate() {
        match serde_json::from_str(l) {
            Ok(v) => out.push(v),
            // Only the line being written while we read may be partial.
            Err(e) => assert!(i + 1 == lines.len() && !text.ends_with('\n'), "log line {}: {e}", i + 1),
        }
    }
    out
}

fn mv(e: &Value) -> Move {
    (
        e["x"].as_f64().unwrap(),
        e["y"].as_f64().unwrap(),
        e["z"].as_f64().unwrap(),
        e["beam"].as_bool().unwrap(),
    )
}

/// Every move the stage started, in order (a clean run's moves).
fn executed(ev: &[Value]) -> Vec<Move> {
    ev.iter().filter(|e| e["ev"] == "move").map(mv).collect()
}

fn p3(v: &Value) -> P3 {
    P3::new(v[0].as_f64().unwrap(), v[1].as_f64().unwrap(), v[2].as_f64().unwrap())
}

/// The geometric check: every beam-on piece the stage executed (a move
/// cut short where its run was aborted) lies on a beam-on move of the
/// clean job, and the pieces cover each beam-on move exactly once: no
/// stretch twice, none missing. Answers the first fault.
///
/// `allow_twice_mm`: re-cut tolerated in total (a controller reset loses
/// its counters: what ran after the last confirmed counter is cut again).
fn coverage(logs: &[Vec<Value>], text: &str, allow_twice_mm: f64) -> Result<(), String> {
    let mut twice = 0.0;
    let job = UploadPlan::read(text, &Names::default()).unwrap();
    let moves = job.moves();
    let mut cover: Vec<Vec<(f64, f64)>> = vec![Vec::new(); moves.len()];
    for ev in logs {
        for (i, e) in ev.iter().enumerate() {
            if e["ev"] != "move" || e["beam"] != true {
                continue;
            }
            let from = p3(&e["from"]);
            let to = P3::new(
                e["x"].as_f64().unwrap(),
                e["y"].as_f64().unwrap(),
                e["z"].as_f64().unwrap(),
            );
            let (t, dur) = (e["t"].as_f64().unwrap(), e["dur"].as_f64().unwrap());
            // Cut short by an abort (or reset) before its end?
            let mut end = to;
            for f in &ev[i + 1..] {
                if f["ev"] == "move" || f["ev"] == "done" {
                    break;
                }
                if f["ev"] == "abort" && f["t"].as_f64().unwrap() < t + dur - 1e-9 {
                    end = P3::new(
                        f["x"].as_f64().unwrap(),
                        f["y"].as_f64().unwrap(),
                        f["z"].as_f64().unwrap(),
                    );
                    break;
                }
            }
            let k = moves
                .iter()
                .position(|m| m.beam && (m.to - to).norm() < 1e-3 && m.project(from).0 < 2e-3)
                .ok_or_else(|| format!("beam-on piece {from:?} -> {to:?} is not on a beam-on move of the job"))?;
            let (sa, sb) = (moves[k].project(from).1, moves[k].project(end).1);
            cover[k].push((sa.min(sb), sa.max(sb)));
        }
    }
    for (k, m) in moves.iter().enumerate() {
        if !m.beam {
            continue;
        }
        let len = m.length();
        let mut iv = cover[k].clone();
        iv.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut at = 0.0;
        for (a, b) in iv {
            if b - a < 1e-9 {
                continue;
            }
            if a < at - 2e-3 {
                twice += at.min(b) - a;
                if twice > allow_twice_mm {
                    return Err(format!("move {} cut twice around {a:.4}..{at:.4} mm", k + 1));
                }
            }
            if a > at + 2e-3 {
                return Err(format!("move {} not cut from {at:.4} to {a:.4} mm", k + 1));
            }
            at = at.max(b);
        }
        if at < len - 2e-3 {
            return Err(format!("move {} not cut from {at:.4} to {len:.4} mm", k + 1));
        }
    }
    Ok(())
}

fn same(a: &[Move], b: &[Move]) -> bool {
    a.len() == b.len()
        && a.iter().zip(b).all(|(p, q)| {
            (p.0 - q.0).abs() < 1e-3 && (p.1 - q.1).abs() < 1e-3 && (p.2 - q.2).abs() < 1e-3 && p.3 == q.3
        })
}

fn shutter_closed(e: &Emu) -> bool {
    e.server.controller.lock().unwrap().var(b'M', 33) == 0.0
}

fn counters_in_order(ev: &[Value]) -> Vec<u64> {
    ev.iter()
        .filter(|e| e["ev"] == "var" && e["name"] == "P400")
        .map(|e| e["value"].as_f64().unwrap() as u64)
        .filter(|&c| c > 0)
        .collect()
}

fn small() -> Config {
    Config {
        memory_words: 450,
        ..Config::default()
    }
}

#[test]
fn program_mode_runs_every_move_once() {
    let e = emu(Config::default(), Faults::default(), 500.0);
    let o = send(&e, &["--mode", "program"]);
    assert_eq!(o.code, 0, "{}", o.stderr);
    let want = expected(&program(30));
    let ev = events(&e.log);
    assert!(same(&executed(&ev), &want));
    assert_eq!(counters_in_order(&ev), (1..=want.len() as u64).collect::<Vec<_>>());
    assert_eq!(o.summary["final_counter"], want.len() as u64);
    assert!(shutter_closed(&e));
}

#[test]
fn iso_input_is_converted_and_runs_as_read() {
    let e = emu(Config::default(), Faults::default(), 500.0);
    let iso = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/testdata/writer/laser.ngc")).unwrap();
    // Content decides the dialect, not the file name.
    std::fs::write(e.dir.path().join("job.pmac"), &iso).unwrap();
    let o = send(&e, &["--mode", "program"]);
    assert_eq!(o.code, 0, "{}", o.stderr);
    let want = expected(&iso);
    assert!(want.iter().any(|m| m.3), "the sample switches the beam");
    let ev = events(&e.log);
    assert!(same(&executed(&ev), &want));
    // F120 mm/min in ISO is F2 mm/s on the controller.
    assert!(ev.iter().any(|v| v["ev"] == "move" && v["feed"] == 2.0));
}

#[test]
fn program_mode_over_plain_line_transport() {
    let e = emu(Config::default(), Faults::default(), 500.0);
    let o = send(&e, &["--mode", "program", "--transport", "line"]);
    assert_eq!(o.code, 0, "{}", o.stderr);
    assert!(same(&executed(&events(&e.log)), &expected(&program(30))));
}

#[test]
fn program_too_big_for_memory_is_refused_before_running() {
    let e = emu(small(), Faults::default(), 500.0);
    let o = send(&e, &["--mode", "program"]);
    assert_eq!(o.code, 1);
    assert!(o.stderr.contains("use --mode split"), "{}", o.stderr);
    assert!(!events(&e.log).iter().any(|v| v["ev"] == "move"));
}

#[test]
fn split_mode_cuts_only_with_beam_off() {
    let e = emu(small(), Faults::default(), 500.0);
    let o = send(&e, &["--mode", "split"]);
    assert_eq!(o.code, 0, "{}", o.stderr);
    let n = o.summary["chunks"].as_u64().unwrap();
    assert!(n >= 3, "{n}");
    let ev = events(&e.log);
    assert!(same(&executed(&ev), &expected(&program(30))));
    assert_eq!(
        counters_in_order(&ev),
        (1..=expected(&program(30)).len() as u64).collect::<Vec<_>>()
    );
    // Every run is one chunk: it starts and ends with the beam off.
    let mut runs: Vec<Vec<Move>> = Vec::new();
    for v in &ev {
        match v["ev"].as_str().unwrap() {
            "run" => runs.push(Vec::new()),
            "move" => runs.last_mut().unwrap().push(mv(v)),
            _ => {}
        }
    }
    assert_eq!(runs.len() as u64, n);
    for r in &runs {
        assert!(!r.first().unwrap().3 && !r.last().unwrap().3);
    }
    assert_eq!(ev.iter().filter(|v| v["ev"] == "done").count() as u64, n);
    assert!(shutter_closed(&e));
}

#[test]
fn rotary_mode_streams_without_idling() {
    // 700 words of rotary buffer hold about a tenth of the job: the client
    // must keep it fed while the stage runs. At 10x time the job (32 s
    // simulated) takes 3.2 s and the buffer lasts about 0.3 s: a client
    // stalled that long by a loaded CI machine is not what this tests (at
    // 50x, 65 ms of stall would have emptied it).
    let e = emu(Config::default(), Faults::default(), 10.0);
    let o = send(
        &e,
        &["--mode", "rotary", "--rotary-words", "700", "--chunk-words", "150"],
    );
    assert_eq!(o.code, 0, "{}", o.stderr);
    let ev = events(&e.log);
    assert!(same(&executed(&ev), &expected(&program(30))));
    assert_eq!(
        counters_in_order(&ev),
        (1..=expected(&program(30)).len() as u64).collect::<Vec<_>>()
    );
    let idle: Vec<&Value> = ev.iter().filter(|v| v["ev"] == "idle").collect();
    assert!(idle.is_empty(), "stage idled: {idle:?}");
    assert_eq!(ev.iter().filter(|v| v["ev"] == "run").count(), 1);
    assert!(shutter_closed(&e));
}

/// How a session is stopped from outside.
#[derive(Clone, Copy, Debug)]
enum Hit {
    /// Only the emulator's faults.
    None,
    /// Send this signal to pmac-send once the log shows this many moves.
    Signal(&'static str, usize),
}

fn split_args() -> Vec<&'static str> {
    vec!["--mode", "split"]
}

fn rotary_args() -> Vec<&'static str> {
    vec!["--mode", "rotary", "--rotary-words", "700", "--chunk-words", "150"]
}

/// Start pmac-send; with `Signal`, signal it once the emulator has
/// started that many moves.
fn send_hit(e: &Emu, extra: &[&str], hit: Hit) -> Outcome {
    let Hit::Signal(sig, after) = hit else {
        return send(e, extra);
    };
    let mut child = spawn_send(e.dir.path(), e.server.addr().port(), extra, Stdio::piped());
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        let moved = events(&e.log).iter().filter(|v| v["ev"] == "move").count();
        if moved >= after || child.try_wait().unwrap().is_some() {
            break;
        }
        assert!(Instant::now() < deadline, "no move {after} seen");
        std::thread::sleep(Duration::from_millis(2));
    }
    let _ = Command::new("kill").args([sig, &child.id().to_string()]).status();
    let deadline = Instant::now() + Duration::from_secs(60);
    while child.try_wait().unwrap().is_none() {
        assert!(Instant::now() < deadline, "pmac-send ignored {sig}");
        std::thread::sleep(Duration::from_millis(10));
    }
    let out = child.wait_with_output().unwrap();
    Outcome {
        code: out.status.code().unwrap_or(-1),
        summary: serde_json::from_str(String::from_utf8_lossy(&out.stdout).trim()).unwrap_or(Value::Null),
        stderr: String::from_utf8_lossy(&out.stderr).to_string(),
    }
}

/// Run with a fault (and/or a signal), then --resume (up to three times)
/// on a healthy link. After every stop the shutter is closed and nothing
/// runs; at the end the beam-on path is covered exactly once. Answers
/// whether the job was stopped at all.
fn scenario(cfg: Config, faults: Faults, scale: f64, mode: &[&str], hit: Hit) -> bool {
    // Only a reset makes the controller forget its counters.
    let allow = if faults.reset_at.is_some() || faults.reset_mid_run_from.is_some() {
        3.0
    } else {
        0.0
    };
    let e = emu(cfg, faults, scale);
    let o = send_hit(&e, mode, hit);
    let killed = matches!(hit, Hit::Signal("-KILL", _));
    let mut stopped = o.code != 0;
    if stopped && !killed {
        assert_eq!(o.code, 1, "{}", o.stderr);
        assert!(o.stderr.contains("--resume"), "{}", o.stderr);
        assert!(o.stderr.contains("shutter closed"), "{}", o.stderr);
    }
    let mut last = o;
    for _ in 0..3 {
        if last.code == 0 {
            break;
        }
        if last.code != -1 {
            let c = e.server.controller.lock().unwrap();
            assert_eq!(c.var(b'M', 33), 0.0, "shutter open after the stop: {}", last.stderr);
            assert!(!c.running(), "program still running after the stop");
        }
        last = send(&e, &[mode, &["--resume"]].concat());
        stopped = true;
    }
    assert_eq!(last.code, 0, "{}", last.stderr);
    let ev = events(&e.log);
    if let Err(msg) = coverage(&[ev], &program(30), allow) {
        panic!("{hit:?}: {msg}");
    }
    assert!(shutter_closed(&e));
    stopped
}

#[test]
fn split_interrupted_mid_move_at_many_points_resumes_exactly() {
    for after in [3, 20, 61, 130, 222] {
        assert!(scenario(
            small(),
            Faults::default(),
            30.0,
            &split_args(),
            Hit::Signal("-INT", after)
        ));
    }
}

#[test]
fn rotary_interrupted_mid_move_at_many_points_resumes_exactly() {
    for after in [4, 35, 99, 170, 230] {
        assert!(scenario(
            Config::default(),
            Faults::default(),
            30.0,
            &rotary_args(),
            Hit::Signal("-INT", after)
        ));
    }
}

#[test]
fn dropped_connection_at_many_points_resumes_exactly() {
    let mut stopped = 0;
    for at in [2, 9, 40, 120, 300] {
        let faults = Faults {
            drop_at: Some(at),
            ..Faults::default()
        };
        stopped += usize::from(scenario(small(), faults.clone(), 30.0, &split_args(), Hit::None));
        stopped += usize::from(scenario(Config::default(), faults, 30.0, &rotary_args(), Hit::None));
    }
    assert!(stopped >= 8, "only {stopped} of 10 drops stopped the job");
}

/// The fault matrix of docs/pmac-send.md: each fault in split and rotary
/// mode, then up to three resumes.
fn matrix(mode: &[&str], cfg: Config) {
    let at = 60;
    let cases: Vec<(&str, Config, Faults, Hit)> = vec![
        (
            "drop",
            cfg.clone(),
            Faults {
                drop_at: Some(at),
                ..Faults::default()
            },
            Hit::None,
        ),
        (
            "ERR006",
            Config {
                err006_at_line: Some(100),
                ..cfg.clone()
            },
            Faults::default(),
            Hit::None,
        ),
        (
            "reset",
            cfg.clone(),
            Faults {
                reset_mid_run_from: Some(at),
                ..Faults::default()
            },
            Hit::None,
        ),
        (
            "slow",
            cfg.clone(),
            Faults {
                delay: Duration::from_millis(2500),
                delay_from: at,
                delay_count: Some(3),
                ..Faults::default()
            },
            Hit::None,
        ),
        (
            "lie",
            cfg.clone(),
            Faults {
                lie_at: Some(at),
                ..Faults::default()
            },
            Hit::None,
        ),
        ("SIGINT", cfg.clone(), Faults::default(), Hit::Signal("-INT", 50)),
        ("SIGTERM", cfg.clone(), Faults::default(), Hit::Signal("-TERM", 80)),
        ("SIGKILL", cfg.clone(), Faults::default(), Hit::Signal("-KILL", 110)),
    ];
    for (name, cfg, faults, hit) in cases {
        eprintln!("{mode:?} {name}");
        assert!(scenario(cfg, faults, 30.0, mode, hit), "{name} did not stop the job");
    }
}

/// A reset at a fixed request lands wherever the client then is: mid-run,
/// or between runs while the next chunk downloads (which loses nothing).
/// Either way the job ends with every move cut once.
#[test]
fn reset_at_any_request_is_safe() {
    for at in [7, 45, 130] {
        let faults = Faults {
            reset_at: Some(at),
            ..Faults::default()
        };
        scenario(small(), faults, 30.0, &split_args(), Hit::None);
    }
}

#[test]
fn fault_matrix_split() {
    matrix(&split_args(), small());
}

#[test]
fn fault_matrix_rotary() {
    matrix(&rotary_args(), Config::default());
}

#[test]
fn lying_counter_is_never_taken_as_progress() {
    let faults = Faults {
        lie_at: Some(60),
        ..Faults::default()
    };
    let e = emu(small(), faults, 30.0);
    let o = send(&e, &split_args());
    assert_eq!(o.code, 1, "{}", o.stderr);
    assert!(o.stderr.contains("bad reply"), "{}", o.stderr);
    let state: Value =
        serde_json::from_str(&std::fs::read_to_string(e.dir.path().join("pmac-send.state.json")).unwrap()).unwrap();
    assert!(state["next_move"].as_u64().unwrap() < 240, "{state}");
}

#[test]
fn resume_refuses_another_program() {
    let e = emu(small(), Faults::default(), 500.0);
    assert_eq!(send(&e, &["--mode", "split"]).code, 0);
    std::fs::write(e.dir.path().join("job.pmac"), program(29)).unwrap();
    let o = send(&e, &["--mode", "split", "--resume"]);
    assert_eq!(o.code, 2);
    assert!(o.stderr.contains("another program"), "{}", o.stderr);
}

#[test]
fn dry_run_writes_chunks_and_plan_without_network() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("job.pmac"), program(30)).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_pmac-send"))
        .args([
            "job.pmac",
            "--dry-run",
            "chunks",
            "--buffer-words",
            "500",
            "--host",
            "127.0.0.1:9",
        ])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let plan: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("chunks/plan.json")).unwrap()).unwrap();
    let chunks = plan["chunks"].as_array().unwrap();
    assert!(chunks.len() >= 3);
    // The chunk files, read back in order, are the program.
    let mut all = Vec::new();
    let mut start = microcam::geometry::P3::origin();
    for c in chunks {
        assert!(c["words"].as_u64().unwrap() <= 500);
        let text = std::fs::read_to_string(dir.path().join("chunks").join(c["file"].as_str().unwrap())).unwrap();
        let opts = ReadOptions {
            start,
            ..ReadOptions::default()
        };
        let (_, recs) = read_str(&text, &opts).unwrap();
        let moves: Vec<Move> = recs
            .iter()
            .filter_map(|r| r.motion().map(|m| (m.to.x, m.to.y, m.to.z, m.beam)))
            .collect();
        assert!(
            !moves.first().unwrap().3 && !moves.last().unwrap().3,
            "chunk cut with the beam on"
        );
        let l = moves.last().unwrap();
        start = microcam::geometry::P3::new(l.0, l.1, l.2);
        all.extend(moves);
    }
    assert!(same(&all, &expected(&program(30))));
}

#[test]
fn split_mode_line_by_line_getresponse_transport() {
    let e = emu(small(), Faults::default(), 500.0);
    let o = send(&e, &["--mode", "split", "--transport", "ethernet-lines"]);
    assert_eq!(o.code, 0, "{}", o.stderr);
    assert!(same(&executed(&events(&e.log)), &expected(&program(30))));
}

#[test]
fn replies_slower_than_the_timeout_still_close_the_shutter() {
    // From request 30 on the controller answers slower than the client
    // waits (--timeout-ms 150): the safety stop keeps trying with its own
    // longer timeout until the controller confirms the shutter closed.
    let faults = Faults {
        delay: Duration::from_millis(400),
        delay_from: 30,
        ..Faults::default()
    };
    let e = emu(small(), faults, 30.0);
    let o = send(&e, &["--mode", "split", "--timeout-ms", "150"]);
    assert_eq!(o.code, 1);
    assert!(o.stderr.contains("no reply within"), "{}", o.stderr);
    assert!(o.stderr.contains("shutter closed"), "{}", o.stderr);
    let c = e.server.controller.lock().unwrap();
    assert_eq!(c.var(b'M', 33), 0.0);
    assert!(!c.running());
}

#[test]
fn bad_flags_and_hosts_are_usage_errors() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("job.pmac"), program(2)).unwrap();
    for args in [
        &["--host", "127.0.0.1:99999"][..],
        &["--host", ""],
        &["--host", ":1025"],
        &["--stall-s", "nan"],
        &["--stall-s", "inf"],
        &["--stall-s", "-1"],
        &["--stop-deadline-s", "1e308"],
        &["--timeout-ms", "0"],
        &["--line-counter-var", "X5"],
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_pmac-send"))
            .arg("job.pmac")
            .args(args)
            .current_dir(dir.path())
            .output()
            .unwrap();
        assert_eq!(
            out.status.code(),
            Some(2),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    for args in [
        &["--duration", "1e308"][..],
        &["--duration", "nan"],
        &["--duration", "-1"],
        &["--time-scale", "inf"],
        &["--time-scale", "0"],
        &["--memory-words", "-5"],
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_pmac-emu"))
            .args(["--port", "0"])
            .args(args)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "pmac-emu {args:?}");
    }
}

#[test]
fn dry_run_into_an_earlier_plan_leaves_no_stale_chunks() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("job.pmac"), program(30)).unwrap();
    let run = |words: &str| {
        let out = Command::new(env!("CARGO_BIN_EXE_pmac-send"))
            .args(["job.pmac", "--dry-run", "chunks", "--buffer-words", words])
            .current_dir(dir.path())
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    };
    run("300");
    let many = std::fs::read_dir(dir.path().join("chunks")).unwrap().count();
    run("3000");
    let plan: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("chunks/plan.json")).unwrap()).unwrap();
    let n = plan["chunks"].as_array().unwrap().len();
    let files = std::fs::read_dir(dir.path().join("chunks")).unwrap().count();
    assert!(many > files, "{many} {files}");
    assert_eq!(files, n + 1);
}

/// The emulator as a process of its own (`pmac-emu`), so it can be killed
/// as a controller loses power: its memory, buffers and counters go.
struct EmuProc {
    child: std::process::Child,
    port: u16,
}

impl Drop for EmuProc {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn emu_proc(dir: &Path, log: &str, port: u16, memory_words: i64) -> EmuProc {
    use std::io::BufRead;
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        let mut child = Command::new(env!("CARGO_BIN_EXE_pmac-emu"))
            .args(["--port", &port.to_string(), "--time-scale", "30", "--log", log])
            .args(["--memory-words", &memory_words.to_string()])
            .current_dir(dir)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let mut line = String::new();
        let _ = std::io::BufReader::new(child.stdout.take().unwrap()).read_line(&mut line);
        if let Ok(p) = line.trim().parse::<u16>() {
            return EmuProc { child, port: p };
        }
        // The old port may still be held for a moment: try again.
        let _ = child.kill();
        let _ = child.wait();
        assert!(Instant::now() < deadline, "pmac-emu would not listen on port {port}");
        std::thread::sleep(Duration::from_millis(100));
    }
}

fn send_to(dir: &Path, port: u16, extra: &[&str]) -> std::process::Child {
    spawn_send(dir, port, extra, Stdio::null())
}

fn finish(child: std::process::Child) -> (i32, String) {
    let deadline = Instant::now() + Duration::from_secs(90);
    let mut child = child;
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("pmac-send did not finish in 90 s");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let out = child.wait_with_output().unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).to_string(),
    )
}

/// SIGKILL of the emulator mid-chunk (the controller loses power): it is
/// restarted empty on the same port, pmac-send stops (its safety stop
/// reaching the restarted controller), and up to three `--resume` runs
/// finish the job. The beam-on path is covered once, except what ran
/// after the last counter pmac-send confirmed (the restart erases the
/// counters, as a reset does: at most 3 mm in all), and the shutter is
/// closed at the end.
fn emulator_killed(mode: &[&str], memory_words: i64, after: usize) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("job.pmac"), program(30)).unwrap();
    let emu = emu_proc(dir.path(), "ev1.jsonl", 0, memory_words);
    let port = emu.port;
    let sender = send_to(dir.path(), port, mode);
    let deadline = Instant::now() + Duration::from_secs(60);
    while events(&dir.path().join("ev1.jsonl"))
        .iter()
        .filter(|v| v["ev"] == "move")
        .count()
        < after
    {
        assert!(Instant::now() < deadline, "no move {after} seen");
        std::thread::sleep(Duration::from_millis(2));
    }
    let _ = Command::new("kill")
        .args(["-KILL", &emu.child.id().to_string()])
        .status();
    drop(emu);
    std::thread::sleep(Duration::from_millis(300));
    let emu2 = emu_proc(dir.path(), "ev2.jsonl", port, memory_words);
    let (code, stderr) = finish(sender);
    assert_eq!(code, 1, "pmac-send after the emulator died: {stderr}");
    assert!(stderr.contains("--resume"), "{stderr}");
    let mut last = (code, stderr);
    for _ in 0..3 {
        if last.0 == 0 {
            break;
        }
        last = finish(send_to(dir.path(), emu2.port, &[mode, &["--resume"]].concat()));
    }
    assert_eq!(last.0, 0, "{}", last.1);
    let logs = [
        events(&dir.path().join("ev1.jsonl")),
        events(&dir.path().join("ev2.jsonl")),
    ];
    if let Err(msg) = coverage(&logs, &program(30), 3.0) {
        panic!("emulator killed after move {after}: {msg}");
    }
    // The restarted controller's shutter, as its log last set it.
    let shutter = logs[1]
        .iter()
        .rfind(|e| e["ev"] == "var" && e["name"] == "M33")
        .map(|e| e["value"].as_f64().unwrap());
    assert_eq!(shutter, Some(0.0), "shutter not closed at the end");
}

#[test]
fn fault_matrix_split_emulator_killed() {
    emulator_killed(&split_args(), small().memory_words, 110);
}

#[test]
fn fault_matrix_rotary_emulator_killed() {
    emulator_killed(&rotary_args(), Config::default().memory_words, 110);
}
