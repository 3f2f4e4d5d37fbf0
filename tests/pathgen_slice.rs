//! End to end: `pathgen slice` and `pathgen mesh-info` on generated meshes
//! and on the corpus.

use microcam::formats::chains::ChainsReader;
use microcam::geometry::P3;
use microcam::mesh::read_stl::{write_ascii, write_binary};
use microcam::mesh::solids;
use microcam::slice::chain_area;
use std::process::{Command, Output};

const PATHGEN: &str = env!("CARGO_BIN_EXE_pathgen");

mod common;

fn run(args: &[&str]) -> Output {
    common::run(PATHGEN, args, None)
}

fn chains(out: &[u8]) -> Vec<microcam::model::chain::Chain> {
    let r = ChainsReader::new(out).expect("chains header");
    r.collect::<Result<Vec<_>, _>>().expect("chains")
}

#[test]
fn slices_a_torus_into_outer_and_hole_at_each_level() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("torus.stl");
    // Welded by the reader's neighbours: write as binary STL (a soup).
    let m = solids::torus(P3::new(0.0, 0.0, 1.0), 3.0, 1.0, 256, 64);
    std::fs::write(&p, write_binary(&m, "solid torus (binary, header says solid)")).unwrap();
    let o = run(&["slice", p.to_str().unwrap(), "--z-step", "0.5", "--from", "bottom"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let c = chains(&o.stdout);
    // Levels 0 (bottom: the tube's lowest ring), 0.5, 1, 1.5: two loops each
    // except at the very bottom where the ring is a single circle of points.
    let zs: Vec<f64> = c.iter().map(|c| c.segments[0].start().z).collect();
    assert!(zs.windows(2).all(|w| w[0] <= w[1]), "{zs:?}");
    for z in [0.5, 1.0, 1.5] {
        let at: Vec<_> = c.iter().filter(|c| c.segments[0].start().z == z).collect();
        assert_eq!(at.len(), 2, "z {z}");
        assert!(at.iter().all(|c| c.closed));
        let area: f64 = at.iter().map(|c| chain_area(c)).sum();
        let h = z - 1.0;
        let exact = 4.0 * std::f64::consts::PI * 3.0 * (1.0f64 - h * h).sqrt();
        assert!((area / exact - 1.0).abs() < 2e-3, "z {z}: {area} vs {exact}");
        assert_eq!(at.iter().filter(|c| c.layer.as_deref() == Some("hole")).count(), 1);
    }
    // The same from stdin, ASCII, and with arcs: closer to the true area.
    let a = dir.path().join("t.txt");
    std::fs::write(&a, write_ascii(&m, "torus")).unwrap();
    let o2 = Command::new("sh")
        .arg("-c")
        .arg(format!(
            "{PATHGEN} slice --levels 1.0 --arc-tol 0.0001 < {}",
            a.display()
        ))
        .output()
        .unwrap();
    assert!(o2.status.success(), "{}", String::from_utf8_lossy(&o2.stderr));
    let c2 = chains(&o2.stdout);
    assert_eq!(c2.len(), 2);
    assert!(c2.iter().any(|c| {
        c.segments
            .iter()
            .any(|s| matches!(s, microcam::model::chain::Segment::Arc { .. }))
    }));
    let poly: f64 = c
        .iter()
        .filter(|c| c.segments[0].start().z == 1.0)
        .map(chain_area)
        .sum();
    let arcs: f64 = c2.iter().map(chain_area).sum();
    let exact = 12.0 * std::f64::consts::PI;
    assert!((arcs / exact - 1.0).abs() < 1e-4, "{arcs} vs {exact}");
    assert!(
        (arcs / exact - 1.0).abs() < (poly / exact - 1.0).abs(),
        "arcs {arcs} no closer than polygon {poly}"
    );
    // Byte-identical output for identical input.
    let o3 = run(&["slice", p.to_str().unwrap(), "--z-step", "0.5", "--from", "bottom"]);
    assert_eq!(o.stdout, o3.stdout);
}

#[test]
fn malformed_input_exits_2_naming_the_place_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad.stl");
    std::fs::write(
        &p,
        "solid x\nfacet normal 0 0 1\n outer loop\n  vertex 0 0 0\n  vertex 1 0 oops\n",
    )
    .unwrap();
    let out = dir.path().join("out.jsonl");
    let o = run(&[
        "slice",
        p.to_str().unwrap(),
        "--levels",
        "0",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("bad.stl:5:") && e.contains("oops"), "{e}");
    assert!(!out.exists());
    let b = dir.path().join("short.stl");
    let mut bytes = write_binary(&solids::cuboid(P3::origin(), P3::new(1.0, 1.0, 1.0)), "x");
    bytes.truncate(300);
    std::fs::write(&b, bytes).unwrap();
    let o = run(&["mesh-info", b.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("byte 284"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(o.stdout.is_empty());
    let o = run(&["slice", b.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn mesh_info_reports_topology_and_repairs() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("box.obj");
    // A box with one face inside out and a duplicate face.
    std::fs::write(
        &p,
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
         f 1 4 3 2\nf 8 7 6 5\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 1 5 8 4\nf 1 5 8 4\nl 1 7\n",
    )
    .unwrap();
    let o = run(&["mesh-info", p.to_str().unwrap(), "--units", "inch"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["topology"]["duplicate_triangles"], 2);
    assert_eq!(j["topology"]["watertight"], false);
    assert_eq!(j["repaired"]["watertight"], true);
    let v = j["repaired"]["volume_mm3"].as_f64().unwrap();
    assert!((v - 25.4f64.powi(3)).abs() < 1e-6, "{v}");
    assert!(j["repairs"][0].as_str().unwrap().contains("removed 2 duplicate"));
    assert!(
        j["repairs"][1].as_str().unwrap().contains("flipped 2 "),
        "{}",
        j["repairs"]
    );
    assert!(j["notes"][0].as_str().unwrap().contains("line elements"));
}

#[test]
fn corpus_meshes_slice_or_are_refused() {
    let files = microcam::corpus::meshes();
    if files.is_empty() {
        microcam::corpus::skip("corpus_meshes_slice_or_are_refused");
        return;
    }
    for f in &files {
        let o = run(&["slice", f.to_str().unwrap(), "--z-step", "0.25"]);
        let code = o.status.code();
        assert!(code == Some(0) || code == Some(2), "{}: {code:?}", f.display());
        if code == Some(0) {
            chains(&o.stdout);
        } else {
            assert!(!o.stderr.is_empty());
        }
        let o = run(&["mesh-info", f.to_str().unwrap()]);
        assert!(o.status.success(), "{}", f.display());
    }
    microcam::corpus::record("corpus_meshes_slice_or_are_refused", files.len());
}

/// A weld tolerance that joins every corner into one point leaves nothing
/// to report: exit 2 naming the flag, nothing on stdout.
#[test]
fn mesh_info_refuses_a_weld_that_joins_everything() {
    let dome = concat!(env!("CARGO_MANIFEST_DIR"), "/testdata/samples/dome.stl");
    let o = run(&["mesh-info", "--weld-tol", "1e9", dome]);
    assert_eq!(o.status.code(), Some(2));
    assert!(o.stdout.is_empty());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--weld-tol"));
}
