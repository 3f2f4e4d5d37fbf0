//! pmac-emu: a Turbo PMAC emulator on loopback, for running and testing
//! pmac-send (and any other client) with no hardware.

// Diagnostics go through `microcam::diag!` and data through the
// library's writers: `eprintln!`/`println!` panic when stderr or stdout
// is a closed pipe.
#![deny(clippy::print_stderr, clippy::print_stdout)]

use clap::Parser;
use microcam::cli::{self, CliError};
use microcam::pmac::controller::{Clock, Config, Emulator};
use microcam::pmac::server::{Faults, Server};
use std::io::Write;
use std::net::{IpAddr, SocketAddr};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

const EXAMPLES: &str = "\
Examples:
  pmac-emu                                   listen on 127.0.0.1:1025
  pmac-emu --port 0 --time-scale 1000 --log events.jsonl
                                             pick a free port (printed on stdout),
                                             run programs 1000x faster than real
                                             time, log every move and variable
  pmac-emu --port 0 --drop-at 40             close the connection instead of
                                             answering the 40th request (once)
  pmac-emu --memory-words 2000               a small controller: pmac-send splits

Speaks the Turbo PMAC Ethernet protocol (GETRESPONSE, GETBUFFER, SENDLINE,
GETLINE, READREADY, FLUSH, CTRL_RESPONSE, WRITEBUFFER) and, on the same port,
plain text lines ended by CR. Replies are framed as with I3=2 I6=1.
The event log is JSON Lines: {\"ev\":\"move\",\"t\":..,\"run\":..,\"x\":..,
\"y\":..,\"z\":..,\"beam\":..}, \"var\", \"run\", \"done\", \"abort\", \"idle\",
\"dwell\", \"error\", \"reset\"; t is simulated seconds.
Exit status: 0 after --duration, 1 on failure, 2 on bad usage.";

/// Emulate a Delta Tau Turbo PMAC (Geo Brick) on TCP.
#[derive(Parser)]
#[command(name = "pmac-emu", version, about, after_help = EXAMPLES)]
struct Args {
    /// TCP port; 0 picks a free one. The port is printed on stdout.
    #[arg(long, default_value_t = 1025)]
    port: u16,
    /// Address to listen on. Only loopback unless you mean it.
    #[arg(long, default_value = "127.0.0.1")]
    bind: IpAddr,
    /// User memory for program and rotary buffers, words (SIZE).
    #[arg(long, default_value_t = 65_536)]
    memory_words: i64,
    /// A gather buffer holding this many words at start (freed by DELETE GATHER).
    #[arg(long, default_value_t = 0)]
    gather_words: i64,
    /// Simulated seconds per real second.
    #[arg(long, default_value_t = 1.0)]
    time_scale: f64,
    /// Write the event log (JSON Lines) here.
    #[arg(long)]
    log: Option<PathBuf>,
    /// The shutter variable.
    #[arg(long, default_value = "M33")]
    shutter_var: String,
    /// Fault: close the connection instead of answering request N (once).
    #[arg(long, value_name = "N")]
    drop_at: Option<u64>,
    /// Fault: wait this many milliseconds before every reply.
    #[arg(long, value_name = "MS", default_value_t = 0)]
    delay_ms: u64,
    /// Fault: delay only from request N on.
    #[arg(long, value_name = "N", default_value_t = 0)]
    delay_from: u64,
    /// Fault: delay only this many requests (default: all from --delay-from).
    #[arg(long, value_name = "N")]
    delay_count: Option<u64>,
    /// Fault: answer request N (once) with every number replaced by 99999.
    #[arg(long, value_name = "N")]
    lie_at: Option<u64>,
    /// Fault: answer ERR006 to the Nth program line stored (once).
    #[arg(long, value_name = "N")]
    err006_at_line: Option<u64>,
    /// Fault: reset the controller ($$$) at request N (once), whatever it
    /// is doing then.
    #[arg(long, value_name = "N")]
    reset_at: Option<u64>,
    /// Fault: reset the controller ($$$) once, at the first request from
    /// the Nth on at which a motion program is running (a reset mid-run).
    #[arg(long, value_name = "N")]
    reset_mid_run_from: Option<u64>,
    /// Exit after this many real seconds (default: run until killed).
    #[arg(long)]
    duration: Option<f64>,
}

fn main() -> ExitCode {
    let args = microcam::cli::parse::<Args>();
    cli::run("pmac-emu", || run(args))
}

fn run(args: Args) -> Result<(), CliError> {
    if !(args.time_scale.is_finite() && args.time_scale > 0.0 && args.time_scale <= 1e9) {
        return Err(CliError::input(format!(
            "--time-scale must be a positive number up to 1e9, not {}",
            args.time_scale
        )));
    }
    if let Some(d) = args.duration
        && !(d.is_finite() && (0.0..=1e7).contains(&d))
    {
        return Err(CliError::input(format!(
            "--duration must be a number of seconds from 0 to 1e7, not {d}"
        )));
    }
    if args.memory_words < 0 || args.gather_words < 0 || args.gather_words > args.memory_words {
        return Err(CliError::input(
            "--memory-words and --gather-words must be 0 or more, the gather buffer no larger than memory",
        ));
    }
    if args.delay_ms > 3_600_000 {
        return Err(CliError::input(format!(
            "--delay-ms must be at most 3600000, not {}",
            args.delay_ms
        )));
    }
    if !args.bind.is_loopback() {
        // An emulator reachable from the network could be mistaken for the
        // machine's controller by a real client.
        microcam::diag!("pmac-emu: warning: listening on {}, not loopback", args.bind);
    }
    let log: Option<Box<dyn Write + Send>> = match &args.log {
        Some(p) => Some(Box::new(std::io::BufWriter::new(
            std::fs::File::create(p).map_err(|e| CliError::failure(format!("{}: {e}", p.display())))?,
        ))),
        None => None,
    };
    let cfg = Config {
        memory_words: args.memory_words,
        gather_words: args.gather_words,
        err006_at_line: args.err006_at_line,
        shutter_var: args.shutter_var.to_ascii_uppercase(),
    };
    let faults = Faults {
        drop_at: args.drop_at,
        delay: Duration::from_millis(args.delay_ms),
        delay_from: args.delay_from,
        reset_at: args.reset_at,
        reset_mid_run_from: args.reset_mid_run_from,
        delay_count: args.delay_count,
        lie_at: args.lie_at,
    };
    let ctl = Emulator::new(cfg, Clock::scaled(args.time_scale), log);
    let server = Server::start(SocketAddr::new(args.bind, args.port), ctl, faults)
        .map_err(|e| CliError::failure(format!("cannot listen on {}:{}: {e}", args.bind, args.port)))?;
    let addr = server.addr();
    microcam::cli::print_line(&addr.port().to_string())?;
    microcam::diag!("pmac-emu: listening on {addr}");
    match args.duration {
        Some(s) => std::thread::sleep(Duration::from_secs_f64(s)),
        None => loop {
            std::thread::sleep(Duration::from_secs(3600));
        },
    }
    Ok(())
}
