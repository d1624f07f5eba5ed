//! The robot's belief of where its lidar head was along a sweep taken as it moved, smoothed
//! back from the sweep's end.
//!
//! The odometry places the base from the anchor sole, taken flat on its tread; a loaded sole
//! rocks on its edge under a weight shift (a few tenths of a degree in MuJoCo's soft contact,
//! as a rubber sole does), and the base's tilt through the legs errs by as much while the
//! robot moves: 0.3-0.6 deg at the head along a step-up's rows, 2-3 cm at 3 m of range. When
//! the sweep ends the robot stands still and its sole lies flat again. The gyro measures the
//! base's turn between any two instants to about 0.02 deg over a sweep's 6 s (its noise
//! integrated; its bias taken off as measured standing), so each row's base orientation is
//! the sweep's last one turned back by what the gyro measured since (a fixed-lag smoother, as
//! lidar odometry deskews a sweep with its IMU). The base is turned about the anchor sole,
//! which does not move while loaded: the legs' position of the base errs with the sole's rock
//! too. MuJoCo-free.

use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};

/// The robot's belief at one row's instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Belief {
    /// The base as the odometry has it.
    pub base: Isometry3<f64>,
    /// The head in the base (the encoders through the model's kinematics).
    pub head_in_base: Isometry3<f64>,
    /// The anchor sole's origin, where the odometry holds it.
    pub pivot: Point3<f64>,
    /// The base's orientation as the gyro integrates it, from any origin (the same along a
    /// sweep); `None` without a gyro (the belief is then taken as it is).
    pub turn: Option<UnitQuaternion<f64>>,
}

impl Belief {
    /// The head as the odometry alone has it.
    pub fn head(&self) -> Isometry3<f64> {
        self.base * self.head_in_base
    }
}

/// The heads along `path` (oldest first, the robot still at the last): each base oriented as
/// the last one, turned back by the gyro's turn between them, about its anchor sole.
pub fn smoothed_heads(path: &[Belief]) -> Vec<Isometry3<f64>> {
    let Some(Belief { base: last, turn: Some(turn_last), .. }) = path.last().copied() else {
        return path.iter().map(Belief::head).collect();
    };
    path.iter()
        .map(|b| {
            let Some(turn) = b.turn else { return b.head() };
            let rotation = last.rotation * turn_last.inverse() * turn;
            let delta = rotation * b.base.rotation.inverse();
            let at = b.pivot + delta * (b.base.translation.vector - b.pivot.coords);
            Isometry3::from_parts(at.into(), rotation) * b.head_in_base
        })
        .collect()
}

/// The gyro's readings integrated into the base's orientation, from the identity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GyroTurn(UnitQuaternion<f64>);

impl Default for GyroTurn {
    fn default() -> Self {
        Self(UnitQuaternion::identity())
    }
}

impl GyroTurn {
    /// A reading of `rate_rad_s` (base axes, its bias taken off) held for `dt_s`.
    pub fn add(&mut self, rate_rad_s: &Vector3<f64>, dt_s: f64) {
        self.0 *= UnitQuaternion::from_scaled_axis(rate_rad_s * dt_s);
    }

    /// The orientation so far.
    pub fn orientation(&self) -> UnitQuaternion<f64> {
        self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Translation3;

    /// A base swaying 3 deg about the anchor sole along a sweep, the odometry holding it
    /// upright (a rocked sole taken flat) but for the last instant: the gyro's turns, taken
    /// back from the last, give every head within a micrometre and a microradian of the
    /// truth; the odometry alone is off by centimetres.
    #[test]
    fn the_gyros_turns_back_from_the_sweeps_end_give_the_heads() {
        let pivot = Point3::new(0.2, -0.1, 0.0);
        let head_in_base =
            Isometry3::from_parts(Translation3::new(0.05, 0.0, 0.6), UnitQuaternion::identity());
        let upright = Isometry3::from_parts(Translation3::new(0.2, 0.0, 0.75), UnitQuaternion::identity());
        let n = 100;
        let dt_s = 0.025;
        let sway = |k: usize| 3f64.to_radians() * (std::f64::consts::PI * k as f64 / (n - 1) as f64).sin();
        // The true base: upright turned about the pivot by the sway (roll).
        let truth = |k: usize| {
            let r = UnitQuaternion::from_euler_angles(sway(k), 0.0, 0.0);
            let at = pivot + r * (upright.translation.vector - pivot.coords);
            Isometry3::from_parts(at.into(), r)
        };
        let mut gyro = GyroTurn::default();
        let mut path = Vec::new();
        for k in 0..n {
            if k > 0 {
                gyro.add(&Vector3::new((sway(k) - sway(k - 1)) / dt_s, 0.0, 0.0), dt_s);
            }
            let base = if k == n - 1 { truth(k) } else { upright };
            path.push(Belief { base, head_in_base, pivot, turn: Some(gyro.orientation()) });
        }
        let heads = smoothed_heads(&path);
        let mut odometry_off_m = 0.0f64;
        for (k, (head, b)) in heads.iter().zip(&path).enumerate() {
            let true_head = truth(k) * head_in_base;
            assert!((head.translation.vector - true_head.translation.vector).norm() < 1e-6, "row {k}");
            assert!(head.rotation.angle_to(&true_head.rotation) < 1e-6, "row {k}");
            odometry_off_m =
                odometry_off_m.max((b.head().translation.vector - true_head.translation.vector).norm());
        }
        assert!(odometry_off_m > 0.03, "{odometry_off_m}");
        // Without a gyro, the belief as it is.
        let plain: Vec<Belief> = path.iter().map(|b| Belief { turn: None, ..*b }).collect();
        assert_eq!(smoothed_heads(&plain), plain.iter().map(Belief::head).collect::<Vec<_>>());
    }
}
