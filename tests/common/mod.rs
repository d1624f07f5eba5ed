//! Helpers shared by the integration tests: an independent ray caster (slab method on the
//! scene's boxes, no MuJoCo) to check the simulated lidar against; the Exp. 1 world settled
//! and its true step rectangles, moved as a perception error made on purpose.

// Test helpers unwrap: a panic there is the test failing.
#![allow(clippy::unwrap_used)]
#![allow(dead_code)]

use nalgebra::{Isometry3, Point3, Vector3};
use stairbench::scene::{Scene, SceneBox};

/// Entry distance of the ray into a box, if it hits (and the origin is outside).
pub fn ray_box(
    origin: &Point3<f64>,
    dir: &Vector3<f64>,
    pose: &Isometry3<f64>,
    half: &Vector3<f64>,
) -> Option<f64> {
    let o = pose.inverse_transform_point(origin);
    let d = pose.inverse_transform_vector(dir);
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    for k in 0..3 {
        if d[k].abs() < 1e-15 {
            if o[k].abs() > half[k] {
                return None;
            }
            continue;
        }
        let a = (-half[k] - o[k]) / d[k];
        let b = (half[k] - o[k]) / d[k];
        t0 = t0.max(a.min(b));
        t1 = t1.min(a.max(b));
    }
    (t1 >= t0 && t0 > 0.0).then_some(t0)
}

/// The nearest box hit by a ray, and its distance.
pub fn cast<'a>(
    boxes: &'a [SceneBox],
    origin: &Point3<f64>,
    dir: &Vector3<f64>,
) -> Option<(f64, &'a SceneBox)> {
    boxes
        .iter()
        .filter_map(|b| ray_box(origin, dir, b.pose(), b.half_extents_m()).map(|t| (t, b)))
        .min_by(|a, b| a.0.total_cmp(&b.0))
}

/// The case of the `regressions` suite named `name` (its file in the repository).
pub fn regression(name: &str) -> stairbench::scenario::Scenario {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join(format!("scenarios/suites/regressions/{name}.toml"));
    stairbench::scenario::Scenario::load(&path).unwrap()
}

/// The scene of a scenario (unwrapping: test inputs are valid).
pub fn scene_of(s: &stairbench::scenario::Scenario) -> Scene {
    Scene::from_scenario(s).expect("valid scenario")
}

/// The Exp. 1 world after settling (300 physics steps), the robot's model and configuration.
pub fn settled_exp1() -> (Scene, stairbench::robot::RobotModel, stairbench::sim::World, Vec<f64>) {
    let scene = Scene::from_scenario(&stairbench::scenario::Scenario::default()).unwrap();
    let model = stairbench::robot::hrp4::model().unwrap();
    let mut world = stairbench::sim::World::for_scene(&scene).unwrap();
    for _ in 0..300 {
        world.data_mut().step();
    }
    let q0 = world.data().qpos()[..model.nq()].to_vec();
    (scene, model, world, q0)
}

/// The true step rectangles of `scene`, each moved by `offset` (a perception error made on
/// purpose).
pub fn step_tops_moved(scene: &Scene, offset: Vector3<f64>) -> Vec<stairbench::perception::PlaneSegment> {
    stairbench::planning::rectangles::from_step_tops(scene.steps())
        .iter()
        .map(|r| {
            stairbench::perception::PlaneSegment::new(
                r.center() + offset,
                r.along(),
                r.depth_m(),
                r.width_m(),
                r.normal().into_inner(),
                r.voxel_count(),
            )
            .unwrap()
        })
        .collect()
}
