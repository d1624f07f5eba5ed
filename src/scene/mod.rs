//! The world of a scenario as geometry: every solid box (floor, walls, ceiling, steps,
//! clutter) and the ground truth the bench measures against (each step's top rectangle).
//!
//! A [`Scene`] is built from a validated [`Scenario`] and is the only input of the MJCF writer
//! ([`mjcf`]), so the simulator and the ground truth can never disagree.

pub mod geometry;
pub mod mjcf;

use crate::scenario::{Risers, Scenario, ScenarioError};
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

        let (flight, steps) = flight_boxes(s);
        boxes.extend(flight);
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
        for (i, o) in s.objects.iter().enumerate() {
            let name = if o.name.is_empty() {
                format!("object_{}", i + 1)
            } else {
                format!("object_{}_{}", i + 1, o.name)
            };
            let (corners, base_z_m) = o.placed(&s.staircase);
            let centre = Point3::new(
                corners.iter().map(|c| c[0]).sum::<f64>() / 4.0,
                corners.iter().map(|c| c[1]).sum::<f64>() / 4.0,
                base_z_m + o.size_m[2] / 2.0,
            );
            let yaw = s.staircase.yaw_rad() + o.yaw_deg.to_radians();
            boxes.push(SceneBox::new(
                &name,
                SurfaceRole::Object,
                centre,
                Vector3::from(o.size_m) / 2.0,
                yaw,
                0.7,
            ));
        }
        let yaw = s.staircase.yaw_rad();
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
    pub fn rehearsal(name: &str, steps: &[PerceivedTop], friction: f64) -> Self {
        let mut boxes = Vec::new();
        let extent = steps
            .iter()
            .flat_map(|s| s.corners.iter().map(|c| c.x.abs().max(c.y.abs())))
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
        let mut by_height: Vec<&PerceivedTop> = steps.iter().collect();
        by_height.sort_by(|a, b| a.height_m.total_cmp(&b.height_m));
        for (i, r) in by_height.iter().enumerate() {
            let (c, along, h) = (r.center(), r.along(), r.height_m.max(0.005));
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

/// A perceived step's top rectangle, as [`Scene::rehearsal`] builds a box under it: its
/// corners (front edge first, corners 0 to 1 along the ascent, 0 to 3 across, as perception
/// gives them) and its height, metres.
#[derive(Debug, Clone, PartialEq)]
pub struct PerceivedTop {
    /// The rectangle's corners.
    pub corners: [Point3<f64>; 4],
    /// Its height above the floor.
    pub height_m: f64,
}

impl PerceivedTop {
    fn center(&self) -> Point3<f64> {
        Point3::from(self.corners.iter().map(|c| c.coords).sum::<Vector3<f64>>() / 4.0)
    }

    fn along(&self) -> Vector3<f64> {
        (self.corners[1] - self.corners[0]).normalize()
    }

    fn depth_m(&self) -> f64 {
        (self.corners[1] - self.corners[0]).norm()
    }

    fn width_m(&self) -> f64 {
        (self.corners[3] - self.corners[0]).norm()
    }
}

/// Cross-section of a handrail's bar, metres (a 5 cm bar).
pub const RAIL_M: f64 = 0.05;
/// Cross-section of its posts, metres (4 cm balusters).
const POST_M: f64 = 0.04;
/// How far a handrail (its bar's middle, its posts) stands in from the flight's side, metres.
pub const RAIL_INSET_M: f64 = 0.05;

/// The staircase's boxes (steps, nosings, slabs, handrails) and each present step's tread,
/// the ground truth: the rectangle a foot can stand on, from its nose to the next riser.
fn flight_boxes(s: &Scenario) -> (Vec<SceneBox>, Vec<StepTop>) {
    let st = &s.staircase;
    let yaw = st.yaw_rad();
    let along = Vector2::new(yaw.cos(), yaw.sin());
    let left = Vector2::new(-yaw.sin(), yaw.cos());
    let start = Vector2::new(st.start_m[0], st.start_m[1]);
    // A box spanning [a0, a1] along the ascent, [w0, w1] across and [z0, z1] up.
    let block =
        |name: String, role: SurfaceRole, [a0, a1]: [f64; 2], [w0, w1]: [f64; 2], [z0, z1]: [f64; 2], mu| {
            let mid = start + along * ((a0 + a1) / 2.0) + left * ((w0 + w1) / 2.0);
            let half = Vector3::new((a1 - a0) / 2.0, (w1 - w0) / 2.0, (z1 - z0) / 2.0);
            SceneBox::new(&name, role, Point3::new(mid.x, mid.y, (z0 + z1) / 2.0), half, yaw, mu)
        };
    let (mut boxes, mut tops) = (Vec::new(), Vec::new());
    let half_w = st.width_m / 2.0;
    let layout = st.layout();
    for step in layout.iter().filter(|l| !l.missing) {
        let (i, top) = (step.index, step.height_m);
        let (nose, riser, back) = (step.nose_m(st.nosing_m), step.riser_m, step.riser_m + step.going_m);
        let role = SurfaceRole::Step(i);
        let name = format!("step_{}", i + 1);
        let width = [-half_w, half_w];
        let tread = match st.risers {
            Risers::Closed if st.nosing_m <= 0.0 => {
                block(name, role, [riser, back], width, [0.0, top], step.friction)
            }
            Risers::Closed => {
                let board = st.nosing_thickness_m;
                boxes.push(block(
                    name.clone(),
                    role,
                    [riser, back],
                    width,
                    [0.0, top - board],
                    step.friction,
                ));
                block(format!("{name}_tread"), role, [nose, back], width, [top - board, top], step.friction)
            }
            Risers::Open => {
                block(name, role, [nose, back], width, [top - st.tread_thickness_m, top], step.friction)
            }
        };
        tops.push(StepTop::of_box(i, &tread));
        boxes.push(tread);
        for &side in st.handrails.sides() {
            let w = side * (half_w - RAIL_INSET_M);
            let across = [w - RAIL_M / 2.0, w + RAIL_M / 2.0];
            let rail_top = top + st.handrail_height_m;
            let end = if step.index + 1 == layout.len() { back } else { nose + st.tread_of(i) };
            let tag = if side > 0.0 { "left" } else { "right" };
            boxes.push(block(
                format!("handrail_{tag}_{}", i + 1),
                SurfaceRole::Fixture,
                [nose, end],
                across,
                [rail_top - RAIL_M, rail_top],
                0.5,
            ));
            let every = st.handrail_post_every as usize;
            let post_here = if every == 0 { i == 0 || i + 1 == layout.len() } else { i % every == 0 };
            if post_here {
                let a = nose + (RAIL_INSET_M + POST_M / 2.0).min(st.tread_of(i) / 2.0);
                boxes.push(block(
                    format!("post_{tag}_{}", i + 1),
                    SurfaceRole::Fixture,
                    [a - POST_M / 2.0, a + POST_M / 2.0],
                    [w - POST_M / 2.0, w + POST_M / 2.0],
                    [top, rail_top - RAIL_M],
                    0.5,
                ));
            }
        }
    }
    (boxes, tops)
}
