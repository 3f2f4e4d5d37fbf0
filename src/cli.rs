//! Command-line conventions every binary shares: `-` for stdin/stdout,
//! outputs that appear whole or not at all, exit codes (0 ok, 1 failure,
//! 2 bad usage or bad input) and error reports that name the file and line.

use std::fs::File;
use std::io::{self, BufRead, BufReader, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// What went wrong, and which exit status it earns.
#[derive(Debug)]
pub struct CliError {
    /// 1 = the job failed (I/O, a fault), 2 = bad usage or bad input.
    pub status: u8,
    pub message: String,
    /// The reader of our stdout went away (`| head`): the job ends with
    /// status 1 but without a message, as Unix filters do.
    pub broken_pipe: bool,
}

impl CliError {
    /// Bad input or usage: exit status 2.
    pub fn input(message: impl Into<String>) -> Self {
        CliError {
            status: 2,
            message: message.into(),
            broken_pipe: false,
        }
    }

    /// The job could not be done: exit status 1.
    pub fn failure(message: impl Into<String>) -> Self {
        CliError {
            status: 1,
            message: message.into(),
            broken_pipe: false,
        }
    }

    /// An input error located in `source` (a file name or `<stdin>`).
    pub fn in_file(source: &str, err: impl std::fmt::Display) -> Self {
        CliError::input(format!("{source}:{err}").replacen(":line ", ":", 1))
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
/// an error worth a message.
pub fn run(tool: &str, body: impl FnOnce() -> Result<(), CliError>) -> ExitCode {
    match body() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if e.broken_pipe => ExitCode::from(e.status),
        Err(e) => {
            eprintln!("{tool}: {}", e.message);
            ExitCode::from(e.status)
        }
    }
}

/// An input named on the command line: a path, or `-`/absent for stdin.
pub struct Input {
    /// How to name it in messages.
    pub name: String,
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
                        tmp: io::BufWriter::with_capacity(1 << 20, t),
                    },
                    Err(e) => Sink::Broken(format!("{}: {e}", path.display())),
                }
            }
        };
        Output { sink }
    }

    /// Make the output appear at its destination.
    pub fn commit(self) -> Result<(), CliError> {
        match self.sink {
            Sink::Broken(msg) => Err(CliError::failure(msg)),
            Sink::Special(mut w) => {
                w.flush()?;
                Ok(())
            }
            Sink::File { path, tmp } => {
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
                tmp.persist(&path)
                    .map_err(|e| CliError::failure(format!("{}: {e}", path.display())))?;
                Ok(())
            }
            Sink::Stdout { mem, spill } => {
                let stdout = io::stdout();
                let mut lock = stdout.lock();
                if let Some(mut f) = spill {
                    f.write_all(&mem)?;
                    f.seek(SeekFrom::Start(0))?;
                    // A plain File lets io::copy use the kernel's
                    // copy_file_range/splice/sendfile where it can.
                    io::copy(&mut f, &mut lock)?;
                } else {
                    lock.write_all(&mem)?;
                }
                lock.flush()?;
                Ok(())
            }
        }
    }
}

impl Write for Output {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        match &mut self.sink {
            Sink::Broken(msg) => Err(io::Error::other(msg.clone())),
            Sink::File { tmp, .. } => tmp.write(buf),
            Sink::Special(w) => w.write(buf),
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
            match avail.iter().position(|&c| c == b'\n' || c == b'\r') {
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
mod line_ending_tests {
    use super::read_line_any_ending;

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
}
