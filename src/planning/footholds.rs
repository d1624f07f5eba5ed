//! Footholds (§6.1, §6.4): from the step rectangles and the feet where they stand, the
//! sequence of stances the gait goes through, both feet on each step. Each foothold sits in
//! the middle of its rectangle along the direction of ascent; across, each foot keeps the
//! lane it starts in; its height and tilt come from the rectangle's plane and its yaw from
//! the staircase. Steps the feet cannot use are refused here, with the reason, before any
//! motion is computed.

use super::PlanError;
use crate::perception::PlaneSegment;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

/// Which foot.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Foot {
    /// The right foot (it leads each step, §6.1).
    Right,
    /// The left foot.
    Left,
}

impl Foot {
    /// Both feet, in `[right, left]` order.
    pub const BOTH: [Foot; 2] = [Foot::Right, Foot::Left];

    /// 0 for the right foot, 1 for the left: the index into every `[right, left]` pair.
    pub fn index(self) -> usize {
        match self {
            Foot::Right => 0,
            Foot::Left => 1,
        }
    }
}

/// Both feet's sole poses in one double-support stance.
#[derive(Debug, Clone, PartialEq)]
pub struct Stance {
    /// Right sole centre (z = sole normal).
    pub right: Isometry3<f64>,
    /// Left sole centre.
    pub left: Isometry3<f64>,
    /// Index of the step stood on (in ascending order), `None` on the floor.
    pub step: Option<usize>,
}

impl Stance {
    /// The pose of one foot.
    pub fn foot(&self, f: Foot) -> &Isometry3<f64> {
        match f {
            Foot::Right => &self.right,
            Foot::Left => &self.left,
        }
    }
}

/// What the feet can use (§6.1, §6.4). Lengths in metres.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GaitParams {
    /// Shortest tread a foot is placed on. The sole is 24 cm; the default lets it overhang a
    /// perceived rectangle by 1 cm at each end, since perception under-measures a tread by
    /// up to about half a voxel per edge (§4, v = 2 cm; the paper's Exp. 1 step 1 is
    /// 23.2 cm deep on a 27 cm tread).
    pub min_tread_m: f64,
    /// Highest rise between consecutive treads the legs can climb (HRP-4's 24 cm step,
    /// §6.3, is within; the knee's fold and the trailing leg's reach set the limit).
    pub max_rise_m: f64,
    /// A rise this many times the median rise means a step was not seen (a missing step).
    pub missing_step_ratio: f64,
    /// Largest horizontal gap between consecutive treads. Perception leaves up to about
    /// 6 cm between treads of a continuous staircase (the paper's Exp. 1 rectangles: 6.4 cm
    /// between steps 2 and 3).
    pub max_gap_m: f64,
    /// Longest stride between consecutive footholds along the ascent.
    pub max_stride_m: f64,
    /// Stride of the floor steps taken to reach the first step when it is farther than
    /// `max_stride_m` (the same five-segment gait on the floor, §6.4).
    pub approach_stride_m: f64,
    /// On a rectangle deeper than twice this (a landing), the foothold is this far past its
    /// front edge instead of in its middle.
    pub landing_foothold_m: f64,
    /// Floor footholds before the first step keep the toes this far behind its riser.
    pub toe_gap_m: f64,
    /// How far a sole may overhang its rectangle's side.
    pub side_overhang_m: f64,
    /// Sole length (HRP-4: 24 cm).
    pub sole_length_m: f64,
    /// Sole width (HRP-4: 13 cm).
    pub sole_width_m: f64,
    /// Fault injection, to test the regression tooling only: every foothold on a step is
    /// moved this far along the ascent, metres (0: none). A planner with this set is broken
    /// on purpose, and `regress --baseline` must say so.
    pub test_foothold_shift_m: f64,
}

impl Default for GaitParams {
    fn default() -> Self {
        Self {
            min_tread_m: 0.22,
            max_rise_m: 0.28,
            missing_step_ratio: 1.6,
            max_gap_m: 0.10,
            max_stride_m: 0.40,
            approach_stride_m: 0.25,
            landing_foothold_m: 0.18,
            toe_gap_m: 0.03,
            side_overhang_m: 0.02,
            sole_length_m: crate::robot::hrp4::SOLE_SIZE_M[0],
            sole_width_m: crate::robot::hrp4::SOLE_SIZE_M[1],
            test_foothold_shift_m: 0.0,
        }
    }
}

/// The stances after `start`, ending with both feet on the highest rectangle, or the reason
/// the staircase cannot be climbed.
pub fn footholds(start: &Stance, rects: &[PlaneSegment], p: &GaitParams) -> Result<Vec<Stance>, PlanError> {
    if rects.is_empty() {
        return Err(PlanError::NoSteps);
    }
    let steps = super::rectangles::by_height(rects);
    let u = steps[0].along();
    let limit_rad = 10f64.to_radians();
    for (i, s) in steps.iter().enumerate() {
        let angle_rad = s.along().dot(&u).clamp(-1.0, 1.0).acos();
        if s.along().dot(&u) < limit_rad.cos() {
            return Err(PlanError::NotStraight { step: i, angle_rad, limit_rad });
        }
    }
    let w = Vector3::z().cross(&u);
    let o = steps[0].center();
    let (r0, l0) = (start.right.translation.vector, start.left.translation.vector);
    let floor_z = r0.z.min(l0.z);
    let lanes = [(r0 - o.coords).dot(&w), (l0 - o.coords).dot(&w)];
    let start_along = ((r0 + l0) / 2.0 - o.coords).dot(&u);

    let rises = super::rectangles::rises_m(&steps, Some(floor_z));
    let median = super::rectangles::median(&rises).unwrap_or(0.0);
    let yaw = UnitQuaternion::from_euler_angles(0.0, 0.0, u.y.atan2(u.x));
    // Both feet `along` the ascent in their lanes, on the plane through `point` with normal
    // `n` (the foot tilted with it, yawed with the staircase).
    let stance_on = |along: f64, point: Point3<f64>, n: Vector3<f64>, step: Option<usize>| {
        let tilt =
            UnitQuaternion::rotation_between(&Vector3::z(), &n).unwrap_or_else(UnitQuaternion::identity);
        let foot = |lane: f64| {
            let xy = o + u * along + w * lane;
            let z = point.z - (n.x * (xy.x - point.x) + n.y * (xy.y - point.y)) / n.z;
            Isometry3::from_parts(Translation3::new(xy.x, xy.y, z), tilt * yaw)
        };
        Stance { right: foot(lanes[0]), left: foot(lanes[1]), step }
    };
    let floor = Point3::new(o.x, o.y, floor_z);

    let mut out = Vec::new();
    let mut prev_along = start_along;
    for (i, s) in steps.iter().enumerate() {
        let c = s.center();
        let front = (c - o).dot(&u) - s.depth_m() / 2.0;
        let along = front + (s.depth_m() / 2.0).min(p.landing_foothold_m);
        if s.depth_m() < p.min_tread_m {
            return Err(PlanError::ShortTread { step: i, depth_m: s.depth_m(), min_m: p.min_tread_m });
        }
        if rises.len() >= 3 && rises[i] >= p.missing_step_ratio * median {
            return Err(PlanError::MissingStep { step: i, rise_m: rises[i], median_m: median });
        }
        if rises[i] > p.max_rise_m {
            return Err(PlanError::HighRise { step: i, rise_m: rises[i], max_m: p.max_rise_m });
        }
        if i > 0 {
            let back = (steps[i - 1].center() - o).dot(&u) + steps[i - 1].depth_m() / 2.0;
            let gap = front - back;
            if gap > p.max_gap_m {
                return Err(PlanError::Gap { step: i, gap_m: gap, max_m: p.max_gap_m });
            }
        }
        let side = (c - o).dot(&w);
        for (f, lane) in Foot::BOTH.into_iter().zip(lanes) {
            let over = (lane - side).abs() + p.sole_width_m / 2.0 - s.width_m() / 2.0;
            if over > p.side_overhang_m {
                return Err(PlanError::OffTheSide {
                    step: i,
                    foot: f,
                    overhang_m: over,
                    max_m: p.side_overhang_m,
                });
            }
        }
        if i == 0 && along - prev_along > p.max_stride_m {
            // Walk up to the first step on the floor, the toes staying behind its riser.
            let last = front - p.sole_length_m / 2.0 - p.toe_gap_m;
            let n = ((last - prev_along) / p.approach_stride_m).ceil().max(0.0) as usize;
            for k in 1..=n {
                let a = prev_along + (last - prev_along) * k as f64 / n as f64;
                out.push(stance_on(a, floor, Vector3::z(), None));
            }
            if n > 0 {
                prev_along = last;
            }
        }
        let stride = along - prev_along;
        if stride > p.max_stride_m || stride < 0.0 {
            return Err(PlanError::Stride { step: i, stride_m: stride, max_m: p.max_stride_m });
        }
        out.push(stance_on(along + p.test_foothold_shift_m, c, s.normal().into_inner(), Some(i)));
        prev_along = along;
    }
    Ok(out)
}
