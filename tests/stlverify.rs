//! stlverify end to end on Singh 2014's own inputs: the CL data of its
//! Annexure 1 (3-axis) and Annexure 2 (5-axis), stock 25 x 50 x 40 mm,
//! flat end mill R 3 mm, L 10 mm. The annexures are read in place from
//! the thesis text beside the shared corpus; without it the test skips.

use std::path::{Path, PathBuf};
use std::process::Command;

fn bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_stlverify"))
}

/// The thesis text, if the shared folder is present.
fn thesis() -> Option<PathBuf> {
    let shared = microcam::corpus::dir()?.parent()?.join("seeds");
    let mut v: Vec<PathBuf> = std::fs::read_dir(shared)
        .ok()?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("001_"))
        })
        .collect();
    v.sort();
    v.into_iter().next()
}

/// The lines of the text between the heading `from` and the line starting
/// with `to`.
fn section(text: &str, from: &str, to: &str) -> String {
    let mut on = false;
    let mut out = String::new();
    for l in text.lines() {
        if l.trim() == from {
            on = true;
            continue;
        }
        if on && l.starts_with(to) {
            break;
        }
        if on {
            out.push_str(l);
            out.push('\n');
        }
    }
    out
}

fn run(args: &[&str]) -> (i32, serde_json::Value) {
    let out = Command::new(bin()).args(args).output().unwrap();
    let code = out.status.code().unwrap_or(-1);
    let v = serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|_| panic!("{args:?}: {}", String::from_utf8_lossy(&out.stderr)));
    (code, v)
}

/// Area of the union of stadiums (segment, radius) inside [0,25] x [0,50],
/// by columns: each stadium covers one y-interval per column.
/// A straight move of the tool centre in XY: start and end.
type Seg = ((f64, f64), (f64, f64));

fn stadium_union_area(segs: &[Seg], r: f64) -> f64 {
    let (x0, x1, n) = (0.0, 25.0, 50_000);
    let dx = (x1 - x0) / n as f64;
    let mut area = 0.0;
    for k in 0..n {
        let x = x0 + (k as f64 + 0.5) * dx;
        let mut ivs: Vec<(f64, f64)> = Vec::new();
        for &(p, q) in segs {
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for i in 0..=2000 {
                let u = i as f64 / 2000.0;
                let (cx, cy) = (p.0 + (q.0 - p.0) * u, p.1 + (q.1 - p.1) * u);
                let h2 = r * r - (x - cx) * (x - cx);
                if h2 >= 0.0 {
                    lo = lo.min(cy - h2.sqrt());
                    hi = hi.max(cy + h2.sqrt());
                }
            }
            if lo <= hi {
                ivs.push((lo.max(0.0), hi.min(50.0)));
            }
        }
        ivs.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (mut len, mut end) = (0.0, f64::NEG_INFINITY);
        for (a, b) in ivs {
            if b <= end {
                continue;
            }
            len += b - a.max(end);
            end = b;
        }
        area += len * dx;
    }
    area
}

const STOCK: &str = "0,0,-40,25,50,0";

#[test]
fn singh_2014_annexures_end_to_end() {
    let Some(path) = thesis() else {
        microcam::corpus::skip("stlverify_annexures");
        return;
    };
    let text = std::fs::read_to_string(&path).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let a1 = d.join("annexure1.txt");
    let a2 = d.join("annexure2.txt");
    std::fs::write(&a1, section(&text, "ANNEXURE 1", "ANNEXURE 2")).unwrap();
    std::fs::write(&a2, section(&text, "ANNEXURE 2", "REFER")).unwrap();
    let p = |n: &str| d.join(n).display().to_string();

    // Annexure 1: 49 locations at z = -9.5 in two passes (x 10 and 11).
    let (code, r) = run(&[
        "--stock",
        STOCK,
        "--tool",
        "flat:6",
        "--flute-length",
        "10",
        "--spacing",
        "0.1",
        "--stl",
        &p("a1.stl"),
        &a1.display().to_string(),
    ]);
    assert_eq!(code, 0);
    assert_eq!(r["locations"], 49);
    assert_eq!(r["five_axis"], false);
    // Independent figure: the union of the three stadiums the tool centre
    // sweeps (two passes and the link between them) times the depth.
    let want = 9.5
        * stadium_union_area(
            &[
                ((10.0, 0.5), (10.0, 12.5)),
                ((10.0, 12.5), (11.0, 0.5)),
                ((11.0, 0.5), (11.0, 12.0)),
            ],
            3.0,
        );
    let got = r["removed_volume_mm3"].as_f64().unwrap();
    assert!((got - want).abs() < 0.005 * want, "removed {got} mm³, want {want}");
    let stl = &r["stl"];
    assert!(stl["triangles"].as_u64().unwrap() * 20 <= stl["per_cell_triangles"].as_u64().unwrap());
    let bytes = std::fs::read(d.join("a1.stl")).unwrap();
    assert_eq!(bytes.len() as u64, 84 + 50 * stl["triangles"].as_u64().unwrap());

    // The machined part verifies against its own STL with the thesis' ray
    // grid (0.1 x 0.25 mm, ±0.1 mm) over the slot floor (at the walls a
    // height-field STL slants a vertical wall across one cell, so vertical
    // rays there compare the slant); pictures and profiles too.
    let (code, r) = run(&[
        "--stock",
        STOCK,
        "--tool",
        "flat:6",
        "--flute-length",
        "10",
        "--spacing",
        "0.1",
        "--design",
        &p("a1.stl"),
        "--region",
        "7.5,13.5,2,10",
        "--png",
        &p("a1.png"),
        "--svg",
        &p("a1.svg"),
        "--profile-y",
        "10",
        "--profiles",
        &p("a1.csv"),
        "--profiles-svg",
        &p("a1p.svg"),
        &a1.display().to_string(),
    ]);
    assert_eq!(code, 0, "{r}");
    let v = &r["verification"];
    assert_eq!(v["gouge"], 0);
    assert_eq!(v["excess"], 0);
    assert_eq!(v["points"], 61 * 33);
    assert_eq!(v["not_compared"], 0);
    for f in ["a1.png", "a1.svg", "a1.csv", "a1p.svg"] {
        assert!(std::fs::metadata(d.join(f)).unwrap().len() > 100, "{f}");
    }

    // Annexure 2: 48 five-axis locations, the axis tilting up to ~50°.
    let (code, r) = run(&[
        "--stock",
        STOCK,
        "--tool",
        "flat:6",
        "--flute-length",
        "10",
        "--spacing",
        "0.1",
        "--stl",
        &p("a2.stl"),
        &a2.display().to_string(),
    ]);
    assert_eq!(code, 0);
    assert_eq!(r["locations"], 48);
    assert_eq!(r["five_axis"], true);
    let fam = &r["removed_volume_by_family_mm3"];
    let (x, y, z) = (
        fam["x"].as_f64().unwrap(),
        fam["y"].as_f64().unwrap(),
        fam["z"].as_f64().unwrap(),
    );
    assert!(z > 500.0, "{z}");
    for v in [x, y] {
        assert!((v - z).abs() < 0.01 * z, "families disagree: {x} {y} {z}");
    }
    assert!(r["sub_moves"].as_u64().unwrap() > 48);
    assert!(r["sweep_shape_error_mm"].as_f64().unwrap() <= 0.05 + 1e-12);
    // A design that is the uncut stock top: everything cut is a gouge, so
    // the job fails with exit 1.
    let box_stl = d.join("box.stl");
    write_box(&box_stl, [0.0, 0.0, -40.0], [25.0, 50.0, 0.0]);
    let (code, r) = run(&[
        "--stock",
        STOCK,
        "--tool",
        "flat:6",
        "--flute-length",
        "10",
        "--spacing",
        "0.1",
        "--design",
        &box_stl.display().to_string(),
        "--region",
        "0,4,10,30",
        &a2.display().to_string(),
    ]);
    assert_eq!(code, 1);
    let v = &r["verification"];
    assert_eq!(v["points"], 41 * 81);
    assert!(v["gouge"].as_u64().unwrap() > 100);
    assert_eq!(v["excess"], 0);
    microcam::corpus::record("stlverify_annexures", 2);
}

/// A closed box as ASCII STL (12 triangles, outward normals).
fn write_box(path: &Path, lo: [f64; 3], hi: [f64; 3]) {
    let c = |i: usize| {
        [
            if i & 1 == 0 { lo[0] } else { hi[0] },
            if i & 2 == 0 { lo[1] } else { hi[1] },
            if i & 4 == 0 { lo[2] } else { hi[2] },
        ]
    };
    let faces = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let mut s = String::from("solid box\n");
    for f in faces {
        for t in [[f[0], f[1], f[2]], [f[0], f[2], f[3]]] {
            s.push_str("facet normal 0 0 0\nouter loop\n");
            for i in t {
                let v = c(i);
                s.push_str(&format!("vertex {} {} {}\n", v[0], v[1], v[2]));
            }
            s.push_str("endloop\nendfacet\n");
        }
    }
    s.push_str("endsolid box\n");
    std::fs::write(path, s).unwrap();
}

#[test]
fn bad_input_exits_2_and_names_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("bad.cl");
    std::fs::write(&f, "1 2 3\n4 5 6\n7 8\n").unwrap();
    let out = Command::new(bin())
        .args(["--stock", "0,0,-1,10,10,0", "--tool", "flat:2"])
        .arg(&f)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("bad.cl:3"), "{e}");
    assert!(out.stdout.is_empty());
    let out = Command::new(bin())
        .args(["--stock", "0,0,-1,10,10,0", "--tool", "flat:2", "--svg", "x.svg"])
        .arg(&f)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
}

/// A closed solid over [0, x1] × [0, y1] from z = `bottom` up to a plane
/// top rising from `z0` at x = 0 to `z1` at x = x1 (ASCII STL, the faces
/// of [`write_box`]).
fn write_ramp(path: &Path, x1: f64, y1: f64, bottom: f64, z0: f64, z1: f64) {
    write_box(path, [0.0, 0.0, bottom], [x1, y1, 1.0]);
    let text = std::fs::read_to_string(path).unwrap();
    // write_box puts z = 1 on the top corners: bend them onto the ramp.
    let mut s = String::new();
    for l in text.lines() {
        match l.strip_prefix("vertex ") {
            Some(v) => {
                let w: Vec<f64> = v.split(' ').map(|x| x.parse().unwrap()).collect();
                let z = if w[2] == 1.0 { z0 + (z1 - z0) * w[0] / x1 } else { w[2] };
                s.push_str(&format!("vertex {} {} {}\n", w[0], w[1], z));
            }
            None => {
                s.push_str(l);
                s.push('\n');
            }
        }
    }
    std::fs::write(path, s).unwrap();
}

/// Scallop height left between ball passes `s` apart (horizontally) on a
/// plane of slope `tan_a` across the passes, measured vertically: the
/// cusp stands `R - √(R² - (w/2)²)` off the plane along its normal, with
/// `w = s / cos a` the passes' distance along the plane.
fn scallop(r: f64, s: f64, tan_a: f64) -> f64 {
    let cos = 1.0 / tan_a.hypot(1.0);
    let w = s / cos;
    (r - (r * r - 0.25 * w * w).sqrt()) / cos
}

#[test]
fn drop_cutter_data_of_a_part_verify_without_gouges_and_with_analytic_scallops() {
    let pathgen = PathBuf::from(env!("CARGO_BIN_EXE_pathgen"));
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Two design parts, 10 x 10 mm, machined from a stock 3 mm high: a
    // level top at z = -0.5 and a top sloping from -0.5 to -2.5 across
    // the passes (slope 0.2). Ball R 1 mm, passes along Y 0.5 mm apart.
    for (name, z1, tan_a) in [("level", -0.5, 0.0), ("ramp", -2.5, 0.2)] {
        let design = d.join(format!("{name}.stl"));
        write_ramp(&design, 10.0, 10.0, -3.0, -0.5, z1);
        let cl = d.join(format!("{name}.cl"));
        let out = Command::new(&pathgen)
            .args([
                "dropcutter",
                "--tool",
                "ball:2",
                "--step-over",
                "0.5",
                "--step-forward",
                "0.1",
            ])
            .args(["--direction", "y", "-o"])
            .arg(&cl)
            .arg(&design)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let (code, r) = run(&[
            "--stock",
            "0,0,-3,10,10,0",
            "--tool",
            "ball:2",
            "--spacing",
            "0.05",
            "--design",
            &design.display().to_string(),
            "--region",
            "0.5,9.5,0.5,9.5",
            "--step-forward",
            "0.01",
            "--step-over",
            "0.25",
            "--profile-y",
            "5",
            &cl.display().to_string(),
        ]);
        let v = &r["verification"];
        assert_eq!(code, 0, "{name}: {v}");
        assert_eq!(v["gouge"], 0, "{name}");
        assert_eq!(v["not_compared"], 0, "{name}");
        // Drop-cutter locations touch the design: nothing below it beyond
        // rounding.
        assert!(v["max_gouge_mm"].as_f64().unwrap() < 1e-4, "{name}: {v}");
        let want = scallop(1.0, 0.5, tan_a);
        let got = v["profiles"][0]["max_excess_mm"].as_f64().unwrap();
        assert!(
            (got - want).abs() <= 0.1 * want,
            "{name}: scallop {got} mm, analytic {want} mm"
        );
        assert!(
            (v["max_excess_mm"].as_f64().unwrap() - want).abs() <= 0.1 * want,
            "{name}: {v}"
        );
        eprintln!("{name}: scallop {got:.5} mm, analytic {want:.5} mm");
    }
}

/// CAM programs from the corpus (Fusion 360 adaptive clearing with
/// helical ramps, a Fusion contour, CamBam, jscut), read as stlverify reads
/// a program, cut by a flat end mill and a torus: the material left is the
/// same whether each family's pieces are prepared all at once, in a few
/// batches or one move a batch, and the tool's tip has cleared the
/// material above it at every location inside the stock.
#[test]
fn corpus_programs_cut_in_batches_leave_what_one_pass_leaves() {
    use microcam::cutter::Cutter;
    use microcam::dexel::TriDexel;
    use microcam::dexel::tool::ToolShape;
    use microcam::geometry::P3;
    use microcam::verify::{self, VerifyJob};
    const NAME: &str = "stlverify_corpus_programs_in_batches";
    let names = [
        "SergeyPopovGit_CNC__HeatSink_mill.tap",
        "shooshx_led_floor__1108_wall_better_m4_m6_holes.nc",
        "winder_Universal-G-Code-Sender__Gates_combined_R12.nc",
        "cncjs_cncjs__jsdc.gcode",
    ];
    let files: Vec<PathBuf> = names
        .iter()
        .filter_map(|n| microcam::corpus::file(&format!("gcode-cam/{n}")))
        .filter(|p| p.exists())
        .collect();
    if files.len() < names.len() {
        microcam::corpus::skip(NAME);
        return;
    }
    let mut cases = 0;
    for path in &files {
        let input = microcam::cli::open_input(Some(path)).unwrap();
        let src = microcam::source::ToolpathSource::open(input, &verify::cl::program_options()).unwrap();
        let locations = verify::cl::program_locations(src, 0.01).unwrap();
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for l in &locations {
            for k in 0..3 {
                lo[k] = lo[k].min(l.tip[k]);
                hi[k] = hi[k].max(l.tip[k]);
            }
        }
        assert!(lo[2] < -0.1, "{}: the program never goes below z = 0", path.display());
        for cutter in [
            Cutter::Flat { radius: 1.5 },
            Cutter::Torus {
                radius: 1.5,
                corner: 0.4,
            },
        ] {
            let tool = ToolShape { cutter, length: 10.0 };
            // The stock: the program's box grown by the tool, top at z = 0.
            let (smin, smax) = (
                P3::new(lo[0] - 2.0, lo[1] - 2.0, lo[2] - 1.0),
                P3::new(hi[0] + 2.0, hi[1] + 2.0, 0.0),
            );
            // Fine enough across the depth for the X and Y rays (at cell
            // centres in Z) to see the same volume as the Z rays.
            let spacing = (((hi[0] - lo[0]).max(hi[1] - lo[1]) + 4.0) / 250.0).min(-lo[2] / 10.0);
            let job = VerifyJob {
                stock_min: smin,
                stock_max: smax,
                tool,
                spacing,
                sweep_tol: spacing / 2.0,
                ring_tol: None,
                locations: locations.clone(),
            };
            // One pass: the whole job's pieces are well under the 256 MiB
            // that `simulate` prepares at a time.
            let sim = verify::simulate(&job).unwrap();
            let sweeps = verify::sweeps(&job);
            let one_pass = (sim.stats, sim.dexels.volumes(), sim.dexels.heights());
            let cut = |budget: usize| {
                let mut d = TriDexel::new(smin, smax, spacing).unwrap();
                let st = d.cut_in_batches(&sweeps, budget);
                (st, d.volumes(), d.heights())
            };
            let tag = format!("{} {:?}", path.display(), cutter);
            // Pieces of some 300 moves a batch, then (the flat cutter's, the
            // cheaper) of some 10. One move a batch is the unit test's, on
            // generated moves: here it would take seconds.
            let few = sweeps.iter().take(300).map(|s| s.fine.len()).sum::<usize>() * 600;
            assert!(few < 1 << 28);
            let budgets = match cutter {
                Cutter::Flat { .. } => vec![few, few / 30],
                _ => vec![few],
            };
            for budget in budgets {
                let batched = cut(budget);
                assert_eq!(batched.0, one_pass.0, "{tag}: budget {budget}");
                assert_eq!(batched.1, one_pass.1, "{tag}: budget {budget}");
                assert!(batched.2 == one_pass.2, "{tag}: budget {budget}: the tops differ");
            }
            let stock = (smax.x - smin.x) * (smax.y - smin.y) * (smax.z - smin.z);
            let removed = one_pass.1.map(|v| stock - v);
            assert!(removed[2] > 1.0, "{tag}: removed {removed:?}");
            // The three families see the same part, to their resolution.
            for k in 0..2 {
                assert!(
                    (removed[k] - removed[2]).abs() <= 0.05 * removed[2],
                    "{tag}: removed by family {removed:?}"
                );
            }
            // Wherever the tip went inside the stock, nothing is left above it.
            let mut checked = 0;
            for l in locations.iter().step_by(13) {
                if l.tip.z < smax.z - 1e-6 && l.tip.z > smin.z {
                    let top = sim.top_at(l.tip.x, l.tip.y).unwrap();
                    assert!(
                        top <= l.tip.z + 1e-9,
                        "{tag}: material at {top} above the tip at {:?}",
                        l.tip
                    );
                    checked += 1;
                }
            }
            assert!(checked > 10, "{tag}: {checked} locations inside the stock");
            cases += 1;
        }
    }
    microcam::corpus::record(NAME, cases);
}
