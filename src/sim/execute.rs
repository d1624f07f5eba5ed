//! Execution of a planned trajectory in MuJoCo: the robot's position servos track q(t) at
//! the physics rate, on MuJoCo's own contacts and friction, and the [`Monitor`] checks every
//! physics step. With the stabilizer on, the servos' set points come from it instead, at its
//! control rate (interpolated in between), from the robot's own sensors. [`SimRobot`] is the
//! simulated HRP-4 as the closed loop's [`Executor`].

use super::checks::{fall_check, slip_check, Ids, Monitor};
use super::head_track::HeadTrack;
use super::params::{ServoParams, SimParams};
use super::sensors::SimSensors;
use super::world::{SimError, World};
use crate::cancel::Cancel;
use crate::climb::{
    Check, ControlCost, Event, Execution, Executor, Observer, RobotState, RunParams, Standing, Watch,
};
use crate::control::attitude::TiltFilter;
use crate::control::Stabilizer;
use crate::estimate::path::Belief;
use crate::estimate::still::BaseSpeed;
use crate::estimate::Odometry;
use crate::planning::gait::Swing;
use crate::planning::{Foot, Plan};
use crate::robot::hrp4;
use crate::robot::model::{base_pose, set_base_pose, RobotModel, Q_JOINTS};
use crate::scene::Scene;
use nalgebra::{Isometry3, Vector3};
use std::cell::{Cell, RefCell};

/// The position servos with the integral term of [`ServoParams`].
struct Servos {
    kp: Vec<f64>,
    kv: Vec<f64>,
    integral: Vec<f64>,
    gain_per_s: f64,
    /// The set points sent last.
    set_points: Vec<f64>,
}

impl Servos {
    /// The servos taking over from the set points they hold in `world` toward a plan that
    /// starts at configuration `q_ref0`: the integral starts where the first set point is the
    /// one held. A plan starts at the measured configuration, which under load sags from the
    /// set points by what the integral had wound up; starting the integral from zero dropped
    /// that at once at each plan's start (x 2 speed, Exp. 1's step 1: the feet's loads went
    /// from 114 / 270 N to 335 / 48 N in 5 ms, and the CoM left the right sole's polygon).
    fn new(world: &World, p: &ServoParams, q_ref0: &[f64]) -> Self {
        let (kp, kv) = world.servo_gains();
        let held = world.set_points();
        let integral = (0..kp.len())
            .map(|a| match p.integral_gain_per_s > 0.0 {
                true => (held[a] - q_ref0[Q_JOINTS + a]) / p.integral_gain_per_s,
                false => 0.0,
            })
            .collect();
        let set_points = held.to_vec();
        Self { kp, kv, integral, gain_per_s: p.integral_gain_per_s, set_points }
    }

    /// Sets the servos' set points toward the joint angles of `q_ref` (a configuration).
    fn command(&mut self, world: &mut World, q_ref: &[f64], dt_s: f64) {
        for (a, i) in self.integral.iter_mut().enumerate() {
            *i += (q_ref[Q_JOINTS + a] - world.joint_q(a)) * dt_s;
        }
        for (a, c) in self.set_points.iter_mut().enumerate() {
            *c = q_ref[Q_JOINTS + a] + self.gain_per_s * self.integral[a];
        }
        world.send_set_points(&self.set_points);
    }

    /// Actuator `a`'s unclamped torque demand, N m (MuJoCo clamps its output at the force
    /// range, so checking the output would prove nothing), on the set point reaching it.
    fn demand_nm(&self, world: &World, a: usize) -> f64 {
        self.kp[a] * (world.data().ctrl()[a] - world.joint_q(a)) - self.kv[a] * world.joint_qd(a)
    }
}

/// Runs `plan` in `world` (whose robot stands where the plan starts) and checks it against
/// `scene` (the true step tops) with the checks of `params`, the polygons by its double
/// description, the servos, sensors and stabilizer of `params` too. `observer` sees the
/// robot's state after every physics step (and each stabilizer tick); a cancelled `cancel`
/// ends the execution at the next step. The violations come back with cycle 0.
pub fn execute(
    world: &mut World,
    model: &RobotModel,
    scene: &Scene,
    plan: &Plan,
    params: &SimParams,
    observer: &mut dyn Observer,
    cancel: &Cancel,
) -> Result<Execution, SimError> {
    execute_from(
        world,
        model,
        scene,
        plan,
        &Isometry3::identity(),
        params,
        None,
        None,
        None,
        observer,
        cancel,
    )
}

/// [`execute`] of a plan made in a frame that lies at `plan_to_world` in the true world (the
/// robot's own estimate when the plan began): the touchdowns are judged against their
/// targets carried into the world ([`Monitor::plan_to_world`]). With `tilt`, the
/// stabilizer's IMU tilt filter carries on from it and is left there for the next plan; with
/// `gyro`, the gyro the robot's estimate reads ([`RobotState::gyro_rad_s`]) draws its noise on
/// from it (a fresh reader repeats the same noise at every plan). With `seen_speed`, the
/// base's speed as the robot's estimate has it after the last physics step
/// ([`crate::estimate::still`]) judges when the body is still at the plan's end; without,
/// the simulator's (a robot that keeps no estimate plans on the truth).
#[allow(clippy::too_many_arguments)]
pub fn execute_from(
    world: &mut World,
    model: &RobotModel,
    scene: &Scene,
    plan: &Plan,
    plan_to_world: &Isometry3<f64>,
    params: &SimParams,
    tilt: Option<&mut TiltFilter>,
    gyro: Option<&mut SimSensors>,
    seen_speed: Option<&dyn Fn() -> f64>,
    observer: &mut dyn Observer,
    cancel: &Cancel,
) -> Result<Execution, SimError> {
    let (servo, p) = (&params.servo, &params.checks);
    let dt = world.model().opt().timestep;
    let t_start = world.data().time();
    let base_z0 = world.data().qpos()[2];
    let traj = &plan.trajectory;
    let mut servos = Servos::new(world, servo, &traj.sample_at(0.0).q);
    // The feet are the bodies carrying the sole frames (the sole plates, on a bushed body).
    let sole_sites = [world.site_id(hrp4::R_SOLE)?, world.site_id(hrp4::L_SOLE)?];
    let ids = Ids {
        feet_bodies: sole_sites.map(|s| world.model().site_bodyid()[s] as usize),
        sole_sites,
        root_body: world.body_id(&model.root().name)?,
    };
    let head_site = world.site_id(crate::scene::mjcf::HEAD_SITE)?;
    let mut mon = Monitor::new(world, ids, scene, hrp4::sole_half_m(model)?, p, &params.plan.step);
    mon.plan_to_world = *plan_to_world;
    let joints = &model.joints()[..servos.kp.len().min(model.joints().len())];
    // Segment end times, for the touchdowns.
    let ends: Vec<f64> = plan
        .segments
        .iter()
        .scan(0.0, |acc, s| {
            *acc += s.duration_s;
            Some(*acc)
        })
        .collect();
    let mut seg = 0usize;
    let mut landed = vec![false; plan.segments.len()];
    // Touchdowns due: the swing, and the plan time by which its foot must be down.
    let mut due: Vec<(&Swing, f64)> = Vec::new();
    let mut q = vec![0.0; model.nq()];
    let mut control = match params.stabilizer.enabled {
        true => Some(Control {
            stabilizer: {
                let s = Stabilizer::new(model, plan, &params.plan, &params.stabilizer)?;
                match tilt.as_deref() {
                    Some(t) => s.with_tilt(t.clone()),
                    None => s,
                }
            },
            sensors: sensors(world, params, STABILIZER_STREAM)?,
            from: plan.trajectory.sample_at(0.0).q.clone(),
            to: plan.trajectory.sample_at(0.0).q.clone(),
            plan_from_s: 0.0,
            plan_to_s: 0.0,
            plan_s: 0.0,
            tick_s: 0.0,
            next_s: 0.0,
            wall_s: 0.0,
            ticks: 0,
        }),
        false => None,
    };
    // Physics steps until the plan's clock reaches its end: with the stabilizer, that clock
    // may wait for a late foot (at most its `max_hold_s`), so the steps are counted on it;
    // then the stabilizer holds the plan's last instant until the body is still (at most
    // its `max_end_hold_s`).
    let steps = (traj.duration_s() / dt).round() as usize;
    let end_s = steps as f64 * dt;
    let stabilized = control.is_some();
    let held_steps =
        if stabilized { params.stabilizer.max_hold_s + params.stabilizer.max_end_hold_s } else { 0.0 };
    let last_step = steps + (held_steps / dt).ceil() as usize + 1;
    let mut end_hold = EndHold::default();
    let seen = |w: &World| seen_speed.map_or_else(|| base_speed_m_s(w), |s| s());
    let mut q_now = Vec::new();
    // The gyro as the robot's estimate reads it at every physics step.
    let mut fresh = None;
    let gyro = match gyro {
        Some(g) => g,
        None => fresh.insert(gyro_reader(world, params)?),
    };
    for k in 1..=last_step {
        // The step from k - 1 to k, and where it ends on the plan's clock.
        let t = match control.as_mut() {
            Some(c) => {
                c.set_point(world, (k - 1) as f64 * dt, dt, &mut q, observer)?;
                c.plan_time_s()
            }
            None => {
                traj.q_at(k as f64 * dt, &mut q);
                k as f64 * dt
            }
        };
        if t > end_s + dt / 2.0
            && (!stabilized || end_hold.done(seen(world), dt, &params.run, params.stabilizer.max_end_hold_s))
        {
            // The bench's measure of the robot's judgement that it was still.
            mon.ex.still_true_speed_m_s = end_hold.still.then(|| base_speed_m_s(world));
            break;
        }
        servos.command(world, &q, dt);
        let physics = std::time::Instant::now();
        world.step();
        mon.ex.physics_wall_s += physics.elapsed().as_secs_f64();
        let now = world.data().time() - t_start;
        if mon.warnings(world, now).is_some() {
            break;
        }
        let soles = mon.ids.sole_sites.map(|s| world.site_pose(s));
        // A swing segment's end: its foot's touchdown is due.
        while t > ends[seg] - dt / 2.0 && !landed[seg] {
            landed[seg] = true;
            if let Some(sw) = &plan.segments[seg].swing {
                let by_s = ends.get(seg + 1).copied().unwrap_or(ends[seg]);
                due.push((sw, by_s));
            }
            if seg + 1 < plan.segments.len() {
                seg += 1;
            }
        }
        let planned = traj.sample_at(t);
        let swing = plan.segments[seg].swing.as_ref().map(|sw| (sw, &planned.feet[sw.foot.index()]));
        let loads = mon.contacts(world, now, swing);
        let down = mon.feet(now, &loads, &soles);
        // Touchdown: measured once the foot is down after its swing's end (the compliant
        // touchdown lowers it slowly the last centimetre, and the servos lag their set points:
        // at the swing's end on the plan's clock it may still be millimetres above), or, if
        // it is not down by the end of the next segment, there, in the air.
        due.retain(|&(sw, by_s)| {
            let now_due = down[sw.foot.index()] || t > by_s - dt / 2.0;
            if now_due {
                mon.touchdown(now, sw, &soles);
            }
            !now_due
        });
        let margin_m = mon.margin(world, now, &loads, down, &soles);
        let max_torque_ratio = mon.joints(joints, |a| servos.demand_nm(world, a), |a| world.joint_qd(a), now);
        world.configuration_into(&mut q_now);
        let gyro_rad_s = gyro.imu(world).gyro_rad_s;
        // The attitude is the stabilizer's filter's (none runs without the stabilizer).
        let up_base = control.as_ref().and_then(|c| c.stabilizer.tilt().up_base());
        let state = RobotState {
            q: &q_now,
            foot_forces_n: loads.force,
            margin_m,
            max_torque_ratio,
            gyro_rad_s,
            up_base,
            head_to_world: Some(world.site_pose(head_site)),
        };
        observer.event(&Event::State { stamp_s: world.data().time(), state: &state });
        // The planned base carried into the world, where the fall is judged.
        let base = mon.plan_to_world * base_pose(&planned.q);
        let mut planned_base = [0.0; Q_JOINTS];
        set_base_pose(&mut planned_base, &base);
        if mon.fell(world, now, planned_base[2].min(base_z0) - p.fall_drop_m, &planned_base) {
            break;
        }
        if cancel.is_cancelled() {
            mon.ex.cancelled = true;
            break;
        }
    }
    // A touchdown still due when the plan ended (or the run stopped): measured as it is.
    let soles = mon.ids.sole_sites.map(|s| world.site_pose(s));
    let now = world.data().time() - t_start;
    for (sw, _) in due {
        mon.touchdown(now, sw, &soles);
    }
    mon.ex.sim_s = now;
    if let Some(c) = control {
        if let Some(t) = tilt {
            *t = c.stabilizer.tilt().clone();
        }
        mon.ex.control = Some(ControlCost { ticks: c.ticks, wall_s: c.wall_s });
    }
    Ok(mon.ex)
}

/// The stabilizer's hold of the plan's last instant, after the plan's clock has ended.
#[derive(Debug, Default)]
struct EndHold {
    /// Seconds held so far.
    held_s: f64,
    /// Of them, the last ones the base was still.
    still_s: f64,
    /// The hold ended on the base still (not on its longest).
    still: bool,
}

impl EndHold {
    /// Whether the hold is over before the next physics step of `dt_s`, the base moving at
    /// `speed_m_s` now: still for `run.still_s` (no faster than `run.still_speed_m_s`), or
    /// `max_s` held.
    fn done(&mut self, speed_m_s: f64, dt_s: f64, run: &RunParams, max_s: f64) -> bool {
        if self.held_s > 0.0 {
            self.still_s = if speed_m_s > run.still_speed_m_s { 0.0 } else { self.still_s + dt_s };
        }
        self.still = self.still_s + dt_s / 2.0 >= run.still_s;
        let done = self.still || self.held_s + dt_s / 2.0 >= max_s;
        self.held_s += dt_s;
        done
    }
}

/// The stabilizer in the physics loop: its ticks at its own rate, the set points
/// interpolated between them.
struct Control<'m> {
    stabilizer: Stabilizer<'m>,
    sensors: SimSensors,
    from: Vec<f64>,
    to: Vec<f64>,
    plan_from_s: f64,
    plan_to_s: f64,
    plan_s: f64,
    tick_s: f64,
    next_s: f64,
    wall_s: f64,
    ticks: usize,
}

impl Control<'_> {
    /// The set points for the physics step from `t_s` (the execution's time) to `t_s + dt_s`,
    /// into `q`; a tick runs first when one is due, on what the sensors read now.
    fn set_point(
        &mut self,
        world: &World,
        t_s: f64,
        dt_s: f64,
        q: &mut [f64],
        observer: &mut dyn Observer,
    ) -> Result<(), SimError> {
        while t_s >= self.next_s - dt_s / 2.0 {
            let m = self.sensors.read(world);
            self.plan_from_s = self.stabilizer.plan_time_s();
            let next = self
                .stabilizer
                .tick(&m)
                .map_err(|error| SimError::Stabilizer { t_s: self.plan_from_s, error })?;
            std::mem::swap(&mut self.from, &mut self.to);
            self.to.copy_from_slice(next);
            self.plan_to_s = self.stabilizer.plan_time_s();
            self.tick_s = self.next_s;
            self.next_s += self.stabilizer.period_s();
            let record = self.stabilizer.record();
            self.wall_s += record.wall_s;
            self.ticks += 1;
            observer.event(&Event::Control { stamp_s: world.data().time(), tick: record });
        }
        let s = ((t_s + dt_s - self.tick_s) / self.stabilizer.period_s()).clamp(0.0, 1.0);
        for (o, (a, b)) in q.iter_mut().zip(self.from.iter().zip(&self.to)) {
            *o = a + (b - a) * s;
        }
        self.plan_s = self.plan_from_s + (self.plan_to_s - self.plan_from_s) * s;
        Ok(())
    }

    /// The plan's clock at the end of the last step set, seconds.
    fn plan_time_s(&self) -> f64 {
        self.plan_s
    }
}

/// Holds the robot at its commanded posture for `seconds`.
pub fn settle(world: &mut World, seconds: f64) {
    settle_watched(world, seconds, &mut |_| {});
}

/// [`settle`], `on_step` called after each physics step.
fn settle_watched(world: &mut World, seconds: f64, on_step: &mut dyn FnMut(&World)) {
    let n = (seconds / world.model().opt().timestep).round() as usize;
    for _ in 0..n {
        world.step();
        on_step(world);
    }
}

/// The speed of the robot's base (its free joint's linear velocity), m/s.
fn base_speed_m_s(world: &World) -> f64 {
    world.data().qvel()[..3].iter().map(|v| v * v).sum::<f64>().sqrt()
}

/// Holds the robot at its commanded posture until its base has moved no faster than
/// `speed_m_s` for `still_s` seconds in a row (a sway's turning point is slow for an
/// instant only), for at most `max_s` seconds; the time it stood, seconds.
pub fn settle_until_still(world: &mut World, speed_m_s: f64, still_s: f64, max_s: f64) -> f64 {
    settle_until_still_watched(world, speed_m_s, still_s, max_s, &base_speed_m_s, &mut |_| {})
}

/// [`settle_until_still`], the base's speed as `seen(world)` has it (m/s), `on_step` called
/// after each physics step.
fn settle_until_still_watched(
    world: &mut World,
    speed_m_s: f64,
    still_s: f64,
    max_s: f64,
    seen: &dyn Fn(&World) -> f64,
    on_step: &mut dyn FnMut(&World),
) -> f64 {
    let dt = world.model().opt().timestep;
    let (mut t_s, mut still_from_s) = (0.0, 0.0);
    while t_s + dt / 2.0 < max_s {
        if seen(world) > speed_m_s {
            still_from_s = t_s + dt;
        } else if t_s - still_from_s + dt / 2.0 >= still_s {
            break;
        }
        world.step();
        on_step(world);
        t_s += dt;
    }
    t_s
}

/// Noise streams of the sensors' seed: the stabilizer's readings, the estimate's gyro during
/// executions, the gyro's start-up calibration (each reader's noise apart from the others').
const STABILIZER_STREAM: u64 = 0;
const GYRO_STREAM: u64 = 1;
const CALIBRATION_STREAM: u64 = 2;

/// A reader of the robot's sensors drawing its noise from `stream` of the sensors' seed.
fn sensors(world: &World, params: &SimParams, stream: u64) -> Result<SimSensors, SimError> {
    Ok(SimSensors::new(world, [hrp4::R_SOLE, hrp4::L_SOLE], &params.sensors)?.with_stream(stream))
}

/// The gyro as the robot's estimate reads it during executions.
fn gyro_reader(world: &World, params: &SimParams) -> Result<SimSensors, SimError> {
    sensors(world, params, GYRO_STREAM)
}

/// The simulated HRP-4 in a MuJoCo world, as the loop's [`Executor`]: it shares the world
/// with the simulated lidar (one borrows it for a sweep, the other for an execution, never
/// both at once).
pub struct SimRobot<'a> {
    world: &'a RefCell<World>,
    model: &'a RobotModel,
    scene: &'a Scene,
    params: SimParams,
    /// The robot's own estimate of its pose, when `params.estimate` enables it.
    odometry: Option<Odometry<'a>>,
    /// The stabilizer's IMU tilt filter, carried from plan to plan and fed while the robot
    /// settles between them (as the real robot's runs all along), by `imu`.
    tilt: TiltFilter,
    imu: SimSensors,
    /// The gyro as the estimate reads it during executions, carried from plan to plan.
    gyro: SimSensors,
    /// Where the lidar head goes as the robot moves and stands, for a lidar that sweeps on
    /// the way ([`SimRobot::with_track`]).
    track: Option<&'a RefCell<HeadTrack>>,
}

impl<'a> SimRobot<'a> {
    /// The robot of `world` (built from `scene`, the ground truth the checks judge against),
    /// its servos, sensors, stabilizer and checks from `params`; with `params.estimate` on,
    /// it knows its pose by odometry from where it stands now.
    pub fn new(
        world: &'a RefCell<World>,
        model: &'a RobotModel,
        scene: &'a Scene,
        params: &SimParams,
    ) -> Result<Self, SimError> {
        let odometry = match params.estimate.enabled {
            true => {
                let w = world.borrow();
                let mut odo = Odometry::new(model, &w.configuration(), &params.estimate)?;
                // The gyro's start-up calibration: the robot standing still, its readings
                // differ only by their noise (drawn at the physics' rate, the physics not
                // stepped), from their own stream. The world is as built, at rest (its sensor
                // data computed at the keyframe, every velocity zero): a world already moving
                // would lend its motion to every reading, as a bias.
                let mut gyro = sensors(&w, params, CALIBRATION_STREAM)?;
                let n = (params.estimate.gyro_calibration_s / w.model().opt().timestep).round() as usize;
                for _ in 0..n {
                    odo.stand(&gyro.imu(&w).gyro_rad_s);
                }
                Some(odo)
            }
            false => None,
        };
        let imu = sensors(&world.borrow(), params, STABILIZER_STREAM)?;
        let tilt =
            TiltFilter::new(params.stabilizer.tilt_filter_time_s, params.stabilizer.tilt_accel_tolerance);
        let gyro = gyro_reader(&world.borrow(), params)?;
        Ok(Self { world, model, scene, params: params.clone(), odometry, tilt, imu, gyro, track: None })
    }

    /// The robot recording into `track`, at the lidar's row period, its head's true pose and
    /// where it believes the head is (its own estimate's configuration through the model's
    /// kinematics), as it executes and as it stands: the path a lidar sweeping on the way
    /// takes ([`super::SimSource::with_track`]).
    pub fn with_track(mut self, track: &'a RefCell<HeadTrack>) -> Self {
        self.track = Some(track);
        self
    }
}

/// Records the head into `track`, when a sample is due at `t_s` (a physics step of `dt_s`
/// ends there): its true pose `truth` gives, and the robot's belief from what `believed`
/// gives (the configuration it believes and where it holds its anchor sole's origin) through
/// `model`'s kinematics.
fn sample_head(
    track: Option<&RefCell<HeadTrack>>,
    model: &RobotModel,
    t_s: f64,
    dt_s: f64,
    truth: impl FnOnce() -> Option<Isometry3<f64>>,
    believed: impl FnOnce() -> Option<(Vec<f64>, nalgebra::Point3<f64>)>,
) {
    let Some(track) = track else { return };
    let mut track = track.borrow_mut();
    if !track.due(t_s, dt_s) {
        return;
    }
    if let Some(truth) = truth() {
        let belief = believed().and_then(|(q, pivot)| {
            let base = base_pose(&q);
            let head = crate::climb::head_pose(model, &q)?;
            Some(Belief { base, head_in_base: base.inverse() * head, pivot, turn: None })
        });
        track.record(t_s, truth, belief);
    }
}

/// The base's turn the gyro reads, `gyro_rad_s` less the bias `odometry` measured standing,
/// over `dt_s`, into `track`.
fn turn_head(track: Option<&RefCell<HeadTrack>>, odometry: &Odometry, gyro_rad_s: &Vector3<f64>, dt_s: f64) {
    if let Some(track) = track {
        track.borrow_mut().turn_by(&(gyro_rad_s - odometry.gyro_bias_rad_s()), dt_s);
    }
}

impl Executor for SimRobot<'_> {
    type Error = SimError;

    fn now_s(&self) -> f64 {
        self.world.borrow().data().time()
    }

    fn configuration(&self) -> Vec<f64> {
        let truth = self.world.borrow().configuration().to_vec();
        match &self.odometry {
            // The encoders read the joints; the base is the odometry's, whose kinematics cannot
            // fail on the joints of the model's own world (never the truth in its place).
            Some(odo) => odo.configuration(&truth[Q_JOINTS..]).expect("the model's own joints"),
            None => truth,
        }
    }

    fn correct(&mut self, offset: &nalgebra::Isometry3<f64>) -> bool {
        match self.odometry.as_mut() {
            Some(odo) => {
                odo.correct(offset);
                if let Some(track) = self.track {
                    track.borrow_mut().correct(offset);
                }
                true
            }
            None => false,
        }
    }

    fn true_configuration(&self) -> Option<Vec<f64>> {
        self.odometry.as_ref().map(|_| self.world.borrow().configuration().to_vec())
    }

    /// At least `seconds`, then on until the base is still ([`RunParams::still_speed_m_s`],
    /// [`RunParams::max_settle_s`]).
    ///
    /// [`RunParams::still_speed_m_s`]: crate::climb::RunParams::still_speed_m_s
    /// [`RunParams::max_settle_s`]: crate::climb::RunParams::max_settle_s
    fn settle(&mut self, seconds: f64) -> Result<Standing, SimError> {
        let world = &mut self.world.borrow_mut();
        let start = world.data().qpos().to_vec();
        // The tilt filter fed at the stabilizer's rate.
        let period_s = 1.0 / self.params.stabilizer.rate_hz;
        let (mut since_s, dt) = (0.0, world.model().opt().timestep);
        let (imu, tilt, gyro, odometry) = (&mut self.imu, &mut self.tilt, &mut self.gyro, &mut self.odometry);
        // The odometry follows the standing robot as it follows an execution: the gyro's turn
        // and the IMU's tilt (the feet stay where they are: no anchor switches).
        let (mut since_gyro_s, mut lost) = (None, None);
        // Each sole's farthest slide from where it stood when the settle began.
        let soles = [world.site_id(hrp4::R_SOLE)?, world.site_id(hrp4::L_SOLE)?];
        let stood = soles.map(|s| world.site_pose(s).translation.vector);
        let mut slid: Option<Check> = None;
        let checks = &self.params.checks;
        let (track, model) = (self.track, self.model);
        let head_site = world.site_id(crate::scene::mjcf::HEAD_SITE)?;
        // The base's speed as the estimate has it, which judges when the robot is still (the
        // simulator's where it keeps none).
        let (estimated, seen, mut speed) = (odometry.is_some(), Cell::new(f64::INFINITY), BaseSpeed::new());
        let mut feed = |w: &World| {
            for (k, foot) in [Foot::Right, Foot::Left].into_iter().enumerate() {
                let at = w.site_pose(soles[k]).translation.vector;
                if let Some(slip @ Check::Slip { slip_m, .. }) = slip_check(foot, &at, &stood[k], checks) {
                    if !matches!(slid, Some(Check::Slip { slip_m: most, .. }) if most >= slip_m) {
                        slid = Some(slip);
                    }
                }
            }
            since_s += dt;
            if since_s >= period_s - dt / 2.0 {
                tilt.update(&imu.read(w).imu, since_s);
                since_s = 0.0;
            }
            if let Some(odo) = odometry.as_mut() {
                let joints = &w.configuration()[Q_JOINTS..];
                let up = tilt.up_base();
                let gyro_rad_s = gyro.imu(w).gyro_rad_s;
                if let Err(error) = odo.follow(joints, up.as_ref(), &gyro_rad_s, since_gyro_s) {
                    lost.get_or_insert(error);
                }
                seen.set(speed.follow_estimate(w.data().time(), odo, joints));
                turn_head(track, odo, &gyro_rad_s, dt);
                since_gyro_s = Some(dt);
            }
            let believed = || match odometry.as_ref() {
                Some(odo) => {
                    let q = odo.configuration(&w.configuration()[Q_JOINTS..]).ok()?;
                    Some((q, odo.anchor().translation.vector.into()))
                }
                None => {
                    let q = w.configuration().to_vec();
                    let pivot = base_pose(&q).translation.vector.into();
                    Some((q, pivot))
                }
            };
            sample_head(track, model, w.data().time(), dt, || Some(w.site_pose(head_site)), believed);
        };
        settle_watched(world, seconds, &mut feed);
        let run = &self.params.run;
        let max_s = (run.max_settle_s - seconds).max(0.0);
        let seen_speed = |w: &World| if estimated { seen.get() } else { base_speed_m_s(w) };
        settle_until_still_watched(world, run.still_speed_m_s, run.still_s, max_s, &seen_speed, &mut feed);
        if let Some(error) = lost {
            return Err(error.into());
        }
        // Judged as an execution's fall against the pose it stood in when the settle began,
        // and against upright (an execution ending part way down, within its plan's limits,
        // leaves a start pose that says nothing).
        let qpos = world.data().qpos();
        let mut upright = start.clone();
        upright[3..7].copy_from_slice(&[1.0, 0.0, 0.0, 0.0]);
        let fall = fall_check(qpos, &start, start[2] - checks.fall_drop_m, checks)
            .or_else(|| fall_check(qpos, &upright, f64::NEG_INFINITY, checks));
        Ok(match (fall, slid) {
            (Some(fall), _) => Standing::Fell(fall),
            (None, Some(slip)) => Standing::Slid(slip),
            (None, None) => Standing::Upright,
        })
    }

    fn execute(
        &mut self,
        plan: &Plan,
        observer: &mut dyn Observer,
        cancel: &Cancel,
    ) -> Result<Execution, SimError> {
        let mut world = self.world.borrow_mut();
        let (tilt, gyro) = (Some(&mut self.tilt), Some(&mut self.gyro));
        let (track, model, dt) = (self.track, self.model, world.model().opt().timestep);
        let Some(odo) = self.odometry.as_mut() else {
            let identity = Isometry3::identity();
            // The head's belief is the true configuration through the model's kinematics.
            let mut head = Watch(|e: &Event| {
                if let Event::State { stamp_s, state } = e {
                    let truth = || state.head_to_world;
                    let believed = || {
                        let q = state.q.to_vec();
                        let pivot = base_pose(&q).translation.vector.into();
                        Some((q, pivot))
                    };
                    sample_head(track, model, *stamp_s, dt, truth, believed);
                }
                observer.event(e);
            });
            return execute_from(
                &mut world,
                self.model,
                self.scene,
                plan,
                &identity,
                &self.params,
                tilt,
                gyro,
                None,
                &mut head,
                cancel,
            );
        };
        // The plan's frame in the world: the true base against the estimated one, now.
        let truth = world.configuration().to_vec();
        let estimate = odo.configuration(&truth[Q_JOINTS..])?;
        let plan_to_world = base_pose(&truth) * base_pose(&estimate).inverse();
        // The odometry follows every physics step: the encoders, the feet's loads, the gyro.
        let mut lost = None;
        let mut last_s = None;
        // The base's speed as the estimate has it, which judges the end of the plan's hold.
        let (seen, mut speed) = (Cell::new(f64::INFINITY), BaseSpeed::new());
        let mut odometry = Watch(|e: &Event| {
            if let Event::State { stamp_s, state } = e {
                let loads = state.foot_forces_n.map(|f| f.z);
                let joints = &state.q[Q_JOINTS..];
                let since_last_s = last_s.map(|t| stamp_s - t);
                last_s = Some(*stamp_s);
                if let Err(error) = odo
                    .follow(joints, state.up_base.as_ref(), &state.gyro_rad_s, since_last_s)
                    .and_then(|()| odo.update(joints, loads))
                {
                    lost.get_or_insert(error);
                }
                seen.set(speed.follow_estimate(*stamp_s, odo, joints));
                turn_head(track, odo, &state.gyro_rad_s, since_last_s.unwrap_or(dt));
                let truth = || state.head_to_world;
                let believed =
                    || Some((odo.configuration(joints).ok()?, odo.anchor().translation.vector.into()));
                sample_head(track, model, *stamp_s, dt, truth, believed);
            }
            observer.event(e);
        });
        let ex = execute_from(
            &mut world,
            self.model,
            self.scene,
            plan,
            &plan_to_world,
            &self.params,
            tilt,
            gyro,
            Some(&|| seen.get()),
            &mut odometry,
            cancel,
        )?;
        match lost {
            Some(error) => Err(error.into()),
            None => Ok(ex),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A plan starts at the measured configuration, sagged under load from the set points
    /// the servos hold: the servos take over with the first set point the one held (before,
    /// the integral started from zero and the sag's compensation dropped at each plan's
    /// start), and then integrate the plan's tracking error as before.
    #[test]
    fn the_servos_take_over_from_the_set_points_they_hold() {
        let scene = Scene::from_scenario(&crate::scenario::Scenario::default()).unwrap();
        let mut world = World::for_scene(&scene).unwrap();
        settle(&mut world, 0.5);
        let held: Vec<f64> = world.data().ctrl().to_vec();
        let q_ref0: Vec<f64> = world.data().qpos().to_vec();
        let sag = (0..held.len()).map(|a| (held[a] - q_ref0[Q_JOINTS + a]).abs()).fold(0.0, f64::max);
        assert!(sag > 1e-4, "the robot sags under its weight from its set points: {sag} rad");
        let p = ServoParams::default();
        let dt = world.model().opt().timestep;
        let mut servos = Servos::new(&world, &p, &q_ref0);
        servos.command(&mut world, &q_ref0, dt);
        let first = world.data().ctrl().to_vec();
        for (a, (c, h)) in first.iter().zip(&held).enumerate() {
            let integrated =
                p.integral_gain_per_s * (q_ref0[Q_JOINTS + a] - world.data().qpos()[Q_JOINTS + a]) * dt;
            assert!((c - h - integrated).abs() < 1e-12, "actuator {a}: {c} after {h}");
        }
    }

    /// On a slippery floor (friction 0.1), a robot that stands still stands upright; one set
    /// moving forward at 0.3 m/s (the whole body, its feet with it) slides about 5 cm before
    /// friction stops it: reported as a sole that slid while it stood, not as standing.
    #[test]
    fn a_sole_sliding_while_the_robot_stands_is_reported() {
        let mut scenario = crate::scenario::Scenario::default();
        scenario.room.floor_friction = 0.1;
        let scene = Scene::from_scenario(&scenario).unwrap();
        let model = hrp4::model().unwrap();
        let world = RefCell::new(World::for_scene(&scene).unwrap());
        let params = SimParams::default();
        let mut robot = SimRobot::new(&world, &model, &scene, &params).unwrap();
        assert_eq!(robot.settle(0.5).unwrap(), Standing::Upright);
        world.borrow_mut().data_mut().qvel_mut()[0] = 0.3;
        match robot.settle(0.5).unwrap() {
            Standing::Slid(Check::Slip { slip_m, limit_m, .. }) => {
                assert!(slip_m > 2.0 * limit_m, "{slip_m}")
            }
            other => panic!("{other:?}"),
        }
    }

    /// The robot judges itself still on its own estimate, as a real one must: set sliding
    /// at 0.3 m/s on a floor of friction 0.05 (its feet sliding with it, a motion its encoders
    /// and the sole its estimate stands on cannot feel), it stops waiting after about half a
    /// second, the body still sliding at several times the limit, and the bench reports the
    /// slide. On the simulator's speed (the estimate off) it waits until the slide is over
    /// (about 1.6 s).
    #[test]
    fn the_robot_judges_itself_still_on_its_own_estimate() {
        let mut scenario = crate::scenario::Scenario::default();
        scenario.room.floor_friction = 0.05;
        let scene = Scene::from_scenario(&scenario).unwrap();
        let model = hrp4::model().unwrap();
        let stand = |estimated: bool| {
            let world = RefCell::new(World::for_scene(&scene).unwrap());
            let mut params = SimParams::default();
            params.estimate.enabled = estimated;
            let mut robot = SimRobot::new(&world, &model, &scene, &params).unwrap();
            assert_eq!(robot.settle(0.5).unwrap(), Standing::Upright);
            world.borrow_mut().data_mut().qvel_mut()[0] = 0.3;
            let t0_s = world.borrow().data().time();
            let standing = robot.settle(0.0).unwrap();
            assert!(matches!(standing, Standing::Slid(_)), "{standing:?}");
            let w = world.borrow();
            (w.data().time() - t0_s, base_speed_m_s(&w))
        };
        let still = RunParams::default().still_speed_m_s;
        let (own_s, own_speed) = stand(true);
        let (truth_s, truth_speed) = stand(false);
        assert!(own_speed > 3.0 * still, "stood {own_s} s, the base at {own_speed} m/s at its end");
        assert!(truth_speed <= still, "stood {truth_s} s, the base at {truth_speed} m/s at its end");
        assert!(truth_s > own_s + 0.5, "{own_s} s on its estimate, {truth_s} s on the truth");
    }

    /// A robot pushed sideways stands until it is still, not until the first instant its
    /// base is slow (a sway's turning point); a still robot stands `still_s` only.
    #[test]
    fn a_swaying_robot_stands_until_it_is_still() {
        let scene = Scene::from_scenario(&crate::scenario::Scenario::default()).unwrap();
        let mut world = World::for_scene(&scene).unwrap();
        settle(&mut world, 0.5);
        let still = settle_until_still(&mut world, 0.01, 0.2, 2.0);
        assert!((still - 0.2).abs() < 0.002, "a still robot stood {still} s");
        world.data_mut().qvel_mut()[1] = 0.15;
        let stood = settle_until_still(&mut world, 0.01, 0.2, 2.0);
        assert!(stood > 0.25 && stood < 2.0, "stood {stood} s");
        for _ in 0..100 {
            world.data_mut().step();
            let v = base_speed_m_s(&world);
            assert!(v <= 0.01, "swaying again at {v} m/s");
        }
    }
}
