//! End-to-end checks of the manners every binary shares: help with
//! examples, exit codes, errors that name the file and line, nothing on
//! stdout (or in an -o file) when a run fails, identical output for
//! identical input.

use std::path::Path;
use std::process::{Command, Stdio};

mod common;

use common::run;

const GSIM: &str = env!("CARGO_BIN_EXE_gsim");
const PATHGEN: &str = env!("CARGO_BIN_EXE_pathgen");

#[test]
fn help_teaches_with_examples() {
    for (bin, args) in [(GSIM, vec!["-h"]), (PATHGEN, vec!["-h"]), (PATHGEN, vec!["emit", "-h"])] {
        let o = run(bin, &args, None);
        assert_eq!(o.status.code(), Some(0));
        let text = String::from_utf8_lossy(&o.stdout);
        assert!(text.contains("Examples:"), "{bin} {args:?}: {text}");
    }
}

#[test]
fn bad_usage_and_bad_input_exit_2_and_name_the_problem() {
    let o = run(GSIM, &["--dialect", "fanuc", "x.ngc"], None);
    assert_eq!(o.status.code(), Some(2));
    let o = run(GSIM, &["no/such/file.ngc"], None);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("no/such/file.ngc"));
    assert!(o.stdout.is_empty());
    let o = run(GSIM, &["--moves", "-"], Some("G0 X1\nG0 X2\nG2 X3 F1\n"));
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.starts_with("gsim: <stdin>:3: "), "{err}");
    assert!(
        o.stdout.is_empty(),
        "half-written output: {}",
        String::from_utf8_lossy(&o.stdout)
    );
}

#[test]
fn a_failed_run_leaves_no_output_file_and_keeps_an_old_one() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("moves.jsonl");
    let out_s = out.to_str().unwrap();
    // Long enough that the bad line comes after plenty of output.
    let mut prog: String = (0..20_000).map(|i| format!("G0 X{i}\n")).collect();
    prog.push_str("G1 X0\n");
    let o = run(GSIM, &["--moves", "-o", out_s, "-"], Some(&prog));
    assert_eq!(o.status.code(), Some(2));
    assert!(!out.exists(), "a failed run must not leave a file");
    std::fs::write(&out, "old\n").unwrap();
    let o = run(GSIM, &["--moves", "-o", out_s, "-"], Some(&prog));
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "old\n");
    let o = run(GSIM, &["--moves", "-o", out_s, "-"], Some("G0 X1\n"));
    assert_eq!(o.status.code(), Some(0));
    assert!(std::fs::read_to_string(&out).unwrap().contains("\"to\":[1,0,0]"));
    // Large outputs to stdout spill to disk and still arrive whole.
    let big: String = (0..300_000).map(|i| format!("G0 X{i}\n")).collect();
    let o = run(GSIM, &["--moves", "-"], Some(&big));
    assert_eq!(o.status.code(), Some(0));
    assert_eq!(o.stdout.iter().filter(|&&b| b == b'\n').count(), 300_001);
}

#[test]
fn devices_and_symlinks_are_written_in_place() {
    let dir = tempfile::tempdir().unwrap();
    // -o /dev/stdout with stdout redirected to a regular file: the system's
    // /dev/stdout link must survive and the data reach the file.
    let target = dir.path().join("out.jsonl");
    let f = std::fs::File::create(&target).unwrap();
    let status = Command::new(GSIM)
        .args(["--moves", "-o", "/dev/stdout", "testdata/gcode/badge.ngc"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(f)
        .status()
        .unwrap();
    assert!(status.success());
    assert!(
        std::fs::symlink_metadata("/dev/stdout")
            .unwrap()
            .file_type()
            .is_symlink()
            || !Path::new("/dev/stdout").is_file()
    );
    assert!(
        std::fs::read_to_string(&target)
            .unwrap()
            .contains("microcam.toolpath/1")
    );
    // A symlink to a file: the file is replaced, the link kept.
    #[cfg(unix)]
    {
        let real = dir.path().join("real.jsonl");
        let link = dir.path().join("link.jsonl");
        std::fs::write(&real, "old\n").unwrap();
        std::os::unix::fs::symlink(&real, &link).unwrap();
        let o = run(
            GSIM,
            &["--moves", "-o", link.to_str().unwrap(), "testdata/gcode/badge.ngc"],
            None,
        );
        assert_eq!(o.status.code(), Some(0));
        assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
        assert!(std::fs::read_to_string(&real).unwrap().contains("microcam.toolpath/1"));
    }
}

/// Diagnostics are not data: a tool whose stderr cannot be written (a pipe
/// whose reader has gone, as in `2>&1 | head -1`) still writes its output
/// and exits 0. `eprintln!` panics on a failed write, which ended such
/// runs with status 101 and nothing written.
#[test]
fn a_closed_stderr_does_not_stop_a_run() {
    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dome = root.join("testdata/samples/dome.stl");
    let part = root.join("testdata/samples/part.dxf");
    let cl = dir.path().join("dome.cl");
    let chains = dir.path().join("part.jsonl");
    let runs: Vec<(&str, Vec<&std::ffi::OsStr>, &Path)> = vec![
        (
            PATHGEN,
            [
                "dropcutter",
                "--tool",
                "flat:1",
                "--step-over",
                "0.5",
                "--five-axis",
                "-o",
            ]
            .iter()
            .map(std::ffi::OsStr::new)
            .chain([cl.as_os_str(), dome.as_os_str()])
            .collect(),
            &cl,
        ),
        (
            env!("CARGO_BIN_EXE_dxf2chains"),
            vec![part.as_os_str(), "-o".as_ref(), chains.as_os_str()],
            &chains,
        ),
    ];
    for (bin, args, out) in runs {
        let mut child = Command::new(bin)
            .args(&args)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // Close the read end before the tool writes a word.
        drop(child.stderr.take());
        let status = child.wait().unwrap();
        assert_eq!(status.code(), Some(0), "{bin} {args:?}");
        assert!(std::fs::metadata(out).unwrap().len() > 100, "{bin}: {}", out.display());
    }
}

#[test]
fn identical_input_gives_identical_output() {
    let prog = Path::new("testdata/gcode/encoder-disc.ngc").to_str().unwrap();
    let a = run(GSIM, &["--moves", prog], None);
    let b = run(GSIM, &["--moves", prog], None);
    assert_eq!(a.status.code(), Some(0));
    assert_eq!(a.stdout, b.stdout);
    let pa = run(PATHGEN, &["emit", "--dialect", "pmac", prog], None);
    let pb = run(PATHGEN, &["emit", "--dialect", "pmac", prog], None);
    assert_eq!(pa.status.code(), Some(0));
    assert_eq!(pa.stdout, pb.stdout);
}

/// Pinned workers (`MICROCAM_PIN_THREADS=1`) change where threads run,
/// never what they compute: the same bytes as with rayon's own pool.
#[test]
fn pinned_workers_give_the_same_output() {
    let dxf = Path::new("testdata/samples/blocks.dxf").to_str().unwrap();
    let bin = env!("CARGO_BIN_EXE_dxf2chains");
    let plain = run(bin, &[dxf], None);
    let pinned = Command::new(bin)
        .arg(dxf)
        .env("MICROCAM_PIN_THREADS", "1")
        .output()
        .unwrap();
    assert_eq!(plain.status.code(), Some(0));
    assert_eq!(
        pinned.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&pinned.stderr)
    );
    assert!(!plain.stdout.is_empty());
    assert_eq!(plain.stdout, pinned.stdout);
}

#[test]
fn iso_to_pmac_and_back_keeps_the_path() {
    let prog = "testdata/gcode/badge.ngc";
    let direct = run(GSIM, &[prog], None);
    let pmac = run(PATHGEN, &["emit", "--dialect", "pmac", "--decimals", "6", prog], None);
    assert_eq!(pmac.status.code(), Some(0), "{}", String::from_utf8_lossy(&pmac.stderr));
    let text = String::from_utf8(pmac.stdout).unwrap();
    let back = run(GSIM, &["-"], Some(&text));
    assert_eq!(back.status.code(), Some(0), "{}", String::from_utf8_lossy(&back.stderr));
    let field = |o: &[u8], k: &str| -> f64 {
        let v: serde_json::Value = serde_json::from_slice(o).unwrap();
        v[k].as_f64().unwrap()
    };
    for k in ["feed_length_mm", "rapid_length_mm", "arcs", "lines"] {
        let (a, b) = (field(&direct.stdout, k), field(&back.stdout, k));
        assert!((a - b).abs() <= 1e-4 * a.abs().max(1.0), "{k}: {a} vs {b}");
    }
}

const FEEDOPT: &str = env!("CARGO_BIN_EXE_feedopt");

/// Files in `dir`, hidden ones included, sorted.
fn listing(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn all_outputs_of_a_run_appear_together_or_not_at_all() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let p = |n: &str| d.join(n).to_str().unwrap().to_string();
    let prog = "G21 G90\nG0 X1 Y1\nG1 X5 F300\nG1 Y4\n";
    // gsim: the block CSV and the report are fine, the SVG cannot be
    // written: neither appears.
    let bad = "/nonexistent-dir/x.svg";
    for args in [
        vec!["--blocks", &p("b.csv"), "--svg", bad, "-o", &p("r.json"), "-"],
        vec![
            "--svg",
            &p("s.svg"),
            "--blocks",
            &p("b.csv"),
            "-o",
            "/nonexistent-dir/r.json",
            "-",
        ],
        vec!["--moves", "--svg", &p("s.svg"), "-o", "/nonexistent-dir/m.jsonl", "-"],
    ] {
        let o = run(GSIM, &args, Some(prog));
        assert_eq!(
            o.status.code(),
            Some(1),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(String::from_utf8_lossy(&o.stderr).contains("nonexistent-dir"));
        assert!(listing(d).is_empty(), "{args:?} left {:?}", listing(d));
    }
    // The same run with every destination writable: all of them appear.
    let o = run(
        GSIM,
        &["--blocks", &p("b.csv"), "--svg", &p("s.svg"), "-o", &p("r.json"), "-"],
        Some(prog),
    );
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(listing(d), ["b.csv", "r.json", "s.svg"]);
    // feedopt: program, report, CSV and PNG together, or nothing when the
    // last one cannot be written.
    let prog = "G21 G90\nS60000 M3\nG0 X-1 Y0 Z1\nG1 Z-0.05 F120\nG1 X1 F120\nG0 Z1\nM30\n";
    let e = tempfile::tempdir().unwrap();
    let q = |n: &str| e.path().join(n).to_str().unwrap().to_string();
    let base = ["--tool", "flat:0.5", "--stock", "-2,-2,-1,2,2,0", "--cell-mm", "0.02"];
    let mut args: Vec<String> = base.iter().map(|s| s.to_string()).collect();
    for (k, v) in [("-o", q("o.ngc")), ("--report", q("r.json")), ("--csv", q("s.csv"))] {
        args.push(k.into());
        args.push(v);
    }
    let mut bad = args.clone();
    bad.extend(["--png".into(), "/nonexistent-dir/p.png".into(), "-".into()]);
    let o = run(FEEDOPT, &bad.iter().map(String::as_str).collect::<Vec<_>>(), Some(prog));
    assert_eq!(o.status.code(), Some(1), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(listing(e.path()).is_empty(), "{:?}", listing(e.path()));
    args.extend(["--png".into(), q("p.png"), "-".into()]);
    let o = run(
        FEEDOPT,
        &args.iter().map(String::as_str).collect::<Vec<_>>(),
        Some(prog),
    );
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(listing(e.path()), ["o.ngc", "p.png", "r.json", "s.csv"]);
}

/// Start `bin args` writing `-o dir/out`, feed it `head` on stdin, wait
/// until its hidden temporary file exists, send `signal`, and return what
/// is left in `dir` and how the process ended.
fn interrupted(bin: &str, args: &[&str], head: &[u8], signal: &str) -> (Vec<String>, std::process::ExitStatus) {
    use std::io::Write;
    use std::os::unix::process::CommandExt;
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let mut cmd = Command::new(bin);
    // A test run in the background inherits SIGINT ignored; the tool
    // rightly keeps an ignored signal ignored, so give it the default.
    // SAFETY: signal() is async-signal-safe, as pre_exec requires.
    unsafe {
        cmd.pre_exec(|| {
            libc::signal(libc::SIGINT, libc::SIG_DFL);
            libc::signal(libc::SIGTERM, libc::SIG_DFL);
            Ok(())
        });
    }
    let mut child = cmd
        .args(args)
        .args(["-o", out.to_str().unwrap(), "-"])
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    stdin.write_all(head).unwrap();
    stdin.flush().unwrap();
    let t0 = std::time::Instant::now();
    while listing(dir.path()).is_empty() {
        assert!(t0.elapsed().as_secs() < 30, "{bin}: no temporary file appeared");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    // The run is under way (stdin still open: it waits for more input).
    let k = Command::new("kill")
        .args([signal, &child.id().to_string()])
        .status()
        .unwrap();
    assert!(k.success());
    let status = child.wait().unwrap();
    drop(stdin);
    (listing(dir.path()), status)
}

#[test]
fn an_interrupted_run_leaves_no_hidden_temporary_file() {
    use std::os::unix::process::ExitStatusExt;
    let prog: String = (0..200_000)
        .map(|i| format!("G1 X{} Y{} F600\n", i % 100, i % 37))
        .collect();
    let moves = run(GSIM, &["--moves", "-"], Some(&prog));
    assert_eq!(moves.status.code(), Some(0));
    let toolpath = moves.stdout;
    for (signal, number) in [("-INT", 2), ("-TERM", 15)] {
        let (left, status) = interrupted(GSIM, &["--moves"], prog.as_bytes(), signal);
        assert!(left.is_empty(), "gsim {signal}: left {left:?}");
        assert_eq!(status.signal(), Some(number), "gsim ends by the signal");
        let (left, status) = interrupted(PATHGEN, &["emit", "--dialect", "pmac"], &toolpath, signal);
        assert!(left.is_empty(), "pathgen emit {signal}: left {left:?}");
        assert_eq!(status.signal(), Some(number));
    }
}

#[test]
fn writing_to_a_closed_stdout_fails_with_a_message() {
    let dir = tempfile::tempdir().unwrap();
    let prog = dir.path().join("p.ngc");
    std::fs::write(&prog, "G21 G90\nG1 X5 F300\n").unwrap();
    let svg = dir.path().join("s.svg");
    let sh = |cmd: &str| {
        Command::new("sh")
            .args([
                "-c",
                cmd,
                "sh",
                GSIM,
                PATHGEN,
                prog.to_str().unwrap(),
                svg.to_str().unwrap(),
            ])
            .output()
            .unwrap()
    };
    for cmd in [
        r#""$1" --moves "$3" >&-"#,
        r#""$1" --moves --svg "$4" "$3" >&-"#,
        r#""$1" --moves "$3" | "$2" emit --dialect iso >&-"#,
    ] {
        let o = sh(cmd);
        assert_eq!(o.status.code(), Some(1), "{cmd}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains("standard output is closed"), "{cmd}: {err}");
        assert!(!svg.exists(), "{cmd}: the SVG appeared without the program");
    }
    // To /dev/null is a destination, not a closed stdout, also opened
    // read-write (as Python's subprocess.DEVNULL does).
    for cmd in [r#""$1" --moves "$3" >/dev/null"#, r#""$1" --moves "$3" 1<>/dev/null"#] {
        let o = sh(cmd);
        assert_eq!(
            o.status.code(),
            Some(0),
            "{cmd}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
}

#[test]
fn make_install_puts_binaries_man_pages_and_completions_under_a_prefix() {
    let prefix = tempfile::tempdir().unwrap();
    let bin_dir = Path::new(GSIM).parent().unwrap();
    let o = Command::new(Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/install"))
        .args([
            "--prefix",
            prefix.path().to_str().unwrap(),
            "--bin-dir",
            bin_dir.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let p = |s: &str| prefix.path().join(s);
    let read = |s: &str| std::fs::read_to_string(p(s)).unwrap_or_else(|e| panic!("{s}: {e}"));
    for t in [
        "dxf2chains",
        "pathgen",
        "gsim",
        "feedopt",
        "plough2d",
        "stlverify",
        "probescan",
        "pmac-send",
        "pmac-emu",
    ] {
        let v = Command::new(p(&format!("bin/{t}"))).arg("--version").output().unwrap();
        assert!(
            v.status.success() && String::from_utf8_lossy(&v.stdout).starts_with(t),
            "{t} --version"
        );
        assert!(
            read(&format!("share/man/man1/{t}.1")).contains(&format!(".TH {t}")),
            "{t}.1"
        );
        assert!(read(&format!("share/bash-completion/completions/{t}")).contains("complete"));
        assert!(read(&format!("share/zsh/site-functions/_{t}")).contains(&format!("#compdef {t}")));
        assert!(read(&format!("share/fish/vendor_completions.d/{t}.fish")).contains(&format!("complete -c {t}")));
    }
    // A page per subcommand, and the flags of the real definition.
    assert!(read("share/man/man1/pathgen-contour.1").contains("offset"));
    assert!(read("share/man/man1/feedopt.1").contains("png"));
    assert!(read("share/bash-completion/completions/gsim").contains("--moves"));
}
