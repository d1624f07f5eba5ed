//! Clearance of the legs from the steps. §6.1 adds its posture term "to prevent the robot
//! from accidentally touching the following staircase steps"; on this model that is not
//! enough: with 27 cm treads the shank of the leg on a step leans into the next riser's nose,
//! and the trailing shank into the nose it climbs past. So the planner keeps every leg
//! capsule (thigh, shank) a set distance from the steps: the steps are the rectangles
//! extruded down to below the feet ([`step_blocks`]), [`nearest`] finds a capsule's closest
//! block with the distance and its direction, the IK turns that into a velocity damper
//! (`ik::clearance`), and tracking refuses a trajectory whose legs touch a step.

use crate::perception::PlaneSegment;
use crate::robot::model::{RobotModel, Shape};
use crate::robot::Kinematics;
use crate::scene::{SceneBox, SurfaceRole};
use nalgebra::{Point3, Vector3};

/// A leg link's collision capsule: its axis from `a` to `b` in the link's frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Limb {
    /// The link it belongs to.
    pub link: usize,
    /// The link's name (for messages).
    pub name: String,
    a: Point3<f64>,
    b: Point3<f64>,
    /// Capsule radius, metres.
    pub radius_m: f64,
}

impl Limb {
    /// The ends of the capsule's axis, world frame, at the configuration `kin` holds.
    pub fn axis_world(&self, kin: &Kinematics) -> (Point3<f64>, Point3<f64>) {
        let pose = kin.link_pose(self.link);
        (pose * self.a, pose * self.b)
    }
}

/// The capsules (cylinder collisions, capsules in the simulator) of the links on the chains
/// from the root to `feet` (frames), root excluded.
pub fn limbs(model: &RobotModel, feet: &[usize]) -> Vec<Limb> {
    let mut out = Vec::new();
    for &f in feet {
        let mut link = Some(model.frames()[f].link);
        while let Some(l) = link {
            let parent = model.links()[l].parent;
            if parent.is_none() {
                break;
            }
            for c in &model.links()[l].collisions {
                if let Shape::Cylinder { radius_m, length_m } = c.shape {
                    let half = Vector3::z() * (length_m / 2.0);
                    out.push(Limb {
                        link: l,
                        name: model.links()[l].name.clone(),
                        a: c.placement * Point3::from(half),
                        b: c.placement * Point3::from(-half),
                        radius_m,
                    });
                }
            }
            link = parent;
        }
    }
    out
}

/// Each step rectangle as a solid box from its top (its highest corner) down to `bottom_z`.
pub fn step_blocks(rects: &[PlaneSegment], bottom_z: f64) -> Vec<SceneBox> {
    rects
        .iter()
        .enumerate()
        .filter_map(|(i, r)| {
            let top = r.corners().iter().map(|c| c.z).fold(f64::NEG_INFINITY, f64::max);
            let c = r.center();
            let along = r.along();
            let half_height = (top - bottom_z) / 2.0;
            (half_height > 0.0).then(|| {
                SceneBox::new(
                    &format!("step_{}", i + 1),
                    SurfaceRole::Step(i),
                    Point3::new(c.x, c.y, bottom_z + half_height),
                    Vector3::new(r.depth_m() / 2.0, r.width_m() / 2.0, half_height),
                    along.y.atan2(along.x),
                    0.0,
                )
            })
        })
        .collect()
}

/// A capsule's closest block.
#[derive(Debug, Clone, PartialEq)]
pub struct Nearest {
    /// Index of the block.
    pub block: usize,
    /// Distance from the capsule's surface to the block, metres (negative: they overlap).
    pub clearance_m: f64,
    /// The point of the capsule's axis nearest the block, world frame.
    pub point: Point3<f64>,
    /// Unit direction, world frame, in which moving `point` increases the clearance.
    pub normal: Vector3<f64>,
}

/// The block nearest to `limb` at the configuration `kin` holds; `None` when no block is
/// within `range_m` of the capsule (or there are no blocks).
pub fn nearest(kin: &Kinematics, limb: &Limb, blocks: &[SceneBox], range_m: f64) -> Option<Nearest> {
    let (a, b) = limb.axis_world(kin);
    let half_length = (b - a).norm() / 2.0;
    let middle = Point3::from((a.coords + b.coords) / 2.0);
    let mut best: Option<Nearest> = None;
    for (i, block) in blocks.iter().enumerate() {
        // A block farther from the middle than half the axis plus the range cannot be near.
        if block.signed_distance(&middle) > half_length + limb.radius_m + range_m {
            continue;
        }
        let t = minimize_on_unit(|t| block.signed_distance(&a.lerp(&b, t)));
        let point = a.lerp(&b, t);
        let (d, normal) = block.signed_distance_and_normal(&point);
        let clearance_m = d - limb.radius_m;
        if clearance_m <= range_m && best.as_ref().is_none_or(|n| clearance_m < n.clearance_m) {
            best = Some(Nearest { block: i, clearance_m, point, normal });
        }
    }
    best
}

/// The minimum of a convex function on [0, 1] (golden-section search to 1e-6). A box's
/// signed distance along a segment is convex, so this finds the segment's nearest point.
fn minimize_on_unit(f: impl Fn(f64) -> f64) -> f64 {
    const INV_PHI: f64 = 0.618_033_988_749_895;
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    let mut x1 = hi - INV_PHI * (hi - lo);
    let mut x2 = lo + INV_PHI * (hi - lo);
    let (mut f1, mut f2) = (f(x1), f(x2));
    while hi - lo > 1e-6 {
        if f1 <= f2 {
            hi = x2;
            x2 = x1;
            f2 = f1;
            x1 = hi - INV_PHI * (hi - lo);
            f1 = f(x1);
        } else {
            lo = x1;
            x1 = x2;
            f1 = f2;
            x2 = lo + INV_PHI * (hi - lo);
            f2 = f(x2);
        }
    }
    // The ends are candidates too (a monotone function's minimum sits there).
    let mid = (lo + hi) / 2.0;
    [0.0, mid, 1.0].into_iter().fold(mid, |best, t| if f(t) < f(best) { t } else { best })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn golden_section_finds_the_minimum_of_a_convex_function() {
        assert!((minimize_on_unit(|t| (t - 0.3) * (t - 0.3)) - 0.3).abs() < 1e-5);
        assert_eq!(minimize_on_unit(|t| t), 0.0);
        assert_eq!(minimize_on_unit(|t| -t), 1.0);
    }

    #[test]
    fn a_block_is_the_rectangle_extruded_down() {
        let r = PlaneSegment::new(Point3::new(1.0, 0.0, 0.2), Vector3::y(), 0.27, 0.5, Vector3::z(), 1)
            .expect("valid rectangle");
        let blocks = step_blocks(&[r], -0.1);
        assert_eq!(blocks.len(), 1);
        let b = &blocks[0];
        // Ascending along +y: 27 cm deep in y, 50 cm wide in x, from z = -0.1 to 0.2.
        assert!(b.signed_distance(&Point3::new(1.0, 0.0, 0.05)) < -0.1);
        assert!((b.signed_distance(&Point3::new(1.0, 0.135 + 0.01, 0.0)) - 0.01).abs() < 1e-9);
        assert!((b.signed_distance(&Point3::new(1.25 + 0.02, 0.0, 0.0)) - 0.02).abs() < 1e-9);
        assert!((b.signed_distance(&Point3::new(1.0, 0.0, 0.25)) - 0.05).abs() < 1e-9);
    }
}
