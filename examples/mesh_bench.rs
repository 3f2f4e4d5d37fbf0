//! Timing harness for scripts/bench/rays (not a tool): reads a mesh and a
//! file of rays, builds the BVH and casts the rays, printing one JSON line.
//!
//!   mesh_bench MESH.stl RAYS.f64 [REPEAT]
//!
//! RAYS.f64 holds little-endian f64 sextuples (origin x y z, direction
//! x y z). HITS go to RAYS.f64.hits as f64 t per ray (NaN for a miss), so
//! the script can compare them with the anchor's.

use std::time::Instant;

use microcam::geometry::{P3, V3};
use microcam::mesh::bvh::{Bvh, Ray};
use microcam::mesh::{ReadOptions, read_path};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        eprintln!("usage: mesh_bench MESH.stl RAYS.f64 [REPEAT]");
        std::process::exit(2);
    }
    let repeat: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(3);
    let t0 = Instant::now();
    let m = read_path(args[1].as_ref(), &ReadOptions::default()).unwrap_or_else(|e| {
        eprintln!("{}: {e}", args[1]);
        std::process::exit(2)
    });
    let read_s = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let bvh = Bvh::new(&m.mesh);
    let build_s = t1.elapsed().as_secs_f64();
    let raw = std::fs::read(&args[2]).expect("rays file");
    let f: Vec<f64> = raw.chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().unwrap())).collect();
    let rays: Vec<Ray> = f
        .chunks_exact(6)
        .map(|c| Ray::new(P3::new(c[0], c[1], c[2]), V3::new(c[3], c[4], c[5])))
        .collect();
    // One thread: the per-core figure.
    let mut best1 = f64::INFINITY;
    let mut hits = Vec::new();
    for _ in 0..repeat {
        let t = Instant::now();
        hits = rays.iter().map(|r| bvh.first_hit(r)).collect::<Vec<_>>();
        best1 = best1.min(t.elapsed().as_secs_f64());
    }
    // Every thread rayon has.
    let mut best_n = f64::INFINITY;
    for _ in 0..repeat {
        let t = Instant::now();
        let h = bvh.first_hits(&rays);
        best_n = best_n.min(t.elapsed().as_secs_f64());
        assert_eq!(h.len(), hits.len());
    }
    let (mut cn, mut ct) = (0usize, 0usize);
    for r in &rays {
        let (a, b) = bvh.first_hit_cost(r);
        cn += a;
        ct += b;
    }
    eprintln!("per ray: {:.1} interior nodes, {:.1} triangle tests", cn as f64 / rays.len() as f64, ct as f64 / rays.len() as f64);
    let t = Instant::now();
    let n_all: usize = rays.iter().map(|r| bvh.count_hits(r)).sum();
    let all_s = t.elapsed().as_secs_f64();
    let out: Vec<u8> = hits.iter().flat_map(|h| h.map_or(f64::NAN, |h| h.t).to_le_bytes()).collect();
    std::fs::write(format!("{}.hits", args[2]), out).expect("write hits");
    let n_hit = hits.iter().filter(|h| h.is_some()).count();
    println!(
        "{{\"triangles\":{},\"nodes\":{},\"read_s\":{read_s:.6},\"build_s\":{build_s:.6},\"rays\":{},\"hit\":{n_hit},\"first_hit_1thread_s\":{best1:.6},\"first_hit_par_s\":{best_n:.6},\"threads\":{},\"all_hits\":{n_all},\"all_hits_1thread_s\":{all_s:.6}}}",
        m.mesh.triangles.len(),
        bvh.node_count(),
        rays.len(),
        rayon::current_num_threads()
    );
}
