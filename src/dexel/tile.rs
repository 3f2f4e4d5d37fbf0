//! A square block of parallel dexels (rays holding material intervals).
//!
//! Most dexels of a milled part hold one interval, so each is stored in 8
//! bytes: `[lo, hi]` as two `f32`s. An empty dexel is `[+inf, -inf]`; a
//! dexel cut into several intervals (undercuts, tilted tools) keeps them
//! in a side list and stores `[NaN, index]`.

/// Rays along each side of a tile.
pub const TILE: usize = 32;

const EMPTY: [f32; 2] = [f32::INFINITY, f32::NEG_INFINITY];

/// `TILE × TILE` parallel dexels, dexel `k = j·TILE + i` for ray (i, j)
/// of the tile; positions along the rays in mm, as `f32` (the module
/// documentation gives the layout).
#[derive(Debug, Clone)]
pub struct Tile {
    rays: Vec<[f32; 2]>,
    multi: Vec<Vec<[f32; 2]>>,
}

impl Tile {
    /// Every dexel full from `lo` to `hi`.
    pub fn full(lo: f32, hi: f32) -> Tile {
        Tile {
            rays: vec![[lo, hi]; TILE * TILE],
            multi: Vec::new(),
        }
    }

    /// The intervals of dexel `k`, in order.
    pub fn intervals(&self, k: usize) -> &[[f32; 2]] {
        let r = &self.rays[k];
        if r[0].is_nan() {
            &self.multi[r[1].to_bits() as usize]
        } else if r[0] <= r[1] {
            std::slice::from_ref(r)
        } else {
            &[]
        }
    }

    /// Whether dexel `k` holds material strictly inside (t0, t1).
    pub fn has_material(&self, k: usize, t0: f64, t1: f64) -> bool {
        self.intervals(k)
            .iter()
            .any(|iv| (iv[0] as f64) < t1 && (iv[1] as f64) > t0)
    }

    /// Remove (t0, t1) from dexel `k`.
    pub fn subtract(&mut self, k: usize, t0: f64, t1: f64) {
        let (c0, c1) = (t0 as f32, t1 as f32);
        let r = self.rays[k];
        if r[0].is_nan() {
            let idx = r[1].to_bits() as usize;
            let v = &mut self.multi[idx];
            let mut out = Vec::with_capacity(v.len() + 1);
            for iv in v.iter() {
                cut(*iv, c0, c1, &mut out);
            }
            match out.len() {
                0 => {
                    self.rays[k] = EMPTY;
                    v.clear();
                }
                1 => {
                    self.rays[k] = out[0];
                    v.clear();
                }
                _ => *v = out,
            }
            return;
        }
        if r[0] > r[1] || c1 <= r[0] || c0 >= r[1] {
            return;
        }
        // One interval in, at most two out: no allocation unless it splits.
        match (c0 > r[0], c1 < r[1]) {
            (false, false) => self.rays[k] = EMPTY,
            (true, false) => self.rays[k] = [r[0], c0],
            (false, true) => self.rays[k] = [c1, r[1]],
            (true, true) => {
                let out = vec![[r[0], c0], [c1, r[1]]];
                // Reuse a cleared side slot when there is one.
                let idx = match self.multi.iter().position(|v| v.is_empty()) {
                    Some(i) => {
                        self.multi[i] = out;
                        i
                    }
                    None => {
                        self.multi.push(out);
                        self.multi.len() - 1
                    }
                };
                self.rays[k] = [f32::NAN, f32::from_bits(idx as u32)];
            }
        }
    }

    /// Bytes this tile holds (for the memory report).
    pub fn bytes(&self) -> usize {
        self.rays.len() * 8 + self.multi.iter().map(|v| 24 + v.capacity() * 8).sum::<usize>()
    }
}

/// `iv` minus (c0, c1), appended to `out`.
fn cut(iv: [f32; 2], c0: f32, c1: f32, out: &mut Vec<[f32; 2]>) {
    if c1 <= iv[0] || c0 >= iv[1] {
        out.push(iv);
        return;
    }
    if c0 > iv[0] {
        out.push([iv[0], c0]);
    }
    if c1 < iv[1] {
        out.push([c1, iv[1]]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn subtract_splits_merges_and_empties() {
        let mut t = Tile::full(0.0, 10.0);
        t.subtract(3, 2.0, 4.0);
        assert_eq!(t.intervals(3), &[[0.0, 2.0], [4.0, 10.0]]);
        assert!(t.has_material(3, 1.0, 3.0) && !t.has_material(3, 2.5, 3.5));
        t.subtract(3, 5.0, 6.0);
        assert_eq!(t.intervals(3).len(), 3);
        t.subtract(3, -1.0, 5.5);
        assert_eq!(t.intervals(3), &[[6.0, 10.0]]);
        t.subtract(3, 6.0, 10.0);
        assert!(t.intervals(3).is_empty());
        // The side slot is reused.
        t.subtract(4, 1.0, 2.0);
        assert_eq!(t.intervals(4), &[[0.0, 1.0], [2.0, 10.0]]);
        assert_eq!(t.multi.len(), 1);
        assert_eq!(t.intervals(5), &[[0.0, 10.0]]);
    }
}
