//! An emulated MX-64 on a pseudo-terminal: Protocol 1.0 or 2.0 with the firmware's control
//! table (ping, read, write: torque enable, goal position, moving speed or profile velocity,
//! present position, model number, hardware error status), moving at its set speed toward its
//! goal in real time, each answer after the bus time of its bytes at its baud rate and its
//! return delay. It answers garbage when the driver's baud rate is not its own, nothing to the
//! other protocol, and can be told to fall silent or to overload.

use super::pty::Pty;
use crate::sensor::dynamixel::packet::{instruction, status, PacketReader};
use crate::sensor::dynamixel::{Protocol, Table};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// What can go wrong with the emulated servo.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ServoFaults {
    /// It never answers.
    pub silent: bool,
    /// From this many seconds after the emulator starts, it reports an overload (and drops its
    /// torque, as the MX-64's shutdown does).
    pub overload_after_s: Option<f64>,
    /// Every this many replies, one goes out with its checksum (CRC) wrong, as a noisy bus
    /// garbles a packet now and then (1: every reply).
    pub garble_every: Option<usize>,
}

/// The emulated servo's settings.
#[derive(Debug, Clone, PartialEq)]
pub struct ServoSpec {
    /// Protocol of its firmware.
    pub protocol: Protocol,
    /// Its id.
    pub id: u8,
    /// Its baud rate.
    pub baud: u32,
    /// Its return delay, seconds (the MX-64's default: 500 us).
    pub return_delay_s: f64,
    /// Reading when level, ticks.
    pub zero_tick: i64,
    /// Ticks per revolution.
    pub ticks_per_rev: u32,
    /// +1 when growing ticks pitch the scan plane down.
    pub direction: i8,
    /// Faults.
    pub faults: ServoFaults,
}

impl Default for ServoSpec {
    fn default() -> Self {
        Self {
            protocol: Protocol::One,
            id: 1,
            baud: 1_000_000,
            return_delay_s: 500e-6,
            zero_tick: 2048,
            ticks_per_rev: 4096,
            direction: 1,
            faults: ServoFaults::default(),
        }
    }
}

/// The servo's motion: from `from_rad` at `since` toward `goal_rad` at `speed_rad_s`.
#[derive(Debug, Clone, PartialEq)]
pub struct Motion {
    from_rad: f64,
    goal_rad: f64,
    speed_rad_s: f64,
    since: Instant,
    torque: bool,
    overloaded: bool,
}

impl Motion {
    /// At rest at `tilt_rad`.
    pub fn at(tilt_rad: f64) -> Self {
        Self {
            from_rad: tilt_rad,
            goal_rad: tilt_rad,
            speed_rad_s: 0.5,
            since: Instant::now(),
            torque: false,
            overloaded: false,
        }
    }

    /// The tilt at `t`, radians.
    pub fn tilt_at(&self, t: Instant) -> f64 {
        if !self.torque {
            return self.from_rad;
        }
        let travel = self.speed_rad_s * t.saturating_duration_since(self.since).as_secs_f64();
        let gap = self.goal_rad - self.from_rad;
        if travel >= gap.abs() {
            self.goal_rad
        } else {
            self.from_rad + travel * gap.signum()
        }
    }

    fn retarget(&mut self, goal_rad: Option<f64>, speed_rad_s: Option<f64>) {
        let now = Instant::now();
        self.from_rad = self.tilt_at(now);
        self.since = now;
        if let Some(g) = goal_rad {
            self.goal_rad = g;
        }
        if let Some(s) = speed_rad_s {
            self.speed_rad_s = s;
        }
    }
}

/// The emulated servo, shared with the lidar (which tilts with it).
pub type SharedMotion = Arc<Mutex<Motion>>;

/// Serves `spec` on `pty` until `stop`.
pub fn serve(mut pty: Pty, spec: ServoSpec, motion: SharedMotion, stop: Arc<AtomicBool>, started: Instant) {
    let table = Table::mx64(spec.protocol);
    let mut reader = PacketReader::new(spec.protocol);
    let mut buf = [0u8; 512];
    let mut rng_state = 0x2545_f491_4f6c_dd1d_u64;
    let mut replies = 0usize;
    while !stop.load(Ordering::Relaxed) {
        let n = match pty.read_timeout(&mut buf, 20) {
            Ok(n) => n,
            Err(_) => break,
        };
        if n == 0 {
            continue;
        }
        reader.push(&buf[..n]);
        let wrong_baud = pty.baud().is_some_and(|b| b != spec.baud);
        while let Some(p) = reader.next_packet() {
            if spec.faults.silent || (p.id != spec.id && p.id != 0xfe) {
                continue;
            }
            let overloaded =
                spec.faults.overload_after_s.is_some_and(|s| started.elapsed().as_secs_f64() >= s);
            let reply = {
                let mut m = match motion.lock() {
                    Ok(m) => m,
                    Err(_) => return,
                };
                if overloaded && !m.overloaded {
                    m.retarget(None, None);
                    m.torque = false;
                    m.overloaded = true;
                }
                answer(&spec, &table, &mut m, p.instruction, &p.params)
            };
            let Some(mut reply) = reply.filter(|_| p.id != 0xfe) else { continue };
            // The bus time of request and reply at the device's rate, and its return delay.
            let bytes = reply.len() + 10;
            std::thread::sleep(Duration::from_secs_f64(
                spec.return_delay_s + bytes as f64 * 10.0 / f64::from(spec.baud),
            ));
            replies += 1;
            if let (Some(every), Some(last)) = (spec.faults.garble_every, reply.last_mut()) {
                if replies.is_multiple_of(every.max(1)) {
                    *last ^= 0x5a;
                }
            }
            if wrong_baud {
                for b in &mut reply {
                    rng_state ^= rng_state << 13;
                    rng_state ^= rng_state >> 7;
                    rng_state ^= rng_state << 17;
                    *b = rng_state as u8;
                }
            }
            if std::io::Write::write_all(&mut pty.master, &reply).is_err() {
                return;
            }
        }
    }
}

/// The tick of a tilt, and back.
fn tick_of(spec: &ServoSpec, tilt_rad: f64) -> i64 {
    spec.zero_tick
        + (f64::from(spec.direction) * tilt_rad / std::f64::consts::TAU * f64::from(spec.ticks_per_rev))
            .round() as i64
}

fn tilt_of(spec: &ServoSpec, tick: i64) -> f64 {
    (tick - spec.zero_tick) as f64 / f64::from(spec.ticks_per_rev)
        * std::f64::consts::TAU
        * f64::from(spec.direction)
}

/// The status packet answering one instruction (`None`: no answer, e.g. a broadcast).
fn answer(spec: &ServoSpec, table: &Table, m: &mut Motion, inst: u8, params: &[u8]) -> Option<Vec<u8>> {
    let error = match (spec.protocol, m.overloaded) {
        (_, false) => 0,
        (Protocol::One, true) => 0x20,
        (Protocol::Two, true) => 0x80,
    };
    let ok = |data: &[u8]| Some(status(spec.protocol, spec.id, error, data));
    let (address, rest): (u16, &[u8]) = match spec.protocol {
        Protocol::One => (u16::from(*params.first().unwrap_or(&0)), params.get(1..).unwrap_or_default()),
        Protocol::Two => (
            u16::from_le_bytes([*params.first().unwrap_or(&0), *params.get(1).unwrap_or(&0)]),
            params.get(2..).unwrap_or_default(),
        ),
    };
    match inst {
        instruction::PING => match spec.protocol {
            Protocol::One => ok(&[]),
            Protocol::Two => ok(&[table.mx64 as u8, (table.mx64 >> 8) as u8, 41]),
        },
        instruction::READ => {
            let len = match spec.protocol {
                Protocol::One => usize::from(*rest.first()?),
                Protocol::Two => usize::from(u16::from_le_bytes([*rest.first()?, *rest.get(1)?])),
            };
            let value: i64 = if address == table.model_number.address {
                i64::from(table.mx64)
            } else if address == table.present_position.address {
                tick_of(spec, m.tilt_at(Instant::now()))
            } else if address == table.torque_enable.address {
                i64::from(m.torque)
            } else if Some(address) == table.hardware_error.map(|r| r.address) {
                if m.overloaded {
                    0x20
                } else {
                    0
                }
            } else {
                0
            };
            let bytes = value.to_le_bytes();
            ok(&bytes[..len.min(8)])
        }
        instruction::WRITE => {
            let mut v = [0u8; 8];
            for (k, b) in rest.iter().take(8).enumerate() {
                v[k] = *b;
            }
            let value = i64::from_le_bytes(v);
            if address == table.torque_enable.address {
                m.retarget(None, None);
                m.torque = value != 0 && !m.overloaded;
            } else if address == table.goal_position.address {
                m.retarget(Some(tilt_of(spec, value)), None);
            } else if address == table.speed.address {
                let rpm = value as f64 * table.speed_rpm_per_unit;
                let speed = if value == 0 { 12.0 } else { rpm * std::f64::consts::TAU / 60.0 };
                m.retarget(None, Some(speed));
            }
            ok(&[])
        }
        _ => match spec.protocol {
            Protocol::One => Some(status(spec.protocol, spec.id, error | 0x40, &[])),
            Protocol::Two => Some(status(spec.protocol, spec.id, error | 0x02, &[])),
        },
    }
}
