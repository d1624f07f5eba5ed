//! The speed margin: how much faster than planned the closed-loop climb can run and still
//! pass every check. The paper's motion is quasi-static (§6.2 neglects the CoM's
//! acceleration); this measures how far from that edge the plan runs. Each try is a whole
//! climb with the plan's timing sped up ([`PlanParams::faster`]: its speeds, shortest
//! durations and the IK's rates; the CoM's acceleration bound stays, so where it holds a
//! segment the plan shortens by less than the factor); the factor is doubled until a climb
//! fails, then bisected (geometrically) between the last pass and the first failure, each
//! factor tried rounded to [`FACTOR_STEP`] so that it is printed as tried and
//! `run --speedup` gives that climb again.
//!
//! The search takes a climb's outcome to change once along the factors; near the edge it
//! need not (a factor between two that climb may fall: CHANGELOG, sixty-first session), so
//! the margin is the last factor that passed before the first that failed, not a guarantee
//! for every factor below it.
//!
//! A try passes when it keeps every check and the planned timing's outcome: to the top
//! where that climbed. Where the case allows a refusal (its expected outcome `refuse` or
//! `either`) and the planned timing stopped safely short of the top (refused, or no
//! staircase seen ahead, every cycle passing), a try passes too when it stops safely no
//! earlier (at that cycle or later, as many steps climbed or more), so that the margin is of
//! the motion before the stop (the walks on the floor to look again); a faster try refused
//! sooner, before the motion it is to measure, fails.
//!
//! [`PlanParams::faster`]: crate::planning::PlanParams::faster

use super::outcome::{StopReason, Violation};
use super::ClimbReport;
use crate::planning::PlanParams;

/// The grid of the bisection's factors: hundredths, as `run` prints them.
pub const FACTOR_STEP: f64 = 0.01;

/// `f` on the grid of [`FACTOR_STEP`]: the nearest hundredth, as `--speedup` parses its
/// decimal (a division, rounded once).
fn on_grid(f: f64) -> f64 {
    let per_unit = (1.0 / FACTOR_STEP).round();
    (f * per_unit).round() / per_unit
}

/// The hundredth at or below `f` (`f` a hundredth itself give or take the rounding of its
/// decimal, `f` again).
fn on_grid_below(f: f64) -> f64 {
    let per_unit = (1.0 / FACTOR_STEP).round();
    (f * per_unit + 1e-6).floor() / per_unit
}

/// One climb of the search.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Try {
    /// Speed-up of the planned timing.
    pub factor: f64,
    /// The climb passed every check to the top.
    pub success: bool,
    /// It kept every check and the planned timing's outcome (see the module's doc): the
    /// search's pass.
    pub passes: bool,
    /// Its first violated check, if any.
    pub first_violation: Option<Violation>,
    /// Why the loop stopped early, if it did.
    pub stop: Option<StopReason>,
    /// Why it failed, in one line ([`ClimbReport::why_failed`]).
    pub why: Option<String>,
    /// Simulated time of the climb, seconds.
    pub sim_s: f64,
    /// Wall time, seconds.
    pub wall_s: f64,
}

/// The search's result.
#[derive(Debug, Clone, serde::Serialize)]
pub struct SpeedMargin {
    /// The case allows a refusal and the planned timing's climb stopped safely short of the
    /// top (see the module's doc): a try then passes by stopping safely no earlier.
    pub planned_stopped_safely: bool,
    /// The largest factor that passed (`None`: even the planned timing fails).
    pub passes_at: Option<f64>,
    /// The smallest factor that failed (`None`: every factor up to the maximum passed).
    pub fails_at: Option<f64>,
    /// Every climb, in the order run.
    pub tries: Vec<Try>,
}

/// Searches factors from 1 up to `max_factor` (the hundredth at or below it) until the pass
/// and fail factors are within `1 + resolution` of each other, or no factor of the grid
/// ([`FACTOR_STEP`]) lies between. `climb(plan)` runs one whole climb with the planner's
/// parameters `plan` (the given ones sped up); `on_try` sees each climb as it ends.
/// `refusal_allowed`: the case may be refused (see the module's doc).
pub fn speed_margin<E>(
    plan: &PlanParams,
    max_factor: f64,
    resolution: f64,
    refusal_allowed: bool,
    climb: &mut dyn FnMut(&PlanParams) -> Result<ClimbReport, E>,
    on_try: &mut dyn FnMut(&Try),
) -> Result<SpeedMargin, E> {
    let mut out =
        SpeedMargin { planned_stopped_safely: false, passes_at: None, fails_at: None, tries: Vec::new() };
    // Where the planned timing stopped safely (its cycle, steps climbed), when it did.
    let mut planned_stop: Option<(usize, usize)> = None;
    let mut attempt = |factor: f64, out: &mut SpeedMargin| -> Result<bool, E> {
        let r = climb(&plan.faster(factor))?;
        let stop = safe_stop(&r);
        if out.tries.is_empty() && refusal_allowed {
            planned_stop = stop;
            out.planned_stopped_safely = stop.is_some();
        }
        let no_earlier =
            |(cycle, steps): (usize, usize)| planned_stop.is_some_and(|(c0, s0)| cycle >= c0 && steps >= s0);
        let passes = r.success || stop.is_some_and(no_earlier);
        let t = Try {
            factor,
            success: r.success,
            passes,
            first_violation: r.first_violation().cloned(),
            stop: r.stop.clone(),
            why: r.why_failed(),
            sim_s: r.sim_s,
            wall_s: r.wall_s,
        };
        on_try(&t);
        out.tries.push(t);
        Ok(passes)
    };
    if !attempt(1.0, &mut out)? {
        out.fails_at = Some(1.0);
        return Ok(out);
    }
    // The largest factor tried is on the grid too.
    let max_factor = on_grid_below(max_factor).max(1.0);
    let (mut lo, mut hi) = (1.0_f64, None::<f64>);
    let mut f = 2.0_f64.min(max_factor);
    while f > lo {
        if attempt(f, &mut out)? {
            lo = f;
            f = (2.0 * f).min(max_factor);
        } else {
            hi = Some(f);
            break;
        }
    }
    if let Some(mut h) = hi {
        while h / lo > 1.0 + resolution {
            let mid = on_grid((lo * h).sqrt());
            if mid <= lo || mid >= h {
                break;
            }
            if attempt(mid, &mut out)? {
                lo = mid;
            } else {
                h = mid;
            }
        }
        hi = Some(h);
    }
    out.passes_at = Some(lo);
    out.fails_at = hi;
    Ok(out)
}

/// Where climb `r` stopped short of the top safely (its cycle and the steps climbed):
/// refused by the planner, or with no staircase seen ahead, every cycle passing; `None`
/// when it did not.
fn safe_stop(r: &ClimbReport) -> Option<(usize, usize)> {
    if r.first_violation().is_some() || !r.cycles.iter().all(|c| c.pass) {
        return None;
    }
    match r.stop {
        Some(StopReason::Refused { cycle, .. } | StopReason::NoStaircaseAhead { cycle, .. }) => {
            Some((cycle, r.steps_climbed))
        }
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::climb::report::fixture::report;
    use crate::climb::Footing;
    use crate::planning::PlanError;

    /// A climb through two floor cycles that ends as `stop` says (none: to the top), its
    /// last cycle breaking a check where `violated`.
    fn ended(stop: Option<StopReason>, violated: bool) -> ClimbReport {
        report(&[Footing::Floor, Footing::Floor], stop, violated)
    }

    /// The margin of climbs that end, by the speed-up they are made at, as `outcome` says
    /// (how they stopped, and whether a check broke on the way), of a case that may be
    /// refused or not.
    fn margin_with(
        refusal_allowed: bool,
        outcome: impl Fn(f64) -> (Option<StopReason>, bool),
    ) -> SpeedMargin {
        let base = PlanParams::default();
        let mut climb = |p: &PlanParams| -> Result<ClimbReport, ()> {
            let (stop, violated) = outcome(p.step.com_speed_m_s / base.step.com_speed_m_s);
            Ok(ended(stop, violated))
        };
        speed_margin(&base, 8.0, 0.1, refusal_allowed, &mut climb, &mut |_| {}).unwrap()
    }

    fn margin_of(refusal_allowed: bool, outcome: impl Fn(f64) -> Option<StopReason>) -> SpeedMargin {
        margin_with(refusal_allowed, |f| (outcome(f), false))
    }

    fn margin(outcome: impl Fn(f64) -> Option<StopReason>) -> SpeedMargin {
        margin_of(true, outcome)
    }

    #[test]
    fn a_refusal_at_the_planned_timing_is_measured_to_where_a_check_breaks() {
        let refused_at = |cycle| Some(StopReason::Refused { cycle, refusal: PlanError::NoSteps.refusal() });
        let refused = || refused_at(2);
        let fell = || Some(StopReason::Fell { cycle: 2 });
        // Refused up to x 3 (or climbing, as a faster look may see more), falls from x 3.
        for before in [refused(), None] {
            let m = margin(|f| {
                if f >= 3.0 - 1e-9 {
                    fell()
                } else if f <= 1.0 {
                    refused()
                } else {
                    before.clone()
                }
            });
            assert!(m.planned_stopped_safely);
            let (pass, fail) = (m.passes_at.unwrap(), m.fails_at.unwrap());
            assert!(pass < 3.0 && fail >= 3.0 - 1e-9 && fail / pass <= 1.1 + 1e-9, "{pass} {fail}");
            for t in &m.tries {
                assert_eq!(t.passes, t.factor < 3.0 - 1e-9, "x {}", t.factor);
            }
        }
        // A climb to the top at the planned timing keeps its margin only while it climbs:
        // a refusal when faster is a failure.
        let m = margin(|f| if f < 2.0 - 1e-9 { None } else { refused() });
        assert!(!m.planned_stopped_safely);
        assert!(m.passes_at.unwrap() < 2.0 && m.fails_at.unwrap() >= 2.0 - 1e-9);
        // A faster try refused sooner (before the walk it is to measure) fails.
        let m = margin(|f| if f <= 1.0 { refused() } else { refused_at(1) });
        assert_eq!(m.passes_at, Some(1.0));
        assert!(m.tries.iter().all(|t| t.passes == (t.factor <= 1.0)));
        // A case expected to climb has no margin where the planned timing is refused.
        let m = margin_of(false, |_| refused());
        assert!(!m.planned_stopped_safely);
        assert_eq!((m.passes_at, m.fails_at), (None, Some(1.0)));
        // A fall at the planned timing leaves no margin.
        let m = margin(|_| fell());
        assert_eq!((m.passes_at, m.fails_at), (None, Some(1.0)));
        // A refusal after a check broke is no safe stop: not at the planned timing (no
        // margin) ...
        let m = margin_with(true, |_| (refused(), true));
        assert!(!m.planned_stopped_safely);
        assert_eq!((m.passes_at, m.fails_at), (None, Some(1.0)));
        // ... nor at a faster one, refused at the same cycle as the planned timing.
        let m = margin_with(true, |f| (refused(), f >= 3.0 - 1e-9));
        assert!(m.planned_stopped_safely);
        assert!(m.passes_at.unwrap() < 3.0 && m.fails_at.unwrap() >= 3.0 - 1e-9);
        assert!(m.tries.iter().all(|t| t.passes == (t.factor < 3.0 - 1e-9)), "{:?}", m.tries);
    }

    /// The bisected factors are hundredths, each as `run` prints it and `--speedup` reads
    /// it: climbs failing from x 1.83 are bracketed by x 1.68 and x 1.83 at the CLI's
    /// resolution (unrounded, the bisection tried x 1.4142, 1.6818 and 1.8340), and a
    /// resolution finer than the grid ends where no hundredth lies between the two.
    #[test]
    fn the_bisected_factors_are_hundredths() {
        let base = PlanParams::default();
        for (resolution, bracket) in [(0.1, (1.68, 1.83)), (1e-6, (1.82, 1.83))] {
            let mut climb = |p: &PlanParams| -> Result<ClimbReport, ()> {
                let f = p.step.com_speed_m_s / base.step.com_speed_m_s;
                Ok(ended(None, f >= 1.83 - 1e-9))
            };
            let m = speed_margin(&base, 8.0, resolution, false, &mut climb, &mut |_| {}).unwrap();
            assert_eq!((m.passes_at, m.fails_at), (Some(bracket.0), Some(bracket.1)), "{:?}", m.tries);
            for t in &m.tries {
                assert_eq!(format!("{:.2}", t.factor).parse::<f64>(), Ok(t.factor));
            }
        }
        // The largest factor, as typed, is the hundredth at or below it.
        for hundredths in 100..=5000 {
            let typed: f64 = format!("{}.{:02}", hundredths / 100, hundredths % 100).parse().unwrap();
            assert_eq!(on_grid_below(typed), typed, "{typed}");
            assert_eq!(on_grid_below(typed + 0.004), typed, "{typed} + 0.004");
        }
    }
}
