//! Scenario files: defaults, the shipped files, and clear errors on bad input.

mod common;

use proptest::prelude::*;
use stairbench::scenario::{Scenario, ScenarioError};
use stairbench::sim::World;

fn err(text: &str) -> String {
    match Scenario::from_toml_str(text, "bad.toml") {
        Ok(_) => panic!("accepted: {text}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn an_empty_file_is_the_papers_exp1() {
    let s = Scenario::from_toml_str("", "empty.toml").unwrap();
    assert_eq!(s, Scenario::default());
    let scene = common::scene_of(&s);
    let heights: Vec<f64> = scene.steps().iter().map(|t| t.height_m).collect();
    assert_eq!(heights.len(), 3);
    for (h, want) in heights.iter().zip([0.2, 0.4, 0.6]) {
        assert!((h - want).abs() < 1e-12);
    }
    for t in scene.steps() {
        assert!((t.depth_m - 0.27).abs() < 1e-12 && (t.width_m - 0.50).abs() < 1e-12);
    }
    // Exp. 1's room: 11 x 7 x 3 m.
    assert_eq!(s.room.size_m, [11.0, 7.0, 3.0]);
}

#[test]
fn shipped_scenarios_load_and_compile_in_mujoco() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
    let mut n = 0;
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            let s = Scenario::load(&path).unwrap_or_else(|e| panic!("{e}"));
            let scene = common::scene_of(&s);
            let world = World::for_scene(&scene).unwrap();
            let world_geoms = (0..world.model().ffi().ngeom as usize)
                .filter(|&g| world.geom_group(g) == stairbench::scene::mjcf::WORLD_GEOM_GROUP)
                .count();
            assert_eq!(world_geoms, scene.boxes().len(), "{}", path.display());
            assert_eq!(world.model().ffi().nu, 34, "the robot's servos");
            n += 1;
        }
    }
    assert!(n >= 3);
    let exp2 =
        Scenario::load(std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/exp2.toml")))
            .unwrap();
    assert_eq!(
        (exp2.staircase.steps, exp2.staircase.rise_m, exp2.staircase.tread_m, exp2.staircase.width_m),
        (11, 0.18, 0.265, 1.23)
    );
}

#[test]
fn a_yawed_staircase_has_its_ground_truth_turned() {
    let s = Scenario::from_toml_str("[staircase]\nyaw_deg = 30\nstart_m = [1.0, 0.5]\n", "yaw.toml").unwrap();
    let scene = common::scene_of(&s);
    let t = &scene.steps()[0];
    let along = (t.corners[1] - t.corners[0]).normalize();
    assert!((along.y.atan2(along.x).to_degrees() - 30.0).abs() < 1e-9);
    let c = t.center();
    let expect = nalgebra::Vector2::new(1.0, 0.5)
        + nalgebra::Vector2::new(30f64.to_radians().cos(), 30f64.to_radians().sin()) * 0.135;
    assert!((c.x - expect.x).abs() < 1e-9 && (c.y - expect.y).abs() < 1e-9);
}

#[test]
fn unknown_key_names_the_key_and_line() {
    let e = err("seed = 1\n[staircase]\nsteps = 3\nrize_m = 0.2\n");
    assert!(e.contains("bad.toml:4"), "{e}");
    assert!(e.contains("rize_m"), "{e}");
}

#[test]
fn negative_rise_names_the_field_and_line() {
    let e = err("[staircase]\nsteps = 3\n\nrise_m = -0.2\n");
    assert!(e.contains("staircase.rise_m") && e.contains("bad.toml:4") && e.contains("> 0"), "{e}");
}

#[test]
fn a_bound_on_the_estimate_that_is_not_positive_names_the_field_and_line() {
    let e = err("[expect]\noutcome = \"climb\"\nmax_estimate_error_m = -0.02\n");
    assert!(
        e.contains("expect.max_estimate_error_m") && e.contains("bad.toml:3") && e.contains("> 0"),
        "{e}"
    );
}

#[test]
fn zero_steps_is_refused() {
    let e = err("[staircase]\nsteps = 0\n");
    assert!(e.contains("staircase.steps") && e.contains("bad.toml:2"), "{e}");
}

#[test]
fn nan_and_infinity_are_refused() {
    let e = err("[lidar]\nnoise_sigma_m = nan\n");
    assert!(e.contains("lidar.noise_sigma_m") && e.contains("finite") && e.contains(":2"), "{e}");
    let e = err("[staircase]\nstart_m = [inf, 0.0]\n");
    assert!(e.contains("staircase.start_m"), "{e}");
}

#[test]
fn bad_clutter_box_names_its_index() {
    let e = err(
        "[[boxes]]\ncenter_m = [1, 0, 0.1]\n\n[[boxes]]\ncenter_m = [2, 0, 0.1]\nsize_m = [0.2, -1, 0.2]\n",
    );
    assert!(e.contains("boxes[1].size_m") && e.contains("bad.toml:6"), "{e}");
}

#[test]
fn wrong_types_and_syntax_errors_are_located() {
    let e = err("[staircase]\nsteps = \"three\"\n");
    assert!(e.contains("bad.toml:2") && e.contains("`staircase.steps`"), "{e}");
    let e = err("[staircase]\nsteps = -1\n");
    assert!(e.contains("bad.toml:2") && e.contains("`staircase.steps`"), "{e}");
    let e = err("[[boxes]]\nsize_m = [1, 1, 1]\n[[boxes]]\nyaw_deg = \"left\"\n");
    assert!(e.contains("bad.toml:4") && e.contains("`boxes[1].yaw_deg`"), "{e}");
    let e = err("[staircase\nsteps = 3\n");
    assert!(e.contains("bad.toml:1"), "{e}");
    let e = err("[lidar]\ntilt_start_deg = 30\ntilt_end_deg = 30\n");
    assert!(e.contains("lidar.tilt_end_deg"), "{e}");
}

#[test]
fn a_missing_file_is_a_clear_error() {
    let e = Scenario::load(std::path::Path::new("/nonexistent/s.toml")).unwrap_err();
    assert!(matches!(e, ScenarioError::Read { .. }));
    assert!(e.to_string().contains("/nonexistent/s.toml"));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Arbitrary text never panics the parser or the scene builder.
    #[test]
    fn arbitrary_text_never_panics(text in "\\PC{0,200}") {
        if let Ok(s) = Scenario::from_toml_str(&text, "fuzz.toml") {
            let _ = stairbench::scene::Scene::from_scenario(&s);
        }
    }

    /// Any numbers in the staircase section either give a valid scene or a named error.
    #[test]
    fn arbitrary_staircase_numbers(steps in -5i64..300, rise in prop::num::f64::ANY, tread in -1.0f64..2.0, width in prop::num::f64::ANY) {
        let text = format!("[staircase]\nsteps = {steps}\nrise_m = {rise:?}\ntread_m = {tread:?}\nwidth_m = {width:?}\n")
            .replace("NaN", "nan");
        match Scenario::from_toml_str(&text, "p.toml") {
            Ok(s) => {
                let scene = stairbench::scene::Scene::from_scenario(&s).unwrap();
                prop_assert_eq!(scene.steps().len() as i64, steps);
                prop_assert!(rise > 0.0 && tread > 0.0 && width > 0.0);
            }
            // Only staircase numbers vary, so the error must name one of them.
            Err(e) => prop_assert!(e.to_string().contains("`staircase."), "{}", e),
        }
    }
}
