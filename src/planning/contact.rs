//! A rectangular surface contact and its contact wrench cone (CWC, §6.2): the face form's 16
//! inequalities of Caron, Pham and Nakamura ("Stability of surface contacts for humanoid
//! robots", RSS 2015) and the span form (each sole corner with each edge of a four-sided
//! friction pyramid).
//!
//! Wrenches are 6-vectors (force, torque). A contact's wrench in the world is taken at the
//! world origin, so wrenches of several contacts add.

use nalgebra::{Isometry3, Point3, SMatrix, Vector3, Vector6};
use serde::Deserialize;

/// Why a contact was refused.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("invalid contact {index}: {reason}")]
pub struct ContactError {
    /// Position of the contact in its list.
    pub index: usize,
    /// What is wrong.
    pub reason: String,
}

/// A rectangular contact: a sole (or any flat patch) on a surface. Valid once built: finite
/// pose, positive half sizes, positive friction.
#[derive(Debug, Clone, PartialEq)]
pub struct Contact {
    pose: Isometry3<f64>,
    half_length_m: f64,
    half_width_m: f64,
    friction: f64,
}

/// The JSON form of a contact (`stairbench polygon`): centre, roll-pitch-yaw (radians), half
/// sizes (metres), friction coefficient.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactSpec {
    /// Centre of the rectangle, world frame, metres.
    pub center: [f64; 3],
    /// Orientation as roll, pitch, yaw, radians; the contact normal is the local z.
    #[serde(default)]
    pub rpy: [f64; 3],
    /// Half length along the local x, metres.
    pub half_length: f64,
    /// Half width along the local y, metres.
    pub half_width: f64,
    /// Friction coefficient (default 0.7).
    #[serde(default = "default_friction")]
    pub friction: f64,
}

fn default_friction() -> f64 {
    DEFAULT_FRICTION
}

/// Friction coefficient used when none is given (§6.2).
pub const DEFAULT_FRICTION: f64 = 0.7;

impl ContactSpec {
    /// The validated contact; `index` names it in errors.
    pub fn build(&self, index: usize) -> Result<Contact, ContactError> {
        let [x, y, z] = self.center;
        let [r, p, yw] = self.rpy;
        let pose = Isometry3::from_parts(
            nalgebra::Translation3::new(x, y, z),
            nalgebra::UnitQuaternion::from_euler_angles(r, p, yw),
        );
        Contact::new(pose, self.half_length, self.half_width, self.friction)
            .map_err(|reason| ContactError { index, reason })
    }
}

impl Contact {
    /// A contact at `pose` (normal = local z) with the given half sizes and friction.
    pub fn new(
        pose: Isometry3<f64>,
        half_length_m: f64,
        half_width_m: f64,
        friction: f64,
    ) -> Result<Self, String> {
        let finite = pose.translation.vector.iter().chain(pose.rotation.coords.iter()).all(|v| v.is_finite());
        if !finite {
            return Err("its pose is not finite".into());
        }
        if !(half_length_m > 0.0
            && half_width_m > 0.0
            && half_length_m.is_finite()
            && half_width_m.is_finite())
        {
            return Err(format!("half sizes must be positive, got {half_length_m} x {half_width_m} m"));
        }
        if !(friction > 0.0 && friction.is_finite()) {
            return Err(format!("friction must be positive, got {friction}"));
        }
        Ok(Self { pose, half_length_m, half_width_m, friction })
    }

    /// Pose of the contact frame (normal = local z).
    pub fn pose(&self) -> &Isometry3<f64> {
        &self.pose
    }

    /// Half length (local x), metres.
    pub fn half_length_m(&self) -> f64 {
        self.half_length_m
    }

    /// Half width (local y), metres.
    pub fn half_width_m(&self) -> f64 {
        self.half_width_m
    }

    /// Friction coefficient.
    pub fn friction(&self) -> f64 {
        self.friction
    }

    /// The four corners in the world frame, counter-clockwise about the normal.
    pub fn corners(&self) -> [Point3<f64>; 4] {
        let (x, y) = (self.half_length_m, self.half_width_m);
        [(x, -y), (x, y), (-x, y), (-x, -y)].map(|(a, b)| self.pose * Point3::new(a, b, 0.0))
    }

    /// Span form: 16 generators of the CWC (world wrenches at the origin), one per corner and
    /// friction-pyramid edge. Every contact wrench is a non-negative combination of them.
    pub fn span(&self) -> [Vector6<f64>; 16] {
        let mu = self.friction;
        // The edges of the pyramid |f_x| <= mu f_z, |f_y| <= mu f_z (the face form's).
        let edges = [(mu, mu), (mu, -mu), (-mu, mu), (-mu, -mu)]
            .map(|(a, b)| (self.pose.rotation * Vector3::new(a, b, 1.0)).normalize());
        let mut out = [Vector6::zeros(); 16];
        for (i, c) in self.corners().iter().enumerate() {
            for (k, e) in edges.iter().enumerate() {
                let t = c.coords.cross(e);
                out[4 * i + k] = Vector6::new(e.x, e.y, e.z, t.x, t.y, t.z);
            }
        }
        out
    }

    /// Face form in the contact frame: rows a with a . (f, tau) <= 0, the wrench taken at the
    /// contact's centre in its own frame (Caron et al. 2015, Eq. 13-16).
    pub fn local_faces(&self) -> SMatrix<f64, 16, 6> {
        let (x, y, mu) = (self.half_length_m, self.half_width_m, self.friction);
        let mut a = SMatrix::<f64, 16, 6>::zeros();
        let rows: [[f64; 6]; 8] = [
            [1.0, 0.0, -mu, 0.0, 0.0, 0.0],
            [-1.0, 0.0, -mu, 0.0, 0.0, 0.0],
            [0.0, 1.0, -mu, 0.0, 0.0, 0.0],
            [0.0, -1.0, -mu, 0.0, 0.0, 0.0],
            [0.0, 0.0, -y, 1.0, 0.0, 0.0],
            [0.0, 0.0, -y, -1.0, 0.0, 0.0],
            [0.0, 0.0, -x, 0.0, 1.0, 0.0],
            [0.0, 0.0, -x, 0.0, -1.0, 0.0],
        ];
        for (i, r) in rows.iter().enumerate() {
            a.set_row(i, &nalgebra::RowVector6::from_row_slice(r));
        }
        let mut i = 8;
        for s1 in [1.0, -1.0] {
            for s2 in [1.0, -1.0] {
                // tau_z >= -mu (X + Y) f_z + |Y f_x - mu tau_x| + |X f_y - mu tau_y|
                a.set_row(
                    i,
                    &nalgebra::RowVector6::new(s1 * y, s2 * x, -mu * (x + y), -s1 * mu, -s2 * mu, -1.0),
                );
                // tau_z <= mu (X + Y) f_z - |Y f_x + mu tau_x| - |X f_y + mu tau_y|
                a.set_row(
                    i + 1,
                    &nalgebra::RowVector6::new(s1 * y, s2 * x, -mu * (x + y), s1 * mu, s2 * mu, 1.0),
                );
                i += 2;
            }
        }
        a
    }

    /// Face form in the world: rows a with a . w <= 0 for the world wrench w at the origin.
    pub fn faces(&self) -> SMatrix<f64, 16, 6> {
        // Local wrench from world wrench: f_l = R^T f, tau_l = R^T (tau - p x f).
        let r = self.pose.rotation.to_rotation_matrix().into_inner();
        let p = self.pose.translation.vector;
        let px = p.cross_matrix();
        let mut m = SMatrix::<f64, 6, 6>::zeros();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&r.transpose());
        m.fixed_view_mut::<3, 3>(3, 0).copy_from(&(-(r.transpose() * px)));
        m.fixed_view_mut::<3, 3>(3, 3).copy_from(&r.transpose());
        self.local_faces() * m
    }
}
