//! Fit one point file with the thesis' curvature-matching method
//! (`laser::arcfit_seed`) and with our biarcs (`laser::arcfit`, the same
//! call `pathgen arcfit` makes; or, with `--fit`, take `pathgen arcfit`'s
//! own output) and print one JSON object: block counts,
//! deviation from the points (and with `--polyline-dev`, both ways from
//! their polyline by dense sampling), tangent breaks and run time for each.
//!
//! Usage: cargo run --release --example arcfit_compare -- [--tolerance MM]
//!        [--elements] [--raw] [--polyline-dev] [--fit CHAINS] [FILE|-]
//!
//! `--elements` adds the thesis' pieces (`[x0,y0,x1,y1]` lines,
//! `[x0,y0,x1,y1,cx,cy,ccw]` arcs) so a caller can measure them against a
//! true curve; `--raw` adds the thesis method without tolerance enforcement.
//! Points: one `x y` or `x,y` per line, `#` comments (as `pathgen arcfit`).

use microcam::formats::chains::ChainsReader;
use microcam::geometry::P2;
use microcam::geometry::line::point_segment_distance;
use microcam::laser::arcfit;
use microcam::laser::arcfit::{Grid, elem_box};
use microcam::laser::arcfit_seed::{SeedParams, fit_curvature_matching_with};
use microcam::model::chain::Segment;
use serde_json::{Value, json};
use std::io::Read;
use std::time::Instant;

/// The pieces of every chain in a microcam.chains/1 file.
fn read_fit(path: &str) -> Result<Vec<Segment>, String> {
    let f = std::fs::File::open(path).map_err(|e| format!("{path}: {e}"))?;
    let r = ChainsReader::new(std::io::BufReader::new(f)).map_err(|e| format!("{path}: {e}"))?;
    let mut out = Vec::new();
    for c in r {
        for s in c.map_err(|e| format!("{path}: {e}"))?.segments {
            out.push(s.checked().ok_or_else(|| format!("{path}: degenerate arc"))?);
        }
    }
    Ok(out)
}

struct Measure {
    point_dev: f64,
    polyline_dev: f64,
    breaks: usize,
    max_turn_deg: f64,
}

fn measure(fit: &[Segment], pts: &[P2], polyline: bool) -> Measure {
    // Points to the fit.
    let fg = Grid::new(&fit.iter().map(elem_box).collect::<Vec<_>>());
    let point_dev = pts
        .iter()
        .map(|p| fg.nearest(p, |i| arcfit::dist_to_elem(p, &fit[i])))
        .fold(0.0, f64::max);
    // The fit, densely sampled (64 per piece, at least 4 when there are
    // very many pieces), to the polyline.
    let boxes: Vec<(P2, P2)> = pts
        .windows(2)
        .map(|w| {
            (
                P2::new(w[0].x.min(w[1].x), w[0].y.min(w[1].y)),
                P2::new(w[0].x.max(w[1].x), w[0].y.max(w[1].y)),
            )
        })
        .collect();
    let pg = Grid::new(&boxes);
    let per = (4_000_000 / fit.len().max(1)).clamp(4, 64);
    let mut polyline_dev = point_dev;
    for e in fit.iter().filter(|_| polyline) {
        for k in 0..=per {
            let q = e.point_at_length(e.length() * k as f64 / per as f64).xy();
            let d = pg.nearest(&q, |i| point_segment_distance(&q, &pts[i], &pts[i + 1]));
            polyline_dev = polyline_dev.max(d);
        }
    }
    let mut breaks = 0;
    let mut max_turn: f64 = 0.0;
    for w in fit.windows(2) {
        let c = w[0].end_tangent().dot(&w[1].start_tangent()).clamp(-1.0, 1.0);
        let deg = c.acos().to_degrees();
        max_turn = max_turn.max(deg);
        if deg > 0.5 {
            breaks += 1;
        }
    }
    Measure {
        point_dev,
        polyline_dev,
        breaks,
        max_turn_deg: max_turn,
    }
}

fn elements(fit: &[Segment]) -> Value {
    Value::Array(
        fit.iter()
            .map(|e| match e {
                Segment::Line(l) => json!([l.start.x, l.start.y, l.end.x, l.end.y]),
                Segment::Arc(a) => json!([
                    a.start.x,
                    a.start.y,
                    a.end.x,
                    a.end.y,
                    a.center.x,
                    a.center.y,
                    u8::from(a.ccw)
                ]),
            })
            .collect(),
    )
}

fn summary(fit: &[Segment], pts: &[P2], polyline: bool, secs: f64) -> serde_json::Map<String, Value> {
    let m = measure(fit, pts, polyline);
    let arcs = fit.iter().filter(|e| matches!(e, Segment::Arc(_))).count();
    let mut o = serde_json::Map::new();
    o.insert("blocks".into(), json!(fit.len()));
    o.insert("arcs".into(), json!(arcs));
    o.insert("lines".into(), json!(fit.len() - arcs));
    o.insert("max_point_deviation_mm".into(), json!(m.point_dev));
    if polyline {
        o.insert("max_polyline_deviation_mm".into(), json!(m.polyline_dev));
    }
    o.insert("tangent_breaks".into(), json!(m.breaks));
    o.insert("max_turn_deg".into(), json!(m.max_turn_deg));
    o.insert("time_s".into(), json!(secs));
    o
}

fn main() {
    let mut tol = 1e-3;
    let (mut want_elements, mut raw, mut poly, mut file) = (false, false, false, None::<String>);
    let mut fit_file = None::<String>;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--tolerance" => {
                tol = args
                    .next()
                    .and_then(|v| v.parse().ok())
                    .filter(|v: &f64| v.is_finite() && *v > 0.0)
                    .unwrap_or_else(|| fail("--tolerance needs a positive number"));
            }
            "--elements" => want_elements = true,
            "--raw" => raw = true,
            "--polyline-dev" => poly = true,
            "--fit" => fit_file = Some(args.next().unwrap_or_else(|| fail("--fit needs a file"))),
            "-h" | "--help" => {
                println!(
                    "usage: arcfit_compare [--tolerance MM] [--elements] [--raw] [--polyline-dev] [--fit CHAINS] [FILE|-]"
                );
                return;
            }
            _ if file.is_none() => file = Some(a),
            _ => fail(&format!("unexpected argument '{a}'")),
        }
    }
    let mut text = String::new();
    match file.as_deref() {
        None | Some("-") => std::io::stdin().read_to_string(&mut text).map(|_| ()),
        Some(f) => std::fs::read_to_string(f).map(|t| text = t),
    }
    .unwrap_or_else(|e| fail(&format!("reading input: {e}")));
    let pts = arcfit::parse_points(&text).unwrap_or_else(|(line, msg)| fail(&format!("line {line}: {msg}")));
    if pts.len() < 2 {
        fail("need at least two points");
    }

    let t0 = Instant::now();
    let (seed, stats) = fit_curvature_matching_with(&pts, tol, 0.0, &SeedParams::default());
    let seed_secs = t0.elapsed().as_secs_f64();
    let mut s = summary(&seed, &pts, poly, seed_secs);
    s.insert("runs".into(), json!(stats.runs));
    s.insert("splits".into(), json!(stats.splits));
    s.insert("unmet".into(), json!(stats.unmet));
    s.insert("steps".into(), json!(stats.steps));
    if want_elements {
        s.insert("elements".into(), elements(&seed));
    }

    let t0 = Instant::now();
    let ours = match fit_file.as_deref() {
        Some(f) => read_fit(f).unwrap_or_else(|e| fail(&e)),
        None => arcfit::fit_points(&pts, tol, 0.0, false),
    };
    let ours_secs = t0.elapsed().as_secs_f64();
    let mut o = summary(&ours, &pts, poly, ours_secs);
    o.insert("source".into(), json!(fit_file.as_deref().unwrap_or("library")));

    let mut out = json!({
        "schema": "microcam.arcfit-compare/1",
        "points": pts.len(),
        "polyline_blocks": pts.len() - 1,
        "tolerance_mm": tol,
        "seed": s,
        "biarc": o,
    });
    if raw {
        let p = SeedParams {
            enforce_tolerance: false,
            ..SeedParams::default()
        };
        let t0 = Instant::now();
        let (r, st) = fit_curvature_matching_with(&pts, tol, 0.0, &p);
        let mut rs = summary(&r, &pts, poly, t0.elapsed().as_secs_f64());
        rs.insert("runs".into(), json!(st.runs));
        if want_elements {
            rs.insert("elements".into(), elements(&r));
        }
        out["seed_raw"] = Value::Object(rs);
    }
    println!("{out}");
}

fn fail(msg: &str) -> ! {
    eprintln!("arcfit_compare: {msg}");
    std::process::exit(2);
}
