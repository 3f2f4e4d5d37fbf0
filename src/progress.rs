//! Progress of the one long job a tool process runs, and the bar that shows it.
//!
//! The engines (removal, verification, drop-cutter, ploughing, slicing, the
//! feed schedule's simulation, contour and fill planning, the pocket's
//! touching heights) know how much work they have and how much is done, but
//! must not know about terminals. So they only advance two process-wide
//! counters — relaxed atomic adds, cheap enough for every move or row, safe
//! from rayon's threads — and a tool that wants a bar starts a [`Meter`], a
//! thread that reads the counters ten times a second and draws them with
//! `indicatif`.
//!
//! Unix manners: the bar goes to stderr, appears only for work that lasts
//! over about a second, only when stderr is a terminal (never in a pipeline
//! log or a test), never with `--quiet`; `--progress` forces plain progress
//! lines where there is no terminal (a log you tail).

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

static DONE: AtomicU64 = AtomicU64::new(0);
static TOTAL: AtomicU64 = AtomicU64::new(0);
/// What the job is doing now, when it has named its stage (see [`stage`]).
static STAGE: Mutex<Option<&'static str>> = Mutex::new(None);
/// The bar a meter draws now, if any (for [`note`]).
static SHOWN: Mutex<Option<ProgressBar>> = Mutex::new(None);

/// When the environment sets `MICROCAM_TIMING`, print to stderr how long
/// the job spent since the last lap (or since the first call), with the
/// stage's name, and the process's peak resident memory so far: where a
/// tool's wall time and memory go, for tuning, without a profiler. Costs one
/// environment lookup, once, when unset.
pub fn lap(what: &str) {
    use std::sync::OnceLock;
    static ON: OnceLock<bool> = OnceLock::new();
    static LAST: Mutex<Option<(Instant, f64)>> = Mutex::new(None);
    if !*ON.get_or_init(|| std::env::var_os("MICROCAM_TIMING").is_some()) {
        return;
    }
    let (cpu_now, peak_kib) = cpu_seconds_and_peak_kib();
    let now = (Instant::now(), cpu_now);
    let mut last = LAST.lock().unwrap_or_else(|e| e.into_inner());
    let (wall, cpu) = last.map_or((0.0, 0.0), |(t, c)| {
        ((now.0 - t).as_secs_f64() * 1e3, (now.1 - c) * 1e3)
    });
    *last = Some(now);
    let peak_mib = peak_kib as f64 / 1024.0;
    crate::diag!("timing: {what:<24} {wall:8.2} ms wall {cpu:8.2} ms CPU {peak_mib:7.1} MiB peak");
}

/// The process's CPU time so far (user and system, all threads), seconds,
/// and its peak resident memory so far, KiB (Linux's unit for `ru_maxrss`).
fn cpu_seconds_and_peak_kib() -> (f64, i64) {
    // SAFETY: getrusage only writes the struct it is given.
    let mut ru: libc::rusage = unsafe { std::mem::zeroed() };
    if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut ru) } != 0 {
        return (0.0, 0);
    }
    let t = |v: libc::timeval| v.tv_sec as f64 + v.tv_usec as f64 * 1e-6;
    (t(ru.ru_utime) + t(ru.ru_stime), ru.ru_maxrss as i64)
}

/// Start counting a new job of `total` units (0 when not known yet).
pub fn begin(total: u64) {
    DONE.store(0, Ordering::Relaxed);
    TOTAL.store(total, Ordering::Relaxed);
}

/// A job of several stages starts the next one: the counters restart at
/// `total` units (0 when not known) and a meter shows `what` in place of
/// what it was started with. For a job whose stages count different things
/// (chains offset, then paths planned), so no bar mixes units.
pub fn stage(what: &'static str, total: u64) {
    // Under the lock, so a meter never shows one stage's name with the
    // other's counts (see `snapshot`).
    let mut st = STAGE.lock().unwrap_or_else(|e| e.into_inner());
    begin(total);
    *st = Some(what);
}

/// The stage named last since the meter started (if any) and the counters,
/// read together.
fn snapshot() -> (Option<&'static str>, u64, u64) {
    let st = STAGE.lock().unwrap_or_else(|e| e.into_inner());
    let (done, total) = counts();
    (*st, done, total)
}

/// The work done is `done` units (a job that learns its progress as a
/// position, such as a controller's line counter, not as increments).
pub fn set(done: u64) {
    DONE.store(done, Ordering::Relaxed);
}

/// Write `line` on stderr without breaking a bar being drawn: the bar is
/// hidden for the write and drawn again below the line. For a tool that
/// logs as it works (pmac-send); others print after their meter finishes.
pub fn note(line: &str) {
    let bar = SHOWN.lock().unwrap_or_else(|e| e.into_inner()).clone();
    match bar {
        Some(b) => b.suspend(|| crate::diag!("{line}")),
        None => crate::diag!("{line}"),
    }
}

/// More work found (a job whose size is learnt as it goes).
pub fn add_total(n: u64) {
    TOTAL.fetch_add(n, Ordering::Relaxed);
}

/// `n` more units done.
pub fn advance(n: u64) {
    DONE.fetch_add(n, Ordering::Relaxed);
}

/// (done, total) as the counters stand.
pub fn counts() -> (u64, u64) {
    (DONE.load(Ordering::Relaxed), TOTAL.load(Ordering::Relaxed))
}

/// When a meter shows itself.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Show {
    /// A bar when stderr is a terminal, nothing otherwise (the default).
    Auto,
    /// Never (`--quiet`).
    Never,
    /// A bar on a terminal, plain lines otherwise (`--progress`).
    Always,
}

impl Show {
    /// The choice of a tool's `--quiet` and (where it has one) `--progress`.
    pub fn from_flags(quiet: bool, progress: bool) -> Show {
        match (quiet, progress) {
            (true, _) => Show::Never,
            (false, true) => Show::Always,
            (false, false) => Show::Auto,
        }
    }
}

/// Work shorter than this shows nothing.
const DELAY: Duration = Duration::from_millis(1000);
/// How often the bar is redrawn.
const TICK: Duration = Duration::from_millis(100);
/// How often a plain progress line is written.
const PLAIN_EVERY: Duration = Duration::from_secs(2);

/// A progress display of the counters on stderr, for as long as it lives.
pub struct Meter {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Meter {
    /// Show `tool: what` with the counters' progress (see [`Show`]). The
    /// counters are reset to `total` units (0 when not known yet).
    pub fn start(tool: &'static str, what: &'static str, total: u64, show: Show) -> Meter {
        {
            let mut st = STAGE.lock().unwrap_or_else(|e| e.into_inner());
            begin(total);
            *st = None;
        }
        let stop = Arc::new(AtomicBool::new(false));
        let terminal = std::io::stderr().is_terminal();
        let thread = match show {
            Show::Never => None,
            Show::Auto if !terminal => None,
            _ => {
                let stop = Arc::clone(&stop);
                std::thread::Builder::new()
                    .name("progress".into())
                    .spawn(move || run(tool, what, terminal, &stop))
                    .ok()
            }
        };
        Meter { stop, thread }
    }

    /// Stop and clear the display (also done on drop).
    pub fn finish(mut self) {
        self.halt();
    }

    fn halt(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for Meter {
    fn drop(&mut self) {
        self.halt();
    }
}

/// Sleep up to `d`, waking early when stopped; false when stopped.
fn wait(d: Duration, stop: &AtomicBool) -> bool {
    let end = Instant::now() + d;
    while Instant::now() < end {
        if stop.load(Ordering::Relaxed) {
            return false;
        }
        std::thread::sleep(Duration::from_millis(20).min(end - Instant::now()));
    }
    !stop.load(Ordering::Relaxed)
}

fn run(tool: &'static str, what: &'static str, terminal: bool, stop: &AtomicBool) {
    let started = Instant::now();
    if !wait(DELAY, stop) {
        return;
    }
    if !terminal {
        loop {
            let (stage, done, total) = snapshot();
            let what = stage.unwrap_or(what);
            crate::diag!("{}", plain_line(tool, what, done, total, started.elapsed()));
            if !wait(PLAIN_EVERY, stop) {
                return;
            }
        }
    }
    let style =
        |template: &str| ProgressStyle::with_template(template).unwrap_or_else(|_| ProgressStyle::default_bar());
    let known = style("{prefix}: {msg} [{wide_bar}] {percent:>3}% {human_pos}/{human_len} ({elapsed}, eta {eta})")
        .progress_chars("=> ");
    let unknown = style("{prefix}: {msg} {spinner} {human_pos} ({elapsed})");
    // A new stage (another name, or a total where there was none) gets a
    // new bar, built hidden and shown whole: setting name, style and counts
    // one by one on a visible bar draws frames that mix two stages.
    let fresh = |msg: &'static str, done: u64, total: u64| {
        let bar = ProgressBar::with_draw_target((total > 0).then_some(total), ProgressDrawTarget::hidden())
            .with_style(if total > 0 { known.clone() } else { unknown.clone() })
            .with_prefix(tool.to_string())
            .with_message(msg)
            .with_position(done)
            .with_elapsed(started.elapsed());
        bar.set_draw_target(ProgressDrawTarget::stderr());
        bar
    };
    let show = |bar: Option<&ProgressBar>| *SHOWN.lock().unwrap_or_else(|e| e.into_inner()) = bar.cloned();
    let (stage, done, total) = snapshot();
    let mut shown = (stage.unwrap_or(what), total > 0);
    let mut bar = fresh(shown.0, done, total);
    show(Some(&bar));
    loop {
        let (stage, done, total) = snapshot();
        let now = (stage.unwrap_or(what), total > 0);
        if now != shown {
            bar.finish_and_clear();
            bar = fresh(now.0, done, total);
            show(Some(&bar));
            shown = now;
        }
        if total > 0 {
            bar.set_length(total);
        }
        bar.set_position(if total > 0 { done.min(total) } else { done });
        if !wait(TICK, stop) {
            break;
        }
    }
    show(None);
    bar.finish_and_clear();
}

/// One plain progress line, for logs: `gsim: simulating 1,234 of 5,000 (24 %), 3 s`.
pub fn plain_line(tool: &str, what: &str, done: u64, total: u64, elapsed: Duration) -> String {
    let secs = elapsed.as_secs();
    if total > 0 {
        let pct = (100.0 * done.min(total) as f64 / total as f64).floor();
        format!(
            "{tool}: {what} {} of {} ({pct:.0} %), {secs} s",
            grouped(done),
            grouped(total)
        )
    } else {
        format!("{tool}: {what} {}, {secs} s", grouped(done))
    }
}

/// 1234567 as "1,234,567".
fn grouped(n: u64) -> String {
    let s = n.to_string();
    let mut out = String::with_capacity(s.len() + s.len() / 3);
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plain_lines_say_what_how_far_and_how_long() {
        let l = plain_line("gsim", "simulating", 1234, 5000, Duration::from_secs(3));
        assert_eq!(l, "gsim: simulating 1,234 of 5,000 (24 %), 3 s");
        let l = plain_line("stlverify", "moves", 7, 0, Duration::from_millis(2500));
        assert_eq!(l, "stlverify: moves 7, 2 s");
        // Done past the total (a job that found more work late) caps at 100 %.
        assert!(plain_line("t", "w", 12, 10, Duration::ZERO).contains("(100 %)"));
    }

    #[test]
    fn thousands_are_grouped() {
        assert_eq!(grouped(0), "0");
        assert_eq!(grouped(999), "999");
        assert_eq!(grouped(1000), "1,000");
        assert_eq!(grouped(1_234_567), "1,234,567");
    }

    #[test]
    fn flags_choose_the_display() {
        assert_eq!(Show::from_flags(true, true), Show::Never);
        assert_eq!(Show::from_flags(false, true), Show::Always);
        assert_eq!(Show::from_flags(false, false), Show::Auto);
    }

    #[test]
    fn a_short_job_shows_nothing_and_the_meter_stops_at_once() {
        // Always: would print plain lines after DELAY; finishing first
        // must stop the thread before it writes anything.
        let t = Instant::now();
        let m = Meter::start("test", "nothing", 10, Show::Always);
        advance(3);
        m.finish();
        assert!(t.elapsed() < DELAY, "finish waits for the delay: {:?}", t.elapsed());
    }
}
