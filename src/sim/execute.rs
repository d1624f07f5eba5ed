//! Execution of a planned trajectory in MuJoCo with every check at every physics step: the
//! robot's position servos track q(t) at the physics rate, on MuJoCo's own contacts and
//! friction, and a [`Monitor`] checks, from what the simulator actually has, the CoM inside
//! the static-stability polygon of the feet really in contact, each contact force inside the
//! friction pyramid the plan assumed, each sole's centre of pressure inside the sole, joint
//! torques (the servos' unclamped demand) and speeds within the model's limits, the feet at
//! their targets at touchdown and on their step, no foot strike during a swing, no part other
//! than the soles touching the world, and no fall.

use super::world::{SimError, World};
use crate::geom2d::P2;
use crate::planning::contact::Contact;
use crate::planning::dd::DdParams;
use crate::planning::footholds::Foot;
use crate::planning::polygon::{by_double_description, margin};
use crate::planning::Plan;
use crate::robot::hrp4;
use crate::robot::model::{RobotModel, Q_JOINTS, V_JOINTS};
use crate::scene::mjcf::ROBOT_GEOM_GROUP;
use crate::scene::Scene;
use nalgebra::{Isometry3, Point3, Vector3};

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
    /// Simulation time, seconds.
    pub t_s: f64,
    /// Which check (`margin`, `friction`, `cop`, `torque`, `speed`, `touchdown`,
    /// `off_step`, `strike`, `collision`, `fall`).
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
}

/// The robot's identifiers in the world.
struct Ids {
    feet_bodies: [usize; 2],
    sole_sites: [usize; 2],
    root_body: usize,
    kp: Vec<f64>,
    kv: Vec<f64>,
}

impl Ids {
    fn of(world: &World, model: &RobotModel) -> Result<Self, SimError> {
        let sole_sites = [world.site_id(hrp4::R_SOLE)?, world.site_id(hrp4::L_SOLE)?];
        let foot_link =
            |f: &str| model.frame_id(f).map(|i| model.links()[model.frames()[i].link].name.clone());
        let feet_bodies = [
            world.body_id(&foot_link(hrp4::R_SOLE).map_err(SimError::from)?)?,
            world.body_id(&foot_link(hrp4::L_SOLE).map_err(SimError::from)?)?,
        ];
        let root_body = world.body_id(&model.root().name)?;
        let m = world.model();
        let nu = m.ffi().nu as usize;
        let (gp, bp) = (m.actuator_gainprm(), m.actuator_biasprm());
        Ok(Self {
            feet_bodies,
            sole_sites,
            root_body,
            kp: (0..nu).map(|a| gp[a][0]).collect(),
            kv: (0..nu).map(|a| -bp[a][2]).collect(),
        })
    }
}

/// The polygon of the feet in contact, recomputed only when they change.
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
            let half = [hrp4::SOLE_SIZE_M[0] / 2.0, hrp4::SOLE_SIZE_M[1] / 2.0];
            let contacts: Vec<Contact> = (0..2)
                .filter(|&k| down[k])
                .filter_map(|k| Contact::new(soles[k], half[0], half[1], friction).ok())
                .collect();
            self.polygon = by_double_description(&contacts, &DdParams::default()).unwrap_or_default();
            self.key = Some((down, *soles));
        }
        &self.polygon
    }
}

/// Runs `plan` in `world` (whose robot stands where the plan starts) and checks it.
/// `scene` gives the true step tops for the on-the-step check.
pub fn execute(
    world: &mut World,
    model: &RobotModel,
    scene: &Scene,
    plan: &Plan,
    servo: &ServoParams,
    p: &CheckParams,
) -> Result<Execution, SimError> {
    let ids = Ids::of(world, model)?;
    let dt = world.model().opt().timestep;
    let nu = ids.kp.len();
    let t_start = world.data().time();
    let base_z0 = world.data().qpos()[2];
    let traj = &plan.trajectory;
    let steps = (traj.duration_s() / dt).round() as usize;
    let mut q = vec![0.0; model.nq()];
    let mut integral = vec![0.0; nu];
    let mut cache = PolygonCache { key: None, polygon: Vec::new() };
    let mut ex = Execution {
        sim_s: 0.0,
        min_margin_m: f64::INFINITY,
        max_torque_ratio: 0.0,
        torque_joint: String::new(),
        max_speed_ratio: 0.0,
        speed_joint: String::new(),
        touchdowns: Vec::new(),
        violations: Vec::new(),
        fell: false,
    };
    let mut last_report: Vec<(&'static str, f64)> = Vec::new();
    let mut report = |ex: &mut Execution, t_s: f64, check: &'static str, detail: String| {
        // One violation of a kind per simulated second.
        if let Some(e) = last_report.iter_mut().find(|(c, _)| *c == check) {
            if t_s - e.1 < 1.0 {
                return;
            }
            e.1 = t_s;
        } else {
            last_report.push((check, t_s));
        }
        ex.violations.push(Violation { t_s, check, detail });
    };
    // Segment end times, for the touchdowns.
    let mut ends = Vec::new();
    let mut acc = 0.0;
    for s in &plan.segments {
        acc += s.duration_s;
        ends.push(acc);
    }
    let mut seg = 0usize;
    let mut landed = vec![false; plan.segments.len()];
    for k in 1..=steps {
        let t = k as f64 * dt;
        traj.q_at(t, &mut q);
        {
            let d = world.data_mut();
            for a in 0..nu {
                integral[a] += (q[Q_JOINTS + a] - d.qpos()[Q_JOINTS + a]) * dt;
            }
            let ctrl = d.ctrl_mut();
            for a in 0..nu {
                ctrl[a] = q[Q_JOINTS + a] + servo.integral_gain_per_s * integral[a];
            }
            d.step();
        }
        let now = world.data().time() - t_start;
        let soles = [world.site_pose(ids.sole_sites[0]), world.site_pose(ids.sole_sites[1])];
        // Touchdown: the moment a swing segment ends (or the trajectory does).
        while t > ends[seg] - dt / 2.0 && !landed[seg] {
            landed[seg] = true;
            if let Some(sw) = &plan.segments[seg].swing {
                touchdown(&mut ex, &mut report, now, sw, &soles, scene, p);
            }
            if seg + 1 < plan.segments.len() {
                seg += 1;
            }
        }
        // Contacts: feet down, forces, CoP, strikes, other parts touching.
        let mut force_n = [0.0f64; 2];
        let mut cop = [Vector3::zeros(); 2];
        let mut force_world = [Vector3::zeros(); 2];
        let swing = plan.segments[seg].swing.as_ref();
        let (contacts, model_geom_body) = {
            let d = world.data();
            (d.contact().to_vec(), world.model().geom_bodyid())
        };
        for (ci, c) in contacts.iter().enumerate() {
            let (g1, g2) = (c.geom1 as usize, c.geom2 as usize);
            let (robot, other) =
                match (world.geom_group(g1) == ROBOT_GEOM_GROUP, world.geom_group(g2) == ROBOT_GEOM_GROUP) {
                    (true, false) => (g1, g2),
                    (false, true) => (g2, g1),
                    (true, true) => {
                        report(
                            &mut ex,
                            now,
                            "collision",
                            format!("{} touches {}", world.geom_name(g1), world.geom_name(g2)),
                        );
                        continue;
                    }
                    _ => continue,
                };
            let body = model_geom_body[robot] as usize;
            let Some(foot) = ids.feet_bodies.iter().position(|&b| b == body) else {
                report(
                    &mut ex,
                    now,
                    "collision",
                    format!("{} touches {}", world.geom_name(robot), world.geom_name(other)),
                );
                continue;
            };
            let f = world.data().contact_force(ci);
            let fn_ = f[0];
            // The contact frame's rows are its normal and two tangents (MuJoCo's layout).
            let axis = |r: usize| Vector3::new(c.frame[3 * r], c.frame[3 * r + 1], c.frame[3 * r + 2]);
            force_world[foot] += axis(0) * f[0] + axis(1) * f[1] + axis(2) * f[2];
            force_n[foot] += fn_.max(0.0);
            cop[foot] += Vector3::from(c.pos) * fn_.max(0.0);
            if let Some(sw) = swing {
                if usize::from(sw.foot == Foot::Left) == foot {
                    let target_z = sw.path[sw.path.len() - 1].translation.z;
                    let planned = plan.trajectory.samples
                        [((t * traj.rate_hz) as usize).min(traj.samples.len() - 1)]
                    .feet[foot];
                    if planned.translation.z - target_z > p.strike_height_m
                        && planned.translation.z - sw.path[0].translation.z > p.strike_height_m
                    {
                        report(
                            &mut ex,
                            now,
                            "strike",
                            format!("the swinging {:?} foot hits {}", sw.foot, world.geom_name(other)),
                        );
                    }
                }
            }
        }
        let down = [force_n[0] > p.contact_force_n, force_n[1] > p.contact_force_n];
        // Each foot's resultant inside the four-sided friction pyramid of its sole (§6.2).
        for k in 0..2 {
            if down[k] {
                let local = soles[k].rotation.inverse() * force_world[k];
                let normal = local.z.abs();
                if local.x.abs() > p.friction * normal || local.y.abs() > p.friction * normal {
                    report(
                        &mut ex,
                        now,
                        "friction",
                        format!(
                            "{} foot: tangential ({:.1}, {:.1}) N beyond {} x normal {normal:.1} N",
                            ["right", "left"][k],
                            local.x,
                            local.y,
                            p.friction
                        ),
                    );
                }
            }
        }
        for k in 0..2 {
            if down[k] {
                let c = soles[k].inverse_transform_point(&Point3::from(cop[k] / force_n[k]));
                let (hx, hy) = (hrp4::SOLE_SIZE_M[0] / 2.0 + 1e-3, hrp4::SOLE_SIZE_M[1] / 2.0 + 1e-3);
                if c.x.abs() > hx || c.y.abs() > hy {
                    report(
                        &mut ex,
                        now,
                        "cop",
                        format!(
                            "{} centre of pressure outside the sole at ({:.3}, {:.3})",
                            ["right", "left"][k],
                            c.x,
                            c.y
                        ),
                    );
                }
            }
        }
        // CoM in the polygon of the real contacts.
        let com = world.data().subtree_com()[ids.root_body];
        let poly = cache.polygon(down, &soles, p.friction);
        let m = if poly.len() >= 3 { margin(poly, &P2::new(com[0], com[1])) } else { f64::NEG_INFINITY };
        ex.min_margin_m = ex.min_margin_m.min(m);
        if m < p.min_margin_m {
            report(
                &mut ex,
                now,
                "margin",
                format!(
                    "CoM {:.1} mm {} the stability polygon of the feet in contact ({:?})",
                    m.abs() * 1e3,
                    if m < 0.0 { "outside" } else { "inside (below the margin)" },
                    down
                ),
            );
        }
        // Torques (the servos' unclamped demand) and speeds.
        {
            let d = world.data();
            for (a, jt) in model.joints().iter().enumerate().take(nu) {
                let demand =
                    ids.kp[a] * (d.ctrl()[a] - d.qpos()[Q_JOINTS + a]) - ids.kv[a] * d.qvel()[V_JOINTS + a];
                let r = demand.abs() / jt.effort_nm;
                if r > ex.max_torque_ratio {
                    ex.max_torque_ratio = r;
                    ex.torque_joint = jt.name.clone();
                }
                let s = d.qvel()[V_JOINTS + a].abs() / jt.velocity_rad_s;
                if s > ex.max_speed_ratio {
                    ex.max_speed_ratio = s;
                    ex.speed_joint = jt.name.clone();
                }
                if r > p.max_torque_ratio {
                    report(
                        &mut ex,
                        now,
                        "torque",
                        format!(
                            "{} needs {:.0} % of its torque limit ({:.1} of {:.1} N m)",
                            jt.name,
                            r * 100.0,
                            demand.abs(),
                            jt.effort_nm
                        ),
                    );
                }
                if s > p.max_speed_ratio {
                    report(
                        &mut ex,
                        now,
                        "speed",
                        format!("{} at {:.0} % of its speed limit", jt.name, s * 100.0),
                    );
                }
            }
        }
        // Fall.
        let d = world.data();
        let base_tilt = {
            let qw = d.qpos()[3..7].to_vec();
            let r = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                qw[0], qw[1], qw[2], qw[3],
            ));
            (r * Vector3::z()).angle(&Vector3::z())
        };
        let planned_z = traj.samples[((t * traj.rate_hz) as usize).min(traj.samples.len() - 1)].q[2];
        if d.qpos()[2] < planned_z.min(base_z0) - p.fall_drop_m || base_tilt > p.fall_tilt_rad {
            report(
                &mut ex,
                now,
                "fall",
                format!(
                    "the robot fell: base at {:.2} m, tilted {:.0} deg",
                    d.qpos()[2],
                    base_tilt.to_degrees()
                ),
            );
            ex.fell = true;
            ex.sim_s = now;
            return Ok(ex);
        }
    }
    ex.sim_s = world.data().time() - t_start;
    Ok(ex)
}

/// Records a touchdown of `sw`'s foot and checks it against its target and its step.
fn touchdown(
    ex: &mut Execution,
    report: &mut impl FnMut(&mut Execution, f64, &'static str, String),
    now: f64,
    sw: &crate::planning::gait::Swing,
    soles: &[Isometry3<f64>; 2],
    scene: &Scene,
    p: &CheckParams,
) {
    let k = usize::from(sw.foot == Foot::Left);
    let target = &sw.path[sw.path.len() - 1];
    let err = (soles[k].translation.vector - target.translation.vector).norm();
    let yaw = (soles[k].rotation.inverse() * target.rotation).euler_angles().2.abs();
    ex.touchdowns.push(Touchdown { foot: sw.foot, error_m: err, yaw_error_rad: yaw });
    if err > p.touchdown_tolerance_m || yaw > p.touchdown_yaw_tolerance_rad {
        report(
            ex,
            now,
            "touchdown",
            format!(
                "{:?} foot lands {:.1} mm and {:.1} deg from its target",
                sw.foot,
                err * 1e3,
                yaw.to_degrees()
            ),
        );
    }
    if let Some(over) = off_step(scene, &soles[k]) {
        if over > p.overhang_tolerance_m {
            report(
                ex,
                now,
                "off_step",
                format!("{:?} foot overhangs its step's edge by {:.1} mm", sw.foot, over * 1e3),
            );
        }
    }
}

/// How far the sole at `sole` overhangs the tread it stands on (the step top nearest below
/// its centre, or the floor), `None` on the floor.
fn off_step(scene: &Scene, sole: &Isometry3<f64>) -> Option<f64> {
    let c = sole.translation.vector;
    let step = scene.steps().iter().find(|s| (s.height_m - c.z).abs() < 0.02)?;
    let (hx, hy) = (hrp4::SOLE_SIZE_M[0] / 2.0, hrp4::SOLE_SIZE_M[1] / 2.0);
    let o = step.corners[0];
    let u = (step.corners[1] - o).normalize();
    let v = (step.corners[3] - o).normalize();
    let mut worst: f64 = 0.0;
    for (sx, sy) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
        let corner = sole.transform_point(&Point3::new(sx * hx, sy * hy, 0.0));
        let d = corner - o;
        let (a, b) = (d.dot(&u), d.dot(&v));
        let over = (-a).max(a - step.depth_m).max(-b).max(b - step.width_m);
        worst = worst.max(over);
    }
    Some(worst)
}
