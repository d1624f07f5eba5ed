//! The world of a scenario as geometry: every solid box (floor, walls, ceiling, steps,
//! clutter) and the ground truth the bench measures against (each step's top rectangle).
//!
//! A [`Scene`] is built from a validated [`Scenario`] and is the only input of the MJCF writer
//! ([`mjcf`]), so the simulator and the ground truth can never disagree.

pub mod geometry;
pub mod mjcf;

use crate::scenario::{Scenario, ScenarioError};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector2, Vector3};

pub use geometry::{SceneBox, StepTop, SurfaceRole};

/// Thickness of the floor, wall and ceiling slabs, metres.
const SLAB_M: f64 = 0.1;

/// A scenario turned into boxes and ground truth. Valid once built.
#[derive(Debug, Clone)]
pub struct Scene {
    name: String,
    boxes: Vec<SceneBox>,
    steps: Vec<StepTop>,
    ascent_yaw_rad: f64,
    robot_start: Isometry3<f64>,
}

impl Scene {
    /// Builds the scene of a scenario (validated again here, so a hand-edited `Scenario`
    /// cannot produce a broken world).
    pub fn from_scenario(s: &Scenario) -> Result<Self, ScenarioError> {
        s.validate().map_err(|i| i.locate(&s.name, ""))?;
        let mut boxes = Vec::new();
        let r = &s.room;
        let [sx, sy, sz] = r.size_m;
        let c = Vector2::new(r.center_m[0], r.center_m[1]);
        let at = |x: f64, y: f64, z: f64| Point3::new(c.x + x, c.y + y, z);
        let floor_half = Vector3::new(sx / 2.0 + SLAB_M, sy / 2.0 + SLAB_M, SLAB_M / 2.0);
        boxes.push(SceneBox::new(
            "floor",
            SurfaceRole::Floor,
            at(0.0, 0.0, -SLAB_M / 2.0),
            floor_half,
            0.0,
            r.floor_friction,
        ));
        if r.walls {
            let h = sz / 2.0;
            let wx = Vector3::new(SLAB_M / 2.0, sy / 2.0 + SLAB_M, h);
            let wy = Vector3::new(sx / 2.0 + SLAB_M, SLAB_M / 2.0, h);
            let off_x = sx / 2.0 + SLAB_M / 2.0;
            let off_y = sy / 2.0 + SLAB_M / 2.0;
            boxes.push(SceneBox::new("wall_front", SurfaceRole::Wall, at(off_x, 0.0, h), wx, 0.0, 0.5));
            boxes.push(SceneBox::new("wall_back", SurfaceRole::Wall, at(-off_x, 0.0, h), wx, 0.0, 0.5));
            boxes.push(SceneBox::new("wall_left", SurfaceRole::Wall, at(0.0, off_y, h), wy, 0.0, 0.5));
            boxes.push(SceneBox::new("wall_right", SurfaceRole::Wall, at(0.0, -off_y, h), wy, 0.0, 0.5));
        }
        if r.ceiling {
            boxes.push(SceneBox::new(
                "ceiling",
                SurfaceRole::Ceiling,
                at(0.0, 0.0, sz + SLAB_M / 2.0),
                floor_half,
                0.0,
                0.5,
            ));
        }

        let st = &s.staircase;
        let yaw = st.yaw_rad();
        let along = Vector2::new(yaw.cos(), yaw.sin());
        let start = Vector2::new(st.start_m[0], st.start_m[1]);
        let mut steps = Vec::new();
        for i in 0..st.steps as usize {
            if st.missing_steps.contains(&(i as u32 + 1)) {
                continue;
            }
            let depth = st.tread_m + if i + 1 == st.steps as usize { st.landing_m } else { 0.0 };
            let top = st.rise_m * (i + 1) as f64;
            let mid = start + along * (st.tread_m * i as f64 + depth / 2.0);
            let half = Vector3::new(depth / 2.0, st.width_m / 2.0, top / 2.0);
            let centre = Point3::new(mid.x, mid.y, top / 2.0);
            let b = SceneBox::new(
                &format!("step_{}", i + 1),
                SurfaceRole::Step(i),
                centre,
                half,
                yaw,
                st.friction,
            );
            steps.push(StepTop::of_box(i, &b));
            boxes.push(b);
        }
        for (i, b) in s.boxes.iter().enumerate() {
            // The scenario's own names get a prefix with the box's number: they can never
            // collide with each other or with the generator's (`floor`, `wall_left`,
            // `step_1`, ...), which MuJoCo would refuse.
            let name = if b.name.is_empty() {
                format!("box_{}", i + 1)
            } else {
                format!("box_{}_{}", i + 1, b.name)
            };
            let half = Vector3::from(b.size_m) / 2.0;
            boxes.push(SceneBox::new(
                &name,
                SurfaceRole::Clutter,
                Point3::from(b.center_m),
                half,
                b.yaw_deg.to_radians(),
                0.7,
            ));
        }
        let robot_start = Isometry3::from_parts(
            Translation3::new(s.robot.position_m[0], s.robot.position_m[1], 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, s.robot.yaw_deg.to_radians()),
        );
        Ok(Self { name: s.name.clone(), boxes, steps, ascent_yaw_rad: yaw, robot_start })
    }

    /// A world built from perceived steps, for rehearsing a plan before the real robot moves
    /// (`run --hardware`): a floor, and under each rectangle a solid box from the floor to it,
    /// turned with it; the robot at the origin facing +x (the frame the hardware path
    /// perceives in). The rectangles are the ground truth the checks judge by. No walls, no
    /// ceiling: only what perception saw stands there.
    pub fn rehearsal(name: &str, steps: &[crate::perception::PlaneSegment], friction: f64) -> Self {
        let mut boxes = Vec::new();
        let extent = steps
            .iter()
            .flat_map(|s| s.corners().iter().map(|c| c.x.abs().max(c.y.abs())))
            .fold(3.0_f64, f64::max)
            + 2.0;
        boxes.push(SceneBox::new(
            "floor",
            SurfaceRole::Floor,
            Point3::new(0.0, 0.0, -SLAB_M / 2.0),
            Vector3::new(extent, extent, SLAB_M / 2.0),
            0.0,
            0.8,
        ));
        let mut tops = Vec::new();
        let mut by_height: Vec<&crate::perception::PlaneSegment> = steps.iter().collect();
        by_height.sort_by(|a, b| a.height_m().total_cmp(&b.height_m()));
        for (i, r) in by_height.iter().enumerate() {
            let (c, along, h) = (r.center(), r.along(), r.height_m().max(0.005));
            let b = SceneBox::new(
                &format!("step_{}", i + 1),
                SurfaceRole::Step(i),
                Point3::new(c.x, c.y, h / 2.0),
                Vector3::new(r.depth_m() / 2.0, r.width_m() / 2.0, h / 2.0),
                along.y.atan2(along.x),
                friction,
            );
            tops.push(StepTop::of_box(i, &b));
            boxes.push(b);
        }
        let ascent_yaw_rad = by_height.first().map_or(0.0, |r| r.along().y.atan2(r.along().x));
        Self {
            name: name.to_string(),
            boxes,
            steps: tops,
            ascent_yaw_rad,
            robot_start: Isometry3::identity(),
        }
    }

    /// The scenario's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Every solid box of the world (floor, walls, ceiling, steps, clutter).
    pub fn boxes(&self) -> &[SceneBox] {
        &self.boxes
    }

    /// Ground truth: the top rectangle of each step, nearest first.
    pub fn steps(&self) -> &[StepTop] {
        &self.steps
    }

    /// Direction of ascent, radians about +z.
    pub fn ascent_yaw_rad(&self) -> f64 {
        self.ascent_yaw_rad
    }

    /// The robot's start: the floor point between its feet, heading along +x of this frame.
    pub fn robot_start(&self) -> Isometry3<f64> {
        self.robot_start
    }

    /// Distance from `p` to the nearest box surface (negative when inside a box), metres.
    pub fn signed_distance(&self, p: &Point3<f64>) -> f64 {
        self.boxes.iter().map(|b| b.signed_distance(p)).fold(f64::INFINITY, f64::min)
    }
}
