//! The simulator's robot, generated from the [`RobotModel`] (itself read from the URDF), so
//! the MJCF can never disagree with the kinematics: one body per link with the same
//! placements, inertias and joint axes, one position servo per joint whose force range is the
//! joint's torque limit, box soles at the exact sole size, capsules elsewhere, and the
//! sensors the real robot has: a 6-axis force/torque sensor at each ankle (at the origin of
//! the link carrying the sole) and an IMU (accelerometer, gyro) at the waist (the root link's
//! origin). Sites and sensors have no mass and no geometry: they change nothing in the physics.

use super::model::{RobotError, RobotModel, Shape, Q_JOINTS};
use crate::scene::mjcf::{RobotFragment, ROBOT_GEOM_GROUP};
use nalgebra::{Isometry3, UnitQuaternion};
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
    write_body(model, 0, &children, &soles, &sites, q, 2, &mut body);
    let mut extras = String::from("  <actuator>\n");
    for j in model.joints() {
        let kp = KP_PER_EFFORT * j.effort_nm;
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
    let qs: Vec<String> = q.iter().map(|x| format!("{x:?}")).collect();
    let ctrl: Vec<String> = q[Q_JOINTS..].iter().map(|x| format!("{x:?}")).collect();
    let _ = write!(
        extras,
        "  <keyframe>\n    <key name=\"initial\" qpos=\"{}\" ctrl=\"{}\"/>\n  </keyframe>",
        qs.join(" "),
        ctrl.join(" ")
    );
    Ok(RobotFragment { body_xml: body.trim_end().to_string(), extras_xml: extras })
}

#[allow(clippy::too_many_arguments)]
fn write_body(
    model: &RobotModel,
    i: usize,
    children: &[Vec<usize>],
    soles: &[bool],
    sites: &[Vec<String>],
    q: &[f64],
    depth: usize,
    out: &mut String,
) {
    let link = &model.links()[i];
    let pad = "  ".repeat(depth);
    let placement = if i == 0 {
        Isometry3::from_parts(
            nalgebra::Translation3::new(q[0], q[1], q[2]),
            UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[3], q[4], q[5], q[6])),
        )
    } else {
        link.placement
    };
    let _ = writeln!(out, r#"{pad}<body name="{}" {}>"#, link.name, fmt_pose(&placement));
    match link.joint {
        None => {
            let _ = writeln!(out, r#"{pad}  <freejoint name="root"/>"#);
        }
        Some(j) => {
            let jt = &model.joints()[j];
            let a = link.axis;
            let range = if jt.lower_rad.is_finite() {
                format!(r#" range="{:?} {:?}""#, jt.lower_rad, jt.upper_rad)
            } else {
                String::new()
            };
            let _ = writeln!(
                out,
                r#"{pad}  <joint name="{}" type="hinge" axis="{:?} {:?} {:?}"{range} armature="{ARMATURE_KGM2:?}" damping="{JOINT_DAMPING:?}"/>"#,
                jt.name, a.x, a.y, a.z
            );
        }
    }
    let c = link.com_m;
    let m = &link.inertia;
    let _ = writeln!(
        out,
        r#"{pad}  <inertial pos="{:?} {:?} {:?}" mass="{:?}" fullinertia="{:?} {:?} {:?} {:?} {:?} {:?}"/>"#,
        c.x,
        c.y,
        c.z,
        link.mass_kg,
        m[(0, 0)],
        m[(1, 1)],
        m[(2, 2)],
        m[(0, 1)],
        m[(0, 2)],
        m[(1, 2)]
    );
    for (k, col) in link.collisions.iter().enumerate() {
        let (kind, size) = match col.shape {
            Shape::Box(s) => ("box", format!("{:?} {:?} {:?}", s[0] / 2.0, s[1] / 2.0, s[2] / 2.0)),
            Shape::Cylinder { radius_m, length_m } => {
                ("capsule", format!("{radius_m:?} {:?}", length_m / 2.0))
            }
            Shape::Sphere(r) => ("sphere", format!("{r:?}")),
        };
        let friction = if soles[i] { SOLE_FRICTION } else { BODY_FRICTION };
        let _ = writeln!(
            out,
            r#"{pad}  <geom name="{}_geom{k}" type="{kind}" size="{size}" {} group="{ROBOT_GEOM_GROUP}" contype="2" conaffinity="1" condim="3" friction="{friction:?} 0.005 0.0001" rgba="0.75 0.78 0.85 1"/>"#,
            link.name,
            fmt_pose(&col.placement)
        );
    }
    for f in model.frames().iter().filter(|f| f.link == i) {
        let _ = writeln!(out, r#"{pad}  <site name="{}" {} size="0.01"/>"#, f.name, fmt_pose(&f.placement));
    }
    for s in &sites[i] {
        let _ = writeln!(out, r#"{pad}  <site name="{s}" size="0.005"/>"#);
    }
    for &c in &children[i] {
        write_body(model, c, children, soles, sites, q, depth + 1, out);
    }
    let _ = writeln!(out, "{pad}</body>");
}
