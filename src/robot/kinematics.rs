//! Floating-base forward kinematics, frame Jacobians, centre of mass and CoM Jacobian, with
//! nalgebra. The IK calls these at every tick: [`Kinematics`] owns all its buffers, and after
//! construction `update`, `frame_jacobian_into` and `com_jacobian_into` allocate nothing.
//!
//! Conventions are MuJoCo's, so the two can be compared entry by entry: Jacobian rows 0-2
//! are the point's linear velocity and rows 3-5 the angular velocity, both in the world frame;
//! the free-flyer's columns are world translations (0-2) and rotations about the base's own
//! axes (3-5).

use super::model::{base_pose, RobotModel, Q_JOINTS, V_JOINTS};
use nalgebra::{Isometry3, Matrix3x6, Matrix3xX, Matrix6xX, Point3, Quaternion, UnitQuaternion, Vector3};

/// Why a configuration was refused.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ConfigError {
    /// No such frame.
    #[error("the robot has no frame {0}")]
    Frame(usize),
    /// Wrong length.
    #[error("configuration has {got} entries, the robot needs {want}")]
    Length {
        /// Entries given.
        got: usize,
        /// Entries needed.
        want: usize,
    },
    /// NaN or infinite entries, or a zero base quaternion.
    #[error("configuration entry {0} is not finite (or the base quaternion is zero)")]
    NotFinite(usize),
}

/// Kinematic state of one configuration of a [`RobotModel`].
#[derive(Debug, Clone)]
pub struct Kinematics<'m> {
    model: &'m RobotModel,
    /// World pose of each link frame.
    poses: Vec<Isometry3<f64>>,
    /// World joint axis of each link (unused for the root).
    axes: Vec<Vector3<f64>>,
    /// Mass times world CoM, summed over each link's subtree.
    subtree_moment: Vec<Vector3<f64>>,
    /// Mass of each link's subtree, kg.
    subtree_mass: Vec<f64>,
}

impl<'m> Kinematics<'m> {
    /// Buffers for `model`, at the identity base and zero joints.
    pub fn new(model: &'m RobotModel) -> Self {
        let n = model.links().len();
        let mut k = Self {
            model,
            poses: vec![Isometry3::identity(); n],
            axes: vec![Vector3::zeros(); n],
            subtree_moment: vec![Vector3::zeros(); n],
            subtree_mass: vec![0.0; n],
        };
        let mut q = vec![0.0; model.nq()];
        q[3] = 1.0;
        // The neutral configuration is valid by construction.
        let _ = k.update(&q);
        k
    }

    /// The model.
    pub fn model(&self) -> &'m RobotModel {
        self.model
    }

    /// Computes every link pose and the subtree masses and centres for configuration `q`
    /// (layout in [`super::model`]); the base quaternion is normalized.
    pub fn update(&mut self, q: &[f64]) -> Result<(), ConfigError> {
        let want = self.model.nq();
        if q.len() != want {
            return Err(ConfigError::Length { got: q.len(), want });
        }
        if let Some(i) = q.iter().position(|x| !x.is_finite()) {
            return Err(ConfigError::NotFinite(i));
        }
        if Quaternion::new(q[3], q[4], q[5], q[6]).norm() < 1e-12 {
            return Err(ConfigError::NotFinite(3));
        }
        let base = base_pose(q);
        for (i, link) in self.model.links().iter().enumerate() {
            match (link.parent, link.joint) {
                (Some(p), Some(j)) => {
                    let angle = q[Q_JOINTS + j];
                    let rot = UnitQuaternion::from_axis_angle(&link.axis, angle);
                    let joint_frame = self.poses[p] * link.placement;
                    self.axes[i] = joint_frame.rotation * link.axis.into_inner();
                    self.poses[i] = joint_frame * rot;
                }
                (Some(p), None) => self.poses[i] = self.poses[p] * link.placement,
                _ => self.poses[i] = base,
            }
            self.subtree_mass[i] = link.mass_kg;
            self.subtree_moment[i] = (self.poses[i] * Point3::from(link.com_m)).coords * link.mass_kg;
        }
        for (i, link) in self.model.links().iter().enumerate().rev() {
            if let Some(p) = link.parent {
                let (m, c) = (self.subtree_mass[i], self.subtree_moment[i]);
                self.subtree_mass[p] += m;
                self.subtree_moment[p] += c;
            }
        }
        Ok(())
    }

    /// World pose of link `link`.
    pub fn link_pose(&self, link: usize) -> &Isometry3<f64> {
        &self.poses[link]
    }

    /// World pose of every link frame, by link index.
    pub fn link_poses(&self) -> &[Isometry3<f64>] {
        &self.poses
    }

    /// World pose of frame `frame`.
    pub fn frame_pose(&self, frame: usize) -> Isometry3<f64> {
        let f = &self.model.frames()[frame];
        self.poses[f.link] * f.placement
    }

    /// Centre of mass of the whole robot, world frame.
    pub fn com(&self) -> Point3<f64> {
        Point3::from(self.subtree_moment[0] / self.subtree_mass[0])
    }

    /// The free-flyer's columns of the linear velocity of a point rigidly attached to the
    /// robot: world translations (identity), then rotations about the base's own axes
    /// (axis x (point - base origin)).
    fn base_linear_block(&self, point_world: &Point3<f64>) -> Matrix3x6<f64> {
        let base = &self.poses[0];
        let r = base.rotation.to_rotation_matrix();
        let d = point_world - Point3::from(base.translation.vector);
        let mut block = Matrix3x6::zeros();
        block.fixed_view_mut::<3, 3>(0, 0).fill_with_identity();
        for k in 0..3 {
            block.set_column(3 + k, &r.matrix().column(k).cross(&d));
        }
        block
    }

    /// 6 x nv Jacobian of the point `point_world` rigidly attached to link `link`: rows 0-2
    /// its linear velocity, rows 3-5 the link's angular velocity, world frame.
    pub fn point_jacobian_into(&self, link: usize, point_world: &Point3<f64>, out: &mut Matrix6xX<f64>) {
        out.fill(0.0);
        out.fixed_view_mut::<3, 6>(0, 0).copy_from(&self.base_linear_block(point_world));
        out.fixed_view_mut::<3, 3>(3, 3).copy_from(self.poses[0].rotation.to_rotation_matrix().matrix());
        let mut i = link;
        while let Some(p) = self.model.links()[i].parent {
            if let Some(j) = self.model.links()[i].joint {
                let a = &self.axes[i];
                // The joint's anchor is the origin of the link frame (joints sit at it).
                let lin = a.cross(&(point_world - Point3::from(self.poses[i].translation.vector)));
                let col = V_JOINTS + j;
                for row in 0..3 {
                    out[(row, col)] = lin[row];
                    out[(3 + row, col)] = a[row];
                }
            }
            i = p;
        }
    }

    /// 6 x nv Jacobian of frame `frame` (its origin's linear velocity and its angular
    /// velocity, world frame), written into `out`.
    pub fn frame_jacobian_into(&self, frame: usize, out: &mut Matrix6xX<f64>) {
        let f = &self.model.frames()[frame];
        let p = self.frame_pose(frame).translation.vector;
        self.point_jacobian_into(f.link, &Point3::from(p), out);
    }

    /// 3 x nv Jacobian of the centre of mass, written into `out`.
    pub fn com_jacobian_into(&self, out: &mut Matrix3xX<f64>) {
        out.fill(0.0);
        let total = self.subtree_mass[0];
        out.fixed_view_mut::<3, 6>(0, 0).copy_from(&self.base_linear_block(&self.com()));
        for (i, link) in self.model.links().iter().enumerate().skip(1) {
            if let Some(j) = link.joint {
                let m = self.subtree_mass[i];
                let c = self.subtree_moment[i] / m;
                let lin = self.axes[i].cross(&(c - self.poses[i].translation.vector)) * (m / total);
                for row in 0..3 {
                    out[(row, V_JOINTS + j)] = lin[row];
                }
            }
        }
    }

    /// A zeroed 6 x nv matrix for [`Self::frame_jacobian_into`].
    pub fn new_frame_jacobian(&self) -> Matrix6xX<f64> {
        Matrix6xX::zeros(self.model.nv())
    }

    /// A zeroed 3 x nv matrix for [`Self::com_jacobian_into`].
    pub fn new_com_jacobian(&self) -> Matrix3xX<f64> {
        Matrix3xX::zeros(self.model.nv())
    }
}

/// The pose of frame `frame` in the base's frame at joint angles `joints` (the joints' order,
/// a missing angle taken as 0), walking only the frame's chain to the root: what
/// [`Kinematics::frame_pose`] gives at the identity base, without the whole tree.
pub fn frame_in_base(
    model: &RobotModel,
    frame: usize,
    joints: &[f64],
) -> Result<Isometry3<f64>, ConfigError> {
    let f = model.frames().get(frame).ok_or(ConfigError::Frame(frame))?;
    let mut pose = f.placement;
    let mut link = Some(f.link);
    while let Some(i) = link {
        let l = &model.links()[i];
        let local = match (l.parent, l.joint) {
            (Some(_), Some(j)) => {
                let angle = joints.get(j).copied().unwrap_or(0.0);
                if !angle.is_finite() {
                    return Err(ConfigError::NotFinite(Q_JOINTS + j));
                }
                l.placement * UnitQuaternion::from_axis_angle(&l.axis, angle)
            }
            (Some(_), None) => l.placement,
            _ => Isometry3::identity(),
        };
        pose = local * pose;
        link = l.parent;
    }
    Ok(pose)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A frame's pose walked up its chain is the whole tree's at the identity base.
    #[test]
    fn a_frames_chain_gives_the_trees_pose() {
        let model = crate::robot::hrp4::model().expect("model");
        let mut q = vec![0.0; model.nq()];
        q[3] = 1.0;
        for (k, x) in q[Q_JOINTS..].iter_mut().enumerate() {
            *x = 0.3 * ((k as f64) * 1.7).sin();
        }
        let mut kin = Kinematics::new(&model);
        kin.update(&q).expect("kinematics");
        for frame in crate::robot::hrp4::sole_frames(&model).expect("soles") {
            let walked = frame_in_base(&model, frame, &q[Q_JOINTS..]).expect("chain");
            let tree = kin.frame_pose(frame);
            assert!((walked.translation.vector - tree.translation.vector).norm() < 1e-12);
            assert!(walked.rotation.angle_to(&tree.rotation) < 1e-12);
        }
        let sole = crate::robot::hrp4::sole_frames(&model).expect("soles")[0];
        let bad = vec![f64::NAN; model.joints().len()];
        assert!(frame_in_base(&model, sole, &bad).is_err(), "a sole's chain has joints");
    }
}
