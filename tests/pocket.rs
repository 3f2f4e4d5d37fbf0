//! `pathgen pocket` end to end, and the proofs of the grid pocket on
//! generated concave polygons with Bezier bottoms: no tool position
//! outside the tool-centre region, every cell visited, the cutter never
//! below the exact surface along any move (sampled far finer than the
//! grid), no rapid into the stock; the Iowa State grid-pocket thesis'
//! (1999) case study inputs; arc + line and Bezier + line within tolerance
//! in fewer blocks than lines; the offset strategy beside the grid.

use cavalier_contours::polyline::{PlineSourceMut, Polyline};
use microcam::cutter::Cutter;
use microcam::geometry::{Arc3, P2, P3};
use microcam::machine::Machine;
use microcam::model::toolpath::{MotionKind, Record};
use microcam::pocket::layers::Feeds;
use microcam::pocket::motion::{FitOptions, MotionMode};
use microcam::pocket::surface::{BezierPatch, Surface};
use microcam::pocket::{Layers, PocketJob, PocketSpec, Strategy, plan};
use std::process::Command;

const UM: f64 = 1e-3;

/// A small deterministic generator (xorshift), so failures reproduce.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A concave polygon: a star-like outline with alternating deep notches
/// (vertices counter-clockwise), about `size` mm across.
fn concave_polygon(rng: &mut Rng, size: f64) -> Vec<P2> {
    let n = 5 + (rng.next() * 4.0) as usize;
    (0..2 * n)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / (2 * n) as f64;
            let r = if k % 2 == 0 {
                0.5 * size * (0.8 + 0.2 * rng.next())
            } else {
                0.5 * size * (0.45 + 0.15 * rng.next())
            };
            P2::new(0.5 * size + r * a.cos(), 0.5 * size + r * a.sin())
        })
        .collect()
}

fn bezier(rng: &mut Rng, size: f64, depth: f64) -> Surface {
    let z: Vec<f64> = (0..16).map(|_| -depth * (0.6 + 0.4 * rng.next())).collect();
    Surface::Bezier(BezierPatch::new([0.0, size], [0.0, size], &z).unwrap())
}

fn spec(
    poly: &[P2],
    surface: Surface,
    cutter: Cutter,
    pitch: (f64, f64),
    layers: usize,
    motion: MotionMode,
) -> PocketSpec {
    let mut pl = Polyline::new_closed();
    for p in poly {
        pl.add(p.x, p.y, 0.0);
    }
    PocketSpec {
        boundary: pl,
        surface,
        cutter,
        top_z: 0.0,
        dx: pitch.0,
        dy: pitch.1,
        origin: Some(P2::origin()),
        layers: Layers::Count(layers),
        feeds: Feeds {
            rough: 3.0,
            finish: 2.0,
            plunge: 0.5,
            safe_z: 1.0,
        },
        motion,
        fit: FitOptions {
            tol: 0.002,
            max_radius: 500.0,
        },
        gouge_tol: 0.0005,
        strategy: Strategy::Grid,
        stepover: pitch.0.min(pitch.1),
        force: false,
        machine: Machine::builtin("micro-mill"),
    }
}

/// Signed distance from `p` to the polygon's boundary: positive inside.
fn inside_distance(poly: &[P2], p: P2) -> f64 {
    let mut best = f64::INFINITY;
    let mut wind = 0i32;
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        let d = b - a;
        let t = ((p - a).dot(&d) / d.norm_squared()).clamp(0.0, 1.0);
        best = best.min((p - (a + d * t)).norm());
        let side = d.perp(&(p - a));
        if a.y <= p.y {
            if b.y > p.y && side > 0.0 {
                wind += 1;
            }
        } else if b.y <= p.y && side < 0.0 {
            wind -= 1;
        }
    }
    if wind != 0 { best } else { -best }
}

/// Points along every feed move, `step` mm apart, with the move's index.
fn feed_samples(job: &PocketJob, step: f64) -> Vec<(usize, P3)> {
    let mut out = Vec::new();
    let mut pos: Option<P3> = None;
    for (k, r) in job.program.records.iter().enumerate() {
        let Some(m) = r.motion() else { continue };
        if let (Some(p), false) = (pos, m.kind == MotionKind::Rapid) {
            match m.kind {
                MotionKind::Arc(a) => {
                    let arc = Arc3::new(a.center, p, m.to, a.ccw, a.plane, 0).unwrap();
                    let n = ((arc.length() / step).ceil() as usize).max(1);
                    out.extend((0..=n).map(|i| (k, arc.point_at(i as f64 / n as f64))));
                }
                _ => {
                    let n = (((m.to - p).norm() / step).ceil() as usize).max(1);
                    out.extend((0..=n).map(|i| (k, p + (m.to - p) * (i as f64 / n as f64))));
                }
            }
        }
        pos = Some(m.to);
    }
    out
}

/// How far the cutter at tip `p` reaches below the surface, checked on a
/// dense polar net under it (24 rings, 8k points on ring k) -- independent
/// of the 8-ring search the planner uses.
fn gouge_at(surface: &Surface, c: &Cutter, p: &P3) -> f64 {
    let r = c.radius();
    let mut worst = f64::NEG_INFINITY;
    for k in 0..=24 {
        let rho = r * k as f64 / 24.0;
        let prof = c.profile(rho).unwrap();
        let m = (8 * k).max(1);
        for a in 0..m {
            let phi = std::f64::consts::TAU * (a as f64 + 0.37) / m as f64;
            let s = surface.height(p.x + rho * phi.cos(), p.y + rho * phi.sin());
            worst = worst.max(s - (p.z + prof));
        }
    }
    worst
}

fn check_proofs(job: &PocketJob, s: &PocketSpec, poly: &[P2], what: &str) {
    let r = s.cutter.radius();
    // 1. Every position below the clearance keeps the cutter inside the
    //    boundary: at least R from it (1 um).
    let samples = feed_samples(job, 0.05 * s.dx.min(s.dy));
    for (k, p) in &samples {
        if p.z < s.feeds.safe_z - 1e-9 {
            let d = inside_distance(poly, P2::new(p.x, p.y));
            assert!(
                d >= r - UM,
                "{what}: record {k} at {p:?} is {d} mm from the wall (R = {r})"
            );
        }
    }
    // 2. Every cell of the region is passed over by a cutting move (arcs
    //    and curves of the final layer lie in vertical planes: from above
    //    they are straight).
    let mut segs: Vec<(P2, P2)> = Vec::new();
    let mut at: Option<P3> = None;
    for r in &job.program.records {
        let Some(m) = r.motion() else { continue };
        if let (Some(p), false) = (at, m.kind == MotionKind::Rapid) {
            segs.push((P2::new(p.x, p.y), P2::new(m.to.x, m.to.y)));
        }
        at = Some(m.to);
    }
    for c in &job.grid.cells {
        let g = job.grid.centre(*c);
        let d = segs
            .iter()
            .map(|(a, b)| {
                let v = b - a;
                let t = if v.norm_squared() > 0.0 {
                    ((g - a).dot(&v) / v.norm_squared()).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                (g - (a + v * t)).norm()
            })
            .fold(f64::INFINITY, f64::min);
        assert!(d < 1e-6, "{what}: cell {c:?} never visited ({d} mm away)");
    }
    // 3. The cutter never below the exact surface (1 um), sampled every
    //    1/10 of the smaller pitch along every feed move.
    let coarse = feed_samples(job, 0.1 * s.dx.min(s.dy));
    let worst = coarse
        .iter()
        .map(|(k, p)| (gouge_at(&s.surface, &s.cutter, p), *k))
        .fold((f64::NEG_INFINITY, 0), |a, b| if b.0 > a.0 { b } else { a });
    assert!(worst.0 <= UM, "{what}: gouge {} mm at record {}", worst.0, worst.1);
    // 4. Rapids only at or above the clearance, or straight up.
    let mut pos: Option<P3> = None;
    for (k, rec) in job.program.records.iter().enumerate() {
        let Some(m) = rec.motion() else { continue };
        if m.kind == MotionKind::Rapid {
            let up = pos.is_some_and(|p| (m.to.x - p.x).abs() < 1e-12 && (m.to.y - p.y).abs() < 1e-12 && m.to.z >= p.z);
            assert!(
                up || m.to.z >= s.feeds.safe_z - 1e-12,
                "{what}: rapid {k} into the pocket"
            );
            if let Some(p) = pos {
                assert!(
                    p.z >= s.feeds.safe_z - 1e-12 || up,
                    "{what}: rapid {k} leaves from below clearance sideways"
                );
            }
        }
        pos = Some(m.to);
    }
}

#[test]
fn generated_concave_pockets_with_bezier_bottoms_keep_every_proof() {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let cutters = [
        Cutter::Ball { radius: 1.0 },
        Cutter::Flat { radius: 1.0 },
        Cutter::Torus {
            radius: 1.0,
            corner: 0.4,
        },
    ];
    for case in 0..6 {
        let poly = concave_polygon(&mut rng, 18.0);
        let surface = bezier(&mut rng, 18.0, 3.0);
        let c = cutters[case % 3];
        let motion = [MotionMode::Lines, MotionMode::ArcLine, MotionMode::BezierLine][case % 3];
        let s = spec(&poly, surface, c, (1.2, 0.9), 2, motion);
        let job = plan(&s).unwrap();
        assert!(job.grid.cells.len() > 40, "case {case}: {} cells", job.grid.cells.len());
        check_proofs(&job, &s, &poly, &format!("case {case} ({c}, {motion:?})"));
    }
}

#[test]
fn the_offset_strategy_keeps_the_same_proofs_except_cell_visits() {
    let mut rng = Rng(12345);
    let poly = concave_polygon(&mut rng, 14.0);
    let mut s = spec(
        &poly,
        bezier(&mut rng, 14.0, 3.0),
        Cutter::Ball { radius: 1.0 },
        (1.2, 0.9),
        2,
        MotionMode::Lines,
    );
    s.strategy = Strategy::Offset;
    let job = plan(&s).unwrap();
    let r = s.cutter.radius();
    for (_, p) in feed_samples(&job, 0.05) {
        if p.z < s.feeds.safe_z - 1e-9 {
            assert!(inside_distance(&poly, P2::new(p.x, p.y)) >= r - UM);
        }
        assert!(gouge_at(&s.surface, &s.cutter, &p) <= UM);
    }
    assert!(job.figures.passes.iter().any(|(k, n)| k == "offset" && *n >= 2));
}

fn case_study() -> (Vec<P2>, Surface) {
    // The thesis' inputs in inches; our own general concave polygon (a
    // cross with a gabled top) and Bezier bottom.
    let inch = 25.4;
    let poly: Vec<P2> = [
        (0.25, 0.75),
        (1.375, 0.75),
        (1.375, 0.375),
        (2.125, 0.375),
        (2.125, 0.75),
        (2.625, 0.75),
        (2.625, 1.75),
        (1.875, 1.75),
        (1.375, 2.0),
        (0.875, 1.75),
        (0.25, 1.75),
    ]
    .iter()
    .map(|&(x, y)| P2::new(x * inch, y * inch))
    .collect();
    let z: Vec<f64> = [
        -0.30, -0.28, -0.32, -0.35, -0.32, -0.25, -0.30, -0.36, -0.35, -0.30, -0.28, -0.34, -0.40, -0.38, -0.36, -0.37,
    ]
    .iter()
    .map(|v| v * inch)
    .collect();
    let s = Surface::Bezier(BezierPatch::new([0.25 * inch, 2.625 * inch], [0.375 * inch, 2.0 * inch], &z).unwrap());
    (poly, s)
}

#[test]
fn thesis_case_study_six_layers_with_every_pass_kind() {
    let (poly, surface) = case_study();
    let mut s = spec(
        &poly,
        surface,
        Cutter::Ball { radius: 0.125 * 25.4 },
        (0.125 * 25.4, 0.0625 * 25.4),
        6,
        MotionMode::Lines,
    );
    s.fit.tol = 0.001;
    let job = plan(&s).unwrap();
    let f = &job.figures;
    assert_eq!(f.layers, 6);
    assert_eq!(f.floors_mm.len(), 5);
    for kind in ["main", "wall", "x_zigzag", "y_zigzag"] {
        assert!(
            f.passes.iter().any(|(k, n)| k == kind && *n > 0),
            "{kind}: {:?}",
            f.passes
        );
    }
    check_proofs(&job, &s, &poly, "case study");
    // Roughing layers never go below their floor.
    let lowest = job
        .program
        .records
        .iter()
        .filter_map(|r| r.motion().map(|m| m.to.z))
        .fold(f64::INFINITY, f64::min);
    assert!(lowest < f.floors_mm[4]);
    // Arc + line and Bezier + line: within tolerance, fewer blocks.
    let blocks = |name: &str| f.motion_blocks.iter().find(|m| m.0 == name).unwrap().clone();
    let (lines, arcs, bez) = (blocks("lines"), blocks("arc_line"), blocks("bezier_line"));
    assert!(arcs.1 < lines.1 && bez.1 < lines.1, "{lines:?} {arcs:?} {bez:?}");
    assert!(
        arcs.2 <= s.fit.tol + 1e-9 && bez.2 <= s.fit.tol + 1e-9,
        "{arcs:?} {bez:?}"
    );
    // And the programs that use them stay gouge-free.
    for m in [MotionMode::ArcLine, MotionMode::BezierLine] {
        let mut s2 = s.clone();
        s2.motion = m;
        s2.layers = Layers::Count(1);
        let job = plan(&s2).unwrap();
        assert_eq!(
            job.program.final_main_blocks,
            if m == MotionMode::ArcLine { arcs.1 } else { bez.1 }
        );
        check_proofs(&job, &s2, &poly, &format!("case study {m:?}"));
    }
}

mod common;

fn bin(name: &str) -> Command {
    Command::new(common::bin(name))
}

const POLY: &str = "0,0;12,0;12,5;7,5;7,10;0,10";
const NET: &str = "-2,-2.2,-2.4,-2,-2.3,-3,-3,-2.4,-2.2,-3,-2.8,-2.1,-2,-2.1,-2.2,-2";

#[test]
fn cli_refuses_a_pitch_above_d_over_root_two_unless_forced() {
    let out = bin("pathgen")
        .args([
            "pocket",
            "--polygon",
            POLY,
            "--tool",
            "ball:2",
            "--grid",
            "1.5,1",
            "--floor-z",
            "-1",
            "--report",
            "-",
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("D/sqrt(2)") && err.contains("material would be left"),
        "{err}"
    );
    let out = bin("pathgen")
        .args([
            "pocket",
            "--polygon",
            POLY,
            "--tool",
            "ball:2",
            "--grid",
            "1.5,1",
            "--floor-z",
            "-1",
            "--report",
            "-",
            "--force",
        ])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for bad in [
        vec!["--tool", "ball:x"],
        vec!["--polygon", "0,0;1,1"],
        vec!["--bezier-z", "1,2"],
    ] {
        let mut args = vec![
            "pocket",
            "--grid",
            "1,1",
            "--floor-z",
            "-1",
            "--polygon",
            POLY,
            "--tool",
            "ball:2",
        ];
        if bad[0] == "--bezier-z" {
            args.retain(|a| *a != "--floor-z" && *a != "-1");
        }
        args.extend(bad.iter());
        let out = bin("pathgen").args(&args).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{bad:?}");
    }
}

#[test]
fn cli_warns_that_only_the_first_closed_chain_is_pocketed() {
    let dir = std::env::temp_dir().join(format!("microcam-pocket-chains-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let square = |id: u32, x: f64, closed: bool| {
        let p = |a: f64, b: f64| format!("[{a},{b}]");
        let line = |a: String, b: String| format!(r#"{{"type":"line","start":{a},"end":{b}}}"#);
        let (c0, c1, c2, c3) = (p(x, 0.0), p(x + 6.0, 0.0), p(x + 6.0, 6.0), p(x, 6.0));
        let mut segs = vec![line(c0.clone(), c1.clone()), line(c1, c2.clone()), line(c2, c3.clone())];
        if closed {
            segs.push(line(c3, c0));
        }
        format!(
            r#"{{"id":{id},"layer":"0","closed":{closed},"segments":[{}]}}"#,
            segs.join(",")
        )
    };
    let header = r#"{"schema":"microcam.chains/1","units":"mm"}"#;
    let run = |chains: &[String]| {
        let f = dir.join("c.jsonl");
        std::fs::write(&f, format!("{header}\n{}\n", chains.join("\n"))).unwrap();
        let out = bin("pathgen")
            .args(["pocket", "--tool", "flat:2", "--grid", "1,1", "--floor-z", "-1"])
            .arg(&f)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        (String::from_utf8_lossy(&out.stderr).to_string(), out.stdout)
    };
    // An open chain first, then three closed ones: the first closed one
    // (id 2) is cut, the two others are named as left.
    let (err, out) = run(&[
        square(1, -20.0, false),
        square(2, 0.0, true),
        square(3, 10.0, true),
        square(4, 20.0, true),
    ]);
    assert!(
        err.contains("pocketing chain 2") && err.contains("2 other closed chains are not pocketed"),
        "{err}"
    );
    let (alone_err, alone) = run(&[square(2, 0.0, true)]);
    assert!(!alone_err.contains("warning"), "{alone_err}");
    // The same program either way (the source line names the same file).
    assert_eq!(out, alone);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn cli_programs_are_repeatable_and_rapid_only_above_the_stock_in_gsim() {
    for dialect in ["pmac", "iso"] {
        let run = || {
            bin("pathgen")
                .args([
                    "pocket",
                    "--polygon",
                    POLY,
                    "--tool",
                    "ball:2",
                    "--grid",
                    "1,1",
                    "--bezier-z",
                    NET,
                    "--layers",
                    "3",
                    "--motion",
                    "arc-line",
                    "--gcode",
                    dialect,
                ])
                .output()
                .unwrap()
        };
        let (a, b) = (run(), run());
        assert!(a.status.success(), "{}", String::from_utf8_lossy(&a.stderr));
        assert_eq!(a.stdout, b.stdout, "byte-identical output");
        let dir = tempfile::tempdir().unwrap();
        let prog = dir.path().join("p.nc");
        std::fs::write(&prog, &a.stdout).unwrap();
        let g = bin("gsim")
            .args([
                "--stock",
                "-1,-1,-4,13,11,0",
                "--tool",
                "ball:2",
                "--cell-mm",
                "0.05",
                "--start",
                "0,0,1",
            ])
            .arg(&prog)
            .output()
            .unwrap();
        assert!(g.status.success(), "{}", String::from_utf8_lossy(&g.stderr));
        let rep: serde_json::Value = serde_json::from_slice(&g.stdout).unwrap();
        assert_eq!(rep["removal"]["rapids_in_material"], 0.0, "{dialect}");
        assert!(rep["removal"]["removed_volume_mm3"].as_f64().unwrap() > 50.0);
    }
}

#[test]
fn cli_reads_chains_and_measured_points() {
    let dir = tempfile::tempdir().unwrap();
    let chains = dir.path().join("b.chains");
    std::fs::write(
        &chains,
        "{\"schema\":\"microcam.chains/1\",\"units\":\"mm\"}\n{\"id\":1,\"closed\":true,\"segments\":[{\"type\":\"line\",\"start\":[0,0],\"end\":[10,0]},{\"type\":\"arc\",\"start\":[10,0],\"end\":[10,8],\"center\":[10,4],\"ccw\":true},{\"type\":\"line\",\"start\":[10,8],\"end\":[0,8]},{\"type\":\"line\",\"start\":[0,8],\"end\":[0,0]}]}\n",
    )
    .unwrap();
    let csv = dir.path().join("probe.csv");
    let mut text = String::from("x,y,z\n");
    for j in 0..=4 {
        for i in 0..=7 {
            let (x, y) = (i as f64 * 2.0, j as f64 * 2.0);
            text.push_str(&format!("{x},{y},{}\n", -1.5 - 0.3 * (0.4 * x).sin() * (0.5 * y).cos()));
        }
    }
    std::fs::write(&csv, text).unwrap();
    let out = bin("pathgen")
        .args([
            "pocket",
            "--tool",
            "ball:2",
            "--grid",
            "1,1",
            "--report",
            "-",
            "--surface",
        ])
        .arg(&csv)
        .arg(&chains)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let rep: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(rep["schema"], "microcam.pocket-report/1");
    assert!(rep["cells"].as_u64().unwrap() > 40);
    assert!(rep["cycle_time_s"].as_f64().unwrap() > 0.0);
}

#[test]
fn tool_positions_of_the_toolpath_output_are_the_library_job() {
    let out = bin("pathgen")
        .args([
            "pocket",
            "--polygon",
            POLY,
            "--tool",
            "flat:2",
            "--grid",
            "1,1",
            "--floor-z",
            "-1",
        ])
        .output()
        .unwrap();
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    let mut lines = text.lines();
    assert!(lines.next().unwrap().contains("microcam.toolpath/1"));
    let moves: Vec<serde_json::Value> = lines.map(|l| serde_json::from_str(l).unwrap()).collect();
    // A flat floor: every cut at -1, rapids only at the clearance.
    for m in &moves {
        let z = m["to"][2].as_f64().unwrap();
        match m["type"].as_str().unwrap() {
            "rapid" => assert_eq!(z, 1.0),
            _ if m["role"] == "cut" => assert_eq!(z, -1.0),
            _ => {}
        }
    }
    let _ = Record::Dwell {
        seconds: 0.0,
        block: None,
    };
}

#[test]
fn the_gouge_check_sees_what_the_planner_avoids() {
    use microcam::pocket::contact::Contact;
    let (_, surface) = case_study();
    let ball = Cutter::Ball { radius: 3.175 };
    let c = Contact::new(&surface, ball, 5e-4);
    // Plain cell-to-cell chords at touching heights dip below the surface
    // somewhere on this row: the planner splits them, the check would fail.
    let mut worst = f64::NEG_INFINITY;
    for k in 0..14 {
        let (x0, x1) = (10.0 + 3.175 * k as f64, 10.0 + 3.175 * (k + 1) as f64);
        let (a, b) = (
            P3::new(x0, 30.0, c.tip_z(x0, 30.0)),
            P3::new(x1, 30.0, c.tip_z(x1, 30.0)),
        );
        for t in [0.25, 0.5, 0.75] {
            worst = worst.max(gouge_at(&surface, &ball, &(a + (b - a) * t)));
        }
        // The planner's split of the same move stays within 1 um.
        let mut pts = Vec::new();
        c.safe_line(a, b, &mut pts);
        let mut p = a;
        for q in pts {
            for t in [0.25, 0.5, 0.75] {
                assert!(gouge_at(&surface, &ball, &(p + (q - p) * t)) <= UM);
            }
            p = q;
        }
    }
    assert!(worst > UM, "chords dip {worst} mm");
    // The surface point under the centre is too low for a ball on a slope.
    let p = P3::new(20.0, 40.0, surface.height(20.0, 40.0));
    let g = gouge_at(&surface, &ball, &p);
    assert!(g > UM, "{g}");
    assert!(gouge_at(&surface, &ball, &P3::new(20.0, 40.0, c.tip_z(20.0, 40.0))) <= 1e-6);
}
