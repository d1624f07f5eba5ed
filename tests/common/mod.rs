//! Helpers shared by the integration tests: an independent ray caster (slab method on the
//! scene's boxes, no MuJoCo) to check the simulated lidar against.
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

/// The scene of a scenario (unwrapping: test inputs are valid).
pub fn scene_of(s: &stairbench::scenario::Scenario) -> Scene {
    Scene::from_scenario(s).expect("valid scenario")
}
