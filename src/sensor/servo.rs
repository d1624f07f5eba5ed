//! The Dynamixel MX-64 tilting the lidar: a constant-speed sweep, and its encoder readings
//! quantized to 4096 ticks per revolution.

use crate::scenario::LidarSpec;

/// One tilt sweep from `start` to `end` at constant speed, with the encoder's quantization.
#[derive(Debug, Clone, PartialEq)]
pub struct TiltSweep {
    start_rad: f64,
    end_rad: f64,
    speed_radps: f64,
    return_speed_radps: f64,
    tick_rad: f64,
    rows: usize,
    row_period_s: f64,
}

impl TiltSweep {
    /// The sweep of a (validated) lidar spec.
    pub fn from_spec(s: &LidarSpec) -> Self {
        let start_rad = s.tilt_start_deg.to_radians();
        let end_rad = s.tilt_end_deg.to_radians();
        let speed_radps = s.tilt_speed_dps.to_radians();
        let duration_s = (end_rad - start_rad).abs() / speed_radps;
        let rows = ((duration_s / s.row_period_s).round() as usize).max(1);
        Self {
            start_rad,
            end_rad,
            speed_radps,
            return_speed_radps: s.tilt_return_speed_dps.to_radians(),
            tick_rad: std::f64::consts::TAU / s.servo_ticks_per_rev as f64,
            rows,
            row_period_s: s.row_period_s,
        }
    }

    /// The same sweep run from its steeper end to the one nearer level (the smaller tilt
    /// either way of level): the pass a head that sweeps as it walks takes, so that the
    /// shallow rows, which cross the space just ahead of the head and chest, are the newest
    /// at the sweep's end, cast from nearest where the head then stands. Unchanged when the
    /// sweep already ends nearer level (one that crosses level may so end looking up).
    pub fn level_last(mut self) -> Self {
        if self.end_rad.abs() > self.start_rad.abs() {
            std::mem::swap(&mut self.start_rad, &mut self.end_rad);
        }
        self
    }

    /// Rows in the sweep (one every row period while the servo moves).
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Stamp of row `k`, seconds after the sweep's start.
    pub fn row_stamp_s(&self, k: usize) -> f64 {
        self.row_period_s * k as f64
    }

    /// Duration of the sweep, seconds.
    pub fn duration_s(&self) -> f64 {
        (self.end_rad - self.start_rad).abs() / self.speed_radps
    }

    /// Time the servo takes back from the sweep's end to its start, between two passes,
    /// seconds.
    pub fn return_s(&self) -> f64 {
        self.to_start_of_s(self)
    }

    /// Time the servo takes at its return speed from this sweep's end to where `next`
    /// starts, seconds: a sweep taken standing from level down ends where a pass run level
    /// last ([`TiltSweep::level_last`]) starts, and none is needed.
    pub fn to_start_of_s(&self, next: &TiltSweep) -> f64 {
        (next.start_rad - self.end_rad).abs() / self.return_speed_radps
    }

    /// The true (continuous) tilt at time `t_s` after the start, radians.
    pub fn tilt_at(&self, t_s: f64) -> f64 {
        let travelled = (self.speed_radps * t_s).clamp(0.0, (self.end_rad - self.start_rad).abs());
        self.start_rad + travelled * (self.end_rad - self.start_rad).signum()
    }

    /// What the encoder reports at time `t_s`: the tilt rounded to a whole tick.
    pub fn reading_at(&self, t_s: f64) -> f64 {
        self.quantize(self.tilt_at(t_s))
    }

    /// An angle rounded to the encoder's ticks.
    pub fn quantize(&self, angle_rad: f64) -> f64 {
        (angle_rad / self.tick_rad).round() * self.tick_rad
    }

    /// One encoder tick, radians.
    pub fn tick_rad(&self) -> f64 {
        self.tick_rad
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sweep_run_level_last_ends_at_the_tilt_nearer_level() {
        let spec = LidarSpec::default();
        let forward = TiltSweep::from_spec(&spec);
        let back = forward.clone().level_last();
        let end_s = forward.duration_s();
        assert_eq!(back.rows(), forward.rows());
        assert!((back.tilt_at(0.0) - forward.tilt_at(end_s)).abs() < 1e-12);
        assert!((back.tilt_at(end_s) - forward.tilt_at(0.0)).abs() < 1e-12);
        assert!(back.tilt_at(end_s).abs() < back.tilt_at(0.0).abs());
        // A sweep that already ends nearer level is kept: so is one crossing level whose end,
        // 20 degrees above level, is nearer it than its start (it ends looking up).
        assert_eq!(back.clone().level_last(), back);
        let up = LidarSpec { tilt_start_deg: 60.0, tilt_end_deg: -20.0, ..LidarSpec::default() };
        assert_eq!(TiltSweep::from_spec(&up).level_last(), TiltSweep::from_spec(&up));
        let crossing = LidarSpec { tilt_start_deg: -20.0, tilt_end_deg: 60.0, ..LidarSpec::default() };
        let crossing = TiltSweep::from_spec(&crossing).level_last();
        assert!((crossing.tilt_at(crossing.duration_s()) + 20f64.to_radians()).abs() < 1e-12);
    }

    #[test]
    fn the_servo_returns_over_the_sweeps_range_at_its_return_speed() {
        let spec = LidarSpec { tilt_return_speed_dps: 40.0, ..LidarSpec::default() };
        // 60 degrees back at 40 degrees a second, whichever way the sweep runs.
        assert!((TiltSweep::from_spec(&spec).return_s() - 1.5).abs() < 1e-12);
        assert!((TiltSweep::from_spec(&spec).level_last().return_s() - 1.5).abs() < 1e-12);
        // From a standing sweep's end (steep) a pass run level last starts where it is; from
        // that pass's end (level) a standing sweep starts where it is too.
        let standing = TiltSweep::from_spec(&spec);
        let walking = standing.clone().level_last();
        assert_eq!(standing.to_start_of_s(&walking), 0.0);
        assert_eq!(walking.to_start_of_s(&standing), 0.0);
        assert!((walking.to_start_of_s(&walking) - 1.5).abs() < 1e-12);
    }
}
