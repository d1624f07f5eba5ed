//! The static-stability polygon of a stance (§6.2): where the CoM may be, in the transverse
//! plane, for the contacts to hold the robot still against gravity.
//!
//! Two independent methods:
//! - [`by_double_description`]: the stance's contact wrench cone in face form, from the
//!   stacked spans of its contacts by the double-description method, then each face becomes
//!   a half-plane in the CoM's (x, y) (static: the CoM's acceleration is neglected), and the
//!   half-planes are intersected into a convex polygon.
//! - [`by_bretl`]: Bretl and Lall's recursive projection, one LP (clarabel) per direction,
//!   refining an inner polygon until every edge is within a tolerance of the outer bound.

use super::contact::Contact;
use super::dd::{extreme_rays, DdError, DdParams};
use crate::geom2d::{self, P2};
use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT};
use nalgebra::Vector6;

/// Why no polygon.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum PolygonError {
    /// No contact given.
    #[error("no contact: a stance needs at least one")]
    NoContact,
    /// The contacts cannot hold the robot still anywhere (e.g. only walls).
    #[error("no static equilibrium: the contacts cannot hold the robot still anywhere")]
    Empty,
    /// The region is unbounded (should not happen with gravity and finite contacts).
    #[error("the stability region is unbounded")]
    Unbounded,
    /// The double description failed.
    #[error("double description: {0}")]
    Dd(#[from] DdError),
    /// The LP solver failed.
    #[error("LP solver: {0}")]
    Lp(String),
}

/// Half extent of the start box the half-planes clip, metres around the contacts.
const BOX_M: f64 = 50.0;

/// The contact wrench cone of the whole stance in face form: rows a with a . w <= 0 for every
/// feasible total contact wrench w (at the world origin).
pub fn stance_faces(contacts: &[Contact], p: &DdParams) -> Result<Vec<Vector6<f64>>, PolygonError> {
    if contacts.is_empty() {
        return Err(PolygonError::NoContact);
    }
    let spans: Vec<Vector6<f64>> = contacts.iter().flat_map(|c| c.span()).collect();
    // The faces of cone(spans) are the extreme rays of its polar {h : s . h <= 0}.
    Ok(extreme_rays(&spans, p)?)
}

/// The static-stability polygon by double description (counter-clockwise vertices).
pub fn by_double_description(contacts: &[Contact], p: &DdParams) -> Result<Vec<P2>, PolygonError> {
    let faces = stance_faces(contacts, p)?;
    // Static equilibrium: the contacts supply w = (-m g, -c x m g). With g = (0, 0, -g0) and
    // m g0 = 1: w = (0, 0, 1, c_y, -c_x, 0), so a face a gives
    //   -a_ty c_x + a_tx c_y <= -a_fz.
    let centre = centre_of(contacts);
    let mut poly: Vec<P2> = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
        .iter()
        .map(|(x, y)| P2::new(centre.x + x * BOX_M, centre.y + y * BOX_M))
        .collect();
    for a in &faces {
        let (nx, ny, b) = (-a[4], a[3], -a[2]);
        let n = (nx * nx + ny * ny).sqrt();
        if n <= p.zero_tol {
            if b < -1e-9 {
                return Err(PolygonError::Empty);
            }
            continue;
        }
        poly = geom2d::clip_half_plane(&poly, &P2::new(nx / n, ny / n), b / n, 0.0);
        if poly.len() < 3 {
            return Err(PolygonError::Empty);
        }
    }
    let poly = simplify(&poly, 1e-9);
    if poly.iter().any(|v| (v.x - centre.x).abs() >= BOX_M * 0.999 || (v.y - centre.y).abs() >= BOX_M * 0.999)
    {
        return Err(PolygonError::Unbounded);
    }
    if poly.len() < 3 {
        return Err(PolygonError::Empty);
    }
    Ok(poly)
}

fn centre_of(contacts: &[Contact]) -> P2 {
    let n = contacts.len() as f64;
    let s = contacts.iter().fold(P2::new(0.0, 0.0), |acc, c| {
        let t = c.pose().translation.vector;
        P2::new(acc.x + t.x, acc.y + t.y)
    });
    P2::new(s.x / n, s.y / n)
}

/// Removes repeated and collinear vertices.
fn simplify(poly: &[P2], tol: f64) -> Vec<P2> {
    let mut v = geom2d::dedup_vertices(poly, tol);
    let mut changed = true;
    while changed && v.len() > 3 {
        changed = false;
        for i in 0..v.len() {
            let (a, b, c) = (v[(i + v.len() - 1) % v.len()], v[i], v[(i + 1) % v.len()]);
            let cross = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
            if cross.abs() <= tol * (c.x - a.x).hypot(c.y - a.y) {
                v.remove(i);
                changed = true;
                break;
            }
        }
    }
    v
}

/// The LP of the projection, built once per stance; only the objective changes per query.
struct Projection {
    a: CscMatrix<f64>,
    b: Vec<f64>,
    p: CscMatrix<f64>,
    cones: [SupportedConeT<f64>; 2],
}

impl Projection {
    /// Variables x = (c_x, c_y, lambda_1..m). Equalities: sum lambda_k s_k = (0, 0, 1, c_y,
    /// -c_x, 0) (with m g0 = 1); lambda >= 0.
    fn new(generators: &[Vector6<f64>]) -> Self {
        let m = generators.len();
        let n = 2 + m;
        let (mut rows, mut cols, mut vals) = (Vec::new(), Vec::new(), Vec::new());
        let mut push = |r: usize, c: usize, v: f64| {
            if v != 0.0 {
                rows.push(r);
                cols.push(c);
                vals.push(v);
            }
        };
        for (k, s) in generators.iter().enumerate() {
            for r in 0..6 {
                push(r, 2 + k, s[r]);
            }
            push(6 + k, 2 + k, -1.0);
        }
        push(3, 1, -1.0); // torque x = c_y
        push(4, 0, 1.0); // torque y = -c_x
        let mut b = vec![0.0; 6 + m];
        b[2] = 1.0;
        Self {
            a: CscMatrix::new_from_triplets(6 + m, n, rows, cols, vals),
            b,
            p: CscMatrix::zeros((n, n)),
            cones: [SupportedConeT::ZeroConeT(6), SupportedConeT::NonnegativeConeT(m)],
        }
    }

    /// The CoM farthest along `dir`, or `None` when no CoM is feasible.
    fn extreme(&self, dir: (f64, f64)) -> Result<Option<P2>, PolygonError> {
        let mut q = vec![0.0; self.a.n];
        q[0] = -dir.0;
        q[1] = -dir.1;
        let settings = DefaultSettingsBuilder::default()
            .verbose(false)
            .tol_gap_abs(1e-10)
            .tol_gap_rel(1e-10)
            .tol_feas(1e-10)
            .build()
            .map_err(|e| PolygonError::Lp(format!("{e:?}")))?;
        let mut solver = DefaultSolver::new(&self.p, &q, &self.a, &self.b, &self.cones, settings)
            .map_err(|e| PolygonError::Lp(e.to_string()))?;
        solver.solve();
        match solver.solution.status {
            SolverStatus::Solved | SolverStatus::AlmostSolved => {
                Ok(Some(P2::new(solver.solution.x[0], solver.solution.x[1])))
            }
            SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible => Ok(None),
            SolverStatus::DualInfeasible | SolverStatus::AlmostDualInfeasible => Err(PolygonError::Unbounded),
            s => Err(PolygonError::Lp(format!("{s:?}"))),
        }
    }
}

/// The static-stability polygon by Bretl and Lall's recursive projection: every edge of the
/// returned (inner) polygon is within `tol_m` of the true boundary.
pub fn by_bretl(contacts: &[Contact], tol_m: f64) -> Result<Vec<P2>, PolygonError> {
    if contacts.is_empty() {
        return Err(PolygonError::NoContact);
    }
    let spans: Vec<Vector6<f64>> = contacts.iter().flat_map(|c| c.span()).collect();
    let lp = Projection::new(&spans);
    let mut poly: Vec<P2> = Vec::new();
    for k in 0..3 {
        let t = std::f64::consts::TAU * k as f64 / 3.0 + 0.1;
        match lp.extreme((t.cos(), t.sin()))? {
            Some(v) => poly.push(v),
            None => return Err(PolygonError::Empty),
        }
    }
    if geom2d::signed_area(&poly) < 0.0 {
        poly.reverse();
    }
    // Edges still to check; an edge i joins poly[i] and poly[i + 1].
    let mut done = vec![false; poly.len()];
    let mut guard = 0;
    while let Some(i) = done.iter().position(|d| !d) {
        guard += 1;
        if guard > 10_000 {
            return Err(PolygonError::Lp("the projection did not converge".into()));
        }
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        let (ex, ey) = (b.x - a.x, b.y - a.y);
        let len = ex.hypot(ey);
        if len <= 1e-12 {
            poly.remove((i + 1) % poly.len());
            done.remove((i + 1) % done.len());
            continue;
        }
        let n = (ey / len, -ex / len); // outward for a counter-clockwise polygon
        let v = lp.extreme(n)?.ok_or(PolygonError::Empty)?;
        let gap = (v.x - a.x) * n.0 + (v.y - a.y) * n.1;
        if gap <= tol_m {
            done[i] = true;
        } else {
            poly.insert(i + 1, v);
            done[i] = false;
            done.insert(i + 1, false);
        }
    }
    Ok(simplify(&poly, 1e-9))
}

fn seg_dist(p: &P2, a: &P2, b: &P2) -> f64 {
    let (dx, dy) = (b.x - a.x, b.y - a.y);
    let l2 = dx * dx + dy * dy;
    let t = if l2 > 0.0 { (((p.x - a.x) * dx + (p.y - a.y) * dy) / l2).clamp(0.0, 1.0) } else { 0.0 };
    (p.x - a.x - t * dx).hypot(p.y - a.y - t * dy)
}

/// Distance from `p` to the boundary of the polygon `poly`, metres.
pub fn boundary_distance(poly: &[P2], p: &P2) -> f64 {
    (0..poly.len()).map(|i| seg_dist(p, &poly[i], &poly[(i + 1) % poly.len()])).fold(f64::INFINITY, f64::min)
}

/// Hausdorff distance between two convex polygons (as regions), metres.
pub fn hausdorff(a: &[P2], b: &[P2]) -> f64 {
    // For convex regions the largest distance is reached at a vertex outside the other.
    let one_way = |a: &[P2], b: &[P2]| {
        a.iter().filter(|p| margin(b, p) < 0.0).map(|p| boundary_distance(b, p)).fold(0.0, f64::max)
    };
    one_way(a, b).max(one_way(b, a))
}

/// Signed distance from `p` to the boundary of the convex counter-clockwise polygon `poly`:
/// positive inside (the stability margin), negative outside.
pub fn margin(poly: &[P2], p: &P2) -> f64 {
    let d = boundary_distance(poly, p);
    if geom2d::contains(poly, p) {
        d
    } else {
        -d
    }
}
