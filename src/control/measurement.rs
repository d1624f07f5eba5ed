//! What the robot's sensors read ([`Measurement`]) and the one conversion the stabilizer
//! needs from them: an ankle force/torque reading to the ground's wrench on the sole
//! ([`FootSensor::ground_wrench`]), with the foot's own weight and inertia (below the sensor)
//! removed.

use crate::robot::model::{RobotError, RobotModel};
use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};

pub use crate::robot::GRAVITY_M_S2;

/// A 6-axis force/torque reading in the sensor's frame: the force and torque (about the
/// sensor's origin) that the leg above applies to the foot below.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct ForceTorque {
    /// Force, N, sensor frame.
    pub force_n: Vector3<f64>,
    /// Torque about the sensor's origin, N m, sensor frame.
    pub torque_nm: Vector3<f64>,
}

/// An IMU reading in its own frame (at the waist).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct Imu {
    /// Specific force (acceleration minus gravity), m/s^2: +9.81 along up when at rest.
    pub accel_m_s2: Vector3<f64>,
    /// Angular velocity, rad/s.
    pub gyro_rad_s: Vector3<f64>,
}

/// Everything the robot measures at one instant.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Measurement {
    /// The ankles' force/torque sensors, `[right, left]`.
    pub ft: [ForceTorque; 2],
    /// The waist IMU.
    pub imu: Imu,
    /// The joint encoders, rad, in the model's joint order.
    pub joints_rad: Vec<f64>,
}

/// The ground's wrench on a sole, in the sole's frame (z its normal) at its centre.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct SoleWrench {
    /// Force, N (z: the normal force, positive when pressing).
    pub force_n: Vector3<f64>,
    /// Torque about the sole's centre, N m.
    pub torque_nm: Vector3<f64>,
}

impl SoleWrench {
    /// The wrench as (force, torque).
    pub fn to_vector(&self) -> nalgebra::Vector6<f64> {
        nalgebra::Vector6::new(
            self.force_n.x,
            self.force_n.y,
            self.force_n.z,
            self.torque_nm.x,
            self.torque_nm.y,
            self.torque_nm.z,
        )
    }

    /// From (force, torque).
    pub fn from_vector(w: &nalgebra::Vector6<f64>) -> Self {
        Self { force_n: w.fixed_rows::<3>(0).into(), torque_nm: w.fixed_rows::<3>(3).into() }
    }

    /// Centre of pressure in the sole's frame, metres (`None` below `min_force_n`).
    pub fn cop_m(&self, min_force_n: f64) -> Option<[f64; 2]> {
        (self.force_n.z > min_force_n)
            .then(|| [-self.torque_nm.y / self.force_n.z, self.torque_nm.x / self.force_n.z])
    }
}

/// An ankle's force/torque sensor: where it sits on the foot's link (at the link's origin,
/// as the simulator's site is) and what hangs below it.
#[derive(Debug, Clone, PartialEq)]
pub struct FootSensor {
    /// The link carrying the sole (and the sensor at its origin).
    pub link: usize,
    /// The sole frame in the link frame.
    pub sole_in_link: Isometry3<f64>,
    /// Mass below the sensor, kg.
    pub mass_kg: f64,
    /// Its centre of mass in the link frame.
    pub com_in_link: Point3<f64>,
}

impl FootSensor {
    /// The sensor of the foot carrying sole frame `sole`.
    pub fn of(model: &RobotModel, sole: usize) -> Result<Self, RobotError> {
        let frame = model
            .frames()
            .get(sole)
            .ok_or_else(|| RobotError::Unknown { kind: "frame", name: format!("#{sole}") })?;
        let link = &model.links()[frame.link];
        Ok(Self {
            link: frame.link,
            sole_in_link: frame.placement,
            mass_kg: link.mass_kg,
            com_in_link: Point3::from(link.com_m),
        })
    }

    /// The ground's wrench on the sole from a reading `ft`, the foot's link at orientation
    /// `link_rotation` (world) and its centre of mass accelerating at `accel_m_s2` (world):
    /// the leg, the ground and the foot's weight give the foot its mass times that
    /// acceleration. A foot starting down at 10 m/s^2 reads 6.6 N of ground (HRP-4's 0.66 kg
    /// foot) in the air if its acceleration is left out. Its rotational inertia is neglected.
    pub fn ground_wrench(
        &self,
        ft: &ForceTorque,
        link_rotation: &UnitQuaternion<f64>,
        accel_m_s2: &Vector3<f64>,
    ) -> SoleWrench {
        // Everything in the link's frame, about the sole's centre o. The foot's weight less
        // its inertia: what the leg and the ground must supply besides its acceleration.
        let apparent_gravity = Vector3::new(0.0, 0.0, -GRAVITY_M_S2) - accel_m_s2;
        let g_link = link_rotation.inverse() * (apparent_gravity * self.mass_kg);
        let o = self.sole_in_link.translation.vector;
        let force = -ft.force_n - g_link;
        let torque = -(ft.torque_nm + (-o).cross(&ft.force_n)) - (self.com_in_link.coords - o).cross(&g_link);
        let r = self.sole_in_link.rotation.inverse();
        SoleWrench { force_n: r * force, torque_nm: r * torque }
    }
}
