//! A case's verdict: what the climb did against what was expected. A case passes when it
//! climbed clean, or when it was refused (or found nothing to climb) as expected before a
//! foot was set on the staircase, no check violated on the way (walking closer on the floor
//! to look is allowed), and the robot's own estimate stayed within the case's bound.

use crate::climb::{ClimbReport, Footing, StopReason};
use crate::scenario::{ExpectSpec, ExpectedOutcome};
use serde::{Deserialize, Serialize};
use std::fmt;

/// The verdict classes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// Climbed to the top with no check violated.
    ClimbedClean,
    /// Refused (or found nothing to climb) as expected, before a foot was on the staircase.
    RefusedAsExpected,
    /// Refused although the staircase is within the planner's limits.
    FalseRefusal,
    /// A check was violated (the climb may have gone on).
    CheckViolated,
    /// The robot fell.
    Fell,
    /// A foot was set on a staircase the planner's limits say must be refused.
    SteppedOntoUnclimbable,
    /// Climbed clean or refused as expected, but the robot's own estimate of its base
    /// strayed from the truth beyond the case's `max_estimate_error_m`.
    EstimateStrayed,
    /// Perception found no staircase to climb before the top.
    NoStaircaseFound,
    /// The bench failed (a setup or executor error, a sensor failure, unstable physics, the
    /// loop giving up after its most cycles).
    Error,
    /// The case ran past its wall-time limit.
    Timeout,
}

impl Verdict {
    /// Every class, in report order.
    pub const ALL: [Verdict; 10] = [
        Verdict::ClimbedClean,
        Verdict::RefusedAsExpected,
        Verdict::FalseRefusal,
        Verdict::CheckViolated,
        Verdict::Fell,
        Verdict::SteppedOntoUnclimbable,
        Verdict::EstimateStrayed,
        Verdict::NoStaircaseFound,
        Verdict::Error,
        Verdict::Timeout,
    ];

    /// Whether this verdict passes.
    pub fn pass(self) -> bool {
        matches!(self, Verdict::ClimbedClean | Verdict::RefusedAsExpected)
    }

    /// Its name (as in JSON and JUnit failure types).
    pub fn name(self) -> &'static str {
        match self {
            Verdict::ClimbedClean => "climbed_clean",
            Verdict::RefusedAsExpected => "refused_as_expected",
            Verdict::FalseRefusal => "false_refusal",
            Verdict::CheckViolated => "check_violated",
            Verdict::Fell => "fell",
            Verdict::SteppedOntoUnclimbable => "stepped_onto_unclimbable",
            Verdict::EstimateStrayed => "estimate_strayed",
            Verdict::NoStaircaseFound => "no_staircase_found",
            Verdict::Error => "error",
            Verdict::Timeout => "timeout",
        }
    }
}

impl fmt::Display for Verdict {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.pad(&self.name().replace('_', " "))
    }
}

/// The verdict of `report` against `expect` ([`classify`]'s on its outcome), and a passing
/// one `estimate_strayed` when the robot's estimate strayed beyond the expectation's bound;
/// `timed_out` when the runner cancelled it.
pub fn verdict_of(expect: &ExpectSpec, report: &ClimbReport, timed_out: bool) -> Verdict {
    let v = classify(expect.outcome, expect.before_step, report, timed_out);
    if v.pass() && strayed(expect, report).is_some() {
        Verdict::EstimateStrayed
    } else {
        v
    }
}

/// How far the robot's estimate strayed beyond `expect`'s bound: what it says, `None` within
/// the bound or without one (or without the truth to judge it by).
pub fn strayed(expect: &ExpectSpec, report: &ClimbReport) -> Option<String> {
    let (most, e) = expect.max_estimate_error_m.zip(report.max_estimate_error_m())?;
    (e > most).then(|| {
        format!(
            "the robot's estimate strayed {:.1} mm from the truth at a sweep (at most {:.1} mm allowed)",
            e * 1e3,
            most * 1e3
        )
    })
}

/// The verdict of `report` against `expect`; `timed_out` when the runner cancelled it. A
/// refusal (`refuse`, or `either` refused) with `before_step` (1-based) forbids a foot on
/// that step and above only before it; without it, on the whole staircase.
pub fn classify(
    expect: ExpectedOutcome,
    before_step: Option<u32>,
    report: &ClimbReport,
    timed_out: bool,
) -> Verdict {
    if timed_out {
        return Verdict::Timeout;
    }
    // A foot set where the expectation forbids one: on the staircase, or on `before_step`
    // and above it.
    let first_forbidden = before_step.map_or(1, |k| k as usize);
    let stepped = report.cycles.iter().any(|c| matches!(c.to, Footing::Step(k) if k >= first_forbidden));
    let fell = matches!(report.stop, Some(StopReason::Fell { .. } | StopReason::FellStanding { .. }))
        || report.cycles.iter().any(|c| c.execution.fell);
    if fell {
        return Verdict::Fell;
    }
    if matches!(
        report.stop,
        Some(
            StopReason::SimulationUnstable { .. }
                | StopReason::SensorFailed { .. }
                | StopReason::PerceptionFailed { .. }
                | StopReason::CyclesExhausted { .. }
        )
    ) {
        return Verdict::Error;
    }
    if matches!(report.stop, Some(StopReason::StoppedByUser { .. })) {
        return Verdict::Timeout;
    }
    // A check violated fails the case whatever came after it: a refusal later on does not
    // undo a foot that pushed past the surface's friction on the way up.
    if report.first_violation().is_some() || matches!(report.stop, Some(StopReason::SlidStanding { .. })) {
        return Verdict::CheckViolated;
    }
    let stopped_short =
        matches!(report.stop, Some(StopReason::Refused { .. } | StopReason::NoStaircaseAhead { .. }));
    match expect {
        ExpectedOutcome::Refuse if stepped => Verdict::SteppedOntoUnclimbable,
        ExpectedOutcome::Refuse if stopped_short => Verdict::RefusedAsExpected,
        ExpectedOutcome::Refuse => Verdict::SteppedOntoUnclimbable,
        ExpectedOutcome::Either if !stepped && stopped_short => Verdict::RefusedAsExpected,
        _ if report.success => Verdict::ClimbedClean,
        _ => match report.stop {
            Some(StopReason::Refused { .. }) => Verdict::FalseRefusal,
            Some(StopReason::NoStaircaseAhead { .. }) => Verdict::NoStaircaseFound,
            _ => Verdict::Error,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::climb::report::fixture::report;
    use crate::planning::PlanError;

    /// Seconds per stair count the cycles that went up a step only: not the floor walk, not
    /// a cycle that stayed on its step; with the stand, each one's standing before its plan.
    #[test]
    fn seconds_per_stair_counts_the_cycles_that_went_up() {
        use Footing::*;
        let mut r = report(&[Floor, Step(1), Step(1), Step(2)], None, false);
        for ((c, s), stood) in r.cycles.iter_mut().zip([10.0, 17.0, 5.0, 19.0]).zip([7.0, 6.5, 9.0, 7.5]) {
            c.execution.sim_s = s;
            c.stood_s = stood;
        }
        assert_eq!(r.seconds_per_stair(), Some(18.0));
        assert_eq!(r.seconds_per_stair_with_stand(), Some(25.0));
        assert_eq!(report(&[Floor, Floor], None, false).seconds_per_stair(), None);
    }

    fn refused(cycle: usize) -> Option<StopReason> {
        Some(StopReason::Refused { cycle, refusal: PlanError::NoSteps.refusal() })
    }

    #[test]
    fn verdicts_follow_the_expectation_and_where_the_feet_went() {
        use ExpectedOutcome::*;
        use Footing::*;
        let climbed = report(&[Floor, Step(1), Step(2), Step(3)], None, false);
        assert_eq!(classify(Climb, None, &climbed, false), Verdict::ClimbedClean);
        assert_eq!(classify(Refuse, None, &climbed, false), Verdict::SteppedOntoUnclimbable);
        assert_eq!(classify(Climb, None, &climbed, true), Verdict::Timeout);
        // Refused after walking closer on the floor: as expected, or a false refusal.
        let looked = report(&[Floor, Floor], refused(3), false);
        assert_eq!(classify(Refuse, None, &looked, false), Verdict::RefusedAsExpected);
        assert_eq!(classify(Either, None, &looked, false), Verdict::RefusedAsExpected);
        assert_eq!(classify(Climb, None, &looked, false), Verdict::FalseRefusal);
        // Refused once on the stairs: an unclimbable staircase was stepped onto.
        let late = report(&[Step(1)], refused(2), false);
        assert_eq!(classify(Refuse, None, &late, false), Verdict::SteppedOntoUnclimbable);
        assert_eq!(classify(Either, None, &late, false), Verdict::FalseRefusal);
        // Something in a lane on step 2, seen from step 1: refused before a foot went on it.
        assert_eq!(classify(Refuse, Some(2), &late, false), Verdict::RefusedAsExpected);
        assert_eq!(classify(Refuse, Some(1), &late, false), Verdict::SteppedOntoUnclimbable);
        // Something near a lane on step 2 (`either`): a refusal from step 1 is one outcome.
        assert_eq!(classify(Either, Some(2), &late, false), Verdict::RefusedAsExpected);
        assert_eq!(classify(Either, Some(1), &late, false), Verdict::FalseRefusal);
        let nothing = report(&[], Some(StopReason::NoStaircaseAhead { cycle: 1, last_view: None }), false);
        assert_eq!(classify(Climb, None, &nothing, false), Verdict::NoStaircaseFound);
        assert_eq!(classify(Refuse, None, &nothing, false), Verdict::RefusedAsExpected);
        let hit = report(&[Floor, Step(1), Step(2), Step(3)], None, true);
        assert_eq!(classify(Climb, None, &hit, false), Verdict::CheckViolated);
        // A check violated on the way up and then refused where a refusal was expected: the
        // violation stands.
        let hit_then_refused = report(&[Step(1)], refused(2), true);
        for expect in [Refuse, Either] {
            assert_eq!(classify(expect, Some(2), &hit_then_refused, false), Verdict::CheckViolated);
        }
        let fell = report(&[Step(1)], Some(StopReason::Fell { cycle: 1 }), true);
        assert_eq!(classify(Climb, None, &fell, false), Verdict::Fell);
        // Down while standing for the next sweep, after a cycle that passed: a fall too.
        let fall = crate::climb::Check::Fall {
            base_z_m: 0.2,
            min_base_z_m: 0.5,
            tilt_rad: 1.4,
            limit_tilt_rad: 0.52,
            upright_tilt_rad: 1.4,
        };
        let down = report(&[Step(1)], Some(StopReason::FellStanding { cycle: 2, fall }), false);
        for expect in [Climb, Refuse, Either] {
            assert_eq!(classify(expect, None, &down, false), Verdict::Fell);
        }
        let gave_up = report(&[Floor], Some(StopReason::CyclesExhausted { cycles: 40 }), false);
        assert_eq!(classify(Climb, None, &gave_up, false), Verdict::Error);
        assert!(Verdict::ALL.iter().filter(|v| v.pass()).count() == 2);
    }

    /// A run that passed with its estimate farther off than the case allows is
    /// `estimate_strayed`; a failing one keeps its own verdict, and without a bound the
    /// estimate is not judged.
    #[test]
    fn an_estimate_beyond_the_bound_fails_a_run_that_passed_otherwise() {
        use Footing::*;
        let off = |mut r: ClimbReport, position_m: f64| {
            r.cycles[0].estimate_error =
                Some(crate::estimate::EstimateError { position_m, height_m: 0.0, yaw_rad: 0.0 });
            r
        };
        let spec = |max_estimate_error_m| ExpectSpec {
            outcome: ExpectedOutcome::Climb,
            reason: String::new(),
            before_step: None,
            max_estimate_error_m,
        };
        let climbed = report(&[Floor, Step(1), Step(2), Step(3)], None, false);
        assert_eq!(
            verdict_of(&spec(Some(0.025)), &off(climbed.clone(), 0.042), false),
            Verdict::EstimateStrayed
        );
        let why = strayed(&spec(Some(0.025)), &off(climbed.clone(), 0.042)).expect("strayed");
        assert!(why.contains("42.0 mm") && why.contains("25.0 mm"), "{why}");
        assert_eq!(
            verdict_of(&spec(Some(0.025)), &off(climbed.clone(), 0.010), false),
            Verdict::ClimbedClean
        );
        assert_eq!(verdict_of(&spec(None), &off(climbed, 0.042), false), Verdict::ClimbedClean);
        let hit = report(&[Floor, Step(1)], None, true);
        assert_eq!(verdict_of(&spec(Some(0.025)), &off(hit, 0.042), false), Verdict::CheckViolated);
        assert!(!Verdict::EstimateStrayed.pass());
    }
}
