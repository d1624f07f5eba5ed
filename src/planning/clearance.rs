//! Clearance of the legs from the steps. §6.1 adds its posture term "to prevent the robot
//! from accidentally touching the following staircase steps"; on this model that is not
//! enough: with 27 cm treads the shank of the leg on a step leans into the next riser's nose,
//! and the trailing shank into the nose it climbs past. So the planner keeps every leg
//! capsule (thigh, shank) a set distance from the steps: the steps are the rectangles
//! extruded down to below the feet ([`step_blocks`]), [`nearest`] finds a capsule's closest
//! block with the distance and its direction, the IK turns that into a velocity damper
//! (`ik::clearance`), and tracking refuses a trajectory whose legs touch a step.
//!
//! The rest of the body (arms, trunk, head) is kept off every surface the lidar saw
//! ([`SeenPoints`], from `perception::surroundings`): a stairwell's walls, a crate beside
//! the flight. The legs (thigh, shank, and so the knee between them) are kept off the same
//! surfaces except the steps' and the floor's own ([`SeenPoints::off_the_steps`]): their
//! feet stand on those, and the step solids keep the legs off them already; a parcel on a
//! tread or a box beside a lane is kept off. The soles are kept off what stands on the floor
//! and the treads by the footholds (`footholds`' obstruction test), not here: a foot's box
//! is no capsule.

use crate::geom3d::Capsule;
use crate::perception::PlaneSegment;
use crate::robot::model::{Collision, RobotModel, Shape};
use crate::robot::Kinematics;
use crate::scene::{SceneBox, SurfaceRole};
use nalgebra::{Point3, Vector3};

/// A link's collision shape as a capsule: its axis from `a` to `b` in the link's frame.
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

    /// The capsule in the world frame, at the configuration `kin` holds.
    pub fn capsule(&self, kin: &Kinematics) -> Capsule {
        let (a, b) = self.axis_world(kin);
        Capsule { a, b, radius_m: self.radius_m }
    }

    /// The capsule of a link's collision shape: a cylinder's own (the simulator makes it a
    /// capsule), a sphere's, or the one around a box (along its longest edge, the radius
    /// reaching the far corners of its cross-section).
    fn of(model: &RobotModel, link: usize, c: &Collision) -> Self {
        let (half, radius_m) = match c.shape {
            Shape::Cylinder { radius_m, length_m } => (Vector3::z() * (length_m / 2.0), radius_m),
            Shape::Sphere(r) => (Vector3::zeros(), r),
            Shape::Box(size) => {
                let long = (0..3).max_by(|&i, &j| size[i].total_cmp(&size[j])).unwrap_or(2);
                let r2: f64 = (0..3).filter(|&i| i != long).map(|i| (size[i] / 2.0).powi(2)).sum();
                (Vector3::ith(long, size[long] / 2.0), r2.sqrt())
            }
        };
        Limb {
            link,
            name: model.links()[link].name.clone(),
            a: c.placement * Point3::from(half),
            b: c.placement * Point3::from(-half),
            radius_m,
        }
    }
}

/// The links on the chains from the root to `feet` (frames), root excluded.
fn leg_links(model: &RobotModel, feet: &[usize]) -> Vec<usize> {
    let mut out = Vec::new();
    for &f in feet {
        let mut link = Some(model.frames()[f].link);
        while let Some(l) = link {
            let parent = model.links()[l].parent;
            if parent.is_none() {
                break;
            }
            out.push(l);
            link = parent;
        }
    }
    out
}

/// The capsules (cylinder collisions, capsules in the simulator) of the links on the chains
/// from the root to `feet` (frames), root excluded.
pub fn limbs(model: &RobotModel, feet: &[usize]) -> Vec<Limb> {
    leg_links(model, feet)
        .into_iter()
        .flat_map(|l| {
            model.links()[l]
                .collisions
                .iter()
                .filter(|c| matches!(c.shape, Shape::Cylinder { .. }))
                .map(move |c| Limb::of(model, l, c))
        })
        .collect()
}

/// The capsules of every collision shape off the chains to `feet` (arms, trunk, head):
/// what is kept off the surroundings.
pub fn upper_limbs(model: &RobotModel, feet: &[usize]) -> Vec<Limb> {
    let legs = leg_links(model, feet);
    (0..model.links().len())
        .filter(|l| !legs.contains(l))
        .flat_map(|l| model.links()[l].collisions.iter().map(move |c| Limb::of(model, l, c)))
        .collect()
}

/// Every collision shape of the robot as a world-frame capsule at the configuration `kin`
/// holds (the surroundings' self-filter).
pub fn body_capsules(model: &RobotModel, kin: &Kinematics) -> Vec<Capsule> {
    (0..model.links().len())
        .flat_map(|l| model.links()[l].collisions.iter().map(move |c| Limb::of(model, l, c).capsule(kin)))
        .collect()
}

/// Spacing of the axis samples of [`SeenPoints::nearest`]'s bounds, metres.
const SAMPLE_SPACING_M: f64 = 0.05;

/// The surfaces the lidar saw, as points (the surroundings' voxel centroids), and the edge
/// of the space it could have seen near the body and did not (`perception::free_space`),
/// with a k-d tree over both for the upper body's clearance queries.
pub struct SeenPoints {
    /// The surfaces' points, then the unseen edge's.
    points: Vec<Point3<f64>>,
    /// How many of `points` are surfaces'.
    surfaces: usize,
    tree: Option<kiddo::ImmutableKdTree<f64, 3>>,
}

impl std::fmt::Debug for SeenPoints {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "SeenPoints({} points, {} unseen)", self.surfaces, self.points.len() - self.surfaces)
    }
}

impl Default for SeenPoints {
    fn default() -> Self {
        Self::new(Vec::new())
    }
}

fn finite(points: Vec<Point3<f64>>) -> Vec<Point3<f64>> {
    points.into_iter().filter(|p| p.coords.iter().all(|v| v.is_finite())).collect()
}

impl SeenPoints {
    /// The surfaces' points (non-finite ones dropped).
    pub fn new(points: Vec<Point3<f64>>) -> Self {
        Self::with_unseen(points, Vec::new())
    }

    /// The surfaces' points and the unseen edge's (non-finite ones dropped).
    pub fn with_unseen(surfaces: Vec<Point3<f64>>, unseen: Vec<Point3<f64>>) -> Self {
        let mut points = finite(surfaces);
        let surfaces = points.len();
        points.extend(finite(unseen));
        let coords: Vec<[f64; 3]> = points.iter().map(|p| [p.x, p.y, p.z]).collect();
        let tree =
            (!coords.is_empty()).then(|| kiddo::ImmutableKdTree::new_from_slice(&coords).ok()).flatten();
        Self { points, surfaces, tree }
    }

    /// The surfaces' points.
    pub fn points(&self) -> &[Point3<f64>] {
        &self.points[..self.surfaces]
    }

    /// The unseen edge's points.
    pub fn unseen(&self) -> &[Point3<f64>] {
        &self.points[self.surfaces..]
    }

    /// Point `i` of a [`Nearest::block`], and whether it is of the unseen edge (`None` if
    /// there is no such point).
    pub fn point(&self, i: usize) -> Option<(Point3<f64>, bool)> {
        self.points.get(i).map(|p| (*p, i >= self.surfaces))
    }

    /// The surfaces' points that are neither the steps' nor the floor's own: farther than
    /// `band_m` from every one of `blocks` (the steps as solids, [`step_blocks`]) and more
    /// than `band_m` above `floor_z` (the floor under the start, and all below it). What the
    /// legs are kept off: a parcel on a tread, a box or a wall beside a lane (not the unseen
    /// edge: the lidar looks down past the legs' places at their shadows).
    pub fn off_the_steps(&self, blocks: &[SceneBox], floor_z: f64, band_m: f64) -> Self {
        Self::new(
            self.points()
                .iter()
                .filter(|q| q.z > floor_z + band_m && blocks.iter().all(|b| b.signed_distance(q) > band_m))
                .copied()
                .collect(),
        )
    }

    /// The point (of a surface or the unseen edge) nearest to `limb` at the configuration
    /// `kin` holds, `Nearest::block` being its index ([`SeenPoints::point`]); `None` when no point is within `range_m` of the capsule.
    pub fn nearest(&self, kin: &Kinematics, limb: &Limb, range_m: f64) -> Option<Nearest> {
        match self.probe(&limb.capsule(kin), range_m) {
            Probe::Near(mut witnesses) => Some(witnesses.swap_remove(0)),
            Probe::Clear { .. } => None,
        }
    }

    /// The witnesses of `capsule`, the point nearest to it first ([`Probe::Near`]), when one
    /// is within `range_m` of it, else how far beyond the range every point is known to be.
    pub fn probe(&self, capsule: &Capsule, range_m: f64) -> Probe {
        let Some(tree) = self.tree.as_ref() else { return Probe::Clear { gap_m: f64::INFINITY } };
        // The nearest point to each of a few axis samples `spacing` apart bounds the axis's
        // distance from above (their least) and from below (that less half the spacing):
        // most capsules are out of range by the lower bound, and the exact search of the
        // rest needs no wider a ball than the upper one (a wall's voxels in a ball around the
        // whole trunk cost more than the IK's QP).
        let half_length = (capsule.b - capsule.a).norm() / 2.0;
        let samples = (2.0 * half_length / SAMPLE_SPACING_M).ceil().max(1.0) as usize;
        let spacing = 2.0 * half_length / samples as f64;
        let upper = (0..=samples)
            .map(|i| {
                let at = capsule.a.lerp(&capsule.b, i as f64 / samples as f64);
                tree.query(&[at.x, at.y, at.z])
                    .nearest_one::<kiddo::SquaredEuclidean<f64>>()
                    .execute()
                    .distance
                    .sqrt()
            })
            .fold(f64::INFINITY, f64::min);
        let gap_m = upper - spacing / 2.0 - capsule.radius_m - range_m;
        if gap_m > 0.0 {
            return Probe::Clear { gap_m };
        }
        let middle = Point3::from((capsule.a.coords + capsule.b.coords) / 2.0);
        // Every point within `WITNESS_BAND_M` of the nearest's clearance lies in the ball
        // (the nearest's axis distance is at most `upper`).
        let reach = half_length + (upper + WITNESS_BAND_M).min(capsule.radius_m + range_m);
        let q = [middle.x, middle.y, middle.z];
        let found = tree.query(&q).within::<kiddo::SquaredEuclidean<f64>>(reach * reach).execute();
        // The nearest of the points `apart` admits, within range.
        let nearest = |apart: &dyn Fn(&Point3<f64>) -> bool| {
            let mut best: Option<Nearest> = None;
            for f in &found {
                let p = self.points[f.item as usize];
                let point = capsule.axis_point_nearest(&p);
                let away = point - p;
                let clearance_m = away.norm() - capsule.radius_m;
                if clearance_m <= range_m
                    && best.as_ref().is_none_or(|n| clearance_m < n.clearance_m)
                    && apart(&p)
                {
                    let normal = away.try_normalize(1e-12).unwrap_or_else(Vector3::z);
                    best = Some(Nearest { block: f.item as usize, clearance_m, point, normal });
                }
            }
            best
        };
        // The witnesses: the nearest point, then each time the nearest of those
        // `WITNESS_SPACING_M` or more from every witness before it, within `WITNESS_BAND_M`
        // of the nearest's clearance.
        let mut witnesses: Vec<Nearest> = Vec::new();
        while witnesses.len() < MAX_WITNESSES {
            let apart = |p: &Point3<f64>| {
                witnesses.iter().all(|w| (p - self.points[w.block]).norm() >= WITNESS_SPACING_M)
            };
            match nearest(&apart) {
                Some(w)
                    if witnesses.first().is_none_or(|f| w.clearance_m <= f.clearance_m + WITNESS_BAND_M) =>
                {
                    witnesses.push(w)
                }
                _ => break,
            }
        }
        if witnesses.is_empty() {
            Probe::Clear { gap_m: 0.0 }
        } else {
            Probe::Near(witnesses)
        }
    }
}

/// How far apart [`SeenPoints::probe`]'s witnesses of a capsule lie at least, metres. A
/// capsule held off its one nearest point moves across the direction it is held in, and so
/// nearer the points beside that one: held off two points of a nose in turn, tick by tick,
/// a chest comes nearer each while held off the other (regression
/// `walking-chest-ratcheted-along-a-nose`), and a point no longer held is one the IK's
/// other tasks pull the capsule toward. The witnesses hold it off each part of what is
/// near at once. More than the diagonal of a 3 cm voxel's face (4.2 cm), so that a
/// witness is not the neighbour of another on the same patch of a surface, which that one's
/// row holds off.
pub const WITNESS_SPACING_M: f64 = 0.05;

/// How much farther than its nearest point a capsule's other witnesses may be, metres: a
/// point 2 cm farther matters once the capsule has moved 2 cm toward it, and is a witness
/// by then (the ratchet went between points within 2 mm of each other).
pub const WITNESS_BAND_M: f64 = 0.02;

/// The most witnesses of a capsule: its nearest point and three more, each at least
/// [`WITNESS_SPACING_M`] from the others (a chest between two rails and over a nose has
/// three parts of what is near it).
pub const MAX_WITNESSES: usize = 4;

/// What [`SeenPoints::probe`] found for a capsule.
#[derive(Debug, Clone, PartialEq)]
pub enum Probe {
    /// The points within range the capsule is held off: the nearest first, then up to
    /// [`MAX_WITNESSES`] in all, each the nearest of those at least [`WITNESS_SPACING_M`]
    /// from the ones before it, while within [`WITNESS_BAND_M`] of the nearest's clearance.
    Near(Vec<Nearest>),
    /// No point within range; every one is at least `gap_m` beyond it (0: not known).
    Clear {
        /// Metres.
        gap_m: f64,
    },
}

/// Saves the probes of capsules that cannot have come within range since their last one,
/// for a tracker's ticks: the axis's points are blends of its ends, so none moves farther
/// than the farther-moved end, and a capsule whose last probe found every point `gap_m`
/// beyond range needs no new probe until an end has moved that far.
#[derive(Debug, Clone, Default)]
pub struct ProbeCache {
    clear: Vec<Option<(Capsule, f64)>>,
}

impl ProbeCache {
    /// The witnesses of capsule `i` (now `capsule`) within `range_m`, the nearest first
    /// ([`Probe::Near`]; empty when none is within range), probing `seen` only when it may
    /// have come within range since its last probe.
    pub fn witnesses(&mut self, i: usize, seen: &SeenPoints, capsule: Capsule, range_m: f64) -> Vec<Nearest> {
        if self.clear.len() <= i {
            self.clear.resize(i + 1, None);
        }
        if let Some((then, gap_m)) = &self.clear[i] {
            if (capsule.a - then.a).norm().max((capsule.b - then.b).norm()) < *gap_m {
                return Vec::new();
            }
        }
        match seen.probe(&capsule, range_m) {
            Probe::Near(witnesses) => {
                self.clear[i] = None;
                witnesses
            }
            Probe::Clear { gap_m } => {
                self.clear[i] = Some((capsule, gap_m));
                Vec::new()
            }
        }
    }
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

/// A capsule's closest block (or seen point).
#[derive(Debug, Clone, PartialEq)]
pub struct Nearest {
    /// Index of the block (of the point, from [`SeenPoints::nearest`]).
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
