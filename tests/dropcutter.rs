//! End-to-end tests of `pathgen dropcutter` on project-made meshes and the
//! corpus STL files.

use microcam::corpus;
use microcam::formats::cldata::read_cldata;
use microcam::geometry::{Line3, P3, Plane, V3};
use microcam::model::toolpath::{Motion, Record, Role};
use std::path::Path;
use std::process::Command;

fn pathgen() -> Command {
    Command::new(env!("CARGO_BIN_EXE_pathgen"))
}

/// Binary STL of triangles.
fn write_stl(path: &Path, tris: &[[[f64; 3]; 3]]) {
    let mut b = vec![0u8; 80];
    b.extend((tris.len() as u32).to_le_bytes());
    for t in tris {
        b.extend([0u8; 12]);
        for v in t {
            for c in v {
                b.extend((*c as f32).to_le_bytes());
            }
        }
        b.extend([0u8; 2]);
    }
    std::fs::write(path, b).unwrap();
}

/// Run a `pathgen dropcutter` job that must succeed: its CL data and its
/// stderr (`what` names the run in a failure).
fn cl_run(mut job: Command, what: &str) -> (microcam::formats::cldata::ClData, String) {
    let o = job.output().unwrap();
    assert_eq!(
        o.status.code(),
        Some(0),
        "{what}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    (
        read_cldata(o.stdout.as_slice()).unwrap(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// `stlverify` of the 5-axis CL data `cl` with a 1 mm end mill (5 mm of
/// flutes) cut from `stock` (X0,Y0,Z0,X1,Y1,Z1), against the design `stl`
/// on a grid of `step` over `region` (X0,X1,Y0,Y1) with a band of 0.01
/// mm: its exit status and its verification record.
fn stlverify_flat_1(stl: &Path, cl: &Path, stock: &str, region: &str, step: &str) -> (Option<i32>, serde_json::Value) {
    let v = Command::new(env!("CARGO_BIN_EXE_stlverify"))
        .args(["--quiet", "--stock", stock, "--tool", "flat:1", "--flute-length", "5"])
        .arg("--design")
        .arg(stl)
        .args([
            "--region",
            region,
            "--step-forward",
            step,
            "--step-over",
            step,
            "--band",
            "0.01",
        ])
        .arg(cl)
        .output()
        .unwrap();
    let r: serde_json::Value = serde_json::from_slice(&v.stdout).unwrap();
    (v.status.code(), r["verification"].clone())
}

/// A job refused as bad usage or bad input: exit 2 and nothing on stdout
/// (`what` names the job in a failure).
fn assert_refused(o: &std::process::Output, what: &str) {
    assert_eq!(
        o.status.code(),
        Some(2),
        "{what}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(o.stdout.is_empty(), "{what}");
}

/// The records of a toolpath (JSON Lines) output.
fn toolpath_records(bytes: &[u8]) -> Vec<Record> {
    microcam::formats::toolpath::ToolpathReader::new(bytes)
        .unwrap()
        .map(|r| r.unwrap())
        .collect()
}

/// A toolpath's passes in order: each plunge with the cut moves after it.
fn plunged_passes(recs: &[Record]) -> Vec<(&Motion, Vec<&Motion>)> {
    let moves: Vec<&Motion> = recs.iter().filter_map(|r| r.motion()).collect();
    (0..moves.len())
        .filter(|&i| moves[i].role == Some(Role::Plunge))
        .map(|i| {
            let cut = moves[i + 1..]
                .iter()
                .copied()
                .take_while(|m| m.role == Some(Role::Cut))
                .collect();
            (moves[i], cut)
        })
        .collect()
}

/// gsim's report of `prog` (PMAC text) on the micro-mill.
fn gsim_micro_mill(dir: &Path, prog: &[u8]) -> serde_json::Value {
    let path = dir.join("sim.pmc");
    std::fs::write(&path, prog).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_gsim"))
        .args(["--machine", "micro-mill"])
        .arg(&path)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

/// Two gsim reports side by side: a G1 per point against arcs.
fn gsim_comparison(plain: &serde_json::Value, arcs: &serde_json::Value) -> String {
    let f = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap();
    format!(
        "G1 per point {} of {} blocks slowed, {:.1} s; arcs {} of {}, {:.1} s (ideal {:.1} s)",
        plain["limited_blocks"],
        plain["feed_blocks"],
        f(plain, "cycle_time_s"),
        arcs["limited_blocks"],
        arcs["feed_blocks"],
        f(arcs, "cycle_time_s"),
        f(arcs, "ideal_cutting_time_s")
    )
}

/// Upper half of a UV sphere of radius `r` about the origin.
fn hemisphere(r: f64, nu: usize, nv: usize) -> Vec<[[f64; 3]; 3]> {
    let p = |i: usize, j: usize| {
        let th = std::f64::consts::FRAC_PI_2 * i as f64 / nv as f64;
        let ph = std::f64::consts::TAU * j as f64 / nu as f64;
        [r * th.sin() * ph.cos(), r * th.sin() * ph.sin(), r * th.cos()]
    };
    let mut t = Vec::new();
    for i in 0..nv {
        for j in 0..nu {
            if i > 0 {
                t.push([p(i, j), p(i + 1, j), p(i, j + 1)]);
            }
            t.push([p(i + 1, j), p(i + 1, j + 1), p(i, j + 1)]);
        }
    }
    t
}

/// The tests' hemisphere (radius 5, 128 x 32 facets) as `s.stl` in a new
/// temporary directory, kept alive by the returned handle.
fn hemisphere_stl() -> (tempfile::TempDir, std::path::PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let stl = dir.path().join("s.stl");
    write_stl(&stl, &hemisphere(5.0, 128, 32));
    (dir, stl)
}

#[test]
fn ball_on_a_sphere_gives_the_offset_sphere() {
    let (_dir, stl) = hemisphere_stl();
    let out = pathgen()
        .args([
            "dropcutter",
            stl.to_str().unwrap(),
            "--tool",
            "ball:1",
            "--step-over",
            "0.5",
        ])
        .args(["--region", "-3,-3,3,3"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let d = read_cldata(&out.stdout[..]).unwrap();
    assert_eq!(d.points.len(), 13 * 13);
    for p in &d.points {
        let want = (5.5f64 * 5.5 - p.x * p.x - p.y * p.y).sqrt() - 0.5;
        assert!(p.z <= want + 1e-6 && p.z > want - 0.01, "{p:?} vs {want}");
    }
    // Same input, same bytes.
    let again = pathgen()
        .args([
            "dropcutter",
            stl.to_str().unwrap(),
            "--tool",
            "ball:1",
            "--step-over",
            "0.5",
        ])
        .args(["--region", "-3,-3,3,3"])
        .output()
        .unwrap();
    assert_eq!(out.stdout, again.stdout);
}

#[test]
fn waterlines_circle_a_hemisphere_at_each_level() {
    // Ball of radius 0.5 round a hemisphere of radius 5 on the table: at tip
    // height z the loop is the circle of radius sqrt(5.5² - (z + 0.5)²),
    // within the tessellation's sag; levels every 1 mm from the top down to
    // the floor (the table, z 0), top down, the part on the right.
    let (_dir, stl) = hemisphere_stl();
    let run = |fmt: &[&str]| {
        pathgen()
            .args(["dropcutter", stl.to_str().unwrap(), "-q", "--tool", "ball:1"])
            .args(["--waterline-step", "1", "--step-over", "0.05", "--safe-z", "7"])
            .args(fmt)
            .output()
            .unwrap()
    };
    let out = run(&[]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("5 waterline levels, 5 loops"), "{err}");
    let d = read_cldata(&out.stdout[..]).unwrap();
    let mut levels: Vec<f64> = Vec::new();
    let sag = 5.0 * (1.0 - (std::f64::consts::PI / 64.0).cos());
    for p in d.points.iter().filter(|p| p.z != 7.0) {
        if levels.last() != Some(&p.z) {
            levels.push(p.z);
        }
        let r = p.x.hypot(p.y);
        let want = (5.5f64 * 5.5 - (p.z + 0.5).powi(2)).sqrt();
        assert!(
            r <= want + 1e-5 && r >= want - 2.0 * sag - 1e-5,
            "{p:?}: r {r} vs {want}"
        );
    }
    assert_eq!(levels, [4.0, 3.0, 2.0, 1.0, 0.0], "top (z 5) down to the table");
    // Clockwise round the part (climb milling with M3).
    let lp: Vec<_> = d.points.iter().filter(|p| p.z == levels[0]).collect();
    let area2: f64 = lp.windows(2).map(|w| w[0].x * w[1].y - w[1].x * w[0].y).sum();
    assert!(area2 < 0.0);
    // G-code and toolpath outputs too, and the same bytes again.
    assert_eq!(run(&[]).stdout, out.stdout);
    let g = run(&["--gcode", "iso"]);
    assert!(g.status.success());
    assert!(String::from_utf8_lossy(&g.stdout).contains("G1"));
    let t = run(&["--format", "toolpath"]);
    assert!(t.status.success());
    assert!(String::from_utf8_lossy(&t.stdout).starts_with("{"));
}

/// `--arc-fit`: the hemisphere's waterlines as G2/G3 instead of a line
/// per point: far fewer moves, each loop at its level, every point of
/// every arc within the tolerance of where the loop's own points lie.
#[test]
fn waterline_loops_are_fitted_with_arcs_within_the_tolerance() {
    let (dir, stl) = hemisphere_stl();
    let run = |fmt: &[&str]| {
        pathgen()
            .args(["dropcutter", stl.to_str().unwrap(), "--tool", "ball:1"])
            .args(["--waterline-step", "1", "--step-over", "0.05", "--safe-z", "7"])
            .args(fmt)
            .output()
            .unwrap()
    };
    let tol = 0.002;
    let out = run(&["--format", "toolpath", "--arc-fit", "0.002"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("arcs fitted within 0.002 mm of the loops' chords"),
        "{err}"
    );
    let recs = toolpath_records(&out.stdout);
    let sag = 5.0 * (1.0 - (std::f64::consts::PI / 64.0).cos());
    let (mut arcs, mut cuts) = (0, 0);
    let mut from = P3::new(0.0, 0.0, 7.0);
    for m in recs.iter().filter_map(|r| r.motion()) {
        if m.role == Some(Role::Cut) {
            cuts += 1;
            assert_eq!(m.to.z, from.z, "a loop stays at its level");
            let want = (5.5f64 * 5.5 - (m.to.z + 0.5).powi(2)).sqrt();
            let pts: Vec<P3> = match m.arc(from) {
                Some(a) => {
                    arcs += 1;
                    (0..=16).map(|k| a.point_at(k as f64 / 16.0)).collect()
                }
                None => vec![m.to],
            };
            for p in pts {
                let r = p.x.hypot(p.y);
                // The band of the loop's own points (the plain test's),
                // widened by the tolerance.
                assert!(
                    r <= want + 1e-5 + tol && r >= want - 2.0 * sag - 1e-5 - tol,
                    "{p:?}: r {r} vs {want}"
                );
            }
        }
        from = m.to;
    }
    let points: usize = err
        .split(" CL points")
        .next()
        .and_then(|h| h.rsplit(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap();
    assert!(
        arcs * 2 > cuts && cuts * 5 < points,
        "{arcs} arcs of {cuts} moves for {points} points"
    );
    // G-code: arcs written as G2/G3; the same bytes again.
    let g = run(&["--gcode", "iso", "--arc-fit", "0.002"]);
    assert!(g.status.success());
    let text = String::from_utf8_lossy(&g.stdout);
    assert!(text.contains("G2") || text.contains("G3"), "{text}");
    assert_eq!(run(&["--gcode", "iso", "--arc-fit", "0.002"]).stdout, g.stdout);
    // The figures docs/dropcutter.md quotes (`-- --nocapture` shows them).
    let plain = run(&["--gcode", "iso"]);
    let lines = |o: &std::process::Output| o.stdout.iter().filter(|&&b| b == b'\n').count();
    eprintln!(
        "hemisphere waterlines: {arcs} arcs of {cuts} moves for {points} points; ISO program {} lines, {} with arcs",
        lines(&plain),
        lines(&g)
    );
    assert!(lines(&g) * 5 < lines(&plain));
    // Run by the controller model (gsim, PMAC, the micro-mill): a G1
    // per point makes blocks shorter than the stage's least move time, so
    // nearly every one runs slow; the arcs do not.
    let (p_sim, a_sim) = (
        gsim_micro_mill(dir.path(), &run(&["--gcode", "pmac"]).stdout),
        gsim_micro_mill(dir.path(), &run(&["--gcode", "pmac", "--arc-fit", "0.002"]).stdout),
    );
    let f = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap();
    eprintln!("gsim: {}", gsim_comparison(&p_sim, &a_sim));
    assert!(f(&a_sim, "limited_blocks") * 10.0 < f(&p_sim, "limited_blocks"));
    assert!(f(&a_sim, "cycle_time_s") * 1.5 < f(&p_sim, "cycle_time_s"));
    // Bad usage: CL data has no arcs; rasters are not fitted; T positive.
    for bad in [
        &["--arc-fit", "0.002"][..],
        &["--format", "toolpath", "--arc-fit", "0"],
        &["--format", "toolpath", "--arc-fit", "nan"],
    ] {
        let o = run(bad);
        assert_refused(&o, &format!("{bad:?}"));
    }
    // Passes along drawn chains lie in no one plane G2/G3 can name.
    let chains = dir.path().join("c.jsonl");
    std::fs::write(&chains, "").unwrap();
    let o = pathgen()
        .args(["dropcutter", stl.to_str().unwrap(), "--tool", "ball:1", "--chains"])
        .arg(&chains)
        .args(["--step-forward", "0.1", "--format", "toolpath", "--arc-fit", "0.002"])
        .output()
        .unwrap();
    assert_refused(&o, "--chains with --arc-fit");
    assert!(String::from_utf8_lossy(&o.stderr).contains("--arc-fit goes with a raster or waterlines"));
}

/// `--arc-fit` on a raster: each pass fitted in its own vertical plane
/// (G18 along X, G19 along Y; a zigzag's links along the region's edge in
/// the other), every sampled point of every move within the tolerance of
/// the plain job's CL polyline, the same bytes twice, and the micro-mill
/// (gsim, PMAC) no longer slowed at every block.
#[test]
fn raster_passes_are_fitted_with_arcs_in_their_planes() {
    let (dir, stl) = hemisphere_stl();
    let tol = 0.001;
    for (direction, pattern, along) in [("x", "zigzag", Plane::Xz), ("y", "one-way", Plane::Yz)] {
        let run = |extra: &[&str]| {
            pathgen()
                .args(["dropcutter", stl.to_str().unwrap(), "--tool", "ball:1"])
                .args(["--step-over", "1", "--step-forward", "0.02", "--region", "-3,-3,3,3"])
                .args(["--direction", direction, "--pattern", pattern, "--safe-z", "7"])
                .args(extra)
                .output()
                .unwrap()
        };
        let plain = run(&[]);
        assert!(plain.status.success());
        let cl = read_cldata(&plain.stdout[..]).unwrap().points;
        // The plain job's passes: CL points below the safe Z, split where
        // the tool goes up to it.
        let mut passes: Vec<Vec<P3>> = vec![Vec::new()];
        for p in &cl {
            if p.z >= 7.0 - 1e-9 {
                if passes.last().is_some_and(|p| !p.is_empty()) {
                    passes.push(Vec::new());
                }
            } else if let Some(pass) = passes.last_mut() {
                pass.push(*p);
            }
        }
        passes.retain(|p| !p.is_empty());
        let near = |q: &P3| {
            passes
                .iter()
                .flat_map(|p| p.windows(2))
                .map(|w| Line3::new(w[0], w[1]).distance(q))
                .fold(f64::INFINITY, f64::min)
        };
        let out = run(&["--format", "toolpath", "--arc-fit", "0.001"]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{err}");
        assert!(
            err.contains("arcs fitted within 0.001 mm of the passes' chords"),
            "{err}"
        );
        let recs = toolpath_records(&out.stdout);
        let (mut arcs, mut along_arcs, mut cuts, mut worst) = (0, 0, 0, 0.0f64);
        let mut from = P3::new(0.0, 0.0, 7.0);
        for m in recs.iter().filter_map(|r| r.motion()) {
            if m.role == Some(Role::Cut) {
                cuts += 1;
                let pts: Vec<P3> = match m.arc(from) {
                    Some(a) => {
                        arcs += 1;
                        along_arcs += usize::from(a.plane == along);
                        // Along a pass (its line of the raster, 1 mm
                        // apart), or along the region's edge on a
                        // zigzag's link.
                        let h = a.plane.normal_coord(&a.start);
                        assert_eq!(a.plane.normal_coord(&a.end), h);
                        if a.plane == along {
                            assert_eq!(h, h.round(), "{a:?}");
                        } else {
                            assert!(pattern == "zigzag" && h.abs() == 3.0, "{a:?}");
                        }
                        (0..=16).map(|k| a.point_at(k as f64 / 16.0)).collect()
                    }
                    None => vec![m.to],
                };
                for p in pts {
                    worst = worst.max(near(&p));
                }
            }
            from = m.to;
        }
        assert!(worst <= tol * 1.0001, "{direction}: {worst}");
        assert!(
            along_arcs * 4 > arcs * 3,
            "{direction}: {along_arcs} of {arcs} arcs along the passes"
        );
        let points: usize = passes.iter().map(Vec::len).sum();
        assert!(cuts * 5 < points, "{direction}: {cuts} moves for {points} points");
        // G-code names the plane; the same bytes again.
        let g = run(&["--gcode", "iso", "--arc-fit", "0.001"]);
        let text = String::from_utf8_lossy(&g.stdout);
        assert!(
            text.contains(if along == Plane::Xz { "G18" } else { "G19" }),
            "{direction}"
        );
        assert_eq!(run(&["--gcode", "iso", "--arc-fit", "0.001"]).stdout, g.stdout);
        // The controller model: a G1 per point is slowed at nearly every
        // block; the arcs run near the feed.
        let (p_sim, a_sim) = (
            gsim_micro_mill(dir.path(), &run(&["--gcode", "pmac"]).stdout),
            gsim_micro_mill(dir.path(), &run(&["--gcode", "pmac", "--arc-fit", "0.001"]).stdout),
        );
        let f = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap();
        // The figures docs/dropcutter.md quotes (`-- --nocapture` shows them).
        eprintln!(
            "raster along {direction}, {pattern}: {arcs} arcs of {cuts} moves for {points} points, worst {worst:.6} mm; gsim micro-mill: {}",
            gsim_comparison(&p_sim, &a_sim)
        );
        assert!(f(&a_sim, "cycle_time_s") * 2.0 < f(&p_sim, "cycle_time_s"));
        assert!(f(&a_sim, "limited_blocks") * 5.0 < f(&p_sim, "limited_blocks"));
    }
}

#[test]
fn chord_tol_refines_waterlines_between_fibres() {
    // Fibres 1 mm apart round a hemisphere of radius 5: the chords between
    // them sag by about chord² / 8r inside the loop of radius ~5 (some
    // 0.05 mm). With --chord-tol 0.001 every chord's middle lies on the
    // offset circle within the tessellation's sag and the tolerance.
    let (_dir, stl) = hemisphere_stl();
    let run = |extra: &[&str]| {
        let out = pathgen()
            .args(["dropcutter", stl.to_str().unwrap(), "-q", "--tool", "ball:1"])
            .args(["--waterline", "2", "--step-over", "1", "--safe-z", "7"])
            .args(extra)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        read_cldata(&out.stdout[..])
            .unwrap()
            .points
            .into_iter()
            .filter(|p| p.z == 2.0)
            .collect::<Vec<_>>()
    };
    let want = (5.5f64 * 5.5 - 2.5f64.powi(2)).sqrt();
    let sag = 5.0 * (1.0 - (std::f64::consts::PI / 64.0).cos());
    let worst_middle = |lp: &[microcam::geometry::P3]| {
        lp.windows(2)
            .map(|w| {
                let m = (w[0].coords + w[1].coords) * 0.5;
                (want - m.x.hypot(m.y)).max(0.0)
            })
            .fold(0.0, f64::max)
    };
    let plain = run(&[]);
    let fine = run(&["--chord-tol", "0.001"]);
    assert!(worst_middle(&plain) > 0.03, "{}", worst_middle(&plain));
    assert!(
        worst_middle(&fine) <= 2.0 * sag + 0.001 + 1e-5,
        "{} > {}",
        worst_middle(&fine),
        2.0 * sag + 0.001
    );
    assert!(fine.len() > plain.len());
    for p in &fine {
        assert!(p.x.hypot(p.y) <= want + 1e-5, "{p:?} inside the offset");
    }
}

#[test]
fn toolpath_gcode_adaptive_and_five_axis_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let stl = dir.path().join("s.stl");
    write_stl(&stl, &hemisphere(5.0, 64, 16));
    let s = stl.to_str().unwrap();
    let run = |args: &[&str]| pathgen().arg("dropcutter").arg(s).args(args).output().unwrap();
    let tp = run(&[
        "--tool",
        "flat:1",
        "--step-over",
        "1",
        "--pattern",
        "one-way",
        "--format",
        "toolpath",
    ]);
    assert!(tp.status.success());
    let text = String::from_utf8(tp.stdout).unwrap();
    assert!(text.starts_with("{\"schema\":\"microcam.toolpath/1\""));
    assert!(text.contains("\"type\":\"rapid\"") && text.contains("\"role\":\"plunge\""));
    let g = run(&["--tool", "torus:1:0.2", "--step-over", "1", "--gcode", "iso"]);
    assert!(g.status.success());
    let g = String::from_utf8(g.stdout).unwrap();
    assert!(g.contains("G1") && g.contains("G0"));
    // Adaptive sampling adds points to a coarse raster.
    let coarse = run(&["--tool", "ball:1", "--step-over", "2"]);
    let fine = run(&["--tool", "ball:1", "--step-over", "2", "--chord-tol", "0.001"]);
    let (c, f) = (
        read_cldata(&coarse.stdout[..]).unwrap(),
        read_cldata(&fine.stdout[..]).unwrap(),
    );
    assert!(
        f.points.len() > 2 * c.points.len(),
        "{} {}",
        f.points.len(),
        c.points.len()
    );
    // 5-axis: six numbers a row, axis points `--axis-length` from the tip.
    let five = run(&[
        "--tool",
        "flat:1",
        "--step-over",
        "1",
        "--region",
        "-2,-2,2,2",
        "--five-axis",
        "--lead",
        "5",
    ]);
    assert!(five.status.success(), "{}", String::from_utf8_lossy(&five.stderr));
    // A gentle patch: no change over the default 20 degrees, and stderr
    // says so rather than counting none.
    let e = String::from_utf8_lossy(&five.stderr);
    assert!(
        e.contains("between neighbouring locations, within --max-axis-change 20.0: nothing stepped or lifted"),
        "{e}"
    );
    let d = read_cldata(&five.stdout[..]).unwrap();
    assert!(d.is_five_axis() && d.points.len() == d.axis.len());
    for (p, q) in d.points.iter().zip(&d.axis) {
        assert!(((q - p).norm() - 50.0).abs() < 1e-6);
    }
    let ball5 = run(&["--tool", "ball:1", "--step-over", "1", "--five-axis"]);
    assert_eq!(ball5.status.code(), Some(2));
}

#[test]
fn bad_input_exits_2_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.stl");
    std::fs::write(&bad, "solid x\n facet normal 0 0 1\n outer loop\n vertex 1 2\n").unwrap();
    let out_file = dir.path().join("out.cl");
    let o = pathgen()
        .args([
            "dropcutter",
            bad.to_str().unwrap(),
            "--tool",
            "ball:1",
            "--step-over",
            "1",
            "-o",
        ])
        .arg(&out_file)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("bad.stl"));
    assert!(!out_file.exists());
    let stl = dir.path().join("s.stl");
    write_stl(&stl, &hemisphere(1.0, 8, 4));
    for args in [
        vec!["--tool", "drill:1", "--step-over", "1"],
        vec!["--tool", "ball:1"],
        vec!["--tool", "ball:1", "--step-over", "0"],
        vec!["--tool", "ball:1", "--step-over", "1", "--region", "1,1,0,0"],
        vec!["--tool", "ball:1", "--step-over", "1e-9"],
        vec!["--tool", "ball:1", "--waterline", "0.5"],
        vec!["--tool", "ball:1", "--step-over", "0.1", "--waterline", "nan"],
        vec!["--tool", "ball:1", "--step-over", "0.1", "--waterline", "-5"],
        vec!["--tool", "ball:1", "--step-over", "0.1", "--waterline-step", "0"],
        vec![
            "--tool",
            "ball:1",
            "--step-over",
            "0.1",
            "--waterline",
            "0.5",
            "--chord-tol",
            "0",
        ],
        vec![
            "--tool",
            "ball:1",
            "--step-over",
            "0.1",
            "--waterline",
            "0.5",
            "--chord-tol",
            "1e-9",
        ],
        vec![
            "--tool",
            "ball:1",
            "--step-over",
            "0.1",
            "--waterline",
            "0.5",
            "--five-axis",
        ],
    ] {
        let o = pathgen().arg("dropcutter").arg(&stl).args(&args).output().unwrap();
        assert_refused(&o, &format!("{args:?}"));
    }
}

/// `pathgen dropcutter FILE ARGS...` on every corpus STL, tallied as
/// `test`: each file with its output; an exit other than 0 (done) or 2
/// (refused) fails the test. Empty when the corpus is absent.
fn on_every_corpus_stl(test: &str, args: &[&str]) -> Vec<(std::path::PathBuf, std::process::Output)> {
    let files = corpus::files("stl", &[".stl"]);
    if files.is_empty() {
        corpus::skip(test);
        return Vec::new();
    }
    let runs: Vec<_> = files
        .into_iter()
        .map(|f| {
            let o = pathgen().arg("dropcutter").arg(&f).args(args).output().unwrap();
            assert!(
                matches!(o.status.code(), Some(0 | 2)),
                "{f:?}: exit {:?}: {}",
                o.status.code(),
                String::from_utf8_lossy(&o.stderr)
            );
            (f, o)
        })
        .collect();
    corpus::record(test, runs.len());
    runs
}

#[test]
fn every_corpus_stl_drops_or_is_refused() {
    let args = [
        "--tool",
        "torus:1:0.2",
        "--step-over",
        "0.5",
        "--step-forward",
        "0.05",
        "--safe-z",
        "1e6",
    ];
    let plain = on_every_corpus_stl("dropcutter_corpus", &args);
    for (f, o) in &plain {
        if o.status.code() == Some(2) {
            assert!(!o.stderr.is_empty(), "{f:?}");
            continue;
        }
        let d = read_cldata(&o.stdout[..]).unwrap();
        assert!(
            !d.points.is_empty() && d.points.iter().all(|p| p.z.is_finite()),
            "{f:?}"
        );
    }
    // With arcs fitted (toolpath): the same meshes read or refused alike;
    // one plunge per pass onto its first point, its cuts ending on its
    // last, and every cut's end within the tolerance of the pass's chords.
    let tol = 0.002;
    let fitted = [&args[..], &["-q", "--format", "toolpath", "--arc-fit", "0.002"]].concat();
    let arcs = on_every_corpus_stl("dropcutter_corpus_arcs", &fitted);
    for ((f, p), (_, a)) in plain.iter().zip(&arcs) {
        assert_eq!(p.status.code(), a.status.code(), "{f:?}");
        if p.status.code() != Some(0) {
            continue;
        }
        let d = read_cldata(&p.stdout[..]).unwrap();
        let passes: Vec<&[P3]> = d.points.split(|q| q.z == 1e6).filter(|l| !l.is_empty()).collect();
        let recs = toolpath_records(&a.stdout);
        let fitted = plunged_passes(&recs);
        assert_eq!(fitted.len(), passes.len(), "{f:?}");
        for ((plunge, cut), pass) in fitted.into_iter().zip(&passes) {
            assert!((plunge.to - pass[0]).norm() < 1e-6, "{f:?}");
            let end = cut.last().map_or(plunge.to, |m| m.to);
            assert!((end - pass[pass.len() - 1]).norm() < 1e-6, "{f:?}: pass not ended");
            for m in cut {
                let d = pass
                    .windows(2)
                    .map(|w| Line3::new(w[0], w[1]).distance(&m.to))
                    .fold(f64::INFINITY, f64::min);
                assert!(d <= tol * 1.0001, "{f:?}: {:?} {d} off the pass", m.to);
            }
        }
    }
}

#[test]
fn every_corpus_stl_gives_closed_waterlines_or_is_refused() {
    // Levels every 0.5 mm down each real mesh, fibres 0.2 mm apart, the
    // chords as they are and refined: every loop closed and at its level,
    // the levels top down.
    let args = [
        "-q",
        "--tool",
        "ball:1",
        "--waterline-step",
        "0.5",
        "--step-over",
        "0.2",
        "--safe-z",
        "1e6",
    ];
    let refined = [&args[..], &["--chord-tol", "0.002"]].concat();
    let plain = on_every_corpus_stl("waterline_corpus", &args);
    let refined = on_every_corpus_stl("waterline_corpus_refined", &refined);
    for (f, o) in plain.iter().chain(&refined) {
        if o.status.code() == Some(2) {
            assert!(!o.stderr.is_empty() && o.stdout.is_empty(), "{f:?}");
            continue;
        }
        let d = read_cldata(&o.stdout[..]).unwrap();
        let mut prev_z = f64::INFINITY;
        for pass in d.points.split(|p| p.z == 1e6).filter(|p| !p.is_empty()) {
            assert!(pass.len() >= 3, "{f:?}: a loop of {} points", pass.len());
            assert_eq!(pass.first(), pass.last(), "{f:?}: loop not closed");
            assert!(pass.iter().all(|p| p.z == pass[0].z), "{f:?}: a loop off its level");
            assert!(pass[0].z <= prev_z, "{f:?}: levels not top down");
            prev_z = pass[0].z;
        }
    }
    // With arcs fitted (toolpath): the same meshes read or are refused
    // alike; each loop's feed moves start and end where its points do,
    // at its level.
    let fitted = [&args[..], &["--format", "toolpath", "--arc-fit", "0.002"]].concat();
    let arcs = on_every_corpus_stl("waterline_corpus_arcs", &fitted);
    for ((f, p), (_, a)) in plain.iter().zip(&arcs) {
        assert_eq!(p.status.code(), a.status.code(), "{f:?}");
        if p.status.code() != Some(0) {
            continue;
        }
        let d = read_cldata(&p.stdout[..]).unwrap();
        let loops: Vec<&[P3]> = d.points.split(|q| q.z == 1e6).filter(|l| !l.is_empty()).collect();
        let recs = toolpath_records(&a.stdout);
        // One plunge per loop, each onto the loop's first point; the cuts
        // after it stay at that level and close the loop.
        let fitted = plunged_passes(&recs);
        assert_eq!(fitted.len(), loops.len(), "{f:?}");
        for ((plunge, cut), l) in fitted.into_iter().zip(&loops) {
            assert!((plunge.to - l[0]).norm() < 1e-6, "{f:?}");
            assert!(cut.iter().all(|m| m.to.z == l[0].z), "{f:?}: off its level");
            let end = cut.last().map_or(plunge.to, |m| m.to);
            assert!((end - l[l.len() - 1]).norm() < 1e-6, "{f:?}: loop not closed");
        }
    }
}

/// A trough along x: the circle of radius `rho` about (y, z) = (0, rho)
/// from -60 to +60 degrees in `m` facets, x from -3 to 3.
fn trough(rho: f64, m: usize) -> Vec<[[f64; 3]; 3]> {
    let th_max = 60f64.to_radians();
    let yz = |k: usize| {
        let th = -th_max + 2.0 * th_max * k as f64 / m as f64;
        (rho * th.sin(), rho * (1.0 - th.cos()))
    };
    let mut t = Vec::new();
    for k in 0..m {
        let ((y0, z0), (y1, z1)) = (yz(k), yz(k + 1));
        t.push([[-3.0, y0, z0], [3.0, y0, z0], [3.0, y1, z1]]);
        t.push([[-3.0, y0, z0], [3.0, y1, z1], [-3.0, y1, z1]]);
    }
    t
}

#[test]
fn five_axis_locations_that_would_gouge_are_lifted_or_reported() {
    let dir = tempfile::tempdir().unwrap();
    let stl = dir.path().join("trough.stl");
    // A trough of radius 2 and a flat end mill of radius 1: along the
    // surface normal its bottom cuts into the rising sides.
    write_stl(&stl, &trough(2.0, 41));
    let s = stl.to_str().unwrap();
    let run = |extra: &[&str]| {
        let o = pathgen()
            .arg("dropcutter")
            .arg(s)
            .args([
                "--tool",
                "flat:1",
                "--step-over",
                "0.4",
                "--region",
                "-1,-1.2,1,1.2",
                "--five-axis",
                "--lead",
                "5",
            ])
            .args(extra)
            .output()
            .unwrap();
        assert!(o.status.success(), "{extra:?}: {}", String::from_utf8_lossy(&o.stderr));
        (
            read_cldata(&o.stdout[..]).unwrap(),
            String::from_utf8(o.stderr).unwrap(),
        )
    };
    let (lifted, e_lift) = run(&[]);
    let (reported, e_report) = run(&["--gouge", "report"]);
    let (off, e_off) = run(&["--gouge", "off"]);
    assert!(
        e_lift.contains("locations cut into the part") && e_lift.contains("lifted along the axis"),
        "{e_lift}"
    );
    assert!(
        e_report.contains("locations cut into the part") && e_report.contains("left as they are"),
        "{e_report}"
    );
    assert!(!e_off.contains("gouge"), "{e_off}");
    assert_eq!(reported.points, off.points);
    assert_eq!(lifted.points.len(), off.points.len());
    let mut moved = 0;
    for i in 0..off.points.len() {
        let (l, o) = (lifted.points[i], off.points[i]);
        let axis = (off.axis[i] - o).normalize();
        let shift = l - o;
        // A lift moves the tool up its own axis, never down or sideways.
        let along = shift.dot(&axis);
        assert!(along >= 0.0 && (shift - axis * along).norm() < 1e-5, "{i}: {shift:?}");
        assert!(((lifted.axis[i] - l).norm() - 50.0).abs() < 1e-5);
        if along > 1e-3 {
            moved += 1;
        }
    }
    assert!(moved * 2 > off.points.len(), "{moved} of {}", off.points.len());
    let (_, e_tilt) = run(&["--gouge", "tilt", "--max-turn", "20", "--turn-step", "10"]);
    assert!(e_tilt.contains("turned to clear it"), "{e_tilt}");
    assert!(e_tilt.contains("more turned part way to ease the axis"), "{e_tilt}");
    // Not eased: the turned locations only.
    let (_, e_sharp) = run(&["--gouge", "tilt", "--turn-ramp", "0"]);
    assert!(e_sharp.contains("; 0 more turned part way"), "{e_sharp}");
    // Bad usage: exit 2, nothing written.
    for bad in [
        &["--five-axis", "--gouge", "tilt", "--max-turn", "100"][..],
        &["--five-axis", "--gouge", "tilt", "--turn-step", "0"],
        &["--five-axis", "--gouge", "tilt", "--turn-ramp", "-1"],
        &["--five-axis", "--gouge", "tilt", "--turn-ramp", "nan"],
        &["--five-axis", "--gouge", "lift", "--turn-ramp", "1"],
        // The turns go with the tilt search, the check with 5-axis output.
        &["--five-axis", "--max-turn", "10"],
        &["--gouge", "report"],
    ] {
        let o = pathgen()
            .args(["dropcutter", s, "--tool", "flat:1", "--step-over", "0.4"])
            .args(bad)
            .output()
            .unwrap();
        assert_refused(&o, &format!("{bad:?}"));
    }
}

/// A roof along x: two planes rising 40 degrees from y = -3 and y = 3 to a
/// ridge at y = 0, z = 3 tan 40.
fn roof() -> Vec<[[f64; 3]; 3]> {
    let h = 3.0 * 40f64.to_radians().tan();
    vec![
        [[-3.0, -3.0, 0.0], [3.0, -3.0, 0.0], [3.0, 0.0, h]],
        [[-3.0, -3.0, 0.0], [3.0, 0.0, h], [-3.0, 0.0, h]],
        [[-3.0, 0.0, h], [3.0, 0.0, h], [3.0, 3.0, 0.0]],
        [[-3.0, 0.0, h], [3.0, 3.0, 0.0], [-3.0, 3.0, 0.0]],
    ]
}

/// `--max-axis-change`: across the ridge of a roof the facet normals turn
/// the tool axis by 80 degrees between two neighbours. With a limit of 30
/// the tool turns over the ridge in steps (each set down on the part); with
/// `--axis-change lift` each crossing ends a run and the tool is lifted to
/// the safe Z, turned there and put down again. Either way every location
/// of the plain job is kept, in order, and no two neighbours in the cut
/// have axes more than 30 degrees apart.
#[test]
fn a_large_change_of_the_tool_axis_is_stepped_or_lifted_instead_of_swung() {
    let dir = tempfile::tempdir().unwrap();
    let stl = dir.path().join("roof.stl");
    write_stl(&stl, &roof());
    let job = |extra: &[&str]| {
        let mut c = pathgen();
        c.arg("dropcutter")
            .arg(&stl)
            .args([
                "--tool",
                "flat:0.5",
                "--step-over",
                "0.5",
                "--step-forward",
                "0.25",
                "--direction",
                "y",
                "--region",
                "-1,-2,1,2",
                "--five-axis",
                "--gouge",
                "off",
                "--safe-z",
                "10",
            ])
            .args(extra);
        c
    };
    type Cl = microcam::formats::cldata::ClData;
    let angle = |d: &Cl, i: usize, j: usize| {
        let (u, v) = (
            (d.axis[i] - d.points[i]).normalize(),
            (d.axis[j] - d.points[j]).normalize(),
        );
        u.cross(&v).norm().atan2(u.dot(&v)).to_degrees()
    };
    // Rows in the cut (tips below the safe Z), and the largest change
    // between two such rows in a row.
    let contacts = |d: &Cl| -> Vec<usize> { (0..d.points.len()).filter(|&i| d.points[i].z < 10.0 - 1e-9).collect() };
    let worst = |d: &Cl, c: &[usize]| {
        c.windows(2)
            .filter(|w| w[1] == w[0] + 1)
            .map(|w| angle(d, w[0], w[1]))
            .fold(0.0, f64::max)
    };
    // Every row of `a` is in `b`, in order.
    let kept_in_order = |a: &Cl, b: &Cl| {
        let mut j = 0;
        a.points.iter().zip(&a.axis).all(|(p, x)| {
            while j < b.points.len() && (b.points[j], b.axis[j]) != (*p, *x) {
                j += 1;
            }
            j < b.points.len()
        })
    };
    let (plain, e_plain) = cl_run(job(&["--max-axis-change", "off"]), "plain");
    assert!(e_plain.contains("the tool axis turns by up to 80.0 deg"), "{e_plain}");
    assert!((worst(&plain, &contacts(&plain)) - 80.0).abs() < 1e-6);
    // The zigzag crosses the ridge at x = -1, -0.5, 0, 0.5 and 1.
    let crossings = 5;

    let (stepped, e_steps) = cl_run(job(&["--max-axis-change", "30"]), "steps");
    assert!(
        e_steps.contains(&format!(
            "{crossings} places where the tool axis turns by more than 30.0 deg between neighbours (up to 80.0 deg): {crossings} turned in {} added steps set down on the part, 0 ending a run",
            2 * crossings
        )),
        "{e_steps}"
    );
    // Two steps of 26.7 degrees added at each crossing, no lift.
    assert_eq!(stepped.points.len(), plain.points.len() + 2 * crossings);
    assert_eq!(contacts(&stepped).len(), stepped.points.len());
    assert!(kept_in_order(&plain, &stepped));
    assert!(worst(&stepped, &contacts(&stepped)) <= 30.0);
    // The steps ride over the ridge: none below the two slopes.
    let h = 3.0 * 40f64.to_radians().tan();
    for (p, x) in stepped.points.iter().zip(&stepped.axis) {
        let a = (x - p).normalize();
        // The flat bottom's rim: the lowest point round the tip.
        let u = (V3::z() - a * a.z).normalize() * -0.25;
        let low = p + u;
        assert!(low.z >= h - h / 3.0 * low.y.abs() - 1e-6, "{p:?} {a:?}");
    }

    let (lifted, e_lift) = cl_run(job(&["--max-axis-change", "30", "--axis-change", "lift"]), "lift");
    assert!(
        e_lift.contains(&format!("{crossings} places where the tool axis turns by more than 30.0 deg between neighbours (up to 80.0 deg): 0 turned in 0 added steps set down on the part, {crossings} ending a run")),
        "{e_lift}"
    );
    // The contacts are the same locations in the same order; the links
    // (tips at the safe Z) are two more per split, and one at the end
    // (the one run of the plain job had none).
    let (pc, lc) = (contacts(&plain), contacts(&lifted));
    assert_eq!(pc.len(), lc.len());
    for (&i, &j) in pc.iter().zip(&lc) {
        assert_eq!((plain.points[i], plain.axis[i]), (lifted.points[j], lifted.axis[j]));
    }
    assert_eq!(lifted.points.len(), plain.points.len() + 2 * crossings + 1);
    assert!(worst(&lifted, &lc) <= 30.0);

    // By default the limit is 20 degrees, in steps; 180 is no limit.
    let (default, e_default) = cl_run(job(&[]), "default");
    let (twenty, _) = cl_run(job(&["--max-axis-change", "20"]), "20");
    assert_eq!((&default.points, &default.axis), (&twenty.points, &twenty.axis));
    assert!(
        e_default.contains(&format!(
            "{crossings} places where the tool axis turns by more than 20.0 deg"
        )),
        "{e_default}"
    );
    assert!(worst(&default, &contacts(&default)) <= 20.0);
    let (half_turn, _) = cl_run(job(&["--max-axis-change", "180"]), "180");
    assert_eq!((&half_turn.points, &half_turn.axis), (&plain.points, &plain.axis));

    for bad in [
        &["--max-axis-change", "0"][..],
        &["--max-axis-change", "0.01"],
        &["--max-axis-change", "181"],
        &["--max-axis-change", "nan"],
        &["--max-axis-change", "of"],
    ] {
        let o = job(bad).output().unwrap();
        assert_refused(&o, &format!("{bad:?}"));
    }
}

/// Machined in simulation (`stlverify`), the roof of the test above with
/// a 1 mm end mill: swung from one slope's normal to the other's between
/// two neighbours, the tool cuts into the ridge; turned in steps set down
/// on the part it cuts nothing away and leaves nothing (the ridge within
/// the band); lifted, it cuts nothing away but leaves the ridge standing.
#[test]
fn stlverify_finds_the_swing_gouge_at_a_ridge_and_none_after_the_steps() {
    let dir = tempfile::tempdir().unwrap();
    let stl = dir.path().join("roof.stl");
    write_stl(&stl, &roof());
    let verify = |extra: &[&str]| {
        let cl = dir.path().join("roof.cl");
        let o = pathgen()
            .arg("dropcutter")
            .arg(&stl)
            .args([
                "--tool",
                "flat:1",
                "--step-over",
                "0.1",
                "--step-forward",
                "0.05",
                "--direction",
                "y",
                "--region",
                "-1,-2,1,2",
                "--five-axis",
                "--gouge",
                "off",
                "-o",
            ])
            .arg(&cl)
            .args(extra)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        stlverify_flat_1(&stl, &cl, "-3,-3,-1,3,3,4", "-0.8,0.8,-1.5,1.5", "0.02")
    };
    let f = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap();
    let (code, swung) = verify(&["--max-axis-change", "off"]);
    assert_eq!(code, Some(1), "{swung}");
    assert!(
        f(&swung, "gouge") > 10.0 && f(&swung, "max_gouge_mm") > 0.015,
        "{swung}"
    );
    // The default: steps of at most 20 degrees.
    let (code, stepped) = verify(&[]);
    assert_eq!(code, Some(0), "{stepped}");
    assert_eq!((f(&stepped, "gouge"), f(&stepped, "excess")), (0.0, 0.0), "{stepped}");
    let (code, lifted) = verify(&["--max-axis-change", "20", "--axis-change", "lift"]);
    assert_eq!(code, Some(1), "{lifted}");
    assert_eq!(f(&lifted, "gouge"), 0.0, "{lifted}");
    assert!(f(&lifted, "max_excess_mm") > 1.0, "{lifted}");
    // The figures docs/dropcutter.md quotes (`-- --nocapture` shows them).
    for (name, v) in [("swung", &swung), ("stepped", &stepped), ("lifted", &lifted)] {
        eprintln!(
            "roof, {name}: {} points, gouges {} (worst {:.4} mm), excess {} (worst {:.4} mm)",
            v["points"],
            v["gouge"],
            f(v, "max_gouge_mm"),
            v["excess"],
            f(v, "max_excess_mm")
        );
    }
}

/// A floor with a block standing on it, 5 mm tall, its near face at
/// x = 1 (the 5-axis holder tests).
fn floor_and_wall() -> Vec<[[f64; 3]; 3]> {
    let mut t = Vec::new();
    let mut quad = |a: [f64; 3], b: [f64; 3], c: [f64; 3], d: [f64; 3]| {
        t.push([a, b, c]);
        t.push([a, c, d]);
    };
    quad([-3.0, -3.0, 0.0], [1.0, -3.0, 0.0], [1.0, 3.0, 0.0], [-3.0, 3.0, 0.0]);
    quad([1.0, -3.0, 5.0], [2.0, -3.0, 5.0], [2.0, 3.0, 5.0], [1.0, 3.0, 5.0]);
    quad([1.0, -3.0, 0.0], [1.0, 3.0, 0.0], [1.0, 3.0, 5.0], [1.0, -3.0, 5.0]);
    t
}

/// `--holder`: a holder 3 mm across from 2 mm up a 1 mm end mill hits the
/// wall where the cutter does not; lifted, the holder's face rises above
/// the wall's top; with the tilt search, locations clear it by leaning away.
#[test]
fn the_holder_is_checked_against_the_part() {
    let dir = tempfile::tempdir().unwrap();
    let stl = dir.path().join("wall.stl");
    write_stl(&stl, &floor_and_wall());
    let s = stl.to_str().unwrap();
    let job = || {
        let mut c = pathgen();
        c.args([
            "dropcutter",
            s,
            "--tool",
            "flat:1",
            "--five-axis",
            "--axis-length",
            "10",
        ]);
        c
    };
    let run = |extra: &[&str]| {
        let mut c = job();
        c.args(["--step-over", "0.25", "--region", "-2,-1,0.4,1"]).args(extra);
        cl_run(c, &format!("{extra:?}"))
    };
    let (plain, e_plain) = run(&["--gouge", "report"]);
    assert!(e_plain.contains("none of"), "{e_plain}");
    let (reported, e_rep) = run(&["--gouge", "report", "--holder", "3:2"]);
    assert!(!e_rep.contains("none of"), "{e_rep}");
    assert_eq!(reported.points, plain.points, "report leaves the locations");
    let (lifted, e_lift) = run(&["--holder", "3:2"]);
    assert!(e_lift.contains("lifted"), "{e_lift}");
    // With smoothed normals the floor's stay upright (the crease keeps
    // the wall's apart), the tools set down where they were, and the
    // holder lifts the same ones by the same amount.
    let (smooth, e_smooth) = run(&["--holder", "3:2", "--normals", "smooth"]);
    assert!(
        e_smooth.contains("set down on the part") && e_smooth.contains("lifted"),
        "{e_smooth}"
    );
    assert_eq!(smooth.points.len(), lifted.points.len());
    for (s, l) in smooth.points.iter().zip(&lifted.points) {
        assert!((s - l).norm() < 1e-6, "{s:?} {l:?}");
    }
    // Lifted where the holder reaches the wall (x > -1.5 + 0.5 on the
    // floor): its face at 2 mm rises to the top at 5 mm.
    let mut rose = 0;
    for (l, p) in lifted.points.iter().zip(&plain.points) {
        let up = l.z - p.z;
        assert!(up.abs() < 1e-9 || (up - 3.0).abs() < 1e-5, "{p:?} -> {l:?}");
        if up > 1.0 {
            assert!(p.x > -0.5 - 1e-9, "{p:?}");
            rose += 1;
        }
    }
    assert!(rose > 0);
    // A stepped holder: a nut too narrow to reach the wall under the
    // same holder (either way of writing it) lifts the same locations by
    // the same amount as that holder alone; a wider nose from 3 mm up
    // lifts more of them, its face to the wall's top (2 mm).
    for stepped in [
        &["--holder", "1.1:1,3:2"][..],
        &["--holder", "1.1:1", "--holder", "3:2"],
    ] {
        let (two, e_two) = run(stepped);
        assert!(e_two.contains("lifted"), "{e_two}");
        assert_eq!(two.points, lifted.points, "{stepped:?}");
    }
    let (nosed, _) = run(&["--holder", "3:2,5:3"]);
    let mut nose_rose = 0;
    for ((n, l), p) in nosed.points.iter().zip(&lifted.points).zip(&plain.points) {
        assert!(n.z >= l.z - 1e-9, "{p:?}: {n:?} below {l:?}");
        if n.z - l.z > 1e-3 {
            assert!((n.z - p.z - 2.0).abs() < 1e-5 && p.x <= -0.5 + 1e-9, "{p:?} -> {n:?}");
            nose_rose += 1;
        }
    }
    assert!(nose_rose > 0);
    let (_, e_tilt) = run(&["--gouge", "tilt", "--holder", "3:2"]);
    let turned: usize = e_tilt
        .split(" turned to clear it")
        .next()
        .and_then(|head| head.rsplit(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or(0);
    assert!(turned > 0, "{e_tilt}");
    // Bad usage: exit 2, nothing written.
    for bad in [
        &["--holder", "0.5:2"][..],
        &["--holder", "3"],
        &["--holder", "3:-1"],
        &["--holder", "3:10"],
        &["--holder", "3:2", "--gouge", "off"],
        &["--holder", "3:2,0.5:4"],
        &["--holder", "3:2,5:10"],
    ] {
        let o = job().args(["--step-over", "0.4"]).args(bad).output().unwrap();
        assert_refused(&o, &format!("{bad:?}"));
    }
}

/// The gouge check seen by the other engine: `stlverify` sweeps the tool
/// along the 5-axis locations through a dexel stock and compares the
/// machined top with the design. Unchecked, the tool cuts into every point
/// of the trough; lifted, nothing is cut below the design and what is left
/// stays within 0.01 mm.
#[test]
fn stlverify_finds_the_unchecked_gouges_and_none_after_the_lift() {
    let dir = tempfile::tempdir().unwrap();
    let stl = dir.path().join("trough.stl");
    write_stl(&stl, &trough(2.0, 41));
    let verify = |mode: &str| {
        let cl = dir.path().join(format!("{mode}.cl"));
        // "smooth-lift": --gouge lift --normals smooth.
        let (gouge, normals) = mode.split_once('-').map_or((mode, "facet"), |(n, g)| (g, n));
        let o = pathgen()
            .arg("dropcutter")
            .arg(&stl)
            .args(["--tool", "flat:1", "--step-over", "0.1", "--region", "-2,-1.2,2,1.2"])
            .args([
                "--five-axis",
                "--lead",
                "5",
                "--gouge",
                gouge,
                "--normals",
                normals,
                "-o",
            ])
            .arg(&cl)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        stlverify_flat_1(&stl, &cl, "-3,-1.7,-1,3,1.7,1", "-1.5,1.5,-1,1", "0.05")
    };
    let (code, off) = verify("off");
    assert_eq!(code, Some(1));
    assert_eq!(off["gouge"], off["points"], "{off}");
    assert!(off["max_gouge_mm"].as_f64().unwrap() > 0.05, "{off}");
    let (code, lift) = verify("lift");
    assert_eq!(code, Some(0), "{lift}");
    assert_eq!(lift["gouge"], 0, "{lift}");
    assert_eq!(lift["excess"], 0, "{lift}");
    assert!(lift["max_excess_mm"].as_f64().unwrap() < 0.01, "{lift}");
    // Turned instead of lifted: clear too, and closer to the design.
    let (code, tilt) = verify("tilt");
    assert_eq!(code, Some(0), "{tilt}");
    assert_eq!(tilt["gouge"], 0, "{tilt}");
    assert!(
        tilt["max_excess_mm"].as_f64().unwrap() < lift["max_excess_mm"].as_f64().unwrap(),
        "{tilt} {lift}"
    );
    // Axes from smoothed normals, each tool set down on the part: no
    // gouge either way, and turned closer to the design than lifted.
    let (code, s_lift) = verify("smooth-lift");
    assert_eq!((code, &s_lift["gouge"]), (Some(0), &serde_json::json!(0)), "{s_lift}");
    let (code, s_tilt) = verify("smooth-tilt");
    assert_eq!((code, &s_tilt["gouge"]), (Some(0), &serde_json::json!(0)), "{s_tilt}");
    let f = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap();
    // The figures docs/dropcutter.md quotes (`-- --nocapture` shows them).
    for (name, v) in [
        ("lift", &lift),
        ("tilt", &tilt),
        ("smooth-lift", &s_lift),
        ("smooth-tilt", &s_tilt),
    ] {
        eprintln!(
            "trough, {name}: worst excess {:.2} um, rms {:.2} um, gouges {}",
            1e3 * f(v, "max_excess_mm"),
            1e3 * f(v, "rms_mm"),
            v["gouge"]
        );
    }
    assert!(
        f(&s_tilt, "max_excess_mm") < f(&s_lift, "max_excess_mm"),
        "{s_tilt} {s_lift}"
    );
    // And closer than the facet normals' (on this trough: 0.4 um rms
    // turned, 1.7 lifted, against 3.2 lifted with facet normals).
    assert!(
        f(&s_tilt, "max_excess_mm") < f(&tilt, "max_excess_mm"),
        "{s_tilt} {tilt}"
    );
    assert!(f(&s_lift, "rms_mm") < f(&lift, "rms_mm"), "{s_lift} {lift}");
}

/// The gouge check on real files (corpus STL written by other programs:
/// open, non-manifold, degenerate triangles): every file gives 5-axis
/// data or is refused; where it runs, the lifted locations are the
/// unchecked ones moved up their own axes, never down or sideways, the
/// summary counts the locations moved, and `--gouge tilt` runs too.
#[test]
fn every_corpus_stl_gets_its_five_axis_locations_checked() {
    let raw = [
        "--tool",
        "torus:1:0.2",
        "--step-over",
        "0.5",
        "--five-axis",
        "--lead",
        "10",
    ];
    // The checks compared location by location: no steps added between.
    let base = [&raw[..], &["--max-axis-change", "off"]].concat();
    let off: Vec<_> = on_every_corpus_stl("gouge_corpus_off", &[&base[..], &["--gouge", "off"]].concat());
    let lift = on_every_corpus_stl("gouge_corpus_lift", &base);
    let tilt = on_every_corpus_stl("gouge_corpus_tilt", &[&base[..], &["--gouge", "tilt"]].concat());
    // With a holder 3 mm across from 2 mm up: lifted along the axes only,
    // at least as far as without it.
    let held = on_every_corpus_stl("gouge_corpus_holder", &[&base[..], &["--holder", "3:2"]].concat());
    // With smoothed normals: the same locations, each tool set down on the
    // part.
    let smooth = on_every_corpus_stl("gouge_corpus_smooth", &[&base[..], &["--normals", "smooth"]].concat());
    // The tilt search with the axis held to 15 degrees between neighbours:
    // every row of the tilt search's output kept in order, and no two
    // rows in the cut (below the safe Z, the highest tip) more than 15
    // degrees apart.
    let limited = on_every_corpus_stl(
        "gouge_corpus_axis_limit",
        &[&raw[..], &["--gouge", "tilt", "--max-axis-change", "15"]].concat(),
    );
    let mut limited_places = 0;
    for ((f, t), (_, m)) in tilt.iter().zip(&limited) {
        assert_eq!(t.status.code(), m.status.code(), "{f:?}");
        if t.status.code() != Some(0) {
            continue;
        }
        let (tc, mc) = (read_cldata(&t.stdout[..]).unwrap(), read_cldata(&m.stdout[..]).unwrap());
        let mut j = 0;
        for (p, x) in tc.points.iter().zip(&tc.axis) {
            while j < mc.points.len() && (mc.points[j], mc.axis[j]) != (*p, *x) {
                j += 1;
            }
            assert!(j < mc.points.len(), "{f:?}: {p:?} lost");
        }
        let safe = mc.points.iter().map(|p| p.z).fold(f64::NEG_INFINITY, f64::max);
        for i in 1..mc.points.len() {
            if mc.points[i].z >= safe - 1e-9 || mc.points[i - 1].z >= safe - 1e-9 {
                continue;
            }
            let (u, v) = (
                (mc.axis[i - 1] - mc.points[i - 1]).normalize(),
                (mc.axis[i] - mc.points[i]).normalize(),
            );
            let deg = u.cross(&v).norm().atan2(u.dot(&v)).to_degrees();
            assert!(deg <= 15.0 + 1e-6, "{f:?} row {i}: {deg} deg");
        }
        let err = String::from_utf8_lossy(&m.stderr);
        let places: usize = if err.contains("within --max-axis-change 15.0: nothing stepped or lifted") {
            0
        } else {
            err.split(" places where the tool axis turns by more than 15.0 deg")
                .next()
                .and_then(|head| head.rsplit(' ').next())
                .and_then(|n| n.parse().ok())
                .unwrap_or_else(|| panic!("{f:?}: {err}"))
        };
        limited_places += places;
    }
    // The corpus has ridges and creases: the limit had work to do.
    assert!(limited.is_empty() || limited_places > 100, "{limited_places}");
    eprintln!("corpus STL, --gouge tilt --max-axis-change 15: {limited_places} places over the limit");
    for ((((f, o), ((_, l), (_, t))), (_, h)), (_, s)) in off.iter().zip(lift.iter().zip(&tilt)).zip(&held).zip(&smooth)
    {
        assert_eq!(o.status.code(), l.status.code(), "{f:?}");
        assert_eq!(o.status.code(), t.status.code(), "{f:?}");
        assert_eq!(o.status.code(), h.status.code(), "{f:?}");
        assert_eq!(o.status.code(), s.status.code(), "{f:?}");
        if o.status.code() != Some(0) {
            continue;
        }
        let (sc, serr) = (read_cldata(&s.stdout[..]).unwrap(), String::from_utf8_lossy(&s.stderr));
        assert_eq!(
            sc.points.len(),
            read_cldata(&l.stdout[..]).unwrap().points.len(),
            "{f:?}"
        );
        assert!(
            serr.contains("set down on the part") && serr.contains("gouge check: "),
            "{f:?}: {serr}"
        );
        for (p, q) in sc.points.iter().zip(&sc.axis) {
            // The default --axis-length, to the CL data's decimals.
            assert!(((q - p).norm() - 50.0).abs() < 1e-4, "{f:?}: {p:?} {q:?}");
        }
        let (lc, hc) = (read_cldata(&l.stdout[..]).unwrap(), read_cldata(&h.stdout[..]).unwrap());
        assert_eq!(lc.points.len(), hc.points.len(), "{f:?}");
        for i in 0..lc.points.len() {
            let axis = (lc.axis[i] - lc.points[i]).normalize();
            let shift = hc.points[i] - lc.points[i];
            let along = shift.dot(&axis);
            assert!(
                along >= -1e-6 && (shift - axis * along).norm() < 1e-5,
                "{f:?} {i}: {shift:?}"
            );
        }
        let (o, l, err) = (
            read_cldata(&o.stdout[..]).unwrap(),
            read_cldata(&l.stdout[..]).unwrap(),
            String::from_utf8_lossy(&l.stderr),
        );
        assert_eq!(o.points.len(), l.points.len(), "{f:?}");
        let mut moved = 0;
        for i in 0..o.points.len() {
            let axis = (o.axis[i] - o.points[i]).normalize();
            let shift = l.points[i] - o.points[i];
            let along = shift.dot(&axis);
            assert!(
                along >= -1e-6 && (shift - axis * along).norm() < 1e-5,
                "{f:?} {i}: {shift:?}"
            );
            moved += (along > 1e-5) as usize;
        }
        let counted: usize = err
            .split("gouge check: ")
            .nth(1)
            .and_then(|r| r.split(' ').next())
            .and_then(|n| if n == "none" { Some(0) } else { n.parse().ok() })
            .unwrap_or_else(|| panic!("{f:?}: {err}"));
        // Locations lifted by less than the CL data's last decimal do not
        // show as moved; none moves that was not counted.
        assert!(moved <= counted, "{f:?}: {moved} moved, {counted} counted");
        assert!(String::from_utf8_lossy(&t.stderr).contains("gouge check:"), "{f:?}");
    }
}

/// `--normals smooth` on a coarse hemisphere: the tool axes follow the
/// sphere's own normals far more closely than the facets' do, and turn
/// between neighbours about as the sphere's normals do; every tool is set
/// down on the mesh (the summary says so), and the flags are checked.
#[test]
fn smoothed_normals_follow_the_surface_and_the_tools_rest_on_it() {
    let dir = tempfile::tempdir().unwrap();
    let stl = dir.path().join("dome.stl");
    write_stl(&stl, &hemisphere(10.0, 48, 12));
    let run = |extra: &[&str]| {
        let mut c = pathgen();
        c.arg("dropcutter")
            .arg(&stl)
            .args([
                "--tool",
                "flat:1",
                "--step-over",
                "0.5",
                "--step-forward",
                "0.1",
                "--region",
                "-6,-6,6,6",
                "--five-axis",
            ])
            .args(extra);
        cl_run(c, &format!("{extra:?}"))
    };
    let (facet, _) = run(&[]);
    let (smooth, err) = run(&["--normals", "smooth"]);
    assert!(err.contains("locations set down on the part along their axes"), "{err}");
    assert!(err.contains("none of"), "nothing left in the part: {err}");
    assert_eq!(facet.points.len(), smooth.points.len());
    // How far each axis is from the sphere's normal at its tip (the tip
    // is on the tool's contact, lead and tilt 0), and how much the axis
    // turns between neighbours on a pass.
    let stats = |cl: &microcam::formats::cldata::ClData| {
        let mut off = Vec::new();
        let mut turn = Vec::new();
        for i in 0..cl.points.len() {
            let a = (cl.axis[i] - cl.points[i]).normalize();
            let n = cl.points[i].coords.normalize();
            off.push(a.dot(&n).clamp(-1.0, 1.0).acos().to_degrees());
            if i > 0 && (cl.points[i] - cl.points[i - 1]).norm() < 0.3 {
                let b = (cl.axis[i - 1] - cl.points[i - 1]).normalize();
                turn.push(a.dot(&b).clamp(-1.0, 1.0).acos().to_degrees());
            }
        }
        let med = |mut v: Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let big = turn.iter().filter(|&&t| t > 2.0).count();
        (med(off), big, turn.len())
    };
    let (f_off, f_big, n) = stats(&facet);
    let (s_off, s_big, _) = stats(&smooth);
    // Facets 7.5 degrees apart: the facet normals are off by a few
    // degrees and jump at each edge; a step of 0.1 mm on a 10 mm sphere
    // turns its normal by 0.6 degrees.
    assert!(
        f_off > 1.0 && s_off < f_off / 4.0,
        "median off the sphere's normal: facet {f_off}, smooth {s_off}"
    );
    assert!(
        f_big > n / 20 && s_big == 0,
        "turns over 2 degrees: facet {f_big}, smooth {s_big} of {n}"
    );
    // The header says how the axes were made.
    let text = String::from_utf8(
        pathgen()
            .arg("dropcutter")
            .arg(&stl)
            .args([
                "--tool",
                "flat:1",
                "--step-over",
                "2",
                "--five-axis",
                "--normals",
                "smooth",
                "--crease",
                "45",
            ])
            .output()
            .unwrap()
            .stdout,
    )
    .unwrap();
    assert!(text.contains("axes from smoothed normals (crease 45 deg)"), "{text}");
    for bad in [
        vec!["--five-axis", "--crease", "30"],
        vec!["--five-axis", "--normals", "smooth", "--crease", "200"],
        vec!["--five-axis", "--normals", "smooth", "--crease", "nan"],
        vec!["--five-axis", "--normals", "round"],
        vec!["--normals", "smooth"],
    ] {
        let o = pathgen()
            .arg("dropcutter")
            .arg(&stl)
            .args(["--tool", "flat:1", "--step-over", "2"])
            .args(&bad)
            .output()
            .unwrap();
        assert_refused(&o, &format!("{bad:?}"));
    }
}

/// Machined in simulation (`stlverify` reading the G-code): a ball raster
/// over the hemisphere written a G1 per point and with `--arc-fit 0.001`
/// (G18 arcs) cuts the same part; the arcs cut in by at most their
/// tolerance more, plus the tenth of the band within which stlverify
/// chords arcs when it has a design (with its old quarter spacing,
/// 0.00625 mm here, the chords' own sag was what it reported).
#[test]
fn raster_arcs_machine_the_part_within_their_tolerance() {
    let (dir, stl) = hemisphere_stl();
    let (tol, band) = (0.001, 0.01);
    let verify = |extra: &[&str]| -> (Option<i32>, serde_json::Value) {
        let prog = dir.path().join("r.ngc");
        let o = pathgen()
            .args(["dropcutter", stl.to_str().unwrap(), "--tool", "ball:1", "-q"])
            .args([
                "--step-over",
                "0.1",
                "--step-forward",
                "0.02",
                "--region",
                "-3,-3,3,3",
                "--gcode",
                "iso",
            ])
            .args(extra)
            .arg("-o")
            .arg(&prog)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let v = Command::new(env!("CARGO_BIN_EXE_stlverify"))
            .args([
                "--quiet",
                "--stock",
                "-3.5,-3.5,0,3.5,3.5,6",
                "--tool",
                "ball:1",
                "--flute-length",
                "6",
            ])
            .arg("--design")
            .arg(&stl)
            .args(["--region", "-2,2,-2,2", "--step-forward", "0.05", "--step-over", "0.05"])
            .args(["--band", &band.to_string(), "--format", "gcode"])
            .arg(&prog)
            .output()
            .unwrap();
        let r: serde_json::Value = serde_json::from_slice(&v.stdout).unwrap();
        (v.status.code(), r["verification"].clone())
    };
    let f = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap();
    let (code, plain) = verify(&[]);
    assert_eq!(code, Some(0), "{plain}");
    let (code, arcs) = verify(&["--arc-fit", "0.001"]);
    assert_eq!(code, Some(0), "{arcs}");
    eprintln!(
        "hemisphere raster, stlverify: G1 per point max gouge {:.6} mm, rms {:.6}; arcs max gouge {:.6} mm, rms {:.6}",
        f(&plain, "max_gouge_mm"),
        f(&plain, "rms_mm"),
        f(&arcs, "max_gouge_mm"),
        f(&arcs, "rms_mm")
    );
    assert!(
        f(&arcs, "max_gouge_mm") <= f(&plain, "max_gouge_mm") + tol + 0.1 * band + 1e-6,
        "{plain} {arcs}"
    );
    assert!((f(&arcs, "rms_mm") - f(&plain, "rms_mm")).abs() < tol, "{plain} {arcs}");
}
