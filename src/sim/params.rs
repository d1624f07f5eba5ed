//! What the simulated robot runs under ([`SimParams`]): its servos, force/torque sensors and
//! IMU, the stabilizer, the checks, its own estimate, the physics (its step, the soles'
//! friction time constant), and the plan's and
//! the loop's figures the execution needs. A climb's whole parameter set
//! (`crate::params::ClimbParams`) hands these down.

use super::checks::CheckParams;
use super::sensors::SensorParams;
use crate::climb::RunParams;
use crate::control::StabilizerParams;
use crate::estimate::EstimateParams;
use crate::planning::PlanParams;
use crate::scene::mjcf::{WorldOptions, TIMESTEP_S};

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
    /// The physics engine's own settings.
    pub physics: PhysicsParams,
}

/// The physics engine's settings.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PhysicsParams {
    /// MuJoCo's time step, seconds. Default [`TIMESTEP_S`], 1 ms: the coarsest step tried at
    /// which what the checks measure has converged. At half of it `regress smoke`'s verdicts
    /// and figures agree with the default's; at twice it (MuJoCo's own default) physics costs half, but a
    /// foot being set down slides at its cone's edge and the friction ratios rise
    /// (BENCHMARKS.md, the physics step's row). For a convergence check of one's own: halve
    /// it and compare.
    pub step_s: f64,
    /// The time constant with which the soles' friction against the world holds them, seconds;
    /// `None` (the default) leaves MuJoCo's, the contacts' own 0.02 s. MuJoCo's friction has
    /// no stiction: it drives a contact's sliding speed toward zero through a reference
    /// acceleration `-b v`, `b = 2 / (dmax timeconst)`, so speed given to a sole bleeds off
    /// over about `dmax timeconst / 2` (9.5 ms at 0.02 s), and a sole rocking on its soft
    /// contact travels by what each rock gives it (the figures: CHANGELOG and BENCHMARKS).
    /// Set, each sole geom and world box becomes an explicit contact pair with this
    /// `solreffriction` (elliptic cones, as `scenes/world.xml` sets), all else as MuJoCo
    /// would make the contact itself; pairs skip the broadphase, each tested every step.
    /// At least twice the step (MuJoCo's bound for a stable reference). Opt-in: a faster
    /// hold raises the friction ratio a touchdown shows.
    pub sole_friction_timeconst_s: Option<f64>,
}

impl Default for PhysicsParams {
    fn default() -> Self {
        Self { step_s: TIMESTEP_S, sole_friction_timeconst_s: None }
    }
}

impl PhysicsParams {
    /// How a world is built to run under these (its boxes laid out as by default).
    pub fn world_options(&self) -> WorldOptions {
        WorldOptions {
            step_s: self.step_s,
            sole_friction_timeconst_s: self.sole_friction_timeconst_s,
            ..Default::default()
        }
    }

    /// The longest step allowed, seconds: the stabilizer's period at 200 Hz, which ticks
    /// between physics steps.
    pub const MAX_STEP_S: f64 = 0.005;
    /// The shortest, seconds.
    pub const MIN_STEP_S: f64 = 1e-5;
    /// The longest sole friction time constant, seconds (a sole that slides for seconds
    /// before it holds is no sole).
    pub const MAX_SOLE_FRICTION_TIMECONST_S: f64 = 1.0;

    /// Checks the step lies in [[`Self::MIN_STEP_S`], [`Self::MAX_STEP_S`]] and at most the
    /// stabilizer's period `stabilizer_period_s`, naming the field.
    pub fn validate(&self, stabilizer_period_s: f64) -> Result<(), String> {
        let most = Self::MAX_STEP_S.min(stabilizer_period_s);
        if !(self.step_s >= Self::MIN_STEP_S && self.step_s <= most) {
            return Err(format!(
                "physics.step_s = {} s: the physics step must lie between {} and {} s (the stabilizer ticks between steps)",
                self.step_s,
                Self::MIN_STEP_S,
                most
            ));
        }
        if let Some(tc) = self.sole_friction_timeconst_s {
            if !(tc >= 2.0 * self.step_s && tc <= Self::MAX_SOLE_FRICTION_TIMECONST_S) {
                return Err(format!(
                    "physics.sole_friction_timeconst_s = {tc} s: it must lie between twice the physics step ({} s) and {} s",
                    2.0 * self.step_s,
                    Self::MAX_SOLE_FRICTION_TIMECONST_S
                ));
            }
        }
        Ok(())
    }
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
