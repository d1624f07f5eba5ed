//! Real stairs (issue 39): nosings, open risers, rises that vary within a flight, handrails
//! and things left on the treads, each part of the ground truth that the world, the checks,
//! the step count and the expectations read; and the loop never setting a foot where the
//! world differs from its plan (a parcel in a lane, the robot set down near the first riser).

mod common;

use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use stairbench::cancel::Cancel;
use stairbench::climb::{ClimbReport, Footing, Nobody, StopReason};
use stairbench::params::ClimbParams;
use stairbench::perception::Method;
use stairbench::planning::footholds::GaitParams;
use stairbench::regress::expect::expect;
use stairbench::scenario::{ExpectedOutcome, ObjectSpec, Risers, Scenario};
use stairbench::scene::Scene;
use stairbench::sim::checks::overhang_m;
use stairbench::sim::climb_scenario;

/// Half sizes of HRP-4's sole (0.24 x 0.13 m).
const SOLE_HALF_M: [f64; 2] = [0.12, 0.065];
/// Each sole's distance from the robot's middle line (HRP-4 half-sitting).
const FEET_HALF_SPACING_M: f64 = 0.1013;

fn climb(s: &Scenario) -> ClimbReport {
    climb_with(s, &ClimbParams::default())
}

fn climb_with(s: &Scenario, p: &ClimbParams) -> ClimbReport {
    let r =
        climb_scenario(s, p.loop_params(), &p.sim(), &mut Nobody, &Cancel::never()).expect("the world runs");
    for c in &r.cycles {
        println!(
            "cycle {} to {}: pass {}, margin {:.1} mm, friction {:.2}, violations {:?}",
            c.cycle,
            c.to,
            c.pass,
            c.execution.min_margin_m * 1e3,
            c.execution.max_friction_ratio,
            c.execution.violations.iter().map(|v| v.check.to_string()).collect::<Vec<_>>()
        );
    }
    println!("{} of {} steps, stopped: {:?}", r.steps_climbed, r.steps_total, r.stop);
    r
}

/// Climbed to the top with no check violated in any cycle.
fn assert_climbed_clean(r: &ClimbReport) {
    assert!(r.success, "{:?}", r.stop);
    assert_eq!(r.steps_climbed, r.steps_total, "the feet end on the top tread (ground truth)");
    for c in &r.cycles {
        assert!(c.execution.violations.is_empty() && !c.execution.fell, "cycle {}", c.cycle);
    }
}

/// The sole at (along, height) on the Exp. 1 flight's middle line, level, facing the ascent.
fn sole_at(along_m: f64, z_m: f64) -> Isometry3<f64> {
    Isometry3::from_parts(Translation3::new(along_m, -0.1, z_m), UnitQuaternion::identity())
}

#[test]
fn a_heel_on_a_nosing_is_on_its_step() {
    let mut s = Scenario::default();
    s.staircase.nosing_m = 0.025;
    let scene = Scene::from_scenario(&s).unwrap();
    let riser = s.staircase.start_m[0];
    let top = &scene.steps()[0];
    assert!((top.depth_m - (0.27 + 0.025)).abs() < 1e-12, "the tread runs from its nose: {}", top.depth_m);
    // The heel 21 mm over the riser, on the nosing: on the step, 4 mm inside its nose.
    let heel_on_nosing = sole_at(riser - 0.021 + SOLE_HALF_M[0], 0.20);
    let over = overhang_m(&scene, &heel_on_nosing, SOLE_HALF_M).expect("on step 1");
    assert!(over <= 0.0, "a heel on the nosing reported {over:.3} m off its step");
    // 35 mm over the riser is 10 mm past the nose.
    let past = sole_at(riser - 0.035 + SOLE_HALF_M[0], 0.20);
    let over = overhang_m(&scene, &past, SOLE_HALF_M).expect("on step 1");
    assert!((over - 0.010).abs() < 1e-9, "{over}");
    // The world has the nosing: a point under the nose, above the riser's foot, is in a box.
    assert!(scene.signed_distance(&nalgebra::Point3::new(riser - 0.01, 0.0, 0.19)) < 0.0);
    assert!(
        scene.signed_distance(&nalgebra::Point3::new(riser - 0.01, 0.0, 0.10)) > 0.0,
        "under the nosing is air"
    );
}

#[test]
fn an_open_riser_flight_has_air_between_its_treads() {
    let mut s = Scenario::default();
    s.staircase.risers = Risers::Open;
    let scene = Scene::from_scenario(&s).unwrap();
    let riser = s.staircase.start_m[0];
    let at = |x: f64, z: f64| scene.signed_distance(&nalgebra::Point3::new(x, 0.0, z));
    assert!(at(riser + 0.1, 0.10) > 0.0, "under the first tread is air");
    assert!(at(riser + 0.1, 0.19) < 0.0, "the first tread is a slab");
    assert!(at(riser + 0.3, 0.25) > 0.0, "between treads 1 and 2 is air");
    // A sole standing over the gap behind tread 1's slab, at tread 1's height, is off it.
    let over =
        overhang_m(&scene, &sole_at(riser + 0.27 + 0.05, 0.20), SOLE_HALF_M).expect("at step 1's height");
    assert!(over > 0.1, "{over}");
}

#[test]
fn rises_and_treads_vary_within_a_flight() {
    let text = "[staircase]\nsteps = 4\nrises_m = [0.17, 0.175, 0.17, 0.20]\ntreads_m = [0.28, 0.27, 0.29, 0.28]\nwidth_m = 1.0\n";
    let s = Scenario::from_toml_str(text, "uneven.toml").unwrap();
    let scene = Scene::from_scenario(&s).unwrap();
    let heights: Vec<f64> = scene.steps().iter().map(|t| t.height_m).collect();
    for (h, want) in heights.iter().zip([0.17, 0.345, 0.515, 0.715]) {
        assert!((h - want).abs() < 1e-9, "{heights:?}");
    }
    let depths: Vec<f64> = scene.steps().iter().map(|t| t.depth_m).collect();
    assert!((depths[1] - 0.27).abs() < 1e-9 && (depths[2] - 0.29).abs() < 1e-9, "{depths:?}");
    // The third tread's riser stands after the first two treads.
    let front = scene.steps()[2].corners[0].x;
    assert!((front - (0.6 + 0.28 + 0.27)).abs() < 1e-9, "{front}");
    assert_eq!(expect(&s, &GaitParams::default(), FEET_HALF_SPACING_M).outcome, ExpectedOutcome::Climb);
}

#[test]
fn the_real_stairs_fields_are_checked_and_located() {
    let err = |t: &str| Scenario::from_toml_str(t, "bad.toml").unwrap_err().to_string();
    let e = err("[staircase]\nsteps = 3\nrises_m = [0.17, 0.17]\n");
    assert!(
        e.contains("staircase.rises_m") && e.contains("bad.toml:3") && e.contains("2 values for 3 steps"),
        "{e}"
    );
    let e = err("[staircase]\nnosing_m = 0.2\n");
    assert!(e.contains("staircase.nosing_m") && e.contains(":2"), "{e}");
    let e = err("[staircase]\nrisers = \"half\"\n");
    assert!(e.contains("risers") && e.contains(":2"), "{e}");
    let e = err("[[objects]]\nstep = 7\n");
    assert!(e.contains("objects[0].step") && e.contains(":2") && e.contains("3"), "{e}");
    let e = err("[[objects]]\nstep = 2\nalong_m = 0.5\n");
    assert!(e.contains("objects[0].along_m") && e.contains(":3"), "{e}");
    // Everything resolved and read back is the same scenario.
    let mut s = Scenario::default();
    s.staircase.nosing_m = 0.02;
    s.staircase.rises_m = vec![0.2, 0.2, 0.23];
    s.objects.push(ObjectSpec::default());
    let back = Scenario::from_toml_str(&s.to_toml_string().unwrap(), "resolved.toml").unwrap();
    assert_eq!(back, s);
}

/// The fall: a parcel left in the right foot's lane on the second tread.
fn exp1_with_a_parcel_on_step_2() -> Scenario {
    let mut s = Scenario::default();
    s.objects.push(ObjectSpec {
        name: "parcel".into(),
        step: 2,
        along_m: 0.14,
        across_m: -0.1,
        ..ObjectSpec::default()
    });
    s
}

#[test]
fn a_parcel_in_a_lane_on_a_tread_is_refused_before_a_foot_is_on_the_flight() {
    let s = exp1_with_a_parcel_on_step_2();
    assert_eq!(expect(&s, &GaitParams::default(), FEET_HALF_SPACING_M).outcome, ExpectedOutcome::Refuse);
    let r = climb(&s);
    assert!(!r.success);
    assert!(matches!(r.stop, Some(StopReason::Refused { .. })), "refused, not {:?}", r.stop);
    for c in &r.cycles {
        assert_eq!(c.to, Footing::Floor, "cycle {}: a foot went onto the flight", c.cycle);
        assert!(c.execution.violations.is_empty() && !c.execution.fell, "cycle {}", c.cycle);
    }
}

#[test]
fn a_top_rise_taller_than_the_rest_is_climbed_and_counted() {
    let text = "[staircase]\nsteps = 5\nrise_m = 0.17\ntread_m = 0.28\nwidth_m = 1.0\nrises_m = [0.17, 0.17, 0.17, 0.17, 0.20]\n";
    let s = Scenario::from_toml_str(text, "top.toml").unwrap();
    let r = climb(&s);
    assert_climbed_clean(&r);
    assert_eq!(r.steps_total, 5);
}

#[test]
fn open_risers_and_nosings_are_climbed_clean() {
    let mut open = Scenario::default();
    open.staircase.risers = Risers::Open;
    assert_climbed_clean(&climb(&open));
    let mut nosed = Scenario::default();
    nosed.staircase.nosing_m = 0.025;
    assert_climbed_clean(&climb(&nosed));
}

#[test]
fn a_robot_set_down_near_the_first_riser_never_sets_a_foot_against_it() {
    let mut s = Scenario::default();
    s.staircase.start_m = [0.28, 0.0];
    let r = climb(&s);
    for c in &r.cycles {
        assert!(c.execution.violations.is_empty() && !c.execution.fell, "cycle {}", c.cycle);
    }
    let refused_on_the_floor =
        matches!(r.stop, Some(StopReason::Refused { .. })) && r.cycles.iter().all(|c| c.to == Footing::Floor);
    assert!(r.success || refused_on_the_floor, "{:?}", r.stop);
}

/// The paper's pipeline's perception incidents, climbed by it (`--method paper`): the
/// `regressions` suite, which `make test` runs whole, climbs every incident by the default,
/// the cell method, whose own incidents (`sight-edge-taken-for-a-face`,
/// `shoe-top-taken-for-the-riser-above`, `wall-column-turned-the-flight`) are there.
/// - an unseen step 1 left two rises (k grew with the noise; `step-1-never-perceived`);
/// - a tread split in two by the supervoxels under 20 mm of noise put a foot on a nose
///   (`tread-split-in-two-under-20mm`);
/// - range noise tilted the treads' fitted planes and a foot landed on its edge
///   (`noise-tilted-the-treads`).
#[test]
fn the_papers_incidents_are_climbed_by_its_pipeline() {
    assert_eq!(
        Method::default(),
        Method::Cells,
        "the regressions suite climbs the cell method's incidents only while it is the default: climb them here"
    );
    for name in ["step-1-never-perceived", "tread-split-in-two-under-20mm", "noise-tilted-the-treads"] {
        let s = common::regression(name);
        let mut p = ClimbParams::default();
        p.perception.method = Method::Paper;
        println!("{name}, by the paper's pipeline:");
        assert_climbed_clean(&climb_with(&s, &p));
    }
}

#[test]
fn a_handrail_along_a_landing_is_no_step() {
    // From the landing the rail's top (5 cm wide, 0.9 m up, along the ascent) was the only
    // level surface ahead, and the loop refused it as a 0.94 m rise.
    let text = "[staircase]\nsteps = 3\nrise_m = 0.17\ntread_m = 0.28\nwidth_m = 1.1\nlanding_m = 1.0\nhandrails = \"both\"\n";
    let s = Scenario::from_toml_str(text, "landing.toml").unwrap();
    assert_climbed_clean(&climb(&s));
}
