//! The simulated tilting lidar against an independent ray caster and the scene's geometry.

// Test helpers unwrap: a panic there is the test failing.
#![allow(clippy::unwrap_used)]

mod common;

use nalgebra::{Point3, Vector3};
use stairbench::cancel::Cancel;
use stairbench::cloud::PointCloud;
use stairbench::scenario::Scenario;
use stairbench::scene::mjcf::ROBOT_GEOM_GROUP;
use stairbench::scene::{Scene, SurfaceRole};
use stairbench::sensor::{AssembleParams, RayCaster, SimLidar, Sweep};
use stairbench::sim::lidar::head_lidar;
use stairbench::sim::World;

fn exp1(noise_sigma_m: f64) -> (Scenario, Scene, World) {
    let mut s = Scenario::default();
    s.lidar.noise_sigma_m = noise_sigma_m;
    let scene = common::scene_of(&s);
    let world = World::for_scene(&scene).unwrap();
    (s, scene, world)
}

/// The scenario's lidar in `world`, one whole sweep of it, and the sweep's cloud.
fn swept<'w>(s: &Scenario, world: &'w World) -> (SimLidar<'w, World>, Sweep, PointCloud) {
    let lidar = head_lidar(world, &s.lidar, s.seed).unwrap();
    let sweep = lidar.sweep_rows(&Cancel::never(), &mut |_, _| {}).unwrap();
    let cloud = sweep.assemble(&AssembleParams::default()).unwrap();
    (lidar, sweep, cloud)
}

/// Largest distance of any point to the world's surfaces, and the most negative signed
/// distance (depth inside a box).
fn surface_errors(scene: &Scene, pts: &[Point3<f32>]) -> (f64, f64) {
    let d: Vec<f64> = pts.iter().map(|p| scene.signed_distance(&p.cast())).collect();
    let worst = d.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let deepest = d.iter().fold(0.0f64, |m, &v| m.min(v));
    (worst, deepest)
}

#[test]
fn noise_free_points_lie_on_the_world_within_a_millimetre() {
    let (s, scene, world) = exp1(0.0);
    let (_, _, cloud) = swept(&s, &world);
    assert_eq!(cloud.len(), 259_440, "every beam of a closed room returns");
    let (worst, deepest) = surface_errors(&scene, cloud.points());
    assert!(worst < 1e-3, "a point is {:.2} mm off every surface", worst * 1e3);
    assert!(deepest > -1e-3, "a point is {:.2} mm inside a box", -deepest * 1e3);
}

#[test]
fn ranges_agree_with_an_independent_ray_caster() {
    let (s, scene, world) = exp1(0.0);
    let lidar = head_lidar(&world, &s.lidar, s.seed).unwrap();
    let mount = lidar.mount_to_world();
    let model = lidar.lidar();
    let mut compared = 0;
    for k in (0..lidar.sweep().rows()).step_by(7) {
        let (row, _) = lidar.row_with_hits(k);
        for i in (0..model.beams()).step_by(3) {
            let tilt = lidar.sweep().tilt_at(row.stamp_s + model.beam_time_offset_s(i));
            let scanner = mount * model.scanner_in_mount(tilt);
            let dir = scanner.rotation * model.beam_direction(i);
            let (t, _) =
                common::cast(scene.boxes(), &scanner.translation.vector.into(), &dir).expect("closed room");
            assert!(
                (row.ranges_m[i] as f64 - t).abs() < 1e-4,
                "row {k} beam {i}: mujoco {} vs slab {t}",
                row.ranges_m[i]
            );
            compared += 1;
        }
    }
    assert!(compared > 10_000);
}

#[test]
fn range_noise_matches_the_configured_sigma() {
    let sigma = 0.01;
    let (s, _scene, world) = exp1(sigma);
    let lidar = head_lidar(&world, &s.lidar, 7).unwrap();
    let mut residuals = Vec::new();
    for k in 0..lidar.sweep().rows() {
        let (row, hits) = lidar.row_with_hits(k);
        for (i, hit) in hits.iter().enumerate() {
            if let (true, Some(h)) = (row.has_return(i), hit) {
                residuals.push(row.ranges_m[i] as f64 - h.distance_m);
            }
        }
    }
    let n = residuals.len() as f64;
    let mean = residuals.iter().sum::<f64>() / n;
    let sd = (residuals.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / n).sqrt();
    assert!((sd - sigma).abs() < 0.1 * sigma, "noise sd {sd} vs configured {sigma}");
    assert!(mean.abs() < 0.05 * sigma, "noise is biased: mean {mean}");
}

#[test]
fn first_step_is_hit_with_the_density_the_geometry_predicts() {
    let (s, scene, world) = exp1(0.0);
    let (lidar, sweep, cloud) = swept(&s, &world);
    let step = &scene.steps()[0];
    let on_tread = |p: &Point3<f64>| (p.z - step.height_m).abs() < 2e-3 && step.contains_xy(p, 0.0);
    let measured = cloud.points().iter().filter(|p| on_tread(&p.cast())).count();

    // Expected: beams whose first hit, by the independent caster, is the first step's top.
    let (mount, model) = (lidar.mount_to_world(), lidar.lidar());
    let mut expected = 0;
    for row in &sweep.rows {
        for i in 0..model.beams() {
            let tilt = lidar.sweep().tilt_at(row.stamp_s + model.beam_time_offset_s(i));
            let scanner = mount * model.scanner_in_mount(tilt);
            let o: Point3<f64> = scanner.translation.vector.into();
            let dir = scanner.rotation * model.beam_direction(i);
            if let Some((t, b)) = common::cast(scene.boxes(), &o, &dir) {
                if b.role() == SurfaceRole::Step(0) && on_tread(&(o + dir * t)) {
                    expected += 1;
                }
            }
        }
    }
    // Density check from first principles too: about r^2 * d_alpha * d_tilt per beam.
    let centre = step.center();
    let sensor: Point3<f64> = mount.translation.vector.into();
    let r = (centre - sensor).norm();
    let cell_m2 = r * r * 0.25f64.to_radians() * 0.25f64.to_radians();
    let incidence = (mount.translation.z - step.height_m) / r;
    let rough = step.area_m2() * incidence / cell_m2;
    assert!(expected > 1000, "the first step must be in view ({expected} beams)");
    assert!((measured as f64 - expected as f64).abs() <= 0.01 * expected as f64, "{measured} vs {expected}");
    assert!(
        (measured as f64 / rough - 1.0).abs() < 0.35,
        "{measured} points vs about {rough:.0} from r^2 d_alpha d_tilt"
    );
}

#[test]
fn the_robot_is_never_hit_though_it_is_in_the_way() {
    let (s, _scene, world) = exp1(0.0);
    let lidar = head_lidar(&world, &s.lidar, s.seed).unwrap();
    let robot_geoms: Vec<usize> = (0..world.model().ffi().ngeom as usize)
        .filter(|&g| world.geom_group(g) == ROBOT_GEOM_GROUP)
        .collect();
    assert!(!robot_geoms.is_empty());
    // HRP-4's head sphere encloses the optical centre (the servo sits on the neck): every
    // beam starts inside a robot geom, so a lidar that did not exclude the robot would hit
    // it with every beam.
    let head =
        world.model().name_to_id(mujoco_rs::prelude::MjtObjBase::mjOBJ_GEOM, "NECK_P_LINK_geom0").unwrap();
    let centre = Vector3::from(world.data().geom_xpos()[head]);
    let radius = world.model().geom_size()[head][0];
    let scanner = lidar.mount_to_world() * lidar.lidar().scanner_in_mount(lidar.sweep().tilt_at(0.0));
    assert!(
        (scanner.translation.vector - centre).norm() < radius,
        "the test needs the sensor inside the head"
    );
    let mut robot_hits = 0;
    for k in (0..lidar.sweep().rows()).step_by(5) {
        let (_, hits) = lidar.row_with_hits(k);
        assert!(hits.iter().all(Option::is_some), "a closed room returns every beam");
        robot_hits += hits.iter().flatten().filter(|h| world.geom_group(h.geom) == ROBOT_GEOM_GROUP).count();
    }
    assert_eq!(robot_hits, 0);
}

#[test]
fn tilt_is_quantized_and_moves_during_each_row() {
    let (s, scene, world) = exp1(0.0);
    let (lidar, sweep, fitted) = swept(&s, &world);
    let tick = lidar.sweep().tick_rad();
    for r in &sweep.rows {
        let ticks = r.tilt_rad / tick;
        assert!((ticks - ticks.round()).abs() < 1e-9, "reading {} is not a whole tick", r.tilt_rad);
    }
    let distinct: std::collections::BTreeSet<i64> =
        sweep.rows.iter().map(|r| (r.tilt_rad / tick).round() as i64).collect();
    assert!(distinct.len() > 200, "readings should step through the encoder's ticks");

    // Holding each row's reading for the whole row leaves errors of several millimetres: the
    // scanner moves during a row. The fitted per-beam tilt removes them.
    let held = sweep.assemble(&AssembleParams { tilt_fit_half_window_rows: 0 }).unwrap();
    let (held_err, _) = surface_errors(&scene, held.points());
    let (fit_err, _) = surface_errors(&scene, fitted.points());
    assert!(
        held_err > 5e-3,
        "held tilt error only {:.2} mm: the scanner does not move in a row",
        held_err * 1e3
    );
    assert!(fit_err < 1e-3, "fitted tilt error {:.2} mm", fit_err * 1e3);
}

/// The world's own fast caster (`BoxRays`, the static boxes culled by their bounds)
/// gives `mj_ray`'s answers bit for bit, geom and distance: on the lidar's own beams, on rays
/// from anywhere in the room in any direction, on rays aimed at every box's corners and
/// edges' midpoints (where a box meets the next and the nearer geom id must win the tie), and
/// on rays along the world's axes from those points (directions with zero components, from
/// origins on a box's faces), in worlds with nosings, handrails, walls and objects on the
/// treads.
#[test]
fn the_worlds_box_caster_answers_as_mj_ray() {
    use rand::{Rng, SeedableRng};
    let files = [
        "scenarios/exp1.toml",
        "scenarios/suites/regressions/exp1-nosing-25mm.toml",
        "scenarios/suites/regressions/chest-between-two-rails.toml",
        "scenarios/suites/regressions/parcel-in-a-lane-on-step-2.toml",
        "scenarios/suites/regressions/stairwell-shoulder-met-the-wall.toml",
        "scenarios/suites/regressions/walking-handrail-end-read-as-a-step-at-the-top.toml",
    ];
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(42);
    for file in files {
        let s = Scenario::load(std::path::Path::new(file)).unwrap();
        let scene = common::scene_of(&s);
        let world = World::for_scene(&scene).unwrap();
        assert!(world.casts_by_boxes(), "{file}: the world is static boxes");
        let mut rays: Vec<(Point3<f64>, Vector3<f64>)> = Vec::new();
        let lidar = head_lidar(&world, &s.lidar, s.seed).unwrap();
        for k in (0..lidar.sweep().rows()).step_by(11) {
            for i in (0..lidar.lidar().beams()).step_by(5) {
                rays.push(lidar.beam_ray(k, i));
            }
        }
        let head: Point3<f64> = lidar.mount_to_world().translation.vector.into();
        for b in scene.boxes() {
            let h = b.half_extents_m();
            for c in 0..27 {
                // Corners, edges' midpoints, faces' centres and the centre of each box.
                let at = Vector3::new(
                    h.x * ((c % 3) as f64 - 1.0),
                    h.y * ((c / 3 % 3) as f64 - 1.0),
                    h.z * ((c / 9) as f64 - 1.0),
                );
                let target = b.pose() * Point3::from(at);
                if let Some(d) = (target - head).try_normalize(1e-9) {
                    rays.push((head, d));
                }
                // Along the world's axes from the box's surface and centre: directions with
                // components of 0, from origins on its faces' planes.
                for axis in 0..6 {
                    let mut d = Vector3::zeros();
                    d[axis % 3] = if axis < 3 { 1.0 } else { -1.0 };
                    rays.push((target, d));
                }
            }
        }
        for _ in 0..20_000 {
            let o = Point3::new(
                rng.random_range(-2.0..6.0),
                rng.random_range(-3.0..3.0),
                rng.random_range(0.05..2.5),
            );
            let d = Vector3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            if let Some(d) = d.try_normalize(1e-6) {
                rays.push((o, d));
            }
        }
        let mut hits = 0;
        for (o, d) in &rays {
            let (fast, mujoco) = (world.ray(o, d), world.ray_by_mujoco(o, d));
            let key = |h: Option<stairbench::sensor::RayHit>| h.map(|h| (h.distance_m.to_bits(), h.geom));
            assert_eq!(key(fast), key(mujoco), "{file}: from {o} along {d}");
            hits += fast.is_some() as usize;
        }
        assert!(hits > rays.len() / 2, "{file}: {hits} of {} rays met a box", rays.len());
    }
}
