//! `stairbench emulate [SCENARIO]`: the sensor head in software, to try the hardware path
//! without hardware: a SCIP 2.0 lidar on TCP (or a pseudo-terminal) and an MX-64 on a
//! pseudo-terminal, the lidar ray-casting the scenario's world at the emulated servo's tilt.
//! It prints where they are and a hardware file that reaches them, then runs until Ctrl-C.

use anyhow::Result;
use clap::Args;
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
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
    /// Put the sensor head here instead of on the robot: its frame's position in the world,
    /// metres, `X,Y,Z` (on a tripod at 1.4 m: `0,0,1.4`; the scenario's stairs start at
    /// x = its `start_distance_m`). The robot's body is not seen.
    #[arg(long, value_name = "X,Y,Z", value_delimiter = ',', num_args = 1, allow_hyphen_values = true)]
    head_xyz: Option<Vec<f64>>,
    /// The placed head's roll, pitch and yaw, degrees, `R,P,Y` (needs `--head-xyz`; default
    /// level, facing +x). The hardware file printed gives the gravity an IMU on the servo base
    /// would read there.
    #[arg(
        long,
        value_name = "R,P,Y",
        value_delimiter = ',',
        num_args = 1,
        allow_hyphen_values = true,
        requires = "head_xyz"
    )]
    head_rpy_deg: Option<Vec<f64>>,
    /// Write the hardware file that reaches the emulator here (else it is printed).
    #[arg(long, value_name = "FILE.toml")]
    write_config: Option<PathBuf>,
}

/// Runs `stairbench emulate`.
pub fn run(a: EmulateArgs) -> Result<ExitCode> {
    let scenario = super::load_scenario(a.scenario.as_deref())?;
    let protocol = Protocol::try_from(a.protocol).map_err(anyhow::Error::msg)?;
    let head_to_world = head_pose(a.head_xyz.as_deref(), a.head_rpy_deg.as_deref())?;
    let cfg = EmulatorConfig {
        lidar: if a.lidar_pty { LidarPort::Pty } else { LidarPort::Tcp(a.lidar_listen.clone()) },
        servo: ServoSpec { protocol, baud: a.servo_baud, ..ServoSpec::default() },
        clock: SensorClock { start_ms: a.clock_start_ms.min((1 << 24) - 1), drift: a.clock_drift_ppm * 1e-6 },
        head_to_world,
        ..EmulatorConfig::default()
    };
    let emu = Emulator::start(&scenario, cfg)?;
    let lidar = match (&emu.lidar_address, &emu.lidar_pty) {
        (Some(addr), _) => format!("address = \"{addr}\""),
        (None, Some(p)) => format!("serial = \"{p}\""),
        (None, None) => String::new(),
    };
    let l = &scenario.lidar;
    let g = emu.gravity_mount(l);
    let config = format!(
        "# stairbench hardware file for the emulator of `{}`\n[lidar]\n{lidar}\n\n[servo]\nserial = \"{}\"\nbaud = {}\nid = 1\nprotocol = {}\nzero_tick = 2048\nticks_per_rev = 4096\ndirection = 1\n\n[sweep]\ntilt_start_deg = {}\ntilt_end_deg = {}\ntilt_speed_dps = {}\nreturn_speed_dps = {}\n\n[mount]\nmount_xyz_m = {:?}\nmount_rpy_deg = {:?}\naxis_to_optical_m = {:?}\n\n# what an IMU on the servo base reads at rest\n[gravity]\nmount = [{:.6}, {:.6}, {:.6}]\n",
        scenario.name,
        emu.servo_pty,
        a.servo_baud,
        a.protocol,
        l.tilt_start_deg,
        l.tilt_end_deg,
        l.tilt_speed_dps,
        l.tilt_return_speed_dps,
        l.mount_xyz_m,
        l.mount_rpy_deg,
        l.axis_to_optical_m,
        g.x,
        g.y,
        g.z
    );
    println!("emulating the sensor head in the world of {}", scenario.name);
    if head_to_world.is_some() {
        let h = emu.head_to_world;
        let (r, p, y) = h.rotation.euler_angles();
        println!(
            "  head at ({:.3}, {:.3}, {:.3}) m, roll {:.1} deg, pitch {:.1} deg, yaw {:.1} deg",
            h.translation.x,
            h.translation.y,
            h.translation.z,
            r.to_degrees() + 0.0, // + 0.0: -0.0 prints as 0.0
            p.to_degrees() + 0.0,
            y.to_degrees() + 0.0
        );
    }
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

/// The head's pose from `--head-xyz` and `--head-rpy-deg` (`None` without them: on the robot).
fn head_pose(xyz_m: Option<&[f64]>, rpy_deg: Option<&[f64]>) -> Result<Option<Isometry3<f64>>> {
    let three = |v: &[f64], flag: &str| -> Result<[f64; 3]> {
        match v {
            [a, b, c] if v.iter().all(|x| x.is_finite()) => Ok([*a, *b, *c]),
            _ => anyhow::bail!("{flag} takes three finite numbers separated by commas, got {v:?}"),
        }
    };
    let Some(xyz) = xyz_m else { return Ok(None) };
    let [x, y, z] = three(xyz, "--head-xyz")?;
    let [r, p, w] = match rpy_deg {
        Some(v) => three(v, "--head-rpy-deg")?,
        None => [0.0; 3],
    };
    Ok(Some(Isometry3::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(r.to_radians(), p.to_radians(), w.to_radians()),
    )))
}
