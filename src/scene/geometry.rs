//! Boxes of the world and the step rectangles of the ground truth.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

/// What a box is in the world; steps carry their index (0 = nearest the start).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SurfaceRole {
    /// The floor slab (its top at z = 0).
    Floor,
    /// A room wall.
    Wall,
    /// The ceiling slab.
    Ceiling,
    /// A step of the staircase.
    Step(usize),
    /// An extra box from the scenario.
    Clutter,
    /// A fixed part of the staircase that is not a tread: a handrail or its posts.
    Fixture,
    /// Something left on a tread or the floor (the scenario's `[[objects]]`).
    Object,
}

/// A solid box with a yaw about +z. Valid once built: finite pose, positive extents.
#[derive(Debug, Clone)]
pub struct SceneBox {
    name: String,
    role: SurfaceRole,
    pose: Isometry3<f64>,
    half_extents_m: Vector3<f64>,
    friction: f64,
}

impl SceneBox {
    /// A box centred at `center`, of half extents `half_extents_m`, turned by `yaw_rad`.
    pub fn new(
        name: &str,
        role: SurfaceRole,
        center: Point3<f64>,
        half_extents_m: Vector3<f64>,
        yaw_rad: f64,
        friction: f64,
    ) -> Self {
        let pose = Isometry3::from_parts(
            Translation3::from(center.coords),
            UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_rad),
        );
        Self { name: name.to_string(), role, pose, half_extents_m, friction }
    }

    /// The box's name (also its MJCF geom name).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// What the box is.
    pub fn role(&self) -> SurfaceRole {
        self.role
    }

    /// Pose of the box's centre in the world.
    pub fn pose(&self) -> &Isometry3<f64> {
        &self.pose
    }

    /// Half extents along the box's own axes, metres.
    pub fn half_extents_m(&self) -> &Vector3<f64> {
        &self.half_extents_m
    }

    /// Coulomb friction coefficient of its surfaces.
    pub fn friction(&self) -> f64 {
        self.friction
    }

    /// Signed distance from `p` to the box's surface: positive outside, negative inside.
    pub fn signed_distance(&self, p: &Point3<f64>) -> f64 {
        self.signed_distance_and_normal(p).0
    }

    /// Signed distance from `p` (as [`Self::signed_distance`]) and its gradient: the unit
    /// direction, world frame, in which the distance grows fastest (out of the box through
    /// the nearest face, edge or corner).
    pub fn signed_distance_and_normal(&self, p: &Point3<f64>) -> (f64, Vector3<f64>) {
        let local = self.pose.inverse_transform_point(p);
        let q = local.coords.abs() - self.half_extents_m;
        let sign = local.coords.map(|v| if v < 0.0 { -1.0 } else { 1.0 });
        let out = q.map(|v| v.max(0.0));
        let outside = out.norm();
        let (distance, gradient_local) = if outside > 0.0 {
            (outside, out.component_mul(&sign) / outside)
        } else {
            // Inside: through the face nearest to p.
            let axis = q.imax();
            (q[axis], Vector3::ith(axis, sign[axis]))
        };
        (distance, self.pose.rotation * gradient_local)
    }
}

/// A sole stands on a true tread when its height is within this of the tread's, metres: its
/// sink into the contact and the ankle's give are millimetres, a step's rise over 10 cm.
pub const SOLE_ON_TREAD_M: f64 = 0.02;

/// Ground truth of one step: the rectangle of its top (tread), in the world frame.
#[derive(Debug, Clone, PartialEq)]
pub struct StepTop {
    /// 0 for the step nearest the start.
    pub index: usize,
    /// Corners counter-clockwise seen from above: front-right, back-right, back-left,
    /// front-left ("front" is the nose, the side the robot comes from).
    pub corners: [Point3<f64>; 4],
    /// Height of the tread above the floor, metres.
    pub height_m: f64,
    /// Depth along the direction of ascent, metres.
    pub depth_m: f64,
    /// Width across the direction of ascent, metres.
    pub width_m: f64,
}

impl StepTop {
    /// The top face of a step box.
    pub fn of_box(index: usize, b: &SceneBox) -> Self {
        let h = b.half_extents_m();
        let corner = |sx: f64, sy: f64| b.pose().transform_point(&Point3::new(sx * h.x, sy * h.y, h.z));
        Self {
            index,
            corners: [corner(-1.0, -1.0), corner(1.0, -1.0), corner(1.0, 1.0), corner(-1.0, 1.0)],
            height_m: b.pose().translation.z + h.z,
            depth_m: 2.0 * h.x,
            width_m: 2.0 * h.y,
        }
    }

    /// Centre of the tread.
    pub fn center(&self) -> Point3<f64> {
        Point3::from(self.corners.iter().map(|c| c.coords).sum::<Vector3<f64>>() / 4.0)
    }

    /// Area of the tread, square metres.
    pub fn area_m2(&self) -> f64 {
        self.depth_m * self.width_m
    }

    /// How far the horizontal projection of `p` lies outside the tread, metres, along its
    /// axes (negative inside: minus the distance to the nearest edge).
    pub fn outside_m(&self, p: &Point3<f64>) -> f64 {
        let o = self.corners[0];
        let u = (self.corners[1] - o).normalize();
        let v = (self.corners[3] - o).normalize();
        let d = p - o;
        let (a, b) = (d.dot(&u), d.dot(&v));
        (-a).max(a - self.depth_m).max(-b).max(b - self.width_m)
    }

    /// Whether the horizontal projection of `p` falls on the tread (with `margin_m` inside).
    pub fn contains_xy(&self, p: &Point3<f64>, margin_m: f64) -> bool {
        self.outside_m(p) <= -margin_m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn signed_distance_of_a_turned_box() {
        let b = SceneBox::new(
            "b",
            SurfaceRole::Clutter,
            Point3::new(1.0, 0.0, 0.5),
            Vector3::new(0.5, 0.25, 0.5),
            std::f64::consts::FRAC_PI_2,
            0.7,
        );
        // turned by 90 degrees: extends 0.25 along x and 0.5 along y
        assert!((b.signed_distance(&Point3::new(1.0, 0.0, 0.5)) + 0.25).abs() < 1e-12);
        assert!((b.signed_distance(&Point3::new(1.5, 0.0, 0.5)) - 0.25).abs() < 1e-12);
        assert!((b.signed_distance(&Point3::new(1.0, 0.7, 0.5)) - 0.2).abs() < 1e-12);
        assert!((b.signed_distance(&Point3::new(1.0, 0.0, 1.3)) - 0.3).abs() < 1e-12);
        // Gradients: out through the nearest face, numerically checked at an edge.
        let (d, n) = b.signed_distance_and_normal(&Point3::new(1.0, 0.0, 0.5));
        assert!((d + 0.25).abs() < 1e-12 && n.z.abs() < 1e-12 && (n.norm() - 1.0).abs() < 1e-12);
        let p = Point3::new(1.4, 0.9, 1.2);
        let (_, n) = b.signed_distance_and_normal(&p);
        let h = 1e-6;
        let numeric = Vector3::from_fn(|i, _| {
            let e = Vector3::ith(i, h);
            (b.signed_distance(&(p + e)) - b.signed_distance(&(p - e))) / (2.0 * h)
        });
        assert!((numeric - n).norm() < 1e-6, "{numeric} vs {n}");
    }
}
