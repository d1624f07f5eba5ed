//! The lidar head's path while the robot moves, for a sweep taken on the way: its true pose
//! and the robot's belief of it, sampled at the lidar's row period by the simulated robot as
//! it executes and stands, and read by the simulated lidar when the loop asks for a sweep.
//! The belief along a sweep is the robot's own, smoothed back from the sweep's end by its
//! gyro ([`crate::estimate::path`]). The servo runs one pass per look, ending at the look,
//! then swings back to the sweep's start: the next pass's rows begin after that return, and
//! a look that comes before a whole pass waits for it standing ([`HeadTrack::whole_at_s`]).
//! A sweep taken standing instead (a look again standing, a look that did not wait for a
//! whole pass) is the lidar spec's own; the paper's runs from level down, so it starts where
//! a pass ends and ends where the next starts ([`HeadTrack::drop_pass`],
//! [`HeadTrack::swept_standing`]).

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
    /// The servo's way back to the sweep's start after a pass, seconds.
    return_s: f64,
    /// The servo's way from the end of a sweep taken standing to the start of a pass,
    /// seconds (0 for the paper's sweep, which runs from level down).
    after_standing_s: f64,
    /// The servo's way from the end of a pass to the start of a sweep taken standing,
    /// seconds (0 for the paper's sweep: a pass ends level, where it starts).
    before_standing_s: f64,
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
        let sweep = TiltSweep::from_spec(spec);
        Self {
            period_s: spec.row_period_s,
            rows: sweep.rows(),
            return_s: sweep.return_s(),
            after_standing_s: sweep.to_start_of_s(&sweep.clone().level_last()),
            before_standing_s: sweep.clone().level_last().to_start_of_s(&sweep),
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

    /// When the track will hold a whole pass, on the world's clock, seconds: `now_s` when it
    /// does, else when the last row it lacks is due (rows one period apart from the next
    /// due, which may wait for the servo's return).
    pub fn whole_at_s(&self, now_s: f64) -> f64 {
        let missing = self.rows.saturating_sub(self.samples.len());
        if missing == 0 {
            return now_s;
        }
        self.next_s.max(now_s) + (missing - 1) as f64 * self.period_s
    }

    /// The pass that ends at `now_s` ([`HeadTrack::sweep`]; `None` when the track holds less
    /// than a whole one, and the head sweeps standing instead, [`HeadTrack::swept_standing`]).
    /// The servo then swings back to the sweep's start: the next pass's rows are due from
    /// `now_s` plus the return on.
    pub fn take(&mut self, now_s: f64) -> Option<Vec<(Isometry3<f64>, Isometry3<f64>)>> {
        let heads = self.sweep();
        self.samples.clear();
        self.next_s = now_s + self.return_s;
        heads
    }

    /// The pass under way is dropped: the next look is a sweep taken standing
    /// ([`HeadTrack::swept_standing`]), not one along the head's path. Returns the seconds
    /// the servo takes from the pass's end to that sweep's start.
    pub fn drop_pass(&mut self) -> f64 {
        self.samples.clear();
        self.before_standing_s
    }

    /// A sweep was taken standing at `now_s` (instead of a pass along the head's path): the
    /// servo goes on from its end to the start of the next pass, whose rows are due from then
    /// on.
    pub fn swept_standing(&mut self, now_s: f64) {
        self.samples.clear();
        self.next_s = now_s + self.after_standing_s;
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

    /// A head at `x` along the world's x axis.
    fn at(x: f64) -> Isometry3<f64> {
        Isometry3::translation(x, 0.0, 0.0)
    }

    /// The robot's belief of a head at `x`: its base there, the head at the base.
    fn belief(x: f64) -> Belief {
        Belief {
            base: at(x),
            head_in_base: Isometry3::identity(),
            pivot: nalgebra::Point3::new(x, 0.0, 0.0),
            turn: None,
        }
    }

    #[test]
    fn a_sweep_is_the_last_rows_on_the_row_grid() {
        let spec = LidarSpec::default();
        let mut track = HeadTrack::new(&spec);
        let rows = TiltSweep::from_spec(&spec).rows();
        let dt = 0.001;
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

    #[test]
    fn a_pass_taken_starts_the_next_after_the_servos_return() {
        let spec = LidarSpec::default();
        let sweep = TiltSweep::from_spec(&spec);
        let mut track = HeadTrack::new(&spec);
        let dt = 0.001;
        // Steps the clock to `until_s`, recording the head (at x = the time) when due.
        let mut t = 0.0;
        let mut run_to = |track: &mut HeadTrack, until_s: f64| {
            while t + dt / 2.0 < until_s {
                t += dt;
                if track.due(t, dt) {
                    track.record(t, at(t), Some(belief(t)));
                }
            }
            t
        };
        let now = run_to(&mut track, 2.0);
        let whole_at = track.whole_at_s(now);
        assert!(whole_at > now, "two seconds are not a pass");
        let now = run_to(&mut track, whole_at);
        assert_eq!(track.whole_at_s(now), now, "whole when it said");
        let first = track.take(now).expect("a whole pass");
        assert_eq!(first.len(), sweep.rows());
        // Nothing is cast while the servo swings back; the next pass is whole a return and a
        // pass after the look, its first row cast after the return.
        let looked = now;
        assert!(track.sweep().is_none());
        let expected = looked + sweep.return_s() + (sweep.rows() - 1) as f64 * spec.row_period_s;
        assert!((track.whole_at_s(looked) - expected).abs() < 1e-9);
        let whole_at = track.whole_at_s(looked);
        let now = run_to(&mut track, whole_at);
        let second = track.take(now).expect("whole after the return and a pass");
        assert!(second[0].0.translation.x >= looked + sweep.return_s() - dt / 2.0);
        // A look before a whole pass gets none, and starts the servo's return all the same.
        let now = run_to(&mut track, now + 1.0);
        assert!(track.take(now).is_none());
        assert!(!track.due(now + sweep.return_s() - 2.0 * dt, dt));
        // A sweep taken standing instead ends where the next pass starts: no return.
        track.swept_standing(now);
        assert!(track.due(now, dt));
        let whole_at = track.whole_at_s(now);
        assert!((whole_at - (now + (sweep.rows() - 1) as f64 * spec.row_period_s)).abs() < 1e-9);
        // A dropped pass is not whole however far it had come.
        let now = run_to(&mut track, whole_at - 1.0);
        assert_eq!(track.drop_pass(), 0.0, "the pass ended level, where a standing sweep starts");
        assert!(track.take(now).is_none());
        // A lidar whose standing sweep runs from steep to level, as its passes do: the servo
        // goes back to the steep end before a standing sweep, and again after one.
        let steep_first = LidarSpec { tilt_start_deg: 70.0, tilt_end_deg: 10.0, ..spec.clone() };
        let mut other = HeadTrack::new(&steep_first);
        assert!((other.drop_pass() - sweep.return_s()).abs() < 1e-12);
        other.swept_standing(now);
        assert!(!other.due(now + sweep.return_s() - 2.0 * dt, dt) && other.due(now + sweep.return_s(), dt));
    }
}
