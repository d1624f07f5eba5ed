//! What a climb shows as it goes: an [`Observer`] sees every stage's data on the simulation's
//! clock (the sweep, the cloud, perception's result, the plan, the robot's state at each
//! physics step, the checks' violations, each cycle's report). The MCAP recorder implements
//! it; [`Nobody`] ignores everything.

use super::climb::CycleReport;
use super::execute::Violation;
use crate::cloud::PointCloud;
use crate::perception::{Perception, PlaneSegment};
use crate::planning::Plan;
use crate::scene::Scene;
use crate::sensor::Sweep;
use nalgebra::Vector3;

/// Receives a climb's data; every method defaults to doing nothing.
pub trait Observer {
    /// The world the climb runs in (once, at the start).
    fn scene(&mut self, _scene: &Scene) {}
    /// A sweep of the lidar, assembled at `stamp_s` (its rows carry their own stamps).
    fn sweep(&mut self, _stamp_s: f64, _sweep: &Sweep) {}
    /// The sweep's assembled cloud.
    fn cloud(&mut self, _stamp_s: f64, _cloud: &PointCloud) {}
    /// Perception's result on that cloud.
    fn perception(&mut self, _stamp_s: f64, _result: &Perception) {}
    /// Perception found nothing on that cloud (or failed), and why.
    fn perception_failed(&mut self, _stamp_s: f64, _why: &str) {}
    /// A plan made on `steps` (the known steps ahead), about to be executed from `stamp_s`.
    fn plan(&mut self, _stamp_s: f64, _steps: &[PlaneSegment], _plan: &Plan) {}
    /// The robot after a physics step.
    fn state(&mut self, _stamp_s: f64, _state: &RobotState) {}
    /// A check's violation.
    fn violation(&mut self, _stamp_s: f64, _v: &Violation) {}
    /// A cycle ended.
    fn cycle(&mut self, _stamp_s: f64, _c: &CycleReport) {}
}

/// The robot after a physics step, with what the checks measured at that instant.
#[derive(Debug, Clone)]
pub struct RobotState<'a> {
    /// Configuration (MuJoCo's qpos layout: base position, base quaternion w x y z, joints).
    pub q: &'a [f64],
    /// Each foot's resultant contact force, world frame, newtons (right, left).
    pub foot_forces_n: [Vector3<f64>; 2],
    /// The CoM's margin in the polygon of the feet in contact, metres (negative outside).
    pub margin_m: f64,
    /// The largest torque demand over its limit among the joints.
    pub max_torque_ratio: f64,
}

/// An observer that ignores everything.
pub struct Nobody;

impl Observer for Nobody {}

/// Several observers, each seeing everything (a recording and a viewer, say).
pub struct Each<'a>(pub Vec<&'a mut dyn Observer>);

impl Observer for Each<'_> {
    fn scene(&mut self, scene: &Scene) {
        self.0.iter_mut().for_each(|o| o.scene(scene));
    }
    fn sweep(&mut self, stamp_s: f64, sweep: &Sweep) {
        self.0.iter_mut().for_each(|o| o.sweep(stamp_s, sweep));
    }
    fn cloud(&mut self, stamp_s: f64, cloud: &PointCloud) {
        self.0.iter_mut().for_each(|o| o.cloud(stamp_s, cloud));
    }
    fn perception(&mut self, stamp_s: f64, result: &Perception) {
        self.0.iter_mut().for_each(|o| o.perception(stamp_s, result));
    }
    fn perception_failed(&mut self, stamp_s: f64, why: &str) {
        self.0.iter_mut().for_each(|o| o.perception_failed(stamp_s, why));
    }
    fn plan(&mut self, stamp_s: f64, steps: &[PlaneSegment], plan: &Plan) {
        self.0.iter_mut().for_each(|o| o.plan(stamp_s, steps, plan));
    }
    fn state(&mut self, stamp_s: f64, state: &RobotState) {
        self.0.iter_mut().for_each(|o| o.state(stamp_s, state));
    }
    fn violation(&mut self, stamp_s: f64, v: &Violation) {
        self.0.iter_mut().for_each(|o| o.violation(stamp_s, v));
    }
    fn cycle(&mut self, stamp_s: f64, c: &CycleReport) {
        self.0.iter_mut().for_each(|o| o.cycle(stamp_s, c));
    }
}
