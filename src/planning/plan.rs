//! The planner end to end: step rectangles and the robot's configuration in, footholds, the
//! gait's segments with their polygons and margins, and the joint trajectory out (§6).

use super::clearance::{step_blocks, SeenPoints};
use super::footholds::{approach, footholds_below, retreat, riser_in_sight, GaitParams};
use super::gait::{segments, Body, Legs, Phase, Segment, StepParams};
use super::motion::{track_until, IkParams, JointTrajectory, Sample, Tracking};
use super::stance::Stance;
use super::{reach, PlanError};
use crate::perception::PlaneSegment;
use crate::robot::hrp4;
use crate::robot::model::RobotModel;
use crate::robot::momentum::mean_radius_m;
use crate::robot::Kinematics;
use crate::robot::GRAVITY_M_S2;
use crate::scene::SceneBox;
use nalgebra::Isometry3;
use std::sync::Arc;
use std::time::Instant;

/// How far below the feet the step solids of the clearance check reach, metres (the legs
/// never go below the soles, so any depth that covers the risers will do).
const BLOCK_DEPTH_M: f64 = 0.1;

/// Rounds of tracking at most to bring the leading leg's touchdowns within its reach (see
/// [`reach`]): the third is kept whatever it leaves (the plans of `bench plan` took two:
/// the hip moves by millimetres with the CoM's height). A round that will be tracked again
/// stops at its last touchdown: what follows it is tracked in the next round.
const REACH_ROUNDS: usize = 3;

/// A touchdown's leg beyond its reach by a waypoint lowering of at most this much is within
/// it, metres.
const REACH_TOLERANCE_M: f64 = 1e-3;

/// Rounds of tracking at most, after the first whole one (not stopped at a touchdown beyond
/// reach: its turn is judged on the round tracked again), that slow the segments whose turn about the
/// vertical asks more of the soles' friction than the plan allows
/// ([`IkParams::max_yaw_moment_share`]); a plan whose last round still asks more is
/// refused ([`PlanError::TurnUnheld`]).
const MOMENT_ROUNDS: usize = 2;

/// A segment slowed for its turn is slowed this much more than the moment's fall (see
/// [`turn_slowing`]) asks.
const SLOWING_MARGIN: f64 = 1.1;

/// The power of the slowing by which a turn's moment is taken to fall before a slowing has
/// been measured: the same path in k times the time asks 1 / k^2 the moment. Tracked with
/// its IK's rates as much slower it is the same path, but its moment falls by less
/// (test `a_segment_slowed_for_its_turn_is_the_same_path_asking_a_smaller_moment`).
const ASSUMED_MOMENT_FALL: f64 = 2.0;

/// The least power of the slowing a measured fall of the moment is taken for: a turn
/// whose moment barely fell when slowed is slowed by the square of what it asks over the
/// limit (then refused, when the rounds are spent).
const MIN_MOMENT_FALL: f64 = 0.5;

/// How many times more slowly a segment must run for its turn's moment `moment_nm`, at
/// slowing `slowed`, to fall under `limit_nm` (with [`SLOWING_MARGIN`]): the moment taken to
/// fall as the slowing's power measured between the round before (`before`: its slowing and
/// moment) and this one, within [`MIN_MOMENT_FALL`] and [`ASSUMED_MOMENT_FALL`], or as that
/// assumed power before a slowing has been measured. A turn's moment may fall much less
/// than the square (a power of about 0.7 in regression
/// `walking-chest-ratcheted-along-a-nose`; CHANGELOG, sixty-third session), and slowed by
/// the square root alone its rounds may be spent with it over the limit.
fn turn_slowing(moment_nm: f64, limit_nm: f64, before: Option<(f64, f64)>, slowed: f64) -> f64 {
    let fall = before
        .filter(|&(k0, m0)| slowed > k0 * (1.0 + 1e-9) && m0 > 0.0 && moment_nm > 0.0)
        .map_or(ASSUMED_MOMENT_FALL, |(k0, m0)| {
            ((m0 / moment_nm).ln() / (slowed / k0).ln()).clamp(MIN_MOMENT_FALL, ASSUMED_MOMENT_FALL)
        });
    (moment_nm / limit_nm).powf(1.0 / fall) * SLOWING_MARGIN
}

/// Every parameter of the planner.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PlanParams {
    /// Footholds: what the feet can use.
    pub gait: GaitParams,
    /// Timing, clearances and margins of the segments.
    pub step: StepParams,
    /// The QP IK.
    pub ik: IkParams,
}

impl PlanParams {
    /// The planner with the quasi-static timing ([`StepParams::quasi_static`],
    /// [`IkParams::quasi_static`]); the default is this
    /// [`DEFAULT_SPEEDUP`](super::gait::DEFAULT_SPEEDUP) times faster.
    pub fn quasi_static() -> Self {
        Self { step: StepParams::quasi_static(), ik: IkParams::quasi_static(), gait: GaitParams::default() }
    }

    /// The same plan `factor` times faster: the gait's speeds up and shortest durations
    /// down ([`StepParams::faster`]), and every rate of the IK up with them
    /// ([`IkParams::faster`]: §6.1's qd_max keeps the motion quasi-static, and left alone it
    /// would refuse the faster timing instead of letting the simulation show what it does;
    /// the tasks' gains left alone would trace another path).
    pub fn faster(&self, factor: f64) -> Self {
        let mut p = self.clone();
        p.step = self.step.faster(factor);
        p.ik = self.ik.faster(factor);
        p
    }
}

/// A planned climb.
#[derive(Debug, Clone)]
pub struct Plan {
    /// Where the feet stood at the start.
    pub start: Stance,
    /// The stances, in order.
    pub stances: Vec<Stance>,
    /// Five segments per stance.
    pub segments: Vec<Segment>,
    /// q(t).
    pub trajectory: JointTrajectory,
    /// How closely q(t) follows the gait.
    pub tracking: Tracking,
    /// Wall time of footholds and polygons (seconds).
    pub gait_time_s: f64,
    /// The steps as solids the legs were kept off (an online IK keeps them off the same).
    pub blocks: Vec<SceneBox>,
    /// The surfaces the lidar saw, which the rest of the body was kept off (the same).
    pub seen: Arc<SeenPoints>,
}

impl Plan {
    /// Duration of the motion, seconds.
    pub fn duration_s(&self) -> f64 {
        self.segments.iter().map(|s| s.duration_s).sum()
    }

    /// The smallest CoM margin over all segments, metres.
    pub fn min_margin_m(&self) -> f64 {
        self.segments.iter().map(|s| s.margin_m).fold(f64::INFINITY, f64::min)
    }

    /// [`PlanError::HeldOffUnseen`] where the upper body came nearer the edge of unseen
    /// space than the clearance the IK keeps from it (`p.body_clearance_m`, the IK's `p`)
    /// and [`HELD_M`] (`Tracking::nearest_unseen_surface`): a capsule's clearance row held
    /// it there. Whether that is a refusal is the
    /// caller's: from a pass taken moving it is (the gap is the moving head's, and a
    /// standing look fills it); from one taken standing the gap is a shadow, and the plan
    /// keeps off it as it must.
    pub fn held_off_unseen(&self, p: &IkParams) -> Option<PlanError> {
        let n = self.tracking.nearest_unseen_surface.as_ref()?;
        (n.clearance_m < p.body_clearance_m + HELD_M).then(|| PlanError::HeldOffUnseen {
            segment: n.segment,
            limb: n.limb.clone(),
            point_m: n.point_m,
            clearance_m: n.clearance_m,
            kept_m: p.body_clearance_m,
            t_s: n.t_s,
        })
    }
}

/// A capsule this near the clearance its row keeps was held there by the row, metres: the
/// row's damper lets a capsule near it only ever more slowly, so one that comes within a
/// millimetre had the row bind.
pub const HELD_M: f64 = 1e-3;

/// Where the feet are in the configuration `kin` was last updated with.
pub fn stance_of(kin: &Kinematics, soles: [usize; 2]) -> Stance {
    Stance { right: kin.frame_pose(soles[0]), left: kin.frame_pose(soles[1]), step: None }
}

/// The legs' limits ([`Legs`]) of the body standing at configuration `q`.
pub fn legs_at(model: &RobotModel, q: &[f64], p: &StepParams) -> Result<Legs, PlanError> {
    let mut kin = Kinematics::new(model);
    kin.update(q)?;
    Ok(Legs::of(&Body::measure(&kin, hrp4::sole_frames(model)?)?, p))
}

/// The body's figures in half-sitting, the posture the gait's heights are taken from,
/// whatever the start's: every plan takes the CoM to half-sitting's height above the soles.
/// The closed loop plans from where the last execution left the body; a plan that took its
/// height from its start carried each execution's offset (the stabilizer's compliance, the
/// motion's lag) into the next, and the offset grew plan after plan until a knee came
/// straight (tests/climb.rs `a_flight_climbed_faster_keeps_its_standing_height`).
pub fn standing_body(model: &RobotModel, soles: [usize; 2]) -> Result<Body, PlanError> {
    let mut kin = Kinematics::new(model);
    kin.update(&hrp4::half_sitting_at(model, &Isometry3::identity())?)?;
    Body::measure(&kin, soles)
}

/// Where the feet are at configuration `q`.
pub fn stance_at(model: &RobotModel, q: &[f64]) -> Result<Stance, PlanError> {
    let mut kin = Kinematics::new(model);
    kin.update(q)?;
    Ok(stance_of(&kin, hrp4::sole_frames(model)?))
}

/// What to plan: from configuration `q0` (standing, both feet down) over the perceived steps
/// `rects`, with `params`. By default the feet may go on every rectangle, nothing is known
/// around the steps and the plan goes to the top; [`PlanRequest::among`],
/// [`PlanRequest::below`] and [`PlanRequest::max_stances`] change that. Then one of
/// [`PlanRequest::climb`], [`PlanRequest::climb_from_the_floor`], [`PlanRequest::approach`] or
/// [`PlanRequest::retreat`] plans it.
#[derive(Clone)]
pub struct PlanRequest<'a> {
    model: &'a RobotModel,
    q0: &'a [f64],
    rects: &'a [PlaneSegment],
    below: usize,
    seen: Arc<SeenPoints>,
    max_stances: Option<usize>,
    params: &'a PlanParams,
}

impl<'a> PlanRequest<'a> {
    /// The climb of all of `rects` from `q0`, to the top, nothing known around the steps.
    pub fn new(
        model: &'a RobotModel,
        q0: &'a [f64],
        rects: &'a [PlaneSegment],
        params: &'a PlanParams,
    ) -> Self {
        Self { model, q0, rects, below: rects.len(), seen: Arc::default(), max_stances: None, params }
    }

    /// The body kept off the surfaces the lidar saw (`seen`, the surroundings) as well as the
    /// legs off the steps.
    #[must_use]
    pub fn among(self, seen: Arc<SeenPoints>) -> Self {
        Self { seen, ..self }
    }

    /// The feet on the `below` lowest rectangles only (a higher one left to be judged from
    /// nearer); the legs still keep off all of them.
    #[must_use]
    pub fn below(self, below: usize) -> Self {
        Self { below, ..self }
    }

    /// The plan limited to its first `max_stances` stances (the closed loop plans a few,
    /// moves, and scans again); `None` plans to the top.
    #[must_use]
    pub fn max_stances(self, max_stances: Option<usize>) -> Self {
        Self { max_stances, ..self }
    }

    /// The climb.
    pub fn climb(&self) -> Result<Plan, PlanError> {
        self.plan_climb(false)
    }

    /// The climb from the floor it starts on (the closed loop; `seen` is everything the lidar
    /// saw), which commits the robot to the flight:
    /// - the first riser may be out of the lidar's sight: a climb that would first walk the
    ///   floor toward the lowest step is refused as [`riser_in_sight`] refuses it, unless that
    ///   riser is in sight. A robot set down near the first riser plans from where it stands
    ///   (its first stance onto the step) or not at all, and never walks a foot into a riser
    ///   it did not see;
    /// - the lanes it chooses are kept up the flight, so a sole may overhang a step's side
    ///   by [`GaitParams::side_commit_margin_m`] less than on the flight
    ///   ([`GaitParams::committing`]).
    pub fn climb_from_the_floor(&self) -> Result<Plan, PlanError> {
        self.plan_climb(true)
    }

    /// The walk on the floor toward the flight ([`footholds::approach`](approach)), planned as a climb is but with
    /// the steps left unjudged: the closed loop walks it to look again at a flight it refused
    /// from afar. `Ok(None)` when there is nothing left to walk (the first step is within a
    /// stride).
    pub fn approach(&self) -> Result<Option<Plan>, PlanError> {
        self.plan_stances(|start, pts, _| Ok(approach(start, self.rects, pts, &self.params.gait)))
    }

    /// The walk on the floor back from the flight ([`footholds::retreat`](retreat)), planned as
    /// [`PlanRequest::approach`] plans its walk: the closed loop walks it to see a first
    /// riser that was out of the lidar's sight ([`riser_in_sight`]). `Ok(None)` when there is
    /// nothing left to walk.
    pub fn retreat(&self) -> Result<Option<Plan>, PlanError> {
        self.plan_stances(|start, pts, _| Ok(retreat(start, self.rects, pts, &self.params.gait)))
    }

    /// The climb of the `below` lowest rectangles; `from_the_floor` as
    /// [`PlanRequest::climb_from_the_floor`] plans it.
    fn plan_climb(&self, from_the_floor: bool) -> Result<Plan, PlanError> {
        let rects = self.rects;
        let gait = &if from_the_floor { self.params.gait.committing() } else { self.params.gait.clone() };
        self.plan_stances(|start, pts, legs| {
            let stances = footholds_below(start, rects, self.below, pts, legs, gait)?;
            if from_the_floor && stances.first().is_some_and(|s| s.step.is_none()) {
                riser_in_sight(start, rects, pts, gait)?;
            }
            Ok(stances)
        })?
        .ok_or(PlanError::NoSteps)
    }

    /// A plan through the stances `stances_from` gives from the start stance, the seen
    /// surfaces and the legs' limits, the first `max_stances` of them: the gait's segments
    /// and the joint trajectory, the legs kept off `rects` and the body off `seen`; `None`
    /// for no stances.
    fn plan_stances(
        &self,
        stances_from: impl FnOnce(&Stance, &[nalgebra::Point3<f64>], &Legs) -> Result<Vec<Stance>, PlanError>,
    ) -> Result<Option<Plan>, PlanError> {
        let Self { model, q0, rects, seen, max_stances, params: p, .. } = self;
        let (model, q0, rects, max_stances) = (*model, *q0, *rects, *max_stances);
        let started = Instant::now();
        let soles = hrp4::sole_frames(model)?;
        let mut kin = Kinematics::new(model);
        kin.update(q0)?;
        let start = stance_of(&kin, soles);
        let body = standing_body(model, soles)?;
        let mut stances = stances_from(&start, seen.points(), &Legs::of(&body, &p.step))?;
        if let Some(n) = max_stances {
            stances.truncate(n);
        }
        if stances.is_empty() {
            return Ok(None);
        }
        // The steps as solids down to below the feet: what the legs must keep clear of.
        let feet_z = start.right.translation.z.min(start.left.translation.z);
        let blocks = step_blocks(rects, feet_z - BLOCK_DEPTH_M);
        // The gait from the legs' model, tracked; where the tracked leading leg lands farther
        // from its hip than it reaches, its touchdown waypoint comes down by as much and the
        // gait is tracked again (the hip's place moves a little with the CoM's height, hence
        // more than one round).
        let reach_m = Legs::of(&body, &p.step).reach_m;
        let yaw_limit_nm = yaw_moment_limit_nm(model, &body, p)?;
        let mut drops_m = vec![0.0; stances.len()];
        // Each segment's time, as many times the gait's as its turn about the vertical asked
        // it to be slowed ([`IkParams::max_yaw_moment_share`]); its IK's rates as many times
        // slower ([`track_until`]).
        let mut slowed: Vec<f64> = Vec::new();
        // Each segment's slowing and moment about the vertical at the last whole round (none
        // after a round that moved the touchdowns).
        let mut judged: Vec<(f64, f64)> = Vec::new();
        let (mut gait_started, mut gait_time_s, mut round, mut moment_round) = (started, 0.0, 1, 0);
        let mut ik_spent = Tracking::default();
        loop {
            let mut segs = segments(kin.com(), &start, &stances, &drops_m, &body, &p.step)?;
            slowed.resize(segs.len(), 1.0);
            for (seg, k) in segs.iter_mut().zip(&slowed) {
                seg.duration_s *= k;
            }
            gait_time_s += gait_started.elapsed().as_secs_f64();
            // A round that will be tracked again (a touchdown beyond the leg's reach, and
            // rounds left) stops once every touchdown is measured: the rest of it is tracked
            // in the next round, where its turn about the vertical is judged.
            let last_touchdown = segs.iter().rposition(|s| s.phase == Phase::SwingRight);
            let (mut landed_kin, mut beyond) = (Kinematics::new(model), false);
            let mut measured = |si: usize, samples: &[Sample]| {
                let seg = &segs[si];
                if let Some(landed) =
                    samples.last().filter(|l| l.segment == si && seg.phase == Phase::SwingRight)
                {
                    let drop_m = reach::touchdown_drop_m(model, &mut landed_kin, seg, &landed.q, reach_m)?;
                    beyond |= drop_m > REACH_TOLERANCE_M;
                }
                Ok(beyond && round < REACH_ROUNDS && Some(si) >= last_touchdown)
            };
            let (trajectory, mut tracking, stopped) =
                track_until(model, q0, &segs, &blocks, seen.clone(), &p.ik, &slowed, &mut measured)?;
            let more_m = reach::touchdown_drops_m(model, &segs, &trajectory, reach_m)?;
            tracking.ik_ticks += ik_spent.ik_ticks;
            tracking.ik_interior_point_qps += ik_spent.ik_interior_point_qps;
            tracking.ik_time_s += ik_spent.ik_time_s;
            let reached = round >= REACH_ROUNDS || more_m.iter().all(|&d| d <= REACH_TOLERANCE_M);
            // A turn the moment takes time for ([`turn_slowing`]). (Judged on a whole round
            // only: a stopped one is tracked again.)
            let over: Vec<(usize, f64)> = (tracking.segment_yaw_moments_nm.iter().enumerate())
                .filter(|&(_, &m)| m > yaw_limit_nm && stopped.is_none())
                .map(|(i, &m)| (i, turn_slowing(m, yaw_limit_nm, judged.get(i).copied(), slowed[i])))
                .collect();
            if stopped.is_none() {
                judged =
                    slowed.iter().copied().zip(tracking.segment_yaw_moments_nm.iter().copied()).collect();
            }
            let slowings_spent = moment_round == MOMENT_ROUNDS;
            if reached && slowings_spent && !over.is_empty() {
                let (segment, moment_nm) = (tracking.segment_yaw_moments_nm.iter().copied().enumerate())
                    .max_by(|a, b| a.1.total_cmp(&b.1))
                    .unwrap_or((0, f64::NAN));
                return Err(PlanError::TurnUnheld { segment, moment_nm, limit_nm: yaw_limit_nm });
            }
            let held = over.is_empty() || slowings_spent;
            if reached && held {
                return Ok(Some(Plan {
                    start,
                    stances,
                    segments: segs,
                    trajectory,
                    tracking,
                    gait_time_s,
                    blocks,
                    seen: Arc::clone(seen),
                }));
            }
            ik_spent = tracking;
            if !reached {
                for (d, more) in drops_m.iter_mut().zip(more_m) {
                    *d += more;
                }
                round += 1;
                // Touchdowns moved: the next round's moments are not this slowing's alone.
                judged.clear();
            }
            if !held {
                for (i, k) in over {
                    slowed[i] *= k;
                }
                moment_round += 1;
            }
            gait_started = Instant::now();
        }
    }
}

/// The largest moment about the vertical a plan may ask of the contacts, N m: the share
/// [`IkParams::max_yaw_moment_share`] of what friction holds under the smaller sole at
/// uniform pressure with the whole weight on it.
fn yaw_moment_limit_nm(model: &RobotModel, body: &Body, p: &PlanParams) -> Result<f64, PlanError> {
    let share = p.ik.max_yaw_moment_share;
    if !(share.is_finite() && share > 0.0) {
        return Err(PlanError::Config(format!("max_yaw_moment_share must be positive, got {share}")));
    }
    let lever_m = body.sole_half_m.iter().map(|[a, b]| mean_radius_m(*a, *b)).fold(f64::INFINITY, f64::min);
    Ok(share * p.step.friction * model.total_mass_kg() * GRAVITY_M_S2 * lever_m)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Before a slowing is measured, the moment is taken to fall as the square; once two
    /// whole rounds have measured it, as the power they show: the segment that fell from
    /// 13.3 to 11.3 N m slowed by 1.287 (a power of 0.66) is slowed enough for that fall to
    /// take it under the limit, where the square root would leave it over.
    #[test]
    fn a_turn_is_slowed_by_the_fall_of_its_moment_as_measured() {
        let limit_nm = 9.73;
        let first = turn_slowing(13.32, limit_nm, None, 1.0);
        assert!((first - (13.32 / limit_nm).sqrt() * SLOWING_MARGIN).abs() < 1e-12);
        let (k1, m1): (f64, f64) = (1.287, 11.29);
        let fall = (13.32f64 / m1).ln() / k1.ln();
        let more = turn_slowing(m1, limit_nm, Some((1.0, 13.32)), k1);
        let predicted_nm = m1 / more.powf(fall);
        assert!(predicted_nm < limit_nm, "{predicted_nm}");
        let square_root = (m1 / limit_nm).sqrt() * SLOWING_MARGIN;
        assert!(m1 / square_root.powf(fall) > limit_nm, "the square root would not have done");
        // A moment that did not fall is slowed by the square of what it asks over the limit;
        // one not slowed since (another segment was) by the assumed square.
        let flat = turn_slowing(m1, limit_nm, Some((1.0, m1)), k1);
        assert!((flat - (m1 / limit_nm).powi(2) * SLOWING_MARGIN).abs() < 1e-12);
        let unslowed = turn_slowing(m1, limit_nm, Some((k1, 12.0)), k1);
        assert!((unslowed - square_root).abs() < 1e-12);
    }
}
