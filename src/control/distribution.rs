//! Wrench distribution: the net contact wrench the CoM needs, split over the feet in
//! contact by one small QP (Caron et al. 2019, §III-B), each foot's wrench inside its contact
//! wrench cone (the 16 faces of `planning::contact`), the tangential forces and ankle torques
//! as small as the net wrench allows, and the normal force shared as the pressure ratio says.
//!
//! Unknowns: each foot's ground wrench in its sole frame at its centre (6 per foot).
//!
//!   minimize  w_net ||sum_i G_i x_i - w||^2 + w_p (pressure ratio)^2
//!             + w_t sum_i ||x_i tangential||^2 + w_a sum_i ||x_i torque||^2
//!   subject to  F_i x_i <= 0  (each foot's cone)

use super::measurement::SoleWrench;
use super::params::StabilizerParams;
use crate::planning::contact::Contact;
use crate::planning::ik::{self, IkError, Inequality, Task};
use nalgebra::{DMatrix, DVector, Matrix6, Point3, Vector6};

/// A foot the distribution may load: its contact (sole pose, size, friction) and its wanted
/// share of the total normal force (0..1; the shares of all feet need not sum to 1, the
/// QP's pressure term uses the first foot's against the others').
#[derive(Debug, Clone)]
pub struct Support {
    /// The sole as a contact.
    pub contact: Contact,
    /// Wanted share of the normal force.
    pub share: f64,
}

/// Maps a sole-frame wrench at the sole's centre to the world wrench about `point`.
fn to_world(contact: &Contact, point: &Point3<f64>) -> Matrix6<f64> {
    let r = contact.pose().rotation.to_rotation_matrix().into_inner();
    let arm = (contact.pose().translation.vector - point.coords).cross_matrix();
    let mut g = Matrix6::zeros();
    g.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
    g.fixed_view_mut::<3, 3>(3, 0).copy_from(&(arm * r));
    g.fixed_view_mut::<3, 3>(3, 3).copy_from(&r);
    g
}

/// Why no distribution was found.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DistributionError {
    /// The QP failed (a solver status or a malformed problem).
    #[error(transparent)]
    Solver(#[from] IkError),
    /// No wrench in the feet's cones makes the wanted one: the closest misses it by this much
    /// (a CoM outside the support, a pull on the ground, no foot in contact).
    #[error("the wanted wrench is outside the feet's cones: the closest misses it by {force_n:.1} N and {torque_nm:.1} N m")]
    Infeasible {
        /// Force residual, N.
        force_n: f64,
        /// Torque residual, N m.
        torque_nm: f64,
    },
}

/// A residual of the net wrench above which a request counts as infeasible: this fraction of
/// the wanted force (the regularization alone leaves about 0.5 %), and this torque per
/// newton of it (metres: the CoP off by this much).
const INFEASIBLE_FORCE_FRACTION: f64 = 0.02;
const INFEASIBLE_ARM_M: f64 = 0.005;

/// The weight of each axis of a sole's wrench (force x y z, torque x y z) in the QP's
/// regularization: tangential forces and ankle torques, none on the normal force.
pub fn regularization_weights(p: &StabilizerParams) -> [f64; 6] {
    let (t, a) = (p.weight_tangential, p.weight_ankle_torque);
    [t, t, 0.0, a, a, a]
}

/// The feet's wrenches (sole frames, in `supports`' order) closest to producing `wanted`
/// (world force, and torque about `point`); an error when even the closest misses it.
pub fn distribute(
    supports: &[Support],
    wanted: &Vector6<f64>,
    point: &Point3<f64>,
    p: &StabilizerParams,
) -> Result<Vec<SoleWrench>, DistributionError> {
    Distributor::default().distribute(supports, wanted, point, p)
}

/// [`distribute`] for a stream of ticks: a solver kept for each number of feet, so a tick's
/// active-set guess starts from the cone faces that bound the last tick's wrenches, as
/// the IK's does. A fresh solver's guesses start from none, and where more faces bind than
/// its few guesses reach (a CoM near a sole's edge) the QP goes to the interior-point
/// solver, at about ten times the cost.
#[derive(Default)]
pub struct Distributor {
    /// For one foot, then two.
    solvers: [Option<ik::Solver>; 2],
    /// QPs the interior-point solver took.
    interior_point_qps: usize,
}

impl Distributor {
    /// How many of its QPs went to the interior-point solver (the others: active sets).
    pub fn interior_point_qps(&self) -> usize {
        self.interior_point_qps
    }

    /// As [`distribute`].
    pub fn distribute(
        &mut self,
        supports: &[Support],
        wanted: &Vector6<f64>,
        point: &Point3<f64>,
        p: &StabilizerParams,
    ) -> Result<Vec<SoleWrench>, DistributionError> {
        let n = supports.len();
        let force = wanted.fixed_rows::<3>(0).norm();
        if n == 0 {
            return match force > 0.0 {
                true => Err(DistributionError::Infeasible {
                    force_n: force,
                    torque_nm: wanted.fixed_rows::<3>(3).norm(),
                }),
                false => Ok(Vec::new()),
            };
        }
        let nv = 6 * n;
        let mut net = DMatrix::zeros(6, nv);
        let mut cones = Inequality { jacobian: DMatrix::zeros(16 * n, nv), bound: DVector::zeros(16 * n) };
        let mut regular = DMatrix::zeros(nv, nv);
        let diag = regularization_weights(p).map(f64::sqrt);
        let diag = Vector6::from_column_slice(&diag);
        for (i, s) in supports.iter().enumerate() {
            net.view_mut((0, 6 * i), (6, 6)).copy_from(&to_world(&s.contact, point));
            cones.jacobian.view_mut((16 * i, 6 * i), (16, 6)).copy_from(&s.contact.local_faces());
            regular.view_mut((6 * i, 6 * i), (6, 6)).copy_from(&Matrix6::from_diagonal(&diag));
        }
        let mut tasks = vec![
            Task {
                jacobian: net,
                velocity: DVector::from_column_slice(wanted.as_slice()),
                weight: p.weight_net_wrench,
            },
            Task { jacobian: regular, velocity: DVector::zeros(nv), weight: 1.0 },
        ];
        if n > 1 {
            // (1 - rho) f_z,0 - rho sum_{i>0} f_z,i = 0, each normal force along its sole's normal.
            let rho = supports[0].share.clamp(0.0, 1.0);
            let mut row = DMatrix::zeros(1, nv);
            row[(0, 2)] = 1.0 - rho;
            for i in 1..n {
                row[(0, 6 * i + 2)] = -rho;
            }
            tasks.push(Task { jacobian: row, velocity: DVector::zeros(1), weight: p.weight_pressure });
        }
        // More than two feet (not a biped's) get a solver of their own.
        let mut fresh = None;
        let solver = match self.solvers.get_mut(n - 1) {
            Some(kept) => kept.get_or_insert_with(|| ik::Solver::new(nv, 1e-9).with_active_set(true)),
            None => fresh.insert(ik::Solver::new(nv, 1e-9).with_active_set(true)),
        };
        let before = solver.interior_point_qps();
        let x = solver.solve(&tasks, &[], std::slice::from_ref(&cones), &[]);
        self.interior_point_qps += solver.interior_point_qps() - before;
        let x = x?;
        let wrenches: Vec<SoleWrench> =
            (0..n).map(|i| SoleWrench::from_vector(&x.fixed_rows::<6>(6 * i).into_owned())).collect();
        let contacts: Vec<&Contact> = supports.iter().map(|s| &s.contact).collect();
        let miss = net_wrench(&contacts, &wrenches, point) - wanted;
        let (force_n, torque_nm) = (miss.fixed_rows::<3>(0).norm(), miss.fixed_rows::<3>(3).norm());
        if force_n > INFEASIBLE_FORCE_FRACTION * force || torque_nm > INFEASIBLE_ARM_M * force {
            return Err(DistributionError::Infeasible { force_n, torque_nm });
        }
        Ok(wrenches)
    }
}

/// The world wrench (force, torque about `point`) of sole-frame wrenches on `contacts`.
pub fn net_wrench(contacts: &[&Contact], wrenches: &[SoleWrench], point: &Point3<f64>) -> Vector6<f64> {
    contacts.iter().zip(wrenches).map(|(c, w)| to_world(c, point) * w.to_vector()).sum()
}
