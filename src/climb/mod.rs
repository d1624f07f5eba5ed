//! The closed loop, the bench's main job: stand, sweep the lidar, perceive, update the step
//! map, plan the next stance, execute it with every check, sweep again from the new pose,
//! until the top (the upper steps are reconstructed after stepping on the lower ones, as in
//! the paper). The loop knows its sensor only as a [`Source`] and its robot only as an
//! [`Executor`]; the MuJoCo simulation is one implementation of each (`sim`), the real
//! sensors and recordings others. What happens is told to an [`Observer`] as [`Event`]s;
//! outcomes are typed ([`outcome`]).

pub mod event;
pub mod execution;
pub mod executor;
pub mod outcome;
pub mod report;
pub mod speed_margin;

pub use event::{Each, Event, Nobody, Observer, RobotState, Watch};
pub use execution::{ControlCost, Execution, Touchdown};
pub use executor::{Executor, Standing};
pub use outcome::{Check, CheckKind, SimWarning, StopReason, Violation};
pub use report::{ClimbReport, CycleReport, Footing, StageTimes};

use crate::cancel::Cancel;
use crate::estimate::EstimateError;
use crate::perception::step_map::{NextInput, StepMap, StepMapParams};
use crate::perception::surroundings::{Surroundings, SurroundingsParams};
use crate::perception::PlaneSegment;
use crate::perception::{perceive, PerceptionError, PerceptionParams};
use crate::planning::clearance::{body_capsules, SeenPoints};
use crate::planning::footholds::riser_in_sight;
use crate::planning::plan::stance_at;
use crate::planning::{Plan, PlanParams, PlanRequest, Refusal};
use crate::robot::hrp4;
use crate::robot::model::RobotModel;
use crate::robot::Kinematics;
use crate::scene::geometry::SOLE_ON_TREAD_M;
use crate::scene::Scene;
use crate::sensor::{AssembleParams, SensorError, Source};
use std::sync::Arc;
use std::time::Instant;

/// Settings of the loop itself.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RunParams {
    /// Stances planned and executed between two scans.
    pub stances_per_scan: usize,
    /// Most scan-plan-execute cycles before giving up.
    pub max_cycles: usize,
    /// Standing still before each scan, seconds (the servos settle; the real robot scans
    /// standing still too).
    pub settle_s: f64,
    /// After `settle_s`, the robot stands on until its base has moved no faster than this
    /// for `still_s` in a row, m/s (at most `max_settle_s` in all), as its own estimate
    /// places the base (encoders, the anchor sole, the IMU; the simulator's truth where the
    /// loop reads it, `[estimate] enabled = false`): a plan starts from the
    /// measured configuration, taken at rest (§6.2's motion is quasi-static). At x 2 speed
    /// Exp. 1's floor walk ended with the robot swaying sideways at 0.1 m/s; the next plan
    /// started mid-sway and the CoM left the right sole's polygon 43 ms in.
    pub still_speed_m_s: f64,
    /// How long the base must stay under `still_speed_m_s`, seconds (a sway's turning point
    /// is slow for an instant: a plan started there, the robot tipping, failed at once).
    /// The two also end the stabilizer's hold of a plan's last instant
    /// (`StabilizerParams::max_end_hold_s`).
    pub still_s: f64,
    /// Longest stand before a scan, seconds: the settle's (a head that sweeps as the robot
    /// moves then stands on until its pass is whole, `sweep_while_moving`).
    pub max_settle_s: f64,
    /// The lidar sweeps as the robot moves (issue 42's "no standing still for a scan"): the
    /// sweep a plan is made from is the servo's last pass, which ends when the loop looks
    /// and runs level last ([`crate::sensor::TiltSweep::level_last`]), each row cast from
    /// where the head was at its instant and assembled where the robot's own estimate had
    /// the head then, smoothed back from the sweep's end by its gyro
    /// (`crate::estimate::path`; in simulation the robot records the head's path,
    /// `sim::head_track`; the real sensors sweep standing). After each pass the servo swings
    /// back (`LidarSpec::tilt_return_speed_dps`) and the next begins; a look that comes
    /// before it is whole (the first, one after a short motion) stands until it is
    /// (`crate::sensor::Source::whole_in_s`). Off (the default): every sweep is taken where
    /// the robot stands after its settle (in simulation cast in no simulated time; a real
    /// robot stands the sweep's 6 s). A plan refused on a pass the head took moving is made
    /// again once on a look taken standing where the robot is
    /// (`CycleReport::looked_again_standing`): a moving head's pass leaves space near the
    /// body no ray crossed (its steep rows are the oldest), which the body keeps off; so is
    /// one the body is held off such a gap in (`look_standing_when_held_off_unseen`). Not
    /// yet the default: nothing drives the real servo so, though every suite passes with it
    /// on (the figures: BENCHMARKS.md).
    pub sweep_while_moving: bool,
    /// With `sweep_while_moving`, a plan made on a pass the head took moving that holds the
    /// upper body at its clearance from space the pass left unseen
    /// ([`crate::planning::Plan::held_off_unseen`]) is made again on a look taken standing,
    /// as a refused one is. On by default: the gap is the moving head's (a standing look
    /// fills it), and a motion bent around it bows and twists the trunk to keep off it.
    /// Off: such plans are executed (to see what they do).
    pub look_standing_when_held_off_unseen: bool,
    /// Friction coefficient of the surfaces of a hardware rehearsal's world (`run
    /// --hardware`: the perceived steps rebuilt in simulation, whose true friction nobody
    /// measured; the checks judge the rehearsal against it). Default 0.7, the plan's.
    pub rehearsal_friction: f64,
}

impl Default for RunParams {
    fn default() -> Self {
        Self {
            stances_per_scan: 1,
            max_cycles: 40,
            settle_s: 0.3,
            still_speed_m_s: 0.01,
            still_s: 0.2,
            max_settle_s: 2.0,
            sweep_while_moving: false,
            look_standing_when_held_off_unseen: true,
            rehearsal_friction: crate::planning::contact::DEFAULT_FRICTION,
        }
    }
}

/// The parameters the loop uses (the executor has its own).
#[derive(Debug, Clone, Copy)]
pub struct LoopParams<'a> {
    /// Perception (§4, Table 1).
    pub perception: &'a PerceptionParams,
    /// The step map.
    pub step_map: &'a StepMapParams,
    /// What the lidar saw around the steps (the body's clearance).
    pub surroundings: &'a SurroundingsParams,
    /// Planning (§6).
    pub plan: &'a PlanParams,
    /// The loop's own settings.
    pub run: &'a RunParams,
}

/// What the loop runs against.
pub struct Bench<'a, E: Executor> {
    /// Where sweeps come from.
    pub source: &'a mut dyn Source,
    /// What executes the plans.
    pub robot: &'a mut E,
    /// The model of the robot (kinematics for planning and for where the feet are).
    pub model: &'a RobotModel,
    /// The world as it really is: the steps to climb, and how many the robot climbed (in
    /// simulation the scenario's scene; in a rehearsal the world built from perception).
    pub truth: &'a Scene,
}

/// Why a climb could not run at all (a failing executor), as opposed to a failed climb.
#[derive(Debug, thiserror::Error)]
pub enum ClimbError {
    /// The executor failed (not a check: a broken simulator or robot link).
    #[error("the executor failed: {0}")]
    Executor(#[source] Box<dyn std::error::Error + Send + Sync>),
    /// The robot model.
    #[error(transparent)]
    Robot(#[from] crate::robot::RobotError),
}

/// Runs the closed loop to the top, a refusal, a fall, a cancellation or `max_cycles`.
pub fn run<E: Executor>(
    bench: Bench<'_, E>,
    p: LoopParams<'_>,
    observer: &mut dyn Observer,
    cancel: &Cancel,
) -> Result<ClimbReport, ClimbError> {
    let Bench { source, robot, model, truth } = bench;
    let failed = |e: E::Error| ClimbError::Executor(Box::new(e));
    let started = Instant::now();
    let t0 = robot.now_s();
    let mut report = ClimbReport {
        scenario: truth.name().to_string(),
        success: false,
        steps_climbed: 0,
        steps_total: truth.steps().len(),
        stop: None,
        cycles: Vec::new(),
        sim_s: 0.0,
        wall_s: 0.0,
        looked_again_standing: Vec::new(),
    };
    observer.event(&Event::Scene(truth));
    let mut map = StepMap::default();
    let mut around = Surroundings::default();
    let mut last_cycle = 0;
    // The floor the climb starts from: the only one the loop walks on to look closer.
    let mut start_floor = None;
    // The refusal of a plan made from a sweep taken moving, set aside to look again standing.
    let mut set_aside: Option<SetAside> = None;
    for cycle in 1..=p.run.max_cycles {
        last_cycle = cycle;
        let stand_from_s = robot.now_s();
        if let Some(stop) = stand_to_look(robot, source, p.run, set_aside.is_some(), cycle).map_err(failed)? {
            report.stop = Some(stop);
            break;
        }
        let mut q = robot.configuration();
        let start_floor_z_m = *start_floor.get_or_insert_with(|| feet_height_m(model, &q));
        let stamp_s = robot.now_s();
        let estimate_error = robot.true_configuration().and_then(|truth| EstimateError::of(&q, &truth));
        let View { mut sweep, mut cloud, seen, nothing, scan_s, perceive_s } =
            match look(source, model, &q, cycle, stamp_s, p.perception, observer, cancel) {
                Ok(view) => view,
                Err(stop) => {
                    report.stop = Some(*stop);
                    break;
                }
            };
        let stood_s = stood_s(&sweep, stand_from_s, stamp_s, robot.now_s());
        // A look set aside before this one moved the estimate too: the cycle reports both moves.
        let mut correction = set_aside.as_ref().map_or((None, None), |f| f.correction);
        let seen = register(robot, &map, seen, (&mut q, &mut sweep, &mut cloud), p.step_map, &mut correction);
        let (correction_m, correction_yaw_rad) = correction;
        let t = Instant::now();
        // A plan refused on a sweep the head took moving is refused for what that sweep saw:
        // its rows crossed the space about the body from where the head was, seconds before.
        // The robot stands and looks again (a sweep taken standing, from here); a refusal on
        // that view stands. So is a plan held at its clearance from a gap the moving pass left
        // (`Plan::held_off_unseen`; tests/climb.rs `a_plan_bent_around_a_moving_pass_gap...`).
        // The look taken standing replaces the one set aside: that look's steps leave the map
        // (kept, a step it misread outlives the look that does not see it: tests/loop.rs
        // `a_step_only_a_look_set_aside_saw_is_not_kept`); its returns stay in the surroundings.
        let may_look_standing =
            set_aside.is_none() && cycle < p.run.max_cycles && sweep.head_travel_m() > STILL_HEAD_M;
        let known_before = may_look_standing.then(|| map.clone());
        let ViewInput { next, surfaces } = take_view(&mut map, &mut around, seen, &cloud, model, &q, p);
        let view = |observer: &mut dyn Observer, set_aside: bool| {
            observer.event(&Event::View { stamp_s, q: &q, set_aside });
        };
        let ahead = &next.ahead;
        if ahead.is_empty() {
            view(observer, false);
            // The stop's reason is the report's: judged on the true pose where it is known.
            let true_q = robot.true_configuration().unwrap_or_else(|| q.clone());
            if climbed(truth, model, &true_q) < truth.steps().len() {
                report.stop = Some(StopReason::NoStaircaseAhead { cycle, last_view: nothing });
            }
            break;
        }
        let planned = plan_next(model, &q, &next, surfaces, p.run.stances_per_scan, start_floor_z_m, p.plan);
        let refuse_held = may_look_standing && p.run.look_standing_when_held_off_unseen;
        let (planned, closer_look) = match refusing_held_off_unseen(planned, &p.plan.ik, refuse_held) {
            Ok(x) => x,
            Err(refusal) if may_look_standing => {
                report.looked_again_standing.push((*refusal).clone());
                map = known_before.unwrap_or(map);
                view(observer, true);
                let plan_s = t.elapsed().as_secs_f64();
                let correction = (correction_m, correction_yaw_rad);
                set_aside =
                    Some(SetAside { refusal: *refusal, stood_s, scan_s, perceive_s, plan_s, correction });
                continue;
            }
            Err(refusal) => {
                view(observer, false);
                report.stop = Some(StopReason::Refused { cycle, refusal: *refusal });
                break;
            }
        };
        view(observer, false);
        let plan_s = t.elapsed().as_secs_f64();
        let plan_height_error_m = robot.true_configuration().map_or(0.0, |t| q[2] - t[2]);
        let t = Instant::now();
        observer.event(&Event::Plan { stamp_s: robot.now_s(), steps: ahead, plan: &planned });
        let exec_start_s = robot.now_s();
        let mut execution = robot.execute(&planned, observer, cancel).map_err(failed)?;
        let execute_s = t.elapsed().as_secs_f64();
        for v in &mut execution.violations {
            v.cycle = cycle;
            observer.event(&Event::Violation { stamp_s: exec_start_s + v.t_s, violation: v });
        }
        // Where the cycle went, on the true treads (the report's): the stance's height carried
        // into the world by the estimate's height error when the plan was made.
        let to = planned.stances.last().map_or(Footing::Floor, |s| {
            footing(truth, start_floor_z_m, s.right.translation.z - plan_height_error_m)
        });
        let first = set_aside.take();
        let c = CycleReport {
            cycle,
            to,
            pass: execution.pass(),
            steps_seen: ahead.len(),
            closer_look,
            stood_s: stood_s + first.as_ref().map_or(0.0, |f| f.stood_s),
            scan_s: scan_s + first.as_ref().map_or(0.0, |f| f.scan_s),
            perceive_s: perceive_s + first.as_ref().map_or(0.0, |f| f.perceive_s),
            plan_s: plan_s + first.as_ref().map_or(0.0, |f| f.plan_s),
            looked_again_standing: first.map(|f| f.refusal),
            execute_s,
            estimate_error,
            correction_m,
            correction_yaw_rad,
            plan_nearest_surface: planned.tracking.nearest_body_surface.clone(),
            plan_nearest_unseen: planned.tracking.nearest_unseen_surface.clone(),
            plan_moments_nm: Some(planned.tracking.moments_nm()),
            execution,
        };
        observer.event(&Event::Cycle { stamp_s: robot.now_s(), report: &c });
        let stop = stop_after(&c.execution, cycle, cancel);
        report.cycles.push(c);
        if stop.is_some() {
            report.stop = stop;
            break;
        }
    }
    // The cycles ran out with nothing stopping the loop: it stands once more, so a fall after
    // the last execution is not a success.
    if report.stop.is_none() && last_cycle == p.run.max_cycles {
        report.stop = standing_stop(robot.settle(p.run.settle_s).map_err(failed)?, last_cycle + 1);
    }
    let q = robot.true_configuration().unwrap_or_else(|| robot.configuration());
    report.steps_climbed = climbed(truth, model, &q);
    if report.stop.is_none() && last_cycle == p.run.max_cycles && report.steps_climbed < report.steps_total {
        report.stop = Some(StopReason::CyclesExhausted { cycles: last_cycle });
    }
    report.sim_s = robot.now_s() - t0;
    report.wall_s = started.elapsed().as_secs_f64();
    report.success = report.stop.is_none()
        && report.steps_climbed == report.steps_total
        && report.cycles.iter().all(|c| c.pass);
    Ok(report)
}

/// How a registration moved the robot's estimate: metres (x, y, z), and about the vertical,
/// radians; `None` where it did not.
type Correction = (Option<[f64; 3]>, Option<f64>);

/// A view under the estimate's drift registered on the known steps and moved onto them, and
/// the estimate with it (the robot's own; a robot that keeps none is not moved, nor is its
/// view): its steps, with the view's configuration `q`, sweep and cloud moved, and the move
/// added to `correction`.
fn register<E: Executor>(
    robot: &mut E,
    map: &StepMap,
    seen: Vec<PlaneSegment>,
    (q, sweep, cloud): (&mut Vec<f64>, &mut crate::sensor::Sweep, &mut crate::cloud::PointCloud),
    p: &StepMapParams,
    correction: &mut Correction,
) -> Vec<PlaneSegment> {
    let viewpoint = nalgebra::Point3::from(sweep.mount_to_world.translation.vector);
    match map.register(&seen, &viewpoint, p) {
        Some(offset) if robot.correct(&offset) => {
            let before = q[..3].to_vec();
            *q = robot.configuration();
            let earlier = correction.0.unwrap_or([0.0; 3]);
            correction.0 = Some([0, 1, 2].map(|i| earlier[i] + q[i] - before[i]));
            correction.1 = Some(correction.1.unwrap_or(0.0) + offset.rotation.euler_angles().2);
            let (moved, moved_cloud) = moved_view(&offset, seen, sweep);
            if let Some(c) = moved_cloud {
                *cloud = c;
            }
            moved
        }
        _ => seen,
    }
}

/// One view from where the robot stands: its sweep, put together where the robot believes its
/// head is (at configuration `q`, levelled by the gravity its rows measured), and what
/// perception found in it.
struct View {
    sweep: crate::sensor::Sweep,
    cloud: crate::cloud::PointCloud,
    /// The steps found (none when perception found no staircase, and then why).
    seen: Vec<PlaneSegment>,
    nothing: Option<crate::perception::NoStaircase>,
    scan_s: f64,
    perceive_s: f64,
}

/// A look whose plan was refused on a sweep taken walking, set aside to look again standing:
/// the refusal, and what the look took (seconds), carried into the next executed cycle.
struct SetAside {
    refusal: Refusal,
    stood_s: f64,
    scan_s: f64,
    perceive_s: f64,
    plan_s: f64,
    /// How its view's registration moved the estimate: the robot stays moved.
    correction: Correction,
}

/// A head that went no farther during a sweep, metres, saw as a standing one does (a
/// standing robot's sway moves it by millimetres; a step's walk by tenths of a metre).
const STILL_HEAD_M: f64 = 0.02;

/// Seconds the robot stood before a plan: from `from_s` (the settle's start) to `looked_s`
/// (the view in hand), and, for a sweep taken standing, the rows' time a real head takes
/// that the source's clock did not pass from `still_s` (the settle's end) on (a simulated
/// standing sweep is cast in none).
fn stood_s(sweep: &crate::sensor::Sweep, from_s: f64, still_s: f64, looked_s: f64) -> f64 {
    let rows_s = match sweep.moving() {
        true => 0.0,
        false => sweep.rows.len() as f64 * sweep.lidar.row_period_s(),
    };
    (looked_s - from_s) + (rows_s - (looked_s - still_s)).max(0.0)
}

/// Sweeps `source` and perceives the view at configuration `q` (its events told to
/// `observer`, stamped `stamp_s`); the cycle's stop when the sensor or perception fails.
#[allow(clippy::too_many_arguments)]
fn look(
    source: &mut dyn Source,
    model: &RobotModel,
    q: &[f64],
    cycle: usize,
    stamp_s: f64,
    perception: &PerceptionParams,
    observer: &mut dyn Observer,
    cancel: &Cancel,
) -> Result<View, Box<StopReason>> {
    let t = Instant::now();
    let failed = |error: String| Box::new(StopReason::SensorFailed { cycle, error });
    let mut sweep = match source.sweep(cancel, &mut |_, _| {}) {
        Ok(s) => s,
        Err(SensorError::Cancelled { .. }) => return Err(Box::new(StopReason::StoppedByUser { cycle })),
        Err(e) => return Err(failed(e.to_string())),
    };
    let head =
        head_pose(model, q).ok_or_else(|| failed("the robot's configuration gives no head pose".into()))?;
    sweep.mount_to_world = head * sweep.lidar.mount_in_head;
    let cloud = sweep.assemble(&AssembleParams::default()).map_err(|e| failed(e.to_string()))?;
    let scan_s = t.elapsed().as_secs_f64();
    observer.event(&Event::Sweep { stamp_s, sweep: &sweep });
    observer.event(&Event::Cloud { stamp_s, cloud: &cloud });
    let t = Instant::now();
    let perceived = perceive(&cloud, perception);
    let perceive_s = t.elapsed().as_secs_f64();
    let (seen, nothing) = match perceived {
        Ok(r) => {
            observer.event(&Event::Perception { stamp_s, result: &r });
            (r.segments, None)
        }
        Err(e) => {
            observer.event(&Event::PerceptionFailed { stamp_s, error: &e });
            match e {
                PerceptionError::NoStaircase(why) => (Vec::new(), Some(why)),
                e => return Err(Box::new(StopReason::PerceptionFailed { cycle, error: e.to_string() })),
            }
        }
    };
    Ok(View { sweep, cloud, seen, nothing, scan_s, perceive_s })
}

/// The robot stands for a look: it settles (`run.settle_s`, then until still); a head that
/// sweeps as the robot moves looks when its pass is whole, and the robot stands on while
/// the servo returns from the last pass or the pass under way ends. A look again standing
/// (`again`) comes where the robot settled for the look set aside: it stands on only until
/// still and while the servo goes from where its pass ended to where a sweep taken standing
/// starts (no time for the paper's sweep: a pass ends level, where that sweep starts). The
/// stop when the robot fell or slid standing.
fn stand_to_look<E: Executor>(
    robot: &mut E,
    source: &mut dyn Source,
    run: &RunParams,
    again: bool,
    cycle: usize,
) -> Result<Option<StopReason>, E::Error> {
    let settle_s = if again { 0.0 } else { run.settle_s };
    if let Some(stop) = standing_stop(robot.settle(settle_s)?, cycle) {
        return Ok(Some(stop));
    }
    let wait_s = if again { source.sweep_standing_next() } else { source.whole_in_s() };
    if wait_s > 0.0 {
        return Ok(standing_stop(robot.settle(wait_s)?, cycle));
    }
    Ok(None)
}

/// Why the loop stops after the robot stood before `cycle`'s sweep, if it does.
fn standing_stop(standing: Standing, cycle: usize) -> Option<StopReason> {
    match standing {
        Standing::Upright => None,
        Standing::Fell(fall) => Some(StopReason::FellStanding { cycle, fall }),
        Standing::Slid(slip) => Some(StopReason::SlidStanding { cycle, slip }),
    }
}

/// Why the loop stops after a cycle's execution: a fall, a simulation gone unstable, or a
/// cancellation.
fn stop_after(ex: &Execution, cycle: usize, cancel: &Cancel) -> Option<StopReason> {
    if ex.fell {
        Some(StopReason::Fell { cycle })
    } else if let Some(warning) = ex.unstable {
        Some(StopReason::SimulationUnstable { cycle, warning })
    } else if ex.cancelled || cancel.is_cancelled() {
        Some(StopReason::StoppedByUser { cycle })
    } else {
        None
    }
}

/// `planned`, or the refusal [`crate::planning::Plan::held_off_unseen`] makes of it when
/// `refuse` (a plan made from a pass taken moving, which a look taken standing may remake).
fn refusing_held_off_unseen(
    planned: Result<(Plan, Option<Refusal>), Box<Refusal>>,
    ik: &crate::planning::motion::IkParams,
    refuse: bool,
) -> Result<(Plan, Option<Refusal>), Box<Refusal>> {
    planned.and_then(|(plan, closer)| match plan.held_off_unseen(ik) {
        Some(bent) if refuse => Err(Box::new(bent.refusal())),
        _ => Ok((plan, closer)),
    })
}

/// The loop's next plan from configuration `q`: the first `stances` stances of the climb
/// of the step map's `next.ahead`, or, where that is refused for the steps as seen from here
/// ([`RefusalKind::about_the_view`](crate::planning::RefusalKind::about_the_view)), a plan
/// that goes to look again (with the refusal; the steps' upper part is reconstructed from
/// nearer, as in the paper):
/// - a refused step above the next one: the climb of the steps below it, when its first
///   stance is on the flight (a far step seen in part at the edge of the lidar's view is
///   refused as overhung: regression `far-step-in-part-and-an-unloaded-foot`);
/// - else, with the feet on the floor the climb started from (within `floor_band_m` of
///   `start_floor_z_m`), the first stances of the walk on the floor toward them. Never from
///   a step: the walk's "floor" would be the tread under the feet, and its stances within
///   the lidar's blind reach need no returns under them (a walk from the top tread toward
///   a strip seen on a wall went past the tread's back edge: regression
///   `wall-strip-taken-for-a-step`). A missing step is looked at again by this walk only
///   ([`RefusalKind::looked_at_again_from_the_floor`](crate::planning::RefusalKind::looked_at_again_from_the_floor)).
///
/// On that floor, no stance walks toward a first riser out of the lidar's sight
/// ([`riser_in_sight`]: its front not placed on the riser, no floor seen before it): set
/// down within 0.3 m of the first riser, the robot sees step 1 in part from where its sight
/// begins, and a walk nearer puts the feet into the riser (regression
/// `set-down-near-the-first-riser`). Such a robot plans from where it stands (the climb's
/// first stance onto the step), or walks back until the riser is in sight
/// ([`PlanRequest::retreat`]), and looks again. And on that floor, where the lanes the climb
/// keeps are chosen, a sole keeps a margin off a step's side that the flight does not ask
/// ([`PlanRequest::climb_from_the_floor`]).
///
/// The step map's lowest step left for a closer look ([`NextInput::deferred`]):
/// no foot goes on it, but its front bounds the tread below it (left out of the plan, the
/// tread below would be planned as the top, open behind, and the toe strike its riser:
/// regression `step-2-planned-as-the-top`).
///
/// The refusal when neither is possible (nothing left to walk on the floor, a refused next
/// step, feet on a step), or they are refused too.
pub fn plan_next(
    model: &RobotModel,
    q: &[f64],
    next: &NextInput,
    surfaces: Arc<SeenPoints>,
    stances: usize,
    start_floor_z_m: f64,
    p: &PlanParams,
) -> Result<(Plan, Option<Refusal>), Box<Refusal>> {
    let ahead = &next.ahead;
    let steps: Vec<PlaneSegment> = ahead.iter().chain(&next.deferred).cloned().collect();
    let on_start_floor = (feet_height_m(model, q) - start_floor_z_m).abs() <= p.gait.floor_band_m;
    let request = PlanRequest::new(model, q, &steps, p).among(surfaces.clone()).max_stances(Some(stances));
    let climb_from_here = |r: PlanRequest| if on_start_floor { r.climb_from_the_floor() } else { r.climb() };
    let climb = climb_from_here(request.clone().below(ahead.len()));
    let refusal = match climb {
        Ok(plan) => return Ok((plan, None)),
        Err(e) => e.refusal(),
    };
    let again_from_the_floor = on_start_floor && refusal.kind.looked_at_again_from_the_floor();
    if !refusal.kind.about_the_view() && !again_from_the_floor {
        return Err(Box::new(refusal));
    }
    let below = refusal.step.and_then(|s| s.checked_sub(1)).filter(|&b| b > 0);
    if let Some(below) = below.filter(|_| refusal.kind.about_the_view()) {
        if let Ok(plan) = climb_from_here(request.below(below)) {
            if plan.stances.first().is_some_and(|s| s.step.is_some()) {
                return Ok((plan, Some(refusal)));
            }
        }
    }
    if !on_start_floor {
        return Err(Box::new(refusal));
    }
    let in_sight =
        stance_at(model, q).is_ok_and(|s| riser_in_sight(&s, ahead, surfaces.points(), &p.gait).is_ok());
    let walk_request = PlanRequest::new(model, q, ahead, p).among(surfaces).max_stances(Some(stances));
    let walk = if in_sight { walk_request.approach() } else { walk_request.retreat() };
    match walk {
        Ok(Some(walk)) => Ok((walk, Some(refusal))),
        _ => Err(Box::new(refusal)),
    }
}

/// What the planner is given from one view: the step map's next input and the surfaces the
/// body is kept off.
pub struct ViewInput {
    /// The steps ahead (and a partly seen top step left for a closer look).
    pub next: NextInput,
    /// Everything the lidar saw so far, the robot's own body left out, and the edge of the
    /// space near the body it could have seen and did not.
    pub surfaces: Arc<SeenPoints>,
}

/// Takes one view, seen from configuration `q`, into the step map and the surroundings: its
/// `cloud` added to `around` (the body at `q` left out), its steps `seen` merged into `map`.
/// The loop, `replay` and a rehearsal take a view alike.
pub fn take_view(
    map: &mut StepMap,
    around: &mut Surroundings,
    seen: Vec<PlaneSegment>,
    cloud: &crate::cloud::PointCloud,
    model: &RobotModel,
    q: &[f64],
    p: LoopParams<'_>,
) -> ViewInput {
    add_view(around, cloud, model, q, p.surroundings);
    let next = map.next_input(seen, feet_height_m(model, q), p.plan.gait.min_tread_m, p.step_map);
    let surfaces = SeenPoints::with_unseen(around.points(p.surroundings), around.unseen(p.surroundings));
    ViewInput { next, surfaces: Arc::new(surfaces) }
}

/// Adds a sweep's cloud to the surroundings, leaving out the robot's own body at the
/// configuration `q` it was taken from (nothing is left out when `q` is unusable: the
/// planner then keeps the body off its own returns and refuses, rather than ignoring a wall).
pub fn add_view(
    around: &mut Surroundings,
    cloud: &crate::cloud::PointCloud,
    model: &RobotModel,
    q: &[f64],
    p: &SurroundingsParams,
) {
    let mut kin = Kinematics::new(model);
    let body = match kin.update(q) {
        Ok(()) => body_capsules(model, &kin),
        Err(_) => Vec::new(),
    };
    around.add(cloud, &body, p);
}

/// A view moved by a registration's `offset` ([`StepMap::register`]): its rectangles, and its
/// sweep's mount with the cloud assembled anew there (`None` if that fails). The loop and
/// `replay` move a view alike.
pub fn moved_view(
    offset: &nalgebra::Isometry3<f64>,
    seen: Vec<PlaneSegment>,
    sweep: &mut crate::sensor::Sweep,
) -> (Vec<PlaneSegment>, Option<crate::cloud::PointCloud>) {
    sweep.moved(offset);
    let cloud = sweep.assemble(&AssembleParams::default()).ok();
    (seen.into_iter().map(|s| s.transformed(offset)).collect(), cloud)
}

/// The lidar's head frame (the robot model's [`hrp4::LIDAR_MOUNT`]) at configuration `q`
/// (`None` if `q` is unusable).
pub fn head_pose(model: &RobotModel, q: &[f64]) -> Option<nalgebra::Isometry3<f64>> {
    let frame = model.frame_id(hrp4::LIDAR_MOUNT).ok()?;
    let mut kin = Kinematics::new(model);
    kin.update(q).ok()?;
    Some(kin.frame_pose(frame))
}

/// The higher sole's height at configuration `q`, metres (`-inf` if `q` is unusable).
pub fn feet_height_m(model: &RobotModel, q: &[f64]) -> f64 {
    stance_at(model, q).map(|s| s.right.translation.z.max(s.left.translation.z)).unwrap_or(f64::NEG_INFINITY)
}

/// Where soles at height `z` stand in the ground truth: the floor (soles at `floor_z_m`) or
/// the true step (1-based) nearest in height. By height, not by the plan's stance: a walk
/// across a tread too deep for one stride is planned as the floor walk is (no step of its
/// own), yet it stands on a step.
fn footing(scene: &Scene, floor_z_m: f64, z: f64) -> Footing {
    let nearest = scene
        .steps()
        .iter()
        .enumerate()
        .map(|(i, s)| (i + 1, (s.height_m - z).abs()))
        .min_by(|a, b| a.1.total_cmp(&b.1));
    match nearest {
        Some((step, off_m)) if off_m < (z - floor_z_m).abs() => Footing::Step(step),
        _ => Footing::Floor,
    }
}

/// How many steps the robot has climbed: the highest true step both soles stand on.
pub fn climbed(scene: &Scene, model: &RobotModel, q: &[f64]) -> usize {
    let Ok(stance) = stance_at(model, q) else { return 0 };
    let on = |i: usize| {
        let s = &scene.steps()[i];
        [&stance.right, &stance.left].iter().all(|f| {
            let c = nalgebra::Point3::from(f.translation.vector);
            (c.z - s.height_m).abs() < SOLE_ON_TREAD_M && s.contains_xy(&c, 0.0)
        })
    };
    (0..scene.steps().len()).rev().find(|&i| on(i)).map_or(0, |i| i + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stance_stands_where_its_height_is_not_where_the_plan_filed_it() {
        let scene = Scene::from_scenario(&crate::scenario::Scenario::default()).unwrap();
        let floor_z = 0.0;
        let first = scene.steps()[0].height_m;
        assert_eq!(footing(&scene, floor_z, floor_z + 0.002), Footing::Floor);
        // A walk across the first tread (a floor-walk stance there): on step 1.
        assert_eq!(footing(&scene, floor_z, first - 0.001), Footing::Step(1));
        let last = scene.steps().len();
        assert_eq!(footing(&scene, floor_z, scene.steps()[last - 1].height_m), Footing::Step(last));
    }
}
