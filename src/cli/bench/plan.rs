//! `bench plan`: the planner (§6) on the Exp. 1 and Exp. 2 ground truth: one IK tick against
//! its sample period, and the whole plan against the duration of the motion it makes; and
//! the surroundings the plan is kept off, made from the Exp. 1 sweep.

use super::{machine, median_s};
use anyhow::{Context, Result};
use nalgebra::{Point3, Vector3};
use stairbench::planning::clearance::SeenPoints;
use stairbench::planning::ik::{self, Solver};
use stairbench::planning::motion::{self, IkParams};
use stairbench::planning::{rectangles, Plan, PlanParams, PlanRequest};
use stairbench::robot::model::Q_JOINTS;
use stairbench::robot::{hrp4, Kinematics};
use stairbench::scene::Scene;
use std::time::Instant;

/// Plans scenario `name`'s ground truth; with `walls`, among a 0.9 m stairwell's walls
/// (3 cm grids of points 0.45 m either side of the robot's start, along the flight, as the
/// surroundings hold a wall the lidar saw); with `active_set` off, clarabel solves every QP
/// of the IK. Returns the plan and its wall time.
fn once(name: &str, walls: bool, active_set: bool) -> Result<(Plan, f64)> {
    let scenario = crate::cli::load_scenario(Some(std::path::Path::new(name)))?;
    let scene = Scene::from_scenario(&scenario)?;
    let model = hrp4::model()?;
    let start = scene.robot_start();
    let q0 = hrp4::half_sitting_at(&model, &start)?;
    let rects = rectangles::from_step_tops(scene.steps());
    let seen: Vec<Point3<f64>> = if walls {
        let (along, across) = (start.rotation * Vector3::x(), start.rotation * Vector3::y());
        let o = Point3::from(start.translation.vector);
        [-0.45, 0.45]
            .into_iter()
            .flat_map(|side| {
                (0..120).flat_map(move |i| {
                    (0..100).map(move |k| {
                        o + along * (-0.5 + 0.03 * i as f64)
                            + across * side
                            + Vector3::z() * (0.03 * k as f64)
                    })
                })
            })
            .collect()
    } else {
        Vec::new()
    };
    let seen = std::sync::Arc::new(SeenPoints::new(seen));
    let mut params = PlanParams::default();
    params.ik.active_set = active_set;
    let t = Instant::now();
    let p = PlanRequest::new(&model, &q0, &rects, &params)
        .among(seen)
        .climb()
        .with_context(|| format!("{name}: plan refused"))?;
    Ok((p, t.elapsed().as_secs_f64()))
}

/// QPs per timing run of the solver comparison.
const QPS: usize = 2000;

/// One double-support IK QP of half-sitting (CoM task moving, posture, base, both contacts,
/// joint bounds) solved `QPS` times: clarabel built for each QP (the baseline) against the
/// [`Solver`] that keeps it and updates the data; and by active sets (the binding limits
/// carried from the last solve), each guess's KKT system whole by one LU (the baseline)
/// against the Schur complement on the objective's Cholesky factor (the default).
fn qp_reuse(repeat: usize) -> Result<QpTimes> {
    let model = hrp4::model()?;
    let q = hrp4::half_sitting_at(&model, &nalgebra::Isometry3::identity())?;
    let p = IkParams::default();
    let mut kin = Kinematics::new(&model);
    kin.update(&q)?;
    let soles = hrp4::sole_frames(&model)?;
    let (mut cj, mut fj) = (kin.new_com_jacobian(), kin.new_frame_jacobian());
    let target = kin.com() + Vector3::new(0.0, 0.01, 0.0);
    let mask = vec![true; model.joints().len()];
    let tasks = [
        ik::com_task(
            &kin,
            &mut cj,
            &Point3::from(target.coords),
            &Vector3::zeros(),
            p.task_gain_per_s,
            p.weight_com,
        ),
        ik::posture_task(&model, &q, &q[Q_JOINTS..], &mask, p.posture_gain_per_s, p.weight_posture),
    ];
    let eqs: Vec<ik::Equality> = soles
        .iter()
        .map(|&f| {
            ik::contact(
                &kin,
                &mut fj,
                f,
                &kin.frame_pose(f),
                p.contact_gain_per_s,
                [p.max_contact_correction_m_s, p.max_contact_correction_rad_s],
            )
        })
        .collect();
    let lower = motion::ik_lower_limits(&model, [true; 2], &p)?;
    let bounds = [ik::joint_limits(&model, &q, &lower, p.max_joint_speed_rad_s, p.limit_gain_per_s)];
    let fresh = ik::solve(model.nv(), &tasks, &eqs, &[], &bounds, p.damping)?;
    let mut solver = Solver::new(model.nv(), p.damping);
    let reused = solver.solve(&tasks, &eqs, &[], &bounds)?;
    let again = solver.solve(&tasks, &eqs, &[], &bounds)?;
    let diff = (&fresh - &reused).amax().max((&fresh - &again).amax());
    let fresh_s = median_s(repeat, || {
        for _ in 0..QPS {
            let _ = std::hint::black_box(ik::solve(model.nv(), &tasks, &eqs, &[], &bounds, p.damping));
        }
    }) / QPS as f64;
    let reused_s = median_s(repeat, || {
        for _ in 0..QPS {
            let _ = std::hint::black_box(solver.solve(&tasks, &eqs, &[], &bounds));
        }
    }) / QPS as f64;
    let mut by_lu = Solver::new(model.nv(), p.damping).with_active_set(true).with_full_kkt(true);
    let mut by_schur = Solver::new(model.nv(), p.damping).with_active_set(true);
    let [lu_s, schur_s] = [&mut by_lu, &mut by_schur].map(|solver| {
        median_s(repeat, || {
            for _ in 0..QPS {
                let _ = std::hint::black_box(solver.solve(&tasks, &eqs, &[], &bounds));
            }
        }) / QPS as f64
    });
    // After the timed solves, from the limits they carried over (the first, from none, may
    // have gone to clarabel).
    let (lu, schur) = (by_lu.solve(&tasks, &eqs, &[], &bounds)?, by_schur.solve(&tasks, &eqs, &[], &bounds)?);
    let active_diff_rad_s = (&lu - &schur).amax();
    let by_clarabel = by_lu.interior_point_qps().max(by_schur.interior_point_qps());
    Ok(QpTimes { fresh_s, reused_s, diff, lu_s, schur_s, active_diff_rad_s, by_clarabel })
}

/// Seconds per QP of [`qp_reuse`]'s solvers, and the largest differences of their solutions.
struct QpTimes {
    /// clarabel built for each QP.
    fresh_s: f64,
    /// clarabel kept and updated.
    reused_s: f64,
    /// Between those two, rad/s.
    diff: f64,
    /// Active sets, the KKT system by one LU.
    lu_s: f64,
    /// Active sets, by the Schur complement.
    schur_s: f64,
    /// Between those two, rad/s.
    active_diff_rad_s: f64,
    /// QPs either active-set solver left to clarabel (of the `QPS` times `repeat` and more
    /// it solved).
    by_clarabel: usize,
}

/// The Exp. 1 sweep (simulated, from the robot's start) taken into the surroundings and made
/// the plan's `SeenPoints`, as the loop takes a view: the returns' voxels alone (the
/// baseline, `unseen_kept_off = false`) against them with the crossed space and its unseen
/// edge (the default), median seconds each, and the edge's points; and the rays' walk alone,
/// each thread into chunks of its own (the baseline) against one dense block.
fn surroundings(repeat: usize) -> Result<(f64, f64, usize, usize, WalkTimes)> {
    use stairbench::perception::free_space::FreeSpace;
    use stairbench::perception::ray_walk::Walker;
    use stairbench::perception::surroundings::{Surroundings, SurroundingsParams};
    let scenario = crate::cli::load_scenario(Some(std::path::Path::new("exp1")))?;
    let scene = Scene::from_scenario(&scenario)?;
    let model = hrp4::model()?;
    let q0 = hrp4::half_sitting_at(&model, &scene.robot_start())?;
    let scan = stairbench::sim::scan_scenario(&scenario, &mut |_, _| {})?;
    let cloud = scan.sweep.assemble(&stairbench::sensor::AssembleParams::default())?;
    let mut unseen = 0;
    let mut time = |p: &SurroundingsParams| {
        median_s(repeat, || {
            let mut around = Surroundings::default();
            stairbench::climb::add_view(&mut around, &cloud, &model, &q0, p);
            let seen = SeenPoints::with_unseen(around.points(p), around.unseen(p));
            unseen = seen.unseen().len();
        })
    };
    let baseline_s = time(&SurroundingsParams { unseen_kept_off: false, ..Default::default() });
    let with_s = time(&SurroundingsParams::default());
    let fs = SurroundingsParams::default().free_space();
    let mut voxels = [0; 2];
    let [chunks_s, block_s] = [Walker::Chunks, Walker::Block].map(|walker| {
        median_s(repeat, || {
            let mut space = FreeSpace::default();
            space.add_walked(&cloud, &[], &fs, walker);
            voxels[(walker == Walker::Block) as usize] = space.crossed_voxels();
        })
    });
    let walk = WalkTimes { chunks_s, block_s, voxels };
    Ok((baseline_s, with_s, unseen, cloud.len(), walk))
}

/// Seconds of the rays' walk into the crossed space, and the voxels crossed, by each walker.
struct WalkTimes {
    /// Each thread into chunks of its own, merged after (the baseline).
    chunks_s: f64,
    /// One dense block spanning the rays (the default).
    block_s: f64,
    /// Voxels crossed, by the chunks and by the block.
    voxels: [usize; 2],
}

/// Returns the Markdown table.
pub fn run(repeat: usize) -> Result<String> {
    let rate = IkParams::default().rate_hz;
    let period_ms = 1e3 / rate;
    let mut t = format!(
        "Planner on the scenarios' ground-truth steps, default parameters (IK at {rate} Hz), median of {repeat} runs; machine: {}.\n\n",
        machine()
    );
    t += &format!("| scenario | stances | segments | motion | plan wall time | motion / wall | IK ticks | one IK tick | tick / {period_ms} ms period | gait + polygons |\n|---|---|---|---|---|---|---|---|---|---|\n");
    let mut ticks_s = Vec::new();
    let mut against = String::new();
    for (name, walls) in [("exp1", false), ("exp1", true), ("exp2", false)] {
        let median = |active_set: bool| -> Result<(Plan, f64)> {
            let mut runs: Vec<(Plan, f64)> =
                (0..repeat).map(|_| once(name, walls, active_set)).collect::<Result<_>>()?;
            runs.sort_by(|a, b| a.1.total_cmp(&b.1));
            Ok(runs.swap_remove(runs.len() / 2))
        };
        let (p, wall) = &median(true)?;
        let (_, clarabel_wall) = median(false)?;
        against += &format!(
            "| {name}{} | {:.2} s | {wall:.2} s | {:.2} | {} of {} |\n",
            if walls { " in the stairwell" } else { "" },
            clarabel_wall,
            clarabel_wall / wall,
            p.tracking.ik_interior_point_qps,
            p.tracking.ik_ticks
        );
        let tick = p.tracking.ik_time_s / p.tracking.ik_ticks.max(1) as f64;
        ticks_s.push(tick);
        let label = if walls { format!("{name} in a 0.9 m stairwell") } else { name.to_string() };
        t += &format!(
            "| {label} | {} | {} | {:.1} s | {:.2} s | {:.1} | {} | {:.3} ms | {:.3} | {:.1} ms |\n",
            p.stances.len(),
            p.segments.len(),
            p.duration_s(),
            wall,
            p.duration_s() / wall,
            p.tracking.ik_ticks,
            tick * 1e3,
            tick * rate,
            p.gait_time_s * 1e3
        );
    }
    t += &format!(
        "\nIn the stairwell (24,000 wall points, the rest of the body kept 3 cm off them: a clearance row for each arm, trunk or head shape within 8 cm of a wall point), an IK tick costs {:.2} x the open flight's.\n",
        ticks_s[1] / ticks_s[0]
    );
    t += "\nThe IK's QPs by active sets from the last tick's binding limits (`plan.ik.active_set`, the default) against clarabel for every QP, the same plans in the same process:\n\n| scenario | plan wall, clarabel for every QP | plan wall, active sets | ratio | QPs clarabel still solved |\n|---|---|---|---|---|\n";
    t += &against;
    let q = qp_reuse(repeat)?;
    t += &format!(
        "\nThe QP alone (double support in half-sitting, {QPS} solves, same process): clarabel built for every QP (baseline) {:.3} ms, built once and updated (`ik::Solver`) {:.3} ms, ratio {:.2}; solutions differ by at most {:.1e} rad/s. By active sets (the default, the binding limits carried over): each guess's KKT system whole by one LU (baseline) {:.4} ms, by the Schur complement on the objective's Cholesky factor (the default) {:.4} ms, ratio {:.2}; solutions differ by at most {:.1e} rad/s; clarabel solved {} of either's QPs.\n",
        q.fresh_s * 1e3,
        q.reused_s * 1e3,
        q.fresh_s / q.reused_s,
        q.diff,
        q.lu_s * 1e3,
        q.schur_s * 1e3,
        q.lu_s / q.schur_s,
        q.active_diff_rad_s,
        q.by_clarabel
    );
    let (baseline_s, with_s, unseen, returns, walk) = surroundings(repeat)?;
    t += &format!(
        "\nThe Exp. 1 sweep ({returns} returns, from the robot's start) into the surroundings and the plan's seen points, same process: the returns' voxels alone (baseline, `[surroundings] unseen_kept_off = false`) {:.1} ms, with the space the rays crossed (every second beam and row, 5 cm voxels, out to 2.5 m) and its unseen edge near the body (the default) {:.1} ms, ratio {:.2}; {unseen} unseen-edge points.\n",
        baseline_s * 1e3,
        with_s * 1e3,
        with_s / baseline_s
    );
    t += &format!(
        "\nThe rays' walk alone (the same sweep, same process): each thread into chunks of its own, merged after (baseline) {:.1} ms, into one dense block spanning the rays (the default) {:.1} ms, ratio {:.2}; {} and {} voxels crossed.\n",
        walk.chunks_s * 1e3,
        walk.block_s * 1e3,
        walk.chunks_s / walk.block_s,
        walk.voxels[0],
        walk.voxels[1]
    );
    t += "\nOne IK tick = the kinematics update, the task Jacobians, building the QP (40 velocities, contact equalities, one leg-clearance row per thigh and shank, 68 joint bounds) and its solve. The plan's wall time is nearly all IK ticks.\n";
    Ok(t)
}
