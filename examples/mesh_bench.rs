//! Timing harness for scripts/bench/rays (not a tool): reads a mesh and a
//! file of rays, builds the BVH and casts the rays, printing one JSON line.
//!
//!   mesh_bench MESH.stl RAYS.f64 [REPEAT [GRID.f64]]
//!
//! RAYS.f64 holds little-endian f64 sextuples (origin x y z, direction
//! x y z). HITS go to RAYS.f64.hits as f64 t per ray (NaN for a miss), so
//! the script can compare them with the anchor's. GRID.f64 (optional) is a
//! second ray file whose rays all share one direction (the verification
//! rays' case): cast through the BVH and through `ParallelRays`, hits to
//! GRID.f64.hits. Read, weld (1e-6 mm) and build are timed separately.

use std::time::Instant;

use microcam::geometry::{P3, V3};
use microcam::mesh::bvh::{Bvh, Ray};
use microcam::mesh::parallel::{Lattice, ParallelRays};
use microcam::mesh::{ReadOptions, read_path};

/// CPU seconds (user + system) this process has used, to the nanosecond
/// (CLOCK_PROCESS_CPUTIME_ID). On a shared machine the wall time includes
/// waiting for a core; CPU time does not.
fn cpu_s() -> f64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: clock_gettime writes one timespec, which `ts` is.
    if unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) } != 0 {
        return 0.0;
    }
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

fn main() {
    // Workers pinned when MICROCAM_PIN_THREADS=1 asks, as in the tools.
    microcam::cli::threads::init_pool();
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        eprintln!("usage: mesh_bench MESH.stl RAYS.f64 [REPEAT]");
        std::process::exit(2);
    }
    let repeat: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(3);
    let c0 = cpu_s();
    let t0 = Instant::now();
    let m = read_path(args[1].as_ref(), &ReadOptions::default()).unwrap_or_else(|e| {
        eprintln!("{}: {e}", args[1]);
        std::process::exit(2)
    });
    let read_s = t0.elapsed().as_secs_f64();
    let read_cpu_s = cpu_s() - c0;
    let (c1, t1) = (cpu_s(), Instant::now());
    let (welded, _) = microcam::mesh::weld::weld(&m.mesh, 1e-6);
    let weld_s = t1.elapsed().as_secs_f64();
    let weld_cpu_s = cpu_s() - c1;
    let (c1, t1) = (cpu_s(), Instant::now());
    let bvh = Bvh::new(&m.mesh);
    let build_s = t1.elapsed().as_secs_f64();
    let build_cpu_s = cpu_s() - c1;
    let read_build_cpu_s = read_cpu_s + build_cpu_s;
    let rays = read_rays(&args[2]);
    // One thread: the per-core figure.
    let mut best1 = f64::INFINITY;
    let mut hits = Vec::new();
    let c1 = cpu_s();
    for _ in 0..repeat {
        let t = Instant::now();
        hits = rays.iter().map(|r| bvh.first_hit(r)).collect::<Vec<_>>();
        best1 = best1.min(t.elapsed().as_secs_f64());
    }
    let rays_cpu_s = (cpu_s() - c1) / repeat as f64;
    // The batch call (rays cast in sorted order) on one thread: the
    // per-core figure of a batch; the answers must be the single ones.
    let pool1 = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("pool");
    let mut batch1 = f64::INFINITY;
    let c1 = cpu_s();
    for _ in 0..repeat {
        let t = Instant::now();
        let h = pool1.install(|| bvh.first_hits(&rays));
        batch1 = batch1.min(t.elapsed().as_secs_f64());
        assert!(h == hits, "batch answers differ from single ones");
    }
    let batch1_cpu_s = (cpu_s() - c1) / repeat as f64;
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
    eprintln!(
        "per ray: {:.1} quads box-tested, {:.1} triangle tests",
        cn as f64 / rays.len() as f64,
        ct as f64 / rays.len() as f64
    );
    let t = Instant::now();
    let n_all: usize = rays.iter().map(|r| bvh.count_hits(r)).sum();
    let all_s = t.elapsed().as_secs_f64();
    let out: Vec<u8> = hits
        .iter()
        .flat_map(|h| h.map_or(f64::NAN, |h| h.t).to_le_bytes())
        .collect();
    std::fs::write(format!("{}.hits", args[2]), out).expect("write hits");
    let n_hit = hits.iter().filter(|h| h.is_some()).count();
    let grid = args
        .get(4)
        .map(|g| grid_bench(&m.mesh, &bvh, g, repeat))
        .unwrap_or_default();
    println!(
        "{{\"weld_s\":{weld_s:.6},\"weld_cpu_s\":{weld_cpu_s:.6},\"welded_vertices\":{},\"read_cpu_s\":{read_cpu_s:.6},\"build_cpu_s\":{build_cpu_s:.6},{grid}\"triangles\":{},\"nodes\":{},\"read_s\":{read_s:.6},\"build_s\":{build_s:.6},\"read_build_cpu_s\":{read_build_cpu_s:.6},\"first_hit_1thread_cpu_s\":{rays_cpu_s:.6},\"batch_1thread_s\":{batch1:.6},\"batch_1thread_cpu_s\":{batch1_cpu_s:.6},\"rays\":{},\"hit\":{n_hit},\"first_hit_1thread_s\":{best1:.6},\"first_hit_par_s\":{best_n:.6},\"threads\":{},\"all_hits\":{n_all},\"all_hits_1thread_s\":{all_s:.6}}}",
        welded.vertices.len(),
        m.mesh.triangles.len(),
        bvh.node_count(),
        rays.len(),
        rayon::current_num_threads()
    );
}

fn read_rays(path: &str) -> Vec<Ray> {
    let raw = std::fs::read(path).expect("rays file");
    let f: Vec<f64> = raw
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect();
    f.chunks_exact(6)
        .map(|c| Ray::new(P3::new(c[0], c[1], c[2]), V3::new(c[3], c[4], c[5])))
        .collect()
}

/// Parallel rays (one direction): through the BVH and through
/// `ParallelRays`, one thread and all; JSON fields (with a trailing comma).
fn grid_bench(mesh: &microcam::mesh::Mesh, bvh: &Bvh, path: &str, repeat: usize) -> String {
    let rays = read_rays(path);
    let Some(dir) = rays.first().map(|r| r.dir) else {
        return String::new();
    };
    assert!(rays.iter().all(|r| r.dir == dir), "grid rays must share one direction");
    let origins: Vec<P3> = rays.iter().map(|r| r.origin).collect();
    let (c0, t0) = (cpu_s(), Instant::now());
    let pr = ParallelRays::new(mesh, dir);
    // The cell grid is built on first use: build it here, in the timing.
    let _ = pr.cells();
    let (pr_build_s, pr_build_cpu_s) = (t0.elapsed().as_secs_f64(), cpu_s() - c0);
    let time = |f: &dyn Fn() -> Vec<Option<microcam::mesh::bvh::Hit>>| {
        let mut best = f64::INFINITY;
        let mut cpu = f64::INFINITY;
        let mut out = Vec::new();
        for _ in 0..repeat {
            let (c, t) = (cpu_s(), Instant::now());
            out = f();
            best = best.min(t.elapsed().as_secs_f64());
            cpu = cpu.min(cpu_s() - c);
        }
        (best, cpu, out)
    };
    let (bvh1, bvh1_cpu, hb) = time(&|| rays.iter().map(|r| bvh.first_hit(r)).collect());
    let (pr1, pr1_cpu, hp) = time(&|| origins.iter().map(|o| pr.first_hit(o)).collect());
    let (prn, _, hpn) = time(&|| pr.first_hits(&origins));
    let (bvhn, _, _) = time(&|| bvh.first_hits(&rays));
    let same = hb.iter().zip(&hp).filter(|(a, b)| a == b).count();
    assert_eq!(hp, hpn);
    let lattice = lattice_bench(&pr, &origins, &hb, repeat);
    let out: Vec<u8> = hp
        .iter()
        .flat_map(|h| h.map_or(f64::NAN, |h| h.t).to_le_bytes())
        .collect();
    std::fs::write(format!("{path}.hits"), out).expect("write hits");
    format!(
        "{lattice}\"grid_rays\":{},\"grid_hit\":{},\"grid_same_as_bvh\":{same},\"grid_bvh_1thread_s\":{bvh1:.6},\"grid_bvh_1thread_cpu_s\":{bvh1_cpu:.6},\"grid_bvh_par_s\":{bvhn:.6},\"grid_pr_build_s\":{pr_build_s:.6},\"grid_pr_build_cpu_s\":{pr_build_cpu_s:.6},\"grid_pr_cells\":{},\"grid_pr_refs\":{},\"grid_pr_1thread_s\":{pr1:.6},\"grid_pr_1thread_cpu_s\":{pr1_cpu:.6},\"grid_pr_par_s\":{prn:.6},",
        rays.len(),
        hp.iter().filter(|h| h.is_some()).count(),
        pr.cells(),
        pr.references()
    )
}

/// The grid rays as a lattice (`first_hits_lattice`) when they are one:
/// origins `(x_i, y_j, z)` row by row. JSON fields (trailing comma), or
/// nothing when the rays are not such a lattice.
fn lattice_bench(
    pr: &ParallelRays,
    origins: &[P3],
    want: &[Option<microcam::mesh::bvh::Hit>],
    repeat: usize,
) -> String {
    let Some(o0) = origins.first() else {
        return String::new();
    };
    let nu = origins.iter().take_while(|o| o.y == o0.y).count();
    if !origins.len().is_multiple_of(nu) {
        return String::new();
    }
    let us: Vec<f64> = origins[..nu].iter().map(|o| o.x).collect();
    let vs: Vec<f64> = origins.iter().step_by(nu).map(|o| o.y).collect();
    let l = Lattice {
        base: P3::new(0.0, 0.0, o0.z),
        eu: V3::x(),
        ev: V3::y(),
        us: &us,
        vs: &vs,
    };
    let is_lattice = origins.iter().enumerate().all(|(k, o)| *o == l.origin(k % nu, k / nu));
    if !is_lattice {
        return String::new();
    }
    let pool1 = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("pool");
    // The first call also sorts the triangles by depth (kept for later calls).
    let (c0, t0) = (cpu_s(), Instant::now());
    let first = pool1.install(|| pr.first_hits_lattice(&l));
    let (first_s, first_cpu_s) = (t0.elapsed().as_secs_f64(), cpu_s() - c0);
    let (mut best1, mut cpu1, mut best_n) = (f64::INFINITY, f64::INFINITY, f64::INFINITY);
    for _ in 0..repeat {
        let (c, t) = (cpu_s(), Instant::now());
        let h = pool1.install(|| pr.first_hits_lattice(&l));
        best1 = best1.min(t.elapsed().as_secs_f64());
        cpu1 = cpu1.min(cpu_s() - c);
        assert!(h == first);
        let t = Instant::now();
        let h = pr.first_hits_lattice(&l);
        best_n = best_n.min(t.elapsed().as_secs_f64());
        assert!(h == first);
    }
    // Depths only (what stlverify asks for): the same t, bit for bit.
    let (mut dbest1, mut dcpu1, mut dbest_n) = (f64::INFINITY, f64::INFINITY, f64::INFINITY);
    for _ in 0..repeat {
        let (c, t) = (cpu_s(), Instant::now());
        let d = pool1.install(|| pr.first_depths_lattice(&l));
        dbest1 = dbest1.min(t.elapsed().as_secs_f64());
        dcpu1 = dcpu1.min(cpu_s() - c);
        let t = Instant::now();
        let dn = pr.first_depths_lattice(&l);
        dbest_n = dbest_n.min(t.elapsed().as_secs_f64());
        assert!(d == dn);
        assert!(
            d.iter()
                .zip(&first)
                .all(|(d, h)| d.to_bits() == h.map_or(f64::INFINITY, |h| h.t).to_bits())
        );
    }
    let same = want.iter().zip(&first).filter(|(a, b)| a == b).count();
    format!(
        "\"lattice_same_as_bvh\":{same},\"lattice_first_s\":{first_s:.6},\"lattice_first_cpu_s\":{first_cpu_s:.6},\"lattice_1thread_s\":{best1:.6},\"lattice_1thread_cpu_s\":{cpu1:.6},\"lattice_par_s\":{best_n:.6},\"depths_1thread_s\":{dbest1:.6},\"depths_1thread_cpu_s\":{dcpu1:.6},\"depths_par_s\":{dbest_n:.6},"
    )
}
