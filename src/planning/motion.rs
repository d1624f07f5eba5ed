//! The whole-body trajectory (§6.1): the gait's CoM and free-foot paths tracked by the QP
//! IK of [`super::ik`] at a fixed rate, giving q(t) sampled as a [`JointTrajectory`], with
//! what it reached (CoM, feet) and how closely it tracked.

use super::clearance::{self, Limb, Nearest, ProbeCache, SeenPoints};
use super::gait::{ease, Segment, Swing, DEFAULT_SPEEDUP};
use super::ik::{self, Task};
use super::stance::Foot;
use super::PlanError;
use crate::robot::hrp4;
use crate::robot::model::{normalize_base_rotation, RobotError, RobotModel};
use crate::robot::momentum::{centroidal_angular_momentum, MomentRates};
use crate::robot::Kinematics;
use crate::scene::SceneBox;
use nalgebra::{Isometry3, Point3, Translation3, Vector6};
use std::sync::Arc;
use std::time::Instant;

/// The IK's weights and gains (§6.1). The rates (the gains per second, the speed bounds)
/// written beside each field are those of the quasi-static timing
/// ([`IkParams::quasi_static`]); the default is them [`DEFAULT_SPEEDUP`] times, with the
/// gait's ([`IkParams::faster`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct IkParams {
    /// Samples per second of the trajectory (one QP per sample). 100 Hz: against 200 Hz
    /// it halves the planning time, and on Exp. 1 the CoM still tracks within 0.9 mm (0.45)
    /// and the feet land within 0.1 mm (0.05); the servos interpolate q(t) at 1 kHz.
    pub rate_hz: f64,
    /// §6.1 objective (1): CoM deviation, w_CoM = 1.
    pub weight_com: f64,
    /// §6.1 objective (2): free foot pose deviation, w_free = 0.2.
    pub weight_free_foot: f64,
    /// §6.1 objective (3): deviation from the reference posture, w_ref = 0.001.
    pub weight_posture: f64,
    /// Weight of the base's orientation task (the pelvis held upright, facing where the feet
    /// point), beyond the paper, whose objective (3) holds the posture alone: by default the
    /// posture's. The IK reaches the CoM partly by bowing the waist, and a quick roll of a
    /// bowed pelvis before a touchdown swings the landing sole sideways in simulation (the
    /// servos lag it). Raised, the waist bows less but the legs take the reach, and over
    /// `regress real` the landings' friction ratios rose at ten times this; at a hundred
    /// times the base task fights the CoM's (CHANGELOG's fifteenth session has the figures).
    pub weight_base_orientation: f64,
    /// Gain turning CoM and foot errors into velocities, 1/s.
    pub task_gain_per_s: f64,
    /// K_ref of the posture term, 1/s.
    pub posture_gain_per_s: f64,
    /// Gain removing integration drift from the contacts (0 = the paper's J qd = 0), 1/s.
    pub contact_gain_per_s: f64,
    /// Largest linear speed at which a contact's drift correction moves the sole toward its
    /// target, m/s. Offline the drift is under a millimetre and this never binds; online the
    /// stabilizer may move a contact by centimetres at once (a foot held where it landed).
    pub max_contact_correction_m_s: f64,
    /// Largest angular speed of the same correction, rad/s.
    pub max_contact_correction_rad_s: f64,
    /// §6.1 constraint (2): the fixed maximum joint speed qd_max, rad/s (small, so the
    /// motion stays near quasi-static).
    pub max_joint_speed_rad_s: f64,
    /// §6.1 constraint (2): K, the DOF-limit velocity gain, 1/s.
    pub limit_gain_per_s: f64,
    /// Damping on every velocity (keeps the QP strictly convex).
    pub damping: f64,
    /// The interior-point solver's tolerance (duality gap, feasibility), for the QPs the
    /// active sets leave to it, rad/s: 1e-4 gives the same
    /// tracking on Exp. 1 as 1e-7 (CoM 0.9 mm, feet 0.1 mm) with 27 % less time per tick.
    pub qp_tolerance: f64,
    /// Solve each tick's QP by active sets first, starting from the limits that bound the
    /// tick before (exact; clarabel when a few guesses do not find the optimum): the limits
    /// that bind change little from one tick to the next: clarabel solved none of the 7745
    /// QPs of Exp. 1's ground-truth plan, and about 1 in 80 over a closed-loop Exp. 1 climb
    /// (plan, online IK and wrench distribution). `false`: clarabel for every QP, to compare
    /// (`bench plan`).
    pub active_set: bool,
    /// Largest CoM tracking error accepted, metres; beyond, the plan is refused.
    pub com_tolerance_m: f64,
    /// Largest free-foot error at touchdown accepted, metres.
    pub foot_tolerance_m: f64,
    /// Least distance kept between a leg capsule (thigh, shank) and a step, metres (the
    /// purpose §6.1 gives its posture term, held as a constraint; see `clearance`). 3 cm:
    /// a perceived riser may sit half a voxel (1 cm) behind the true one, and with 2 cm the
    /// trailing shank touched the 24 cm step's nose in simulation.
    pub leg_clearance_m: f64,
    /// Distance from a step below which a leg's clearance constraint is active, metres.
    pub clearance_range_m: f64,
    /// Gain of the clearance's velocity damper, 1/s: the clearance may shrink at most this
    /// times its excess over `leg_clearance_m`.
    pub clearance_gain_per_s: f64,
    /// Least distance kept between the rest of the body (arms, trunk, head) and every
    /// surface the lidar saw, metres, measured to the surroundings' voxel centroids (so a
    /// noisy wall's nearest centroids stand a little proud of it), and between the legs
    /// (thigh, shank) and every such surface off the steps and the floor
    /// (`leg_surface_band_m`). 3 cm, as the legs from the steps.
    pub body_clearance_m: f64,
    /// Least distance a plan may bring the rest of the body (arms, trunk, head) to a
    /// surface the lidar saw, metres, or it is refused: the clearance the IK keeps
    /// (`body_clearance_m`) holds each capsule off a few witnesses near it
    /// (`clearance::Probe::Near`), and between two
    /// surfaces (a chest between two handrails) or past a noisy one it gives way; the body
    /// executed sways about its plan, ±20 mm measured on the chest under the stabilizer
    /// (regression `chest-between-two-rails`'s recording), so a plan nearer than that
    /// touches. 2 cm.
    pub min_body_clearance_m: f64,
    /// The surroundings' points within this of a step solid, or of the floor under the
    /// start, are the steps' and the floor's own surfaces, which the legs are not kept off
    /// by `body_clearance_m` (their feet stand on them; `leg_clearance_m` keeps the legs off
    /// the steps), metres: three standard deviations of the suites' highest range noise,
    /// 25 mm (the `wide` suite's), plus half a 3 cm voxel: a riser's or a tread's voxels
    /// stray that far (at 3 sigma of 20 mm, strays of treads under 21-25 mm of noise keep
    /// the legs off and leave the IK no solution).
    pub leg_surface_band_m: f64,
    /// Least knee bend the IK allows a leg carrying weight (a support, or lifting off: see
    /// [`ik_lower_limits`]), radians (HRP-4's knee stops at 0, straight). Near
    /// straight a leg is a strut: a sole's height, which the stabilizer's foot force
    /// difference control moves through the knee, takes 1/(l sin(knee/2)) of knee per metre
    /// (l = 0.353 m, thigh and shank), so the leg's axial stiffness grows as
    /// 1/sin^2(knee/2): at 0.1 rad 50 times half-sitting's (0.72 rad), and what the leg
    /// carries runs along it, tangential to the tread as much as the leg leans (regression
    /// `trailing-knee-straightened-into-a-strut`). 0.2 rad keeps that stiffness within 12
    /// times half-sitting's, below the loaded knees of Exp. 1's, Exp. 2's and the 24 cm
    /// step's plans (32, 30 and 26 deg, `stairbench plan`).
    pub min_knee_rad: f64,
    /// Largest share of the support soles' friction torque a plan's turn about the vertical
    /// may ask ([`Tracking::max_yaw_moment_nm`] against `StepParams::friction` times the
    /// weight times a sole's mean distance from its centre, the torque a sole at uniform
    /// pressure holds before it turns): where a segment asks more, the planner slows it and
    /// tracks again (see `plan`). Half: the friction is shared with the forces along the
    /// tread, and the pressure under a sole is not uniform; for HRP-4 on the plan's
    /// friction, 9.8 N m. A plan whose trunk twisted away from unseen space asked 21 N m of
    /// the 19.5 N m, and its stance sole slid (test
    /// `a_trunk_twisted_fast_off_unseen_space_is_slowed_until_the_sole_holds_it`).
    pub max_yaw_moment_share: f64,
}

impl Default for IkParams {
    /// The IK of the quasi-static timing made as much faster as the gait's default
    /// ([`DEFAULT_SPEEDUP`]): every rate that many times.
    fn default() -> Self {
        Self::quasi_static().faster(DEFAULT_SPEEDUP)
    }
}

impl IkParams {
    /// The IK with the quasi-static timing ([`super::gait::StepParams::quasi_static`]): the
    /// gains, correction speeds and joint speed bound as written beside each field.
    pub fn quasi_static() -> Self {
        Self {
            rate_hz: 100.0,
            weight_com: 1.0,
            weight_free_foot: 0.2,
            weight_posture: 0.001,
            weight_base_orientation: 0.001,
            task_gain_per_s: 40.0,
            posture_gain_per_s: 0.5,
            contact_gain_per_s: 40.0,
            max_contact_correction_m_s: 0.1,
            max_contact_correction_rad_s: 0.5,
            max_joint_speed_rad_s: 1.0,
            limit_gain_per_s: 5.0,
            damping: 1e-6,
            qp_tolerance: 1e-4,
            active_set: true,
            com_tolerance_m: 0.01,
            foot_tolerance_m: 0.005,
            leg_clearance_m: 0.03,
            clearance_range_m: 0.08,
            clearance_gain_per_s: 5.0,
            body_clearance_m: 0.03,
            min_body_clearance_m: 0.02,
            leg_surface_band_m: 0.09,
            min_knee_rad: 0.2,
            max_yaw_moment_share: 0.5,
        }
    }

    /// The same tracking `factor` times faster: every rate (the gains per second, the speed
    /// bounds) `factor` times, so that the IK follows a plan made `factor` times faster along
    /// the same path. Its tasks converge at their gains per second: left alone, a faster plan
    /// leaves them less time, and the pelvis of a robot started turned from the flight turns
    /// less of the way (test `a_plan_made_faster_is_the_same_path_in_less_time`).
    pub fn faster(&self, factor: f64) -> Self {
        Self {
            task_gain_per_s: self.task_gain_per_s * factor,
            posture_gain_per_s: self.posture_gain_per_s * factor,
            contact_gain_per_s: self.contact_gain_per_s * factor,
            max_contact_correction_m_s: self.max_contact_correction_m_s * factor,
            max_contact_correction_rad_s: self.max_contact_correction_rad_s * factor,
            max_joint_speed_rad_s: self.max_joint_speed_rad_s * factor,
            limit_gain_per_s: self.limit_gain_per_s * factor,
            clearance_gain_per_s: self.clearance_gain_per_s * factor,
            ..self.clone()
        }
    }
}

/// One sample of the trajectory.
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    /// Time from the start, seconds.
    pub t_s: f64,
    /// Configuration (layout of [`crate::robot::model`]).
    pub q: Vec<f64>,
    /// CoM reached.
    pub com: Point3<f64>,
    /// CoM wanted.
    pub com_ref: Point3<f64>,
    /// Right and left sole poses reached.
    pub feet: [Isometry3<f64>; 2],
    /// Index of the segment.
    pub segment: usize,
}

/// q(t) at a fixed rate.
#[derive(Debug, Clone, PartialEq)]
pub struct JointTrajectory {
    /// Samples per second.
    pub rate_hz: f64,
    /// The samples, from t = 0.
    pub samples: Vec<Sample>,
}

impl JointTrajectory {
    /// Duration, seconds.
    pub fn duration_s(&self) -> f64 {
        self.samples.last().map_or(0.0, |s| s.t_s)
    }

    /// The sample at or just before `t_s` (clamped to the ends).
    pub fn sample_at(&self, t_s: f64) -> &Sample {
        let i = ((t_s * self.rate_hz).max(0.0) as usize).min(self.samples.len().saturating_sub(1));
        &self.samples[i]
    }

    /// The configuration at `t_s`, linearly interpolated (the base quaternion normalized),
    /// written into `q`.
    pub fn q_at(&self, t_s: f64, q: &mut [f64]) {
        let n = self.samples.len();
        if n == 0 {
            return;
        }
        let x = (t_s * self.rate_hz).clamp(0.0, (n - 1) as f64);
        let i = (x.floor() as usize).min(n - 1);
        let j = (i + 1).min(n - 1);
        let f = x - i as f64;
        for (k, qk) in q.iter_mut().enumerate() {
            *qk = self.samples[i].q[k] * (1.0 - f) + self.samples[j].q[k] * f;
        }
        normalize_base_rotation(q);
    }
}

/// How well the IK tracked the gait.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Tracking {
    /// Largest CoM error over the trajectory, metres.
    pub max_com_error_m: f64,
    /// Largest free-foot position error at touchdown, metres.
    pub max_touchdown_error_m: f64,
    /// Largest displacement of a contact from where it was set, metres.
    pub max_contact_drift_m: f64,
    /// Least distance between a leg capsule and a step over the trajectory, metres; `None`
    /// when no step came within `clearance_range_m` of the legs.
    pub min_leg_clearance_m: Option<f64>,
    /// Least distance between the rest of the body and a surface the lidar saw, and where;
    /// `None` when none came within `clearance_range_m`.
    #[serde(default)]
    pub nearest_body_surface: Option<NearestSurface>,
    /// Least distance between the rest of the body and the edge of space the lidar left
    /// unseen, and where (each capsule's clearance row keeps it off its nearest point, seen
    /// or unseen: a nearer seen surface elsewhere does not hide a capsule held off unseen
    /// space); `None` when none came within `clearance_range_m`.
    #[serde(default)]
    pub nearest_unseen_surface: Option<NearestSurface>,
    /// QPs solved (over every round of tracking the plan took, see [`super::reach`]).
    pub ik_ticks: usize,
    /// Of them, the QPs the active sets did not solve and clarabel did (all of them with
    /// `IkParams::active_set` off).
    #[serde(default)]
    pub ik_interior_point_qps: usize,
    /// Wall time in the IK (kinematics, QP build, solve), seconds, over every round.
    pub ik_time_s: f64,
    /// Largest tilt of the base (the waist) from upright over the trajectory, radians: the
    /// IK keeps the CoM on its path by bowing the body where the legs cannot take it there
    /// (their clearance from the steps holds the knees back).
    #[serde(default)]
    pub max_base_tilt_rad: f64,
    /// Least knee bend of a leg carrying weight (a support, or lifting off) over the
    /// trajectory, radians (see `IkParams::min_knee_rad`); `None` without one.
    #[serde(default)]
    pub min_loaded_knee_rad: Option<f64>,
    /// Largest rate of change of the body's angular momentum about its CoM (over
    /// [`crate::robot::momentum::RATE_WINDOW_S`]), about a horizontal axis, N m: the
    /// quasi-static plan keeps the CoM over its polygon, and this much moment moves the ZMP
    /// off the CoM's projection by its ratio to the weight.
    #[serde(default)]
    pub max_tipping_moment_nm: f64,
    /// ... about the vertical, N m: the turn the support soles hold by friction.
    #[serde(default)]
    pub max_yaw_moment_nm: f64,
    /// The largest moment about the vertical asked in each segment, N m: of every window
    /// whose motion it takes part in (a window over a boundary counts for both segments).
    #[serde(skip)]
    pub segment_yaw_moments_nm: Vec<f64>,
}

impl Tracking {
    /// The largest moments the motion's change of angular momentum asks, N m: about a
    /// horizontal axis, and about the vertical.
    pub fn moments_nm(&self) -> [f64; 2] {
        [self.max_tipping_moment_nm, self.max_yaw_moment_nm]
    }
}

/// Where the body came nearest a surface the lidar saw.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct NearestSurface {
    /// Distance from the capsule's surface to the point, metres (negative: inside it).
    pub clearance_m: f64,
    /// The body's capsule (its link's name).
    pub limb: String,
    /// The seen point (a voxel's centroid, or an unseen voxel's centre), world frame, metres.
    pub point_m: [f64; 3],
    /// Whether the point is of the edge of the unseen space, not a surface.
    #[serde(default)]
    pub unseen: bool,
    /// The trajectory's time, seconds.
    pub t_s: f64,
    /// The segment it was in (0-based).
    #[serde(default)]
    pub segment: usize,
}

/// The free foot's pose and twist at fraction `tau` of its swing; `duration_s` scales the twist.
/// The lift's pieces are one stretch of the time law ([`Swing::shares`]), each other piece
/// its own.
fn along_path(sw: &Swing, tau: f64, duration_s: f64) -> (Isometry3<f64>, Vector6<f64>) {
    let lift = sw.lift_pieces();
    let stretches = std::iter::once(0..lift.max(1)).chain((lift.max(1)..sw.shares.len()).map(|k| k..k + 1));
    let mut start = 0.0;
    for stretch in stretches {
        let share: f64 = sw.shares[stretch.clone()].iter().sum();
        if tau > start + share && stretch.end < sw.shares.len() {
            start += share;
            continue;
        }
        if share <= 0.0 {
            return (sw.path[stretch.end], Vector6::zeros());
        }
        let (s, ds) = ease((tau - start) / share);
        // The sole turns over the stretch as a whole, from its first pose's orientation to
        // its last's (the lift's poses before its top are level).
        let dt_stretch = share * duration_s;
        let (r0, r1) = (sw.path[stretch.start].rotation, sw.path[stretch.end].rotation);
        let r = r0.slerp(&r1, s);
        let omega = (r1 * r0.inverse()).scaled_axis() * ds / dt_stretch;
        // Its path: the stretch's pieces in turn, each over its share (`at`, a fraction of
        // the stretch's path, and of the piece's `u`).
        let mut at = s;
        for k in stretch.clone() {
            let piece = sw.shares[k] / share;
            if at > piece && k + 1 < stretch.end {
                at -= piece;
                continue;
            }
            let (w0, w1) = (&sw.path[k], &sw.path[k + 1]);
            let (u, dt_piece) =
                if piece > 0.0 { ((at / piece).min(1.0), dt_stretch * piece) } else { (1.0, f64::INFINITY) };
            let p = w0.translation.vector.lerp(&w1.translation.vector, u);
            let v = (w1.translation.vector - w0.translation.vector) * ds / dt_piece;
            let pose = Isometry3::from_parts(Translation3::from(p), r);
            return (pose, Vector6::new(v.x, v.y, v.z, omega.x, omega.y, omega.z));
        }
    }
    (sw.path[sw.path.len() - 1], Vector6::zeros())
}

/// The joints' lower limits the IK keeps, radians, in the model's joint order: the model's,
/// but the knees of the feet `loaded` (right then left: those carrying weight), which stay
/// `p.min_knee_rad` from straight. A leg in the air keeps the model's limit: it carries
/// nothing, and held bent it reaches by turning the pelvis instead, a shoulder toward the
/// steps ahead (regression `riser-strays-under-the-floor-toes`); where it lands is
/// [`super::reach`]'s. A foot lifting off counts as loaded ([`lifting`]): its sole still
/// bounces on the tread (regression `trailing-knee-straightened-into-a-strut`).
pub fn ik_lower_limits(model: &RobotModel, loaded: [bool; 2], p: &IkParams) -> Result<Vec<f64>, RobotError> {
    let mut lower: Vec<f64> = model.joints().iter().map(|j| j.lower_rad).collect();
    set_knee_limits(&mut lower, model, hrp4::knee_joints(model)?, loaded, p);
    Ok(lower)
}

/// The knees' entries of `lower` (the IK's lower limits) for the feet `loaded`.
fn set_knee_limits(
    lower: &mut [f64],
    model: &RobotModel,
    knees: [usize; 2],
    loaded: [bool; 2],
    p: &IkParams,
) {
    for (k, down) in knees.into_iter().zip(loaded) {
        let own = model.joints()[k].lower_rad;
        lower[k] = if down { own.max(p.min_knee_rad) } else { own };
    }
}

/// The joints of the upper body: every joint not on a chain from the root to a foot
/// (§6.1 holds these near the reference posture).
pub fn upper_body_mask(model: &RobotModel, feet: &[usize]) -> Vec<bool> {
    let mut mask = vec![true; model.joints().len()];
    for &f in feet {
        let mut link = Some(model.frames()[f].link);
        while let Some(l) = link {
            if let Some(j) = model.links()[l].joint {
                mask[j] = false;
            }
            link = model.links()[l].parent;
        }
    }
    mask
}

/// Clearance rows for `limbs` into `g`: with `fixed`, one row per capsule (a fixed count
/// keeps the QP's shape; the legs, near a step at every stride), the damper of its nearest
/// obstacle (`witnesses`' first) when one is within range, else a row of zeros; without, a row per
/// capsule with an obstacle in range only (the rest of the body, rarely near anything: a
/// row of zeros per arm, trunk and head shape made every open-flight IK tick 23 % dearer);
/// and, without `fixed`, a row more for each other witness `witnesses` gives (see
/// [`clearance::Probe::Near`]). Returns the least clearance and which capsule (index in `limbs`) and obstacle it is
/// between, and the same of the obstacles `marked` only.
#[allow(clippy::too_many_arguments)]
fn clearance_rows(
    kin: &Kinematics,
    jac: &mut nalgebra::Matrix6xX<f64>,
    limbs: &[Limb],
    mut witnesses: impl FnMut(usize, &Limb) -> Vec<Nearest>,
    min_m: f64,
    gain_per_s: f64,
    g: &mut ik::Inequality,
    fixed: bool,
    marked: impl Fn(usize) -> bool,
) -> [Option<(f64, usize, usize)>; 2] {
    // A row per witness of each limb, the nearest first (with none, an inactive row where
    // the rows are `fixed`).
    let mut rows: Vec<(usize, Option<Nearest>, bool)> = Vec::with_capacity(limbs.len());
    for (i, limb) in limbs.iter().enumerate() {
        let near = witnesses(i, limb);
        debug_assert!(!fixed || near.len() <= 1, "fixed rows hold one obstacle a capsule");
        if near.is_empty() && fixed {
            rows.push((i, None, true));
        }
        rows.extend(near.into_iter().enumerate().map(|(k, n)| (i, Some(n), k == 0)));
    }
    if g.bound.len() != rows.len() {
        *g = ik::Inequality {
            jacobian: nalgebra::DMatrix::zeros(rows.len(), jac.ncols()),
            bound: nalgebra::DVector::zeros(rows.len()),
        };
    }
    let mut least: [Option<(f64, usize, usize)>; 2] = [None, None];
    for (r, (i, near, first)) in rows.into_iter().enumerate() {
        g.jacobian.row_mut(r).fill(0.0);
        g.bound[r] = 1.0;
        if let Some(near) = near {
            g.bound[r] =
                ik::clearance(kin, jac, limbs[i].link, &near, min_m, gain_per_s, g.jacobian.row_mut(r));
            // The least clearances are of the nearest points (the other witnesses are farther).
            for (k, kept) in [first, first && marked(near.block)].into_iter().enumerate() {
                if kept && least[k].is_none_or(|(d, _, _)| near.clearance_m < d) {
                    least[k] = Some((near.clearance_m, i, near.block));
                }
            }
        }
    }
    least
}

/// What one IK tick tracks: the CoM (position, velocity), the free foot (pose, twist), and the
/// feet held in contact (their poses).
#[derive(Debug, Clone)]
pub struct Targets<'a> {
    /// CoM wanted, world frame.
    pub com: Point3<f64>,
    /// CoM velocity wanted (feed-forward), m/s.
    pub com_velocity: nalgebra::Vector3<f64>,
    /// The free foot, its pose and twist (linear, angular; world).
    pub swing: Option<(Foot, Isometry3<f64>, Vector6<f64>)>,
    /// The feet held in contact and where.
    pub support: &'a [(Foot, Isometry3<f64>)],
    /// The swinging foot while it lifts off ([`lifting`]), right then left: its knee, as a
    /// support's, stays `min_knee_rad` from straight ([`ik_lower_limits`]).
    pub lifting: [bool; 2],
}

impl Targets<'_> {
    /// The feet whose knees stay bent: the supports and the foot lifting off, right then left.
    fn loaded(&self) -> [bool; 2] {
        Foot::BOTH.map(|f| self.lifting[f.index()] || self.support.iter().any(|(s, _)| *s == f))
    }
}

/// The swinging foot of `seg` at fraction `tau` while in its swing's lift, every piece but
/// the last two (right then left): the sole leaves the ground then, and in its first ticks
/// it still bounces on it and carries weight.
pub fn lifting(seg: &Segment, tau: f64) -> [bool; 2] {
    let mut out = [false; 2];
    if let Some(sw) = &seg.swing {
        out[sw.foot.index()] = tau < sw.lift_share();
    }
    out
}

/// The QP IK of §6.1 as a stream of ticks from a configuration: the planner runs it over the
/// gait ([`track`]), the stabilizer online with corrected targets. It keeps its own
/// configuration (integrated from the velocities it solves, as a robot's controller does).
pub struct Tracker<'m> {
    model: &'m RobotModel,
    p: IkParams,
    kin: Kinematics<'m>,
    feet: [usize; 2],
    q: Vec<f64>,
    q_ref: Vec<f64>,
    upper: Vec<bool>,
    /// The joints' lower limits the IK keeps ([`ik_lower_limits`]), set each tick for the
    /// feet then down.
    lower_rad: Vec<f64>,
    /// The knee joints, right then left.
    knees: [usize; 2],
    limbs: Vec<Limb>,
    blocks: Vec<SceneBox>,
    upper_limbs: Vec<Limb>,
    seen: Arc<SeenPoints>,
    probes: ProbeCache,
    /// The seen points off the steps and the floor: what the legs are kept off.
    leg_seen: SeenPoints,
    leg_probes: ProbeCache,
    base_ref: nalgebra::UnitQuaternion<f64>,
    com_jac: nalgebra::Matrix3xX<f64>,
    frame_jac: nalgebra::Matrix6xX<f64>,
    qp: ik::Solver,
    /// The legs' clearance rows from the steps, the rest of the body's from the seen
    /// surfaces, the legs' from the seen surfaces off the steps.
    clear: [ik::Inequality; 3],
    least: Option<(f64, usize, usize)>,
    least_body: Option<(f64, usize, usize)>,
    least_unseen: Option<(f64, usize, usize)>,
    least_leg_surface: Option<(f64, usize, usize)>,
}

impl<'m> Tracker<'m> {
    /// A tracker from configuration `q0` (the posture term holds the upper body toward
    /// half-sitting; the base task holds the base upright, facing where the feet point), keeping the legs `p.leg_clearance_m`
    /// off `blocks` and the rest of the body `p.body_clearance_m` off the `seen` surfaces, the
    /// legs as far off those of them off the steps and the floor under the soles at `q0`
    /// ([`SeenPoints::off_the_steps`]).
    pub fn new(
        model: &'m RobotModel,
        q0: &[f64],
        blocks: &[SceneBox],
        seen: Arc<SeenPoints>,
        p: &IkParams,
    ) -> Result<Self, PlanError> {
        let mut kin = Kinematics::new(model);
        kin.update(q0)?;
        let feet = hrp4::sole_frames(model)?;
        let upper = upper_body_mask(model, &feet);
        let limbs = clearance::limbs(model, &feet);
        let upper_limbs = clearance::upper_limbs(model, &feet);
        let floor_z = feet.iter().map(|&f| kin.frame_pose(f).translation.z).fold(f64::INFINITY, f64::min);
        let leg_seen = seen.off_the_steps(blocks, floor_z, p.leg_surface_band_m);
        // The base held upright: a reference taken from q0 as it is would keep whatever tilt
        // the last motion left, and the tilts of successive plans would add up (Exp. 2 ended
        // its 11 steps pitched 14 deg forward). Its heading follows the feet (see `tick`);
        // this one is for targets without a foot.
        let (_, _, yaw) = kin.link_pose(0).rotation.euler_angles();
        let base_ref = nalgebra::UnitQuaternion::from_euler_angles(0.0, 0.0, yaw);
        let (com_jac, frame_jac) = (kin.new_com_jacobian(), kin.new_frame_jacobian());
        let legs = ik::Inequality {
            jacobian: nalgebra::DMatrix::zeros(limbs.len(), model.nv()),
            bound: nalgebra::DVector::zeros(limbs.len()),
        };
        let body = ik::Inequality {
            jacobian: nalgebra::DMatrix::zeros(0, model.nv()),
            bound: nalgebra::DVector::zeros(0),
        };
        let legs_off_seen = body.clone();
        let mut t = Self {
            model,
            p: p.clone(),
            kin,
            feet,
            q: q0.to_vec(),
            // §6.1's reference pose, the same for every plan: a reference taken from q0
            // would keep whatever the last plan left, and the upper body's drift would add
            // up over the cycles (regression `chest-between-two-rails`).
            q_ref: hrp4::half_sitting_joints(model)?,
            lower_rad: model.joints().iter().map(|j| j.lower_rad).collect(),
            knees: hrp4::knee_joints(model)?,
            upper,
            limbs,
            blocks: blocks.to_vec(),
            upper_limbs,
            seen,
            probes: ProbeCache::default(),
            leg_seen,
            leg_probes: ProbeCache::default(),
            base_ref,
            com_jac,
            frame_jac,
            qp: ik::Solver::with_tolerance(model.nv(), p.damping, p.qp_tolerance)
                .with_active_set(p.active_set),
            clear: [legs, body, legs_off_seen],
            least: None,
            least_body: None,
            least_unseen: None,
            least_leg_surface: None,
        };
        t.update_clearances();
        Ok(t)
    }

    /// The clearance rows and least clearances at the configuration reached.
    fn update_clearances(&mut self) {
        let (p, kin) = (&self.p, &self.kin);
        let range = p.clearance_range_m;
        self.least = clearance_rows(
            kin,
            &mut self.frame_jac,
            &self.limbs,
            |_, limb| clearance::nearest(kin, limb, &self.blocks, range).into_iter().collect(),
            p.leg_clearance_m,
            p.clearance_gain_per_s,
            &mut self.clear[0],
            true,
            |_| false,
        )[0];
        [self.least_body, self.least_unseen] = clearance_rows(
            kin,
            &mut self.frame_jac,
            &self.upper_limbs,
            |i, limb| self.probes.witnesses(i, &self.seen, limb.capsule(kin), range),
            p.body_clearance_m,
            p.clearance_gain_per_s,
            &mut self.clear[1],
            false,
            |point| self.seen.point(point).is_some_and(|(_, unseen)| unseen),
        );
        self.least_leg_surface = clearance_rows(
            kin,
            &mut self.frame_jac,
            &self.limbs,
            |i, limb| self.leg_probes.witnesses(i, &self.leg_seen, limb.capsule(kin), range),
            p.body_clearance_m,
            p.clearance_gain_per_s,
            &mut self.clear[2],
            false,
            |_| false,
        )[0];
    }

    /// The configuration reached.
    pub fn q(&self) -> &[f64] {
        &self.q
    }

    /// The kinematics at the configuration reached.
    pub fn kinematics(&self) -> &Kinematics<'m> {
        &self.kin
    }

    /// Adds the posture it holds now to `stats`: the base's tilt, and the knees of the feet
    /// `loaded`.
    fn note_posture(&self, loaded: [bool; 2], stats: &mut Tracking) {
        let up = self.kin.link_pose(0).rotation * nalgebra::Vector3::z();
        stats.max_base_tilt_rad = stats.max_base_tilt_rad.max(up.angle(&nalgebra::Vector3::z()));
        for (&k, down) in self.knees.iter().zip(loaded) {
            if down {
                let q = self.q[crate::robot::model::Q_JOINTS + k];
                stats.min_loaded_knee_rad = Some(stats.min_loaded_knee_rad.map_or(q, |m: f64| m.min(q)));
            }
        }
    }

    /// The sole frames, right then left.
    pub fn sole_frames(&self) -> [usize; 2] {
        self.feet
    }

    /// The least clearance between a leg capsule and a step at the configuration reached,
    /// with the capsule's index and the step's (`None` when none is within range).
    pub fn least_clearance(&self) -> Option<(f64, usize, usize)> {
        self.least
    }

    /// The leg capsules' names, by index.
    pub fn limb_name(&self, limb: usize) -> &str {
        &self.limbs[limb].name
    }

    /// The least clearance between the rest of the body and a surface the lidar saw, with
    /// the capsule's index (see [`Tracker::upper_limb_name`]) and the point's (in `seen`).
    pub fn least_body_clearance(&self) -> Option<(f64, usize, usize)> {
        self.least_body
    }

    /// The same, of the edge of the unseen space only (a capsule's nearest point, the one its
    /// row keeps it off, when that is unseen).
    pub fn least_unseen_clearance(&self) -> Option<(f64, usize, usize)> {
        self.least_unseen
    }

    /// The upper body's capsules' names, by index.
    pub fn upper_limb_name(&self, limb: usize) -> &str {
        &self.upper_limbs[limb].name
    }

    /// The surfaces the lidar saw, as this tracker keeps the body off them.
    pub fn seen(&self) -> &SeenPoints {
        &self.seen
    }

    /// The least clearance between a leg capsule and a surface the lidar saw off the steps
    /// and the floor, with the capsule's index (see [`Tracker::limb_name`]) and the point's
    /// (in [`Tracker::leg_seen`]).
    pub fn least_leg_surface_clearance(&self) -> Option<(f64, usize, usize)> {
        self.least_leg_surface
    }

    /// The surfaces the lidar saw off the steps and the floor, as this tracker keeps the
    /// legs off them.
    pub fn leg_seen(&self) -> &SeenPoints {
        &self.leg_seen
    }

    /// One QP toward `targets`, integrated over `dt_s`.
    pub fn tick(&mut self, targets: &Targets, dt_s: f64) -> Result<(), ik::IkError> {
        let p = &self.p;
        let mut tasks: Vec<Task> = vec![ik::com_task(
            &self.kin,
            &mut self.com_jac,
            &targets.com,
            &targets.com_velocity,
            p.task_gain_per_s,
            p.weight_com,
        )];
        if let Some((foot, pose, twist)) = &targets.swing {
            tasks.push(ik::frame_task(
                &self.kin,
                &mut self.frame_jac,
                self.feet[foot.index()],
                pose,
                twist,
                p.task_gain_per_s,
                p.weight_free_foot,
            ));
        }
        tasks.push(ik::posture_task(
            self.model,
            &self.q,
            &self.q_ref,
            &self.upper,
            p.posture_gain_per_s,
            p.weight_posture,
        ));
        let base_ref = feet_heading(targets)
            .map_or(self.base_ref, |yaw| nalgebra::UnitQuaternion::from_euler_angles(0.0, 0.0, yaw));
        tasks.push(ik::base_orientation_task(
            &self.kin,
            &mut self.frame_jac,
            &base_ref,
            p.posture_gain_per_s,
            p.weight_base_orientation,
        ));
        let equalities: Vec<ik::Equality> = targets
            .support
            .iter()
            .map(|(f, pose)| {
                ik::contact(
                    &self.kin,
                    &mut self.frame_jac,
                    self.feet[f.index()],
                    pose,
                    p.contact_gain_per_s,
                    [p.max_contact_correction_m_s, p.max_contact_correction_rad_s],
                )
            })
            .collect();
        set_knee_limits(&mut self.lower_rad, self.model, self.knees, targets.loaded(), p);
        let bounds = [ik::joint_limits(
            self.model,
            &self.q,
            &self.lower_rad,
            p.max_joint_speed_rad_s,
            p.limit_gain_per_s,
        )];
        let qd = self.qp.solve(&tasks, &equalities, &self.clear, &bounds)?;
        ik::integrate(&mut self.q, qd.as_slice(), dt_s);
        self.kin.update(&self.q).map_err(|e| ik::IkError::Setup(e.to_string()))?;
        self.update_clearances();
        Ok(())
    }
}

/// The mean heading of the feet `targets` hold and move (radians about z), `None` without
/// a foot: the base faces where the feet point. Held at its starting heading instead, a
/// robot that starts turned from the flight climbs with its pelvis turned, the hips twisted
/// to point the feet up the steps, and the plan's pelvis can roll the chest to within the
/// body's clearance of a wall, which the IK answers with a sudden yaw (regression
/// `pelvis-held-turned-from-the-flight`).
fn feet_heading(targets: &Targets) -> Option<f64> {
    let poses = targets.support.iter().map(|(_, p)| p).chain(targets.swing.iter().map(|(_, p, _)| p));
    let sum: nalgebra::Vector2<f64> = poses
        .map(|p| {
            let x = p.rotation * nalgebra::Vector3::x();
            nalgebra::Vector2::new(x.x, x.y).try_normalize(1e-9).unwrap_or_else(nalgebra::Vector2::zeros)
        })
        .sum();
    (sum.norm() > 1e-9).then(|| sum.y.atan2(sum.x))
}

/// The free foot's target at fraction `tau` of segment `seg` (`None` without one).
pub fn swing_target(seg: &Segment, tau: f64) -> Option<(Foot, Isometry3<f64>, Vector6<f64>)> {
    seg.swing.as_ref().map(|sw| {
        let (pose, twist) = along_path(sw, tau, seg.duration_s);
        (sw.foot, pose, twist)
    })
}

/// The CoM's position and velocity at fraction `tau` of segment `seg`.
pub fn com_target(seg: &Segment, tau: f64) -> (Point3<f64>, nalgebra::Vector3<f64>) {
    let (s, ds) = ease(tau);
    (seg.com_start + (seg.com_end - seg.com_start) * s, (seg.com_end - seg.com_start) * ds / seg.duration_s)
}

/// `nearest` becomes the upper body's clearance `least` (its value, capsule and point, in
/// `tracker`) at time `t_s` of segment `segment` when it is nearer.
fn note_nearest(
    nearest: &mut Option<NearestSurface>,
    tracker: &Tracker,
    least: (f64, usize, usize),
    t_s: f64,
    segment: usize,
) {
    let (d, limb, point) = least;
    if nearest.as_ref().is_some_and(|n| d >= n.clearance_m) {
        return;
    }
    let (at, unseen) = tracker.seen().point(point).unwrap_or((Point3::origin(), false));
    *nearest = Some(NearestSurface {
        clearance_m: d,
        limb: tracker.upper_limb_name(limb).to_string(),
        point_m: [at.x, at.y, at.z],
        unseen,
        t_s,
        segment,
    });
}

/// Tracks `segments` from configuration `q0`: one QP per sample at `p.rate_hz`, keeping the
/// legs `p.leg_clearance_m` off the `blocks` (the steps, see [`clearance::step_blocks`]) and
/// the whole body `p.body_clearance_m` off the `seen` surfaces (the legs off those off the
/// steps and the floor, see [`Tracker::new`]).
pub fn track(
    model: &RobotModel,
    q0: &[f64],
    segments: &[Segment],
    blocks: &[SceneBox],
    seen: Arc<SeenPoints>,
    p: &IkParams,
) -> Result<(JointTrajectory, Tracking), PlanError> {
    track_until(model, q0, segments, blocks, seen, p, &[], &mut |_, _| Ok(false)).map(|(t, s, _)| (t, s))
}

/// Whether [`track_until`] stops after a segment (its index, the samples so far).
pub type StopAfter<'a> = dyn FnMut(usize, &[Sample]) -> Result<bool, PlanError> + 'a;

/// [`track`], stopped after the first segment `stop(segment, samples so far)` says `true`
/// of (its checks done, the tracking's figures of the segments tracked): the trajectory so
/// far, its tracking and the segment it stopped after (`None` when it tracked them all).
/// `stop`'s error is returned as it is. A segment `slowed[i]` times longer than the gait
/// made it (none where `slowed` has no entry) is tracked with the IK's rates that many
/// times slower ([`IkParams::faster`]): the same path in that much more time, every rate
/// of it, a reconfiguration at the joints' speed bound included, that many times slower.
#[allow(clippy::too_many_arguments)]
pub fn track_until(
    model: &RobotModel,
    q0: &[f64],
    segments: &[Segment],
    blocks: &[SceneBox],
    seen: Arc<SeenPoints>,
    p: &IkParams,
    slowed: &[f64],
    stop: &mut StopAfter<'_>,
) -> Result<(JointTrajectory, Tracking, Option<usize>), PlanError> {
    let mut tracker = Tracker::new(model, q0, blocks, seen, p)?;
    let feet = tracker.sole_frames();
    let dt = 1.0 / p.rate_hz;
    let mut stats = Tracking::default();
    let sample = |kin: &Kinematics, q: &[f64], t_s: f64, com_ref: Point3<f64>, segment: usize| Sample {
        t_s,
        q: q.to_vec(),
        com: kin.com(),
        com_ref,
        feet: [kin.frame_pose(feet[0]), kin.frame_pose(feet[1])],
        segment,
    };
    let mut samples = vec![sample(tracker.kinematics(), tracker.q(), 0.0, tracker.kinematics().com(), 0)];
    let mut t0 = 0.0;
    let mut tick = 0usize;
    let mut worst_com_segment = 0;
    // The link poses of the tick before, for the body's angular momentum over each tick.
    let mut before = tracker.kinematics().link_poses().to_vec();
    // Each momentum labelled with its tick's segment.
    let mut moments = MomentRates::default();
    let mut stopped = None;
    for (si, seg) in segments.iter().enumerate() {
        let k = slowed.get(si).copied().unwrap_or(1.0);
        tracker.p = if k == 1.0 { p.clone() } else { p.faster(1.0 / k) };
        let end = t0 + seg.duration_s;
        while (tick + 1) as f64 * dt <= end + 1e-9 {
            let t = (tick + 1) as f64 * dt;
            let tau = ((t - t0) / seg.duration_s).clamp(0.0, 1.0);
            let (com_ref, com_v) = com_target(seg, tau);
            let started = Instant::now();
            let targets = Targets {
                com: com_ref,
                com_velocity: com_v,
                swing: swing_target(seg, tau),
                support: &seg.support,
                lifting: lifting(seg, tau),
            };
            tracker.tick(&targets, dt).map_err(|error| PlanError::Ik { t_s: t, segment: si, error })?;
            stats.ik_time_s += started.elapsed().as_secs_f64();
            let poses = tracker.kinematics().link_poses();
            if let Some((rate, first)) =
                moments.add(t - dt / 2.0, centroidal_angular_momentum(model, &before, poses, dt), si)
            {
                // Charged to every segment the window spans, from the one its first
                // momentum was taken in: a window over a boundary is both segments'
                // motion, and slowing the later alone may not bring it down.
                stats.segment_yaw_moments_nm.resize(segments.len(), 0.0);
                debug_assert!(first <= si, "a window's first momentum is from a later segment");
                for m in &mut stats.segment_yaw_moments_nm[first..=si] {
                    *m = m.max(rate.z.abs());
                }
            }
            before.copy_from_slice(poses);
            tracker.note_posture(targets.loaded(), &mut stats);
            stats.ik_ticks += 1;
            tick += 1;
            if let Some((d, limb, block)) = tracker.least_clearance() {
                stats.min_leg_clearance_m = Some(stats.min_leg_clearance_m.map_or(d, |m: f64| m.min(d)));
                if d < 0.0 {
                    return Err(PlanError::LimbTouchesStep {
                        segment: si,
                        limb: tracker.limb_name(limb).to_string(),
                        step: block,
                        depth_m: -d,
                        t_s: t,
                    });
                }
            }
            if let Some((d, limb, point)) = tracker.least_unseen_clearance() {
                note_nearest(&mut stats.nearest_unseen_surface, &tracker, (d, limb, point), t, si);
            }
            if let Some((d, limb, point)) = tracker.least_body_clearance() {
                let (at, unseen) = tracker.seen().point(point).unwrap_or((Point3::origin(), false));
                note_nearest(&mut stats.nearest_body_surface, &tracker, (d, limb, point), t, si);
                if d < p.min_body_clearance_m {
                    return Err(PlanError::BodyNearSurface {
                        segment: si,
                        limb: tracker.upper_limb_name(limb).to_string(),
                        point_m: [at.x, at.y, at.z],
                        unseen,
                        clearance_m: d,
                        min_m: p.min_body_clearance_m,
                        t_s: t,
                    });
                }
            }
            if let Some((d, limb, point)) = tracker.least_leg_surface_clearance() {
                if d < 0.0 {
                    let at = tracker.leg_seen().points()[point];
                    return Err(PlanError::BodyTouchesSurface {
                        segment: si,
                        limb: tracker.limb_name(limb).to_string(),
                        point_m: [at.x, at.y, at.z],
                        depth_m: -d,
                        t_s: t,
                    });
                }
            }
            let kin = tracker.kinematics();
            let com_error = (kin.com() - com_ref).norm();
            if com_error > stats.max_com_error_m {
                stats.max_com_error_m = com_error;
                worst_com_segment = si;
            }
            for (f, pose) in &seg.support {
                let at = kin.frame_pose(feet[f.index()]);
                stats.max_contact_drift_m =
                    stats.max_contact_drift_m.max((at.translation.vector - pose.translation.vector).norm());
            }
            samples.push(sample(kin, tracker.q(), t, com_ref, si));
        }
        if let Some(sw) = &seg.swing {
            let f = feet[sw.foot.index()];
            let target = sw.path[sw.path.len() - 1].translation.vector;
            let err = (tracker.kinematics().frame_pose(f).translation.vector - target).norm();
            stats.max_touchdown_error_m = stats.max_touchdown_error_m.max(err);
            if err > p.foot_tolerance_m {
                return Err(PlanError::FootMisses {
                    segment: si,
                    foot: sw.foot,
                    error_m: err,
                    limit_m: p.foot_tolerance_m,
                });
            }
        }
        t0 = end;
        if stop(si, &samples)? {
            stopped = Some(si);
            break;
        }
    }
    stats.ik_interior_point_qps = tracker.qp.interior_point_qps();
    stats.max_tipping_moment_nm = moments.max_tipping_nm;
    stats.max_yaw_moment_nm = moments.max_yaw_nm;
    if stats.max_com_error_m > p.com_tolerance_m {
        return Err(PlanError::ComStrays {
            segment: worst_com_segment,
            error_m: stats.max_com_error_m,
            limit_m: p.com_tolerance_m,
        });
    }
    Ok((JointTrajectory { rate_hz: p.rate_hz, samples }, stats, stopped))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planning::gait::piece_lengths_m;

    fn sole(yaw_deg: f64) -> Isometry3<f64> {
        Isometry3::rotation(nalgebra::Vector3::z() * yaw_deg.to_radians())
    }

    /// The knee: a parcel's voxel 2 cm off the right shank is kept off by the legs'
    /// clearance (`body_clearance_m`, as the arms and trunk); the floor under the soles and
    /// a step's tread, which the feet stand on (the step solids keep the legs off the steps),
    /// are not.
    #[test]
    fn the_legs_are_kept_off_what_the_lidar_saw_off_the_steps_and_the_floor() {
        let model = hrp4::model().expect("the model");
        let q0 = hrp4::half_sitting_at(&model, &Isometry3::identity()).expect("standing at the origin");
        let mut kin = Kinematics::new(&model);
        kin.update(&q0).expect("a configuration");
        let limbs = clearance::limbs(&model, &hrp4::sole_frames(&model).expect("soles"));
        let shank = limbs.iter().find(|l| l.name == "R_KNEE_LINK").expect("the right shank");
        let c = shank.capsule(&kin);
        let mid = Point3::from((c.a.coords + c.b.coords) / 2.0);
        let parcel = mid - nalgebra::Vector3::y() * (c.radius_m + 0.02);
        let floor = Point3::new(mid.x, mid.y, 0.02);
        let step = crate::perception::PlaneSegment::level_along_x(0.3, 0.17, 0.28);
        let blocks = clearance::step_blocks(&[step], -0.1);
        let tread = Point3::new(0.44, 0.0, 0.19);
        let seen = Arc::new(SeenPoints::new(vec![floor, tread, parcel]));
        let tracker = Tracker::new(&model, &q0, &blocks, seen, &IkParams::default()).expect("a tracker");
        assert_eq!(tracker.leg_seen().points(), &[parcel][..], "only the parcel is kept off");
        let (d, limb, point) = tracker.least_leg_surface_clearance().expect("the parcel is near the shank");
        assert_eq!((tracker.limb_name(limb), point), ("R_KNEE_LINK", 0));
        assert!((d - 0.02).abs() < 1e-3, "{d}");
    }

    /// A CoM wanted higher than the legs reach: the IK stretches them as far as it may, and
    /// no further than `min_knee_rad` from straight (with the model's own limit, 0, they go
    /// straight: the property holds because of the limit, not of the posture).
    #[test]
    fn the_knees_stop_short_of_straight_when_the_com_is_wanted_out_of_reach() {
        let model = hrp4::model().expect("the model");
        let q0 = hrp4::half_sitting_at(&model, &Isometry3::identity()).expect("standing at the origin");
        let knees = hrp4::knee_joints(&model).expect("knees");
        let least_knee = |p: &IkParams| {
            let mut tracker =
                Tracker::new(&model, &q0, &[], Arc::new(SeenPoints::new(vec![])), p).expect("a tracker");
            let soles = tracker.sole_frames();
            let kin = tracker.kinematics();
            let support = [(Foot::Right, kin.frame_pose(soles[0])), (Foot::Left, kin.frame_pose(soles[1]))];
            let com = kin.com() + nalgebra::Vector3::new(0.0, 0.0, 0.2);
            let targets = Targets {
                com,
                com_velocity: nalgebra::Vector3::zeros(),
                swing: None,
                support: &support,
                lifting: [false; 2],
            };
            let mut least = f64::INFINITY;
            for _ in 0..300 {
                tracker.tick(&targets, 0.01).expect("a tick");
                least = knees
                    .iter()
                    .map(|&k| tracker.q()[crate::robot::model::Q_JOINTS + k])
                    .fold(least, f64::min);
            }
            least
        };
        let p = IkParams::default();
        let kept = least_knee(&p);
        assert!(kept >= p.min_knee_rad - 1e-6 && kept < p.min_knee_rad + 0.01, "{kept}");
        let straight = least_knee(&IkParams { min_knee_rad: 0.0, ..p.clone() });
        assert!(straight < 0.05, "the model's own limit lets them straighten: {straight}");
    }

    /// Standing on the left foot, the right one wanted out of its reach, forward and down:
    /// in the air its knee straightens as far as the model allows (a leg carrying nothing
    /// is no strut, and held bent it would reach by turning the pelvis), lifting off it
    /// stops at `min_knee_rad` as a support's does.
    #[test]
    fn a_swinging_knee_is_held_bent_only_while_it_lifts_off() {
        let model = hrp4::model().expect("the model");
        let q0 = hrp4::half_sitting_at(&model, &Isometry3::identity()).expect("standing at the origin");
        let right_knee = hrp4::knee_joints(&model).expect("knees")[0];
        let p = IkParams::default();
        let least_knee = |lifting: [bool; 2]| {
            let mut tracker =
                Tracker::new(&model, &q0, &[], Arc::new(SeenPoints::new(vec![])), &p).expect("a tracker");
            let soles = tracker.sole_frames();
            let kin = tracker.kinematics();
            let support = [(Foot::Left, kin.frame_pose(soles[1]))];
            let mut far = kin.frame_pose(soles[0]);
            far.translation.vector += nalgebra::Vector3::new(0.8, 0.0, -0.2);
            let targets = Targets {
                com: kin.com(),
                com_velocity: nalgebra::Vector3::zeros(),
                swing: Some((Foot::Right, far, Vector6::zeros())),
                support: &support,
                lifting,
            };
            let mut least = f64::INFINITY;
            for _ in 0..300 {
                tracker.tick(&targets, 0.01).expect("a tick");
                least = least.min(tracker.q()[crate::robot::model::Q_JOINTS + right_knee]);
            }
            least
        };
        let in_the_air = least_knee([false; 2]);
        assert!(in_the_air < 0.05, "{in_the_air}");
        let lifting_off = least_knee([true, false]);
        assert!(lifting_off >= p.min_knee_rad - 1e-6 && lifting_off < p.min_knee_rad + 0.01, "{lifting_off}");
    }

    /// The swing's pieces before its last two are its lift: the swinging foot is lifting
    /// until they end, no foot of a segment without a swing ever is.
    #[test]
    fn a_foot_lifts_off_until_its_swings_lift_ends() {
        let sw = Swing {
            foot: Foot::Left,
            path: vec![sole(0.0); 4],
            shares: vec![0.25, 0.5, 0.25],
            natural_s: 2.0,
        };
        let seg = |swing: Option<Swing>| Segment {
            phase: super::super::gait::Phase::LiftSwingLeft,
            stance: 0,
            duration_s: 2.0,
            com_start: Point3::origin(),
            com_end: Point3::origin(),
            support: vec![],
            swing,
            polygon: vec![],
            margin_m: 0.0,
        };
        let swinging = seg(Some(sw));
        assert_eq!(lifting(&swinging, 0.1), [false, true]);
        assert_eq!(lifting(&swinging, 0.3), [false, false]);
        assert_eq!(lifting(&seg(None), 0.1), [false, false]);
        // A lift backing away from a riser has more pieces, every one before the last two:
        // the foot lifts through them.
        let backing = Swing {
            foot: Foot::Right,
            path: vec![sole(0.0); 6],
            shares: vec![0.1, 0.1, 0.2, 0.3, 0.3],
            natural_s: 2.0,
        };
        assert_eq!(lifting(&seg(Some(backing.clone())), 0.35), [true, false]);
        assert_eq!(lifting(&seg(Some(backing)), 0.45), [false, false]);
    }

    /// The lift's pieces are one stretch: the foot does not stop at the waypoints between
    /// them, only at the lift's top and after each later piece, and the twist is the pose's
    /// rate of change all along.
    #[test]
    fn a_swing_foot_moves_through_its_lifts_waypoints_without_stopping() {
        let at = |x: f64, z: f64| Isometry3::translation(x, 0.0, z);
        // The lift's top pitched toe down, as `toe_down` may.
        let mut top = at(-0.01, 0.2);
        top.rotation = nalgebra::UnitQuaternion::from_euler_angles(0.0, 0.2, 0.0);
        let path = vec![at(0.0, 0.0), at(0.0, 0.01), at(-0.01, 0.04), top, at(0.3, 0.2), at(0.3, 0.18)];
        let lengths = piece_lengths_m(&path);
        let lift_m: f64 = lengths[..3].iter().sum();
        let mut shares: Vec<f64> = lengths[..3].iter().map(|l| 0.5 * l / lift_m).collect();
        shares.extend([0.3, 0.2]);
        let sw = Swing { foot: Foot::Left, path, shares, natural_s: 2.0 };
        assert_eq!(sw.lift_pieces(), 3);
        let duration_s = 2.0;
        let speed = |tau: f64| along_path(&sw, tau, duration_s).1.xyz().norm();
        // At its inner waypoints the foot moves at no less than a third of the lift's mean
        // speed (the time law's ends are the only stops); at the lift's top it stops.
        let mean = lift_m / (0.5 * duration_s);
        let when = |fraction: f64| {
            let (mut lo, mut hi) = (0.0, 1.0);
            for _ in 0..60 {
                let mid = (lo + hi) / 2.0;
                if ease(mid).0 < fraction {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            0.5 * lo
        };
        for tau in [when(sw.shares[0] / 0.5), when((sw.shares[0] + sw.shares[1]) / 0.5)] {
            assert!(speed(tau) > mean / 3.0, "{} at {tau}", speed(tau));
            let pose = along_path(&sw, tau, duration_s).0;
            assert!(pose.translation.vector.z > 0.0 && pose.translation.vector.z < 0.2);
        }
        // All along the lift its speed is the time law's over the lift's whole length (its
        // pieces' shares going as their lengths).
        for i in 1..1000 {
            let t = i as f64 / 1000.0;
            let want = mean * ease(t).1;
            assert!(
                (speed(0.5 * t) - want).abs() < 1e-9,
                "{} at {t} of the lift, {want} wanted",
                speed(0.5 * t)
            );
        }
        assert!(speed(0.5) < 1e-9 && speed(0.8) < 1e-9 && speed(0.0) < 1e-9);
        // The twist against the pose's finite difference, and no jump in the pose.
        let h = 1e-6;
        for i in 1..1000 {
            let tau = i as f64 / 1000.0;
            let (before, after) =
                (along_path(&sw, tau - h, duration_s).0, along_path(&sw, tau + h, duration_s).0);
            let rate = (after.translation.vector - before.translation.vector) / (2.0 * h * duration_s);
            let turn = (after.rotation * before.rotation.inverse()).scaled_axis() / (2.0 * h * duration_s);
            let twist = along_path(&sw, tau, duration_s).1;
            let (v, omega) = (twist.xyz(), nalgebra::Vector3::new(twist[3], twist[4], twist[5]));
            assert!((rate - v).norm() < 1e-4 * (1.0 + v.norm()), "tau {tau}: {rate:?} against {v:?}");
            assert!(
                (turn - omega).norm() < 1e-4 * (1.0 + omega.norm()),
                "tau {tau}: {turn:?} against {omega:?}"
            );
        }
    }

    #[test]
    fn the_heading_is_the_feet_mean_across_the_wrap() {
        let heading = |support: &[(Foot, Isometry3<f64>)], swing: Option<f64>| {
            let targets = Targets {
                com: Point3::origin(),
                com_velocity: nalgebra::Vector3::zeros(),
                swing: swing.map(|y| (Foot::Right, sole(y), Vector6::zeros())),
                support,
                lifting: [false; 2],
            };
            feet_heading(&targets).map(f64::to_degrees)
        };
        let both = [(Foot::Right, sole(10.0)), (Foot::Left, sole(30.0))];
        assert!((heading(&both, None).unwrap() - 20.0).abs() < 1e-9);
        // A support foot and the swinging one's target count alike.
        assert!((heading(&both[1..], Some(10.0)).unwrap() - 20.0).abs() < 1e-9);
        // 170 and -170 deg are 20 deg apart about 180, not about 0.
        let wrap = [(Foot::Right, sole(170.0)), (Foot::Left, sole(-170.0))];
        assert!((heading(&wrap, None).unwrap().abs() - 180.0).abs() < 1e-9);
        assert_eq!(heading(&[], None), None);
    }
}
