//! The simulated robot's own sensors as the stabilizer reads them: the ankles' 6-axis
//! force/torque sensors and the waist IMU (MuJoCo `force`, `torque`, `accelerometer` and
//! `gyro` sensors on the sites of `robot::mjcf`), the joint encoders, each with a bias and
//! Gaussian noise from a seeded generator. The checks never read these: they judge from
//! MuJoCo's contact list.

use super::world::{SimError, World};
use crate::control::{ForceTorque, Imu, Measurement};
use crate::robot::mjcf::{ft_site, IMU_SITE};
use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// Noise and bias of the simulated sensors (`[sensors]` of a params file). Defaults are of
/// the order of a six-axis ankle sensor's and a MEMS IMU's data sheets.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SensorParams {
    /// Standard deviation of each force axis, N.
    pub force_noise_n: f64,
    /// Standard deviation of each torque axis, N m.
    pub torque_noise_nm: f64,
    /// Bias of the force axes (sensor frame), N, the same on both ankles.
    pub force_bias_n: [f64; 3],
    /// Bias of the torque axes, N m.
    pub torque_bias_nm: [f64; 3],
    /// Standard deviation of each accelerometer axis, m/s^2.
    pub accel_noise_m_s2: f64,
    /// Standard deviation of each gyro axis, rad/s.
    pub gyro_noise_rad_s: f64,
    /// Bias of each gyro axis, rad/s: none by default, like the force sensors'. A MEMS
    /// gyro's turn-on bias before calibration is of this order: Bosch's BMI088 data sheet
    /// gives a zero-rate offset of +-1 deg/s (0.017 rad/s); the robot measures it standing
    /// still ([`crate::estimate::Odometry::stand`]).
    pub gyro_bias_rad_s: [f64; 3],
    /// Standard deviation of each joint encoder, rad.
    pub encoder_noise_rad: f64,
    /// Seed of the noise.
    pub seed: u64,
}

impl Default for SensorParams {
    fn default() -> Self {
        Self {
            force_noise_n: 1.0,
            torque_noise_nm: 0.1,
            force_bias_n: [0.0; 3],
            torque_bias_nm: [0.0; 3],
            accel_noise_m_s2: 0.05,
            gyro_noise_rad_s: 0.005,
            gyro_bias_rad_s: [0.0; 3],
            encoder_noise_rad: 1e-4,
            seed: 0,
        }
    }
}

impl SensorParams {
    /// Refuses settings that cannot be drawn, naming the field: a standard deviation must be
    /// finite and at least zero, a bias finite.
    pub fn validate(&self) -> Result<(), String> {
        let sigmas = [
            ("force_noise_n", self.force_noise_n),
            ("torque_noise_nm", self.torque_noise_nm),
            ("accel_noise_m_s2", self.accel_noise_m_s2),
            ("gyro_noise_rad_s", self.gyro_noise_rad_s),
            ("encoder_noise_rad", self.encoder_noise_rad),
        ];
        if let Some((name, v)) = sigmas.iter().find(|(_, v)| !(v.is_finite() && *v >= 0.0)) {
            return Err(format!("sensors.{name} must be a finite deviation >= 0, got {v}"));
        }
        let biases = [
            ("force_bias_n", self.force_bias_n),
            ("torque_bias_nm", self.torque_bias_nm),
            ("gyro_bias_rad_s", self.gyro_bias_rad_s),
        ];
        if let Some((name, v)) = biases.iter().find(|(_, v)| !v.iter().all(|c| c.is_finite())) {
            return Err(format!("sensors.{name} must be finite, got {v:?}"));
        }
        Ok(())
    }
}

/// Where each sensor's values are in MuJoCo's sensor data.
pub struct SimSensors {
    /// Addresses: accelerometer, gyro, then force and torque of each sole, `[right, left]`.
    adr: [usize; 6],
    joints: usize,
    p: SensorParams,
    rng: ChaCha8Rng,
}

impl SimSensors {
    /// The sensors of `world`'s robot, whose soles are the frames `soles` (`[right, left]`).
    pub fn new(world: &World, soles: [&str; 2], p: &SensorParams) -> Result<Self, SimError> {
        p.validate().map_err(SimError::Params)?;
        let [r, l] = soles.map(ft_site);
        let names = [
            format!("{IMU_SITE}_accel"),
            format!("{IMU_SITE}_gyro"),
            format!("{r}_force"),
            format!("{r}_torque"),
            format!("{l}_force"),
            format!("{l}_torque"),
        ];
        let mut adr = [0; 6];
        for (a, n) in adr.iter_mut().zip(&names) {
            *a = world.sensor_adr(n)?;
        }
        Ok(Self {
            adr,
            joints: world.model().ffi().nu as usize,
            p: p.clone(),
            rng: ChaCha8Rng::seed_from_u64(p.seed),
        })
    }

    /// The same sensors drawing their noise from their own stream `stream` of the seed (a
    /// second reader of the same sensors, whose noise is not the first reader's again).
    pub fn with_stream(mut self, stream: u64) -> Self {
        self.rng.set_stream(stream);
        self
    }

    /// What the IMU reads now (after the last physics step).
    pub fn imu(&mut self, world: &World) -> Imu {
        let p = &self.p;
        Imu {
            accel_m_s2: noisy(world, &mut self.rng, self.adr[0], p.accel_noise_m_s2, [0.0; 3]),
            gyro_rad_s: noisy(world, &mut self.rng, self.adr[1], p.gyro_noise_rad_s, p.gyro_bias_rad_s),
        }
    }

    /// What the sensors read now (after the last physics step).
    pub fn read(&mut self, world: &World) -> Measurement {
        let imu = self.imu(world);
        let (p, rng) = (&self.p, &mut self.rng);
        let ft = [0, 1].map(|k| ForceTorque {
            force_n: noisy(world, rng, self.adr[2 + 2 * k], p.force_noise_n, p.force_bias_n),
            torque_nm: noisy(world, rng, self.adr[3 + 2 * k], p.torque_noise_nm, p.torque_bias_nm),
        });
        let enc =
            Normal::new(0.0, p.encoder_noise_rad.max(0.0)).unwrap_or(Normal::new(0.0, 0.0).expect("sigma 0"));
        let joints_rad = (0..self.joints).map(|a| world.joint_q(a) + enc.sample(&mut self.rng)).collect();
        Measurement { ft, imu, joints_rad }
    }
}

/// The three values at `adr` of `world`'s sensor data with `bias` and Gaussian noise of
/// standard deviation `sigma` drawn from `rng`.
fn noisy(world: &World, rng: &mut ChaCha8Rng, adr: usize, sigma: f64, bias: [f64; 3]) -> Vector3<f64> {
    let data = world.data().sensordata();
    let n = Normal::new(0.0, sigma.max(0.0)).unwrap_or(Normal::new(0.0, 0.0).expect("sigma 0"));
    Vector3::new(
        data[adr] + bias[0] + n.sample(rng),
        data[adr + 1] + bias[1] + n.sample(rng),
        data[adr + 2] + bias[2] + n.sample(rng),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A bias that is not a number, or a negative deviation, is refused by name (a NaN bias
    /// would make every reading skipped, silently).
    #[test]
    fn sensor_settings_that_cannot_be_drawn_are_refused_by_name() {
        assert!(SensorParams::default().validate().is_ok());
        let bad = SensorParams { gyro_bias_rad_s: [0.0, f64::NAN, 0.0], ..SensorParams::default() };
        assert!(bad.validate().is_err_and(|e| e.contains("gyro_bias_rad_s")));
        let bad = SensorParams { accel_noise_m_s2: -0.1, ..SensorParams::default() };
        assert!(bad.validate().is_err_and(|e| e.contains("accel_noise_m_s2")));
    }
}
