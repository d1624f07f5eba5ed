//! Relating a sensor's own clock to the host's: the Hokuyo counts milliseconds in 24 bits
//! (it wraps every 2^24 ms, about 4.66 h), starts at an unknown offset and drifts. A batch of
//! `TM1` exchanges (host time sent, sensor time, host time received) gives the offset: each
//! exchange's delay is taken as symmetric (the midpoint estimate of Carballo et al. 2007 that
//! Hokuyo's drivers use), and the median over the exchanges with the shortest round trips is
//! kept. A later batch, at least [`MIN_DRIFT_SPAN_S`] of sensor time after, gives the drift
//! (the offsets' change over the time between). A stamp is unwrapped against the last one seen
//! and mapped to host seconds.

/// A 24-bit millisecond counter's period, ms.
pub const WRAP_MS: u64 = 1 << 24;

/// Seconds on the host's monotonic clock since the process first asked: the common clock
/// every hardware reading (a lidar scan, a servo position) is stamped on.
pub fn host_now_s() -> f64 {
    static ORIGIN: std::sync::OnceLock<std::time::Instant> = std::sync::OnceLock::new();
    ORIGIN.get_or_init(std::time::Instant::now).elapsed().as_secs_f64()
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
pub const MIN_DRIFT_SPAN_S: f64 = 5.0;

/// The relation host = anchor_host + (1 + drift) x (sensor - anchor_sensor), in seconds.
#[derive(Debug, Clone, Copy, PartialEq)]
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
}

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
        Ok(Self { anchor_sensor_s, anchor_host_s, drift: 0.0, round_trip_s, unwrap })
    }

    /// Takes a later batch: a new anchor and, when it is far enough from the last, the drift.
    pub fn refine(&mut self, exchanges: &[Exchange]) -> Result<(), ClockError> {
        let (s, h, rt) = batch(exchanges, &mut self.unwrap)?;
        let span = s - self.anchor_sensor_s;
        if span >= MIN_DRIFT_SPAN_S {
            self.drift = (h - self.anchor_host_s) / span - 1.0;
        }
        self.anchor_sensor_s = s;
        self.anchor_host_s = h;
        self.round_trip_s = rt;
        Ok(())
    }

    /// The host time of a sensor stamp (24 bits), seconds. Stamps must come in time order
    /// (each within half a period of the last), as a scan stream's do.
    pub fn host_s(&mut self, sensor_ms: u32) -> f64 {
        let t = self.unwrap.unwrap(sensor_ms) as f64 * 1e-3;
        self.anchor_host_s + (1.0 + self.drift) * (t - self.anchor_sensor_s)
    }
}

/// A batch's anchor (sensor time, host time) and its shortest round trip.
fn batch(exchanges: &[Exchange], unwrap: &mut Unwrap) -> Result<(f64, f64, f64), ClockError> {
    if let Some(e) = exchanges.iter().find(|e| e.received_s.partial_cmp(&e.sent_s).is_none_or(|o| o.is_lt())) {
        return Err(ClockError::Backwards { sent_s: e.sent_s, received_s: e.received_s });
    }
    let pts: Vec<(f64, f64, f64)> = exchanges
        .iter()
        .map(|e| {
            let s = unwrap.unwrap(e.sensor_ms) as f64 * 1e-3;
            (s, (e.sent_s + e.received_s) / 2.0 - s, e.received_s - e.sent_s)
        })
        .collect();
    let shortest = pts.iter().map(|p| p.2).fold(f64::INFINITY, f64::min);
    if !shortest.is_finite() {
        return Err(ClockError::Empty);
    }
    // The exchanges that were quick: their midpoints are the best estimates.
    let mut good: Vec<(f64, f64)> =
        pts.iter().filter(|p| p.2 <= 1.5 * shortest + 2e-4).map(|p| (p.0, p.1)).collect();
    good.sort_by(|a, b| a.1.total_cmp(&b.1));
    let (s, offset) = good[good.len() / 2];
    Ok((s, s + offset, shortest))
}

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

    /// A sensor clock with an offset, a drift of 80 ppm and a wrap during the scans: beam
    /// stamps mapped to host time within 1 ms of the truth, with each exchange delayed by
    /// 0.2-1.0 ms each way (a LAN or a USB link). Two batches 30 s apart give the drift.
    #[test]
    fn offset_drift_and_wrap_give_stamps_within_a_millisecond() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let drift = 80e-6;
        let start_ms = WRAP_MS as f64 - 40_000.0; // the counter wraps 40 s in
                                                  // The sensor's count at host time h (it started at host time 100 s).
        let sensor_at = |h: f64| (start_ms + (h - 100.0) / (1.0 + drift) * 1e3).floor() as u64 % WRAP_MS;
        let mut batch_at = |t0: f64| -> Vec<Exchange> {
            (0..10)
                .map(|k| {
                    let sent_s = t0 + 0.01 * k as f64;
                    let (up, down) = (rng.random_range(0.0002..0.001), rng.random_range(0.0002..0.001));
                    Exchange {
                        sent_s,
                        sensor_ms: sensor_at(sent_s + up) as u32,
                        received_s: sent_s + up + down,
                    }
                })
                .collect()
        };
        let mut sync = ClockSync::fit(&batch_at(100.0)).expect("a fit");
        // Scans of the first sweep, 6 s, before any drift is known.
        for k in 0..240 {
            let truth = 100.2 + 0.025 * k as f64;
            let got = sync.host_s(sensor_at(truth) as u32);
            assert!((got - truth).abs() < 1e-3, "scan {k}: {got} for {truth}");
        }
        sync.refine(&batch_at(130.0)).expect("a second batch");
        assert!((sync.drift - drift).abs() < 20e-6, "drift {}", sync.drift);
        // The next 20 s of scans, across the wrap at 140 s.
        for k in 0..800 {
            let truth = 130.2 + 0.025 * k as f64;
            let got = sync.host_s(sensor_at(truth) as u32);
            assert!((got - truth).abs() < 1e-3, "scan {k}: {got} for {truth}");
        }
        assert_eq!(ClockSync::fit(&[]), Err(ClockError::Empty));
        let backwards = Exchange { sent_s: 2.0, sensor_ms: 0, received_s: 1.0 };
        assert!(ClockSync::fit(&[backwards]).is_err());
    }
}
