//! The Dynamixel MX-64 tilting the lidar: a constant-speed sweep, and its encoder readings
//! quantized to 4096 ticks per revolution.

use crate::scenario::LidarSpec;

/// One tilt sweep from `start` to `end` at constant speed, with the encoder's quantization.
#[derive(Debug, Clone, PartialEq)]
pub struct TiltSweep {
    start_rad: f64,
    end_rad: f64,
    speed_radps: f64,
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
            tick_rad: std::f64::consts::TAU / s.servo_ticks_per_rev as f64,
            rows,
            row_period_s: s.row_period_s,
        }
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
