//! The MuJoCo side of the bench: the compiled world and what is asked of it (ray casts,
//! frames), the simulated lidar as a sensor [`Source`](crate::sensor::Source), the simulated
//! HRP-4 with its checks as the loop's [`Executor`](crate::climb::Executor) in the body of
//! the scenario's `[plant]` ([`plant`]), and the two together on a scenario
//! ([`climb_scenario`], [`scan_scenario`]); a rehearsal on perceived steps ([`rehearsal`]).

pub mod box_rays;
pub mod checks;
pub mod emulator;
pub mod execute;
pub mod head_track;
pub mod lidar;
pub mod params;
pub mod plant;
pub mod rehearsal;
pub mod sensors;
pub mod world;

pub use execute::SimRobot;
pub use lidar::SimSource;
pub use params::SimParams;
pub use world::{SimError, World};

use crate::cancel::Cancel;
use crate::climb::{self, Bench, ClimbError, ClimbReport, LoopParams, Observer};
use crate::scenario::Scenario;
use crate::scene::Scene;
use crate::sensor::{SensorError, Sweep};
use plant::Plant;
use std::cell::RefCell;

/// Why a scenario's world could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum SetupError {
    /// The scenario is invalid.
    #[error(transparent)]
    Scenario(#[from] crate::scenario::ScenarioError),
    /// The world.
    #[error(transparent)]
    Sim(#[from] SimError),
    /// The robot model.
    #[error(transparent)]
    Robot(#[from] crate::robot::RobotError),
    /// The sensor.
    #[error(transparent)]
    Sensor(#[from] SensorError),
    /// The climb.
    #[error(transparent)]
    Climb(#[from] ClimbError),
}

/// Runs the closed loop on `scenario` in MuJoCo: its world, its lidar as the source, the
/// simulated HRP-4 as the executor, judged against the scenario's ground truth: the loop
/// under `p`, the robot under `sim` (a climb's parameters give both,
/// `crate::params::ClimbParams::loop_params` and `::sim`).
pub fn climb_scenario(
    scenario: &Scenario,
    p: LoopParams<'_>,
    sim: &SimParams,
    observer: &mut dyn Observer,
    cancel: &Cancel,
) -> Result<ClimbReport, SetupError> {
    let scene = Scene::from_scenario(scenario)?;
    let model = crate::robot::hrp4::model()?;
    let plant = Plant::of_scenario(&model, scenario);
    let world = RefCell::new(World::with_plant_options(&scene, &plant, &sim.physics.world_options())?);
    let track = RefCell::new(head_track::HeadTrack::new(&scenario.lidar));
    let mut source = SimSource::new(&world, &scenario.lidar, scenario.seed)?;
    debug_assert!(p.plan == &sim.plan && p.run == &sim.run, "the loop and the robot under one plan");
    let mut robot = SimRobot::new(&world, &model, &scene, sim)?;
    if sim.run.sweep_while_moving {
        source = source.with_track(&track);
        robot = robot.with_track(&track);
    }
    let bench = Bench { source: &mut source, robot: &mut robot, model: &model, truth: &scene };
    Ok(climb::run(bench, p, observer, cancel)?)
}

/// A scenario's world, scanned once by its lidar from the robot's start.
pub struct ScenarioScan {
    /// The scenario's scene (ground truth included).
    pub scene: Scene,
    /// The sweep.
    pub sweep: Sweep,
}

/// Builds the world of `scenario` (with the bench's robot, see [`World::for_scene`]) and
/// sweeps its lidar once (noise drawn from the scenario's seed); `progress(done_rows,
/// total_rows)` is called along the way.
pub fn scan_scenario(
    scenario: &Scenario,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<ScenarioScan, SetupError> {
    let scene = Scene::from_scenario(scenario)?;
    let world = World::for_scene(&scene)?;
    let sweep =
        lidar::head_lidar(&world, &scenario.lidar, scenario.seed)?.sweep_rows(&Cancel::never(), progress)?;
    Ok(ScenarioScan { scene, sweep })
}
