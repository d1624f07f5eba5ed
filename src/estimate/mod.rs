//! The robot's own estimate of where it is: kinematic odometry anchored on the support foot.
//!
//! The real HRP-4 knows its floating base only through its joint encoders, its IMU and the
//! foot it stands on. The foot carrying most of the weight is the anchor: it is taken not to
//! move while loaded, and the base is placed from it through the legs' forward kinematics on
//! the encoders' angles. When the other foot takes over (its force sensor reads more than
//! `switch_load_fraction` of the feet's load), that foot becomes the anchor where the
//! kinematics put it, levelled (a loaded sole lies flat on a level tread: its roll and pitch
//! are the legs' error, not the tread's). Whatever the anchor's foot does unseen (a slip, a
//! sole rocking as it lands, a compliant ankle) becomes drift; the gravity the IMU measures
//! levels each view's cloud ([`crate::sensor::assemble`]), and the step map's registration
//! ([`Odometry::correct`]) takes out what the views show.
//!
//! MuJoCo-free: the simulated robot feeds it the encoders and the feet's loads, a real robot
//! would feed it the same.

use crate::robot::hrp4;
use crate::robot::model::{base_pose, set_base_pose, RobotError, RobotModel, Q_JOINTS};
use crate::robot::Kinematics;
use nalgebra::{Isometry3, UnitQuaternion};

/// Settings of the odometry (`[estimate]` of a params file).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EstimateParams {
    /// The loop plans from the robot's own estimate (this odometry), as the real robot must;
    /// `false` plans from the simulator's true pose (the bench's view before the estimate, a
    /// reference to compare against). The checks and the report judge in the true world
    /// either way. Default on: a rehearsal knows only what the robot's sensors say.
    pub enabled: bool,
    /// Share of the feet's summed normal load above which a foot becomes the anchor (over 0.5,
    /// at most 1; at 0.5 equal loads would swap the anchor at every step): 0.6 switches once the new foot clearly carries the robot, after the weight's
    /// transfer has begun and before the old foot lifts.
    pub switch_load_fraction: f64,
    /// Summed normal load under which the feet are not trusted to say which one stands (in
    /// the air, a fall), N: a tenth of HRP-4's 39 kg weight.
    pub min_load_n: f64,
}

impl Default for EstimateParams {
    fn default() -> Self {
        Self { enabled: true, switch_load_fraction: 0.6, min_load_n: 40.0 }
    }
}

impl EstimateParams {
    /// Refuses settings that cannot work, naming the field.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.switch_load_fraction > 0.5 && self.switch_load_fraction <= 1.0) {
            return Err(format!(
                "estimate.switch_load_fraction must be over 0.5 and at most 1, got {}",
                self.switch_load_fraction
            ));
        }
        if !(self.min_load_n >= 0.0 && self.min_load_n.is_finite()) {
            return Err(format!("estimate.min_load_n must be a finite load >= 0, got {}", self.min_load_n));
        }
        Ok(())
    }
}

/// Kinematic odometry: the anchor foot's pose in the estimate's frame and the legs' angles.
#[derive(Debug, Clone)]
pub struct Odometry<'m> {
    model: &'m RobotModel,
    soles: [usize; 2],
    anchor_foot: usize,
    anchor: Isometry3<f64>,
    p: EstimateParams,
    switches: usize,
}

impl<'m> Odometry<'m> {
    /// Odometry starting from configuration `q0` (where the robot stands when it is told
    /// where it is: the climb's frame), anchored on the right foot.
    pub fn new(model: &'m RobotModel, q0: &[f64], p: &EstimateParams) -> Result<Self, RobotError> {
        p.validate().map_err(RobotError::Invalid)?;
        let soles = hrp4::sole_frames(model)?;
        let mut kin = Kinematics::new(model);
        kin.update(q0).map_err(|e| RobotError::Invalid(e.to_string()))?;
        Ok(Self { model, soles, anchor_foot: 0, anchor: kin.frame_pose(soles[0]), p: p.clone(), switches: 0 })
    }

    /// The sole of `foot` (0 right, 1 left) in the base frame at joint angles `joints`.
    fn sole_in_base(&self, foot: usize, joints: &[f64]) -> Result<Isometry3<f64>, RobotError> {
        let mut q = vec![0.0; self.model.nq()];
        q[3] = 1.0;
        let n = joints.len().min(q.len() - Q_JOINTS);
        q[Q_JOINTS..Q_JOINTS + n].copy_from_slice(&joints[..n]);
        let mut kin = Kinematics::new(self.model);
        kin.update(&q).map_err(|e| RobotError::Invalid(e.to_string()))?;
        Ok(kin.frame_pose(self.soles[foot]))
    }

    /// The base's pose from the anchor foot through the legs at `joints`.
    fn base(&self, joints: &[f64]) -> Result<Isometry3<f64>, RobotError> {
        Ok(self.anchor * self.sole_in_base(self.anchor_foot, joints)?.inverse())
    }

    /// Takes the encoders' `joints` and the feet's normal loads `[right, left]`, N: the
    /// anchor moves to the other foot when it carries the robot.
    pub fn update(&mut self, joints: &[f64], normal_load_n: [f64; 2]) -> Result<(), RobotError> {
        let total = normal_load_n[0].max(0.0) + normal_load_n[1].max(0.0);
        let other = 1 - self.anchor_foot;
        if total < self.p.min_load_n || normal_load_n[other] < self.p.switch_load_fraction * total {
            return Ok(());
        }
        let landed = self.base(joints)? * self.sole_in_base(other, joints)?;
        let (_, _, yaw) = landed.rotation.euler_angles();
        self.anchor =
            Isometry3::from_parts(landed.translation, UnitQuaternion::from_euler_angles(0.0, 0.0, yaw));
        self.anchor_foot = other;
        self.switches += 1;
        Ok(())
    }

    /// The estimated configuration at the encoders' `joints`: the base from the anchor, the
    /// joints as read.
    pub fn configuration(&self, joints: &[f64]) -> Result<Vec<f64>, RobotError> {
        let base = self.base(joints)?;
        let mut q = vec![0.0; self.model.nq()];
        set_base_pose(&mut q, &base);
        let n = joints.len().min(q.len() - Q_JOINTS);
        q[Q_JOINTS..Q_JOINTS + n].copy_from_slice(&joints[..n]);
        Ok(q)
    }

    /// A correction of the estimate's frame (the step map's registration of a view): the
    /// anchor, and with it the base, moves by `delta` (applied in the estimate's frame).
    pub fn correct(&mut self, delta: &Isometry3<f64>) {
        self.anchor = delta * self.anchor;
    }

    /// Times the anchor moved to the other foot.
    pub fn switches(&self) -> usize {
        self.switches
    }
}

/// How far an estimated configuration is from the true one: the base's position and yaw.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct EstimateError {
    /// Distance between the estimated and the true base position, metres.
    pub position_m: f64,
    /// Of which vertical, metres (estimate minus truth).
    pub height_m: f64,
    /// Yaw of the estimate minus the truth's, radians (within +-pi).
    pub yaw_rad: f64,
}

impl EstimateError {
    /// The error of `estimate` against `truth` (configurations: base position, quaternion w x
    /// y z, joints); `None` when either is too short.
    pub fn of(estimate: &[f64], truth: &[f64]) -> Option<Self> {
        if estimate.len() < 7 || truth.len() < 7 {
            return None;
        }
        let heading = |q: &[f64]| base_pose(q).rotation.euler_angles().2;
        let d =
            nalgebra::Vector3::new(estimate[0] - truth[0], estimate[1] - truth[1], estimate[2] - truth[2]);
        let yaw = heading(estimate) - heading(truth);
        let yaw_rad = (yaw + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
        Some(Self { position_m: d.norm(), height_m: d.z, yaw_rad })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn standing(x_m: f64, yaw_deg: f64) -> (RobotModel, Vec<f64>) {
        let model = hrp4::model().expect("model");
        let feet = Isometry3::from_parts(
            nalgebra::Translation3::new(x_m, 0.1, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_deg.to_radians()),
        );
        let q = hrp4::half_sitting_at(&model, &feet).expect("standing");
        (model, q)
    }

    #[test]
    fn standing_still_the_estimate_is_the_start() {
        let (model, q) = standing(0.3, 20.0);
        let mut odo = Odometry::new(&model, &q, &EstimateParams::default()).expect("odometry");
        let joints = q[Q_JOINTS..].to_vec();
        for _ in 0..3 {
            odo.update(&joints, [200.0, 180.0]).expect("update");
        }
        let e = EstimateError::of(&odo.configuration(&joints).expect("q"), &q).expect("error");
        assert!(e.position_m < 1e-9 && e.yaw_rad.abs() < 1e-9, "{e:?}");
        assert_eq!(odo.switches(), 0, "neither foot carries 60 %");
    }

    /// The anchor moves to the foot that takes the load, where the legs put it (laid flat),
    /// and a correction moves the estimate by what it says.
    #[test]
    fn the_anchor_follows_the_loaded_foot_and_a_correction_moves_it() {
        let (model, q) = standing(0.0, 0.0);
        let mut odo = Odometry::new(&model, &q, &EstimateParams::default()).expect("odometry");
        let joints = q[Q_JOINTS..].to_vec();
        odo.update(&joints, [50.0, 330.0]).expect("update");
        assert_eq!(odo.switches(), 1);
        // Laid flat, the left sole moves the base by a few millimetres: the model's
        // half-sitting soles are a fraction of a degree from parallel.
        let e = EstimateError::of(&odo.configuration(&joints).expect("q"), &q).expect("error");
        assert!(e.position_m < 0.005 && e.yaw_rad.abs() < 1e-3, "{e:?}");
        let before = e;
        let delta = Isometry3::from_parts(
            nalgebra::Translation3::new(0.02, -0.01, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 0.01),
        );
        odo.correct(&delta);
        let e = EstimateError::of(&odo.configuration(&joints).expect("q"), &q).expect("error");
        assert!((e.yaw_rad - before.yaw_rad - 0.01).abs() < 1e-3 && e.position_m > 0.015, "{e:?}");
        for bad in [0.3, 0.5, 1.2, f64::NAN] {
            let p = EstimateParams { switch_load_fraction: bad, ..EstimateParams::default() };
            assert!(p.validate().is_err(), "{bad}");
        }
    }
}
