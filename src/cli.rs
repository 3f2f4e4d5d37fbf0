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
}

impl CliError {
    /// Bad input or usage: exit status 2.
    pub fn input(message: impl Into<String>) -> Self {
        CliError {
            status: 2,
            message: message.into(),
        }
    }

    /// The job could not be done: exit status 1.
    pub fn failure(message: impl Into<String>) -> Self {
        CliError {
            status: 1,
            message: message.into(),
        }
    }

    /// An input error located in `source` (a file name or `<stdin>`).
    pub fn in_file(source: &str, err: impl std::fmt::Display) -> Self {
        CliError::input(format!("{source}:{err}").replacen(":line ", ":", 1))
    }
}

impl From<io::Error> for CliError {
    fn from(e: io::Error) -> Self {
        CliError::failure(e.to_string())
    }
}

/// Run a tool's body and turn its outcome into an exit status, printing
/// `tool: message` on stderr for errors. A closed stdout (`| head`) is not
/// an error worth a message.
pub fn run(tool: &str, body: impl FnOnce() -> Result<(), CliError>) -> ExitCode {
    match body() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if e.message.contains("Broken pipe") => ExitCode::from(e.status),
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
/// leaves no half-written output. Up to `SPILL_BYTES` are held in memory;
/// beyond that the output spills to a temporary file, so memory stays flat.
pub struct Output {
    dest: Option<PathBuf>,
    mem: Vec<u8>,
    spill: Option<File>,
}

const SPILL_BYTES: usize = 32 << 20;

impl Output {
    /// `None` or `-` is stdout.
    pub fn new(path: Option<&Path>) -> Output {
        let dest = path.filter(|p| p.as_os_str() != "-").map(Path::to_path_buf);
        Output {
            dest,
            mem: Vec::with_capacity(1 << 16),
            spill: None,
        }
    }

    /// Make the output appear at its destination.
    pub fn commit(mut self) -> Result<(), CliError> {
        match self.dest.take() {
            None => {
                let stdout = io::stdout();
                let mut lock = stdout.lock();
                if let Some(mut f) = self.spill.take() {
                    f.write_all(&self.mem)?;
                    f.seek(SeekFrom::Start(0))?;
                    let mut r = BufReader::with_capacity(1 << 20, f);
                    io::copy(&mut r, &mut lock)?;
                } else {
                    lock.write_all(&self.mem)?;
                }
                lock.flush()?;
            }
            Some(path) => {
                let dir = path
                    .parent()
                    .filter(|d| !d.as_os_str().is_empty())
                    .unwrap_or(Path::new("."));
                let mut tmp = tempfile::NamedTempFile::new_in(dir)
                    .map_err(|e| CliError::failure(format!("{}: {e}", path.display())))?;
                if let Some(mut f) = self.spill.take() {
                    f.write_all(&self.mem)?;
                    f.seek(SeekFrom::Start(0))?;
                    let mut r = BufReader::with_capacity(1 << 20, f);
                    io::copy(&mut r, &mut tmp)?;
                } else {
                    tmp.write_all(&self.mem)?;
                }
                tmp.persist(&path)
                    .map_err(|e| CliError::failure(format!("{}: {e}", path.display())))?;
            }
        }
        Ok(())
    }
}

impl Write for Output {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.mem.extend_from_slice(buf);
        if self.mem.len() >= SPILL_BYTES {
            if self.spill.is_none() {
                self.spill = Some(tempfile::tempfile()?);
            }
            if let Some(f) = self.spill.as_mut() {
                f.write_all(&self.mem)?;
            }
            self.mem.clear();
        }
        Ok(buf.len())
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
