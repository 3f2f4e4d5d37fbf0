//! One flag vocabulary across the binaries: each shared idea has one name
//! (tolerances `--<what>-tol`, times with their unit `--ta-ms`), the names
//! it replaced are hidden aliases that still work, and no tool lists a
//! retired name as its own.

mod common;

use common::{bin, help_flags, run};

/// The shared ideas under their one name (times and rates with their unit,
/// tolerances `--<what>-tol`).
const IDEAS: &[&str] = &[
    "join-tol",
    "arc-tol",
    "chain-tol",
    "step-over",
    "tool",
    "flutes",
    "step-scale",
    "program",
    "line-counter-var",
    "ta-ms",
    "td-ms",
    "ts-ms",
    "accel-mm-s2",
    "cut-ta-ms",
];

/// Retired spellings: (command, old name, its one name now). No command
/// lists an old name; each still parses, as a hidden alias, where it was.
const RETIRED: &[(&str, &str, &str)] = &[
    ("dxf2chains", "tol", "join-tol"),
    ("gsim", "chain-tol-mm", "chain-tol"),
    ("pathgen arcfit", "tolerance", "arc-tol"),
    ("pathgen pocket", "tolerance", "arc-tol"),
    ("pathgen spiral", "tolerance", "arc-tol"),
    ("pathgen cone", "tolerance", "arc-tol"),
    ("pathgen fill", "stepover", "step-over"),
    ("pathgen pocket", "stepover", "step-over"),
    ("pathgen dropcutter", "cutter", "tool"),
    ("plough2d", "teeth", "flutes"),
    ("plough2d", "scale", "step-scale"),
    ("pmac-send", "prog", "program"),
    ("pmac-send", "line-counter", "line-counter-var"),
    ("pathgen emit", "line-counter", "line-counter-var"),
    ("pathgen contour", "line-counter", "line-counter-var"),
    ("pathgen contour", "ta", "ta-ms"),
    ("pathgen contour", "td", "td-ms"),
    ("pathgen contour", "ts", "ts-ms"),
    ("pathgen contour", "accel", "accel-mm-s2"),
    ("pathgen contour", "cut-ta", "cut-ta-ms"),
];

/// Every command that takes flags: a binary, or pathgen and a subcommand.
fn commands() -> Vec<Vec<&'static str>> {
    let mut v: Vec<Vec<&str>> = common::BINARIES
        .iter()
        .filter(|b| **b != "pathgen")
        .map(|b| vec![*b])
        .collect();
    for s in [
        "emit",
        "contour",
        "helix",
        "spiral",
        "zigzag",
        "cone",
        "arcfit",
        "audit",
        "slice",
        "mesh-info",
        "pocket",
        "dropcutter",
        "fill",
    ] {
        v.push(vec!["pathgen", s]);
    }
    v
}

fn help(cmd: &[&str]) -> String {
    let exe = bin(cmd[0]);
    let mut args: Vec<&str> = cmd[1..].to_vec();
    args.push("--help");
    let o = run(exe.to_str().unwrap(), &args, None);
    assert!(
        o.status.success(),
        "{cmd:?} --help: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8(o.stdout).unwrap()
}

#[test]
fn no_command_lists_a_retired_name_and_old_spellings_still_parse() {
    let mut seen = std::collections::BTreeMap::<&str, usize>::new();
    let retired: Vec<&str> = RETIRED.iter().map(|r| r.1).collect();
    for cmd in commands() {
        let text = help(&cmd);
        let flags = help_flags(&text);
        assert!(flags.len() > 2, "{cmd:?}: no flags found in\n{text}");
        assert!(!text.contains("[aliases:"), "{cmd:?} shows an alias:\n{text}");
        let name = cmd.join(" ");
        for f in &flags {
            // `--scale` of dxf2chains is a geometric scale, another idea.
            let other_idea = name == "dxf2chains" && f == "scale";
            assert!(
                !retired.contains(&f.as_str()) || other_idea,
                "{name} lists the retired name --{f}"
            );
            if let Some(i) = IDEAS.iter().find(|i| **i == f) {
                *seen.entry(i).or_default() += 1;
            }
        }
        for (_, old, new) in RETIRED.iter().filter(|r| r.0 == name) {
            assert!(flags.iter().any(|f| f == new), "{name}: no --{new}");
            let exe = bin(cmd[0]);
            let flag = format!("--{old}");
            let mut args: Vec<&str> = cmd[1..].to_vec();
            args.extend([flag.as_str(), "1", "--help"]);
            let o = run(exe.to_str().unwrap(), &args, None);
            assert!(
                o.status.success(),
                "{name}: --{old} (alias of --{new}) refused: {}",
                String::from_utf8_lossy(&o.stderr)
            );
        }
    }
    // Each idea is offered by some command (a renamed flag cannot vanish),
    // the ones many tools share by all of them under the one name.
    for idea in IDEAS {
        assert!(seen.contains_key(idea), "no command has --{idea}");
    }
    for (idea, at_least) in [
        ("flutes", 3),
        ("tool", 5),
        ("step-over", 4),
        ("arc-tol", 6),
        ("step-scale", 2),
    ] {
        assert!(
            seen[idea] >= at_least,
            "--{idea} in {} commands, expected {at_least}",
            seen[idea]
        );
    }
}

#[test]
fn every_command_teaches_with_examples_that_use_its_own_flags() {
    // An example is copied into a shell as it stands: a flag the command
    // does not take (a renamed one, say) would fail at once.
    let mut known = std::collections::BTreeMap::new();
    let mut texts = Vec::new();
    for cmd in commands() {
        let text = help(&cmd);
        known.insert(cmd.join(" "), help_flags(&text));
        texts.push((cmd.join(" "), text));
    }
    for (name, text) in &texts {
        let examples = text
            .split_once("Examples:")
            .unwrap_or_else(|| panic!("{name}: no examples in --help:\n{text}"))
            .1
            .replace("\\\n", " ");
        let mut checked = 0;
        for part in examples.lines().flat_map(|l| l.split('|')) {
            let words: Vec<&str> = part.split_whitespace().collect();
            let Some(tool) = words.first().filter(|w| common::BINARIES.contains(w)) else {
                continue;
            };
            let key = match words.get(1) {
                Some(sub) if *tool == "pathgen" && known.contains_key(&format!("pathgen {sub}")) => {
                    format!("pathgen {sub}")
                }
                _ => tool.to_string(),
            };
            let flags = &known[&key];
            for w in &words {
                let Some(flag) = w.strip_prefix("--") else { continue };
                let flag = flag.split('=').next().unwrap_or(flag);
                assert!(
                    flag.is_empty() || flags.iter().any(|f| f == flag),
                    "{name}: an example gives `{key}` --{flag}, which it does not take: {}",
                    part.trim()
                );
                checked += 1;
            }
        }
        assert!(checked > 0 || name == "pmac-emu", "{name}: no example flag checked");
    }
}
