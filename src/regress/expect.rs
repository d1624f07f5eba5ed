//! The expected outcome of a case, from its ground truth and the planner's declared limits
//! (the gait parameters, §6.1 and §6.4): `climb` when every step is within them, `refuse` when
//! one is beyond, `either` within perception's tolerance of a limit (perception measures a
//! tread up to about a voxel short and a rise to about a centimetre, so the planner may see
//! such a case on either side). Nothing here runs the planner: the expectation is what the
//! planner declares it can do, so a false refusal shows as one.

use crate::planning::footholds::GaitParams;
use crate::scenario::{ExpectSpec, ExpectedOutcome, Scenario};
use crate::scene::{RAIL_INSET_M, RAIL_M};

/// How far perception may err on a tread's depth (about one voxel, §4.1: v = 2 cm, plus the
/// rectangle's fit), metres.
pub const TREAD_TOLERANCE_M: f64 = 0.03;
/// How far perception may err on the span between two steps' fronts placed on their
/// risers or noses (each within a few millimetres at 10 mm of range noise, see
/// `perception::riser`), metres.
pub const BETWEEN_TOLERANCE_M: f64 = 0.015;
/// How far perception may err on a rise, metres.
pub const RISE_TOLERANCE_M: f64 = 0.01;
/// How far perception may err on a lane's overhang (the width of a step), metres.
pub const SIDE_TOLERANCE_M: f64 = 0.03;

/// The expectation of `s` for a robot whose soles stand `feet_half_spacing_m` either side of
/// its start line, planned with `gait`.
pub fn expect(s: &Scenario, gait: &GaitParams, feet_half_spacing_m: f64) -> ExpectSpec {
    let st = &s.staircase;
    let layout = st.layout();
    let mut either = Vec::new();
    // The rises between the treads present: a missing step makes one of two rises.
    let mut rises = Vec::new();
    let mut below_m = 0.0;
    for step in layout.iter().filter(|l| !l.missing) {
        rises.push((step.index, step.height_m - below_m));
        below_m = step.height_m;
    }
    let usual_m = crate::stats::median(rises.iter().map(|r| r.1)).unwrap_or(st.rise_m);
    if let Some(&k) = st.missing_steps.first() {
        return refuse(format!(
            "step {k} is missing: a rise of {:.3} m where the others rise {usual_m:.3} m (plan.gait.missing_step_ratio {})",
            rises.iter().map(|r| r.1).fold(0.0, f64::max),
            gait.missing_step_ratio
        ));
    }
    for &(i, rise) in &rises {
        if rises.len() >= 3 && rise >= gait.missing_step_ratio * usual_m - RISE_TOLERANCE_M {
            let why = format!(
                "step {}'s rise {rise:.3} m is {:.2} times the flight's usual {usual_m:.3} m (plan.gait.missing_step_ratio {}: taken for a missing step)",
                i + 1,
                rise / usual_m,
                gait.missing_step_ratio
            );
            if rise >= gait.missing_step_ratio * usual_m + RISE_TOLERANCE_M {
                return refuse(why);
            }
            either.push(why);
        }
        if rise > gait.max_rise_m {
            return refuse(format!(
                "step {}: rise {rise:.3} m is beyond the legs' {:.3} m (plan.gait.max_rise_m)",
                i + 1,
                gait.max_rise_m
            ));
        }
        if rise > gait.max_rise_m - RISE_TOLERANCE_M {
            either.push(format!(
                "step {}: rise {rise:.3} m is within {RISE_TOLERANCE_M} m of plan.gait.max_rise_m",
                i + 1
            ));
        }
    }
    let max_rise_m = rises.iter().map(|r| r.1).fold(0.0, f64::max);
    // Between two steps the toes keep `toe_clearance_m` behind the next nose and the heel
    // overhangs its own by `heel_overhang_m` at most (the footholds' rule, with the fronts on
    // the noses): such a tread needs more than the top one, open behind.
    let between_m = gait.sole_length_m + gait.toe_clearance_m - gait.heel_overhang_m;
    let last = layout.len().saturating_sub(1);
    if let Some(short) = layout
        .iter()
        .filter(|l| l.index < last && l.going_m < between_m + BETWEEN_TOLERANCE_M)
        .min_by(|a, b| a.going_m.total_cmp(&b.going_m))
    {
        let why = format!(
            "step {}: tread {:.3} m between two steps, where the toes' clearance and the heel's overhang leave a sole {between_m:.3} m",
            short.index + 1,
            short.going_m
        );
        // Refused for sure only below `min_tread_m` (below): the footholds keep the toes
        // off a next front placed on its riser, and from afar a front may not be.
        either.push(format!("{why}, within {BETWEEN_TOLERANCE_M} m"));
    }
    let min_tread_m = layout.iter().map(|l| l.going_m).fold(f64::INFINITY, f64::min);
    if min_tread_m < gait.min_tread_m {
        return refuse(format!(
            "tread {min_tread_m:.3} m is shorter than a foot needs, {:.3} m (plan.gait.min_tread_m)",
            gait.min_tread_m
        ));
    }
    if min_tread_m < gait.min_tread_m + TREAD_TOLERANCE_M {
        either.push(format!(
            "tread {min_tread_m:.3} m is within {TREAD_TOLERANCE_M} m of plan.gait.min_tread_m"
        ));
    }
    // Each foot keeps its lane across the flight (§6.1): its sole must stay on the treads.
    let over = lane_overhang_m(s, gait, feet_half_spacing_m);
    if over > gait.side_overhang_m {
        return refuse(format!(
            "a foot's lane overhangs the {:.3} m wide flight by {over:.3} m (plan.gait.side_overhang_m {})",
            st.width_m, gait.side_overhang_m
        ));
    }
    if over > gait.side_overhang_m - SIDE_TOLERANCE_M {
        either.push(format!("a foot's lane overhangs the flight by {over:.3} m, within {SIDE_TOLERANCE_M} m of plan.gait.side_overhang_m"));
    }
    let lanes = lanes_m(s, feet_half_spacing_m);
    // The highest tread with something near a lane on it: seen only from nearer, it may be
    // refused from the steps below it (and the lanes, moved away from it, may leave a lower
    // tread too narrow: a refusal there is about it too).
    let mut object_step = None;
    for (k, o) in s.objects.iter().enumerate() {
        match object_in_the_way(s, o, lanes, gait) {
            Some(Blocks::Lane(why)) => {
                // Refused before a foot is set on the object's tread: from the floor the
                // lidar may not see a high tread, and the steps below it are safe to climb.
                return ExpectSpec { before_step: Some(o.step), ..refuse(format!("objects[{k}] {why}")) };
            }
            Some(Blocks::Near(why)) => {
                object_step = object_step.max((o.step > 0).then_some(o.step));
                either.push(format!("objects[{k}] {why}"))
            }
            None => {}
        }
    }
    if let Some(why) = between_handrails(s, gait) {
        return refuse(why);
    }
    if let Some(why) = handrail_near_the_body(s, lanes, gait) {
        either.push(why);
    }
    if either.is_empty() {
        ExpectSpec::new(
            ExpectedOutcome::Climb,
            format!(
                "every step within the planner's limits: rise {max_rise_m:.3} <= {:.3} m, tread {min_tread_m:.3} >= {:.3} m, soles {:.3} m inside the flight's sides ({:.3} m over allowed)",
                gait.max_rise_m, gait.min_tread_m, -over, gait.side_overhang_m
            ),
        )
    } else {
        ExpectSpec { before_step: object_step, ..ExpectSpec::new(ExpectedOutcome::Either, either.join("; ")) }
    }
}

/// How near a leg's lane a thing beside it may stand before the legs' clearance from what
/// the lidar saw may refuse the lane, metres (the legs keep 3 cm from seen points, which
/// stand up to 2 cm proud of a surface under noise, and the sole may shift a few
/// centimetres across).
pub const LANE_CLEARANCE_M: f64 = 0.10;

/// What an object does to the climb.
enum Blocks {
    /// It stands in a foot's lane on its tread with no room for a sole before or behind it.
    Lane(String),
    /// It stands near a lane, or in one with room for a sole beside it: the planner may
    /// refuse it or climb past.
    Near(String),
}

/// Whether object `o` is in the way of the feet (lanes `lanes`, across the flight from its
/// middle line) or of the body.
fn object_in_the_way(
    s: &Scenario,
    o: &crate::scenario::ObjectSpec,
    lanes: [f64; 2],
    gait: &GaitParams,
) -> Option<Blocks> {
    let st = &s.staircase;
    let (corners, _) = o.placed(st);
    let yaw = st.yaw_rad();
    let (u, w) = ([yaw.cos(), yaw.sin()], [-yaw.sin(), yaw.cos()]);
    let rel = |c: &[f64; 2], d: [f64; 2]| (c[0] - st.start_m[0]) * d[0] + (c[1] - st.start_m[1]) * d[1];
    let span = |d: [f64; 2]| {
        corners
            .iter()
            .map(|c| rel(c, d))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |m, x| (m.0.min(x), m.1.max(x)))
    };
    let ((a0, a1), (w0, w1)) = (span(u), span(w));
    let half_sole = gait.sole_width_m / 2.0;
    let gap_to_lane = lanes
        .iter()
        .map(|&l| (w0 - (l + half_sole)).max((l - half_sole) - w1).max(0.0))
        .fold(f64::INFINITY, f64::min);
    let what = format!("({:.2} x {:.2} x {:.2} m)", o.size_m[0], o.size_m[1], o.size_m[2]);
    if o.step == 0 {
        // On the floor: in the way only between the robot and the flight, or under the path.
        let before = a1 > -2.0 && a0 < 0.0;
        return (before && gap_to_lane < LANE_CLEARANCE_M).then(|| {
            Blocks::Near(format!(
                "{what} on the floor {:.2} m from a lane, on the way to the flight",
                gap_to_lane
            ))
        });
    }
    let step = st.layout()[o.step as usize - 1];
    if gap_to_lane <= 0.0 {
        let nose = step.nose_m(st.nosing_m);
        let end = step.riser_m + step.going_m;
        let room_m = (a0 - nose).max(end - a1);
        let needs_m = gait.sole_length_m + 2.0 * LANE_CLEARANCE_M;
        // A thing as tall as the body's band stands beside the body too: the lanes may move
        // away from it (the footholds' lane shift), where the flight is wide enough.
        let lanes_may_shift = o.size_m[2] >= gait.body_band_m[0];
        return Some(if room_m < needs_m && !lanes_may_shift {
            Blocks::Lane(format!(
                "{what} on step {} stands in a foot's lane, leaving {room_m:.2} m of the tread where a sole needs {needs_m:.2} m",
                o.step
            ))
        } else {
            Blocks::Near(format!(
                "{what} on step {} stands in a foot's lane with {room_m:.2} m of the tread free{}",
                o.step,
                if lanes_may_shift { ", tall enough for the lanes to move away from it" } else { "" }
            ))
        });
    }
    let mid = (lanes[0] + lanes[1]) / 2.0;
    let body_m = (w0 - mid).max(mid - w1);
    if gap_to_lane < LANE_CLEARANCE_M
        || (body_m < gait.body_half_width_m + LANE_CLEARANCE_M && o.size_m[2] > gait.body_band_m[0])
    {
        return Some(Blocks::Near(format!(
            "{what} on step {} stands {gap_to_lane:.2} m beside a foot's lane",
            o.step
        )));
    }
    None
}

/// Handrails on both sides with less room between them than the body's whole width
/// (`body_half_width_m` twice), beyond perception's tolerance: the planner refuses the
/// flight before a foot is set on it.
fn between_handrails(s: &Scenario, gait: &GaitParams) -> Option<String> {
    let st = &s.staircase;
    let room_m = st.width_m - 2.0 * (RAIL_INSET_M + RAIL_M / 2.0);
    let needs_m = 2.0 * gait.body_half_width_m;
    (st.handrails.sides().len() == 2 && room_m < needs_m - SIDE_TOLERANCE_M).then(|| {
        format!("the handrails leave {room_m:.2} m between them, less than the {needs_m:.2} m the body sweeps (plan.gait.body_half_width_m twice)")
    })
}

/// A handrail's posts or rail within the body's half width (`body_half_width_m`, the lane
/// the arms sweep with their clearance) of the robot's middle line, within perception's
/// tolerance: the planner moves the lanes away from it where the flight is wide enough, or
/// refuses; a reason for `either`.
fn handrail_near_the_body(s: &Scenario, lanes: [f64; 2], gait: &GaitParams) -> Option<String> {
    let st = &s.staircase;
    let mid = (lanes[0] + lanes[1]) / 2.0;
    st.handrails.sides().iter().find_map(|&side| {
        let rail = side * (st.width_m / 2.0 - RAIL_INSET_M) - mid;
        let room_m = rail.abs() - RAIL_M / 2.0;
        (room_m < gait.body_half_width_m + SIDE_TOLERANCE_M).then(|| {
            format!(
                "the {} handrail stands {room_m:.2} m from the robot's middle line, within the body's {:.2} m half width and perception's {SIDE_TOLERANCE_M:.2} m tolerance",
                if side > 0.0 { "left" } else { "right" },
                gait.body_half_width_m
            )
        })
    })
}

/// Each foot's lane across the flight, from its middle line (left positive), right first,
/// metres, as the feet stand at the start.
pub fn lanes_m(s: &Scenario, feet_half_spacing_m: f64) -> [f64; 2] {
    let st = &s.staircase;
    let (yaw, heading) = (st.yaw_rad(), s.robot.yaw_deg.to_radians());
    let left_of_flight = [-yaw.sin(), yaw.cos()];
    let left_of_robot = [-heading.sin(), heading.cos()];
    let mid = st.start_m;
    [-1.0, 1.0].map(|side| {
        let foot = [
            s.robot.position_m[0] + side * feet_half_spacing_m * left_of_robot[0],
            s.robot.position_m[1] + side * feet_half_spacing_m * left_of_robot[1],
        ];
        (foot[0] - mid[0]) * left_of_flight[0] + (foot[1] - mid[1]) * left_of_flight[1]
    })
}

fn refuse(reason: String) -> ExpectSpec {
    ExpectSpec::new(ExpectedOutcome::Refuse, reason)
}

/// How far the worse foot's sole overhangs the flight's side when it keeps its start lane,
/// metres (negative: inside).
pub fn lane_overhang_m(s: &Scenario, gait: &GaitParams, feet_half_spacing_m: f64) -> f64 {
    lanes_m(s, feet_half_spacing_m)
        .iter()
        .map(|lane| lane.abs() + gait.sole_width_m / 2.0 - s.staircase.width_m / 2.0)
        .fold(f64::NEG_INFINITY, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    const FEET: f64 = 0.1013;

    fn outcome(f: impl Fn(&mut Scenario)) -> ExpectedOutcome {
        let mut s = Scenario::default();
        f(&mut s);
        expect(&s, &GaitParams::default(), FEET).outcome
    }

    #[test]
    fn the_expectation_follows_the_declared_limits_with_a_band_for_perception() {
        assert_eq!(outcome(|_| {}), ExpectedOutcome::Climb, "Exp. 1");
        assert_eq!(outcome(|s| s.staircase.rise_m = 0.24), ExpectedOutcome::Climb, "the paper's 24 cm step");
        assert_eq!(outcome(|s| s.staircase.rise_m = 0.40), ExpectedOutcome::Refuse);
        assert_eq!(outcome(|s| s.staircase.rise_m = 0.275), ExpectedOutcome::Either);
        assert_eq!(outcome(|s| s.staircase.tread_m = 0.18), ExpectedOutcome::Refuse);
        assert_eq!(outcome(|s| s.staircase.tread_m = 0.23), ExpectedOutcome::Either);
        assert_eq!(outcome(|s| s.staircase.missing_steps = vec![2]), ExpectedOutcome::Refuse);
        // Lanes 0.101 m either side: a 0.25 m flight puts each sole 0.044 m over its sides.
        assert_eq!(outcome(|s| s.staircase.width_m = 0.25), ExpectedOutcome::Refuse);
        assert_eq!(outcome(|s| s.staircase.width_m = 0.32), ExpectedOutcome::Either);
        // The same flight with the robot 20 cm off its middle line: the left lane is off.
        assert_eq!(outcome(|s| s.robot.position_m[1] = 0.2), ExpectedOutcome::Refuse);
    }

    /// Regression `chest-between-two-rails`: handrails on both sides of a 0.82 m flight
    /// leave 0.67 m between their bars, less than the body's 0.72 m: refused; with 0.76 m
    /// between them (a 0.91 m flight), perception's tolerance decides: either.
    #[test]
    fn handrails_on_both_sides_nearer_than_the_body_are_refused() {
        use crate::scenario::Handrails;
        let both = |width_m: f64| {
            outcome(|s| {
                s.staircase.width_m = width_m;
                s.staircase.handrails = Handrails::Both;
            })
        };
        assert_eq!(both(0.82), ExpectedOutcome::Refuse);
        assert_eq!(both(0.89), ExpectedOutcome::Either);
        assert_eq!(both(1.2), ExpectedOutcome::Climb);
        let one = outcome(|s| {
            s.staircase.width_m = 0.82;
            s.staircase.handrails = Handrails::Left;
        });
        assert_eq!(one, ExpectedOutcome::Either, "one rail: the lanes may move away from it");
    }

    #[test]
    fn something_near_a_lane_high_on_the_flight_may_be_refused_from_below_it() {
        let mut s = Scenario::default();
        s.staircase.steps = 6;
        s.staircase.width_m = 1.2;
        // A person-tall bag in the right lane on step 5: the lanes may move away from it.
        let bag = crate::scenario::ObjectSpec {
            step: 5,
            along_m: 0.12,
            across_m: -0.1,
            size_m: [0.3, 0.25, 0.5],
            ..Default::default()
        };
        s.objects.push(bag.clone());
        let e = expect(&s, &GaitParams::default(), FEET);
        assert_eq!((e.outcome, e.before_step), (ExpectedOutcome::Either, Some(5)), "{}", e.reason);
        // On the floor beside the path: any refusal comes before the flight.
        s.objects[0] = crate::scenario::ObjectSpec { step: 0, along_m: -0.3, across_m: 0.3, ..bag };
        let e = expect(&s, &GaitParams::default(), FEET);
        assert_eq!((e.outcome, e.before_step), (ExpectedOutcome::Either, None), "{}", e.reason);
    }

    #[test]
    fn a_lane_overhang_is_measured_across_the_flight_whatever_the_yaws() {
        let mut s = Scenario::default();
        let gait = GaitParams::default();
        let straight = lane_overhang_m(&s, &gait, FEET);
        assert!((straight - (FEET + 0.065 - 0.25)).abs() < 1e-12);
        // Turn the whole world by 30 degrees about the robot: nothing changes.
        let yaw = 30f64.to_radians();
        s.staircase.yaw_deg = 30.0;
        s.robot.yaw_deg = 30.0;
        s.staircase.start_m = [0.6 * yaw.cos(), 0.6 * yaw.sin()];
        assert!((lane_overhang_m(&s, &gait, FEET) - straight).abs() < 1e-12);
    }
}
