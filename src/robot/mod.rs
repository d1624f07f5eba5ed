//! The robot: its kinematic tree read from a URDF, floating-base kinematics and angular
//! momentum, the MJCF the simulator runs, and the HRP-4-class model the bench uses.

pub mod hrp4;
pub mod kinematics;
pub mod mjcf;
pub mod model;
pub mod momentum;

pub use kinematics::{ConfigError, Kinematics};
pub use model::{RobotError, RobotModel};

/// Standard gravity the bench's world and its models use, m/s^2 (the MJCF world's too).
pub const GRAVITY_M_S2: f64 = 9.81;
