//! Command-line conventions every binary shares: `-` for stdin/stdout,
//! outputs that appear whole or not at all, exit codes (0 ok, 1 failure,
//! 2 bad usage or bad input) and error reports that name the file and line.
//!
//! All outputs of a run appear together or not at all: inside [`run`], an
//! [`Output::commit`] only stages the output (flushed, checked), and the
//! staged outputs are released when the tool's body succeeds — stdout
//! first (a closed or broken stdout then fails the run before any file
//! appears), then the files, renamed into place in the order they were
//! committed. When the body fails, nothing staged appears and the hidden
//! temporary files are removed, also on SIGINT, SIGTERM and SIGHUP
//! ([`cleanup`]). Man pages and completions come from each tool's clap
//! definition ([`generate`]).
#![warn(missing_docs)]

pub mod cleanup;
pub mod generate;
pub mod threads;
pub use generate::parse;

use std::fs::File;
use std::io::{self, BufRead, BufReader, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// What went wrong, and which exit status it earns.
#[derive(Debug)]
pub struct CliError {
    /// 1 = the job failed (I/O, a fault), 2 = bad usage or bad input.
    pub status: u8,
    /// What to print after `tool: ` (may be empty: nothing is printed).
    pub message: String,
    /// The reader of our stdout went away (`| head`): the job ends with
    /// status 1 but without a message, as Unix filters do.
    pub broken_pipe: bool,
    /// A verdict, not a failure of the run (stlverify outside its band,
    /// an audit that finds broken limits): every output was written and
    /// must appear, and the status says what the job found.
    pub keep_outputs: bool,
}

impl CliError {
    /// Bad input or usage: exit status 2.
    pub fn input(message: impl Into<String>) -> Self {
        CliError {
            status: 2,
            message: message.into(),
            broken_pipe: false,
            keep_outputs: false,
        }
    }

    /// The job was done and its outputs are written, but what it found is
    /// a failure (a part outside its tolerance band): exit status 1, with
    /// every output in place for the user to look at.
    pub fn verdict(message: impl Into<String>) -> Self {
        CliError {
            keep_outputs: true,
            ..CliError::failure(message)
        }
    }

    /// The job could not be done: exit status 1.
    pub fn failure(message: impl Into<String>) -> Self {
        CliError {
            status: 1,
            message: message.into(),
            broken_pipe: false,
            keep_outputs: false,
        }
    }

    /// An input error located in `source` (a file name or `<stdin>`).
    pub fn in_file(source: &str, err: impl std::fmt::Display) -> Self {
        let err = err.to_string();
        match err.strip_prefix("line ") {
            Some(rest) => CliError::input(format!("{source}:{rest}")),
            None => CliError::input(format!("{source}: {err}")),
        }
    }
}

impl From<io::Error> for CliError {
    fn from(e: io::Error) -> Self {
        let mut c = CliError::failure(e.to_string());
        c.broken_pipe = e.kind() == io::ErrorKind::BrokenPipe;
        c
    }
}

/// Run a tool's body and turn its outcome into an exit status, printing
/// `tool: message` on stderr for errors. A closed stdout (`| head`) is not
/// an error worth a message. First, the worker pool is set up as the
/// environment asks ([`threads::init_pool`]).
pub fn run(tool: &str, body: impl FnOnce() -> Result<(), CliError>) -> ExitCode {
    threads::init_pool();
    let args: Vec<String> = std::env::args().skip(1).collect();
    if let Err(e) = check_numeric_arguments(&args) {
        crate::diag!("{tool}: {}", e.message);
        return ExitCode::from(e.status);
    }
    /// Drops whatever is still staged when the body fails or unwinds, so
    /// temporary files go with it.
    struct Discard;
    impl Drop for Discard {
        fn drop(&mut self) {
            drop(take_staged());
        }
    }
    *staged() = Some(Vec::new());
    let discard = Discard;
    let outcome = match body() {
        Ok(()) => release(take_staged().unwrap_or_default()),
        Err(e) if e.keep_outputs => release(take_staged().unwrap_or_default()).and(Err(e)),
        Err(e) => Err(e),
    };
    drop(discard);
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if e.broken_pipe => ExitCode::from(e.status),
        Err(e) => {
            crate::diag!("{tool}: {}", e.message);
            ExitCode::from(e.status)
        }
    }
}

/// Largest magnitude a number on the command line may have. Nothing a
/// micro-machining tool is asked (millimetres, seconds, rpm, counts) comes
/// near it; anything beyond is a typo or an attack, and would overflow the
/// arithmetic downstream into infinities.
pub const MAX_ARGUMENT_MAGNITUDE: f64 = 1e12;

/// Refuse, for every tool at once, command-line values that are numbers no
/// computation can use: NaN, infinities, and magnitudes beyond
/// [`MAX_ARGUMENT_MAGNITUDE`], alone or inside a comma, semicolon or colon
/// list (`--stock 0,0,nan,1,1,1`, `--holder 1e308:20`; a tool spec such as
/// `torus:2:0.5` has a name in it and is left to its own parser). Rust's float parser accepts `nan`, `inf` and
/// `1e999`, so without this each flag would need its own guard; flags that
/// need a tighter range (a step that must be positive, a count of moves)
/// still check it where they are used.
pub fn check_numeric_arguments(args: &[String]) -> Result<(), CliError> {
    let mut flag: Option<&str> = None;
    for a in args {
        let (name, value) = match a.split_once('=') {
            Some((n, v)) if n.starts_with("--") => (Some(n), v),
            _ if a.starts_with("--") => {
                flag = Some(a.as_str());
                continue;
            }
            _ => (flag, a.as_str()),
        };
        flag = None;
        let pieces: Vec<&str> = value.split([',', ';', ':']).map(str::trim).collect();
        let numbers: Vec<f64> = pieces.iter().filter_map(|p| p.parse::<f64>().ok()).collect();
        if numbers.len() != pieces.len() || numbers.is_empty() {
            continue; // not a number (a path, a name, a tool spec)
        }
        if pieces.iter().all(|p| p.parse::<i128>().is_ok()) {
            continue; // integers (seeds, counts): clap's integer types check their own range
        }
        if let Some(bad) = numbers
            .iter()
            .find(|x| !x.is_finite() || x.abs() > MAX_ARGUMENT_MAGNITUDE)
        {
            let what = if bad.is_nan() {
                "not a number".to_string()
            } else if bad.is_infinite() {
                "infinite".to_string()
            } else {
                format!("beyond ±{MAX_ARGUMENT_MAGNITUDE:e}")
            };
            let whose = name.map(|n| format!("{n} ")).unwrap_or_default();
            return Err(CliError::input(format!(
                "{whose}'{value}': {what}; numbers must be finite and within ±{MAX_ARGUMENT_MAGNITUDE:e}"
            )));
        }
    }
    Ok(())
}

/// An input named on the command line: a path, or `-`/absent for stdin.
pub struct Input {
    /// How to name it in messages.
    pub name: String,
    /// The bytes, buffered.
    pub reader: Box<dyn BufRead>,
}

/// Open `path` (or stdin for `None` / `-`) with a large buffer.
pub fn open_input(path: Option<&Path>) -> Result<Input, CliError> {
    match path {
        None => Ok(stdin_input()),
        Some(p) if p.as_os_str() == "-" => Ok(stdin_input()),
        Some(p) => {
            let f = File::open(p).map_err(|e| CliError::input(format!("{}: {e}", p.display())))?;
            Ok(Input {
                name: p.display().to_string(),
                reader: Box::new(BufReader::with_capacity(1 << 16, f)),
            })
        }
    }
}

fn stdin_input() -> Input {
    Input {
        name: "<stdin>".into(),
        reader: Box::new(BufReader::with_capacity(1 << 16, io::stdin())),
    }
}

/// Where output goes: a file or stdout. Nothing reaches the destination
/// unless [`Output::commit`] is called, so a tool that fails half-way
/// leaves no half-written output.
///
/// A file destination is written into a temporary file beside it and
/// renamed over it on commit (one copy, atomic). Stdout cannot be taken
/// back, so up to `SPILL_BYTES` are held in memory and the rest spills to
/// an anonymous temporary file that is copied out on commit: memory stays
/// flat however large the output.
pub struct Output {
    sink: Sink,
}

enum Sink {
    File {
        path: PathBuf,
        tmp: io::BufWriter<tempfile::NamedTempFile>,
        /// Removes the temporary file on a signal while it exists.
        guard: cleanup::Guard,
    },
    Stdout {
        mem: Vec<u8>,
        spill: Option<File>,
    },
    /// A device or FIFO (`-o /dev/null`): nothing to rename over, written
    /// directly.
    Special(io::BufWriter<File>),
    /// Opening the destination failed; reported on first write or commit.
    Broken(String),
}

const SPILL_BYTES: usize = 8 << 20;

/// A destination that must be written in place: a device, FIFO or socket,
/// or anything under /dev or /proc (`-o /dev/stdout` is a symlink to
/// /proc/self/fd/1, which may be a regular file; renaming a temp file over
/// it would replace the system's link).
fn is_special(path: &Path) -> bool {
    let under = |p: &Path| p.starts_with("/dev") || p.starts_with("/proc");
    under(path)
        || std::fs::canonicalize(path).is_ok_and(|p| under(&p))
        || std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir())
}

impl Output {
    /// `None` or `-` is stdout.
    pub fn new(path: Option<&Path>) -> Output {
        let sink = match path.filter(|p| p.as_os_str() != "-") {
            None => Sink::Stdout {
                mem: Vec::with_capacity(1 << 16),
                spill: None,
            },
            Some(path) if is_special(path) => match std::fs::OpenOptions::new().write(true).open(path) {
                Ok(f) => Sink::Special(io::BufWriter::with_capacity(1 << 20, f)),
                Err(e) => Sink::Broken(format!("{}: {e}", path.display())),
            },
            Some(path) => {
                // Write beside the file a symlink points to, and rename onto
                // that file, so the link survives.
                let target = match std::fs::symlink_metadata(path) {
                    Ok(m) if m.file_type().is_symlink() => {
                        std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf())
                    }
                    _ => path.to_path_buf(),
                };
                let dir = target
                    .parent()
                    .filter(|d| !d.as_os_str().is_empty())
                    .unwrap_or(Path::new("."));
                match tempfile::NamedTempFile::new_in(dir) {
                    Ok(t) => Sink::File {
                        path: target.clone(),
                        guard: cleanup::register(t.path()),
                        tmp: io::BufWriter::with_capacity(1 << 20, t),
                    },
                    Err(e) => Sink::Broken(format!("{}: {e}", path.display())),
                }
            }
        };
        Output { sink }
    }

    /// Make the output appear at its destination. Inside [`run`] it is
    /// staged: checked and flushed now, released when the run succeeds
    /// (with every other output of the run), discarded when it fails.
    /// Outside [`run`] it appears now.
    pub fn commit(self) -> Result<(), CliError> {
        let s = self.stage()?;
        let mut group = staged();
        if let Some(g) = group.as_mut() {
            g.push(s);
            return Ok(());
        }
        drop(group);
        s.release()
    }

    /// Make the output appear now, whatever else the run does (progress
    /// that must survive a later failure).
    pub fn commit_now(self) -> Result<(), CliError> {
        self.stage()?.release()
    }

    /// Everything that can fail before the output appears.
    fn stage(self) -> Result<Staged, CliError> {
        match self.sink {
            Sink::Broken(msg) => Err(CliError::failure(msg)),
            Sink::Special(mut w) => {
                w.flush()?;
                Ok(Staged::Done)
            }
            Sink::File { path, tmp, guard } => {
                let tmp = tmp
                    .into_inner()
                    .map_err(|e| CliError::failure(format!("{}: {}", path.display(), e.error())))?;
                // A temp file is private (0600); the result should look like
                // any file the user writes: the old file's mode, else 0644.
                let perms = match std::fs::metadata(&path) {
                    Ok(m) => Some(m.permissions()),
                    #[cfg(unix)]
                    Err(_) => {
                        use std::os::unix::fs::PermissionsExt;
                        Some(std::fs::Permissions::from_mode(0o644))
                    }
                    // Elsewhere a new file keeps the temp file's defaults.
                    #[cfg(not(unix))]
                    Err(_) => None,
                };
                if let Some(perms) = perms {
                    tmp.as_file()
                        .set_permissions(perms)
                        .map_err(|e| CliError::failure(format!("{}: {e}", path.display())))?;
                }
                Ok(Staged::File { path, tmp, guard })
            }
            Sink::Stdout { mem, spill } => Ok(Staged::Stdout { mem, spill }),
        }
    }
}

/// An output ready to appear.
enum Staged {
    /// Already at its destination (a device or FIFO).
    Done,
    File {
        path: PathBuf,
        tmp: tempfile::NamedTempFile,
        guard: cleanup::Guard,
    },
    Stdout {
        mem: Vec<u8>,
        spill: Option<File>,
    },
}

impl Staged {
    fn release(self) -> Result<(), CliError> {
        match self {
            Staged::Done => Ok(()),
            Staged::File { path, tmp, guard } => {
                tmp.persist(&path)
                    .map_err(|e| CliError::failure(format!("{}: {e}", path.display())))?;
                drop(guard);
                Ok(())
            }
            Staged::Stdout { mem, spill } => write_stdout(&mem, spill),
        }
    }
}

/// The outputs staged by the running tool (`None` outside [`run`]).
static STAGED: std::sync::Mutex<Option<Vec<Staged>>> = std::sync::Mutex::new(None);

fn staged() -> std::sync::MutexGuard<'static, Option<Vec<Staged>>> {
    STAGED.lock().unwrap_or_else(|e| e.into_inner())
}

fn take_staged() -> Option<Vec<Staged>> {
    staged().take()
}

/// Release a successful run's outputs: stdout first, then the files in
/// commit order. On the first failure the rest are dropped (their temporary
/// files removed).
fn release(outputs: Vec<Staged>) -> Result<(), CliError> {
    let (out, files): (Vec<_>, Vec<_>) = outputs.into_iter().partition(|s| matches!(s, Staged::Stdout { .. }));
    for s in out.into_iter().chain(files) {
        s.release()?;
    }
    Ok(())
}

/// Write one line (a report, a summary) on stdout and flush it, returning
/// the error instead of panicking as `println!` does when stdout is a pipe
/// whose reader has gone: [`run`] then ends the tool quietly (a closed
/// stdout is not worth a message), and a caller with more to say (a safety
/// message after a stopped upload) can ignore the error and go on.
pub fn print_line(line: &str) -> io::Result<()> {
    let mut out = io::stdout().lock();
    out.write_all(line.as_bytes())?;
    out.write_all(b"\n")?;
    out.flush()
}

/// True when this process was started with stdout closed (`tool >&-`).
///
/// The Rust runtime reopens a closed descriptor 1 on /dev/null before
/// `main` (so no file the tool opens lands there), after which a closed
/// stdout cannot be told from a redirection to /dev/null. So a constructor
/// (`stdout_at_start`, run from `.init_array` before the runtime starts)
/// looks first and remembers. Output that would go there has nowhere to go.
pub fn stdout_closed() -> bool {
    #[cfg(target_os = "linux")]
    {
        stdout_at_start::CLOSED.load(std::sync::atomic::Ordering::Relaxed)
    }
    #[cfg(not(target_os = "linux"))]
    false
}

/// Whether descriptor 1 was open when the process started (Linux:
/// `.init_array` constructors run before the Rust runtime's own set-up).
#[cfg(target_os = "linux")]
mod stdout_at_start {
    use std::sync::atomic::{AtomicBool, Ordering};

    pub static CLOSED: AtomicBool = AtomicBool::new(false);

    extern "C" fn check() {
        // SAFETY: F_GETFD only asks whether the descriptor is open.
        if unsafe { libc::fcntl(1, libc::F_GETFD) } == -1 {
            CLOSED.store(true, Ordering::Relaxed);
        }
    }

    #[used]
    #[unsafe(link_section = ".init_array")]
    static CHECK: extern "C" fn() = check;
}

/// Write held-back output to stdout: the spilled part by the kernel's
/// file-to-file copy (`io::copy` between two `File`s uses copy_file_range,
/// sendfile or splice on Linux), then the in-memory tail in one write.
fn write_stdout(mem: &[u8], spill: Option<File>) -> Result<(), CliError> {
    if stdout_closed() {
        return Err(CliError::failure(
            "standard output is closed: the output had nowhere to go (nothing written)",
        ));
    }
    let stdout = io::stdout();
    let mut lock = stdout.lock();
    lock.flush()?;
    #[cfg(unix)]
    {
        use std::os::fd::AsFd;
        if let Ok(fd) = lock.as_fd().try_clone_to_owned() {
            let mut out = File::from(fd);
            if let Some(mut f) = spill {
                f.seek(SeekFrom::Start(0))?;
                io::copy(&mut f, &mut out)?;
            }
            out.write_all(mem)?;
            return Ok(());
        }
    }
    if let Some(mut f) = spill {
        f.seek(SeekFrom::Start(0))?;
        io::copy(&mut f, &mut lock)?;
    }
    lock.write_all(mem)?;
    lock.flush()?;
    Ok(())
}

impl Write for Output {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        match &mut self.sink {
            Sink::Broken(msg) => Err(io::Error::other(msg.clone())),
            Sink::File { tmp, .. } => write_through(tmp, buf),
            Sink::Special(w) => write_through(w, buf),
            Sink::Stdout { mem, spill } => {
                mem.extend_from_slice(buf);
                if mem.len() >= SPILL_BYTES {
                    if spill.is_none() {
                        *spill = Some(tempfile::tempfile()?);
                    }
                    if let Some(f) = spill.as_mut() {
                        f.write_all(mem)?;
                    }
                    mem.clear();
                }
                Ok(buf.len())
            }
        }
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// A write of at least this many bytes skips the buffer (see
/// [`write_through`]).
const THROUGH_BYTES: usize = 1 << 16;

/// Write `buf` through `w`: a large block (a batch of records formatted on
/// several threads, some 200 KB each in `dxf2chains`) goes straight to the
/// destination once what is buffered before it has gone, instead of being
/// copied into the buffer first. `BufWriter` does that only for blocks as
/// large as its whole buffer (1 MiB here); copying the 42 MB of text of the
/// mix benchmark into it cost about 5 ms of a core. Order is kept: the
/// buffer is flushed first.
fn write_through<W: Write>(w: &mut io::BufWriter<W>, buf: &[u8]) -> io::Result<usize> {
    if buf.len() >= THROUGH_BYTES {
        w.flush()?;
        return w.get_mut().write(buf);
    }
    w.write(buf)
}

/// Read all of an input into a string, naming it on failure.
pub fn read_to_string(input: &mut Input) -> Result<String, CliError> {
    let mut s = String::new();
    input
        .reader
        .read_to_string(&mut s)
        .map_err(|e| CliError::input(format!("{}: {e}", input.name)))?;
    Ok(s)
}

/// `N` comma-separated finite numbers for option `opt` (`form` names them
/// in the message, e.g. `"X,Y,Z"`). NaN and infinities are bad input: no
/// coordinate or size means them.
///
/// ```
/// use microcam::cli::parse_numbers;
/// assert_eq!(parse_numbers::<3>("1, -2,3.5", "--start", "X,Y,Z").unwrap(), [1.0, -2.0, 3.5]);
/// assert!(parse_numbers::<3>("1,2", "--start", "X,Y,Z").is_err());
/// assert!(parse_numbers::<2>("nan,1", "--at", "X,Y").is_err());
/// ```
pub fn parse_numbers<const N: usize>(s: &str, opt: &str, form: &str) -> Result<[f64; N], CliError> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| CliError::input(format!("{opt} '{s}': {e}")))?;
    if let Some(bad) = v.iter().find(|x| !x.is_finite()) {
        return Err(CliError::input(format!("{opt} '{s}': {bad} is not a finite number")));
    }
    v.try_into()
        .map_err(|_| CliError::input(format!("{opt} '{s}': {N} numbers {form}")))
}

#[cfg(test)]
mod numeric_argument_tests {
    use super::check_numeric_arguments;

    fn check(args: &[&str]) -> Result<(), String> {
        let v: Vec<String> = args.iter().map(|s| s.to_string()).collect();
        check_numeric_arguments(&v).map_err(|e| e.message)
    }

    #[test]
    fn finite_numbers_names_and_paths_pass() {
        assert!(
            check(&[
                "--feed",
                "2.5",
                "--stock",
                "0,0,-1,4,3,0",
                "--tool",
                "ball:2",
                "--holder",
                "6:20",
                "--host",
                "127.0.0.1:1025",
                "part.ngc"
            ])
            .is_ok()
        );
        assert!(
            check(&[
                "--start=-5,0,0",
                "--polygon",
                "0,0;4,0;4,3",
                "-",
                "--shutter-var",
                "M33"
            ])
            .is_ok()
        );
        assert!(check(&["--seed", "18446744073709551615", "--levels", "-1e11"]).is_ok());
    }

    #[test]
    fn non_finite_and_huge_numbers_are_refused_with_the_flag_named() {
        for (args, flag) in [
            (&["--feed", "nan"][..], "--feed"),
            (&["--radius", "inf"][..], "--radius"),
            (&["--stock", "0,0,-inf,1,1,0"][..], "--stock"),
            (&["--duration=1e308"][..], "--duration"),
            (&["--turns", "1e999"][..], "--turns"),
            (&["--z", "-1e13"][..], "--z"),
            (&["--holder", "1e308:20"][..], "--holder"),
            (&["--holder", "6:nan"][..], "--holder"),
        ] {
            let e = check(args).unwrap_err();
            assert!(e.contains(flag), "{e}");
        }
    }
}

/// Read one text line into `buf`, ending at LF, CR or CRLF (the ending is
/// kept in `buf`), so files written on any system, or with mixed endings,
/// read line for line. Returns the bytes consumed; 0 at end of input.
/// Every line-based reader (G-code of both dialects, the JSON Lines
/// formats) reads through this.
pub fn read_line_any_ending<R: BufRead + ?Sized>(input: &mut R, buf: &mut Vec<u8>) -> io::Result<usize> {
    let mut total = 0;
    loop {
        let (end, used) = {
            let avail = match input.fill_buf() {
                Ok(b) => b,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(e),
            };
            if avail.is_empty() {
                return Ok(total);
            }
            match memchr::memchr2(b'\n', b'\r', avail) {
                Some(i) => {
                    buf.extend_from_slice(&avail[..=i]);
                    (Some(avail[i]), i + 1)
                }
                None => {
                    buf.extend_from_slice(avail);
                    (None, avail.len())
                }
            }
        };
        input.consume(used);
        total += used;
        match end {
            None => continue,
            Some(b'\r') => loop {
                // CRLF is one line end: take the LF with the CR.
                match input.fill_buf() {
                    Ok(b) => {
                        if b.first() == Some(&b'\n') {
                            buf.push(b'\n');
                            input.consume(1);
                            total += 1;
                        }
                        return Ok(total);
                    }
                    Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                    Err(e) => return Err(e),
                }
            },
            Some(_) => return Ok(total),
        }
    }
}

#[cfg(test)]
mod io_tests {
    use super::{THROUGH_BYTES, read_line_any_ending, write_through};
    use std::io;

    fn lines(text: &[u8], cap: usize) -> Vec<Vec<u8>> {
        // A tiny buffer capacity puts CR and LF of one CRLF in different
        // fills, as a pipe may.
        let mut r = std::io::BufReader::with_capacity(cap, text);
        let mut out = Vec::new();
        loop {
            let mut b = Vec::new();
            if read_line_any_ending(&mut r, &mut b).unwrap() == 0 {
                return out;
            }
            out.push(b);
        }
    }

    #[test]
    fn lf_cr_crlf_and_mixed_endings_all_end_a_line() {
        for cap in [1, 2, 3, 64] {
            let got = lines(b"a\nb\rc\r\nd\r\re\n\nf", cap);
            let want: Vec<&[u8]> = vec![b"a\n", b"b\r", b"c\r\n", b"d\r", b"\r", b"e\n", b"\n", b"f"];
            assert_eq!(got, want, "buffer capacity {cap}");
        }
        assert!(lines(b"", 8).is_empty());
    }

    #[test]
    fn large_writes_go_through_in_order() {
        // Small, large, small, large, large: the large ones skip the
        // buffer but never overtake what was buffered before them.
        let mut w = io::BufWriter::with_capacity(1 << 20, Vec::new());
        let mut want = Vec::new();
        for (k, n) in [10usize, THROUGH_BYTES, 3, 2 * THROUGH_BYTES + 1, THROUGH_BYTES, 7]
            .into_iter()
            .enumerate()
        {
            let block = vec![b'a' + k as u8; n];
            let mut rest = &block[..];
            while !rest.is_empty() {
                let m = write_through(&mut w, rest).unwrap();
                assert!(m > 0);
                rest = &rest[m..];
            }
            want.extend_from_slice(&block);
        }
        assert_eq!(w.into_inner().unwrap(), want);
    }
}
