//! End-to-end tests of feedopt on a pocket like Bayesteh 2013's (ch. 3):
//! contour-parallel passes with a 0.794 mm two-flute mill at 60,000 rpm and
//! 1 µm per tooth, under the micro mill's Turbo PMAC model.

use microcam::cutter::Cutter;
use microcam::feedopt::sample::Pocket;
use microcam::gcode::{Dialect, ReadOptions, read_str};
use microcam::geometry::{Arc3, P3};
use microcam::model::toolpath::{MotionKind, Record};
use microcam::sim::removal::{CutMove, Engine};
use microcam::sim::stock::Stock;
use microcam::sim::time::MoveClass;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const STOCK: &str = "-2,-2,-1,2,2,0";
/// Height-field cell, mm: fine enough that the largest chip is within 5 %
/// of the true slot (coarser cells overestimate it, which loosens the cap).
const CELL: &str = "0.005";

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("feedopt-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn feedopt(args: &[&str], input: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_feedopt"))
        .args([
            "--tool",
            "flat:0.794",
            "--stock",
            STOCK,
            "--cell-mm",
            CELL,
            "--rpm",
            "60000",
        ])
        .args(args)
        .arg(input)
        .output()
        .unwrap()
}

fn write(d: &Path, name: &str, text: &str) -> PathBuf {
    let p = d.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn json(p: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

fn ok(o: &Output) -> String {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8(o.stdout.clone()).unwrap()
}

/// Largest chip volume per tooth of a program (mm³), recomputed here
/// independently: the program is cut in 10 µm steps on a fresh stock, and
/// each step's volume per mm times the feed per tooth its F word gives.
/// Plunges (no XY travel) are left out, as feedopt leaves them alone.
fn peak_chip_per_tooth(text: &str) -> f64 {
    let (d, recs) = read_str(text, &ReadOptions::default()).unwrap();
    let to_mm_s = d.feed_unit().to_mm_per_s();
    let stock = Stock::new(P3::new(-2.0, -2.0, -1.0), P3::new(2.0, 2.0, 0.0), CELL.parse().unwrap()).unwrap();
    let mut e = Engine::new(stock, Cutter::Flat { radius: 0.397 });
    let mut pos = P3::origin();
    let mut fz = Vec::new();
    for r in &recs {
        let Record::Move(m) = r else { continue };
        let (class, arc) = match m.kind {
            MotionKind::Rapid => (MoveClass::Rapid, None),
            MotionKind::Line => (MoveClass::Line, None),
            MotionKind::Arc(a) => (
                MoveClass::Arc,
                Arc3::new(a.center, pos, m.to, a.ccw, a.plane, a.extra_turns),
            ),
        };
        let len = arc.map_or((m.to - pos).norm(), |a| a.length());
        let plunge = arc.is_none() && (m.to.xy() - pos.xy()).norm() < 1e-9;
        e.push(&CutMove {
            line: m.block,
            class,
            from: pos,
            to: m.to,
            arc,
            length_mm: len,
            step_mm: (class != MoveClass::Rapid).then_some(0.01),
        });
        fz.push((!plunge && class != MoveClass::Rapid).then(|| m.feed.unwrap() * to_mm_s / 2000.0));
        pos = m.to;
    }
    e.flush();
    let mut peak: f64 = 0.0;
    for f in fz {
        let b = e.pop().unwrap();
        if let Some(f) = f {
            let step = b.length_mm / b.steps.len() as f64;
            for s in &b.steps {
                peak = peak.max(s.volume_mm3 / step * f);
            }
        }
    }
    peak
}

#[test]
fn per_block_shortens_the_pocket_by_13_percent_without_a_larger_chip() {
    let d = dir("per-block");
    for (dialect, name) in [(Dialect::Pmac, "p.pmc"), (Dialect::Iso, "p.ngc")] {
        let nominal = Pocket::default().program(dialect);
        let p = write(&d, name, &nominal);
        let rep = d.join("r.json");
        let out = ok(&feedopt(&["--report", rep.to_str().unwrap()], &p));
        let r = json(&rep);
        let (before, after) = (
            r["cycle_time_before_s"].as_f64().unwrap(),
            r["cycle_time_after_s"].as_f64().unwrap(),
        );
        assert!(after <= 0.87 * before, "{name}: {after} s vs {before} s");
        assert_eq!(r["mode_used"], "per-block");
        let (p0, p1) = (peak_chip_per_tooth(&nominal), peak_chip_per_tooth(&out));
        assert!(
            p1 <= p0 * (1.0 + 1e-9),
            "{name}: peak chip {p1} mm³ vs nominal {p0} mm³"
        );
        let r0 = &r["chip_volume_per_tooth_before"];
        let r1 = &r["chip_volume_per_tooth_after"];
        assert!(r1["max_mm3"].as_f64() <= r0["max_mm3"].as_f64());
        assert!(
            r1["mean_mm3"].as_f64() > r0["mean_mm3"].as_f64(),
            "bigger chips on average: faster"
        );
        assert_eq!(r["blocks_added"], 0);
    }
}

/// Source lines of a program touched by splitting: the inserted lines and
/// the line each run of them precedes.
fn split_lines(text: &str) -> Vec<usize> {
    let lines: Vec<&str> = text.lines().collect();
    let mut out = Vec::new();
    for (i, l) in lines.iter().enumerate() {
        let marked = |s: &str| s.contains("feedopt split");
        if marked(l) || (i > 0 && marked(lines[i - 1])) {
            out.push(i + 1);
        }
    }
    out
}

#[test]
fn split_blocks_last_at_least_the_minimum_and_beat_per_block() {
    let d = dir("split");
    let p = write(&d, "p.pmc", &Pocket::default().program(Dialect::Pmac));
    let rep = d.join("r.json");
    let out = ok(&feedopt(&["--mode", "split", "--report", rep.to_str().unwrap()], &p));
    let r = json(&rep);
    assert_eq!(r["mode_used"], "split");
    let t_min = r["min_block_time_s"].as_f64().unwrap();
    assert!((t_min - 0.133).abs() < 1e-9, "the micro mill's TA");
    assert!(r["blocks_added"].as_u64().unwrap() > 0);
    let (split, per_block) = (
        r["cycle_time_after_s"].as_f64().unwrap(),
        r["per_block_cycle_time_s"].as_f64().unwrap(),
    );
    assert!(split < per_block, "{split} vs {per_block}");
    // Every sub-block and every split block's remainder lasts at least TA
    // at its feed.
    let touched = split_lines(&out);
    assert!(!touched.is_empty());
    let (_, recs) = read_str(&out, &ReadOptions::default()).unwrap();
    let mut pos = P3::origin();
    let mut checked = 0;
    for r in &recs {
        let Record::Move(m) = r else { continue };
        if touched.contains(&(m.block.unwrap() as usize)) {
            let t = (m.to - pos).norm() / m.feed.unwrap();
            assert!(t >= t_min, "line {}: {t} s", m.block.unwrap());
            checked += 1;
        }
        pos = m.to;
    }
    assert_eq!(checked, touched.len());
    assert!(peak_chip_per_tooth(&out) <= peak_chip_per_tooth(&Pocket::default().program(Dialect::Pmac)) * (1.0 + 1e-9));
}

#[test]
fn naive_splitting_loses_time_on_a_pmac_and_ours_does_not() {
    let d = dir("naive");
    let p = write(&d, "p.pmc", &Pocket::default().program(Dialect::Pmac));
    let (rn, rs) = (d.join("n.json"), d.join("s.json"));
    ok(&feedopt(&["--mode", "naive", "--report", rn.to_str().unwrap()], &p));
    ok(&feedopt(&["--mode", "split", "--report", rs.to_str().unwrap()], &p));
    let (n, s) = (json(&rn), json(&rs));
    let before = n["cycle_time_before_s"].as_f64().unwrap();
    assert!(
        n["cycle_time_after_s"].as_f64().unwrap() > before,
        "the thesis' failure (Fig. 3-19)"
    );
    assert!(s["cycle_time_after_s"].as_f64().unwrap() < before);
}

#[test]
fn only_f_words_change_and_a_second_run_changes_nothing() {
    let d = dir("idem");
    for dialect in [Dialect::Iso, Dialect::Pmac] {
        let nominal = Pocket::default().program(dialect);
        let p = write(&d, "p.txt", &nominal);
        for mode in ["per-block", "split"] {
            let once = ok(&feedopt(&["--mode", mode], &p));
            let p1 = write(&d, "once.txt", &once);
            let twice = ok(&feedopt(&["--mode", mode], &p1));
            assert_eq!(once, twice, "{dialect:?} {mode}: not idempotent");
            // Line by line, without the inserted lines: equal once F words
            // are taken out, and the comment and line end byte-identical.
            let kept: Vec<&str> = once
                .split_inclusive('\n')
                .filter(|l| !l.contains("feedopt split"))
                .collect();
            let orig: Vec<&str> = nominal.split_inclusive('\n').collect();
            assert_eq!(kept.len(), orig.len(), "{dialect:?} {mode}");
            for (a, b) in orig.iter().zip(&kept) {
                assert_eq!(without_f(a), without_f(b), "{dialect:?} {mode}");
                let tail = |l: &str| l.find(['(', ';']).map(|i| l[i..].to_string());
                assert_eq!(tail(a), tail(b));
                assert_eq!(a.ends_with('\n'), b.ends_with('\n'));
            }
        }
    }
}

/// A program with canned cycles (G81 with L repeats in G91, G83 pecks)
/// and cutter compensation (G41.1 round a square with an arc) passes
/// through feedopt with nothing but its F words changed: the cycles and
/// the compensation words stay as written, and the result reads to the
/// same path.
#[test]
fn cycles_and_compensation_pass_through_with_only_f_changed() {
    let d = dir("cycles-comp");
    let program = "\
(cycles and compensation, feedopt pass-through)
G21 G17 G90 G94 G40 G80
S60000 M3
G0 X-1.5 Y-1.5 Z0.5
G91 G81 X0.5 Y0 Z-0.3 R-0.2 L3 F60 (three holes)
G90 G80
G98 G83 X1.2 Y-1.2 Z-0.4 R0.2 Q0.15 F50
G80 G0 X-1.6 Y-1.6 Z0.5
G41.1 D0.794 G1 X-1 Y-1 F80
G1 Z-0.2
X1 (side one)
Y0.5
G3 X0.5 Y1 R0.5
G1 X-1
Y-1
G40 G1 X-1.6 Y-1.6
G0 Z0.5
M5 M2
";
    let p = write(&d, "cc.ngc", program);
    let read = |text: &str| {
        let opts = ReadOptions {
            dialect: Some(Dialect::Iso),
            ..Default::default()
        };
        let (_, recs) = read_str(text, &opts).unwrap();
        recs.into_iter()
            .filter_map(|r| match r {
                Record::Move(m) => Some((m.to, std::mem::discriminant(&m.kind))),
                _ => None,
            })
            .collect::<Vec<_>>()
    };
    for mode in ["per-block", "split"] {
        let out = ok(&feedopt(&["--mode", mode], &p));
        let orig: Vec<&str> = program.split_inclusive('\n').collect();
        let kept: Vec<&str> = out.split_inclusive('\n').collect();
        assert_eq!(
            kept.len(),
            orig.len(),
            "{mode}: lines added or lost (no sub-blocks in G91 or under compensation)\n{out}"
        );
        let mut changed = 0;
        for (a, b) in orig.iter().zip(&kept) {
            assert_eq!(without_f(a), without_f(b), "{mode}");
            changed += usize::from(a != b);
        }
        assert!(changed > 0, "{mode}: feedopt changed no F word\n{out}");
        let (pa, pb) = (read(program), read(&out));
        assert_eq!(pa.len(), pb.len(), "{mode}");
        for (a, b) in pa.iter().zip(&pb) {
            assert!((a.0 - b.0).norm() < 1e-12 && a.1 == b.1, "{mode}: {a:?} vs {b:?}");
        }
    }
    // G93 and G95 feeds are no mm/min: refused, naming the mode.
    for (text, needle) in [("G93 G1 X1 F2\n", "G93"), ("S1000 M3\nG95 G1 X1 F0.01\n", "G95")] {
        let p = write(&d, "fm.ngc", text);
        let o = feedopt(&[], &p);
        assert_eq!(o.status.code(), Some(2), "{text}");
        assert!(String::from_utf8_lossy(&o.stderr).contains(needle), "{text}");
    }
}

/// A line without its F words, blanks collapsed.
fn without_f(l: &str) -> String {
    let mut s = String::new();
    let mut it = l.chars().peekable();
    while let Some(c) = it.next() {
        if c == 'F' && it.peek().is_some_and(|n| n.is_ascii_digit()) {
            while it.peek().is_some_and(|n| n.is_ascii_digit() || *n == '.') {
                it.next();
            }
            continue;
        }
        s.push(c);
    }
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

#[test]
fn bad_input_names_what_is_missing_and_writes_nothing() {
    let d = dir("bad");
    let pmac = write(&d, "p.pmc", &Pocket::default().program(Dialect::Pmac));
    let (o, rep) = (d.join("out.pmc"), d.join("r.json"));
    let run = |args: &[&str], input: &Path| -> String {
        let out = Command::new(env!("CARGO_BIN_EXE_feedopt"))
            .args(["-o", o.to_str().unwrap(), "--report", rep.to_str().unwrap()])
            .args(args)
            .arg(input)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert!(!o.exists() && !rep.exists(), "nothing written");
        String::from_utf8(out.stderr).unwrap()
    };
    let e = run(&["--tool", "flat:0.794", "--stock", STOCK], &pmac);
    assert!(e.contains("no spindle speed") && e.contains("p.pmc:"), "{e}");
    let e = run(
        &["--tool", "flat:0.794", "--stock", "10,10,-1,20,20,0", "--rpm", "60000"],
        &pmac,
    );
    assert!(e.contains("does not overlap the stock"), "{e}");
    let plunge = write(
        &d,
        "plunge.ngc",
        "G21 G90\nS60000 M3\nG0 Z1\nG1 Z-0.1 F60\nG0 Z1\nM30\n",
    );
    let e = run(&["--tool", "flat:0.794", "--stock", STOCK], &plunge);
    assert!(e.contains("never cuts"), "{e}");
    let inch = write(&d, "inch.ngc", "G20 G90\nS60000 M3\nG1 X0.01 F1\nM30\n");
    let e = run(&["--tool", "flat:0.794", "--stock", STOCK], &inch);
    assert!(e.contains("inch"), "{e}");
    let e = run(
        &["--tool", "flat:0.794", "--stock", STOCK, "--target", "force"],
        &plunge,
    );
    assert!(e.contains("--force"), "{e}");
}

#[test]
fn force_figures_and_series_are_reported() {
    let d = dir("force");
    let p = write(&d, "p.ngc", &Pocket::default().program(Dialect::Iso));
    let (rep, csv, svg) = (d.join("r.json"), d.join("s.csv"), d.join("p.svg"));
    ok(&feedopt(
        &[
            "--force",
            "--report",
            rep.to_str().unwrap(),
            "--csv",
            csv.to_str().unwrap(),
            "--svg",
            svg.to_str().unwrap(),
        ],
        &p,
    ));
    let r = json(&rep);
    let f = &r["force"];
    for k in ["mean_before_n", "mean_after_n", "peak_before_n", "peak_after_n"] {
        assert!(f[k].as_f64().unwrap() > 0.0, "{k}");
    }
    assert!(f["peak_after_n"].as_f64() <= f["peak_before_n"].as_f64().map(|v| v * 1.5));
    let rows = std::fs::read_to_string(&csv).unwrap();
    assert!(rows.starts_with("line,x_mm,"));
    let cutting = rows
        .lines()
        .skip(1)
        .filter(|l| l.split(',').nth(6) == Some("1"))
        .count();
    assert_eq!(
        cutting as u64,
        r["chip_volume_per_tooth_before"]["steps"].as_u64().unwrap()
    );
    assert!(std::fs::read_to_string(&svg).unwrap().contains("<polyline"));
    // Constant force: the mean force over time rises towards the target
    // but never above the largest chip's force at f_min.
    let rep2 = d.join("r2.json");
    ok(&feedopt(
        &["--force", "--target", "force", "--report", rep2.to_str().unwrap()],
        &p,
    ));
    let r2 = json(&rep2);
    assert_eq!(r2["target"], "force");
    assert!(r2["cycle_time_after_s"].as_f64() < r2["cycle_time_before_s"].as_f64());
}

/// Decode an 8-bit RGB PNG whose IDAT holds stored (uncompressed) deflate
/// blocks, checking every chunk's CRC and the zlib Adler-32: (width,
/// height, pixels).
fn decode_png(b: &[u8]) -> (usize, usize, Vec<u8>) {
    fn crc(data: &[u8]) -> u32 {
        let mut c = !0u32;
        for &x in data {
            c ^= x as u32;
            for _ in 0..8 {
                c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
            }
        }
        !c
    }
    assert_eq!(&b[..8], b"\x89PNG\r\n\x1a\n");
    let (mut i, mut w, mut h, mut z) = (8, 0, 0, Vec::new());
    let mut end = false;
    while i < b.len() {
        let n = u32::from_be_bytes(b[i..i + 4].try_into().unwrap()) as usize;
        let kind = &b[i + 4..i + 8];
        let data = &b[i + 8..i + 8 + n];
        let c = u32::from_be_bytes(b[i + 8 + n..i + 12 + n].try_into().unwrap());
        assert_eq!(crc(&b[i + 4..i + 8 + n]), c, "CRC of {}", String::from_utf8_lossy(kind));
        match kind {
            b"IHDR" => {
                w = u32::from_be_bytes(data[0..4].try_into().unwrap()) as usize;
                h = u32::from_be_bytes(data[4..8].try_into().unwrap()) as usize;
                assert_eq!(&data[8..], &[8, 2, 0, 0, 0], "8-bit RGB, no interlace");
            }
            b"IDAT" => z.extend_from_slice(data),
            b"IEND" => end = true,
            _ => {}
        }
        i += 12 + n;
    }
    assert!(end && w > 0 && h > 0);
    assert_eq!(z[0] & 0x0f, 8, "zlib deflate");
    let (mut k, mut raw) = (2, Vec::new());
    loop {
        let fin = z[k] & 1;
        assert_eq!(z[k] >> 1 & 3, 0, "stored blocks");
        let n = u16::from_le_bytes([z[k + 1], z[k + 2]]) as usize;
        assert_eq!(!(n as u16), u16::from_le_bytes([z[k + 3], z[k + 4]]));
        raw.extend_from_slice(&z[k + 5..k + 5 + n]);
        k += 5 + n;
        if fin == 1 {
            break;
        }
    }
    let (mut s1, mut s2) = (1u32, 0u32);
    for &x in &raw {
        s1 = (s1 + x as u32) % 65_521;
        s2 = (s2 + s1) % 65_521;
    }
    assert_eq!(u32::from_be_bytes(z[k..k + 4].try_into().unwrap()), (s2 << 16) | s1);
    assert_eq!(raw.len(), h * (3 * w + 1));
    let mut rgb = Vec::with_capacity(w * h * 3);
    for row in raw.chunks(3 * w + 1) {
        assert_eq!(row[0], 0, "filter none");
        rgb.extend_from_slice(&row[1..]);
    }
    (w, h, rgb)
}

#[test]
fn the_png_shows_chip_and_feed_profiles_before_and_after() {
    let d = dir("png");
    let p = write(&d, "p.pmc", &Pocket::default().program(Dialect::Pmac));
    let png = d.join("profile.png");
    ok(&feedopt(
        &["--png", png.to_str().unwrap(), "-o", d.join("o.pmc").to_str().unwrap()],
        &p,
    ));
    let (w, h, rgb) = decode_png(&std::fs::read(&png).unwrap());
    assert_eq!((w, h), (900, 520));
    let (before, after) = ([150u8, 150, 150], [31u8, 95, 191]);
    let count = |y0: usize, y1: usize, c: [u8; 3]| {
        (y0..y1)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .filter(|&(x, y)| rgb[(y * w + x) * 3..(y * w + x) * 3 + 3] == c)
            .count()
    };
    for (panel, (y0, y1)) in [("chip", (0, h / 2)), ("feed", (h / 2, h))] {
        // A profile spans the path: drawn in most of the 818 columns.
        assert!(count(y0, y1, after) > 400, "{panel}: blue profile drawn");
        assert!(count(y0, y1, before) > 100, "{panel}: grey profile drawn");
    }
    // The feeds after lie at or above the nominal 1 µm/tooth, which the
    // grey line marks: in every column, blue is never below grey.
    let col = |x: usize, c: [u8; 3]| (h / 2..h).find(|&y| rgb[(y * w + x) * 3..(y * w + x) * 3 + 3] == c);
    let mut compared = 0;
    for x in 42..w - 42 {
        if let (Some(b), Some(a)) = (col(x, before), col(x, after)) {
            assert!(a <= b, "column {x}: feed after below the nominal");
            compared += 1;
        }
    }
    assert!(compared > 50);
}
