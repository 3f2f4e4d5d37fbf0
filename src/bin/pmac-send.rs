//! pmac-send: upload a program to a Turbo PMAC and run it, whole, in
//! chunks cut where the beam is off, or streamed through a rotary buffer.

// Diagnostics go through `microcam::diag!` and data through the
// library's writers: `eprintln!`/`println!` panic when stderr or stdout
// is a closed pipe.
#![deny(clippy::print_stderr, clippy::print_stdout)]

use clap::{Parser, ValueEnum};
use microcam::cli::{self, CliError};
use microcam::pmac::client::{Client, Transport};
use microcam::pmac::send::{
    BUFFER_FILL, Mode, SendError, SendOptions, SendSummary, Sender, State, dry_run_budget, input_hash,
    is_stale_plan_file, split_budget,
};
use microcam::pmac::upload_plan::{Names, UploadPlan};
use microcam::progress::{self, Meter, Show};
use std::io::Write;
use std::net::ToSocketAddrs;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

const EXAMPLES: &str = "\
Examples:
  pmac-send part.pmac --host 10.0.0.5              split into chunks that fit, run each
  pathgen emit --dialect pmac tp.jsonl | pmac-send --mode rotary --host 10.0.0.5
  pmac-send part.ngc --mode program --host 127.0.0.1:1025
  pmac-send part.pmac --dry-run chunks/ --buffer-words 5000
  pmac-send part.pmac --resume                      after a stop: go on from the
                                                    last chunk confirmed complete

Input is PMAC motion-program text or ISO G-code ('-' or no FILE: stdin); it is
read by the project's interpreter and rewritten as PMAC text (ABS, M33==1 shutter
switching, P400 line counter running on across chunks). Progress goes to stderr,
a JSON summary to stdout.

Safety: on Ctrl-C, SIGTERM, an ERR reply, a timeout or a lost connection the
shutter is closed (M33=0) and &1 aborted (reconnecting if needed), the resume
state is written (--state), and the exit status is 1. The stop keeps trying,
reconnecting, for --stop-deadline-s until the controller confirms the program
aborted and the shutter closed; it then reads the motor positions and the line
counter (M7400==n, synchronous, pointed at P400) and saves the move the stage
stopped in and where along it. --resume first does the same (the controller's
word before the state file), then goes there with the beam off and continues
from that point: no beam-on path twice, none skipped.
Exit status: 0 done, 1 stopped or failed, 2 bad usage or bad input.";

#[derive(Clone, Copy, ValueEnum)]
enum ModeArg {
    Program,
    Split,
    Rotary,
}

#[derive(Clone, Copy, ValueEnum)]
enum TransportArg {
    /// Turbo PMAC Ethernet protocol, WRITEBUFFER downloads.
    Ethernet,
    /// Ethernet protocol, one GETRESPONSE per line (slow; for old firmware).
    EthernetLines,
    /// Plain text lines over TCP.
    Line,
}

/// Upload, run and watch a motion program on a Turbo PMAC.
#[derive(Parser)]
#[command(name = "pmac-send", version, about, after_help = EXAMPLES)]
struct Args {
    /// Program to send ('-' for stdin).
    file: Option<PathBuf>,
    /// Controller address, HOST or HOST:PORT (port 1025 by default).
    #[arg(long, default_value = "127.0.0.1")]
    host: String,
    /// How to get the job onto the controller.
    #[arg(long, value_enum, default_value = "split")]
    mode: ModeArg,
    #[arg(long, value_enum, default_value = "ethernet")]
    transport: TransportArg,
    /// Program buffer number (program and split modes).
    #[arg(long = "program", alias = "prog", value_name = "PROGRAM", default_value_t = 1)]
    prog: u32,
    /// Most words a chunk may take (default: 90% of SIZE after clearing).
    #[arg(long)]
    buffer_words: Option<usize>,
    /// Rotary buffer size, words.
    #[arg(long, default_value_t = 4096)]
    rotary_words: usize,
    /// Rotary mode: words per chunk (the unit of resume); default a quarter
    /// of the rotary buffer.
    #[arg(long)]
    chunk_words: Option<usize>,
    /// Write the chunks and plan.json here; no network.
    #[arg(long, value_name = "DIR")]
    dry_run: Option<PathBuf>,
    /// Continue a stopped job from its state file.
    #[arg(long)]
    resume: bool,
    /// Resume state file.
    #[arg(long, default_value = "pmac-send.state.json")]
    state: PathBuf,
    /// Status poll interval, ms.
    #[arg(long, default_value_t = 50)]
    poll_ms: u64,
    /// Reply timeout, ms.
    #[arg(long, default_value_t = 5000)]
    timeout_ms: u64,
    /// Give up when the controller shows no progress for this many seconds.
    #[arg(long, default_value_t = 60.0)]
    stall_s: f64,
    /// How long a safety stop keeps trying to confirm the shutter closed, s.
    #[arg(long, default_value_t = 120.0)]
    stop_deadline_s: f64,
    /// Program mode only: store the program but do not run it.
    #[arg(long)]
    upload_only: bool,
    #[arg(long, default_value = "M33")]
    shutter_var: String,
    #[arg(
        long = "line-counter-var",
        alias = "line-counter",
        value_name = "LINE_COUNTER_VAR",
        default_value = "P400"
    )]
    line_counter: String,
    /// Variable set to the chunk number after a chunk's last motion
    /// (behind DWELL0); confirms chunks even across an abort.
    #[arg(long, default_value = "P401")]
    done_var: String,
    /// M-variable pointed at the line counter's P register and assigned
    /// synchronously, so the counter follows motion.
    #[arg(long, default_value = "M7400")]
    counter_mvar: String,
    /// Variable holding the job's session number.
    #[arg(long, default_value = "P402")]
    session_var: String,
    /// No progress bar on stderr (the log lines, warnings and errors still
    /// appear).
    #[arg(short, long)]
    quiet: bool,
}

/// Lines the sender logs, passed to stderr through `progress::note`, so a
/// bar drawn on the terminal stays whole below them.
struct Notes(Vec<u8>);

impl Write for Notes {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.extend_from_slice(buf);
        while let Some(i) = self.0.iter().position(|&b| b == b'\n') {
            let line: Vec<u8> = self.0.drain(..=i).collect();
            progress::note(&String::from_utf8_lossy(&line[..i]));
        }
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        if !self.0.is_empty() {
            progress::note(&String::from_utf8_lossy(&std::mem::take(&mut self.0)));
        }
        Ok(())
    }
}

/// Check the numeric flags and the host before anything else: bad usage is
/// exit 2.
fn check_args(args: &Args) -> Result<String, CliError> {
    for (name, v) in [("--stall-s", args.stall_s), ("--stop-deadline-s", args.stop_deadline_s)] {
        if !(v.is_finite() && v > 0.0 && v <= 1e6) {
            return Err(CliError::input(format!(
                "{name} must be a positive number of seconds up to 1e6, not {v}"
            )));
        }
    }
    for (name, v) in [("--timeout-ms", args.timeout_ms), ("--poll-ms", args.poll_ms)] {
        if v == 0 || v > 3_600_000 {
            return Err(CliError::input(format!("{name} must be 1..3600000, not {v}")));
        }
    }
    if args.rotary_words < 64 || args.rotary_words > 1 << 24 {
        return Err(CliError::input(format!(
            "--rotary-words must be 64..16777216, not {}",
            args.rotary_words
        )));
    }
    for (flag, v, letter) in [
        ("--shutter-var", &args.shutter_var, None),
        ("--line-counter-var", &args.line_counter, Some('P')),
        ("--done-var", &args.done_var, None),
        ("--counter-mvar", &args.counter_mvar, Some('M')),
        ("--session-var", &args.session_var, None),
    ] {
        let u = v.to_ascii_uppercase();
        let ok = u.len() > 1
            && matches!(u.as_bytes()[0], b'P' | b'M' | b'Q' | b'I')
            && letter.is_none_or(|l| u.starts_with(l))
            && u[1..].parse::<u32>().is_ok_and(|n| n < 8192);
        if !ok {
            return Err(CliError::input(format!(
                "{flag} '{v}' is not a variable (P0..P8191 and the like)"
            )));
        }
    }
    let host = args.host.trim();
    let host = if host.contains(':') {
        host.to_string()
    } else {
        format!("{host}:1025")
    };
    let (name, port) = host.rsplit_once(':').unwrap_or((&host, ""));
    if name.is_empty() || port.parse::<u16>().map_or(true, |p| p == 0) {
        return Err(CliError::input(format!(
            "--host '{}' is not HOST or HOST:PORT (port 1..65535)",
            args.host
        )));
    }
    if args.dry_run.is_none() && host.to_socket_addrs().map_or(true, |mut a| a.next().is_none()) {
        return Err(CliError::input(format!("--host '{}': no such host", args.host)));
    }
    Ok(host)
}

fn main() -> ExitCode {
    let args = microcam::cli::parse::<Args>();
    cli::run("pmac-send", || run(args))
}

fn run(args: Args) -> Result<(), CliError> {
    let host = check_args(&args)?;
    let mut input = cli::open_input(args.file.as_deref())?;
    let text = cli::read_to_string(&mut input)?;
    let names = Names {
        shutter: args.shutter_var.to_ascii_uppercase(),
        counter: args.line_counter.to_ascii_uppercase(),
        done: args.done_var.to_ascii_uppercase(),
        counter_m: args.counter_mvar.to_ascii_uppercase(),
        session: args.session_var.to_ascii_uppercase(),
    };
    let job = UploadPlan::read(&text, &names).map_err(|e| CliError::in_file(&input.name, e))?;
    let mode = match args.mode {
        ModeArg::Program => Mode::Program,
        ModeArg::Split => Mode::Split,
        ModeArg::Rotary => Mode::Rotary,
    };
    if args.upload_only && mode != Mode::Program {
        return Err(CliError::input("--upload-only needs --mode program"));
    }
    let chunk_words = args.chunk_words.unwrap_or(args.rotary_words / 4).max(16);
    if let Some(dir) = &args.dry_run {
        let budget = dry_run_budget(mode, args.buffer_words, chunk_words).map_err(CliError::input)?;
        return dry_run(
            &job,
            &input.name,
            mode,
            budget,
            args.prog,
            &args.done_var.to_ascii_uppercase(),
            dir,
        );
    }
    let hash = input_hash(&text);
    let transport = match args.transport {
        TransportArg::Ethernet => Transport::Ethernet,
        TransportArg::EthernetLines => Transport::EthernetLines,
        TransportArg::Line => Transport::Line,
    };
    let timeout = Duration::from_millis(args.timeout_ms);
    let moves = job.moves();
    let mut state = if args.resume {
        let s = State::load(&args.state).map_err(|e| CliError::input(e.to_string()))?;
        s.check_resume(&hash, mode, &args.state)
            .map_err(|e| CliError::input(e.to_string()))?;
        s
    } else {
        State::new(hash, mode, moves.len() as u64)
    };
    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        // Ctrl-C and SIGTERM ask the run loop to stop; it then closes the
        // shutter and aborts before exiting.
        ctrlc::set_handler(move || stop.store(true, Ordering::SeqCst))
            .map_err(|e| CliError::failure(format!("cannot install the signal handler: {e}")))?;
    }
    // Written before the controller is touched, so a stop at any point
    // leaves a state to resume from.
    state.save(&args.state).map_err(|e| CliError::failure(e.to_string()))?;
    let client = Client::connect(&host, transport, timeout).map_err(|e| CliError::failure(e.to_string()))?;
    let opts = SendOptions {
        mode,
        prog: args.prog,
        rotary_words: args.rotary_words,
        rotary_fill: BUFFER_FILL,
        poll: Duration::from_millis(args.poll_ms),
        stall: Duration::from_secs_f64(args.stall_s.max(0.1)),
        stop_deadline: Duration::from_secs_f64(args.stop_deadline_s),
        stop_timeout: (timeout * 4).max(Duration::from_secs(2)),
        names,
        state_path: args.state.clone(),
        upload_only: args.upload_only,
    };
    let mut notes = Notes(Vec::new());
    let mut sender = Sender::new(client, &host, opts, stop, &mut notes, moves);
    if args.resume {
        // The controller's word first: after a hard kill of an earlier
        // session it may have run on past what the state file says.
        sender
            .recover(&mut state, false)
            .map_err(|e| CliError::failure(format!("SAFETY: {e}; not resuming (state in {})", args.state.display())))?;
    }
    // The budget: from the state on resume (the same cut), else measured.
    let budget = match (mode, state.budget) {
        (Mode::Program, _) => None,
        (_, Some(b)) => Some(b),
        (Mode::Split, None) => {
            let free = sender.free_words().map_err(|e| stopped(&mut sender, e, &args))?;
            Some(split_budget(free, args.buffer_words))
        }
        (Mode::Rotary, None) => Some(chunk_words),
    };
    state.budget = budget;
    if state.next_move > state.moves {
        microcam::diag!("pmac-send: nothing to resume: all {} moves have executed", state.moves);
        cli::print_line(&SendSummary::finished(&state).to_json(true).to_string())?;
        return Ok(());
    }
    let rest = job.rest(state.next_move, state.resume_point()).ok_or_else(|| {
        CliError::failure(format!(
            "{}: no move {} in the job",
            args.state.display(),
            state.next_move
        ))
    })?;
    let chunks = rest
        .job
        .cut_from(budget, mode != Mode::Rotary, rest.start, rest.ta, rest.counter0)
        .map_err(|e| CliError::in_file(&input.name, e))?;
    if mode == Mode::Program {
        let free = sender.free_words().map_err(|e| stopped(&mut sender, e, &args))?;
        if chunks[0].words as i64 > free {
            return Err(CliError::failure(format!(
                "the program needs {} words, the controller has {free} free: use --mode split or rotary",
                chunks[0].words
            )));
        }
    }
    microcam::diag!(
        "pmac-send: {} mode, {} chunk(s), {} lines, starting at move {} of {}{}",
        mode.name(),
        chunks.len(),
        chunks.iter().map(|c| c.lines.len()).sum::<usize>(),
        state.next_move,
        state.moves,
        if state.resume_at.is_some() {
            " (part way along)"
        } else {
            ""
        }
    );
    // On a terminal, a bar of the moves the controller confirms executed
    // (its line counter), below the log lines.
    let meter = Meter::start(
        "pmac-send",
        "moves executed",
        state.moves,
        Show::from_flags(args.quiet, false),
    );
    progress::set(state.next_move.saturating_sub(1));
    let ran = sender.run(&chunks, &mut state);
    meter.finish();
    match ran {
        Ok(summary) => {
            cli::print_line(&summary.to_json(true).to_string())?;
            Ok(())
        }
        Err(f) => {
            // Stdout gone or not, the safety message below must follow.
            let _ = cli::print_line(&f.to_json().to_string());
            let safety = match &f.safe_stop {
                Ok(()) => format!(
                    "shutter closed ({}=0) and &1 aborted",
                    args.shutter_var.to_ascii_uppercase()
                ),
                Err(e) => format!("SAFETY: {e}"),
            };
            Err(CliError::failure(format!(
                "stopped: {}; {safety}; {} of {} moves executed{}; continue with --resume (state in {})",
                f.error,
                f.state.next_move - 1,
                f.state.moves,
                if f.state.resume_at.is_some() {
                    " and part of the next"
                } else {
                    ""
                },
                args.state.display()
            )))
        }
    }
}

/// A failure before the first chunk: stop safely all the same.
fn stopped(sender: &mut Sender, e: SendError, args: &Args) -> CliError {
    let mut state = match State::load(&args.state) {
        Ok(s) => s,
        Err(err) => return CliError::failure(format!("stopped: {e}; {err}")),
    };
    let safety = match sender.recover(&mut state, e.is_link()) {
        Ok(()) => format!(
            "shutter closed ({}=0) and &1 aborted",
            args.shutter_var.to_ascii_uppercase()
        ),
        Err(s) => format!("SAFETY: {s}"),
    };
    CliError::failure(format!(
        "stopped: {e}; {safety}; no chunk run; continue with --resume (state in {})",
        args.state.display()
    ))
}

fn dry_run(
    job: &UploadPlan,
    input: &str,
    mode: Mode,
    budget: Option<usize>,
    prog: u32,
    done: &str,
    dir: &Path,
) -> Result<(), CliError> {
    let (files, plan) =
        microcam::pmac::send::dry_run(job, mode, budget, prog, done).map_err(|e| CliError::in_file(input, e))?;
    std::fs::create_dir_all(dir).map_err(|e| CliError::failure(format!("{}: {e}", dir.display())))?;
    for f in &files {
        let mut out = cli::Output::new(Some(&dir.join(&f.name)));
        out.write_all(f.text.as_bytes())?;
        out.commit()?;
    }
    let mut out = cli::Output::new(Some(&dir.join("plan.json")));
    writeln!(out, "{}", serde_json::to_string_pretty(&plan).unwrap_or_default())?;
    out.commit()?;
    // Chunk files of an earlier, longer plan are not part of this one.
    let stale: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| CliError::failure(format!("{}: {e}", dir.display())))?
        .filter_map(|e| e.ok())
        .map(|e| e.path())
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| is_stale_plan_file(n, files.len()))
        })
        .collect();
    for p in stale {
        std::fs::remove_file(&p).map_err(|e| CliError::failure(format!("{}: {e}", p.display())))?;
    }
    cli::print_line(&serde_json::json!({"dry_run": dir.display().to_string(), "chunks": files.len()}).to_string())?;
    Ok(())
}
