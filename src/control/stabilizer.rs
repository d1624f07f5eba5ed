//! The stabilizer's tick: read the sensors, estimate the CoM, distribute the wanted net
//! wrench over the feet the plan has in contact, move each foot's reference by admittance,
//! stop a landing foot where it meets the ground and set it down by its normal force, keep
//! the single support's centre of pressure on the DCM feedback where that is on, tilt
//! the single support's sole with the body's sway where that is on, and solve the QP IK
//! online toward the corrected targets. The joint angles it returns are the
//! servos' set points.

use super::admittance::{self, FootOffset};
use super::attitude::{leaning, PointAcceleration, TiltFilter};
use super::distribution::{DistributionError, Distributor, Support};
use super::measurement::{FootSensor, Measurement, SoleWrench, GRAVITY_M_S2};
use super::params::StabilizerParams;
use crate::planning::contact::Contact;
use crate::planning::gait::Segment;
use crate::planning::ik::IkError;
use crate::planning::motion::{com_target, lifting, swing_target, Targets, Tracker};
use crate::planning::{Foot, Plan, PlanError, PlanParams};
use crate::robot::model::{base_pose, RobotModel, Q_JOINTS};
use crate::robot::{hrp4, Kinematics};
use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3, Vector6};
use std::time::Instant;

/// The least CoM height above the support sole the DCM feedback takes for its pendulum,
/// metres: a guard against a reference at or below the sole (never met by a plan; HRP-4's
/// CoM stands about 0.78 m above its soles).
const MIN_PENDULUM_HEIGHT_M: f64 = 0.3;

/// What one tick wanted and measured, for recording and plots.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize)]
pub struct TickRecord {
    /// Time of the tick from the plan's start, seconds.
    pub t_s: f64,
    /// The distribution's wrench per foot (`None`: not in the plan's contacts).
    pub wanted: [Option<SoleWrench>; 2],
    /// The measured ground wrench per foot.
    pub measured: [SoleWrench; 2],
    /// Each foot's offset after this tick: the admittance's with the sway's tilt
    /// ([`admittance::follow_sway`]), clamped as applied.
    pub offsets: [FootOffset; 2],
    /// Where each foot landed, when the stabilizer holds it there instead of its planned
    /// place (world, metres).
    pub held_m: [Option<Vector3<f64>>; 2],
    /// When the wanted wrench was beyond the feet's cones: how far the closest missed it
    /// (force N, torque N m); the offsets only leaked that tick.
    pub infeasible: Option<[f64; 2]>,
    /// The estimated CoM's error from the plan's, metres.
    pub com_error_m: Vector3<f64>,
    /// The lean the IMU sees beyond what the encoders and the commanded base say: the CoM's
    /// displacement it makes (world), metres.
    pub lean_m: Vector3<f64>,
    /// The base's tilt from upright as the IMU has it, radians.
    pub tilt_rad: f64,
    /// Wall time of the tick, seconds.
    pub wall_s: f64,
}

/// Where the stabilizer puts the CoM at one tick (world, metres).
struct ComEstimate {
    /// On the encoders and the commanded base, moved onto the support sole.
    encoders: Point3<f64>,
    /// The same, leaning as the IMU says the base does: the estimate.
    leaning: Point3<f64>,
    /// The shift to add to any frame of the stabilizer's kinematics to have it in the world.
    shift: Vector3<f64>,
}

/// The stabilizer over one plan.
pub struct Stabilizer<'m> {
    p: StabilizerParams,
    friction: f64,
    sole_half_m: [[f64; 2]; 2],
    tracker: Tracker<'m>,
    estimate: Kinematics<'m>,
    sensors: [FootSensor; 2],
    soles: [usize; 2],
    mass_kg: f64,
    segments: std::sync::Arc<[Segment]>,
    starts_s: Vec<f64>,
    segment: usize,
    offsets: [FootOffset; 2],
    /// Each sole's tilt following the body's sway, `[roll, pitch]`, rad
    /// ([`admittance::follow_sway`]), on top of `offsets`.
    sway_rad: [[f64; 2]; 2],
    /// The support sole and the lean the encoders do not see about it, low-passed, as of the
    /// tick before (a rotation vector, world; [`TiltFilter::unseen_lean`]), for its change.
    unseen_lean_filtered_rad: Option<(usize, Vector3<f64>)>,
    held: [Option<Isometry3<f64>>; 2],
    landing: [bool; 2],
    lifted: [FootOffset; 2],
    /// The swinging foot's commanded sole height at the last tick of its descent, or where
    /// it was held when a touch read in the air is let go, m (`None` before its descent; not
    /// read once it has landed): where the descent's speed cap goes on from.
    approach_z: Option<f64>,
    seeking: [Option<f64>; 2],
    /// Whether each foot has let go a touch read in the air (`touch_lost_after_s`) since it
    /// last lifted off (a support: since the plan began): the ground may be near, and its
    /// descent goes no faster than the approach's entry speed, not braked from the swing's
    /// ([`Stabilizer::descent_speed`]).
    let_go_since_lift: [bool; 2],
    /// How long each foot held where it touched has read no contact since, seconds
    /// (`StabilizerParams::touch_lost_after_s`), until it has carried its contact force
    /// that long.
    touch_lost_s: [f64; 2],
    /// How long each foot has carried `contact_force_n` since it touched, seconds.
    loaded_s: [f64; 2],
    com_prev: Option<Point3<f64>>,
    /// The estimated CoM's velocity over the last tick (world), m/s.
    com_velocity_m_s: Vector3<f64>,
    t_s: f64,
    held_s: f64,
    pressed_ticks: [usize; 2],
    q_est: Vec<f64>,
    tilt: TiltFilter,
    /// The commanded base's acceleration, taken off the IMU's specific force for its tilt.
    base_accel: PointAcceleration,
    /// Each free foot's last commanded sole positions (its swing or its seeking); cleared
    /// while the foot is not free.
    free_foot_path: [PointAcceleration; 2],
    /// The downward part of each free foot's commanded acceleration over the last tick, at
    /// most `GRAVITY_M_S2`, m/s^2, taken for its centre of mass's (the foot's turning
    /// neglected): the servos deliver it over the next tick, when the force sensor would
    /// read it as ground. Zero for a foot that is not free. The upward part is left: the
    /// commanded braking reads as a pull, not a touch, and the servos follow it ticks late
    /// (a speed stepped down within one tick, removed at once, reads as a touch
    /// centimetres above the floor: test `every_touch_the_stabilizer_reads_is_the_grounds`).
    /// The bound keeps a jump of the
    /// target, which no servo follows, from hiding a real touch (a descent's start asks
    /// about as much at x 1.83 the default timing).
    free_foot_accel_m_s2: [Vector3<f64>; 2],
    distributor: Distributor,
    record: TickRecord,
}

impl<'m> Stabilizer<'m> {
    /// A stabilizer for `plan` (whose trajectory starts at the robot's configuration),
    /// keeping the legs off the plan's step solids with the plan's IK parameters.
    pub fn new(
        model: &'m RobotModel,
        plan: &Plan,
        plan_params: &PlanParams,
        p: &StabilizerParams,
    ) -> Result<Self, PlanError> {
        p.validate().map_err(PlanError::Config)?;
        let q0 = plan.trajectory.sample_at(0.0).q.clone();
        let soles = hrp4::sole_frames(model)?;
        let sensors = [FootSensor::of(model, soles[0])?, FootSensor::of(model, soles[1])?];
        let starts_s = plan
            .segments
            .iter()
            .scan(0.0, |t, s| {
                let start = *t;
                *t += s.duration_s;
                Some(start)
            })
            .collect();
        Ok(Self {
            p: p.clone(),
            friction: plan_params.step.friction,
            sole_half_m: hrp4::sole_half_m(model)?,
            tracker: Tracker::new(model, &q0, &plan.blocks, plan.seen.clone(), &plan_params.ik)?,
            estimate: Kinematics::new(model),
            sensors,
            soles,
            mass_kg: model.total_mass_kg(),
            segments: plan.segments.clone().into(),
            starts_s,
            segment: 0,
            offsets: [FootOffset::default(); 2],
            sway_rad: [[0.0; 2]; 2],
            unseen_lean_filtered_rad: None,
            held: [None; 2],
            landing: [false; 2],
            lifted: [FootOffset::default(); 2],
            approach_z: None,
            seeking: [None; 2],
            let_go_since_lift: [false; 2],
            touch_lost_s: [0.0; 2],
            loaded_s: [0.0; 2],
            com_prev: None,
            com_velocity_m_s: Vector3::zeros(),
            t_s: 0.0,
            held_s: 0.0,
            pressed_ticks: [0; 2],
            q_est: q0,
            tilt: TiltFilter::new(p.tilt_filter_time_s, p.tilt_accel_tolerance),
            base_accel: PointAcceleration::default(),
            free_foot_path: Default::default(),
            free_foot_accel_m_s2: [Vector3::zeros(); 2],
            distributor: Distributor::default(),
            record: TickRecord::default(),
        })
    }

    /// The stabilizer with `tilt` as its IMU's tilt filter, carried on from before the plan
    /// (from its first reading, else).
    #[must_use]
    pub fn with_tilt(mut self, tilt: TiltFilter) -> Self {
        self.tilt = tilt;
        self
    }

    /// Its IMU's tilt filter, to carry on into the next plan.
    pub fn tilt(&self) -> &TiltFilter {
        &self.tilt
    }

    /// The control period, seconds.
    pub fn period_s(&self) -> f64 {
        1.0 / self.p.rate_hz
    }

    /// What the last tick wanted and measured.
    pub fn record(&self) -> &TickRecord {
        &self.record
    }

    /// The segment at plan time `t_s` and the fraction of it done.
    fn segment_at(&self, t_s: f64) -> (usize, f64) {
        let i = self.starts_s.partition_point(|&s| s <= t_s).saturating_sub(1);
        let seg = &self.segments[i];
        (i, ((t_s - self.starts_s[i]) / seg.duration_s).clamp(0.0, 1.0))
    }

    /// Handles the passage to segment `next`: a foot whose swing ended short of the ground
    /// goes on seeking it; a foot lifting off takes its difference from the plan into the
    /// swing (it fades out over it).
    fn enter(&mut self, next: usize) {
        while self.segment < next {
            if let Some(sw) = &self.segments[self.segment].swing {
                let k = sw.foot.index();
                if self.held[k].is_none() {
                    let planned = sw.path[sw.path.len() - 1].translation.z;
                    self.seeking[k] = Some(self.approach_z.unwrap_or(planned));
                }
            }
            self.approach_z = None;
            self.segment += 1;
            if let Some(sw) = &self.segments[self.segment].swing {
                let k = sw.foot.index();
                let mut lift = self.offsets[k];
                // The sway's tilt lifts with the foot and fades over its swing as the offsets do.
                let [roll_rad, pitch_rad] = std::mem::take(&mut self.sway_rad[k]);
                lift.roll_rad += roll_rad;
                lift.pitch_rad += pitch_rad;
                if let Some(held) = self.held[k] {
                    lift.translation_m += held.translation.vector - sw.path[0].translation.vector;
                }
                self.lifted[k] = lift;
                self.offsets[k] = FootOffset::default();
                self.held[k] = None;
                self.landing[k] = false;
                self.seeking[k] = None;
                self.let_go_since_lift[k] = false;
            }
        }
    }

    /// A support foot's target: where it landed (or, before it has, its planned pose) with
    /// the admittance's offsets and the sway's tilt.
    fn corrected(&self, foot: Foot, planned: &Isometry3<f64>) -> Isometry3<f64> {
        let k = foot.index();
        self.applied_offset(k).apply(self.held[k].as_ref().unwrap_or(planned))
    }

    /// Foot `k`'s admittance offsets with its sway's tilt, within `cop_max_rad`: what its
    /// target is moved by.
    fn applied_offset(&self, k: usize) -> FootOffset {
        let o = self.offsets[k];
        match self.sway_rad[k] {
            [0.0, 0.0] => o,
            [roll_rad, pitch_rad] => {
                let m = self.p.cop_max_rad;
                let (roll_rad, pitch_rad) =
                    ((o.roll_rad + roll_rad).clamp(-m, m), (o.pitch_rad + pitch_rad).clamp(-m, m));
                FootOffset { roll_rad, pitch_rad, ..o }
            }
        }
    }

    /// The fastest foot `k` may descend at `height_m` above its planned landing, m/s:
    /// [`StabilizerParams::approach_speed_at`], at most the approach's entry speed once the
    /// foot has let go a touch read in the air (`let_go_since_lift`).
    fn descent_speed(&self, k: usize, height_m: f64) -> f64 {
        let height_m =
            if self.let_go_since_lift[k] { height_m.min(self.p.approach_height_m) } else { height_m };
        self.p.approach_speed_at(height_m)
    }

    /// How long each held foot has read no contact (`touching` false) since it touched,
    /// until it has carried its contact force as long as a lost touch takes: a tick's spike
    /// as a swinging sole slows is no load ([`StabilizerParams::touch_lost_after_s`]).
    fn count_lost_touches(&mut self, measured: &[SoleWrench; 2], touching: [bool; 2], dt: f64) {
        for k in 0..2 {
            let held = self.held[k].is_some();
            let loaded = measured[k].force_n.z > self.p.contact_force_n;
            self.loaded_s[k] = match (held, loaded) {
                (true, true) => self.loaded_s[k] + dt,
                (true, false) => self.loaded_s[k],
                (false, _) => 0.0,
            };
            let lost = held && self.loaded_s[k] < self.p.touch_lost_after_s && !touching[k];
            self.touch_lost_s[k] = if lost { self.touch_lost_s[k] + dt } else { 0.0 };
        }
    }

    /// A foot held where it touched that has read no contact for `touch_lost_after_s` has
    /// not met the ground: a support of a double support seeks it from its target's height
    /// (the plan waits for it); the segment's swinging foot goes on down its swing's
    /// approach from there. A single support's foot is kept (it is all the body stands on).
    fn let_lost_touches_go(&mut self) {
        if !self.p.touch_lost_after_s.is_finite() {
            return;
        }
        let segments = std::sync::Arc::clone(&self.segments);
        let seg = &segments[self.segment];
        for k in 0..2 {
            if self.touch_lost_s[k] < self.p.touch_lost_after_s || self.held[k].is_none() {
                continue;
            }
            let swinging = seg.swing.as_ref().is_some_and(|sw| sw.foot.index() == k);
            match seg.support.iter().find(|(f, _)| f.index() == k) {
                Some((f, pose)) if seg.swing.is_none() => {
                    self.seeking[k] = Some(self.corrected(*f, pose).translation.z);
                }
                Some(_) => continue,
                None if swinging => {
                    // The approach goes on from the height the foot was held at, not from
                    // where the swing's path has got to meanwhile.
                    self.approach_z = self.held[k].map(|h| self.applied_offset(k).apply(&h).translation.z);
                }
                None => {}
            }
            self.held[k] = None;
            self.landing[k] = false;
            self.let_go_since_lift[k] = true;
            self.offsets[k] = FootOffset::default();
            self.touch_lost_s[k] = 0.0;
            self.loaded_s[k] = 0.0;
        }
    }

    /// Where foot `k` met the ground: its measured position (`at`, world), its planned
    /// orientation (flat on the tread).
    fn land(&mut self, k: usize, at: Vector3<f64>, planned: &Isometry3<f64>) {
        self.held[k] = Some(Isometry3::from_parts(at.into(), planned.rotation));
        self.landing[k] = true;
        self.seeking[k] = None;
        self.loaded_s[k] = 0.0;
        self.touch_lost_s[k] = 0.0;
    }

    /// The kinematics from the encoders, the commanded base moved so the first planned
    /// support sole is where the stabilizer holds it; then the lean the IMU sees beyond the
    /// commanded base's tilt, taken about that sole: the CoM where the body leans it.
    fn estimate_com(
        &mut self,
        m: &Measurement,
        anchor: Option<(usize, Isometry3<f64>)>,
        dt_s: f64,
    ) -> Result<ComEstimate, IkError> {
        self.q_est[..Q_JOINTS].copy_from_slice(&self.tracker.q()[..Q_JOINTS]);
        self.q_est[Q_JOINTS..].copy_from_slice(&m.joints_rad);
        self.estimate.update(&self.q_est).map_err(|e| IkError::Setup(e.to_string()))?;
        let shift = anchor.map_or(Vector3::zeros(), |(k, held)| {
            held.translation.vector - self.estimate.frame_pose(self.soles[k]).translation.vector
        });
        let encoders = self.estimate.com() + shift;
        let base = base_pose(&self.q_est);
        let accel = self.base_accel.push(&Point3::from(base.translation.vector), dt_s);
        self.tilt.update_moving(&m.imu, &accel, &base.rotation, dt_s);
        // The commanded base's orientation is in the plan's frame and the IMU's up is the
        // world's: with the robot's own estimate on, a tilt between the two frames (none
        // on level ground) would count as lean. Without a support (every foot seeking the
        // ground) there is no pivot and no lean is taken: the estimate jumps when one lands.
        let leaning = match anchor {
            Some((_, held)) => leaning(
                &encoders,
                &Point3::from(held.translation.vector),
                &self.tilt.lean(&base_pose(&self.q_est).rotation),
            ),
            None => encoders,
        };
        Ok(ComEstimate { encoders, leaning, shift })
    }

    /// Where the stabilizer is on the plan's clock, seconds. It runs with the robot's clock
    /// except while a foot that should be down has not met the ground yet: the plan then
    /// waits for it (at most `max_hold_s` over the plan), so the CoM does not move toward
    /// a foot in the air.
    pub fn plan_time_s(&self) -> f64 {
        self.t_s
    }

    /// One tick with measurement `m`: the servos' set points one period later (a
    /// configuration; the joints from `Q_JOINTS`).
    pub fn tick(&mut self, m: &Measurement) -> Result<&[f64], IkError> {
        let started = Instant::now();
        let dt = self.period_s();
        let t_s = self.t_s;
        self.let_lost_touches_go();
        let hold = self.seeking.iter().any(Option::is_some) && self.held_s + dt <= self.p.max_hold_s;
        let step_s = if hold { 0.0 } else { dt };
        self.held_s += dt - step_s;
        let (si, tau) = self.segment_at(t_s + step_s);
        self.enter(si);
        // The segment by a shared handle: the tick changes the stabilizer's state while it
        // reads the segment, and copying the segment (polygon, swing path) every tick is waste.
        let segments = std::sync::Arc::clone(&self.segments);
        let seg = &segments[si];
        let mut supports: Vec<(Foot, Isometry3<f64>)> = seg
            .support
            .iter()
            .filter(|(f, _)| self.seeking[f.index()].is_none())
            .map(|(f, pose)| (*f, self.corrected(*f, pose)))
            .collect();
        // Measured ground wrenches, the feet's orientations from the encoders.
        let anchor = supports.first().map(|(f, pose)| (f.index(), *pose));
        let ComEstimate { encoders: com_encoders, leaning: com, shift } = self.estimate_com(m, anchor, dt)?;
        let measured = self.ground_wrenches(m);
        // The swing: its planned path with the lift-off offsets fading; from the moment it
        // meets the ground in its descent, a contact held where it landed (compliant
        // touchdown: not pushed on to the planned height).
        // A sole meets the ground when its normal force stays above the threshold for
        // `touchdown_ticks` ticks (see the parameter: one by default).
        for (ticks, w) in self.pressed_ticks.iter_mut().zip(&measured) {
            *ticks = if w.force_n.z > self.p.touchdown_force_n { *ticks + 1 } else { 0 };
        }
        let touching = self.pressed_ticks.map(|n| n >= self.p.touchdown_ticks.max(1));
        self.count_lost_touches(&measured, touching, dt);
        let mut swing = None;
        let sole_at: [Vector3<f64>; 2] =
            [0, 1].map(|k| self.estimate.frame_pose(self.soles[k]).translation.vector + shift);
        if let (Some(sw), Some((foot, pose, twist))) = (&seg.swing, swing_target(seg, tau)) {
            let k = foot.index();
            let last = sw.path[sw.path.len() - 1];
            let descent = 1.0 - sw.shares[sw.shares.len() - 1] * (1.0 - self.p.touchdown_window);
            if self.held[k].is_none() && tau >= descent && touching[k] {
                self.land(k, sole_at[k], &last);
            }
            match self.held[k] {
                Some(_) => supports.push((foot, self.corrected(foot, &last))),
                None => {
                    let (mut target, mut twist) = (self.lifted[k].scaled(1.0 - tau).apply(&pose), twist);
                    // The descent: braked to the approach's entry speed by
                    // `approach_height_m` above the planned height, the approach's speed
                    // below that, on below the planned height to meet a lower ground; never
                    // faster than the plan (`approach_z`: the last tick's commanded height).
                    let final_z = last.translation.z;
                    let z = target.translation.z;
                    if tau >= descent {
                        let from = self.approach_z.unwrap_or(z);
                        let speed = self.descent_speed(k, from - final_z);
                        let slowest = from - speed * dt;
                        let lowest = final_z - self.p.max_seek_m;
                        let next = if tau >= 1.0 { slowest.max(lowest) } else { slowest.max(z) };
                        if next > z || tau >= 1.0 {
                            twist[2] = -speed;
                        }
                        target.translation.z = next;
                        self.approach_z = Some(next);
                    }
                    swing = Some((foot, target, twist));
                }
            }
        }
        // A foot whose swing ended before it met the ground: on down its approach (at
        // `approach_speed_m_s` from the planned height on), still free (not pulled to its
        // planned place as a held contact would be).
        for (f, pose) in &seg.support {
            let k = f.index();
            let Some(z) = self.seeking[k] else { continue };
            if touching[k] {
                self.land(k, sole_at[k], pose);
                supports.push((*f, self.corrected(*f, pose)));
            } else if swing.is_none() {
                let speed = self.descent_speed(k, z - pose.translation.z);
                let next = (z - speed * dt).max(pose.translation.z - self.p.max_seek_m);
                self.seeking[k] = Some(next);
                let mut target = *pose;
                target.translation.z = next;
                let descending = if next < z { -speed } else { 0.0 };
                swing = Some((*f, target, Vector6::new(0.0, 0.0, descending, 0.0, 0.0, 0.0)));
            }
        }
        self.follow_free_foot(swing.as_ref().map(|(f, target, _)| (*f, target)), dt);
        // The wanted net wrench: quasi-static, with the CoM feedback.
        let (wanted_net, com_ref) = self.wanted_net(com, seg, tau, t_s, hold, dt);
        let contacts = self.contacts(&supports, &com_ref)?;
        let mut wanted_by_foot = [None; 2];
        let commanded = base_pose(&self.q_est).rotation;
        let lean = self.tilt.lean(&commanded).scaled_axis();
        let mut swaying = None;
        // The point the wanted wrench is taken about: where its zero moment puts the CoP.
        let about = match supports.as_slice() {
            [(_, sole)] if self.p.single_support_dcm_gain_per_s > 0.0 => {
                let v_ref = if hold { Vector3::zeros() } else { com_target(seg, tau).1 };
                self.dcm_feedback_cop(&com, &com_ref, &v_ref, sole.translation.z)
            }
            _ if self.p.wrench_about_estimated_com => com,
            _ => com_ref,
        };
        // No distribution (the CoM outside what the feet down can hold): the offsets only
        // leak back to the plan this tick, and the record says so.
        let infeasible = match self.distributor.distribute(&contacts, &wanted_net, &about, &self.p) {
            Ok(wanted) => {
                for ((f, _), w) in supports.iter().zip(&wanted) {
                    wanted_by_foot[f.index()] = Some(*w);
                }
                self.admit(&supports, &measured, &wanted_by_foot, dt);
                if let [(f, pose)] = supports.as_slice() {
                    let k = f.index();
                    if self.p.lean_follow_rate_per_s != 0.0 {
                        let lean_sole = pose.rotation.inverse() * lean;
                        admittance::follow_lean(&mut self.offsets[k], &lean_sole, &self.p, dt);
                    }
                    if self.p.lean_washout_gain != 0.0 {
                        self.follow_sway(*f, pose, seg, &commanded, dt);
                        swaying = Some(k);
                    }
                }
                None
            }
            Err(DistributionError::Infeasible { force_n, torque_nm }) => {
                for (f, _) in &supports {
                    admittance::leak(&mut self.offsets[f.index()], &self.p, dt);
                }
                Some([force_n, torque_nm])
            }
            Err(DistributionError::Solver(e)) => return Err(e),
        };
        // Out of single support, the unseen lean's change starts again at the next one.
        if swaying.is_none() {
            self.unseen_lean_filtered_rad = None;
        }
        // A sole not in single support this tick (or whose distribution failed): its
        // sway's tilt only washes out.
        for (k, tilt) in self.sway_rad.iter_mut().enumerate() {
            if swaying != Some(k) && *tilt != [0.0; 2] {
                admittance::follow_sway(tilt, &Vector3::zeros(), &self.p, dt);
            }
        }
        let (com_next, com_v_next) = com_target(seg, tau);
        let com_v_next = if hold { Vector3::zeros() } else { com_v_next };
        self.t_s = t_s + step_s;
        let targets = Targets {
            com: com_next,
            com_velocity: com_v_next,
            swing,
            support: &supports,
            lifting: lifting(seg, tau),
        };
        self.tracker.tick(&targets, dt)?;
        self.record = TickRecord {
            t_s,
            wanted: wanted_by_foot,
            measured,
            offsets: [0, 1].map(|k| self.applied_offset(k)),
            held_m: [0, 1].map(|k| self.held[k].map(|h| h.translation.vector)),
            infeasible,
            com_error_m: com - com_ref,
            lean_m: com - com_encoders,
            tilt_rad: self.tilt.tilt_rad().unwrap_or(0.0),
            wall_s: started.elapsed().as_secs_f64(),
        };
        Ok(self.tracker.q())
    }

    /// The ground's wrench on each sole from `m`, the feet's orientations from the
    /// encoders, a free foot's commanded downward inertia taken off (see
    /// `free_foot_accel_m_s2`).
    fn ground_wrenches(&self, m: &Measurement) -> [SoleWrench; 2] {
        [0, 1].map(|k| {
            let rotation = self.estimate.link_pose(self.sensors[k].link).rotation;
            let accel = if self.p.free_foot_inertia_removed {
                self.free_foot_accel_m_s2[k]
            } else {
                Vector3::zeros()
            };
            self.sensors[k].ground_wrench(&m.ft[k], &rotation, &accel)
        })
    }

    /// Keeps the free foot's commanded path (`free`: the foot and its target this tick, if
    /// one is free) and the downward part of its acceleration, for the next tick's reading;
    /// a foot that is not free starts its path again.
    fn follow_free_foot(&mut self, free: Option<(Foot, &Isometry3<f64>)>, dt: f64) {
        for k in 0..2 {
            match free {
                Some((f, target)) if f.index() == k => {
                    let accel = self.free_foot_path[k].push(&target.translation.vector.into(), dt);
                    self.free_foot_accel_m_s2[k] = Vector3::new(0.0, 0.0, accel.z.clamp(-GRAVITY_M_S2, 0.0));
                }
                _ => {
                    self.free_foot_path[k] = PointAcceleration::default();
                    self.free_foot_accel_m_s2[k] = Vector3::zeros();
                }
            }
        }
    }

    /// The sway's washout on `foot`, the single support's sole at `pose` in segment `seg`,
    /// under the commanded base rotation `commanded`: the sole's tilt follows the change of
    /// the lean the encoders do not read (see `TiltFilter::unseen_lean`), the sole lying as
    /// planned (where it landed, else as its segment has it), low-passed from its value as
    /// the single support begins: the change of the sway, not of the contact's give.
    fn follow_sway(
        &mut self,
        foot: Foot,
        pose: &Isometry3<f64>,
        seg: &Segment,
        commanded: &UnitQuaternion<f64>,
        dt: f64,
    ) {
        let k = foot.index();
        let planned = seg.support.iter().find(|(g, _)| *g == foot).map(|s| s.1.rotation);
        let lies = self.held[k].map(|h| h.rotation).or(planned).unwrap_or(pose.rotation);
        let seen = self.estimate.frame_pose(self.soles[k]).rotation;
        let unseen = self.tilt.unseen_lean(commanded, &seen, &lies).scaled_axis();
        let change = match &mut self.unseen_lean_filtered_rad {
            Some((before_k, filtered)) if *before_k == k => {
                admittance::low_passed_change(filtered, &unseen, self.p.lean_washout_filter_s, dt)
            }
            before => {
                *before = Some((k, unseen));
                Vector3::zeros()
            }
        };
        let change_sole = pose.rotation.inverse() * change;
        admittance::follow_sway(&mut self.sway_rad[k], &change_sole, &self.p, dt);
    }

    /// The net wrench the feet should apply now (quasi-static, with the CoM's feedback) for
    /// the CoM measured at `com`, the plan's next instant at `tau` of `seg`; and the CoM's
    /// reference now.
    fn wanted_net(
        &mut self,
        com: Point3<f64>,
        seg: &Segment,
        tau: f64,
        t_s: f64,
        hold: bool,
        dt: f64,
    ) -> (Vector6<f64>, Point3<f64>) {
        let (now, _) = self.segment_at(t_s);
        let tau_now = ((t_s - self.starts_s[now]) / self.segments[now].duration_s).clamp(0.0, 1.0);
        let (com_ref, com_v) = com_target(&self.segments[now], tau_now);
        let com_velocity = self.com_prev.map_or(Vector3::zeros(), |c| (com - c) / dt);
        self.com_prev = Some(com);
        self.com_velocity_m_s = com_velocity;
        let (_, v_next) = com_target(seg, tau);
        let (com_v, v_next) = if hold { (Vector3::zeros(), Vector3::zeros()) } else { (com_v, v_next) };
        let accel = (v_next - com_v) / dt;
        let force = self.mass_kg
            * (Vector3::new(0.0, 0.0, GRAVITY_M_S2)
                + accel
                + self.p.com_stiffness_per_s2 * (com_ref - com)
                + self.p.com_damping_per_s * (com_v - com_velocity));
        (Vector6::new(force.x, force.y, force.z, 0.0, 0.0, 0.0), com_ref)
    }

    /// Where the DCM feedback of single support puts the centre of pressure (horizontally;
    /// `StabilizerParams::single_support_dcm_gain_per_s`): the reference CoM `com_ref` moved
    /// by `1 + k / omega` times the error of the divergent component of motion of the
    /// estimated CoM `com` (its velocity over the last tick) from the reference's (its
    /// velocity `v_ref`), `omega` from the reference's height above the support sole at
    /// `sole_z_m`.
    fn dcm_feedback_cop(
        &self,
        com: &Point3<f64>,
        com_ref: &Point3<f64>,
        v_ref: &Vector3<f64>,
        sole_z_m: f64,
    ) -> Point3<f64> {
        let height_m = (com_ref.z - sole_z_m).max(MIN_PENDULUM_HEIGHT_M);
        let omega = (GRAVITY_M_S2 / height_m).sqrt();
        let dcm_error = (com - com_ref) + (self.com_velocity_m_s - v_ref) / omega;
        let shift = (1.0 + self.p.single_support_dcm_gain_per_s / omega) * dcm_error;
        Point3::new(com_ref.x + shift.x, com_ref.y + shift.y, com_ref.z)
    }

    /// The supports as contacts, each with its share of the normal force from where the CoM's
    /// reference `com_ref` lies between the feet.
    fn contacts(
        &self,
        supports: &[(Foot, Isometry3<f64>)],
        com_ref: &Point3<f64>,
    ) -> Result<Vec<Support>, IkError> {
        let share = |k: usize| -> f64 {
            if supports.len() < 2 {
                return 1.0;
            }
            let (a, b) = (supports[0].1.translation.vector.xy(), supports[1].1.translation.vector.xy());
            let ab = b - a;
            let s = ((com_ref.coords.xy() - a).dot(&ab) / ab.norm_squared().max(1e-9)).clamp(0.0, 1.0);
            if k == 0 {
                1.0 - s
            } else {
                s
            }
        };
        supports
            .iter()
            .enumerate()
            .map(|(i, (f, pose))| {
                let [hx, hy] = self.sole_half_m[f.index()];
                let contact = Contact::new(*pose, hx, hy, self.friction).map_err(IkError::Setup)?;
                Ok(Support { contact, share: share(i) })
            })
            .collect()
    }

    /// The admittance laws over the feet the plan has in contact.
    fn admit(
        &mut self,
        supports: &[(Foot, Isometry3<f64>)],
        measured: &[SoleWrench; 2],
        wanted: &[Option<SoleWrench>; 2],
        dt: f64,
    ) {
        let p = &self.p;
        let loaded = |k: usize| measured[k].force_n.z > p.contact_force_n;
        for k in (0..2).filter(|&k| loaded(k)) {
            self.landing[k] = false;
        }
        if let [(a, pa), (b, pb)] = supports {
            let (i, j) = (a.index(), b.index());
            if let (true, true, Some(wi), Some(wj)) = (loaded(i), loaded(j), wanted[i], wanted[j]) {
                let mut pair = [self.offsets[0], self.offsets[1]];
                let mut fz_w = [0.0; 2];
                fz_w[i] = wi.force_n.z;
                fz_w[j] = wj.force_n.z;
                admittance::force_difference(
                    &mut pair,
                    [measured[0].force_n.z, measured[1].force_n.z],
                    fz_w,
                    p,
                    dt,
                );
                // The ankles' torque errors, less their common part: a common error is the
                // CoM's (only moving the CoM changes it), the rest is how the two soles
                // share the load, which the ankles do change.
                let world = |pose: &Isometry3<f64>, v: &Vector3<f64>| pose.rotation * v;
                let common = (world(pa, &(measured[i].torque_nm - wi.torque_nm))
                    + world(pb, &(measured[j].torque_nm - wj.torque_nm)))
                    / 2.0;
                for (k, pose, w) in [(i, pa, wi), (j, pb, wj)] {
                    admittance::tangential(
                        &mut pair[k],
                        &world(pose, &measured[k].force_n),
                        &world(pose, &w.force_n),
                        p,
                        dt,
                    );
                    let own = SoleWrench {
                        torque_nm: measured[k].torque_nm - pose.rotation.inverse() * common,
                        ..measured[k]
                    };
                    admittance::cop_damping(&mut pair[k], &own, &w, p, dt);
                }
                self.offsets = pair;
                return;
            }
        }
        // One foot down (or none loaded): its CoP is where the CoM puts it; the offsets
        // return to the plan, but for the other foot of a double support: touching the
        // ground lightly, its tangential force still yields; wanted and not touching, it
        // goes down to meet the ground; just landed, its height follows its normal force
        // until it carries the contact force.
        let double = supports.len() == 2;
        for (f, pose) in supports {
            let k = f.index();
            let light = measured[k].force_n.z > p.touchdown_force_n && !loaded(k);
            match wanted[k] {
                Some(w) if double && self.landing[k] => admittance::landing(
                    &mut self.offsets[k],
                    &(pose.rotation * measured[k].force_n),
                    &(pose.rotation * w.force_n),
                    [measured[k].force_n.z, w.force_n.z.max(p.landing_preload_n)],
                    p,
                    dt,
                ),
                Some(w)
                    if double
                        && measured[k].force_n.z <= p.touchdown_force_n
                        && w.force_n.z > p.touchdown_force_n =>
                {
                    admittance::press(&mut self.offsets[k], p, dt)
                }
                Some(w) if double && light => admittance::light_contact(
                    &mut self.offsets[k],
                    &(pose.rotation * measured[k].force_n),
                    &(pose.rotation * w.force_n),
                    p,
                    dt,
                ),
                // Single support with the DCM feedback: the foot's damping puts the CoP
                // where the feedback wants it.
                Some(w) if !double && loaded(k) && p.single_support_dcm_gain_per_s > 0.0 => {
                    admittance::cop_damping(&mut self.offsets[k], &measured[k], &w, p, dt)
                }
                _ => admittance::leak(&mut self.offsets[k], p, dt),
            }
        }
    }
}
