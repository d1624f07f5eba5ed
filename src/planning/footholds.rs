//! Footholds (§6.1, §6.4): from the step rectangles and the feet where they stand, the
//! sequence of stances the gait goes through, both feet on each step. Each foothold sits in
//! the middle of its rectangle along the direction of ascent; across, each foot keeps the
//! lane it starts in, unless a surface the lidar saw beside the flight (a stairwell's wall,
//! a crate) would then be nearer the body than its half width: both lanes then move away
//! from it, on the floor before the flight or at the first step, and a flight with less room
//! between such surfaces than the body's whole width is refused
//! ([`PlanError::NarrowFlight`]); its height comes from the
//! rectangle and its yaw from the staircase, and it is level (no roll or pitch: §6.2 takes
//! every contact frame level; the rectangle's fitted normal is not a measure of a tread's
//! tilt under range noise, and a tread's tilt is assumed level, not measured). Steps the
//! feet cannot use are refused here, with the reason, before any motion is computed, and so
//! is every stance (on the floor, a tread or a landing) whose sole, or its lane on the way
//! there, is where the lidar saw something standing ([`PlanError::FloorObstructed`],
//! [`PlanError::TreadObstructed`]): the lanes do not move around it.

use super::gait::Legs;
use super::stance::{Foot, Stance};
use super::PlanError;
use crate::perception::PlaneSegment;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

/// What the feet can use (§6.1, §6.4). Lengths in metres.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GaitParams {
    /// Shortest tread a foot is placed on. The sole is 24 cm; the default lets it overhang a
    /// perceived rectangle by 1 cm at each end, since perception under-measures a tread by
    /// up to about half a voxel per edge (§4, v = 2 cm; the paper's Exp. 1 step 1 is
    /// 23.2 cm deep on a 27 cm tread). Between two steps the toe's end is the next riser,
    /// not air: there the toes keep `toe_clearance_m` behind the next front edge and the
    /// heel overhangs the nose by `heel_overhang_m` at most, so such a tread needs the sole
    /// plus the one less the other, 0.245 m (the fronts, placed on the risers by
    /// perception, within a few millimetres of the noses); this limit holds for the top
    /// tread, open behind, and for the step map's judgement of a partly seen highest step.
    pub min_tread_m: f64,
    /// Highest rise between consecutive treads the legs can climb (HRP-4's 24 cm step,
    /// §6.3, is within; the knee's fold and the trailing leg's reach set the limit).
    pub max_rise_m: f64,
    /// A rise this many times the flight's usual rise (the median of three or more, the lower
    /// of two) means a step was not seen (a missing step).
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
    /// Floor footholds before the first step keep the toes this far behind its riser as
    /// perceived. Under range noise the first step's front edge comes back onto the tread
    /// (its nose's normals mix with the riser's), by up to about 3 cm at 20 mm of noise on
    /// the paper's k = 10 normals; at 3 cm the toes reached the true riser and the swinging
    /// foot struck it (regression `noisy-views-in-pieces-and-turned`). Farther back, the
    /// feet are farther apart for the first step up, and HRP-4's 24 cm step (§6.3) is
    /// refused from 6 cm on (the leading knee would fold past its limit). 5 cm keeps the
    /// toes off the riser up to 20 mm of noise.
    pub toe_gap_m: f64,
    /// On a tread with a step above it, the toes stay at least this far behind that step's
    /// front edge as perceived: on a tread shorter than the sole plus twice this, the foot
    /// moves back from the middle, its heel toward the nose (centred on a tread barely
    /// longer than the sole, the toe meets the next riser, which perception places within a
    /// few millimetres).
    pub toe_clearance_m: f64,
    /// How far the heel may overhang a tread's front edge as perceived when the toes keep
    /// `toe_clearance_m`; a tread that needs more is refused as short.
    pub heel_overhang_m: f64,
    /// How far a sole may overhang its rectangle's side.
    pub side_overhang_m: f64,
    /// From the floor the climb starts on, a sole may overhang its rectangle's side by
    /// `side_overhang_m` less this. The lanes chosen there are kept up the flight, and each
    /// step is judged again from the treads: its side edges move by millimetres between
    /// views, the feet land millimetres off their plan, and a step judged at the limit from
    /// the floor was refused with the robot on the flight, beside an object it had moved
    /// its lanes away from (regression `lanes-at-the-limit-refused-on-the-flight`). Half a
    /// voxel (§4, v = 2 cm), perception's reach on an edge; on the flight the limit is
    /// `side_overhang_m` itself.
    pub side_commit_margin_m: f64,
    /// A foothold moved back from its tread's middle, so that the stride stays within
    /// `max_stride_m`, keeps the heel at least this far onto the tread from its front edge
    /// as perceived (about a voxel: perception places an edge within half a voxel, §4's
    /// v = 2 cm).
    pub edge_margin_m: f64,
    /// Sole length (HRP-4: 24 cm).
    pub sole_length_m: f64,
    /// Sole width (HRP-4: 13 cm).
    pub sole_width_m: f64,
    /// Half the width of the lane the body sweeps as it climbs, from the midline between
    /// the feet, metres: HRP-4's upper arms reach 0.215 m from its midline (the shoulder
    /// joint 0.175 m out, the arm 4 cm thick), the CoM sways over each foot (half the lanes'
    /// spacing, about 0.1 m), and the body keeps its 3 cm clearance from the surroundings'
    /// points, which stand up to 2 cm proud of a noisy wall. 0.36 m. The lanes move to keep
    /// what stands beside the flight this far from their midline, and a flight with less
    /// than twice this between what stands beside it at the body's height is refused from
    /// the floor (on the flight, `room_commit_margin_m` less).
    pub body_half_width_m: f64,
    /// On the flight, a room between the points seen beside it down to twice
    /// `body_half_width_m` less this is kept, metres; from the floor the climb starts on,
    /// the whole of twice `body_half_width_m` is needed ([`GaitParams::committing`] sets
    /// this to 0). The room is measured to the nearest of the points, voxel centroids that
    /// stand proud of a noisy rail or wall by the tail of the noise; a nearer look, from the
    /// flight or walking, sees more of them, and their nearest stands farther in, by
    /// centimetres (regression `walking-room-narrowed-on-the-flight`). A judgment at the
    /// limit is thus made once, before a foot is set, as
    /// `side_commit_margin_m` keeps the lanes'. 3 cm: what is left is the arms' reach, the
    /// CoM's sway and the IK's 3 cm clearance from the points themselves (0.345 m a side),
    /// which the IK's own check (`IkParams::min_body_clearance_m`) still guards.
    pub room_commit_margin_m: f64,
    /// Heights above the tread below in which a surface the lidar saw beside the feet is
    /// beside the body (from the hands to above the shoulders), metres. Lower, it is a
    /// riser, a tread's edge or a low box the legs pass above.
    pub body_band_m: [f64; 2],
    /// A walk on the floor toward a flight refused from afar ([`approach`]) sets a sole only
    /// where the lidar saw nothing standing on the floor (not two surroundings points above
    /// `floor_band_m` and below 0.5 m over it: a step nobody took for one, a box) and,
    /// beyond `approach_blind_m`, where it saw floor: at least this many points within
    /// `floor_band_m` of the floor's height under the sole. A 3 cm voxel grid holds about 34
    /// points under HRP-4's sole; 8 is a quarter of it.
    pub approach_floor_returns: usize,
    /// A stance of a climb's plan (on the floor, a tread or a landing) is refused where at
    /// least this many of the surroundings' points stand in a sole's way (its footprint
    /// grown by `obstruction_margin_m`, and its lane back to where the foot stood before),
    /// above `floor_band_m` and below 0.5 m over the floor or the perceived tread under
    /// them, off the perceived steps' own surfaces: a step perception did not take for one,
    /// a box, a parcel left on a tread. Fewer are the scatter of a riser ahead of the toes:
    /// under 20 mm of range noise the first riser's voxels stray several centimetres toward
    /// the robot along the rays, and a few stand under the last floor stance's toes
    /// (regression `riser-strays-under-the-floor-toes`). A 3 cm voxel grid holds about 34
    /// points under HRP-4's sole; 6 are a strip of it 4 cm deep.
    pub floor_obstruction_returns: usize,
    /// The same on a tread or a landing: a stance there is refused where at least this many
    /// points stand in a sole's way. Higher than on the floor: between two steps the next
    /// riser stands just past the toes, and under 20-25 mm of range noise its voxels stray
    /// past the 6 cm band that keeps a perceived step's own surfaces out (`floor_band_m`),
    /// or belong to a step not yet perceived: up to about 16 of them stand in a sole's way
    /// under 21-25 mm of noise. A thing that leaves no room for a sole shows more: a shoe's
    /// top alone is 30 x 12 cm, 40 voxels of 3 cm (regression
    /// `parcel-in-a-lane-on-step-2`). 20 is half a shoe's top.
    pub tread_obstruction_returns: usize,
    /// The surroundings' points within this of a perceived step's solid are that step's own
    /// surfaces (its tread, its riser, its nose), not something standing in a sole's way,
    /// metres: as `IkParams::leg_surface_band_m`, three standard deviations of 25 mm of range
    /// noise plus half a voxel (at `floor_band_m`'s 6 cm, over 20 strays of the next riser
    /// stand in a sole's way under 25 mm of noise). A thing lower than this on a tread is
    /// not told from the tread's own noise.
    pub step_band_m: f64,
    /// How far past a sole's outline, on every side, the obstruction test of a stance
    /// (`floor_obstruction_returns`) looks, metres: the IK keeps the legs 3 cm
    /// (`IkParams::body_clearance_m`) off what the lidar saw, but not the foot (its box is
    /// no capsule), so the footholds keep as much room around the sole.
    pub obstruction_margin_m: f64,
    /// How far ahead of the feet, along the ascent, the floor lies under the head's lidar
    /// and out of its sight, metres: tilting to 70 deg down from about 1.4 m, it sees the
    /// floor from about 0.5 m ahead of the feet. A sole nearer the start than this needs
    /// no floor returns (only nothing seen standing there).
    pub approach_blind_m: f64,
    /// Half the height of the band around the floor in which a surroundings point is floor,
    /// metres: three standard deviations of a 20 mm range noise (a voxel's centroid on the
    /// floor strays that far); a step's rise is more than twice it.
    pub floor_band_m: f64,
    /// Fault injection, to test the regression tooling only: every foothold on a step is
    /// moved this far along the ascent, metres (0: none). A planner with this set is broken
    /// on purpose, and `regress --baseline` must say so.
    pub test_foothold_shift_m: f64,
}

impl GaitParams {
    /// These limits for a climb planned from the floor it starts on: a sole's side overhang
    /// within `side_overhang_m - side_commit_margin_m`, and the room beside the flight the
    /// whole of the body's lane (no `room_commit_margin_m` taken off).
    #[must_use]
    pub fn committing(&self) -> Self {
        Self {
            side_overhang_m: self.side_overhang_m - self.side_commit_margin_m,
            room_commit_margin_m: 0.0,
            ..self.clone()
        }
    }
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
            toe_gap_m: 0.05,
            toe_clearance_m: 0.015,
            heel_overhang_m: 0.01,
            side_overhang_m: 0.02,
            side_commit_margin_m: 0.01,
            edge_margin_m: 0.02,
            sole_length_m: crate::robot::hrp4::SOLE_SIZE_M[0],
            sole_width_m: crate::robot::hrp4::SOLE_SIZE_M[1],
            body_half_width_m: 0.36,
            room_commit_margin_m: 0.03,
            body_band_m: [0.4, 1.5],
            approach_floor_returns: 8,
            floor_obstruction_returns: 6,
            tread_obstruction_returns: 20,
            step_band_m: 0.09,
            obstruction_margin_m: 0.03,
            approach_blind_m: 0.6,
            floor_band_m: 0.06,
            test_foothold_shift_m: 0.0,
        }
    }
}

/// How far inside the legs' longest stride ([`Legs::max_stride_m`]) the footholds keep a
/// step up, metres: the gait's knee check measures between the ankles, about 9 cm above the
/// soles; a measured start stance tilted a degree (the footholds' own are level,
/// [`Layout::stance_on`]) moves that by up to 4.5 mm, and at the limit itself rounding
/// alone refuses (regression `high-rise-on-a-deep-tread`). Beyond the limit itself the
/// footholds refuse.
const KNEE_STRIDE_SLACK_M: f64 = 0.005;

/// The stances after `start`, ending with both feet on the highest rectangle, or the reason
/// the staircase cannot be climbed. `seen` are the surfaces the lidar saw (the
/// surroundings' points; empty when nothing is known beside the steps); `legs` limit how far
/// apart the feet may stand for each step up.
pub fn footholds(
    start: &Stance,
    rects: &[PlaneSegment],
    seen: &[Point3<f64>],
    legs: &Legs,
    p: &GaitParams,
) -> Result<Vec<Stance>, PlanError> {
    footholds_below(start, rects, rects.len(), seen, legs, p)
}

/// [`footholds`] on the `below` lowest rectangles of `rects` only, a higher one left to be
/// judged from nearer; the next one still bounds the last's usable depth (were the last
/// judged as the top, open behind, its foot would go in its middle and the toe against the
/// next riser: regression `step-2-planned-as-the-top`).
pub fn footholds_below(
    start: &Stance,
    rects: &[PlaneSegment],
    below: usize,
    seen: &[Point3<f64>],
    legs: &Legs,
    p: &GaitParams,
) -> Result<Vec<Stance>, PlanError> {
    let all = super::rectangles::by_height(rects);
    let steps = &all[..below.min(all.len())];
    if steps.is_empty() {
        return Err(PlanError::NoSteps);
    }
    let lay = Layout::new(start, steps, seen, p);
    let u = lay.frame.u;
    let limit_rad = 10f64.to_radians();
    for (i, s) in steps.iter().enumerate() {
        let angle_rad = lay.up(s).dot(&u).clamp(-1.0, 1.0).acos();
        if lay.up(s).dot(&u) < limit_rad.cos() {
            return Err(PlanError::NotStraight { step: i, angle_rad, limit_rad });
        }
    }
    let lanes = lay.start_lanes.map(|l| l + lay.shift);
    let rises = super::rectangles::rises_m(steps, Some(lay.floor_z));
    let usual = usual_rise_m(&rises);

    let mut out = Vec::new();
    let mut prev_along = lay.start_along;
    for (i, s) in steps.iter().enumerate() {
        // The rise before the depth: a depth may grow from nearer (a step seen in part), a
        // rise does not, and a refusal for the depth sends the loop nearer to look again (a
        // strip seen high above the top tread, refused as short, was walked toward:
        // regression `wall-strip-taken-for-a-step`).
        if let Some(usual_m) = usual.filter(|&u| rises[i] >= p.missing_step_ratio * u) {
            return Err(PlanError::MissingStep { step: i, rise_m: rises[i], usual_m });
        }
        if rises[i] > p.max_rise_m {
            return Err(PlanError::HighRise { step: i, rise_m: rises[i], max_m: p.max_rise_m });
        }
        let (front, along, usable_m) = lay.foothold_along(&all, i, p);
        if let Some(as_seen) = refused_as_seen(&lay, steps, i, (front, along, usable_m), lanes, &all, p) {
            // A step refused for how it was seen (the loop would look closer) is refused for
            // good where the lidar saw something standing in a foot's lane on it: a parcel
            // that hides half the tread leaves it too narrow or too short, and no closer
            // look takes it away.
            let probe = lay.stance_on(lanes, along, s.height_m(), Some(i));
            unobstructed(&lay, &all, &probe, std::slice::from_ref(&probe), out.len(), seen, p)?;
            return Err(as_seen);
        }
        // How far along the foot may go: within the gait's stride of the stance before, and
        // within the legs' for this rise of its trailing foot (a high rise with the feet
        // far apart folds the leading knee past its limit: regression
        // `high-rise-on-a-deep-tread`); the nearest it may go keeps the heel on the tread.
        let knee_m = legs.max_stride_m(rises[i]);
        let reach = |prev: f64, trail: f64| (prev + p.max_stride_m).min(trail + knee_m - KNEE_STRIDE_SLACK_M);
        let nearest_m = along.min(front + p.sole_length_m / 2.0 + p.edge_margin_m);
        // The foot that trails the first step up is the start's left (the gait's order).
        let mut trail_along = if i == 0 { lay.start_left_along } else { prev_along };
        if i == 0 {
            // The floor walk: unless the tread's middle is within the gait's stride of the
            // start and its nearest foothold within reach.
            let within =
                along - lay.start_along <= p.max_stride_m && nearest_m <= reach(prev_along, trail_along);
            let walk = if within { Vec::new() } else { lay.floor_walk(front, p) };
            unobstructed(&lay, &all, out.last().unwrap_or(start), &walk, out.len(), seen, p)?;
            if !walk.is_empty() {
                prev_along = Layout::toes_behind(front, p);
                trail_along = prev_along;
            }
            out.extend(walk);
        } else if nearest_m > reach(prev_along, trail_along) {
            // A tread too deep for that reach (a landing, or a high rise on a deep tread):
            // the feet first walk across it toward its back, the toes ending `toe_gap_m`
            // behind the next riser as the floor's last stance keeps them (the loop,
            // planning from the tread, walks it as its floor).
            let below = steps[i - 1];
            let (below_front, _, below_usable_m) = lay.foothold_along(&all, i - 1, p);
            let across = Layout::toes_behind(below_front + below_usable_m, p);
            let walk: Vec<Stance> = strides(prev_along, across, p.approach_stride_m)
                .map(|a| lay.stance_on(lanes, a + p.test_foothold_shift_m, below.height_m(), Some(i - 1)))
                .collect();
            unobstructed(&lay, &all, out.last().unwrap_or(start), &walk, out.len(), seen, p)?;
            out.extend(walk);
            prev_along = prev_along.max(across);
            trail_along = prev_along;
        }
        // A tread deeper than the reach (regression `treads-deeper-than-the-stride`): the
        // foot goes back from the middle toward the front edge as far as the reach needs,
        // the whole sole staying on the tread.
        let far_m = reach(prev_along, trail_along);
        let along = if along > far_m { far_m.max(nearest_m).min(along) } else { along };
        if along - trail_along > knee_m {
            let (d, r) = (along - trail_along, legs.reach_m);
            return Err(PlanError::KneeFold {
                stance: out.len(),
                hip_above_ankle_m: (r * r - d * d).max(0.0).sqrt() - rises[i],
                needs_m: legs.fold_m,
                knee_max_rad: legs.knee_max_rad,
            });
        }
        let stride = along - prev_along;
        if stride > p.max_stride_m || stride < 0.0 {
            return Err(PlanError::Stride { step: i, stride_m: stride, max_m: p.max_stride_m });
        }
        let on_step = lay.stance_on(lanes, along + p.test_foothold_shift_m, s.height_m(), Some(i));
        let before = out.last().unwrap_or(start);
        unobstructed(&lay, &all, before, std::slice::from_ref(&on_step), out.len(), seen, p)?;
        out.push(on_step);
        prev_along = along;
    }
    // Between two handrails (or walls) nearer each other than the body's lane, the IK held
    // each capsule off its one nearest point and gave way toward the other side: the
    // chest went onto a rail (regression `chest-between-two-rails`). Judged over the whole
    // flight seen, not only the steps planned now, so that a narrowing higher up is refused
    // before a foot is set; and after the steps themselves (a riser over 40 cm high stands
    // in the body's band beside the feet, and is refused as the rise it is).
    let room_m = match steps.len() < all.len() {
        true => lay.room_m.min(Layout::new(start, &all, seen, p).room_m),
        false => lay.room_m,
    };
    let needs_m = 2.0 * p.body_half_width_m - p.room_commit_margin_m;
    if room_m < needs_m {
        return Err(PlanError::NarrowFlight { room_m, needs_m });
    }
    Ok(out)
}

/// The positions along the ascent of a walk from `from` to `to` in equal strides of at most
/// `stride_m`, `to` last; none when `to` is not ahead of `from`.
fn strides(from: f64, to: f64, stride_m: f64) -> impl Iterator<Item = f64> {
    let n = if to > from { ((to - from) / stride_m).ceil() as usize } else { 0 };
    (1..=n).map(move |k| from + (to - from) * k as f64 / n as f64)
}

/// The stances on the floor that walk the feet from `start` toward the flight of `rects`,
/// as [`footholds`] begins its plan, without judging the steps: where a plan was refused
/// from afar for what a closer view may show otherwise (a step seen in part, a noisy
/// tread), the loop walks these and looks again. Empty when the first step's foothold is
/// within a stride already (nothing is left to walk: a refusal then stands) or there are
/// no steps.
pub fn approach(start: &Stance, rects: &[PlaneSegment], seen: &[Point3<f64>], p: &GaitParams) -> Vec<Stance> {
    if rects.is_empty() {
        return Vec::new();
    }
    let steps = super::rectangles::by_height(rects);
    let lay = Layout::new(start, &steps, seen, p);
    let (front, along, _) = lay.foothold_along(&steps, 0, p);
    if along - lay.start_along <= p.max_stride_m {
        return Vec::new();
    }
    let mut walk = lay.floor_walk(front, p);
    let seen_free = |f: &Isometry3<f64>| {
        let blind = (f.translation.vector - lay.frame.o.coords).dot(&lay.frame.u) - lay.start_along
            < p.approach_blind_m;
        on_seen_floor(f, seen, lay.floor_z, if blind { 0 } else { p.approach_floor_returns }, p)
            && clear_of_steps(f, &steps, p)
    };
    let seen_to = walk.iter().take_while(|s| seen_free(&s.right) && seen_free(&s.left)).count();
    walk.truncate(seen_to);
    walk
}

/// Floor returns (surroundings points within `floor_band_m` of the floor) in the feet's lanes
/// before the lowest step's front that show the lidar's sight reaching there
/// ([`riser_in_sight`]): two, so that a lone stray is not taken for it.
const FLOOR_IN_SIGHT_RETURNS: usize = 2;

/// `Ok` when the lowest step of `rects` has its riser where its front edge is perceived, as
/// far as the lidar can tell from the views `seen` holds, so that a walk on the floor toward
/// it may end with the toes `toe_gap_m` behind that front: the front was placed on its riser,
/// or the lidar saw floor in the feet's lanes before it (at least `FLOOR_IN_SIGHT_RETURNS`
/// of `seen` within `floor_band_m` of the floor under `start`). The lidar sees whatever lies
/// farther than the nearest floor it sees, and higher surfaces from nearer still: a riser
/// beyond that floor would have shown its tread from the riser on, and floor stands only
/// before a riser. Else [`PlanError::RiserOutOfSight`]: set down near the first riser, the
/// robot has the floor before it and the tread's near part under its lidar, out of sight,
/// and the front it sees is where its sight begins (set down within 0.3 m of the riser, the
/// robot saw step 1 0.209 m deep, and the walk nearer, its toes 5 cm behind that front, put
/// the right foot into the riser: friction 2.55, a fall in the first cycle). For the closed
/// loop, whose `seen` is everything the lidar saw: a caller with nothing known beside the
/// steps (ground truth, a rectangles file) has no sight to judge.
pub fn riser_in_sight(
    start: &Stance,
    rects: &[PlaneSegment],
    seen: &[Point3<f64>],
    p: &GaitParams,
) -> Result<(), PlanError> {
    let steps = super::rectangles::by_height(rects);
    let Some(first) = steps.first() else { return Ok(()) };
    if first.front_on_riser() {
        return Ok(());
    }
    let lay = Layout::new(start, &steps, seen, p);
    let (o, u, w) = (lay.frame.o, lay.frame.u, lay.frame.w);
    let (front, _, _) = lay.foothold_along(&steps, 0, p);
    let lanes = lay.start_lanes.map(|l| l + lay.shift);
    let floor = seen
        .iter()
        .filter(|q| {
            let (along, across) = ((*q - o).dot(&u), (*q - o).dot(&w));
            (q.z - lay.floor_z).abs() <= p.floor_band_m
                && along < front
                && lanes.iter().any(|l| (across - l).abs() <= p.sole_width_m / 2.0)
        })
        .count();
    if floor >= FLOOR_IN_SIGHT_RETURNS {
        Ok(())
    } else {
        Err(PlanError::RiserOutOfSight { step: 0, ahead_m: front - lay.start_along })
    }
}

/// A walk back ([`retreat`]) shorter than this is not walked, metres: the feet land within
/// millimetres of a plan's stance, and a robot that stepped back as far as the front asks is
/// not sent back again by millimetres, view after view.
const LEAST_WALK_BACK_M: f64 = 0.05;

/// The stances on the floor that walk the feet back from `start`, away from the flight of
/// `rects`, for a robot whose first riser is out of the lidar's sight ([`riser_in_sight`]):
/// walking nearer could set a foot into that riser, and from farther back the lidar sees it.
/// In strides of at most `approach_stride_m`, in the lanes the feet stand in, to where the
/// lowest step's front as perceived is `approach_blind_m` ahead of the feet (the floor before
/// it then in sight); as [`approach`], only where the lidar saw nothing standing on the
/// floor (behind the feet it sees nothing) and never into or against a perceived step. The
/// front as perceived moves toward the robot as nearer parts of the tread come into view,
/// never past the riser, so walks back from it stop. Empty when the feet are that far back
/// already (within `LEAST_WALK_BACK_M`), or there are no steps. Empty too when the feet
/// stand past the lowest step's front (their middle): the view puts the step where the robot
/// stands on the floor, so it is wrong (a lone step seen with its axes swapped), and a walk
/// back from it goes backward, where the lidar never looked, as far as that wrong front asks.
pub fn retreat(start: &Stance, rects: &[PlaneSegment], seen: &[Point3<f64>], p: &GaitParams) -> Vec<Stance> {
    if rects.is_empty() {
        return Vec::new();
    }
    let steps = super::rectangles::by_height(rects);
    let lay = Layout::new(start, &steps, seen, p);
    let (front, _, _) = lay.foothold_along(&steps, 0, p);
    let back_to = front - p.approach_blind_m;
    if lay.start_along - back_to < LEAST_WALK_BACK_M || lay.start_along > front {
        return Vec::new();
    }
    let free = |f: &Isometry3<f64>| on_seen_floor(f, seen, lay.floor_z, 0, p) && clear_of_steps(f, &steps, p);
    // `strides` walks up the ascent; down it is its mirror image.
    strides(-lay.start_along, -back_to, p.approach_stride_m)
        .map(|a| lay.stance_on(lay.start_lanes, -a, lay.floor_z, None))
        .take_while(|s| free(&s.right) && free(&s.left))
        .collect()
}

/// Whether the sole at `foot`, grown by `toe_clearance_m` on every side, stays outside every
/// rectangle of `steps` seen from above: a floor stance's sole inside a step's footprint
/// would stand in its block, against its riser. Two rectangles are apart when one of their
/// four axes separates their corners.
fn clear_of_steps(foot: &Isometry3<f64>, steps: &[&PlaneSegment], p: &GaitParams) -> bool {
    let (half_l, half_w) =
        (p.sole_length_m / 2.0 + p.toe_clearance_m, p.sole_width_m / 2.0 + p.toe_clearance_m);
    let (x, y) = (foot.rotation * Vector3::x(), foot.rotation * Vector3::y());
    let c = foot.translation.vector;
    let sole = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
        .map(|(a, b)| c + x * (a * half_l) + y * (b * half_w));
    let span = |points: &[Vector3<f64>; 4], axis: &Vector3<f64>| {
        points.iter().fold([f64::INFINITY, f64::NEG_INFINITY], |[lo, hi], q| {
            let t = q.x * axis.x + q.y * axis.y;
            [lo.min(t), hi.max(t)]
        })
    };
    steps.iter().all(|s| {
        let corners: [Vector3<f64>; 4] = std::array::from_fn(|i| s.corners()[i].coords);
        let along = s.along();
        [along, Vector3::z().cross(&along), x, y].iter().any(|axis| {
            let (a, b) = (span(&sole, axis), span(&corners, axis));
            a[1] <= b[0] || b[1] <= a[0]
        })
    })
}

/// The flight's usual rise, against which a rise far above it means a step not seen: the
/// median of three or more rises; the lower of two (with step 1 unseen, the rise up to step
/// 2 is two rises, within the legs' reach, and the median of two is no guide: regression
/// `step-1-never-perceived`). None for one rise.
fn usual_rise_m(rises: &[f64]) -> Option<f64> {
    match rises {
        [] | [_] => None,
        [a, b] => Some(a.min(*b)),
        _ => crate::stats::median(rises.iter().copied()),
    }
}

/// Why step `i` of `steps` (sorted by height, `all` the whole flight) cannot be planned as
/// seen: its usable depth (`front`, `along`, `usable_m` from [`Layout::foothold_along`])
/// too short for a sole, a gap before it, or a foot's lane (`lanes`) off its side; `None`
/// when it can. Each is about the view: a closer look may see more of the step.
fn refused_as_seen(
    lay: &Layout,
    steps: &[&PlaneSegment],
    i: usize,
    (front, along, usable_m): (f64, f64, f64),
    lanes: [f64; 2],
    all: &[&PlaneSegment],
    p: &GaitParams,
) -> Option<PlanError> {
    let (o, u, w) = (lay.frame.o, lay.frame.u, lay.frame.w);
    let heel_over_m = front - (along - p.sole_length_m / 2.0);
    if usable_m < p.min_tread_m || heel_over_m > p.heel_overhang_m + 1e-9 {
        let toes_kept = all.get(i + 1).is_some_and(|n| n.front_on_riser());
        let between_m = p.sole_length_m + p.toe_clearance_m - p.heel_overhang_m;
        let min_m = if toes_kept { p.min_tread_m.max(between_m) } else { p.min_tread_m };
        return Some(PlanError::ShortTread { step: i, depth_m: usable_m, min_m });
    }
    if i > 0 {
        let back = (steps[i - 1].center() - o).dot(&u) + steps[i - 1].depth_m() / 2.0;
        let gap = front - back;
        if gap > p.max_gap_m {
            return Some(PlanError::Gap { step: i, gap_m: gap, max_m: p.max_gap_m });
        }
    }
    let side = (steps[i].center() - o).dot(&w);
    Foot::BOTH.into_iter().zip(lanes).find_map(|(f, lane)| {
        let over = (lane - side).abs() + p.sole_width_m / 2.0 - steps[i].width_m() / 2.0;
        (over > p.side_overhang_m).then_some(PlanError::OffTheSide {
            step: i,
            foot: f,
            overhang_m: over,
            max_m: p.side_overhang_m,
        })
    })
}

/// The approach walk ([`approach`]) stops before a sole with this many points standing
/// under it: it walks toward a flight refused from afar, over ground no plan has judged,
/// and errs toward stopping (a lone point is a stray: a noise spike, a mixed pixel at a
/// riser's top). A climb's own stances refuse only a surface
/// ([`GaitParams::floor_obstruction_returns`], see [`unobstructed`]).
const STANDING_RETURNS: usize = 2;

/// `Ok` when no foot of the stances `walk` (the plan's from index `first`, the feet standing
/// at `before` ahead of the first) lands on or swings through a place where the lidar saw
/// something standing (at least `floor_obstruction_returns` of `seen` in its way, see
/// [`Layout::standing_in_lane`]; `steps` are the perceived steps, sorted by height); else
/// the first such stance and foot, [`PlanError::FloorObstructed`] for a floor stance (the
/// floor the walk starts on), [`PlanError::TreadObstructed`] for one on a step.
fn unobstructed(
    lay: &Layout,
    steps: &[&PlaneSegment],
    before: &Stance,
    walk: &[Stance],
    first: usize,
    seen: &[Point3<f64>],
    p: &GaitParams,
) -> Result<(), PlanError> {
    let mut from = before;
    for (stance, st) in (first..).zip(walk) {
        for foot in Foot::BOTH {
            let (points, height_m) = lay.standing_in_lane(steps, from.foot(foot), st.foot(foot), seen, p);
            let least =
                if st.step.is_some() { p.tread_obstruction_returns } else { p.floor_obstruction_returns };
            if points >= least.max(1) {
                return Err(match st.step {
                    None => PlanError::FloorObstructed { stance, foot, points, height_m },
                    Some(step) => PlanError::TreadObstructed { stance, step, foot, points, height_m },
                });
            }
        }
        from = st;
    }
    Ok(())
}

/// A point up to this height above the floor or a tread stands on it, metres (higher, the
/// legs pass under it; the IK keeps the body off it).
const STANDING_M: f64 = 0.5;

/// The lidar's returns under a sole on the floor: the surroundings' points inside the sole's
/// outline within `floor_band_m` of the floor's height, and those above that band and below
/// 0.5 m over the floor (standing on it).
struct UnderSole {
    floor: usize,
    standing: usize,
    /// The highest standing point above the floor, metres (0 when none).
    highest_m: f64,
}

impl UnderSole {
    fn count(foot: &Isometry3<f64>, seen: &[Point3<f64>], floor_z: f64, p: &GaitParams) -> Self {
        let inv = foot.inverse();
        let mut under = Self { floor: 0, standing: 0, highest_m: 0.0 };
        for q in seen {
            let dz = q.z - floor_z;
            if dz < -p.floor_band_m || dz > STANDING_M {
                continue;
            }
            let local = inv * q;
            if local.x.abs() > p.sole_length_m / 2.0 || local.y.abs() > p.sole_width_m / 2.0 {
                continue;
            }
            if dz <= p.floor_band_m {
                under.floor += 1;
            } else {
                under.standing += 1;
                under.highest_m = under.highest_m.max(dz);
            }
        }
        under
    }
}

/// Whether the lidar saw floor under the sole at `foot` (at least `floor_returns` of `seen`
/// within `floor_band_m` of `floor_z` inside the sole) and nothing standing on it.
fn on_seen_floor(
    foot: &Isometry3<f64>,
    seen: &[Point3<f64>],
    floor_z: f64,
    floor_returns: usize,
    p: &GaitParams,
) -> bool {
    let under = UnderSole::count(foot, seen, floor_z, p);
    under.floor >= floor_returns && under.standing < STANDING_RETURNS
}

/// The flight laid out from the start stance: its frame, its yaw, the feet's lanes across
/// it (and how far they move aside), where the feet start along it.
struct Layout {
    frame: Frame,
    /// Up the flight, from its lowest step toward its highest (horizontal).
    rise: Vector3<f64>,
    yaw: UnitQuaternion<f64>,
    start_lanes: [f64; 2],
    shift: f64,
    /// The room across the flight between what the lidar saw beside it at the body's height,
    /// metres (see `Frame::lane_shift`).
    room_m: f64,
    start_along: f64,
    /// Where the start's left foot stands along the ascent (the gait's first step up
    /// trails it).
    start_left_along: f64,
    floor_z: f64,
}

impl Layout {
    /// `steps` sorted by height, at least one.
    fn new(start: &Stance, steps: &[&PlaneSegment], seen: &[Point3<f64>], p: &GaitParams) -> Self {
        // A rectangle gives its tread's axis; which way along it is up comes from the
        // flight: from the lowest step toward the highest (a landing seen alone from afar
        // comes back with its ascent reversed: regression
        // `landing-seen-alone-ascent-reversed`). A lone step keeps its own.
        let rise = steps[steps.len() - 1].center() - steps[0].center();
        let rise = Vector3::new(rise.x, rise.y, 0.0);
        let up = |s: &PlaneSegment| if s.along().dot(&rise) < 0.0 { -s.along() } else { s.along() };
        // The staircase's axis: the steps' directions of ascent weighed by their voxels.
        // The step map keeps each step's direction from its fuller view, so steps come from
        // different scans and differ by a degree or two; one step's direction, carried a
        // metre up a flight, puts the landing's centre centimetres sideways (regression
        // `landing-sideways-on-one-steps-axis`).
        let u = steps
            .iter()
            .map(|s| up(s) * s.voxel_count().max(1) as f64)
            .sum::<Vector3<f64>>()
            .try_normalize(1e-9)
            .unwrap_or_else(|| up(steps[0]));
        let w = Vector3::z().cross(&u);
        let o = steps[0].center();
        let (r0, l0) = (start.right.translation.vector, start.left.translation.vector);
        let floor_z = r0.z.min(l0.z);
        let start_lanes = [(r0 - o.coords).dot(&w), (l0 - o.coords).dot(&w)];
        let start_along = ((r0 + l0) / 2.0 - o.coords).dot(&u);
        let start_left_along = (l0 - o.coords).dot(&u);
        let frame = Frame { o, u, w };
        let (shift, room_m) = frame.lane_shift(steps, seen, start_lanes, start_along, floor_z, p);
        let yaw = UnitQuaternion::from_euler_angles(0.0, 0.0, u.y.atan2(u.x));
        Self { frame, rise, yaw, start_lanes, shift, room_m, start_along, start_left_along, floor_z }
    }

    /// A step's direction of ascent, pointing up the flight.
    fn up(&self, s: &PlaneSegment) -> Vector3<f64> {
        if s.along().dot(&self.rise) < 0.0 {
            -s.along()
        } else {
            s.along()
        }
    }

    /// Where a stance before a riser at `front` stands along the ascent (the floor's last
    /// before the first step, a walk's last across a tread): the toes `toe_gap_m` behind it.
    fn toes_behind(front: f64, p: &GaitParams) -> f64 {
        front - p.sole_length_m / 2.0 - p.toe_gap_m
    }

    /// Step `i`'s front edge, its foothold along the ascent, and its usable depth (up to
    /// the next step's nose, at most its own). The foot goes in the middle of that depth: a
    /// tread's back edge is its view's least sure (the next nose hides it from afar, and
    /// its voxels reach past the riser), and the toes must stay off the next riser (a tread
    /// seen past it puts them against it: regression `toe-struck-the-next-riser`). Where
    /// the next front was placed on its riser (perception's `riser`, within millimetres of
    /// the nose), the foot goes back from the middle as far as the toes need to stay
    /// `toe_clearance_m` behind it; a front from voxels errs by centimetres either way, and
    /// the middle is the best guess (the paper's own rectangles: Exp. 1's step 1 0.222 m
    /// deep up to step 2).
    fn foothold_along(&self, steps: &[&PlaneSegment], i: usize, p: &GaitParams) -> (f64, f64, f64) {
        let front = |s: &PlaneSegment| (s.center() - self.frame.o).dot(&self.frame.u) - s.depth_m() / 2.0;
        let s = steps[i];
        let next = steps.get(i + 1);
        let usable_m = next.map_or(s.depth_m(), |n| (front(n) - front(s)).clamp(0.0, s.depth_m()));
        let middle = front(s) + (usable_m / 2.0).min(p.landing_foothold_m);
        let toes_kept =
            next.filter(|n| n.front_on_riser()).map(|n| front(n) - p.sole_length_m / 2.0 - p.toe_clearance_m);
        (front(s), toes_kept.map_or(middle, |a| middle.min(a)), usable_m)
    }

    /// Both feet `along` the ascent in `lanes`, level at `height_m`, yawed with the
    /// staircase. Level, whatever the rectangle's fitted normal: §6.2 takes every contact
    /// frame level (its rotation the identity), and a building code's treads are level
    /// (within 1:48); the fitted normal is not a measure of a tread's tilt under range
    /// noise: the voxels' plane leans away from the sensor as a range error moves a point
    /// down and away together (under 25 mm of noise, level treads come out degrees off
    /// level, and a foot planned on that tilt lands on its edge: regression
    /// `noise-tilted-the-treads`), and a maximum-likelihood fit along the rays
    /// over-corrects the far treads and leaves the near ones degrees off. The rectangle's
    /// height is its voxels' mean, which that noise leaves alone.
    fn stance_on(&self, lanes: [f64; 2], along: f64, height_m: f64, step: Option<usize>) -> Stance {
        let Frame { o, u, w } = self.frame;
        let foot = |lane: f64| {
            let xy = o + u * along + w * lane;
            Isometry3::from_parts(Translation3::new(xy.x, xy.y, height_m), self.yaw)
        };
        Stance { right: foot(lanes[0]), left: foot(lanes[1]), step }
    }

    /// Where step `s`'s front edge is along the ascent.
    fn front(&self, s: &PlaneSegment) -> f64 {
        (s.center() - self.frame.o).dot(&self.frame.u) - s.depth_m() / 2.0
    }

    /// The height of what a foot stands on at `along` the ascent: the highest of the floor
    /// and the `steps` whose front edge is behind it.
    fn surface_z(&self, steps: &[&PlaneSegment], along: f64) -> f64 {
        steps.iter().filter(|s| self.front(s) <= along).map(|s| s.height_m()).fold(self.floor_z, f64::max)
    }

    /// Whether `q` is one of the perceived `steps`' own surfaces, within `band_m` of one: of
    /// its solid (the rectangle extruded down: its tread, the riser under its front edge,
    /// its nose), or of the riser rising from its back edge (the next step's, perceived or
    /// not: a flight's highest rectangle seen from below ends at the riser above it). The
    /// toes keep only `toe_clearance_m` behind the next riser, and under range noise its
    /// voxels stray toward the robot along the rays by up to three standard deviations
    /// (`floor_band_m`).
    fn by_a_step(&self, steps: &[&PlaneSegment], q: &Point3<f64>, band_m: f64) -> bool {
        steps.iter().any(|s| {
            let (up, d) = (self.up(s), q - s.center());
            let (along, across) = (d.dot(&up), d.dot(&Vector3::z().cross(&up)));
            let (half_depth, top) = (s.depth_m() / 2.0, s.height_m());
            across.abs() <= s.width_m() / 2.0 + band_m
                && ((along.abs() <= half_depth + band_m && q.z <= top + band_m)
                    || ((along - half_depth).abs() <= band_m && q.z >= top - band_m))
        })
    }

    /// How many of `seen` stand in a foot's way as it goes from `from` to `to`, and the
    /// highest of them above what is under it (metres, 0 when none). Its way: across the
    /// ascent, the sole's width about both poses; along it, from the toes at `from` to the
    /// toes at `to` (the whole sole there); both grown by `obstruction_margin_m`. A point
    /// stands where it is more than `floor_band_m` and at most 0.5 m above the floor or the
    /// perceived tread under it ([`Layout::surface_z`]) and not a perceived step's own
    /// surface ([`Layout::by_a_step`]).
    fn standing_in_lane(
        &self,
        steps: &[&PlaneSegment],
        from: &Isometry3<f64>,
        to: &Isometry3<f64>,
        seen: &[Point3<f64>],
        p: &GaitParams,
    ) -> (usize, f64) {
        let Frame { o, u, w } = self.frame;
        let at = |f: &Isometry3<f64>| {
            let v = f.translation.vector - o.coords;
            (v.dot(&u), v.dot(&w))
        };
        let ((along0, lane0), (along1, lane1)) = (at(from), at(to));
        let (half_length, half_width) = (p.sole_length_m / 2.0, p.sole_width_m / 2.0);
        let margin = p.obstruction_margin_m;
        let back = (along1 - half_length - margin).min(along0 + half_length);
        let along = [back, along1 + half_length + margin];
        let across = [lane0.min(lane1) - half_width - margin, lane0.max(lane1) + half_width + margin];
        let (mut points, mut highest_m) = (0, 0.0_f64);
        for q in seen {
            let (a, c) = ((q - o).dot(&u), (q - o).dot(&w));
            if a < along[0] || a > along[1] || c < across[0] || c > across[1] {
                continue;
            }
            let dz = q.z - self.surface_z(steps, a);
            if dz <= p.floor_band_m || dz > STANDING_M || self.by_a_step(steps, q, p.step_band_m) {
                continue;
            }
            points += 1;
            highest_m = highest_m.max(dz);
        }
        (points, highest_m)
    }

    /// The floor stances up to the first step, whose front edge is at `front`: strides of
    /// at most `approach_stride_m`, the toes ending `toe_gap_m` behind its riser, the lanes
    /// moving aside a share each stance (none when the start is there already).
    fn floor_walk(&self, front: f64, p: &GaitParams) -> Vec<Stance> {
        let last = Self::toes_behind(front, p);
        let span = last - self.start_along;
        strides(self.start_along, last, p.approach_stride_m)
            .map(|a| {
                let f = (a - self.start_along) / span;
                self.stance_on(self.start_lanes.map(|l| l + self.shift * f), a, self.floor_z, None)
            })
            .collect()
    }
}

/// The body's half depth along the climb (trunk and arms, ahead of and behind the feet's
/// midpoint), metres: what stands beside the flight that far beyond the first and last
/// footholds is beside the body.
const BODY_HALF_DEPTH_M: f64 = 0.3;

/// The staircase's frame: origin `o` (step 1's centre), ascent `u`, across `w` (leftward).
struct Frame {
    o: Point3<f64>,
    u: Vector3<f64>,
    w: Vector3<f64>,
}

impl Frame {
    /// How far both lanes move across (along `w`, metres) so that no surface in `seen`
    /// beside the feet, at the body's height over the tread below it and along the climb,
    /// is nearer their midline than `p.body_half_width_m`: 0 when none is; between two
    /// surfaces nearer each other than twice that, the middle. And the room between the
    /// nearest such surfaces on either side, metres (infinite without two sides): a climb
    /// is refused where it is narrower than the body's lane ([`footholds_below`]).
    fn lane_shift(
        &self,
        steps: &[&PlaneSegment],
        seen: &[Point3<f64>],
        lanes: [f64; 2],
        start_along: f64,
        floor_z: f64,
        p: &GaitParams,
    ) -> (f64, f64) {
        let Some(top) = steps.last() else { return (0.0, f64::INFINITY) };
        let front = |s: &PlaneSegment| (s.center() - self.o).dot(&self.u) - s.depth_m() / 2.0;
        // From behind the start to past the top foothold, by the body's half depth.
        let (first, last) = (
            start_along - BODY_HALF_DEPTH_M,
            front(top) + (top.depth_m() / 2.0).min(p.landing_foothold_m) + BODY_HALF_DEPTH_M,
        );
        let mid = (lanes[0] + lanes[1]) / 2.0;
        let feet_half = (lanes[0] - lanes[1]).abs() / 2.0 + p.sole_width_m / 2.0;
        let (mut right, mut left) = (f64::NEG_INFINITY, f64::INFINITY);
        for q in seen {
            let along = (q - self.o).dot(&self.u);
            if along < first || along > last {
                continue;
            }
            let across = (q - self.o).dot(&self.w) - mid;
            if across.abs() <= feet_half {
                continue; // ahead of the feet (a tread, a riser): not beside the body
            }
            let tread_z =
                steps.iter().filter(|s| front(s) <= along).map(|s| s.height_m()).fold(floor_z, f64::max);
            let above = q.z - tread_z;
            if above < p.body_band_m[0] || above > p.body_band_m[1] {
                continue;
            }
            if across > 0.0 {
                left = left.min(across);
            } else {
                right = right.max(across);
            }
        }
        let half = p.body_half_width_m;
        let shift = if left - right < 2.0 * half {
            (left + right) / 2.0
        } else {
            // The least move that fits (right + half <= left - half here).
            0.0_f64.max(right + half).min(left - half)
        };
        (shift, left - right)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::perception::FrontMark;
    use nalgebra::Point3;

    /// About HRP-4's legs: thigh and shank 0.353 m, the trailing leg to 95 % of their length,
    /// the knee folded to 125 deg at most (the planner measures them on the model).
    const LEGS: Legs =
        Legs { reach_m: 0.95 * 0.706, fold_m: 0.326, knee_max_rad: 125.0 * std::f64::consts::PI / 180.0 };

    /// Regression `landing-sideways-on-one-steps-axis`: a 0.5 m flight yawed 15.5 degrees,
    /// the robot off its centre line; the step map's steps carry directions 13.8, 14.5 and
    /// 15.5 degrees (each from its fuller view). Planned along step 1's direction, the
    /// landing 1 m up came out 3 cm sideways and the right foot "would overhang its side";
    /// along the steps' weighed direction every foot is on its tread.
    #[test]
    fn the_axis_is_the_steps_weighed_direction_not_the_first_steps() {
        let dir = |deg: f64| Vector3::new(deg.to_radians().cos(), deg.to_radians().sin(), 0.0);
        let (u, w) = (dir(15.5), dir(105.5));
        let start = Point3::new(0.94, 0.32, 0.0);
        let rect = |along: f64, z: f64, depth: f64, width: f64, yaw: f64, voxels: usize| {
            PlaneSegment::new(
                start + u * along + Vector3::z() * z,
                dir(yaw),
                depth,
                width,
                Vector3::z(),
                voxels,
            )
            .expect("valid rectangle")
        };
        let rects = [
            rect(0.135, 0.2, 0.256, 0.474, 13.8, 193),
            rect(0.405, 0.4, 0.276, 0.478, 14.5, 221),
            rect(1.18, 0.6, 1.28, 0.498, 15.5, 1580),
        ];
        let sole = |lane: f64| {
            let at = start + u * -0.3 + w * lane;
            Isometry3::from_parts(
                Translation3::new(at.x, at.y, 0.0),
                UnitQuaternion::from_euler_angles(0.0, 0.0, 15.5f64.to_radians()),
            )
        };
        let stance = Stance { right: sole(-0.165), left: sole(0.025), step: None };
        let p = GaitParams::default();
        let stances = footholds(&stance, &rects, &[], &LEGS, &p).expect("planned");
        let top = stances.last().expect("a stance");
        let landing = &rects[2];
        for foot in [&top.right, &top.left] {
            let side = (foot.translation.vector - landing.center().coords).dot(&w).abs();
            assert!(side + p.sole_width_m / 2.0 - landing.width_m() / 2.0 <= p.side_overhang_m, "{side}");
        }
    }

    /// Regression `step-1-never-perceived`: the walk on the floor to step 2 put a sole on
    /// step 1's tread, which the lidar saw. A floor stance where the lidar saw a surface
    /// standing on the floor (a box here) is refused; the floor itself, noisy, and two
    /// strays (regression `riser-strays-under-the-floor-toes`) are no obstruction.
    #[test]
    fn a_floor_stance_on_a_surface_the_lidar_saw_is_refused() {
        let p = GaitParams::default();
        let (rects, stance) = flight_and_stance(0.0);
        let grid = |z: f64, x0: f64, x1: f64| -> Vec<Point3<f64>> {
            let n = ((x1 - x0) / 0.03) as usize;
            (0..=n)
                .flat_map(|i| {
                    (0..=14).map(move |k| Point3::new(x0 + 0.03 * i as f64, -0.21 + 0.03 * k as f64, z))
                })
                .collect()
        };
        // Floor seen from the feet to the first riser, 4 cm either side of its height.
        let mut floor = grid(0.04, 0.0, 0.45);
        floor.extend(grid(-0.04, 0.0, 0.45));
        let walk = footholds(&stance, &rects, &floor, &LEGS, &p).expect("planned over seen floor");
        assert!(walk[0].step.is_none(), "a floor stance first");
        // Two strays above the floor under the sole (a noisy riser's scatter): no surface.
        let sole = walk[0].right.translation.vector;
        let mut strays = floor.clone();
        strays.extend([
            Point3::new(sole.x + 0.1, sole.y, 0.17),
            Point3::new(sole.x + 0.1, sole.y + 0.03, 0.16),
        ]);
        footholds(&stance, &rects, &strays, &LEGS, &p).expect("planned over two strays");
        // A 12 cm high box top under the floor stance, seen.
        let mut boxed = floor.clone();
        boxed.extend(grid(0.12, 0.25, 0.40));
        match footholds(&stance, &rects, &boxed, &LEGS, &p) {
            Err(PlanError::FloorObstructed { stance: 0, points, height_m, .. }) => {
                assert!(
                    points >= p.floor_obstruction_returns && (height_m - 0.12).abs() < 1e-9,
                    "{points} {height_m}"
                )
            }
            other => panic!("expected the floor stance refused, got {other:?}"),
        }
    }

    /// Regression `parcel-in-a-lane-on-step-2`: a parcel (0.32 x 0.20 x 0.12 m) on step 2,
    /// in the right foot's lane: the loop set the sole on it, the knee and then the
    /// swinging foot struck it, and the robot fell. A stance on a tread where the lidar saw
    /// something standing in a sole's way is refused; the treads' and risers' own voxels,
    /// noisy, are no obstruction, nor is the parcel beside the lane.
    #[test]
    fn a_tread_stance_where_the_lidar_saw_an_object_is_refused() {
        let p = GaitParams::default();
        let (rects, stance) = flight_and_stance(0.0);
        // Voxel centroids every 3 cm over x in `xs` and y in `ys`, at height `z`.
        let grid = |xs: [f64; 2], ys: [f64; 2], z: f64| -> Vec<Point3<f64>> {
            let n = |r: [f64; 2]| ((r[1] - r[0]) / 0.03).round() as usize;
            (0..=n(xs))
                .flat_map(|i| {
                    (0..=n(ys)).map(move |k| Point3::new(xs[0] + 0.03 * i as f64, ys[0] + 0.03 * k as f64, z))
                })
                .collect()
        };
        // Each tread seen 4 cm either side of its height, and each riser's voxels strayed
        // 2 and 4.5 cm toward the robot (20 mm of range noise).
        let mut steps_seen = Vec::new();
        for r in &rects {
            let (front, z) = (r.center().x - r.depth_m() / 2.0, r.height_m());
            for dz in [-0.04, 0.04] {
                steps_seen.extend(grid([front, front + 0.27], [-0.42, 0.42], z + dz));
            }
            for dx in [0.02, 0.045] {
                for k in 0..5 {
                    steps_seen.extend(grid([front - dx; 2], [-0.42, 0.42], z - 0.1 + 0.02 * k as f64));
                }
            }
        }
        let clear = footholds(&stance, &rects, &steps_seen, &LEGS, &p).expect("no obstruction");
        let on_step_2 = clear.iter().position(|s| s.step == Some(1)).expect("a stance on step 2");
        // The parcel's top on step 2 (its tread from x = 0.78, 0.34 m up) in the right lane.
        let mut parcel = steps_seen.clone();
        parcel.extend(grid([0.80, 1.04], [-0.19, -0.01], 0.46));
        match footholds(&stance, &rects, &parcel, &LEGS, &p) {
            Err(PlanError::TreadObstructed { stance, step: 1, foot: Foot::Right, points, height_m }) => {
                assert_eq!(stance, on_step_2);
                assert!(
                    points >= p.tread_obstruction_returns && (height_m - 0.12).abs() < 1e-9,
                    "{points} {height_m}"
                );
            }
            other => panic!("a sole set on the parcel: {other:?}"),
        }
        // The same parcel 12 cm beside the right sole: no obstruction.
        let mut beside = steps_seen.clone();
        beside.extend(grid([0.80, 1.04], [-0.46, -0.28], 0.46));
        assert_eq!(footholds(&stance, &rects, &beside, &LEGS, &p).expect("a parcel beside the lane"), clear);
    }

    /// Regression `step-1-never-perceived`: step 1 unseen, the flight seen as 0.263 m up to
    /// step 2 and 0.132 m to step 3. With two rises the median says nothing, 0.263 m is
    /// within the legs' 0.28 m, and the walk went onto step 1. The lower of two rises is
    /// the usual one: a step is missing.
    #[test]
    fn a_rise_twice_the_other_of_two_is_a_missing_step() {
        let step = |along: f64, z: f64| {
            PlaneSegment::new(Point3::new(along, 0.0, z), Vector3::x(), 0.33, 1.2, Vector3::z(), 300)
                .expect("valid rectangle")
        };
        let rects = [step(0.5, 0.263), step(0.83, 0.395)];
        let sole = |y: f64| Isometry3::translation(0.0, y, 0.0);
        let stance = Stance { right: sole(-0.095), left: sole(0.095), step: None };
        match footholds(&stance, &rects, &[], &LEGS, &GaitParams::default()) {
            Err(PlanError::MissingStep { step: 0, usual_m, .. }) => assert!((usual_m - 0.132).abs() < 1e-9),
            other => panic!("expected a missing step below step 1, got {other:?}"),
        }
        // Two equal rises are a flight.
        let even = [step(0.5, 0.132), step(0.83, 0.264)];
        footholds(&stance, &even, &[], &LEGS, &GaitParams::default()).expect("planned");
    }

    /// A straight flight of three 17 cm steps along x, 0.9 m wide, the robot standing on
    /// the floor `lateral` off its middle.
    fn flight_and_stance(lateral: f64) -> (Vec<PlaneSegment>, Stance) {
        let rects: Vec<PlaneSegment> = (0..3)
            .map(|i| {
                PlaneSegment::new(
                    Point3::new(0.64 + 0.28 * i as f64, 0.0, 0.17 * (i + 1) as f64),
                    Vector3::x(),
                    0.28,
                    0.9,
                    Vector3::z(),
                    300,
                )
                .expect("valid rectangle")
            })
            .collect();
        let sole = |y: f64| Isometry3::translation(0.2, lateral + y, 0.0);
        (rects, Stance { right: sole(-0.095), left: sole(0.095), step: None })
    }

    /// Points of a vertical wall at `y`, from the floor to 2 m, along the flight.
    fn wall(y: f64) -> Vec<Point3<f64>> {
        (0..60)
            .flat_map(|i| (0..66).map(move |k| Point3::new(-0.2 + 0.03 * i as f64, y, 0.03 * k as f64)))
            .collect()
    }

    fn lanes_of(stances: &[Stance]) -> Vec<f64> {
        stances.iter().map(|s| (s.right.translation.y + s.left.translation.y) / 2.0).collect()
    }

    /// Regression `stairwell-shoulder-met-the-wall`: a stairwell 0.9 m wide, the robot
    /// 15 cm off its middle. In its lanes, the left shoulder met the wall as the CoM went
    /// over the left foot; the lanes move to keep the body's half width off the wall, on
    /// the floor first.
    #[test]
    fn lanes_move_off_a_wall_beside_the_flight_and_stay_without_one() {
        let p = GaitParams::default();
        let (rects, stance) = flight_and_stance(0.15);
        let free = footholds(&stance, &rects, &[], &LEGS, &p).expect("planned");
        assert!(lanes_of(&free).iter().all(|y| (y - 0.15).abs() < 1e-9), "no wall: lanes kept");
        // A low box beside (its top below the hands) moves nothing either.
        let low: Vec<Point3<f64>> = wall(0.45).into_iter().filter(|q| q.z < 0.3).collect();
        let beside_low = footholds(&stance, &rects, &low, &LEGS, &p).expect("planned");
        assert_eq!(lanes_of(&beside_low), lanes_of(&free));
        // A wall at y = 0.45: the midline goes to 0.45 - 0.36 = 0.09, by the top for good.
        let walled = footholds(&stance, &rects, &wall(0.45), &LEGS, &p).expect("planned");
        let lanes = lanes_of(&walled);
        assert!(lanes.iter().all(|y| *y <= 0.15 + 1e-9 && *y >= 0.09 - 1e-9), "{lanes:?}");
        assert!((lanes.last().expect("stances") - 0.09).abs() < 1e-9, "{lanes:?}");
        for s in &walled {
            let half_gap = (s.left.translation.y - s.right.translation.y) / 2.0;
            assert!((half_gap - 0.095).abs() < 1e-9, "the feet keep their spacing");
        }
        // Walls on both sides with room for the body's lane: the lanes go where it fits.
        let mut both = wall(0.45);
        both.extend(wall(-0.30));
        let between = footholds(&stance, &rects, &both, &LEGS, &p).expect("planned");
        let last = *lanes_of(&between).last().expect("stances");
        assert!(
            last - p.body_half_width_m >= -0.30 - 1e-9 && last + p.body_half_width_m <= 0.45 + 1e-9,
            "{last}"
        );
    }

    /// Regression `lanes-at-the-limit-refused-on-the-flight`: a lane whose sole overhangs the
    /// steps' side by 15 mm is within the flight's 20 mm, but not within what a climb planned
    /// from the floor keeps (`side_commit_margin_m` less), where the lanes are chosen for the
    /// whole flight.
    #[test]
    fn a_lane_near_the_side_is_kept_on_the_flight_and_refused_from_the_floor() {
        let p = GaitParams::default();
        let over_m = 0.015;
        let (rects, stance) = flight_and_stance(0.45 + over_m - p.sole_width_m / 2.0 - 0.095);
        assert!(footholds(&stance, &rects, &[], &LEGS, &p).is_ok(), "within side_overhang_m");
        match footholds(&stance, &rects, &[], &LEGS, &p.committing()) {
            Err(PlanError::OffTheSide { foot: Foot::Left, overhang_m, max_m, .. }) => {
                assert!((overhang_m - over_m).abs() < 1e-9, "{overhang_m}");
                assert!((max_m - (p.side_overhang_m - p.side_commit_margin_m)).abs() < 1e-12, "{max_m}");
            }
            other => panic!("expected the left lane refused from the floor, got {other:?}"),
        }
    }

    /// Regression `chest-between-two-rails`: handrails on both sides of a 0.82 m flight. The
    /// lanes went to the middle and the IK was left to keep the body off both rails; holding
    /// each capsule off its one nearest point, it let the chest come to 7 mm of a rail and
    /// the robot fell. Walls on both sides nearer each other than the body's lane: refused,
    /// from the floor.
    #[test]
    fn a_flight_narrower_than_the_bodys_lane_is_refused() {
        let p = GaitParams::default();
        let (rects, stance) = flight_and_stance(0.15);
        let mut both = wall(0.35);
        both.extend(wall(-0.2));
        match footholds(&stance, &rects, &both, &LEGS, &p.committing()) {
            Err(PlanError::NarrowFlight { room_m, needs_m }) => {
                assert!(
                    (room_m - 0.55).abs() < 1e-9 && (needs_m - 2.0 * p.body_half_width_m).abs() < 1e-12,
                    "{room_m}"
                )
            }
            other => panic!("expected the flight refused as narrow, got {other:?}"),
        }
    }

    /// Regression `walking-room-narrowed-on-the-flight`: a nearer look sees more of a noisy
    /// rail's returns, and the nearest of them stands farther in. A room between the
    /// flight's limit and the floor's (`room_commit_margin_m` wider) is refused from the
    /// floor and kept on the flight, so that a judgment at the limit is made once, before a
    /// foot is set.
    #[test]
    fn a_room_near_the_limit_is_refused_from_the_floor_and_kept_on_the_flight() {
        let p = GaitParams::default();
        let (rects, stance) = flight_and_stance(0.0);
        let room_m = 2.0 * p.body_half_width_m - p.room_commit_margin_m / 2.0;
        let mut both = wall(room_m / 2.0);
        both.extend(wall(-room_m / 2.0));
        let on_the_flight = footholds(&stance, &rects, &both, &LEGS, &p).expect("room enough on the flight");
        assert!(lanes_of(&on_the_flight).iter().all(|l| l.abs() < 1e-9), "{:?}", lanes_of(&on_the_flight));
        match footholds(&stance, &rects, &both, &LEGS, &p.committing()) {
            Err(PlanError::NarrowFlight { room_m: seen_m, needs_m }) => {
                assert!((seen_m - room_m).abs() < 1e-9, "{seen_m}");
                assert!((needs_m - 2.0 * p.body_half_width_m).abs() < 1e-12, "{needs_m}");
            }
            other => panic!("expected the flight refused from the floor, got {other:?}"),
        }
    }

    /// Regression `landing-seen-alone-ascent-reversed`: the top landing, seen alone from
    /// afar, came back with its ascent reversed; a rectangle is the same whichever way its
    /// axis points, and the flight's rise says which way is up.
    #[test]
    fn a_step_returned_with_its_ascent_reversed_is_read_up_the_flight() {
        let (mut rects, stance) = flight_and_stance(0.0);
        let top = rects[2].clone();
        rects[2] =
            PlaneSegment::new(top.center(), -top.along(), top.depth_m(), top.width_m(), Vector3::z(), 3000)
                .expect("valid rectangle");
        let stances = footholds(&stance, &rects, &[], &LEGS, &GaitParams::default()).expect("planned");
        let on_top = stances.last().expect("stances");
        assert_eq!(on_top.step, Some(2));
        assert!((on_top.right.translation.x - 1.2).abs() < 1e-9, "{}", on_top.right.translation.x);
        // Truly turned is still refused.
        let turned =
            PlaneSegment::new(top.center(), Vector3::y(), 0.28, 0.9, Vector3::z(), 10).expect("valid");
        rects[2] = turned;
        assert!(matches!(
            footholds(&stance, &rects, &[], &LEGS, &GaitParams::default()),
            Err(PlanError::NotStraight { step: 2, .. })
        ));
    }

    /// A level tread 1 m wide ascending along x, its nose at `front`, its top at `z`.
    fn tread(front: f64, z: f64, depth: f64) -> PlaneSegment {
        PlaneSegment::level_along_x(front, z, depth)
    }

    /// A tread's back edge seen 2 cm past the next riser (voxels reach past it): the foot goes
    /// in the middle of the tread up to the next nose, so the toes stay as far from the next
    /// riser as the heel from the nose (regression `toe-struck-the-next-riser`).
    #[test]
    fn a_foot_is_centred_between_the_nose_and_the_next_nose() {
        let rects = [tread(0.5, 0.17, 0.29), tread(0.77, 0.34, 0.27)];
        let sole = |y: f64| Isometry3::translation(0.3, y, 0.0);
        let stances = footholds(
            &Stance { right: sole(-0.1), left: sole(0.1), step: None },
            &rects,
            &[],
            &LEGS,
            &GaitParams::default(),
        )
        .expect("planned");
        let on_step_1 = stances.iter().find(|s| s.step == Some(0)).expect("a stance on step 1");
        assert!((on_step_1.right.translation.x - 0.635).abs() < 1e-9, "{}", on_step_1.right.translation.x);
        let on_step_2 = stances.iter().find(|s| s.step == Some(1)).expect("a stance on step 2");
        assert!((on_step_2.right.translation.x - 0.905).abs() < 1e-9, "the top step: its own middle");
    }

    /// Regression `wall-strip-taken-for-a-step`: from the top tread (0.461 m), a strip 6 cm
    /// deep seen 1.03 m above the feet (on the room's far wall). Its rise is judged before
    /// its depth: refused as too high, which a closer look cannot undo, not as a short
    /// tread, which sent the loop walking toward it.
    #[test]
    fn a_rise_is_judged_before_the_depth() {
        let sole = |y: f64| Isometry3::translation(0.3, y, 0.461);
        let start = Stance { right: sole(-0.1), left: sole(0.1), step: Some(2) };
        match footholds(&start, &[tread(1.1, 1.496, 0.058)], &[], &LEGS, &GaitParams::default()) {
            Err(PlanError::HighRise { step: 0, rise_m, .. }) => assert!((rise_m - 1.035).abs() < 1e-9),
            other => panic!("expected a rise too high, got {other:?}"),
        }
    }

    /// Regression `tread-split-in-two-under-20mm`: a view split a tread in two pieces at
    /// one height, one 4 mm past the other; the first left no depth up to the second's
    /// front, its foothold went on the nose and the robot fell. A tread is as deep as the
    /// foot can use, up to the next step's front edge: one too shallow that way is refused
    /// like a short tread.
    #[test]
    fn a_tread_hidden_by_the_next_step_is_refused_as_short() {
        let sole = |y: f64| Isometry3::translation(0.3, y, 0.0);
        let start = Stance { right: sole(-0.1), left: sole(0.1), step: None };
        let p = GaitParams::default();
        let split = [tread(0.5, 0.17, 0.29), tread(0.504, 0.172, 0.286), tread(0.79, 0.34, 0.27)];
        match footholds(&start, &split, &[], &LEGS, &p) {
            Err(PlanError::ShortTread { step: 0, depth_m, .. }) => assert!((depth_m - 0.004).abs() < 1e-9),
            other => panic!("a foothold on the nose: {other:?}"),
        }
        // The next step's front 0.25 m past: the sole fits, planned.
        let whole = [tread(0.5, 0.17, 0.29), tread(0.75, 0.34, 0.27)];
        assert!(footholds(&start, &whole, &[], &LEGS, &p).is_ok());
    }

    /// Treads deeper than the stride (regression `treads-deeper-than-the-stride`: 0.368 m
    /// treads, their middles 0.402 m apart as seen) were refused for a stride of 0.402 m
    /// over 0.400. The foot goes back toward the nose by what the stride needs, the sole
    /// wholly on its tread; a tread whose whole sole would not then fit within the stride
    /// is still refused.
    #[test]
    fn a_tread_deeper_than_the_stride_takes_the_foot_back_toward_its_nose() {
        let p = GaitParams::default();
        // Steps of (front edge, depth) along x, 15 cm apart in height.
        let flight = |steps: &[(f64, f64)]| -> Vec<PlaneSegment> {
            steps
                .iter()
                .enumerate()
                .map(|(i, &(front, d))| {
                    PlaneSegment::new(
                        Point3::new(front + d / 2.0, 0.0, 0.15 * (i + 1) as f64),
                        Vector3::x(),
                        d,
                        1.0,
                        Vector3::z(),
                        100,
                    )
                    .expect("valid rectangle")
                })
                .collect()
        };
        let sole = |y: f64| Isometry3::translation(0.3, y, 0.0);
        let start = Stance { right: sole(-0.1), left: sole(0.1), step: None };
        // Step 3's front 0.402 m past step 2's (as the view of ci 6 had it), 36 cm treads.
        let rects = flight(&[(0.5, 0.36), (0.868, 0.36), (1.27, 0.36)]);
        let stances = footholds(&start, &rects, &[], &LEGS, &p).expect("planned within the stride");
        let xs: Vec<f64> =
            stances.iter().filter(|s| s.step.is_some()).map(|s| s.right.translation.x).collect();
        for (k, w) in xs.windows(2).enumerate() {
            assert!(w[1] - w[0] <= p.max_stride_m + 1e-9, "stride {} is {:.3} m", k + 2, w[1] - w[0]);
        }
        for (x, r) in xs.iter().zip(&rects) {
            let front = r.center().x - r.depth_m() / 2.0;
            assert!(
                x - p.sole_length_m / 2.0 >= front + p.edge_margin_m - 1e-9,
                "a heel off its tread at {x:.3}"
            );
            assert!(x + p.sole_length_m / 2.0 <= front + r.depth_m() + 1e-9, "toes off the tread at {x:.3}");
        }
        assert!(xs[2] < 1.27 + 0.18 - 1e-3, "step 3's foot went back from where it would go: {:.3}", xs[2]);
        // After a 1.2 m landing, step 3's whole sole is not within a stride: the feet walk
        // across the landing first, every stride within the gait's.
        let far = flight(&[(0.5, 0.36), (0.868, 1.2), (2.068, 0.36)]);
        let stances = footholds(&start, &far, &[], &LEGS, &p).expect("planned across the landing");
        let xs: Vec<f64> = stances.iter().map(|s| s.right.translation.x).collect();
        assert!(xs.windows(2).all(|w| w[1] > w[0] && w[1] - w[0] <= p.max_stride_m + 1e-9), "{xs:?}");
        assert!(stances.iter().filter(|s| s.step == Some(1)).count() >= 4, "{xs:?}");
    }

    /// High rises on deep treads (regression `high-rise-on-a-deep-tread`): the feet a
    /// tread's depth apart fold the leading knee past its limit, and the climb was refused
    /// for it. Each step up keeps the feet within the stride the legs allow for its rise:
    /// the foot goes toward the nose, and where even that is too far the feet first walk
    /// across the tread below to its back; every sole stays on its tread, the toes off the
    /// next riser.
    #[test]
    fn a_high_rise_on_a_deep_tread_keeps_the_feet_within_the_knees_stride() {
        let p = GaitParams::default();
        let (rise, depth) = (0.26, 0.40);
        let rects: Vec<PlaneSegment> =
            (0..3).map(|i| tread(1.0 + depth * i as f64, rise * (i + 1) as f64, depth)).collect();
        let sole = |y: f64| Isometry3::translation(0.3, y, 0.0);
        let start = Stance { right: sole(-0.1), left: sole(0.1), step: None };
        let stances = footholds(&start, &rects, &[], &LEGS, &p).expect("planned within the knee's stride");
        let mut prev = &start;
        for (k, st) in stances.iter().enumerate() {
            let (from, to) = (prev.left.translation, st.right.translation);
            let (d, up) = (to.x - from.x, to.z - from.z);
            assert!(d >= 0.0 && d <= p.max_stride_m + 1e-9, "stance {k}: stride {d:.3} m");
            if up > 1e-6 {
                let max = LEGS.max_stride_m(up);
                assert!(
                    d <= max + 1e-9,
                    "stance {k}: {d:.3} m apart for a {up:.2} m rise, the knee allows {max:.3}"
                );
            }
            if let Some(i) = st.step {
                let front = 1.0 + depth * i as f64;
                for f in [&st.right, &st.left] {
                    let x = f.translation.x;
                    assert!(
                        (f.translation.z - rise * (i + 1) as f64).abs() < 1e-9,
                        "stance {k} off its tread"
                    );
                    assert!(
                        x - p.sole_length_m / 2.0 >= front + p.edge_margin_m - 1e-9,
                        "stance {k}: heel over the nose"
                    );
                    assert!(
                        x + p.sole_length_m / 2.0 <= front + depth - p.toe_gap_m + 1e-9,
                        "stance {k}: toes at the riser"
                    );
                }
            }
            prev = st;
        }
        // Three steps up, and a walk across each of the two lower treads.
        assert_eq!(stances.iter().filter(|s| s.step.is_some()).count(), 5);
        // A 0.28 m rise: the nearest footholds, toes behind the riser and heel on the tread,
        // are beyond the knee's stride for it; refused here, before the floor walk's first
        // stance could be taken (the loop takes one stance a scan).
        let high: Vec<PlaneSegment> =
            (0..3).map(|i| tread(1.0 + depth * i as f64, 0.28 * (i + 1) as f64, depth)).collect();
        match footholds(&start, &high, &[], &LEGS, &p) {
            Err(PlanError::KneeFold { stance, .. }) => assert!(stance > 0, "after the floor walk's stances"),
            other => panic!("a 0.28 m rise on 0.40 m treads: {other:?}"),
        }
        // The gait's own limit alone (legs that reach far) keeps the tread's middle.
        let long = Legs { reach_m: 2.0, ..LEGS };
        let free = footholds(&start, &rects, &[], &long, &p).expect("planned");
        assert_eq!(free.iter().filter(|s| s.step.is_some()).count(), 3);
    }

    /// A tread barely longer than the sole between two steps (the foot centred on it puts
    /// its toe on the next riser, and the swing strikes it): the toes keep
    /// `toe_clearance_m` behind the next front edge, the heel overhanging the nose by
    /// `heel_overhang_m` at most; a tread that would need more is refused as short, but not
    /// the top one, whose back edge is open.
    #[test]
    fn on_a_short_tread_the_toes_keep_off_the_next_riser() {
        let p = GaitParams::default();
        let sole = |y: f64| Isometry3::translation(0.3, y, 0.0);
        let start = Stance { right: sole(-0.1), left: sole(0.1), step: None };
        let flight = |depth: f64| -> Vec<PlaneSegment> {
            (0..3)
                .map(|i| {
                    tread(0.5 + depth * i as f64, 0.15 * (i + 1) as f64, depth).with_front(FrontMark::Riser)
                })
                .collect()
        };
        let stances = footholds(&start, &flight(0.25), &[], &LEGS, &p).expect("a 0.25 m tread is used");
        for st in stances.iter().filter(|s| s.step.is_some_and(|i| i < 2)) {
            let i = st.step.unwrap_or(0);
            let (front, next) = (0.5 + 0.25 * i as f64, 0.5 + 0.25 * (i + 1) as f64);
            for f in [&st.right, &st.left] {
                let x = f.translation.x;
                assert!(
                    x + p.sole_length_m / 2.0 <= next - p.toe_clearance_m + 1e-9,
                    "step {i}: toe at {x:.3}"
                );
                assert!(
                    x - p.sole_length_m / 2.0 >= front - p.heel_overhang_m - 1e-9,
                    "step {i}: heel at {x:.3}"
                );
            }
        }
        match footholds(&start, &flight(0.24), &[], &LEGS, &p) {
            Err(PlanError::ShortTread { step: 0, min_m, .. }) => {
                assert!((min_m - 0.245).abs() < 1e-9, "{min_m}")
            }
            other => panic!("a 0.24 m tread between two steps: {other:?}"),
        }
        let top = [tread(0.5, 0.15, 0.24)];
        assert!(footholds(&start, &top, &[], &LEGS, &p).is_ok(), "a lone 0.24 m tread has no riser behind");
        // Fronts from voxels (off by centimetres either way): the foot in the middle.
        let voxels: Vec<PlaneSegment> =
            (0..3).map(|i| tread(0.5 + 0.24 * i as f64, 0.15 * (i + 1) as f64, 0.24)).collect();
        let stances = footholds(&start, &voxels, &[], &LEGS, &p).expect("the middle of a 0.24 m tread");
        let first = stances.iter().find(|s| s.step == Some(0)).expect("step 1");
        assert!((first.right.translation.x - 0.62).abs() < 1e-9);
    }

    /// Regression `set-down-near-the-first-riser`: set down 0.28 m from the first riser of
    /// the paper's Exp. 1 (the feet's middle to the riser), the robot sees step 1 only from
    /// where its lidar's sight begins: 0.209 m of its 0.27 m tread, from 0.341 m, the front
    /// not on the riser, no floor seen before it. The walk toward that front, one stride,
    /// put the toes `toe_gap_m` behind it, 11 mm past the riser: the right foot struck it.
    /// That riser is out of sight, and the feet walk back instead, to where the front is
    /// `approach_blind_m` ahead; a front on its riser, or floor seen in a lane before it,
    /// is in sight.
    #[test]
    fn a_first_riser_out_of_sight_is_walked_away_from_not_toward() {
        let p = GaitParams::default();
        let stance_at = |x: f64| Stance {
            right: Isometry3::translation(x, -0.1, 0.0),
            left: Isometry3::translation(x, 0.1, 0.0),
            step: None,
        };
        let start = stance_at(0.0);
        let rects = [tread(0.341, 0.2, 0.209), tread(0.55, 0.4, 0.27), tread(0.82, 0.6, 0.27)];
        match riser_in_sight(&start, &rects, &[], &p) {
            Err(PlanError::RiserOutOfSight { step: 0, ahead_m }) => {
                assert!((ahead_m - 0.341).abs() < 1e-9, "{ahead_m}")
            }
            other => panic!("a front seen where the sight begins: {other:?}"),
        }
        // The walk nearer goes past the riser at 0.28 m: what this refusal keeps from moving.
        let nearer = approach(&start, &rects, &[], &p);
        let toe = |st: &Stance| st.right.translation.x + p.sole_length_m / 2.0;
        assert!(nearer.last().is_some_and(|st| toe(st) > 0.28), "the walk toward the front as seen");
        // Floor seen beside the flight only, and one stray in a lane: still out of sight.
        let mut seen: Vec<Point3<f64>> =
            (0..20).flat_map(|i| [-0.6, 0.6].map(|y| Point3::new(0.4 + 0.03 * i as f64, y, 0.0))).collect();
        seen.push(Point3::new(0.3, 0.1, 0.01));
        assert!(riser_in_sight(&start, &rects, &seen, &p).is_err(), "a lone stray is no floor");
        // Floor seen in the lanes before the front, or the front on its riser: in sight.
        seen.push(Point3::new(0.32, -0.1, -0.01));
        assert!(riser_in_sight(&start, &rects, &seen, &p).is_ok());
        let mut placed = rects.clone();
        placed[0] = rects[0].clone().with_front(FrontMark::Riser);
        assert!(riser_in_sight(&start, &placed, &[], &p).is_ok());

        // The walk back: in the feet's lanes, within the approach's stride, on the floor, to
        // the front less `approach_blind_m`.
        let back = retreat(&start, &rects, &[], &p);
        let mut from = 0.0;
        for st in &back {
            assert_eq!(st.step, None);
            let x = st.right.translation.x;
            assert!(x < from && from - x <= p.approach_stride_m + 1e-9, "{from:.3} -> {x:.3}");
            for (f, y) in [(&st.right, -0.1), (&st.left, 0.1)] {
                assert!((f.translation.x - x).abs() < 1e-9 && (f.translation.y - y).abs() < 1e-9);
                assert!(f.translation.z.abs() < 1e-9);
            }
            from = x;
        }
        assert!((from - (0.341 - p.approach_blind_m)).abs() < 1e-9, "ends at {from:.3}");
        // From there (within millimetres), nothing more is walked back.
        assert!(retreat(&stance_at(from + 0.004), &rects, &[], &p).is_empty());
        // Feet whose middle stands past the front stand where the view puts the step: nothing
        // is walked back, however far the front asks (`real-0073`: a lone step seen turned
        // walked the robot back into a wall no view had seen). With the middle before it (the
        // toes over it, as a front seen centimetres off allows) the walk back stands.
        assert!(retreat(&stance_at(0.35), &rects, &[], &p).is_empty());
        assert!(!retreat(&stance_at(0.33), &rects, &[], &p).is_empty());
        // A box seen where the feet would go: no stance there.
        let boxed: Vec<Point3<f64>> = (0..10)
            .flat_map(|i| {
                (0..12).map(move |k| Point3::new(-0.3 + 0.03 * i as f64, -0.18 + 0.03 * k as f64, 0.2))
            })
            .collect();
        assert!(retreat(&start, &rects, &boxed, &p).is_empty());
    }

    /// A walk nearer keeps every sole, grown by `toe_clearance_m`, off every perceived step's
    /// footprint, not only the lowest step's front: a higher rectangle reaching nearer than
    /// the lowest one's front (a view no plan has judged) stops the walk before it.
    #[test]
    fn the_walk_nearer_keeps_off_every_perceived_step() {
        let p = GaitParams::default();
        let sole = |y: f64| Isometry3::translation(0.0, y, 0.0);
        let start = Stance { right: sole(-0.1), left: sole(0.1), step: None };
        let floor: Vec<Point3<f64>> = (0..=30)
            .flat_map(|i| (0..=14).map(move |k| Point3::new(0.03 * i as f64, -0.21 + 0.03 * k as f64, 0.0)))
            .collect();
        let toe = |st: &Stance| st.right.translation.x + p.sole_length_m / 2.0;
        let lowest = tread(0.9, 0.15, 0.3);
        let walk = approach(&start, std::slice::from_ref(&lowest), &floor, &p);
        assert_eq!(walk.len(), 3);
        assert!((toe(&walk[2]) - (0.9 - p.toe_gap_m)).abs() < 1e-9, "the toes toe_gap_m behind the front");
        // A rectangle 0.15 m higher from 0.6 m to 1.8 m: its front nearer than the lowest's.
        let nearer = PlaneSegment::new(Point3::new(1.2, 0.0, 0.3), Vector3::x(), 1.2, 1.0, Vector3::z(), 10)
            .expect("valid rectangle");
        let kept = approach(&start, &[lowest, nearer], &floor, &p);
        assert!(!kept.is_empty() && kept.len() < walk.len(), "{} stances", kept.len());
        for st in &kept {
            assert!(toe(st) <= 0.6 - p.toe_clearance_m + 1e-9, "a toe at {:.3} m", toe(st));
        }
    }

    /// The lowest steps planned alone, a higher one left for a closer look: the next one's
    /// front still bounds the last planned tread (regression `step-2-planned-as-the-top`).
    #[test]
    fn a_step_left_for_later_still_bounds_the_tread_below_it() {
        let p = GaitParams::default();
        let sole = |y: f64| Isometry3::translation(0.3, y, 0.0);
        let start = Stance { right: sole(-0.1), left: sole(0.1), step: None };
        let rects: Vec<PlaneSegment> = (0..3)
            .map(|i| tread(0.5 + 0.23 * i as f64, 0.1 * (i + 1) as f64, 0.23).with_front(FrontMark::Riser))
            .collect();
        assert!(matches!(
            footholds_below(&start, &rects, 1, &[], &LEGS, &p),
            Err(PlanError::ShortTread { step: 0, .. })
        ));
        // Alone (nothing known beyond it), a 0.23 m tread is the top, open behind.
        let alone = footholds(&start, &rects[..1], &[], &LEGS, &p);
        assert!(alone.is_ok(), "{alone:?}");
    }
}
