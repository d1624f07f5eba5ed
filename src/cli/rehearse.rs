//! `stairbench run --hardware FILE`: rehearsal before the real robot moves. One sweep of the
//! real sensor head, the steps perceived in it, the whole climb planned from the robot
//! standing in half-sitting, then executed in MuJoCo on a world built from the perceived
//! steps, with every check. The trajectory (CSV, and MCAP with `--record`) is written only
//! when the rehearsal passes. Nothing here commands the robot's joints: its own controller
//! does that, from the trajectory.

use anyhow::{Context, Result};
use stairbench::climb::{Event, Observer, Watch};
use stairbench::params::ClimbParams;
use stairbench::perception::perceive;
use stairbench::sensor::AssembleParams;
use stairbench::sim::rehearsal::rehearse;
use std::path::Path;
use std::process::ExitCode;

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
    // The plan is printed as it is made, before the rehearsal runs it.
    let on_plan = |e: &Event| {
        if let Event::Plan { plan, .. } = e {
            println!(
                "planned {} stances, {:.1} s of motion; rehearsing it in MuJoCo on the perceived steps",
                plan.stances.len(),
                plan.duration_s()
            );
        }
    };
    let r = match rec.as_mut() {
        Some(rec) => rehearse(
            &steps,
            &cloud,
            params.loop_params(),
            &params.sim(),
            &mut Watch(|e: &Event| {
                on_plan(e);
                rec.event(e);
            }),
        )?,
        None => rehearse(&steps, &cloud, params.loop_params(), &params.sim(), &mut Watch(on_plan))?,
    };
    if let Some([height_m, depth_m]) = r.deferred {
        println!(
            "  the step at {height_m:.3} m, seen {depth_m:.3} m deep, and any above it are left out: a closer look is needed before climbing them"
        );
    }
    let planned = match &r.plan {
        Ok(p) => p,
        Err(e) => {
            discard(rec);
            println!("REFUSED: {e}");
            return Ok(ExitCode::from(1));
        }
    };
    let model = stairbench::robot::hrp4::model()?;
    if let Some((ex, climbed)) = &r.execution {
        for v in &ex.violations {
            println!("  t = {:.3} s  {}: {}", v.t_s, v.check.kind(), v.check);
        }
        println!(
            "rehearsal: {} of {} steps, CoM margin {:.1} mm at least, torque {:.0} % of a limit ({}), friction ratio {:.2}",
            climbed,
            r.scene.steps().len(),
            ex.min_margin_m * 1e3,
            ex.max_torque_ratio * 100.0,
            ex.torque_joint,
            ex.max_friction_ratio
        );
    }
    if !r.passed() {
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
