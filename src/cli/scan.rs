//! `stairbench scan`: one tilt sweep of the simulated lidar, written as a point cloud.

use anyhow::{Context, Result};
use clap::Args;
use stairbench::cloud::io::{write_cloud, CloudFormat};
use stairbench::params::ClimbParams;
use stairbench::sensor::AssembleParams;
use stairbench::sim::{scan_scenario, ScenarioScan};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

/// Arguments of `stairbench scan`.
#[derive(Debug, Args)]
pub struct ScanArgs {
    /// Scenario file or name in scenarios/ (default: the paper's Exp. 1).
    scenario: Option<PathBuf>,
    /// Output cloud; the extension chooses the format (.ply or .pcd).
    #[arg(short, long, default_value = "out/cloud.ply")]
    output: PathBuf,
    #[command(flatten)]
    noise: super::NoiseArgs,
    /// No progress bar.
    #[arg(short, long)]
    quiet: bool,
    /// Also record the sweep (raw rows, the cloud) to this MCAP file.
    #[arg(long, value_name = "FILE.mcap")]
    record: Option<PathBuf>,
    /// Sweep the real sensor head of this hardware file (a Hokuyo on TCP or serial and the
    /// Dynamixel servo; or `stairbench emulate`) instead of a scenario's simulated one.
    #[arg(long, value_name = "FILE.toml", conflicts_with_all = ["scenario", "noise_mm", "seed"])]
    hardware: Option<PathBuf>,
}

/// `scan --hardware`: a sweep of the real head, to a cloud (and a recording).
fn run_hardware(a: &ScanArgs, hardware: &std::path::Path) -> Result<ExitCode> {
    let format = CloudFormat::from_path(&a.output)
        .with_context(|| format!("{}: the extension must be .ply or .pcd", a.output.display()))?;
    let hw = stairbench::sensor::hardware::HardwareConfig::load(hardware)?;
    let mut rec = a
        .record
        .as_ref()
        .map(|p| super::start_hardware_recording(p, "scan --hardware", &hw, &ClimbParams::default()))
        .transpose()?;
    let t0 = Instant::now();
    let swept = super::hardware_sweep(hardware, a.quiet, rec.as_mut());
    let (_, sweep) = match swept {
        Ok(x) => x,
        Err(e) => {
            if let (Some(r), Some(p)) = (rec, &a.record) {
                r.finish().with_context(|| format!("recording {} failed", p.display()))?;
            }
            return Err(e);
        }
    };
    let cloud = sweep.assemble(&AssembleParams::default())?;
    if let (Some(mut r), Some(p)) = (rec, &a.record) {
        r.cloud(sweep.rows.last().map_or(0.0, |r| r.stamp_s), &cloud);
        let n = r.finish().with_context(|| format!("recording {} failed", p.display()))?;
        println!("recorded {n} messages to {}", p.display());
    }
    super::ensure_parent(&a.output)?;
    write_cloud(&cloud, &a.output, format)?;
    println!(
        "hardware sweep: {} rows x {} beams in {:.2} s, {} points; cloud written to {}",
        sweep.rows.len(),
        sweep.lidar.beams(),
        t0.elapsed().as_secs_f64(),
        cloud.len(),
        a.output.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// Runs `stairbench scan`.
pub fn run(a: ScanArgs) -> Result<ExitCode> {
    if let Some(hw) = &a.hardware {
        return run_hardware(&a, hw);
    }
    let mut scenario = super::load_scenario(a.scenario.as_deref())?;
    a.noise.apply(&mut scenario);
    let format = CloudFormat::from_path(&a.output)
        .with_context(|| format!("{}: the extension must be .ply or .pcd", a.output.display()))?;
    let bar = super::progress_bar(0, "scan", a.quiet);
    let t0 = Instant::now();
    let ScenarioScan { scene, sweep } = scan_scenario(&scenario, &mut |done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    })?;
    let scan_s = t0.elapsed().as_secs_f64();
    bar.finish_and_clear();
    let cloud = sweep.assemble(&AssembleParams::default())?;
    if let Some(path) = &a.record {
        let mut rec = super::start_recording(path, "scan", &scenario, &ClimbParams::default())?;
        let stamp_s = sweep.rows.last().map_or(0.0, |r| r.stamp_s);
        rec.sweep(stamp_s, &sweep);
        rec.cloud(stamp_s, &cloud);
        let n = rec.finish().with_context(|| format!("recording {} failed", path.display()))?;
        println!("recorded {n} messages to {}", path.display());
    }
    super::ensure_parent(&a.output)?;
    write_cloud(&cloud, &a.output, format)?;

    let beams = sweep.beam_count();
    println!(
        "scenario {}: {} rows x {} beams = {} beams over {:.2} s of sweep",
        scene.name(),
        sweep.rows.len(),
        sweep.lidar.beams(),
        beams,
        sweep.rows.len() as f64 * sweep.lidar.row_period_s()
    );
    println!(
        "  {} points ({:.1} % returned), noise sigma {:.1} mm",
        cloud.len(),
        100.0 * cloud.len() as f64 / beams.max(1) as f64,
        scenario.lidar.noise_sigma_m * 1000.0
    );
    for step in scene.steps() {
        let on_top = cloud
            .points()
            .iter()
            .filter(|p| {
                let p = p.cast::<f64>();
                (p.z - step.height_m).abs() < 0.03 && step.contains_xy(&p, 0.0)
            })
            .count();
        println!("  step {} (top at {:.2} m): {} points on the tread", step.index + 1, step.height_m, on_top);
    }
    println!("  world built and swept in {scan_s:.3} s wall (`stairbench bench lidar` measures ray speed)");
    println!("cloud written to {}", a.output.display());
    Ok(ExitCode::SUCCESS)
}
