//! Arguments and output helpers shared by pathgen's subcommands.

use clap::Args as ClapArgs;
use microcam::cli::{CliError, Output};
use microcam::formats::toolpath::ToolpathWriter;
use microcam::gcode::Dialect;
use microcam::gcode::writer::{GcodeWriter, WriteError, WriteOptions};
use microcam::geometry::P3;
use microcam::laser::contour::Warning;
use microcam::laser::setup::{DEFAULT_DECIMALS, LaserSetup};
use microcam::machine::{Controller, Machine, pmac};
use microcam::model::toolpath::{FeedUnit, Header, Record};
use microcam::progress::{self, Meter, Show};
use std::path::PathBuf;

pub(crate) fn parse_triple_f64(s: &str) -> Result<(f64, f64, f64), String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>().ok().filter(|v| v.is_finite()))
        .collect::<Option<_>>()
        .ok_or_else(|| format!("expected X,Y,Z, got '{s}'"))?;
    match v[..] {
        [x, y, z] => Ok((x, y, z)),
        _ => Err(format!("expected X,Y,Z, got '{s}'")),
    }
}

pub(crate) fn positive(name: &str, v: f64) -> Result<f64, CliError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(CliError::input(format!("--{name} must be positive, got {v}")))
    }
}

pub(crate) fn finite(name: &str, v: f64) -> Result<f64, CliError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(CliError::input(format!("--{name} must be a finite number, got {v}")))
    }
}

pub(crate) fn non_negative(name: &str, v: f64) -> Result<f64, CliError> {
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(CliError::input(format!(
            "--{name} must be a finite number >= 0, got {v}"
        )))
    }
}

pub(crate) fn at_least_one(name: &str, v: u32) -> Result<u32, CliError> {
    if v >= 1 {
        Ok(v)
    } else {
        Err(CliError::input(format!("--{name} must be at least 1, got {v}")))
    }
}

/// The stage and shutter: a machine profile (`--machine`, default the
/// laser stage of Bayesteh 2013), then these flags over it.
#[derive(ClapArgs)]
pub(crate) struct MachineArgs {
    /// Machine profile: a built-in name (laser-stage, lookahead) or a
    /// microcam.machine/1 JSON file. Its acceleration time and shutter are
    /// the defaults of the flags below.
    #[arg(long, default_value = "laser-stage", value_name = "NAME|FILE")]
    pub(crate) machine: String,
    /// Feed V while the beam is on (mm/s).
    #[arg(long, default_value_t = 2.0)]
    pub(crate) feed: f64,
    /// Acceleration time TA (ms). Default: the profile's (on a Turbo PMAC
    /// its TA/TS rule; on a look-ahead planner V over its acceleration).
    #[arg(long = "ta-ms", alias = "ta", allow_negative_numbers = true)]
    pub(crate) ta: Option<f64>,
    /// Deceleration time TD (ms). Default: TA.
    #[arg(long = "td-ms", alias = "td", allow_negative_numbers = true)]
    pub(crate) td: Option<f64>,
    /// S-curve time TS (ms) written into the program.
    #[arg(long = "ts-ms", alias = "ts", default_value_t = 0.0, allow_negative_numbers = true)]
    pub(crate) ts: f64,
    /// Acceleration (mm/s^2): sets TA = TD = V/a instead.
    #[arg(long = "accel-mm-s2", alias = "accel", allow_negative_numbers = true)]
    pub(crate) accel: Option<f64>,
    /// Shutter delay before opening starts (ms). Default: the profile's.
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) open_delay: Option<f64>,
    /// Shutter transfer time to fully open (ms). Default: the profile's.
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) open_transfer: Option<f64>,
    /// Shutter delay before closing starts (ms). Default: the profile's.
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) close_delay: Option<f64>,
    /// Shutter transfer time to fully closed (ms). Default: the profile's.
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) close_transfer: Option<f64>,
    /// Minimum exposure (ms); shorter cuts are reported. Default: the profile's.
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) min_exposure: Option<f64>,
    /// Corners turning less than this (degrees) are tangent: no loop.
    #[arg(long, default_value_t = 0.5)]
    pub(crate) tangent_tol: f64,
    /// Controller the program is planned for: pmac (M33== acts where the
    /// blend into its block starts; blocks at V get a short TA) or lookahead
    /// (commands act at block boundaries). Default: lookahead with --gcode
    /// iso, else the profile's.
    #[arg(long, value_enum)]
    pub(crate) controller: Option<Controller>,
    /// PMAC: TA (whole ms) of the blocks at V between a path's ramps.
    /// Default: 2 × the close delay, so the close command sits on the
    /// boundary at the cut end.
    #[arg(long = "cut-ta-ms", alias = "cut-ta")]
    pub(crate) cut_ta: Option<f64>,
}

impl MachineArgs {
    /// The laser setup: the profile, then the flags; `gcode` is the dialect
    /// written, which picks the controller when `--controller` is not given.
    pub(crate) fn machine(&self, gcode: Option<&str>) -> Result<LaserSetup, CliError> {
        let profile = Machine::load(&self.machine).map_err(|e| CliError::input(format!("--machine: {e}")))?;
        let shutter = profile.shutter.clone().ok_or_else(|| {
            CliError::input(format!(
                "--machine: profile '{}' has no shutter section; the laser strategies need one",
                profile.name
            ))
        })?;
        let controller = match (self.controller, gcode) {
            (Some(c), _) => c,
            (None, Some("iso")) => Controller::Lookahead,
            (None, _) => profile.controller,
        };
        let profile_ta_ms = match profile.controller {
            Controller::Pmac => 1000.0 * pmac::accel_time_s(profile.ta_ms, profile.ts_ms),
            Controller::Lookahead => 1000.0 * self.feed / profile.accel_mm_s2,
        };
        let ta = self.ta.unwrap_or(profile_ta_ms);
        let close_delay = self.close_delay.unwrap_or(shutter.close_delay_ms);
        let mut m = LaserSetup {
            feed: self.feed,
            ta_ms: ta,
            td_ms: self.td.unwrap_or(ta),
            ts_ms: self.ts,
            open_delay_ms: self.open_delay.unwrap_or(shutter.open_delay_ms),
            open_transfer_ms: self.open_transfer.unwrap_or(shutter.open_transfer_ms),
            close_delay_ms: close_delay,
            close_transfer_ms: self.close_transfer.unwrap_or(shutter.close_transfer_ms),
            min_exposure_ms: self.min_exposure.unwrap_or(shutter.min_exposure_ms),
            tangent_tol_deg: self.tangent_tol,
            controller,
            cut_ta_ms: self
                .cut_ta
                .unwrap_or((2.0 * close_delay).clamp(1.0, ta.max(self.td.unwrap_or(ta)).max(1.0))),
            decimals: DEFAULT_DECIMALS,
        };
        if let Some(a) = self.accel {
            if !(a.is_finite() && a > 0.0) {
                return Err(CliError::input(format!("--accel-mm-s2 must be positive, got {a}")));
            }
            m = m.with_accel(a);
        }
        m.validate().map_err(|e| CliError::input(e.to_string()))?;
        Ok(m)
    }
}

/// Where generated moves go.
#[derive(ClapArgs)]
pub(crate) struct GenOutput {
    /// Write G-code of this dialect instead of a toolpath.
    #[arg(long, value_parser = ["iso", "pmac"])]
    pub(crate) gcode: Option<String>,
    #[command(flatten)]
    pub(crate) writer: WriterArgs,
    /// Also write an SVG preview here.
    #[arg(long, value_name = "FILE")]
    pub(crate) svg: Option<PathBuf>,
    /// Write output here instead of stdout.
    #[arg(short, long)]
    pub(crate) output: Option<PathBuf>,
    /// Refuse (exit 2) a job estimated to make more moves than this.
    #[arg(long, default_value_t = DEFAULT_MAX_MOVES, value_name = "N")]
    pub(crate) max_moves: u64,
    /// No progress bar on stderr (warnings and errors still appear).
    #[arg(short, long)]
    pub(crate) quiet: bool,
}

/// Default of `--max-moves`: 10 million moves, about 1 GB of toolpath text.
pub(crate) const DEFAULT_MAX_MOVES: u64 = 10_000_000;

impl GenOutput {
    /// The machine for a generator: the profile and flags, with the block
    /// margin taken from the decimals the program is written with.
    pub(crate) fn setup(&self, machine: &MachineArgs) -> Result<LaserSetup, CliError> {
        let mut m = machine.machine(self.gcode.as_deref())?;
        m.decimals = self.writer.decimals.unwrap_or(DEFAULT_DECIMALS);
        Ok(m)
    }

    /// Refuse a job whose estimated size passes `--max-moves`.
    pub(crate) fn check_size(&self, what: &str, moves: f64, how: &str) -> Result<(), CliError> {
        if moves.is_nan() || moves > self.max_moves as f64 {
            return Err(self.too_big(what, moves, how));
        }
        Ok(())
    }

    /// The job's progress display (see [`meter`]).
    pub(crate) fn meter(&self, what: &'static str, total: u64) -> Meter {
        meter(what, total, self.quiet)
    }

    pub(crate) fn too_big(&self, what: &str, moves: f64, how: &str) -> CliError {
        CliError::input(format!(
            "{what}: {how} makes about {moves:.3e} moves, more than --max-moves {}; ask for less, or raise \
             --max-moves",
            self.max_moves
        ))
    }
}

/// A progress display of pathgen's job on stderr (`microcam::progress`):
/// a bar on a terminal for work over about a second, nothing in a pipeline
/// log, nothing with `--quiet`. `what` names the unit counted.
pub(crate) fn meter(what: &'static str, total: u64, quiet: bool) -> Meter {
    Meter::start("pathgen", what, total, Show::from_flags(quiet, false))
}

pub(crate) fn parse_pair_f64(s: &str) -> Result<(f64, f64), String> {
    let (a, b) = s.split_once(',').ok_or_else(|| format!("expected X,Y, got '{s}'"))?;
    let p = |t: &str| {
        t.trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("'{t}' is not a finite number"))
    };
    Ok((p(a)?, p(b)?))
}

pub(crate) fn parse_pair_u32(s: &str) -> Result<(u32, u32), String> {
    let (a, b) = s.split_once(',').ok_or_else(|| format!("expected NX,NY, got '{s}'"))?;
    let p = |t: &str| {
        t.trim()
            .parse::<u32>()
            .ok()
            .filter(|&v| v >= 1)
            .ok_or_else(|| format!("'{t}' is not a count >= 1"))
    };
    Ok((p(a)?, p(b)?))
}

/// How G-code is written: shared by `emit` and every generator's `--gcode`,
/// so a generated program is byte-identical to generating a toolpath and
/// piping it through `pathgen emit`.
#[derive(ClapArgs)]
pub(crate) struct WriterArgs {
    /// Decimal places of coordinates and feeds (0-9).
    #[arg(long, value_parser = clap::value_parser!(u8).range(0..=9))]
    pub(crate) decimals: Option<u8>,
    /// Shutter variable (PMAC).
    #[arg(long, default_value = "M33")]
    pub(crate) shutter_var: String,
    /// Assign the shutter immediately (`M33=1`, executed at look-ahead)
    /// instead of synchronously with motion (`M33==1`, the default).
    #[arg(long)]
    pub(crate) shutter_immediate: bool,
    /// Line-counter variable (PMAC), one increment per motion block.
    #[arg(
        long = "line-counter-var",
        alias = "line-counter",
        value_name = "LINE_COUNTER_VAR",
        default_value = "P400"
    )]
    pub(crate) line_counter: String,
    /// Write no line counter.
    #[arg(long)]
    pub(crate) no_line_counter: bool,
    /// PMAC program buffer number for the default header (OPEN PROG n CLEAR).
    #[arg(long, default_value_t = 1)]
    pub(crate) program: u32,
    /// Header lines instead of the default (repeatable).
    #[arg(long = "header")]
    pub(crate) header: Vec<String>,
    /// Trailer lines instead of the default (repeatable).
    #[arg(long = "trailer")]
    pub(crate) trailer: Vec<String>,
    /// ISO: number blocks N10, N20, ... with this step.
    #[arg(long, value_name = "STEP")]
    pub(crate) line_numbers: Option<u32>,
    /// Arc centres absolute (G90.1 / ABS(R)) instead of incremental.
    #[arg(long)]
    pub(crate) absolute_centers: bool,
    /// Repeat the motion word on every block.
    #[arg(long)]
    pub(crate) repeat_motion: bool,
    /// Comment each change of source chain and role.
    #[arg(long)]
    pub(crate) comments: bool,
}

pub(crate) fn write_options(dialect: Dialect, a: &WriterArgs) -> WriteOptions {
    let mut opts = WriteOptions::for_dialect(dialect);
    if let Some(d) = a.decimals {
        opts.decimals = d;
    }
    opts.shutter_var = a.shutter_var.to_ascii_uppercase();
    opts.shutter_sync = !a.shutter_immediate;
    opts.line_counter = (!a.no_line_counter && dialect == Dialect::Pmac).then(|| a.line_counter.to_ascii_uppercase());
    opts.line_numbers = a.line_numbers;
    opts.absolute_centers = a.absolute_centers;
    opts.repeat_motion = a.repeat_motion;
    opts.comments = a.comments;
    if !a.header.is_empty() {
        opts.header = Some(a.header.clone());
    } else if dialect == Dialect::Pmac && a.program != 1 {
        let mut h = opts.default_header();
        if let Some(first) = h.first_mut() {
            *first = format!("OPEN PROG {} CLEAR", a.program);
        }
        opts.header = Some(h);
    }
    if !a.trailer.is_empty() {
        opts.trailer = Some(a.trailer.clone());
    }
    opts
}

/// Write records as G-code: the one code path of `emit` and `--gcode`.
pub(crate) fn write_gcode<E>(
    records: impl Iterator<Item = Result<Record, E>>,
    feed_unit: FeedUnit,
    opts: WriteOptions,
    name: &str,
    out: &mut Output,
) -> Result<(), CliError>
where
    CliError: From<E>,
{
    let mut w = GcodeWriter::new(out, opts, feed_unit);
    let bad = |e: WriteError| match e {
        WriteError::Io(e) => <CliError as From<std::io::Error>>::from(e),
        e => CliError::input(format!("{name}: {e}")),
    };
    for rec in records {
        w.record(&rec?).map_err(bad)?;
    }
    w.finish().map_err(bad)?;
    Ok(())
}

/// Warnings beyond this many are counted, not printed: a drawing with
/// thousands of tight fillets should not bury the rest of stderr.
pub(crate) const MAX_WARNINGS: usize = 20;

pub(crate) fn warn_all(warnings: &[Warning]) {
    for w in warnings.iter().take(MAX_WARNINGS) {
        microcam::diag!("pathgen: warning: chain {}: {}", w.chain, w.message);
    }
    if warnings.len() > MAX_WARNINGS {
        microcam::diag!(
            "pathgen: warning: {} more warnings not shown",
            warnings.len() - MAX_WARNINGS
        );
    }
}

/// Note on stderr the `short` of `total` feed moves a Turbo PMAC would
/// stretch to its least TA (shorter than 1 ms at V).
pub(crate) fn short_note(short: usize, total: usize, m: &LaserSetup) {
    if short > 0 {
        let what = match m.controller {
            microcam::machine::Controller::Pmac => "a Turbo PMAC stretches them to its least TA and slows down there",
            microcam::machine::Controller::Lookahead => {
                "a look-ahead control computing about 1,000 blocks a second slows down there"
            }
        };
        microcam::diag!(
            "pathgen: note: {short} of {total} feed moves last less than 1 ms at V ({:.6} mm); {what}",
            m.min_block()
        );
    }
}

/// Write generated records as a toolpath or, with `--gcode`, as G-code
/// through the same writer as `emit`; the SVG preview goes beside. Returns
/// the feed moves a Turbo PMAC would stretch, (stretched, all), for
/// [`short_note`], which the caller prints after its other notes (and
/// after its progress display has cleared).
///
/// With `count`, each record written advances the progress counters by one
/// (for a caller whose meter counts moves written; a caller whose meter
/// counts planning work passes false).
pub(crate) fn write_generated(
    records: &[Record],
    o: &GenOutput,
    source: Option<String>,
    m: &LaserSetup,
    count: bool,
) -> Result<(usize, usize), CliError> {
    let stretched = microcam::laser::audit::stretched_blocks(records, m, P3::origin());
    if let Some(path) = &o.svg {
        let mut svg = Output::new(Some(path));
        microcam::laser::svg::write_svg(&mut svg, records, m).map_err(CliError::from)?;
        svg.commit()?;
    }
    let mut out = Output::new(o.output.as_deref());
    let counted = records.iter().cloned().inspect(|_| {
        if count {
            progress::advance(1);
        }
    });
    write_records(counted, o, source, &mut out)?;
    out.commit()?;
    Ok(stretched)
}

/// The one place generated records become output bytes.
pub(crate) fn write_records(
    records: impl Iterator<Item = Record>,
    o: &GenOutput,
    source: Option<String>,
    out: &mut Output,
) -> Result<(), CliError> {
    match &o.gcode {
        Some(d) => {
            let dialect: Dialect = d.parse().map_err(CliError::input)?;
            let opts = write_options(dialect, &o.writer);
            let name = source.unwrap_or_else(|| "<generated>".into());
            write_gcode(records.map(Ok::<_, CliError>), FeedUnit::MmPerS, opts, &name, out)
        }
        None => {
            let mut w = ToolpathWriter::new(out);
            w.header(&Header {
                feed_unit: FeedUnit::MmPerS,
                source,
            })?;
            for r in records {
                w.record(&r)?;
            }
            w.finish()?;
            Ok(())
        }
    }
}

/// [`write_streamed`], counting as the chunks pass the feed moves a Turbo
/// PMAC would stretch (`laser::audit::stretched_blocks`): (stretched, all)
/// for [`short_note`], which the caller prints after its other notes.
pub(crate) fn write_streamed_counting_short(
    o: &GenOutput,
    source: Option<String>,
    m: &LaserSetup,
    produce: impl FnOnce(&mut dyn FnMut(Vec<Record>) -> bool),
) -> Result<(usize, usize), CliError> {
    let (mut short, mut total) = (0, 0);
    write_streamed(o, source, |sink| {
        produce(&mut |chunk| {
            let (s, t) = microcam::laser::audit::stretched_blocks(&chunk, m, P3::origin());
            short += s;
            total += t;
            sink(chunk)
        })
    })?;
    Ok((short, total))
}

/// Write records handed over in chunks by `produce` on a second thread, so
/// formatting overlaps planning. Output is byte-identical to
/// [`write_generated`] (same writer, same records, same order).
pub(crate) fn write_streamed(
    o: &GenOutput,
    source: Option<String>,
    produce: impl FnOnce(&mut dyn FnMut(Vec<Record>) -> bool),
) -> Result<(), CliError> {
    let mut out = Output::new(o.output.as_deref());
    let (tx, rx) = std::sync::mpsc::sync_channel::<Vec<Record>>(2);
    let written = std::thread::scope(|s| {
        let out = &mut out;
        let writer = s.spawn(move || write_records(rx.into_iter().flatten(), o, source, out));
        // A failed writer drops the receiver; stop planning then.
        produce(&mut |chunk| tx.send(chunk).is_ok());
        drop(tx);
        writer
            .join()
            .unwrap_or_else(|_| Err(CliError::failure("the writer thread panicked")))
    });
    written?;
    out.commit()
}
