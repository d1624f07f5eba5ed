//! The speed margin: how much faster than planned the closed-loop climb can run and still
//! pass every check. The paper's motion is quasi-static (§6.2 neglects the CoM's
//! acceleration); this measures how far from that edge the plan runs. Each try is a whole
//! climb with the plan's timing sped up ([`PlanParams::faster`]: its speeds, shortest
//! durations and the IK's rates; the CoM's acceleration bound stays, so where it holds a
//! segment the plan shortens by less than the factor); the factor is doubled until a climb
//! fails, then bisected (geometrically) between the last pass and the first failure.
//!
//! [`PlanParams::faster`]: crate::planning::PlanParams::faster

use super::outcome::{StopReason, Violation};
use super::ClimbReport;
use crate::planning::PlanParams;

/// One climb of the search.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Try {
    /// Speed-up of the planned timing.
    pub factor: f64,
    /// The climb passed every check to the top.
    pub success: bool,
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
    /// The largest factor that passed (`None`: even the planned timing fails).
    pub passes_at: Option<f64>,
    /// The smallest factor that failed (`None`: every factor up to the maximum passed).
    pub fails_at: Option<f64>,
    /// Every climb, in the order run.
    pub tries: Vec<Try>,
}

/// Searches factors from 1 up to `max_factor` until the pass and fail factors are within
/// `1 + resolution` of each other. `climb(plan)` runs one whole climb with the planner's
/// parameters `plan` (the given ones sped up); `on_try` sees each climb as it ends.
pub fn speed_margin<E>(
    plan: &PlanParams,
    max_factor: f64,
    resolution: f64,
    climb: &mut dyn FnMut(&PlanParams) -> Result<ClimbReport, E>,
    on_try: &mut dyn FnMut(&Try),
) -> Result<SpeedMargin, E> {
    let mut out = SpeedMargin { passes_at: None, fails_at: None, tries: Vec::new() };
    let mut attempt = |factor: f64, out: &mut SpeedMargin| -> Result<bool, E> {
        let r = climb(&plan.faster(factor))?;
        let t = Try {
            factor,
            success: r.success,
            first_violation: r.first_violation().cloned(),
            stop: r.stop.clone(),
            why: r.why_failed(),
            sim_s: r.sim_s,
            wall_s: r.wall_s,
        };
        on_try(&t);
        out.tries.push(t);
        Ok(r.success)
    };
    if !attempt(1.0, &mut out)? {
        out.fails_at = Some(1.0);
        return Ok(out);
    }
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
            let mid = (lo * h).sqrt();
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
