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
    let label_of_cell: FxHashMap<[i32; 3], u32> =
        seeded.iter().enumerate().map(|(l, e)| (e.0, l as u32)).collect();
    // The search volume of each seed cell: the supervoxels seeded in it and its neighbours.
    let mut search: FxHashMap<[i32; 3], Vec<u32>> = FxHashMap::default();
    for &(c, _) in &seeded {
        let mut v = Vec::with_capacity(27);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    if let Some(&l) = label_of_cell.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) {
                        v.push(l);
                    }
                }
            }
        }
        search.insert(c, v);
    }
    let volume: Vec<&[u32]> = cells.iter().map(|c| search.get(c).map_or(&[][..], Vec::as_slice)).collect();

    let mut centres: Vec<Point3<f32>> = seeded.iter().map(|e| vc.positions[e.1 as usize]).collect();
    let mut normals: Vec<Vector3<f32>> = seeded.iter().map(|e| vc.normals[e.1 as usize]).collect();
    let mut labels = vec![UNLABELLED; n];
    // Centres (position or normal) changed by the last update: a voxel none of whose
    // candidates changed keeps its label, exactly as a full re-evaluation would give.
    let mut changed = vec![true; centres.len()];
    let mut rounds = 0;
    while rounds < MAX_ROUNDS {
        rounds += 1;
        // Attachment given fixed centres is independent per voxel (a Lloyd step).
        let next: Vec<u32> = (0..n)
            .into_par_iter()
            .map(|i| {
                if !volume[i].iter().any(|&l| changed[l as usize]) {
                    return labels[i];
                }
                let (q, nq) = (vc.positions[i], vc.normals[i]);
                let mut best = (f32::INFINITY, UNLABELLED);
                for &l in volume[i] {
                    let d = distance(p, q - centres[l as usize], &nq, &normals[l as usize]);
                    if d < best.0 {
                        best = (d, l);
                    }
                }
                best.1
            })
            .collect();
        let moved = next.iter().zip(&labels).filter(|(a, b)| a != b).count();
        labels = next;
        update_centres(vc, &labels, &mut centres, &mut normals, &mut changed);
        if moved == 0 {
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

fn update_centres(
    vc: &VoxelCloud,
    labels: &[u32],
    centres: &mut [Point3<f32>],
    normals: &mut [Vector3<f32>],
    changed: &mut [bool],
) {
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
    for l in 0..centres.len() {
        changed[l] = false;
        if count[l] > 0 {
            let (c, nl) = (
                Point3::from(sum_p[l] / count[l] as f32),
                sum_n[l].try_normalize(1e-12).unwrap_or(normals[l]),
            );
            changed[l] = c != centres[l] || nl != normals[l];
            centres[l] = c;
            normals[l] = nl;
        }
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
