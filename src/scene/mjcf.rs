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
/// Every geom's torsional and rolling friction coefficients, the second and third of its
/// `friction` (MuJoCo's defaults); the sliding one is the surface's.
pub const SPIN_ROLL_FRICTION: [f64; 2] = [0.005, 0.0001];
/// Name of the site that is the robot's head frame, where the lidar's servo is mounted.
pub const HEAD_SITE: &str = "head";

/// The robot's part of the MJCF: its body tree (inside `<worldbody>`) and what follows the
/// world body (actuators, sensors, the initial keyframe).
#[derive(Debug, Clone, Default)]
pub struct RobotFragment {
    /// XML placed inside `<worldbody>`; its soles' geoms carry [`SOLE_CONAFFINITY`] for
    /// their `conaffinity`, which the world fills ([`WorldOptions::sole_friction_timeconst_s`]).
    pub body_xml: String,
    /// XML placed after `</worldbody>`.
    pub extras_xml: String,
    /// The names of the collision geoms of the links that carry the soles.
    pub sole_geoms: Vec<String>,
}

/// The slot a robot fragment's sole geoms have for their `conaffinity`: 1 where MuJoCo
/// finds their contacts with the world itself, 0 where the world lists them as pairs.
pub const SOLE_CONAFFINITY: &str = "{{SOLE_CONAFFINITY}}";

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
    /// The time constant of the soles' friction against the world, seconds
    /// (`crate::sim::params::PhysicsParams::sole_friction_timeconst_s`): `Some`, each sole
    /// geom and world box is an explicit pair with it as `solreffriction`; `None`, MuJoCo
    /// finds the soles' contacts as any other's.
    pub sole_friction_timeconst_s: Option<f64>,
}

impl Default for WorldOptions {
    fn default() -> Self {
        Self { layout: BoxBodies::default(), step_s: TIMESTEP_S, sole_friction_timeconst_s: None }
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
            r#"{indent}<geom class="world" name="{}" pos="{} {} {}" euler="0 0 {}" size="{} {} {}" friction="{} {} {}" rgba="{}"/>"#,
            xml_escape(b.name()),
            p.x,
            p.y,
            p.z,
            yaw,
            h.x,
            h.y,
            h.z,
            b.friction(),
            SPIN_ROLL_FRICTION[0],
            SPIN_ROLL_FRICTION[1],
            rgba
        );
        geoms.push_str(close);
    }
    let mut extras = robot.extras_xml.clone();
    let conaffinity = match options.sole_friction_timeconst_s {
        Some(tc) => {
            extras.push_str(&sole_pairs(scene, &robot.sole_geoms, tc));
            "0"
        }
        None => "1",
    };
    WORLD_TEMPLATE
        .replace("{{NAME}}", &xml_escape(scene.name()))
        .replace("{{TIMESTEP_S}}", &options.step_s.to_string())
        .replace("{{WORLD_GEOMS}}", geoms.trim_end())
        .replace("{{ROBOT_BODY}}", &robot.body_xml.replace(SOLE_CONAFFINITY, conaffinity))
        .replace("{{ROBOT_EXTRAS}}", &extras)
}

/// Each of `soles` (geom names) against each of `scene`'s boxes as an explicit contact pair
/// whose friction converges with time constant `timeconst_s`: what MuJoCo would make of the
/// pair itself (the box's friction, condim 3, its default solver parameters, as the world
/// geoms' priority gives them) but for `solreffriction`, which only a pair can set.
fn sole_pairs(scene: &Scene, soles: &[String], timeconst_s: f64) -> String {
    let mut out = String::from("\n  <contact>\n");
    let [spin, roll] = SPIN_ROLL_FRICTION;
    for sole in soles {
        for b in scene.boxes() {
            let mu = b.friction();
            let _ = writeln!(
                out,
                r#"    <pair geom1="{}" geom2="{}" condim="3" friction="{mu} {mu} {spin} {roll} {roll}" solreffriction="{timeconst_s:?} 1"/>"#,
                xml_escape(sole),
                xml_escape(b.name())
            );
        }
    }
    out.push_str("  </contact>");
    out
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
        .replace('\'', "&apos;")
}
