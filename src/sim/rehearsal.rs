//! A rehearsal before the real robot moves ([`rehearse`]): the steps perceived in one sweep of
//! the real sensor head rebuilt as a world, the whole climb planned from the robot standing in
//! half-sitting at its origin (with the loop's step map and the body kept off every surface
//! the sensor saw), and executed in MuJoCo on that world with every check.

use super::execute::{execute, settle};
use super::{SetupError, SimParams, World};
use crate::cancel::Cancel;
use crate::climb::{climbed, take_view, Event, Execution, LoopParams, Observer, ViewInput};
use crate::cloud::PointCloud;
use crate::perception::step_map::StepMap;
use crate::perception::surroundings::Surroundings;
use crate::perception::PlaneSegment;
use crate::planning::{Plan, PlanError, PlanRequest};
use crate::scene::{PerceivedTop, Scene};

/// What a rehearsal did.
#[derive(Debug)]
pub struct Rehearsal {
    /// The world of the perceived steps it ran on.
    pub scene: Scene,
    /// A step the step map left out for a closer look (its height and the depth seen,
    /// metres): it and the steps above it were not rehearsed.
    pub deferred: Option<[f64; 2]>,
    /// The plan, or why it was refused.
    pub plan: Result<Plan, PlanError>,
    /// The plan's execution with every check, and the steps climbed (none when refused).
    pub execution: Option<(Execution, usize)>,
}

impl Rehearsal {
    /// Whether the plan was executed with every check passing, to the top of the rehearsed
    /// world.
    pub fn passed(&self) -> bool {
        self.execution.as_ref().is_some_and(|(ex, climbed)| ex.pass() && *climbed == self.scene.steps().len())
    }
}

/// Rehearses the climb of `steps` (perceived in `cloud`, the sensor head's frame at the robot's
/// origin) under the loop's `p` and the robot's `sim`; the world's surfaces have friction
/// `p.run.rehearsal_friction`. `observer` is told the scene, the plan and the execution.
pub fn rehearse(
    steps: &[PlaneSegment],
    cloud: &PointCloud,
    p: LoopParams<'_>,
    sim: &SimParams,
    observer: &mut dyn Observer,
) -> Result<Rehearsal, SetupError> {
    let tops: Vec<PerceivedTop> =
        steps.iter().map(|s| PerceivedTop { corners: *s.corners(), height_m: s.height_m() }).collect();
    let scene = Scene::rehearsal("hardware rehearsal", &tops, p.run.rehearsal_friction);
    let model = crate::robot::hrp4::model()?;
    let mut world = World::for_scene_options(&scene, &sim.physics.world_options())?;
    settle(&mut world, p.run.settle_s);
    let q0 = world.configuration().to_vec();
    // The plan's input as the loop (and replay) make it: the steps above the feet, a partly
    // seen top step left out; the body kept off every surface the sensor saw (walls,
    // clutter): the rehearsal's world holds the perceived steps only, the real one the rest too.
    let ViewInput { next, surfaces } = take_view(
        &mut StepMap::default(),
        &mut Surroundings::default(),
        steps.to_vec(),
        cloud,
        &model,
        &q0,
        p,
    );
    let deferred = next.deferred.as_ref().map(|top| [top.height_m(), top.depth_m()]);
    // The step left for a closer look bounds the tread below it, as in the loop.
    let bounded: Vec<_> = next.ahead.iter().chain(next.deferred.as_ref()).cloned().collect();
    let plan =
        PlanRequest::new(&model, &q0, &bounded, p.plan).among(surfaces).below(next.ahead.len()).climb();
    let execution = match &plan {
        Err(_) => None,
        Ok(planned) => {
            let t0 = world.data().time();
            observer.event(&Event::Scene(&scene));
            observer.event(&Event::Plan { stamp_s: t0, steps: &next.ahead, plan: planned });
            let ex = execute(&mut world, &model, &scene, planned, sim, observer, &Cancel::never())?;
            Some((ex, climbed(&scene, &model, &world.configuration())))
        }
    };
    Ok(Rehearsal { scene, deferred, plan, execution })
}
