//! The double-description method (Motzkin et al. 1953; Fukuda and Prodon 1996): the extreme
//! rays of a pointed polyhedral cone {x : A x <= 0} from its inequalities, by adding one
//! inequality at a time and combining only adjacent rays (combinatorial adjacency test).
//!
//! Used on the polar of a contact wrench cone: the extreme rays of {h : G h <= 0}, where the
//! rows of G span the cone, are the cone's face normals (span form to face form).
//!
//! Numerics: rows and rays are normalized to unit length; a ray is on a hyperplane when
//! |a . r| <= [`DdParams::zero_tol`]; rows closer than `duplicate_tol` to an earlier row are
//! dropped.

use nalgebra::SVector;

/// Tolerances of the method.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DdParams {
    /// |a . r| below this counts as zero (unit rows and rays).
    pub zero_tol: f64,
    /// Rows within this (Euclidean, unit-normalized) of an earlier row are duplicates.
    pub duplicate_tol: f64,
}

impl Default for DdParams {
    fn default() -> Self {
        Self { zero_tol: 1e-10, duplicate_tol: 1e-12 }
    }
}

/// Why the rays could not be computed.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum DdError {
    /// The rows do not span the space: the cone contains a line (is not pointed).
    #[error("the cone is not pointed: its {rows} inequalities have rank {rank} < {dim}")]
    NotPointed {
        /// Rank of the rows.
        rank: usize,
        /// Dimension.
        dim: usize,
        /// Rows given.
        rows: usize,
    },
    /// More rows than the zero-set bitsets hold.
    #[error("too many inequalities ({0}; at most {MAX_ROWS})")]
    TooManyRows(usize),
    /// Non-finite input.
    #[error("an inequality is not finite")]
    NotFinite,
}

/// Most inequalities handled (zero sets are fixed-size bitsets).
pub const MAX_ROWS: usize = 256;

#[derive(Clone, Copy, PartialEq, Eq, Default)]
struct Bits([u64; MAX_ROWS / 64]);

impl Bits {
    fn set(&mut self, i: usize) {
        self.0[i / 64] |= 1 << (i % 64);
    }
    fn and(&self, o: &Bits) -> Bits {
        let mut r = *self;
        for (a, b) in r.0.iter_mut().zip(o.0.iter()) {
            *a &= b;
        }
        r
    }
    fn count(&self) -> usize {
        self.0.iter().map(|w| w.count_ones() as usize).sum()
    }
    fn contains(&self, sub: &Bits) -> bool {
        self.0.iter().zip(sub.0.iter()).all(|(a, b)| a & b == *b)
    }
}

/// Extreme rays (unit vectors) of the pointed cone {x : a . x <= 0 for every a in `rows`}.
pub fn extreme_rays<const D: usize>(
    rows: &[SVector<f64, D>],
    p: &DdParams,
) -> Result<Vec<SVector<f64, D>>, DdError> {
    if rows.iter().any(|r| r.iter().any(|v| !v.is_finite())) {
        return Err(DdError::NotFinite);
    }
    // Unit rows, zero and duplicate rows dropped.
    let mut a: Vec<SVector<f64, D>> = Vec::with_capacity(rows.len());
    for r in rows {
        let n = r.norm();
        if n <= p.zero_tol {
            continue;
        }
        let u = r / n;
        if a.iter().all(|b| (b - u).norm() > p.duplicate_tol) {
            a.push(u);
        }
    }
    if a.len() > MAX_ROWS {
        return Err(DdError::TooManyRows(a.len()));
    }
    // D independent rows (Gram-Schmidt on the rows, largest residual first).
    let mut basis: Vec<usize> = Vec::with_capacity(D);
    let mut ortho: Vec<SVector<f64, D>> = Vec::with_capacity(D);
    while basis.len() < D {
        let best = (0..a.len())
            .filter(|i| !basis.contains(i))
            .map(|i| {
                let mut v = a[i];
                for q in &ortho {
                    v -= q * q.dot(&v);
                }
                (i, v)
            })
            .max_by(|x, y| x.1.norm().total_cmp(&y.1.norm()));
        match best {
            Some((i, v)) if v.norm() > 1e-9 => {
                basis.push(i);
                ortho.push(v.normalize());
            }
            _ => return Err(DdError::NotPointed { rank: basis.len(), dim: D, rows: rows.len() }),
        }
    }
    // Initial cone {x : A_K x <= 0}: rays r_j = -(A_K)^-1 e_j, zero on every basis row but j.
    let ak = nalgebra::SMatrix::<f64, D, D>::from_fn(|r, c| a[basis[r]][c]);
    let inv = ak.try_inverse().ok_or(DdError::NotPointed { rank: D - 1, dim: D, rows: rows.len() })?;
    let mut rays: Vec<(SVector<f64, D>, Bits)> = (0..D)
        .map(|j| {
            let r: SVector<f64, D> = -inv.column(j);
            let mut z = Bits::default();
            for (k, &row) in basis.iter().enumerate() {
                if k != j {
                    z.set(row);
                }
            }
            (r.normalize(), z)
        })
        .collect();
    let mut values: Vec<f64> = Vec::new();
    for (i, ai) in a.iter().enumerate() {
        if basis.contains(&i) {
            continue;
        }
        values.clear();
        values.extend(rays.iter().map(|(r, _)| ai.dot(r)));
        let plus: Vec<usize> = (0..rays.len()).filter(|&k| values[k] > p.zero_tol).collect();
        if plus.is_empty() {
            for (k, (_, z)) in rays.iter_mut().enumerate() {
                if values[k].abs() <= p.zero_tol {
                    z.set(i);
                }
            }
            continue;
        }
        let minus: Vec<usize> = (0..rays.len()).filter(|&k| values[k] < -p.zero_tol).collect();
        let mut next: Vec<(SVector<f64, D>, Bits)> =
            Vec::with_capacity(rays.len() + plus.len() * minus.len());
        for &m in &minus {
            for &q in &plus {
                let common = rays[m].1.and(&rays[q].1);
                if common.count() + 2 < D {
                    continue;
                }
                let adjacent =
                    rays.iter().enumerate().all(|(k, (_, z))| k == m || k == q || !z.contains(&common));
                if !adjacent {
                    continue;
                }
                let v = rays[m].0 * values[q] - rays[q].0 * values[m];
                let n = v.norm();
                if n > 0.0 {
                    let mut z = common;
                    z.set(i);
                    next.push((v / n, z));
                }
            }
        }
        for (k, (r, z)) in rays.iter().enumerate() {
            if values[k] <= p.zero_tol {
                let mut z = *z;
                if values[k] >= -p.zero_tol {
                    z.set(i);
                }
                next.push((*r, z));
            }
        }
        rays = next;
    }
    Ok(rays.into_iter().map(|(r, _)| r).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn the_positive_orthant_has_the_axes_as_rays() {
        let rows = [-Vector3::x(), -Vector3::y(), -Vector3::z()];
        let mut rays = extreme_rays(&rows, &DdParams::default()).unwrap();
        rays.sort_by(|a, b| b.x.total_cmp(&a.x).then(b.y.total_cmp(&a.y)));
        assert_eq!(rays.len(), 3);
        assert!((rays[0] - Vector3::x()).norm() < 1e-12);
    }

    #[test]
    fn a_square_pyramid_has_four_rays_whatever_the_redundant_rows() {
        // {x : |x| <= z, |y| <= z} with a redundant row (z >= 0) and a duplicate.
        let rows = [
            Vector3::new(1.0, 0.0, -1.0),
            Vector3::new(-1.0, 0.0, -1.0),
            Vector3::new(0.0, 1.0, -1.0),
            Vector3::new(0.0, -1.0, -1.0),
            Vector3::new(0.0, 0.0, -1.0),
            Vector3::new(2.0, 0.0, -2.0),
        ];
        let rays = extreme_rays(&rows, &DdParams::default()).unwrap();
        assert_eq!(rays.len(), 4, "{rays:?}");
        for r in &rays {
            assert!((r.x.abs() - r.z).abs() < 1e-12 && (r.y.abs() - r.z).abs() < 1e-12);
            for a in &rows {
                assert!(a.dot(r) <= 1e-12);
            }
        }
    }

    #[test]
    fn a_cone_with_a_line_is_refused() {
        let rows = [Vector3::new(1.0, 0.0, 0.0), Vector3::new(0.0, 1.0, 0.0)];
        assert!(matches!(extreme_rays(&rows, &DdParams::default()), Err(DdError::NotPointed { .. })));
        let nan = [Vector3::new(f64::NAN, 0.0, 0.0)];
        assert_eq!(extreme_rays(&nan, &DdParams::default()), Err(DdError::NotFinite));
    }
}
