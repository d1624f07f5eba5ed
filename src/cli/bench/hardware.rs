//! `stairbench bench hardware`: do the drivers keep up with the sensor head? Sweeps of the
//! hardware path against the emulator (`stairbench emulate`, run as a child process so that its
//! ray casting is not counted here), with the servo read as fast as its bus allows. Reported
//! against the devices' own rates: the lidar's rows per second (40 for the UTM-30LX-EW) and
//! the servo's readings per second the bus can carry (the bytes of a read at the baud rate
//! plus the MX-64's return delay, which the emulator keeps), with the CPU share of each driver
//! thread and of the whole process.

use anyhow::{bail, Context, Result};
use stairbench::robot::hrp4::standing_head_pose;
use stairbench::sensor::dynamixel::packet::{self, Protocol};
use stairbench::sensor::dynamixel::Table;
use stairbench::sensor::hardware::{HardwareConfig, HardwareSource, SweepStats};
use stairbench::sensor::Source;
use stairbench::sim::emulator::ServoSpec;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// The emulator child, killed when dropped.
struct EmulatorProcess(Child);

impl Drop for EmulatorProcess {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Starts `stairbench emulate` for protocol `protocol` and waits for its hardware file.
fn start_emulator(protocol: Protocol, dir: &Path) -> Result<(EmulatorProcess, HardwareConfig)> {
    let config = dir.join(format!("hardware-p{}.toml", u8::from(protocol)));
    let _ = std::fs::remove_file(&config);
    let exe = std::env::current_exe().context("cannot find this program to start the emulator")?;
    let child = Command::new(exe)
        .args(["emulate", "--lidar-listen", "127.0.0.1:0", "--protocol"])
        .arg((u8::from(protocol)).to_string())
        .arg("--write-config")
        .arg(&config)
        .stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .spawn()
        .context("cannot start `stairbench emulate`")?;
    let mut child = EmulatorProcess(child);
    let limit = Instant::now() + Duration::from_secs(60);
    loop {
        if let Ok(text) = std::fs::read_to_string(&config) {
            if text.contains("[mount]") {
                let cfg = HardwareConfig::parse(&text, &config.display().to_string())?;
                return Ok((child, cfg));
            }
        }
        if let Some(status) = child.0.try_wait()? {
            bail!("the emulator ended ({status}) before writing {}", config.display());
        }
        if Instant::now() > limit {
            bail!("the emulator wrote no hardware file in 60 s ({})", config.display());
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// The CPU time of this process, seconds (user and system).
fn process_cpu_s() -> f64 {
    // SAFETY: getrusage fills the struct it is given, a zeroed local here.
    let mut u: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: as above; RUSAGE_SELF is a valid target.
    if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) } != 0 {
        return f64::NAN;
    }
    let s = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    s(u.ru_utime) + s(u.ru_stime)
}

/// The readings per second a bus at `baud` carries: a read request and its reply on the wire,
/// plus the servo's return delay.
fn bus_readings_per_s(protocol: Protocol, baud: u32) -> f64 {
    let table = Table::mx64(protocol);
    let r = table.present_position;
    let params: Vec<u8> = match protocol {
        Protocol::One => vec![r.address as u8, r.size],
        Protocol::Two => [r.address.to_le_bytes(), u16::from(r.size).to_le_bytes()].concat(),
    };
    let request = packet::instruction(protocol, 1, packet::instruction::READ, &params).len();
    let reply = packet::status(protocol, 1, 0, &vec![0; usize::from(r.size)]).len();
    1.0 / (ServoSpec::default().return_delay_s + (request + reply) as f64 * 10.0 / f64::from(baud))
}

/// One protocol's sweeps: the stats and the process CPU seconds of each.
fn sweeps(cfg: &HardwareConfig, repeat: usize) -> Result<Vec<(SweepStats, f64)>> {
    let mut source = HardwareSource::new(cfg, standing_head_pose()?, |_| {});
    let cancel = stairbench::cancel::Cancel::new();
    let mut out = Vec::new();
    for i in 0..repeat {
        let cpu0_s = process_cpu_s();
        let t0 = Instant::now();
        source.sweep(&cancel, &mut |_, _| {}).with_context(|| format!("sweep {}", i + 1))?;
        let (cpu_s, wall_s) = (process_cpu_s() - cpu0_s, t0.elapsed().as_secs_f64());
        let stats = source.last_stats().context("the sweep left no figures")?;
        eprintln!(
            "  sweep {}: {} rows, {} servo readings in {:.2} s",
            i + 1,
            stats.scans,
            stats.readings,
            stats.streaming_s
        );
        out.push((stats, cpu_s / wall_s));
    }
    Ok(out)
}

/// The median of `v`, NaN for none (a figure not measured).
fn median(v: impl IntoIterator<Item = f64>) -> f64 {
    stairbench::stats::median(v).unwrap_or(f64::NAN)
}

/// Runs the benchmark: `repeat` sweeps per servo protocol.
pub fn run(repeat: usize) -> Result<String> {
    let dir = PathBuf::from("out/bench");
    std::fs::create_dir_all(&dir)?;
    let mut t = String::new();
    writeln!(
        t,
        "Machine: {}. Against `stairbench emulate` (Exp. 1's world) in a child process: lidar \
         on TCP, MX-64 on a pseudo-terminal at its baud rate with its 500 us return delay. \
         Medians of {repeat} sweeps per protocol.\n",
        super::machine()
    )?;
    writeln!(
        t,
        "| servo | rows/s | sensor rows/s | ratio | readings/s | bus readings/s | ratio | \
         servo thread CPU | lidar thread CPU | process CPU |"
    )?;
    writeln!(t, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")?;
    for protocol in [Protocol::One, Protocol::Two] {
        eprintln!("Protocol {}:", u8::from(protocol));
        let (_emulator, cfg) = start_emulator(protocol, &dir)?;
        let runs = sweeps(&cfg, repeat)?;
        let per = |f: &dyn Fn(&SweepStats) -> f64| median(runs.iter().map(|(s, _)| f(s)));
        let rows_s = per(&|s| s.scans as f64 / s.streaming_s);
        let readings_s = per(&|s| s.readings as f64 / s.streaming_s);
        let servo_cpu = per(&|s| s.servo_cpu_s / s.streaming_s);
        let lidar_cpu = per(&|s| s.lidar_cpu_s / s.streaming_s);
        let process_cpu = median(runs.iter().map(|r| r.1));
        let sensor_rows_s =
            1.0 / HardwareSource::new(&cfg, Default::default(), |_| {}).model().row_period_s();
        let bus_s = bus_readings_per_s(protocol, cfg.servo.baud);
        writeln!(
            t,
            "| MX-64 Protocol {}, {} baud | {rows_s:.1} | {sensor_rows_s:.1} | {:.3} | {readings_s:.0} | \
             {bus_s:.0} | {:.2} | {:.1} % | {:.1} % | {:.1} % |",
            u8::from(protocol),
            cfg.servo.baud,
            rows_s / sensor_rows_s,
            readings_s / bus_s,
            servo_cpu * 100.0,
            lidar_cpu * 100.0,
            process_cpu * 100.0
        )?;
    }
    writeln!(
        t,
        "\nCPU shares are of one core over the streaming (thread CPU time, CLOCK_THREAD_CPUTIME_ID) \
         and over the whole sweep with the moves before it (getrusage of this process)."
    )?;
    Ok(t)
}
