//! Planning (§6): footholds on the step rectangles, the five-segment gait, contact wrench
//! cones and static-stability polygons (double description, checked by Bretl and Lall's
//! projection), and the QP IK that turns the gait into a whole-body trajectory.

pub mod clearance;
pub mod contact;
pub mod dd;
pub mod footholds;
pub mod gait;
pub mod ik;
pub mod motion;
pub mod plan;
pub mod polygon;
pub mod rectangles;

pub use contact::{Contact, ContactSpec};
pub use footholds::{Foot, Stance};
pub use plan::{plan, Plan, PlanParams};

/// Why a climb was refused. Steps are numbered from 1, the lowest, in messages.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum PlanError {
    /// No rectangles.
    #[error("no staircase: no step rectangles to plan on")]
    NoSteps,
    /// A rectangle's direction of ascent differs from the first one's.
    #[error("step {} is turned more than 10 deg from step 1: not a straight staircase", .step + 1)]
    NotStraight {
        /// 0-based step.
        step: usize,
    },
    /// A tread shorter than the foot.
    #[error("step {}: tread {depth_m:.3} m is shorter than the foot needs ({min_m:.3} m)", .step + 1)]
    ShortTread {
        /// 0-based step.
        step: usize,
        /// Its depth.
        depth_m: f64,
        /// The least accepted.
        min_m: f64,
    },
    /// A rise far above the others: a step in between was not seen.
    #[error("step {}: rise {rise_m:.3} m is {:.1} times the median rise {median_m:.3} m: a step is missing below it", .step + 1, .rise_m / .median_m)]
    MissingStep {
        /// 0-based step.
        step: usize,
        /// Its rise.
        rise_m: f64,
        /// Median rise of the staircase.
        median_m: f64,
    },
    /// A rise the legs cannot climb.
    #[error("step {}: rise {rise_m:.3} m is higher than the legs can climb ({max_m:.3} m)", .step + 1)]
    HighRise {
        /// 0-based step.
        step: usize,
        /// Its rise.
        rise_m: f64,
        /// The highest accepted.
        max_m: f64,
    },
    /// Open space between consecutive treads.
    #[error("step {}: a {gap_m:.3} m gap before it (at most {max_m:.3} m)", .step + 1)]
    Gap {
        /// 0-based step.
        step: usize,
        /// The gap.
        gap_m: f64,
        /// The largest accepted.
        max_m: f64,
    },
    /// A foot's lane runs off the side of a step.
    #[error("step {}: the {foot:?} foot would overhang its side by {overhang_m:.3} m", .step + 1)]
    OffTheSide {
        /// 0-based step.
        step: usize,
        /// Which foot.
        foot: Foot,
        /// By how much.
        overhang_m: f64,
    },
    /// A stride too long (or backward).
    #[error("step {}: stride {stride_m:.3} m is outside 0..{max_m:.3} m", .step + 1)]
    Stride {
        /// 0-based step.
        step: usize,
        /// The stride.
        stride_m: f64,
        /// The longest accepted.
        max_m: f64,
    },
    /// The legs cannot take a stance of the gait.
    #[error("stance {}: {what}", .stance + 1)]
    Reach {
        /// 0-based stance.
        stance: usize,
        /// What fails.
        what: String,
    },
    /// A CoM waypoint cannot be placed inside its polygons with the margin.
    #[error("segment {}: the CoM cannot stay inside the static-stability polygon with margin (margin {margin_m:.3} m)", .segment + 1)]
    Unstable {
        /// 0-based segment.
        segment: usize,
        /// The margin found.
        margin_m: f64,
    },
    /// The stability polygon could not be computed.
    #[error("stability polygon: {0}")]
    Polygon(#[from] polygon::PolygonError),
    /// The IK had no solution at some tick.
    #[error("segment {}, t = {t_s:.3} s: {error}", .segment + 1)]
    Ik {
        /// Time of the tick.
        t_s: f64,
        /// 0-based segment.
        segment: usize,
        /// The solver's complaint.
        error: ik::IkError,
    },
    /// The IK could not follow the gait closely enough.
    #[error("segment {}: {what}", .segment + 1)]
    Tracking {
        /// 0-based segment.
        segment: usize,
        /// What strayed.
        what: String,
    },
    /// The robot model or its configuration is unusable.
    #[error("robot: {0}")]
    Config(String),
}

impl From<crate::robot::RobotError> for PlanError {
    fn from(e: crate::robot::RobotError) -> Self {
        PlanError::Config(e.to_string())
    }
}

impl From<crate::robot::ConfigError> for PlanError {
    fn from(e: crate::robot::ConfigError) -> Self {
        PlanError::Config(e.to_string())
    }
}
