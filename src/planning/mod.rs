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
pub mod reach;
pub mod rectangles;
pub mod stance;

pub use contact::{Contact, ContactSpec};
pub use motion::NearestSurface;
pub use plan::{Plan, PlanParams, PlanRequest};
pub use stance::{Foot, Stance};

/// Why a climb was refused. Steps are numbered from 1, the lowest, in messages.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum PlanError {
    /// No rectangles.
    #[error("no staircase: no step rectangles to plan on")]
    NoSteps,
    /// A rectangle's direction of ascent differs from the flight's (the steps' directions
    /// weighed by their voxels).
    #[error("step {} is turned {:.1} deg from the flight's direction (more than {:.0} deg): not a straight staircase", .step + 1, .angle_rad.to_degrees(), .limit_rad.to_degrees())]
    NotStraight {
        /// 0-based step.
        step: usize,
        /// Its turn from the flight's direction, radians.
        angle_rad: f64,
        /// The largest accepted.
        limit_rad: f64,
    },
    /// A tread shorter than the foot, as deep as the foot can use it: up to the next step's
    /// front edge.
    #[error("step {}: tread {depth_m:.3} m deep (up to the next step's front) is shorter than the foot needs ({min_m:.3} m)", .step + 1)]
    ShortTread {
        /// 0-based step.
        step: usize,
        /// Its depth, up to the next step's front edge.
        depth_m: f64,
        /// The least accepted.
        min_m: f64,
    },
    /// A rise far above the others: a step in between was not seen.
    #[error("step {}: rise {rise_m:.3} m is {:.1} times the flight's usual rise {usual_m:.3} m: a step is missing below it", .step + 1, .rise_m / .usual_m)]
    MissingStep {
        /// 0-based step.
        step: usize,
        /// Its rise.
        rise_m: f64,
        /// The flight's usual rise: the median of three or more rises, the lower of two.
        usual_m: f64,
    },
    /// The lidar saw something standing on the floor where a floor stance puts a sole, or
    /// in its way there: a step perception did not take for one, or an obstacle.
    #[error("stance {}: the lidar saw {points} points standing up to {height_m:.3} m above the floor in the {foot:?} sole's way (a step not perceived, or an obstacle)", .stance + 1)]
    FloorObstructed {
        /// 0-based stance.
        stance: usize,
        /// Which foot.
        foot: Foot,
        /// The surroundings' points in the sole's way above the floor's band.
        points: usize,
        /// The highest of them above the floor, metres.
        height_m: f64,
    },
    /// The lidar saw something standing on a tread or a landing where a stance on a step
    /// puts a sole, or in its way there (an object left on the step): the foot's lane is
    /// blocked, and the lanes do not move around it.
    #[error("stance {} on step {}: the lidar saw {points} points standing up to {height_m:.3} m above the tread in the {foot:?} sole's way (an object on the step)", .stance + 1, .step + 1)]
    TreadObstructed {
        /// 0-based stance.
        stance: usize,
        /// 0-based step the stance stands on.
        step: usize,
        /// Which foot.
        foot: Foot,
        /// The surroundings' points in the sole's way above the tread's band.
        points: usize,
        /// The highest of them above the tread under them, metres.
        height_m: f64,
    },
    /// The lowest step's front edge as perceived is not known to be its nose: it was not
    /// placed on its riser, and the lidar saw no floor before it in the feet's lanes. Set
    /// down near the first riser, the robot has the floor before it and the tread's near part
    /// under its lidar, out of sight: the front it sees is where its sight begins, and the
    /// riser may stand anywhere between the toes and it. A walk on the floor toward that
    /// front could set a foot into the riser, so none is planned.
    #[error("step {}: its front edge, {ahead_m:.3} m ahead of the feet, may be only where the lidar's sight begins: neither its riser nor the floor before it was seen, and no floor stance goes toward it", .step + 1)]
    RiserOutOfSight {
        /// 0-based step.
        step: usize,
        /// Its front edge as perceived, along the ascent from the middle of the feet, metres.
        ahead_m: f64,
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
    #[error("step {}: the {foot:?} foot would overhang its side by {overhang_m:.4} m, more than {max_m:.3} m", .step + 1)]
    OffTheSide {
        /// 0-based step.
        step: usize,
        /// Which foot.
        foot: Foot,
        /// By how much.
        overhang_m: f64,
        /// The largest accepted.
        max_m: f64,
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
    /// The feet of a stance are farther apart along the ascent than a leg reaches.
    #[error("stance {}: the feet are {apart_m:.3} m apart along the ascent, a leg reaches {reach_m:.3} m", .stance + 1)]
    LegReach {
        /// 0-based stance.
        stance: usize,
        /// The feet's distance along the ascent, metres.
        apart_m: f64,
        /// A leg's reach, metres.
        reach_m: f64,
    },
    /// The leading leg's hip, where the tracked trajectory puts it at the touchdown, is
    /// farther from the landing ankle horizontally than the leg reaches (see [`reach`]).
    #[error("stance {}: at the touchdown the leading hip is {across_m:.3} m from the ankle across, the leg reaches {reach_m:.3} m", .stance + 1)]
    TouchdownReach {
        /// 0-based stance.
        stance: usize,
        /// The hip's horizontal distance from the landing ankle, metres.
        across_m: f64,
        /// The leg's reach, metres.
        reach_m: f64,
    },
    /// The leading knee would fold beyond its limit to take a stance.
    #[error("stance {}: the leading knee would fold beyond {:.0} deg: hip {hip_above_ankle_m:.3} m above the ankle, needs {needs_m:.3} m", .stance + 1, .knee_max_rad.to_degrees())]
    KneeFold {
        /// 0-based stance.
        stance: usize,
        /// The hip's height over the ankle the stance allows, metres.
        hip_above_ankle_m: f64,
        /// The least height the knee limit needs, metres.
        needs_m: f64,
        /// The knee limit, radians.
        knee_max_rad: f64,
    },
    /// A CoM waypoint cannot be placed inside its polygons with the margin.
    #[error("segment {}: the CoM cannot stay inside the static-stability polygon with margin (margin {margin_m:.3} m)", .segment + 1)]
    Unstable {
        /// 0-based segment.
        segment: usize,
        /// The margin found, metres (negative outside; -inf without a polygon).
        margin_m: f64,
        /// The least margin asked for, metres.
        min_m: f64,
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
    /// A limb of the IK's trajectory enters a step.
    #[error("segment {}: {limb} touches step {} ({:.1} mm deep) at t = {t_s:.2} s", .segment + 1, .step + 1, .depth_m * 1e3)]
    LimbTouchesStep {
        /// 0-based segment.
        segment: usize,
        /// The limb (its collision capsule's name).
        limb: String,
        /// 0-based step.
        step: usize,
        /// How deep, metres.
        depth_m: f64,
        /// When, seconds from the plan's start.
        t_s: f64,
    },
    /// A leg (thigh or shank) enters a surface the lidar saw off the steps and the floor
    /// (see `clearance::SeenPoints::off_the_steps`); the rest of the body is held farther,
    /// see [`PlanError::BodyNearSurface`].
    #[error("segment {}: {limb} touches a surface the lidar saw at ({:.3}, {:.3}, {:.3}) m ({:.1} mm deep) at t = {t_s:.2} s", .segment + 1, .point_m[0], .point_m[1], .point_m[2], .depth_m * 1e3)]
    BodyTouchesSurface {
        /// 0-based segment.
        segment: usize,
        /// The limb (its link's name).
        limb: String,
        /// The surface's point (a voxel centroid of the surroundings), world frame, metres.
        point_m: [f64; 3],
        /// How deep, metres.
        depth_m: f64,
        /// When, seconds from the plan's start.
        t_s: f64,
    },
    /// The body (an arm, the trunk, the head) comes nearer a surface the lidar saw than the
    /// execution's sway about the plan allows (`motion::IkParams::min_body_clearance_m`), or
    /// nearer the edge of the space the lidar could have seen and did not (`unseen`): what
    /// is there is not known (a shadow, a gap a moving head left), and it is not walked into.
    #[error("segment {}: {limb} comes {:.1} mm from {} at ({:.3}, {:.3}, {:.3}) m at t = {t_s:.2} s, nearer than the {:.0} mm the body's sway needs", .segment + 1, .clearance_m * 1e3, if *.unseen { "space the lidar could have seen and no ray crossed" } else { "a surface the lidar saw" }, .point_m[0], .point_m[1], .point_m[2], .min_m * 1e3)]
    BodyNearSurface {
        /// 0-based segment.
        segment: usize,
        /// The limb (its link's name).
        limb: String,
        /// The surface's point (a voxel centroid of the surroundings) or the unseen voxel's
        /// centre, world frame, metres.
        point_m: [f64; 3],
        /// Whether the point is of the edge of the unseen space, not a surface.
        unseen: bool,
        /// Its distance from the limb's capsule, metres (negative: inside it).
        clearance_m: f64,
        /// The least accepted, metres.
        min_m: f64,
        /// When, seconds from the plan's start.
        t_s: f64,
    },
    /// A plan made from a pass the head took moving holds the upper body at its clearance
    /// (`motion::IkParams::body_clearance_m`) from the edge of space that pass left unseen
    /// ([`Plan::held_off_unseen`]): the IK bent the motion around a gap the moving head
    /// left near the body, which a pass taken standing fills. The loop looks again standing.
    #[error("segment {}: the plan holds {limb} at its clearance, {:.1} mm from space the pass taken moving left unseen at ({:.3}, {:.3}, {:.3}) m, at t = {t_s:.2} s: its motion is bent around a gap a pass taken standing would fill", .segment + 1, .clearance_m * 1e3, .point_m[0], .point_m[1], .point_m[2])]
    HeldOffUnseen {
        /// 0-based segment.
        segment: usize,
        /// The limb (its link's name).
        limb: String,
        /// The unseen voxel's centre, world frame, metres.
        point_m: [f64; 3],
        /// Its distance from the limb's capsule, metres.
        clearance_m: f64,
        /// The clearance the IK keeps, metres.
        kept_m: f64,
        /// When, seconds from the plan's start.
        t_s: f64,
    },
    /// What the lidar saw beside the flight at the body's height (handrails, walls) leaves
    /// less room across than the body's lane (twice `GaitParams::body_half_width_m`; on the
    /// flight, `GaitParams::room_commit_margin_m` less).
    #[error("the flight leaves {room_m:.2} m between what stands beside it at the body's height, less than the {needs_m:.2} m the body sweeps")]
    NarrowFlight {
        /// The room between the nearest surfaces on either side, metres.
        room_m: f64,
        /// The room needed, metres: the body's lane (from the floor), or it less the commit
        /// margin (on the flight).
        needs_m: f64,
    },
    /// The IK's swing foot ends too far from its target.
    #[error("segment {}: {foot:?} foot misses its target by {:.1} mm", .segment + 1, .error_m * 1e3)]
    FootMisses {
        /// 0-based segment.
        segment: usize,
        /// Which foot.
        foot: Foot,
        /// The distance, metres.
        error_m: f64,
        /// The largest accepted, metres.
        limit_m: f64,
    },
    /// The IK's CoM strays from the planned path.
    #[error("segment {}: the CoM strays {:.1} mm from its path", .segment + 1, .error_m * 1e3)]
    ComStrays {
        /// 0-based segment.
        segment: usize,
        /// The largest distance, metres.
        error_m: f64,
        /// The largest accepted, metres.
        limit_m: f64,
    },
    /// A segment's turn about the vertical asks the soles more than the plan allows
    /// (`IkParams::max_yaw_moment_share`) after the rounds that slow it.
    #[error("segment {}: its turn asks {moment_nm:.1} N m about the vertical after it was slowed, more than the soles are asked to hold ({limit_nm:.1} N m)", .segment + 1)]
    TurnUnheld {
        /// 0-based segment.
        segment: usize,
        /// The moment it asks, N m.
        moment_nm: f64,
        /// The largest allowed, N m.
        limit_nm: f64,
    },
    /// The robot model or its configuration is unusable.
    #[error("robot: {0}")]
    Config(String),
}

/// What kind of refusal a [`Refusal`] is (one per [`PlanError`] variant).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RefusalKind {
    /// [`PlanError::NoSteps`].
    NoSteps,
    /// [`PlanError::NotStraight`].
    NotStraight,
    /// [`PlanError::ShortTread`].
    ShortTread,
    /// [`PlanError::MissingStep`].
    MissingStep,
    /// [`PlanError::FloorObstructed`].
    FloorObstructed,
    /// [`PlanError::TreadObstructed`].
    TreadObstructed,
    /// [`PlanError::RiserOutOfSight`].
    RiserOutOfSight,
    /// [`PlanError::HighRise`].
    HighRise,
    /// [`PlanError::Gap`].
    Gap,
    /// [`PlanError::OffTheSide`].
    OffTheSide,
    /// [`PlanError::Stride`].
    Stride,
    /// [`PlanError::LegReach`].
    LegReach,
    /// [`PlanError::TouchdownReach`].
    TouchdownReach,
    /// [`PlanError::KneeFold`].
    KneeFold,
    /// [`PlanError::Unstable`].
    Unstable,
    /// [`PlanError::Polygon`].
    Polygon,
    /// [`PlanError::Ik`].
    Ik,
    /// [`PlanError::LimbTouchesStep`].
    LimbTouchesStep,
    /// [`PlanError::BodyTouchesSurface`].
    BodyTouchesSurface,
    /// [`PlanError::BodyNearSurface`].
    BodyNearSurface,
    /// [`PlanError::BodyNearSurface`] at the edge of unseen space.
    BodyNearUnseen,
    /// [`PlanError::HeldOffUnseen`].
    HeldOffUnseen,
    /// [`PlanError::NarrowFlight`].
    NarrowFlight,
    /// [`PlanError::FootMisses`].
    FootMisses,
    /// [`PlanError::ComStrays`].
    ComStrays,
    /// [`PlanError::TurnUnheld`].
    TurnUnheld,
    /// [`PlanError::Config`].
    Robot,
}

impl RefusalKind {
    /// Whether another view of the steps may undo this refusal: a judgement of a step's
    /// extent as seen (a step seen in part is narrow or shallow, leaves a gap or a long
    /// stride, or comes back turned; a first riser out of the lidar's sight, seen from
    /// farther back), not of the robot's motion over the steps. Rises are not: a height is
    /// measured whole from any view, and a staircase too high to climb is refused before
    /// anything moves.
    pub fn about_the_view(self) -> bool {
        use RefusalKind as K;
        matches!(
            self,
            K::NotStraight | K::ShortTread | K::Gap | K::OffTheSide | K::Stride | K::RiserOutOfSight
        )
    }

    /// Whether the loop, on the floor the climb starts from, looks again from nearer before
    /// this refusal stands: the refusals [about the view](Self::about_the_view), and a
    /// missing step. A rise is measured whole from any view, but a missing step is a rise
    /// between two treads seen with none between them, and a tread perception did not find
    /// in one view (under noise) reads the same (regression `tread-missed-in-the-first-view`).
    /// It never climbs toward a missing step: only the walk on the floor looks again.
    pub fn looked_at_again_from_the_floor(self) -> bool {
        self.about_the_view() || self == RefusalKind::MissingStep
    }
}

/// A refusal as data, for reports and regression tables: its kind, where (1-based step,
/// stance or segment, as in messages), the value that broke a limit and the limit, and the
/// message. Made by [`PlanError::refusal`].
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Refusal {
    /// Which refusal.
    pub kind: RefusalKind,
    /// The step (1 = lowest) it is about, if one.
    pub step: Option<usize>,
    /// The stance (1 = first planned) it is about, if one.
    pub stance: Option<usize>,
    /// The segment (1 = first) it is about, if one.
    pub segment: Option<usize>,
    /// The value found, in `unit`.
    pub value: Option<f64>,
    /// The limit it broke, in `unit`.
    pub limit: Option<f64>,
    /// Unit of `value` and `limit` (`m`, `rad`, `ratio`, `N m`).
    pub unit: Option<String>,
    /// The message, as printed.
    pub message: String,
}

impl PlanError {
    /// This refusal as data.
    pub fn refusal(&self) -> Refusal {
        use RefusalKind as K;
        let m = |v: f64, l: f64| (Some(v), Some(l), Some("m"));
        let none = (None, None, None);
        let (kind, step, stance, segment, (value, limit, unit)) = match self {
            PlanError::NoSteps => (K::NoSteps, None, None, None, none),
            PlanError::NotStraight { step, angle_rad, limit_rad } => {
                (K::NotStraight, Some(*step), None, None, (Some(*angle_rad), Some(*limit_rad), Some("rad")))
            }
            PlanError::ShortTread { step, depth_m, min_m } => {
                (K::ShortTread, Some(*step), None, None, m(*depth_m, *min_m))
            }
            PlanError::MissingStep { step, rise_m, usual_m } => {
                (K::MissingStep, Some(*step), None, None, m(*rise_m, *usual_m))
            }
            PlanError::FloorObstructed { stance, height_m, .. } => {
                (K::FloorObstructed, None, Some(*stance), None, (Some(*height_m), None, Some("m")))
            }
            PlanError::TreadObstructed { stance, step, height_m, .. } => {
                (K::TreadObstructed, Some(*step), Some(*stance), None, (Some(*height_m), None, Some("m")))
            }
            PlanError::RiserOutOfSight { step, ahead_m } => {
                (K::RiserOutOfSight, Some(*step), None, None, (Some(*ahead_m), None, Some("m")))
            }
            PlanError::HighRise { step, rise_m, max_m } => {
                (K::HighRise, Some(*step), None, None, m(*rise_m, *max_m))
            }
            PlanError::Gap { step, gap_m, max_m } => (K::Gap, Some(*step), None, None, m(*gap_m, *max_m)),
            PlanError::OffTheSide { step, overhang_m, max_m, .. } => {
                (K::OffTheSide, Some(*step), None, None, m(*overhang_m, *max_m))
            }
            PlanError::Stride { step, stride_m, max_m } => {
                (K::Stride, Some(*step), None, None, m(*stride_m, *max_m))
            }
            PlanError::LegReach { stance, apart_m, reach_m } => {
                (K::LegReach, None, Some(*stance), None, m(*apart_m, *reach_m))
            }
            PlanError::TouchdownReach { stance, across_m, reach_m } => {
                (K::TouchdownReach, None, Some(*stance), None, m(*across_m, *reach_m))
            }
            PlanError::KneeFold { stance, hip_above_ankle_m, needs_m, .. } => {
                (K::KneeFold, None, Some(*stance), None, m(*hip_above_ankle_m, *needs_m))
            }
            PlanError::Unstable { segment, margin_m, min_m } => {
                (K::Unstable, None, None, Some(*segment), m(*margin_m, *min_m))
            }
            PlanError::Polygon(_) => (K::Polygon, None, None, None, none),
            PlanError::Ik { segment, .. } => (K::Ik, None, None, Some(*segment), none),
            PlanError::LimbTouchesStep { segment, step, depth_m, .. } => {
                (K::LimbTouchesStep, Some(*step), None, Some(*segment), m(*depth_m, 0.0))
            }
            PlanError::BodyTouchesSurface { segment, depth_m, .. } => {
                (K::BodyTouchesSurface, None, None, Some(*segment), m(*depth_m, 0.0))
            }
            PlanError::NarrowFlight { room_m, needs_m } => {
                (K::NarrowFlight, None, None, None, m(*room_m, *needs_m))
            }
            PlanError::BodyNearSurface { segment, clearance_m, min_m, unseen, .. } => {
                let kind = if *unseen { K::BodyNearUnseen } else { K::BodyNearSurface };
                (kind, None, None, Some(*segment), m(*clearance_m, *min_m))
            }
            PlanError::HeldOffUnseen { segment, clearance_m, kept_m, .. } => {
                (K::HeldOffUnseen, None, None, Some(*segment), m(*clearance_m, *kept_m))
            }
            PlanError::FootMisses { segment, error_m, limit_m, .. } => {
                (K::FootMisses, None, None, Some(*segment), m(*error_m, *limit_m))
            }
            PlanError::ComStrays { segment, error_m, limit_m } => {
                (K::ComStrays, None, None, Some(*segment), m(*error_m, *limit_m))
            }
            PlanError::TurnUnheld { segment, moment_nm, limit_nm } => {
                (K::TurnUnheld, None, None, Some(*segment), (Some(*moment_nm), Some(*limit_nm), Some("N m")))
            }
            PlanError::Config(_) => (K::Robot, None, None, None, none),
        };
        Refusal {
            kind,
            step: step.map(|i| i + 1),
            stance: stance.map(|i| i + 1),
            segment: segment.map(|i| i + 1),
            value,
            limit,
            unit: unit.map(str::to_string),
            message: self.to_string(),
        }
    }
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
