//! Supervoxel clustering (§4.2), the clustering of adjacent supervoxels, and Filter 3.
//!
//! As §4.2 describes it: seeds are the voxels nearest the centres of the occupied cells of a
//! grid of resolution R_seed; every voxel is attached to the closest supervoxel centre, by the
//! distance D of Eq. 1 (D_n of Eq. 2), among the supervoxels seeded in its own and the 26
//! neighbouring seed cells (its search volume); after each such expansion every centre
//! (position and normal) becomes the mean of its members, and the attachment is repeated
//! until no voxel changes supervoxel. Attachment does not need the voxels to touch, so a scan
//! whose lines are farther apart than a voxel (the paper's own Exp. 1 data) still forms
//! supervoxels across its lines.
//!
//! Each round attaches again only the voxels of the seed cells that see a centre the last
//! round moved (every voxel of a cell has the same candidates); this gives the labels a full
//! re-evaluation gives (a unit test compares them) at a fraction of the cost. The centres
//! are summed in f32 in voxel order, as before: a centre that moves by a rounding error
//! changes the closed loop's later views enough to matter (f64 running sums made the
//! Exp. 1 climb fall on step 2).

use super::voxel::VoxelCloud;
use super::PerceptionParams;
use crate::geom2d::{self, P2};
use nalgebra::{Point3, Vector3};
use rayon::prelude::*;
use rustc_hash::FxHashMap;

/// Label of a voxel that no supervoxel reached.
pub const UNLABELLED: u32 = u32::MAX;

/// The supervoxels of a voxel cloud.
#[derive(Debug, Clone, Default)]
pub struct Supervoxels {
    /// Supervoxel of each voxel, or [`UNLABELLED`].
    pub labels: Vec<u32>,
    /// Centre of each supervoxel: mean position of its voxels.
    pub centres: Vec<Point3<f32>>,
    /// Mean normal of each supervoxel's voxels (unit).
    pub normals: Vec<Vector3<f32>>,
    /// Voxels in each supervoxel.
    pub sizes: Vec<u32>,
    /// Expansion rounds run.
    pub rounds: usize,
}

/// The distance D of Eq. 1 between a voxel and a supervoxel centre.
pub fn distance(
    p: &PerceptionParams,
    dp: Vector3<f32>,
    n_voxel: &Vector3<f32>,
    n_centre: &Vector3<f32>,
) -> f32 {
    let mu = p.distance_impact_factor as f32;
    let r = p.seed_resolution_m as f32;
    let ds2 = dp.norm_squared();
    let dn = 1.0 - n_voxel.dot(n_centre);
    (mu * ds2 / (3.0 * r * r) + (1.0 - mu) * dn * dn).sqrt()
}

/// Most attachment rounds (a guard; they stop as soon as no voxel moves).
const MAX_ROUNDS: usize = 20;

fn seed_cell(q: &Point3<f32>, rs: f32) -> [i32; 3] {
    [(q.x / rs).floor() as i32, (q.y / rs).floor() as i32, (q.z / rs).floor() as i32]
}

/// Clusters the voxels into supervoxels.
pub fn supervoxels(vc: &VoxelCloud, p: &PerceptionParams) -> Supervoxels {
    let n = vc.len();
    let rs = p.seed_resolution_m as f32;
    // Seeds: the voxel nearest the centre of each occupied seed cell.
    let cells: Vec<[i32; 3]> = vc.positions.iter().map(|q| seed_cell(q, rs)).collect();
    let mut best: FxHashMap<[i32; 3], (f32, u32)> = FxHashMap::default();
    for (i, q) in vc.positions.iter().enumerate() {
        let c = cells[i];
        let centre = Vector3::new(c[0] as f32 + 0.5, c[1] as f32 + 0.5, c[2] as f32 + 0.5) * rs;
        let d = (q.coords - centre).norm_squared();
        let e = best.entry(c).or_insert((f32::INFINITY, 0));
        if d < e.0 {
            *e = (d, i as u32);
        }
    }
    let mut seeded: Vec<([i32; 3], u32)> = best.iter().map(|(c, v)| (*c, v.1)).collect();
    seeded.sort_unstable_by_key(|e| e.1);
    let m = seeded.len();
    // Each occupied seed cell holds one seed: a cell and its supervoxel share a label.
    let label_of_cell: FxHashMap<[i32; 3], u32> =
        seeded.iter().enumerate().map(|(l, e)| (e.0, l as u32)).collect();
    // The search volume of each seed cell: the supervoxels seeded in it and its neighbours.
    // The relation is symmetric, so it also lists the cells whose voxels see a supervoxel.
    let volume = Csr::build(m, |l, out| {
        let c = seeded[l].0;
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    if let Some(&k) = label_of_cell.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) {
                        out.push(k);
                    }
                }
            }
        }
    });
    let own: Vec<u32> = cells.iter().map(|c| label_of_cell[c]).collect();
    let members = Csr::group(m, &own);

    let mut centres: Vec<Point3<f32>> = seeded.iter().map(|e| vc.positions[e.1 as usize]).collect();
    let mut normals: Vec<Vector3<f32>> = seeded.iter().map(|e| vc.normals[e.1 as usize]).collect();
    let mut labels = vec![UNLABELLED; n];
    // Centres (position or normal) moved by the last update: only voxels that see one of
    // them are attached again, which gives what attaching every voxel would.
    let mut moved_centres: Vec<u32> = (0..m as u32).collect();
    let mut flag = vec![false; m];
    let mut rounds = 0;
    while rounds < MAX_ROUNDS {
        rounds += 1;
        let cells_to_attach = distinct(moved_centres.iter().map(|&l| volume.get(l as usize)), &mut flag);
        // Attachment given fixed centres is independent per voxel (a Lloyd step).
        let moves: Vec<(u32, u32)> = cells_to_attach
            .par_iter()
            .flat_map_iter(|&c| {
                let candidates = volume.get(c as usize);
                let (centres, normals, labels) = (&centres, &normals, &labels);
                members.get(c as usize).iter().filter_map(move |&i| {
                    let (q, nq) = (vc.positions[i as usize], vc.normals[i as usize]);
                    let mut best = (f32::INFINITY, UNLABELLED);
                    for &l in candidates {
                        let d = distance(p, q - centres[l as usize], &nq, &normals[l as usize]);
                        if d < best.0 {
                            best = (d, l);
                        }
                    }
                    (best.1 != labels[i as usize]).then_some((i, best.1))
                })
            })
            .collect();
        for &(i, l) in &moves {
            labels[i as usize] = l;
        }
        moved_centres = update_centres(vc, &labels, &mut centres, &mut normals);
        if moves.is_empty() {
            break;
        }
    }
    let mut sizes = vec![0u32; centres.len()];
    for &l in &labels {
        if l != UNLABELLED {
            sizes[l as usize] += 1;
        }
    }
    Supervoxels { labels, centres, normals, sizes, rounds }
}

/// Every centre (position and normal) becomes the mean of its voxels, summed in f32 in
/// voxel order; returns the supervoxels whose centre moved.
fn update_centres(
    vc: &VoxelCloud,
    labels: &[u32],
    centres: &mut [Point3<f32>],
    normals: &mut [Vector3<f32>],
) -> Vec<u32> {
    let mut sum_p = vec![Vector3::<f32>::zeros(); centres.len()];
    let mut sum_n = vec![Vector3::<f32>::zeros(); centres.len()];
    let mut count = vec![0u32; centres.len()];
    for (i, &l) in labels.iter().enumerate() {
        if l != UNLABELLED {
            sum_p[l as usize] += vc.positions[i].coords;
            sum_n[l as usize] += vc.normals[i];
            count[l as usize] += 1;
        }
    }
    let mut moved = Vec::new();
    for l in 0..centres.len() {
        if count[l] > 0 {
            let c = Point3::from(sum_p[l] / count[l] as f32);
            let nl = sum_n[l].try_normalize(1e-12).unwrap_or(normals[l]);
            if c != centres[l] || nl != normals[l] {
                moved.push(l as u32);
            }
            centres[l] = c;
            normals[l] = nl;
        }
    }
    moved
}

/// The distinct items of `lists`, in first-seen order. `flag` (one per item, all false) is
/// left all false.
fn distinct<'a>(lists: impl Iterator<Item = &'a [u32]>, flag: &mut [bool]) -> Vec<u32> {
    let mut out = Vec::new();
    for list in lists {
        for &x in list {
            if !flag[x as usize] {
                flag[x as usize] = true;
                out.push(x);
            }
        }
    }
    for &x in &out {
        flag[x as usize] = false;
    }
    out
}

/// Lists of u32 per index, concatenated (compressed sparse rows).
struct Csr {
    start: Vec<u32>,
    items: Vec<u32>,
}

impl Csr {
    /// The lists of `0..n`, list i filled by `fill(i, out)`.
    fn build(n: usize, mut fill: impl FnMut(usize, &mut Vec<u32>)) -> Self {
        let mut start = Vec::with_capacity(n + 1);
        let mut items = Vec::new();
        start.push(0);
        for i in 0..n {
            fill(i, &mut items);
            start.push(items.len() as u32);
        }
        Self { start, items }
    }

    /// The indices of `keys` grouped by key (each below `n`), in increasing order per group.
    fn group(n: usize, keys: &[u32]) -> Self {
        let mut start = vec![0u32; n + 1];
        for &k in keys {
            start[k as usize + 1] += 1;
        }
        for i in 0..n {
            start[i + 1] += start[i];
        }
        let mut next = start.clone();
        let mut items = vec![0u32; keys.len()];
        for (i, &k) in keys.iter().enumerate() {
            items[next[k as usize] as usize] = i as u32;
            next[k as usize] += 1;
        }
        Self { start, items }
    }

    fn get(&self, i: usize) -> &[u32] {
        &self.items[self.start[i] as usize..self.start[i + 1] as usize]
    }
}

/// Clusters of adjacent supervoxels after Filter 3.
#[derive(Debug, Clone, Default)]
pub struct Clusters {
    /// Cluster of each supervoxel, or [`UNLABELLED`] when its cluster was filtered out.
    pub of_supervoxel: Vec<u32>,
    /// Voxels in each kept cluster.
    pub voxel_counts: Vec<u32>,
    /// Footprint (convex hull area in the transverse plane) of each kept cluster, m^2.
    pub areas_m2: Vec<f64>,
    /// Clusters before Filter 3.
    pub before_filter: usize,
}

/// Supervoxels whose centres are closer than this many seed spacings are adjacent (seeds sit
/// one spacing apart, diagonal neighbours 1.41).
const ADJACENT_SEEDS: f32 = 1.5;

/// Merges adjacent supervoxels (centres within 1.5 R_seed) whose centres lie within epsilon
/// in height and whose normals differ by less than the slope threshold (the paper gives no
/// rule; these are its own §4.1 and §4.3 tolerances). Filter 3 then drops the clusters
/// smaller than the robot's sole: footprint (convex hull of the voxels in the transverse
/// plane) below the sole's area. The footprint, not the voxel count, because a sparse scan
/// covers a step with lines of voxels (the paper's Exp. 1 data: lines 8-10 cm apart).
pub fn cluster(vc: &VoxelCloud, sv: &Supervoxels, p: &PerceptionParams) -> Clusters {
    let m = sv.centres.len();
    let mut parent: Vec<u32> = (0..m as u32).collect();
    fn find(parent: &mut [u32], mut x: u32) -> u32 {
        while parent[x as usize] != x {
            parent[x as usize] = parent[parent[x as usize] as usize];
            x = parent[x as usize];
        }
        x
    }
    let eps = p.max_height_extent_m as f32;
    let cos_slope = (p.normal_distance_threshold - 1.0) as f32; // cos 15 deg by default
    let reach = ADJACENT_SEEDS * p.seed_resolution_m as f32;
    let cell = |q: &Point3<f32>| {
        [(q.x / reach).floor() as i32, (q.y / reach).floor() as i32, (q.z / reach).floor() as i32]
    };
    let mut grid: FxHashMap<[i32; 3], Vec<u32>> = FxHashMap::default();
    for l in 0..m {
        if sv.sizes[l] > 0 {
            grid.entry(cell(&sv.centres[l])).or_default().push(l as u32);
        }
    }
    for a in 0..m {
        if sv.sizes[a] == 0 {
            continue;
        }
        let (ca, c) = (sv.centres[a], cell(&sv.centres[a]));
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let Some(list) = grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) else { continue };
                    for &b in list {
                        let b = b as usize;
                        if b <= a || (sv.centres[b] - ca).norm() > reach {
                            continue;
                        }
                        let close = (sv.centres[b].z - ca.z).abs() < eps;
                        let aligned = sv.normals[a].dot(&sv.normals[b]) > cos_slope;
                        if close && aligned {
                            let (ra, rb) = (find(&mut parent, a as u32), find(&mut parent, b as u32));
                            parent[ra as usize] = rb;
                        }
                    }
                }
            }
        }
    }
    let mut root_to_cluster: FxHashMap<u32, u32> = FxHashMap::default();
    let mut counts: Vec<u32> = Vec::new();
    let mut of_sv = vec![UNLABELLED; m];
    for (l, slot) in of_sv.iter_mut().enumerate() {
        if sv.sizes[l] == 0 {
            continue;
        }
        let r = find(&mut parent, l as u32);
        let c = *root_to_cluster.entry(r).or_insert_with(|| {
            counts.push(0);
            (counts.len() - 1) as u32
        });
        *slot = c;
        counts[c as usize] += sv.sizes[l];
    }
    let before_filter = counts.len();
    let mut xy: Vec<Vec<P2>> = vec![Vec::new(); counts.len()];
    for (i, &l) in sv.labels.iter().enumerate() {
        if l != UNLABELLED {
            let q = vc.positions[i];
            xy[of_sv[l as usize] as usize].push(P2::new(q.x as f64, q.y as f64));
        }
    }
    let foot = p.foot_length_m * p.foot_width_m;
    let mut remap = vec![UNLABELLED; counts.len()];
    let (mut kept, mut areas) = (Vec::new(), Vec::new());
    for (c, &n) in counts.iter().enumerate() {
        // Quick accept: enough voxels to cover a sole whatever their layout.
        let a = if n as f64 * p.voxel_resolution_m.powi(2) >= foot {
            f64::INFINITY
        } else {
            geom2d::area(&geom2d::convex_hull(&xy[c]))
        };
        if a >= foot {
            remap[c] = kept.len() as u32;
            kept.push(n);
            areas.push(if a.is_finite() { a } else { geom2d::area(&geom2d::convex_hull(&xy[c])) });
        }
    }
    for c in of_sv.iter_mut() {
        if *c != UNLABELLED {
            *c = remap[*c as usize];
        }
    }
    Clusters { of_supervoxel: of_sv, voxel_counts: kept, areas_m2: areas, before_filter }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every round attaches every voxel (by its own seeding and search volumes, found by
    /// scanning the seed list), then updates the centres.
    fn reference(vc: &VoxelCloud, p: &PerceptionParams) -> (Vec<u32>, usize) {
        let rs = p.seed_resolution_m as f32;
        let cells: Vec<[i32; 3]> = vc.positions.iter().map(|q| seed_cell(q, rs)).collect();
        let mut seeds: Vec<([i32; 3], u32)> = Vec::new();
        for (i, q) in vc.positions.iter().enumerate() {
            let c = cells[i];
            let centre = Vector3::new(c[0] as f32 + 0.5, c[1] as f32 + 0.5, c[2] as f32 + 0.5) * rs;
            let d = (q.coords - centre).norm_squared();
            match seeds.iter_mut().find(|s| s.0 == c) {
                Some(s) if d < (vc.positions[s.1 as usize].coords - centre).norm_squared() => s.1 = i as u32,
                Some(_) => {}
                None => seeds.push((c, i as u32)),
            }
        }
        seeds.sort_by_key(|s| s.1);
        let mut centres: Vec<Point3<f32>> = seeds.iter().map(|s| vc.positions[s.1 as usize]).collect();
        let mut normals: Vec<Vector3<f32>> = seeds.iter().map(|s| vc.normals[s.1 as usize]).collect();
        let mut labels = vec![UNLABELLED; vc.len()];
        let mut rounds = 0;
        while rounds < MAX_ROUNDS {
            rounds += 1;
            let next: Vec<u32> = (0..vc.len())
                .map(|i| {
                    let mut best = (f32::INFINITY, UNLABELLED);
                    for dx in -1..=1 {
                        for dy in -1..=1 {
                            for dz in -1..=1 {
                                let c = [cells[i][0] + dx, cells[i][1] + dy, cells[i][2] + dz];
                                let Some(l) = seeds.iter().position(|s| s.0 == c) else { continue };
                                let d =
                                    distance(p, vc.positions[i] - centres[l], &vc.normals[i], &normals[l]);
                                if d < best.0 {
                                    best = (d, l as u32);
                                }
                            }
                        }
                    }
                    best.1
                })
                .collect();
            let moved = next != labels;
            labels = next;
            // The centres as the implementation computes them: only the attachment differs.
            update_centres(vc, &labels, &mut centres, &mut normals);
            if !moved {
                break;
            }
        }
        (labels, rounds)
    }

    #[test]
    fn incremental_rounds_give_the_full_re_evaluation() {
        // A floor and a step 20 cm up, voxels 2 cm apart with jittered positions and normals.
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut rnd = || rng.random_range(-0.5f32..0.5);
        let mut vc = VoxelCloud { resolution_m: 0.02, ..Default::default() };
        for i in 0..40 {
            for j in 0..25 {
                let (x, y) = (i as f32 * 0.02 + 0.01, j as f32 * 0.02 + 0.01);
                let z = if x > 0.45 { 0.2 } else { 0.0 } + 0.004 * rnd();
                vc.positions.push(Point3::new(x + 0.006 * rnd(), y + 0.006 * rnd(), z));
                vc.normals.push(Vector3::new(0.2 * rnd(), 0.2 * rnd(), 1.0).normalize());
            }
        }
        let p = PerceptionParams::default();
        let sv = supervoxels(&vc, &p);
        let (labels, rounds) = reference(&vc, &p);
        assert!(rounds > 2, "the test needs several rounds, got {rounds}");
        assert_eq!(sv.labels, labels);
        assert_eq!(sv.rounds, rounds);
    }
}
