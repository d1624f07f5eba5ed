//! RANSAC plane fitting over the supervoxel centres (§4.3): planes are drawn one after the
//! other from the centres not yet explained. Only planes within the slope threshold of
//! horizontal are candidates (Filter 1 kept nothing else), so a plane cannot bridge two
//! steps by tilting through them.

use super::PerceptionParams;
use nalgebra::{Matrix3, Point3, Unit, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A plane found by RANSAC: `normal . x = offset`, and the centres it explains.
#[derive(Debug, Clone)]
pub struct Plane {
    /// Unit normal (against gravity).
    pub normal: Vector3<f32>,
    /// Offset along the normal, metres.
    pub offset: f32,
    /// Indices (into the centres given) of its inliers.
    pub inliers: Vec<u32>,
}

/// Fits planes to `centres[candidates]` until fewer than three centres remain unexplained or
/// no plane has three inliers.
pub fn planes(
    centres: &[Point3<f32>],
    candidates: &[u32],
    gravity: &Unit<Vector3<f64>>,
    p: &PerceptionParams,
) -> Vec<Plane> {
    let up = -gravity.into_inner().cast::<f32>();
    let cos_slope = (p.normal_distance_threshold - 1.0) as f32;
    let thr = p.ransac_distance_m as f32;
    let mut rng = ChaCha8Rng::seed_from_u64(p.ransac_seed);
    let mut remaining: Vec<u32> = candidates.to_vec();
    let mut out = Vec::new();
    while remaining.len() >= 3 && out.len() < p.ransac_max_planes {
        let mut best: Option<(usize, Vector3<f32>, f32)> = None;
        let mut needed = p.ransac_iterations;
        let mut it = 0;
        while it < needed.min(p.ransac_iterations) {
            it += 1;
            let pick =
                |rng: &mut ChaCha8Rng| centres[remaining[rng.random_range(0..remaining.len())] as usize];
            let (a, b, c) = (pick(&mut rng), pick(&mut rng), pick(&mut rng));
            let Some(n) = (b - a).cross(&(c - a)).try_normalize(1e-9) else { continue };
            let n = if n.dot(&up) < 0.0 { -n } else { n };
            if n.dot(&up) < cos_slope {
                continue;
            }
            let off = n.dot(&a.coords);
            let count =
                remaining.iter().filter(|&&i| (n.dot(&centres[i as usize].coords) - off).abs() < thr).count();
            if best.is_none_or(|b| count > b.0) {
                best = Some((count, n, off));
                // Adaptive stop: enough draws to see an all-inlier sample with 99 % odds.
                let w = count as f64 / remaining.len() as f64;
                let p_good = w.powi(3).clamp(1e-9, 1.0 - 1e-12);
                needed = ((0.01f64).ln() / (1.0 - p_good).ln()).ceil().max(8.0) as usize;
            }
        }
        let Some((count, n, off)) = best else { break };
        if count < 3 {
            break;
        }
        // Refine by least squares on the inliers, then take the inliers of the refined plane.
        let inl: Vec<u32> = remaining
            .iter()
            .copied()
            .filter(|&i| (n.dot(&centres[i as usize].coords) - off).abs() < thr)
            .collect();
        let (n, off) = refit(centres, &inl, &up).unwrap_or((n, off));
        let (inliers, rest): (Vec<u32>, Vec<u32>) =
            remaining.iter().partition(|&&i| (n.dot(&centres[i as usize].coords) - off).abs() < thr);
        if inliers.len() < 3 {
            break;
        }
        remaining = rest;
        out.push(Plane { normal: n, offset: off, inliers });
    }
    out
}

/// Least-squares plane through `centres[idx]` (normal toward `up`); `None` when they do
/// not span a plane. Also fits a segment's normal to its own voxels (`staircase`).
pub(super) fn refit(centres: &[Point3<f32>], idx: &[u32], up: &Vector3<f32>) -> Option<(Vector3<f32>, f32)> {
    let n = idx.len() as f32;
    let mean = idx.iter().map(|&i| centres[i as usize].coords).sum::<Vector3<f32>>() / n;
    let mut c = Matrix3::<f32>::zeros();
    for &i in idx {
        let d = centres[i as usize].coords - mean;
        c += d * d.transpose();
    }
    let v = super::normals::smallest_eigenvector(&(c / n))?;
    let v = if v.dot(up) < 0.0 { -v } else { v };
    Some((v, v.dot(&mean)))
}
