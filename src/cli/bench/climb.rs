//! `bench climb`: the closed loop on Exp. 1 and on the paper's 24 cm step. The simulated time
//! is the baseline: the whole loop's and the execution's speed as multiples of real time, and
//! the perception plus planning each cycle waits for (issue 6's goals: the simulation faster
//! than 10 x real time, perception and planning under 1 s); and the cost of recording the
//! climb to MCAP, against the same climb unrecorded (issue 7's goal: under 10 %).

use super::machine;
use anyhow::Result;
use stairbench::cancel::Cancel;
use stairbench::climb::{ClimbReport, Nobody, Observer};
use stairbench::params::ClimbParams;
use stairbench::scenario::Scenario;
use stairbench::sim::climb_scenario;

/// One climb of `scenario` with `params`, seen by `observer`.
fn climb(scenario: &Scenario, params: &ClimbParams, observer: &mut dyn Observer) -> Result<ClimbReport> {
    Ok(climb_scenario(scenario, params, observer, &Cancel::never())?)
}

/// Returns the Markdown table.
pub fn run(repeat: usize) -> Result<String> {
    let mut t = format!(
        "Closed-loop climbs (scan, perceive, plan one stance, execute with every check at 1 kHz), default parameters, median of {repeat} runs by wall time; machine: {}.\n\n",
        machine()
    );
    t += "| scenario | result | cycles | simulated | wall | loop / real time | execution / real time | perceive + plan, worst cycle | perceive, mean | plan, mean | lidar ray casting, mean |\n|---|---|---|---|---|---|---|---|---|---|---|\n";
    for name in ["exp1", "hrp4_step"] {
        let scenario = crate::cli::load_scenario(Some(std::path::Path::new(name)))?;
        let mut runs: Vec<ClimbReport> = (0..repeat)
            .map(|_| climb(&scenario, &ClimbParams::default(), &mut Nobody))
            .collect::<Result<_, _>>()?;
        runs.sort_by(|a, b| a.wall_s.total_cmp(&b.wall_s));
        let r = &runs[runs.len() / 2];
        t += &format!(
            "| {name} | {} {}/{} steps | {} | {:.1} s | {:.2} s | {:.1} x | {:.1} x | {:.2} s | {:.0} ms | {:.2} s | {:.0} ms |\n",
            if r.success { "climbed" } else { "FAILED" },
            r.steps_climbed,
            r.steps_total,
            r.cycles.len(),
            r.sim_s,
            r.wall_s,
            r.sim_s / r.wall_s,
            r.execution_speed(),
            r.worst_think_s(),
            1e3 * r.mean_per_cycle(|c| c.perceive_s),
            r.mean_per_cycle(|c| c.plan_s),
            1e3 * r.mean_per_cycle(|c| c.scan_s),
        );
    }
    // Recording's cost: the same climb with and without --record, alternated, same process.
    let scenario = crate::cli::load_scenario(None)?;
    let params = ClimbParams::default();
    let path = std::env::temp_dir().join(format!("stairbench-bench-{}.mcap", std::process::id()));
    let (mut plain, mut recorded, mut bytes) = (Vec::new(), Vec::new(), 0);
    for _ in 0..repeat {
        plain.push(climb(&scenario, &params, &mut Nobody)?.wall_s);
        let started = std::time::Instant::now();
        let mut rec = crate::cli::start_recording(&path, "bench climb", &scenario, &params)?;
        climb(&scenario, &params, &mut rec)?;
        rec.finish()?;
        recorded.push(started.elapsed().as_secs_f64());
        bytes = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
    }
    let _ = std::fs::remove_file(&path);
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (a, b) = (median(&mut plain), median(&mut recorded));
    t += &format!(
        "\nRecording (`run --record`, every stage to MCAP, LZ4 chunks from a writer thread), exp1, same process, median of {repeat} alternated runs: {a:.2} s without, {b:.2} s with (file closed), ratio {:.3} ({:+.1} %); the file is {:.0} MB.\n",
        b / a,
        100.0 * (b / a - 1.0),
        bytes as f64 / 1e6
    );
    t += "\nLoop / real time counts everything (ray casting, perception, planning, execution); execution / real time is MuJoCo with the servos and every check alone. Planning is nearly all IK ticks (see bench plan).\n";
    Ok(t)
}
