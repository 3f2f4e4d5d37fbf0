//! Height-field kernel throughput: flat-tool horizontal cuts over a
//! 2000 x 2000 stock, printed as cell updates per second. Run by
//! scripts/bench/heightfield beside the same algorithm in plain C.
//! Threads: RAYON_NUM_THREADS.

use microcam::geometry::P3;
use microcam::stock::{Cutter, HeightField};
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let moves: usize = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(2000);
    let res = 0.01;
    let mut s = HeightField::new(P3::new(0.0, 0.0, -10.0), P3::new(20.0, 20.0, 0.0), res).unwrap();
    let tool = Cutter::flat(2.0).unwrap();
    // Deterministic zig-zag of long horizontal moves, each a little deeper.
    let mut updates = 0u64;
    let t = Instant::now();
    let mut removed = 0.0;
    for k in 0..moves {
        let y = 2.0 + 16.0 * ((k as f64 * 0.381_966) % 1.0);
        let z = -0.001 * (k as f64 + 1.0);
        let (a, b) = if k % 2 == 0 { (2.0, 18.0) } else { (18.0, 2.0) };
        removed += s.cut(P3::new(a, y, z), P3::new(b, y, z), &tool).unwrap();
        // Cells the capsule covers: rectangle plus the two half discs.
        updates += ((16.0 * 4.0 + std::f64::consts::PI * 4.0) / (res * res)) as u64;
    }
    let secs = t.elapsed().as_secs_f64();
    println!(
        "{{\"moves\":{moves},\"cell_updates\":{updates},\"seconds\":{secs:.4},\"cell_updates_per_s\":{:.0},\"removed_mm3\":{removed:.3}}}",
        updates as f64 / secs
    );
}
