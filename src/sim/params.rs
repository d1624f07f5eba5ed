//! What the simulated robot runs under ([`SimParams`]): its servos, force/torque sensors and
//! IMU, the stabilizer, the checks, its own estimate, and the plan's and the loop's figures
//! the execution needs. A climb's whole parameter set (`crate::params::ClimbParams`) hands
//! these down.

use super::checks::CheckParams;
use super::sensors::SensorParams;
use crate::climb::RunParams;
use crate::control::StabilizerParams;
use crate::estimate::EstimateParams;
use crate::planning::PlanParams;

/// The simulated robot's parameters.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SimParams {
    /// The servos tracking q(t).
    pub servo: ServoParams,
    /// The force/torque sensors, IMU and encoders.
    pub sensors: SensorParams,
    /// The stabilizer between the plan and the servos.
    pub stabilizer: StabilizerParams,
    /// The checks judging every physics step.
    pub checks: CheckParams,
    /// The robot's own estimate of its pose.
    pub estimate: EstimateParams,
    /// The plan's parameters (the stabilizer's and the checks' polygons are built with them).
    pub plan: PlanParams,
    /// The loop's settings (how long the robot settles before a scan).
    pub run: RunParams,
}

/// How the servos track q(t).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ServoParams {
    /// Integral gain on each joint's tracking error, 1/s: the set point sent to the position
    /// servo is q_ref + K_i * integral(q_ref - q) dt, as a servo drive's integral term
    /// removes the sag a pure PD servo keeps under load (0 = pure PD).
    pub integral_gain_per_s: f64,
}

impl Default for ServoParams {
    fn default() -> Self {
        Self { integral_gain_per_s: 1.0 }
    }
}
