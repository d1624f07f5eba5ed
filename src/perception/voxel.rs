//! The voxel grid of resolution v (Algorithm 1, lines 9-15) and Filter 2.
//!
//! A hashed grid rather than an octree: the points are sorted by (x, y, z) cell, so each
//! (x, y) column of cells is a contiguous run, and a dense 2-D table of column runs answers
//! "how many voxels are in the 3 x 3 x 3 block around this one" with nine short scans and
//! no hashing. Each voxel is represented by its point closest to the voxel's mean (GET_CENTER)
//! and carries the mean of its points' normals.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;
use rustc_hash::FxHashMap;

/// Voxels of a cloud, with their adjacency sizes. Index-aligned arrays.
#[derive(Debug, Clone, Default)]
pub struct VoxelCloud {
    /// Edge of a voxel, metres.
    pub resolution_m: f32,
    /// Integer cell of each voxel.
    pub keys: Vec<[i32; 3]>,
    /// Representative point of each voxel (its point closest to the mean).
    pub positions: Vec<Point3<f32>>,
    /// Mean normal of each voxel's points (unit).
    pub normals: Vec<Vector3<f32>>,
    /// Points in each voxel.
    pub counts: Vec<u32>,
    /// Adjacency size of each voxel as Algorithm 1 counts it: occupied cells of its
    /// 3 x 3 x 3 block, itself included, among the voxels it was voxelized with.
    pub adjacency: Vec<u8>,
}

impl VoxelCloud {
    /// Number of voxels.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether there is no voxel.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }
}

fn cell(p: &Point3<f32>, v: f32) -> [i32; 3] {
    [(p.x / v).floor() as i32, (p.y / v).floor() as i32, (p.z / v).floor() as i32]
}

/// Voxelizes the points `indices` of `points` (with their `normals`) at resolution `v`.
/// Non-finite points and cells beyond +/-2^20 voxels from the origin are skipped. A voxel
/// none of whose points has a normal gets `fallback_normal` if given, else is skipped.
pub fn voxelize(
    points: &[Point3<f32>],
    normals: &[[f32; 3]],
    indices: &[u32],
    v: f32,
    fallback_normal: Option<Vector3<f32>>,
) -> VoxelCloud {
    const LIMIT: i32 = 1 << 20;
    let mut keyed: Vec<(u64, u32)> = indices
        .par_iter()
        .filter_map(|&i| {
            let p = points[i as usize];
            let c = cell(&p, v);
            let ok = c.iter().all(|x| (-LIMIT..LIMIT).contains(x)) && p.coords.iter().all(|x| x.is_finite());
            ok.then(|| (pack(c), i))
        })
        .collect();
    keyed.par_sort_unstable_by_key(|e| e.0);
    let mut vc = VoxelCloud { resolution_m: v, ..Default::default() };
    let mut start = 0;
    while start < keyed.len() {
        let key = keyed[start].0;
        let mut end = start + 1;
        while end < keyed.len() && keyed[end].0 == key {
            end += 1;
        }
        let members = &keyed[start..end];
        let n = members.len() as f32;
        let mean = members.iter().map(|m| points[m.1 as usize].coords).sum::<Vector3<f32>>() / n;
        let rep = members
            .iter()
            .map(|m| points[m.1 as usize])
            .min_by(|a, b| (a.coords - mean).norm_squared().total_cmp(&(b.coords - mean).norm_squared()))
            .unwrap_or(Point3::from(mean));
        let nsum: Vector3<f32> = members
            .iter()
            .map(|m| Vector3::from(normals[m.1 as usize]))
            .filter(|n| n.iter().all(|x| x.is_finite()))
            .sum();
        start = end;
        let Some(normal) = nsum.try_normalize(1e-12).or(fallback_normal) else { continue };
        vc.keys.push(unpack(key));
        vc.positions.push(rep);
        vc.normals.push(normal);
        vc.counts.push(members.len() as u32);
    }
    vc.adjacency = adjacency(&vc.keys);
    vc
}

/// Filter 2: keeps the voxels whose adjacency size exceeds `min_adjacent` (n_t). The kept
/// voxels keep the adjacency size they had before the filter.
pub fn filter_sparse(vc: &VoxelCloud, min_adjacent: usize) -> VoxelCloud {
    let kept: Vec<usize> = (0..vc.len()).filter(|&i| vc.adjacency[i] as usize > min_adjacent).collect();
    VoxelCloud {
        resolution_m: vc.resolution_m,
        keys: kept.iter().map(|&i| vc.keys[i]).collect(),
        positions: kept.iter().map(|&i| vc.positions[i]).collect(),
        normals: kept.iter().map(|&i| vc.normals[i]).collect(),
        counts: kept.iter().map(|&i| vc.counts[i]).collect(),
        adjacency: kept.iter().map(|&i| vc.adjacency[i]).collect(),
    }
}

const BITS: u32 = 21;
const OFFSET: i64 = 1 << (BITS - 1);

/// Packs a cell into a key that sorts by x, then y, then z.
fn pack(c: [i32; 3]) -> u64 {
    let f = |x: i32| ((x as i64 + OFFSET) as u64) & ((1 << BITS) - 1);
    (f(c[0]) << (2 * BITS)) | (f(c[1]) << BITS) | f(c[2])
}

fn unpack(k: u64) -> [i32; 3] {
    let f = |x: u64| ((x & ((1 << BITS) - 1)) as i64 - OFFSET) as i32;
    [f(k >> (2 * BITS)), f(k >> BITS), f(k)]
}

/// Largest dense column table, cells; beyond it the columns go in a hash map.
const MAX_DENSE_COLUMNS: usize = 1 << 24;

/// Adjacency size (occupied cells of the 3 x 3 x 3 block, itself included) of each of the
/// distinct cells `keys`, sorted by (x, y, z).
fn adjacency(keys: &[[i32; 3]]) -> Vec<u8> {
    let n = keys.len();
    if n == 0 {
        return Vec::new();
    }
    // Runs of equal (x, y): the columns.
    let (mut xmin, mut xmax, mut ymin, mut ymax) = (i32::MAX, i32::MIN, i32::MAX, i32::MIN);
    for k in keys {
        xmin = xmin.min(k[0]);
        xmax = xmax.max(k[0]);
        ymin = ymin.min(k[1]);
        ymax = ymax.max(k[1]);
    }
    let mut runs: Vec<(i32, i32, u32, u32)> = Vec::new();
    let mut s = 0;
    while s < n {
        let mut e = s + 1;
        while e < n && keys[e][0] == keys[s][0] && keys[e][1] == keys[s][1] {
            e += 1;
        }
        runs.push((keys[s][0], keys[s][1], s as u32, e as u32));
        s = e;
    }
    let (w, h) = ((xmax - xmin + 1) as usize, (ymax - ymin + 1) as usize);
    let columns = Columns::new(&runs, xmin, ymin, w, h);
    keys.par_iter()
        .map(|&[x, y, z]| {
            let mut size = 0u8;
            for dx in -1..=1 {
                for dy in -1..=1 {
                    if let Some((a, b)) = columns.get(x + dx, y + dy) {
                        // Keys are unique cells, so at most 27 pass this test.
                        size += keys[a as usize..b as usize].iter().filter(|k| (k[2] - z).abs() <= 1).count()
                            as u8;
                    }
                }
            }
            size
        })
        .collect()
}

/// Column runs by (x, y): a dense table when the grid's footprint is small, else a hash map.
enum Columns {
    Dense { xmin: i32, ymin: i32, w: usize, h: usize, table: Vec<(u32, u32)> },
    Sparse(FxHashMap<(i32, i32), (u32, u32)>),
}

impl Columns {
    fn new(runs: &[(i32, i32, u32, u32)], xmin: i32, ymin: i32, w: usize, h: usize) -> Self {
        if w.saturating_mul(h) <= MAX_DENSE_COLUMNS {
            let mut table = vec![(0u32, 0u32); w * h];
            for &(x, y, a, b) in runs {
                table[(x - xmin) as usize * h + (y - ymin) as usize] = (a, b);
            }
            Self::Dense { xmin, ymin, w, h, table }
        } else {
            Self::Sparse(runs.iter().map(|&(x, y, a, b)| ((x, y), (a, b))).collect())
        }
    }

    fn get(&self, x: i32, y: i32) -> Option<(u32, u32)> {
        match self {
            Self::Dense { xmin, ymin, w, h, table } => {
                let (i, j) = (x - xmin, y - ymin);
                if i < 0 || j < 0 || i as usize >= *w || j as usize >= *h {
                    return None;
                }
                Some(table[i as usize * h + j as usize]).filter(|r| r.1 > r.0)
            }
            Self::Sparse(map) => map.get(&(x, y)).copied(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pack_round_trips_and_sorts() {
        for c in [[0, 0, 0], [-5, 7, -1], [1000, -1000, 3], [-(1 << 19), (1 << 19) - 1, 0]] {
            assert_eq!(unpack(pack(c)), c);
        }
        assert!(pack([0, 5, 9]) < pack([1, -5, -9]));
        assert!(pack([0, 5, 9]) < pack([0, 6, -9]));
    }

    #[test]
    fn adjacency_of_a_plane_and_filter_two() {
        // A 10 x 10 plane of voxels plus one isolated voxel far away.
        let mut pts = Vec::new();
        for i in 0..10 {
            for j in 0..10 {
                pts.push(Point3::new(i as f32 * 0.02 + 0.01, j as f32 * 0.02 + 0.01, 0.01));
            }
        }
        pts.push(Point3::new(5.0, 5.0, 5.0));
        let normals = vec![[0.0, 0.0, 1.0]; pts.len()];
        let idx: Vec<u32> = (0..pts.len() as u32).collect();
        let vc = voxelize(&pts, &normals, &idx, 0.02, None);
        assert_eq!(vc.len(), 101);
        let corner = vc.keys.iter().position(|k| *k == [0, 0, 0]).unwrap();
        let inner = vc.keys.iter().position(|k| *k == [5, 5, 0]).unwrap();
        assert_eq!(vc.adjacency[corner], 4);
        assert_eq!(vc.adjacency[inner], 9);
        // Against counting every pair of cells.
        for (i, a) in vc.keys.iter().enumerate() {
            let brute = vc.keys.iter().filter(|b| (0..3).all(|d| (a[d] - b[d]).abs() <= 1)).count();
            assert_eq!(vc.adjacency[i] as usize, brute);
        }
        let kept = filter_sparse(&vc, 5);
        // corners (4) and the isolated voxel go; edges have 6 > 5 and stay
        assert_eq!(kept.len(), 96);
        assert!(kept.keys.iter().all(|k| !(k[0] % 9 == 0 && k[1] % 9 == 0)), "a corner was kept");
    }
}
