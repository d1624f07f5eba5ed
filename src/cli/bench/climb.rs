//! `bench climb`: the closed loop on Exp. 1 and on the paper's 24 cm step, with the
//! stabilizer and without it (the same climbs in the same process). The simulated time is the
//! baseline: the whole loop's and the execution's speed as multiples of real time, and the
//! perception plus planning each cycle waits for (issue 6's goals: the simulation faster than
//! 10 x real time, perception and planning under 1 s); the stabilizer's tick and its share of
//! the execution (issue 18); and the cost of recording the climb to MCAP, against the same
//! climb unrecorded (issue 7's goal: under 10 %).

use super::machine;
use anyhow::Result;
use stairbench::cancel::Cancel;
use stairbench::climb::{ClimbReport, Nobody, Observer};
use stairbench::params::ClimbParams;
use stairbench::scenario::Scenario;
use stairbench::sim::climb_scenario;

/// One climb of `scenario` with `params`, seen by `observer`.
fn climb(scenario: &Scenario, params: &ClimbParams, observer: &mut dyn Observer) -> Result<ClimbReport> {
    Ok(climb_scenario(scenario, params.loop_params(), &params.sim(), observer, &Cancel::never())?)
}

/// Returns the Markdown table.
pub fn run(repeat: usize) -> Result<String> {
    let mut t = format!(
        "Closed-loop climbs (scan, perceive, plan one stance, execute with every check at 1 kHz), default parameters, median of {repeat} runs by wall time; machine: {}.\n\n",
        machine()
    );
    t += "| scenario | stabilizer | result | friction ratio, largest | cycles | simulated | wall | loop / real time | execution / real time | stabilizer tick, mean | perceive + plan, worst cycle | perceive, mean | plan, mean | lidar ray casting, mean |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    for name in ["exp1", "hrp4_step"] {
        let scenario = crate::cli::load_scenario(Some(std::path::Path::new(name)))?;
        let mut wall = [0.0; 2];
        for (k, on) in [true, false].into_iter().enumerate() {
            let mut params = ClimbParams::default();
            params.stabilizer.enabled = on;
            let mut runs: Vec<ClimbReport> =
                (0..repeat).map(|_| climb(&scenario, &params, &mut Nobody)).collect::<Result<_, _>>()?;
            runs.sort_by(|a, b| a.wall_s.total_cmp(&b.wall_s));
            let r = &runs[runs.len() / 2];
            wall[k] = r.wall_s / r.sim_s;
            let (ticks, tick_s) = r
                .cycles
                .iter()
                .filter_map(|c| c.execution.control)
                .fold((0, 0.0), |(n, s), c| (n + c.ticks, s + c.wall_s));
            let tick = if ticks > 0 { format!("{:.0} us", 1e6 * tick_s / ticks as f64) } else { "-".into() };
            t += &format!(
                "| {name} | {} | {} {}/{} steps | {:.2} | {} | {:.1} s | {:.2} s | {:.1} x | {:.1} x | {tick} | {:.2} s | {:.0} ms | {:.2} s | {:.0} ms |\n",
                if on { "on" } else { "off" },
                if r.success { "climbed" } else { "FAILED" },
                r.steps_climbed,
                r.steps_total,
                r.max_friction_ratio(),
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
        t += &format!(
            "| {name} | on / off | | | | | wall per simulated second x {:.2} | | | | | | | |\n",
            wall[0] / wall[1]
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
    let median = |v: Vec<f64>| stairbench::stats::median(v).unwrap_or(f64::NAN);
    let (a, b) = (median(plain), median(recorded));
    t += &format!(
        "\nRecording (`run --record`, every stage to MCAP, LZ4 chunks from a writer thread), exp1, same process, median of {repeat} alternated runs: {a:.2} s without, {b:.2} s with (file closed), ratio {:.3} ({:+.1} %); the file is {:.0} MB.\n",
        b / a,
        100.0 * (b / a - 1.0),
        bytes as f64 / 1e6
    );
    t += "\nThe friction ratio is the largest tangential over normal force of a loaded foot (the check's limit is the friction coefficient, 0.7). ";
    t += "Loop / real time counts everything (ray casting, perception, planning, execution); execution / real time is MuJoCo with the servos and every check alone. Planning is nearly all IK ticks (see bench plan).\n";
    Ok(t)
}
