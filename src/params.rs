//! Every parameter of a climb, as a parameters file holds them (`run --params`, the MCAP
//! attachment `params.toml`): perception (§4, Table 1), the step map, planning (§6), the
//! simulated robot's servos and the checks that judge the execution, the robot's own
//! estimate of its pose, and the loop's own settings. Fields left out keep their defaults; unknown fields are refused.

use crate::climb::{LoopParams, RunParams};
use crate::control::StabilizerParams;
use crate::estimate::EstimateParams;
use crate::perception::step_map::StepMapParams;
use crate::perception::surroundings::SurroundingsParams;
use crate::perception::PerceptionParams;
use crate::planning::PlanParams;
use crate::sim::checks::CheckParams;
use crate::sim::params::{ServoParams, SimParams};
use crate::sim::sensors::SensorParams;

/// Every parameter of a climb.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ClimbParams {
    /// Perception (§4, Table 1).
    pub perception: PerceptionParams,
    /// The step map (known steps merged with each new view).
    pub step_map: StepMapParams,
    /// What the lidar saw around the steps, kept for the body's clearance.
    pub surroundings: SurroundingsParams,
    /// Planning (§6).
    pub plan: PlanParams,
    /// The simulated robot's servos.
    pub servo: ServoParams,
    /// The simulated robot's force/torque sensors, IMU and encoders.
    pub sensors: SensorParams,
    /// The stabilizer between the plan and the servos.
    pub stabilizer: StabilizerParams,
    /// The checks.
    pub checks: CheckParams,
    /// The robot's own estimate of its pose (the loop's frame when enabled).
    pub estimate: EstimateParams,
    /// Loop settings.
    pub run: RunParams,
}

impl ClimbParams {
    /// The parts the loop uses.
    pub fn loop_params(&self) -> LoopParams<'_> {
        LoopParams {
            perception: &self.perception,
            step_map: &self.step_map,
            surroundings: &self.surroundings,
            plan: &self.plan,
            run: &self.run,
        }
    }

    /// The parts the simulated robot uses.
    pub fn sim(&self) -> SimParams {
        SimParams {
            servo: self.servo.clone(),
            sensors: self.sensors.clone(),
            stabilizer: self.stabilizer.clone(),
            checks: self.checks.clone(),
            estimate: self.estimate.clone(),
            plan: self.plan.clone(),
            run: self.run.clone(),
        }
    }
}
