//! The lidar head's path while the robot moves, for a sweep taken on the way: its true pose
//! and the robot's belief of it, sampled at the lidar's row period by the simulated robot as
//! it executes and stands, and read by the simulated lidar when the loop asks for a sweep.
//! The belief along a sweep is the robot's own, smoothed back from the sweep's end by its
//! gyro ([`crate::estimate::path`]).

use crate::estimate::path::{smoothed_heads, Belief, GyroTurn};
use crate::scenario::LidarSpec;
use crate::sensor::TiltSweep;
use nalgebra::{Isometry3, Vector3};
use std::collections::VecDeque;

/// The head's last sweep's worth of poses, one per lidar row period.
#[derive(Debug, Clone)]
pub struct HeadTrack {
    /// Between two samples, seconds (the lidar's row period).
    period_s: f64,
    /// Samples kept: a sweep's rows.
    rows: usize,
    /// When the next sample is due, on the world's clock, seconds.
    next_s: f64,
    /// (true head pose, the robot's belief), oldest first.
    samples: VecDeque<(Isometry3<f64>, Belief)>,
    /// The gyro's readings integrated, once the robot reads one.
    gyro: Option<GyroTurn>,
}

impl HeadTrack {
    /// An empty track for the sweeps of `spec`'s lidar.
    pub fn new(spec: &LidarSpec) -> Self {
        let rows = TiltSweep::from_spec(spec).rows();
        Self {
            period_s: spec.row_period_s,
            rows,
            next_s: f64::NEG_INFINITY,
            samples: VecDeque::new(),
            gyro: None,
        }
    }

    /// A reading of the robot's gyro (base axes, its bias taken off) held for `dt_s`: the
    /// beliefs recorded from now on carry the base's turn.
    pub fn turn_by(&mut self, rate_rad_s: &Vector3<f64>, dt_s: f64) {
        self.gyro.get_or_insert_with(GyroTurn::default).add(rate_rad_s, dt_s);
    }

    /// Whether a sample is due at `t_s` (a physics step of `dt_s` ends there).
    pub fn due(&self, t_s: f64, dt_s: f64) -> bool {
        t_s + dt_s / 2.0 >= self.next_s
    }

    /// The head at `t_s`: where it is, and the robot's belief (its `turn` is the track's
    /// gyro's; `None`: the belief failed; the track starts again, a sweep has to be a whole
    /// one).
    pub fn record(&mut self, t_s: f64, truth: Isometry3<f64>, believed: Option<Belief>) {
        // On the row grid; a gap (a clock that jumped) starts it anew from here.
        self.next_s =
            if t_s - self.next_s > self.period_s { t_s + self.period_s } else { self.next_s + self.period_s };
        let Some(believed) = believed else {
            self.samples.clear();
            return;
        };
        let turn = self.gyro.map(|g| g.orientation());
        self.samples.push_back((truth, Belief { turn, ..believed }));
        while self.samples.len() > self.rows {
            self.samples.pop_front();
        }
    }

    /// A registration moved the robot's estimate by `offset` (in the world): the beliefs
    /// already recorded move with it.
    pub fn correct(&mut self, offset: &Isometry3<f64>) {
        for (_, believed) in &mut self.samples {
            believed.base = offset * believed.base;
            believed.pivot = offset * believed.pivot;
        }
    }

    /// The last sweep's worth of heads, oldest first, when the track holds that many: each
    /// true pose, and where the robot believed the head was, smoothed back from the last
    /// ([`smoothed_heads`]).
    pub fn sweep(&self) -> Option<Vec<(Isometry3<f64>, Isometry3<f64>)>> {
        if self.samples.len() != self.rows {
            return None;
        }
        let beliefs: Vec<Belief> = self.samples.iter().map(|(_, b)| *b).collect();
        Some(self.samples.iter().map(|(t, _)| *t).zip(smoothed_heads(&beliefs)).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sweep_is_the_last_rows_on_the_row_grid() {
        let spec = LidarSpec::default();
        let mut track = HeadTrack::new(&spec);
        let rows = TiltSweep::from_spec(&spec).rows();
        let dt = 0.001;
        let at = |x: f64| Isometry3::translation(x, 0.0, 0.0);
        let belief = |x: f64| Belief {
            base: at(x),
            head_in_base: Isometry3::identity(),
            pivot: nalgebra::Point3::new(x, 0.0, 0.0),
            turn: None,
        };
        let mut t = 0.0;
        let mut sampled = Vec::new();
        while sampled.len() < rows + 10 {
            t += dt;
            if track.due(t, dt) {
                track.record(t, at(t), Some(belief(-t)));
                sampled.push(t);
            }
            if sampled.len() == rows - 1 {
                assert!(track.sweep().is_none(), "not a whole sweep yet");
            }
        }
        let sweep = track.sweep().expect("a whole sweep");
        assert_eq!(sweep.len(), rows);
        // The newest last, one row period apart.
        let last = sampled[sampled.len() - 1];
        assert!((sweep[rows - 1].0.translation.x - last).abs() < 1e-12);
        let gap = sweep[1].0.translation.x - sweep[0].0.translation.x;
        assert!((gap - spec.row_period_s).abs() < dt, "{gap}");
        // A correction moves the beliefs only; a failed belief starts the track again.
        track.correct(&Isometry3::translation(0.0, 0.0, 1.0));
        let moved = track.sweep().expect("still whole");
        assert_eq!(moved[0].0, sweep[0].0);
        assert!((moved[0].1.translation.z - sweep[0].1.translation.z - 1.0).abs() < 1e-12);
        track.record(t + spec.row_period_s, at(0.0), None);
        assert!(track.sweep().is_none());
    }
}
