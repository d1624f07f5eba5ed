//! `stairbench run`: the closed-loop climb of a scenario in MuJoCo (scan, perceive, plan,
//! execute, scan again) with every check, a report per cycle, and an exit code for CI.

use anyhow::{Context, Result};
use clap::Args;
use stairbench::cancel::Cancel;
use stairbench::climb::speed_margin::speed_margin;
use stairbench::climb::{ClimbReport, CycleReport, Each, Event, Observer, Watch};
use stairbench::params::ClimbParams;
use stairbench::record::viewer::{RerunLogger, Sink};
use stairbench::regress::verdict::{strayed, verdict_of};
use stairbench::scenario::{ExpectedOutcome, Scenario};
use stairbench::sim::climb_scenario;
use stairbench::sim::params::PhysicsParams;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `stairbench run`.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// The scenario (file or name in scenarios/; default: the paper's Exp. 1).
    scenario: Option<PathBuf>,
    /// Parameters as TOML: sections [perception], [step_map], [plan.gait], [plan.step]
    /// (with [plan.step.dd]), [plan.ik], [servo], [sensors], [stabilizer], [checks],
    /// [estimate], [run];
    /// fields left out keep their defaults, unknown fields are refused.
    #[arg(long)]
    params: Option<PathBuf>,
    /// The stabilizer between the plan and the servos (force/torque and IMU feedback, §6.3's
    /// future work): `on`, or `off` for the planned q(t) open loop as the paper ran it.
    /// Overrides [stabilizer] enabled of --params.
    #[arg(long, value_name = "on|off")]
    stabilizer: Option<OnOff>,
    /// The robot's own estimate of its pose: `on` (the default), the loop plans from
    /// odometry (encoders and the support foot) and assembles each view where it believes its
    /// head is; `off`, from the simulator's true pose. The checks judge in the true world
    /// either way, and the report gives the estimate's error. Overrides [estimate] enabled of
    /// --params.
    #[arg(long, value_name = "on|off")]
    estimate: Option<OnOff>,
    #[command(flatten)]
    noise: super::NoiseArgs,
    /// The simulated body: `hrp4-like` for a body that differs from the planner's model as a
    /// real HRP-4 does (masses, CoMs, inertias, friction, play, latency, servo gains,
    /// compliant ankles; drawn from the scenario's seed), `nominal` for the model exactly.
    /// Sets the scenario's [plant] preset; the fields its file sets stay.
    #[arg(long, value_name = "PRESET")]
    plant: Option<super::PlantArg>,
    /// Speed the planned motion up by this factor (CoM and foot speeds, shortest
    /// segment and swing piece, the IK's rates), to see how far from quasi-static the
    /// plan runs; the bound on the CoM's acceleration ([step] max_zmp_shift_m) stays. The
    /// default timing is already twice the quasi-static one; below 1 slows it.
    #[arg(long, default_value_t = 1.0)]
    speedup: f64,
    /// Instead of one climb, find the speed margin: the largest speed-up of the planned
    /// timing (the default's, or --params') at which the climb still passes every check
    /// (factors as --speedup's, doubled up to --max-speedup, then bisected to 10 %; each
    /// try is a whole climb, its simulated time printed). For a case that may be refused (its
    /// [expect] outcome refuse or either) whose planned timing is refused, a try passes when
    /// it is refused no earlier with every check kept: the margin of the walks before.
    #[arg(long)]
    speed_margin: bool,
    /// Largest factor --speed-margin tries.
    #[arg(long, default_value_t = 8.0)]
    max_speedup: f64,
    /// Also write the report as JSON to this file.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Record every stage (lidar rows, cloud, perception, plans, robot state, checks) to
    /// this MCAP file; `stairbench replay` reads it back, Foxglove opens it.
    #[arg(long, value_name = "FILE.mcap")]
    record: Option<PathBuf>,
    /// Show every stage in Rerun: alone, spawns a viewer (`rerun` on the PATH, from
    /// `pip install rerun-sdk==0.36.3`); with a URL, streams to that viewer
    /// (e.g. rerun+http://127.0.0.1:9876/proxy).
    #[arg(long, value_name = "URL", num_args = 0..=1, default_missing_value = "spawn", conflicts_with = "rrd")]
    rerun: Option<String>,
    /// Save what --rerun would show to this .rrd file (open it with `rerun FILE.rrd`).
    #[arg(long, value_name = "FILE.rrd")]
    rrd: Option<PathBuf>,
    /// Rehearsal with the real sensors of this hardware file: one sweep, the steps perceived,
    /// the climb planned and executed in MuJoCo on a world built from those steps with every
    /// check; the trajectory is written (CSV, and MCAP with --record) only if it passes.
    /// Nothing commands the robot's joints.
    #[arg(long, value_name = "FILE.toml", conflicts_with_all = ["scenario", "speed_margin", "rerun", "rrd"])]
    hardware: Option<PathBuf>,
    /// With --hardware: where the rehearsed trajectory goes.
    #[arg(long, value_name = "FILE.csv", default_value = "out/hardware/trajectory.csv")]
    trajectory: PathBuf,
}

/// A switch's two positions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum OnOff {
    /// On.
    On,
    /// Off.
    Off,
}

/// Runs `stairbench run`; exit code 0 when the climb succeeded (or, for a scenario with an
/// expected outcome, when the verdict passes), 1 when it failed, 130 when interrupted.
pub fn run(a: RunArgs) -> Result<ExitCode> {
    let mut scenario = super::load_scenario(a.scenario.as_deref())?;
    a.noise.apply(&mut scenario);
    if let Some(p) = a.plant {
        scenario.plant.preset = p.preset();
    }
    let mut params: ClimbParams = super::climb_params(a.params.as_deref())?;
    super::speed_up(&mut params, a.speedup)?;
    if let Some(s) = a.stabilizer {
        params.stabilizer.enabled = s == OnOff::On;
    }
    if let Some(e) = a.estimate {
        params.estimate.enabled = e == OnOff::On;
    }
    if let Some(hw) = &a.hardware {
        return super::rehearse::run(hw, &params, a.record.as_deref(), &a.trajectory);
    }
    if a.speed_margin {
        return run_speed_margin(&scenario, &params, &a);
    }
    println!(
        "climbing {} ({} steps): scan, perceive, plan, execute, scan again",
        scenario.name, scenario.staircase.steps
    );
    let plant = scenario.plant.errors();
    if !plant.is_nominal() {
        let fields: Vec<String> = plant.fields().iter().map(|(n, v)| format!("{n} {v}")).collect();
        println!("the body differs from the planner's model (seed {}): {}", scenario.seed, fields.join(", "));
    }
    if params.physics != PhysicsParams::default() {
        let soles = params.physics.sole_friction_timeconst_s.map_or_else(
            || "MuJoCo's own".to_string(),
            |tc| format!("held with a time constant of {} ms", tc * 1e3),
        );
        println!(
            "physics step {} ms (the default {} ms: [physics] step_s); the soles' friction {soles} ([physics] sole_friction_timeconst_s)",
            params.physics.step_s * 1e3,
            PhysicsParams::default().step_s * 1e3
        );
    }
    println!(
        "{:>5}  {:<8} {:<5} {:>10} {:>14} {:<14} {:>12} {:>8} {:>8} {:>6} {:>10} {:>8} {:>7}",
        "cycle",
        "to",
        "pass",
        "margin mm",
        "torque % lim",
        "joint",
        "touchdown mm",
        "slip mm",
        "friction",
        "seen",
        "perceive s",
        "plan s",
        "sim s"
    );
    // Ctrl-C ends the climb at the next physics step, so the report and the recordings are
    // completed; a second Ctrl-C quits at once.
    let cancel = Cancel::new();
    let on_signal = cancel.clone();
    let handler = ctrlc::set_handler(move || {
        if on_signal.is_cancelled() {
            std::process::exit(130);
        }
        eprintln!("\nstopping after this physics step (Ctrl-C again to quit now)");
        on_signal.cancel();
    });
    if let Err(e) = handler {
        eprintln!("warning: Ctrl-C will not stop the climb cleanly: {e}");
    }
    let model = stairbench::robot::hrp4::model()?;
    let mut recorder =
        a.record.as_ref().map(|p| super::start_recording(p, "run", &scenario, &params)).transpose()?;
    let sink = match (&a.rerun, &a.rrd) {
        (Some(url), _) if url == "spawn" => Some(Sink::Spawn),
        (Some(url), _) => Some(Sink::Connect(url.clone())),
        (None, Some(path)) => {
            super::ensure_parent(path)?;
            Some(Sink::Save(path.clone()))
        }
        (None, None) => None,
    };
    let mut viewer = sink.as_ref().map(|s| RerunLogger::new(s, &model)).transpose()?;
    let mut table = Watch(|e: &Event| {
        if let Event::Cycle { report, .. } = e {
            print_cycle(report);
        }
    });
    let mut observers: Vec<&mut dyn Observer> = vec![&mut table];
    if let Some(r) = recorder.as_mut() {
        observers.push(r);
    }
    if let Some(v) = viewer.as_mut() {
        observers.push(v);
    }
    let report =
        climb_scenario(&scenario, params.loop_params(), &params.sim(), &mut Each(observers), &cancel)?;
    if let (Some(rec), Some(path)) = (recorder, &a.record) {
        let n = rec.finish().with_context(|| format!("recording {} failed", path.display()))?;
        println!("recorded {n} messages to {}", path.display());
    }
    if let Some(v) = viewer {
        v.finish()?;
        if let Some(path) = &a.rrd {
            println!("Rerun recording saved to {}", path.display());
        }
    }
    print_summary(&report, params.run.still_speed_m_s);
    // A scenario written by `regress` says what the bench should do: the verdict against it.
    let verdict = scenario.expect.as_ref().map(|e| (e, verdict_of(e, &report, false)));
    if let Some((e, v)) = &verdict {
        println!("verdict: {v} (expected {:?}: {})", e.outcome, e.reason);
        if let Some(why) = strayed(e, &report) {
            println!("  {why}");
        }
    }
    if let Some(path) = &a.json {
        let mut json = serde_json::to_value(&report)?;
        json["plant"] = serde_json::to_value(scenario.plant.errors())?;
        json["s_per_stair"] = serde_json::to_value(report.seconds_per_stair())?;
        json["s_per_stair_with_stand"] = serde_json::to_value(report.seconds_per_stair_with_stand())?;
        json["plant_preset"] = serde_json::to_value(scenario.plant.preset)?;
        json["physics_step_s"] = serde_json::to_value(params.physics.step_s)?;
        json["sole_friction_timeconst_s"] = serde_json::to_value(params.physics.sole_friction_timeconst_s)?;
        if let Some((e, v)) = &verdict {
            json["verdict"] = serde_json::to_value(v)?;
            json["expect"] = serde_json::to_value(e)?;
        }
        std::fs::write(path, serde_json::to_string_pretty(&json)?)
            .with_context(|| format!("cannot write {}", path.display()))?;
        println!("report written to {}", path.display());
    }
    let passed = verdict.map_or(report.success, |(_, v)| v.pass());
    Ok(match (passed, cancel.is_cancelled()) {
        (_, true) => ExitCode::from(130),
        (true, false) => ExitCode::SUCCESS,
        (false, false) => ExitCode::from(1),
    })
}

/// `--speed-margin`: the search, a line per climb, the result.
fn run_speed_margin(scenario: &Scenario, params: &ClimbParams, a: &RunArgs) -> Result<ExitCode> {
    anyhow::ensure!(a.max_speedup >= 1.0, "--max-speedup must be at least 1, got {}", a.max_speedup);
    println!("speed margin of {}: whole climbs with the planned timing sped up", scenario.name);
    let never = Cancel::never();
    let mut climb = |plan: &stairbench::planning::PlanParams| {
        let p = ClimbParams { plan: plan.clone(), ..params.clone() };
        climb_scenario(scenario, p.loop_params(), &p.sim(), &mut stairbench::climb::Nobody, &never)
    };
    let refusal_allowed = scenario.expect.as_ref().is_some_and(|e| e.outcome != ExpectedOutcome::Climb);
    let m = speed_margin(&params.plan, a.max_speedup, 0.1, refusal_allowed, &mut climb, &mut |t| {
        println!(
            "  x {:.2}: {} ({:.1} s simulated in {:.1} s){}",
            t.factor,
            match (t.passes, t.success) {
                (true, true) => "passes",
                (true, false) => "stops safely, every check kept",
                (false, _) => "FAILS",
            },
            t.sim_s,
            t.wall_s,
            t.why.as_ref().map(|w| format!("\n      {w}")).unwrap_or_default()
        );
    })?;
    if m.planned_stopped_safely {
        println!(
            "the planned timing stops short of the top with every check kept, as the case allows: a faster try passes when it stops so no earlier, and the margin is of the motion before the stop"
        );
    }
    match (m.passes_at, m.fails_at) {
        (Some(p), Some(f)) => println!("speed margin: passes at x {p:.2}, fails at x {f:.2}"),
        (Some(p), None) => println!("speed margin: passes at every factor tried, up to x {p:.2}"),
        _ => println!("speed margin: none, the planned timing itself fails"),
    }
    if let Some(path) = &a.json {
        std::fs::write(path, serde_json::to_string_pretty(&m)?)
            .with_context(|| format!("cannot write {}", path.display()))?;
        println!("report written to {}", path.display());
    }
    Ok(if m.passes_at.is_some() { ExitCode::SUCCESS } else { ExitCode::from(1) })
}

fn print_cycle(c: &CycleReport) {
    println!(
        "{:>5}  {:<8} {:<5} {:>10.1} {:>14.0} {:<14} {:>12.2} {:>8.2} {:>8.2} {:>6} {:>10.3} {:>8.2} {:>7.1}",
        c.cycle,
        c.to,
        if c.pass { "yes" } else { "NO" },
        c.execution.min_margin_m * 1e3,
        c.execution.max_torque_ratio * 100.0,
        c.execution.torque_joint,
        c.execution.max_touchdown_error_m() * 1e3,
        c.execution.max_slip_m * 1e3,
        c.execution.max_friction_ratio,
        c.steps_seen,
        c.perceive_s,
        c.plan_s,
        c.execution.sim_s
    );
    if let Some(r) = &c.looked_again_standing {
        println!("         stood to look again (the sweep taken walking was refused): {}", r.message);
    }
    if let Some(r) = &c.closer_look {
        println!(
            "         walked to look again (nearer, or back to see the first riser): from the last view, {}",
            r.message
        );
    }
    for v in &c.execution.violations {
        println!("         t = {:.3} s  {}: {}", v.t_s, v.check.kind(), v.check);
    }
}

/// The climb's summary lines; `still_speed_m_s` is the speed under which the robot takes itself
/// to be still.
fn print_summary(r: &ClimbReport, still_speed_m_s: f64) {
    println!(
        "\n{}: {} of {} steps climbed, {:.1} s simulated in {:.1} s wall ({:.1} x real time)",
        if r.success { "SUCCESS" } else { "FAILED" },
        r.steps_climbed,
        r.steps_total,
        r.sim_s,
        r.wall_s,
        r.sim_s / r.wall_s.max(1e-9)
    );
    if let Some(why) = &r.stop {
        println!("stopped: {why}");
    }
    if !r.looked_again_standing.is_empty() {
        println!(
            "looked again standing: {} plan(s) made from a sweep taken walking refused and planned again on a look taken standing",
            r.looked_again_standing.len()
        );
    }
    if let (Some(s), Some(with)) = (r.seconds_per_stair(), r.seconds_per_stair_with_stand()) {
        println!("seconds per stair: {s:.1} s of motion per cycle that went up a step; {with:.1} s with the settle and the standing sweep before each plan (perception and planning not counted)");
    }
    if !r.cycles.is_empty() {
        let st = r.stage_times();
        println!(
            "speed: the simulation with its checks ran {:.1} x real time (of its {:.1} s of wall time: physics {:.1} s, stabilizer {:.1} s, checks and the loop {:.1} s); perception + planning took at most {:.2} s per cycle",
            r.execution_speed(),
            st.execute_s,
            st.physics_s,
            st.control_s,
            st.execute_s - st.physics_s - st.control_s,
            r.worst_think_s()
        );
        let (ticks, tick_s) = r
            .cycles
            .iter()
            .filter_map(|c| c.execution.control)
            .fold((0, 0.0), |(n, s), c| (n + c.ticks, s + c.wall_s));
        match r.max_estimate_error_m().zip(r.max_estimate_yaw_rad()) {
            Some((pos_m, yaw_rad)) => println!(
                "estimate: the robot's own (odometry); at a sweep its base was at most {:.1} mm and {:.2} deg off the truth",
                pos_m * 1e3,
                yaw_rad.to_degrees()
            ),
            None => println!("estimate: off (the loop read the simulator's true pose)"),
        }
        if let Some(v) = r.max_still_true_speed_m_s() {
            println!(
                "still: the robot judged itself still at each plan's end (its base under {:.0} mm/s as it saw it) with its base truly at most {:.1} mm/s",
                still_speed_m_s * 1e3,
                v * 1e3
            );
        }
        match ticks {
            0 => println!("stabilizer: off (the planned q(t) open loop)"),
            _ => println!(
                "stabilizer: {ticks} ticks, {:.0} us each on average ({:.1} s of the wall time); friction ratio at most {:.2}",
                1e6 * tick_s / ticks as f64,
                tick_s,
                r.max_friction_ratio()
            ),
        }
    }
}
