//! The SCIP 2.0 driver: it connects (TCP or serial), identifies the sensor (`VV`, `PP`, `II`)
//! and checks its geometry against the configured lidar model, relates the sensor's clock to
//! the host's (`TM0`, `TM1` several times, `TM2`), streams scans (`MD`, or `ME` with
//! intensities) and stops them (`QT`). A reply's status other than `00`/`99` is an error with
//! its meaning; a run of bad replies or timeouts is for the caller to answer with
//! [`Lidar::reconnect`], which retries with a growing delay and says so in the log.

use super::message::{status_meaning, Message, MessageError, Reader};
use super::{key_values, ReplyError, Scan, SensorParams};
use crate::sensor::clock::{host_now_s, ClockError, ClockSync, Exchange};
use crate::sensor::link::{Link, SerialLink, TcpLink};
use crate::sensor::LidarModel;
use std::collections::BTreeMap;
use std::io::ErrorKind;
use std::time::{Duration, Instant};

/// How to reach the lidar and how patient to be with it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LidarConfig {
    /// TCP address `host:port` (the UTM-30LX-EW: factory 192.168.0.10:10940).
    pub address: Option<String>,
    /// Serial port (the USB models: UTM-30LX, URG-04LX), instead of `address`.
    pub serial: Option<String>,
    /// Serial baud rate (a USB CDC port ignores it).
    pub baud: u32,
    /// Stream ranges and intensities (`ME`) instead of ranges (`MD`).
    pub intensity: bool,
    /// Longest wait for a reply, seconds.
    pub reply_timeout_s: f64,
    /// Bad replies or timeouts in a row before the caller should reconnect.
    pub error_limit: usize,
    /// Connection attempts before giving up, the delay doubling from `retry_delay_s`.
    pub connect_tries: usize,
    /// First delay between connection attempts, seconds.
    pub retry_delay_s: f64,
    /// `TM1` exchanges per clock synchronization.
    pub time_exchanges: usize,
}

impl Default for LidarConfig {
    fn default() -> Self {
        Self {
            address: Some("192.168.0.10:10940".into()),
            serial: None,
            baud: 115_200,
            intensity: false,
            reply_timeout_s: 0.5,
            error_limit: 4,
            connect_tries: 4,
            retry_delay_s: 0.5,
            time_exchanges: 20,
        }
    }
}

impl LidarConfig {
    /// Where the lidar is, for messages.
    pub fn describe(&self) -> String {
        match (&self.serial, &self.address) {
            (Some(s), _) => format!("serial {s}"),
            (None, Some(a)) => format!("tcp {a}"),
            (None, None) => "no address".into(),
        }
    }
}

/// Why the lidar failed.
#[derive(Debug, thiserror::Error)]
pub enum LidarError {
    /// No connection after every try.
    #[error("no connection to the lidar at {link} after {tries} tries: {source}")]
    Connect {
        /// Where.
        link: String,
        /// How many tries.
        tries: usize,
        /// The last failure.
        source: std::io::Error,
    },
    /// The configuration names no link.
    #[error("the lidar configuration has neither `address` nor `serial`")]
    NoLink,
    /// The link failed (unplugged, reset).
    #[error("the link to the lidar ({link}) failed: {source}")]
    Io {
        /// Where.
        link: String,
        /// Why.
        source: std::io::Error,
    },
    /// No reply in time.
    #[error("the lidar at {link} did not answer `{waiting_for}` within {timeout_s} s")]
    Timeout {
        /// Where.
        link: String,
        /// The command waited on.
        waiting_for: String,
        /// How long.
        timeout_s: f64,
    },
    /// A reply could not be read (a garbled byte, a broken stream).
    #[error(transparent)]
    Message(#[from] MessageError),
    /// A status of error.
    #[error("the lidar answered `{command}` with status {status}: {meaning}")]
    Status {
        /// The command.
        command: String,
        /// The status.
        status: String,
        /// What it means.
        meaning: &'static str,
    },
    /// A reply that does not fit (the wrong sensor, a malformed scan).
    #[error(transparent)]
    Reply(#[from] ReplyError),
    /// The clock exchanges.
    #[error(transparent)]
    Clock(#[from] ClockError),
}

impl LidarError {
    /// Whether the link itself is gone (a reconnection, not a retry, can help).
    pub fn link_lost(&self) -> bool {
        matches!(self, LidarError::Io { .. })
    }
}

/// A connected lidar.
pub struct Lidar {
    link: Box<dyn Link>,
    cfg: LidarConfig,
    reader: Reader,
    buf: Vec<u8>,
    /// Geometry from `PP`.
    pub params: SensorParams,
    /// Identity from `VV` (vendor, product, firmware, protocol, serial).
    pub identity: BTreeMap<String, String>,
    /// State from `II` (laser, motor speed, status).
    pub state: BTreeMap<String, String>,
    clock: Option<ClockSync>,
    streaming: bool,
    errors_in_a_row: usize,
    log: fn(&str),
}

fn open_link(cfg: &LidarConfig) -> Result<Box<dyn Link>, std::io::Error> {
    let timeout = Duration::from_secs_f64(cfg.reply_timeout_s.max(0.05) * 4.0);
    match (&cfg.serial, &cfg.address) {
        (Some(path), _) => Ok(Box::new(SerialLink::open(path, cfg.baud).map_err(std::io::Error::other)?)),
        (None, Some(address)) => Ok(Box::new(TcpLink::connect(address, timeout)?)),
        (None, None) => Err(std::io::Error::new(ErrorKind::InvalidInput, "no address")),
    }
}

/// Connects, retrying with a doubling delay, logging each failure.
fn connect(cfg: &LidarConfig, log: fn(&str)) -> Result<Box<dyn Link>, LidarError> {
    if cfg.serial.is_none() && cfg.address.is_none() {
        return Err(LidarError::NoLink);
    }
    let mut delay = cfg.retry_delay_s.max(0.0);
    let tries = cfg.connect_tries.max(1);
    let mut last = None;
    for k in 1..=tries {
        match open_link(cfg) {
            Ok(l) => return Ok(l),
            Err(e) => {
                log(&format!("lidar: connecting to {} failed ({e}), try {k} of {tries}", cfg.describe()));
                last = Some(e);
            }
        }
        if k < tries {
            std::thread::sleep(Duration::from_secs_f64(delay));
            delay *= 2.0;
        }
    }
    let source = last.unwrap_or_else(|| std::io::Error::other("no attempt"));
    Err(LidarError::Connect { link: cfg.describe(), tries, source })
}

impl Lidar {
    /// Connects to the lidar of `cfg`, identifies it and checks it against `model`, and
    /// relates its clock to the host's. `log` receives what an operator should see
    /// (reconnections, skipped replies).
    pub fn open(cfg: &LidarConfig, model: &LidarModel, log: fn(&str)) -> Result<Self, LidarError> {
        let link = connect(cfg, log)?;
        let mut lidar = Self {
            link,
            cfg: cfg.clone(),
            reader: Reader::new(),
            buf: vec![0; 16 * 1024],
            params: SensorParams {
                model: String::new(),
                dmin_mm: 0,
                dmax_mm: 0,
                ares: 1,
                amin: 0,
                amax: 0,
                afrt: 0,
                scan_rpm: 1,
            },
            identity: BTreeMap::new(),
            state: BTreeMap::new(),
            clock: None,
            streaming: false,
            errors_in_a_row: 0,
            log,
        };
        lidar.handshake(model)?;
        lidar.sync_clock()?;
        Ok(lidar)
    }

    /// The link, for messages.
    pub fn describe(&self) -> String {
        self.link.describe()
    }

    /// Stops any stream left from before, then `VV`, `PP` (checked against `model`), `II`.
    fn handshake(&mut self, model: &LidarModel) -> Result<(), LidarError> {
        // A sensor still streaming (or in time-adjust mode) is brought back to rest; its reply
        // may be buried in scans or be an error, which is fine here.
        let _ = self.send("QT");
        let _ = self.await_echo("QT", self.cfg.reply_timeout_s);
        let _ = self.send("TM2");
        let _ = self.await_echo("TM2", self.cfg.reply_timeout_s);
        self.reader.clear();
        self.streaming = false;
        self.identity = key_values(&self.request("VV")?);
        let pp = self.request("PP")?;
        self.params = SensorParams::from_pp(&pp)?;
        self.params.check(model)?;
        self.state = key_values(&self.request("II")?);
        Ok(())
    }

    fn send(&mut self, command: &str) -> Result<(), LidarError> {
        let link = self.link.describe();
        self.link.send(format!("{command}\n").as_bytes()).map_err(|source| LidarError::Io { link, source })
    }

    /// The next reply, waiting until `deadline`.
    fn next_reply(&mut self, deadline: Instant, waiting_for: &str) -> Result<Message, LidarError> {
        loop {
            if let Some(m) = self.reader.next_message() {
                return Ok(m?);
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(LidarError::Timeout {
                    link: self.link.describe(),
                    waiting_for: waiting_for.into(),
                    timeout_s: self.cfg.reply_timeout_s,
                });
            }
            match self.link.receive(&mut self.buf, left) {
                Ok(n) => self.reader.push(&self.buf[..n]),
                Err(e) if e.kind() == ErrorKind::TimedOut => {}
                Err(source) => return Err(LidarError::Io { link: self.link.describe(), source }),
            }
        }
    }

    /// The reply to `command`, skipping other replies (streamed scans) before it.
    fn await_echo(&mut self, command: &str, timeout_s: f64) -> Result<Message, LidarError> {
        let deadline = Instant::now() + Duration::from_secs_f64(timeout_s.max(0.0));
        loop {
            match self.next_reply(deadline, command) {
                Ok(m) if m.echo.starts_with(command.as_bytes()) => return Ok(m),
                Ok(_) | Err(LidarError::Message(_)) => continue,
                Err(e) => return Err(e),
            }
        }
    }

    /// Sends `command` and returns its reply, which must have status `00`.
    pub fn request(&mut self, command: &str) -> Result<Message, LidarError> {
        self.send(command)?;
        let m = self.await_echo(command, self.cfg.reply_timeout_s)?;
        if &m.status != b"00" {
            return Err(LidarError::Status {
                command: command.into(),
                status: m.status_text(),
                meaning: status_meaning(command.as_bytes(), m.status),
            });
        }
        Ok(m)
    }

    /// Relates the sensor's clock to the host's: `TM0`, `TM1` x n (each timed on the host's
    /// clock), `TM2`. The first batch gives the offset; later ones refine it and the drift.
    pub fn sync_clock(&mut self) -> Result<(), LidarError> {
        self.request("TM0")?;
        let mut exchanges = Vec::new();
        let result = (|| {
            for _ in 0..self.cfg.time_exchanges.max(2) {
                let sent_s = host_now_s();
                let m = self.request("TM1")?;
                let received_s = host_now_s();
                let line = m.lines.first().ok_or(ReplyError::NoStamp)?;
                let sensor_ms = (line.len() == 4)
                    .then(|| super::codec::decode(line))
                    .flatten()
                    .ok_or(ReplyError::NoStamp)?;
                exchanges.push(Exchange { sent_s, sensor_ms, received_s });
            }
            Ok::<(), LidarError>(())
        })();
        // Time-adjust mode is left whatever happened (the sensor takes no other command in it).
        let left = self.request("TM2");
        result?;
        left?;
        match &mut self.clock {
            Some(c) => c.refine(&exchanges)?,
            None => self.clock = Some(ClockSync::fit(&exchanges)?),
        }
        Ok(())
    }

    /// The clock relation in use.
    pub fn clock(&self) -> Option<&ClockSync> {
        self.clock.as_ref()
    }

    /// Starts the stream of scans over every step (`MD`, or `ME`), endless until [`Lidar::stop`].
    pub fn start(&mut self) -> Result<(), LidarError> {
        let cmd = if self.cfg.intensity { "ME" } else { "MD" };
        let command = format!("{cmd}{:04}{:04}01000", self.params.amin, self.params.amax);
        self.request(&command)?;
        self.streaming = true;
        self.errors_in_a_row = 0;
        Ok(())
    }

    /// The next scan of the stream and its first step's host time, seconds. A bad reply or a
    /// timeout is an error; `errors_in_a_row` counts them until a good scan.
    pub fn next_scan(&mut self) -> Result<(Scan, f64), LidarError> {
        let wait = self.cfg.reply_timeout_s.max(4.0 * self.params.scan_period_s());
        let deadline = Instant::now() + Duration::from_secs_f64(wait);
        let result = loop {
            match self.next_reply(deadline, "the next scan") {
                Ok(m) if &m.status == b"99" => {
                    break Scan::from_message(&m, self.cfg.intensity).map_err(LidarError::from)
                }
                Ok(m) if &m.status == b"00" => continue,
                Ok(m) => {
                    break Err(LidarError::Status {
                        command: m.echo_text(),
                        status: m.status_text(),
                        meaning: status_meaning(&m.echo, m.status),
                    })
                }
                Err(e) => break Err(e),
            }
        };
        match result {
            Ok(scan) => {
                self.errors_in_a_row = 0;
                let host_s = self.clock.as_mut().map_or_else(host_now_s, |c| c.host_s(scan.stamp_ms));
                Ok((scan, host_s))
            }
            Err(e) => {
                self.errors_in_a_row += 1;
                (self.log)(&format!("lidar: {e} ({} in a row)", self.errors_in_a_row));
                Err(e)
            }
        }
    }

    /// Bad replies or timeouts since the last good scan.
    pub fn errors_in_a_row(&self) -> usize {
        self.errors_in_a_row
    }

    /// Whether that run of errors calls for a reconnection.
    pub fn should_reconnect(&self) -> bool {
        self.errors_in_a_row > self.cfg.error_limit
    }

    /// Stops the stream (`QT`), reading past the scans still coming.
    pub fn stop(&mut self) -> Result<(), LidarError> {
        if !self.streaming {
            return Ok(());
        }
        self.streaming = false;
        self.send("QT")?;
        let m = self.await_echo("QT", self.cfg.reply_timeout_s + 4.0 * self.params.scan_period_s())?;
        if &m.status != b"00" {
            return Err(LidarError::Status {
                command: "QT".into(),
                status: m.status_text(),
                meaning: status_meaning(b"QT", m.status),
            });
        }
        Ok(())
    }

    /// Drops the connection and makes a new one (retrying with a growing delay), identifies
    /// the sensor again and resynchronizes its clock; says so in the log.
    pub fn reconnect(&mut self, model: &LidarModel) -> Result<(), LidarError> {
        (self.log)(&format!(
            "lidar: reconnecting to {} after {} errors in a row",
            self.cfg.describe(),
            self.errors_in_a_row
        ));
        self.link = connect(&self.cfg, self.log)?;
        self.reader.clear();
        self.streaming = false;
        self.errors_in_a_row = 0;
        self.handshake(model)?;
        self.clock = None;
        self.sync_clock()
    }
}

impl Drop for Lidar {
    /// A lidar left streaming is stopped, so the next connection finds it at rest.
    fn drop(&mut self) {
        if self.streaming {
            let _ = self.send("QT");
        }
    }
}
