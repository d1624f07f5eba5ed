//! Velocity inverse kinematics as one quadratic programme per tick (§6.1), in the shape of
//! Caron's pink library: a [`Task`] gives a Jacobian, a desired velocity and a weight; an
//! [`Equality`] is a hard kinematic constraint (a contact held still); an [`Inequality`] a
//! hard one-sided limit (a leg kept off a step); a [`Bounds`] is a box on the velocities
//! (joint limits). [`solve`] stacks them into one QP for clarabel:
//!
//!   minimize   sum_k w_k ||J_k qd - v_k||^2 + damping ||qd||^2
//!   subject to E qd = e,   G qd <= h,   lower <= qd <= upper.
//!
//! Constructors for the paper's terms ([`com_task`], [`frame_task`], [`posture_task`],
//! [`contact`], [`joint_limits`]) and for the legs' clearance ([`clearance`]) turn the
//! robot's state into these values, so a new term (a hand on a rail, say) is one more value
//! in a list.

use super::clearance::Nearest;
use crate::robot::model::{base_pose, set_base_rotation, RobotModel, Q_JOINTS, V_JOINTS};
use crate::robot::Kinematics;
use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};
use nalgebra::{
    DMatrix, DVector, Dyn, Isometry3, Matrix3xX, Matrix6xX, MatrixViewMut, Point3, UnitQuaternion, Vector3,
    Vector6, U1,
};

/// A soft objective: weight * ||jacobian qd - velocity||^2.
#[derive(Debug, Clone)]
pub struct Task {
    /// rows x nv.
    pub jacobian: DMatrix<f64>,
    /// Desired velocity of the task's coordinates (rows).
    pub velocity: DVector<f64>,
    /// Weight (§6.1: CoM 1, free foot 0.2, posture 0.001).
    pub weight: f64,
}

/// A hard equality: jacobian qd = velocity.
#[derive(Debug, Clone)]
pub struct Equality {
    /// rows x nv.
    pub jacobian: DMatrix<f64>,
    /// Right-hand side (rows).
    pub velocity: DVector<f64>,
}

/// A hard inequality: jacobian qd <= bound, row by row.
#[derive(Debug, Clone)]
pub struct Inequality {
    /// rows x nv.
    pub jacobian: DMatrix<f64>,
    /// Right-hand side (rows).
    pub bound: DVector<f64>,
}

/// A box on the generalized velocities, nv entries each; infinite for a free coordinate.
#[derive(Debug, Clone)]
pub struct Bounds {
    /// Lower bound, rad/s or m/s.
    pub lower: DVector<f64>,
    /// Upper bound.
    pub upper: DVector<f64>,
}

/// Why a tick's QP had no solution.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum IkError {
    /// Sizes of the terms disagree with nv.
    #[error("IK term has {got} columns, the robot has {want} velocities")]
    Size {
        /// Columns given.
        got: usize,
        /// Velocities of the robot.
        want: usize,
    },
    /// The bounds leave no velocity (lower > upper).
    #[error("velocity bounds cross at coordinate {0} (a joint is outside its limits)")]
    CrossedBounds(usize),
    /// The solver did not converge or found the constraints infeasible.
    #[error("the IK QP failed: {0:?}")]
    Solver(SolverStatus),
    /// The solver refused the problem's data (sizes or values it cannot take): a bug of
    /// the problem's assembly, with the solver's message.
    #[error("the IK QP could not be set up: {0}")]
    Setup(String),
}

/// Velocities minimizing the weighted tasks subject to the equalities and bounds.
/// `damping` (>= 0) is added on every velocity so the QP stays strictly convex.
pub fn solve(
    nv: usize,
    tasks: &[Task],
    equalities: &[Equality],
    inequalities: &[Inequality],
    bounds: &[Bounds],
    damping: f64,
) -> Result<DVector<f64>, IkError> {
    Solver::new(nv, damping).solve(tasks, equalities, inequalities, bounds)
}

/// The rows of a QP whose structure repeats from tick to tick: the equality rows, the
/// inequality rows, and each finite bound as (coordinate, +1 for an upper bound or -1 for a
/// lower one).
#[derive(Debug, Clone, PartialEq)]
struct Shape {
    equality_rows: usize,
    inequality_rows: usize,
    bound_rows: Vec<(usize, f64)>,
}

/// One inequality of a QP as the active-set guess names it: a row of the stacked
/// inequalities, or a coordinate's upper or lower bound.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Limit {
    Row(usize),
    Upper(usize),
    Lower(usize),
}

/// [`solve`] for a stream of ticks: clarabel's solver (its KKT system and symbolic
/// factorization) is built for the first QP of a shape, and later QPs of the same shape
/// only update its data. The shape changes with the number of contacts (keep the number of
/// inequality rows fixed, with rows of zeros when a limit is inactive, to keep it).
pub struct Solver {
    nv: usize,
    damping: f64,
    tolerance: f64,
    qp: Option<(Shape, DefaultSolver<f64>)>,
    active_set_first: bool,
    full_kkt: bool,
    /// A row's nonzero entries (column, value), reused.
    nonzeros: Vec<(usize, f64)>,
    working: Vec<Limit>,
    interior_point_qps: usize,
    h: DMatrix<f64>,
    c: DVector<f64>,
    p_values: Vec<f64>,
    a_values: Vec<f64>,
    b: Vec<f64>,
}

impl Solver {
    /// A solver for `nv` velocities with `damping` on each.
    pub fn new(nv: usize, damping: f64) -> Self {
        Self::with_tolerance(nv, damping, 1e-7)
    }

    /// A solver stopping at `tolerance` on the duality gap and the feasibility (clarabel's
    /// absolute and relative tolerances): the IK runs at 1e-4 rad/s, where its task gains
    /// absorb the difference and each QP takes fewer iterations.
    pub fn with_tolerance(nv: usize, damping: f64, tolerance: f64) -> Self {
        Self {
            nv,
            damping,
            tolerance,
            qp: None,
            active_set_first: false,
            full_kkt: false,
            nonzeros: Vec::new(),
            working: Vec::new(),
            interior_point_qps: 0,
            h: DMatrix::zeros(nv, nv),
            c: DVector::zeros(nv),
            p_values: Vec::new(),
            a_values: Vec::new(),
            b: Vec::new(),
        }
    }

    /// The same solver, with `on`, trying active sets first (dense KKT solves, from the
    /// limits that bound the last solution; see `active_set`): the optimum found exactly
    /// instead of to the interior-point tolerance; clarabel solves the QP as before when a
    /// few guesses do not find it. For streams of ticks, where the binding limits change
    /// little from one tick to the next.
    pub fn with_active_set(mut self, on: bool) -> Self {
        self.active_set_first = on;
        self
    }

    /// The same solver, with `on`, solving each active-set guess's KKT system whole by one
    /// LU instead of by the Schur complement on the objective's Cholesky factor (see
    /// `Kkt`): the same solutions to rounding, slower; the baseline `bench plan` measures.
    pub fn with_full_kkt(mut self, on: bool) -> Self {
        self.full_kkt = on;
        self
    }

    /// How many QPs clarabel solved (the others: the active sets).
    pub fn interior_point_qps(&self) -> usize {
        self.interior_point_qps
    }

    /// The QP's solution by active sets, when a few guesses find it: the limits that bound
    /// the last solution are held as equalities and the equality-constrained least squares
    /// solved (one dense KKT solve); a held limit with a negative multiplier (pulling the
    /// solution inward) is let go, the most violated free one is held, and the guess
    /// repeats. A point that meets every limit with every multiplier nonnegative meets the
    /// KKT conditions, so it is the optimum (the QP is strictly convex), exact rather than
    /// at the interior-point tolerance. `None` sends the QP to clarabel.
    fn active_set(
        &mut self,
        equalities: &[Equality],
        inequalities: &[Inequality],
        bounds: &[Bounds],
    ) -> Option<DVector<f64>> {
        const SLACK: f64 = 1e-9;
        const GUESSES: usize = 5;
        let nv = self.nv;
        let (mut lower, mut upper) = (vec![f64::NEG_INFINITY; nv], vec![f64::INFINITY; nv]);
        for b in bounds {
            for i in 0..nv {
                lower[i] = lower[i].max(b.lower[i]);
                upper[i] = upper[i].min(b.upper[i]);
            }
        }
        let rows: Vec<(&Inequality, usize)> =
            inequalities.iter().flat_map(|g| (0..g.jacobian.nrows()).map(move |r| (g, r))).collect();
        let limits = (0..rows.len())
            .map(Limit::Row)
            .chain((0..nv).filter(|&i| upper[i].is_finite()).map(Limit::Upper))
            .chain((0..nv).filter(|&i| lower[i].is_finite()).map(Limit::Lower));
        // Each limit reads row . x <= rhs: its right-hand side, its row's value at x, and
        // whether a guess carried over from the last tick still names one of this QP's limits.
        let rhs = |l: Limit| match l {
            Limit::Row(r) => rows[r].0.bound[rows[r].1],
            Limit::Upper(i) => upper[i],
            Limit::Lower(i) => -lower[i],
        };
        let value = |l: Limit, x: &DVector<f64>| match l {
            Limit::Row(r) => rows[r].0.jacobian.row(rows[r].1).tr_dot(x),
            Limit::Upper(i) => x[i],
            Limit::Lower(i) => -x[i],
        };
        let held = |l: &Limit| match *l {
            Limit::Row(r) => r < rows.len(),
            Limit::Upper(i) => i < nv && upper[i].is_finite(),
            Limit::Lower(i) => i < nv && lower[i].is_finite(),
        };
        let mut working: Vec<Limit> = self.working.iter().copied().filter(held).collect();
        let m: usize = equalities.iter().map(|e| e.jacobian.nrows()).sum();
        // The equalities' rows and right-hand sides, the same for every guess.
        let mut eq_rows = DMatrix::zeros(m, nv);
        let mut eq_rhs = DVector::zeros(m);
        let mut row = 0;
        for e in equalities {
            let r = e.jacobian.nrows();
            eq_rows.view_mut((row, 0), (r, nv)).copy_from(&e.jacobian);
            eq_rhs.rows_mut(row, r).copy_from(&e.velocity);
            row += r;
        }
        let kkt = Kkt::new(&self.h, &self.c, eq_rows, eq_rhs, self.full_kkt);
        for _ in 0..GUESSES {
            // The held limits' rows (row . x = rhs).
            let mut held_rows = DMatrix::zeros(working.len(), nv);
            let mut held_rhs = DVector::zeros(working.len());
            for (k, &l) in working.iter().enumerate() {
                match l {
                    Limit::Row(r) => held_rows.row_mut(k).copy_from(&rows[r].0.jacobian.row(rows[r].1)),
                    Limit::Upper(i) => held_rows[(k, i)] = 1.0,
                    Limit::Lower(i) => held_rows[(k, i)] = -1.0,
                }
                held_rhs[k] = rhs(l);
            }
            let (x, held_mu) = kkt.solve(&held_rows, &held_rhs)?;
            let pulling = held_mu
                .iter()
                .copied()
                .enumerate()
                .filter(|(_, mu)| *mu < -SLACK)
                .min_by(|a, b| a.1.total_cmp(&b.1));
            if let Some((j, _)) = pulling {
                working.swap_remove(j);
                continue;
            }
            let violated = limits
                .clone()
                .filter(|l| !working.contains(l))
                .map(|l| (l, value(l, &x) - rhs(l)))
                .filter(|(_, excess)| *excess > SLACK)
                .max_by(|a, b| a.1.total_cmp(&b.1));
            match violated {
                Some((l, _)) => working.push(l),
                None => {
                    self.working = working;
                    return Some(x);
                }
            }
        }
        None
    }

    /// One QP (see the module's documentation).
    pub fn solve(
        &mut self,
        tasks: &[Task],
        equalities: &[Equality],
        inequalities: &[Inequality],
        bounds: &[Bounds],
    ) -> Result<DVector<f64>, IkError> {
        let nv = self.nv;
        self.h.fill_with_identity();
        self.h *= self.damping;
        self.c.fill(0.0);
        for t in tasks {
            check(nv, t.jacobian.ncols())?;
            // 0.5 x' P x + c' x with P = 2 w J'J, c = -2 w J'v.
            add_gram_upper(&mut self.h, 2.0 * t.weight, &t.jacobian, &mut self.nonzeros);
            self.c.gemv_tr(-2.0 * t.weight, &t.jacobian, &t.velocity, 1.0);
        }
        self.h.fill_lower_triangle_with_upper_triangle();
        self.b.clear();
        for e in equalities {
            check(nv, e.jacobian.ncols())?;
            self.b.extend(e.velocity.iter());
        }
        let equality_rows = self.b.len();
        for g in inequalities {
            check(nv, g.jacobian.ncols())?;
            self.b.extend(g.bound.iter());
        }
        let mut shape =
            Shape { equality_rows, inequality_rows: self.b.len() - equality_rows, bound_rows: Vec::new() };
        if self.active_set_first {
            for bd in bounds {
                check(nv, bd.lower.len())?;
                check(nv, bd.upper.len())?;
            }
            if let Some(x) = self.active_set(equalities, inequalities, bounds) {
                return Ok(x);
            }
        }
        for bd in bounds {
            check(nv, bd.lower.len())?;
            check(nv, bd.upper.len())?;
            for i in 0..nv {
                let (lo, hi) = (bd.lower[i], bd.upper[i]);
                if lo > hi {
                    return Err(IkError::CrossedBounds(i));
                }
                if hi.is_finite() {
                    shape.bound_rows.push((i, 1.0));
                    self.b.push(hi);
                }
                if lo.is_finite() {
                    shape.bound_rows.push((i, -1.0));
                    self.b.push(-lo);
                }
            }
        }
        // P's values, upper triangle column by column (every entry, so the pattern is fixed).
        self.p_values.clear();
        for j in 0..nv {
            self.p_values.extend((0..=j).map(|i| self.h[(i, j)]));
        }
        // A's values column by column: the equality rows, the inequality rows, then that
        // column's bound rows.
        self.a_values.clear();
        for col in 0..nv {
            for e in equalities {
                self.a_values.extend(e.jacobian.column(col).iter());
            }
            for g in inequalities {
                self.a_values.extend(g.jacobian.column(col).iter());
            }
            self.a_values.extend(shape.bound_rows.iter().filter(|(i, _)| *i == col).map(|(_, coef)| coef));
        }
        let solver = match &mut self.qp {
            Some((s, solver)) if *s == shape => {
                let update = |e: clarabel::solver::DataUpdateError| IkError::Setup(e.to_string());
                solver.update_P(&self.p_values).map_err(update)?;
                solver.update_q(self.c.data.as_vec()).map_err(update)?;
                solver.update_A(&self.a_values).map_err(update)?;
                solver.update_b(&self.b).map_err(update)?;
                solver
            }
            _ => {
                let built = self.build(&shape)?;
                &mut self.qp.insert((shape.clone(), built)).1
            }
        };
        solver.solve();
        self.interior_point_qps += 1;
        let solution = &solver.solution;
        match solution.status {
            SolverStatus::Solved | SolverStatus::AlmostSolved => {
                // The limits that bind (multiplier above slack) are the next tick's first guess.
                let n_dense = shape.equality_rows + shape.inequality_rows;
                self.working = (shape.equality_rows..solution.z.len())
                    .filter(|&k| solution.z[k] > solution.s[k])
                    .map(|k| match k < n_dense {
                        true => Limit::Row(k - shape.equality_rows),
                        false => match shape.bound_rows[k - n_dense] {
                            (i, sign) if sign > 0.0 => Limit::Upper(i),
                            (i, _) => Limit::Lower(i),
                        },
                    })
                    .collect();
                Ok(DVector::from_column_slice(&solution.x))
            }
            s => Err(IkError::Solver(s)),
        }
    }

    /// A clarabel solver for `shape` holding the current values.
    fn build(&self, shape: &Shape) -> Result<DefaultSolver<f64>, IkError> {
        let (nv, n_eq) = (self.nv, shape.equality_rows);
        let n_dense = n_eq + shape.inequality_rows;
        let p_colptr: Vec<usize> = (0..=nv).map(|j| j * (j + 1) / 2).collect();
        let p_rows: Vec<usize> = (0..nv).flat_map(|j| 0..=j).collect();
        let p = CscMatrix::new(nv, nv, p_colptr, p_rows, self.p_values.clone());
        let (mut a_colptr, mut a_rows) = (vec![0], Vec::new());
        for col in 0..nv {
            a_rows.extend(0..n_dense);
            a_rows.extend(
                shape.bound_rows.iter().enumerate().filter(|(_, (i, _))| *i == col).map(|(k, _)| n_dense + k),
            );
            a_colptr.push(a_rows.len());
        }
        let m = n_dense + shape.bound_rows.len();
        let a = CscMatrix::new(m, nv, a_colptr, a_rows, self.a_values.clone());
        let cones = [SupportedConeT::ZeroConeT(n_eq), SupportedConeT::NonnegativeConeT(m - n_eq)];
        DefaultSolver::new(&p, self.c.as_slice(), &a, &self.b, &cones, settings(self.tolerance))
            .map_err(|e| IkError::Setup(e.to_string()))
    }
}

/// Adds `scale J'J` to the upper triangle of `h`, row by row over each row's nonzero
/// entries: a posture task's rows hold one each, and its dense product would cost as much
/// as the rest of the QP.
fn add_gram_upper(h: &mut DMatrix<f64>, scale: f64, j: &DMatrix<f64>, nonzeros: &mut Vec<(usize, f64)>) {
    for r in 0..j.nrows() {
        nonzeros.clear();
        nonzeros.extend(j.row(r).iter().enumerate().filter(|(_, v)| **v != 0.0).map(|(c, v)| (c, *v)));
        for (k, &(a, va)) in nonzeros.iter().enumerate() {
            let sa = scale * va;
            for &(b, vb) in &nonzeros[k..] {
                h[(a, b)] += sa * vb;
            }
        }
    }
}

/// The KKT system of an equality-constrained least squares, `[H A'; A 0] [x; mu] = [-c; b]`,
/// whose rows `A` are a QP's equalities (the same for every active-set guess) over the limits
/// a guess holds.
enum Kkt {
    /// By the Schur complement on `H`'s Cholesky factor `L L' = H`: with `z0 = L^-1 c` and
    /// `Z = L^-1 A'`, the multipliers solve `(Z'Z) mu = -Z' z0 - b` and
    /// `x = -L'^-1 (z0 + Z mu)`. The equalities' part of `Z` and `Z'Z` is taken once per
    /// QP; each guess adds its held rows' columns.
    Schur {
        /// `L`, its upper triangle not zeroed.
        l: DMatrix<f64>,
        z0: DVector<f64>,
        /// `L^-1 E'` for the equalities' rows `E`.
        eq_z: DMatrix<f64>,
        /// `eq_z' eq_z`.
        eq_s: DMatrix<f64>,
        /// `-eq_z' z0 - e`, `e` the equalities' right-hand sides.
        eq_r: DVector<f64>,
    },
    /// The whole system by one LU with partial pivoting each guess: where `H` is not
    /// positive definite as rounded or its pivots span over 12 orders of magnitude, and the
    /// baseline `bench plan` measures against.
    Full { h: DMatrix<f64>, c: DVector<f64>, eq_rows: DMatrix<f64>, eq_rhs: DVector<f64> },
}

impl Kkt {
    /// The system of `h` (symmetric), `c` and the equalities' rows and right-hand sides;
    /// `full` forces [`Kkt::Full`].
    fn new(
        h: &DMatrix<f64>,
        c: &DVector<f64>,
        eq_rows: DMatrix<f64>,
        eq_rhs: DVector<f64>,
        full: bool,
    ) -> Self {
        let chol = (!full).then(|| h.clone().cholesky()).flatten();
        let Some(chol) = chol else {
            return Self::Full { h: h.clone(), c: c.clone(), eq_rows, eq_rhs };
        };
        let l = chol.unpack_dirty();
        // `H` singular but for rounding (no damping, tasks that leave a direction free):
        // the Schur complement would square its conditioning, where the whole system may
        // still be well posed.
        let pivots = l.diagonal().map(|d| d * d);
        if pivots.min() <= 1e-12 * pivots.max() {
            return Self::Full { h: h.clone(), c: c.clone(), eq_rows, eq_rhs };
        }
        let mut z0 = c.clone();
        let mut eq_z = eq_rows.transpose();
        if !(l.solve_lower_triangular_mut(&mut z0) && l.solve_lower_triangular_mut(&mut eq_z)) {
            return Self::Full { h: h.clone(), c: c.clone(), eq_rows, eq_rhs };
        }
        let eq_s = eq_z.tr_mul(&eq_z);
        let eq_r = -eq_z.tr_mul(&z0) - eq_rhs;
        Self::Schur { l, z0, eq_z, eq_s, eq_r }
    }

    /// The solution holding also `held` (rows) at `held_rhs`, and the held rows'
    /// multipliers; `None` when the rows are dependent (the system singular).
    fn solve(&self, held: &DMatrix<f64>, held_rhs: &DVector<f64>) -> Option<(DVector<f64>, DVector<f64>)> {
        let finite = |v: &DVector<f64>| v.iter().all(|x| x.is_finite());
        let k = held.nrows();
        match self {
            Self::Schur { l, z0, eq_z, eq_s, eq_r } => {
                let m = eq_z.ncols();
                let mut held_z = held.transpose();
                if !l.solve_lower_triangular_mut(&mut held_z) {
                    return None;
                }
                let mut s = DMatrix::zeros(m + k, m + k);
                s.view_mut((0, 0), (m, m)).copy_from(eq_s);
                let cross = held_z.tr_mul(eq_z);
                s.view_mut((m, 0), (k, m)).copy_from(&cross);
                s.view_mut((0, m), (m, k)).copy_from(&cross.transpose());
                s.view_mut((m, m), (k, k)).copy_from(&held_z.tr_mul(&held_z));
                let mut r = DVector::zeros(m + k);
                r.rows_mut(0, m).copy_from(eq_r);
                r.rows_mut(m, k).copy_from(&(-held_z.tr_mul(z0) - held_rhs));
                let mu = match s.clone().cholesky() {
                    Some(f) => f.solve(&r),
                    None => s.lu().solve(&r)?,
                };
                let mut x = -(z0 + eq_z * mu.rows(0, m) + &held_z * mu.rows(m, k));
                if !l.tr_solve_lower_triangular_mut(&mut x) {
                    return None;
                }
                (finite(&x) && finite(&mu)).then(|| (x, mu.rows(m, k).into_owned()))
            }
            Self::Full { h, c, eq_rows, eq_rhs } => {
                let (nv, m) = (h.nrows(), eq_rows.nrows());
                let n = nv + m + k;
                let mut kkt = DMatrix::zeros(n, n);
                let mut b = DVector::zeros(n);
                kkt.view_mut((0, 0), (nv, nv)).copy_from(h);
                b.rows_mut(0, nv).copy_from(&(-c));
                for (at, rows, rhs) in [(nv, eq_rows, eq_rhs), (nv + m, held, held_rhs)] {
                    let r = rows.nrows();
                    kkt.view_mut((at, 0), (r, nv)).copy_from(rows);
                    kkt.view_mut((0, at), (nv, r)).copy_from(&rows.transpose());
                    b.rows_mut(at, r).copy_from(rhs);
                }
                let solution = kkt.lu().solve(&b).filter(finite)?;
                Some((solution.rows(0, nv).into_owned(), solution.rows(nv + m, k).into_owned()))
            }
        }
    }
}

fn check(want: usize, got: usize) -> Result<(), IkError> {
    if got == want {
        Ok(())
    } else {
        Err(IkError::Size { got, want })
    }
}

fn settings(tolerance: f64) -> DefaultSettings<f64> {
    // Valid by construction (every field is within its range).
    // No presolve and no dropped zeros: both would forbid the data updates of [`Solver`].
    DefaultSettingsBuilder::default()
        .verbose(false)
        .presolve_enable(false)
        .input_sparse_dropzeros(false)
        .tol_gap_abs(tolerance)
        .tol_gap_rel(tolerance)
        .tol_feas(tolerance)
        .build()
        .unwrap_or_default()
}

/// 6-vector from a pose error: position (target - current), then the rotation vector taking
/// the current orientation to the target, world frame.
pub fn pose_error(current: &Isometry3<f64>, target: &Isometry3<f64>) -> Vector6<f64> {
    let dp = target.translation.vector - current.translation.vector;
    let dr: UnitQuaternion<f64> = target.rotation * current.rotation.inverse();
    let w = dr.scaled_axis();
    Vector6::new(dp.x, dp.y, dp.z, w.x, w.y, w.z)
}

/// CoM task: its velocity follows `velocity_ff` (m/s) plus `gain` (1/s) times the error.
pub fn com_task(
    kin: &Kinematics,
    jac: &mut Matrix3xX<f64>,
    target: &Point3<f64>,
    velocity_ff: &Vector3<f64>,
    gain: f64,
    weight: f64,
) -> Task {
    kin.com_jacobian_into(jac);
    let v = velocity_ff + (target - kin.com()) * gain;
    Task {
        jacobian: DMatrix::from_column_slice(3, jac.ncols(), jac.as_slice()),
        velocity: DVector::from_column_slice(v.as_slice()),
        weight,
    }
}

/// Frame pose task (position and orientation): twist `twist_ff` (linear, angular; world)
/// plus `gain` times the pose error.
pub fn frame_task(
    kin: &Kinematics,
    jac: &mut Matrix6xX<f64>,
    frame: usize,
    target: &Isometry3<f64>,
    twist_ff: &Vector6<f64>,
    gain: f64,
    weight: f64,
) -> Task {
    kin.frame_jacobian_into(frame, jac);
    let v = twist_ff + pose_error(&kin.frame_pose(frame), target) * gain;
    Task {
        jacobian: DMatrix::from_column_slice(6, jac.ncols(), jac.as_slice()),
        velocity: DVector::from_column_slice(v.as_slice()),
        weight,
    }
}

/// A contact held still at `target`: J qd = gain * pose error (the gain only removes
/// integration drift; 0 gives the paper's J qd = 0), the correction's linear and angular
/// parts capped at `max_speed` (m/s, rad/s). The cap binds only when the target is far from
/// the frame, as when the stabilizer holds a foot where its sensors say it landed and the
/// servos had lagged the command by centimetres: uncapped, such a jump asked the legs for
/// more than their joint speed limits and the QP had no solution.
pub fn contact(
    kin: &Kinematics,
    jac: &mut Matrix6xX<f64>,
    frame: usize,
    target: &Isometry3<f64>,
    gain: f64,
    max_speed: [f64; 2],
) -> Equality {
    // The frame task's rows with no feed-forward, held exactly instead of weighted.
    let mut t = frame_task(kin, jac, frame, target, &Vector6::zeros(), gain, 1.0);
    for (part, cap) in [(0, max_speed[0]), (3, max_speed[1])] {
        let n = t.velocity.rows(part, 3).norm();
        if n > cap {
            t.velocity.rows_mut(part, 3).scale_mut(cap / n);
        }
    }
    Equality { jacobian: t.jacobian, velocity: t.velocity }
}

/// Posture task on the joints flagged in `mask`: qd_j = gain (q_ref_j - q_j); the other
/// joints and the free-flyer are left to the other tasks.
pub fn posture_task(
    model: &RobotModel,
    q: &[f64],
    q_ref_joints: &[f64],
    mask: &[bool],
    gain: f64,
    weight: f64,
) -> Task {
    let rows: Vec<usize> = (0..model.joints().len()).filter(|&i| mask[i]).collect();
    let mut j = DMatrix::zeros(rows.len(), model.nv());
    let mut v = DVector::zeros(rows.len());
    for (r, &i) in rows.iter().enumerate() {
        j[(r, V_JOINTS + i)] = 1.0;
        v[r] = gain * (q_ref_joints[i] - q[Q_JOINTS + i]);
    }
    Task { jacobian: j, velocity: v, weight }
}

/// Orientation task on the free-flyer (the root link): its angular velocity, world frame,
/// follows `gain` times the rotation from its orientation to `target`.
pub fn base_orientation_task(
    kin: &Kinematics,
    jac: &mut Matrix6xX<f64>,
    target: &UnitQuaternion<f64>,
    gain: f64,
    weight: f64,
) -> Task {
    let base = *kin.link_pose(0);
    kin.point_jacobian_into(0, &Point3::from(base.translation.vector), jac);
    let w = (target * base.rotation.inverse()).scaled_axis() * gain;
    Task {
        jacobian: DMatrix::from_fn(3, jac.ncols(), |r, c| jac[(3 + r, c)]),
        velocity: DVector::from_column_slice(w.as_slice()),
        weight,
    }
}

/// A velocity damper keeping a leg off a step: writes its Jacobian row into `row` and
/// returns its bound. The clearance `near.clearance_m` may shrink no faster than `gain`
/// times its excess over `min_m` (so it never goes below `min_m`, and a clearance already
/// below it must grow), i.e. -n' J_p qd <= gain (d - d_min), with J_p the Jacobian of the
/// limb's nearest point and n the direction away from the step.
pub fn clearance(
    kin: &Kinematics,
    jac: &mut Matrix6xX<f64>,
    link: usize,
    near: &Nearest,
    min_m: f64,
    gain: f64,
    mut row: MatrixViewMut<f64, U1, Dyn, U1, Dyn>,
) -> f64 {
    kin.point_jacobian_into(link, &near.point, jac);
    for c in 0..jac.ncols() {
        row[c] = -(near.normal.x * jac[(0, c)] + near.normal.y * jac[(1, c)] + near.normal.z * jac[(2, c)]);
    }
    gain * (near.clearance_m - min_m)
}

/// §6.1's first-order velocity regulation: qd <= min(qd_max, K (q_max - q)) and
/// qd >= max(-qd_max, K (q_min - q)) for every joint, q_min being `lower_rad` (the model's
/// lower limits, or tighter ones the planner keeps: see [`super::motion::ik_lower_limits`]);
/// a joint already below its q_min is not pushed back, only kept from going further. The
/// free-flyer is unbounded.
pub fn joint_limits(
    model: &RobotModel,
    q: &[f64],
    lower_rad: &[f64],
    max_speed_rad_s: f64,
    gain: f64,
) -> Bounds {
    let nv = model.nv();
    let mut lower = DVector::from_element(nv, f64::NEG_INFINITY);
    let mut upper = DVector::from_element(nv, f64::INFINITY);
    for (i, jt) in model.joints().iter().enumerate() {
        let qi = q[Q_JOINTS + i];
        let vmax = max_speed_rad_s.min(jt.velocity_rad_s);
        upper[V_JOINTS + i] = vmax.min(gain * (jt.upper_rad - qi)).max(0.0);
        lower[V_JOINTS + i] = (-vmax).max(gain * (lower_rad[i] - qi)).min(0.0);
    }
    Bounds { lower, upper }
}

/// q advanced by velocity `qd` for `dt_s`: world translation, the base rotated about its own
/// axes (MuJoCo's free-joint convention), joints added.
pub fn integrate(q: &mut [f64], qd: &[f64], dt_s: f64) {
    for k in 0..3 {
        q[k] += qd[k] * dt_s;
    }
    let w = Vector3::new(qd[3], qd[4], qd[5]) * dt_s;
    let next = base_pose(q).rotation * UnitQuaternion::from_scaled_axis(w);
    set_base_rotation(q, &next);
    for (qi, vi) in q[Q_JOINTS..].iter_mut().zip(&qd[V_JOINTS..]) {
        *qi += vi * dt_s;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unconstrained_least_squares_is_exact() {
        // Two tasks on disjoint coordinates are each met exactly.
        let mut j1 = DMatrix::zeros(1, 3);
        j1[(0, 0)] = 2.0;
        let mut j2 = DMatrix::zeros(1, 3);
        j2[(0, 1)] = 1.0;
        let t = [
            Task { jacobian: j1, velocity: DVector::from_element(1, 4.0), weight: 1.0 },
            Task { jacobian: j2, velocity: DVector::from_element(1, -1.0), weight: 0.2 },
        ];
        let x = solve(3, &t, &[], &[], &[], 1e-9).unwrap();
        assert!((x[0] - 2.0).abs() < 1e-6 && (x[1] + 1.0).abs() < 1e-6 && x[2].abs() < 1e-6, "{x}");
    }

    #[test]
    fn equality_and_bounds_hold() {
        let t = [Task {
            jacobian: DMatrix::identity(2, 2),
            velocity: DVector::from_vec(vec![3.0, 3.0]),
            weight: 1.0,
        }];
        let e = [Equality {
            jacobian: DMatrix::from_row_slice(1, 2, &[1.0, 1.0]),
            velocity: DVector::from_element(1, 1.0),
        }];
        let b = [Bounds {
            lower: DVector::from_vec(vec![-10.0, -10.0]),
            upper: DVector::from_vec(vec![0.25, 10.0]),
        }];
        let x = solve(2, &t, &e, &[], &b, 0.0).unwrap();
        assert!((x[0] - 0.25).abs() < 1e-6 && (x[1] - 0.75).abs() < 1e-6, "{x}");
        let bad =
            [Bounds { lower: DVector::from_vec(vec![1.0, 0.0]), upper: DVector::from_vec(vec![0.0, 1.0]) }];
        assert_eq!(solve(2, &t, &[], &[], &bad, 0.0), Err(IkError::CrossedBounds(0)));
    }

    #[test]
    fn inequalities_hold_and_bind_only_when_they_must() {
        // Want x = (1, 2); x0 + x1 <= 1 binds, x0 - x1 <= 5 does not.
        let t = [Task {
            jacobian: DMatrix::identity(2, 2),
            velocity: DVector::from_vec(vec![1.0, 2.0]),
            weight: 1.0,
        }];
        let g = [Inequality {
            jacobian: DMatrix::from_row_slice(2, 2, &[1.0, 1.0, 1.0, -1.0]),
            bound: DVector::from_vec(vec![1.0, 5.0]),
        }];
        let x = solve(2, &t, &[], &g, &[], 1e-12).unwrap();
        // The projection of (1, 2) on x0 + x1 = 1 is (0, 1).
        assert!((x[0]).abs() < 1e-6 && (x[1] - 1.0).abs() < 1e-6, "{x}");
    }

    /// The active sets give the optimum clarabel gives, limits binding or not, tick after
    /// tick: a stream of QPs (a dense task whose wanted velocity turns, an equality,
    /// inequalities and bounds, the binding limits changing along the stream) solved by one
    /// kept solver with active sets against clarabel alone at a tight tolerance. Every
    /// equality and limit holds, and the active sets solve most of the stream themselves.
    #[test]
    fn active_sets_agree_with_the_interior_point_solver() {
        let n = 6;
        let mut seed = 7u64;
        let mut rnd = move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let jacobian = DMatrix::from_fn(n, n, |_, _| rnd());
        let e = [Equality {
            jacobian: DMatrix::from_fn(1, n, |_, _| rnd()),
            velocity: DVector::from_element(1, 0.1),
        }];
        let g = [Inequality {
            jacobian: DMatrix::from_fn(3, n, |_, _| rnd()),
            bound: DVector::from_fn(3, |_, _| 0.3 + 0.5 * rnd().abs()),
        }];
        let b = [Bounds { lower: DVector::from_element(n, -0.8), upper: DVector::from_element(n, 0.6) }];
        let phases: Vec<f64> = (0..n).map(|_| 3.0 * rnd()).collect();
        let mut kept = Solver::new(n, 1e-6).with_active_set(true);
        let mut full = Solver::new(n, 1e-6).with_active_set(true).with_full_kkt(true);
        let (mut binding, mut sets) = (0, std::collections::HashSet::new());
        const TICKS: usize = 300;
        for tick in 0..TICKS {
            let wanted = DVector::from_fn(n, |i, _| 2.5 * (0.05 * tick as f64 + phases[i]).sin());
            let t = [Task { jacobian: jacobian.clone(), velocity: wanted, weight: 1.0 }];
            let slow = Solver::with_tolerance(n, 1e-6, 1e-10).solve(&t, &e, &g, &b).unwrap();
            let fast = kept.solve(&t, &e, &g, &b).unwrap();
            assert!((&slow - &fast).amax() < 1e-6, "tick {tick}: {slow} against {fast}");
            // The Schur complement and the whole system's LU find the same optimum.
            let by_lu = full.solve(&t, &e, &g, &b).unwrap();
            assert!((&by_lu - &fast).amax() < 1e-9, "tick {tick}: {by_lu} by one LU against {fast}");
            assert!(
                (e[0].jacobian.row(0).tr_dot(&fast) - 0.1).abs() < 1e-9,
                "tick {tick}: the equality holds"
            );
            let excess = (&g[0].jacobian * &fast - &g[0].bound).max();
            assert!(excess < 1e-9, "tick {tick}: an inequality broken by {excess}");
            assert!(fast.iter().all(|v| (-0.8 - 1e-9..=0.6 + 1e-9).contains(v)), "tick {tick}: {fast}");
            let active: Vec<bool> = (0..n)
                .map(|i| fast[i] > 0.6 - 1e-7 || fast[i] < -0.8 + 1e-7)
                .chain((0..3).map(|r| g[0].jacobian.row(r).tr_dot(&fast) > g[0].bound[r] - 1e-7))
                .collect();
            binding += usize::from(active.contains(&true));
            sets.insert(active);
        }
        assert!(
            binding > TICKS / 2 && sets.len() >= 5,
            "{binding} ticks with a limit binding, {} sets",
            sets.len()
        );
        let by_clarabel = kept.interior_point_qps();
        assert!(by_clarabel < TICKS / 5, "clarabel solved {by_clarabel} of {TICKS}");
    }

    /// The objective's matrix taken over each row's nonzero entries is the dense `J'J`.
    #[test]
    fn the_sparse_gram_is_the_dense_product() {
        let mut seed = 3u64;
        let mut rnd = move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        // Rows of one, a few and every entry, as the posture, a foot's and the CoM's tasks.
        let j = DMatrix::from_fn(9, 12, |r, c| match r % 3 {
            0 if c == r => 1.0,
            1 if c % 4 == r % 4 => rnd(),
            2 => rnd(),
            _ => 0.0,
        });
        let mut h = DMatrix::identity(12, 12);
        add_gram_upper(&mut h, 0.7, &j, &mut Vec::new());
        h.fill_lower_triangle_with_upper_triangle();
        let dense = DMatrix::identity(12, 12) + j.tr_mul(&j) * 0.7;
        assert!((&h - &dense).amax() < 1e-14, "{h} against {dense}");
    }

    #[test]
    fn a_kept_solver_gives_what_a_fresh_one_gives() {
        let task = |v: [f64; 2], w: f64| Task {
            jacobian: DMatrix::from_row_slice(2, 2, &[1.0, 0.5, 0.0, 2.0]),
            velocity: DVector::from_vec(v.to_vec()),
            weight: w,
        };
        let eq = |v: f64| Equality {
            jacobian: DMatrix::from_row_slice(1, 2, &[1.0, -1.0]),
            velocity: DVector::from_element(1, v),
        };
        let bounds = |hi: f64| Bounds {
            lower: DVector::from_vec(vec![-1.0, -1.0]),
            upper: DVector::from_vec(vec![hi, 1.0]),
        };
        let ineq = |h: f64| Inequality {
            jacobian: DMatrix::from_row_slice(1, 2, &[0.0, 1.0]),
            bound: DVector::from_element(1, h),
        };
        let mut kept = Solver::new(2, 1e-9);
        // The same shape with new data (updated in place), then new shapes (rebuilt).
        let cases: [(Task, Vec<Equality>, Vec<Inequality>, f64); 5] = [
            (task([3.0, 3.0], 1.0), vec![eq(1.0)], vec![], 0.25),
            (task([-2.0, 0.5], 0.3), vec![eq(-0.2)], vec![], 0.8),
            (task([1.0, -1.0], 2.0), vec![], vec![], 0.1),
            (task([1.0, 3.0], 2.0), vec![], vec![ineq(0.3)], 0.9),
            (task([1.0, 2.0], 1.0), vec![], vec![ineq(-0.1)], 0.9),
        ];
        for (t, e, g, hi) in &cases {
            let b = [bounds(*hi)];
            let fresh = solve(2, std::slice::from_ref(t), e, g, &b, 1e-9).unwrap();
            let got = kept.solve(std::slice::from_ref(t), e, g, &b).unwrap();
            // Both within the solver's tolerance (1e-7 on the gap) of the optimum.
            assert!((&fresh - &got).amax() < 1e-6, "kept {got} vs fresh {fresh}");
        }
    }

    #[test]
    fn pose_error_is_the_rotation_vector() {
        let a = Isometry3::identity();
        let b = Isometry3::new(Vector3::new(0.1, 0.0, 0.0), Vector3::new(0.0, 0.0, 0.3));
        let e = pose_error(&a, &b);
        assert!((e[0] - 0.1).abs() < 1e-12 && (e[5] - 0.3).abs() < 1e-12);
    }
}
