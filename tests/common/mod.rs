//! Helpers the end-to-end tests share: where the binaries are and how one
//! is run with arguments and standard input. `mod common;` in a test file.
#![allow(dead_code)] // each test file uses some of them

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

/// The package's binaries, as cargo built them for this test run.
pub const GSIM: &str = env!("CARGO_BIN_EXE_gsim");
pub const PATHGEN: &str = env!("CARGO_BIN_EXE_pathgen");
pub const DXF2CHAINS: &str = env!("CARGO_BIN_EXE_dxf2chains");
pub const FEEDOPT: &str = env!("CARGO_BIN_EXE_feedopt");
pub const PLOUGH2D: &str = env!("CARGO_BIN_EXE_plough2d");
pub const STLVERIFY: &str = env!("CARGO_BIN_EXE_stlverify");
pub const PROBESCAN: &str = env!("CARGO_BIN_EXE_probescan");
pub const PMAC_SEND: &str = env!("CARGO_BIN_EXE_pmac-send");
pub const PMAC_EMU: &str = env!("CARGO_BIN_EXE_pmac-emu");

/// Every binary of the package, by name.
pub const BINARIES: [&str; 9] = [
    "dxf2chains",
    "feedopt",
    "gsim",
    "pathgen",
    "plough2d",
    "pmac-emu",
    "pmac-send",
    "probescan",
    "stlverify",
];

/// The path of binary `name` (built beside the others).
pub fn bin(name: &str) -> PathBuf {
    Path::new(GSIM).parent().expect("a folder").join(name)
}

/// Run `bin` with `args` in the package folder, `stdin` written to it (or
/// nothing: stdin closed), and collect its output.
pub fn run(bin: &str, args: &[&str], stdin: Option<&str>) -> Output {
    run_bytes(bin, args, stdin.map(str::as_bytes))
}

/// [`run`] with any bytes on stdin. The bytes are written from a thread,
/// so a child that answers before reading them all cannot deadlock the
/// test, and a child that refuses before reading is not an error.
pub fn run_bytes(bin: &str, args: &[&str], stdin: Option<&[u8]>) -> Output {
    let mut child = Command::new(bin)
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn");
    let mut input = child.stdin.take().expect("stdin");
    let data = stdin.map(<[u8]>::to_vec);
    let feeder = std::thread::spawn(move || {
        if let Some(d) = data {
            let _ = input.write_all(&d);
        }
    });
    let out = child.wait_with_output().expect("wait");
    feeder.join().expect("feeder");
    out
}

/// The long flags a `--help` text lists (without the dashes), in order.
pub fn help_flags(help: &str) -> Vec<String> {
    help.lines()
        .filter_map(|l| {
            let t = l.trim_start();
            let t = t
                .strip_prefix("-")
                .filter(|r| r.len() > 2 && r.as_bytes()[1] == b',')
                .map_or(t, |r| r[2..].trim_start());
            let name: String = t
                .strip_prefix("--")?
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '-')
                .collect();
            (!name.is_empty()).then_some(name)
        })
        .collect()
}
