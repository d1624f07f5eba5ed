//! The `stairbench` command line: argument parsing and dispatch only; the work is in the
//! library and in `cli/`.

mod cli;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// Simulation-in-the-loop test bench for humanoid stair climbing: a MuJoCo staircase world,
/// a simulated tilting Hokuyo lidar, the paper's perception and planning, an HRP-4-class robot.
#[derive(Debug, Parser)]
#[command(name = "stairbench", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Scan a scenario's world with the simulated tilting lidar and write the point cloud.
    Scan(cli::scan::ScanArgs),
    /// Find the staircase's steps in a scan (the paper's §4 perception).
    Perceive(cli::perceive::PerceiveArgs),
    /// The static-stability polygon of a stance (contacts as JSON), by double description
    /// or Bretl's projection.
    Polygon(cli::polygon::PolygonArgs),
    /// Plan the climb (§6): footholds, the five-segment gait with stability polygons, and
    /// the whole-body trajectory by QP IK.
    Plan(cli::plan::PlanArgs),
    /// The closed-loop climb in MuJoCo: scan, perceive, plan, execute with every check, scan
    /// again, to the top; a report per cycle and a non-zero exit code when the climb fails.
    Run(cli::run::RunArgs),
    /// Rerun perception on a recording's lidar rows and compare with what it recorded.
    Replay(cli::replay::ReplayArgs),
    /// CI regression: a suite's generated staircases climbed in parallel, verdicts against
    /// the expected outcomes, JUnit, capability maps, baseline comparison, shards.
    Regress(cli::regress::RegressArgs),
    /// Build a scenario's world: print its ground truth, optionally write the MJCF.
    Scene(cli::scene::SceneArgs),
    /// The sensor head in software: a SCIP 2.0 lidar (TCP or pty) and an MX-64 (pty) seeing a
    /// scenario's world, to try the hardware path (`--hardware`) without hardware.
    Emulate(cli::emulate::EmulateArgs),
    /// Measure speed (rays per second of the simulated lidar, ...).
    Bench(cli::bench::BenchArgs),
}

fn main() -> ExitCode {
    // Output piped into `head` or `less` ends the process quietly when the reader goes,
    // as command-line tools do, instead of a panic on the broken pipe.
    #[cfg(unix)]
    // SAFETY: restores the default action of one signal before any thread starts; no
    // handler of ours is replaced.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    keep_freed_memory();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Scan(a) => cli::scan::run(a),
        Command::Scene(a) => cli::scene::run(a),
        Command::Emulate(a) => cli::emulate::run(a),
        Command::Perceive(a) => cli::perceive::run(a),
        Command::Polygon(a) => cli::polygon::run(a),
        Command::Plan(a) => cli::plan::run(a),
        Command::Run(a) => cli::run::run(a),
        Command::Replay(a) => cli::replay::run(a),
        Command::Regress(a) => cli::regress::run(a),
        Command::Bench(a) => cli::bench::run(a),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {}", error_chain(&e));
            ExitCode::from(2)
        }
    }
}

/// An error and its causes, each cause left out where the message before already says it
/// (errors that name their source in their own message would otherwise say it twice).
fn error_chain(e: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if !out.contains(&text) {
            if !out.is_empty() {
                out.push_str(": ");
            }
            out.push_str(&text);
        }
    }
    out
}

/// Memory freed by glibc's malloc is kept for the next allocation instead of going back to
/// the system: a perception of a sweep takes and frees some megabytes each time, and with
/// glibc's defaults (given back above 128 kB at the heap's top, blocks of 128 kB and more
/// mapped and unmapped each time) each frame touched them afresh, a page fault per 4 kB.
/// Up to 64 MB are kept at the heap's top (`M_TOP_PAD`), and blocks under 32 MB (glibc's
/// own ceiling for its sliding threshold) come from the heap (`M_MMAP_THRESHOLD`).
fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        const TOP_PAD_BYTES: i32 = 64 << 20;
        const MMAP_THRESHOLD_BYTES: i32 = 32 << 20;
        // SAFETY: mallopt only sets allocator parameters; called before any thread starts.
        unsafe {
            libc::mallopt(libc::M_TOP_PAD, TOP_PAD_BYTES);
            libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES);
        }
    }
}
