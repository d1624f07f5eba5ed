//! `stairbench bench`: speed measurements, each as a ratio against a baseline run in the same
//! process, printed as a Markdown table and optionally written into BENCHMARKS.md.

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use stairbench::scenario::Scenario;
use stairbench::scene::Scene;
use stairbench::sensor::SimLidar;
use stairbench::sim::World;
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
}

/// The benchmarks.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum BenchWhat {
    /// Rays per second of the simulated lidar on the Exp. 1 world with the robot present.
    Lidar,
}

/// Runs `stairbench bench`.
pub fn run(a: BenchArgs) -> Result<ExitCode> {
    let (key, table) = match a.what {
        BenchWhat::Lidar => ("lidar", lidar(a.repeat.max(1))?),
    };
    print!("{table}");
    if let Some(path) = a.write {
        write_section(&path, key, &table)?;
        println!("written to {}", path.display());
    }
    Ok(ExitCode::SUCCESS)
}

/// Median wall time of `f` over `repeat` runs, seconds.
pub fn median_s(repeat: usize, mut f: impl FnMut()) -> f64 {
    let mut t: Vec<f64> = (0..repeat)
        .map(|_| {
            let t0 = Instant::now();
            f();
            t0.elapsed().as_secs_f64()
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
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

fn lidar(repeat: usize) -> Result<String> {
    const REAL_POINTS_PER_S: f64 = 43_240.0;
    let scenario = Scenario::default();
    let scene = Scene::from_scenario(&scenario)?;
    let world = World::for_scene(&scene)?;
    let lidar = SimLidar::new(&world, &scenario.lidar, scenario.seed)?;
    let rows = lidar.sweep().rows();
    let rays = (rows * lidar.lidar().beams()) as f64;
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().context("thread pool")?;
    let base_s = median_s(repeat, || {
        one.install(|| std::hint::black_box(lidar.rows(0..rows)));
    });
    let par_s = median_s(repeat, || {
        std::hint::black_box(lidar.rows(0..rows));
    });
    let mut t = String::new();
    t += &format!(
        "Simulated lidar, Exp. 1 world with the robot stand-in ({} geoms), one sweep of {rows} rows x {} beams = {rays:.0} rays, median of {repeat}; {}.\n\n",
        world.model().ffi().ngeom,
        lidar.lidar().beams(),
        machine()
    );
    t += "| variant | wall per sweep | rays/s | x real sensor (43 240 points/s) | ratio to baseline |\n|---|---|---|---|---|\n";
    for (name, s) in [("baseline: 1 thread, mj_ray per beam", base_s), ("rayon over rows, all cores", par_s)]
    {
        t += &format!(
            "| {name} | {:.1} ms | {:.2} M | {:.0} x | {:.2} |\n",
            s * 1e3,
            rays / s / 1e6,
            rays / s / REAL_POINTS_PER_S,
            base_s / s
        );
    }
    Ok(t)
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
