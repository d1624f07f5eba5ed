//! Execution of a planned trajectory in MuJoCo with every check at every physics step: the
//! robot's position servos track q(t) at the physics rate, on MuJoCo's own contacts and
//! friction, and a `Monitor` checks, from what the simulator actually has, the CoM inside
//! the static-stability polygon of the feet really in contact, each contact force inside the
//! friction pyramid the plan assumed, each sole's centre of pressure inside the sole, joint
//! torques (the servos' unclamped demand) and speeds within the model's limits, the feet at
//! their targets at touchdown and on their step, no foot strike during a swing, no part other
//! than the soles touching the world, and no fall.

use super::observe::{Observer, RobotState};
use super::world::{SimError, World};
use crate::geom2d::P2;
use crate::planning::contact::Contact;
use crate::planning::dd::DdParams;
use crate::planning::footholds::Foot;
use crate::planning::gait::Swing;
use crate::planning::polygon::{by_double_description, margin};
use crate::planning::Plan;
use crate::robot::hrp4;
use crate::robot::model::{RobotModel, Q_JOINTS, V_JOINTS};
use crate::scene::mjcf::ROBOT_GEOM_GROUP;
use crate::scene::Scene;
use nalgebra::{Isometry3, Point3, Quaternion, UnitQuaternion, Vector3};

/// Limits of the checks.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CheckParams {
    /// Least CoM margin inside the stability polygon, metres (0: inside is enough).
    pub min_margin_m: f64,
    /// Friction coefficient the contact forces must respect (the plan's pyramid, §6.2).
    pub friction: f64,
    /// Largest torque demand as a fraction of the joint's torque limit.
    pub max_torque_ratio: f64,
    /// Largest joint speed as a fraction of the joint's speed limit.
    pub max_speed_ratio: f64,
    /// Largest sole position error at touchdown, metres.
    pub touchdown_tolerance_m: f64,
    /// Largest sole yaw error at touchdown, radians.
    pub touchdown_yaw_tolerance_rad: f64,
    /// How far a landed sole may overhang its step's tread, metres.
    pub overhang_tolerance_m: f64,
    /// A swinging foot touching the world while its planned sole is higher than this above
    /// its target is a strike, metres.
    pub strike_height_m: f64,
    /// Normal force above which a foot counts as in contact, newtons.
    pub contact_force_n: f64,
    /// Normal force from which a foot's resultant must lie in the friction pyramid, newtons.
    /// A foot carrying less is being set down or lifted by position servos: its tangential
    /// force is the closed chain's internal force, not the plan's, and what that does (the
    /// sole sliding) is checked by `slip_tolerance_m` instead.
    pub friction_load_n: f64,
    /// How far a sole in contact may slide from where it came down, metres.
    pub slip_tolerance_m: f64,
    /// A fall: the base this far below its start height, metres.
    pub fall_drop_m: f64,
    /// A fall: the base tilted more than this, radians.
    pub fall_tilt_rad: f64,
}

impl Default for CheckParams {
    fn default() -> Self {
        Self {
            min_margin_m: 0.0,
            friction: crate::planning::contact::DEFAULT_FRICTION,
            max_torque_ratio: 1.0,
            max_speed_ratio: 1.0,
            touchdown_tolerance_m: 0.02,
            touchdown_yaw_tolerance_rad: 3f64.to_radians(),
            overhang_tolerance_m: 0.02,
            strike_height_m: 0.01,
            contact_force_n: 5.0,
            friction_load_n: 40.0,
            slip_tolerance_m: 0.005,
            fall_drop_m: 0.25,
            fall_tilt_rad: 30f64.to_radians(),
        }
    }
}

/// How the servos track q(t).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ServoParams {
    /// Integral gain on each joint's tracking error, 1/s: the set point sent to the position
    /// servo is q_ref + K_i * integral(q_ref - q) dt, as a servo drive's integral term
    /// removes the sag a pure PD servo keeps under load (0 = pure PD).
    pub integral_gain_per_s: f64,
}

impl Default for ServoParams {
    fn default() -> Self {
        Self { integral_gain_per_s: 1.0 }
    }
}

/// One violated check, with the instant.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Violation {
    /// Time from the start of the execution (the plan's clock), seconds.
    pub t_s: f64,
    /// Which check (`margin`, `friction`, `cop`, `torque`, `speed`, `touchdown`,
    /// `slip`, `off_step`, `strike`, `collision`, `fall`).
    pub check: &'static str,
    /// What exactly.
    pub detail: String,
}

/// A touchdown: where a foot landed against its target.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Touchdown {
    /// Which foot.
    pub foot: Foot,
    /// Position error, metres.
    pub error_m: f64,
    /// Yaw error, radians.
    pub yaw_error_rad: f64,
}

/// What one execution found.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Execution {
    /// Simulated time, seconds.
    pub sim_s: f64,
    /// Smallest CoM margin in the polygon of the real contacts, metres.
    pub min_margin_m: f64,
    /// Largest torque demand over limit, and its joint.
    pub max_torque_ratio: f64,
    /// The joint of `max_torque_ratio`.
    pub torque_joint: String,
    /// Largest speed over limit, and its joint.
    pub max_speed_ratio: f64,
    /// The joint of `max_speed_ratio`.
    pub speed_joint: String,
    /// Every touchdown.
    pub touchdowns: Vec<Touchdown>,
    /// Largest horizontal slide of a sole in contact from where it came down, metres.
    pub max_slip_m: f64,
    /// Largest friction a loaded foot used: tangential over normal force, per sole axis
    /// (the pyramid's measure; the check's limit is `CheckParams::friction`).
    pub max_friction_ratio: f64,
    /// Violations (the first of each kind per second of simulation, to keep reports short).
    pub violations: Vec<Violation>,
    /// The robot fell (the execution stopped).
    pub fell: bool,
}

impl Execution {
    /// No check violated.
    pub fn pass(&self) -> bool {
        self.violations.is_empty() && !self.fell
    }

    /// The largest touchdown position error, metres (0 without touchdowns).
    pub fn max_touchdown_error_m(&self) -> f64 {
        self.touchdowns.iter().map(|t| t.error_m).fold(0.0, f64::max)
    }
}

/// The robot's identifiers in the world.
struct Ids {
    feet_bodies: [usize; 2],
    sole_sites: [usize; 2],
    root_body: usize,
}

impl Ids {
    fn of(world: &World, model: &RobotModel) -> Result<Self, SimError> {
        let soles = hrp4::sole_frames(model)?;
        let body_of = |frame: usize| world.body_id(&model.links()[model.frames()[frame].link].name);
        Ok(Self {
            feet_bodies: [body_of(soles[0])?, body_of(soles[1])?],
            sole_sites: [world.site_id(hrp4::R_SOLE)?, world.site_id(hrp4::L_SOLE)?],
            root_body: world.body_id(&model.root().name)?,
        })
    }
}

/// The polygon of the feet in contact, recomputed only when they change.
#[derive(Default)]
struct PolygonCache {
    key: Option<([bool; 2], [Isometry3<f64>; 2])>,
    polygon: Vec<P2>,
}

impl PolygonCache {
    fn polygon(&mut self, down: [bool; 2], soles: &[Isometry3<f64>; 2], friction: f64) -> &[P2] {
        let moved = |a: &Isometry3<f64>, b: &Isometry3<f64>| {
            (a.translation.vector - b.translation.vector).norm() > 1e-3
                || a.rotation.angle_to(&b.rotation) > 5e-3
        };
        let stale = match &self.key {
            Some((d, s)) => *d != down || (0..2).any(|k| down[k] && moved(&s[k], &soles[k])),
            None => true,
        };
        if stale {
            let [hx, hy] = hrp4::SOLE_HALF_M;
            let contacts: Vec<Contact> = (0..2)
                .filter(|&k| down[k])
                .filter_map(|k| Contact::new(soles[k], hx, hy, friction).ok())
                .collect();
            self.polygon = by_double_description(&contacts, &DdParams::default()).unwrap_or_default();
            self.key = Some((down, *soles));
        }
        &self.polygon
    }
}

/// The position servos with the integral term of [`ServoParams`].
struct Servos {
    kp: Vec<f64>,
    kv: Vec<f64>,
    integral: Vec<f64>,
    gain_per_s: f64,
}

impl Servos {
    fn new(world: &World, p: &ServoParams) -> Self {
        let (kp, kv) = world.servo_gains();
        let integral = vec![0.0; kp.len()];
        Self { kp, kv, integral, gain_per_s: p.integral_gain_per_s }
    }

    /// Sets the servos' set points toward the joint angles of `q_ref` (a configuration).
    fn command(&mut self, world: &mut World, q_ref: &[f64], dt_s: f64) {
        let d = world.data_mut();
        for (a, i) in self.integral.iter_mut().enumerate() {
            *i += (q_ref[Q_JOINTS + a] - d.qpos()[Q_JOINTS + a]) * dt_s;
        }
        for (a, c) in d.ctrl_mut().iter_mut().enumerate().take(self.integral.len()) {
            *c = q_ref[Q_JOINTS + a] + self.gain_per_s * self.integral[a];
        }
    }

    /// Actuator `a`'s unclamped torque demand, N m (MuJoCo clamps its output at the force
    /// range, so checking the output would prove nothing).
    fn demand_nm(&self, world: &World, a: usize) -> f64 {
        let d = world.data();
        self.kp[a] * (d.ctrl()[a] - d.qpos()[Q_JOINTS + a]) - self.kv[a] * d.qvel()[V_JOINTS + a]
    }
}

/// What the feet's contacts carry at one instant.
#[derive(Default)]
struct FootLoads {
    /// Sum of normal forces, newtons.
    normal_n: [f64; 2],
    /// Sum of contact points weighted by their normal force.
    moment: [Vector3<f64>; 2],
    /// Resultant force, world frame.
    force: [Vector3<f64>; 2],
}

/// The checks, with what they found so far.
struct Monitor<'a> {
    ids: Ids,
    p: &'a CheckParams,
    scene: &'a Scene,
    cache: PolygonCache,
    last_report: Vec<(&'static str, f64)>,
    /// Where each sole in contact came down (world), `None` while it is in the air.
    landed: [Option<Vector3<f64>>; 2],
    ex: Execution,
}

impl Monitor<'_> {
    /// Records a violation, the first of its kind per simulated second.
    fn report(&mut self, t_s: f64, check: &'static str, detail: String) {
        if let Some(e) = self.last_report.iter_mut().find(|(c, _)| *c == check) {
            if t_s - e.1 < 1.0 {
                return;
            }
            e.1 = t_s;
        } else {
            self.last_report.push((check, t_s));
        }
        self.ex.violations.push(Violation { t_s, check, detail });
    }

    /// Sums the feet's contact forces; reports other parts touching the world, robot parts
    /// touching each other, and a swinging foot that strikes (`swing` with its planned sole).
    fn contacts(&mut self, world: &World, now: f64, swing: Option<(&Swing, &Isometry3<f64>)>) -> FootLoads {
        let mut loads = FootLoads::default();
        let d = world.data();
        let geom_body = world.model().geom_bodyid();
        for (ci, c) in d.contact().iter().enumerate() {
            let (g1, g2) = (c.geom1 as usize, c.geom2 as usize);
            let (robot, other) =
                match (world.geom_group(g1) == ROBOT_GEOM_GROUP, world.geom_group(g2) == ROBOT_GEOM_GROUP) {
                    (true, false) => (g1, g2),
                    (false, true) => (g2, g1),
                    (true, true) => (g1, g2),
                    _ => continue,
                };
            let foot = self.ids.feet_bodies.iter().position(|&b| b == geom_body[robot] as usize);
            let Some(foot) = foot.filter(|_| world.geom_group(other) != ROBOT_GEOM_GROUP) else {
                self.report(
                    now,
                    "collision",
                    format!("{} touches {}", world.geom_name(robot), world.geom_name(other)),
                );
                continue;
            };
            let f = d.contact_force(ci);
            // The contact frame's rows are its normal and two tangents (MuJoCo's layout).
            let axis = |r: usize| Vector3::new(c.frame[3 * r], c.frame[3 * r + 1], c.frame[3 * r + 2]);
            loads.force[foot] += axis(0) * f[0] + axis(1) * f[1] + axis(2) * f[2];
            loads.normal_n[foot] += f[0].max(0.0);
            loads.moment[foot] += Vector3::from(c.pos) * f[0].max(0.0);
            if let Some((sw, planned)) = swing.filter(|(sw, _)| sw.foot.index() == foot) {
                let above = |pose: &Isometry3<f64>| planned.translation.z - pose.translation.z;
                if above(&sw.path[sw.path.len() - 1]) > self.p.strike_height_m
                    && above(&sw.path[0]) > self.p.strike_height_m
                {
                    let at = planned.inverse_transform_point(&Point3::from(c.pos));
                    self.report(
                        now,
                        "strike",
                        format!(
                            "the swinging {:?} foot hits {} at ({:.3}, {:.3}, {:.3}) m in its planned sole frame, {:.1} mm above its target",
                            sw.foot,
                            world.geom_name(other),
                            at.x,
                            at.y,
                            at.z,
                            above(&sw.path[sw.path.len() - 1]) * 1e3
                        ),
                    );
                }
            }
        }
        loads
    }

    /// Which feet carry load; each one's resultant inside its sole's friction pyramid (§6.2),
    /// its centre of pressure inside the sole, and the sole not sliding.
    fn feet(&mut self, now: f64, loads: &FootLoads, soles: &[Isometry3<f64>; 2]) -> [bool; 2] {
        let down = loads.normal_n.map(|n| n > self.p.contact_force_n);
        for (k, foot) in Foot::BOTH.into_iter().enumerate() {
            if !down[k] {
                self.landed[k] = None;
                continue;
            }
            let at = soles[k].translation.vector;
            let from = *self.landed[k].get_or_insert(at);
            let slip = (at - from).xy().norm();
            self.ex.max_slip_m = self.ex.max_slip_m.max(slip);
            if slip > self.p.slip_tolerance_m {
                self.report(now, "slip", format!("{foot:?} foot slid {:.1} mm while in contact", slip * 1e3));
                self.landed[k] = Some(at);
            }
            let local = soles[k].rotation.inverse() * loads.force[k];
            let normal = local.z.abs();
            let mu = self.p.friction;
            let loaded = normal >= self.p.friction_load_n;
            if loaded {
                let ratio = local.x.abs().max(local.y.abs()) / normal;
                self.ex.max_friction_ratio = self.ex.max_friction_ratio.max(ratio);
            }
            if loaded && (local.x.abs() > mu * normal || local.y.abs() > mu * normal) {
                let detail = format!(
                    "{foot:?} foot: tangential ({:.1}, {:.1}) N beyond {mu} x normal {normal:.1} N",
                    local.x, local.y
                );
                self.report(now, "friction", detail);
            }
            let cop = soles[k].inverse_transform_point(&Point3::from(loads.moment[k] / loads.normal_n[k]));
            let [hx, hy] = hrp4::SOLE_HALF_M;
            if cop.x.abs() > hx + 1e-3 || cop.y.abs() > hy + 1e-3 {
                self.report(
                    now,
                    "cop",
                    format!("{foot:?} centre of pressure outside the sole at ({:.3}, {:.3})", cop.x, cop.y),
                );
            }
        }
        down
    }

    /// The CoM against the stability polygon of the feet in contact.
    /// Returns this instant's margin, metres (negative outside, -inf without a polygon).
    fn margin(&mut self, world: &World, now: f64, down: [bool; 2], soles: &[Isometry3<f64>; 2]) -> f64 {
        let com = world.data().subtree_com()[self.ids.root_body];
        let poly = self.cache.polygon(down, soles, self.p.friction);
        let m = if poly.len() >= 3 { margin(poly, &P2::new(com[0], com[1])) } else { f64::NEG_INFINITY };
        self.ex.min_margin_m = self.ex.min_margin_m.min(m);
        if m < self.p.min_margin_m {
            let side = if m < 0.0 { "outside" } else { "inside (below the margin)" };
            let detail = format!(
                "CoM {:.1} mm {side} the stability polygon of the feet in contact ({down:?})",
                m.abs() * 1e3
            );
            self.report(now, "margin", detail);
        }
        m
    }

    /// Joint torques (the servos' demand) and speeds against the model's limits; returns
    /// this instant's largest torque ratio.
    fn joints(&mut self, world: &World, model: &RobotModel, servos: &Servos, now: f64) -> f64 {
        let mut now_max = 0.0_f64;
        for (a, jt) in model.joints().iter().enumerate().take(servos.kp.len()) {
            let demand = servos.demand_nm(world, a);
            let r = demand.abs() / jt.effort_nm;
            now_max = now_max.max(r);
            let s = world.data().qvel()[V_JOINTS + a].abs() / jt.velocity_rad_s;
            if r > self.ex.max_torque_ratio {
                self.ex.max_torque_ratio = r;
                self.ex.torque_joint.clone_from(&jt.name);
            }
            if s > self.ex.max_speed_ratio {
                self.ex.max_speed_ratio = s;
                self.ex.speed_joint.clone_from(&jt.name);
            }
            if r > self.p.max_torque_ratio {
                let detail = format!(
                    "{} needs {:.0} % of its torque limit ({:.1} of {:.1} N m)",
                    jt.name,
                    r * 100.0,
                    demand.abs(),
                    jt.effort_nm
                );
                self.report(now, "torque", detail);
            }
            if s > self.p.max_speed_ratio {
                self.report(now, "speed", format!("{} at {:.0} % of its speed limit", jt.name, s * 100.0));
            }
        }
        now_max
    }

    /// Records a touchdown of `sw`'s foot and checks it against its target and its step.
    fn touchdown(&mut self, now: f64, sw: &Swing, soles: &[Isometry3<f64>; 2]) {
        let sole = &soles[sw.foot.index()];
        let target = &sw.path[sw.path.len() - 1];
        let err = (sole.translation.vector - target.translation.vector).norm();
        let yaw = (sole.rotation.inverse() * target.rotation).euler_angles().2.abs();
        self.ex.touchdowns.push(Touchdown { foot: sw.foot, error_m: err, yaw_error_rad: yaw });
        if err > self.p.touchdown_tolerance_m || yaw > self.p.touchdown_yaw_tolerance_rad {
            let detail = format!(
                "{:?} foot lands {:.1} mm and {:.1} deg from its target",
                sw.foot,
                err * 1e3,
                yaw.to_degrees()
            );
            self.report(now, "touchdown", detail);
        }
        if let Some(over) = off_step(self.scene, sole).filter(|o| *o > self.p.overhang_tolerance_m) {
            self.report(
                now,
                "off_step",
                format!("{:?} foot overhangs its step's edge by {:.1} mm", sw.foot, over * 1e3),
            );
        }
    }

    /// Whether the robot fell: the base too far below both its start and its plan, or tilted
    /// away from the plan's base orientation (the plan leans the pelvis to keep the knees
    /// off the steps; a lean it asked for is not a fall).
    fn fell(&mut self, world: &World, now: f64, base_z_limit: f64, planned_q: &[f64]) -> bool {
        let quat = |q: &[f64]| UnitQuaternion::from_quaternion(Quaternion::new(q[3], q[4], q[5], q[6]));
        let qpos = world.data().qpos();
        let up = quat(qpos) * Vector3::z();
        let tilt = up.angle(&(quat(planned_q) * Vector3::z()));
        let fell = qpos[2] < base_z_limit || tilt > self.p.fall_tilt_rad;
        if fell {
            let detail = format!(
                "the robot fell: base at {:.2} m, tilted {:.0} deg from the plan's ({:.0} deg from upright)",
                qpos[2],
                tilt.to_degrees(),
                up.angle(&Vector3::z()).to_degrees()
            );
            self.report(now, "fall", detail);
            self.ex.fell = true;
        }
        fell
    }
}

/// Runs `plan` in `world` (whose robot stands where the plan starts) and checks it.
/// `scene` gives the true step tops for the on-the-step check; `observer` sees the robot's
/// state after every physics step and the violations at the end.
pub fn execute(
    world: &mut World,
    model: &RobotModel,
    scene: &Scene,
    plan: &Plan,
    servo: &ServoParams,
    p: &CheckParams,
    observer: &mut dyn Observer,
) -> Result<Execution, SimError> {
    let dt = world.model().opt().timestep;
    let t_start = world.data().time();
    let base_z0 = world.data().qpos()[2];
    let traj = &plan.trajectory;
    let mut servos = Servos::new(world, servo);
    let mut mon = Monitor {
        ids: Ids::of(world, model)?,
        p,
        scene,
        cache: PolygonCache::default(),
        last_report: Vec::new(),
        landed: [None, None],
        ex: Execution {
            max_slip_m: 0.0,
            max_friction_ratio: 0.0,
            sim_s: 0.0,
            min_margin_m: f64::INFINITY,
            max_torque_ratio: 0.0,
            torque_joint: String::new(),
            max_speed_ratio: 0.0,
            speed_joint: String::new(),
            touchdowns: Vec::new(),
            violations: Vec::new(),
            fell: false,
        },
    };
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
    let mut q = vec![0.0; model.nq()];
    for k in 1..=(traj.duration_s() / dt).round() as usize {
        let t = k as f64 * dt;
        traj.q_at(t, &mut q);
        servos.command(world, &q, dt);
        world.data_mut().step();
        let now = world.data().time() - t_start;
        let soles = mon.ids.sole_sites.map(|s| world.site_pose(s));
        // Touchdown: the moment a swing segment ends (or the trajectory does).
        while t > ends[seg] - dt / 2.0 && !landed[seg] {
            landed[seg] = true;
            if let Some(sw) = &plan.segments[seg].swing {
                mon.touchdown(now, sw, &soles);
            }
            if seg + 1 < plan.segments.len() {
                seg += 1;
            }
        }
        let planned = traj.sample_at(t);
        let swing = plan.segments[seg].swing.as_ref().map(|sw| (sw, &planned.feet[sw.foot.index()]));
        let loads = mon.contacts(world, now, swing);
        let down = mon.feet(now, &loads, &soles);
        let margin_m = mon.margin(world, now, down, &soles);
        let max_torque_ratio = mon.joints(world, model, &servos, now);
        let state = RobotState {
            q: &world.data().qpos()[..model.nq()],
            foot_forces_n: loads.force,
            margin_m,
            max_torque_ratio,
        };
        observer.state(world.data().time(), &state);
        if mon.fell(world, now, planned.q[2].min(base_z0) - p.fall_drop_m, &planned.q)
            || super::stop::requested()
        {
            break;
        }
    }
    mon.ex.sim_s = world.data().time() - t_start;
    for v in &mon.ex.violations {
        observer.violation(t_start + v.t_s, v);
    }
    Ok(mon.ex)
}

/// How far the sole at `sole` overhangs the tread it stands on (the step whose height is
/// within 2 cm of it), `None` on the floor.
fn off_step(scene: &Scene, sole: &Isometry3<f64>) -> Option<f64> {
    let step = scene.steps().iter().find(|s| (s.height_m - sole.translation.z).abs() < 0.02)?;
    let [hx, hy] = hrp4::SOLE_HALF_M;
    let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
    Some(
        corners
            .iter()
            .map(|(sx, sy)| step.outside_m(&sole.transform_point(&Point3::new(sx * hx, sy * hy, 0.0))))
            .fold(0.0, f64::max),
    )
}
