//! End to end: pmac-send (the binary) against the emulator (in-process, on
//! 127.0.0.1:0), checked through the emulator's event log: the moves the
//! stage executed and the shutter state during each must equal the
//! program's, with no line lost or run twice, in every mode and after
//! faults and --resume.

use microcam::gcode::{ReadOptions, read_str};
use microcam::model::toolpath::Record;
use microcam::pmac::controller::{Clock, Config, Controller};
use microcam::pmac::server::{Faults, Server};
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
    let ctl = Controller::new(cfg, Clock::scaled(scale), Some(Box::new(f)));
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

fn send(e: &Emu, extra: &[&str]) -> Outcome {
    let port = e.server.addr().port().to_string();
    let host = format!("127.0.0.1:{port}");
    let mut args = vec!["job.pmac", "--host", &host, "--poll-ms", "5", "--stall-s", "10"];
    if !extra.contains(&"--timeout-ms") {
        args.extend_from_slice(&["--timeout-ms", "2000"]);
    }
    args.extend_from_slice(extra);
    let mut child = Command::new(env!("CARGO_BIN_EXE_pmac-send"))
        .args(&args)
        .current_dir(e.dir.path())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
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

/// The moves that count: all of each finished run; of an aborted run only
/// those before its counter passed `confirmed` (the last line the client
/// confirmed; the rest is redone after resume); minus the beam-off
/// reposition that starts a resumed session (first move of run `reposition_run`).
fn executed(ev: &[Value], confirmed: u64, reposition_run: Option<u64>) -> Vec<Move> {
    // Per run: id, (move, counter when it started), finished.
    type Run = (u64, Vec<(Move, u64)>, bool);
    let mut runs: Vec<Run> = Vec::new();
    let mut counter = 0u64;
    for e in ev {
        match e["ev"].as_str().unwrap() {
            "run" => runs.push((e["run"].as_u64().unwrap(), Vec::new(), false)),
            "move" => {
                let r = runs.last_mut().unwrap();
                r.1.push((mv(e), counter));
            }
            "var" if e["name"] == "P400" => counter = e["value"].as_f64().unwrap() as u64,
            "done" => runs.last_mut().unwrap().2 = true,
            _ => {}
        }
    }
    let mut out = Vec::new();
    for (id, moves, done) in runs {
        let skip = usize::from(Some(id) == reposition_run);
        for (m, c) in moves.into_iter().skip(skip) {
            // A move logged while the counter showed c is line c+1.
            if done || c < confirmed {
                out.push(m);
            }
        }
    }
    out
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
    assert!(same(&executed(&ev, 0, None), &want));
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
    assert!(same(&executed(&ev, 0, None), &want));
    // F120 mm/min in ISO is F2 mm/s on the controller.
    assert!(ev.iter().any(|v| v["ev"] == "move" && v["feed"] == 2.0));
}

#[test]
fn program_mode_over_plain_line_transport() {
    let e = emu(Config::default(), Faults::default(), 500.0);
    let o = send(&e, &["--mode", "program", "--transport", "line"]);
    assert_eq!(o.code, 0, "{}", o.stderr);
    assert!(same(&executed(&events(&e.log), 0, None), &expected(&program(30))));
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
    assert!(same(&executed(&ev, 0, None), &expected(&program(30))));
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
    // must keep it fed while the stage runs.
    let e = emu(Config::default(), Faults::default(), 50.0);
    let o = send(
        &e,
        &["--mode", "rotary", "--rotary-words", "700", "--chunk-words", "150"],
    );
    assert_eq!(o.code, 0, "{}", o.stderr);
    let ev = events(&e.log);
    assert!(same(&executed(&ev, 0, None), &expected(&program(30))));
    assert_eq!(
        counters_in_order(&ev),
        (1..=expected(&program(30)).len() as u64).collect::<Vec<_>>()
    );
    let idle: Vec<&Value> = ev.iter().filter(|v| v["ev"] == "idle").collect();
    assert!(idle.is_empty(), "stage idled: {idle:?}");
    assert_eq!(ev.iter().filter(|v| v["ev"] == "run").count(), 1);
    assert!(shutter_closed(&e));
}

/// Run with a fault, then --resume on a healthy link; the result must be
/// one clean run. Answers whether the fault stopped the job.
fn fault_then_resume(cfg: Config, faults: Faults, scale: f64, mode: &[&str]) -> bool {
    let e = emu(cfg, faults, scale);
    let o = send(&e, mode);
    let ev1 = events(&e.log);
    let state: Value =
        serde_json::from_str(&std::fs::read_to_string(e.dir.path().join("pmac-send.state.json")).unwrap()).unwrap();
    if o.code == 0 {
        // The fault hit after the last confirmation (e.g. in the final
        // clean-up): nothing to resume, and the log must already be whole.
        assert!(same(&executed(&ev1, 0, None), &expected(&program(30))));
        eprintln!("fault did not stop the job: {}", o.stderr);
        return false;
    }
    assert_eq!(o.code, 1);
    assert!(o.stderr.contains("--resume"), "{}", o.stderr);
    assert!(o.stderr.contains("shutter closed"), "{}", o.stderr);
    assert!(shutter_closed(&e), "shutter open after the stop");
    let confirmed = state["last_counter"].as_u64().unwrap();
    let last_run = ev1.iter().filter(|v| v["ev"] == "run").count() as u64;
    let o2 = send(&e, &[mode, &["--resume"]].concat());
    assert_eq!(o2.code, 0, "{}", o2.stderr);
    let repo = o2.summary["repositioned"].as_bool().unwrap().then_some(last_run + 1);
    let ev = events(&e.log);
    let got = executed(&ev, confirmed, repo);
    let want = expected(&program(30));
    assert!(
        same(&got, &want),
        "executed {} moves, want {}; stderr {}",
        got.len(),
        want.len(),
        o.stderr
    );
    assert!(shutter_closed(&e));
    // No run finished twice over the same lines.
    let done = ev.iter().filter(|v| v["ev"] == "done").count();
    if mode.contains(&"split") {
        assert_eq!(done as u64, o2.summary["chunks"].as_u64().unwrap());
    }
    true
}

#[test]
fn split_dropped_connection_at_many_points_resumes_to_one_clean_run() {
    // A clean run's request count sets where the drops fall.
    let e = emu(small(), Faults::default(), 500.0);
    let o = send(&e, &["--mode", "split"]);
    let total = o.summary["requests"].as_u64().unwrap();
    assert!(total > 20);
    drop(e);
    let mut stopped = 0;
    for at in [2, 5, 9, total / 4, total / 2, 3 * total / 4, total - 2] {
        let faults = Faults {
            drop_at: Some(at),
            ..Faults::default()
        };
        stopped += usize::from(fault_then_resume(small(), faults, 500.0, &["--mode", "split"]));
    }
    assert!(stopped >= 6, "only {stopped} of 7 drops stopped the job");
}

#[test]
fn rotary_dropped_connection_resumes_to_one_clean_run() {
    for at in [12, 25, 40] {
        let faults = Faults {
            drop_at: Some(at),
            ..Faults::default()
        };
        assert!(fault_then_resume(
            Config::default(),
            faults,
            50.0,
            &["--mode", "rotary", "--rotary-words", "700", "--chunk-words", "150"],
        ));
    }
}

#[test]
fn err006_during_download_stops_safely_and_resumes() {
    for line in [3, 60, 150] {
        let cfg = Config {
            err006_at_line: Some(line),
            ..small()
        };
        assert!(
            fault_then_resume(cfg, Faults::default(), 500.0, &["--mode", "split"]),
            "ERR006 at line {line}"
        );
    }
}

#[test]
fn controller_reset_mid_job_is_detected_and_resumed() {
    // A reset between chunks is harmless (the next chunk is uploaded
    // whole); one during a run or an upload must stop the job. Time runs
    // slowly enough here that most requests are polls of a running chunk.
    let mut stopped = 0;
    for at in [15, 30, 45, 60] {
        let faults = Faults {
            reset_at: Some(at),
            ..Faults::default()
        };
        stopped += usize::from(fault_then_resume(small(), faults, 100.0, &["--mode", "split"]));
    }
    assert!(stopped >= 2, "only {stopped} of 4 resets stopped the job");
}

#[test]
fn delayed_replies_still_run_clean() {
    let faults = Faults {
        delay: Duration::from_millis(3),
        ..Faults::default()
    };
    let e = emu(small(), faults, 200.0);
    let o = send(&e, &["--mode", "split"]);
    assert_eq!(o.code, 0, "{}", o.stderr);
    assert!(same(&executed(&events(&e.log), 0, None), &expected(&program(30))));
}

#[test]
fn sigterm_closes_shutter_and_resume_finishes() {
    // Slow time so the job is still running when the signal comes.
    let e = emu(small(), Faults::default(), 20.0);
    let port = e.server.addr().port().to_string();
    let host = format!("127.0.0.1:{port}");
    let mut child = Command::new(env!("CARGO_BIN_EXE_pmac-send"))
        .args(["job.pmac", "--host", &host, "--mode", "split", "--poll-ms", "5"])
        .current_dir(e.dir.path())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(20);
    // Wait until the beam has been on at least once, then stop.
    loop {
        assert!(Instant::now() < deadline, "no move seen");
        if events(&e.log).iter().any(|v| v["ev"] == "move" && v["beam"] == true) {
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let killed = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let deadline = Instant::now() + Duration::from_secs(20);
    while child.try_wait().unwrap().is_none() {
        assert!(Instant::now() < deadline, "pmac-send ignored SIGTERM");
        std::thread::sleep(Duration::from_millis(10));
    }
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("interrupted"), "{stderr}");
    assert!(shutter_closed(&e));
    let ev1 = events(&e.log);
    assert!(ev1.iter().any(|v| v["ev"] == "abort"));
    let state: Value =
        serde_json::from_str(&std::fs::read_to_string(e.dir.path().join("pmac-send.state.json")).unwrap()).unwrap();
    let last_run = ev1.iter().filter(|v| v["ev"] == "run").count() as u64;
    let o2 = send(&e, &["--mode", "split", "--resume"]);
    assert_eq!(o2.code, 0, "{}", o2.stderr);
    let repo = o2.summary["repositioned"].as_bool().unwrap().then_some(last_run + 1);
    let got = executed(&events(&e.log), state["last_counter"].as_u64().unwrap(), repo);
    assert!(same(&got, &expected(&program(30))));
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
    assert!(same(&executed(&events(&e.log), 0, None), &expected(&program(30))));
}

#[test]
fn replies_slower_than_the_timeout_stop_with_a_clear_message() {
    // The controller answers normally, then (from request 30, mid-job)
    // slower than the client waits.
    let faults = Faults {
        delay: Duration::from_millis(400),
        delay_from: 30,
        ..Faults::default()
    };
    let e = emu(small(), faults, 500.0);
    let o = send(&e, &["--mode", "split", "--timeout-ms", "150"]);
    assert_eq!(o.code, 1);
    assert!(o.stderr.contains("no reply within"), "{}", o.stderr);
    // Nothing answers in time, so neither can the safety stop: the message
    // must say so rather than claim the shutter is closed.
    assert!(
        o.stderr.contains("SAFETY: could not reach the controller"),
        "{}",
        o.stderr
    );
    assert!(!o.stderr.contains("shutter closed"), "{}", o.stderr);
}
