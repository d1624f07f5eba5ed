//! `stairbench bench`: speed measurements, each as a ratio against a baseline run in the same
//! process, printed as a Markdown table and optionally written into BENCHMARKS.md.

mod climb;
mod fuzz;
mod hardware;
mod lidar;
mod perceive;
mod plan;
mod plot;
mod polygon;
mod robot;

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

/// Arguments of `stairbench bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// What to measure.
    what: BenchWhat,
    /// Repetitions of each measurement (the median is reported).
    #[arg(long, default_value_t = 7)]
    repeat: usize,
    /// Also write the table into this Markdown file, replacing its previous section.
    #[arg(long)]
    write: Option<PathBuf>,
    /// Perception: where to draw the Fig. 5 plot (PNG). Default: `docs/fig5-perception.png`
    /// beside the `--write` file, or no plot without `--write`.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Perception: the PCL peer's binary (built from ../shared/peers), run side by side on
    /// the same exported cloud. Default: /tmp/peers/build/pcl_pipeline when it exists.
    #[arg(long)]
    pcl: Option<PathBuf>,
    /// Fuzz: inputs per parser.
    #[arg(long, default_value_t = 1_000_000)]
    inputs: u64,
    /// Fuzz: the seed of the inputs (a failure names its chunk and index under it).
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

/// The benchmarks.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum BenchWhat {
    /// Rays per second of the simulated lidar on the Exp. 1 world with the robot present.
    Lidar,
    /// The perception pipeline (§4): Fig. 5's sweep over k on Exp. 1 and Exp. 2, time per
    /// phase, the k-d tree baseline, and the PCL peer on the same cloud.
    #[value(alias = "perception")]
    Perceive,
    /// The static-stability polygon: double description against Bretl's projection.
    Polygon,
    /// The planner: one IK tick, and the Exp. 1 and Exp. 2 plans against their motion.
    Plan,
    /// The closed-loop climb of Exp. 1 and of the 24 cm step: wall time against simulated time.
    Climb,
    /// The robot's kinematics (FK, Jacobians, CoM) against MuJoCo's, and simulation speed.
    Robot,
    /// The device parsers (SCIP 2.0, Dynamixel 1.0 and 2.0) on --inputs seeded mutated and
    /// arbitrary inputs each: failures (panics, loops) and speed. Exits non-zero on a failure.
    Fuzz,
    /// The hardware drivers against the emulator (a child process): rows and servo readings per
    /// second against the devices' rates, and the CPU share of the driver threads.
    Hardware,
}

/// Runs `stairbench bench`.
pub fn run(a: BenchArgs) -> Result<ExitCode> {
    let repeat = a.repeat.max(1);
    let mut passed = true;
    let (key, table) = match a.what {
        BenchWhat::Lidar => ("lidar", lidar::run(repeat)?),
        BenchWhat::Robot => ("robot", robot::run(repeat)?),
        BenchWhat::Polygon => ("polygon", polygon::run(repeat)?),
        BenchWhat::Plan => ("plan", plan::run(repeat)?),
        BenchWhat::Climb => ("climb", climb::run(repeat)?),
        BenchWhat::Hardware => ("hardware", hardware::run(repeat)?),
        BenchWhat::Fuzz => {
            let (table, ok) = fuzz::run(a.inputs, a.seed)?;
            passed = ok;
            ("fuzz", table)
        }
        BenchWhat::Perceive => {
            const FIG5: &str = "docs/fig5-perception.png";
            let plot = match (&a.plot, &a.write) {
                (Some(p), _) => Some((p.clone(), p.display().to_string())),
                (None, Some(w)) => Some((w.with_file_name(FIG5), FIG5.to_string())),
                (None, None) => None,
            };
            let plot = plot.as_ref().map(|(p, link)| (p.as_path(), link.as_str()));
            ("perceive", perceive::run(repeat, plot, a.pcl.as_deref())?)
        }
    };
    print!("{table}");
    if let Some(path) = a.write {
        write_section(&path, key, &table)?;
        println!("written to {}", path.display());
    }
    Ok(if passed { ExitCode::SUCCESS } else { ExitCode::FAILURE })
}

/// Median wall time of `f` over `repeat` runs, seconds.
pub fn median_s(repeat: usize, mut f: impl FnMut()) -> f64 {
    let t = (0..repeat).map(|_| {
        let t0 = Instant::now();
        f();
        t0.elapsed().as_secs_f64()
    });
    stairbench::stats::median(t).unwrap_or(f64::NAN)
}

/// The machine, for the record: cores and CPU model.
pub fn machine() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .map(|l| l.split(':').nth(1).unwrap_or("").trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    format!("{} cores ({cpu})", rayon::current_num_threads())
}

/// Replaces the section `key` of a Markdown file (between `<!-- bench:key -->` and
/// `<!-- /bench:key -->`), appending it when absent.
pub fn write_section(path: &Path, key: &str, body: &str) -> Result<()> {
    let (open, close) = (format!("<!-- bench:{key} -->"), format!("<!-- /bench:{key} -->"));
    let old = std::fs::read_to_string(path).unwrap_or_default();
    let cmd = std::env::args().collect::<Vec<_>>().join(" ");
    let section = format!("{open}\nCommand: `{cmd}`\n\n{body}{close}");
    let new = match (old.find(&open), old.find(&close)) {
        (Some(a), Some(b)) if b > a => format!("{}{}{}", &old[..a], section, &old[b + close.len()..]),
        _ => format!("{}\n{}\n", old.trim_end(), section),
    };
    std::fs::write(path, new).with_context(|| format!("cannot write {}", path.display()))
}
