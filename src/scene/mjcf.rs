//! Writes a [`Scene`] into an MJCF world by filling the template `scenes/world.xml`.
//!
//! The robot is a separate fragment ([`RobotFragment`]): the HRP-4-class model when it is
//! available, or a static stand-in of the robot's size with a `head` site, so the lidar can be
//! mounted and its self-exclusion tested before the robot model exists.

use super::{Scene, SurfaceRole};
use nalgebra::Isometry3;
use std::fmt::Write;

/// The world template, compiled into the binary so it runs from any folder.
pub const WORLD_TEMPLATE: &str = include_str!("../../scenes/world.xml");

/// MuJoCo geom group of the world's boxes (seen by the lidar).
pub const WORLD_GEOM_GROUP: usize = 0;
/// MuJoCo geom group of the robot's geoms (excluded from its own lidar's rays).
pub const ROBOT_GEOM_GROUP: usize = 2;
/// Name of the site that is the robot's head frame, where the lidar's servo is mounted.
pub const HEAD_SITE: &str = "head";

/// Height of the stand-in's head frame above the floor, metres (about HRP-4's neck in
/// half-sitting; the lidar's default mount puts the optical centre near 1.40 m).
pub const STAND_IN_HEAD_HEIGHT_M: f64 = 1.30;

/// The robot's part of the MJCF: its body tree (inside `<worldbody>`) and what follows the
/// world body (actuators, sensors, contact exclusions).
#[derive(Debug, Clone, Default)]
pub struct RobotFragment {
    /// XML placed inside `<worldbody>`.
    pub body_xml: String,
    /// XML placed after `</worldbody>`.
    pub extras_xml: String,
}

impl RobotFragment {
    /// A static box of HRP-4's size with a `head` site, standing at `start` (geom group 2).
    pub fn stand_in(start: &Isometry3<f64>) -> Self {
        let (x, y, z) = (start.translation.x, start.translation.y, start.translation.z);
        let (_, _, yaw) = start.rotation.euler_angles();
        let h = STAND_IN_HEAD_HEIGHT_M;
        let body_xml = format!(
            r#"    <body name="robot_stand_in" pos="{x} {y} {z}" euler="0 0 {yaw}">
      <geom name="stand_in_legs" type="box" size="0.12 0.16 0.40" pos="0 0 0.40" group="{g}" contype="0" conaffinity="0" rgba="0.3 0.5 0.8 1"/>
      <geom name="stand_in_torso" type="box" size="0.12 0.22 0.27" pos="0 0 1.07" group="{g}" contype="0" conaffinity="0" rgba="0.3 0.5 0.8 1"/>
      <geom name="stand_in_head" type="sphere" size="0.10" pos="0 0 {hz}" group="{g}" contype="0" conaffinity="0" rgba="0.3 0.5 0.8 1"/>
      <site name="{HEAD_SITE}" pos="0 0 {h}"/>
    </body>"#,
            g = ROBOT_GEOM_GROUP,
            hz = h + 0.05,
        );
        Self { body_xml, extras_xml: String::new() }
    }
}

/// Physics time step of generated worlds, seconds (1 kHz).
pub const TIMESTEP_S: f64 = 0.001;

/// The MJCF text of `scene` with `robot` in it.
pub fn world_xml(scene: &Scene, robot: &RobotFragment) -> String {
    let mut geoms = String::new();
    for b in scene.boxes() {
        let p = b.pose().translation.vector;
        let (_, _, yaw) = b.pose().rotation.euler_angles();
        let h = b.half_extents_m();
        let rgba = match b.role() {
            SurfaceRole::Floor => "0.55 0.55 0.5 1",
            SurfaceRole::Wall | SurfaceRole::Ceiling => "0.8 0.8 0.78 0.3",
            SurfaceRole::Step(_) => "0.65 0.45 0.3 1",
            SurfaceRole::Clutter => "0.4 0.6 0.4 1",
        };
        let _ = writeln!(
            geoms,
            r#"    <geom class="world" name="{}" pos="{} {} {}" euler="0 0 {}" size="{} {} {}" friction="{} 0.005 0.0001" rgba="{}"/>"#,
            xml_escape(b.name()),
            p.x,
            p.y,
            p.z,
            yaw,
            h.x,
            h.y,
            h.z,
            b.friction(),
            rgba
        );
    }
    WORLD_TEMPLATE
        .replace("{{NAME}}", &xml_escape(scene.name()))
        .replace("{{TIMESTEP_S}}", &TIMESTEP_S.to_string())
        .replace("{{WORLD_GEOMS}}", geoms.trim_end())
        .replace("{{ROBOT_BODY}}", &robot.body_xml)
        .replace("{{ROBOT_EXTRAS}}", &robot.extras_xml)
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
        .replace('\'', "&apos;")
}
