//! The simulator's robot, generated from the [`RobotModel`] (itself read from the URDF), so
//! the MJCF can never disagree with the kinematics: one body per link with the same
//! placements, inertias and joint axes, one position servo per joint whose force range is the
//! joint's torque limit, box soles at the exact sole size, capsules elsewhere, and the
//! sensors the real robot has: a 6-axis force/torque sensor at each ankle (at the origin of
//! the link carrying the sole) and an IMU (accelerometer, gyro) at the waist (the root link's
//! origin). Sites and sensors have no mass and no geometry: they change nothing in the physics.
//!
//! A [`BodyVariation`] makes the simulated body differ from the model on purpose (masses,
//! centres of mass, inertias, joint friction, servo gains, a compliant bush under each
//! ankle); the nominal variation writes the model exactly.

use super::model::{base_pose, RobotError, RobotModel, Shape, Q_JOINTS};
use crate::scene::mjcf::{RobotFragment, ROBOT_GEOM_GROUP, SOLE_CONAFFINITY, SPIN_ROLL_FRICTION};
use nalgebra::{Isometry3, UnitQuaternion, Vector3};
use std::fmt::Write;

/// Servo position gain per newton-metre of torque limit, N m/rad per N m: the servo reaches
/// its torque limit at about 2 degrees of error.
pub const KP_PER_EFFORT: f64 = 28.6;
/// Servo damping gain as a fraction of the position gain, s (a 10 ms velocity time constant).
pub const KV_OVER_KP: f64 = 0.01;
/// Reflected rotor inertia added to every joint, kg m^2 (an estimate for harmonic-drive
/// servos of this class; it also keeps the 1 kHz integration stable on light links).
pub const ARMATURE_KGM2: f64 = 0.02;
/// Viscous friction of every joint, N m s/rad (estimate).
pub const JOINT_DAMPING: f64 = 0.5;
/// Sole friction coefficient (against the world it is unused: the world's geoms have a
/// higher priority, so a contact takes the surface's friction from the scenario).
pub const SOLE_FRICTION: f64 = 1.0;
/// Friction of the robot's other geoms (shins, arms) among themselves (against the world,
/// as for the soles, the surface's friction applies).
pub const BODY_FRICTION: f64 = 0.5;

/// Name of the force/torque sensor site on the link carrying sole frame `sole`; its force
/// and torque sensors are `<site>_force` and `<site>_torque`.
pub fn ft_site(sole: &str) -> String {
    format!("{sole}_FT")
}

/// Mass of the sole plate below an ankle bush, kg (taken from the ankle link's own mass, so
/// the body weighs what it did; an estimate for a plate of this size).
pub const SOLE_PLATE_MASS_KG: f64 = 0.2;

/// How the simulated body differs from the model it is generated from.
#[derive(Debug, Clone, PartialEq)]
pub struct BodyVariation {
    /// Each link's mass over the model's (by link index).
    pub mass_scale: Vec<f64>,
    /// Each link's centre of mass moved by this, in the link frame, metres.
    pub com_offset_m: Vec<Vector3<f64>>,
    /// Each link's inertia tensor over the model's.
    pub inertia_scale: Vec<f64>,
    /// Each servo's gains over the model's (by joint index).
    pub gain_scale: Vec<f64>,
    /// Dry friction of every joint, N m.
    pub joint_friction_nm: f64,
    /// A compliant bush between each sole-carrying link and its sole, if any.
    pub ankle_bush: Option<AnkleBush>,
}

/// A rotational spring and damper about the sole's pitch and roll axes at the ankle link's
/// origin: the sole plate (its geoms and frames) moves on it, unseen by the encoders.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AnkleBush {
    /// N m/rad.
    pub stiffness_nm_per_rad: f64,
    /// N m s/rad.
    pub damping_nms_per_rad: f64,
}

impl BodyVariation {
    /// The model exactly.
    pub fn nominal(model: &RobotModel) -> Self {
        let n = model.links().len();
        Self {
            mass_scale: vec![1.0; n],
            com_offset_m: vec![Vector3::zeros(); n],
            inertia_scale: vec![1.0; n],
            gain_scale: vec![1.0; model.joints().len()],
            joint_friction_nm: 0.0,
            ankle_bush: None,
        }
    }
}

/// Name of the bush joints under the link `link` (pitch, roll).
pub fn bush_joints(link: &str) -> [String; 2] {
    [format!("{link}_BUSH_P"), format!("{link}_BUSH_R")]
}

/// Name of the IMU site at the root link's origin; its sensors are `IMU_accel`, `IMU_gyro`.
pub const IMU_SITE: &str = "IMU";

fn fmt_pose(p: &Isometry3<f64>) -> String {
    let t = p.translation.vector;
    let q: &UnitQuaternion<f64> = &p.rotation;
    format!(r#"pos="{:?} {:?} {:?}" quat="{:?} {:?} {:?} {:?}""#, t.x, t.y, t.z, q.w, q.i, q.j, q.k)
}

/// The robot's MJCF fragment, its base at `q`'s free-flyer pose; `q` also becomes the
/// keyframe `initial` (load it with `mj_resetDataKeyframe`, or set qpos directly). The
/// links carrying the frames `sole_frames` get the sole friction.
pub fn fragment(model: &RobotModel, q: &[f64], sole_frames: &[&str]) -> Result<RobotFragment, RobotError> {
    fragment_varied(model, q, sole_frames, &BodyVariation::nominal(model))
}

/// [`fragment`] of a body that differs from `model` by `var`. With an ankle bush, MuJoCo's
/// qpos has the bush's two angles after each sole-carrying link's joint: read joints by
/// address (the keyframe has them at 0).
pub fn fragment_varied(
    model: &RobotModel,
    q: &[f64],
    sole_frames: &[&str],
    var: &BodyVariation,
) -> Result<RobotFragment, RobotError> {
    let mut soles = vec![false; model.links().len()];
    for f in sole_frames {
        soles[model.frames()[model.frame_id(f)?].link] = true;
    }
    let links = model.links();
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); links.len()];
    for (i, l) in links.iter().enumerate() {
        if let Some(p) = l.parent {
            children[p].push(i);
        }
    }
    // The sensors, and their sites by link.
    let mut sites: Vec<Vec<String>> = vec![Vec::new(); links.len()];
    let mut sensors = String::from("  <sensor>\n");
    sites[0].push(IMU_SITE.to_string());
    let _ = writeln!(sensors, r#"    <accelerometer name="{IMU_SITE}_accel" site="{IMU_SITE}"/>"#);
    let _ = writeln!(sensors, r#"    <gyro name="{IMU_SITE}_gyro" site="{IMU_SITE}"/>"#);
    for f in sole_frames {
        let site = ft_site(f);
        sites[model.frames()[model.frame_id(f)?].link].push(site.clone());
        let _ = writeln!(sensors, r#"    <force name="{site}_force" site="{site}"/>"#);
        let _ = writeln!(sensors, r#"    <torque name="{site}_torque" site="{site}"/>"#);
    }
    sensors += "  </sensor>\n";
    let mut body = String::new();
    let mut qpos = Vec::with_capacity(q.len() + 4);
    let tree = Tree { model, children: &children, soles: &soles, sites: &sites, var };
    tree.write_body(0, q, 2, &mut body, &mut qpos);
    let mut extras = String::from("  <actuator>\n");
    for (k, j) in model.joints().iter().enumerate() {
        let kp = KP_PER_EFFORT * j.effort_nm * var.gain_scale[k];
        let _ = writeln!(
            extras,
            r#"    <position name="{n}" joint="{n}" kp="{kp:?}" kv="{kv:?}" forcerange="{lo:?} {hi:?}" ctrlrange="{cl:?} {ch:?}"/>"#,
            n = j.name,
            kv = kp * KV_OVER_KP,
            lo = -j.effort_nm,
            hi = j.effort_nm,
            cl = j.lower_rad,
            ch = j.upper_rad,
        );
    }
    extras += "  </actuator>\n";
    extras += &sensors;
    let qs: Vec<String> = qpos.iter().map(|x| format!("{x:?}")).collect();
    let ctrl: Vec<String> = q[Q_JOINTS..].iter().map(|x| format!("{x:?}")).collect();
    let _ = write!(
        extras,
        "  <keyframe>\n    <key name=\"initial\" qpos=\"{}\" ctrl=\"{}\"/>\n  </keyframe>",
        qs.join(" "),
        ctrl.join(" ")
    );
    let sole_geoms = (0..links.len())
        .filter(|&i| soles[i])
        .flat_map(|i| (0..links[i].collisions.len()).map(move |k| geom_name(&links[i].name, k)))
        .collect();
    Ok(RobotFragment { body_xml: body.trim_end().to_string(), extras_xml: extras, sole_geoms })
}

/// The name of link `link`'s `k`-th collision geom.
fn geom_name(link: &str, k: usize) -> String {
    format!("{link}_geom{k}")
}

/// The model's tree and what the MJCF writer needs along it.
struct Tree<'a> {
    model: &'a RobotModel,
    children: &'a [Vec<usize>],
    soles: &'a [bool],
    sites: &'a [Vec<String>],
    var: &'a BodyVariation,
}

impl Tree<'_> {
    /// Writes link `i`'s body (and its subtree) at indentation `depth`, and its joints'
    /// keyframe values (from `q`, the bush's at 0) in MuJoCo's qpos order into `qpos`.
    fn write_body(&self, i: usize, q: &[f64], depth: usize, out: &mut String, qpos: &mut Vec<f64>) {
        let (model, var) = (self.model, self.var);
        let link = &model.links()[i];
        let pad = "  ".repeat(depth);
        let placement = if i == 0 { base_pose(q) } else { link.placement };
        let _ = writeln!(out, r#"{pad}<body name="{}" {}>"#, link.name, fmt_pose(&placement));
        match link.joint {
            None => {
                let _ = writeln!(out, r#"{pad}  <freejoint name="root"/>"#);
                qpos.extend_from_slice(&q[..Q_JOINTS]);
            }
            Some(j) => {
                let jt = &model.joints()[j];
                let a = link.axis;
                let range = if jt.lower_rad.is_finite() {
                    format!(r#" range="{:?} {:?}""#, jt.lower_rad, jt.upper_rad)
                } else {
                    String::new()
                };
                let friction = match var.joint_friction_nm > 0.0 {
                    true => format!(r#" frictionloss="{:?}""#, var.joint_friction_nm),
                    false => String::new(),
                };
                let _ = writeln!(
                    out,
                    r#"{pad}  <joint name="{}" type="hinge" axis="{:?} {:?} {:?}"{range} armature="{ARMATURE_KGM2:?}" damping="{JOINT_DAMPING:?}"{friction}/>"#,
                    jt.name, a.x, a.y, a.z
                );
                qpos.push(q[Q_JOINTS + j]);
            }
        }
        let bush = var.ankle_bush.filter(|_| self.soles[i]);
        let plate_kg = if bush.is_some() { SOLE_PLATE_MASS_KG.min(link.mass_kg / 2.0) } else { 0.0 };
        let c = link.com_m + var.com_offset_m[i];
        let m = link.inertia * var.inertia_scale[i];
        let _ = writeln!(
            out,
            r#"{pad}  <inertial pos="{:?} {:?} {:?}" mass="{:?}" fullinertia="{:?} {:?} {:?} {:?} {:?} {:?}"/>"#,
            c.x,
            c.y,
            c.z,
            link.mass_kg * var.mass_scale[i] - plate_kg,
            m[(0, 0)],
            m[(1, 1)],
            m[(2, 2)],
            m[(0, 1)],
            m[(0, 2)],
            m[(1, 2)]
        );
        // The sole plate on its bush: the link's geoms and frames move with it.
        let inner = match bush {
            Some(b) => {
                let [p, r] = bush_joints(&link.name);
                let _ = writeln!(out, r#"{pad}  <body name="{}_PLATE">"#, link.name);
                for (name, axis) in [(p, "0 1 0"), (r, "1 0 0")] {
                    let _ = writeln!(
                        out,
                        r#"{pad}    <joint name="{name}" type="hinge" axis="{axis}" stiffness="{:?}" damping="{:?}" armature="{ARMATURE_KGM2:?}"/>"#,
                        b.stiffness_nm_per_rad, b.damping_nms_per_rad
                    );
                    qpos.push(0.0);
                }
                let _ = writeln!(
                    out,
                    r#"{pad}    <inertial pos="{:?} {:?} {:?}" mass="{plate_kg:?}" diaginertia="1e-4 1e-4 1e-4"/>"#,
                    c.x, c.y, c.z
                );
                format!("{pad}  ")
            }
            None => pad.clone(),
        };
        for (k, col) in link.collisions.iter().enumerate() {
            let (kind, size) = match col.shape {
                Shape::Box(s) => ("box", format!("{:?} {:?} {:?}", s[0] / 2.0, s[1] / 2.0, s[2] / 2.0)),
                Shape::Cylinder { radius_m, length_m } => {
                    ("capsule", format!("{radius_m:?} {:?}", length_m / 2.0))
                }
                Shape::Sphere(r) => ("sphere", format!("{r:?}")),
            };
            let [spin, roll] = SPIN_ROLL_FRICTION;
            let (friction, conaffinity) =
                if self.soles[i] { (SOLE_FRICTION, SOLE_CONAFFINITY) } else { (BODY_FRICTION, "1") };
            let _ = writeln!(
                out,
                r#"{inner}  <geom name="{}" type="{kind}" size="{size}" {} group="{ROBOT_GEOM_GROUP}" contype="2" conaffinity="{conaffinity}" condim="3" friction="{friction:?} {spin} {roll}" rgba="0.75 0.78 0.85 1"/>"#,
                geom_name(&link.name, k),
                fmt_pose(&col.placement)
            );
        }
        for f in model.frames().iter().filter(|f| f.link == i) {
            let _ =
                writeln!(out, r#"{inner}  <site name="{}" {} size="0.01"/>"#, f.name, fmt_pose(&f.placement));
        }
        if bush.is_some() {
            let _ = writeln!(out, "{pad}  </body>");
        }
        for s in &self.sites[i] {
            let _ = writeln!(out, r#"{pad}  <site name="{s}" size="0.005"/>"#);
        }
        for &c in &self.children[i] {
            self.write_body(c, q, depth + 1, out, qpos);
        }
        let _ = writeln!(out, "{pad}</body>");
    }
}
