//! `stairbench run --hardware FILE`: rehearsal before the real robot moves. One sweep of the
//! real sensor head, the steps perceived in it, the whole climb planned from the robot
//! standing in half-sitting, then executed in MuJoCo on a world built from the perceived
//! steps, with every check. The trajectory (CSV, and MCAP with `--record`) is written only
//! when the rehearsal passes. Nothing here commands the robot's joints: its own controller
//! does that, from the trajectory.

use anyhow::{Context, Result};
use stairbench::cancel::Cancel;
use stairbench::climb::{add_view, Event, Nobody, Observer};
use stairbench::params::ClimbParams;
use stairbench::perception::perceive;
use stairbench::perception::step_map::StepMap;
use stairbench::perception::surroundings::Surroundings;
use stairbench::planning::clearance::SeenPoints;
use stairbench::planning::plan_below;
use stairbench::scene::{PerceivedTop, Scene};
use stairbench::sensor::AssembleParams;
use stairbench::sim::execute::{execute, settle};
use stairbench::sim::World;
use std::path::Path;
use std::process::ExitCode;
use std::sync::Arc;

/// The rehearsal; `record` and `trajectory` are written only when it passes.
pub fn run(
    hardware: &Path,
    params: &ClimbParams,
    record: Option<&Path>,
    trajectory: &Path,
) -> Result<ExitCode> {
    let hw = stairbench::sensor::hardware::HardwareConfig::load(hardware)?;
    // Recorded to a file of its own first; kept only when the rehearsal passes.
    let part = record.map(|p| p.with_extension("mcap.part"));
    let mut rec = part
        .as_deref()
        .map(|p| super::start_hardware_recording(p, "run --hardware", &hw, params))
        .transpose()?;
    let discard = |rec: Option<stairbench::record::Recorder>| {
        if let (Some(r), Some(p)) = (rec, part.as_deref()) {
            let _ = r.finish();
            let _ = std::fs::remove_file(p);
        }
    };
    let (_, sweep) = match super::hardware_sweep(hardware, false, rec.as_mut()) {
        Ok(x) => x,
        Err(e) => {
            discard(rec);
            return Err(e);
        }
    };
    let cloud = sweep.assemble(&AssembleParams::default())?;
    let stamp_s = sweep.rows.last().map_or(0.0, |r| r.stamp_s);
    let perceived = perceive(&cloud, &params.perception);
    if let Some(r) = rec.as_mut() {
        r.cloud(stamp_s, &cloud);
        match &perceived {
            Ok(p) => r.event(&Event::Perception { stamp_s, result: p }),
            Err(e) => r.event(&Event::PerceptionFailed { stamp_s, error: e }),
        }
    }
    let steps = match perceived {
        Ok(p) => p.segments,
        Err(e) => {
            discard(rec);
            println!("REFUSED: {e}; nothing to rehearse");
            return Ok(ExitCode::from(1));
        }
    };
    println!("perceived {} steps:", steps.len());
    for (i, s) in steps.iter().enumerate() {
        let c = s.center();
        println!(
            "  step {}: top at {:.3} m, {:.3} m deep, {:.3} m wide, centre ({:.3}, {:.3})",
            i + 1,
            s.height_m(),
            s.depth_m(),
            s.width_m(),
            c.x,
            c.y
        );
    }
    // The world of what was perceived, the robot standing at the origin.
    let tops: Vec<PerceivedTop> =
        steps.iter().map(|s| PerceivedTop { corners: *s.corners(), height_m: s.height_m() }).collect();
    let scene = Scene::rehearsal("hardware rehearsal", &tops, params.run.rehearsal_friction);
    let model = stairbench::robot::hrp4::model()?;
    let mut world = World::for_scene(&scene)?;
    settle(&mut world, params.run.settle_s);
    let q0 = world.configuration().to_vec();
    // The plan's input as the loop (and replay) make it: the steps above the feet, a partly
    // seen top step left out.
    let next = StepMap::default().next_input(
        steps.clone(),
        stairbench::climb::feet_height_m(&model, &q0),
        params.plan.gait.min_tread_m,
        &params.step_map,
    );
    if let Some(top) = &next.deferred {
        println!(
            "  the step at {:.3} m, seen {:.3} m deep, and any above it are left out: a closer look is needed before climbing them",
            top.height_m(),
            top.depth_m()
        );
    }
    let steps = next.ahead.clone();
    // The body kept off every surface the sensor saw (walls, clutter), as the loop does:
    // the rehearsal's world holds the perceived steps only, the real one the rest too.
    let mut around = Surroundings::default();
    add_view(&mut around, &cloud, &model, &q0, &params.surroundings);
    let surfaces = Arc::new(SeenPoints::new(around.points(&params.surroundings)));
    // The step left for a closer look bounds the tread below it, as in the loop.
    let bounded: Vec<_> = steps.iter().chain(next.deferred.as_ref()).cloned().collect();
    let planned = match plan_below(&model, &q0, &bounded, steps.len(), surfaces, None, &params.plan) {
        Ok(p) => p,
        Err(e) => {
            discard(rec);
            println!("REFUSED: {e}");
            return Ok(ExitCode::from(1));
        }
    };
    println!(
        "planned {} stances, {:.1} s of motion; rehearsing it in MuJoCo on the perceived steps",
        planned.stances.len(),
        planned.duration_s()
    );
    let t0 = world.data().time();
    if let Some(r) = rec.as_mut() {
        r.event(&Event::Scene(&scene));
        r.event(&Event::Plan { stamp_s: t0, steps: &steps, plan: &planned });
    }
    let observer: &mut dyn Observer = match rec.as_mut() {
        Some(r) => r,
        None => &mut Nobody,
    };
    let ex = execute(&mut world, &model, &scene, &planned, &params.sim(), observer, &Cancel::never())?;
    for v in &ex.violations {
        println!("  t = {:.3} s  {}: {}", v.t_s, v.check.kind(), v.check);
    }
    let climbed = stairbench::climb::climbed(&scene, &model, &world.configuration());
    println!(
        "rehearsal: {} of {} steps, CoM margin {:.1} mm at least, torque {:.0} % of a limit ({}), friction ratio {:.2}",
        climbed,
        scene.steps().len(),
        ex.min_margin_m * 1e3,
        ex.max_torque_ratio * 100.0,
        ex.torque_joint,
        ex.max_friction_ratio
    );
    if !ex.pass() || climbed < scene.steps().len() {
        discard(rec);
        println!("REHEARSAL FAILED: no trajectory written; the robot must not run this plan");
        return Ok(ExitCode::from(1));
    }
    super::ensure_parent(trajectory)?;
    super::plan::write_csv(trajectory, &model, &planned.trajectory)?;
    println!("REHEARSAL PASSED: trajectory written to {}", trajectory.display());
    if let (Some(r), Some(part), Some(path)) = (rec, part.as_deref(), record) {
        r.finish().context("the recording failed")?;
        std::fs::rename(part, path).with_context(|| format!("cannot write {}", path.display()))?;
        println!("recorded to {}", path.display());
    }
    Ok(ExitCode::SUCCESS)
}
