//! `stairbench bench`: speed measurements, as ratios against a baseline run in the same process.

use anyhow::Result;
use clap::{Args, ValueEnum};
use std::process::ExitCode;

/// Arguments of `stairbench bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// What to measure.
    what: BenchWhat,
    /// Repetitions of each measurement (the median is reported).
    #[arg(long, default_value_t = 5)]
    repeat: usize,
}

/// The benchmarks.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum BenchWhat {
    /// Rays per second of the simulated lidar on the Exp. 1 world with the robot present.
    Lidar,
}

/// Runs `stairbench bench`.
pub fn run(a: BenchArgs) -> Result<ExitCode> {
    match a.what {
        BenchWhat::Lidar => lidar(a.repeat),
    }
}

fn lidar(_repeat: usize) -> Result<ExitCode> {
    anyhow::bail!("not yet")
}
