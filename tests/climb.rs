//! The closed loop (issue 6): the HRP-4 model climbs in MuJoCo with every check at every
//! physics step; refusals stop the loop before anything moves; a broken plan, a foot off its
//! step and a too-fast timing are each caught and named.

mod common;

use common::{settled_exp1, step_tops_moved};
use nalgebra::{Translation3, Vector3};
use stairbench::cancel::Cancel;
use stairbench::climb::speed_margin::speed_margin;
use stairbench::climb::{Check, CheckKind, ClimbReport, Execution, Footing, Nobody, StopReason};
use stairbench::params::ClimbParams;
use stairbench::planning::clearance::step_blocks;
use stairbench::planning::gait::Phase;
use stairbench::planning::motion::track;
use stairbench::planning::RefusalKind;
use stairbench::planning::{rectangles, Foot, Plan, PlanParams, PlanRequest};
use stairbench::robot::RobotModel;
use stairbench::scenario::Scenario;
use stairbench::scene::Scene;
use stairbench::sim::checks::CheckParams;
use stairbench::sim::execute::execute;
use stairbench::sim::{climb_scenario, SimParams, World};

/// The closed loop on `s` with `p`, nothing observing.
fn climb(s: &Scenario, p: &ClimbParams) -> ClimbReport {
    climb_scenario(s, p.loop_params(), &p.sim(), &mut Nobody, &Cancel::never()).expect("the world runs")
}

fn print_report(r: &ClimbReport) {
    for c in &r.cycles {
        println!(
            "cycle {} to {}: pass {}, margin {:.1} mm, torque {:.0} % ({}), touchdown {:.2} mm, slip {:.2} mm, friction {:.2}",
            c.cycle,
            c.to,
            c.pass,
            c.execution.min_margin_m * 1e3,
            c.execution.max_torque_ratio * 100.0,
            c.execution.torque_joint,
            c.execution.max_touchdown_error_m() * 1e3,
            c.execution.max_slip_m * 1e3,
            c.execution.max_friction_ratio
        );
        for v in &c.execution.violations {
            println!("  t = {:.3} s {}: {}", v.t_s, v.check.kind(), v.check);
        }
    }
    println!("{} of {} steps, stopped: {:?}", r.steps_climbed, r.steps_total, r.stop);
}

/// What a climb to the top must show in every cycle: no violation, the CoM inside the
/// polygon of the real contacts, torques within limits, every loaded foot inside the friction
/// pyramid of the surfaces of `s` (the least of the steps' and the floor's), feet where
/// planned.
fn assert_climbed(r: &ClimbReport, s: &Scenario, p: &CheckParams) {
    let mu = s.staircase.friction.min(s.room.floor_friction);
    print_report(r);
    assert!(r.success, "{:?}", r.stop);
    assert_eq!(r.steps_climbed, r.steps_total, "the feet end on the top step (ground truth)");
    for c in &r.cycles {
        let ex = &c.execution;
        assert!(ex.violations.is_empty() && !ex.fell, "cycle {}: {:?}", c.cycle, ex.violations);
        assert!(ex.min_margin_m > 0.0, "cycle {}: CoM left the polygon", c.cycle);
        assert!(ex.max_torque_ratio < 1.0, "cycle {}: {} over its limit", c.cycle, ex.torque_joint);
        assert!(
            ex.max_friction_ratio <= mu,
            "cycle {}: friction ratio {:.2}",
            c.cycle,
            ex.max_friction_ratio
        );
        assert_eq!(ex.touchdowns.len(), 2, "cycle {}: both feet land", c.cycle);
        assert!(ex.max_touchdown_error_m() < p.touchdown_tolerance_m);
    }
}

#[test]
fn exp1_is_climbed_to_the_top_with_no_check_violated() {
    let p = ClimbParams::default();
    let r = climb(&Scenario::default(), &p);
    assert_climbed(&r, &Scenario::default(), &p.checks);
    let steps: Vec<Footing> = r.cycles.iter().map(|c| c.to).filter(|t| *t != Footing::Floor).collect();
    assert_eq!(steps, [Footing::Step(1), Footing::Step(2), Footing::Step(3)], "one cycle per step");
    // Where the execution's wall time went: the physics and the stabilizer are parts of it.
    let t = r.stage_times();
    assert!(t.physics_s > 0.0 && t.control_s > 0.0, "both measured: {t:?}");
    assert!(t.physics_s + t.control_s <= t.execute_s, "parts of the execution's time: {t:?}");
}

/// The physics step is fine enough for what the checks measure: Exp. 1 simulated at half the
/// default step (a reference the default's figures are not made from) climbs the same cycles
/// to the same footings, and each cycle's figures agree with the default's within what the
/// checks resolve: the CoM margin within 1 mm, the touchdown within 1 mm, the slide within
/// 0.5 mm, the friction ratio within 0.02 (a tenth of Exp. 1's). 2 ms against 1 ms fails
/// it. On Exp. 1's own noise draw only: the least margin is that of the feet judged in
/// contact, and a sole touching with about the checks' `contact_force_n` leaves and
/// rejoins the polygon within a few steps, so on other draws the least margin is the
/// step's chance (the draws and figures: CHANGELOG, sixtieth session).
#[test]
fn the_default_physics_step_gives_the_figures_of_half_of_it() {
    assert_half_the_step_agrees(&ClimbParams::default(), Some(0.02));
}

/// The same with the sway's washout on (`lean_washout_gain` 0.15, off by default): its
/// input, the lean the encoders do not read, is under a stiff body the simulated contact's
/// own give, which changes within a few physics steps. Taken raw (`lean_washout_filter_s`
/// 0) it moves cycle 2's CoM margin 2.2 mm between the 1 and 0.5 ms steps, and fails this;
/// low-passed at the default 0.03 s the figures agree. All but the friction ratio: with the
/// washout on, a landing sole chatters on its contact for tens of milliseconds, at its
/// cone's edge while its load is under the checks' `friction_load_n`, and whether the load
/// crosses that while the sole is still held back is the step's chance, on Exp. 1's own
/// draw as on others (the figures: CHANGELOG, sixtieth session).
#[test]
fn the_sway_washout_gives_the_figures_of_half_the_physics_step() {
    let mut p = ClimbParams::default();
    p.stabilizer.lean_washout_gain = 0.15;
    assert_half_the_step_agrees(&p, None);
}

/// Exp. 1 climbed with `p` at its physics step and at half of it: the same cycles, each
/// cycle's figures within what the checks resolve (see the tests above), the friction
/// ratio within `friction_tol` where that is given.
fn assert_half_the_step_agrees(p: &ClimbParams, friction_tol: Option<f64>) {
    let half = ClimbParams {
        physics: stairbench::sim::params::PhysicsParams {
            step_s: p.physics.step_s / 2.0,
            ..p.physics.clone()
        },
        ..p.clone()
    };
    let (a, b) = (climb(&Scenario::default(), p), climb(&Scenario::default(), &half));
    print_report(&a);
    print_report(&b);
    assert!(a.success && b.success, "{:?} / {:?}", a.stop, b.stop);
    let to = |r: &ClimbReport| r.cycles.iter().map(|c| c.to).collect::<Vec<_>>();
    assert_eq!(to(&a), to(&b), "the same cycles to the same footings");
    for (x, y) in a.cycles.iter().zip(&b.cycles) {
        let (x, y) = (&x.execution, &y.execution);
        let near = |u: f64, v: f64, tol: f64, what: &str| {
            assert!((u - v).abs() <= tol, "{what}: {u:.4} at the step, {v:.4} at half of it");
        };
        near(x.min_margin_m, y.min_margin_m, 1e-3, "CoM margin, m");
        near(x.max_touchdown_error_m(), y.max_touchdown_error_m(), 1e-3, "touchdown, m");
        near(x.max_slip_m, y.max_slip_m, 0.5e-3, "slide, m");
        if let Some(tol) = friction_tol {
            near(x.max_friction_ratio, y.max_friction_ratio, tol, "friction ratio");
        }
    }
}

/// The default scenario must not pass by the luck of its noise draw. Seeds 1 and 2 (the
/// first after the default) both failed the friction check at step 2's touchdown before the
/// merge of views measured a step's nose by its edge and kept the fuller view's plane.
#[test]
fn exp1_is_climbed_through_other_noise_draws() {
    let p = ClimbParams::default();
    for seed in [1, 2] {
        let s = Scenario { seed, ..Scenario::default() };
        let r = climb(&s, &p);
        println!("seed {seed}:");
        assert_climbed(&r, &s, &p.checks);
    }
}

#[test]
fn the_papers_24_cm_step_is_climbed_within_torque_limits() {
    let s = Scenario::load(std::path::Path::new("scenarios/hrp4_step.toml")).unwrap();
    assert!((s.staircase.rise_m - 0.24).abs() < 1e-12);
    let p = ClimbParams::default();
    let r = climb(&s, &p);
    assert_climbed(&r, &s, &p.checks);
    let worst = r.cycles.iter().map(|c| c.execution.max_torque_ratio).fold(0.0, f64::max);
    println!("largest torque demand: {:.0} % of a joint's limit", worst * 100.0);
}

#[test]
fn a_40_cm_rise_is_refused_before_anything_moves() {
    let mut s = Scenario::default();
    s.staircase.rise_m = 0.40;
    let p = ClimbParams::default();
    let r = climb(&s, &p);
    println!("{:?}", r.stop);
    assert!(!r.success);
    assert!(r.cycles.is_empty(), "nothing may move");
    let Some(StopReason::Refused { cycle: 1, refusal }) = r.stop else { panic!("refused: {:?}", r.stop) };
    assert_eq!(refusal.kind, RefusalKind::HighRise);
    assert_eq!((refusal.step, refusal.unit.as_deref()), (Some(1), Some("m")));
    assert!((refusal.value.expect("the rise") - 0.40).abs() < 0.01, "{refusal:?}");
    assert!(refusal.value > refusal.limit);
    // The stand before the scan: `settle_s`, then on until still, `max_settle_s` at most.
    assert!(r.sim_s <= p.run.max_settle_s + 1e-9, "only the settling before the scan ran: {} s", r.sim_s);
}

#[test]
fn a_floor_stance_executes_in_mujoco_with_the_checks_holding() {
    let (scene, model, mut world, q0) = settled_exp1();
    let rects = rectangles::from_step_tops(scene.steps());
    let p =
        PlanRequest::new(&model, &q0, &rects, &PlanParams::default()).max_stances(Some(1)).climb().unwrap();
    let ex = execute_checked(&mut world, &model, &scene, &p);
    println!(
        "margin {:.1} mm, torque {:.0} % ({}), speed {:.0} % ({}), touchdowns {:?}",
        ex.min_margin_m * 1e3,
        ex.max_torque_ratio * 100.0,
        ex.torque_joint,
        ex.max_speed_ratio * 100.0,
        ex.speed_joint,
        ex.touchdowns
    );
    assert!(!ex.fell);
    assert!(ex.min_margin_m > 0.02, "CoM margin {}", ex.min_margin_m);
    assert!(ex.max_torque_ratio < 1.0);
    assert_eq!(ex.touchdowns.len(), 2, "both feet land");
    assert!(ex.touchdowns.iter().all(|t| t.error_m < 0.005), "{:?}", ex.touchdowns);
    assert!(ex.violations.is_empty(), "{:?}", ex.violations);
    assert!(ex.max_friction_ratio < 0.7 && ex.max_slip_m < 0.005);
}

/// `plan` executed in `world` with the default servos, stabilizer and checks; its
/// violations printed.
fn execute_checked(world: &mut World, model: &RobotModel, scene: &Scene, plan: &Plan) -> Execution {
    let ex = execute(world, model, scene, plan, &SimParams::default(), &mut Nobody, &Cancel::never())
        .expect("the world runs");
    for v in &ex.violations {
        println!("t = {:.3} s {}: {}", v.t_s, v.check.kind(), v.check);
    }
    ex
}

#[test]
fn a_broken_plan_lifting_the_support_foot_is_caught_with_its_instant() {
    let (scene, model, mut world, q0) = settled_exp1();
    let rects = rectangles::from_step_tops(scene.steps());
    let params = PlanParams::default();
    let good = PlanRequest::new(&model, &q0, &rects, &params).max_stances(Some(1)).climb().unwrap();
    // Break segment (2): the CoM is over the left ankle, and the left foot is lifted along
    // the right foot's swing path moved over to it, while only the right foot holds.
    let mut segments = good.segments.clone();
    let seg = &mut segments[1];
    assert_eq!(seg.phase, Phase::SwingRight);
    let left = seg.support.iter().find(|(f, _)| *f == Foot::Left).unwrap().1;
    let sw = seg.swing.as_mut().unwrap();
    let shift = Translation3::from(left.translation.vector - sw.path[0].translation.vector);
    sw.path.iter_mut().for_each(|pose| *pose = shift * *pose);
    sw.foot = Foot::Left;
    let stay = (Foot::Right, *good.start.foot(Foot::Right));
    seg.support = vec![stay];
    // The remaining segments keep both feet where they were (the plan ends there).
    segments.truncate(2);
    let blocks = step_blocks(&rects, -0.1);
    let (trajectory, tracking) =
        track(&model, &q0, &segments, &blocks, Default::default(), &params.ik).unwrap();
    let broken = Plan { segments, trajectory, tracking, ..good };
    let from_s = broken.segments[0].duration_s;
    let ex = execute_checked(&mut world, &model, &scene, &broken);
    let first = ex
        .violations
        .iter()
        .find(|v| matches!(v.check.kind(), CheckKind::Margin | CheckKind::Fall))
        .expect("caught");
    let Check::Margin { margin_m, feet_down, .. } = first.check else {
        panic!("the margin check sees it before the fall: {:?}", first.check)
    };
    assert!(margin_m.is_none_or(|m| m < 0.0), "the CoM is outside: {margin_m:?}");
    assert!(!feet_down[1], "the lifted left foot is out of the polygon: {feet_down:?}");
    let at = first.t_s; // on the plan's clock
    assert!(at > from_s && at < from_s + broken.segments[1].duration_s, "caught at {at} s, in segment (2)");
}

#[test]
fn a_foot_placed_5_cm_off_its_steps_edge_is_reported() {
    let (scene, model, mut world, q0) = settled_exp1();
    // The step rectangles as if perceived 6.5 cm too near: the foothold in the middle of
    // step 1's wrong rectangle puts the heel 5 cm over the true nose ((27 - 24) / 2 + 5 cm).
    let shift = -0.065;
    let rects = step_tops_moved(&scene, Vector3::new(shift, 0.0, 0.0));
    let p =
        PlanRequest::new(&model, &q0, &rects, &PlanParams::default()).max_stances(Some(3)).climb().unwrap();
    assert_eq!(p.stances.last().unwrap().step, Some(0), "the third stance is on step 1");
    let ex = execute_checked(&mut world, &model, &scene, &p);
    let off = ex.first(CheckKind::OffStep).expect("the overhang is reported");
    let Check::OffStep { overhang_m, limit_m, .. } = off.check else { panic!("{:?}", off.check) };
    assert!((overhang_m - 0.05).abs() < 0.01, "overhang {overhang_m} m, placed 50 mm off");
    assert!(overhang_m > limit_m);
}

#[test]
fn the_speed_margin_is_measured_and_its_edge_names_a_check() {
    let params = ClimbParams::default();
    let mut one = |plan: &PlanParams| {
        let p = ClimbParams { plan: plan.clone(), ..params.clone() };
        climb_scenario(&Scenario::default(), p.loop_params(), &p.sim(), &mut Nobody, &Cancel::never())
    };
    let m = speed_margin(&params.plan, 8.0, 0.25, false, &mut one, &mut |t| {
        println!("x {:.2}: {} {:?}", t.factor, t.success, t.why);
    })
    .unwrap();
    println!("passes at {:?}, fails at {:?}", m.passes_at, m.fails_at);
    let pass = m.passes_at.expect("the planned timing passes");
    let fail = m.fails_at.expect("some speed-up up to x 8 fails: the motion is quasi-static");
    assert!(pass >= 1.0 && fail > pass && fail / pass <= 1.25 + 1e-9);
    let at_fail = m.tries.iter().find(|t| t.factor == fail).unwrap();
    assert!(!at_fail.success && at_fail.why.is_some());
    assert!(at_fail.first_violation.is_some() || at_fail.stop.is_some(), "the failure is named as data");
    // The search is consistent: every faster try failed, every slower one passed, and the
    // planned timing (x 1) was tried.
    assert!(m.tries.iter().any(|t| t.factor == 1.0 && t.success));
    for t in &m.tries {
        assert_eq!(t.success, t.factor <= pass, "x {} passed: {}", t.factor, t.success);
    }
}

/// A free foot's own inertia is not read as a touch. At x 1.83 of the default timing, Exp.
/// 1's floor cycles begin the left sole's descent at about 10 m/s^2: with that
/// inertia left in the ankle sensor's reading (`free_foot_inertia_removed` false), the
/// reading passes `touchdown_force_n` 4.6 cm above the floor, the foot is held there and
/// lowered at the landing's pace while the plan moves the CoM onto it, and the robot falls.
/// With the commanded acceleration's inertia removed (the default) the touch is not read,
/// and the climb keeps every check. The opt-in `touch_lost_after_s` (0.1 s) recovers from
/// the same false touch instead: the foot is let go, comes down, and the plan waits for it.
/// (The fall is an edge: x 1.82 climbs with the inertia left in, so a change to the gait or
/// the physics may move the case off it; the first assertion then fails and says so.)
#[test]
fn a_free_foots_inertia_is_not_read_as_a_touch() {
    let s = Scenario::default();
    let mut p = ClimbParams::default();
    p.plan = p.plan.faster(1.83);
    let mut read_in = p.clone();
    read_in.stabilizer.free_foot_inertia_removed = false;
    let r = climb(&s, &read_in);
    assert!(r.cycles.iter().any(|c| c.execution.fell), "the inertia read as a touch: {:?}", r.stop);
    let r = climb(&s, &p);
    assert_climbed(&r, &s, &p.checks);
    let mut let_go = read_in;
    let_go.stabilizer.touch_lost_after_s = 0.1;
    let r = climb(&s, &let_go);
    assert_climbed(&r, &s, &let_go.checks);
}

/// A fast swing is braked before its approach. Regression
/// `a-sole-hanging-low-struck-at-the-swings-speed` (an `hrp4-like` body, its sole hanging
/// about 8 mm below where its model puts it) at x 1.25 the default timing: cycle 2's left
/// swing comes down at 0.31 m/s with 1.5 cm to go. With its speed stepped down to the
/// approach's within one tick there (`approach_braking_time_s` 0), the servos brake the
/// foot over their lag and its sole strikes the floor at the swing's speed: a friction
/// violation at the landing. Braked over the default time, it climbs clean.
#[test]
fn a_fast_swing_is_braked_before_its_approach() {
    const CASE: &str = "scenarios/suites/regressions/a-sole-hanging-low-struck-at-the-swings-speed.toml";
    let s = Scenario::load(std::path::Path::new(CASE)).unwrap();
    let mut p = ClimbParams::default();
    p.plan = p.plan.faster(1.25);
    let mut stepped = p.clone();
    stepped.stabilizer.approach_braking_time_s = 0.0;
    let r = climb(&s, &stepped);
    print_report(&r);
    let struck = r.cycles.iter().find(|c| !c.pass).expect("a cycle fails with the speed stepped down");
    assert!(
        struck.execution.violations.iter().any(|v| v.check.kind() == CheckKind::Friction),
        "the landing slips: {:?}",
        struck.execution.violations
    );
    let r = climb(&s, &p);
    assert_climbed(&r, &s, &p.checks);
}

/// The wanted wrench taken about the estimated CoM (`[stabilizer]
/// wrench_about_estimated_com`, opt-in): regression `walking-trunk-twisted-off-unseen-space`
/// (sweeps taken walking) at x 1.25 the default timing, whose deeply bowed trunk rocks the
/// stance sole toward its edges in single support, lands a foot farther off its target than
/// the check allows about the reference CoM, and climbs clean about the estimate.
#[test]
fn the_wrench_about_the_estimated_com_lands_the_bowed_trunks_feet() {
    const CASE: &str = "scenarios/suites/regressions/walking-trunk-twisted-off-unseen-space.toml";
    let s = Scenario::load(std::path::Path::new(CASE)).unwrap();
    let mut p = ClimbParams::default();
    // As the regression runs it: the twisted plan executed, not made again on a standing look.
    p.run.sweep_while_moving = true;
    p.run.look_standing_when_held_off_unseen = false;
    p.plan = p.plan.faster(1.25);
    let r = climb(&s, &p);
    print_report(&r);
    let off = r.cycles.iter().find(|c| !c.pass).expect("a cycle fails about the reference CoM");
    assert!(
        off.execution.violations.iter().any(|v| v.check.kind() == CheckKind::Touchdown),
        "a foot lands off its target: {:?}",
        off.execution.violations
    );
    p.stabilizer.wrench_about_estimated_com = true;
    let r = climb(&s, &p);
    assert_climbed(&r, &s, &p.checks);
}

/// The DCM feedback in single support (`[stabilizer] single_support_dcm_gain_per_s`,
/// opt-in) holds a body on soft ankle bushes over its support sole: regression
/// `soft-ankles-swayed-off-the-inner-edge` (a body twice as far from its model as a real
/// HRP-4's, on ankle bushes of 1000 N m/rad) sways out over the left sole's inner edge in
/// single support and falls without it, and climbs every step clean with it.
#[test]
fn the_dcm_feedback_holds_the_sway_of_a_soft_ankled_single_support() {
    const CASE: &str = "scenarios/suites/regressions/soft-ankles-swayed-off-the-inner-edge.toml";
    let s = Scenario::load(std::path::Path::new(CASE)).unwrap();
    let mut p = ClimbParams::default();
    let r = climb(&s, &p);
    assert!(
        matches!(r.stop, Some(StopReason::Fell { .. })),
        "the sway ends in a fall without the feedback: {:?}",
        r.stop
    );
    let fell = r.cycles.iter().find(|c| !c.pass).expect("a cycle fails");
    assert!(
        fell.execution
            .violations
            .iter()
            .any(|v| matches!(v.check, Check::Margin { feet_down: [false, true], .. })),
        "the CoM leaves the left sole's single support: {:?}",
        fell.execution.violations
    );
    p.stabilizer.single_support_dcm_gain_per_s = 1.0;
    let r = climb(&s, &p);
    assert_climbed(&r, &s, &p.checks);
}

/// A foot whose swing ended before it met the ground goes on down its approach, as it would
/// have in the swing: braked above it, slowing through it, the plan waiting for it in single
/// support no longer than that. Exp. 1 at x 2 the default timing, where the braking leaves
/// the foot higher at its swing's end than the plan's clock: climbed clean (at the landing
/// speed alone from there, it failed: CHANGELOG, sixty-third session).
#[test]
fn a_foot_goes_on_down_its_approach_after_its_swing_has_ended() {
    let s = Scenario::default();
    let mut p = ClimbParams::default();
    p.plan = p.plan.faster(2.0);
    let r = climb(&s, &p);
    assert_climbed(&r, &s, &p.checks);
}

/// A turn slowed for its moment about the vertical is slowed by the moment's fall as
/// measured: regression `walking-chest-ratcheted-along-a-nose` (sweeps taken walking), whose
/// third plan's turn asks more of the soles than they are asked to hold, is climbed to the
/// top, every check clean. A guard: the false refusal it keeps out was seen with an earlier
/// braking of the descent (CHANGELOG, sixty-third session); the slowing's rule itself is
/// tested in `a_turn_is_slowed_by_the_fall_of_its_moment_as_measured`.
#[test]
fn a_turn_is_slowed_as_its_moment_falls_and_the_flight_climbed() {
    const CASE: &str = "scenarios/suites/regressions/walking-chest-ratcheted-along-a-nose.toml";
    let s = Scenario::load(std::path::Path::new(CASE)).unwrap();
    let mut p = ClimbParams::default();
    p.run.sweep_while_moving = true;
    let r = climb(&s, &p);
    assert_climbed(&r, &s, &p.checks);
}

/// The plan's timing three times the quasi-static one (1.5 times the default) climbs Exp. 1
/// clean with the CoM's acceleration bound by the ZMP shift it may ask
/// (`StepParams::max_zmp_shift_m`, its default `ZMP_SHIFT_M`). With the speed bound alone,
/// the first sideways shift (10 cm in 0.56 s) pushes the unloading right foot out of its
/// friction cone at t = 1.4 s, and the robot falls.
#[test]
fn a_climb_three_times_the_quasi_static_timing_keeps_every_check() {
    use stairbench::planning::gait::ZMP_SHIFT_M;
    let plan = PlanParams::quasi_static().faster(3.0);
    assert_eq!(plan.step.max_zmp_shift_m, ZMP_SHIFT_M);
    let p = ClimbParams { plan, ..ClimbParams::default() };
    let r = climb(&Scenario::default(), &p);
    assert_climbed(&r, &Scenario::default(), &p.checks);
}

/// Exp. 1 on the robot's own estimate (odometry from the encoders and the support foot): the
/// views are assembled where it believes its head is and the plans start where it believes
/// it stands. Climbed clean, the estimate within a centimetre of the truth at every sweep;
/// and when the estimate jumps 5 cm up the flight after the first step-up (an unseen slip),
/// the next view is registered on the known steps, the estimate corrected, and the climb
/// goes on clean.
#[test]
fn exp1_is_climbed_on_the_robots_own_estimate_and_a_slip_is_registered_away() {
    use stairbench::climb::{self, Bench};
    let p = ClimbParams {
        estimate: stairbench::estimate::EstimateParams { enabled: true, ..Default::default() },
        ..ClimbParams::default()
    };
    let s = Scenario::default();
    let r = climb(&s, &p);
    assert_climbed(&r, &s, &p.checks);
    let pos_m = r.max_estimate_error_m().expect("the truth is known in simulation");
    let yaw_rad = r.max_estimate_yaw_rad().expect("and the yaw");
    println!("estimate at most {:.1} mm, {:.2} deg off", pos_m * 1e3, yaw_rad.to_degrees());
    assert!(r.cycles.iter().all(|c| c.estimate_error.is_some()));
    assert!(pos_m < 0.01 && yaw_rad < 1f64.to_radians());

    let scene = Scene::from_scenario(&s).unwrap();
    let model = stairbench::robot::hrp4::model().unwrap();
    let world = std::cell::RefCell::new(World::for_scene(&scene).unwrap());
    let mut source = stairbench::sim::SimSource::new(&world, &s.lidar, s.seed).unwrap();
    let slip = nalgebra::Isometry3::translation(0.05, 0.0, 0.0);
    let robot = stairbench::sim::SimRobot::new(&world, &model, &scene, &p.sim()).unwrap();
    let mut slipping = Corrected { robot, executions: 0, moves: Vec::new(), slip: (3, slip) };
    let bench = Bench { source: &mut source, robot: &mut slipping, model: &model, truth: &scene };
    let r = climb::run(bench, p.loop_params(), &mut Nobody, &Cancel::never()).unwrap();
    for c in &r.cycles {
        println!("cycle {}: estimate {:?}, corrected by {:?}", c.cycle, c.estimate_error, c.correction_m);
    }
    assert_climbed(&r, &s, &p.checks);
    let corrected = r.cycles.iter().find_map(|c| c.correction_m).expect("the slip is registered");
    assert!((corrected[0] + 0.05).abs() < 0.01, "corrected by {corrected:?}");
    let last = r.cycles.last().and_then(|c| c.estimate_error).expect("an error");
    assert!(last.position_m < 0.015, "after the correction: {last:?}");
}

/// The simulated robot whose own estimate jumps by `slip.1` after its `slip.0`-th execution,
/// as a foot sliding unseen on the tread would leave it (the true robot does not move); each
/// move of its estimate by a registration kept: how far its base went, and after how many
/// executions.
struct Corrected<'a> {
    robot: stairbench::sim::SimRobot<'a>,
    executions: usize,
    /// Each move: the executions before it, the robot's clock then (s), and the move (m).
    moves: Vec<(usize, f64, [f64; 3])>,
    slip: (usize, nalgebra::Isometry3<f64>),
}

impl stairbench::climb::Executor for Corrected<'_> {
    type Error = stairbench::sim::SimError;

    fn now_s(&self) -> f64 {
        self.robot.now_s()
    }

    fn configuration(&self) -> Vec<f64> {
        self.robot.configuration()
    }

    fn true_configuration(&self) -> Option<Vec<f64>> {
        self.robot.true_configuration()
    }

    fn correct(&mut self, offset: &nalgebra::Isometry3<f64>) -> bool {
        let before = self.robot.configuration();
        let moved = self.robot.correct(offset);
        if moved {
            let after = self.robot.configuration();
            let moved_m = [0, 1, 2].map(|i| after[i] - before[i]);
            self.moves.push((self.executions, self.robot.now_s(), moved_m));
        }
        moved
    }

    fn settle(&mut self, seconds: f64) -> Result<stairbench::climb::Standing, Self::Error> {
        self.robot.settle(seconds)
    }

    fn execute(
        &mut self,
        plan: &Plan,
        observer: &mut dyn stairbench::climb::Observer,
        cancel: &Cancel,
    ) -> Result<Execution, Self::Error> {
        let ex = self.robot.execute(plan, observer, cancel)?;
        self.executions += 1;
        if self.executions == self.slip.0 {
            assert!(self.robot.correct(&self.slip.1), "the robot keeps an estimate");
        }
        Ok(ex)
    }
}

/// Every move a registration made of the robot's estimate is in the cycles' reports: the
/// moves made on a look set aside to look again standing too (summed into the next cycle's
/// `correction_m`), which the reports left out before. A walking climb of `CASE`, its
/// estimate made to slip after the fourth execution, before a look that is set aside. (A
/// look after which the climb stops, the top's or a refusal's, is followed by no cycle.)
#[test]
fn every_move_of_the_estimate_is_reported_a_look_set_asides_too() {
    use stairbench::climb::{self, Bench};
    const CASE: &str = "scenarios/suites/regressions/walking-handrail-end-read-as-a-step-at-the-top.toml";
    let s = Scenario::load(std::path::Path::new(CASE)).unwrap();
    let mut p = ClimbParams::default();
    p.run.sweep_while_moving = true;
    let scene = Scene::from_scenario(&s).unwrap();
    let model = stairbench::robot::hrp4::model().unwrap();
    let plant = stairbench::sim::plant::Plant::of_scenario(&model, &s);
    let world = std::cell::RefCell::new(World::with_plant(&scene, &plant).unwrap());
    // The head's path, which the sweeps taken walking are cast along.
    let track = std::cell::RefCell::new(stairbench::sim::head_track::HeadTrack::new(&s.lidar));
    let mut source = stairbench::sim::SimSource::new(&world, &s.lidar, s.seed).unwrap().with_track(&track);
    let robot = stairbench::sim::SimRobot::new(&world, &model, &scene, &p.sim()).unwrap().with_track(&track);
    // The estimate slips 5 cm up the flight after the fourth execution.
    let slip = (4, nalgebra::Isometry3::translation(0.05, 0.0, 0.0));
    let mut robot = Corrected { robot, executions: 0, moves: Vec::new(), slip };
    let bench = Bench { source: &mut source, robot: &mut robot, model: &model, truth: &scene };
    // Each look's stamp, and whether it was set aside.
    let mut views: Vec<(f64, bool)> = Vec::new();
    let mut watch = climb::Watch(|e: &stairbench::climb::Event| {
        if let stairbench::climb::Event::View { stamp_s, set_aside, .. } = e {
            views.push((*stamp_s, *set_aside));
        }
    });
    let r = climb::run(bench, p.loop_params(), &mut watch, &Cancel::never()).unwrap();
    // A look after the last execution (the top's) is followed by no cycle to report it.
    let moves: Vec<_> = robot.moves.iter().filter(|(e, ..)| *e < robot.executions).copied().collect();
    println!("moves {moves:?}");
    for c in &r.cycles {
        println!(
            "cycle {}: set aside {}, corrected by {:?}",
            c.cycle,
            c.looked_again_standing.is_some(),
            c.correction_m
        );
    }
    // A move made on a look set aside: at that look's stamp (the registration follows the
    // look at once, in no simulated time).
    let set_aside_at = |t_s: f64| views.iter().any(|&(at_s, aside)| aside && (at_s - t_s).abs() < 1e-9);
    assert!(
        moves.iter().any(|&(_, t_s, _)| set_aside_at(t_s)),
        "no look set aside moved the estimate: the test no longer holds its case"
    );
    let sum = |v: &mut dyn Iterator<Item = [f64; 3]>| v.fold([0.0; 3], |a, m| [0, 1, 2].map(|i| a[i] + m[i]));
    let moved = sum(&mut moves.iter().map(|(.., m)| *m));
    let reported = sum(&mut r.cycles.iter().filter_map(|c| c.correction_m));
    for i in 0..3 {
        assert!((moved[i] - reported[i]).abs() < 1e-9, "moved {moved:?}, reported {reported:?}");
    }
}

/// The height of the CoM above the soles' middle at each plan's start (the robot's own
/// estimate of its configuration), metres, with the climb's report.
fn standing_heights(s: &Scenario, p: &ClimbParams) -> (Vec<f64>, ClimbReport) {
    struct Heights<'m>(stairbench::robot::Kinematics<'m>, [usize; 2], Vec<f64>);
    impl stairbench::climb::Observer for Heights<'_> {
        fn event(&mut self, event: &stairbench::climb::Event) {
            if let stairbench::climb::Event::Plan { plan, .. } = event {
                let Heights(kin, soles, heights) = self;
                kin.update(&plan.trajectory.samples[0].q).expect("a plan's start is a configuration");
                let soles_z =
                    (kin.frame_pose(soles[0]).translation.z + kin.frame_pose(soles[1]).translation.z) / 2.0;
                heights.push(kin.com().z - soles_z);
            }
        }
    }
    let model = stairbench::robot::hrp4::model().expect("the model loads");
    let soles = stairbench::robot::hrp4::sole_frames(&model).expect("HRP-4 has soles");
    let mut seen = Heights(stairbench::robot::Kinematics::new(&model), soles, Vec::new());
    let r =
        climb_scenario(s, p.loop_params(), &p.sim(), &mut seen, &Cancel::never()).expect("the world runs");
    (seen.2, r)
}

/// Every plan takes the CoM to half-sitting's height above the soles, whatever height it
/// starts from: a flight climbed at the default timing (x 2 the quasi-static), whose
/// executions ended each step a little higher than planned, starts every plan near standing
/// height and climbs to the top. Before,
/// each plan took its height from its start, the offset grew step after step, and on `ci-0030`
/// (eleven steps of 16 cm, an hrp4-like body) the knees came all but straight (0.72 to 0.22
/// rad) and the ninth step's plan was refused: "Left foot misses its target by 5.5 mm".
#[test]
fn a_flight_climbed_faster_keeps_its_standing_height() {
    let s = Scenario::load(std::path::Path::new("tests/fixtures/turned-shallow-flight.toml")).unwrap();
    let model = stairbench::robot::hrp4::model().expect("the model loads");
    let soles = stairbench::robot::hrp4::sole_frames(&model).expect("HRP-4 has soles");
    let standing = stairbench::planning::plan::standing_body(&model, soles).unwrap().com_height_m;
    let p = ClimbParams::default();
    let (heights, r) = standing_heights(&s, &p);
    let off_mm: Vec<f64> = heights.iter().map(|h| (h - standing) * 1e3).collect();
    println!("standing height {:.1} mm; each plan's start off it by {off_mm:.1?} mm", standing * 1e3);
    assert_climbed(&r, &s, &p.checks);
    assert!(heights.len() >= s.staircase.steps as usize, "a plan a step at least: {}", heights.len());
    let worst_mm = off_mm.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    let tolerance_mm = p.plan.ik.com_tolerance_m * 1e3;
    assert!(
        worst_mm < tolerance_mm,
        "a plan started {worst_mm:.1} mm off standing height (> {tolerance_mm} mm)"
    );
}

/// Issue 42's "no standing still for a scan": with `[run] sweep_while_moving`, every sweep
/// after the first is the last sweep's time of rows the lidar took as the robot moved and
/// stood, each row from where the head was at its instant and assembled where the robot's own
/// estimate had it then, the servo's pass ending at the look level last. Exp. 1 is climbed
/// clean on them with unseen space kept off (the default), the head rising along the rows of
/// each sweep after a step-up, and every step they show within 2 cm of its true height (a
/// plan made again on a look taken standing has that look's head still). Run
/// from level down (the rows just ahead of the head cast first, from farther back), the
/// space the chest walks into was never crossed and the climb was refused at its fourth
/// cycle; the space a few centimetres beside the body, which only the oldest rows looked at,
/// refused it too while it was judged.
#[test]
fn exp1_is_climbed_on_sweeps_taken_as_the_robot_moves() {
    #[derive(Default)]
    struct Sweeps {
        /// Per sweep: whether its rows carry their own poses, and how far the head rose
        /// along them, metres.
        moving: Vec<(bool, f64)>,
        /// Every perceived step's height, metres.
        heights: Vec<f64>,
        /// When the loop looked, on the world's clock, seconds.
        looked_s: Vec<f64>,
    }
    impl stairbench::climb::Observer for Sweeps {
        fn event(&mut self, event: &stairbench::climb::Event) {
            match event {
                stairbench::climb::Event::Sweep { sweep, stamp_s } => {
                    self.looked_s.push(*stamp_s);
                    let z: Vec<f64> =
                        sweep.rows.iter().filter_map(|r| r.mount_to_world.map(|m| m.translation.z)).collect();
                    let rise_m = match (z.first(), z.last()) {
                        (Some(a), Some(b)) => b - a,
                        _ => 0.0,
                    };
                    self.moving.push((sweep.moving(), rise_m));
                }
                stairbench::climb::Event::Perception { result, .. } => {
                    self.heights.extend(result.segments.iter().map(|s| s.height_m()));
                }
                _ => {}
            }
        }
    }
    let s = Scenario::default();
    let mut p = ClimbParams::default();
    p.run.sweep_while_moving = true;
    assert!(p.surroundings.unseen_kept_off);
    let mut seen = Sweeps::default();
    let r =
        climb_scenario(&s, p.loop_params(), &p.sim(), &mut seen, &Cancel::never()).expect("the world runs");
    println!("sweeps (moving, head's rise m): {:?}", seen.moving);
    assert_climbed(&r, &s, &p.checks);
    // One look a cycle: the look after cycle `n` is sweep `n` (0-based). A cycle whose plan
    // was made again on a look taken standing had that look after the set-aside cycle
    // before it: a sweep taken standing (no rows along a moving head). Every other is a
    // pass along the head's path.
    assert_eq!(seen.moving.len(), r.cycles.last().map_or(0, |c| c.cycle) + 1, "one look a cycle");
    let again: Vec<usize> =
        r.cycles.iter().filter(|c| c.looked_again_standing.is_some()).map(|c| c.cycle - 1).collect();
    for (i, (moving, rise_m)) in seen.moving.iter().enumerate() {
        assert_eq!(*moving, !again.contains(&i), "sweep {}: {:?}", i + 1, seen.moving);
        if again.contains(&i) {
            assert!(rise_m.abs() < 0.01, "sweep {}: taken standing, the head rose {rise_m} m", i + 1);
        }
    }
    assert!(seen.moving.len() >= 5);
    assert!(seen.moving[0].1.abs() < 0.01, "the first pass is taken standing: nothing moved before it");
    // One pass per look, ending at it (at its last row's instant), and the servo's return
    // between two: the looks are at least a return and a pass's rows apart (a look sooner
    // stands until its pass is whole). A look again standing sweeps at once, from where the
    // pass ended, and the pass after it starts where that sweep ends: no return.
    let servo = stairbench::sensor::TiltSweep::from_spec(&s.lidar);
    let rows_s = (servo.rows() - 1) as f64 * s.lidar.row_period_s;
    for (i, w) in seen.looked_s.windows(2).enumerate() {
        let apart_s = w[1] - w[0];
        let least_s = match (again.contains(&i), again.contains(&(i + 1))) {
            (_, true) => p.run.still_s,
            (true, false) => rows_s,
            (false, false) => servo.return_s() + rows_s,
        };
        assert!(apart_s >= least_s - 1e-3, "looks {apart_s:.3} s apart, less than {least_s:.3} s");
    }
    // The sweeps after the three step-ups (cycles 3 to 5 end on steps 1 to 3): the head rose
    // with the body along their rows.
    let ups = r.cycles.iter().filter(|c| c.to != Footing::Floor).map(|c| c.cycle);
    for sweep in ups {
        assert!(seen.moving[sweep].1 > 0.1, "sweep {}: the head rose {} m", sweep + 1, seen.moving[sweep].1);
    }
    // The floor (the ground stood on is among the surfaces found) and the steps.
    let scene = Scene::from_scenario(&s).unwrap();
    let truth: Vec<f64> = std::iter::once(0.0).chain(scene.steps().iter().map(|t| t.height_m)).collect();
    println!("heights seen, m: {:.3?}", seen.heights);
    for h in &seen.heights {
        let off_m = truth.iter().map(|t| (t - h).abs()).fold(f64::INFINITY, f64::min);
        assert!(off_m < 0.02, "a step seen at {h:.3} m, {off_m:.3} m from every true step");
    }
}

/// Exp. 1 at noise seed 1 on sweeps taken as the robot moves: the plan made from the pass the
/// head took stepping up onto step 1 brings the right wrist within 19 mm of space beside the
/// arm that pass's rows never crossed (cast seconds before, from lower and farther back), and
/// was refused there. The robot stands and looks again from where it is, a sweep taken
/// standing, and climbs on that view; the stand is counted.
#[test]
fn a_plan_refused_on_a_sweep_taken_walking_is_made_again_on_a_standing_look() {
    /// The looks (when, how far the head went during the sweep, metres, and the seconds a
    /// sweep taken standing takes, cast in no simulated time) and the cycles' ends (when, the
    /// seconds the cycle says it stood), in the order they came.
    #[derive(Default)]
    struct Looks(Vec<(bool, f64, f64, f64)>);
    impl stairbench::climb::Observer for Looks {
        fn event(&mut self, event: &stairbench::climb::Event) {
            match event {
                stairbench::climb::Event::Sweep { sweep, stamp_s } => {
                    let standing_s = match sweep.moving() {
                        true => 0.0,
                        false => sweep.rows.len() as f64 * sweep.lidar.row_period_s(),
                    };
                    self.0.push((true, *stamp_s, sweep.head_travel_m(), standing_s))
                }
                stairbench::climb::Event::Cycle { stamp_s, report } => {
                    self.0.push((false, *stamp_s, report.stood_s, 0.0))
                }
                _ => {}
            }
        }
    }
    let s = Scenario { seed: 1, ..Scenario::default() };
    let mut p = ClimbParams::default();
    p.run.sweep_while_moving = true;
    let mut looks = Looks::default();
    let r =
        climb_scenario(&s, p.loop_params(), &p.sim(), &mut looks, &Cancel::never()).expect("the world runs");
    assert_climbed(&r, &s, &p.checks);
    assert!(!r.looked_again_standing.is_empty(), "no plan was made again on a standing look");
    let again = r.cycles.iter().filter(|c| c.looked_again_standing.is_some()).count();
    assert_eq!(again, r.looked_again_standing.len(), "each set aside refusal carried by the cycle after it");
    // Every second of the climb's stands is counted: a cycle stood from the end of the one
    // before to its last look (its sweeps taken walking cost no stand of their own), the
    // set-aside look's stand included, and the sweep of a look taken standing. A second look
    // is a sweep taken standing.
    let mut cycle_end_s: Option<f64> = None;
    let mut cycle_looks: Vec<(f64, f64, f64)> = Vec::new();
    for &(is_look, stamp_s, x, standing_s) in &looks.0 {
        if is_look {
            cycle_looks.push((stamp_s, x, standing_s));
            continue;
        }
        let (looked_s, _, sweep_s) = *cycle_looks.last().expect("a look before each cycle");
        if let Some(from_s) = cycle_end_s {
            assert!(
                (x - (looked_s - from_s + sweep_s)).abs() < 1e-6,
                "stood {x:.3} s, {:.3} s from the last cycle to its look and {sweep_s:.3} s of standing sweep",
                looked_s - from_s
            );
        }
        if cycle_looks.len() > 1 {
            let (_, travel_m, sweep_s) = cycle_looks[cycle_looks.len() - 1];
            assert!(travel_m < 0.02, "the second look's head went {travel_m:.3} m");
            assert!(sweep_s > 0.0, "the second look is a sweep taken standing");
        }
        cycle_end_s = Some(stamp_s);
        cycle_looks.clear();
    }
}

/// A plan whose trunk twists fast asks the stance sole for a moment about the vertical that
/// friction holds only up to `mu m g r` (`r` the sole's mean radius): `wide-0031`'s fifth
/// cycle, its view taken walking, twisted the trunk to keep the chest off unseen space and
/// asked 21 N m of the sole's 19.5, which slid 5 mm. The planner now slows a segment that asks
/// more than `IkParams::max_yaw_moment_share` of it: every plan stays within what the sole
/// holds, and the climb keeps every check.
#[test]
fn a_trunk_twisted_fast_off_unseen_space_is_slowed_until_the_sole_holds_it() {
    use stairbench::robot::momentum::mean_radius_m;
    let s =
        Scenario::load(std::path::Path::new("tests/fixtures/trunk-twisted-off-unseen-space.toml")).unwrap();
    let mut p = ClimbParams::default();
    p.run.sweep_while_moving = true;
    // Its plan is now made again from a standing look (the next test): executed as planned
    // from the moving pass, it shows the slowing.
    p.run.look_standing_when_held_off_unseen = false;
    let r = climb(&s, &p);
    assert_climbed(&r, &s, &p.checks);
    let model = stairbench::robot::hrp4::model().unwrap();
    let soles = stairbench::robot::hrp4::sole_frames(&model).unwrap();
    let [a_m, b_m] = model.sole_half_m(soles[0]).unwrap();
    let sole = mean_radius_m(a_m, b_m);
    let holds_nm = p.plan.step.friction * model.total_mass_kg() * stairbench::robot::GRAVITY_M_S2 * sole;
    for c in &r.cycles {
        let [_, yaw_nm] = c.plan_moments_nm.expect("each cycle reports its plan's moments");
        println!(
            "cycle {}: the plan asks {yaw_nm:.1} N m about the vertical, the sole holds {holds_nm:.1}",
            c.cycle
        );
        assert!(yaw_nm < holds_nm, "cycle {}: {yaw_nm:.1} N m against the sole's {holds_nm:.1}", c.cycle);
    }
}

/// A pass the head took moving leaves space near the body no ray crossed, and the IK keeps the
/// upper body 3 cm off its edge: `ci-0101`'s eighth cycle, planned from such a pass, held the
/// chest there, bowed the trunk 47 deg to do it, and brought both knees straight at the left
/// foot's touchdown; the loaded knee's bound then yanked the landing knee back and the foot
/// landed 22.1 mm off. A plan so held (`Plan::held_off_unseen`) is made again on a look taken
/// standing, which fills the gap: the climb keeps every check, and no plan executed from a
/// moving pass holds the body off such a gap.
#[test]
fn a_plan_bent_around_a_moving_pass_gap_is_made_again_from_a_standing_look() {
    use stairbench::planning::plan::HELD_M;
    let s =
        Scenario::load(std::path::Path::new("tests/fixtures/chest-held-off-a-moving-pass-gap.toml")).unwrap();
    let mut p = ClimbParams::default();
    p.run.sweep_while_moving = true;
    let r = climb(&s, &p);
    assert_climbed(&r, &s, &p.checks);
    let looked_again: Vec<usize> = (r.cycles.iter())
        .filter(|c| c.looked_again_standing.as_ref().is_some_and(|f| f.kind == RefusalKind::HeldOffUnseen))
        .map(|c| c.cycle)
        .collect();
    println!("made again from a standing look: cycles {looked_again:?}");
    assert!(!looked_again.is_empty(), "the moving pass of cycle 8 leaves the gap");
    // The look again costs one sweep taken standing: the robot settled for the look set
    // aside (its pass was whole by then), stands on until still, and the servo sweeps at
    // once from where its pass ended (level), with no return to the pass's start and no
    // second settle.
    let sweep_s = stairbench::sensor::TiltSweep::from_spec(&s.lidar).duration_s();
    for c in r.cycles.iter().filter(|c| looked_again.contains(&c.cycle)) {
        let most_s = p.run.settle_s + 2.0 * p.run.still_s + sweep_s + s.lidar.row_period_s;
        println!("cycle {}: stood {:.2} s, at most {most_s:.2} s", c.cycle, c.stood_s);
        assert!(c.stood_s <= most_s, "cycle {}: stood {:.2} s to look again", c.cycle, c.stood_s);
    }
    for c in &r.cycles {
        let held = (c.plan_nearest_unseen.as_ref())
            .is_some_and(|n| n.clearance_m < p.plan.ik.body_clearance_m + HELD_M);
        assert!(
            !held || c.cycle == 1 || c.looked_again_standing.is_some(),
            "cycle {}: a plan from a moving pass holds the body off its gap: {:?}",
            c.cycle,
            c.plan_nearest_unseen
        );
    }
}
