//! Every parameter of a climb, as a parameters file holds them (`run --params`, the MCAP
//! attachment `params.toml`): perception (§4, Table 1), the step map, planning (§6), the
//! simulated robot's servos and the checks that judge the execution, the robot's own
//! estimate of its pose, the loop's own settings and the simulation's physics (its step, the
//! soles' friction time constant). Fields
//! left out keep their defaults; unknown fields are refused.

use crate::climb::{LoopParams, RunParams};
use crate::control::StabilizerParams;
use crate::estimate::EstimateParams;
use crate::perception::step_map::StepMapParams;
use crate::perception::surroundings::SurroundingsParams;
use crate::perception::PerceptionParams;
use crate::planning::PlanParams;
use crate::sim::checks::CheckParams;
use crate::sim::params::{PhysicsParams, ServoParams, SimParams};
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
    /// The simulation's physics (its time step, the soles' friction time constant).
    pub physics: PhysicsParams,
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

    /// Checks the rules a parameters file's types do not hold (perception's, the step
    /// bound, the stabilizer's gains, the sensors' noise, the estimate's), naming the field.
    pub fn validate(&self) -> Result<(), String> {
        self.perception.validate().map_err(|e| e.to_string())?;
        self.plan.step.validate()?;
        self.stabilizer.validate()?;
        self.sensors.validate()?;
        self.estimate.validate()?;
        self.physics.validate(1.0 / self.stabilizer.rate_hz)
    }

    /// These parameters with `overrides` laid over them: a parameters file's fields as a
    /// TOML table, its tables merged key by key into these, its values replacing theirs
    /// (a suite case's `params`). Unknown fields and broken rules are refused.
    pub fn with_overrides(&self, overrides: &toml::Table) -> Result<ClimbParams, String> {
        fn lay(under: &mut toml::Table, over: &toml::Table) {
            for (k, v) in over {
                match (under.get_mut(k), v) {
                    (Some(toml::Value::Table(u)), toml::Value::Table(o)) => lay(u, o),
                    _ => {
                        under.insert(k.clone(), v.clone());
                    }
                }
            }
        }
        let mut merged = toml::Table::try_from(self).map_err(|e| e.to_string())?;
        lay(&mut merged, overrides);
        let params: ClimbParams =
            merged.try_into().map_err(|e: toml::de::Error| e.to_string().trim().replace('\n', " "))?;
        params.validate()?;
        Ok(params)
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
            physics: self.physics.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(text: &str) -> toml::Table {
        toml::from_str(text).unwrap()
    }

    #[test]
    fn overrides_replace_their_fields_and_keep_every_other() {
        let mut base = ClimbParams::default();
        base.run.max_cycles = 7;
        base.plan.ik.body_clearance_m = 0.05;
        let p = base
            .with_overrides(&table("[run]\nsweep_while_moving = true\n[plan.ik]\nbody_clearance_m = 0.04\n"))
            .unwrap();
        assert!(p.run.sweep_while_moving);
        assert_eq!(p.plan.ik.body_clearance_m, 0.04);
        assert_eq!(p.run.max_cycles, 7, "a field the overrides leave out keeps the base's value");
        let mut expected = base.clone();
        expected.run.sweep_while_moving = true;
        expected.plan.ik.body_clearance_m = 0.04;
        assert_eq!(p, expected, "nothing else moved");
        assert_eq!(base.with_overrides(&toml::Table::new()).unwrap(), base);
    }

    #[test]
    fn overrides_with_unknown_fields_or_wrong_types_are_refused() {
        let base = ClimbParams::default();
        let e = base.with_overrides(&table("[run]\nsweep_while_movin = true\n")).unwrap_err();
        assert!(e.contains("sweep_while_movin"), "{e}");
        let e = base.with_overrides(&table("[run]\nsweep_while_moving = 3\n")).unwrap_err();
        assert!(e.contains("bool") || e.contains("boolean"), "{e}");
        assert!(base.with_overrides(&table("run = 1\n")).is_err());
        let e = base.with_overrides(&table("[plan.ik]\nbody_clearance = 0.04\n")).unwrap_err();
        assert!(e.contains("plan.ik"), "the error names the table: {e}");
    }

    #[test]
    fn overrides_that_break_a_rule_of_any_part_are_refused() {
        let base = ClimbParams::default();
        for (text, field) in [
            ("[estimate]\nswitch_load_fraction = 0.2\n", "switch_load_fraction"),
            ("[sensors]\ngyro_bias_rad_s = [nan, 0.0, 0.0]\n", "gyro_bias_rad_s"),
            ("[perception]\nvoxel_resolution_m = -0.01\n", "voxel_resolution_m"),
            ("[physics]\nstep_s = 0.01\n", "physics.step_s"),
            ("[physics]\nstep_s = 0.0\n", "physics.step_s"),
            ("[physics]\nstep_s = nan\n", "physics.step_s"),
            // Above the stabilizer's period (2.5 ms at 400 Hz), within the engine's bound.
            ("[physics]\nstep_s = 0.004\n[stabilizer]\nrate_hz = 400.0\n", "physics.step_s"),
            // Under twice the step, over a second, and not a number.
            ("[physics]\nsole_friction_timeconst_s = 0.0015\n", "physics.sole_friction_timeconst_s"),
            ("[physics]\nsole_friction_timeconst_s = 2.0\n", "physics.sole_friction_timeconst_s"),
            ("[physics]\nsole_friction_timeconst_s = nan\n", "physics.sole_friction_timeconst_s"),
        ] {
            let e = base.with_overrides(&table(text)).expect_err(text);
            assert!(e.contains(field), "{text}: {e}");
        }
    }
}
