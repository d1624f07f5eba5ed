//! `stairbench emulate [SCENARIO]`: the sensor head in software, to try the hardware path
//! without hardware: a SCIP 2.0 lidar on TCP (or a pseudo-terminal) and an MX-64 on a
//! pseudo-terminal, the lidar ray-casting the scenario's world at the emulated servo's tilt.
//! It prints where they are and a hardware file that reaches them, then runs until Ctrl-C.

use anyhow::Result;
use clap::Args;
use stairbench::sensor::dynamixel::Protocol;
use stairbench::sim::emulator::{Emulator, EmulatorConfig, LidarPort, SensorClock, ServoSpec};
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `stairbench emulate`.
#[derive(Debug, Args)]
pub struct EmulateArgs {
    /// The scenario whose world the lidar sees (file or name; default: the paper's Exp. 1).
    scenario: Option<PathBuf>,
    /// The lidar's TCP address (the UTM-30LX-EW's factory port is 10940; port 0: any free).
    #[arg(long, default_value = "127.0.0.1:10940")]
    lidar_listen: String,
    /// Put the lidar on a pseudo-terminal instead (a USB lidar), its path printed.
    #[arg(long)]
    lidar_pty: bool,
    /// The servo is on a pseudo-terminal (always; the flag is accepted for scripts).
    #[arg(long)]
    servo_pty: bool,
    /// The servo's firmware protocol, 1 or 2.
    #[arg(long, default_value_t = 1)]
    protocol: u8,
    /// The servo's baud rate (a driver at another rate hears garbage, as on a real bus).
    #[arg(long, default_value_t = 1_000_000)]
    servo_baud: u32,
    /// The lidar clock's count at start, ms (2^24 = 16777216 wraps; start near it to try the
    /// wrap).
    #[arg(long, default_value_t = 1_234_567)]
    clock_start_ms: u32,
    /// The lidar clock's drift, ppm.
    #[arg(long, default_value_t = 0.0)]
    clock_drift_ppm: f64,
    /// Write the hardware file that reaches the emulator here (else it is printed).
    #[arg(long, value_name = "FILE.toml")]
    write_config: Option<PathBuf>,
}

/// Runs `stairbench emulate`.
pub fn run(a: EmulateArgs) -> Result<ExitCode> {
    let scenario = super::load_scenario(a.scenario.as_deref())?;
    let protocol = Protocol::try_from(a.protocol).map_err(anyhow::Error::msg)?;
    let cfg = EmulatorConfig {
        lidar: if a.lidar_pty { LidarPort::Pty } else { LidarPort::Tcp(a.lidar_listen.clone()) },
        servo: ServoSpec { protocol, baud: a.servo_baud, ..ServoSpec::default() },
        clock: SensorClock { start_ms: a.clock_start_ms.min((1 << 24) - 1), drift: a.clock_drift_ppm * 1e-6 },
        ..EmulatorConfig::default()
    };
    let emu = Emulator::start(&scenario, cfg)?;
    let lidar = match (&emu.lidar_address, &emu.lidar_pty) {
        (Some(addr), _) => format!("address = \"{addr}\""),
        (None, Some(p)) => format!("serial = \"{p}\""),
        (None, None) => String::new(),
    };
    let l = &scenario.lidar;
    let config = format!(
        "# stairbench hardware file for the emulator of `{}`\n[lidar]\n{lidar}\n\n[servo]\nserial = \"{}\"\nbaud = {}\nid = 1\nprotocol = {}\nzero_tick = 2048\nticks_per_rev = 4096\ndirection = 1\n\n[sweep]\ntilt_start_deg = {}\ntilt_end_deg = {}\ntilt_speed_dps = {}\n\n[mount]\nmount_xyz_m = {:?}\nmount_rpy_deg = {:?}\naxis_to_optical_m = {:?}\n",
        scenario.name,
        emu.servo_pty,
        a.servo_baud,
        a.protocol,
        l.tilt_start_deg,
        l.tilt_end_deg,
        l.tilt_speed_dps,
        l.mount_xyz_m,
        l.mount_rpy_deg,
        l.axis_to_optical_m
    );
    println!("emulating the sensor head in the world of {}", scenario.name);
    match (&emu.lidar_address, &emu.lidar_pty) {
        (Some(addr), _) => println!("  lidar (SCIP 2.0, UTM-30LX-EW) on tcp {addr}"),
        (None, Some(p)) => println!("  lidar (SCIP 2.0, UTM-30LX-EW) on {p}"),
        _ => {}
    }
    println!("  servo (MX-64, Protocol {}, {} baud) on {}", a.protocol, a.servo_baud, emu.servo_pty);
    match &a.write_config {
        Some(path) => {
            super::ensure_parent(path)?;
            std::fs::write(path, &config)?;
            println!(
                "hardware file written to {}: stairbench scan --hardware {}",
                path.display(),
                path.display()
            );
        }
        None => println!("a hardware file for it:\n\n{config}"),
    }
    println!("Ctrl-C stops the emulator");
    let (tx, rx) = std::sync::mpsc::channel();
    ctrlc::set_handler(move || {
        let _ = tx.send(());
    })?;
    let _ = rx.recv();
    emu.stop();
    Ok(ExitCode::SUCCESS)
}
