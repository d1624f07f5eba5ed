//! The robot's own control between the plan and the servos: a stabilizer that reads only
//! what the real HRP-4 can read (the ankles' force/torque sensors, the waist IMU, the joint
//! encoders) and corrects the planned motion so the measured contact wrenches follow a
//! distribution inside each foot's contact wrench cone. This is the paper's own future work
//! (§6.3: "a stabilizer that takes into account the static-stability polygon"), after Caron
//! et al., "Stair Climbing Stabilization of the HRP-4 Humanoid Robot using Whole-body
//! Admittance Control" (ICRA 2019).
//!
//! Nothing here knows the simulator: [`measurement`] is what the sensors read,
//! [`distribution`] splits the wanted net wrench over the feet (a QP in the cones of
//! `planning::contact`), [`admittance`] turns wrench errors into foot offsets, [`attitude`]
//! reads the base's tilt from the IMU, and [`stabilizer`] runs them at the control rate with
//! the QP IK of `planning::motion` online.

pub mod admittance;
pub mod attitude;
pub mod distribution;
pub mod measurement;
pub mod params;
pub mod stabilizer;

pub use measurement::{FootSensor, ForceTorque, Imu, Measurement, SoleWrench};
pub use params::StabilizerParams;
pub use stabilizer::{Stabilizer, TickRecord};
