//! The gait (§6.1): five segments per step, each a linear CoM path between two waypoints and,
//! when a foot moves, a swing path that clears the step's nose. Every segment has its own
//! static-stability polygon (§6.2, from the contacts it keeps); both ends of its CoM path
//! must lie inside with a margin. A waypoint too close to an edge is moved toward the middle
//! of the polygons it belongs to; when even that does not give the margin, the plan is refused.

use super::contact::Contact;
use super::dd::DdParams;
use super::polygon::{by_double_description, margin};
use super::stance::{Foot, Stance};
use super::PlanError;
use crate::geom2d::{self, P2};
use crate::robot::{Kinematics, GRAVITY_M_S2};
use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};

/// The five segments of a step (§6.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Phase {
    /// (1) CoM over the left ankle.
    ShiftToLeft,
    /// (2) Right foot to its target, making contact.
    SwingRight,
    /// (3) CoM over the right foot's contact.
    ShiftToRight,
    /// (4) CoM lifts while the left foot reaches its target.
    LiftSwingLeft,
    /// (5) CoM to the middle of the support area.
    Centre,
}

/// A foot in the air: its sole's path as poses, each piece with its share of the time.
#[derive(Debug, Clone, PartialEq)]
pub struct Swing {
    /// The moving foot.
    pub foot: Foot,
    /// Lift-off, the top of the lift, above the target, the target; a lift backing away from
    /// a riser follows a curve, sampled in more poses before its top (see `swing_path`):
    /// every piece before the last two is the lift ([`Swing::lift_pieces`]).
    pub path: Vec<Isometry3<f64>>,
    /// Each piece's share of the segment's duration (sums to 1). The lift's pieces are one
    /// stretch of the time law, the foot not stopping between them, their shares in
    /// proportion to their lengths; the others stop at their ends.
    pub shares: Vec<f64>,
    /// The swing's own duration at the foot's speed, seconds (the segment may be longer when
    /// the CoM has farther to go).
    pub natural_s: f64,
}

impl Swing {
    /// From `a` to `b`: lift to `p.swing_clearance_m` above the higher sole, cross, descend,
    /// each at the foot's speed and no shorter than `p.min_piece_s`. Toward a higher tread
    /// with the CoM moving (`com_at` not constant: the trailing foot), the lift backs away
    /// from the riser ahead along a curve (`p.lift_retreat_m`, see [`swing_path`]), timed as
    /// one stretch by its length, its pieces in proportion. At the top of the
    /// lift the sole is pitched toe down as far as its ankle cannot bend with the CoM at
    /// `com_at(fraction of the swing)` ([`toe_down`]).
    fn new(
        foot: Foot,
        a: &Isometry3<f64>,
        b: &Isometry3<f64>,
        com_at: impl Fn(f64) -> Point3<f64>,
        body: &Body,
        p: &StepParams,
    ) -> Self {
        let body_moves = (com_at(1.0) - com_at(0.0)).norm() > COM_STILL_M;
        let retreat_m = if body_moves { p.lift_retreat_m } else { 0.0 };
        let retreat = Retreat { by_m: retreat_m, unload_m: p.lift_unload_m, until_m: p.lift_retreat_until_m };
        let mut path = swing_path(a, b, p.swing_clearance_m, &retreat);
        let lengths_m = piece_lengths_m(&path);
        let top = path.len() - 3;
        let lift_m: f64 = lengths_m[..top].iter().sum();
        let lift_s = (lift_m / p.foot_speed_m_s).max(p.min_piece_s);
        let pieces: Vec<f64> = lengths_m
            .iter()
            .enumerate()
            .map(|(k, len_m)| match k < top {
                true if lift_m > 0.0 => lift_s * (len_m / lift_m),
                true => lift_s / top as f64,
                false => (len_m / p.foot_speed_m_s).max(p.min_piece_s),
            })
            .collect();
        let natural_s: f64 = pieces.iter().sum();
        let mut shares: Vec<f64> = pieces.iter().map(|x| x / natural_s).collect();
        let lift_share: f64 = shares[..top].iter().sum();
        let hip = com_at(lift_share) - Vector3::z() * body.com_above_hip_m;
        path[top] = toe_down(foot, &path[top], &hip, body, p);
        // The pitch raised the top: the lift's pieces share its time by their new lengths
        // (its whole unchanged), so that the foot's speed has no jump at a waypoint.
        if top > 1 {
            let lengths_m = piece_lengths_m(&path[..=top]);
            let lift_m: f64 = lengths_m.iter().sum();
            for (share, len_m) in shares.iter_mut().zip(&lengths_m) {
                *share = lift_share * (len_m / lift_m);
            }
        }
        Self { foot, path, shares, natural_s }
    }

    /// How many of the path's first pieces are the lift: all but the last two (across and
    /// the descent), none in a swing of two pieces or fewer.
    pub fn lift_pieces(&self) -> usize {
        self.shares.len().saturating_sub(2)
    }

    /// The lift's share of the segment's duration.
    pub fn lift_share(&self) -> f64 {
        self.shares[..self.lift_pieces()].iter().sum()
    }
}

/// The swinging sole at the top of its lift (`lift`, level), pitched toe down by as much as
/// its ankle would have to bend beyond `p.ankle_flex_margin_rad` short of its limit for the
/// sole to stay level, with the hip pitch axis at `hip`, and raised so that its toe stays at
/// `lift`'s height. A trailing foot lifted from a tread behind the hip (a deep
/// tread, the hip lowered for the leading leg's reach) otherwise asks its ankle more than
/// the joint allows, and the IK, its ankle held at the limit, keeps the sole level by
/// rolling the pelvis and bowing the chest in a few tenths of a second at its joint speed
/// bound, which turns the stance sole on its tread (regression
/// `a-sole-twisting-under-load-turned-the-estimate` at twice the quasi-static timing).
/// A person lifts that heel first. The leg is taken in the sagittal plane of the sole, the
/// hip straight above the sole's axis (the leg's sideways reach left out, which bends its
/// knee less: on the safe side).
fn toe_down(
    foot: Foot,
    lift: &Isometry3<f64>,
    hip: &Point3<f64>,
    body: &Body,
    p: &StepParams,
) -> Isometry3<f64> {
    let half_length_m = body.sole_half_m[foot.index()][0];
    let forward = lift.rotation * Vector3::x();
    let forward = Vector3::new(forward.x, forward.y, 0.0).try_normalize(1e-9).unwrap_or_else(Vector3::x);
    let allowed_rad = body.ankle_flex_max_rad - p.ankle_flex_margin_rad;
    let pitched = |pitch_rad: f64| {
        let mut pose = *lift;
        pose.rotation = lift.rotation * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), pitch_rad);
        pose.translation.z += half_length_m * pitch_rad.sin();
        pose
    };
    // The ankle's bend needed depends on where the pitch puts the ankle: a fixed point. Its
    // first step moves the ankle by centimetres and each next by about a quarter of the
    // last; four leave the pitch within a milliradian.
    let mut pitch_rad = 0.0;
    for _ in 0..4 {
        let ankle = body.ankle(foot, &pitched(pitch_rad));
        let lean_rad = shank_lean_rad(body, &ankle, hip, &forward);
        pitch_rad = (lean_rad - allowed_rad).max(0.0);
    }
    if pitch_rad > 0.0 {
        pitched(pitch_rad)
    } else {
        *lift
    }
}

/// How far forward of vertical the shank leans, radians, with the ankle at `ankle`, the hip
/// pitch axis at `hip`, `forward` the sagittal direction (horizontal): the leg in that plane,
/// its knee bent forward. A hip out of the leg's reach gives the leg straight along it.
fn shank_lean_rad(body: &Body, ankle: &Point3<f64>, hip: &Point3<f64>, forward: &Vector3<f64>) -> f64 {
    let (thigh, shank) = (body.thigh_m, body.shank_m);
    let to_hip = hip - ankle;
    let (d, h) = (to_hip.dot(forward), to_hip.z);
    let r = d.hypot(h).max(1e-9);
    let cos_knee_side = ((shank * shank + r * r - thigh * thigh) / (2.0 * shank * r)).clamp(-1.0, 1.0);
    d.atan2(h) + cos_knee_side.acos()
}

/// One segment of the motion.
#[derive(Debug, Clone, PartialEq)]
pub struct Segment {
    /// Which of the five.
    pub phase: Phase,
    /// Index of the stance this step goes to.
    pub stance: usize,
    /// Duration, seconds.
    pub duration_s: f64,
    /// CoM at the start, world frame.
    pub com_start: Point3<f64>,
    /// CoM at the end.
    pub com_end: Point3<f64>,
    /// Feet in contact, held still, with their poses.
    pub support: Vec<(Foot, Isometry3<f64>)>,
    /// The foot that moves, if one does.
    pub swing: Option<Swing>,
    /// Static-stability polygon of the support (counter-clockwise, world x-y).
    pub polygon: Vec<P2>,
    /// Smallest distance of the two CoM ends from the polygon's edges, metres.
    pub margin_m: f64,
}

impl Segment {
    /// The stability polygon as a closed ring in 3-D, drawn at the lowest supporting sole
    /// (the polygon itself is a prism's base in the transverse plane; this is where viewers
    /// show it).
    pub fn polygon_ring(&self) -> Vec<Point3<f64>> {
        let z = self.support.iter().map(|(_, p)| p.translation.z).fold(f64::INFINITY, f64::min);
        let z = if z.is_finite() { z } else { 0.0 };
        let mut ring: Vec<Point3<f64>> = self.polygon.iter().map(|p| Point3::new(p.x, p.y, z)).collect();
        if let Some(first) = ring.first().copied() {
            ring.push(first);
        }
        ring
    }
}

/// Timing and clearances of the motion. Lengths in metres.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StepParams {
    /// CoM speed along its linear segments, m/s (slow: the static criterion of §6.2 holds
    /// only when accelerations are negligible; see [`StepParams::quasi_static`] and
    /// [`DEFAULT_SPEEDUP`] for the default's).
    pub com_speed_m_s: f64,
    /// Largest shift of the ZMP from the CoM's ground point that the CoM's acceleration along
    /// a segment may ask, metres: by the linear inverted pendulum (Kajita et al. 2001) the
    /// shift is `h / g` times the acceleration, `h` the CoM's height above the soles, and the
    /// segments' time law (`ease`, 3 t^2 - 2 t^3) peaks at `6 d / T^2` over a path of `d` in `T`, so a
    /// segment lasts at least `sqrt(6 d h / (g shift))`. `d` is the CoM's whole path, its
    /// vertical part counted as if it were horizontal (on the safe side: a rise shifts no ZMP
    /// but loads and unloads the feet). The speed bound alone makes short moves the hardest
    /// (their peak acceleration is `6 v^2 / d`); this bound holds them whatever the speed.
    /// Not scaled by [`StepParams::faster`].
    ///
    /// [`ZMP_SHIFT_M`] by default (TOML `inf`: no bound, the CoM's speed alone): at the
    /// default's x 2 the speed bound alone asks up to 74 mm of Exp. 1's sideways shifts and
    /// the body overshoots the last centring onto one sole (CHANGELOG, 2026-12-02).
    pub max_zmp_shift_m: f64,
    /// Free-foot speed along its path, m/s.
    pub foot_speed_m_s: f64,
    /// Shortest segment, seconds.
    pub min_segment_s: f64,
    /// Shortest piece of a swing (the lift, whatever its path; across; descent), seconds: the
    /// foot lands slowly.
    pub min_piece_s: f64,
    /// Height of the swing above the higher of lift-off and target (§6.1: clears the
    /// step's nose and edge).
    pub swing_clearance_m: f64,
    /// How far a sole lifting toward a higher tread while the CoM moves backs away from the
    /// riser ahead (along the target sole's heading) as it rises from `lift_unload_m` to
    /// `lift_retreat_until_m`, metres (0: straight up). Default 0.015 m. The toes keep at least
    /// `GaitParams::toe_clearance_m` (1.5 cm) behind that riser as perceived, a few
    /// millimetres less where the perception and the touchdown err, and a body whose servos
    /// lag carries the lifting sole forward with the rising CoM (about 1 cm at 20-30 ms;
    /// regression `a-lagging-body-carried-the-trailing-toe-into-the-riser`).
    /// 0.015 m, as much again as the toes' clearance, keeps the toes off that riser. The
    /// lift, a few millimetres longer, is timed as one stretch and costs no time (CHANGELOG,
    /// fifty-eighth to sixtieth sessions).
    pub lift_retreat_m: f64,
    /// Height above the lift-off by which such a sole has backed away the whole
    /// `lift_retreat_m`, metres (the lift's top if lower), above `lift_unload_m`. The
    /// retreat's acceleration goes as the inverse square of the height it is spread over,
    /// and the stance sole pushes against it; spread too high, the toe has hardly backed
    /// away where a lagging body's toe meets the riser, a few centimetres up. Default
    /// 0.12 m: 4 mm back 5 cm up, the stance sole's friction as with a straight lift
    /// (CHANGELOG, fifty-ninth session, for the runs).
    pub lift_retreat_until_m: f64,
    /// How high such a sole first rises straight up before it backs away, metres, below
    /// `lift_retreat_until_m` (0: it backs away from the lift-off). Default 0.015 m: the sole
    /// is still unloading as it leaves, and backing away at once slides it back along its
    /// tread under load (CHANGELOG, fifty-eighth session).
    pub lift_unload_m: f64,
    /// Least distance of a CoM waypoint from its polygons' edges.
    pub min_margin_m: f64,
    /// Friction coefficient of the contacts' pyramids (§6.2; Caron et al. 2015).
    pub friction: f64,
    /// The trailing leg is kept within this fraction of its full length (hip to ankle), and
    /// the leading leg lands within it (measured on the tracked trajectory, see
    /// [`super::reach`]: a leg landing straight is a strut that slides its sole).
    pub reach_fraction: f64,
    /// Largest knee bend the leading leg may need, radians (the name carries the unit in
    /// parameter files too).
    pub knee_max_rad: f64,
    /// How far short of its limit a swinging foot's ankle is planned to bend at the top of
    /// its lift, radians: beyond, the sole is pitched toe down there (see `toe_down`). The
    /// IK's joint-limit damper (§6.1, `limit_gain_per_s`, 5/s at the quasi-static timing)
    /// lets a joint close on its limit at most that gain times the distance left, and the
    /// trailing ankle turns toward it at up to 0.5 rad/s in the quasi-static lift (Exp. 1's
    /// plan and 37 cm treads'), so within 0.1 rad of the limit the damper would slow it at
    /// its fastest (the ratio is the same at any speed-up, both scaling alike); it bends
    /// most at the lift's top, where it has slowed. 0.15 rad (8.6 deg) adds to that most of
    /// the 0.06 rad by which the gait's planar leg, its hip taken at the CoM, misjudges the
    /// tracked one on deep treads (the pelvis stands ahead of the CoM there).
    pub ankle_flex_margin_rad: f64,
    /// Tolerances of the double description that computes the stability polygons (§6.2);
    /// the execution's checks build theirs with the same.
    pub dd: DdParams,
}

/// The default bound on the ZMP shift the CoM's acceleration may ask
/// ([`StepParams::max_zmp_shift_m`]), metres: under a third of the model's 13 cm sole
/// width, and about what x 1.5 the quasi-static timing's shortest shifts ask without it (up
/// to 42 mm on Exp. 1), a timing every suite passed at. The quasi-static timing never
/// reaches it (its shifts ask at most 19 mm).
pub const ZMP_SHIFT_M: f64 = 0.04;

/// How many times faster than the quasi-static timing ([`StepParams::quasi_static`]) the
/// planner moves by default, every rate of the IK with it
/// ([`IkParams::faster`](super::motion::IkParams::faster)); the bound on the CoM's
/// acceleration ([`StepParams::max_zmp_shift_m`]) is not sped up, so the segments it holds
/// are longer than the quasi-static ones over this factor. Issue 42 asks x 1.5 at the
/// least; the stabilizer's speed margin over this default (`run --speed-margin`) and the
/// suites' figures are in BENCHMARKS.md.
pub const DEFAULT_SPEEDUP: f64 = 2.0;

impl Default for StepParams {
    /// The quasi-static timing [`DEFAULT_SPEEDUP`] times faster.
    fn default() -> Self {
        Self::quasi_static().faster(DEFAULT_SPEEDUP)
    }
}

impl StepParams {
    /// The quasi-static timing: the CoM at 6 cm/s, the foot at 15 cm/s, a segment 0.8 s and
    /// a swing's piece 0.6 s at the shortest (§6.2's static criterion holds when the
    /// accelerations are negligible), the ZMP's shift bounded at [`ZMP_SHIFT_M`] (which a
    /// speed-up keeps). The other fields are the defaults'.
    pub fn quasi_static() -> Self {
        Self {
            com_speed_m_s: 0.06,
            max_zmp_shift_m: ZMP_SHIFT_M,
            foot_speed_m_s: 0.15,
            min_segment_s: 0.8,
            min_piece_s: 0.6,
            swing_clearance_m: 0.05,
            lift_retreat_m: 0.015,
            lift_retreat_until_m: 0.12,
            lift_unload_m: 0.015,
            min_margin_m: 0.02,
            friction: super::contact::DEFAULT_FRICTION,
            reach_fraction: 0.95,
            knee_max_rad: 125f64.to_radians(),
            ankle_flex_margin_rad: 0.15,
            dd: DdParams::default(),
        }
    }

    /// Why these parameters cannot time a gait, if they cannot: a speed that is not positive
    /// and finite, a ZMP shift that is not positive, a shortest duration, the ankle's margin
    /// or the lift's retreat, its height or its unload negative or not finite (a zero speed
    /// would make every segment last forever), an unload not below the retreat's height.
    pub fn validate(&self) -> Result<(), String> {
        let speeds = [("com_speed_m_s", self.com_speed_m_s), ("foot_speed_m_s", self.foot_speed_m_s)];
        if let Some((name, v)) = speeds.iter().find(|(_, v)| !(v.is_finite() && *v > 0.0)) {
            return Err(format!("[step] {name} must be positive and finite, got {v}"));
        }
        if self.max_zmp_shift_m.is_nan() || self.max_zmp_shift_m <= 0.0 {
            let v = self.max_zmp_shift_m;
            return Err(format!("[step] max_zmp_shift_m must be positive (inf: no bound), got {v}"));
        }
        let non_negative = [
            ("min_segment_s", self.min_segment_s),
            ("min_piece_s", self.min_piece_s),
            ("ankle_flex_margin_rad", self.ankle_flex_margin_rad),
            ("lift_retreat_m", self.lift_retreat_m),
            ("lift_unload_m", self.lift_unload_m),
            ("lift_retreat_until_m", self.lift_retreat_until_m),
        ];
        if let Some((name, v)) = non_negative.iter().find(|(_, v)| !(v.is_finite() && *v >= 0.0)) {
            return Err(format!("[step] {name} must be finite and not negative, got {v}"));
        }
        if self.lift_unload_m >= self.lift_retreat_until_m {
            let (u, c) = (self.lift_unload_m, self.lift_retreat_until_m);
            return Err(format!("[step] lift_unload_m ({u}) must be below lift_retreat_until_m ({c})"));
        }
        Ok(())
    }

    /// The same motion `factor` times faster (speeds up, shortest durations down).
    pub fn faster(&self, factor: f64) -> Self {
        Self {
            com_speed_m_s: self.com_speed_m_s * factor,
            foot_speed_m_s: self.foot_speed_m_s * factor,
            min_segment_s: self.min_segment_s / factor,
            min_piece_s: self.min_piece_s / factor,
            ..self.clone()
        }
    }
}

/// What the legs allow a step up (§6.3), from the body's figures and the gait's limits: the
/// trailing leg reaches `reach_fraction` of its length, the leading knee folds at most
/// `knee_max_rad`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Legs {
    /// Hip pitch to ankle pitch, the farthest the trailing leg may reach, metres.
    pub reach_m: f64,
    /// Least height of the hip above the leading ankle with the knee at its largest fold,
    /// metres.
    pub fold_m: f64,
    /// The knee's largest fold, radians (`StepParams::knee_max_rad`).
    pub knee_max_rad: f64,
}

impl Legs {
    /// The limits of `body`'s legs under `p`.
    pub fn of(body: &Body, p: &StepParams) -> Self {
        let (t, s) = (body.thigh_m, body.shank_m);
        Self {
            reach_m: p.reach_fraction * (t + s),
            fold_m: (t * t + s * s + 2.0 * t * s * p.knee_max_rad.cos()).sqrt(),
            knee_max_rad: p.knee_max_rad,
        }
    }

    /// Longest horizontal distance along the ascent between the trailing and the leading
    /// ankle for a step up `rise_m`: the hip over the leading ankle, as high as the trailing
    /// leg reaches from there, must stand `fold_m` above it (the knee check of
    /// [`segments`], whose other bound, the hip no higher than standing, binds only for
    /// rises above HRP-4's 0.33 m); 0 when no distance allows the rise.
    pub fn max_stride_m(&self, rise_m: f64) -> f64 {
        let h = (self.fold_m + rise_m).max(0.0);
        if h >= self.reach_m {
            0.0
        } else {
            (self.reach_m * self.reach_m - h * h).sqrt()
        }
    }
}

/// The figures of the body the gait needs, measured on the model standing (the planner
/// measures them in half-sitting, [`standing_body`](super::plan::standing_body)).
#[derive(Debug, Clone, PartialEq)]
pub struct Body {
    /// CoM height above the soles standing: the height the gait holds the CoM at.
    pub com_height_m: f64,
    /// CoM height above the hip pitch axes standing.
    pub com_above_hip_m: f64,
    /// Hip pitch to knee.
    pub thigh_m: f64,
    /// Knee to ankle pitch.
    pub shank_m: f64,
    /// Ankle (pitch axis) in each sole's frame: right, left.
    pub ankle_in_sole: [Vector3<f64>; 2],
    /// Each sole's half length and half width (right, left), from the model's foot boxes.
    pub sole_half_m: [[f64; 2]; 2],
    /// The most the ankles bend the shank forward over a level sole (dorsiflexion), radians:
    /// the model's ankle pitch limit (HRP-4: 75 deg), the lesser of the two.
    pub ankle_flex_max_rad: f64,
}

impl Body {
    /// Measures the body in the configuration `kin` was last updated with (standing on level
    /// soles); `soles` are the sole frames, right then left.
    pub fn measure(kin: &Kinematics, soles: [usize; 2]) -> Result<Self, PlanError> {
        let model = kin.model();
        let at = |l: usize| kin.link_pose(l).translation.vector;
        let (hip, knee) = (model.joint_link("R_HIP_P")?, model.joint_link("R_KNEE_P")?);
        let (ankle, left_ankle) = (model.joint_link("R_ANKLE_P")?, model.joint_link("L_ANKLE_P")?);
        let (rs, ls) = (kin.frame_pose(soles[0]), kin.frame_pose(soles[1]));
        let com = kin.com();
        let sole_z = (rs.translation.z + ls.translation.z) / 2.0;
        Ok(Self {
            com_height_m: com.z - sole_z,
            com_above_hip_m: com.z - at(hip).z,
            thigh_m: (at(hip) - at(knee)).norm(),
            shank_m: (at(knee) - at(ankle)).norm(),
            ankle_in_sole: [
                rs.inverse_transform_point(&Point3::from(at(ankle))).coords,
                ls.inverse_transform_point(&Point3::from(at(left_ankle))).coords,
            ],
            sole_half_m: [model.sole_half_m(soles[0])?, model.sole_half_m(soles[1])?],
            ankle_flex_max_rad: ["R_ANKLE_P", "L_ANKLE_P"]
                .iter()
                .map(|n| model.joint_id(n).map(|j| -model.joints()[j].lower_rad))
                .collect::<Result<Vec<f64>, _>>()?
                .into_iter()
                .fold(f64::INFINITY, f64::min),
        })
    }

    fn ankle(&self, foot: Foot, sole: &Isometry3<f64>) -> Point3<f64> {
        let k = foot.index();
        sole.transform_point(&Point3::from(self.ankle_in_sole[k]))
    }

    fn contact(&self, foot: Foot, sole: &Isometry3<f64>, friction: f64) -> Result<Contact, PlanError> {
        let [hx, hy] = self.sole_half_m[foot.index()];
        Contact::new(*sole, hx, hy, friction).map_err(PlanError::Config)
    }
}

/// The segments from `com` standing in `start` through every stance of `stances`; the CoM
/// waypoint of stance `k`'s first touchdown `drops_m[k]` lower than the legs' model puts it
/// (measured on the tracked trajectory, see [`super::reach`]; a stance past the slice's end
/// is not lowered).
pub fn segments(
    com: Point3<f64>,
    start: &Stance,
    stances: &[Stance],
    drops_m: &[f64],
    body: &Body,
    p: &StepParams,
) -> Result<Vec<Segment>, PlanError> {
    p.validate().map_err(PlanError::Config)?;
    let mut out: Vec<Segment> = Vec::new();
    let mut from = start.clone();
    let mut c = com;
    let legs = Legs::of(body, p);
    for (k, to) in stances.iter().enumerate() {
        let drop_m = drops_m.get(k).copied().unwrap_or(0.0);
        let step = one_step(c, &from, to, (k, drop_m), body, &legs, p)?;
        c = step.last().map(|s| s.com_end).unwrap_or(c);
        out.extend(step);
        from = to.clone();
    }
    settle_waypoints(&mut out, p.min_margin_m)?;
    for s in &mut out {
        s.duration_s = duration(s, body.com_height_m, p);
    }
    Ok(out)
}

fn one_step(
    com: Point3<f64>,
    from: &Stance,
    to: &Stance,
    (k, drop_m): (usize, f64),
    body: &Body,
    legs: &Legs,
    p: &StepParams,
) -> Result<Vec<Segment>, PlanError> {
    let (lo_z, lead_z) = (from.left.translation.z, to.right.translation.z);
    // Along the leading sole's own axis: level, as the footholds plan every sole
    // (`footholds::Layout::stance_on`), so horizontal; a stance given tilted (a degree)
    // counts a little of the rise as distance (4.5 mm on a 0.26 m rise, within the
    // footholds' slack).
    let forward = to.right.rotation * Vector3::x();
    let lead_ankle = body.ankle(Foot::Right, &to.right);
    let trail_ankle = body.ankle(Foot::Left, &from.left);
    // (1): over the left ankle, low enough that the right leg reaches its target from there
    // (and `drop_m` lower, where the tracked leg reached farther than the model said).
    let z1 = com.z.min(hip_height_max(legs, &trail_ankle, &lead_ankle, &forward, k)? + body.com_above_hip_m)
        - drop_m;
    let w1 = over(trail_ankle, z1);
    // (3): over the right ankle, as high as the trailing leg reaches, no higher than standing.
    let hip3 = hip_height_max(legs, &lead_ankle, &trail_ankle, &forward, k)?
        .min(lo_z.min(lead_z) + body.com_height_m - body.com_above_hip_m);
    check_fold(legs, p, hip3 - lead_ankle.z, k)?;
    let w3 = over(lead_ankle, hip3 + body.com_above_hip_m);
    // (4): standing height over the right ankle. (5): between the soles.
    let w4 = over(lead_ankle, lead_z + body.com_height_m);
    let mid = (to.right.translation.vector + to.left.translation.vector) / 2.0;
    let w5 = Point3::new(mid.x, mid.y, mid.z + body.com_height_m);

    let both = |a: &Isometry3<f64>, b: &Isometry3<f64>| vec![(Foot::Right, *a), (Foot::Left, *b)];
    let still = |c: Point3<f64>| move |_: f64| c;
    let moving = |a: Point3<f64>, b: Point3<f64>| move |tau: f64| a + (b - a) * ease(tau).0;
    let plan = [
        (Phase::ShiftToLeft, com, w1, both(&from.right, &from.left), None),
        (
            Phase::SwingRight,
            w1,
            w1,
            vec![(Foot::Left, from.left)],
            Some(Swing::new(Foot::Right, &from.right, &to.right, still(w1), body, p)),
        ),
        (Phase::ShiftToRight, w1, w3, both(&to.right, &from.left), None),
        (
            Phase::LiftSwingLeft,
            w3,
            w4,
            vec![(Foot::Right, to.right)],
            Some(Swing::new(Foot::Left, &from.left, &to.left, moving(w3, w4), body, p)),
        ),
        (Phase::Centre, w4, w5, both(&to.right, &to.left), None),
    ];
    plan.into_iter()
        .map(|(phase, a, b, support, swing)| {
            let contacts: Vec<Contact> = support
                .iter()
                .map(|(foot, pose)| body.contact(*foot, pose, p.friction))
                .collect::<Result<_, _>>()?;
            let polygon = by_double_description(&contacts, &p.dd)?;
            Ok(Segment {
                phase,
                stance: k,
                duration_s: 0.0,
                com_start: a,
                com_end: b,
                support,
                swing,
                polygon,
                margin_m: 0.0,
            })
        })
        .collect()
}

fn over(p: Point3<f64>, z: f64) -> Point3<f64> {
    Point3::new(p.x, p.y, z)
}

/// The highest the hip over `over` can be while the leg still reaches `ankle` (within
/// `reach_fraction` of its length), the distance measured along `forward`.
fn hip_height_max(
    legs: &Legs,
    over: &Point3<f64>,
    ankle: &Point3<f64>,
    forward: &Vector3<f64>,
    stance: usize,
) -> Result<f64, PlanError> {
    let reach = legs.reach_m;
    let d = (ankle - over).dot(forward).abs();
    if d >= reach {
        return Err(PlanError::LegReach { stance, apart_m: d, reach_m: reach });
    }
    Ok(ankle.z + (reach * reach - d * d).sqrt())
}

/// The segments' time law on [0, 1] (3 t^2 - 2 t^3, at rest at both ends) and its
/// derivative: the CoM's and each swing piece's fraction of their path at fraction `t` of
/// their time.
pub(crate) fn ease(t: f64) -> (f64, f64) {
    let t = t.clamp(0.0, 1.0);
    (t * t * (3.0 - 2.0 * t), 6.0 * t * (1.0 - t))
}

/// Refuses a stance whose leading knee would fold beyond `knee_max_rad` with the hip
/// `hip_above_ankle_m` over the ankle.
fn check_fold(legs: &Legs, p: &StepParams, hip_above_ankle_m: f64, stance: usize) -> Result<(), PlanError> {
    if hip_above_ankle_m < legs.fold_m {
        return Err(PlanError::KneeFold {
            stance,
            hip_above_ankle_m,
            needs_m: legs.fold_m,
            knee_max_rad: p.knee_max_rad,
        });
    }
    Ok(())
}

/// How a lift backs away from the riser ahead (see [`swing_path`]), metres: by `by_m`
/// (0: it does not), beginning `unload_m` above the lift-off, done `until_m` above it.
struct Retreat {
    by_m: f64,
    unload_m: f64,
    until_m: f64,
}

/// Lift vertically to `clearance_m` above the higher of the two soles, move across, descend.
/// Toward a tread higher by more than [`RISER_AHEAD_M`] (a riser between), with a retreat,
/// the lift first rises `unload_m` straight up, then backs away by `by_m` against `b`'s
/// heading (the riser's normal: the footholds yaw every sole with the staircase) as it
/// rises to `until_m` (the lift's top if lower), then goes on up: a curve, vertical where
/// it leaves and where it rejoins the straight parts (the retreat eased in, 3 f^2 - 2 f^3
/// of the rise's fraction `f`), sampled in [`RETREAT_PIECES`] pieces.
fn swing_path(
    a: &Isometry3<f64>,
    b: &Isometry3<f64>,
    clearance_m: f64,
    retreat: &Retreat,
) -> Vec<Isometry3<f64>> {
    let top = a.translation.z.max(b.translation.z) + clearance_m;
    let mut lift = *a;
    lift.translation.z = top;
    let mut above = *b;
    above.translation.z = top;
    let heading = b.rotation * Vector3::x();
    let rises = b.translation.z - a.translation.z > RISER_AHEAD_M;
    let mut path = vec![*a];
    if let Some(forward) = Vector3::new(heading.x, heading.y, 0.0).try_normalize(1e-9) {
        let until_m = retreat.until_m.min(top - a.translation.z);
        if rises && retreat.by_m > 0.0 && until_m > retreat.unload_m {
            let back = -forward * retreat.by_m;
            let first = if retreat.unload_m > 0.0 { 0 } else { 1 };
            for k in first..=RETREAT_PIECES {
                let f = k as f64 / RETREAT_PIECES as f64;
                let up_m = retreat.unload_m + (until_m - retreat.unload_m) * f;
                let mut pose = *a;
                pose.translation.vector += back * ease(f).0 + Vector3::z() * up_m;
                path.push(pose);
            }
            lift.translation.vector += back;
            if until_m >= top - a.translation.z {
                // The curve ends at the lift's top: no straight piece after it.
                path.pop();
            }
        }
    }
    path.extend([lift, above, *b]);
    path
}

/// How many pieces sample the curve of a lift backing away from a riser ([`swing_path`]):
/// at sixteen its direction turns at most a few degrees between two.
const RETREAT_PIECES: usize = 16;

/// A swing's target higher than its lift-off by more than this has a riser between them,
/// metres: a stair's rise is 10 cm or more, a floor perceived uneven by millimetres.
const RISER_AHEAD_M: f64 = 0.05;

/// The CoM moving less than this over a swing counts as still (the leading foot's swing,
/// the CoM held over the trailing ankle), metres.
const COM_STILL_M: f64 = 1e-3;

/// The lengths of a path's pieces (each pose's origin to the next's), metres.
pub(super) fn piece_lengths_m(path: &[Isometry3<f64>]) -> Vec<f64> {
    path.windows(2).map(|w| (w[1].translation.vector - w[0].translation.vector).norm()).collect()
}

/// Checks every CoM waypoint against the polygons of both segments it joins, moving it
/// toward the middle of their intersection when its margin is short.
fn settle_waypoints(segs: &mut [Segment], min_margin_m: f64) -> Result<(), PlanError> {
    let start = P2::new(segs[0].com_start.x, segs[0].com_start.y);
    if margin(&segs[0].polygon, &start) < 0.0 {
        return Err(PlanError::Unstable {
            segment: 0,
            margin_m: margin(&segs[0].polygon, &start),
            min_m: 0.0,
        });
    }
    for i in 0..segs.len() {
        let end = segs[i].com_end;
        let mut region = segs[i].polygon.clone();
        if let Some(next) = segs.get(i + 1) {
            region = geom2d::clip_convex(&region, &next.polygon);
        }
        let xy = P2::new(end.x, end.y);
        let moved = if region.len() >= 3 && margin(&region, &xy) >= min_margin_m {
            xy
        } else {
            toward_middle(&region, xy, min_margin_m).ok_or(PlanError::Unstable {
                segment: i,
                margin_m: if region.len() >= 3 { margin(&region, &xy) } else { f64::NEG_INFINITY },
                min_m: min_margin_m,
            })?
        };
        let new = Point3::new(moved.x, moved.y, end.z);
        segs[i].com_end = new;
        if let Some(next) = segs.get_mut(i + 1) {
            // A segment whose CoM does not move keeps it still at the new place.
            if next.com_end == next.com_start {
                next.com_end = new;
            }
            next.com_start = new;
        }
    }
    for s in segs.iter_mut() {
        let ends = [s.com_start, s.com_end].map(|c| margin(&s.polygon, &P2::new(c.x, c.y)));
        s.margin_m = ends[0].min(ends[1]);
    }
    Ok(())
}

/// The point nearest `p` on the segment from `p` to the region's centroid with at least
/// `min_margin_m` of margin (bisection), or `None` when even the centroid has less.
fn toward_middle(region: &[P2], p: P2, min_margin_m: f64) -> Option<P2> {
    if region.len() < 3 {
        return None;
    }
    let centroid = region.iter().sum::<P2>() / region.len() as f64;
    if margin(region, &centroid) < min_margin_m {
        return None;
    }
    let (mut lo, mut hi) = (0.0, 1.0); // fraction toward the centroid: lo fails, hi passes
    for _ in 0..40 {
        let mid = (lo + hi) / 2.0;
        if margin(region, &(p + (centroid - p) * mid)) >= min_margin_m {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Some(p + (centroid - p) * hi)
}

/// The segment's duration from the CoM's and the free foot's path lengths, and the CoM's
/// acceleration at a CoM height of `com_height_m` ([`StepParams::max_zmp_shift_m`]).
fn duration(s: &Segment, com_height_m: f64, p: &StepParams) -> f64 {
    let path_m = (s.com_end - s.com_start).norm();
    let com = (path_m / p.com_speed_m_s).max(shortest_for_zmp_s(path_m, com_height_m, p.max_zmp_shift_m));
    let foot = s.swing.as_ref().map_or(0.0, |sw| sw.natural_s);
    com.max(foot).max(p.min_segment_s)
}

/// Peak acceleration of the segments' time law (`ease`, 3 t^2 - 2 t^3) over a path of 1 m in 1 s,
/// m/s^2: at both ends.
const EASE_PEAK_ACCEL: f64 = 6.0;

/// The shortest time in which the CoM moves `path_m` on the segments' time law with its ZMP
/// shifted at most `max_zmp_shift_m` by the acceleration (linear inverted pendulum at
/// `com_height_m`), seconds.
pub fn shortest_for_zmp_s(path_m: f64, com_height_m: f64, max_zmp_shift_m: f64) -> f64 {
    (EASE_PEAK_ACCEL * path_m * com_height_m / (GRAVITY_M_S2 * max_zmp_shift_m)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Translation3;

    fn square(x0: f64, y0: f64, s: f64) -> Vec<P2> {
        vec![P2::new(x0, y0), P2::new(x0 + s, y0), P2::new(x0 + s, y0 + s), P2::new(x0, y0 + s)]
    }

    #[test]
    fn the_polygon_ring_closes_at_the_lowest_supporting_sole() {
        let mut s = seg(Point3::origin(), Point3::origin(), square(0.0, 0.0, 1.0));
        s.support = vec![
            (Foot::Right, Isometry3::translation(0.0, -0.1, 0.2)),
            (Foot::Left, Isometry3::translation(0.0, 0.1, 0.05)),
        ];
        let ring = s.polygon_ring();
        assert_eq!(ring.len(), 5);
        assert_eq!(ring[0], ring[4]);
        // At the lower sole (not the fallback height 0), through the polygon's own vertices.
        assert!(ring.iter().all(|p| p.z == 0.05));
        assert!(ring[..4].iter().zip(&s.polygon).all(|(p, q)| p.x == q.x && p.y == q.y));
    }

    fn seg(a: Point3<f64>, b: Point3<f64>, polygon: Vec<P2>) -> Segment {
        Segment {
            phase: Phase::ShiftToLeft,
            stance: 0,
            duration_s: 1.0,
            com_start: a,
            com_end: b,
            support: Vec::new(),
            swing: None,
            polygon,
            margin_m: 0.0,
        }
    }

    #[test]
    fn a_waypoint_outside_is_moved_inside_both_polygons_or_refused() {
        // The end of the first segment lies outside the second's polygon: it moves into the
        // intersection with the margin, and the second segment starts there.
        let mut segs = vec![
            seg(Point3::new(0.5, 0.5, 0.8), Point3::new(0.95, 0.5, 0.8), square(0.0, 0.0, 1.0)),
            seg(Point3::new(0.95, 0.5, 0.8), Point3::new(0.5, 0.3, 0.8), square(0.0, 0.0, 0.8)),
        ];
        settle_waypoints(&mut segs, 0.02).unwrap();
        let end = P2::new(segs[0].com_end.x, segs[0].com_end.y);
        assert!(margin(&segs[1].polygon, &end) >= 0.02 - 1e-9, "{end:?}");
        assert_eq!(segs[0].com_end, segs[1].com_start);
        assert!(segs.iter().all(|s| s.margin_m >= 0.02 - 1e-9));
        // Disjoint polygons: no place for the waypoint, the plan is refused.
        let mut apart = vec![
            seg(Point3::new(0.5, 0.5, 0.8), Point3::new(0.9, 0.5, 0.8), square(0.0, 0.0, 1.0)),
            seg(Point3::new(0.9, 0.5, 0.8), Point3::new(2.5, 0.5, 0.8), square(2.0, 0.0, 1.0)),
        ];
        assert!(matches!(settle_waypoints(&mut apart, 0.02), Err(PlanError::Unstable { segment: 0, .. })));
    }

    /// Leg figures of HRP-4's size (round numbers; the test's reference uses the same).
    fn hrp4_like() -> Body {
        Body {
            com_height_m: 0.78,
            com_above_hip_m: 0.1,
            thigh_m: 0.3,
            shank_m: 0.353,
            ankle_in_sole: [Vector3::new(0.0, 0.0, 0.09); 2],
            sole_half_m: [[0.11, 0.065]; 2],
            ankle_flex_max_rad: 75f64.to_radians(),
        }
    }

    /// The shank's lean from vertical, by the knee found as the crossing of two circles in
    /// the x-z plane (the one ahead of the ankle-hip line): a reference written apart from
    /// `shank_lean_rad`'s law of cosines.
    fn lean_by_circles(body: &Body, ankle: &Point3<f64>, hip: &Point3<f64>) -> f64 {
        let (a, h) = (nalgebra::Vector2::new(ankle.x, ankle.z), nalgebra::Vector2::new(hip.x, hip.z));
        let d = (h - a).norm();
        let along = (body.shank_m.powi(2) - body.thigh_m.powi(2) + d * d) / (2.0 * d);
        let off = (body.shank_m.powi(2) - along * along).max(0.0).sqrt();
        let u = (h - a) / d;
        let normal = nalgebra::Vector2::new(u.y, -u.x); // to the right of the line up: forward
        let knee = a + u * along + normal * off;
        (knee.x - a.x).atan2(knee.y - a.y)
    }

    #[test]
    fn a_sole_lifted_behind_the_hip_is_pitched_toe_down_as_far_as_its_ankle_cannot_bend() {
        let body = hrp4_like();
        let p = StepParams::default();
        let lift = Isometry3::translation(0.0, 0.0, 0.2);
        // The hip above the ankle: the sole stays level.
        let above = Point3::new(0.05, 0.0, 0.2 + 0.09 + 0.55);
        assert_eq!(toe_down(Foot::Left, &lift, &above, &body, &p), lift);
        // The hip 0.36 m ahead and 0.38 m up: level, the shank would lean beyond the limit.
        let hip = Point3::new(0.36, 0.0, 0.2 + 0.09 + 0.38);
        let level_lean = lean_by_circles(&body, &body.ankle(Foot::Left, &lift), &hip);
        assert!(level_lean > body.ankle_flex_max_rad, "{level_lean}");
        let pitched = toe_down(Foot::Left, &lift, &hip, &body, &p);
        let sole_x = pitched.rotation * Vector3::x();
        let pitch = (-sole_x.z).asin();
        assert!(pitch > 0.05, "toe down by {pitch}");
        assert!(sole_x.y.abs() < 1e-12, "pitched about the sole's own y axis");
        // The toe stays at the lift's height; the ankle bends its margin short of the limit.
        let toe = pitched.transform_point(&Point3::new(body.sole_half_m[1][0], 0.0, 0.0));
        assert!((toe.z - 0.2).abs() < 1e-9, "toe at {}", toe.z);
        let bend = lean_by_circles(&body, &body.ankle(Foot::Left, &pitched), &hip) - pitch;
        let want = body.ankle_flex_max_rad - p.ankle_flex_margin_rad;
        // The fixed point's four steps leave it within a milliradian (0.7 mrad here).
        assert!((bend - want).abs() < 2e-3, "the ankle bends {bend:.4} rad, {want:.4} wanted");
    }

    /// By default a sole lifting toward a higher tread while the CoM rises (the trailing
    /// foot) first rises straight, then backs away from the riser ahead along a curve before
    /// it goes on up, the whole lift timed as one stretch; the leading foot's lift (the CoM
    /// still) and a swing along the floor go straight up.
    #[test]
    fn a_trailing_sole_backs_away_from_the_riser_ahead_as_it_lifts() {
        let body = hrp4_like();
        let p = StepParams::default();
        assert!(p.lift_retreat_m > 0.0 && p.lift_retreat_until_m < 0.18 + p.swing_clearance_m);
        let yawed = |x: f64, y: f64, z: f64| {
            Isometry3::from_parts(
                Translation3::new(x, y, z),
                UnitQuaternion::from_euler_angles(0.0, 0.0, 0.3),
            )
        };
        let forward = Vector3::new(0.3f64.cos(), 0.3f64.sin(), 0.0);
        let left = Vector3::new(-forward.y, forward.x, 0.0);
        // The target a tread up and 5 cm to the side: the retreat is along its heading (the
        // riser's normal), not along the way to it.
        let up_there = forward * 0.28 + left * 0.05;
        let (from, to) = (yawed(0.0, 0.1, 0.18), yawed(up_there.x, 0.1 + up_there.y, 0.36));
        let rising = |t: f64| Point3::new(0.3, 0.0, 0.9 + 0.1 * t);
        let sw = Swing::new(Foot::Left, &from, &to, rising, &body, &p);
        let top = RETREAT_PIECES + 2;
        assert_eq!(sw.path.len(), top + 3);
        assert_eq!(sw.lift_pieces(), top);
        let moved = |k: usize| sw.path[k].translation.vector - from.translation.vector;
        // Straight up by the unload, then back along the heading (never sideways, never
        // forward, farther at each pose) while rising to the retreat's height, level until
        // the top.
        assert!(moved(1).xy().norm() < 1e-12 && (moved(1).z - p.lift_unload_m).abs() < 1e-12);
        for k in 2..top {
            let (back, was) = (-moved(k).dot(&forward), -moved(k - 1).dot(&forward));
            assert!(back > was && back <= p.lift_retreat_m + 1e-12, "pose {k}: {:?}", moved(k));
            assert!(moved(k).dot(&left).abs() < 1e-12, "pose {k}: {:?}", moved(k));
            assert!(moved(k).z > moved(k - 1).z);
            assert!(sw.path[k].rotation == from.rotation);
        }
        assert!((moved(top - 1).dot(&forward) + p.lift_retreat_m).abs() < 1e-12);
        assert!((moved(top - 1).z - p.lift_retreat_until_m).abs() < 1e-12);
        // The curve leaves the straight rise and rejoins the straight rise above vertically:
        // its first and last pieces lean less than its middle.
        let lean = |k: usize| {
            let d = moved(k + 1) - moved(k);
            d.xy().norm().atan2(d.z)
        };
        assert!(lean(1) < lean(top / 2) / 3.0 && lean(top - 2) < lean(top / 2) / 3.0);
        // The lift's top: the clearance above the target, pitched toe down as `toe_down` asks
        // with the hip where the CoM is when the lift ends.
        let mut lift_top = from;
        lift_top.translation.vector += -forward * p.lift_retreat_m;
        lift_top.translation.z = 0.36 + p.swing_clearance_m;
        let hip = rising(sw.lift_share()) - Vector3::z() * body.com_above_hip_m;
        let pitched = toe_down(Foot::Left, &lift_top, &hip, &body, &p);
        assert!(pitched != lift_top, "the test's lift is pitched");
        assert_eq!(sw.path[top], pitched);
        assert_eq!(sw.path[top + 2], to);
        assert!((sw.shares.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        // The lift is timed as one stretch at the foot's speed: its pieces' shares go as
        // their lengths (the top pitched), and it takes as long as the foot's speed asks of
        // its length before the pitch.
        let lengths = |path: &[Isometry3<f64>]| piece_lengths_m(&path[..=top]);
        let pitched_m = lengths(&sw.path);
        for (k, len) in pitched_m.iter().enumerate() {
            let want = len / pitched_m.iter().sum::<f64>();
            assert!((sw.shares[k] / sw.lift_share() - want).abs() < 1e-9, "piece {k}");
        }
        let mut level = sw.path.clone();
        level[top] = lift_top;
        let lift_m: f64 = lengths(&level).iter().sum();
        let lift_s = sw.lift_share() * sw.natural_s;
        assert!((lift_s - (lift_m / p.foot_speed_m_s).max(p.min_piece_s)).abs() < 1e-9, "{lift_s}");
        // No straight part asked: it backs away from the lift-off at once.
        let at_once = StepParams { lift_unload_m: 0.0, ..p.clone() };
        let sw0 = Swing::new(Foot::Left, &from, &to, rising, &body, &at_once);
        assert_eq!(sw0.path.len(), RETREAT_PIECES + 4);
        assert!(sw0.path[1].translation.vector.xy() != from.translation.vector.xy());
        // The CoM held still (the leading foot's swing), and along the floor: straight up.
        let still = |_: f64| Point3::new(0.3, 0.0, 0.9);
        assert_eq!(Swing::new(Foot::Right, &from, &to, still, &body, &p).path.len(), 4);
        let ahead = yawed(0.25, 0.1, 0.185);
        let floor = Swing::new(Foot::Left, &from, &ahead, rising, &body, &p);
        assert_eq!(floor.path.len(), 4);
        assert!(floor.path[1].translation.vector.xy() == from.translation.vector.xy());
        // A lift lower than the retreat's height backs away all the way to its top.
        let low = StepParams { lift_retreat_until_m: 0.5, ..p.clone() };
        let all_the_way = Swing::new(Foot::Left, &from, &to, rising, &body, &low);
        assert_eq!(all_the_way.path.len(), RETREAT_PIECES + 4);
        let below_top = all_the_way.path[RETREAT_PIECES].translation.vector - from.translation.vector;
        assert!(below_top.z < 0.18 + p.swing_clearance_m && -below_top.dot(&forward) < p.lift_retreat_m);
        // No retreat asked: straight up. An unload not below the retreat's height: refused.
        let straight = StepParams { lift_retreat_m: 0.0, ..p.clone() };
        assert_eq!(Swing::new(Foot::Left, &from, &to, rising, &body, &straight).path.len(), 4);
        let high = StepParams { lift_unload_m: 0.12, ..p.clone() };
        assert!(high.validate().unwrap_err().contains("lift_unload_m"));
    }
}
