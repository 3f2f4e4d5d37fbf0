//! End-to-end and accuracy tests of probescan: exact artefacts measure
//! exactly, noisy ones fall within their predicted uncertainty, contours
//! with concave and convex corners close without skipping features, narrow
//! slots are reported, minimum-zone roundness agrees with an independent
//! brute-force solver, and the ISO program runs through LinuxCNC's rs274.

use microcam::geometry::{P2, V2};
use microcam::probe::fit;
use microcam::probe::job::{self, Measure, ProbeJob};
use microcam::probe::noise::{NoiseModel, Rng};
use microcam::probe::part::{Part, Prim};
use microcam::probe::scan::{ScanParams, Stop};
use microcam::probe::tip::Probe;
use std::process::{Command, Output, Stdio};

const BIN: &str = env!("CARGO_BIN_EXE_probescan");

mod common;

fn run(args: &[&str], stdin: Option<&str>) -> Output {
    common::run(BIN, args, stdin)
}

fn json(o: &Output) -> serde_json::Value {
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).expect("report JSON")
}

fn f(v: &serde_json::Value, path: &[&str]) -> f64 {
    let mut v = v;
    for p in path {
        v = &v[*p];
    }
    v.as_f64().unwrap_or_else(|| panic!("{path:?} missing"))
}

#[test]
fn plug_gauge_without_noise_measures_its_diameter_and_zero_form() {
    let r = json(&run(&["--circle", "12.7", "--center", "3,-2", "--points", "100"], None));
    assert_eq!(r["scan"]["stop"], "closed");
    let n = f(&r, &["scan", "contacts"]);
    assert!((99.0..=102.0).contains(&n), "{n} contacts");
    assert!((f(&r, &["circle", "diameter_lsq_mm"]) - 12.7).abs() < 1e-7);
    assert!((f(&r, &["circle", "diameter_mz_mm"]) - 12.7).abs() < 1e-7);
    assert!(f(&r, &["circle", "roundness_mz_mm"]) < 1e-9);
    assert!(f(&r, &["circle", "roundness_lsq_mm"]) < 1e-9);
    let c = &r["circle"]["center_mz_mm"];
    assert!((c[0].as_f64().unwrap() - 3.0).abs() < 1e-7 && (c[1].as_f64().unwrap() + 2.0).abs() < 1e-7);
}

#[test]
fn gauge_blocks_without_noise_measure_their_widths() {
    for w in ["20", "12.7", "9.525"] {
        let r = json(&run(&["--gauge", w, "--face-points", "12", "--de", "0.0016"], None));
        let got = f(&r, &["width", "width_mm"]);
        assert!((got - w.parse::<f64>().unwrap()).abs() < 1e-7, "{w}: {got}");
    }
}

fn noisy_job(measure: Measure, seed: u64) -> ProbeJob {
    let probe = Probe::new(0.1, 30_000.0, 0.05).unwrap();
    let noise = NoiseModel {
        sigma_mm: 0.0008,
        delay_s: 0.002,
        quantise: true,
    };
    let (part, params) = match measure {
        Measure::Width {
            nominal_mm,
            face_points,
        } => job::gauge_params(nominal_mm, 9.0, face_points, 0.5, 0.1, probe.radius()).unwrap(),
        _ => (
            Part::circle(P2::new(0.0, 0.0), 12.7),
            ScanParams {
                step_mm: job::step_for_points(6.35 + 0.05, 100),
                offset_mm: 0.1,
                start: P2::new(-7.0, 0.0),
                dir: V2::new(1.0, 0.0),
                max_points: 500,
                max_approach_mm: 5.0,
            },
        ),
    };
    ProbeJob {
        design: part.clone(),
        part,
        probe,
        noise,
        params,
        measure,
        seed,
    }
}

/// Counts how often |error| <= k u for k = 1 and for the 99 % factor.
#[derive(Default, Debug)]
struct Tally {
    k1: usize,
    k99: usize,
}

impl Tally {
    fn add(&mut self, err: f64, u: f64) {
        self.k1 += usize::from(err.abs() <= u);
        self.k99 += usize::from(err.abs() <= microcam::probe::measure::K99 * u);
    }
}

#[test]
fn noisy_estimates_fall_within_the_predicted_uncertainty() {
    let runs = 200u64;
    let (mut d, mut cx, mut cy, mut w) = (Tally::default(), Tally::default(), Tally::default(), Tally::default());
    for seed in 1..=runs {
        let out = job::run(&noisy_job(Measure::Circle, seed)).unwrap();
        assert_eq!(out.scan.stop, Stop::Closed);
        let c = out.circle.unwrap();
        d.add(c.diameter_lsq_mm - 12.7, c.u_diameter_mm);
        cx.add(c.lsq.center.x, c.u_center_mm[0]);
        cy.add(c.lsq.center.y, c.u_center_mm[1]);
        let g = job::run(&noisy_job(
            Measure::Width {
                nominal_mm: 12.7,
                face_points: 10,
            },
            seed,
        ))
        .unwrap()
        .width
        .unwrap();
        w.add(g.width_mm - 12.7, g.u_width_mm);
    }
    eprintln!("of {runs}: diameter {d:?}, centre x {cx:?}, centre y {cy:?}, width {w:?}");
    for (name, t) in [("diameter", &d), ("centre x", &cx), ("centre y", &cy), ("width", &w)] {
        // The 99 % interval holds at least 95 % of the estimates...
        assert!(t.k99 as f64 >= 0.95 * runs as f64, "{name}: {t:?}");
        // ...and is not inflated: the standard uncertainty holds about
        // 68 % of them (binomial 3-sigma band for 200 runs).
        assert!((116..=157).contains(&t.k1), "{name}: {t:?}");
    }
}

fn poly(pts: &[(f64, f64)]) -> Vec<Prim> {
    (0..pts.len())
        .map(|i| {
            let (a, b) = (pts[i], pts[(i + 1) % pts.len()]);
            Prim::Line {
                a: P2::new(a.0, a.1),
                b: P2::new(b.0, b.1),
            }
        })
        .collect()
}

fn check_closes(part: &Part, start: P2, dir: V2, de: f64, rs: f64, what: &str) {
    let (lo, hi) = bbox(part);
    let probe = Probe::new(de, 30_000.0, 0.05).unwrap();
    let params = ScanParams {
        step_mm: rs,
        offset_mm: rs / 2.0,
        start,
        dir,
        max_points: 20_000,
        max_approach_mm: 2.0 * (hi - lo).norm() + 1.0,
    };
    let j = ProbeJob {
        part: part.clone(),
        design: part.clone(),
        probe,
        noise: NoiseModel::default(),
        params,
        measure: Measure::Contour,
        seed: 1,
    };
    let out = job::run(&j).unwrap_or_else(|e| panic!("{what}: {e}"));
    assert_eq!(out.scan.stop, Stop::Closed, "{what}: {}", out.scan.stop.message());
    assert!(
        out.coverage.missed.is_empty(),
        "{what}: skipped pieces {:?}",
        out.coverage.missed
    );
    // Every contact is a true touch: R_e from the part, never inside it.
    for c in &out.scan.contacts {
        let (d, _) = part.distance(c.center);
        assert!(
            (d - de / 2.0).abs() < 1e-9,
            "{what}: contact {:?} is {d} from the part",
            c.center
        );
    }
}

fn castle() -> Vec<(f64, f64)> {
    vec![
        (0.0, 0.0),
        (8.0, 0.0),
        (8.0, 4.0),
        (7.0, 4.0),
        (7.0, 5.0),
        (6.0, 5.0),
        (6.0, 4.0),
        (4.5, 4.0),
        (4.5, 5.0),
        (3.5, 5.0),
        (3.5, 4.0),
        (2.0, 4.0),
        (2.0, 5.0),
        (1.0, 5.0),
        (1.0, 4.0),
        (0.0, 4.0),
    ]
}

fn star(n: usize, r1: f64, r2: f64) -> Vec<(f64, f64)> {
    (0..2 * n)
        .map(|i| {
            let a = i as f64 * std::f64::consts::PI / n as f64;
            let r = if i % 2 == 0 { r1 } else { r2 };
            (r * a.cos(), r * a.sin())
        })
        .collect()
}

#[test]
fn generated_convex_and_concave_contours_close_without_skipping() {
    let single = Part::single_loop;
    let castle_part = single(poly(&castle()));
    for (dir, tag) in [
        (V2::new(1.0, 0.0), "castle"),
        (V2::new(1.0, -0.4), "castle, slanted start"),
    ] {
        check_closes(&castle_part, P2::new(-1.0, 2.0), dir, 0.1, 0.2, tag);
    }
    check_closes(
        &single(poly(&star(7, 5.0, 2.5))),
        P2::new(-6.0, 0.3),
        V2::new(1.0, 0.0),
        0.1,
        0.25,
        "star",
    );
    // A bump smaller than R_s on a face: touched on the way or stepped
    // over, never looped on.
    let bump = single(poly(&[
        (0.0, 0.0),
        (6.0, 0.0),
        (6.0, 3.0),
        (3.05, 3.0),
        (3.05, 3.05),
        (2.95, 3.05),
        (2.95, 3.0),
        (0.0, 3.0),
    ]));
    check_closes(&bump, P2::new(-1.0, 1.5), V2::new(1.0, 0.0), 0.05, 0.3, "small bump");
    // The castle as a pocket: scanned from inside, the corners swap roles.
    let mut pocket = poly(&[(-2.0, -2.0), (10.0, -2.0), (10.0, 7.0), (-2.0, 7.0)]);
    pocket.extend(poly(&castle()));
    let pocket = Part {
        prims: pocket,
        loops: vec![0..4, 4..20],
    };
    check_closes(
        &pocket,
        P2::new(4.0, 2.0),
        V2::new(0.0, -1.0),
        0.1,
        0.2,
        "castle pocket",
    );
    // A disc with a keyway-like notch (arcs and lines).
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/testdata/chains/plate.chains")).unwrap();
    let chains: Vec<_> = microcam::formats::chains::ChainsReader::new(text.as_bytes())
        .unwrap()
        .map(Result::unwrap)
        .filter(|c| c.closed)
        .collect();
    let arcs = Part::from_chains(&chains).unwrap();
    check_closes(
        &arcs,
        P2::new(-1.0, 2.0),
        V2::new(1.0, 0.0),
        0.05,
        0.15,
        "plate outside",
    );
    check_closes(
        &arcs,
        P2::new(1.0, 2.0),
        V2::new(1.0, 0.0),
        0.05,
        0.1,
        "plate round hole",
    );
}

#[test]
fn corpus_contours_close_without_skipping() {
    let files = microcam::corpus::files("dxf", &[".dxf"]);
    if files.is_empty() {
        microcam::corpus::skip("probescan_corpus_contours");
        return;
    }
    let mut cases = 0;
    for file in files {
        let o = Command::new(env!("CARGO_BIN_EXE_dxf2chains"))
            .arg("-q")
            .arg(&file)
            .stdin(Stdio::null())
            .output()
            .unwrap();
        if !o.status.success() {
            continue;
        }
        let Ok(reader) = microcam::formats::chains::ChainsReader::new(&o.stdout[..]) else {
            continue;
        };
        let chains: Vec<_> = reader.filter_map(Result::ok).filter(|c| c.closed).collect();
        // Each closed chain on its own, as a plate scanned from outside;
        // simple outlines only (a self-crossing one has no outside).
        for ch in chains.iter().take(6) {
            let Ok(part) = Part::from_chains(std::slice::from_ref(ch)) else {
                continue;
            };
            if part.prims.len() > 400 || self_crossing(&part) {
                continue;
            }
            let (lo, hi) = bbox(&part);
            let size = (hi - lo).norm();
            if size <= 0.0 {
                continue;
            }
            let de = size / 400.0;
            let rs = size / 80.0;
            let start = P2::new(lo.x - de - rs, (lo.y + hi.y) / 2.0 + 1e-3 * size);
            let name = format!("{} chain {}", file.display(), ch.id);
            check_closes(&part, start, V2::new(1.0, 0.0), de, rs, &name);
            cases += 1;
        }
    }
    microcam::corpus::record("probescan_corpus_contours", cases);
    assert!(cases > 0);
}

fn bbox(part: &Part) -> (P2, P2) {
    let (mut lo, mut hi) = (
        P2::new(f64::INFINITY, f64::INFINITY),
        P2::new(f64::NEG_INFINITY, f64::NEG_INFINITY),
    );
    for p in &part.prims {
        for i in 0..=32 {
            let q = p.at(p.length() * i as f64 / 32.0);
            lo = P2::new(lo.x.min(q.x), lo.y.min(q.y));
            hi = P2::new(hi.x.max(q.x), hi.y.max(q.y));
        }
    }
    (lo, hi)
}

/// True when the outline crosses itself: its pieces, sampled into a
/// polygon, have two non-neighbouring edges that properly cross.
fn self_crossing(part: &Part) -> bool {
    let per = (2000 / part.prims.len().max(1)).clamp(2, 32);
    let mut pts = Vec::new();
    for p in &part.prims {
        for k in 0..per {
            pts.push(p.at(p.length() * k as f64 / per as f64));
        }
    }
    let n = pts.len();
    let orient = |a: P2, b: P2, c: P2| (b - a).perp(&(c - a));
    for i in 0..n {
        let (a, b) = (pts[i], pts[(i + 1) % n]);
        for j in i + 2..n {
            if (j + 1) % n == i {
                continue;
            }
            let (c, d) = (pts[j], pts[(j + 1) % n]);
            let (o1, o2) = (orient(a, b, c), orient(a, b, d));
            let (o3, o4) = (orient(c, d, a), orient(c, d, b));
            if o1 * o2 < 0.0 && o3 * o4 < 0.0 {
                return true;
            }
        }
    }
    false
}

#[test]
fn a_slot_narrower_than_the_probe_is_reported_not_entered() {
    let o = run(&["testdata/chains/slot.chains", "--de", "0.1", "--step", "0.2"], None);
    let r = json(&o);
    assert_eq!(r["scan"]["stop"], "closed");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("out of reach"), "{err}");
    // The longest unreachable stretch is the slot: its walls and floor.
    let un = r["coverage"]["unreachable"].as_array().unwrap();
    let slot = un
        .iter()
        .max_by(|a, b| {
            a["length_mm"]
                .as_f64()
                .unwrap()
                .total_cmp(&b["length_mm"].as_f64().unwrap())
        })
        .unwrap();
    let len = slot["length_mm"].as_f64().unwrap();
    assert!(len > 2.0 && len < 2.2, "slot stretch {len}");
    // No contact inside the slot: every probe centre stays above its mouth.
    let csv = run(
        &[
            "testdata/chains/slot.chains",
            "--de",
            "0.1",
            "--step",
            "0.2",
            "--csv",
            "/dev/stdout",
            "-o",
            "/dev/null",
        ],
        None,
    );
    let text = String::from_utf8_lossy(&csv.stdout);
    for line in text.lines().skip(1) {
        let v: Vec<f64> = line.split(',').skip(2).take(2).map(|x| x.parse().unwrap()).collect();
        assert!(
            !(v[0] > 2.9 && v[0] < 3.1 && v[1] > 2.9 && v[1] < 3.99),
            "entered the slot: {line}"
        );
    }
}

/// Minimum zone by brute force: every centre equidistant from two pairs of
/// points, or from three points, evaluated on all points.
fn brute_min_zone(pts: &[P2]) -> f64 {
    let n = pts.len();
    let mut cands = Vec::new();
    for a in 0..n {
        for b in a + 1..n {
            for c in 0..n {
                for d in c + 1..n {
                    cands.extend(fit::bisectors_cross(pts[a], pts[b], pts[c], pts[d]));
                }
            }
        }
    }
    let mut best = f64::INFINITY;
    for c in cands {
        let (lo, hi) = fit::radial_range(pts, c);
        best = best.min(hi - lo);
    }
    best
}

#[test]
fn minimum_zone_agrees_with_brute_force() {
    let mut rng = Rng::new(11);
    for case in 0..40 {
        let n = 8 + case % 7;
        let lobes = 2.0 + (case % 4) as f64;
        let pts: Vec<P2> = (0..n)
            .map(|i| {
                let a = (i as f64 + 0.3 * rng.uniform()) * std::f64::consts::TAU / n as f64;
                let r = 6.35 + 0.003 * (lobes * a).cos() + 0.002 * rng.normal();
                P2::new(1.0 + r * a.cos(), -0.5 + r * a.sin())
            })
            .collect();
        let ours = fit::circle_min_zone(&pts).unwrap().zone();
        let theirs = brute_min_zone(&pts);
        assert!(
            (ours - theirs).abs() < 1e-12,
            "case {case}: {ours} vs brute force {theirs}"
        );
    }
}

#[test]
fn iso_program_runs_through_rs274() {
    let Ok(rs) = Command::new("rs274").arg("-h").stdin(Stdio::null()).output() else {
        eprintln!("iso_program_runs_through_rs274: skipped, no rs274 (LinuxCNC) on PATH");
        return;
    };
    let _ = rs;
    let dir = tempfile::tempdir().unwrap();
    let prog = dir.path().join("scan.ngc");
    let o = run(
        &[
            "--circle",
            "12.7",
            "--points",
            "20",
            "--program",
            prog.to_str().unwrap(),
            "--dialect",
            "iso",
        ],
        None,
    );
    assert!(o.status.success());
    std::fs::write(dir.path().join("tools.tbl"), "T1 P1 D0.1 Z0\n").unwrap();
    let canon = dir.path().join("canon.txt");
    let st = Command::new("rs274")
        .current_dir(dir.path())
        .args(["-t", "tools.tbl", "-g", "scan.ngc", canon.to_str().unwrap()])
        .stdin(Stdio::null())
        .output()
        .unwrap();
    let text = std::fs::read_to_string(&canon).unwrap_or_default();
    assert!(
        st.status.success(),
        "rs274 failed: {}",
        String::from_utf8_lossy(&st.stderr)
    );
    // rs274 alone has no probe: G38.2 "touches" at its end, G38.3 never.
    // So the program logs two contacts, then runs one full step (retract,
    // reposition, approach, two searches) and stops on the lost surface,
    // with the step's points where the planner puts them.
    let probes: Vec<Vec<f64>> = text
        .lines()
        .filter_map(|l| l.split_once("STRAIGHT_PROBE(").map(|(_, r)| r))
        .map(|r| r.split(',').take(2).map(|x| x.trim().parse().unwrap()).collect())
        .collect();
    assert!(text.contains("lost surface"), "{text}");
    assert_eq!(probes.len(), 7, "{probes:?}");
    let rs = job::step_for_points(6.4, 20);
    let (p1, ro) = ((-6.6 + 5.0, rs), 0.1);
    let near = |p: &Vec<f64>, x: f64, y: f64| (p[0] - x).abs() < 1e-3 && (p[1] - y).abs() < 1e-3;
    // u = +Y (P0 -> P1), material to the right (+X); the back-off is an
    // unguarded feed move.
    let feeds: Vec<Vec<f64>> = text
        .lines()
        .filter_map(|l| l.split_once("STRAIGHT_FEED(").map(|(_, r)| r))
        .map(|r| r.split(',').take(2).map(|x| x.trim().parse().unwrap()).collect())
        .collect();
    assert!(near(&feeds[1], p1.0 - ro, p1.1), "back-off {feeds:?}");
    assert!(near(&probes[3], p1.0 - ro, p1.1 + rs), "reposition {:?}", probes[3]);
    assert!(near(&probes[4], p1.0 + rs, p1.1 + rs), "approach {:?}", probes[4]);
    assert!(near(&probes[5], p1.0 + rs, p1.1 - ro), "search {:?}", probes[5]);
    assert!(near(&probes[6], p1.0, p1.1), "back to P1 {:?}", probes[6]);
}

#[test]
fn pmac_program_is_balanced() {
    let o = run(
        &["--circle", "12.7", "--program", "/dev/stdout", "-o", "/dev/null"],
        None,
    );
    let text = String::from_utf8_lossy(&o.stdout);
    let count = |w: &str| text.lines().filter(|l| l.trim_start().starts_with(w)).count();
    assert_eq!(count("IF ("), count("ENDIF"));
    assert_eq!(count("WHILE ("), count("ENDWHILE"));
    assert!(text.contains("^0") && text.contains("OPEN PROG 50 CLEAR") && text.trim_end().ends_with("CLOSE"));
}

#[test]
fn failures_say_why_and_write_nothing() {
    // The start inside the part.
    let o = run(&["--circle", "12.7", "--start", "0,0"], None);
    assert_eq!(o.status.code(), Some(2));
    assert!(o.stdout.is_empty());
    assert!(String::from_utf8_lossy(&o.stderr).contains("in the part"));
    // Nothing along the initial direction.
    let o = run(&["--circle", "12.7", "--dir", "-1,0"], None);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("maximum approach"));
    // The contact limit: exit 1, nothing written unless --partial.
    let o = run(&["--circle", "12.7", "--max-points", "10"], None);
    assert_eq!(o.status.code(), Some(1));
    assert!(o.stdout.is_empty());
    assert!(String::from_utf8_lossy(&o.stderr).contains("limit of 10 contacts"));
    let o = run(&["--circle", "12.7", "--max-points", "10", "--partial"], None);
    assert_eq!(json(&o)["scan"]["stop"], "max_points");
    // Open chains bound nothing.
    let open = "{\"schema\":\"microcam.chains/1\"}\n{\"id\":1,\"closed\":false,\"segments\":[{\"type\":\"line\",\"start\":[0,0],\"end\":[1,0]}]}\n";
    let o = run(&["-"], Some(open));
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("open"));
    let o = run(&["--circle", "-1"], None);
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn same_seed_same_bytes() {
    let args = [
        "--circle",
        "12.7",
        "--noise",
        "0.001",
        "--quantise",
        "--seed",
        "9",
        "--csv",
        "/dev/stdout",
    ];
    let (a, b) = (run(&args, None), run(&args, None));
    assert!(a.status.success());
    assert_eq!(a.stdout, b.stdout);
    let c = run(
        &[
            "--circle",
            "12.7",
            "--noise",
            "0.001",
            "--quantise",
            "--seed",
            "10",
            "--csv",
            "/dev/stdout",
        ],
        None,
    );
    assert_ne!(a.stdout, c.stdout);
}
