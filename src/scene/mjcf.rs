//! Writes a [`Scene`] into an MJCF world by filling the template `scenes/world.xml`.
//!
//! The robot is a separate fragment ([`RobotFragment`]), generated from its URDF by
//! `robot::mjcf`.

use super::{Scene, SurfaceRole};
use std::fmt::Write;

/// The world template, compiled into the binary so it runs from any folder.
pub const WORLD_TEMPLATE: &str = include_str!("../../scenes/world.xml");

/// MuJoCo geom group of the world's boxes (seen by the lidar).
pub const WORLD_GEOM_GROUP: usize = 0;
/// MuJoCo geom group of the robot's geoms (excluded from its own lidar's rays).
pub const ROBOT_GEOM_GROUP: usize = 2;
/// Name of the site that is the robot's head frame, where the lidar's servo is mounted.
pub const HEAD_SITE: &str = "head";

/// The robot's part of the MJCF: its body tree (inside `<worldbody>`) and what follows the
/// world body (actuators, sensors, contact exclusions).
#[derive(Debug, Clone, Default)]
pub struct RobotFragment {
    /// XML placed inside `<worldbody>`.
    pub body_xml: String,
    /// XML placed after `</worldbody>`.
    pub extras_xml: String,
}

/// Physics time step of generated worlds by default, seconds (1 kHz; why:
/// `crate::sim::params::PhysicsParams::step_s`).
pub const TIMESTEP_S: f64 = 0.001;

/// How a world's MJCF is built beyond its scene and robot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorldOptions {
    /// Where the boxes sit in the body tree.
    pub layout: BoxBodies,
    /// MuJoCo's time step, seconds.
    pub step_s: f64,
}

impl Default for WorldOptions {
    fn default() -> Self {
        Self { layout: BoxBodies::default(), step_s: TIMESTEP_S }
    }
}

/// Where the world's boxes sit in the MJCF's body tree. Either way MuJoCo has the same
/// geoms, finds the same contacts and computes the same physics (to rounding: the contacts
/// come in another order); what differs is the work its collision detection does per step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BoxBodies {
    /// Each box in a static body of its own (the default): MuJoCo's broadphase sorts the
    /// bodies' bounding boxes and drops the pairs that are apart, so a foot is tested only
    /// against the few boxes near it.
    #[default]
    OneEach,
    /// Every box in the world body: for each robot body whose bounding box overlaps the
    /// world body's (nearly every one, since the world body's spans the whole scene),
    /// MuJoCo walks the world body's tree of boxes (`mj_collideTree`, `mj_collideOBB`).
    /// `bench robot`'s baseline.
    InWorldBody,
}

/// The MJCF text of `scene` with `robot` in it.
pub fn world_xml(scene: &Scene, robot: &RobotFragment) -> String {
    world_xml_with(scene, robot, &WorldOptions::default())
}

/// [`world_xml`] built as `options` say.
pub fn world_xml_with(scene: &Scene, robot: &RobotFragment, options: &WorldOptions) -> String {
    // Each box's geom line, with what opens and closes around it.
    let (open, indent, close) = match options.layout {
        BoxBodies::OneEach => ("    <body>\n", "      ", "    </body>\n"),
        BoxBodies::InWorldBody => ("", "    ", ""),
    };
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
            SurfaceRole::Fixture => "0.3 0.3 0.35 1",
            SurfaceRole::Object => "0.8 0.5 0.2 1",
        };
        geoms.push_str(open);
        let _ = writeln!(
            geoms,
            r#"{indent}<geom class="world" name="{}" pos="{} {} {}" euler="0 0 {}" size="{} {} {}" friction="{} 0.005 0.0001" rgba="{}"/>"#,
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
        geoms.push_str(close);
    }
    WORLD_TEMPLATE
        .replace("{{NAME}}", &xml_escape(scene.name()))
        .replace("{{TIMESTEP_S}}", &options.step_s.to_string())
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
