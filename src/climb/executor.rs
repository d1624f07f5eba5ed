//! What executes a plan for the loop ([`Executor`]); what an execution reports is
//! [`Execution`]. The simulated HRP-4 in MuJoCo is one executor; a rehearsal on a world
//! built from the perceived steps is another; a test's fake robot is a third.

use super::event::Observer;
use super::execution::Execution;
use super::outcome::Check;
use crate::cancel::Cancel;
use crate::planning::Plan;

/// How the robot came out of a settle: still up, down (a body that kept no balance while it
/// stood, after an execution or at the set-down, is a fall as much as one mid-step), or up
/// on a foot that slid (a body still moving when its plan ended, rocking back onto its feet).
#[derive(Debug, Clone, PartialEq)]
pub enum Standing {
    /// Up: neither dropped nor tilted past a fall's limits.
    Upright,
    /// Fallen while it stood, with what the fall check measured.
    Fell(Check),
    /// Up, but a sole slid on its tread while it stood farther than a contact may
    /// ([`Check::Slip`]: from where it stood when the settle began).
    Slid(Check),
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
    /// the simulated robot stands on until it is still); whether the robot stayed up, and on
    /// feet that did not slide.
    fn settle(&mut self, seconds: f64) -> Result<Standing, Self::Error>;

    /// Executes `plan` from the current state with every check; `observer` sees the state
    /// after every physics step. A cancelled `cancel` ends it at the next step.
    fn execute(
        &mut self,
        plan: &Plan,
        observer: &mut dyn Observer,
        cancel: &Cancel,
    ) -> Result<Execution, Self::Error>;
}
