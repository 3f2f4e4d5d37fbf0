//! `microcam-bench-crates MESH.stl RAYS.f64 [GRID.f64]`: build each
//! crate's BVH over the binary STL's triangles and cast the rays (one
//! thread), printing one JSON object with build CPU seconds, rays per CPU-second
//! and how many first hits agree with microcam's (read from RAYS.f64.hits,
//! written by examples/mesh_bench.rs: hit/miss, t within 1e-4 mm). Ray
//! files: little-endian f64 sextuples (origin, direction).

struct Ray {
    origin: [f64; 3],
    dir: [f64; 3],
}

fn f64s(path: &str) -> Vec<f64> {
    let raw = std::fs::read(path).expect("f64 file");
    raw.chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect()
}

fn read_rays(path: &str) -> Vec<Ray> {
    f64s(path)
        .chunks_exact(6)
        .map(|c| Ray {
            origin: [c[0], c[1], c[2]],
            dir: [c[3], c[4], c[5]],
        })
        .collect()
}

/// A binary STL's triangles (the benchmark writes plain ones).
fn read_stl(path: &str) -> Vec<[[f32; 3]; 3]> {
    let b = std::fs::read(path).expect("stl");
    let n = u32::from_le_bytes(b[80..84].try_into().unwrap()) as usize;
    (0..n)
        .map(|i| {
            let r = &b[84 + 50 * i..84 + 50 * i + 50];
            let f = |o: usize| f32::from_le_bytes(r[o..o + 4].try_into().unwrap());
            [0, 1, 2].map(|k| [f(12 + 12 * k), f(16 + 12 * k), f(20 + 12 * k)])
        })
        .collect()
}

/// CPU seconds (user + system) of this process, from /proc (Linux): on a
/// shared machine the wall time includes waiting for a core.
fn cpu_s() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    let rest = stat.rsplit(')').next().unwrap_or("");
    let f: Vec<&str> = rest.split_whitespace().collect();
    let tick = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    (tick(11) + tick(12)) / 100.0
}

/// CPU seconds of the cheapest of three runs (the loops are single
/// threaded), and its answers.
fn time<T>(f: impl Fn() -> Vec<T>) -> (f64, Vec<T>) {
    let mut best = f64::INFINITY;
    let mut out = Vec::new();
    for _ in 0..3 {
        let c = cpu_s();
        out = f();
        best = best.min((cpu_s() - c).max(0.01));
    }
    (best, out)
}

fn agree(a: &[Option<f64>], b: &[Option<f64>]) -> usize {
    a.iter()
        .zip(b)
        .filter(|(x, y)| match (x, y) {
            (Some(x), Some(y)) => (x - y).abs() < 1e-4,
            (None, None) => true,
            _ => false,
        })
        .count()
}

// --- bvh (svenstaro/bvh): SAH BVH over shapes, f32, Möller-Trumbore.
struct Tri {
    p: [nalgebra::Point3<f32>; 3],
    node: usize,
}
impl bvh::aabb::Bounded<f32, 3> for Tri {
    fn aabb(&self) -> bvh::aabb::Aabb<f32, 3> {
        bvh::aabb::Aabb::empty()
            .grow(&self.p[0])
            .grow(&self.p[1])
            .grow(&self.p[2])
    }
}
impl bvh::bounding_hierarchy::BHShape<f32, 3> for Tri {
    fn set_bh_node_index(&mut self, i: usize) {
        self.node = i;
    }
    fn bh_node_index(&self) -> usize {
        self.node
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let tris = read_stl(&args[1]);
    let mut sets = vec![("random", read_rays(&args[2]))];
    let mut want = vec![f64s(&format!("{}.hits", args[2]))];
    if let Some(g) = args.get(3) {
        sets.push(("grid", read_rays(g)));
        want.push(f64s(&format!("{g}.hits")));
    }
    let want: Vec<Vec<Option<f64>>> = want
        .into_iter()
        .map(|w| w.into_iter().map(|t| (!t.is_nan()).then_some(t)).collect())
        .collect();
    let mut out = Vec::new();

    // bvh
    let t = cpu_s();
    let mut shapes: Vec<Tri> = tris
        .iter()
        .map(|t| Tri {
            p: t.map(|p| nalgebra::Point3::new(p[0], p[1], p[2])),
            node: 0,
        })
        .collect();
    let b = bvh::bvh::Bvh::build(&mut shapes);
    out.push(format!("\"bvh_build_cpu_s\":{:.3}", cpu_s() - t));
    for ((name, rays), want) in sets.iter().zip(&want) {
        let rs: Vec<bvh::ray::Ray<f32, 3>> = rays
            .iter()
            .map(|r| {
                bvh::ray::Ray::new(
                    nalgebra::Point3::new(r.origin[0] as f32, r.origin[1] as f32, r.origin[2] as f32),
                    nalgebra::Vector3::new(r.dir[0] as f32, r.dir[1] as f32, r.dir[2] as f32),
                )
            })
            .collect();
        let (s, h) = time(|| {
            rs.iter()
                .map(|r| {
                    let mut best = f32::INFINITY;
                    for sh in b.traverse_iterator(r, &shapes) {
                        let i = r.intersects_triangle(&sh.p[0], &sh.p[1], &sh.p[2]);
                        if i.distance >= 0.0 && i.distance < best {
                            best = i.distance;
                        }
                    }
                    best.is_finite().then_some(best as f64)
                })
                .collect()
        });
        out.push(format!("\"bvh_{name}_rays_per_cpu_s\":{:.0}", rays.len() as f64 / s));
        out.push(format!("\"bvh_{name}_agree\":{}", agree(&h, want)));
    }

    // obvhs: CWBVH (8-wide, compressed), PLOC build, f32.
    let t = cpu_s();
    let otris: Vec<obvhs::triangle::Triangle> = tris
        .iter()
        .map(|t| obvhs::triangle::Triangle {
            v0: glam::Vec3A::from_array(t[0]),
            v1: glam::Vec3A::from_array(t[1]),
            v2: glam::Vec3A::from_array(t[2]),
        })
        .collect();
    let cw = obvhs::cwbvh::builder::build_cwbvh_from_tris(
        &otris,
        obvhs::BvhBuildParams::medium_build(),
        &mut std::time::Duration::default(),
    );
    out.push(format!("\"obvhs_build_cpu_s\":{:.3}", cpu_s() - t));
    for ((name, rays), want) in sets.iter().zip(&want) {
        let rs: Vec<obvhs::ray::Ray> = rays
            .iter()
            .map(|r| {
                obvhs::ray::Ray::new_inf(
                    glam::vec3a(r.origin[0] as f32, r.origin[1] as f32, r.origin[2] as f32),
                    glam::vec3a(r.dir[0] as f32, r.dir[1] as f32, r.dir[2] as f32),
                )
            })
            .collect();
        let (s, h) = time(|| {
            rs.iter()
                .map(|r| {
                    let mut hit = obvhs::ray::RayHit::none();
                    cw.ray_traverse(*r, &mut hit, |ray, id| {
                        otris[cw.primitive_indices[id] as usize].intersect(ray)
                    })
                    .then_some(hit.t as f64)
                })
                .collect()
        });
        out.push(format!("\"obvhs_{name}_rays_per_cpu_s\":{:.0}", rays.len() as f64 / s));
        out.push(format!("\"obvhs_{name}_agree\":{}", agree(&h, want)));
    }

    // parry3d: TriMesh (its own BVH), f32.
    use parry3d::query::RayCast;
    let t = cpu_s();
    let verts: Vec<parry3d::math::Point<f32>> = tris
        .iter()
        .flatten()
        .map(|p| parry3d::math::Point::new(p[0], p[1], p[2]))
        .collect();
    let idx: Vec<[u32; 3]> = (0..tris.len() as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
    let pm = parry3d::shape::TriMesh::new(verts, idx).expect("parry trimesh");
    out.push(format!("\"parry3d_build_cpu_s\":{:.3}", cpu_s() - t));
    for ((name, rays), want) in sets.iter().zip(&want) {
        let rs: Vec<parry3d::query::Ray> = rays
            .iter()
            .map(|r| {
                parry3d::query::Ray::new(
                    parry3d::math::Point::new(r.origin[0] as f32, r.origin[1] as f32, r.origin[2] as f32),
                    parry3d::math::Vector::new(r.dir[0] as f32, r.dir[1] as f32, r.dir[2] as f32),
                )
            })
            .collect();
        let (s, h) = time(|| {
            rs.iter()
                .map(|r| pm.cast_local_ray(r, f32::MAX, true).map(|t| t as f64))
                .collect()
        });
        out.push(format!(
            "\"parry3d_{name}_rays_per_cpu_s\":{:.0}",
            rays.len() as f64 / s
        ));
        out.push(format!("\"parry3d_{name}_agree\":{}", agree(&h, want)));
    }
    let n: Vec<String> = sets.iter().map(|(n, r)| format!("\"{n}_rays\":{}", r.len())).collect();
    println!("{{\"triangles\":{},{},{}}}", tris.len(), n.join(","), out.join(","));
}
