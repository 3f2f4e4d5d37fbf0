//! gsim's material removal with one cutter per tool (issue 16): each
//! section of a multi-tool program cuts with its own tool's cutter, from
//! the CAM post's header comments or the tool table; `--tool` still forces
//! one cutter for everything.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("gsim-tools-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn write(d: &Path, name: &str, text: &str) -> PathBuf {
    let p = d.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

const STOCK: &str = "-2,-3,-1,10,8,0";

fn gsim(p: &Path, extra: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_gsim"))
        .arg(p)
        .args(["--stock", STOCK, "--cell-mm", "0.05"])
        .args(extra)
        .output()
        .unwrap()
}

fn removed(o: &Output) -> f64 {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    v["removal"]["removed_volume_mm3"].as_f64().unwrap()
}

/// A flat 1 mm slot 0.3 deep at y = 0 with T1, then a 2 mm ball slot 0.4
/// deep at y = 5 with T2: the slots do not touch.
const SLOT1: &str = "T1 M6\nS10000 M3\nG0 X0 Y0 Z1\nG1 Z-0.3 F100\nG1 X8\nG0 Z1\n";
const SLOT2: &str = "T2 M6\nS10000 M3\nG0 X0 Y5 Z1\nG1 Z-0.4 F100\nG1 X8\nG0 Z1\n";

#[test]
fn each_tool_cuts_with_its_own_cutter() {
    let d = dir("sections");
    let header = "(T1 D=1 CR=0 - flat end mill)\n(T2 D=2 CR=1 - ball end mill)\nG21 G90 G17\n";
    let both = write(&d, "both.ngc", &format!("{header}{SLOT1}{SLOT2}M2\n"));
    let v = removed(&gsim(&both, &[]));
    // Each section alone, with its cutter forced.
    let v1 = removed(&gsim(
        &write(&d, "1.ngc", &format!("G21 G90\n{SLOT1}M2\n")),
        &["--tool", "flat:1"],
    ));
    let v2 = removed(&gsim(
        &write(&d, "2.ngc", &format!("G21 G90\n{SLOT2}M2\n")),
        &["--tool", "ball:2"],
    ));
    assert!((v - (v1 + v2)).abs() < 1e-9 * v, "{v} vs {v1} + {v2}");
    // The ball slot: 8 mm of a circular segment of height 0.4 (r = 1),
    // plus a spherical cap of height 0.4 split over its two ends.
    let segment = (0.6f64).acos() - 0.6 * 0.8;
    let cap = std::f64::consts::PI * 0.16 * (3.0 - 0.4) / 3.0;
    assert!((v2 - (8.0 * segment + cap)).abs() < 0.02 * v2, "{v2}");
    // --tool still forces one cutter for the whole program.
    let forced = removed(&gsim(&both, &["--tool", "flat:1"]));
    assert!((forced - v).abs() > 0.1, "{forced} vs {v}");
    // The same from a tool table (flat end mills: a .tbl has no corner).
    let plain = write(&d, "plain.ngc", &format!("G21 G90\n{SLOT1}{SLOT2}M2\n"));
    let tbl = write(&d, "t.tbl", "T1 P1 D1 ;flat 1\nT2 P2 D2 ;flat 2\n");
    let vt = removed(&gsim(&plain, &["--tool-table", tbl.to_str().unwrap()]));
    let v2f = removed(&gsim(
        &write(&d, "2f.ngc", &format!("G21 G90\n{SLOT2}M2\n")),
        &["--tool", "flat:2"],
    ));
    assert!((vt - (v1 + v2f)).abs() < 1e-9 * vt, "{vt} vs {v1} + {v2f}");
}

#[test]
fn a_tool_without_a_cutter_is_an_error_naming_its_line() {
    let d = dir("missing");
    let p = write(
        &d,
        "p.ngc",
        &format!(
            "(T1 D=1 CR=0 - flat end mill)\nG21 G90\n{SLOT1}{}M2\n",
            SLOT2.replace("T2", "T3")
        ),
    );
    let o = gsim(&p, &[]);
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("p.ngc:11:") && e.contains("tool T3 has no cutter"), "{e}");
    // No cutter at all: --stock says what it needs.
    let p = write(&d, "q.ngc", &format!("G21 G90\n{SLOT1}M2\n"));
    let o = gsim(&p, &[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--stock needs a cutter"));
}

/// A stock that ends inside the cutter's reach: on rows where the move's
/// chord starts past the stock's last cell the run of cells is empty. It
/// used to start beyond the row (a panic, exit 101) for a level move whose
/// reach only just overlapped the stock (the extreme-numbers test found
/// it with the stock's far side at 1e-12).
#[test]
fn a_stock_ending_under_the_cutter_is_cut_without_a_panic() {
    let slot = Path::new(env!("CARGO_MANIFEST_DIR")).join("testdata/sim/microslot.ngc");
    for tool in ["flat:1", "ball:1", "torus:1:0.2"] {
        for stock in ["-6,-6,-1,1e-12,6,0", "-6,-6,-1,0,6,0", "-6,-6,-1,0.3,6,0"] {
            let o = Command::new(env!("CARGO_BIN_EXE_gsim"))
                .arg(&slot)
                .args(["--stock", stock, "--tool", tool])
                .output()
                .unwrap();
            let v = removed(&o);
            assert!(v.is_finite() && v >= 0.0, "{tool} {stock}: {v}");
        }
    }
}
