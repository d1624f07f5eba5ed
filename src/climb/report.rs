//! The loop's reports: one [`CycleReport`] per scan-plan-execute cycle and a [`ClimbReport`]
//! for the climb, typed data from which the terminal table and the JSON are rendered. The
//! JSON keeps the keys its readers know (`success`, `steps_climbed`, `steps_total`, `stopped`
//! as text, `cycles[].pass`, `cycles[].min_margin_m`, `cycles[].max_torque_ratio`,
//! `cycles[].violations`) and adds the typed ones (`stop`, `first_violation`, the summary
//! figures).

use super::execution::Execution;
use super::outcome::{StopReason, Violation};
use crate::estimate::EstimateError;
use crate::planning::{NearestSurface, Refusal};
use serde::{Serialize, Serializer};
use std::fmt;

/// Where a cycle took the feet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Footing {
    /// Still on the floor (walking closer to look).
    Floor,
    /// On this step (1 = lowest; the ground truth's numbering).
    Step(usize),
}

impl fmt::Display for Footing {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // `pad`, so tables can align it with `{:<8}`.
        match self {
            Footing::Floor => f.pad("floor"),
            Footing::Step(n) => f.pad(&format!("step {n}")),
        }
    }
}

impl Serialize for Footing {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

/// One scan-plan-execute cycle.
#[derive(Debug, Clone, Serialize)]
pub struct CycleReport {
    /// 1-based cycle.
    pub cycle: usize,
    /// Where the cycle took the feet (`floor` or `step N` in JSON).
    pub to: Footing,
    /// No check violated (`execution.pass()`, kept for the JSON report's readers).
    pub pass: bool,
    /// Steps the plan was made on (the known steps ahead).
    pub steps_seen: usize,
    /// The refusal this cycle walked to look at again (the plan of the flight was refused
    /// from here for what another view may show otherwise: the cycle walked on the floor
    /// toward the flight, or back from a first riser out of the lidar's sight, or climbed the
    /// steps below the refused one); `None` for a cycle of the climb's own plan.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub closer_look: Option<Refusal>,
    /// The refusal of the plan made from a sweep taken as the robot moved, which the loop set
    /// aside to stand and look again from where it stood (its pass then all cast from
    /// there) before this cycle's plan; `None` where the first plan held. The refused look
    /// took a cycle's number of its own, which no report carries; its stand is in this
    /// cycle's `stood_s`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub looked_again_standing: Option<Refusal>,
    /// Simulated (or the robot's clock's) seconds it stood before the cycle's plan: its
    /// settle, and its sweep when the sweep was taken standing, at the time a real head
    /// takes for the rows (the simulated lidar casts a standing sweep in no simulated time).
    /// A sweep taken as the robot moved costs no standing.
    pub stood_s: f64,
    /// Wall time of the sweep, seconds.
    pub scan_s: f64,
    /// Perception wall time, seconds.
    pub perceive_s: f64,
    /// Planning wall time, seconds.
    pub plan_s: f64,
    /// Wall time of the execution with its checks, seconds.
    pub execute_s: f64,
    /// How far the robot's estimate of its base was from the truth when the cycle's sweep
    /// was taken (`None` where no truth is known, as on a real robot).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub estimate_error: Option<EstimateError>,
    /// The offset the step map's registration moved the robot's estimate by this cycle,
    /// metres (x, y, z), when it did: on this cycle's view, and on a look set aside before it
    /// (`looked_again_standing`), summed. A look after which the climb stopped (the top's, a
    /// refusal's, even one taken again after a look set aside) is in no cycle.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub correction_m: Option<[f64; 3]>,
    /// And turned it by about the vertical, radians (summed likewise).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub correction_yaw_rad: Option<f64>,
    /// Where the plan brought the body (arms, trunk, head) nearest a surface the lidar saw
    /// (what the plan kept against what the execution touched), in the plan's frame (the
    /// robot's estimate of the world when it keeps one); absent when none came within the
    /// IK's clearance range.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub plan_nearest_surface: Option<NearestSurface>,
    /// Where the plan brought the body nearest the edge of space the lidar left unseen
    /// (`Tracking::nearest_unseen_surface`), in the same frame; absent when none came
    /// within the IK's clearance range.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plan_nearest_unseen: Option<NearestSurface>,
    /// The largest moments the plan's change of angular momentum asked of the contacts, N m:
    /// about a horizontal axis, and about the vertical (`Tracking::max_tipping_moment_nm`,
    /// `max_yaw_moment_nm`); absent in reports written before it was measured.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plan_moments_nm: Option<[f64; 2]>,
    /// What the execution found (flattened into the JSON: `min_margin_m`,
    /// `max_torque_ratio`, `torque_joint`, `touchdowns`, `violations`, `sim_s`, ...).
    #[serde(flatten)]
    pub execution: Execution,
}

/// The whole climb.
#[derive(Debug, Clone)]
pub struct ClimbReport {
    /// Scenario name.
    pub scenario: String,
    /// Climbed to the top with no check violated.
    pub success: bool,
    /// Steps whose tread both feet stood on at the end (the highest reached).
    pub steps_climbed: usize,
    /// Steps of the staircase.
    pub steps_total: usize,
    /// Why the loop stopped early (a refusal, no staircase, a fall), if it did.
    pub stop: Option<StopReason>,
    /// One entry per cycle.
    pub cycles: Vec<CycleReport>,
    /// Simulated time, seconds.
    pub sim_s: f64,
    /// Wall time, seconds.
    pub wall_s: f64,
    /// Every refusal of a plan made from a sweep taken walking that the loop set aside to
    /// look again standing, in order (the cycle after each carries it; a last one may be
    /// followed by the refusal that stopped the climb, made on the standing look).
    pub looked_again_standing: Vec<Refusal>,
}

/// Wall time of a climb by stage, seconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct StageTimes {
    /// Sweeps.
    pub scan_s: f64,
    /// Perception.
    pub perceive_s: f64,
    /// Planning.
    pub plan_s: f64,
    /// Execution with its checks: the physics, the stabilizer, and the checks with the
    /// rest of the loop.
    pub execute_s: f64,
    /// Of `execute_s`, MuJoCo's steps (0 in results written before it was kept).
    #[serde(default)]
    pub physics_s: f64,
    /// Of `execute_s`, the stabilizer's ticks (0 likewise, and without the stabilizer).
    #[serde(default)]
    pub control_s: f64,
}

impl ClimbReport {
    /// How many times faster than real time the execution ran (MuJoCo with the servos and
    /// every check, without scanning, perception or planning).
    pub fn execution_speed(&self) -> f64 {
        let sim_s: f64 = self.cycles.iter().map(|c| c.execution.sim_s).sum();
        sim_s / self.stage_times().execute_s.max(1e-9)
    }

    /// Simulated seconds of motion per stair: the mean execution time of the cycles that
    /// went up onto a step (each plans one stance a scan by default), the stabilizer's hold
    /// of the plan's end until the body is still counted, without the standing still before
    /// each scan and the sweep; `None` when no cycle went up.
    pub fn seconds_per_stair(&self) -> Option<f64> {
        let ups: Vec<f64> = self.up_cycles().map(|c| c.execution.sim_s).collect();
        (!ups.is_empty()).then(|| ups.iter().sum::<f64>() / ups.len() as f64)
    }

    /// Seconds per stair with the standing: [`Self::seconds_per_stair`]'s cycles, each with
    /// the standing before its plan ([`CycleReport::stood_s`]: the settle and a standing
    /// sweep) counted; perception and planning, which a real robot also stands through
    /// (a fraction of a second each here), are not.
    pub fn seconds_per_stair_with_stand(&self) -> Option<f64> {
        let ups: Vec<f64> = self.up_cycles().map(|c| c.stood_s + c.execution.sim_s).collect();
        (!ups.is_empty()).then(|| ups.iter().sum::<f64>() / ups.len() as f64)
    }

    /// The cycles that went up onto a step.
    fn up_cycles(&self) -> impl Iterator<Item = &CycleReport> {
        let mut below = Footing::Floor;
        self.cycles.iter().filter(move |c| {
            let up = match (below, c.to) {
                (Footing::Floor, Footing::Step(_)) => true,
                (Footing::Step(a), Footing::Step(b)) => b > a,
                _ => false,
            };
            below = c.to;
            up
        })
    }

    /// The longest a cycle waited for perception and planning, seconds.
    pub fn worst_think_s(&self) -> f64 {
        self.cycles.iter().map(|c| c.perceive_s + c.plan_s).fold(0.0, f64::max)
    }

    /// The mean over the cycles of `f`, 0 without cycles.
    pub fn mean_per_cycle(&self, f: impl Fn(&CycleReport) -> f64) -> f64 {
        self.cycles.iter().map(f).sum::<f64>() / self.cycles.len().max(1) as f64
    }

    /// Wall time summed over the cycles, by stage.
    pub fn stage_times(&self) -> StageTimes {
        self.cycles.iter().fold(StageTimes::default(), |t, c| StageTimes {
            scan_s: t.scan_s + c.scan_s,
            perceive_s: t.perceive_s + c.perceive_s,
            plan_s: t.plan_s + c.plan_s,
            execute_s: t.execute_s + c.execute_s,
            physics_s: t.physics_s + c.execution.physics_wall_s,
            control_s: t.control_s + c.execution.control.map_or(0.0, |k| k.wall_s),
        })
    }

    /// The first violated check of the climb.
    pub fn first_violation(&self) -> Option<&Violation> {
        self.cycles.iter().flat_map(|c| &c.execution.violations).next()
    }

    /// The smallest CoM margin over every cycle, metres (`+inf` without cycles).
    pub fn min_margin_m(&self) -> f64 {
        self.cycles.iter().map(|c| c.execution.min_margin_m).fold(f64::INFINITY, f64::min)
    }

    /// The largest torque ratio over every cycle, with its joint.
    pub fn max_torque(&self) -> (f64, &str) {
        self.cycles
            .iter()
            .map(|c| (c.execution.max_torque_ratio, c.execution.torque_joint.as_str()))
            .fold((0.0, ""), |a, b| if b.0 > a.0 { b } else { a })
    }

    /// The largest friction ratio a loaded foot used over every cycle.
    pub fn max_friction_ratio(&self) -> f64 {
        self.cycles.iter().map(|c| c.execution.max_friction_ratio).fold(0.0, f64::max)
    }

    /// The largest moment about the vertical a cycle's plan asked of the contacts, N m
    /// ([`CycleReport::plan_moments_nm`]); `None` when no cycle reports one.
    pub fn max_plan_yaw_moment_nm(&self) -> Option<f64> {
        self.cycles.iter().filter_map(|c| c.plan_moments_nm.map(|m| m[1])).reduce(f64::max)
    }

    /// The largest true speed of the base at which the robot judged itself still at a plan's
    /// end, m/s ([`Execution::still_true_speed_m_s`]; `None` when no hold ended so).
    pub fn max_still_true_speed_m_s(&self) -> Option<f64> {
        self.cycles.iter().filter_map(|c| c.execution.still_true_speed_m_s).reduce(f64::max)
    }

    /// The largest error of the robot's estimate of its base's position at a sweep over every
    /// cycle, metres (`None` when no cycle knew the truth beside an estimate).
    pub fn max_estimate_error_m(&self) -> Option<f64> {
        self.cycles.iter().filter_map(|c| c.estimate_error).map(|e| e.position_m).reduce(f64::max)
    }

    /// The largest error of the robot's estimate of its yaw at a sweep, radians (absolute;
    /// `None` as for [`ClimbReport::max_estimate_error_m`]).
    pub fn max_estimate_yaw_rad(&self) -> Option<f64> {
        self.cycles.iter().filter_map(|c| c.estimate_error).map(|e| e.yaw_rad.abs()).reduce(f64::max)
    }

    /// Why the climb failed, in one line: the first violated check, else why the loop
    /// stopped, else how far it got (`None` on success).
    pub fn why_failed(&self) -> Option<String> {
        if self.success {
            return None;
        }
        let line = match (self.first_violation(), &self.stop) {
            (Some(v), _) => v.to_string(),
            (None, Some(s)) => s.to_string(),
            (None, None) => format!("{} of {} steps climbed", self.steps_climbed, self.steps_total),
        };
        Some(line)
    }
}

/// The JSON form of a [`ClimbReport`].
#[derive(Serialize)]
struct ClimbReportJson<'a> {
    scenario: &'a str,
    success: bool,
    steps_climbed: usize,
    steps_total: usize,
    /// The stop reason's message (the key older readers know).
    stopped: Option<String>,
    /// The stop reason as data.
    stop: &'a Option<StopReason>,
    first_violation: Option<&'a Violation>,
    min_margin_m: Option<f64>,
    max_torque_ratio: f64,
    torque_joint: &'a str,
    max_friction_ratio: f64,
    stage_times: StageTimes,
    cycles: &'a [CycleReport],
    sim_s: f64,
    wall_s: f64,
}

impl Serialize for ClimbReport {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let (max_torque_ratio, torque_joint) = self.max_torque();
        let margin = self.min_margin_m();
        ClimbReportJson {
            scenario: &self.scenario,
            success: self.success,
            steps_climbed: self.steps_climbed,
            steps_total: self.steps_total,
            stopped: self.stop.as_ref().map(ToString::to_string),
            stop: &self.stop,
            first_violation: self.first_violation(),
            min_margin_m: margin.is_finite().then_some(margin),
            max_torque_ratio,
            torque_joint,
            max_friction_ratio: self.max_friction_ratio(),
            stage_times: self.stage_times(),
            cycles: &self.cycles,
            sim_s: self.sim_s,
            wall_s: self.wall_s,
        }
        .serialize(s)
    }
}

/// Reports made up for tests of what reads them.
#[cfg(test)]
pub(crate) mod fixture {
    use super::*;
    use crate::climb::outcome::Check;

    /// A climb of 3 steps through cycles to `cycles`, stopped by `stop` (none: to the top);
    /// `violated`: its last cycle broke a check (a knee's collision with step 2).
    pub(crate) fn report(cycles: &[Footing], stop: Option<StopReason>, violated: bool) -> ClimbReport {
        let cycles: Vec<CycleReport> = cycles
            .iter()
            .enumerate()
            .map(|(i, to)| {
                let mut execution = Execution::empty();
                let broke = violated && i + 1 == cycles.len();
                if broke {
                    execution.violations.push(Violation {
                        t_s: 1.0,
                        cycle: i + 1,
                        check: Check::Collision { geom: "knee".into(), other: "step_2".into() },
                    });
                }
                CycleReport {
                    cycle: i + 1,
                    to: *to,
                    pass: !broke,
                    steps_seen: 3,
                    closer_look: None,
                    looked_again_standing: None,
                    stood_s: 0.0,
                    scan_s: 0.0,
                    perceive_s: 0.0,
                    plan_s: 0.0,
                    execute_s: 0.0,
                    estimate_error: None,
                    correction_m: None,
                    correction_yaw_rad: None,
                    plan_nearest_surface: None,
                    plan_nearest_unseen: None,
                    plan_moments_nm: None,
                    execution,
                }
            })
            .collect();
        let success = stop.is_none() && !violated;
        ClimbReport {
            scenario: "t".into(),
            success,
            steps_climbed: if success { 3 } else { 0 },
            steps_total: 3,
            stop,
            cycles,
            sim_s: 0.0,
            wall_s: 0.0,
            looked_again_standing: Vec::new(),
        }
    }
}
