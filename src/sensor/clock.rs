//! Relating a sensor's own clock to the host's: the Hokuyo counts milliseconds in 24 bits
//! (it wraps every 2^24 ms, about 4.66 h), starts at an unknown offset and drifts. A batch of
//! `TM1` exchanges (host time sent, sensor time, host time received) gives the offset: each
//! exchange bounds it (the tick read was counting during the exchange), and the middle of the
//! bounds' intersection is kept (the midpoint estimate of Carballo et al. 2007, which Hokuyo's
//! drivers use, made exact to the counter's millisecond). A later batch, at least [`MIN_DRIFT_SPAN_S`] of sensor time after, gives the drift
//! (the offsets' change over the time between). A stamp is unwrapped against the last one seen
//! and mapped to host seconds.

use crate::stats::median;

/// A 24-bit millisecond counter's period, ms.
pub const WRAP_MS: u64 = 1 << 24;

/// Seconds on the host's monotonic clock since the process first asked: the common clock
/// every hardware reading (a lidar scan, a servo position) is stamped on.
pub fn host_now_s() -> f64 {
    static ORIGIN: std::sync::OnceLock<std::time::Instant> = std::sync::OnceLock::new();
    ORIGIN.get_or_init(std::time::Instant::now).elapsed().as_secs_f64()
}

/// CPU time the calling thread has used, seconds (for the drivers' CPU share; NaN where the
/// clock cannot be read).
pub fn thread_cpu_s() -> f64 {
    let mut t = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: clock_gettime writes one timespec through the pointer it is given, a local here.
    let ok = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut t) } == 0;
    if ok {
        t.tv_sec as f64 + t.tv_nsec as f64 * 1e-9
    } else {
        f64::NAN
    }
}

/// One time exchange.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Exchange {
    /// Host time when the request left, seconds.
    pub sent_s: f64,
    /// The sensor's counter in its reply, ms (24 bits).
    pub sensor_ms: u32,
    /// Host time when the reply arrived, seconds.
    pub received_s: f64,
}

/// Unwraps a 24-bit counter into a continuous count of milliseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Unwrap {
    last: Option<u64>,
}

impl Unwrap {
    /// The continuous count of `raw` (24 bits), the counter having moved forward by less than
    /// half a period since the last one (jitter backwards by less than that is kept as is).
    pub fn unwrap(&mut self, raw: u32) -> u64 {
        let raw = u64::from(raw) & (WRAP_MS - 1);
        let value = match self.last {
            None => raw,
            Some(last) => {
                let base = last - (last & (WRAP_MS - 1));
                let candidates =
                    [base.wrapping_sub(WRAP_MS), base, base + WRAP_MS].map(|b| b.wrapping_add(raw));
                candidates
                    .into_iter()
                    .filter(|c| *c < u64::MAX / 2)
                    .min_by_key(|c| c.abs_diff(last))
                    .unwrap_or(base + raw)
            }
        };
        self.last = Some(self.last.map_or(value, |l| l.max(value)));
        value
    }
}

/// Sensor time between two batches for the drift to be estimated from them, seconds (over a
/// shorter span, the exchanges' jitter would outweigh a drift of tens of ppm).
pub const MIN_DRIFT_SPAN_S: f64 = 15.0;

/// The relation host = anchor_host + (1 + drift) x (sensor - anchor_sensor), in seconds, the
/// anchor being the start of a tick of the sensor's counter.
#[derive(Debug, Clone, PartialEq)]
pub struct ClockSync {
    /// Sensor time of the last batch (of the unwrapped count), seconds.
    pub anchor_sensor_s: f64,
    /// Host time at that sensor time, seconds.
    pub anchor_host_s: f64,
    /// Rate difference: host seconds per sensor second, minus 1 (0 until a second batch).
    pub drift: f64,
    /// Shortest round trip of the last batch, seconds (the offset is good to about half of it).
    pub round_trip_s: f64,
    unwrap: Unwrap,
    /// The batches' anchors (sensor, host), the last [`MAX_ANCHORS`].
    anchors: Vec<(f64, f64)>,
}

/// Batches the drift is fitted over (a sweep each: some minutes of a climb).
pub const MAX_ANCHORS: usize = 32;

/// Why a clock could not be related.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ClockError {
    /// No exchange.
    #[error("no time exchange")]
    Empty,
    /// A reply came before its request left.
    #[error("a time exchange ends before it starts ({sent_s} s -> {received_s} s)")]
    Backwards {
        /// When it left.
        sent_s: f64,
        /// When it came back.
        received_s: f64,
    },
}

impl ClockSync {
    /// The relation from a first batch of exchanges (drift 0).
    pub fn fit(exchanges: &[Exchange]) -> Result<Self, ClockError> {
        let mut unwrap = Unwrap::default();
        let (anchor_sensor_s, anchor_host_s, round_trip_s) = batch(exchanges, &mut unwrap)?;
        Ok(Self {
            anchor_sensor_s,
            anchor_host_s,
            drift: 0.0,
            round_trip_s,
            unwrap,
            anchors: vec![(anchor_sensor_s, anchor_host_s)],
        })
    }

    /// Takes a later batch: the drift is fitted (least squares) over the batches so far once
    /// they span [`MIN_DRIFT_SPAN_S`], and the anchor moves to the new batch, on that fit.
    pub fn refine(&mut self, exchanges: &[Exchange]) -> Result<(), ClockError> {
        let (s, h, rt) = batch(exchanges, &mut self.unwrap)?;
        self.anchors.push((s, h));
        if self.anchors.len() > MAX_ANCHORS {
            self.anchors.remove(0);
        }
        self.round_trip_s = rt;
        let n = self.anchors.len() as f64;
        let (ms, mh) = self.anchors.iter().fold((0.0, 0.0), |a, p| (a.0 + p.0 / n, a.1 + (p.1 - p.0) / n));
        let span = s - self.anchors[0].0;
        let sss: f64 = self.anchors.iter().map(|p| (p.0 - ms).powi(2)).sum();
        if span >= MIN_DRIFT_SPAN_S && sss > 0.0 {
            // The offsets host - sensor against sensor time: their slope is the drift.
            let slope: f64 = self.anchors.iter().map(|p| (p.0 - ms) * (p.1 - p.0 - mh)).sum::<f64>() / sss;
            self.drift = slope;
            self.anchor_sensor_s = s;
            self.anchor_host_s = s + mh + slope * (s - ms);
        } else {
            self.anchor_sensor_s = s;
            self.anchor_host_s = h;
        }
        Ok(())
    }

    /// The host time of a sensor stamp (24 bits), seconds. Stamps must come in time order
    /// (each within half a period of the last), as a scan stream's do.
    pub fn host_s(&mut self, sensor_ms: u32) -> f64 {
        // The middle of the tick: the event stamped m happened within [m, m + 1) ms.
        let t = self.unwrap.unwrap(sensor_ms) as f64 * 1e-3 + TICK_S / 2.0;
        self.anchor_host_s + (1.0 + self.drift) * (t - self.anchor_sensor_s)
    }
}

/// A batch's anchor (a sensor tick's start and its host time) and its shortest round trip.
/// Each exchange bounds the offset c = host - sensor: the tick m it read was counting at some
/// host time within the exchange, so c lies in (sent - (m + 1 ms), received - m]; the
/// intersection over the batch (its middle) is the estimate, good to the shortest round trip
/// and the counter's millisecond. Should the bounds not meet (a drift within the batch, a
/// delay no bound holds), the median of the exchanges' midpoints is taken instead.
fn batch(exchanges: &[Exchange], unwrap: &mut Unwrap) -> Result<(f64, f64, f64), ClockError> {
    if let Some(e) = exchanges.iter().find(|e| e.received_s.partial_cmp(&e.sent_s).is_none_or(|o| o.is_lt()))
    {
        return Err(ClockError::Backwards { sent_s: e.sent_s, received_s: e.received_s });
    }
    let pts: Vec<(f64, &Exchange)> =
        exchanges.iter().map(|e| (unwrap.unwrap(e.sensor_ms) as f64 * 1e-3, e)).collect();
    let shortest = pts.iter().map(|p| p.1.received_s - p.1.sent_s).fold(f64::INFINITY, f64::min);
    if !shortest.is_finite() {
        return Err(ClockError::Empty);
    }
    let lo = pts.iter().map(|(s, e)| e.sent_s - (s + TICK_S)).fold(f64::NEG_INFINITY, f64::max);
    let hi = pts.iter().map(|(s, e)| e.received_s - s).fold(f64::INFINITY, f64::min);
    let offset = if lo <= hi {
        (lo + hi) / 2.0
    } else {
        median(pts.iter().map(|(s, e)| (e.sent_s + e.received_s) / 2.0 - s - TICK_S / 2.0))
            .ok_or(ClockError::Empty)?
    };
    let s = median(pts.iter().map(|p| p.0)).ok_or(ClockError::Empty)?;
    Ok((s, s + offset, shortest))
}

/// The counter's resolution, seconds.
const TICK_S: f64 = 1e-3;

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn the_counter_unwraps_across_its_24_bits() {
        let mut u = Unwrap::default();
        assert_eq!(u.unwrap((WRAP_MS - 10) as u32), WRAP_MS - 10);
        assert_eq!(u.unwrap(5), WRAP_MS + 5);
        assert_eq!(u.unwrap(3), WRAP_MS + 3, "a little backwards is not a wrap");
        assert_eq!(u.unwrap(1000), WRAP_MS + 1000);
    }

    /// A sensor clock with an offset, a drift of 40 ppm (a quartz clock's typical tolerance is
    /// 50 ppm; before a second batch gives the drift, 40 ppm over a 6 s sweep costs 0.24 ms of
    /// the budget, the counter's millisecond 0.5 ms) and a wrap: beam stamps mapped to host
    /// time within 1 ms of the truth, with each exchange delayed by 0.2-1.0 ms each way (a LAN
    /// or a USB link), as the driver uses it: a batch of exchanges before each sweep, a sweep's
    /// 6 s of scans after it, six sweeps across the wrap. Checked on 200 draws of the delays.
    #[test]
    fn offset_drift_and_wrap_give_stamps_within_a_millisecond() {
        for seed in 0..200u64 {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let drift = 40e-6;
            let start_ms = WRAP_MS as f64 - 20_000.0; // the counter wraps 20 s in
                                                      // The sensor's count at host time h (it started at host time 100 s).
            let sensor_at = |h: f64| (start_ms + (h - 100.0) / (1.0 + drift) * 1e3).floor() as u64 % WRAP_MS;
            let mut sync: Option<ClockSync> = None;
            for sweep in 0..6 {
                let t0 = 100.0 + 8.0 * sweep as f64;
                // Back-to-back exchanges, 2-12 ms apart as a host's scheduling has them.
                let mut sent_s = t0;
                let batch: Vec<Exchange> = (0..20)
                    .map(|_| {
                        sent_s += rng.random_range(0.002..0.012);
                        let (up, down) = (rng.random_range(0.0002..0.001), rng.random_range(0.0002..0.001));
                        Exchange {
                            sent_s,
                            sensor_ms: sensor_at(sent_s + up) as u32,
                            received_s: sent_s + up + down,
                        }
                    })
                    .collect();
                match sync.as_mut() {
                    None => sync = Some(ClockSync::fit(&batch).expect("a fit")),
                    Some(c) => c.refine(&batch).expect("a batch"),
                }
                let c = sync.as_mut().expect("fitted");
                for k in 0..240 {
                    let truth = t0 + 0.2 + 0.025 * k as f64 + rng.random_range(0.0..0.001);
                    let got = c.host_s(sensor_at(truth) as u32);
                    assert!(
                        (got - truth).abs() < 1e-3,
                        "seed {seed}, sweep {sweep}, scan {k}: {got} for {truth}"
                    );
                }
            }
            let c = sync.expect("fitted");
            assert!((c.drift - drift).abs() < 20e-6, "seed {seed}: drift {}", c.drift);
        }
        assert_eq!(ClockSync::fit(&[]), Err(ClockError::Empty));
        let backwards = Exchange { sent_s: 2.0, sensor_ms: 0, received_s: 1.0 };
        assert!(ClockSync::fit(&[backwards]).is_err());
    }
}
