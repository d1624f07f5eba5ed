//! Whether the robot is still, as it can tell: the speed of its base as its own estimate
//! places it, step to step. A plan starts from a body at rest, and a stand or a plan's last
//! instant lasts until the body is still (`RunParams::still_speed_m_s`); a real robot judges
//! that on what its encoders, feet and IMU tell its estimate, not on a simulator's state.
//!
//! What the estimate cannot see it cannot judge: a sway on compliance outside the joints (an
//! ankle bush) moves the base where the legs' kinematics do not (the IMU's tilt levels the
//! estimate only where `EstimateParams::imu_tilt` has it), as it would on the real robot.
//! MuJoCo-free.

use super::Odometry;
use nalgebra::Vector3;

/// The base's speed from the estimate's positions of it, one per instant.
#[derive(Debug, Clone)]
pub struct BaseSpeed {
    /// The last position and its instant, seconds.
    last: Option<(f64, Vector3<f64>)>,
    speed_m_s: f64,
}

impl Default for BaseSpeed {
    fn default() -> Self {
        Self::new()
    }
}

impl BaseSpeed {
    /// No position yet: the speed is unknown, taken as infinite (not still).
    pub fn new() -> Self {
        Self { last: None, speed_m_s: f64::INFINITY }
    }

    /// The estimate had the base at `position_m` at `stamp_s`; the speed since the last
    /// position, m/s (unchanged for a stamp not after the last, or a position not finite).
    pub fn follow(&mut self, stamp_s: f64, position_m: &Vector3<f64>) -> f64 {
        if !position_m.iter().all(|c| c.is_finite()) || !stamp_s.is_finite() {
            return self.speed_m_s;
        }
        match self.last {
            Some((t_s, p)) if stamp_s > t_s => {
                self.speed_m_s = (position_m - p).norm() / (stamp_s - t_s);
                self.last = Some((stamp_s, *position_m));
            }
            Some(_) => {}
            None => self.last = Some((stamp_s, *position_m)),
        }
        self.speed_m_s
    }

    /// [`BaseSpeed::follow`] with the base where `odometry` places it at the encoders'
    /// `joints` (unchanged where its kinematics fail).
    pub fn follow_estimate(&mut self, stamp_s: f64, odometry: &Odometry, joints: &[f64]) -> f64 {
        match odometry.base(joints) {
            Ok(base) => self.follow(stamp_s, &base.translation.vector),
            Err(_) => self.speed_m_s,
        }
    }

    /// The speed at the last position, m/s (infinite before two).
    pub fn speed_m_s(&self) -> f64 {
        self.speed_m_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The speed is the step between positions over the time between them; unknown (not
    /// still) until two are known; a repeated or earlier stamp, or a position not finite,
    /// changes nothing.
    #[test]
    fn the_speed_is_the_last_step_over_its_time() {
        let mut s = BaseSpeed::new();
        assert_eq!(s.follow(1.0, &Vector3::new(0.0, 0.0, 0.7)), f64::INFINITY);
        let v = s.follow(1.002, &Vector3::new(0.0, 0.00002, 0.7));
        assert!((v - 0.01).abs() < 1e-9, "{v}");
        assert_eq!(s.follow(1.002, &Vector3::new(5.0, 0.0, 0.7)), v);
        assert_eq!(s.follow(0.5, &Vector3::new(5.0, 0.0, 0.7)), v);
        assert_eq!(s.follow(1.004, &Vector3::new(f64::NAN, 0.0, 0.7)), v);
        let v = s.follow(1.003, &Vector3::new(0.0, 0.00002, 0.7));
        assert_eq!(v, 0.0);
        assert_eq!(s.speed_m_s(), 0.0);
    }
}
