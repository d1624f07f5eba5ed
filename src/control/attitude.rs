//! The base's tilt from the waist IMU: a complementary filter on the direction of "up" in
//! the base's frame. The gyro carries it from tick to tick (up is fixed in the world, so in
//! a frame turning at w it turns at -w); the accelerometer's specific force (gravity's
//! reaction, plus the base's own acceleration, small in a quasi-static climb) pulls it back
//! with time constant `tilt_filter_time_s`, so neither the gyro's drift nor the walk's
//! accelerations last. The base's own acceleration, where the motion knows it (the commanded
//! base's, [`PointAcceleration`]), is taken off the specific force first
//! ([`TiltFilter::update_moving`]): a sideways shift of the CoM at 0.15 m/s^2 otherwise reads
//! as 0.9 deg of tilt for as long as it lasts. An estimate that keeps the base at its
//! commanded orientation misses what the body bends between its joints' set points and the
//! ground (a compliant ankle, servos yielding under load); the IMU does not.

use super::measurement::{Imu, GRAVITY_M_S2};
use nalgebra::{Point3, UnitQuaternion, Vector3};

/// Up in the base's frame, filtered.
#[derive(Debug, Clone, PartialEq)]
pub struct TiltFilter {
    up_base: Option<Vector3<f64>>,
    time_s: f64,
    accel_tolerance: f64,
    /// Time since its first reading, seconds.
    age_s: f64,
}

impl TiltFilter {
    /// A filter pulled toward the accelerometer with time constant `time_s` (seconds; 0
    /// takes each accelerometer reading as it is), by the readings whose magnitude is within
    /// `accel_tolerance` (a fraction) of gravity's: one farther off is mostly the body's own
    /// acceleration (a foot's impact, the robot set down) and says little of where up is; the
    /// gyro alone carries the filter over it. It starts on its first such reading and
    /// averages the readings while it is younger than `time_s` (each as much as the ones
    /// before it), so a filter started at rest is as good as its readings' mean from the
    /// start, not one reading's noise forgotten over `time_s`.
    pub fn new(time_s: f64, accel_tolerance: f64) -> Self {
        Self { up_base: None, time_s: time_s.max(0.0), accel_tolerance, age_s: 0.0 }
    }

    /// Takes the IMU's reading over the `dt_s` since the last: up in the base's frame
    /// (`None` while no reading has shown a direction: a zero or non-finite specific force,
    /// or one too far from gravity's magnitude).
    pub fn update(&mut self, imu: &Imu, dt_s: f64) -> Option<Vector3<f64>> {
        let near_g = (imu.accel_m_s2.norm() - GRAVITY_M_S2).abs() <= self.accel_tolerance * GRAVITY_M_S2;
        let measured =
            imu.accel_m_s2.try_normalize(1e-6).filter(|v| near_g && v.iter().all(|c| c.is_finite()));
        let gyro =
            if imu.gyro_rad_s.iter().all(|c| c.is_finite()) { imu.gyro_rad_s } else { Vector3::zeros() };
        self.up_base = match (self.up_base, measured) {
            (None, m) => m,
            (Some(up), m) => {
                let carried = UnitQuaternion::from_scaled_axis(-gyro * dt_s) * up;
                self.age_s += dt_s;
                let blend = dt_s / (self.time_s.min(self.age_s) + dt_s);
                let pulled = match m {
                    Some(m) if blend.is_finite() => carried + (m - carried) * blend,
                    _ => carried,
                };
                Some(
                    pulled.try_normalize(1e-9).filter(|v| v.iter().all(|c| c.is_finite())).unwrap_or(carried),
                )
            }
        };
        self.up_base
    }

    /// [`TiltFilter::update`] with the base's own acceleration, `base_accel_m_s2` (world
    /// axes), taken off the specific force, the base's orientation `base` (world from base)
    /// turning it into the IMU's axes: what is left is gravity's reaction alone.
    pub fn update_moving(
        &mut self,
        imu: &Imu,
        base_accel_m_s2: &Vector3<f64>,
        base: &UnitQuaternion<f64>,
        dt_s: f64,
    ) -> Option<Vector3<f64>> {
        let own = base.inverse() * base_accel_m_s2;
        let imu = match own.iter().all(|c| c.is_finite()) {
            true => Imu { accel_m_s2: imu.accel_m_s2 - own, ..*imu },
            false => *imu,
        };
        self.update(&imu, dt_s)
    }

    /// Up in the base's frame as filtered, unit (`None` before any reading).
    pub fn up_base(&self) -> Option<Vector3<f64>> {
        self.up_base
    }

    /// The base's tilt from upright, radians: the angle between its z axis and the filtered
    /// up (`None` before any reading).
    pub fn tilt_rad(&self) -> Option<f64> {
        self.up_base.map(|up| up.angle(&Vector3::z()))
    }

    /// The smallest rotation taking a base whose orientation is `believed` (world from base)
    /// to one where the filtered up is the world's +z: what the body leans beyond what the
    /// encoders and the commanded base say (identity before any reading).
    pub fn lean(&self, believed: &UnitQuaternion<f64>) -> UnitQuaternion<f64> {
        self.up_base
            .and_then(|up| UnitQuaternion::rotation_between(&(believed * up), &Vector3::z()))
            .unwrap_or_else(UnitQuaternion::identity)
    }

    /// The lean beyond what the encoders see, about a support sole: [`TiltFilter::lean`]
    /// of the base as the encoders hold it from that sole, the sole lying as `sole_lies`
    /// (as planned) and seen by the encoders at `sole_seen` under the commanded base
    /// `commanded` (all world from body; the commanded base cancels, as it only placed
    /// `sole_seen`). A servo that gives under load shows in its encoder and is not in it; a
    /// compliance between the encoders and the ground (an ankle bush, a sole's rubber) is.
    pub fn unseen_lean(
        &self,
        commanded: &UnitQuaternion<f64>,
        sole_seen: &UnitQuaternion<f64>,
        sole_lies: &UnitQuaternion<f64>,
    ) -> UnitQuaternion<f64> {
        self.lean(&(sole_lies * sole_seen.inverse() * commanded))
    }
}

/// The acceleration of a point from its positions at a steady period: the second difference
/// of the last three (zero until there are three).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PointAcceleration {
    last: Option<Point3<f64>>,
    before: Option<Point3<f64>>,
}

impl PointAcceleration {
    /// Takes the position `at`, `dt_s` after the last one: the acceleration, m/s^2.
    pub fn push(&mut self, at: &Point3<f64>, dt_s: f64) -> Vector3<f64> {
        let accel = match (self.last, self.before) {
            (Some(last), Some(before)) if dt_s > 0.0 => {
                (at - 2.0 * last.coords + before.coords).coords / (dt_s * dt_s)
            }
            _ => Vector3::zeros(),
        };
        (self.before, self.last) = (self.last, Some(*at));
        accel
    }
}

/// Where `point` is when the body leans by `lean` about `pivot` (the support sole's centre:
/// a compliant ankle bends at the ankle, a few centimetres above it, so this is off by the
/// lean times that height, about 2 mm at 0.02 rad).
pub fn leaning(point: &Point3<f64>, pivot: &Point3<f64>, lean: &UnitQuaternion<f64>) -> Point3<f64> {
    pivot + lean * (point - pivot)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at_rest(tilt: &UnitQuaternion<f64>) -> Imu {
        // Specific force at rest: +g along the world's up, seen in the base's frame.
        Imu { accel_m_s2: tilt.inverse() * Vector3::new(0.0, 0.0, 9.81), gyro_rad_s: Vector3::zeros() }
    }

    #[test]
    fn a_base_at_rest_reads_its_own_tilt() {
        let tilt = UnitQuaternion::from_euler_angles(0.03, -0.05, 0.4);
        let mut f = TiltFilter::new(0.5, 0.1);
        for _ in 0..10 {
            f.update(&at_rest(&tilt), 0.005);
        }
        // Believing the base level (same heading), the lean found is the tilt's roll and pitch.
        let believed = UnitQuaternion::from_euler_angles(0.0, 0.0, 0.4);
        let lean = f.lean(&believed);
        let corrected = lean * believed;
        assert!((corrected * f.up_base.unwrap() - Vector3::z()).norm() < 1e-9);
        let true_tilt = (tilt * Vector3::z()).angle(&Vector3::z());
        assert!((lean.angle() - true_tilt).abs() < 1e-9, "{} vs {true_tilt}", lean.angle());
        assert!((f.tilt_rad().unwrap() - true_tilt).abs() < 1e-9);
        // Believing the truth, no lean.
        assert!(f.lean(&tilt).angle() < 1e-9);
    }

    /// A level base shifting sideways at 0.3 m/s^2 (its positions' second difference): the
    /// specific force leans 1.75 deg from up, which the plain filter takes for tilt; with the
    /// base's acceleration taken off it reads level. Turned 40 deg about the vertical, the
    /// world's acceleration is carried into the IMU's axes.
    #[test]
    fn the_bases_own_acceleration_is_not_taken_for_tilt() {
        let (dt, a) = (0.005, Vector3::new(0.0, 0.3, 0.0));
        let base = UnitQuaternion::from_euler_angles(0.0, 0.0, 40f64.to_radians());
        let imu = Imu {
            accel_m_s2: base.inverse() * (a + Vector3::new(0.0, 0.0, 9.81)),
            gyro_rad_s: Vector3::zeros(),
        };
        let mut history = PointAcceleration::default();
        let (mut plain, mut moving) = (TiltFilter::new(0.5, 0.1), TiltFilter::new(0.5, 0.1));
        for k in 0..400 {
            let t = k as f64 * dt;
            let accel = history.push(&Point3::from(a * t * t / 2.0), dt);
            if k >= 2 {
                assert!((accel - a).norm() < 1e-9, "{accel:?}");
            }
            plain.update(&imu, dt);
            moving.update_moving(&imu, &accel, &base, dt);
        }
        let leaned = (0.3f64 / 9.81).atan();
        assert!((plain.tilt_rad().unwrap() - leaned).abs() < 1e-3, "{:?}", plain.tilt_rad());
        assert!(moving.tilt_rad().unwrap() < 1e-4, "{:?}", moving.tilt_rad());
    }

    #[test]
    fn the_gyro_carries_a_turn_and_the_accelerometer_corrects_a_push() {
        let dt = 0.005;
        let mut f = TiltFilter::new(0.5, 0.1);
        f.update(&at_rest(&UnitQuaternion::identity()), dt);
        // Pitching at 0.1 rad/s for 1 s, the accelerometer agreeing: up follows the turn.
        let rate = Vector3::new(0.0, 0.1, 0.0);
        for i in 1..=200 {
            let tilt = UnitQuaternion::from_scaled_axis(rate * (i as f64 * dt));
            f.update(&Imu { gyro_rad_s: rate, ..at_rest(&tilt) }, dt);
        }
        let tilt = UnitQuaternion::from_scaled_axis(rate * 1.0);
        assert!(f.lean(&tilt).angle() < 1e-3, "{}", f.lean(&tilt).angle());
        // A sideways push of 1 m/s^2 for 0.1 s while still: moves up by far less than the
        // 0.1 rad the accelerometer alone would say.
        let push =
            Imu { accel_m_s2: tilt.inverse() * Vector3::new(1.0, 0.0, 9.81), gyro_rad_s: Vector3::zeros() };
        for _ in 0..20 {
            f.update(&push, dt);
        }
        let lean = f.lean(&tilt).angle();
        assert!(lean > 0.005 && lean < 0.025, "{lean}");
        // Then at rest again for 3 s: back within 1 mrad.
        for _ in 0..600 {
            f.update(&at_rest(&tilt), dt);
        }
        assert!(f.lean(&tilt).angle() < 1e-3);
    }

    /// A body pitched forward by 0.05 rad (about +y: its top toward +x), believed upright:
    /// a CoM 0.75 m above the sole leans forward by 0.75 sin 0.05 and down by 0.75 (1 - cos).
    #[test]
    fn a_forward_pitch_leans_the_com_forward() {
        let pitch = UnitQuaternion::from_euler_angles(0.0, 0.05, 0.0);
        let mut f = TiltFilter::new(2.0, 0.1);
        f.update(&at_rest(&pitch), 0.005);
        let lean = f.lean(&UnitQuaternion::identity());
        let pivot = Point3::new(0.3, -0.1, 0.2);
        let com = leaning(&(pivot + Vector3::new(0.0, 0.0, 0.75)), &pivot, &lean);
        let expected = pivot + Vector3::new(0.75 * 0.05f64.sin(), 0.0, 0.75 * 0.05f64.cos());
        assert!((com - expected).norm() < 1e-9, "{com} against {expected}");
    }

    /// A body bent 0.04 rad from its commanded base on a support sole lying on a sloped
    /// tread: where a servo gave (the encoders read the bend), none of the lean is unseen;
    /// where an ankle bush between the encoders and the sole gave, all of it is. The lean
    /// against the commanded base counts both.
    #[test]
    fn the_unseen_lean_is_what_the_encoders_do_not_read() {
        // About an axis off the world's, on a sloped tread, the base commanded tilted.
        let bend = UnitQuaternion::from_scaled_axis(Vector3::new(0.3, 1.0, 0.2).normalize() * 0.04);
        let commanded = UnitQuaternion::from_euler_angles(0.02, 0.0, 0.3);
        let tread = UnitQuaternion::from_euler_angles(0.0, 0.05, 0.1);
        let truly = bend * commanded;
        let mut f = TiltFilter::new(0.5, 0.1);
        f.update(&at_rest(&truly), 0.005);
        // The servo gave: the encoders read the joints as they are, the base truly where
        // the IMU has it; put under the commanded base, the sole lies off the tread.
        let servo = f.unseen_lean(&commanded, &(commanded * truly.inverse() * tread), &tread);
        // The bush gave: the encoders read the joints as commanded, the sole on the tread.
        let bush = f.unseen_lean(&commanded, &tread, &tread);
        let whole = f.lean(&commanded);
        // What of the bend an up can show: its tilt (its turn about the vertical, none).
        let tilt = (bend * Vector3::z()).angle(&Vector3::z());
        assert!(servo.angle() < 1e-9, "{}", servo.angle());
        assert!((bush.angle() - tilt).abs() < 1e-9, "{} against {tilt}", bush.angle());
        assert!((whole.angle() - tilt).abs() < 1e-9, "{} against {tilt}", whole.angle());
    }

    #[test]
    fn no_direction_no_lean() {
        let mut f = TiltFilter::new(0.5, 0.1);
        assert!(f.update(&Imu::default(), 0.005).is_none());
        assert_eq!(f.lean(&UnitQuaternion::identity()), UnitQuaternion::identity());
    }
}
