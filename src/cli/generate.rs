//! Man pages and shell completions from each tool's own clap definition.
//!
//! Every binary parses its command line with [`parse`], which first answers
//! two hidden requests and exits:
//!
//! - `TOOL --generate-man DIR`: `TOOL.1`, and `TOOL-SUB.1` for each
//!   subcommand, into DIR (clap_mangen);
//! - `TOOL --generate-completions SHELL DIR`: the completion script for
//!   SHELL (`bash`, `zsh`, `fish`, `elvish`, `powershell`, or `all` for the
//!   first three) into DIR under clap_complete's file names (`TOOL.bash`,
//!   `_TOOL`, `TOOL.fish`, ...).
//!
//! So the pages can never drift from the flags the binary really takes,
//! and the binaries stay thin: one call in `main`. `make install`
//! (scripts/install) runs these for every tool.

use clap::{Command, Parser};
use clap_complete::Shell;
use std::ffi::OsString;
use std::path::Path;

/// Parse the command line as `P`, after answering `--generate-man` and
/// `--generate-completions` (which exit).
pub fn parse<P: Parser>() -> P {
    let argv: Vec<OsString> = std::env::args_os().collect();
    if let Some(code) = answer(P::command(), &argv) {
        std::process::exit(code);
    }
    P::parse()
}

/// If `argv` (with the program name first) is a generation request, carry
/// it out for `cmd` and return the exit status (0 done, 1 failed to write,
/// 2 bad usage); otherwise `None`.
pub fn answer(cmd: Command, argv: &[OsString]) -> Option<i32> {
    let name = cmd.get_name().to_string();
    let (status, msg) = match argv.get(1).and_then(|a| a.to_str())? {
        "--generate-man" => match argv.get(2..) {
            Some([dir]) => match man(cmd, Path::new(dir)) {
                Ok(()) => return Some(0),
                Err(e) => (1, format!("{}: {e}", Path::new(dir).display())),
            },
            _ => (2, "usage: --generate-man DIR".to_string()),
        },
        "--generate-completions" => match argv.get(2..) {
            Some([shell, dir]) => match shells(&shell.to_string_lossy()) {
                Some(list) => match completions(cmd, &list, Path::new(dir)) {
                    Ok(()) => return Some(0),
                    Err(e) => (1, format!("{}: {e}", Path::new(dir).display())),
                },
                None => (
                    2,
                    format!(
                        "--generate-completions: unknown shell '{}' (bash, zsh, fish, elvish, powershell or all)",
                        shell.to_string_lossy()
                    ),
                ),
            },
            _ => (2, "usage: --generate-completions SHELL DIR".to_string()),
        },
        _ => return None,
    };
    crate::diag!("{name}: {msg}");
    Some(status)
}

fn shells(s: &str) -> Option<Vec<Shell>> {
    match s {
        "all" => Some(vec![Shell::Bash, Shell::Zsh, Shell::Fish]),
        "bash" => Some(vec![Shell::Bash]),
        "zsh" => Some(vec![Shell::Zsh]),
        "fish" => Some(vec![Shell::Fish]),
        "elvish" => Some(vec![Shell::Elvish]),
        "powershell" => Some(vec![Shell::PowerShell]),
        _ => None,
    }
}

/// Write the man pages of `cmd` and its subcommands into `dir`.
pub fn man(cmd: Command, dir: &Path) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    clap_mangen::generate_to(cmd, dir)
}

/// Write completion scripts of `cmd` for `shells` into `dir`.
pub fn completions(mut cmd: Command, shells: &[Shell], dir: &Path) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let name = cmd.get_name().to_string();
    for &s in shells {
        clap_complete::generate_to(s, &mut cmd, &name, dir)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Subcommand;

    /// A tool with a subcommand.
    #[derive(Parser)]
    #[command(name = "demo-tool", version, about = "Does a demo.")]
    struct Demo {
        #[command(subcommand)]
        cmd: Sub,
    }

    #[derive(Subcommand)]
    enum Sub {
        /// Cut a contour.
        Contour {
            /// Offset, mm.
            #[arg(long)]
            offset: f64,
        },
    }

    fn argv(a: &[&str]) -> Vec<OsString> {
        a.iter().map(OsString::from).collect()
    }

    #[test]
    fn pages_and_completions_come_from_the_definition() {
        use clap::CommandFactory;
        let d = tempfile::tempdir().unwrap();
        let dir = d.path().to_str().unwrap();
        assert_eq!(answer(Demo::command(), &argv(&["demo-tool", "x"])), None);
        assert_eq!(answer(Demo::command(), &argv(&["demo-tool"])), None);
        assert_eq!(
            answer(Demo::command(), &argv(&["demo-tool", "--generate-man", dir])),
            Some(0)
        );
        let page = std::fs::read_to_string(d.path().join("demo-tool.1")).unwrap();
        assert!(
            page.contains(".TH demo-tool") && page.contains("Does a demo."),
            "{page}"
        );
        let sub = std::fs::read_to_string(d.path().join("demo-tool-contour.1")).unwrap();
        assert!(sub.contains("offset"), "{sub}");
        assert_eq!(
            answer(
                Demo::command(),
                &argv(&["demo-tool", "--generate-completions", "all", dir])
            ),
            Some(0)
        );
        let bash = std::fs::read_to_string(d.path().join("demo-tool.bash")).unwrap();
        assert!(bash.contains("complete") && bash.contains("--offset"));
        assert!(d.path().join("_demo-tool").exists() && d.path().join("demo-tool.fish").exists());
        assert_eq!(
            answer(
                Demo::command(),
                &argv(&["demo-tool", "--generate-completions", "tcsh", dir])
            ),
            Some(2)
        );
        assert_eq!(
            answer(Demo::command(), &argv(&["demo-tool", "--generate-man"])),
            Some(2)
        );
    }
}
