//! `stairbench plan`: footholds, the five-segment gait with its stability polygons, and the
//! whole-body trajectory, from a scenario's steps (ground truth or perceived) or from a
//! rectangles file in the paper's format.

use anyhow::{bail, Context, Result};
use clap::Args;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use stairbench::climb::add_view;
use stairbench::perception::step_map::{without_partial_top, NextInput};
use stairbench::perception::surroundings::{Surroundings, SurroundingsParams};
use stairbench::perception::{perceive, PerceptionParams, PlaneSegment};
use stairbench::planning::clearance::SeenPoints;
use stairbench::planning::motion::JointTrajectory;
use stairbench::planning::{rectangles, Plan, PlanError, PlanParams, PlanRequest};
use stairbench::record::messages::{PlanMsg, PlanReport};
use stairbench::robot::{hrp4, RobotModel};
use stairbench::scene::Scene;
use stairbench::sensor::AssembleParams;
use stairbench::sim::scan_scenario;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Instant;

/// Arguments of `stairbench plan`.
#[derive(Debug, Args)]
pub struct PlanArgs {
    /// A scenario (file or name; default: the paper's Exp. 1) or a rectangles file (.txt, the
    /// paper's format: x,y,z rows, four corners per step). Perceived steps (a rectangles
    /// file, `--perceived`) are planned as the closed loop plans a view: a step seen
    /// shallower than a foot needs above lower ones is left for a closer look, with every
    /// step above it, and the steps below it are planned.
    input: Option<PathBuf>,
    /// Plan on the perceived steps (scan the scenario's world, run §4's perception) instead
    /// of its ground truth, keeping the body off every surface the scan saw (walls, clutter)
    /// as the closed loop does; on ground truth or a rectangles file nothing is known beside
    /// the steps.
    #[arg(long)]
    perceived: bool,
    /// Rectangles file only: the floor's height in the file's frame, metres (default: the
    /// lowest step's height minus the median rise).
    #[arg(long, allow_negative_numbers = true)]
    floor_z: Option<f64>,
    /// Rectangles file only: the robot's start, from the middle of its feet to the lowest
    /// step's front edge, metres.
    #[arg(long, default_value_t = 0.20)]
    standoff_m: f64,
    /// Plan only the first N stances (default: to the top).
    #[arg(long)]
    stances: Option<usize>,
    /// Planner parameters as TOML (sections [gait], [step], [ik]; fields left out keep
    /// their defaults).
    #[arg(long)]
    params: Option<PathBuf>,
    /// Write q(t) as CSV (t_s, base x y z qw qx qy qz, then one column per joint).
    #[arg(long)]
    trajectory: Option<PathBuf>,
    /// Print one JSON object instead of tables: `ok`, `reason` and `refusal` (the refusal
    /// as data) when refused, else the plan as the MCAP `/plan` message holds it (`steps`,
    /// `stances`, `segments` with polygons and margins, `duration_s`, `tracking`, ...).
    #[arg(long)]
    json: bool,
}

/// Runs `stairbench plan`.
pub fn run(a: PlanArgs) -> Result<ExitCode> {
    let params: PlanParams = match &a.params {
        Some(p) => toml::from_str(
            &std::fs::read_to_string(p).with_context(|| format!("cannot read {}", p.display()))?,
        )
        .with_context(|| format!("{}: not planner parameters", p.display()))?,
        None => PlanParams::default(),
    };
    if let Some(p) = &a.params {
        params.step.validate().map_err(|e| anyhow::anyhow!("{}: {e}", p.display()))?;
    }
    let model = hrp4::model()?;
    let (rects, q0, seen, perceived) = inputs(&a, &model)?;
    // As the closed loop plans a view (`climb::plan_next`): a step seen in part above lower
    // ones waits for a closer look with the steps above it, and bounds the tread below it.
    // Ground truth is whole: a short tread there is refused.
    let next = if perceived {
        without_partial_top(rects.clone(), params.gait.min_tread_m)
    } else {
        NextInput { ahead: rects.clone(), deferred: None }
    };
    let below = next.ahead.len();
    let closer_look = next.deferred.as_ref().map(|d| {
        PlanError::ShortTread { step: below, depth_m: d.depth_m(), min_m: params.gait.min_tread_m }.refusal()
    });
    let steps: Vec<PlaneSegment> = next.ahead.into_iter().chain(next.deferred).collect();
    let started = Instant::now();
    let result = PlanRequest::new(&model, &q0, &steps, &params)
        .among(seen)
        .below(below)
        .max_stances(a.stances)
        .climb();
    let wall_s = started.elapsed().as_secs_f64();
    if let (Some(c), false) = (&closer_look, a.json) {
        println!(
            "{}: left for a closer look with any step above it; the {below} below it are planned",
            c.message
        );
    }
    let planned = match result {
        Ok(p) => p,
        Err(e) => {
            if a.json {
                let report = PlanReport {
                    ok: false,
                    reason: Some(e.to_string()),
                    refusal: Some(e.refusal()),
                    wall_s,
                    closer_look,
                    plan: None,
                };
                println!("{}", serde_json::to_string_pretty(&report)?);
            } else {
                println!("refused: {e}");
            }
            return Ok(ExitCode::from(1));
        }
    };
    if let Some(path) = &a.trajectory {
        write_csv(path, &model, &planned.trajectory)?;
    }
    if a.json {
        let plan = PlanMsg::of(0.0, &rects, &planned);
        let report =
            PlanReport { ok: true, reason: None, refusal: None, wall_s, closer_look, plan: Some(plan) };
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_tables(&planned, &model, wall_s);
    }
    Ok(ExitCode::SUCCESS)
}

/// What a plan starts from: the rectangles, the start configuration, the surfaces seen
/// around the steps, and whether the rectangles are perceived.
type Inputs = (Vec<PlaneSegment>, Vec<f64>, Arc<SeenPoints>, bool);

/// The rectangles, the start configuration, the surfaces seen around the steps (a
/// perceived scenario's whole scan, the body kept off it as the loop does; nothing
/// otherwise), and whether the rectangles are perceived (a rectangles file, a scan), not
/// ground truth.
fn inputs(a: &PlanArgs, model: &RobotModel) -> Result<Inputs> {
    let is_txt = a.input.as_deref().and_then(Path::extension).is_some_and(|e| e.eq_ignore_ascii_case("txt"));
    if is_txt {
        let path = a.input.as_deref().unwrap_or(Path::new(""));
        let text =
            std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
        let rects = rectangles::parse(&text).with_context(|| path.display().to_string())?;
        let start = start_before(&rects, a.floor_z, a.standoff_m)?;
        return Ok((rects, hrp4::half_sitting_at(model, &start)?, Arc::default(), true));
    }
    if a.floor_z.is_some() {
        bail!("--floor-z is for rectangles files; a scenario's floor is at z = 0");
    }
    let scenario = super::load_scenario(a.input.as_deref())?;
    let scene = Scene::from_scenario(&scenario)?;
    let q0 = hrp4::half_sitting_at(model, &scene.robot_start())?;
    if a.perceived {
        let scan = scan_scenario(&scenario, &mut |_, _| {})?;
        let cloud = scan.sweep.assemble(&AssembleParams::default())?;
        let rects = perceive(&cloud, &PerceptionParams::default())?.segments;
        let p = SurroundingsParams::default();
        let mut around = Surroundings::default();
        add_view(&mut around, &cloud, model, &q0, &p);
        let seen = SeenPoints::with_unseen(around.points(&p), around.unseen(&p));
        return Ok((rects, q0, Arc::new(seen), true));
    }
    Ok((rectangles::from_step_tops(scene.steps()), q0, Arc::default(), false))
}

/// The floor point between the feet, `standoff_m` in front of the lowest rectangle's front
/// edge, facing up the stairs.
fn start_before(rects: &[PlaneSegment], floor_z: Option<f64>, standoff_m: f64) -> Result<Isometry3<f64>> {
    let by_height = rectangles::by_height(rects);
    let first = by_height[0];
    let floor = match (floor_z, stairbench::stats::median(rectangles::rises_m(&by_height, None))) {
        (Some(z), _) => z,
        (None, Some(rise)) => first.height_m() - rise,
        (None, None) => bail!("one step only: give the floor's height with --floor-z"),
    };
    let u = first.along();
    let front = first.center() - u * (first.depth_m() / 2.0 + standoff_m);
    Ok(Isometry3::from_parts(
        Translation3::new(front.x, front.y, floor),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), u.y.atan2(u.x)),
    ))
}

fn print_tables(p: &Plan, model: &RobotModel, wall_s: f64) {
    println!("footholds (sole centres, m):");
    println!("  stance  on      right (x, y, z)            left (x, y, z)");
    for (i, s) in p.stances.iter().enumerate() {
        let (r, l) = (s.right.translation.vector, s.left.translation.vector);
        let on = s.step.map_or("floor".to_string(), |k| format!("step {}", k + 1));
        println!(
            "  {:>6}  {on:<7} {:>7.3} {:>7.3} {:>7.3}    {:>7.3} {:>7.3} {:>7.3}",
            i + 1,
            r.x,
            r.y,
            r.z,
            l.x,
            l.y,
            l.z
        );
    }
    println!("\nsegments:");
    println!(
        "  #   stance  phase          time s   CoM start (x, y, z)      CoM end (x, y, z)        margin mm"
    );
    for (i, s) in p.segments.iter().enumerate() {
        println!(
            "  {:<3} {:>6}  {:<14} {:>6.2}   {:>6.3} {:>6.3} {:>6.3}    {:>6.3} {:>6.3} {:>6.3}    {:>6.1}",
            i + 1,
            s.stance + 1,
            format!("{:?}", s.phase),
            s.duration_s,
            s.com_start.x,
            s.com_start.y,
            s.com_start.z,
            s.com_end.x,
            s.com_end.y,
            s.com_end.z,
            s.margin_m * 1e3
        );
    }
    let t = &p.tracking;
    println!(
        "\nmotion {:.1} s, {} samples at {} Hz; smallest margin {:.1} mm",
        p.duration_s(),
        p.trajectory.samples.len(),
        p.trajectory.rate_hz,
        p.min_margin_m() * 1e3
    );
    println!(
        "tracking: CoM within {:.2} mm, feet at touchdown within {:.2} mm, contacts still within {:.3} mm",
        t.max_com_error_m * 1e3,
        t.max_touchdown_error_m * 1e3,
        t.max_contact_drift_m * 1e3
    );
    println!(
        "posture: the waist tilts at most {:.1} deg from upright; the loaded knees bend at least {}",
        t.max_base_tilt_rad.to_degrees(),
        t.min_loaded_knee_rad.map_or("(none loaded)".to_string(), |k| format!("{:.1} deg", k.to_degrees()))
    );
    let weight_n = model.total_mass_kg() * stairbench::robot::GRAVITY_M_S2;
    println!(
        "momentum: its change asks at most {:.1} N m about a horizontal axis (the ZMP {:.1} mm off the CoM's projection) and {:.1} N m about the vertical, over {:.2} s",
        t.max_tipping_moment_nm,
        t.max_tipping_moment_nm / weight_n * 1e3,
        t.max_yaw_moment_nm,
        stairbench::robot::momentum::RATE_WINDOW_S
    );
    match t.min_leg_clearance_m {
        Some(d) => println!("legs: at least {:.1} mm from the steps", d * 1e3),
        None => println!("legs: never near a step"),
    }
    match &t.nearest_body_surface {
        Some(n) => println!(
            "body: at least {:.1} mm from the seen surfaces and unseen space ({} by {} at ({:.3}, {:.3}, {:.3}) m at {:.2} s)",
            n.clearance_m * 1e3,
            n.limb,
            if n.unseen { "unseen space" } else { "a surface" },
            n.point_m[0],
            n.point_m[1],
            n.point_m[2],
            n.t_s
        ),
        None => println!("body: never near a seen surface"),
    }
    println!(
        "planning took {:.2} s: gait and polygons {:.1} ms, IK {} ticks at {:.3} ms each",
        wall_s,
        p.gait_time_s * 1e3,
        t.ik_ticks,
        1e3 * t.ik_time_s / t.ik_ticks.max(1) as f64
    );
}

/// Writes q(t) as CSV: t_s, the base x y z qw qx qy qz, then one column per joint.
pub fn write_csv(path: &Path, model: &RobotModel, traj: &JointTrajectory) -> Result<()> {
    let mut f = std::io::BufWriter::new(
        std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?,
    );
    let names: Vec<&str> = model.joints().iter().map(|j| j.name.as_str()).collect();
    writeln!(f, "t_s,x,y,z,qw,qx,qy,qz,{}", names.join(","))?;
    for s in &traj.samples {
        let row: Vec<String> =
            std::iter::once(s.t_s).chain(s.q.iter().copied()).map(|v| format!("{v:.6}")).collect();
        writeln!(f, "{}", row.join(","))?;
    }
    f.flush()?;
    Ok(())
}
