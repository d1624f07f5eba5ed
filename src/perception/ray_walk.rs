//! The voxels a sweep's rays cross: each ray walked voxel by voxel from its origin toward its
//! return (Amanatides and Woo's walk), the crossed voxels kept as bits in chunks of 16³.
//! The rays are walked into one dense block of bits spanning them all (its words shared by
//! the threads), or, where they span more than [`MAX_BLOCK_BITS`], into each thread's own
//! chunks, merged after (also the baseline `bench plan` times the block against). Both give
//! the same set of voxels on any number of threads.

use nalgebra::Point3;
use rustc_hash::FxHashMap;
use std::sync::atomic::{AtomicU64, Ordering};

/// Edge of a chunk of voxels, in voxels (a chunk's bits fill `CHUNK_WORDS` words).
pub const CHUNK: i32 = 16;
/// Words of a chunk's bits.
pub const CHUNK_WORDS: usize = (CHUNK * CHUNK * CHUNK / 64) as usize;
/// Most bits of a dense block (2^27: 16 MiB); rays spanning more are walked into chunks.
pub const MAX_BLOCK_BITS: i64 = 1 << 27;
/// Rays a thread walks at a time.
const RAYS_PER_TASK: usize = 4096;

/// Chunks of voxel bits by their chunk coordinates.
pub type Chunks = FxHashMap<[i32; 3], Box<[u64; CHUNK_WORDS]>>;

/// How the rays are walked.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Walker {
    /// Into one dense block spanning every ray (the default), chunks where it would be too
    /// large.
    Block,
    /// Into each thread's own chunks, merged after.
    Chunks,
}

/// The chunk of voxel `v`, and `v`'s bit in it.
pub fn chunk_of(v: [i32; 3]) -> ([i32; 3], usize) {
    let key = v.map(|c| c.div_euclid(CHUNK));
    let [x, y, z] = v.map(|c| c.rem_euclid(CHUNK) as usize);
    (key, x + (y + z * CHUNK as usize) * CHUNK as usize)
}

/// The voxel holding `p`.
pub fn voxel(p: &Point3<f64>, voxel_m: f64) -> [i32; 3] {
    [0, 1, 2].map(|i| (p[i] / voxel_m).floor() as i32)
}

/// `from`'s bits added to `into`'s.
pub fn merge(into: &mut Chunks, from: Chunks) {
    for (key, words) in from {
        match into.entry(key) {
            std::collections::hash_map::Entry::Occupied(mut e) => {
                for (a, b) in e.get_mut().iter_mut().zip(words.iter()) {
                    *a |= b;
                }
            }
            std::collections::hash_map::Entry::Vacant(e) => {
                e.insert(words);
            }
        }
    }
}

/// One ray's walk: the voxel it starts in, its steps and the distances along it to each
/// axis's next voxel boundary, how far it goes, and the voxel of its return (never marked).
struct Walk {
    start: [i32; 3],
    step: [i32; 3],
    t_next_m: [f64; 3],
    t_delta_m: [f64; 3],
    end_m: f64,
    hit: [i32; 3],
    /// The voxel where the walk ends.
    far: [i32; 3],
}

impl Walk {
    /// The walk from `from` toward `to`: up to a voxel's edge short of `to` along it and no
    /// farther than `reach_m`; none when that is no way at all.
    fn new(from: &Point3<f64>, to: &Point3<f64>, voxel_m: f64, reach_m: f64) -> Option<Self> {
        let d = to - from;
        let length = d.norm();
        let end = (length - voxel_m).min(reach_m);
        // A ray with no finite length goes nowhere (`min` would take the reach for it).
        if !length.is_finite() || end.is_nan() || end <= 0.0 {
            return None;
        }
        let dir = d / length;
        let start = voxel(from, voxel_m);
        let (mut step, mut t_next_m, mut t_delta_m) = ([0i32; 3], [f64::INFINITY; 3], [f64::INFINITY; 3]);
        for i in 0..3 {
            if dir[i] > 0.0 {
                step[i] = 1;
                t_next_m[i] = ((start[i] + 1) as f64 * voxel_m - from[i]) / dir[i];
                t_delta_m[i] = voxel_m / dir[i];
            } else if dir[i] < 0.0 {
                step[i] = -1;
                t_next_m[i] = (start[i] as f64 * voxel_m - from[i]) / dir[i];
                t_delta_m[i] = -voxel_m / dir[i];
            }
        }
        let far = voxel(&(from + dir * end), voxel_m);
        Some(Self { start, step, t_next_m, t_delta_m, end_m: end, hit: voxel(to, voxel_m), far })
    }
}

/// Marks in `chunks` the voxels of `w` (the baseline walk).
fn trace_chunks(chunks: &mut Chunks, w: &Walk) {
    let (mut v, mut t_next_m) = (w.start, w.t_next_m);
    // The voxel's chunk and its place in it are stepped with the voxel: the chunk is looked
    // up only when the walk leaves it.
    let (mut key, _) = chunk_of(v);
    let mut local = v.map(|c| c.rem_euclid(CHUNK));
    let mut words = chunks.entry(key).or_insert_with(|| Box::new([0; CHUNK_WORDS]));
    let mut t = 0.0;
    while t < w.end_m && v != w.hit {
        let bit = (local[0] + (local[1] + local[2] * CHUNK) * CHUNK) as usize;
        words[bit / 64] |= 1 << (bit % 64);
        // The axis whose boundary comes first (the first of equals).
        let i = if t_next_m[0] <= t_next_m[1] && t_next_m[0] <= t_next_m[2] {
            0
        } else if t_next_m[1] <= t_next_m[2] {
            1
        } else {
            2
        };
        t = t_next_m[i];
        t_next_m[i] += w.t_delta_m[i];
        v[i] += w.step[i];
        local[i] += w.step[i];
        if !(0..CHUNK).contains(&local[i]) {
            local[i] -= w.step[i] * CHUNK;
            key[i] += w.step[i];
            words = chunks.entry(key).or_insert_with(|| Box::new([0; CHUNK_WORDS]));
        }
    }
}

/// A dense box of voxel bits, x fastest; its corner on a chunk's and its extent whole chunks
/// on every axis, so a chunk's row of 16 bits lies in one word and every chunk is whole.
struct Block {
    lo: [i32; 3],
    n: [i64; 3],
    bits: Vec<AtomicU64>,
}

impl Block {
    /// The block spanning voxels `lo..=hi` (grown to whole chunks, so its bits fill whole
    /// words), or none when larger than [`MAX_BLOCK_BITS`].
    fn spanning(lo: [i32; 3], hi: [i32; 3]) -> Option<Self> {
        let lo = lo.map(|c| c.div_euclid(CHUNK) * CHUNK);
        let n = [0, 1, 2].map(|i| (hi[i].div_euclid(CHUNK) as i64 + 1) * CHUNK as i64 - lo[i] as i64);
        let bits = n.iter().try_fold(1i64, |a, &k| a.checked_mul(k)).filter(|&b| b <= MAX_BLOCK_BITS)?;
        Some(Self { lo, n, bits: (0..bits / 64).map(|_| AtomicU64::new(0)).collect() })
    }

    /// The bit of voxel `v`, or none outside the block.
    fn index(&self, v: [i32; 3]) -> Option<i64> {
        let d = [0, 1, 2].map(|i| v[i] as i64 - self.lo[i] as i64);
        (0..3).all(|i| (0..self.n[i]).contains(&d[i])).then(|| d[0] + self.n[0] * (d[1] + self.n[1] * d[2]))
    }

    /// Marks the voxels of `w`: the same voxels as [`trace_chunks`], the walk's bit stepped
    /// with it.
    fn trace(&self, w: &Walk) {
        let Some(mut at) = self.index(w.start) else { return };
        // The return's voxel outside the block is never reached (the walk stays inside).
        let hit = self.index(w.hit).unwrap_or(-1);
        let stride =
            [w.step[0] as i64, w.step[1] as i64 * self.n[0], w.step[2] as i64 * self.n[0] * self.n[1]];
        let [mut tx, mut ty, mut tz] = w.t_next_m;
        let mut t = 0.0;
        while t < w.end_m && at != hit {
            // The walk stays within the block: the block spans every walk's voxels a voxel
            // more each way (`walk`). A voxel outside it on one axis would name another voxel
            // of the block; only a bit outside the whole block is dropped here.
            if let Some(word) = usize::try_from(at >> 6).ok().and_then(|k| self.bits.get(k)) {
                let bit = 1u64 << (at & 63);
                if word.load(Ordering::Relaxed) & bit == 0 {
                    word.fetch_or(bit, Ordering::Relaxed);
                }
            }
            // The axis whose boundary comes first (the first of equals).
            if tx <= ty && tx <= tz {
                t = tx;
                tx += w.t_delta_m[0];
                at += stride[0];
            } else if ty <= tz {
                t = ty;
                ty += w.t_delta_m[1];
                at += stride[1];
            } else {
                t = tz;
                tz += w.t_delta_m[2];
                at += stride[2];
            }
        }
    }

    /// The block's bits as chunks (those with any bit set).
    fn into_chunks(self) -> Chunks {
        let words: Vec<u64> = self.bits.into_iter().map(AtomicU64::into_inner).collect();
        let c = CHUNK as i64;
        let mut out = Chunks::default();
        for cz in 0..self.n[2] / c {
            for cy in 0..self.n[1] / c {
                for cx in 0..self.n[0] / c {
                    let mut chunk = [0u64; CHUNK_WORDS];
                    for z in 0..c {
                        for y in 0..c {
                            let at = cx * c + self.n[0] * (cy * c + y + self.n[1] * (cz * c + z));
                            let row = (words[(at >> 6) as usize] >> (at & 63)) & 0xFFFF;
                            // The row's 16 bits in the chunk's x + 16 (y + 16 z) order.
                            let bit = c * (y + c * z);
                            chunk[(bit >> 6) as usize] |= row << (bit & 63);
                        }
                    }
                    if chunk.iter().any(|&w| w != 0) {
                        let within = [cx, cy, cz];
                        let key = [0, 1, 2].map(|i| self.lo[i].div_euclid(CHUNK) + within[i] as i32);
                        out.insert(key, Box::new(chunk));
                    }
                }
            }
        }
        out
    }
}

/// The voxels (of edge `voxel_m`) the segments `rays` (origin, return) cross, each from its
/// origin up to a voxel's edge short of its return and no farther than `reach_m`, never the
/// return's own voxel.
pub fn walk(rays: &[(Point3<f64>, Point3<f64>)], voxel_m: f64, reach_m: f64, walker: Walker) -> Chunks {
    use rayon::prelude::*;
    let walks: Vec<Walk> =
        rays.iter().filter_map(|(from, to)| Walk::new(from, to, voxel_m, reach_m)).collect();
    let block = match walker {
        Walker::Chunks => None,
        Walker::Block => {
            let (mut lo, mut hi) = ([i32::MAX; 3], [i32::MIN; 3]);
            // A voxel more each way than the walks' ends: rounding never steps out.
            for w in &walks {
                for i in 0..3 {
                    lo[i] = lo[i].min(w.start[i].min(w.far[i]).saturating_sub(1));
                    hi[i] = hi[i].max(w.start[i].max(w.far[i]).saturating_add(1));
                }
            }
            (!walks.is_empty()).then(|| Block::spanning(lo, hi)).flatten()
        }
    };
    match block {
        Some(block) => {
            walks.par_chunks(RAYS_PER_TASK).for_each(|share| share.iter().for_each(|w| block.trace(w)));
            block.into_chunks()
        }
        None => walks
            .par_chunks(RAYS_PER_TASK)
            .map(|share| {
                let mut chunks = Chunks::default();
                share.iter().for_each(|w| trace_chunks(&mut chunks, w));
                chunks
            })
            .reduce(Chunks::default, |mut a, b| {
                merge(&mut a, b);
                a
            }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use std::collections::BTreeSet;

    const VOXEL_M: f64 = 0.05;
    const REACH_M: f64 = 2.5;

    fn set(chunks: &Chunks) -> BTreeSet<[i32; 3]> {
        let mut out = BTreeSet::new();
        for (key, words) in chunks {
            for bit in 0..CHUNK_WORDS * 64 {
                if words[bit / 64] & (1 << (bit % 64)) != 0 {
                    let b = bit as i32;
                    let local = [b % CHUNK, (b / CHUNK) % CHUNK, b / (CHUNK * CHUNK)];
                    out.insert([0, 1, 2].map(|i| key[i] * CHUNK + local[i]));
                }
            }
        }
        out
    }

    /// Rays from a few origins a sweep's head could have (moving between rows) to returns
    /// on every side, near and beyond the reach.
    fn rays(seed: u64, count: usize) -> Vec<(Point3<f64>, Point3<f64>)> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        (0..count)
            .map(|k| {
                // Off the voxels' boundaries: a walk from one enters the voxel it touches.
                let from =
                    Point3::new(0.0123 + 0.01 * (k / 500) as f64, -0.3071, 1.3117 + 0.001 * (k / 500) as f64);
                let d = nalgebra::Vector3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..0.3),
                );
                (from, from + d.normalize() * rng.random_range(0.0..4.0))
            })
            .collect()
    }

    /// The voxels whose boxes the segment from `from` toward `to` enters before the walk's
    /// end (slab test), but the return's own: the walk's voxels, drawn without walking.
    fn by_slabs(from: &Point3<f64>, to: &Point3<f64>) -> BTreeSet<[i32; 3]> {
        let d = to - from;
        let end = (d.norm() - VOXEL_M).min(REACH_M);
        let mut out = BTreeSet::new();
        if end <= 0.0 {
            return out;
        }
        let dir = d.normalize();
        let (a, b) = (voxel(from, VOXEL_M), voxel(&(from + dir * end), VOXEL_M));
        for x in a[0].min(b[0]) - 1..=a[0].max(b[0]) + 1 {
            for y in a[1].min(b[1]) - 1..=a[1].max(b[1]) + 1 {
                for z in a[2].min(b[2]) - 1..=a[2].max(b[2]) + 1 {
                    let v = [x, y, z];
                    let (mut t0, mut t1) = (0.0f64, end);
                    for i in 0..3 {
                        let (lo, hi) = (v[i] as f64 * VOXEL_M, (v[i] + 1) as f64 * VOXEL_M);
                        let (s0, s1) = ((lo - from[i]) / dir[i], (hi - from[i]) / dir[i]);
                        t0 = t0.max(s0.min(s1));
                        t1 = t1.min(s0.max(s1));
                    }
                    // Entered before the end (a voxel entered exactly there is not).
                    if t0 < t1 && t0 < end && v != voxel(to, VOXEL_M) {
                        out.insert(v);
                    }
                }
            }
        }
        out
    }

    #[test]
    fn a_walk_crosses_the_voxels_its_segment_enters() {
        for (from, to) in rays(7, 300) {
            let walked = set(&walk(&[(from, to)], VOXEL_M, REACH_M, Walker::Block));
            assert_eq!(walked, by_slabs(&from, &to), "{from} -> {to}");
        }
    }

    #[test]
    fn the_block_and_the_chunks_cross_the_same_voxels() {
        let rays = rays(11, 20_000);
        let block = set(&walk(&rays, VOXEL_M, REACH_M, Walker::Block));
        assert!(block.len() > 10_000, "{}", block.len());
        assert_eq!(block, set(&walk(&rays, VOXEL_M, REACH_M, Walker::Chunks)));
        // Along the axes and through voxels' corners and edges (ties between the axes).
        let from = Point3::new(0.0, 0.0, 1.0);
        let edges: Vec<_> =
            [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 1.0, 0.0], [1.0, -1.0, -1.0]]
                .into_iter()
                .map(|d| (from, from + nalgebra::Vector3::from(d)))
                .collect();
        assert_eq!(
            set(&walk(&edges, VOXEL_M, REACH_M, Walker::Block)),
            set(&walk(&edges, VOXEL_M, REACH_M, Walker::Chunks))
        );
    }

    /// Rays a kilometre apart span more than a block may hold: they are walked into chunks,
    /// the same voxels.
    #[test]
    fn rays_too_far_apart_for_a_block_are_walked_into_chunks() {
        let near = rays(3, 50);
        let far: Vec<_> = near
            .iter()
            .map(|(a, b)| (a + nalgebra::Vector3::repeat(1e3), b + nalgebra::Vector3::repeat(1e3)))
            .collect();
        let both: Vec<_> = near.iter().chain(far.iter()).copied().collect();
        assert!(Block::spanning([0; 3], [20_000; 3]).is_none());
        let walked = set(&walk(&both, VOXEL_M, REACH_M, Walker::Block));
        let apart: BTreeSet<_> = set(&walk(&near, VOXEL_M, REACH_M, Walker::Block))
            .union(&set(&walk(&far, VOXEL_M, REACH_M, Walker::Block)))
            .copied()
            .collect();
        assert!(!walked.is_empty());
        assert_eq!(walked, apart);
    }
}
