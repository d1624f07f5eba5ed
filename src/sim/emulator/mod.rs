//! The sensor-head emulator (`stairbench emulate`): a SCIP 2.0 lidar on TCP or a
//! pseudo-terminal and an MX-64 on a pseudo-terminal, in one process, the lidar ray-casting a
//! scenario's world at the tilt the emulated servo has reached. Engineers try the hardware
//! path with it before the hardware is there; the tests drive the real drivers against it,
//! faults included.

pub mod lidar;
pub mod pty;
pub mod servo;

pub use lidar::{LidarFaults, SensorClock};
pub use servo::{ServoFaults, ServoSpec};

use super::world::World;
use crate::scenario::Scenario;
use crate::scene::mjcf::HEAD_SITE;
use crate::scene::Scene;
use nalgebra::Isometry3;
use pty::{read_timeout, Pty};
use servo::{Motion, SharedMotion};
use std::io::Write;
use std::net::TcpListener;
use std::os::fd::AsRawFd;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Where the emulated lidar listens.
#[derive(Debug, Clone, PartialEq)]
pub enum LidarPort {
    /// A TCP address (`127.0.0.1:10940`; port 0 for any free one).
    Tcp(String),
    /// A pseudo-terminal (a USB lidar).
    Pty,
}

/// The emulator's settings.
#[derive(Debug, Clone)]
pub struct EmulatorConfig {
    /// The lidar's port.
    pub lidar: LidarPort,
    /// The servo.
    pub servo: ServoSpec,
    /// The lidar's clock.
    pub clock: SensorClock,
    /// The lidar's faults.
    pub lidar_faults: LidarFaults,
    /// The servo's tilt at start, degrees.
    pub start_tilt_deg: f64,
    /// Seed of the lidar's noise.
    pub seed: u64,
    /// Where the sensor head is: its frame in the world (a tripod's, a bench's); `None`, on
    /// the robot standing at the scenario's start. The robot's body is never seen.
    pub head_to_world: Option<Isometry3<f64>>,
}

impl Default for EmulatorConfig {
    fn default() -> Self {
        Self {
            lidar: LidarPort::Tcp("127.0.0.1:0".into()),
            servo: ServoSpec::default(),
            clock: SensorClock::default(),
            lidar_faults: LidarFaults::default(),
            start_tilt_deg: 0.0,
            seed: 1,
            head_to_world: None,
        }
    }
}

/// Why the emulator could not start.
#[derive(Debug, thiserror::Error)]
pub enum EmulatorError {
    /// A port or pseudo-terminal.
    #[error("emulator: {0}")]
    Io(#[from] std::io::Error),
    /// The scenario's world.
    #[error("emulator: {0}")]
    World(String),
}

/// A running emulator; stopped when dropped.
pub struct Emulator {
    /// The lidar's TCP address, when on TCP.
    pub lidar_address: Option<String>,
    /// The lidar's pseudo-terminal, when on one.
    pub lidar_pty: Option<String>,
    /// The servo's pseudo-terminal.
    pub servo_pty: String,
    /// Where the sensor head is (its frame in the world).
    pub head_to_world: Isometry3<f64>,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
}

/// Cuts a TCP connection with a reset (no orderly close), as a pulled cable is seen after the
/// switch notices.
fn reset(stream: std::net::TcpStream) {
    let linger = libc::linger { l_onoff: 1, l_linger: 0 };
    // SAFETY: a valid socket fd and a linger struct of the size given.
    unsafe {
        libc::setsockopt(
            stream.as_raw_fd(),
            libc::SOL_SOCKET,
            libc::SO_LINGER,
            (&linger as *const libc::linger).cast(),
            std::mem::size_of::<libc::linger>() as libc::socklen_t,
        );
    }
    drop(stream);
}

/// One connection's loop: commands in, replies and due scans out, until the host leaves, a
/// cut fault, or `stop`.
fn converse<S: std::io::Read + Write + AsRawFd, C: crate::sensor::RayCaster>(
    stream: &mut S,
    device: &mut lidar::Device<'_, C>,
    stop: &AtomicBool,
) -> lidar::Next {
    let mut buf = [0u8; 4096];
    while !stop.load(Ordering::Relaxed) {
        let wait = device
            .next_due()
            .map_or(20, |d| d.saturating_duration_since(Instant::now()).as_millis().min(20) as i32);
        match read_timeout(stream, &mut buf, wait) {
            Ok(0) => {}
            Ok(n) => {
                if device.input(&buf[..n], stream).is_err() {
                    return lidar::Next::Continue;
                }
            }
            Err(_) => return lidar::Next::Continue,
        }
        match device.tick(stream) {
            Ok(lidar::Next::Cut) => return lidar::Next::Cut,
            Ok(lidar::Next::Continue) => {}
            Err(_) => return lidar::Next::Continue,
        }
    }
    lidar::Next::Continue
}

impl Emulator {
    /// Starts the emulator on `scenario`'s world (the lidar on the head as the scenario's
    /// `[lidar]` mounts it, the head where `cfg` puts it or on the robot standing at its
    /// start).
    pub fn start(scenario: &Scenario, cfg: EmulatorConfig) -> Result<Self, EmulatorError> {
        let stop = Arc::new(AtomicBool::new(false));
        let started = Instant::now();
        let motion: SharedMotion = Arc::new(Mutex::new(Motion::at(cfg.start_tilt_deg.to_radians())));
        let servo_pty = Pty::open()?;
        let servo_path = servo_pty.path.clone();
        let mut threads = Vec::new();
        {
            let (spec, motion, stop) = (cfg.servo.clone(), motion.clone(), stop.clone());
            threads.push(std::thread::spawn(move || servo::serve(servo_pty, spec, motion, stop, started)));
        }
        let (lidar_address, lidar_pty, port) = match &cfg.lidar {
            LidarPort::Tcp(addr) => {
                let l = TcpListener::bind(addr)?;
                l.set_nonblocking(true)?;
                (Some(l.local_addr()?.to_string()), None, Ok(l))
            }
            LidarPort::Pty => {
                let p = Pty::open()?;
                (None, Some(p.path.clone()), Err(p))
            }
        };
        let (ready_tx, ready_rx) = mpsc::channel::<Result<Isometry3<f64>, String>>();
        let (scene, spec) = (
            Scene::from_scenario(scenario).map_err(|e| EmulatorError::World(e.to_string()))?,
            scenario.lidar.clone(),
        );
        let stop_l = stop.clone();
        let (clock, faults, seed, placed) =
            (cfg.clock, cfg.lidar_faults.clone(), cfg.seed, cfg.head_to_world);
        threads.push(std::thread::spawn(move || {
            let world = match World::for_scene(&scene) {
                Ok(w) => w,
                Err(e) => {
                    let _ = ready_tx.send(Err(e.to_string()));
                    return;
                }
            };
            let head = match (placed, world.site_id(HEAD_SITE)) {
                (Some(h), _) => h,
                (None, Ok(id)) => world.site_pose(id),
                (None, Err(e)) => {
                    let _ = ready_tx.send(Err(e.to_string()));
                    return;
                }
            };
            let _ = ready_tx.send(Ok(head));
            let device = || {
                lidar::Device::new(&world, &spec, &head, motion.clone(), clock, started, faults.clone(), seed)
            };
            match port {
                Ok(listener) => {
                    while !stop_l.load(Ordering::Relaxed) {
                        match listener.accept() {
                            Ok((mut stream, _)) => {
                                let _ = stream.set_nonblocking(false);
                                let _ = stream.set_nodelay(true);
                                let mut d = device();
                                if converse(&mut stream, &mut d, &stop_l) == lidar::Next::Cut {
                                    reset(stream);
                                }
                            }
                            Err(_) => std::thread::sleep(Duration::from_millis(10)),
                        }
                    }
                }
                Err(mut pty) => {
                    let mut d = device();
                    if converse(&mut pty.master, &mut d, &stop_l) == lidar::Next::Cut {
                        pty.hang_up();
                    }
                }
            }
        }));
        let head_to_world = match ready_rx.recv() {
            Ok(Ok(head)) => head,
            Ok(Err(e)) => return Err(EmulatorError::World(e)),
            Err(_) => return Err(EmulatorError::World("the lidar thread ended".into())),
        };
        Ok(Self { lidar_address, lidar_pty, servo_pty: servo_path, head_to_world, stop, threads })
    }

    /// What an IMU on the servo base reads at rest: gravity's unit direction in that frame,
    /// for the lidar of `spec` on this head.
    pub fn gravity_mount(&self, spec: &crate::scenario::LidarSpec) -> nalgebra::Vector3<f64> {
        let mount = self.head_to_world * crate::sensor::LidarModel::from_spec(spec).mount_in_head;
        mount.rotation.inverse() * -nalgebra::Vector3::z()
    }

    /// Stops every thread.
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

impl Drop for Emulator {
    fn drop(&mut self) {
        self.shutdown();
    }
}
