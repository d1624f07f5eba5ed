//! `bench plan`: the planner (§6) on the Exp. 1 and Exp. 2 ground truth: one IK tick against
//! its 5 ms period at 200 Hz, and the whole plan against the duration of the motion it makes.

use super::machine;
use anyhow::{Context, Result};
use stairbench::planning::{plan, rectangles, Plan, PlanParams};
use stairbench::robot::hrp4;
use stairbench::scene::Scene;
use std::time::Instant;

fn once(name: &str) -> Result<(Plan, f64)> {
    let scenario = crate::cli::load_scenario(Some(std::path::Path::new(name)))?;
    let scene = Scene::from_scenario(&scenario)?;
    let model = hrp4::model()?;
    let q0 = hrp4::half_sitting_at(&model, &scene.robot_start())?;
    let rects = rectangles::from_step_tops(scene.steps());
    let t = Instant::now();
    let p = plan(&model, &q0, &rects, None, &PlanParams::default())
        .with_context(|| format!("{name}: plan refused"))?;
    Ok((p, t.elapsed().as_secs_f64()))
}

/// Returns the Markdown table.
pub fn run(repeat: usize) -> Result<String> {
    let mut t = format!(
        "Planner on the scenarios' ground-truth steps, default parameters (IK at 200 Hz), median of {repeat} runs; machine: {}.\n\n",
        machine()
    );
    t += "| scenario | stances | segments | motion | plan wall time | motion / wall | IK ticks | one IK tick | tick / 5 ms period | gait + polygons |\n|---|---|---|---|---|---|---|---|---|---|\n";
    for name in ["exp1", "exp2"] {
        let mut runs: Vec<(Plan, f64)> = (0..repeat).map(|_| once(name)).collect::<Result<_>>()?;
        runs.sort_by(|a, b| a.1.total_cmp(&b.1));
        let (p, wall) = &runs[runs.len() / 2];
        let tick = p.tracking.ik_time_s / p.tracking.ik_ticks.max(1) as f64;
        t += &format!(
            "| {name} | {} | {} | {:.1} s | {:.2} s | {:.1} | {} | {:.3} ms | {:.3} | {:.1} ms |\n",
            p.stances.len(),
            p.segments.len(),
            p.duration_s(),
            wall,
            p.duration_s() / wall,
            p.tracking.ik_ticks,
            tick * 1e3,
            tick / 5e-3,
            p.gait_time_s * 1e3
        );
    }
    t += "\nOne IK tick = the kinematics update, the task Jacobians, building the QP (40 velocities, contact equalities, 68 joint bounds) and clarabel's solve. The plan's wall time is nearly all IK ticks; clarabel's factorization and products are about 60 % of a tick (perf).\n";
    Ok(t)
}
