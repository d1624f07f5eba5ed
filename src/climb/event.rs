//! What a climb shows as it goes: one [`Event`] type for every stage's data on the robot's
//! clock (the world, each sweep, its cloud, perception's result, each plan, the robot's state
//! at each physics step, each violation, each cycle's report). An [`Observer`] sees them all
//! and keeps what it wants; the MCAP recorder, the Rerun logger and the terminal table are
//! observers. A new event is a new variant: observers that ignore it need no change.

use super::outcome::Violation;
use super::report::CycleReport;
use crate::cloud::PointCloud;
use crate::control::TickRecord;
use crate::perception::{Perception, PerceptionError, PlaneSegment};
use crate::planning::Plan;
use crate::scene::Scene;
use crate::sensor::Sweep;
use nalgebra::Vector3;

/// The robot after a physics step, with what the checks measured at that instant.
#[derive(Debug, Clone)]
pub struct RobotState<'a> {
    /// Configuration (MuJoCo's qpos layout: base position, base quaternion w x y z, joints).
    pub q: &'a [f64],
    /// Each foot's resultant contact force, world frame, newtons (right, left).
    pub foot_forces_n: [Vector3<f64>; 2],
    /// The CoM's margin in the polygon of the feet in contact, metres (negative outside,
    /// `-inf` without a polygon).
    pub margin_m: f64,
    /// The largest torque demand over its limit among the joints.
    pub max_torque_ratio: f64,
    /// The base IMU's gyro as the robot reads it (its noise and bias), base axes, rad/s.
    pub gyro_rad_s: Vector3<f64>,
    /// Up in the base's axes as the robot's IMU attitude filter has it (unit; `None` before
    /// its first reading, or without one).
    pub up_base: Option<Vector3<f64>>,
    /// The lidar head's true pose in the world, where the executor knows it (a simulation;
    /// `None` on a real robot).
    pub head_to_world: Option<nalgebra::Isometry3<f64>>,
}

/// One thing that happened during a climb. `stamp_s` is the robot's clock (the simulation's
/// time, or the real robot's).
#[derive(Debug, Clone)]
pub enum Event<'a> {
    /// The world the climb runs in (once, at the start; the ground truth in simulation).
    Scene(&'a Scene),
    /// A sweep of the lidar, taken at `stamp_s` (its rows carry their own stamps).
    Sweep {
        /// When.
        stamp_s: f64,
        /// The rows and what assembles them.
        sweep: &'a Sweep,
    },
    /// The sweep's assembled cloud.
    Cloud {
        /// When.
        stamp_s: f64,
        /// The cloud.
        cloud: &'a PointCloud,
    },
    /// The view of that sweep taken, once the loop knows what came of it: into the
    /// surroundings from the configuration `q` the robot believed it had (after a
    /// registration's correction; the body at `q` is left out), and into the step map unless
    /// its look was set aside. Sent for every view taken, the ones no plan followed too (the
    /// top, a refusal, a look set aside).
    View {
        /// When (the sweep's stamp).
        stamp_s: f64,
        /// The configuration (MuJoCo's qpos layout).
        q: &'a [f64],
        /// The look was set aside to look again standing: its steps left the step map again
        /// (the look taken standing replaces them); its returns stayed in the surroundings.
        set_aside: bool,
    },
    /// Perception's result on that cloud.
    Perception {
        /// When.
        stamp_s: f64,
        /// What it found.
        result: &'a Perception,
    },
    /// Perception found nothing on that cloud (or failed), and why.
    PerceptionFailed {
        /// When.
        stamp_s: f64,
        /// Why.
        error: &'a PerceptionError,
    },
    /// A plan made on `steps` (the known steps ahead), about to be executed from `stamp_s`.
    Plan {
        /// When.
        stamp_s: f64,
        /// The plan's input.
        steps: &'a [PlaneSegment],
        /// The plan.
        plan: &'a Plan,
    },
    /// The robot after a physics step.
    State {
        /// When.
        stamp_s: f64,
        /// The state.
        state: &'a RobotState<'a>,
    },
    /// A tick of the stabilizer: the wrenches it wanted and measured, its foot offsets.
    Control {
        /// When.
        stamp_s: f64,
        /// The tick.
        tick: &'a TickRecord,
    },
    /// A check's violation (at `stamp_s`; the violation carries its time on the plan's clock).
    Violation {
        /// When.
        stamp_s: f64,
        /// What.
        violation: &'a Violation,
    },
    /// A cycle ended.
    Cycle {
        /// When.
        stamp_s: f64,
        /// Its report.
        report: &'a CycleReport,
    },
}

/// Receives a climb's events.
pub trait Observer {
    /// One event; ignore the ones of no interest.
    fn event(&mut self, event: &Event);
}

/// An observer that ignores everything.
pub struct Nobody;

impl Observer for Nobody {
    fn event(&mut self, _event: &Event) {}
}

/// Several observers, each seeing everything (a recording and a viewer, say).
pub struct Each<'a>(pub Vec<&'a mut dyn Observer>);

impl Observer for Each<'_> {
    fn event(&mut self, event: &Event) {
        self.0.iter_mut().for_each(|o| o.event(event));
    }
}

/// A closure as an observer (`Watch(|e| ...)`).
pub struct Watch<F: FnMut(&Event)>(pub F);

impl<F: FnMut(&Event)> Observer for Watch<F> {
    fn event(&mut self, event: &Event) {
        (self.0)(event)
    }
}
