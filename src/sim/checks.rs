//! The checks of an execution, judged from what the simulator actually has (the bench is the
//! judge; the robot's controller never reads this): the CoM inside the static-stability
//! polygon of the feet really in contact, each loaded foot's resultant inside the friction
//! pyramid, each sole's centre of pressure inside the sole, joint torques (the servos'
//! unclamped demand) and speeds within the model's limits, the feet at their targets at
//! touchdown and on their step, soles not sliding, no foot strike during a swing, no part
//! other than the soles touching the world, no fall, and no MuJoCo warning.
//!
//! Each check is a function of measured values returning the violated [`Check`] with its
//! figures, so each is unit-tested alone; [`Monitor`] applies them at every physics step.

use super::world::World;
use crate::climb::{Check, CheckKind, Execution, SimWarning, Touchdown, Violation};
use crate::geom2d::P2;
use crate::planning::contact::Contact;
use crate::planning::dd::DdParams;
use crate::planning::gait::Swing;
use crate::planning::polygon::{by_double_description, margin};
use crate::planning::Foot;
use crate::robot::model::{base_pose, Joint};
use crate::scene::geometry::SOLE_ON_TREAD_M;
use crate::scene::mjcf::ROBOT_GEOM_GROUP;
use crate::scene::Scene;
use nalgebra::{Isometry3, Point3, Vector3};

/// Limits of the checks.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CheckParams {
    /// Least CoM margin inside the stability polygon, metres (0: inside is enough).
    pub min_margin_m: f64,
    /// Largest torque demand as a fraction of the joint's torque limit.
    pub max_torque_ratio: f64,
    /// Largest joint speed as a fraction of the joint's speed limit.
    pub max_speed_ratio: f64,
    /// Largest sole position error at touchdown, metres.
    pub touchdown_tolerance_m: f64,
    /// Largest sole yaw error at touchdown, radians.
    pub touchdown_yaw_tolerance_rad: f64,
    /// How far a landed sole may overhang its step's tread, metres.
    pub overhang_tolerance_m: f64,
    /// A swinging foot touching the world other than on a level face while its planned sole
    /// is farther than this from both its lift-off and its target is a strike, metres (a
    /// distance, whatever the name): the sole's first and last centimetre are its lift-off
    /// and its landing. Below its target too: a foot rising to a higher tread passes the
    /// riser under that tread's nose.
    pub strike_height_m: f64,
    /// Normal force above which a foot counts as in contact, newtons.
    pub contact_force_n: f64,
    /// Normal force from which a foot's resultant must lie in the friction pyramid, newtons.
    /// A foot carrying less is being set down or lifted by position servos: its tangential
    /// force is the closed chain's internal force, not the plan's, and what that does (the
    /// sole sliding) is checked by `slip_tolerance_m` instead.
    pub friction_load_n: f64,
    /// How far a sole in contact may slide from where it came down, metres.
    pub slip_tolerance_m: f64,
    /// A fall: the base this far below its start height, metres.
    pub fall_drop_m: f64,
    /// A fall: the base tilted more than this, radians.
    pub fall_tilt_rad: f64,
}

impl Default for CheckParams {
    fn default() -> Self {
        Self {
            min_margin_m: 0.0,
            max_torque_ratio: 1.0,
            max_speed_ratio: 1.0,
            touchdown_tolerance_m: 0.02,
            touchdown_yaw_tolerance_rad: 3f64.to_radians(),
            overhang_tolerance_m: 0.02,
            strike_height_m: 0.01,
            contact_force_n: 5.0,
            friction_load_n: 40.0,
            slip_tolerance_m: 0.005,
            fall_drop_m: 0.25,
            fall_tilt_rad: 30f64.to_radians(),
        }
    }
}

/// Slack of the centre-of-pressure check beyond the sole's edge, metres (contact points lie
/// on the edge itself, to rounding).
const COP_TOLERANCE_M: f64 = 1e-3;

/// The CoM's margin `margin_m` in the polygon of the feet `down` (-inf without a polygon).
pub fn margin_check(margin_m: f64, down: [bool; 2], p: &CheckParams) -> Option<Check> {
    (margin_m < p.min_margin_m).then(|| Check::Margin {
        margin_m: margin_m.is_finite().then_some(margin_m),
        limit_m: p.min_margin_m,
        feet_down: down,
    })
}

/// A foot's resultant `local_n` in its sole frame: its friction ratio when loaded, and the
/// violation when it leaves the pyramid of the surface's true coefficient `surface_mu` (the
/// simulator's, from the scenario: the bench is the judge), the plan's assumed one
/// (`plan_mu`) named beside it so a failure says which was wrong.
pub fn friction_check(
    foot: Foot,
    local_n: &Vector3<f64>,
    [surface_mu, plan_mu]: [f64; 2],
    p: &CheckParams,
) -> (Option<f64>, Option<Check>) {
    let normal = local_n.z.abs();
    if normal < p.friction_load_n {
        return (None, None);
    }
    let ratio = local_n.x.abs().max(local_n.y.abs()) / normal;
    let mu = surface_mu;
    let out = local_n.x.abs() > mu * normal || local_n.y.abs() > mu * normal;
    let check = out.then_some(Check::Friction {
        foot,
        tangential_n: [local_n.x, local_n.y],
        normal_n: normal,
        limit: mu,
        planned_mu: Some(plan_mu),
    });
    (Some(ratio), check)
}

/// A foot's centre of pressure `cop` in its sole frame against the sole's half sizes.
pub fn cop_check(foot: Foot, cop: &Point3<f64>, half_m: [f64; 2]) -> Option<Check> {
    let [hx, hy] = half_m;
    (cop.x.abs() > hx + COP_TOLERANCE_M || cop.y.abs() > hy + COP_TOLERANCE_M).then_some(Check::Cop {
        foot,
        cop_m: [cop.x, cop.y],
        half_m,
        tolerance_m: COP_TOLERANCE_M,
    })
}

/// A joint's torque demand against its limit.
pub fn torque_check(joint: &Joint, demand_nm: f64, p: &CheckParams) -> Option<Check> {
    (demand_nm.abs() / joint.effort_nm > p.max_torque_ratio).then(|| Check::Torque {
        joint: joint.name.clone(),
        demand_nm: demand_nm.abs(),
        limit_nm: joint.effort_nm,
        max_ratio: p.max_torque_ratio,
    })
}

/// A joint's speed against its limit.
pub fn speed_check(joint: &Joint, speed_rad_s: f64, p: &CheckParams) -> Option<Check> {
    (speed_rad_s.abs() / joint.velocity_rad_s > p.max_speed_ratio).then(|| Check::Speed {
        joint: joint.name.clone(),
        speed_rad_s: speed_rad_s.abs(),
        limit_rad_s: joint.velocity_rad_s,
        max_ratio: p.max_speed_ratio,
    })
}

/// The sole `sole` of `foot` landing against its `target`.
pub fn touchdown_check(
    foot: Foot,
    sole: &Isometry3<f64>,
    target: &Isometry3<f64>,
    p: &CheckParams,
) -> (Touchdown, Option<Check>) {
    let error_m = (sole.translation.vector - target.translation.vector).norm();
    let yaw_error_rad = (sole.rotation.inverse() * target.rotation).euler_angles().2.abs();
    let bad = error_m > p.touchdown_tolerance_m || yaw_error_rad > p.touchdown_yaw_tolerance_rad;
    let check = bad.then_some(Check::Touchdown {
        foot,
        error_m,
        yaw_error_rad,
        limit_m: p.touchdown_tolerance_m,
        limit_yaw_rad: p.touchdown_yaw_tolerance_rad,
    });
    (Touchdown { foot, error_m, yaw_error_rad }, check)
}

/// How far the sole at `sole` (half sizes `half_m`) overhangs the true tread it stands on
/// (the step whose height is within [`SOLE_ON_TREAD_M`] of it); `None` on the floor.
pub fn overhang_m(scene: &Scene, sole: &Isometry3<f64>, half_m: [f64; 2]) -> Option<f64> {
    let step = scene.steps().iter().find(|s| (s.height_m - sole.translation.z).abs() < SOLE_ON_TREAD_M)?;
    let [hx, hy] = half_m;
    let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
    Some(
        corners
            .iter()
            .map(|(sx, sy)| step.outside_m(&sole.transform_point(&Point3::new(sx * hx, sy * hy, 0.0))))
            .fold(0.0, f64::max),
    )
}

/// A landed sole overhanging its step by `overhang_m` ([`overhang_m`]).
pub fn off_step_check(foot: Foot, overhang_m: Option<f64>, p: &CheckParams) -> Option<Check> {
    let over = overhang_m.filter(|o| *o > p.overhang_tolerance_m)?;
    Some(Check::OffStep { foot, overhang_m: over, limit_m: p.overhang_tolerance_m })
}

/// A sole in contact now at `at`, having come down at `from` (world).
pub fn slip_check(foot: Foot, at: &Vector3<f64>, from: &Vector3<f64>, p: &CheckParams) -> Option<Check> {
    let slip_m = (at - from).xy().norm();
    (slip_m > p.slip_tolerance_m).then_some(Check::Slip { foot, slip_m, limit_m: p.slip_tolerance_m })
}

/// Cosine of the largest angle from vertical of a contact normal that is a sole meeting a
/// level surface (20 deg): an early landing, not a strike.
const LEVEL_CONTACT_COS: f64 = 0.9397;

/// A contact at `at` (world, its normal `normal`) between the swinging `sw` and the world's
/// geom `other`, the sole being planned at `planned`: a strike when the planned sole is
/// farther than the strike height from both its lift-off and its target (so not a lift-off,
/// not a landing; below the target too, a lift rising past the riser under a higher tread),
/// against a surface that is not level (a riser, a nose's edge, a wall: a sole that
/// meets a level tread early, on a step higher than perceived, has landed; what that does is
/// judged by the friction, slip and off-step checks).
pub fn strike_check(
    sw: &Swing,
    planned: &Isometry3<f64>,
    at: &Point3<f64>,
    normal: &Vector3<f64>,
    other: &str,
    p: &CheckParams,
) -> Option<Check> {
    let (start, target) = (&sw.path[0], &sw.path[sw.path.len() - 1]);
    let from = |pose: &Isometry3<f64>| (planned.translation.vector - pose.translation.vector).norm();
    let from_ends_m = from(start).min(from(target));
    if from_ends_m <= p.strike_height_m || normal.z.abs() >= LEVEL_CONTACT_COS {
        return None;
    }
    let above_target_m = planned.translation.z - target.translation.z;
    let local = planned.inverse_transform_point(at);
    Some(Check::Strike {
        foot: sw.foot,
        geom: other.to_string(),
        at_m: [local.x, local.y, local.z],
        above_target_m,
        from_ends_m,
        limit_m: p.strike_height_m,
    })
}

/// Whether the robot fell: the base at `qpos` below `min_base_z_m`, or tilted away from the
/// plan's base orientation (`planned_q`; a lean the plan asked for is not a fall).
pub fn fall_check(qpos: &[f64], planned_q: &[f64], min_base_z_m: f64, p: &CheckParams) -> Option<Check> {
    let up = base_pose(qpos).rotation * Vector3::z();
    let tilt_rad = up.angle(&(base_pose(planned_q).rotation * Vector3::z()));
    (qpos[2] < min_base_z_m || tilt_rad > p.fall_tilt_rad).then(|| Check::Fall {
        base_z_m: qpos[2],
        min_base_z_m,
        tilt_rad,
        limit_tilt_rad: p.fall_tilt_rad,
        upright_tilt_rad: up.angle(&Vector3::z()),
    })
}

/// MuJoCo's warnings counted since `seen` (updated), as checks.
pub fn warning_checks(world: &World, seen: &mut [i32; 7]) -> Vec<Check> {
    let stats = world.data().warning();
    let mut out = Vec::new();
    for (k, warning) in SimWarning::ALL.into_iter().enumerate() {
        let Some(s) = stats.get(k) else { continue };
        if s.number > seen[k] {
            seen[k] = s.number;
            out.push(Check::Unstable { warning, count: s.number, info: s.lastinfo });
        }
    }
    out
}

/// What a contact of the robot is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ContactKind {
    /// A sole (foot body `foot`, 0 right, 1 left) on the world.
    Foot(usize),
    /// Anything else of the robot on the world, or the robot on itself: a collision.
    Collision {
        /// The robot's geom.
        robot: usize,
        /// The other geom.
        other: usize,
    },
    /// Not the robot's (the world on the world).
    World,
}

/// Classifies the contact between geoms `g1` and `g2` (the robot's geoms are in group
/// [`ROBOT_GEOM_GROUP`]; its feet are the bodies `feet_bodies`).
pub fn classify_contact(world: &World, g1: usize, g2: usize, feet_bodies: [usize; 2]) -> ContactKind {
    let robot = |g: usize| world.geom_group(g) == ROBOT_GEOM_GROUP;
    let (r, other) = match (robot(g1), robot(g2)) {
        (true, false) => (g1, g2),
        (false, true) => (g2, g1),
        (true, true) => (g1, g2),
        _ => return ContactKind::World,
    };
    let body = world.model().geom_bodyid()[r] as usize;
    match feet_bodies.iter().position(|&b| b == body) {
        Some(foot) if !robot(other) => ContactKind::Foot(foot),
        _ => ContactKind::Collision { robot: r, other },
    }
}

/// The robot's identifiers in the world.
pub struct Ids {
    /// The feet's bodies (right, left).
    pub feet_bodies: [usize; 2],
    /// The sole sites (right, left).
    pub sole_sites: [usize; 2],
    /// The root body (its subtree CoM is the robot's).
    pub root_body: usize,
}

/// The polygon of the feet in contact, recomputed only when they change.
#[derive(Default)]
struct PolygonCache {
    key: Option<([bool; 2], [Isometry3<f64>; 2], f64)>,
    polygon: Vec<P2>,
}

impl PolygonCache {
    fn polygon(
        &mut self,
        down: [bool; 2],
        soles: &[Isometry3<f64>; 2],
        half_m: &[[f64; 2]; 2],
        friction: f64,
        dd: &DdParams,
    ) -> &[P2] {
        let moved = |a: &Isometry3<f64>, b: &Isometry3<f64>| {
            (a.translation.vector - b.translation.vector).norm() > 1e-3
                || a.rotation.angle_to(&b.rotation) > 5e-3
        };
        let stale = match &self.key {
            Some((d, s, mu)) => {
                *d != down || *mu != friction || (0..2).any(|k| down[k] && moved(&s[k], &soles[k]))
            }
            None => true,
        };
        if stale {
            let contacts: Vec<Contact> = (0..2)
                .filter(|&k| down[k])
                .filter_map(|k| Contact::new(soles[k], half_m[k][0], half_m[k][1], friction).ok())
                .collect();
            self.polygon = by_double_description(&contacts, dd).unwrap_or_default();
            self.key = Some((down, *soles, friction));
        }
        &self.polygon
    }
}

/// What the feet's contacts carry at one instant.
pub struct FootLoads {
    /// Sum of normal forces, newtons.
    pub normal_n: [f64; 2],
    /// Sum of contact points weighted by their normal force.
    pub moment: [Vector3<f64>; 2],
    /// Resultant force, world frame.
    pub force: [Vector3<f64>; 2],
    /// The least friction coefficient among each foot's contacts (the surfaces' true ones,
    /// as the simulator applies them); infinite without a contact.
    pub surface_mu: [f64; 2],
}

impl Default for FootLoads {
    fn default() -> Self {
        Self {
            normal_n: [0.0; 2],
            moment: [Vector3::zeros(); 2],
            force: [Vector3::zeros(); 2],
            surface_mu: [f64::INFINITY; 2],
        }
    }
}

/// The checks, with what they found so far.
pub struct Monitor<'a> {
    /// The robot's identifiers.
    pub ids: Ids,
    p: &'a CheckParams,
    /// The friction coefficient the plan assumed.
    plan_mu: f64,
    dd: &'a DdParams,
    scene: &'a Scene,
    sole_half_m: [[f64; 2]; 2],
    cache: PolygonCache,
    last_report: Vec<(CheckKind, f64)>,
    /// Where each sole in contact came down (world), `None` while it is in the air.
    landed: [Option<Vector3<f64>>; 2],
    warnings_seen: [i32; 7],
    /// Where the plan's frame (the robot's estimate when the plan began) lies in the true
    /// world: a touchdown is judged against its target carried there, so it measures how the
    /// body followed the plan, not how far the estimate had drifted (where the foot ended on
    /// the true treads is the overhang's and the collisions' to judge). Identity when the
    /// loop read the true pose.
    pub plan_to_world: Isometry3<f64>,
    /// What was found so far.
    pub ex: Execution,
}

impl<'a> Monitor<'a> {
    /// A monitor judging against `scene` (the true steps) with limits `p`; the polygons are
    /// built with the plan's double description on soles of half sizes `sole_half_m` (right,
    /// left), the friction the plan assumed is named beside the surface's in a failure.
    pub fn new(
        world: &World,
        ids: Ids,
        scene: &'a Scene,
        sole_half_m: [[f64; 2]; 2],
        p: &'a CheckParams,
        plan: &'a crate::planning::gait::StepParams,
    ) -> Self {
        let (dd, plan_mu) = (&plan.dd, plan.friction);
        let mut warnings_seen = [0; 7];
        for (k, s) in world.data().warning().iter().enumerate().take(7) {
            warnings_seen[k] = s.number;
        }
        Self {
            ids,
            p,
            plan_mu,
            dd,
            scene,
            sole_half_m,
            cache: PolygonCache::default(),
            last_report: Vec::new(),
            landed: [None, None],
            warnings_seen,
            plan_to_world: Isometry3::identity(),
            ex: Execution::empty(),
        }
    }

    /// Records a violation, the first of its kind per simulated second.
    fn report(&mut self, t_s: f64, check: Check) {
        let kind = check.kind();
        if let Some(e) = self.last_report.iter_mut().find(|(c, _)| *c == kind) {
            if t_s - e.1 < 1.0 {
                return;
            }
            e.1 = t_s;
        } else {
            self.last_report.push((kind, t_s));
        }
        self.ex.violations.push(Violation { t_s, cycle: 0, check });
    }

    /// Sums the feet's contact forces; reports other parts touching the world, robot parts
    /// touching each other, and a swinging foot that strikes (`swing` with its planned sole).
    pub fn contacts(
        &mut self,
        world: &World,
        now: f64,
        swing: Option<(&Swing, &Isometry3<f64>)>,
    ) -> FootLoads {
        let mut loads = FootLoads::default();
        let d = world.data();
        for (ci, c) in d.contact().iter().enumerate() {
            let foot = match classify_contact(world, c.geom1 as usize, c.geom2 as usize, self.ids.feet_bodies)
            {
                ContactKind::World => continue,
                ContactKind::Collision { robot, other } => {
                    let check = Check::Collision {
                        geom: world.geom_name(robot).to_string(),
                        other: world.geom_name(other).to_string(),
                    };
                    self.report(now, check);
                    continue;
                }
                ContactKind::Foot(foot) => foot,
            };
            let f = d.contact_force(ci);
            // The contact frame's rows are its normal and two tangents (MuJoCo's layout).
            let axis = |r: usize| Vector3::new(c.frame[3 * r], c.frame[3 * r + 1], c.frame[3 * r + 2]);
            loads.force[foot] += axis(0) * f[0] + axis(1) * f[1] + axis(2) * f[2];
            if f[0] > 0.0 {
                loads.surface_mu[foot] = loads.surface_mu[foot].min(c.friction[0]);
            }
            loads.normal_n[foot] += f[0].max(0.0);
            loads.moment[foot] += Vector3::from(c.pos) * f[0].max(0.0);
            if let Some((sw, planned)) = swing.filter(|(sw, _)| sw.foot.index() == foot) {
                let other =
                    if world.geom_group(c.geom1 as usize) == ROBOT_GEOM_GROUP { c.geom2 } else { c.geom1 };
                // The contact carried into the plan's frame, where the swing was planned.
                if let Some(check) = strike_check(
                    sw,
                    planned,
                    &self.plan_to_world.inverse_transform_point(&Point3::from(c.pos)),
                    &self.plan_to_world.inverse_transform_vector(&axis(0)),
                    world.geom_name(other as usize),
                    self.p,
                ) {
                    self.report(now, check);
                }
            }
        }
        loads
    }

    /// Which feet carry load; each one's resultant inside its sole's friction pyramid (§6.2),
    /// its centre of pressure inside the sole, and the sole not sliding.
    pub fn feet(&mut self, now: f64, loads: &FootLoads, soles: &[Isometry3<f64>; 2]) -> [bool; 2] {
        let down = loads.normal_n.map(|n| n > self.p.contact_force_n);
        for (k, foot) in Foot::BOTH.into_iter().enumerate() {
            if !down[k] {
                self.landed[k] = None;
                continue;
            }
            let at = soles[k].translation.vector;
            let from = *self.landed[k].get_or_insert(at);
            self.ex.max_slip_m = self.ex.max_slip_m.max((at - from).xy().norm());
            if let Some(check) = slip_check(foot, &at, &from, self.p) {
                self.report(now, check);
                self.landed[k] = Some(at);
            }
            let local = soles[k].rotation.inverse() * loads.force[k];
            let (ratio, check) = friction_check(foot, &local, [loads.surface_mu[k], self.plan_mu], self.p);
            if let Some(r) = ratio {
                self.ex.max_friction_ratio = self.ex.max_friction_ratio.max(r);
            }
            if let Some(check) = check {
                self.report(now, check);
            }
            let cop = soles[k].inverse_transform_point(&Point3::from(loads.moment[k] / loads.normal_n[k]));
            if let Some(check) = cop_check(foot, &cop, self.sole_half_m[k]) {
                self.report(now, check);
            }
        }
        down
    }

    /// The CoM against the stability polygon of the feet in contact.
    /// Returns this instant's margin, metres (negative outside, -inf without a polygon).
    /// The polygon is that of the surfaces' true friction (`loads.surface_mu`).
    pub fn margin(
        &mut self,
        world: &World,
        now: f64,
        loads: &FootLoads,
        down: [bool; 2],
        soles: &[Isometry3<f64>; 2],
    ) -> f64 {
        let com = world.data().subtree_com()[self.ids.root_body];
        let mu = (0..2).filter(|&k| down[k]).map(|k| loads.surface_mu[k]).fold(f64::INFINITY, f64::min);
        let mu = if mu.is_finite() { mu } else { self.plan_mu };
        let poly = self.cache.polygon(down, soles, &self.sole_half_m, mu, self.dd);
        let m = if poly.len() >= 3 { margin(poly, &P2::new(com[0], com[1])) } else { f64::NEG_INFINITY };
        self.ex.min_margin_m = self.ex.min_margin_m.min(m);
        if let Some(check) = margin_check(m, down, self.p) {
            self.report(now, check);
        }
        m
    }

    /// Joint torques (the servos' demand, `demand_nm(actuator)`) and speeds against the
    /// model's limits; returns this instant's largest torque ratio.
    pub fn joints(
        &mut self,
        joints: &[Joint],
        demand_nm: impl Fn(usize) -> f64,
        speed_rad_s: impl Fn(usize) -> f64,
        now: f64,
    ) -> f64 {
        let mut now_max = 0.0_f64;
        for (a, jt) in joints.iter().enumerate() {
            let demand = demand_nm(a);
            let r = demand.abs() / jt.effort_nm;
            now_max = now_max.max(r);
            let speed = speed_rad_s(a);
            let s = speed.abs() / jt.velocity_rad_s;
            if r > self.ex.max_torque_ratio {
                self.ex.max_torque_ratio = r;
                self.ex.torque_joint.clone_from(&jt.name);
            }
            if s > self.ex.max_speed_ratio {
                self.ex.max_speed_ratio = s;
                self.ex.speed_joint.clone_from(&jt.name);
            }
            if let Some(check) = torque_check(jt, demand, self.p) {
                self.report(now, check);
            }
            if let Some(check) = speed_check(jt, speed, self.p) {
                self.report(now, check);
            }
        }
        now_max
    }

    /// Records a touchdown of `sw`'s foot and checks it against its target and its step.
    pub fn touchdown(&mut self, now: f64, sw: &Swing, soles: &[Isometry3<f64>; 2]) {
        let sole = &soles[sw.foot.index()];
        let target = self.plan_to_world * sw.path[sw.path.len() - 1];
        let (touchdown, check) = touchdown_check(sw.foot, sole, &target, self.p);
        self.ex.touchdowns.push(touchdown);
        if let Some(check) = check {
            self.report(now, check);
        }
        let over = overhang_m(self.scene, sole, self.sole_half_m[sw.foot.index()]);
        if let Some(check) = off_step_check(sw.foot, over, self.p) {
            self.report(now, check);
        }
    }

    /// Whether the robot fell (see [`fall_check`]); the base may not drop below
    /// `min_base_z_m`.
    pub fn fell(&mut self, world: &World, now: f64, min_base_z_m: f64, planned_q: &[f64]) -> bool {
        let Some(check) = fall_check(world.data().qpos(), planned_q, min_base_z_m, self.p) else {
            return false;
        };
        self.report(now, check);
        self.ex.fell = true;
        true
    }

    /// MuJoCo's warnings since the last step; returns the first, which ends the execution.
    pub fn warnings(&mut self, world: &World, now: f64) -> Option<SimWarning> {
        let checks = warning_checks(world, &mut self.warnings_seen);
        let first = checks.iter().find_map(|c| match c {
            Check::Unstable { warning, .. } => Some(*warning),
            _ => None,
        });
        for check in checks {
            self.report(now, check);
        }
        if first.is_some() {
            self.ex.unstable = first;
        }
        first
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planning::gait::Swing;
    use nalgebra::{Translation3, UnitQuaternion};

    fn p() -> CheckParams {
        CheckParams::default()
    }

    fn joint() -> Joint {
        Joint {
            name: "R_KNEE_P".into(),
            link: 0,
            lower_rad: -1.0,
            upper_rad: 1.0,
            effort_nm: 100.0,
            velocity_rad_s: 6.0,
        }
    }

    fn at(x: f64, y: f64, z: f64) -> Isometry3<f64> {
        Isometry3::from_parts(Translation3::new(x, y, z), UnitQuaternion::identity())
    }

    #[test]
    fn margin_fires_below_the_least_margin_and_names_the_feet() {
        assert_eq!(margin_check(0.01, [true, true], &p()), None);
        let c = margin_check(-0.05, [true, false], &p()).expect("outside fires");
        assert_eq!(c, Check::Margin { margin_m: Some(-0.05), limit_m: 0.0, feet_down: [true, false] });
        let c = margin_check(f64::NEG_INFINITY, [false, false], &p()).expect("no polygon fires");
        assert!(matches!(c, Check::Margin { margin_m: None, .. }));
        let strict = CheckParams { min_margin_m: 0.02, ..p() };
        assert!(
            matches!(margin_check(0.01, [true, true], &strict), Some(Check::Margin { limit_m, .. }) if limit_m == 0.02)
        );
    }

    #[test]
    fn friction_judges_loaded_feet_only_against_the_pyramid() {
        let (ratio, check) = friction_check(Foot::Left, &Vector3::new(30.0, -5.0, 100.0), [0.7, 0.7], &p());
        assert_eq!((ratio, check), (Some(0.3), None));
        let (ratio, check) = friction_check(Foot::Right, &Vector3::new(-36.0, 7.9, 48.9), [0.7, 0.7], &p());
        assert!((ratio.expect("loaded") - 36.0 / 48.9).abs() < 1e-12);
        let c = check.expect("beyond 0.7 fires");
        assert_eq!(
            c,
            Check::Friction {
                foot: Foot::Right,
                tangential_n: [-36.0, 7.9],
                normal_n: 48.9,
                limit: 0.7,
                planned_mu: Some(0.7)
            }
        );
        // Just inside the pyramid: 34.2 < 0.7 x 48.9 = 34.23.
        assert_eq!(friction_check(Foot::Right, &Vector3::new(-34.2, 7.9, 48.9), [0.7, 0.7], &p()).1, None);
        // Across the sole's y axis too.
        assert!(friction_check(Foot::Right, &Vector3::new(0.0, 80.0, 100.0), [0.7, 0.7], &p()).1.is_some());
        // A foot being set down (under the load threshold) is not judged.
        assert_eq!(
            friction_check(Foot::Right, &Vector3::new(30.0, 0.0, 20.0), [0.7, 0.7], &p()),
            (None, None)
        );
        // A surface slipperier than the plan assumed: judged by the surface, the plan's named.
        let (ratio, check) = friction_check(Foot::Left, &Vector3::new(50.0, 0.0, 100.0), [0.4, 0.7], &p());
        assert_eq!(ratio, Some(0.5));
        assert!(
            matches!(check, Some(Check::Friction { limit, planned_mu: Some(mu), .. }) if limit == 0.4 && mu == 0.7)
        );
    }

    #[test]
    fn cop_fires_outside_the_sole_beyond_its_slack() {
        let half = [0.12, 0.065];
        assert_eq!(cop_check(Foot::Right, &Point3::new(0.1205, 0.0, 0.0), half), None, "within the slack");
        let c = cop_check(Foot::Left, &Point3::new(0.0, -0.07, 0.0), half).expect("outside fires");
        assert_eq!(c, Check::Cop { foot: Foot::Left, cop_m: [0.0, -0.07], half_m: half, tolerance_m: 1e-3 });
        let m = c.measure().expect("measured");
        assert!((m.value - 0.005).abs() < 1e-12);
    }

    #[test]
    fn torque_and_speed_fire_beyond_their_share_of_the_limits() {
        assert_eq!(torque_check(&joint(), -99.0, &p()), None);
        let c = torque_check(&joint(), -120.0, &p()).expect("over fires");
        assert_eq!(
            c,
            Check::Torque { joint: "R_KNEE_P".into(), demand_nm: 120.0, limit_nm: 100.0, max_ratio: 1.0 }
        );
        assert_eq!(c.to_string(), "R_KNEE_P needs 120 % of its torque limit (120.0 of 100.0 N m)");
        let half = CheckParams { max_torque_ratio: 0.5, ..p() };
        assert!(torque_check(&joint(), 60.0, &half).is_some());
        assert_eq!(speed_check(&joint(), 5.9, &p()), None);
        let c = speed_check(&joint(), -7.5, &p()).expect("over fires");
        assert_eq!(
            c,
            Check::Speed { joint: "R_KNEE_P".into(), speed_rad_s: 7.5, limit_rad_s: 6.0, max_ratio: 1.0 }
        );
    }

    #[test]
    fn touchdown_fires_on_position_or_yaw_error() {
        let target = at(1.0, 0.1, 0.2);
        let (td, c) = touchdown_check(Foot::Right, &at(1.01, 0.1, 0.2), &target, &p());
        assert!((td.error_m - 0.01).abs() < 1e-12 && c.is_none());
        let (_, c) = touchdown_check(Foot::Right, &at(1.03, 0.1, 0.2), &target, &p());
        assert!(
            matches!(c, Some(Check::Touchdown { foot: Foot::Right, error_m, limit_m, .. }) if (error_m - 0.03).abs() < 1e-12 && limit_m == 0.02)
        );
        let yawed =
            Isometry3::from_parts(target.translation, UnitQuaternion::from_euler_angles(0.0, 0.0, 0.1));
        let (td, c) = touchdown_check(Foot::Left, &yawed, &target, &p());
        assert!((td.yaw_error_rad - 0.1).abs() < 1e-9);
        assert!(matches!(c, Some(Check::Touchdown { foot: Foot::Left, .. })));
    }

    #[test]
    fn off_step_fires_on_a_sole_overhanging_the_true_tread() {
        let scene = Scene::from_scenario(&crate::scenario::Scenario::default()).expect("Exp. 1 builds");
        let s1 = &scene.steps()[0];
        let c = s1.corners.iter().map(|c| c.coords).sum::<Vector3<f64>>() / 4.0;
        let half = [0.12, 0.065];
        let on = at(c.x, c.y, s1.height_m);
        assert_eq!(off_step_check(Foot::Right, overhang_m(&scene, &on, half), &p()), None);
        // 5 cm over the nose (the tread's front edge), along the ascent.
        let nose = (s1.corners[0].coords + s1.corners[3].coords) / 2.0;
        let along = (c - nose).normalize();
        let over = nose + along * (0.12 - 0.05);
        let c = off_step_check(Foot::Right, overhang_m(&scene, &at(over.x, over.y, s1.height_m), half), &p());
        assert!(
            matches!(c, Some(Check::OffStep { overhang_m, .. }) if (overhang_m - 0.05).abs() < 1e-6),
            "{c:?}"
        );
        assert_eq!(overhang_m(&scene, &at(0.0, 0.0, 0.0), half), None, "the floor is no step");
    }

    #[test]
    fn slip_fires_on_a_horizontal_slide_only() {
        let from = Vector3::new(1.0, 0.0, 0.2);
        assert_eq!(slip_check(Foot::Left, &Vector3::new(1.003, 0.0, 0.25), &from, &p()), None);
        let c = slip_check(Foot::Left, &Vector3::new(1.0, 0.008, 0.2), &from, &p()).expect("slide fires");
        assert!(
            matches!(c, Check::Slip { foot: Foot::Left, slip_m, limit_m } if (slip_m - 0.008).abs() < 1e-12 && limit_m == 0.005)
        );
    }

    #[test]
    fn strike_fires_mid_swing_but_not_at_landing_or_lift_off() {
        let path = vec![at(0.0, -0.1, 0.0), at(0.2, -0.1, 0.3), at(0.27, -0.1, 0.2)];
        let sw = Swing { foot: Foot::Right, path, shares: vec![0.5, 0.5], natural_s: 2.0 };
        let hit = Point3::new(0.2, -0.1, 0.2);
        let riser = Vector3::new(-1.0, 0.0, 0.0);
        let c =
            strike_check(&sw, &at(0.2, -0.1, 0.25), &hit, &riser, "step_1", &p()).expect("mid-swing fires");
        assert!(
            matches!(&c, Check::Strike { foot: Foot::Right, geom, above_target_m, .. } if geom == "step_1" && (above_target_m - 0.05).abs() < 1e-12)
        );
        let nose = Vector3::new(-0.7, 0.0, 0.7).normalize();
        assert!(
            strike_check(&sw, &at(0.2, -0.1, 0.25), &hit, &nose, "step_1", &p()).is_some(),
            "on the nose"
        );
        assert_eq!(strike_check(&sw, &at(0.27, -0.1, 0.205), &hit, &riser, "step_1", &p()), None, "landing");
        assert_eq!(strike_check(&sw, &at(0.0, -0.1, 0.005), &hit, &riser, "floor", &p()), None, "lift-off");
        let level = Vector3::new(0.05, 0.0, -1.0).normalize();
        assert_eq!(
            strike_check(&sw, &at(0.27, -0.1, 0.22), &hit, &level, "step_1", &p()),
            None,
            "early on the tread"
        );

        // Rising to a higher tread, the toe meets the riser under its nose while the planned
        // sole is still below the target's height.
        let rising = vec![at(0.0, -0.1, 0.0), at(0.0, -0.1, 0.25), at(0.27, -0.1, 0.25), at(0.27, -0.1, 0.2)];
        let up = Swing { foot: Foot::Left, path: rising, shares: vec![0.4, 0.3, 0.3], natural_s: 2.0 };
        let toe = Point3::new(0.13, -0.1, 0.06);
        let c = strike_check(&up, &at(0.0, -0.1, 0.05), &toe, &riser, "step_2", &p())
            .expect("a rising lift fires");
        assert!(matches!(&c, Check::Strike { above_target_m, from_ends_m, .. }
            if (above_target_m + 0.15).abs() < 1e-12 && (from_ends_m - 0.05).abs() < 1e-12));
        assert!(c.to_string().contains("150.0 mm below its target"), "{c}");
        assert_eq!(
            strike_check(&up, &at(0.0, -0.1, 0.008), &toe, &riser, "step_2", &p()),
            None,
            "its lift-off"
        );
    }

    #[test]
    fn fall_fires_on_a_low_base_or_a_tilt_the_plan_did_not_ask_for() {
        let up = [0.0, 0.0, 0.75, 1.0, 0.0, 0.0, 0.0];
        assert_eq!(fall_check(&up, &up, 0.5, &p()), None);
        let c = fall_check(&[0.0, 0.0, 0.3, 1.0, 0.0, 0.0, 0.0], &up, 0.5, &p()).expect("low fires");
        assert!(
            matches!(c, Check::Fall { base_z_m, min_base_z_m, .. } if base_z_m == 0.3 && min_base_z_m == 0.5)
        );
        let q = UnitQuaternion::from_euler_angles(0.0, 40f64.to_radians(), 0.0);
        let tilted = [0.0, 0.0, 0.75, q.w, q.i, q.j, q.k];
        let c = fall_check(&tilted, &up, 0.5, &p()).expect("tilt fires");
        assert!(matches!(c, Check::Fall { tilt_rad, .. } if (tilt_rad - 40f64.to_radians()).abs() < 1e-9));
        assert_eq!(fall_check(&tilted, &tilted, 0.5, &p()), None, "a lean the plan asked for");
    }

    /// A box of the robot's geom group resting on the floor: with its body taken for a foot
    /// it is a sole's contact, else a collision.
    const TWO_BOXES: &str = r#"<mujoco>
      <worldbody>
        <geom name="floor" type="plane" size="2 2 0.1"/>
        <body name="foot" pos="0 0 0.05"><freejoint/><geom name="sole" type="box" size="0.1 0.05 0.05" group="2"/></body>
        <body name="knee" pos="0.5 0 0.05"><freejoint/><geom name="knee_cap" type="box" size="0.05 0.05 0.05" group="2"/></body>
      </worldbody>
    </mujoco>"#;

    #[test]
    fn collision_is_any_robot_contact_but_a_foot_on_the_world() {
        let mut world = World::from_xml(TWO_BOXES.into()).expect("compiles");
        for _ in 0..20 {
            world.data_mut().step();
        }
        let foot = world.body_id("foot").expect("body");
        let kinds: Vec<ContactKind> = world
            .data()
            .contact()
            .iter()
            .map(|c| classify_contact(&world, c.geom1 as usize, c.geom2 as usize, [foot, usize::MAX]))
            .collect();
        assert!(kinds.contains(&ContactKind::Foot(0)), "{kinds:?}");
        let collision = kinds.iter().find_map(|k| match k {
            ContactKind::Collision { robot, other } => {
                Some((world.geom_name(*robot), world.geom_name(*other)))
            }
            _ => None,
        });
        assert_eq!(collision, Some(("knee_cap", "floor")));
    }

    #[test]
    fn a_diverging_simulation_is_reported_once_per_new_warning() {
        let mut world = World::from_xml(TWO_BOXES.into()).expect("compiles");
        let mut seen = [0; 7];
        world.data_mut().step();
        assert!(warning_checks(&world, &mut seen).is_empty(), "a sound step warns nothing");
        world.data_mut().qvel_mut()[0] = 1e12;
        world.data_mut().step();
        let checks = warning_checks(&world, &mut seen);
        assert!(
            checks
                .iter()
                .any(|c| matches!(c, Check::Unstable { warning: SimWarning::BadQvel, count: 1, .. })),
            "{checks:?}"
        );
        assert!(warning_checks(&world, &mut seen).is_empty(), "an old warning is not reported again");
    }
}
