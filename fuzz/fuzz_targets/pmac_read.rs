//! The PMAC readers must never panic, hang or run away: pmac-send's job
//! reader (any dialect, then cut into split chunks and stream chunks, and
//! the moves resume works from), and the emulator's line interpreter fed
//! the same text as a motion program (OPEN PROG, lines, CLOSE, RUN) and as
//! on-line commands, on a manual clock advanced a little per line.
#![no_main]

use libfuzzer_sys::fuzz_target;
use microcam::pmac::controller::{Clock, Config, Emulator, Session};
use microcam::pmac::upload_plan::{Names, UploadPlan};

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    if let Ok(job) = UploadPlan::read(&text, &Names::default()) {
        let _ = job.chunks(Some(2_000));
        let _ = job.stream_chunks(500);
        for m in job.moves().iter().take(1_000) {
            let _ = m.length();
        }
    }
    let mut c = Emulator::new(Config::default(), Clock::Manual(0.0), None);
    let mut s = Session::default();
    let _ = c.command_line(&mut s, "OPEN PROG 1 CLEAR");
    let lines: Vec<&str> = text.split(['\n', '\r']).take(2_000).collect();
    for l in &lines {
        let _ = c.command_line(&mut s, l);
    }
    let _ = c.command_line(&mut s, "CLOSE");
    let _ = c.command_line(&mut s, "&1 B1 R");
    for (i, l) in lines.iter().enumerate() {
        c.set_time(0.01 * (i + 1) as f64);
        let _ = c.command_line(&mut s, l);
    }
    c.set_time(1e3);
    let _ = c.position();
});
