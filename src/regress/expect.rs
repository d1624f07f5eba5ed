//! The expected outcome of a case, from its ground truth and the planner's declared limits
//! (the gait parameters, §6.1 and §6.4): `climb` when every step is within them, `refuse` when
//! one is beyond, `either` within perception's tolerance of a limit (perception measures a
//! tread up to about a voxel short and a rise to about a centimetre, so the planner may see
//! such a case on either side). Nothing here runs the planner: the expectation is what the
//! planner declares it can do, so a false refusal shows as one.

use crate::planning::footholds::GaitParams;
use crate::scenario::{ExpectSpec, ExpectedOutcome, Scenario};

/// How far perception may err on a tread's depth (about one voxel, §4.1: v = 2 cm, plus the
/// rectangle's fit), metres.
pub const TREAD_TOLERANCE_M: f64 = 0.03;
/// How far perception may err on a rise, metres.
pub const RISE_TOLERANCE_M: f64 = 0.01;
/// How far perception may err on a lane's overhang (the width of a step), metres.
pub const SIDE_TOLERANCE_M: f64 = 0.03;

/// The expectation of `s` for a robot whose soles stand `feet_half_spacing_m` either side of
/// its start line, planned with `gait`.
pub fn expect(s: &Scenario, gait: &GaitParams, feet_half_spacing_m: f64) -> ExpectSpec {
    let st = &s.staircase;
    let mut either = Vec::new();
    if let Some(&k) = st.missing_steps.first() {
        return refuse(format!(
            "step {k} is missing: a rise of {:.3} m where the others rise {:.3} m (plan.gait.missing_step_ratio {})",
            2.0 * st.rise_m,
            st.rise_m,
            gait.missing_step_ratio
        ));
    }
    if st.rise_m > gait.max_rise_m {
        return refuse(format!(
            "rise {:.3} m is beyond the legs' {:.3} m (plan.gait.max_rise_m)",
            st.rise_m, gait.max_rise_m
        ));
    }
    if st.rise_m > gait.max_rise_m - RISE_TOLERANCE_M {
        either
            .push(format!("rise {:.3} m is within {RISE_TOLERANCE_M} m of plan.gait.max_rise_m", st.rise_m));
    }
    if st.tread_m < gait.min_tread_m {
        return refuse(format!(
            "tread {:.3} m is shorter than a foot needs, {:.3} m (plan.gait.min_tread_m)",
            st.tread_m, gait.min_tread_m
        ));
    }
    if st.tread_m < gait.min_tread_m + TREAD_TOLERANCE_M {
        either.push(format!(
            "tread {:.3} m is within {TREAD_TOLERANCE_M} m of plan.gait.min_tread_m",
            st.tread_m
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
    if either.is_empty() {
        ExpectSpec {
            outcome: ExpectedOutcome::Climb,
            reason: format!(
                "every step within the planner's limits: rise {:.3} <= {:.3} m, tread {:.3} >= {:.3} m, soles {:.3} m inside the flight's sides ({:.3} m over allowed)",
                st.rise_m, gait.max_rise_m, st.tread_m, gait.min_tread_m, -over, gait.side_overhang_m
            ),
        }
    } else {
        ExpectSpec { outcome: ExpectedOutcome::Either, reason: either.join("; ") }
    }
}

fn refuse(reason: String) -> ExpectSpec {
    ExpectSpec { outcome: ExpectedOutcome::Refuse, reason }
}

/// How far the worse foot's sole overhangs the flight's side when it keeps its start lane,
/// metres (negative: inside).
pub fn lane_overhang_m(s: &Scenario, gait: &GaitParams, feet_half_spacing_m: f64) -> f64 {
    let st = &s.staircase;
    let (yaw, heading) = (st.yaw_rad(), s.robot.yaw_deg.to_radians());
    let left_of_flight = [-yaw.sin(), yaw.cos()];
    let left_of_robot = [-heading.sin(), heading.cos()];
    let mid = st.start_m;
    [-1.0, 1.0]
        .iter()
        .map(|side| {
            let foot = [
                s.robot.position_m[0] + side * feet_half_spacing_m * left_of_robot[0],
                s.robot.position_m[1] + side * feet_half_spacing_m * left_of_robot[1],
            ];
            let lane = (foot[0] - mid[0]) * left_of_flight[0] + (foot[1] - mid[1]) * left_of_flight[1];
            lane.abs() + gait.sole_width_m / 2.0 - st.width_m / 2.0
        })
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
