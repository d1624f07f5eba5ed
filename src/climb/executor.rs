//! What executes a plan for the loop ([`Executor`]) and what an execution reports
//! ([`Execution`]). The simulated HRP-4 in MuJoCo is one executor; a rehearsal on a world
//! built from the perceived steps is another; a test's fake robot is a third.

use super::event::Observer;
use super::outcome::{CheckKind, SimWarning, Violation};
use crate::cancel::Cancel;
use crate::planning::{Foot, Plan};

/// A touchdown: where a foot landed against its target.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Touchdown {
    /// Which foot.
    pub foot: Foot,
    /// Position error, metres.
    pub error_m: f64,
    /// Yaw error, radians.
    pub yaw_error_rad: f64,
}

/// What one execution found.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Execution {
    /// Simulated time, seconds.
    pub sim_s: f64,
    /// Smallest CoM margin in the polygon of the real contacts, metres (`null` in JSON when
    /// no instant had a polygon).
    pub min_margin_m: f64,
    /// Largest torque demand over limit.
    pub max_torque_ratio: f64,
    /// The joint of `max_torque_ratio`.
    pub torque_joint: String,
    /// Largest speed over limit.
    pub max_speed_ratio: f64,
    /// The joint of `max_speed_ratio`.
    pub speed_joint: String,
    /// Every touchdown.
    pub touchdowns: Vec<Touchdown>,
    /// Largest horizontal slide of a sole in contact from where it came down, metres.
    pub max_slip_m: f64,
    /// Largest friction a loaded foot used: tangential over normal force, per sole axis
    /// (the pyramid's measure; the check's limit is the checks' friction coefficient).
    pub max_friction_ratio: f64,
    /// Violations (the first of each kind per second of simulation, to keep reports short).
    pub violations: Vec<Violation>,
    /// The robot fell (the execution stopped).
    pub fell: bool,
    /// MuJoCo warned during a step (the execution stopped): which warning.
    pub unstable: Option<SimWarning>,
    /// The execution was cancelled before its end.
    pub cancelled: bool,
    /// The stabilizer's cost, when it ran.
    pub control: Option<ControlCost>,
}

/// What the stabilizer cost over an execution.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ControlCost {
    /// Its ticks.
    pub ticks: usize,
    /// Their wall time, seconds.
    pub wall_s: f64,
}

impl Execution {
    /// An execution that has not run yet: no time, nothing measured.
    pub fn empty() -> Self {
        Self {
            sim_s: 0.0,
            min_margin_m: f64::INFINITY,
            max_torque_ratio: 0.0,
            torque_joint: String::new(),
            max_speed_ratio: 0.0,
            speed_joint: String::new(),
            touchdowns: Vec::new(),
            max_slip_m: 0.0,
            max_friction_ratio: 0.0,
            violations: Vec::new(),
            fell: false,
            unstable: None,
            cancelled: false,
            control: None,
        }
    }

    /// No check violated.
    pub fn pass(&self) -> bool {
        self.violations.is_empty() && !self.fell && self.unstable.is_none()
    }

    /// The largest touchdown position error, metres (0 without touchdowns).
    pub fn max_touchdown_error_m(&self) -> f64 {
        self.touchdowns.iter().map(|t| t.error_m).fold(0.0, f64::max)
    }

    /// The first violation of `kind`, if any.
    pub fn first(&self, kind: CheckKind) -> Option<&Violation> {
        self.violations.iter().find(|v| v.check.kind() == kind)
    }
}

/// Runs plans on a robot, checking every instant, and tells the loop where the robot is.
pub trait Executor {
    /// Why the executor itself failed (not a failed check: those are in the [`Execution`]).
    type Error: std::error::Error + Send + Sync + 'static;

    /// The robot's clock, seconds.
    fn now_s(&self) -> f64;

    /// The configuration as the robot knows it, in the kinematics' layout (base position,
    /// quaternion w x y z, joints): its own estimate where it keeps one, what the loop plans
    /// from and assembles its views with.
    fn configuration(&self) -> Vec<f64>;

    /// The true configuration where the robot's own differs from it and the truth is known
    /// (a simulator's, under the robot's estimate), for the report only: the steps climbed
    /// and the estimate's error. `None` where [`Executor::configuration`] is the truth, or
    /// no truth is known (a real robot): the report reads that.
    fn true_configuration(&self) -> Option<Vec<f64>> {
        None
    }

    /// Moves the robot's own estimate of its pose by `offset` (in the estimate's frame: the
    /// step map's registration of a view says where the view's frame lies against the known
    /// steps). `false`, and nothing moved, for a robot that keeps no estimate to correct (its
    /// pose is the simulator's truth, or a real robot's own business).
    fn correct(&mut self, _offset: &nalgebra::Isometry3<f64>) -> bool {
        false
    }

    /// Holds the current posture for at least `seconds` (the servos settle before a scan;
    /// the simulated robot stands on until it is still).
    fn settle(&mut self, seconds: f64) -> Result<(), Self::Error>;

    /// Executes `plan` from the current state with every check; `observer` sees the state
    /// after every physics step. A cancelled `cancel` ends it at the next step.
    fn execute(
        &mut self,
        plan: &Plan,
        observer: &mut dyn Observer,
        cancel: &Cancel,
    ) -> Result<Execution, Self::Error>;
}
