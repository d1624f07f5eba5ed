//! A body unlike its model: the `[plant]` section, the simulated body it draws (masses,
//! gains, compliant ankles the encoders do not see), and a climb in that body with the
//! planner and the stabilizer on the nominal model.

// Test helpers unwrap: a panic there is the test failing.
#![allow(clippy::unwrap_used)]

mod common;

use stairbench::params::ClimbParams;
use stairbench::robot::hrp4;
use stairbench::robot::kinematics::Kinematics;
use stairbench::robot::model::base_pose;
use stairbench::scenario::{PlantErrors, PlantPreset, Scenario};
use stairbench::scene::Scene;
use stairbench::sim::plant::Plant;
use stairbench::sim::World;

fn hrp4_like(seed: u64) -> Scenario {
    let mut s = Scenario { seed, ..Scenario::default() };
    s.plant.preset = PlantPreset::Hrp4Like;
    s
}

/// The world's total robot mass, kg (every body but the world's own, whose geoms are static).
fn robot_mass_kg(world: &World, model: &stairbench::robot::RobotModel) -> f64 {
    let root = world.body_id(&model.root().name).unwrap();
    world.model().body_subtreemass()[root]
}

#[test]
fn plant_fields_are_validated_with_their_line() {
    let e =
        Scenario::from_toml_str("seed = 1\n[plant]\npreset = \"hrp4-like\"\nmass_error = 0.7\n", "bad.toml")
            .unwrap_err()
            .to_string();
    assert!(e.contains("plant.mass_error") && e.contains("bad.toml:4"), "{e}");
    let e = Scenario::from_toml_str("[plant]\npreset = \"stiff\"\n", "bad.toml").unwrap_err().to_string();
    assert!(e.contains("bad.toml:2") && e.contains("preset"), "{e}");
    let s =
        Scenario::from_toml_str("[plant]\npreset = \"hrp4-like\"\nlatency_s = 0.01\n", "ok.toml").unwrap();
    assert_eq!(s.plant.errors().latency_s, 0.01);
    assert_eq!(
        s.plant.errors().ankle_stiffness_nm_per_rad,
        PlantErrors::HRP4_LIKE.ankle_stiffness_nm_per_rad
    );
}

/// The simulated body is not the model: its masses and gains are the draw's, while a
/// nominal body is the model to the gram.
#[test]
fn the_simulated_body_differs_from_the_model_by_its_draw() {
    let model = hrp4::model().unwrap();
    let scene = Scene::from_scenario(&Scenario::default()).unwrap();
    let model_kg: f64 = model.links().iter().map(|l| l.mass_kg).sum();
    let nominal = World::for_scene(&scene).unwrap();
    assert!((robot_mass_kg(&nominal, &model) - model_kg).abs() < 1e-9);
    let plant = Plant::of_scenario(&model, &hrp4_like(5));
    let world = World::with_plant(&scene, &plant).unwrap();
    let ratio = robot_mass_kg(&world, &model) / model_kg;
    assert!((ratio - plant.mass_ratio(&model)).abs() < 1e-9, "{ratio} against {}", plant.mass_ratio(&model));
    assert!((ratio - 1.0).abs() > 1e-4, "the draw changed no mass: {ratio}");
    let (kp0, _) = nominal.servo_gains();
    let (kp, _) = world.servo_gains();
    let off = kp.iter().zip(&kp0).map(|(a, b)| (a / b - 1.0).abs()).fold(0.0, f64::max);
    assert!(off > 0.01 && off <= 0.1 + 1e-9, "servo gains off by {off}");
    // The configuration in the model's layout has the model's joints only.
    assert_eq!(world.configuration().len(), model.nq());
}

/// Standing, the soles of a body with ankle bushes are tilted from where the encoders put
/// them (the bush deflects under the ankle torque, and no encoder reads it); a rigid body's
/// soles are where its encoders say.
#[test]
fn a_bushed_sole_is_not_where_the_encoders_put_it() {
    let model = hrp4::model().unwrap();
    let scene = Scene::from_scenario(&Scenario::default()).unwrap();
    let tilt_from_encoders = |world: &mut World| {
        for _ in 0..1000 {
            world.step();
        }
        let q = world.configuration().to_vec();
        let mut k = Kinematics::new(&model);
        k.update(&q).unwrap();
        let frames = hrp4::sole_frames(&model).unwrap();
        let sites = [hrp4::R_SOLE, hrp4::L_SOLE].map(|n| world.site_id(n).unwrap());
        (0..2)
            .map(|i| {
                (k.frame_pose(frames[i]).rotation.inverse() * world.site_pose(sites[i]).rotation).angle()
            })
            .fold(0.0, f64::max)
    };
    let rigid = tilt_from_encoders(&mut World::for_scene(&scene).unwrap());
    let errors = PlantErrors {
        ankle_stiffness_nm_per_rad: 2000.0,
        ankle_damping_nms_per_rad: 20.0,
        ..PlantErrors::NOMINAL
    };
    let plant = Plant::draw(&model, &errors, 0);
    let bushed = tilt_from_encoders(&mut World::with_plant(&scene, &plant).unwrap());
    assert!(rigid < 1e-6, "a rigid sole {rigid} rad from its encoders' pose");
    assert!(bushed > 1e-4, "a bushed sole only {bushed} rad from its encoders' pose");
}

/// Exp. 1 in a body like a real HRP-4's (the planner and the stabilizer on the nominal
/// model): climbed with every check clean.
#[test]
fn exp1_is_climbed_in_an_hrp4_like_body() {
    let scenario = hrp4_like(2);
    let params = ClimbParams::default();
    let report = stairbench::sim::climb_scenario(
        &scenario,
        params.loop_params(),
        &params.sim(),
        &mut stairbench::climb::Nobody,
        &stairbench::cancel::Cancel::never(),
    )
    .unwrap();
    assert!(report.success, "{:?}: {:?}", report.stop, report.first_violation());
    assert_eq!(report.steps_climbed, 3);
}

/// Watches a climb: per stabilizer tick, the lean it saw (its CoM's horizontal displacement
/// beyond the encoders', metres), the base's tilt from upright as its IMU filter has it, and
/// the true base's tilt at that instant (MuJoCo's pose, which the stabilizer never reads),
/// radians.
#[derive(Default)]
struct LeanWatch {
    true_tilt_rad: f64,
    /// Per tick: when (simulated seconds), the lean, the IMU's tilt, the true tilt.
    ticks: Vec<(f64, f64, f64, f64)>,
    /// The IMU's tilt less the true tilt over each plan's first 50 ms (its first tick left
    /// out: the truth is read after each physics step, and none has run yet), radians.
    plan_start_errors_rad: Vec<f64>,
}

impl stairbench::climb::Observer for LeanWatch {
    fn event(&mut self, event: &stairbench::climb::Event) {
        match event {
            stairbench::climb::Event::State { state, .. } => {
                let up = base_pose(state.q).rotation * nalgebra::Vector3::z();
                self.true_tilt_rad = up.angle(&nalgebra::Vector3::z());
            }
            stairbench::climb::Event::Control { stamp_s, tick } => {
                self.ticks.push((*stamp_s, tick.lean_m.xy().norm(), tick.tilt_rad, self.true_tilt_rad));
                if tick.t_s > 0.0 && tick.t_s <= 0.05 {
                    self.plan_start_errors_rad.push(tick.tilt_rad - self.true_tilt_rad);
                }
            }
            _ => {}
        }
    }
}

fn watch_lean(scenario: &Scenario) -> LeanWatch {
    let params = ClimbParams::default();
    let mut watch = LeanWatch::default();
    stairbench::sim::climb_scenario(
        scenario,
        params.loop_params(),
        &params.sim(),
        &mut watch,
        &stairbench::cancel::Cancel::never(),
    )
    .unwrap();
    watch
}

fn quantile(mut v: Vec<f64>, f: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * f).round() as usize]
}

/// The stabilizer reads the base's tilt from the IMU as MuJoCo has it (under 0.15 deg off at
/// the median and 0.75 deg at 99 % of the ticks, in a rigid body and on soft ankle bushes
/// alike, before any fall; the figures are in `StabilizerParams::tilt_filter_time_s`), and
/// so sees a compliant ankle's lean that its commanded base does not show: on 500 N m/rad
/// bushes the body sways by centimetres, several times what a rigid body's servos yield.
#[test]
fn the_stabilizer_reads_the_true_tilt_and_sees_the_lean() {
    let mut soft = Scenario { seed: 3, ..Scenario::default() };
    soft.plant.ankle_stiffness_nm_per_rad = Some(500.0);
    soft.plant.ankle_damping_nms_per_rad = Some(20.0);
    let soft = watch_lean(&soft);
    let rigid = watch_lean(&Scenario { seed: 3, ..Scenario::default() });
    // Every tick but the last second's (where a fall ends the run).
    let before = |w: &LeanWatch| -> Vec<(f64, f64, f64, f64)> {
        let end_s = w.ticks.last().map_or(0.0, |t| t.0);
        w.ticks.iter().filter(|t| t.0 < end_s - 1.0).copied().collect()
    };
    for (name, w) in [("rigid", &rigid), ("soft", &soft)] {
        let before: Vec<f64> = before(w).iter().map(|t| (t.2 - t.3).abs()).collect();
        assert!(before.len() > 1000, "{name}: {} ticks", before.len());
        eprintln!(
            "{name}: tilt off by {:.3} deg median, {:.3} deg at the 99th percentile",
            quantile(before.clone(), 0.5).to_degrees(),
            quantile(before.clone(), 0.99).to_degrees()
        );
        let (median, high) = (quantile(before.clone(), 0.5), quantile(before, 0.99));
        assert!(
            median < 0.15f64.to_radians() && high < 0.75f64.to_radians(),
            "{name}: tilt off by {} deg median, {} deg at the 99th percentile",
            median.to_degrees(),
            high.to_degrees()
        );
    }
    let lean = |w: &LeanWatch| quantile(before(w).iter().map(|t| t.1).collect(), 0.9);
    assert!(
        lean(&soft) > 0.02 && lean(&soft) > 2.0 * lean(&rigid),
        "leans {} (soft), {} (rigid)",
        lean(&soft),
        lean(&rigid)
    );
}

/// The IMU's tilt filter is the robot's, not a plan's: it carries on from plan to plan and
/// runs while the robot settles between them, so a plan starts with the tilt it has had all
/// along. Over Exp. 1 (seed 3) each plan's first 50 ms read 0.059 deg off MuJoCo's tilt at
/// the median and 0.112 deg at most; a filter started afresh at each plan from its first
/// reading read 0.087 and 0.189 deg (the bound sits between the two). Carried on without
/// the start's averaging and the readings near g only, the first plan began 8 deg off: the
/// robot set down at the start shakes the accelerometer.
#[test]
fn the_tilt_filter_carries_on_from_plan_to_plan() {
    let w = watch_lean(&Scenario { seed: 3, ..Scenario::default() });
    let errors: Vec<f64> = w.plan_start_errors_rad.iter().map(|e| e.abs()).collect();
    assert!(errors.len() >= 40, "{} ticks at the plans' starts", errors.len());
    let (median, high) = (quantile(errors.clone(), 0.5), quantile(errors, 1.0));
    eprintln!(
        "at the plans' starts: off by {:.3} deg median, {:.3} deg at most",
        median.to_degrees(),
        high.to_degrees()
    );
    assert!(median < 0.1f64.to_radians(), "{} deg at the median", median.to_degrees());
    assert!(high < 0.15f64.to_radians(), "{} deg at most", high.to_degrees());
}

/// `scene --resolved` writes the body's every error out, the preset's and the file's.
#[test]
fn scene_resolved_prints_every_plant_error() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("plant");
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("body.toml");
    std::fs::write(&file, "[plant]\npreset = \"hrp4-like\"\nlatency_s = 0.01\n").unwrap();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_stairbench"))
        .args(["scene", file.to_str().unwrap(), "--resolved"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    let back = Scenario::from_toml_str(&text, "resolved").unwrap();
    let e = back.plant.errors();
    assert_eq!(e.latency_s, 0.01);
    assert_eq!(e.mass_error, PlantErrors::HRP4_LIKE.mass_error);
    for (name, _) in PlantErrors::NOMINAL.fields() {
        assert!(text.contains(&format!("{name} = ")), "{name} missing from:\n{text}");
    }
}
