//! The Dynamixel MX-64 that tilts the lidar, on a USB serial adapter: Protocol 1.0 (factory
//! firmware) or 2.0 (2.0 firmware), chosen by the configuration, each with its own control
//! table. The packets are written here ([`packet`]) rather than taken from a crate: `rustypot`
//! speaks both protocols over `serialport` but does no Protocol 2.0 byte stuffing, knows the
//! MX-64 only in Protocol 1.0, and asserts (panics) on a stray byte; `dynamixel2` speaks only
//! 2.0 and over another serial crate. The two packet formats are small, and every byte of
//! them is tested against the e-manual's own examples.

pub mod packet;

pub use packet::{Protocol, Status, StatusReader};

use crate::sensor::clock::host_now_s;
use crate::sensor::link::{Link, SerialLink};
use packet::instruction;
use std::time::{Duration, Instant};

/// Where a register is: its address and size in bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Register {
    /// Address.
    pub address: u16,
    /// Bytes.
    pub size: u8,
}

/// The registers the bench uses in one firmware's control table.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Table {
    /// Model number (read at start).
    pub model_number: Register,
    /// The model number an MX-64 of this firmware reports.
    pub mx64: u16,
    /// Torque enable.
    pub torque_enable: Register,
    /// Goal position, ticks.
    pub goal_position: Register,
    /// Moving speed (1.0) or profile velocity (2.0).
    pub speed: Register,
    /// One unit of `speed`, rpm.
    pub speed_rpm_per_unit: f64,
    /// Present position, ticks.
    pub present_position: Register,
    /// Hardware error status (2.0 only).
    pub hardware_error: Option<Register>,
}

impl Table {
    /// The MX-64's control table of `protocol`'s firmware (e-manual, MX-64 and MX-64(2.0)).
    pub fn mx64(protocol: Protocol) -> Self {
        let r = |address, size| Register { address, size };
        match protocol {
            Protocol::One => Self {
                model_number: r(0, 2),
                mx64: 310,
                torque_enable: r(24, 1),
                goal_position: r(30, 2),
                speed: r(32, 2),
                speed_rpm_per_unit: 0.114,
                present_position: r(36, 2),
                hardware_error: None,
            },
            Protocol::Two => Self {
                model_number: r(0, 2),
                mx64: 311,
                torque_enable: r(64, 1),
                goal_position: r(116, 4),
                speed: r(112, 4),
                speed_rpm_per_unit: 0.229,
                present_position: r(132, 4),
                hardware_error: Some(r(70, 1)),
            },
        }
    }
}

/// The names of the errors a status packet's error byte reports.
pub fn status_errors(protocol: Protocol, error: u8) -> Vec<&'static str> {
    match protocol {
        Protocol::One => [
            (0x01, "input voltage"),
            (0x02, "angle limit"),
            (0x04, "overheating"),
            (0x08, "range"),
            (0x10, "checksum"),
            (0x20, "overload"),
            (0x40, "instruction"),
        ]
        .iter()
        .filter(|(bit, _)| error & bit != 0)
        .map(|(_, n)| *n)
        .collect(),
        Protocol::Two => {
            let mut v = match error & 0x7f {
                0 => vec![],
                1 => vec!["result fail"],
                2 => vec!["instruction"],
                3 => vec!["CRC"],
                4 => vec!["data range"],
                5 => vec!["data length"],
                6 => vec!["data limit"],
                7 => vec!["access"],
                _ => vec!["unknown error number"],
            };
            if error & 0x80 != 0 {
                v.push("hardware alert");
            }
            v
        }
    }
}

/// The names of the bits of Protocol 2.0's hardware error status register.
pub fn hardware_errors(status: u8) -> Vec<&'static str> {
    [
        (0x01, "input voltage"),
        (0x04, "overheating"),
        (0x08, "motor encoder"),
        (0x10, "electrical shock"),
        (0x20, "overload"),
    ]
    .iter()
    .filter(|(bit, _)| status & bit != 0)
    .map(|(_, n)| *n)
    .collect()
}

/// The servo's configuration.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ServoConfig {
    /// Serial port of the USB adapter (`/dev/ttyUSB0`).
    pub serial: String,
    /// Baud rate (the MX-64's factory rate is 57600; 1000000 with the latency timer at 1 ms
    /// is what fast sweeps want).
    pub baud: u32,
    /// The servo's id.
    pub id: u8,
    /// Protocol of its firmware.
    pub protocol: Protocol,
    /// Reading when the scan plane is level, ticks.
    pub zero_tick: i64,
    /// Ticks per revolution (MX-64: 4096).
    pub ticks_per_rev: u32,
    /// +1 when growing ticks pitch the scan plane down (the bench's positive tilt), else -1.
    pub direction: i8,
    /// Longest wait for a status packet, seconds.
    pub reply_timeout_s: f64,
    /// Times a request is sent again after a reply whose checksum failed (a noisy bus garbles
    /// a packet now and then); one more garbled reply is an error naming the bytes.
    pub corrupt_retries: u32,
}

impl Default for ServoConfig {
    fn default() -> Self {
        Self {
            serial: "/dev/ttyUSB0".into(),
            baud: 1_000_000,
            id: 1,
            protocol: Protocol::One,
            zero_tick: 2048,
            ticks_per_rev: 4096,
            direction: 1,
            reply_timeout_s: 0.1,
            corrupt_retries: 3,
        }
    }
}

/// Why the servo failed.
#[derive(Debug, thiserror::Error)]
pub enum ServoError {
    /// The port could not be opened.
    #[error("cannot open the servo's port {path}: {source}")]
    Open {
        /// The port.
        path: String,
        /// Why.
        source: serialport::Error,
    },
    /// The link failed (the adapter unplugged).
    #[error("the link to the servo ({link}) failed: {source}")]
    Io {
        /// The port.
        link: String,
        /// Why.
        source: std::io::Error,
    },
    /// No valid status packet in time.
    #[error("servo {id} on {link} did not answer {what} within {timeout_s} s{garbage}")]
    NoAnswer {
        /// Its id.
        id: u8,
        /// The port.
        link: String,
        /// The request.
        what: String,
        /// How long.
        timeout_s: f64,
        /// A note when bytes came that were no packet (a wrong baud rate or protocol).
        garbage: String,
    },
    /// The status reports errors.
    #[error("servo {id} reports {errors:?} on {what}")]
    Device {
        /// Its id.
        id: u8,
        /// The request.
        what: String,
        /// The errors by name.
        errors: Vec<&'static str>,
    },
    /// Not an MX-64 of the configured protocol.
    #[error(
        "servo {id} is model {model}, not an MX-64 with Protocol {protocol:?} firmware (model {expected})"
    )]
    Model {
        /// Its id.
        id: u8,
        /// Its model number.
        model: u16,
        /// The MX-64's.
        expected: u16,
        /// The configured protocol.
        protocol: Protocol,
    },
    /// Every reply to a request, sent again, came garbled.
    #[error(
        "servo {id} on {link} answered {what} {tries} times in a row with a packet whose checksum failed (last: {last})"
    )]
    Corrupt {
        /// Its id.
        id: u8,
        /// The port.
        link: String,
        /// The request.
        what: String,
        /// Replies received, all garbled.
        tries: u32,
        /// The last garbled packet, in hex.
        last: String,
    },
    /// A reply of the wrong size.
    #[error("servo {id} answered {what} with {got} bytes, {expected} expected")]
    Short {
        /// Its id.
        id: u8,
        /// The request.
        what: String,
        /// Bytes received.
        got: usize,
        /// Bytes expected.
        expected: usize,
    },
}

/// A connected MX-64.
pub struct Servo {
    link: Box<dyn Link>,
    cfg: ServoConfig,
    table: Table,
    reader: StatusReader,
    buf: Vec<u8>,
    /// Replies whose checksum failed (each asked again) since the connection was made.
    corrupt_replies: usize,
    /// The firmware's model number.
    pub model: u16,
}

impl Servo {
    /// Opens the port of `cfg`, pings the servo, checks its model and enables its torque.
    pub fn open(cfg: &ServoConfig) -> Result<Self, ServoError> {
        let link = SerialLink::open(&cfg.serial, cfg.baud)
            .map_err(|source| ServoError::Open { path: cfg.serial.clone(), source })?;
        Self::on(Box::new(link), cfg)
    }

    /// The servo of `cfg` on an open link.
    pub fn on(link: Box<dyn Link>, cfg: &ServoConfig) -> Result<Self, ServoError> {
        let mut s = Self {
            link,
            cfg: cfg.clone(),
            table: Table::mx64(cfg.protocol),
            reader: StatusReader::new(cfg.protocol),
            buf: vec![0; 512],
            corrupt_replies: 0,
            model: 0,
        };
        s.transact(instruction::PING, &[], "a ping")?;
        let m = s.read(s.table.model_number, "the model number")?;
        s.model = m as u16;
        if s.model != s.table.mx64 {
            return Err(ServoError::Model {
                id: cfg.id,
                model: s.model,
                expected: s.table.mx64,
                protocol: cfg.protocol,
            });
        }
        s.write(s.table.torque_enable, 1, "torque enable")?;
        Ok(s)
    }

    /// Replies whose checksum failed (each asked again) since the connection was made.
    pub fn corrupt_replies(&self) -> usize {
        self.corrupt_replies
    }

    /// Sends an instruction and returns its status packet (errors in it are errors, named). A
    /// reply whose checksum failed is asked for again, up to `corrupt_retries` times.
    fn transact(&mut self, inst: u8, params: &[u8], what: &str) -> Result<Status, ServoError> {
        let request = packet::instruction(self.cfg.protocol, self.cfg.id, inst, params);
        let link = self.link.describe();
        let mut garbled = 0;
        let mut deadline = self.send(&request, &link)?;
        loop {
            if let Some(bad) = self.reader.take_corrupt() {
                garbled += 1;
                self.corrupt_replies += 1;
                if garbled > self.cfg.corrupt_retries {
                    return Err(ServoError::Corrupt {
                        id: self.cfg.id,
                        link,
                        what: what.into(),
                        tries: garbled,
                        last: bad.iter().map(|b| format!("{b:02x}")).collect::<Vec<_>>().join(" "),
                    });
                }
                deadline = self.send(&request, &link)?;
            }
            if let Some(st) = self.reader.next_status() {
                if st.id != self.cfg.id {
                    continue;
                }
                let errors = status_errors(self.cfg.protocol, st.error);
                if !errors.is_empty() {
                    let errors = self.with_hardware_status(st.error, errors);
                    return Err(ServoError::Device { id: self.cfg.id, what: what.into(), errors });
                }
                return Ok(st);
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                let dropped = self.reader.take_dropped();
                let garbage = if dropped > 0 {
                    format!(" ({dropped} bytes came that were no packet: is the baud rate or the protocol wrong?)")
                } else {
                    String::new()
                };
                return Err(ServoError::NoAnswer {
                    id: self.cfg.id,
                    link,
                    what: what.into(),
                    timeout_s: self.cfg.reply_timeout_s,
                    garbage,
                });
            }
            match self.link.receive(&mut self.buf, left) {
                Ok(n) => self.reader.push(&self.buf[..n]),
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(source) => return Err(ServoError::Io { link, source }),
            }
        }
    }

    /// Sends `request` with the reader cleared for its reply; the reply's deadline.
    fn send(&mut self, request: &[u8], link: &str) -> Result<Instant, ServoError> {
        self.reader.clear();
        self.reader.expect_echo(request);
        self.link.send(request).map_err(|source| ServoError::Io { link: link.into(), source })?;
        Ok(Instant::now() + Duration::from_secs_f64(self.cfg.reply_timeout_s.max(0.001)))
    }

    /// A Protocol 2.0 alert names the hardware errors behind it (the register read once).
    fn with_hardware_status(&mut self, error: u8, mut errors: Vec<&'static str>) -> Vec<&'static str> {
        if let (Protocol::Two, true, Some(reg)) =
            (self.cfg.protocol, error & 0x80 != 0, self.table.hardware_error)
        {
            let request = packet::instruction(
                Protocol::Two,
                self.cfg.id,
                instruction::READ,
                &[reg.address as u8, (reg.address >> 8) as u8, 1, 0],
            );
            self.reader.clear();
            if self.link.send(&request).is_ok() {
                let deadline = Instant::now() + Duration::from_secs_f64(self.cfg.reply_timeout_s.max(0.001));
                while Instant::now() < deadline {
                    if let Some(st) = self.reader.next_status() {
                        if let Some(&bits) = st.params.first() {
                            errors.extend(hardware_errors(bits));
                        }
                        break;
                    }
                    let left = deadline.saturating_duration_since(Instant::now());
                    match self.link.receive(&mut self.buf, left) {
                        Ok(n) => self.reader.push(&self.buf[..n]),
                        Err(_) => break,
                    }
                }
            }
        }
        errors
    }

    fn address_params(&self, reg: Register) -> Vec<u8> {
        match self.cfg.protocol {
            Protocol::One => vec![reg.address as u8],
            Protocol::Two => reg.address.to_le_bytes().to_vec(),
        }
    }

    /// Reads a register (little-endian).
    fn read(&mut self, reg: Register, what: &str) -> Result<u32, ServoError> {
        let mut params = self.address_params(reg);
        match self.cfg.protocol {
            Protocol::One => params.push(reg.size),
            Protocol::Two => params.extend_from_slice(&u16::from(reg.size).to_le_bytes()),
        }
        let st = self.transact(instruction::READ, &params, what)?;
        if st.params.len() != usize::from(reg.size) {
            return Err(ServoError::Short {
                id: self.cfg.id,
                what: what.into(),
                got: st.params.len(),
                expected: reg.size.into(),
            });
        }
        Ok(st.params.iter().rev().fold(0u32, |v, &b| (v << 8) | u32::from(b)))
    }

    /// Writes a register (little-endian).
    fn write(&mut self, reg: Register, value: u32, what: &str) -> Result<(), ServoError> {
        let mut params = self.address_params(reg);
        params.extend_from_slice(&value.to_le_bytes()[..usize::from(reg.size)]);
        self.transact(instruction::WRITE, &params, what).map(|_| ())
    }

    /// The tick of tilt `tilt_rad`.
    pub fn tick_of(&self, tilt_rad: f64) -> i64 {
        self.cfg.zero_tick
            + (f64::from(self.cfg.direction) * tilt_rad / std::f64::consts::TAU
                * f64::from(self.cfg.ticks_per_rev))
            .round() as i64
    }

    /// The tilt of tick `tick`, radians.
    pub fn tilt_of(&self, tick: i64) -> f64 {
        (tick - self.cfg.zero_tick) as f64 / f64::from(self.cfg.ticks_per_rev)
            * std::f64::consts::TAU
            * f64::from(self.cfg.direction)
    }

    /// Moves toward `tilt_rad` at `speed_rad_s` (the speed register first, then the goal).
    pub fn move_to(&mut self, tilt_rad: f64, speed_rad_s: f64) -> Result<(), ServoError> {
        let rpm = speed_rad_s.abs() * 60.0 / std::f64::consts::TAU;
        let units = (rpm / self.table.speed_rpm_per_unit).round().clamp(1.0, 1023.0) as u32;
        self.write(self.table.speed, units, "the speed")?;
        let tick = self.tick_of(tilt_rad).clamp(0, i64::from(self.cfg.ticks_per_rev) - 1);
        self.write(self.table.goal_position, tick as u32, "the goal position")
    }

    /// The present tilt, radians, stamped on the host's clock at the middle of the exchange.
    pub fn tilt(&mut self) -> Result<(f64, f64), ServoError> {
        let t0 = host_now_s();
        let tick = self.read(self.table.present_position, "the present position")?;
        let t1 = host_now_s();
        let tick = match self.table.present_position.size {
            4 => i64::from(tick as i32),
            _ => i64::from(tick),
        };
        Ok((self.tilt_of(tick), (t0 + t1) / 2.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn error_bits_are_named() {
        assert_eq!(
            status_errors(Protocol::One, 0x24),
            vec!["overheating", "overload"],
            "the e-manual's 0x24"
        );
        assert_eq!(status_errors(Protocol::One, 0), Vec::<&str>::new());
        assert_eq!(status_errors(Protocol::Two, 0x80), vec!["hardware alert"]);
        assert_eq!(status_errors(Protocol::Two, 0x03), vec!["CRC"]);
        assert_eq!(hardware_errors(0x34), vec!["overheating", "electrical shock", "overload"]);
    }

    #[test]
    fn the_control_tables_of_both_firmwares() {
        let one = Table::mx64(Protocol::One);
        assert_eq!(
            (one.torque_enable.address, one.goal_position.address, one.present_position.address, one.mx64),
            (24, 30, 36, 310)
        );
        let two = Table::mx64(Protocol::Two);
        assert_eq!(
            (
                two.torque_enable.address,
                two.goal_position.address,
                two.speed.address,
                two.present_position.address,
                two.mx64
            ),
            (64, 116, 112, 132, 311)
        );
        assert_eq!(two.hardware_error.map(|r| r.address), Some(70));
    }
}
