//! What a climb shows as it goes: an [`Observer`] sees every stage's data on the simulation's
//! clock (the sweep, the cloud, perception's result, the plan, the robot's state at each
//! physics step, the checks' violations, each cycle's report). The MCAP recorder implements
//! it; [`Nobody`] ignores everything.

use super::climb::CycleReport;
use super::execute::Violation;
use crate::cloud::PointCloud;
use crate::perception::{Perception, PlaneSegment};
use crate::planning::Plan;
use crate::sensor::Sweep;
use nalgebra::Vector3;

/// Receives a climb's data; every method defaults to doing nothing.
pub trait Observer {
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
    /// The robot after a physics step: configuration (MuJoCo's qpos layout) and each
    /// foot's resultant contact force, world frame, newtons (right, left).
    fn state(&mut self, _stamp_s: f64, _q: &[f64], _foot_forces_n: &[Vector3<f64>; 2]) {}
    /// A check's violation.
    fn violation(&mut self, _stamp_s: f64, _v: &Violation) {}
    /// A cycle ended.
    fn cycle(&mut self, _stamp_s: f64, _c: &CycleReport) {}
}

/// An observer that ignores everything.
pub struct Nobody;

impl Observer for Nobody {}
