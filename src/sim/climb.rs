//! The closed loop (the bench's main job): stand, scan with the head lidar, perceive, plan the
//! next stance, execute it in MuJoCo with every check, scan again from the new pose, until
//! the top. The upper steps are reconstructed after stepping on the lower ones, as in the paper.

use super::execute::{execute, CheckParams, Execution, ServoParams};
use super::observe::{Nobody, Observer};
use super::world::{SimError, World};
use crate::perception::{perceive, PerceptionError, PerceptionParams, PlaneSegment};
use crate::planning::plan::stance_at;
use crate::planning::{plan, PlanParams};
use crate::robot::hrp4;
use crate::robot::model::RobotModel;
use crate::scenario::Scenario;
use crate::scene::Scene;
use crate::sensor::sim::SimLidar;
use crate::sensor::{AssembleParams, SensorError};
use std::time::Instant;

/// Every parameter of a climb.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ClimbParams {
    /// Perception (§4, Table 1).
    pub perception: PerceptionParams,
    /// Planning (§6).
    pub plan: PlanParams,
    /// The servos.
    pub servo: ServoParams,
    /// The checks.
    pub checks: CheckParams,
    /// Loop settings.
    pub run: RunParams,
}

/// Settings of the loop itself.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RunParams {
    /// Stances planned and executed between two scans.
    pub stances_per_scan: usize,
    /// Most scan-plan-execute cycles before giving up.
    pub max_cycles: usize,
    /// Standing still before each scan, seconds (the servos settle; the real robot scans
    /// standing still too).
    pub settle_s: f64,
    /// Steps lower than the feet plus this are behind the robot, metres.
    pub ahead_margin_m: f64,
    /// A new scan's rectangle replaces a known one whose centre is within this distance
    /// (and height within a third of it); known steps the new scan misses (too close under
    /// the lidar, say) are kept.
    pub same_step_m: f64,
}

impl Default for RunParams {
    fn default() -> Self {
        Self { stances_per_scan: 1, max_cycles: 40, settle_s: 0.3, ahead_margin_m: 0.05, same_step_m: 0.15 }
    }
}

/// Why a climb could not run at all (bad world or sensor), as opposed to a failed climb.
#[derive(Debug, thiserror::Error)]
pub enum ClimbError {
    /// The world.
    #[error(transparent)]
    Sim(#[from] SimError),
    /// The lidar.
    #[error(transparent)]
    Sensor(#[from] SensorError),
    /// The scenario.
    #[error(transparent)]
    Scenario(#[from] crate::scenario::ScenarioError),
    /// The robot model.
    #[error(transparent)]
    Robot(#[from] crate::robot::RobotError),
}

/// One scan-plan-execute cycle.
#[derive(Debug, Clone, serde::Serialize)]
pub struct CycleReport {
    /// 1-based cycle.
    pub cycle: usize,
    /// Where the cycle took the feet: `floor` or `step N`.
    pub to: String,
    /// No check violated (`execution.pass()`, kept for the JSON report's readers).
    pub pass: bool,
    /// Steps perception found ahead.
    pub steps_seen: usize,
    /// Wall time of the simulated lidar sweep (ray casting), seconds.
    pub scan_s: f64,
    /// Perception wall time, seconds.
    pub perceive_s: f64,
    /// Planning wall time, seconds.
    pub plan_s: f64,
    /// Wall time of the execution in MuJoCo with its checks, seconds.
    pub execute_s: f64,
    /// What the execution found (flattened into the JSON: `min_margin_m`,
    /// `max_torque_ratio`, `torque_joint`, `touchdowns`, `violations`, `sim_s`, ...).
    #[serde(flatten)]
    pub execution: Execution,
}

/// The whole climb.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ClimbReport {
    /// Scenario name.
    pub scenario: String,
    /// Climbed to the top with no check violated.
    pub success: bool,
    /// Steps whose tread both feet stood on at the end (the highest reached).
    pub steps_climbed: usize,
    /// Steps of the staircase.
    pub steps_total: usize,
    /// Why the loop stopped early (a refusal, no staircase, a fall), if it did.
    pub stopped: Option<String>,
    /// One entry per cycle.
    pub cycles: Vec<CycleReport>,
    /// Simulated time, seconds.
    pub sim_s: f64,
    /// Wall time, seconds.
    pub wall_s: f64,
}

impl ClimbReport {
    /// How many times faster than real time the execution ran (MuJoCo with the servos and
    /// every check, without scanning, perception or planning).
    pub fn execution_speed(&self) -> f64 {
        let sim_s: f64 = self.cycles.iter().map(|c| c.execution.sim_s).sum();
        let wall_s: f64 = self.cycles.iter().map(|c| c.execute_s).sum();
        sim_s / wall_s.max(1e-9)
    }

    /// The longest a cycle waited for perception and planning, seconds.
    pub fn worst_think_s(&self) -> f64 {
        self.cycles.iter().map(|c| c.perceive_s + c.plan_s).fold(0.0, f64::max)
    }

    /// The mean over the cycles of `f`, 0 without cycles.
    pub fn mean_per_cycle(&self, f: impl Fn(&CycleReport) -> f64) -> f64 {
        self.cycles.iter().map(f).sum::<f64>() / self.cycles.len().max(1) as f64
    }
}

/// Holds the robot at its commanded posture for `seconds`.
fn settle(world: &mut World, seconds: f64) {
    let n = (seconds / world.model().opt().timestep).round() as usize;
    for _ in 0..n {
        world.data_mut().step();
    }
}

/// The measured configuration, in the kinematics' layout.
fn measured_q(world: &World, model: &RobotModel) -> Vec<f64> {
    world.data().qpos()[..model.nq()].to_vec()
}

/// Scans from the robot's current pose and perceives.
fn look(
    world: &World,
    scenario: &Scenario,
    cycle: usize,
    p: &PerceptionParams,
    observer: &mut dyn Observer,
) -> Result<Look, ClimbError> {
    let t = Instant::now();
    let stamp_s = world.data().time();
    let lidar = SimLidar::new(world, &scenario.lidar, scenario.seed.wrapping_add(cycle as u64))?;
    let sweep = lidar.sweep_with_progress(&mut |_, _| {});
    let cloud = sweep.assemble(&AssembleParams::default())?;
    let scan_s = t.elapsed().as_secs_f64();
    observer.sweep(stamp_s, &sweep);
    observer.cloud(stamp_s, &cloud);
    let t = Instant::now();
    let result = perceive(&cloud, p);
    let perceive_s = t.elapsed().as_secs_f64();
    match &result {
        Ok(r) => observer.perception(stamp_s, r),
        Err(e) => observer.perception_failed(stamp_s, &e.to_string()),
    }
    Ok(Look { seen: result.map(|r| r.segments), scan_s, perceive_s })
}

/// What one look found, and its wall times.
struct Look {
    seen: Result<Vec<PlaneSegment>, PerceptionError>,
    scan_s: f64,
    perceive_s: f64,
}

/// Runs the closed loop on `scenario`; `on_cycle` sees each cycle as it ends.
pub fn climb(
    scenario: &Scenario,
    p: &ClimbParams,
    on_cycle: &mut dyn FnMut(&CycleReport),
) -> Result<ClimbReport, ClimbError> {
    climb_observed(scenario, p, on_cycle, &mut Nobody)
}

/// [`climb`], with `observer` seeing every stage's data (to record or show it).
pub fn climb_observed(
    scenario: &Scenario,
    p: &ClimbParams,
    on_cycle: &mut dyn FnMut(&CycleReport),
    observer: &mut dyn Observer,
) -> Result<ClimbReport, ClimbError> {
    let started = Instant::now();
    let scene = Scene::from_scenario(scenario)?;
    let model = hrp4::model()?;
    let mut world = World::for_scene(&scene)?;
    let t0 = world.data().time();
    let mut report = ClimbReport {
        scenario: scenario.name.clone(),
        success: false,
        steps_climbed: 0,
        steps_total: scene.steps().len(),
        stopped: None,
        cycles: Vec::new(),
        sim_s: 0.0,
        wall_s: 0.0,
    };
    observer.scene(&scene);
    let mut stairs = Staircase::default();
    for cycle in 1..=p.run.max_cycles {
        settle(&mut world, p.run.settle_s);
        let q = measured_q(&world, &model);
        let Look { seen, scan_s, perceive_s } = look(&world, scenario, cycle, &p.perception, observer)?;
        let feet_z = feet_height_m(&model, &q);
        let seen = match seen {
            Ok(segs) => segs,
            Err(PerceptionError::NoStaircase(_)) => Vec::new(),
            Err(e) => {
                report.stopped = Some(format!("perception failed: {e}"));
                break;
            }
        };
        stairs.update(seen, p.run.same_step_m);
        let ahead = without_partial_top(stairs.ahead(feet_z, p.run.ahead_margin_m), p.plan.gait.min_tread_m);
        if ahead.is_empty() {
            if climbed(&scene, &model, &q) < scene.steps().len() {
                report.stopped = Some("no staircase found ahead before the top".into());
            }
            break;
        }
        let t = Instant::now();
        let planned = match plan(&model, &q, &ahead, Some(p.run.stances_per_scan), &p.plan) {
            Ok(x) => x,
            Err(e) => {
                report.stopped = Some(format!("plan refused: {e}"));
                break;
            }
        };
        let plan_s = t.elapsed().as_secs_f64();
        let t = Instant::now();
        observer.plan(world.data().time(), &ahead, &planned);
        let execution = execute(&mut world, &model, &scene, &planned, &p.servo, &p.checks, observer)?;
        let execute_s = t.elapsed().as_secs_f64();
        let to = match planned.stances.last() {
            Some(s) if s.step.is_some() => format!("step {}", true_step(&scene, s.right.translation.z)),
            _ => "floor".to_string(),
        };
        let c = CycleReport {
            cycle,
            to,
            pass: execution.pass(),
            steps_seen: ahead.len(),
            scan_s,
            perceive_s,
            plan_s,
            execute_s,
            execution,
        };
        on_cycle(&c);
        observer.cycle(world.data().time(), &c);
        let fell = c.execution.fell;
        report.cycles.push(c);
        if fell {
            report.stopped = Some("the robot fell".into());
            break;
        }
        if super::stop::requested() {
            report.stopped = Some("stopped by the user".into());
            break;
        }
    }
    let q = measured_q(&world, &model);
    report.steps_climbed = climbed(&scene, &model, &q);
    report.sim_s = world.data().time() - t0;
    report.wall_s = started.elapsed().as_secs_f64();
    report.success = report.stopped.is_none()
        && report.steps_climbed == report.steps_total
        && report.cycles.iter().all(|c| c.pass);
    Ok(report)
}

/// The steps known so far, updated by each scan ([`merge`]); what the planner gets is the
/// part above the feet ([`Staircase::ahead`]). `replay` reruns the same updates.
#[derive(Debug, Clone, Default)]
pub struct Staircase {
    /// Every step seen so far.
    pub known: Vec<PlaneSegment>,
}

impl Staircase {
    /// Merges a scan's rectangles (see [`merge`]).
    pub fn update(&mut self, seen: Vec<PlaneSegment>, same_m: f64) {
        self.known = merge(&self.known, seen, same_m);
    }

    /// The steps higher than `feet_z` plus `margin_m` (the ones still to climb).
    pub fn ahead(&self, feet_z: f64, margin_m: f64) -> Vec<PlaneSegment> {
        self.known.iter().filter(|s| s.height_m() > feet_z + margin_m).cloned().collect()
    }
}

/// `ahead` without its highest step when that one is shallower than a foot needs and lower
/// steps remain: at the far edge of what the lidar sees, a tread is often seen only in part
/// (Exp. 2, seed 3: 11 cm of a 26.5 cm tread, from step 2), and planning the next stance must
/// not be refused for a step a later scan, from closer, sees whole. A staircase whose next
/// step is too shallow is still refused.
pub fn without_partial_top(mut ahead: Vec<PlaneSegment>, min_tread_m: f64) -> Vec<PlaneSegment> {
    let top =
        ahead.iter().enumerate().max_by(|a, b| a.1.height_m().total_cmp(&b.1.height_m())).map(|(i, _)| i);
    if let Some(i) = top {
        if ahead.len() > 1 && ahead[i].depth_m() < min_tread_m {
            ahead.remove(i);
        }
    }
    ahead
}

/// The higher sole's height at configuration `q`, metres (`-inf` if `q` is unusable).
pub fn feet_height_m(model: &RobotModel, q: &[f64]) -> f64 {
    stance_at(model, q).map(|s| s.right.translation.z.max(s.left.translation.z)).unwrap_or(f64::NEG_INFINITY)
}

/// The staircase as known after a scan: the new rectangles, plus the known ones no new
/// rectangle matches (the paper re-estimates upper steps as the robot climbs; a step under
/// the lidar's blind spot stays as last seen). Where a new rectangle matches a known one, the
/// new one is taken with its front edge (the nose) moved forward to the known one's if that
/// was nearer ([`merge_view`]): close to a riser the head lidar no longer sees the near part
/// of the next tread, and that partial view must not move the nose back.
fn merge(known: &[PlaneSegment], seen: Vec<PlaneSegment>, same_m: f64) -> Vec<PlaneSegment> {
    let matches = |a: &PlaneSegment, b: &PlaneSegment| {
        (a.center() - b.center()).norm() < same_m && (a.height_m() - b.height_m()).abs() < same_m / 3.0
    };
    let kept: Vec<PlaneSegment> =
        known.iter().filter(|k| !seen.iter().any(|s| matches(k, s))).cloned().collect();
    let updated: Vec<PlaneSegment> = seen
        .into_iter()
        .map(|s| match known.iter().find(|k| matches(k, &s)) {
            Some(k) => merge_view(&s, k),
            None => s,
        })
        .collect();
    updated.into_iter().chain(kept).collect()
}

/// The new view `s` of the known step `k`: `s`'s rectangle with its front edge (the nose,
/// toward the robot along `s`'s ascent) moved forward to `k`'s when that was nearer, on the
/// plane (normal) of whichever view rests on more voxels; its back edge, sides and height
/// stay `s`'s.
/// - An edge's place is its midpoint's: a rectangle yawed by a degree or two (as perception
///   returns them) has a front corner up to `width/2 * sin(yaw)` ahead of its front edge,
///   and taking that corner for the edge moved the nose toward the robot at every merge (on
///   the 50 cm Exp. 1 treads, 1.2-1.6 cm over three scans: the heel came down on the nose).
/// - A partial view (the near part of the tread hidden under the lidar) fits its plane to a
///   strip 10-15 cm deep: on Exp. 1 such a view of step 2 came out tilted 2-4 degrees (full
///   views: under 1 degree), and a foot planned on that tilt came down on its toe or heel.
fn merge_view(s: &PlaneSegment, k: &PlaneSegment) -> PlaneSegment {
    let fuller = if k.voxel_count() > s.voxel_count() { k } else { s };
    let along = s.along();
    let c = s.center();
    let front = |r: &PlaneSegment| (r.center() - r.along() * (r.depth_m() / 2.0) - c).dot(&along);
    let (front_s, front_k) = (front(s), front(k));
    let (front, voxels) = if front_k < front_s {
        (front_k, s.voxel_count().max(k.voxel_count()))
    } else {
        (front_s, s.voxel_count())
    };
    let back = s.depth_m() / 2.0;
    let centre = c + along * ((front + back) / 2.0);
    PlaneSegment::new(centre, along, back - front, s.width_m(), fuller.normal().into_inner(), voxels)
        .unwrap_or_else(|| s.clone())
}

/// The true step (1-based) at height `z`: the ground-truth step nearest it.
fn true_step(scene: &Scene, z: f64) -> usize {
    scene
        .steps()
        .iter()
        .enumerate()
        .min_by(|a, b| (a.1.height_m - z).abs().total_cmp(&(b.1.height_m - z).abs()))
        .map_or(0, |(i, _)| i + 1)
}

/// How many steps the robot has climbed: the highest true step both soles stand on.
pub fn climbed(scene: &Scene, model: &RobotModel, q: &[f64]) -> usize {
    let Ok(stance) = stance_at(model, q) else { return 0 };
    let on = |i: usize| {
        let s = &scene.steps()[i];
        [&stance.right, &stance.left].iter().all(|f| {
            let c = nalgebra::Point3::from(f.translation.vector);
            (c.z - s.height_m).abs() < 0.02 && s.contains_xy(&c, 0.0)
        })
    };
    (0..scene.steps().len()).rev().find(|&i| on(i)).map_or(0, |i| i + 1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Point3, Vector3};

    fn step(x: f64, z: f64, depth_m: f64) -> PlaneSegment {
        PlaneSegment::new(Point3::new(x, 0.0, z), Vector3::x(), depth_m, 0.5, Vector3::z(), 10)
            .expect("valid rectangle")
    }

    #[test]
    fn a_partial_view_does_not_shrink_a_step_and_a_new_one_is_added() {
        let known = vec![step(0.735, 0.2, 0.27), step(1.005, 0.4, 0.27)];
        // From close to the riser: step 2's far half only, step 1 unseen, step 3 new.
        let seen = vec![step(1.08, 0.4, 0.12), step(1.275, 0.6, 0.27)];
        let merged = merge(&known, seen, 0.15);
        assert_eq!(merged.len(), 3);
        let at = |z: f64| merged.iter().find(|r| (r.height_m() - z).abs() < 1e-9).expect("step at z");
        assert_eq!(at(0.2).depth_m(), 0.27, "step 1, unseen, is kept");
        assert!((at(0.4).depth_m() - 0.27).abs() < 1e-9, "step 2 keeps its whole tread");
        assert!((at(0.4).center().x - 1.005).abs() < 1e-9);
        assert!((at(0.6).depth_m() - 0.27).abs() < 1e-9, "step 3 is added");
        // A re-estimate takes the new height, its own back edge, and the nearer nose.
        let merged = merge(&known, vec![step(1.01, 0.41, 0.26)], 0.15);
        let s2 = merged.iter().find(|r| (r.height_m() - 0.41).abs() < 1e-9).expect("re-estimated");
        assert!(!merged.iter().any(|r| (r.height_m() - 0.4).abs() < 1e-9));
        let (front, back) = (s2.center().x - s2.depth_m() / 2.0, s2.center().x + s2.depth_m() / 2.0);
        assert!((front - 0.87).abs() < 1e-9 && (back - 1.14).abs() < 1e-9, "{front} {back}");
    }

    #[test]
    fn a_partial_view_does_not_tilt_a_step() {
        let full = step(1.005, 0.4, 0.27);
        let tilt = Vector3::new((3f64).to_radians().sin(), 0.0, (3f64).to_radians().cos());
        let partial = PlaneSegment::new(Point3::new(1.075, 0.0, 0.4), Vector3::x(), 0.13, 0.5, tilt, 5)
            .expect("valid rectangle");
        let merged = merge(std::slice::from_ref(&full), vec![partial.clone()], 0.15);
        assert_eq!(merged.len(), 1);
        assert_eq!(merged[0].normal(), full.normal(), "the fuller view's plane is kept");
        assert!((merged[0].depth_m() - 0.27).abs() < 1e-9);
        // A view on more voxels than the known one brings its own plane.
        let merged = merge(&[partial], vec![full.clone()], 0.15);
        assert_eq!(merged[0].normal(), full.normal());
        let fuller_tilted =
            PlaneSegment::new(Point3::new(1.005, 0.0, 0.4), Vector3::x(), 0.27, 0.5, tilt, 20)
                .expect("valid rectangle");
        let merged = merge(&[full], vec![fuller_tilted.clone()], 0.15);
        assert_eq!(merged[0].normal(), fuller_tilted.normal());
    }

    #[test]
    fn a_shallow_top_step_waits_for_a_closer_look_but_a_shallow_next_step_is_kept() {
        let ahead = vec![step(1.005, 0.4, 0.27), step(1.3, 0.6, 0.11), step(0.735, 0.2, 0.27)];
        let kept = without_partial_top(ahead, 0.22);
        assert_eq!(kept.len(), 2);
        assert!(kept.iter().all(|s| s.height_m() < 0.5), "the 11 cm top is left for later");
        let alone = without_partial_top(vec![step(1.3, 0.6, 0.11)], 0.22);
        assert_eq!(alone.len(), 1, "the only step left is planned (and refused) as it is");
        let shallow_below = vec![step(0.735, 0.2, 0.11), step(1.005, 0.4, 0.27)];
        assert_eq!(without_partial_top(shallow_below, 0.22).len(), 2, "only the top may be dropped");
    }

    /// Perception returns each view of a step yawed a little differently; the front corner
    /// of a view yawed against the known rectangle lies ahead of its front edge, and merging
    /// must not take that corner for the edge, scan after scan.
    #[test]
    fn merging_views_of_differing_yaw_keeps_the_nose() {
        // Centred `s` along x from (1, 0, 0.4), its ascent yawed by `yaw_deg`.
        let view = |s: f64, depth_m: f64, yaw_deg: f64| {
            let along = Vector3::new(yaw_deg.to_radians().cos(), yaw_deg.to_radians().sin(), 0.0);
            PlaneSegment::new(Point3::new(1.0 + s, 0.0, 0.4), along, depth_m, 0.5, Vector3::z(), 10)
                .expect("valid rectangle")
        };
        let mut stairs = Staircase::default();
        for i in 0..6 {
            stairs.update(vec![view(0.0, 0.27, if i % 2 == 0 { 1.5 } else { -1.5 })], 0.15);
        }
        assert_eq!(stairs.known.len(), 1);
        let s = &stairs.known[0];
        assert!((s.depth_m() - 0.27).abs() < 1e-9, "depth {} after six views of one step", s.depth_m());
        assert!((s.center() - Point3::new(1.0, 0.0, 0.4)).norm() < 1e-9);
        // A view whose front edge is 1 cm nearer (same back edge) does move the nose by 1 cm.
        stairs.update(vec![view(-0.005, 0.28, 0.0)], 0.15);
        stairs.update(vec![view(0.0, 0.27, 0.0)], 0.15);
        assert!((stairs.known[0].depth_m() - 0.28).abs() < 1e-9, "{}", stairs.known[0].depth_m());
    }
}
