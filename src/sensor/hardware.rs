//! The real sensor head as a [`Source`]: the Hokuyo lidar (SCIP 2.0, [`super::scip`]) and the
//! Dynamixel MX-64 tilting it ([`super::dynamixel`]), configured by a hardware file. A sweep
//! moves the servo to its start, starts the lidar's stream, sweeps the servo at its set speed
//! while a second thread reads its position as fast as the bus allows (each reading stamped on
//! the host's clock), and gives every row the tilt interpolated at the row's own time on the
//! same clock (the lidar's stamps related to the host's by its `TM` exchanges). Assembly then
//! fits each beam's tilt from the rows' readings, as for simulated rows.
//!
//! Gravity comes from the configuration (an IMU's reading, the robot standing still, §4.1);
//! the head's pose from the caller (the robot model standing in half-sitting, a tripod's):
//! assembly levels the cloud by the gravity, so a pose known roughly still gives a level one.

use super::clock;
use super::dynamixel::{Servo, ServoConfig};
use super::scip::{Lidar, LidarConfig};
use super::{LidarModel, ScanRow, SensorError, Source, Sweep};
use crate::cancel::Cancel;
use crate::scenario::LidarSpec;
use nalgebra::{Isometry3, Vector3};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// The sweep, as a scenario's `[lidar]` has it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SweepConfig {
    /// Tilt at the start, degrees (positive pitches the scan plane down).
    pub tilt_start_deg: f64,
    /// Tilt at the end, degrees.
    pub tilt_end_deg: f64,
    /// Servo speed during the sweep, degrees per second.
    pub tilt_speed_dps: f64,
    /// Servo speed moving to the start, degrees per second.
    pub return_speed_dps: f64,
}

impl Default for SweepConfig {
    fn default() -> Self {
        let l = LidarSpec::default();
        Self {
            tilt_start_deg: l.tilt_start_deg,
            tilt_end_deg: l.tilt_end_deg,
            tilt_speed_dps: l.tilt_speed_dps,
            return_speed_dps: l.tilt_return_speed_dps,
        }
    }
}

/// Where the servo sits on the head, as a scenario's `[lidar]` has it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MountConfig {
    /// Servo tilt axis origin in the head frame, metres.
    pub mount_xyz_m: [f64; 3],
    /// Servo base orientation in the head frame (roll, pitch, yaw), degrees.
    pub mount_rpy_deg: [f64; 3],
    /// Scanner optical centre from the tilt axis, in the tilted frame, metres.
    pub axis_to_optical_m: [f64; 3],
}

impl Default for MountConfig {
    fn default() -> Self {
        let l = LidarSpec::default();
        Self {
            mount_xyz_m: l.mount_xyz_m,
            mount_rpy_deg: l.mount_rpy_deg,
            axis_to_optical_m: l.axis_to_optical_m,
        }
    }
}

/// Gravity at rest.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GravityConfig {
    /// Gravity's direction in the servo base frame, robot standing still (an IMU's reading);
    /// left out, it is the one of the robot standing in half-sitting (the chest pitched 8 deg
    /// forward tilts the head, so it is not straight down the mount's -z).
    pub mount: Option<[f64; 3]>,
}

/// A hardware file.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HardwareConfig {
    /// The lidar.
    pub lidar: LidarConfig,
    /// The servo.
    pub servo: ServoConfig,
    /// The sweep.
    pub sweep: SweepConfig,
    /// The mount.
    pub mount: MountConfig,
    /// Gravity.
    pub gravity: GravityConfig,
}

impl HardwareConfig {
    /// Reads a hardware file; errors name the field and line.
    pub fn load(path: &std::path::Path) -> Result<Self, SensorError> {
        let origin = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| SensorError::Config {
            origin: origin.clone(),
            line: None,
            message: e.to_string(),
        })?;
        Self::parse(&text, &origin)
    }

    /// Reads a hardware file's text.
    pub fn parse(text: &str, origin: &str) -> Result<Self, SensorError> {
        let cfg: Self = toml::from_str(text).map_err(|e| SensorError::Config {
            origin: origin.into(),
            line: e
                .span()
                .map(|s| text[..s.start.min(text.len())].bytes().filter(|&b| b == b'\n').count() + 1),
            message: e.message().trim().to_string(),
        })?;
        let bad = |message: String| Err(SensorError::Config { origin: origin.into(), line: None, message });
        if cfg.lidar.address.is_none() && cfg.lidar.serial.is_none() {
            return bad("[lidar] needs `address` (TCP host:port) or `serial` (a port)".into());
        }
        if cfg.servo.direction != 1 && cfg.servo.direction != -1 {
            return bad(format!("`servo.direction` must be 1 or -1, got {}", cfg.servo.direction));
        }
        if cfg.servo.ticks_per_rev < 4 {
            return bad(format!("`servo.ticks_per_rev` must be at least 4, got {}", cfg.servo.ticks_per_rev));
        }
        if !(cfg.sweep.tilt_speed_dps > 0.0 && cfg.sweep.return_speed_dps > 0.0) {
            return bad("`sweep.tilt_speed_dps` and `sweep.return_speed_dps` must be positive".into());
        }
        if cfg.sweep.tilt_start_deg == cfg.sweep.tilt_end_deg {
            return bad("`sweep.tilt_end_deg` must differ from `tilt_start_deg`".into());
        }
        if let Some(g) = cfg.gravity.mount.map(Vector3::from) {
            if !(g.norm() > 1e-6 && g.iter().all(|v| v.is_finite())) {
                return bad("`gravity.mount` must be a non-zero direction".into());
            }
        }
        Ok(cfg)
    }

    /// The lidar model: the UTM-30LX-EW's figures with this file's sweep and mount.
    pub fn lidar_spec(&self) -> LidarSpec {
        LidarSpec {
            tilt_start_deg: self.sweep.tilt_start_deg,
            tilt_end_deg: self.sweep.tilt_end_deg,
            tilt_speed_dps: self.sweep.tilt_speed_dps,
            tilt_return_speed_dps: self.sweep.return_speed_dps,
            servo_ticks_per_rev: self.servo.ticks_per_rev,
            mount_xyz_m: self.mount.mount_xyz_m,
            mount_rpy_deg: self.mount.mount_rpy_deg,
            axis_to_optical_m: self.mount.axis_to_optical_m,
            ..LidarSpec::default()
        }
    }
}

/// The sensor head.
pub struct HardwareSource {
    cfg: HardwareConfig,
    model: LidarModel,
    lidar: Option<Lidar>,
    servo: Option<Servo>,
    head_to_world: Isometry3<f64>,
    log: fn(&str),
    last: Option<SweepStats>,
}

/// How the drivers kept up during the last sweep's streaming (from the lidar's start to the
/// servo's arrival at the end of the sweep).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweepStats {
    /// Scans received from the lidar.
    pub scans: usize,
    /// Positions read from the servo.
    pub readings: usize,
    /// Wall time the streaming took, seconds.
    pub streaming_s: f64,
    /// CPU time of the thread reading the servo, seconds.
    pub servo_cpu_s: f64,
    /// CPU time of the thread reading the lidar, seconds.
    pub lidar_cpu_s: f64,
    /// Servo replies whose checksum failed, each asked for again.
    pub servo_corrupt_replies: usize,
}

/// A servo reading: host time and tilt, seconds and radians.
type Reading = (f64, f64);

/// The tilt at host time `t_s`, linearly between the readings around it (`None` outside).
pub fn tilt_at(readings: &[Reading], t_s: f64) -> Option<f64> {
    let k = readings.partition_point(|r| r.0 <= t_s);
    if k == 0 || k >= readings.len() {
        return None;
    }
    let (a, b) = (readings[k - 1], readings[k]);
    let f = if b.0 > a.0 { (t_s - a.0) / (b.0 - a.0) } else { 0.0 };
    Some(a.1 + (b.1 - a.1) * f)
}

impl HardwareSource {
    /// The head of `cfg`, mounted on a head at `head_to_world` (the robot's head frame in the
    /// world); connects nothing yet (the first sweep does).
    pub fn new(cfg: &HardwareConfig, head_to_world: Isometry3<f64>, log: fn(&str)) -> Self {
        let model = LidarModel::from_spec(&cfg.lidar_spec());
        Self { cfg: cfg.clone(), model, lidar: None, servo: None, head_to_world, log, last: None }
    }

    /// How the drivers kept up during the last sweep (`None` before one streamed).
    pub fn last_stats(&self) -> Option<SweepStats> {
        self.last
    }

    /// The lidar model in use.
    pub fn model(&self) -> &LidarModel {
        &self.model
    }

    /// The lidar, connected (and its identity logged) if it was not.
    fn lidar(&mut self) -> Result<&mut Lidar, SensorError> {
        if self.lidar.is_none() {
            let l = Lidar::open(&self.cfg.lidar, &self.model, self.log)?;
            (self.log)(&format!(
                "lidar: {} {} on {}; clock offset known to {:.3} ms",
                l.identity.get("PROD").map(String::as_str).unwrap_or(&l.params.model),
                l.identity.get("FIRM").map(String::as_str).unwrap_or(""),
                l.describe(),
                l.clock().map_or(f64::NAN, |c| c.round_trip_s * 500.0)
            ));
            self.lidar = Some(l);
        }
        self.lidar.as_mut().ok_or_else(|| SensorError::Config {
            origin: "lidar".into(),
            line: None,
            message: "not connected".into(),
        })
    }

    fn servo(&mut self) -> Result<&mut Servo, SensorError> {
        if self.servo.is_none() {
            let s = Servo::open(&self.cfg.servo)?;
            (self.log)(&format!("servo: MX-64 (model {}) on {}", s.model, self.cfg.servo.serial));
            self.servo = Some(s);
        }
        self.servo.as_mut().ok_or_else(|| SensorError::Config {
            origin: "servo".into(),
            line: None,
            message: "not connected".into(),
        })
    }

    /// The servo moved to `tilt_rad` and settled there (within two ticks), or an error.
    fn go_to(&mut self, tilt_rad: f64, speed_rad_s: f64, cancel: &Cancel) -> Result<(), SensorError> {
        let servo = self.servo()?;
        servo.move_to(tilt_rad, speed_rad_s)?;
        let tick = std::f64::consts::TAU / f64::from(self.cfg.servo.ticks_per_rev);
        let limit = Instant::now()
            + Duration::from_secs_f64(5.0 + 2.0 * std::f64::consts::PI / speed_rad_s.max(1e-3));
        loop {
            let (t, _) = self.servo()?.tilt()?;
            if (t - tilt_rad).abs() <= 2.0 * tick {
                return Ok(());
            }
            if cancel.is_cancelled() {
                return Err(SensorError::Cancelled { rows: 0 });
            }
            if Instant::now() > limit {
                return Err(SensorError::Config {
                    origin: "servo".into(),
                    line: None,
                    message: format!(
                        "the servo did not reach {:.1} deg (at {:.1} deg)",
                        tilt_rad.to_degrees(),
                        t.to_degrees()
                    ),
                });
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    /// The rows of `scans` (host stamp, ranges) that fall while the servo moved, each with the
    /// tilt of the readings at its stamp.
    fn rows(&self, scans: &[(f64, Vec<f32>)], readings: &[Reading]) -> Vec<ScanRow> {
        let mount_to_world = self.head_to_world * self.model.mount_in_head;
        let g = match self.cfg.gravity.mount {
            Some(g) => Vector3::from(g).normalize(),
            None => mount_to_world.rotation.inverse() * -Vector3::z(),
        };
        let (a, b) = (self.cfg.sweep.tilt_start_deg.to_radians(), self.cfg.sweep.tilt_end_deg.to_radians());
        let (lo, hi) = (a.min(b), a.max(b));
        scans
            .iter()
            .filter_map(|(t, ranges)| {
                let tilt = tilt_at(readings, *t)?;
                (tilt >= lo - 1e-3 && tilt <= hi + 1e-3).then(|| ScanRow {
                    stamp_s: *t,
                    tilt_rad: tilt,
                    ranges_m: ranges.clone(),
                    gravity_mount: g,
                    mount_to_world: None,
                })
            })
            .collect()
    }

    fn sweep_of(&self, rows: Vec<ScanRow>) -> Sweep {
        Sweep {
            rows,
            lidar: self.model.clone(),
            mount_to_world: self.head_to_world * self.model.mount_in_head,
        }
    }

    /// Stops the lidar's stream and drops a connection that failed, so the next sweep makes a
    /// new one.
    fn after_error(&mut self, lost_lidar: bool, lost_servo: bool) {
        if let Some(l) = self.lidar.as_mut() {
            let _ = l.stop();
        }
        if lost_lidar {
            self.lidar = None;
        }
        if lost_servo {
            self.servo = None;
        }
    }
}

impl Source for HardwareSource {
    fn sweep(
        &mut self,
        cancel: &Cancel,
        on_rows: &mut dyn FnMut(usize, usize),
    ) -> Result<Sweep, SensorError> {
        let corrupt_before = self.servo.as_ref().map_or(0, Servo::corrupt_replies);
        let (start, end) =
            (self.cfg.sweep.tilt_start_deg.to_radians(), self.cfg.sweep.tilt_end_deg.to_radians());
        let speed = self.cfg.sweep.tilt_speed_dps.to_radians();
        let expected_rows = ((end - start).abs() / speed / self.model.row_period_s()).round() as usize;
        self.go_to(start, self.cfg.sweep.return_speed_dps.to_radians(), cancel)?;
        // The clock relation is renewed before each sweep (its drift from the last one).
        let lidar = self.lidar()?;
        lidar.sync_clock()?;
        lidar.start()?;
        if let Err(e) = self.servo()?.move_to(end, speed) {
            self.after_error(false, true);
            return Err(e.into());
        }
        let tick = std::f64::consts::TAU / f64::from(self.cfg.servo.ticks_per_rev);
        let readings: Mutex<Vec<Reading>> = Mutex::new(Vec::new());
        let done = AtomicBool::new(false);
        let mut servo = self.servo.take();
        let mut lidar = self.lidar.take();
        let model = self.model.clone();
        let limit_s = (end - start).abs() / speed * 1.5 + 2.0;
        let streaming = Instant::now();
        let (servo_result, lidar_result) = std::thread::scope(|scope| {
            let reader = scope.spawn(|| {
                let cpu0_s = clock::thread_cpu_s();
                let mut read = || {
                    let Some(s) = servo.as_mut() else { return Ok(()) };
                    let started = Instant::now();
                    let mut at_end = 0;
                    while !done.load(Ordering::Relaxed) {
                        let (tilt, t) = s.tilt()?;
                        if let Ok(mut r) = readings.lock() {
                            r.push((t, tilt));
                        }
                        at_end = if (tilt - end).abs() <= tick { at_end + 1 } else { 0 };
                        if at_end >= 3 || started.elapsed().as_secs_f64() > limit_s {
                            break;
                        }
                    }
                    Ok::<(), super::dynamixel::ServoError>(())
                };
                let result = read();
                // However the servo's side ended (its end reached, an error), the lidar's stops.
                done.store(true, Ordering::Relaxed);
                (result, clock::thread_cpu_s() - cpu0_s)
            });
            let cpu0_s = clock::thread_cpu_s();
            let mut scans: Vec<(f64, Vec<f32>)> = Vec::new();
            let mut failure: Option<String> = None;
            let mut last_timeout: Option<String> = None;
            if let Some(l) = lidar.as_mut() {
                while !done.load(Ordering::Relaxed) {
                    if cancel.is_cancelled() {
                        failure = Some("cancelled".into());
                        break;
                    }
                    match l.next_scan() {
                        Ok((scan, t)) => {
                            scans.push((t, scan.ranges_m(&l.params, &model)));
                            on_rows(scans.len(), expected_rows);
                        }
                        Err(e) if e.link_lost() || l.should_reconnect() => {
                            failure = Some(format!("scan {} of the stream: {e}", scans.len() + 1));
                            break;
                        }
                        Err(e) => {
                            let timed_out = matches!(e, super::scip::LidarError::Timeout { .. });
                            last_timeout =
                                timed_out.then(|| format!("scan {} of the stream: {e}", scans.len() + 1));
                        }
                    }
                }
                // The servo finished while the lidar had stopped sending: the rows stop short.
                if failure.is_none() && l.errors_in_a_row() > 0 {
                    failure = last_timeout.take();
                }
            }
            done.store(true, Ordering::Relaxed);
            let lidar_cpu_s = clock::thread_cpu_s() - cpu0_s;
            let servo_result = reader.join().unwrap_or((Ok(()), f64::NAN));
            (servo_result, (scans, failure, lidar_cpu_s))
        });
        let streaming_s = streaming.elapsed().as_secs_f64();
        self.servo = servo;
        self.lidar = lidar;
        let ((servo_result, servo_cpu_s), (scans, lidar_failure, lidar_cpu_s)) = (servo_result, lidar_result);
        let readings = readings.into_inner().unwrap_or_default();
        self.last = Some(SweepStats {
            scans: scans.len(),
            readings: readings.len(),
            streaming_s,
            servo_cpu_s,
            lidar_cpu_s,
            servo_corrupt_replies: self
                .servo
                .as_ref()
                .map_or(0, Servo::corrupt_replies)
                .saturating_sub(corrupt_before),
        });
        let rows = self.rows(&scans, &readings);
        let why = match (servo_result, lidar_failure) {
            (Err(e), _) => Some((format!("servo: {e}"), false, true)),
            (Ok(()), Some(w)) => Some((format!("lidar: {w}"), true, false)),
            (Ok(()), None) => None,
        };
        if let Some((why, lost_lidar, lost_servo)) = why {
            self.after_error(lost_lidar, lost_servo);
            (self.log)(&format!("sweep cut after {} rows: {why}", rows.len()));
            if cancel.is_cancelled() {
                return Err(SensorError::Cancelled { rows: rows.len() });
            }
            return Err(SensorError::Cut { partial: Box::new(self.sweep_of(rows)), why });
        }
        if let Some(l) = self.lidar.as_mut() {
            if let Err(e) = l.stop() {
                (self.log)(&format!("lidar: stopping the stream: {e}"));
                self.lidar = None;
            }
        }
        Ok(self.sweep_of(rows))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_hardware_file_reads_and_wrong_ones_name_the_field() {
        let text = "[lidar]\naddress = \"127.0.0.1:10940\"\n[servo]\nserial = \"/dev/ttyUSB0\"\nbaud = 1000000\nid = 1\nprotocol = 2\nzero_tick = 2048\nticks_per_rev = 4096\ndirection = -1\n[sweep]\ntilt_start_deg = 5.0\ntilt_end_deg = 65.0\ntilt_speed_dps = 20.0\n[gravity]\nmount = [0.0, 0.0, -1.0]\n";
        assert!(HardwareConfig::parse("[gravity]\nmount = [0.0, 0.0, 0.0]\n", "hw.toml").is_err());
        let c = HardwareConfig::parse(text, "hw.toml").expect("valid");
        assert_eq!(c.servo.protocol, crate::sensor::dynamixel::Protocol::Two);
        assert_eq!(c.lidar_spec().tilt_speed_dps, 20.0);
        let e =
            HardwareConfig::parse("[servo]\nprotocol = 3\n", "hw.toml").expect_err("protocol 3").to_string();
        assert!(e.contains("hw.toml:2") && e.contains("1 or 2"), "{e}");
        let e = HardwareConfig::parse("[lidar]\nadress = \"x\"\n", "hw.toml").expect_err("typo").to_string();
        assert!(e.contains("hw.toml:2") && e.contains("adress"), "{e}");
        let e =
            HardwareConfig::parse("[servo]\ndirection = 2\n", "hw.toml").expect_err("direction").to_string();
        assert!(e.contains("servo.direction"), "{e}");
    }

    #[test]
    fn a_rows_tilt_is_interpolated_at_its_own_time() {
        let readings = vec![(1.0, 0.10), (1.002, 0.1004), (1.004, 0.1008)];
        assert!((tilt_at(&readings, 1.001).expect("inside") - 0.1002).abs() < 1e-12);
        assert_eq!(tilt_at(&readings, 0.5), None);
        assert_eq!(tilt_at(&readings, 2.0), None);
    }
}
