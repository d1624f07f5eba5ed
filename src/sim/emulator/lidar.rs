//! An emulated UTM-30LX-EW: SCIP 2.0 over TCP or a pseudo-terminal (`VV`, `PP`, `II`, `TM0`-
//! `TM2`, `MD`/`ME` streams, `QT`, `RS`, `BM`), with the sensor's own timing (a scan every 25 ms,
//! sent when it is complete) and its own 24-bit millisecond clock (an offset, a drift, and the
//! wrap). Each scan ray-casts the scenario's world, beam by beam, with the scan plane at the
//! emulated servo's tilt at the beam's own time. It can be told to cut the connection, garble
//! bytes, answer with an error status, or fall silent.

use super::servo::SharedMotion;
use crate::scenario::LidarSpec;
use crate::sensor::scip::{codec, scan_lines};
use crate::sensor::{RayCaster, SimLidar};
use nalgebra::Isometry3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use std::io::Write;
use std::time::{Duration, Instant};

/// What can go wrong with the emulated lidar.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LidarFaults {
    /// After this many scans of a stream the connection is cut (a TCP reset, a pty hang-up).
    pub cut_after_scans: Option<usize>,
    /// Every this-many-th scan has a garbled byte (its line fails its check character).
    pub garble_every: Option<usize>,
    /// `MD`/`ME` is answered with this status (e.g. `b"50"`, hardware trouble).
    pub md_status: Option<[u8; 2]>,
    /// After this many scans of a stream nothing more is sent (the connection stays).
    pub silent_after_scans: Option<usize>,
}

/// The sensor's clock.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorClock {
    /// Its count when the emulator starts, ms.
    pub start_ms: u32,
    /// Its rate error (sensor seconds per host second, minus 1).
    pub drift: f64,
}

impl Default for SensorClock {
    fn default() -> Self {
        Self { start_ms: 1_234_567, drift: 0.0 }
    }
}

impl SensorClock {
    /// The count at host instant `t`, 24 bits.
    pub fn ms_at(&self, started: Instant, t: Instant) -> u32 {
        let elapsed = t.saturating_duration_since(started).as_secs_f64() * (1.0 + self.drift);
        ((f64::from(self.start_ms) + elapsed * 1e3).floor() as u64 % (1 << 24)) as u32
    }
}

/// The UTM-30LX-EW's figures (its `PP`): DMIN 23 mm, DMAX 60000 mm, 1440 steps a turn, steps
/// 0 to 1080 with 540 ahead, 2400 rpm.
const PP: &[(&str, &str)] = &[
    ("MODL", "UTM-30LX-EW"),
    ("DMIN", "23"),
    ("DMAX", "60000"),
    ("ARES", "1440"),
    ("AMIN", "0"),
    ("AMAX", "1080"),
    ("AFRT", "540"),
    ("SCAN", "2400"),
];

/// A stream in progress.
struct Stream {
    command: Vec<u8>,
    intensity: bool,
    remaining: Option<u32>,
    next_start: Instant,
    sent: usize,
}

/// The lidar's side of one connection.
pub struct Device<'w, C: RayCaster> {
    lidar: SimLidar<'w, C>,
    noise_sigma_m: f64,
    dropout: f64,
    motion: SharedMotion,
    clock: SensorClock,
    started: Instant,
    faults: LidarFaults,
    rng: ChaCha8Rng,
    stream: Option<Stream>,
    adjust_mode: bool,
    laser_on: bool,
    line: Vec<u8>,
}

/// What the connection should do after a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Next {
    /// Go on.
    Continue,
    /// Cut the connection (a fault).
    Cut,
}

impl<'w, C: RayCaster> Device<'w, C> {
    /// A device casting into `world`, its servo base at `head * mount` (the scenario's
    /// `[lidar]` mount), tilting with `motion`.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        world: &'w C,
        spec: &LidarSpec,
        head: &Isometry3<f64>,
        motion: SharedMotion,
        clock: SensorClock,
        started: Instant,
        faults: LidarFaults,
        seed: u64,
    ) -> Self {
        Self {
            lidar: SimLidar::new(world, spec, head, seed),
            noise_sigma_m: spec.noise_sigma_m,
            dropout: spec.dropout_probability,
            motion,
            clock,
            started,
            faults,
            rng: ChaCha8Rng::seed_from_u64(seed),
            stream: None,
            adjust_mode: false,
            laser_on: false,
            line: Vec::new(),
        }
    }

    /// When the next scan is due (for the connection's wait).
    pub fn next_due(&self) -> Option<Instant> {
        self.stream.as_ref().map(|s| s.next_start + Duration::from_millis(25))
    }

    /// Takes bytes from the host; replies are written to `out`.
    pub fn input(&mut self, bytes: &[u8], out: &mut impl Write) -> std::io::Result<()> {
        for &b in bytes {
            if b == b'\n' || b == b'\r' {
                if !self.line.is_empty() {
                    let line = std::mem::take(&mut self.line);
                    self.command(&line, out)?;
                }
            } else if self.line.len() < 256 {
                self.line.push(b);
            }
        }
        Ok(())
    }

    fn reply(out: &mut impl Write, echo: &[u8], status: &[u8; 2], lines: &[Vec<u8>]) -> std::io::Result<()> {
        let mut msg = echo.to_vec();
        msg.push(b'\n');
        msg.extend_from_slice(status);
        msg.push(codec::check_char(status));
        msg.push(b'\n');
        for l in lines {
            msg.extend_from_slice(l);
            msg.push(b'\n');
        }
        msg.push(b'\n');
        out.write_all(&msg)
    }

    fn params(pairs: &[(&str, String)]) -> Vec<Vec<u8>> {
        pairs
            .iter()
            .map(|(k, v)| {
                let body = format!("{k}:{v}");
                let mut l = body.clone().into_bytes();
                l.push(b';');
                l.push(codec::check_char(body.as_bytes()));
                l
            })
            .collect()
    }

    fn command(&mut self, cmd: &[u8], out: &mut impl Write) -> std::io::Result<()> {
        let now = Instant::now();
        let name = cmd.get(..2).unwrap_or_default();
        if self.adjust_mode && !cmd.starts_with(b"TM") {
            return Self::reply(out, cmd, b"0E", &[]);
        }
        match name {
            b"VV" => {
                let vv = [
                    ("VEND", "Hokuyo Automatic Co.,Ltd.".to_string()),
                    ("PROD", "SOKUIKI Sensor UTM-30LX-EW (stairbench emulator)".to_string()),
                    ("FIRM", "1.0.0".to_string()),
                    ("PROT", "SCIP 2.0".to_string()),
                    ("SERI", "H0000000".to_string()),
                ];
                Self::reply(out, cmd, b"00", &Self::params(&vv))
            }
            b"PP" => {
                let pp: Vec<(&str, String)> = PP.iter().map(|(k, v)| (*k, v.to_string())).collect();
                Self::reply(out, cmd, b"00", &Self::params(&pp))
            }
            b"II" => {
                let ii = [
                    ("MODL", "UTM-30LX-EW".to_string()),
                    ("LASR", if self.laser_on { "ON" } else { "OFF" }.to_string()),
                    ("SCSP", "2400".to_string()),
                    ("MESM", if self.stream.is_some() { "Measuring" } else { "Idle" }.to_string()),
                    ("SBPS", "Ethernet 100 [Mbps]".to_string()),
                    ("TIME", format!("{:06X}", self.clock.ms_at(self.started, now))),
                    ("STAT", "Stable 000 no error.".to_string()),
                ];
                Self::reply(out, cmd, b"00", &Self::params(&ii))
            }
            b"TM" => match cmd.get(2) {
                Some(b'0') => {
                    let s = if self.adjust_mode { b"02" } else { b"00" };
                    self.adjust_mode = true;
                    self.stream = None;
                    Self::reply(out, cmd, s, &[])
                }
                Some(b'1') if self.adjust_mode => {
                    let stamp = codec::encode(self.clock.ms_at(self.started, now), 4).unwrap_or_default();
                    let mut l = stamp.clone();
                    l.push(codec::check_char(&stamp));
                    Self::reply(out, cmd, b"00", &[l])
                }
                Some(b'1') => Self::reply(out, cmd, b"04", &[]),
                Some(b'2') => {
                    let s = if self.adjust_mode { b"00" } else { b"03" };
                    self.adjust_mode = false;
                    Self::reply(out, cmd, s, &[])
                }
                _ => Self::reply(out, cmd, b"01", &[]),
            },
            b"MD" | b"ME" => {
                if let Some(s) = self.faults.md_status {
                    return Self::reply(out, cmd, &s, &[]);
                }
                let digits = |r: std::ops::Range<usize>| {
                    cmd.get(r).and_then(|d| std::str::from_utf8(d).ok()).and_then(|d| d.parse::<u32>().ok())
                };
                let (Some(first), Some(last), Some(_cluster), Some(_skip), Some(scans)) =
                    (digits(2..6), digits(6..10), digits(10..12), digits(12..13), digits(13..15))
                else {
                    return Self::reply(out, cmd, b"0C", &[]);
                };
                if first != 0 || last != 1080 {
                    return Self::reply(out, cmd, b"04", &[]);
                }
                self.laser_on = true;
                self.stream = Some(Stream {
                    command: cmd[..15].to_vec(),
                    intensity: name == b"ME",
                    remaining: (scans > 0).then_some(scans),
                    next_start: now,
                    sent: 0,
                });
                Self::reply(out, cmd, b"00", &[])
            }
            b"QT" => {
                self.stream = None;
                self.laser_on = false;
                Self::reply(out, cmd, b"00", &[])
            }
            b"BM" => {
                let s = if self.laser_on { b"02" } else { b"00" };
                self.laser_on = true;
                Self::reply(out, cmd, s, &[])
            }
            b"RS" => {
                self.stream = None;
                self.laser_on = false;
                self.adjust_mode = false;
                self.started = now;
                Self::reply(out, cmd, b"00", &[])
            }
            _ => Self::reply(out, cmd, b"0D", &[]),
        }
    }

    /// Sends the scans that are due by now.
    pub fn tick(&mut self, out: &mut impl Write) -> std::io::Result<Next> {
        let now = Instant::now();
        while let Some(s) = self.stream.as_ref() {
            let end = s.next_start + Duration::from_millis(25);
            if end > now {
                break;
            }
            let start = s.next_start;
            let sent = s.sent;
            if self.faults.cut_after_scans.is_some_and(|n| sent >= n) {
                return Ok(Next::Cut);
            }
            let silent = self.faults.silent_after_scans.is_some_and(|n| sent >= n);
            let msg = self.scan(start);
            let Some(s) = self.stream.as_mut() else { break };
            s.next_start = end;
            s.sent += 1;
            if let Some(r) = s.remaining.as_mut() {
                *r = r.saturating_sub(1);
                if *r == 0 {
                    self.stream = None;
                }
            }
            if !silent {
                out.write_all(&msg)?;
            }
        }
        Ok(Next::Continue)
    }

    /// The message of the scan that started at `start`.
    fn scan(&mut self, start: Instant) -> Vec<u8> {
        let step_s = 60.0 / (2400.0 * 1440.0);
        let tilts: Vec<f64> = match self.motion.lock() {
            Ok(m) => {
                (0..1081).map(|i| m.tilt_at(start + Duration::from_secs_f64(step_s * i as f64))).collect()
            }
            Err(_) => vec![0.0; 1081],
        };
        let hits = self.lidar.hits_at(&|i| tilts[i]);
        let noise = Normal::new(0.0, self.noise_sigma_m).ok().filter(|_| self.noise_sigma_m > 0.0);
        let Some(s) = self.stream.as_ref() else { return Vec::new() };
        let intensity = s.intensity;
        let mut echo = s.command.clone();
        let remaining = s.remaining.map_or(0, |r| r.saturating_sub(1));
        echo.truncate(13);
        echo.extend(format!("{:02}", remaining.min(99)).bytes());
        let sent = s.sent;
        let values: Vec<(u32, Option<u32>)> = hits
            .iter()
            .map(|h| {
                let mut r = h.map_or(f64::NAN, |h| h.distance_m);
                if let Some(n) = &noise {
                    r += n.sample(&mut self.rng);
                }
                let dropped = self.dropout > 0.0 && self.rng.random::<f64>() < self.dropout;
                let mm = (r * 1e3).round();
                // The UTM-30LX's codes below DMIN: 1, no object in range.
                let value = if !mm.is_finite() || dropped || !(23.0..=60_000.0).contains(&mm) {
                    1
                } else {
                    mm as u32
                };
                (value, intensity.then_some(if value > 22 { 1000 } else { 0 }))
            })
            .collect();
        let mut lines = scan_lines(self.clock.ms_at(self.started, start), &values);
        if self.faults.garble_every.is_some_and(|n| n > 0 && (sent + 1) % n == 0) {
            if let Some(l) = lines.get_mut(3) {
                l[5] = if l[5] == b'0' { b'1' } else { b'0' };
            }
        }
        let mut msg = echo;
        msg.extend_from_slice(b"\n99b\n");
        for l in &lines {
            msg.extend_from_slice(l);
            msg.push(b'\n');
        }
        msg.push(b'\n');
        msg
    }
}
