//! The bench's own recorded messages, one serde type each, shared by the MCAP writer, the
//! replay reader and `plan --json` (whose output is a [`PlanMsg`] with the planner's verdict).
//! Steps, stances and segments are numbered from 1 (the lowest step, the first stance), as in
//! every message the bench prints. Lengths in metres, angles in radians.

use crate::perception::{Counts, NoStaircase, Perception, PerceptionError, PhaseTimings, PlaneSegment};
use crate::planning::gait::Phase;
use crate::planning::motion::Tracking;
use crate::planning::{Foot, Plan, Refusal};
use crate::scenario::LidarSpec;
use crate::sensor::Sweep;
use nalgebra::{Isometry3, Point3, Quaternion, Translation3, UnitQuaternion};
use serde::{Deserialize, Serialize};

/// A rigid transform: `translation` [x, y, z] and `rotation` [w, x, y, z].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoseMsg {
    /// Translation, metres.
    pub translation: [f64; 3],
    /// Unit quaternion, w first.
    pub rotation: [f64; 4],
}

impl PoseMsg {
    /// The message of an isometry.
    pub fn of(p: &Isometry3<f64>) -> Self {
        let t = p.translation.vector;
        let q = p.rotation;
        Self { translation: [t.x, t.y, t.z], rotation: [q.w, q.i, q.j, q.k] }
    }

    /// The isometry, when the numbers are finite and the rotation a rotation. A quaternion
    /// of unit norm already is taken as it is, so a recorded pose comes back bit for bit.
    pub fn isometry(&self) -> Result<Isometry3<f64>, String> {
        if !self.translation.iter().chain(&self.rotation).all(|x| x.is_finite()) {
            return Err("a pose has non-finite numbers".into());
        }
        let [w, x, y, z] = self.rotation;
        let q = Quaternion::new(w, x, y, z);
        let rotation = if (q.norm() - 1.0).abs() < 1e-12 {
            UnitQuaternion::new_unchecked(q)
        } else {
            UnitQuaternion::try_new(q, 1e-9).ok_or("a pose's rotation is not a rotation")?
        };
        let [tx, ty, tz] = self.translation;
        Ok(Isometry3::from_parts(Translation3::new(tx, ty, tz), rotation))
    }
}

/// `/lidar/sweep`: a sweep's header; its rows follow on `/lidar/scan`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepMsg {
    /// When the sweep was taken (the robot's clock), seconds.
    pub stamp_s: f64,
    /// Rows that follow.
    pub rows: usize,
    /// The lidar (the scenario's lidar table).
    pub lidar: LidarSpec,
    /// The servo base's pose in the world during the sweep.
    pub mount_to_world: PoseMsg,
}

impl SweepMsg {
    /// The header of `sweep` taken at `stamp_s`.
    pub fn of(stamp_s: f64, sweep: &Sweep) -> Self {
        Self {
            stamp_s,
            rows: sweep.rows.len(),
            lidar: sweep.lidar.spec().clone(),
            mount_to_world: PoseMsg::of(&sweep.mount_to_world),
        }
    }
}

/// `/perception/result`: what perception found on a sweep, or why it found nothing.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PerceptionMsg {
    /// The steps, lowest first (empty when none).
    pub segments: Vec<PlaneSegment>,
    /// Wall time per phase, milliseconds (when it ran to the end).
    pub timings_ms: Option<PhaseTimings>,
    /// Sizes of the intermediate results (when it ran to the end).
    pub counts: Option<Counts>,
    /// Why no staircase was found, as data (when none was).
    pub no_staircase: Option<NoStaircase>,
    /// The error's message (when it found nothing or failed).
    pub error: Option<String>,
}

impl PerceptionMsg {
    /// The message of a perception's result.
    pub fn of(result: Result<&Perception, &PerceptionError>) -> Self {
        match result {
            Ok(r) => Self {
                segments: r.segments.clone(),
                timings_ms: Some(r.timings.clone()),
                counts: Some(r.counts.clone()),
                no_staircase: None,
                error: None,
            },
            Err(e) => Self {
                segments: Vec::new(),
                timings_ms: None,
                counts: None,
                no_staircase: match e {
                    PerceptionError::NoStaircase(why) => Some(why.clone()),
                    _ => None,
                },
                error: Some(e.to_string()),
            },
        }
    }
}

/// A sole's place in a stance.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FootMsg {
    /// Sole centre, metres.
    pub position: [f64; 3],
    /// Yaw, radians.
    pub yaw_rad: f64,
}

impl FootMsg {
    fn of(p: &Isometry3<f64>) -> Self {
        let t = p.translation.vector;
        Self { position: [t.x, t.y, t.z], yaw_rad: p.rotation.euler_angles().2 }
    }
}

/// A planned stance.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StanceMsg {
    /// The step stood on (1 = lowest), `None` on the floor.
    pub step: Option<usize>,
    /// Right sole.
    pub right: FootMsg,
    /// Left sole.
    pub left: FootMsg,
}

/// A segment of the gait.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SegmentMsg {
    /// Its phase (§6.1).
    pub phase: Phase,
    /// Its stance (1 = first).
    pub stance: usize,
    /// Duration, seconds.
    pub duration_s: f64,
    /// CoM at its start, metres.
    pub com_start: [f64; 3],
    /// CoM at its end, metres.
    pub com_end: [f64; 3],
    /// The static-stability polygon, [[x, y]] counter-clockwise, metres.
    pub polygon: Vec<[f64; 2]>,
    /// The CoM path's least margin in it, metres.
    pub margin_m: f64,
    /// The feet in contact.
    pub support: Vec<Foot>,
    /// The swinging foot, if any.
    pub swing: Option<Foot>,
}

/// `/plan` (and `plan --json`): a plan's inputs, footholds, segments and figures.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlanMsg {
    /// When it starts (the robot's clock), seconds.
    pub start_s: f64,
    /// The configuration it starts from (qpos layout).
    pub q0: Vec<f64>,
    /// The steps it was made on (the known steps ahead).
    pub steps: Vec<PlaneSegment>,
    /// The stances.
    pub stances: Vec<StanceMsg>,
    /// The segments.
    pub segments: Vec<SegmentMsg>,
    /// Duration of the motion, seconds.
    pub duration_s: f64,
    /// The smallest CoM margin over the segments, metres.
    pub min_margin_m: f64,
    /// How closely q(t) follows the gait.
    pub tracking: Tracking,
    /// The IK's rate, Hz.
    pub rate_hz: f64,
    /// Samples of q(t).
    pub samples: usize,
}

fn xyz(p: &Point3<f64>) -> [f64; 3] {
    [p.x, p.y, p.z]
}

impl PlanMsg {
    /// The message of `plan`, made on `steps`, starting at `start_s`.
    pub fn of(start_s: f64, steps: &[PlaneSegment], plan: &Plan) -> Self {
        let stances = plan
            .stances
            .iter()
            .map(|s| StanceMsg {
                step: s.step.map(|i| i + 1),
                right: FootMsg::of(&s.right),
                left: FootMsg::of(&s.left),
            })
            .collect();
        let segments = plan
            .segments
            .iter()
            .map(|s| SegmentMsg {
                phase: s.phase,
                stance: s.stance + 1,
                duration_s: s.duration_s,
                com_start: xyz(&s.com_start),
                com_end: xyz(&s.com_end),
                polygon: s.polygon.iter().map(|p| [p.x, p.y]).collect(),
                margin_m: s.margin_m,
                support: s.support.iter().map(|(f, _)| *f).collect(),
                swing: s.swing.as_ref().map(|w| w.foot),
            })
            .collect();
        Self {
            start_s,
            q0: plan.trajectory.samples.first().map(|s| s.q.clone()).unwrap_or_default(),
            steps: steps.to_vec(),
            stances,
            segments,
            duration_s: plan.duration_s(),
            min_margin_m: plan.min_margin_m(),
            tracking: plan.tracking.clone(),
            rate_hz: plan.trajectory.rate_hz,
            samples: plan.trajectory.samples.len(),
        }
    }

    /// The first part in which `other` is another plan (its inputs, footholds, segments or
    /// duration; not its start time or the wall times in `tracking`), `None` when the same.
    pub fn differs_from(&self, other: &PlanMsg) -> Option<&'static str> {
        if self.steps != other.steps {
            Some("steps")
        } else if self.stances != other.stances {
            Some("stances")
        } else if self.segments != other.segments {
            Some("segments")
        } else if self.duration_s != other.duration_s {
            Some("duration_s")
        } else {
            None
        }
    }
}

/// `plan --json`: the planner's verdict, and the plan when there is one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlanReport {
    /// A plan was made.
    pub ok: bool,
    /// The refusal's message, when refused.
    pub reason: Option<String>,
    /// The refusal as data, when refused.
    pub refusal: Option<Refusal>,
    /// Planning wall time, seconds.
    pub wall_s: f64,
    /// The lowest step left for a closer look, with every step above it, as the closed loop
    /// leaves it (seen shallower than a foot needs while lower steps remain:
    /// [`without_partial_top`](crate::perception::step_map::without_partial_top)): the
    /// refusal it would have met. The plan climbs the steps below it, the step bounding the
    /// tread below it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub closer_look: Option<Refusal>,
    /// The plan.
    #[serde(flatten)]
    pub plan: Option<PlanMsg>,
}

/// `/plan/trajectory`: q(t) and the CoM as planned.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrajectoryMsg {
    /// Rate, Hz.
    pub rate_hz: f64,
    /// Joint names (the columns of `q` after the base's 7).
    pub names: Vec<String>,
    /// Sample times from the plan's start, seconds.
    pub t_s: Vec<f64>,
    /// Configurations (base position, quaternion w x y z, joints).
    pub q: Vec<Vec<f64>>,
    /// Planned CoM, metres.
    pub com: Vec<[f64; 3]>,
}

impl TrajectoryMsg {
    /// The message of `plan`'s trajectory.
    pub fn of(plan: &Plan, names: &[String]) -> Self {
        let samples = &plan.trajectory.samples;
        Self {
            rate_hz: plan.trajectory.rate_hz,
            names: names.to_vec(),
            t_s: samples.iter().map(|s| s.t_s).collect(),
            q: samples.iter().map(|s| s.q.clone()).collect(),
            com: samples.iter().map(|s| xyz(&s.com)).collect(),
        }
    }
}

/// `/run/view`: the configuration a sweep's view was taken into the step map and the
/// surroundings from ([`crate::climb::Event::View`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ViewMsg {
    /// The sweep's stamp, seconds.
    pub stamp_s: f64,
    /// The configuration (qpos: base position, quaternion w x y z, joints).
    pub q: Vec<f64>,
    /// The look was set aside to look again standing: its steps left the step map again.
    #[serde(default)]
    pub set_aside: bool,
}

/// `/robot/joints`: the robot at an instant (100 Hz).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointStateMsg {
    /// Joint names.
    pub names: Vec<String>,
    /// Joint positions, radians.
    pub positions_rad: Vec<f64>,
    /// Base position, metres.
    pub position: [f64; 3],
    /// Base orientation [w, x, y, z].
    pub orientation: [f64; 4],
    /// Each foot's resultant contact force, world frame, newtons (right, left).
    pub foot_forces_n: Vec<[f64; 3]>,
    /// The CoM's margin in the polygon of the real contacts (`None` without one), metres.
    pub margin_m: Option<f64>,
    /// The largest torque demand over its limit.
    pub max_torque_ratio: f64,
}
