//! dxf2chains: a DXF drawing to oriented chains of exact lines and arcs
//! (microcam.chains/1 JSON Lines).

// Diagnostics go through `microcam::diag!` and data through the
// library's writers: `eprintln!`/`println!` panic when stderr or stdout
// is a closed pipe.
#![deny(clippy::print_stderr, clippy::print_stdout)]

use clap::Parser;
use microcam::cli::{self, CliError, Output};
use microcam::dxf::transform::{Mirror, Transforms, count, parse_numbers};
use microcam::dxf::{ImportOptions, chain, import, summary, svg, units};
use microcam::formats::chains::{ChainsWriter, format_chain_ref};
use microcam::model::chain::ChainsHeader;
use microcam::progress::{self, Meter, Show};
use std::io::{BufRead, Read, Write};
use std::path::PathBuf;
use std::process::ExitCode;

const EXAMPLES: &str = "\
Examples:
  dxf2chains part.dxf > part.chains                 chains in mm on stdout
  dxf2chains --layer CUT --layer HOLES part.dxf     only these layers
  dxf2chains --units inch old.dxf                   the file's unit, when $INSUNITS is missing or wrong
  dxf2chains --svg preview.svg part.dxf > /dev/null look before cutting
  dxf2chains --rotate 90 --translate 5,5 --array 3,2,12,12 part.dxf
  dxf2chains --polar 6,60,0,0 blade.dxf             six copies, 60 degrees apart, about (0,0)
  dxf2chains part.dxf | pathgen contour --side outside --offset 0.005 > part.jsonl

Splines and ellipses become tangent-continuous arcs within --arc-tol. Ends
within --join-tol are joined; closed outer contours run counter-clockwise, holes
clockwise (by nesting depth). Duplicates, collinear overlaps, zero-length
pieces and gaps are repaired and every repair is listed on the chain
('repairs') and summed up on stderr, with what was skipped (TEXT, HATCH...).
Transforms apply in the order scale, mirror, rotate, translate, then the
array and polar copies. '-' or no FILE reads stdin (ASCII or binary DXF).
Exit status: 0 ok, 1 failure, 2 bad usage or bad input (the message names
the file and line, or byte offset for binary DXF).";

/// Turn a DXF drawing into chains of lines and arcs.
#[derive(Parser)]
#[command(name = "dxf2chains", version, about, after_help = EXAMPLES)]
struct Args {
    /// DXF file to read ('-' for stdin).
    file: Option<PathBuf>,
    /// Join tolerance, mm: ends closer than this are one point.
    #[arg(long = "join-tol", alias = "tol", value_name = "JOIN_TOL", default_value_t = 0.001)]
    tol: f64,
    /// Fitting tolerance for splines and ellipses, mm.
    #[arg(long, default_value_t = 0.001)]
    arc_tol: f64,
    /// Keep only this layer (repeatable).
    #[arg(long = "layer", value_name = "NAME")]
    layers: Vec<String>,
    /// Drawing unit, overriding $INSUNITS: mm, cm, m, inch, ft, um, mil.
    #[arg(long)]
    units: Option<String>,
    /// Move by DX,DY (mm).
    #[arg(long, value_name = "DX,DY", allow_hyphen_values = true)]
    translate: Option<String>,
    /// Rotate about the origin, degrees counter-clockwise.
    #[arg(long, value_name = "DEG", allow_hyphen_values = true)]
    rotate: Option<f64>,
    /// Scale about the origin.
    #[arg(long, value_name = "S", allow_hyphen_values = true)]
    scale: Option<f64>,
    /// Mirror: 'x' negates X (about the Y axis), 'y' negates Y.
    #[arg(long, value_parser = ["x", "y"])]
    mirror: Option<String>,
    /// Linear pattern: NX by NY copies, DX and DY apart (mm).
    #[arg(long, value_name = "NX,NY,DX,DY", allow_hyphen_values = true)]
    array: Option<String>,
    /// Polar pattern: N copies, ANGLE degrees apart, about (CX,CY).
    #[arg(long, value_name = "N,ANGLE,CX,CY", allow_hyphen_values = true)]
    polar: Option<String>,
    /// Also write an SVG preview here.
    #[arg(long, value_name = "FILE")]
    svg: Option<PathBuf>,
    /// No summary and no progress bar on stderr (warnings and errors still
    /// appear).
    #[arg(short, long)]
    quiet: bool,
    /// Write chains here instead of stdout.
    #[arg(short, long)]
    output: Option<PathBuf>,
}

fn main() -> ExitCode {
    // Blocks of a megabyte and more (the reader's buffers, the chaining's
    // arrays) are mapped and unmapped rather than left in the heap: with
    // glibc's sliding threshold, the memory of one phase stays held
    // through the next and the peak grows by a quarter of the file.
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: sets one tuning parameter of the C allocator, before any
    // thread exists; no memory is touched.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 1 << 20);
    }
    let args = microcam::cli::parse::<Args>();
    cli::run("dxf2chains", || run(args))
}

fn transforms(a: &Args) -> Result<Transforms, String> {
    let mut t = Transforms {
        rotate_deg: a.rotate,
        scale: a.scale,
        ..Default::default()
    };
    if let Some(s) = &a.translate {
        let v = parse_numbers(s, 2, "--translate").map_err(|e| e.to_string())?;
        t.translate = Some((v[0], v[1]));
    }
    if let Some(s) = a.scale
        && !(s.is_finite() && s != 0.0)
    {
        return Err(format!("--scale: must be a non-zero number, got {s}"));
    }
    if let Some(r) = a.rotate
        && !r.is_finite()
    {
        return Err("--rotate: must be a finite number".into());
    }
    t.mirror = match a.mirror.as_deref() {
        Some("x") => Some(Mirror::X),
        Some("y") => Some(Mirror::Y),
        _ => None,
    };
    if let Some(s) = &a.array {
        let v = parse_numbers(s, 4, "--array").map_err(|e| e.to_string())?;
        t.array = Some((
            count(v[0], "--array").map_err(|e| e.to_string())?,
            count(v[1], "--array").map_err(|e| e.to_string())?,
            v[2],
            v[3],
        ));
    }
    if let Some(s) = &a.polar {
        let v = parse_numbers(s, 4, "--polar").map_err(|e| e.to_string())?;
        t.polar = Some((count(v[0], "--polar").map_err(|e| e.to_string())?, v[1], v[2], v[3]));
    }
    Ok(t)
}

/// The input, adding the bytes the reader takes to the progress counters.
struct Counted(Box<dyn BufRead>);

impl Read for Counted {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.0.read(buf)?;
        progress::advance(n as u64);
        Ok(n)
    }
}

impl BufRead for Counted {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        self.0.fill_buf()
    }

    fn consume(&mut self, n: usize) {
        progress::advance(n as u64);
        self.0.consume(n);
    }
}

/// The chains in output order, formatted in batches on the thread pool and
/// written in order: the same bytes as `ChainsWriter::chain` on each, in
/// about half the time on two cores, with two batches of text in memory:
/// one is written while the next is formatted.
fn write_chains<W: Write + Send>(chains: &chain::Chains, w: &mut ChainsWriter<W>) -> std::io::Result<()> {
    use rayon::prelude::*;
    const BATCH: usize = 1 << 12;
    const PART: usize = 1 << 8;
    let n = chains.len();
    let format = |parts: &mut [String], from: usize| {
        let to = (from + BATCH).min(n);
        parts.par_iter_mut().enumerate().for_each_init(Vec::new, |buf, (p, s)| {
            s.clear();
            let a = from + p * PART;
            for k in a..(a + PART).min(to) {
                if let Some(c) = chains.view(k, buf) {
                    format_chain_ref(s, &c);
                    s.push('\n');
                }
            }
        });
    };
    // The parts' strings are kept from batch to batch: growing fresh ones
    // each time cost a page fault per 4 KiB written, twice (the copy on
    // growth). Batches of 4,096 chains (about 3 MB of text on the mix
    // benchmark) rather than 16,384: the text's first touch was 3,000 page
    // faults, now about 500, and the pool still has 16 parts to share.
    let mut cur: Vec<String> = vec![String::new(); BATCH / PART];
    let mut next: Vec<String> = vec![String::new(); BATCH / PART];
    let mut from = 0;
    if n > 0 {
        format(&mut cur, 0);
    }
    while from < n {
        let after = from + BATCH;
        let (written, ()) = rayon::join(
            || cur.iter().try_for_each(|p| w.formatted(p)),
            || {
                if after < n {
                    format(&mut next, after);
                }
            },
        );
        written?;
        std::mem::swap(&mut cur, &mut next);
        from = after;
    }
    Ok(())
}

fn run(args: Args) -> Result<(), CliError> {
    for (name, v) in [("--join-tol", args.tol), ("--arc-tol", args.arc_tol)] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(CliError::input(format!(
                "{name}: must be a non-negative number, got {v}"
            )));
        }
    }
    let t = transforms(&args).map_err(CliError::input)?;
    let units_mm =
        match &args.units {
            None => None,
            Some(u) => Some(units::named_mm(u).ok_or_else(|| {
                CliError::input(format!("--units: unknown unit '{u}' (mm, cm, m, inch, ft, um, mil)"))
            })?),
        };
    let opts = ImportOptions {
        arc_tol: args.arc_tol,
        layers: args.layers.clone(),
        units_mm,
        copies: if t.is_identity() { Vec::new() } else { t.copies() },
        ..Default::default()
    };
    let input = cli::open_input(args.file.as_deref())?;
    let name = input.name.clone();
    // Reading is most of the work (about a second for 60 MB): the display
    // counts the bytes read, against the file's size when it is a file.
    let size = args
        .file
        .as_deref()
        .filter(|p| p.as_os_str() != "-")
        .and_then(|p| std::fs::metadata(p).ok())
        .filter(|m| m.is_file())
        .map_or(0, |m| m.len());
    microcam::progress::lap("start");
    let meter = Meter::start("dxf2chains", "bytes read", size, Show::from_flags(args.quiet, false));
    let imp = import(Box::new(Counted(input.reader)), &opts).map_err(|e| match e {
        microcam::dxf::reader::DxfError::Io(io) => CliError::input(format!("{name}: {io}")),
        e => CliError::in_file(&name, e),
    });
    let mut imp = imp?;
    microcam::progress::lap("import");
    let (chains, report) = chain::build(
        std::mem::take(&mut imp.sink.segments),
        &imp.sink.points,
        &imp.sink.layers,
        args.tol,
    );
    meter.finish();
    microcam::progress::lap("chain: counts");

    let mut out = Output::new(args.output.as_deref());
    let mut w = ChainsWriter::new(&mut out);
    w.header(&ChainsHeader {
        source: Some(name.clone()),
    })?;
    write_chains(&chains, &mut w)?;
    w.finish()?;
    microcam::progress::lap("write");
    let svg_out = match &args.svg {
        Some(p) => {
            let mut o = Output::new(Some(p));
            o.write_all(svg::render(chains.iter()).as_bytes())?;
            Some(o)
        }
        None => None,
    };
    // Warnings appear even with --quiet.
    for line in summary::lines(&imp, &report, args.arc_tol, chains.point_chains(), &args.layers) {
        if !args.quiet || line.starts_with("warning") {
            microcam::diag!("dxf2chains: {name}: {line}");
        }
    }
    if let Some(o) = svg_out {
        o.commit()?;
    }
    out.commit()?;
    // The chains and the drawing are tens of megabytes in a few hundred
    // thousand allocations: freeing them one by one took 3 ms of the mix
    // benchmark's 200, and the process's exit, a moment later, gives the
    // memory back at once. They hold nothing but memory.
    std::mem::forget((chains, imp));
    Ok(())
}
