//! The robot's own estimate of where it is: kinematic odometry anchored on the support foot.
//!
//! The real HRP-4 knows its floating base only through its joint encoders, its IMU and the
//! foot it stands on. The foot carrying most of the weight is the anchor: it is taken not to
//! move while loaded, and the base is placed from it through the legs' forward kinematics on
//! the encoders' angles. When the other foot takes over (its force sensor reads more than
//! `switch_load_fraction` of the feet's load), that foot becomes the anchor where the
//! kinematics put it, levelled (a loaded sole lies flat on a level tread: its roll and pitch
//! are the legs' error, not the tread's). The anchor's sole turning about the vertical while
//! it stands (a loaded sole twisting under the swing's reaction, which the legs cannot see)
//! is the difference between the base's turn the IMU's gyro measures and the one the legs
//! give: [`Odometry::turn`] turns the anchor by it, with the gyro's bias taken from its
//! readings while the robot stood still ([`Odometry::stand`]). The anchor's sole tilting
//! while it stands (a loaded sole rocking on its edge under a fast motion, a tread that is
//! not level) is what the IMU's up differs by from the base's up through the legs:
//! [`Odometry::level`] tilts the anchor by it, about the sole's origin, as a
//! kinematic-inertial observer does (the legs give the base's position and heading, the IMU
//! its tilt), where [`EstimateParams::imu_tilt`] has it (off by default, its doc says why);
//! without it a rock of half a degree moves the base 6 mm through the legs' 0.7 m, unseen.
//! [`Odometry::follow`] takes both readings, as they come, while the robot moves or stands.
//! What else the anchor's foot does unseen (a slip, a compliant ankle) becomes drift; the
//! gravity the IMU measures levels each view's cloud ([`crate::sensor::assemble`]), and the
//! step map's registration ([`Odometry::correct`]) takes out what the views show.
//!
//! MuJoCo-free: the simulated robot feeds it the encoders, the feet's loads and the gyro, a
//! real robot would feed it the same.

pub mod path;
pub mod still;

use crate::robot::hrp4;
use crate::robot::kinematics::frame_in_base;
use crate::robot::model::{base_pose, set_base_pose, RobotError, RobotModel, Q_JOINTS};
use crate::robot::Kinematics;
use nalgebra::{Isometry3, UnitQuaternion, Vector3};

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
    /// The anchor's sole turns about the vertical by what the gyro (the base IMU's, less its
    /// bias as measured standing) sees the base turn beyond the legs' kinematics
    /// ([`Odometry::turn`]); `false` trusts the legs alone, the sole never turning while it
    /// stands. Default on: a loaded sole twists under the swing's reaction, which the
    /// encoders cannot see (regression `a-sole-twisting-under-load-turned-the-estimate`).
    pub gyro_yaw: bool,
    /// Seconds the robot stands still before the climb while its gyro's bias is measured
    /// (a start-up calibration, fed to [`Odometry::stand`]): 20 s leaves the default gyro's
    /// noise (0.005 rad/s a reading at 1 kHz) a bias error of about 3.5e-5 rad/s, 0.4 deg
    /// over a three-minute climb's integrated turns. With a gyro without bias (the simulated
    /// one's default) the calibration only adds that error; 0 takes no reading, the bias
    /// then taken as zero.
    pub gyro_calibration_s: f64,
    /// The anchor's sole tilts so the base's up through the legs is the IMU's
    /// ([`Odometry::level`]); `false` keeps it level while it stands (levelled at each
    /// switch), the legs alone giving the base's tilt. A loaded sole rocks on its edge under a
    /// fast motion, which the encoders cannot see. Default off: the planner takes the soles it
    /// starts from as flat on their treads, and a plan made from a base tilted as the IMU has
    /// it (a sole's compliance, the servos' sag) brings the CoM nearer its polygon's edge by
    /// more than the estimate gains at the default timing (measured at x 1.5 the quasi-static,
    /// then the default: CHANGELOG, 2026-12-01).
    pub imu_tilt: bool,
}

impl Default for EstimateParams {
    fn default() -> Self {
        Self {
            enabled: true,
            switch_load_fraction: 0.6,
            min_load_n: 40.0,
            gyro_yaw: true,
            gyro_calibration_s: 20.0,
            imu_tilt: false,
        }
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
        if !(self.gyro_calibration_s >= 0.0 && self.gyro_calibration_s.is_finite()) {
            return Err(format!(
                "estimate.gyro_calibration_s must be a finite time >= 0, got {}",
                self.gyro_calibration_s
            ));
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
    /// The base's orientation in the anchor sole's frame, through the legs, at the gyro's
    /// last reading (`None` before the first, and after one that was not finite).
    legs_rotation: Option<UnitQuaternion<f64>>,
    /// The gyro's readings while the robot stood still: their sum, rad/s, and count.
    standing: (Vector3<f64>, usize),
}

impl<'m> Odometry<'m> {
    /// Odometry starting from configuration `q0` (where the robot stands when it is told
    /// where it is: the climb's frame), anchored on the right foot.
    pub fn new(model: &'m RobotModel, q0: &[f64], p: &EstimateParams) -> Result<Self, RobotError> {
        p.validate().map_err(RobotError::Invalid)?;
        let soles = hrp4::sole_frames(model)?;
        let mut kin = Kinematics::new(model);
        kin.update(q0).map_err(|e| RobotError::Invalid(e.to_string()))?;
        Ok(Self {
            model,
            soles,
            anchor_foot: 0,
            anchor: kin.frame_pose(soles[0]),
            p: p.clone(),
            switches: 0,
            legs_rotation: None,
            standing: (Vector3::zeros(), 0),
        })
    }

    /// The sole of `foot` (0 right, 1 left) in the base frame at joint angles `joints`.
    fn sole_in_base(&self, foot: usize, joints: &[f64]) -> Result<Isometry3<f64>, RobotError> {
        frame_in_base(self.model, self.soles[foot], joints).map_err(|e| RobotError::Invalid(e.to_string()))
    }

    /// The base's pose from the anchor foot through the legs at `joints`.
    pub fn base(&self, joints: &[f64]) -> Result<Isometry3<f64>, RobotError> {
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
        let sole = self.sole_in_base(other, joints)?;
        let landed = self.base(joints)? * sole;
        let (_, _, yaw) = landed.rotation.euler_angles();
        self.anchor =
            Isometry3::from_parts(landed.translation, UnitQuaternion::from_euler_angles(0.0, 0.0, yaw));
        self.anchor_foot = other;
        self.switches += 1;
        // The legs now hold the base from the new anchor: the gyro's series goes on from there.
        if self.legs_rotation.is_some() {
            self.legs_rotation = Some(sole.rotation.inverse());
        }
        Ok(())
    }

    /// A reading of the base IMU's gyro, `gyro_rad_s` (base axes), the encoders reading
    /// `joints`, `since_last_s` after the series' last reading (`None` for its first, which
    /// only marks how the legs hold the base): the anchor's sole turns about the vertical
    /// through its origin by the base's turn the gyro measured (less its bias) beyond the
    /// legs' turn from the anchor. A reading that is not finite is skipped.
    pub fn turn(
        &mut self,
        joints: &[f64],
        gyro_rad_s: &Vector3<f64>,
        since_last_s: Option<f64>,
    ) -> Result<(), RobotError> {
        if !self.p.gyro_yaw {
            return Ok(());
        }
        if !gyro_rad_s.iter().all(|c| c.is_finite()) {
            // The next reading starts a series: the legs' turn until then is not the gyro's.
            self.legs_rotation = None;
            return Ok(());
        }
        let legs = self.sole_in_base(self.anchor_foot, joints)?.rotation.inverse();
        let base = self.anchor.rotation * legs;
        let last = match since_last_s {
            Some(dt_s) if dt_s.is_finite() && dt_s >= 0.0 => self.legs_rotation.map(|r| (r, dt_s)),
            _ => None,
        };
        // The base turns by the anchor's turn and the legs' (angular velocities add, here in
        // the base's axes): the anchor's is the gyro's less the legs', its part about the
        // vertical the sole's twist.
        if let Some((last, dt_s)) = last {
            let up = base.inverse() * Vector3::z();
            let legs_turn = (last.inverse() * legs).scaled_axis();
            let twist = up.dot(&((gyro_rad_s - self.gyro_bias_rad_s()) * dt_s - legs_turn));
            let twist = UnitQuaternion::from_euler_angles(0.0, 0.0, twist);
            self.anchor = Isometry3::from_parts(self.anchor.translation, twist * self.anchor.rotation);
        }
        self.legs_rotation = Some(legs);
        Ok(())
    }

    /// The IMU's up in the base's axes, `up_base` (its attitude filter's), the encoders
    /// reading `joints`: the anchor's sole tilts about its origin by the smallest rotation
    /// that makes the base's up through the legs the IMU's (what the sole rocks or lies
    /// tilted, which the legs cannot see). An up that is zero or not finite is skipped.
    pub fn level(&mut self, joints: &[f64], up_base: &Vector3<f64>) -> Result<(), RobotError> {
        if !self.p.imu_tilt || !up_base.iter().all(|c| c.is_finite()) {
            return Ok(());
        }
        let base = self.anchor.rotation * self.sole_in_base(self.anchor_foot, joints)?.rotation.inverse();
        if let Some(tilt) = UnitQuaternion::rotation_between(&(base * up_base), &Vector3::z()) {
            self.anchor = Isometry3::from_parts(self.anchor.translation, tilt * self.anchor.rotation);
        }
        Ok(())
    }

    /// The IMU's readings at one instant, the encoders reading `joints`: its attitude's up,
    /// where its filter has one ([`Odometry::level`]), then its gyro ([`Odometry::turn`],
    /// `since_last_s` after the series' last reading).
    pub fn follow(
        &mut self,
        joints: &[f64],
        up_base: Option<&Vector3<f64>>,
        gyro_rad_s: &Vector3<f64>,
        since_last_s: Option<f64>,
    ) -> Result<(), RobotError> {
        if let Some(up) = up_base {
            self.level(joints, up)?;
        }
        self.turn(joints, gyro_rad_s, since_last_s)
    }

    /// A reading of the gyro while the robot stands still: what it reads then is its bias
    /// (the mean of all such readings is taken off every reading [`Odometry::turn`] uses).
    pub fn stand(&mut self, gyro_rad_s: &Vector3<f64>) {
        if gyro_rad_s.iter().all(|c| c.is_finite()) {
            self.standing.0 += gyro_rad_s;
            self.standing.1 += 1;
        }
    }

    /// The gyro's bias as measured standing still, rad/s (zero before any reading).
    pub fn gyro_bias_rad_s(&self) -> Vector3<f64> {
        match self.standing.1 {
            0 => Vector3::zeros(),
            n => self.standing.0 / n as f64,
        }
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

    /// The anchor's sole as the odometry holds it (levelled where it became the anchor,
    /// then turned and tilted as it followed).
    pub fn anchor(&self) -> Isometry3<f64> {
        self.anchor
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
        Some(Self { position_m: d.norm(), height_m: d.z, yaw_rad: wrap_rad(yaw) })
    }
}

/// `angle_rad` within +-pi.
fn wrap_rad(angle_rad: f64) -> f64 {
    (angle_rad + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
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
        for bad in [-1.0, f64::INFINITY, f64::NAN] {
            let p = EstimateParams { gyro_calibration_s: bad, ..EstimateParams::default() };
            assert!(p.validate().is_err(), "{bad}");
        }
    }

    /// The true configuration of a robot standing as `q0` does, its right sole then turned by
    /// `twist_rad` about the vertical through its origin, its joints at `joints`: the base
    /// where the legs put it from that sole.
    fn twisted(model: &RobotModel, q0: &[f64], joints: &[f64], twist_rad: f64) -> Vec<f64> {
        let soles = hrp4::sole_frames(model).expect("soles");
        let mut kin = Kinematics::new(model);
        kin.update(q0).expect("kinematics");
        let sole0 = kin.frame_pose(soles[0]);
        let sole = Isometry3::from_parts(
            sole0.translation,
            UnitQuaternion::from_euler_angles(0.0, 0.0, twist_rad) * sole0.rotation,
        );
        let mut q = q0.to_vec();
        q[Q_JOINTS..].copy_from_slice(joints);
        set_base_pose(&mut q, &Isometry3::identity());
        kin.update(&q).expect("kinematics");
        set_base_pose(&mut q, &(sole * kin.frame_pose(soles[0]).inverse()));
        q
    }

    /// The gyro (base axes) of a base turning from `q0`'s orientation to `q1`'s in `dt_s`.
    fn gyro(q0: &[f64], q1: &[f64], dt_s: f64) -> Vector3<f64> {
        (base_pose(q0).rotation.inverse() * base_pose(q1).rotation).scaled_axis() / dt_s
    }

    /// The right sole, carrying the robot, twists 0.5 deg about the vertical while the right
    /// hip turns the base 2 deg on it and pitches it 15 deg (the base's axes then not the
    /// world's): the legs see the hip's turn only, the gyro both, and the estimate follows
    /// the sole by their difference about the vertical. Without the gyro it stays 0.5 deg
    /// off.
    #[test]
    fn a_sole_twisting_under_load_is_followed_by_the_gyro() {
        let (model, q0) = standing(0.3, 20.0);
        let hip = Q_JOINTS + model.joint_id("R_HIP_Y").expect("hip");
        let pitch = Q_JOINTS + model.joint_id("R_HIP_P").expect("hip pitch");
        let (steps, dt_s) = (500, 0.001);
        for gyro_yaw in [true, false] {
            let p = EstimateParams { gyro_yaw, ..EstimateParams::default() };
            let mut odo = Odometry::new(&model, &q0, &p).expect("odometry");
            let mut last = q0.clone();
            for k in 0..=steps {
                let f = k as f64 / steps as f64;
                let mut joints = q0[Q_JOINTS..].to_vec();
                joints[hip - Q_JOINTS] += f * 2f64.to_radians();
                joints[pitch - Q_JOINTS] += f * 15f64.to_radians();
                let q = twisted(&model, &q0, &joints, f * 0.5f64.to_radians());
                let since_last_s = (k > 0).then_some(dt_s);
                odo.turn(&joints, &gyro(&last, &q, dt_s), since_last_s).expect("turn");
                odo.update(&joints, [300.0, 80.0]).expect("update");
                last = q;
            }
            let e = EstimateError::of(&odo.configuration(&last[Q_JOINTS..]).expect("q"), &last).expect("e");
            match gyro_yaw {
                true => assert!(e.yaw_rad.abs() < 0.001f64.to_radians() && e.position_m < 1e-4, "{e:?}"),
                false => assert!((e.yaw_rad + 0.5f64.to_radians()).abs() < 0.01f64.to_radians(), "{e:?}"),
            }
        }
    }

    /// The robot, its joints still, rolls 0.5 deg outward on the right sole's outer edge (a
    /// loaded sole rocking): the legs see nothing, the IMU's up the roll. Levelled by it, the
    /// base is where it is but for the pivot (the edge, not the sole's origin: 0.07 m times
    /// the roll); then the left foot takes the load and becomes the anchor from there. The
    /// legs alone leave the base off by the roll times its height above the sole.
    #[test]
    fn a_sole_rocking_on_its_edge_is_followed_by_the_imu() {
        let (model, q0) = standing(0.2, 30.0);
        let joints = q0[Q_JOINTS..].to_vec();
        let soles = hrp4::sole_frames(&model).expect("soles");
        let mut kin = Kinematics::new(&model);
        kin.update(&q0).expect("kinematics");
        let sole = kin.frame_pose(soles[0]);
        let half_width_m = hrp4::sole_half_m(&model).expect("sole")[0][1];
        let edge = sole * nalgebra::Point3::new(0.0, -half_width_m, 0.0);
        let roll =
            UnitQuaternion::from_axis_angle(&(sole.rotation * Vector3::x_axis()), -0.5f64.to_radians());
        let rocked =
            nalgebra::Translation3::from(edge.coords) * roll * nalgebra::Translation3::from(-edge.coords);
        let mut q = q0.clone();
        set_base_pose(&mut q, &(rocked * base_pose(&q0)));
        let up_base = base_pose(&q).rotation.inverse() * Vector3::z();
        let pivot_m = half_width_m * 0.5f64.to_radians();
        for imu_tilt in [true, false] {
            let p = EstimateParams { imu_tilt, ..EstimateParams::default() };
            let mut odo = Odometry::new(&model, &q0, &p).expect("odometry");
            odo.level(&joints, &Vector3::new(f64::NAN, 0.0, 1.0)).expect("skipped");
            odo.level(&joints, &up_base).expect("level");
            let rocking = EstimateError::of(&odo.configuration(&joints).expect("q"), &q).expect("e");
            odo.update(&joints, [50.0, 330.0]).expect("switch");
            odo.level(&joints, &up_base).expect("level");
            let moved = EstimateError::of(&odo.configuration(&joints).expect("q"), &q).expect("e");
            let height_m = (base_pose(&q0).translation.vector - sole.translation.vector).z;
            match imu_tilt {
                true => {
                    for e in [rocking, moved] {
                        assert!(e.position_m < 1.1 * pivot_m + 1e-4, "{e:?}, pivot {pivot_m}");
                    }
                }
                false => assert!(rocking.position_m > 0.9 * height_m * 0.5f64.to_radians(), "{rocking:?}"),
            }
        }
    }

    /// A gyro reading 0.17-0.29 deg/s on a still robot: its bias, measured standing, is taken
    /// off, and ten seconds later the estimate has not turned; unmeasured, it turns the
    /// estimate by the bias over the time.
    #[test]
    fn the_gyros_bias_is_measured_standing_and_taken_off() {
        let (model, q) = standing(0.0, -30.0);
        let bias = Vector3::new(0.003, -0.004, 0.005);
        let joints = q[Q_JOINTS..].to_vec();
        for calibrated in [true, false] {
            let mut odo = Odometry::new(&model, &q, &EstimateParams::default()).expect("odometry");
            if calibrated {
                (0..100).for_each(|_| odo.stand(&bias));
                assert!((odo.gyro_bias_rad_s() - bias).norm() < 1e-12);
            }
            for k in 0..=1000 {
                odo.turn(&joints, &bias, (k > 0).then_some(0.01)).expect("turn");
            }
            let e = EstimateError::of(&odo.configuration(&joints).expect("q"), &q).expect("error");
            match calibrated {
                true => assert!(e.yaw_rad.abs() < 1e-9, "{e:?}"),
                false => assert!((e.yaw_rad - 0.05).abs() < 0.005, "{e:?}"),
            }
        }
    }
}
