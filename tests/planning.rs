//! The planner end to end (issue 5, §6): footholds, the five segments per step, the CoM
//! checked against each segment's stability polygon (recomputed here by Bretl and Lall's
//! projection, the independent method), the IK trajectory tracking its feet and holding its
//! contacts, the swing clearing the steps, the legs kept off the true steps, and the refusals.

// Test helpers unwrap: a panic there is the test failing.
#![allow(clippy::unwrap_used)]

mod common;

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use stairbench::geom2d::P2;
use stairbench::perception::PlaneSegment;
use stairbench::planning::gait::{Phase, StepParams};
use stairbench::planning::plan::{legs_at, standing_body};
use stairbench::planning::polygon::{by_bretl, margin};
use stairbench::planning::reach;
use stairbench::planning::{clearance, rectangles, Contact, Foot, Plan, PlanError, PlanParams, PlanRequest};
use stairbench::robot::model::{base_pose, Q_JOINTS};
use stairbench::robot::{hrp4, Kinematics, RobotModel};
use stairbench::scenario::Scenario;
use stairbench::scene::Scene;

fn start_q(model: &RobotModel, at: &Isometry3<f64>) -> Vec<f64> {
    hrp4::half_sitting_at(model, at).unwrap()
}

/// The robot model, Exp. 1's true step tops and the robot's start, half-sitting: what a plan
/// of Exp. 1 from its ground truth asks.
fn exp1_on_its_tops() -> (RobotModel, Vec<PlaneSegment>, Vec<f64>) {
    let model = hrp4::model().unwrap();
    let scene = common::scene_of(&Scenario::default());
    let q0 = start_q(&model, &scene.robot_start());
    (model, rectangles::from_step_tops(scene.steps()), q0)
}

fn scenario_plan(s: &Scenario) -> (Scene, Result<Plan, PlanError>) {
    let model = hrp4::model().unwrap();
    let scene = common::scene_of(s);
    let rects = rectangles::from_step_tops(scene.steps());
    let q0 = start_q(&model, &scene.robot_start());
    let r = PlanRequest::new(&model, &q0, &rects, &PlanParams::default()).climb();
    (scene, r)
}

/// Every property the issue names, checked from the plan's samples.
fn check(plan: &Plan, scene: Option<&Scene>) {
    let model = hrp4::model().unwrap();
    let mut kin = Kinematics::new(&model);
    let p = PlanParams::default();
    let mut worst = (f64::INFINITY, f64::INFINITY, 0.0f64, 0.0f64); // margin, sample margin, drift, touchdown
    let polys: Vec<Vec<P2>> = plan
        .segments
        .iter()
        .map(|s| {
            let contacts: Vec<Contact> = s
                .support
                .iter()
                .map(|(_, pose)| Contact::new(*pose, 0.12, 0.065, p.step.friction).unwrap())
                .collect();
            by_bretl(&contacts, 1e-5).unwrap()
        })
        .collect();
    for (s, poly) in plan.segments.iter().zip(&polys) {
        for c in [s.com_start, s.com_end] {
            let m = margin(poly, &P2::new(c.x, c.y));
            assert!(
                m >= p.step.min_margin_m - 1e-4,
                "{:?} of stance {}: CoM waypoint margin {m}",
                s.phase,
                s.stance
            );
            worst.0 = worst.0.min(m);
        }
    }
    let sole_box: Vec<Point3<f64>> = [-1.0, 1.0]
        .iter()
        .flat_map(|&sx| [-1.0, 1.0].map(move |sy| (sx, sy)))
        .flat_map(|(sx, sy)| [0.0, 0.02].map(move |z| Point3::new(0.12 * sx, 0.065 * sy, z)))
        .collect();
    let limbs = clearance::limbs(&model, &hrp4::sole_frames(&model).unwrap());
    assert_eq!(limbs.len(), 4, "thigh and shank of each leg");
    let mut least_leg = f64::INFINITY;
    let reach_m = legs_at(&model, &plan.trajectory.samples[0].q, &p.step).unwrap().reach_m;
    for (i, smp) in plan.trajectory.samples.iter().enumerate().skip(1) {
        let seg = &plan.segments[smp.segment];
        kin.update(&smp.q).unwrap();
        assert!((kin.com() - smp.com).norm() < 1e-9);
        let m = margin(&polys[smp.segment], &P2::new(smp.com.x, smp.com.y));
        assert!(m > 0.0, "sample {i} (t = {:.3} s): CoM outside the polygon by {:.4} m", smp.t_s, -m);
        worst.1 = worst.1.min(m);
        for (f, pose) in &seg.support {
            let at = &smp.feet[f.index()];
            let d = (at.translation.vector - pose.translation.vector).norm();
            assert!(d < 1e-3, "sample {i}: {f:?} contact moved {d} m");
            worst.2 = worst.2.max(d);
        }
        for (j, jt) in model.joints().iter().enumerate() {
            let v = smp.q[Q_JOINTS + j];
            assert!(
                v >= jt.lower_rad - 1e-6 && v <= jt.upper_rad + 1e-6,
                "sample {i}: {} at {v} outside its limits",
                jt.name
            );
        }
        if let Some(scene) = scene {
            // The legs' capsules against the true steps (the scene's boxes, not the
            // rectangles the planner kept them from), at 21 points along each axis.
            for limb in &limbs {
                let (a, b) = limb.axis_world(&kin);
                for k in 0..=20 {
                    let d = scene.signed_distance(&a.lerp(&b, k as f64 / 20.0)) - limb.radius_m;
                    assert!(
                        d > p.ik.leg_clearance_m - 5e-3,
                        "sample {i} (t = {:.3} s): {} is {:.1} mm from a step",
                        smp.t_s,
                        limb.name,
                        d * 1e3
                    );
                    least_leg = least_leg.min(d);
                }
            }
        }
        if let (Some(sw), Some(scene)) = (&seg.swing, scene) {
            let sole = &smp.feet[sw.foot.index()];
            for c in &sole_box {
                let d = scene.signed_distance(&sole.transform_point(c));
                assert!(d > -1e-3, "sample {i} ({:?} of stance {}, t = {:.3} s): the swinging {:?} sole (z {:.4}, tilt {:.4} rad)  corner {c} is {d} m inside a step", seg.phase, seg.stance, smp.t_s, sw.foot, sole.translation.z, sole.rotation.angle());
            }
        }
        let last_of_segment = plan.trajectory.samples.get(i + 1).is_none_or(|n| n.segment != smp.segment);
        if let (Some(sw), true) = (&seg.swing, last_of_segment) {
            let target = sw.path.last().unwrap();
            let d = (smp.feet[sw.foot.index()].translation.vector - target.translation.vector).norm();
            assert!(d < 5e-3, "{:?} foot lands {d} m from its target", sw.foot);
            worst.3 = worst.3.max(d);
            if seg.phase == Phase::SwingRight {
                let apart = leg_length_m(&model, &kin, sw.foot);
                assert!(
                    apart <= reach_m + 2e-3,
                    "stance {}: the leading leg lands {apart:.3} m from hip to ankle, beyond its reach {reach_m:.3} m",
                    seg.stance + 1
                );
            }
        }
    }
    // Five segments per stance, in the paper's order.
    assert_eq!(plan.segments.len(), 5 * plan.stances.len());
    let order =
        [Phase::ShiftToLeft, Phase::SwingRight, Phase::ShiftToRight, Phase::LiftSwingLeft, Phase::Centre];
    assert!(plan.segments.iter().enumerate().all(|(i, s)| s.phase == order[i % 5]));
    println!(
        "waypoint margin >= {:.1} mm, CoM margin at every sample >= {:.1} mm, contacts still within {:.3} mm, touchdown within {:.3} mm, legs >= {:.1} mm from the true steps, {} samples, motion {:.1} s",
        worst.0 * 1e3,
        worst.1 * 1e3,
        worst.2 * 1e3,
        worst.3 * 1e3,
        least_leg * 1e3,
        plan.trajectory.samples.len(),
        plan.duration_s()
    );
}

/// A leg's hip pitch axis to its ankle pitch axis, in `kin`'s configuration.
fn leg_length_m(model: &RobotModel, kin: &Kinematics, foot: Foot) -> f64 {
    let side = if foot == Foot::Right { "R" } else { "L" };
    let at =
        |joint: &str| kin.link_pose(model.joint_link(&format!("{side}_{joint}")).unwrap()).translation.vector;
    (at("HIP_P") - at("ANKLE_P")).norm()
}

/// A low rise on a deep tread (the envelope's 0.10 x 0.36): the leading leg lands within its
/// reach (`reach_fraction` of its length), its knee bent, not straight. The legs' model put
/// the hip over the trailing ankle; the IK put it 6-7 cm behind the CoM and 12 cm to the
/// side, and the leg landed 0.705 m from hip to ankle where it reaches 0.671 m, the knee at
/// 2-5 deg: a strut whose touchdown impact slid the sole.
#[test]
fn the_leading_leg_lands_with_its_knee_bent_on_a_low_deep_step() {
    let mut s = Scenario::default();
    s.staircase.rise_m = 0.10;
    s.staircase.tread_m = 0.36;
    let (scene, r) = scenario_plan(&s);
    let plan = r.expect("0.10 x 0.36 is climbable");
    check(&plan, Some(&scene));
    let model = hrp4::model().unwrap();
    let knee = Q_JOINTS + model.joint_id("R_KNEE_P").unwrap();
    let touchdowns: Vec<f64> = plan
        .segments
        .iter()
        .enumerate()
        .filter(|(_, sg)| sg.phase == Phase::SwingRight)
        .map(|(i, _)| plan.trajectory.samples.iter().rev().find(|smp| smp.segment == i).unwrap().q[knee])
        .collect();
    assert!(touchdowns.len() >= 3);
    for (k, bend) in touchdowns.iter().enumerate() {
        assert!(bend.to_degrees() > 20.0, "touchdown {}: the knee at {:.1} deg", k + 1, bend.to_degrees());
    }
}

/// A trailing foot lifted from a tread well behind the hip keeps its ankle short of the
/// joint's limit, and the rest of the body moves no faster for it: measured on the tracked
/// trajectory, not on the gait's leg model. A sole lifted level there asks the ankle more
/// than the joint has, and the IK, its ankle held at the limit, keeps the sole level by
/// rolling the pelvis and bowing the chest at its joint speed bound, which turns the stance
/// sole on its tread (`gait::toe_down`).
#[test]
fn a_trailing_foot_lifted_behind_the_hip_keeps_its_ankle_and_the_body_unhurried() {
    let model = hrp4::model().unwrap();
    let p = PlanParams::default();
    let joint = |name: &str| model.joint_id(name).unwrap();
    // 12 steps of 13.7 cm on 37 cm treads, a start turned 6.8 deg.
    let deep_treads = common::regression("a-sole-twisting-under-load-turned-the-estimate");
    let mut plans: Vec<(&str, Plan)> = [("Exp. 1", Scenario::default()), ("deep treads", deep_treads)]
        .into_iter()
        .map(|(name, s)| {
            let (scene, r) = scenario_plan(&s);
            let plan = r.unwrap_or_else(|e| panic!("{name}: {e}"));
            check(&plan, Some(&scene));
            (name, plan)
        })
        .collect();
    for (name, plan) in &plans {
        for ankle in ["R_ANKLE_P", "L_ANKLE_P"] {
            let j = joint(ankle);
            let lower = model.joints()[j].lower_rad;
            let least = plan
                .trajectory
                .samples
                .iter()
                .map(|smp| smp.q[Q_JOINTS + j] - lower)
                .fold(f64::INFINITY, f64::min);
            println!("{name}: {ankle} at least {least:.3} rad from its limit");
            assert!(least > 0.05, "{name}: {ankle} came within {least:.3} rad of its limit");
        }
    }
    // While the trailing (left) foot lifts, no joint but its knee, which raises it, turns at
    // the IK's joint speed bound.
    let (_, plan) = plans.pop().unwrap();
    let bound = p.ik.max_joint_speed_rad_s;
    let lifting_knee = joint("L_KNEE_P");
    let samples = &plan.trajectory.samples;
    let mut fastest = (0.0f64, String::new(), 0.0);
    for w in samples.windows(2) {
        if plan.segments[w[1].segment].phase != Phase::LiftSwingLeft {
            continue;
        }
        let dt = w[1].t_s - w[0].t_s;
        for (j, jt) in model.joints().iter().enumerate().filter(|(j, _)| *j != lifting_knee) {
            let speed = (w[1].q[Q_JOINTS + j] - w[0].q[Q_JOINTS + j]).abs() / dt;
            if speed > fastest.0 {
                fastest = (speed, jt.name.clone(), w[1].t_s);
            }
        }
    }
    println!(
        "deep treads: fastest joint while the trailing foot lifts: {} at {:.2} rad/s (t = {:.2} s)",
        fastest.1, fastest.0, fastest.2
    );
    assert!(
        fastest.0 < 0.9 * bound,
        "{} turns at {:.2} rad/s at t = {:.2} s while the trailing foot lifts (the IK's bound {bound:.2})",
        fastest.1,
        fastest.0,
        fastest.2
    );
}

/// The touchdown's measurement (`reach::touchdown_drops_m`) on Exp. 1's plan: a reach
/// beyond every landing asks for no drop; a reach 1 cm short of the first landing's hip to
/// ankle asks for the drop that brings that distance, in three dimensions, to the reach; a
/// reach shorter than the hip is across from the ankle is refused as `TouchdownReach`.
#[test]
fn the_touchdown_reach_is_measured_and_refused_across() {
    let plan = scenario_plan(&Scenario::default()).1.expect("Exp. 1 is climbable");
    let model = hrp4::model().unwrap();
    let (segs, traj) = (&plan.segments, &plan.trajectory);
    assert!(reach::touchdown_drops_m(&model, segs, traj, 1.0).unwrap().iter().all(|&d| d == 0.0));
    let i = segs.iter().position(|sg| sg.phase == Phase::SwingRight).unwrap();
    let landed = traj.samples.iter().rev().find(|smp| smp.segment == i).unwrap();
    let mut kin = Kinematics::new(&model);
    kin.update(&landed.q).unwrap();
    let at = |joint: &str| kin.link_pose(model.joint_link(joint).unwrap()).translation.vector;
    let d = at("R_HIP_P") - at("R_ANKLE_P");
    let reach_m = d.norm() - 0.01;
    let drops = reach::touchdown_drops_m(&model, segs, traj, reach_m).unwrap();
    let lowered = Vector3::new(d.x, d.y, d.z - drops[segs[i].stance]);
    assert!((lowered.norm() - reach_m).abs() < 1e-9, "{} against {reach_m}", lowered.norm());
    match reach::touchdown_drops_m(&model, segs, traj, d.xy().norm() - 1e-3) {
        Err(PlanError::TouchdownReach { stance, .. }) => assert_eq!(stance, segs[i].stance),
        other => panic!("expected a TouchdownReach refusal, got {other:?}"),
    }
}

#[test]
fn exp1_ground_truth_is_planned_to_the_top() {
    let (scene, r) = scenario_plan(&Scenario::default());
    let plan = r.expect("Exp. 1 is climbable");
    check(&plan, Some(&scene));
    // Both feet end on the top step, in the middle of its tread.
    let top = scene.steps().last().unwrap();
    let last = plan.stances.last().unwrap();
    for f in [&last.right, &last.left] {
        assert!((f.translation.z - top.height_m).abs() < 1e-9);
        assert!((f.translation.x - top.center().x).abs() < 1e-9);
    }
}

/// A plan takes the CoM to half-sitting's height above the soles whatever the start's: from a
/// body that sagged (knees 0.25 rad more bent) or rose (0.3 rad straighter), the plan's end
/// stands at half-sitting's height, within the IK's CoM tolerance. The closed loop plans from
/// where the last execution left the body; a plan that kept its start's height carried every
/// execution's offset into the next plan (tests/climb.rs
/// `a_flight_climbed_faster_keeps_its_standing_height`).
#[test]
fn a_plan_ends_at_standing_height_from_a_sagged_or_raised_start() {
    let model = hrp4::model().unwrap();
    let scene = common::scene_of(&Scenario::default());
    let rects = rectangles::from_step_tops(scene.steps());
    let soles = hrp4::sole_frames(&model).unwrap();
    let mut kin = Kinematics::new(&model);
    let mut height = |q: &[f64]| {
        kin.update(q).unwrap();
        kin.com().z - (kin.frame_pose(soles[0]).translation.z + kin.frame_pose(soles[1]).translation.z) / 2.0
    };
    let p = PlanParams::default();
    let standing = height(&start_q(&model, &scene.robot_start()));
    for bend_rad in [0.25, -0.3] {
        let mut joints = hrp4::half_sitting_joints(&model).unwrap();
        for side in ["R", "L"] {
            let mut turn = |joint: &str, by_rad: f64| {
                joints[model.joint_id(&format!("{side}_{joint}")).unwrap()] += by_rad
            };
            turn("KNEE_P", bend_rad);
            turn("HIP_P", -bend_rad / 2.0);
            turn("ANKLE_P", -bend_rad / 2.0);
        }
        let q0 = hrp4::standing_config(&model, &joints, &scene.robot_start()).unwrap();
        let started = height(&q0);
        assert!((started - standing).abs() > 0.02, "the start is {:.1} mm off", (started - standing) * 1e3);
        let plan = PlanRequest::new(&model, &q0, &rects, &p).max_stances(Some(2)).climb().unwrap();
        // The gait's last waypoint is at standing height exactly; the IK reaches it within its
        // CoM tolerance.
        let last = plan.stances.last().unwrap();
        let planned = plan.segments.last().unwrap().com_end.z
            - (last.right.translation.z + last.left.translation.z) / 2.0;
        assert!((planned - standing).abs() < 1e-9, "planned {:+.1} mm off", (planned - standing) * 1e3);
        let ended = height(&plan.trajectory.samples.last().unwrap().q);
        println!(
            "knees {bend_rad:+} rad: start {:+.1} mm, end {:+.1} mm off standing height",
            (started - standing) * 1e3,
            (ended - standing) * 1e3
        );
        assert!(
            (ended - standing).abs() < p.ik.com_tolerance_m,
            "from {:+.1} mm, the plan ends {:+.1} mm off standing height",
            (started - standing) * 1e3,
            (ended - standing) * 1e3
        );
    }
}

/// The default timing is the quasi-static one `DEFAULT_SPEEDUP` times faster, to the bit (so
/// `--speedup 2` of the quasi-static timing runs exactly the default). Without the CoM's
/// acceleration bound (`StepParams::max_zmp_shift_m`, which no speed-up scales) Exp. 1's plan
/// at the default takes that many times less time along the same stances; with it (the
/// default, `ZMP_SHIFT_M`), each segment is the quasi-static one `DEFAULT_SPEEDUP` times
/// faster but where the bound keeps it longer.
#[test]
fn the_default_timing_is_the_quasi_static_one_made_faster() {
    use stairbench::planning::gait::{shortest_for_zmp_s, DEFAULT_SPEEDUP, ZMP_SHIFT_M};
    assert_eq!(PlanParams::default(), PlanParams::quasi_static().faster(DEFAULT_SPEEDUP));
    assert_eq!(PlanParams::default().step.max_zmp_shift_m, ZMP_SHIFT_M);
    let (model, rects, q0) = exp1_on_its_tops();
    let plan = |p: &PlanParams| PlanRequest::new(&model, &q0, &rects, p).climb().unwrap();
    let unbound =
        |p: PlanParams| PlanParams { step: StepParams { max_zmp_shift_m: f64::INFINITY, ..p.step }, ..p };
    let (free, fast) = (plan(&unbound(PlanParams::quasi_static())), plan(&unbound(PlanParams::default())));
    assert_eq!(free.stances, fast.stances);
    let ratio = free.duration_s() / fast.duration_s();
    assert!((ratio - DEFAULT_SPEEDUP).abs() < 0.01, "x {ratio}");
    let (slow, fast) = (plan(&PlanParams::quasi_static()), plan(&PlanParams::default()));
    assert_eq!(slow.stances, fast.stances);
    // The quasi-static timing is never held by the bound: with it, every segment as without.
    assert_eq!(slow.segments.len(), free.segments.len());
    for (k, (a, b)) in slow.segments.iter().zip(&free.segments).enumerate() {
        assert!(
            (a.duration_s - b.duration_s).abs() < 1e-9,
            "segment {k}: {} s, {} s unbound",
            a.duration_s,
            b.duration_s
        );
    }
    let body = standing_body(&model, hrp4::sole_frames(&model).unwrap()).unwrap();
    let mut held = 0;
    for (k, (a, b)) in slow.segments.iter().zip(&fast.segments).enumerate() {
        let path_m = (b.com_end - b.com_start).norm();
        let shortest_s = shortest_for_zmp_s(path_m, body.com_height_m, ZMP_SHIFT_M);
        let expected_s = (a.duration_s / DEFAULT_SPEEDUP).max(shortest_s);
        println!("{k}: {:.3} s -> {:.3} s (ZMP bound {shortest_s:.3} s)", a.duration_s, b.duration_s);
        assert!((b.duration_s - expected_s).abs() < 0.02 * expected_s, "segment {k}: {} s", b.duration_s);
        held += usize::from(shortest_s > a.duration_s / DEFAULT_SPEEDUP);
    }
    let ratio = slow.duration_s() / fast.duration_s();
    println!("with the bound: x {ratio:.3} faster, {held} of {} segments held by it", fast.segments.len());
    assert!(held > 0 && ratio > 1.2 && ratio < DEFAULT_SPEEDUP, "x {ratio}, {held} held");
}

/// Every segment's CoM acceleration, taken on its time law by finite differences (not by the
/// law's derivative), shifts the ZMP (linear inverted pendulum: the CoM's height above its
/// lowest support sole over g, times the horizontal acceleration) no more than
/// `StepParams::max_zmp_shift_m` (its default, `ZMP_SHIFT_M`), at the default timing and
/// twice faster. With the CoM's speed bound alone, x 1.5 the quasi-static timing asks 41.7 mm
/// (its 10 cm sideways shifts), the default's x 2 74 mm, and twice faster four times that.
#[test]
fn the_coms_acceleration_keeps_the_zmp_within_its_allowed_shift() {
    use stairbench::planning::motion::com_target;
    let (model, rects, q0) = exp1_on_its_tops();
    assert_eq!(StepParams::default().max_zmp_shift_m, stairbench::planning::gait::ZMP_SHIFT_M);
    for factor in [1.0, 2.0] {
        let p = PlanParams::default().faster(factor);
        let plan = PlanRequest::new(&model, &q0, &rects, &p).climb().unwrap();
        let mut most_m: f64 = 0.0;
        for seg in &plan.segments {
            let n = 1000;
            let dt = seg.duration_s / n as f64;
            let at = |i: usize| com_target(seg, i as f64 / n as f64).0;
            let lowest_sole_z =
                seg.support.iter().map(|(_, s)| s.translation.z).fold(f64::INFINITY, f64::min);
            for i in 1..n {
                let (a, b, c) = (at(i - 1), at(i), at(i + 1));
                let accel = (a.coords - 2.0 * b.coords + c.coords) / (dt * dt);
                let height_m = b.z - lowest_sole_z;
                most_m = most_m.max(height_m / 9.81 * accel.xy().norm());
            }
        }
        println!("x {factor}: the ZMP shifted at most {:.1} mm", most_m * 1e3);
        assert!(most_m <= p.step.max_zmp_shift_m * 1.02, "x {factor}: {:.1} mm", most_m * 1e3);
        // The bound is what holds the fastest moves, not a far-off ceiling.
        assert!(most_m > p.step.max_zmp_shift_m * 0.9, "x {factor}: {:.1} mm", most_m * 1e3);
    }
}

#[test]
fn the_papers_rectangles_are_planned() {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/paper_exp1/rectangles.txt");
    let text = std::fs::read_to_string(&path).expect("the paper's Exp. 1 rectangles, a committed fixture");
    let rects = rectangles::parse(&text).unwrap();
    assert_eq!(rects.len(), 3);
    let first = rectangles::by_height(&rects)[0];
    // The robot on the floor (1.38 m below the file's origin, its README) in front of step 1.
    let front = first.center() - first.along() * (first.depth_m() / 2.0 + 0.20);
    let start = Isometry3::from_parts(Translation3::new(front.x, front.y, -1.38), UnitQuaternion::identity());
    let model = hrp4::model().unwrap();
    let plan = PlanRequest::new(&model, &start_q(&model, &start), &rects, &PlanParams::default())
        .climb()
        .expect("the paper's climb");
    assert_eq!(plan.stances.len(), 3, "one stance per step, no approach steps needed");
    check(&plan, None);
}

/// High rises on treads deeper than the legs' stride allows for them (the envelope's cells
/// 0.24 x 0.36 and 0.26 x 0.32-0.40 were refused: "the leading knee would fold beyond 125
/// deg"): planned to the top from the true steps, every property checked.
#[test]
fn high_rises_on_deep_treads_are_planned_within_the_knee() {
    for (rise_m, tread_m) in [(0.24, 0.36), (0.26, 0.32), (0.26, 0.40)] {
        let mut s = Scenario::default();
        s.staircase.rise_m = rise_m;
        s.staircase.tread_m = tread_m;
        let (scene, r) = scenario_plan(&s);
        let plan = r.unwrap_or_else(|e| panic!("{rise_m} x {tread_m}: {e}"));
        assert_eq!(plan.stances.last().and_then(|st| st.step), Some(scene.steps().len() - 1));
        check(&plan, Some(&scene));
    }
}

/// The footholds' reach ([`Legs::max_stride_m`]) and the gait's own knee check agree: a
/// step up with the feet just inside the legs' stride for its rise is planned, just beyond
/// it refused for the knee; on soles tilted a degree (a measured start stance can be),
/// within the footholds' 5 mm slack.
#[test]
fn the_legs_stride_is_the_gaits_knee_check() {
    use stairbench::planning::gait::{segments, Body, Legs, StepParams};
    let model = hrp4::model().unwrap();
    let q0 = start_q(&model, &Isometry3::identity());
    let mut kin = Kinematics::new(&model);
    kin.update(&q0).unwrap();
    let soles = hrp4::sole_frames(&model).unwrap();
    let body = Body::measure(&kin, soles).unwrap();
    let p = StepParams::default();
    let legs = Legs::of(&body, &p);
    let start = stairbench::planning::plan::stance_of(&kin, soles);
    let x0 = start.left.translation.x;
    let step_at = |d: f64, rise: f64, tilt_deg: f64| {
        let tilt = UnitQuaternion::from_euler_angles(0.0, -tilt_deg.to_radians(), 0.0);
        let sole = |s: &Isometry3<f64>| {
            Isometry3::from_parts(Translation3::new(x0 + d, s.translation.y, rise), tilt * s.rotation)
        };
        let to = stairbench::planning::Stance {
            right: sole(&start.right),
            left: sole(&start.left),
            step: Some(0),
        };
        segments(kin.com(), &start, &[to], &[], &body, &p)
    };
    for rise in [0.22, 0.26] {
        let max = legs.max_stride_m(rise);
        assert!(max > 0.28 && max < 0.40, "{rise}: {max}");
        assert!(
            step_at(max - 1e-4, rise, 0.0).is_ok(),
            "{rise} m at {:.4} m: {:?}",
            max - 1e-4,
            step_at(max - 1e-4, rise, 0.0).err()
        );
        assert!(
            matches!(step_at(max + 1e-3, rise, 0.0), Err(PlanError::KneeFold { .. })),
            "{rise} m at {:.4} m: {:?}",
            max + 1e-3,
            step_at(max + 1e-3, rise, 0.0).map(|_| ())
        );
        for tilt in [-1.0, 1.0] {
            assert!(step_at(max - 5e-3, rise, tilt).is_ok(), "{rise} m tilted {tilt} deg");
        }
    }
}

fn refusal(s: &Scenario) -> PlanError {
    match scenario_plan(s).1 {
        Ok(p) => panic!("the plan must be refused, got {} stances", p.stances.len()),
        Err(e) => e,
    }
}

#[test]
fn unclimbable_staircases_are_refused_with_the_reason() {
    let mut high = Scenario::default();
    high.staircase.rise_m = 0.40;
    assert!(matches!(refusal(&high), PlanError::HighRise { step: 0, .. }), "{}", refusal(&high));
    let mut short = Scenario::default();
    short.staircase.tread_m = 0.18;
    assert!(matches!(refusal(&short), PlanError::ShortTread { step: 0, .. }));
    let mut narrow = Scenario::default();
    narrow.staircase.width_m = 0.26;
    assert!(matches!(refusal(&narrow), PlanError::OffTheSide { step: 0, .. }));
    println!(
        "40 cm rise: {}\n18 cm tread: {}\n26 cm wide: {}",
        refusal(&high),
        refusal(&short),
        refusal(&narrow)
    );
}

fn moved(r: &PlaneSegment, dx: f64) -> PlaneSegment {
    PlaneSegment::new(
        r.center() + Vector3::new(dx, 0.0, 0.0),
        r.along(),
        r.depth_m(),
        r.width_m(),
        Vector3::z(),
        0,
    )
    .unwrap()
}

#[test]
fn a_gap_a_missing_step_and_nothing_are_refused() {
    let model = hrp4::model().unwrap();
    let mut s = Scenario::default();
    s.staircase.steps = 5;
    let scene = common::scene_of(&s);
    let rects = rectangles::from_step_tops(scene.steps());
    let q0 = start_q(&model, &scene.robot_start());
    let p = PlanParams::default();
    // Steps 4 and 5 moved 15 cm away: a gap before step 4.
    let gap: Vec<PlaneSegment> =
        rects.iter().enumerate().map(|(i, r)| if i >= 3 { moved(r, 0.15) } else { r.clone() }).collect();
    let e = PlanRequest::new(&model, &q0, &gap, &p).climb().unwrap_err();
    assert!(matches!(e, PlanError::Gap { step: 3, .. }), "{e}");
    // Step 3 not seen: the rise to step 4 is twice the others.
    let missing: Vec<PlaneSegment> =
        rects.iter().enumerate().filter(|(i, _)| *i != 2).map(|(_, r)| r.clone()).collect();
    let e2 = PlanRequest::new(&model, &q0, &missing, &p).climb().unwrap_err();
    assert!(matches!(e2, PlanError::MissingStep { step: 2, .. }), "{e2}");
    assert_eq!(PlanRequest::new(&model, &q0, &[], &p).climb().unwrap_err(), PlanError::NoSteps);
    println!("gap: {e}\nmissing: {e2}");
}

#[test]
fn a_yawed_staircase_is_planned_along_its_own_direction() {
    let mut s = Scenario::default();
    s.staircase.yaw_deg = 30.0;
    s.robot.yaw_deg = 30.0;
    let start = s.staircase.start_m;
    let back = (30f64.to_radians().cos() * 0.6, 30f64.to_radians().sin() * 0.6);
    s.robot.position_m = [start[0] - back.0, start[1] - back.1];
    let (scene, r) = scenario_plan(&s);
    let plan = r.expect("a yawed Exp. 1 is climbable");
    check(&plan, Some(&scene));
    let yaw = plan.stances.last().unwrap().right.rotation.euler_angles().2;
    assert!((yaw - 30f64.to_radians()).abs() < 1e-6, "feet yaw {} deg", yaw.to_degrees());
}

/// The base's largest yaw from `heading` (radians) over the plan's samples from `from_s`
/// on, in degrees.
fn base_turn(plan: &Plan, heading: f64, from_s: f64) -> f64 {
    plan.trajectory.samples.iter().filter(|smp| smp.t_s >= from_s).fold(0.0f64, |most, smp| {
        let q = &smp.q;
        let rot = base_pose(q).rotation;
        let turn = UnitQuaternion::from_euler_angles(0.0, 0.0, rot.euler_angles().2 - heading).angle();
        most.max(turn.to_degrees())
    })
}

#[test]
fn the_pelvis_turns_to_face_the_flight() {
    // A robot started turned from the flight: the feet are set along the flight, and the
    // pelvis held its starting heading all the way up (the hips twisted 17 deg to point the
    // feet up the steps; in a stairwell, wide suite case 38, the twisted robot fell).
    let mut s = Scenario::default();
    s.robot.yaw_deg = -17.0;
    let (_, r) = scenario_plan(&s);
    let plan = r.expect("Exp. 1 from a turned start is climbable");
    // Facing the flight (yaw 0) as the feet are, once both stand on the top step (on the
    // way the IK still turns the pelvis as it turns a robot started facing the flight: up to
    // 14 deg while a foot is lifted, with the posture's weight), and never turned further
    // from it than at the start.
    let top_s = plan.trajectory.samples.last().map_or(0.0, |smp| smp.t_s);
    let end = base_turn(&plan, 0.0, top_s);
    assert!(end < 1.0, "turned {end:.1} deg from the flight on the top step");
    let most = base_turn(&plan, 0.0, 0.0);
    assert!(most <= 17.0 + 0.1, "turned {most:.1} deg away");
}

/// Exp. 1's true step tops and the robot's start turned 17 deg from the flight,
/// half-sitting: a plan whose pelvis turns on the way.
fn exp1_turned_from_the_flight() -> (RobotModel, Vec<PlaneSegment>, Vec<f64>) {
    let model = hrp4::model().unwrap();
    let mut s = Scenario::default();
    s.robot.yaw_deg = -17.0;
    let scene = common::scene_of(&s);
    let q0 = start_q(&model, &scene.robot_start());
    (model, rectangles::from_step_tops(scene.steps()), q0)
}

/// How far `other` strays from `path` with its time `ratio` times as long: the largest
/// distance of a foot or the CoM, metres, and of the pelvis's orientation, degrees.
fn strays(
    path: &stairbench::planning::motion::JointTrajectory,
    other: &stairbench::planning::motion::JointTrajectory,
    ratio: f64,
) -> (f64, f64) {
    let (mut worst_m, mut worst_deg) = (0.0f64, 0.0f64);
    for smp in &path.samples {
        let at = other.sample_at(ratio * smp.t_s);
        for f in 0..2 {
            worst_m = worst_m.max((smp.feet[f].translation.vector - at.feet[f].translation.vector).norm());
        }
        worst_m = worst_m.max((smp.com - at.com).norm());
        worst_deg =
            worst_deg.max(base_pose(&smp.q).rotation.angle_to(&base_pose(&at.q).rotation).to_degrees());
    }
    (worst_m, worst_deg)
}

/// A plan made 1.5 times faster is the same path in less time: at each instant of the faster
/// plan the pelvis, the feet and the CoM are where the plan at x 1 has them 1.5 times later,
/// within the IK's tick (Exp. 1 from a start turned 17 deg from the flight, so the pelvis
/// turns on the way). With the IK's gains left at x 1 (its joint speed bound alone made
/// faster) the tasks had less time to converge: the pelvis ended 1.3 deg from the flight
/// instead of 0.36 deg.
#[test]
fn a_plan_made_faster_is_the_same_path_in_less_time() {
    let (model, rects, q0) = exp1_turned_from_the_flight();
    // Without the CoM's acceleration bound (not scaled by a speed-up), every segment is 1.5
    // times shorter.
    let d = PlanParams::default();
    let p = PlanParams { step: StepParams { max_zmp_shift_m: f64::INFINITY, ..d.step }, ..d };
    let slow = PlanRequest::new(&model, &q0, &rects, &p).climb().unwrap();
    let fast = PlanRequest::new(&model, &q0, &rects, &p.faster(1.5)).climb().unwrap();
    assert_eq!(slow.stances, fast.stances);
    let ratio = slow.trajectory.duration_s() / fast.trajectory.duration_s();
    assert!((ratio - 1.5).abs() < 0.01, "x {ratio}");
    let (worst_m, worst_deg) = strays(&fast.trajectory, &slow.trajectory, ratio);
    let top = |plan: &Plan| base_turn(plan, 0.0, plan.trajectory.samples.last().map_or(0.0, |smp| smp.t_s));
    println!(
        "apart at most {:.2} mm, {worst_deg:.2} deg; on the top step {:.2} / {:.2} deg from the flight",
        worst_m * 1e3,
        top(&slow),
        top(&fast)
    );
    assert!(
        (top(&fast) - top(&slow)).abs() < 0.1,
        "the pelvis ends {:.2} deg from the flight, at x 1 {:.2}",
        top(&fast),
        top(&slow)
    );
    assert!(
        worst_deg < 1.0 && worst_m < 0.01,
        "the faster plan strays {worst_deg:.2} deg, {:.1} mm",
        worst_m * 1e3
    );
}

/// A segment the planner slows for its turn (`IkParams::max_yaw_moment_share`) is tracked
/// with the IK's rates as many times slower: the same path in k times the time, asking a
/// smaller moment about the vertical. Tracked at the IK's own rates, its tasks had more
/// time to converge and the pelvis of a robot started turned from the flight turned
/// another way, and a reconfiguration at the joints' speed bound stayed as fast (CHANGELOG,
/// forty-ninth session).
#[test]
fn a_segment_slowed_for_its_turn_is_the_same_path_asking_a_smaller_moment() {
    use stairbench::planning::motion::track_until;
    let (model, rects, q0) = exp1_turned_from_the_flight();
    let p = PlanParams::default();
    let plan = PlanRequest::new(&model, &q0, &rects, &p).climb().unwrap();
    let k = 2.0;
    let mut slow = plan.segments.clone();
    for seg in &mut slow {
        seg.duration_s *= k;
    }
    let slowed = vec![k; slow.len()];
    let (traj, tracking, stopped) =
        track_until(&model, &q0, &slow, &plan.blocks, plan.seen.clone(), &p.ik, &slowed, &mut |_, _| {
            Ok(false)
        })
        .unwrap();
    assert_eq!(stopped, None);
    let (worst_m, worst_deg) = strays(&plan.trajectory, &traj, k);
    let [_, fast_nm] = plan.tracking.moments_nm();
    let [_, slow_nm] = tracking.moments_nm();
    println!(
        "apart at most {:.2} mm, {worst_deg:.2} deg; about the vertical {fast_nm:.2} N m, slowed x {k}: {slow_nm:.2} N m",
        worst_m * 1e3
    );
    assert!(
        worst_deg < 1.0 && worst_m < 0.01,
        "the slowed path strays {worst_deg:.2} deg, {:.1} mm",
        worst_m * 1e3
    );
    // It falls less than 1/k^2 would have it, but more than 1/k.
    assert!(slow_nm < fast_nm / k, "slowed x {k}, the moment fell from {fast_nm:.2} to {slow_nm:.2} N m");
}

/// Each segment is charged (`Tracking::segment_yaw_moments_nm`, what the planner slows a
/// segment by) at least the moment about the vertical of every 0.1 s window whose motion it
/// takes part in: a window over a boundary is the two segments' motion, and charged to the
/// later alone, slowing that one may not bring it down. The windows here are taken again
/// from the plan's samples, each holding the segments of the ticks it spans.
#[test]
fn every_segment_a_turning_window_spans_is_charged_its_moment() {
    use stairbench::robot::momentum::{centroidal_angular_momentum, RATE_WINDOW_S};
    let (model, rects, q0) = exp1_turned_from_the_flight();
    let p = PlanParams::default();
    let plan = PlanRequest::new(&model, &q0, &rects, &p).climb().unwrap();
    let charged = &plan.tracking.segment_yaw_moments_nm;
    let samples = &plan.trajectory.samples;
    let mut kin = Kinematics::new(&model);
    let mut poses = Vec::with_capacity(samples.len());
    for s in samples {
        kin.update(&s.q).unwrap();
        poses.push(kin.link_poses().to_vec());
    }
    // The momentum over each tick (sample j - 1 to j), and the windows of n ticks.
    let dt = samples[1].t_s - samples[0].t_s;
    let l: Vec<Vector3<f64>> = (1..samples.len())
        .map(|j| centroidal_angular_momentum(&model, &poses[j - 1], &poses[j], dt))
        .collect();
    let n = (RATE_WINDOW_S / dt - 1e-6).ceil() as usize;
    let (mut largest, mut short) = (0.0f64, Vec::new());
    for j in n..l.len() {
        let yaw_nm = ((l[j].z - l[j - n].z) / (n as f64 * dt)).abs();
        largest = largest.max(yaw_nm);
        // Tick j is sample j + 1's; the window's first momentum is tick j - n's.
        let mut spanned: Vec<usize> = samples[j - n + 1..=j + 1].iter().map(|s| s.segment).collect();
        spanned.dedup();
        for si in spanned {
            if charged.get(si).copied().unwrap_or(0.0) < yaw_nm - 1e-9 {
                short.push((samples[j + 1].t_s, si, yaw_nm, charged.get(si).copied()));
            }
        }
    }
    println!(
        "largest window {largest:.3} N m (the plan's {:.3}); charged {charged:.2?}",
        plan.tracking.max_yaw_moment_nm
    );
    assert!(
        (largest - plan.tracking.max_yaw_moment_nm).abs() < 1e-6,
        "the windows taken again differ from the plan's"
    );
    assert!(
        short.is_empty(),
        "segments charged less than a window they span (t, segment, window, charged): {short:.3?}"
    );
}

/// A plan whose turn about the vertical its slowing rounds cannot bring within the plan's
/// bound is refused, with the moment it still asks, not kept with its moment in its
/// tracking and nothing said.
#[test]
fn a_turn_the_slowing_cannot_hold_is_refused_not_kept() {
    let (model, rects, q0) = exp1_on_its_tops();
    let mut p = PlanParams::default();
    p.ik.max_yaw_moment_share = 0.001;
    match PlanRequest::new(&model, &q0, &rects, &p).climb() {
        Err(PlanError::TurnUnheld { moment_nm, limit_nm, .. }) => {
            println!("refused: {moment_nm:.2} N m against {limit_nm:.3}");
            assert!(moment_nm > limit_nm, "{moment_nm} against {limit_nm}");
        }
        other => panic!(
            "a bound at 0.001 of the soles' hold was kept: {:?}",
            other.map(|plan| plan.tracking.moments_nm())
        ),
    }
}

/// The upper body's least distance to `points` over the plan's samples, by brute force over
/// every capsule and point (the planner's own query goes through a k-d tree), and the
/// highest y any upper-body capsule reached.
fn upper_body_reach(plan: &Plan, points: &[Point3<f64>]) -> (f64, [f64; 2]) {
    let model = hrp4::model().unwrap();
    let mut kin = Kinematics::new(&model);
    let limbs = clearance::upper_limbs(&model, &hrp4::sole_frames(&model).unwrap());
    let (mut least, mut reach_y) = (f64::INFINITY, [f64::INFINITY, f64::NEG_INFINITY]);
    for s in &plan.trajectory.samples {
        kin.update(&s.q).unwrap();
        for limb in &limbs {
            let c = limb.capsule(&kin);
            reach_y[0] = reach_y[0].min(c.a.y.min(c.b.y) - c.radius_m);
            reach_y[1] = reach_y[1].max(c.a.y.max(c.b.y) + c.radius_m);
            least = points.iter().map(|p| c.distance_m(p)).fold(least, f64::min);
        }
    }
    (least, reach_y)
}

/// A wall of seen points across x and z at `y`, metres.
fn wall_at(y: f64) -> Vec<Point3<f64>> {
    (0..80)
        .flat_map(|i| (0..60).map(move |k| Point3::new(-0.5 + 0.03 * i as f64, y, 0.3 + 0.03 * k as f64)))
        .collect()
}

/// Exp. 1's first two stances planned knowing of no surroundings, the lanes held where the
/// robot stands (a zero body half width, so that only the IK acts): the model, the
/// rectangles, the start, the parameters and the plan.
fn planned_blind() -> (RobotModel, Vec<PlaneSegment>, Vec<f64>, PlanParams, Plan) {
    let model = hrp4::model().unwrap();
    let scene = common::scene_of(&Scenario::default());
    let rects = rectangles::from_step_tops(scene.steps());
    let q0 = start_q(&model, &scene.robot_start());
    let mut p = PlanParams::default();
    p.gait.body_half_width_m = 0.0;
    let blind = PlanRequest::new(&model, &q0, &rects, &p)
        .max_stances(Some(2))
        .climb()
        .expect("planned without surroundings");
    (model, rects, q0, p, blind)
}

/// Issue 19, stairwells: the wrist met a side wall the lidar saw. With the lanes held where
/// the robot stands (a zero body half width, so that only the IK acts), a wall 2 cm beyond
/// the farthest the arms reach in a plan that knows of no wall: planned among the wall's
/// points, the body keeps its 3 cm from every one of them at every sample.
#[test]
fn the_ik_keeps_the_body_off_a_wall_the_lidar_saw() {
    let (model, rects, q0, p, blind) = planned_blind();
    let (_, [_, reach_y]) = upper_body_reach(&blind, &[]);
    let wall = wall_at(reach_y + 0.02);
    let (blind_least, _) = upper_body_reach(&blind, &wall);
    assert!(blind_least < p.ik.body_clearance_m - 0.005, "the blind plan comes within {blind_least} m");
    let seen = std::sync::Arc::new(clearance::SeenPoints::new(wall.clone()));
    let among = PlanRequest::new(&model, &q0, &rects, &p)
        .among(seen)
        .max_stances(Some(2))
        .climb()
        .expect("planned among the wall");
    let (least, _) = upper_body_reach(&among, &wall);
    assert!(least >= p.ik.body_clearance_m - 1e-3, "the body came within {least} m of the wall");
    // The plan says where: its least body clearance is the brute-force one, at a wall point.
    let nearest = among.tracking.nearest_body_surface.as_ref().expect("the body came near the wall");
    assert!(
        (nearest.clearance_m - least).abs() < 1e-6,
        "reported {} m, brute force {least} m",
        nearest.clearance_m
    );
    assert!(wall.iter().any(|q| (q.coords - Vector3::from(nearest.point_m)).norm() < 1e-9));
    assert_eq!(among.stances, blind.stances, "the lanes were held: only the IK acted");
    // The wall where the body stands: refused, naming the limb, not planned through.
    let through: Vec<Point3<f64>> = wall.iter().map(|q| Point3::new(q.x, reach_y - 0.2, q.z)).collect();
    let e = PlanRequest::new(&model, &q0, &rects, &p)
        .among(std::sync::Arc::new(clearance::SeenPoints::new(through)))
        .max_stances(Some(2))
        .climb()
        .expect_err("a wall through the body");
    // Its foot of wall stands in the left foot's lane: the footholds may refuse it first.
    assert!(
        matches!(
            e,
            PlanError::BodyNearSurface { .. }
                | PlanError::Ik { .. }
                | PlanError::ComStrays { .. }
                | PlanError::FloorObstructed { .. }
                | PlanError::TreadObstructed { .. }
        ),
        "{e}"
    );
}

/// Regression `walking-chest-ratcheted-along-a-nose`: the IK held each capsule off its one
/// nearest point, and a capsule moving along a row of points was held off each in turn
/// while it came nearer the next: the chest over a nose, its two nearest points 8 cm apart,
/// went from 30 mm to 19.8 and the plan was refused. Bars of points 6.5 and 10 cm apart
/// across the path of the blind plan's chest, where it leans farthest forward and 5 cm
/// above, 1 cm into it: planned among each, the body keeps its clearance from every point
/// to a third of a millimetre (held off its nearest alone, it came 0.6 mm nearer).
#[test]
fn the_ik_holds_the_body_off_a_row_of_points_not_only_its_nearest() {
    let (model, rects, q0, p, blind) = planned_blind();
    let mut kin = Kinematics::new(&model);
    let chest = clearance::upper_limbs(&model, &hrp4::sole_frames(&model).unwrap())
        .into_iter()
        .find(|l| l.name == "CHEST_Y_LINK")
        .expect("the chest's capsule");
    // The chest's foremost point over the blind plan, and its height there.
    let (mut front_x, mut front_z) = (f64::NEG_INFINITY, 0.0);
    for s in &blind.trajectory.samples {
        kin.update(&s.q).unwrap();
        let c = chest.capsule(&kin);
        for end in [c.a, c.b] {
            if end.x + c.radius_m > front_x {
                (front_x, front_z) = (end.x + c.radius_m, end.z);
            }
        }
    }
    for spacing_m in [0.065, 0.1] {
        for above_m in [0.0, 0.05] {
            let bar: Vec<Point3<f64>> = (-8..=8)
                .map(|k| Point3::new(front_x - 0.01, spacing_m * f64::from(k), front_z + above_m))
                .collect();
            let (blind_least, _) = upper_body_reach(&blind, &bar);
            assert!(blind_least < 0.0, "the blind plan passes through the bar: {blind_least} m");
            let among = PlanRequest::new(&model, &q0, &rects, &p)
                .among(std::sync::Arc::new(clearance::SeenPoints::new(bar.clone())))
                .max_stances(Some(2))
                .climb()
                .expect("planned behind the bar");
            let (least, _) = upper_body_reach(&among, &bar);
            assert!(
                least >= p.ik.body_clearance_m - 3e-4,
                "bar {spacing_m} m apart, {above_m} m up: the body came within {least} m of it"
            );
        }
    }
}

/// Issue 42, real-0014 with sweeps taken as the robot moved: the chest met a right handrail
/// in a gap no ray had crossed, planned as free space. Space the lidar could have seen and
/// did not is kept off as a surface is: the same wall as unseen space 2 cm beyond the blind
/// plan's reach is kept off by the body's clearance, reported as unseen; through the body,
/// the plan is refused as unseen space, not planned through; and the legs and the footholds
/// do not take it for a surface (a plan among unseen space at the legs' height only is the
/// blind plan).
#[test]
fn the_body_keeps_off_space_the_lidar_could_have_seen_and_did_not() {
    let (model, rects, q0, p, blind) = planned_blind();
    let (_, [_, reach_y]) = upper_body_reach(&blind, &[]);
    let unseen = wall_at(reach_y + 0.02);
    let among = |points: Vec<Point3<f64>>| {
        PlanRequest::new(&model, &q0, &rects, &p)
            .among(std::sync::Arc::new(clearance::SeenPoints::with_unseen(Vec::new(), points)))
            .max_stances(Some(2))
            .climb()
    };
    let kept_off = among(unseen.clone()).expect("planned beside unseen space");
    let (least, _) = upper_body_reach(&kept_off, &unseen);
    assert!(least >= p.ik.body_clearance_m - 1e-3, "the body came within {least} m of unseen space");
    let nearest = kept_off.tracking.nearest_body_surface.as_ref().expect("the body came near it");
    assert!(nearest.unseen, "{nearest:?}");
    let through: Vec<Point3<f64>> = unseen.iter().map(|q| Point3::new(q.x, reach_y - 0.2, q.z)).collect();
    let e = among(through).expect_err("unseen space through the body");
    assert!(matches!(e, PlanError::BodyNearSurface { unseen: true, .. } | PlanError::Ik { .. }), "{e}");
    let kind = e.refusal().kind;
    assert_eq!(
        kind == stairbench::planning::RefusalKind::BodyNearUnseen,
        matches!(e, PlanError::BodyNearSurface { .. })
    );
    // At the shanks' height only, across the lanes: neither footholds nor legs keep off it.
    let low: Vec<Point3<f64>> = (0..80)
        .flat_map(|i| {
            (0..30).map(move |j| Point3::new(-0.5 + 0.03 * i as f64, -0.45 + 0.03 * j as f64, 0.25))
        })
        .collect();
    let legs = among(low).expect("unseen space at the shanks' height is not a surface for the legs");
    assert_eq!(legs.stances, blind.stances);
}

/// Issue 39, real-0042 (two handrails 0.82 m apart): the IK holds each capsule off its one
/// nearest seen point, and between two surfaces it gives way toward the other; the body's
/// sway about the plan then put the chest on a rail. Walls on both sides, from 1 cm beyond
/// the blind plan's reach to 11 cm inside it (the arms fold in, the trunk cannot): each plan
/// is refused (the body too near, or no solution) or keeps `min_body_clearance_m`, never
/// returned nearer.
#[test]
fn a_plan_between_two_walls_keeps_the_sway_or_is_refused() {
    let (model, rects, q0, p, blind) = planned_blind();
    let (_, [right_y, left_y]) = upper_body_reach(&blind, &[]);
    let mut refused = 0;
    for inside_m in [-0.01, 0.02, 0.05, 0.08, 0.11] {
        let walls: Vec<Point3<f64>> = [wall_at(right_y + inside_m), wall_at(left_y - inside_m)].concat();
        let seen = std::sync::Arc::new(clearance::SeenPoints::new(walls.clone()));
        match PlanRequest::new(&model, &q0, &rects, &p).among(seen).max_stances(Some(2)).climb() {
            Ok(among) => {
                let (least, _) = upper_body_reach(&among, &walls);
                assert!(
                    least >= p.ik.min_body_clearance_m - 1e-6,
                    "walls {inside_m} m inside the reach: planned with the body {:.1} mm from them",
                    least * 1e3
                );
            }
            Err(e) => {
                assert!(
                    matches!(
                        e,
                        PlanError::BodyNearSurface { .. }
                            | PlanError::Ik { .. }
                            | PlanError::ComStrays { .. }
                    ),
                    "{e}"
                );
                refused += 1;
            }
        }
    }
    assert!(refused > 0, "walls 11 cm inside the body's reach were planned between");
}

/// The planner's nearest seen point equals the brute-force one (every point, every capsule),
/// and so do the witnesses the IK holds each capsule off.
#[test]
fn the_nearest_seen_point_is_the_brute_force_one() {
    let model = hrp4::model().unwrap();
    let scene = common::scene_of(&Scenario::default());
    let q0 = start_q(&model, &scene.robot_start());
    let mut kin = Kinematics::new(&model);
    kin.update(&q0).unwrap();
    let base = kin.link_pose(0).translation.vector;
    // A deterministic scatter around the body (a multiplicative congruential sequence).
    let mut state = 12345u64;
    let mut next = || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let points: Vec<Point3<f64>> = (0..3000)
        .map(|_| Point3::from(base + Vector3::new(next() - 0.5, next() - 0.5, next() * 1.2 - 0.6) * 1.2))
        .collect();
    let seen = clearance::SeenPoints::new(points.clone());
    let range = 0.08;
    let limbs = clearance::upper_limbs(&model, &hrp4::sole_frames(&model).unwrap());
    assert!(limbs.len() >= 6, "arms, trunk and head: {}", limbs.len());
    let (mut found, mut witnessed) = (0, 0);
    for limb in &limbs {
        let c = limb.capsule(&kin);
        let brute = points.iter().map(|p| c.distance_m(p)).fold(f64::INFINITY, f64::min);
        match seen.nearest(&kin, limb, range) {
            Some(n) => {
                found += 1;
                assert!((n.clearance_m - brute).abs() < 1e-9, "{}: {} vs {brute}", limb.name, n.clearance_m);
                assert!((c.distance_m(&points[n.block]) - brute).abs() < 1e-9);
            }
            None => assert!(brute > range, "{}: missed a point {brute} m away", limb.name),
        }
        // Its witnesses, by brute force: each the nearest point within range at least the
        // spacing from every one before it, while within the band of the nearest, up to the
        // most there are.
        let witnesses = match seen.probe(&c, range) {
            clearance::Probe::Near(w) => w,
            clearance::Probe::Clear { .. } => Vec::new(),
        };
        let nearest_apart = |chosen: &[Point3<f64>]| {
            points
                .iter()
                .filter(|p| chosen.iter().all(|q| (*p - q).norm() >= clearance::WITNESS_SPACING_M))
                .map(|p| c.distance_m(p))
                .fold(f64::INFINITY, f64::min)
        };
        let band_m =
            witnesses.first().map_or(range, |w| range.min(w.clearance_m + clearance::WITNESS_BAND_M));
        let mut chosen: Vec<Point3<f64>> = Vec::new();
        for w in &witnesses {
            let brute = nearest_apart(&chosen);
            assert!((w.clearance_m - brute).abs() < 1e-9, "{}: {} vs {brute}", limb.name, w.clearance_m);
            assert!(
                w.clearance_m <= band_m,
                "{}: a witness {} m away, past the band",
                limb.name,
                w.clearance_m
            );
            chosen.push(points[w.block]);
        }
        let more = nearest_apart(&chosen);
        assert!(
            witnesses.len() == clearance::MAX_WITNESSES || more > band_m,
            "{}: {} witnesses, and a point {more} m away apart from them",
            limb.name,
            witnesses.len()
        );
        witnessed = witnessed.max(witnesses.len());
    }
    assert!(found > 0, "the scatter reaches some capsule");
    assert!(witnessed > 1, "some capsule has more than one witness");
}

/// The tracker's probe cache skips a capsule's search only when it cannot have come within
/// range: along a path that sweeps a capsule past a wall and back, in steps of a few
/// millimetres to a few centimetres, the cached answer equals a fresh search at every step.
#[test]
fn the_probe_cache_answers_as_a_fresh_search_does() {
    use stairbench::geom3d::Capsule;
    let wall: Vec<Point3<f64>> = (0..40)
        .flat_map(|i| (0..40).map(move |k| Point3::new(0.03 * i as f64, 0.5, 0.03 * k as f64)))
        .collect();
    let seen = clearance::SeenPoints::new(wall);
    let mut cache = clearance::ProbeCache::default();
    let range = 0.08;
    let mut y = 0.0;
    let mut fresh_hits = 0;
    for step in 0..400 {
        // Out toward the wall and back, faster and slower in turn.
        let speed = if step % 7 == 0 { 0.03 } else { 0.004 };
        y += if step < 200 { speed } else { -speed };
        let capsule = Capsule {
            a: Point3::new(0.5, y, 0.6),
            b: Point3::new(0.55, y + 0.02 * ((step % 5) as f64), 0.4),
            radius_m: 0.04,
        };
        let fresh = match seen.probe(&capsule, range) {
            clearance::Probe::Near(witnesses) => witnesses,
            clearance::Probe::Clear { .. } => Vec::new(),
        };
        fresh_hits += usize::from(!fresh.is_empty());
        assert_eq!(cache.witnesses(0, &seen, capsule, range), fresh, "step {step}, y {y}");
    }
    assert!(fresh_hits > 10, "the path comes within range of the wall: {fresh_hits}");
}

/// Floor points seen every 3 cm over x in `xs`, |y| <= 0.7 m, at height `z`.
fn floor_seen(xs: [f64; 2], z: f64) -> Vec<Point3<f64>> {
    let n = ((xs[1] - xs[0]) / 0.03) as usize;
    (0..=n)
        .flat_map(|i| (0..=46).map(move |j| Point3::new(xs[0] + i as f64 * 0.03, -0.69 + j as f64 * 0.03, z)))
        .collect()
}

/// A flight refused from afar for what a closer view may undo (step 2 seen in part, 0.2 m
/// of its width) is walked toward on the floor, one stance, to look again; not where the
/// lidar saw something standing on the floor, not beyond its sight where it saw no floor.
/// Never from a step (the floor the climb started on is not under the feet).
/// Once the first step is within a stride, step 1 is climbed to look again at step 2 (ci
/// case 175, on the stairs: refused before); a refused step 1 stands.
#[test]
fn a_flight_refused_from_afar_is_walked_toward_on_seen_floor_only() {
    use stairbench::climb::plan_next;
    use stairbench::perception::step_map::NextInput;
    use stairbench::planning::clearance::SeenPoints;
    use stairbench::planning::footholds::{approach, GaitParams};
    use stairbench::planning::RefusalKind;
    use std::sync::Arc;
    let model = hrp4::model().unwrap();
    // Exp. 1's flight `start_m` ahead, step `narrow` seen 0.2 m wide: its rectangles, the
    // whole flight's, and the robot standing at the start.
    let seen_from = |start_m: f64, narrow: usize| {
        let mut s = Scenario::default();
        s.staircase.start_m = [start_m, 0.0];
        let scene = common::scene_of(&s);
        let whole = rectangles::from_step_tops(scene.steps());
        let mut rects = whole.clone();
        let r = &whole[narrow];
        rects[narrow] = PlaneSegment::new(r.center(), r.along(), r.depth_m(), 0.2, Vector3::z(), 0).unwrap();
        (rects, whole, start_q(&model, &scene.robot_start()))
    };
    let ahead = |rects: &[PlaneSegment]| NextInput { ahead: rects.to_vec(), deferred: None };
    let (rects, _, q0) = seen_from(1.6, 1);
    let p = PlanParams::default();
    let floor = floor_seen([0.0, 1.6], 0.0);
    let Err(refused) = PlanRequest::new(&model, &q0, &rects, &p)
        .among(Arc::new(SeenPoints::new(floor.clone())))
        .max_stances(Some(1))
        .climb()
    else {
        panic!("step 2 seen in part was planned")
    };
    assert!(matches!(refused, PlanError::OffTheSide { step: 1, .. }), "{refused}");

    let Ok((walk, why)) =
        plan_next(&model, &q0, &ahead(&rects), Arc::new(SeenPoints::new(floor.clone())), 1, 0.0, &p)
    else {
        panic!("no walk closer")
    };
    assert_eq!(why.map(|r| r.kind), Some(RefusalKind::OffTheSide));
    assert_eq!(walk.stances.len(), 1);
    let start_x = (walk.start.right.translation.x + walk.start.left.translation.x) / 2.0;
    for f in [&walk.stances[0].right, &walk.stances[0].left] {
        let ahead_m = f.translation.x - start_x;
        assert!(ahead_m > 0.05 && ahead_m <= p.gait.approach_stride_m + 1e-9, "a foot {ahead_m:.3} m ahead");
        assert!(f.translation.z.abs() < 1e-9 && walk.stances[0].step.is_none(), "on the floor");
    }

    // The same view with the feet 17 cm above the floor the climb started on (on a step,
    // ci case 83): that floor is not under the feet, nothing is walked, the refusal stands.
    let from_step =
        plan_next(&model, &q0, &ahead(&rects), Arc::new(SeenPoints::new(floor.clone())), 1, -0.17, &p);
    assert_eq!(from_step.err().map(|r| r.kind), Some(RefusalKind::OffTheSide), "walked off a step");

    // A box in the way, 30 cm tall from 0.2 m ahead: nothing is walked, and the climb's
    // own floor walk is refused for it (before any step is judged).
    let mut boxed = floor.clone();
    boxed.extend(floor_seen([0.2, 0.6], 0.3));
    let stopped = plan_next(&model, &q0, &ahead(&rects), Arc::new(SeenPoints::new(boxed)), 1, 0.0, &p);
    assert_eq!(stopped.err().map(|r| r.kind), Some(RefusalKind::FloorObstructed), "walked into a box");

    // No floor seen at all: only the stances within the lidar's blind reach, of all the walk's.
    let g = GaitParams::default();
    let whole = approach(&walk.start, &rects, &floor, &g);
    let blind = approach(&walk.start, &rects, &[], &g);
    assert!(
        whole.len() >= 3 && !blind.is_empty() && blind.len() < whole.len(),
        "{} of {}",
        blind.len(),
        whole.len()
    );
    for st in &blind {
        for f in [&st.right, &st.left] {
            assert!(
                f.translation.x - start_x < g.approach_blind_m,
                "a sole {:.2} m ahead, unseen",
                f.translation.x - start_x
            );
        }
    }

    // Standing within a stride of step 1: step 1 is climbed to look at step 2 again, its
    // own plan's first stance.
    let (near_rects, flight, q_near) = seen_from(0.25, 1);
    let near = |rects: &[PlaneSegment]| {
        plan_next(&model, &q_near, &ahead(rects), Arc::new(SeenPoints::new(floor.clone())), 1, 0.0, &p)
    };
    let Ok((up, why)) = near(&near_rects) else { panic!("step 1 not climbed to look again at step 2") };
    assert_eq!(why.map(|r| r.kind), Some(RefusalKind::OffTheSide));
    let Ok(climb) = PlanRequest::new(&model, &q_near, &flight, &p)
        .among(Arc::new(SeenPoints::new(floor.clone())))
        .max_stances(Some(1))
        .climb()
    else {
        panic!("the whole flight refused")
    };
    assert_eq!(up.stances[0].step, Some(0), "onto step 1");
    let off_m = (up.stances[0].right.translation.vector - climb.stances[0].right.translation.vector).norm();
    assert!(off_m < 1e-3, "the right foot {off_m:.4} m off where the whole flight's climb puts it");
    // Step 1 seen in part within a stride of it: nothing left to walk, the refusal stands.
    let (narrow_first, _, _) = seen_from(0.25, 0);
    assert_eq!(
        near(&narrow_first).err().map(|r| r.kind),
        Some(RefusalKind::OffTheSide),
        "climbed a narrow step 1"
    );
}

/// A tread's fitted normal under range noise leans away from the sensor (the wide suite's
/// case 45, 25 mm: a level flight's treads 1-6 degrees off level; the foot planned on step
/// 1's 5.7 degrees met the tread on its edge and the robot fell): the footholds are level
/// at each rectangle's height, yawed with the flight, whatever its normal (§6.2: every
/// contact frame level), on the default scenario's ground-truth rectangles tilted 5.7
/// degrees either way.
#[test]
fn the_footholds_are_level_on_a_tread_perceived_tilted() {
    use stairbench::planning::footholds::{footholds, GaitParams};
    use stairbench::planning::gait::StepParams;
    use stairbench::planning::plan::stance_at;
    let model = hrp4::model().unwrap();
    let scene = common::scene_of(&Scenario::default());
    let q = start_q(&model, &scene.robot_start());
    let start = stance_at(&model, &q).unwrap();
    let floor_m = start.right.translation.z.min(start.left.translation.z);
    let legs = legs_at(&model, &q, &StepParams::default()).unwrap();
    let tops = rectangles::from_step_tops(scene.steps());
    let truth = rectangles::by_height(&tops);
    let yaw = truth[0].along().y.atan2(truth[0].along().x);
    for tilt_deg in [5.7f64, -5.7] {
        let n = Vector3::new(tilt_deg.to_radians().sin(), 0.01, tilt_deg.to_radians().cos());
        let rects: Vec<PlaneSegment> = truth
            .iter()
            .map(|r| PlaneSegment::new(r.center(), r.along(), r.depth_m(), r.width_m(), n, 100).unwrap())
            .collect();
        let stances = footholds(&start, &rects, &[], &legs, &GaitParams::default()).unwrap();
        let on_steps = stances.iter().filter(|st| st.step.is_some()).count();
        assert!(on_steps >= rects.len(), "{on_steps} stances on {} steps", rects.len());
        for st in &stances {
            let height_m = st.step.map_or(floor_m, |i| rects[i].height_m());
            for sole in [&st.right, &st.left] {
                let up = sole.rotation * Vector3::z();
                assert!(up.z > 1.0 - 1e-12, "{tilt_deg} deg: a sole of stance {st:?} is tilted ({up})");
                assert!(
                    (sole.translation.z - height_m).abs() < 1e-9,
                    "{tilt_deg} deg: sole at {}",
                    sole.translation.z
                );
                let (_, _, sole_yaw) = sole.rotation.euler_angles();
                assert!((sole_yaw - yaw).abs() < 1e-9, "{tilt_deg} deg: yaw {sole_yaw} against {yaw}");
            }
        }
    }
}

/// The toes of the floor stances before the first step stay off its true riser when the
/// front edge comes from a scan under 20 mm of range noise (the paper's Exp. 1, seeds 0-9):
/// perception puts that edge up to 31 mm onto the tread (seed 5), and with the toes 3 cm
/// behind the edge as perceived they ended past the true riser (wide suite case 14: the
/// swinging foot struck it and the robot fell).
#[test]
fn the_floor_stances_keep_the_toes_off_the_true_riser_under_range_noise() {
    use stairbench::perception::{perceive, PerceptionParams};
    use stairbench::planning::footholds::{footholds, GaitParams};
    use stairbench::planning::gait::StepParams;
    use stairbench::planning::plan::{legs_at, stance_at};
    use stairbench::sensor::AssembleParams;
    let model = hrp4::model().unwrap();
    let p = GaitParams::default();
    let mut planned = 0;
    for seed in 0..10 {
        let mut s = Scenario::default();
        s.lidar.noise_sigma_m = 0.02;
        s.seed = seed;
        assert_eq!(s.staircase.yaw_deg, 0.0, "the riser is at x = start_m[0]");
        let riser_x = s.staircase.start_m[0];
        let scene = common::scene_of(&s);
        let cloud = stairbench::sim::scan_scenario(&s, &mut |_, _| {})
            .unwrap()
            .sweep
            .assemble(&AssembleParams::default())
            .unwrap();
        let Ok(seen) = perceive(&cloud, &PerceptionParams::default()) else { continue };
        let q = start_q(&model, &scene.robot_start());
        let start = stance_at(&model, &q).unwrap();
        let legs = legs_at(&model, &q, &StepParams::default()).unwrap();
        let Ok(stances) = footholds(&start, &seen.segments, &[], &legs, &p) else { continue };
        planned += 1;
        for st in stances.iter().filter(|st| st.step.is_none()) {
            for sole in [&st.right, &st.left] {
                let toe_x = (sole * Point3::new(p.sole_length_m / 2.0, 0.0, 0.0)).x;
                assert!(
                    toe_x <= riser_x - 0.01,
                    "seed {seed}: toe at {toe_x:.3} m, the riser at {riser_x:.3} m"
                );
            }
        }
    }
    assert!(planned >= 3, "only {planned} of 10 scans gave a plan");
}

/// The view: set down 0.28 m from the first riser of the paper's Exp. 1 (the feet's
/// middle to the riser), the robot sees step 1 from where its lidar's sight begins, 0.341 m
/// ahead: 0.209 m of its 0.27 m tread, its front not on the riser, and no floor before it
/// (the floor and the tread's near part are under the lidar). The climb is refused for that
/// depth, a matter of the view; the loop walked nearer, one stride, its toes 5 cm behind the
/// front as seen, 11 mm past the riser, and the right foot struck it (friction 2.55, a fall
/// in the first cycle). It steps back to see instead: no floor stance goes toward the
/// riser. A step seen deep enough within a stride is climbed from where the robot stands.
#[test]
fn a_robot_set_down_near_the_first_riser_plans_from_there_or_steps_back_to_see() {
    use stairbench::climb::plan_next;
    use stairbench::perception::step_map::NextInput;
    use stairbench::planning::clearance::SeenPoints;
    use stairbench::planning::RefusalKind;
    use std::sync::Arc;
    let model = hrp4::model().unwrap();
    let q0 = start_q(&model, &Isometry3::identity());
    let p = PlanParams::default();
    let riser_x = 0.28;
    // Treads 0.5 m wide along x from `front`, the voxels' fronts (not on their risers).
    let tread = |front: f64, z: f64, depth: f64| {
        PlaneSegment::new(
            Point3::new(front + depth / 2.0, 0.0, z),
            Vector3::x(),
            depth,
            0.5,
            Vector3::z(),
            300,
        )
        .unwrap()
    };
    let view = vec![tread(0.341, 0.2, 0.209), tread(0.55, 0.4, 0.27), tread(0.82, 0.6, 0.27)];
    // The floor the lidar saw: beside the flight, from 0.4 m on; none in the feet's lanes.
    let floor: Vec<Point3<f64>> =
        floor_seen([0.4, 1.6], 0.0).into_iter().filter(|q| q.y.abs() > 0.3).collect();
    let next = |ahead: Vec<PlaneSegment>| NextInput { ahead, deferred: None };
    let seen = Arc::new(SeenPoints::new(floor));
    let Ok((walk, why)) = plan_next(&model, &q0, &next(view), seen.clone(), 4, 0.0, &p) else {
        panic!("nothing planned")
    };
    assert_eq!(why.map(|r| r.kind), Some(RefusalKind::ShortTread));
    let start_x = (walk.start.right.translation.x + walk.start.left.translation.x) / 2.0;
    assert!(!walk.stances.is_empty());
    for st in &walk.stances {
        assert!(st.step.is_none(), "on the floor");
        for f in [&st.right, &st.left] {
            let toe_x = (f * Point3::new(p.gait.sole_length_m / 2.0, 0.0, 0.0)).x;
            assert!(toe_x <= riser_x - 0.01, "a toe at {toe_x:.3} m, the riser at {riser_x} m");
            assert!(
                f.translation.x < start_x - 0.05,
                "a sole {:.3} m from the start",
                f.translation.x - start_x
            );
        }
    }
    // Step 1 seen 0.3 m deep from 0.2 m, within a stride: climbed from where the robot stands.
    let near = vec![tread(0.2, 0.2, 0.3), tread(0.5, 0.4, 0.35)];
    let Ok((up, why)) = plan_next(&model, &q0, &next(near), seen, 1, 0.0, &p) else {
        panic!("step 1 within a stride not climbed")
    };
    assert!(why.is_none(), "{why:?}");
    assert_eq!(up.stances[0].step, Some(0), "onto step 1, no floor stance");
}

/// The paper's Exp. 2 rectangles, as its code released them
/// (stephane-caron/quasistatic-stair-climbing, data/exp2/rectangles.txt): four steps, the
/// top one seen in part, 0.187 m deep.
const EXP2_RECTANGLES: &str = "\
0.981889,-0.491986,-1.48544
0.981889,0.716378,-1.47865
1.26083,0.716378,-1.48301
1.26083,-0.491986,-1.4898
1.23977,-0.478977,-1.26971
1.23977,0.725987,-1.26971
1.53269,0.725987,-1.26971
1.53269,-0.478977,-1.26971
1.51911,-0.462724,-1.09523
1.51911,0.717216,-1.0924
1.75773,0.717216,-1.10393
1.75773,-0.462724,-1.10676
1.78075,-0.415284,-0.94987
1.78075,0.722436,-0.946674
1.96793,0.722436,-0.947123
1.96793,-0.415284,-0.950319
";

/// `stairbench plan` on a rectangles file whose top step is seen in part plans the steps it
/// can and names the one it left for a closer look, as the loop does (it refused the file:
/// "step 4: tread 0.187 m deep").
#[test]
fn the_plan_command_leaves_a_partly_seen_top_step_for_a_closer_look() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("plan-exp2");
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("rectangles.txt");
    std::fs::write(&file, EXP2_RECTANGLES).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_stairbench"))
        .args(["plan", file.to_str().unwrap(), "--json"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    let report: serde_json::Value = serde_json::from_str(&text).unwrap_or_else(|e| panic!("{e}: {text}"));
    assert!(out.status.success() && report["ok"] == true, "{}", report["reason"]);
    let c = &report["closer_look"];
    assert_eq!((c["kind"].as_str(), c["step"].as_u64()), (Some("short_tread"), Some(4)), "{c}");
    assert!((c["value"].as_f64().unwrap_or(0.0) - 0.187).abs() < 1e-3, "{c}");
    let on: Vec<u64> =
        report["stances"].as_array().expect("stances").iter().filter_map(|s| s["step"].as_u64()).collect();
    assert_eq!(on.last(), Some(&3), "the steps below it climbed: {on:?}");
}

/// A tread perception did not find in one view (under noise) leaves two treads a double rise
/// apart, as a missing step does: from the floor the climb starts on, the robot walks nearer
/// to look again, never onto the flight; from a step, or within a stride of the flight, the
/// refusal stands (regression `tread-missed-in-the-first-view`: refused for good from
/// 0.95 m before).
#[test]
fn a_step_missing_from_one_view_is_looked_at_again_from_nearer_on_the_floor() {
    use stairbench::climb::plan_next;
    use stairbench::perception::step_map::NextInput;
    use stairbench::planning::clearance::SeenPoints;
    use stairbench::planning::RefusalKind;
    use std::sync::Arc;
    let model = hrp4::model().unwrap();
    let p = PlanParams::default();
    let view_from = |start_m: f64| {
        let mut s = Scenario::default();
        s.staircase.steps = 4;
        s.staircase.start_m = [start_m, 0.0];
        let scene = common::scene_of(&s);
        let mut rects = rectangles::from_step_tops(scene.steps());
        rects.remove(1);
        (NextInput { ahead: rects, deferred: None }, start_q(&model, &scene.robot_start()))
    };
    let (next, q0) = view_from(1.6);
    let floor = Arc::new(SeenPoints::new(floor_seen([0.0, 1.6], 0.0)));
    let Ok((walk, why)) = plan_next(&model, &q0, &next, floor.clone(), 1, 0.0, &p) else {
        panic!("refused from 1.6 m without a closer look")
    };
    assert_eq!(why.map(|r| r.kind), Some(RefusalKind::MissingStep));
    assert!(walk.stances.iter().all(|s| s.step.is_none()), "a foot set on the flight");
    // On a step (the climb's floor 17 cm below the feet): refused, nothing walked.
    let from_step = plan_next(&model, &q0, &next, floor, 1, -0.17, &p);
    assert_eq!(from_step.err().map(|r| r.kind), Some(RefusalKind::MissingStep));
    // Within a stride of the first riser: nothing left to walk on the floor, refused.
    let (near, q_near) = view_from(0.25);
    let floor_near = Arc::new(SeenPoints::new(floor_seen([0.0, 0.25], 0.0)));
    let at_riser = plan_next(&model, &q_near, &near, floor_near, 1, 0.0, &p);
    assert_eq!(at_riser.err().map(|r| r.kind), Some(RefusalKind::MissingStep));
}

/// Step parameters that cannot time a gait (a zero speed, a zero ZMP shift: every segment would
/// last forever) are refused at the command line, naming the field, before anything is
/// planned: `plan` reads them as `[step]`, `run` as `[plan.step]`.
#[test]
fn step_parameters_that_cannot_time_a_gait_are_refused_by_name() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("bad-step-params");
    std::fs::create_dir_all(&dir).unwrap();
    for (k, (field, value)) in [("com_speed_m_s", "0.0"), ("max_zmp_shift_m", "0.0"), ("min_piece_s", "-1.0")]
        .into_iter()
        .enumerate()
    {
        for (command, section) in [("plan", "step"), ("run", "plan.step")] {
            let file = dir.join(format!("{command}-{k}.toml"));
            std::fs::write(&file, format!("[{section}]\n{field} = {value}\n")).unwrap();
            let out = std::process::Command::new(env!("CARGO_BIN_EXE_stairbench"))
                .args([command, "--params", file.to_str().unwrap()])
                .output()
                .unwrap();
            let err = String::from_utf8_lossy(&out.stderr);
            let named = format!("[step] {field} must");
            assert!(!out.status.success() && err.contains(&named), "{command} {field}: {err}");
        }
    }
}

/// The library refuses them too (a caller that skips the command line, such as `replay`
/// with its `--set`), as a refusal, not an endless plan.
#[test]
fn a_plan_request_with_a_zero_speed_is_refused() {
    let (model, rects, q0) = exp1_on_its_tops();
    let step = StepParams { com_speed_m_s: 0.0, ..StepParams::default() };
    let p = PlanParams { step, ..PlanParams::default() };
    match PlanRequest::new(&model, &q0, &rects, &p).climb() {
        Err(e) => assert!(e.to_string().contains("[step] com_speed_m_s must"), "{e}"),
        Ok(_) => panic!("planned at zero speed"),
    }
}

/// A plan is its segments tracked whole in one round, and a round tracked again is cut
/// short: a round that found a touchdown beyond the leading leg's reach (the planner lowers
/// it and tracks again, `planning::reach`) stops once every touchdown is measured. Each
/// first stance of Exp. 1 and of 37 cm treads (one stance a plan, as the loop plans; a
/// touchdown lowered in each) tracked again from its start gives the plan's own trajectory
/// to the bit, and the round thrown away took no more ticks than a round takes to its
/// touchdown (a whole round, as it once took, fails this).
#[test]
fn a_plan_is_its_segments_tracked_whole_and_a_round_tracked_again_stops_at_its_touchdown() {
    let model = hrp4::model().unwrap();
    let p = PlanParams::default();
    let deep_treads = common::regression("a-sole-twisting-under-load-turned-the-estimate");
    for (name, s) in [("Exp. 1", Scenario::default()), ("deep treads", deep_treads)] {
        let scene = common::scene_of(&s);
        let rects = rectangles::from_step_tops(scene.steps());
        let q0 = start_q(&model, &scene.robot_start());
        let plan = PlanRequest::new(&model, &q0, &rects, &p).max_stances(Some(1)).climb().unwrap();
        let whole = plan.trajectory.samples.len() - 1;
        let ticks = plan.tracking.ik_ticks;
        // The ticks of a round up to the end of its touchdown (one stance: one touchdown);
        // the round thrown away took as many, to its own timing's 10 % (its touchdown
        // higher, its swing a little shorter).
        let touchdown = plan.segments.iter().rposition(|s| s.phase == Phase::SwingRight).unwrap();
        let to_touchdown = plan.trajectory.samples[1..].iter().filter(|s| s.segment <= touchdown).count();
        println!("{name}: {ticks} IK ticks for a trajectory of {whole}, {to_touchdown} to its touchdown");
        assert!(ticks > whole, "{name}: the test needs a plan tracked again (a touchdown lowered)");
        assert!(
            ticks - whole <= to_touchdown + to_touchdown / 10,
            "{name}: the round thrown away took {} ticks, {to_touchdown} to its touchdown",
            ticks - whole
        );
        let (again, _) = stairbench::planning::motion::track(
            &model,
            &q0,
            &plan.segments,
            &plan.blocks,
            plan.seen.clone(),
            &p.ik,
        )
        .unwrap();
        assert!(
            again == plan.trajectory,
            "{name}: the plan's segments tracked again differ from its trajectory"
        );
    }
}
