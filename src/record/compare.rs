//! A recording replayed through the loop's own pieces ([`replay`]): perception rerun on each
//! sweep's raw rows (not the recorded cloud), the views merged into the step map as the loop
//! merges them (registered on the robot's own estimate), and the next plan made again from the
//! recorded configuration, each compared with what was recorded at the time, as typed verdicts.

use super::messages::PlanMsg;
use super::replay::{RecordedSweep, Recording};
use crate::climb::{add_view, feet_height_m, moved_view, plan_next, take_view, ViewInput};
use crate::params::ClimbParams;
use crate::perception::step_map::StepMap;
use crate::perception::surroundings::Surroundings;
use crate::perception::{perceive, PerceptionError, PlaneSegment};
use crate::robot::model::RobotModel;
use crate::sensor::{AssembleParams, SensorError};

/// Perception now against perception then.
#[derive(Debug, Clone, PartialEq)]
pub enum PerceptionVerdict {
    /// Nothing was recorded to compare with.
    NotRecorded,
    /// No staircase, then and now (why, now).
    SameNoStaircase(String),
    /// The same rectangles, corner for corner.
    SameRectangles,
    /// The same count, corners moved by up to this, metres.
    Moved(f64),
    /// Another count of rectangles.
    Count {
        /// Found now.
        now: usize,
        /// Recorded.
        then: usize,
    },
    /// Perception failed now (why) where it found `then` rectangles.
    FailedNow {
        /// Why.
        error: String,
        /// Recorded.
        then: usize,
    },
}

/// The plan made now against the plan recorded then.
#[derive(Debug, Clone, PartialEq)]
pub enum PlanVerdict {
    /// The recorded plan has no usable start configuration.
    NoStartConfiguration,
    /// Refused now (the refusal's message).
    RefusedNow(String),
    /// The same footholds, segments and (when recorded) q(t).
    Same {
        /// Stances planned.
        stances: usize,
        /// Its motion, seconds.
        duration_s: f64,
        /// Whether q(t) was recorded (and so compared).
        q_recorded: bool,
    },
    /// The same footholds and segments, another joint trajectory.
    OtherTrajectory,
    /// Another plan: what differs first, and the two motions' durations.
    Different {
        /// What differs.
        what: String,
        /// Now, seconds.
        now_s: f64,
        /// Recorded, seconds.
        then_s: f64,
    },
}

impl PerceptionVerdict {
    /// Whether now differs from then.
    pub fn differs(&self) -> bool {
        matches!(self, Self::Moved(_) | Self::Count { .. } | Self::FailedNow { .. })
    }
}

impl PlanVerdict {
    /// Whether now differs from then.
    pub fn differs(&self) -> bool {
        !matches!(self, Self::Same { .. })
    }
}

/// One sweep replayed.
#[derive(Debug, Clone)]
pub struct SweepReplay {
    /// When it was taken, seconds.
    pub stamp_s: f64,
    /// Its rows.
    pub rows: usize,
    /// Points in its cloud.
    pub points: usize,
    /// Rectangles perception finds now.
    pub rectangles: usize,
    /// Against the recorded ones.
    pub perception: PerceptionVerdict,
    /// A step the step map leaves for a closer look (its height and the depth seen, metres).
    pub deferred: Option<[f64; 2]>,
    /// The refusal a walk to look again answers, when the plan made now is one.
    pub closer_look: Option<String>,
    /// The plan made now against the recorded one (none when no plan followed the sweep or
    /// perception failed now).
    pub plan: Option<PlanVerdict>,
}

impl SweepReplay {
    /// Whether anything differs from the recording.
    pub fn differs(&self) -> bool {
        self.perception.differs() || self.plan.as_ref().is_some_and(PlanVerdict::differs)
    }
}

fn corners_of(s: &PlaneSegment) -> [[f64; 3]; 4] {
    s.corners().map(|p| [p.x, p.y, p.z])
}

/// The largest corner distance between two lists of rectangles, metres (`None` when their
/// counts differ).
fn difference_m(a: &[[[f64; 3]; 4]], b: &[[[f64; 3]; 4]]) -> Option<f64> {
    (a.len() == b.len()).then(|| {
        a.iter()
            .zip(b)
            .flat_map(|(x, y)| x.iter().zip(y))
            .map(|(p, q)| ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt())
            .fold(0.0, f64::max)
    })
}

/// Replays every sweep of `rec` with `params` on the robot `model`, in order.
pub fn replay(
    rec: &Recording,
    params: &ClimbParams,
    model: &RobotModel,
) -> Result<Vec<SweepReplay>, SensorError> {
    let mut map = StepMap::default();
    let mut around = Surroundings::default();
    // The floor the climb started from, as the loop took it: the feet at the first plan.
    let start_floor_z_m = rec
        .sweeps
        .iter()
        .find_map(|s| s.plan.as_ref())
        .map_or(f64::NAN, |first| feet_height_m(model, &first.q0));
    let mut out = Vec::with_capacity(rec.sweeps.len());
    for RecordedSweep { stamp_s, sweep, perception, view, plan: planned, trajectory, .. } in &rec.sweeps {
        let mut cloud = sweep.assemble(&AssembleParams::default())?;
        let now = perceive(&cloud, &params.perception);
        let found: Vec<[[f64; 3]; 4]> =
            now.as_ref().map(|r| r.segments.iter().map(corners_of).collect()).unwrap_or_default();
        let then: Option<Vec<[[f64; 3]; 4]>> =
            perception.as_ref().map(|m| m.segments.iter().map(corners_of).collect());
        let recorded_error = perception.as_ref().and_then(|m| m.error.as_deref());
        let verdict = match (&then, &now) {
            (None, _) => PerceptionVerdict::NotRecorded,
            (Some(_), Err(e)) if recorded_error.is_some() => {
                PerceptionVerdict::SameNoStaircase(e.to_string())
            }
            (Some(t), Ok(_)) => match difference_m(t, &found) {
                Some(0.0) => PerceptionVerdict::SameRectangles,
                Some(d) => PerceptionVerdict::Moved(d),
                None => PerceptionVerdict::Count { now: found.len(), then: t.len() },
            },
            (Some(t), Err(e)) => PerceptionVerdict::FailedNow { error: e.to_string(), then: t.len() },
        };
        let mut replayed = SweepReplay {
            stamp_s: *stamp_s,
            rows: sweep.rows.len(),
            points: cloud.len(),
            rectangles: found.len(),
            perception: verdict,
            deferred: None,
            closer_look: None,
            plan: None,
        };
        // The loop's next steps: the step map's next input, planned from the recorded pose.
        let mut seen = match now {
            Ok(r) => r.segments,
            Err(PerceptionError::NoStaircase(_)) => Vec::new(),
            Err(_) => {
                out.push(replayed);
                continue;
            }
        };
        // On the robot's own estimate the loop registered each view on the step map and moved
        // it (the robot with it: the recorded plan starts there): so does the replay.
        let viewpoint = nalgebra::Point3::from(sweep.mount_to_world.translation.vector);
        if let Some(offset) =
            params.estimate.enabled.then(|| map.register(&seen, &viewpoint, &params.step_map)).flatten()
        {
            let (moved, moved_cloud) = moved_view(&offset, seen, &mut sweep.clone());
            seen = moved;
            if let Some(c) = moved_cloud {
                cloud = c;
            }
        }
        let Some(then) = planned else {
            // No plan followed this sweep (the top, a refusal, a look set aside to look again
            // standing): the loop still took its view, into the surroundings too, from the
            // configuration recorded with it; the steps of a look set aside left the map again.
            // A recording without it (made before `/run/view` was recorded) gives the map the
            // view alone.
            match view.as_ref().filter(|v| v.q.len() == model.nq()) {
                Some(v) if v.set_aside => add_view(&mut around, &cloud, model, &v.q, &params.surroundings),
                Some(v) => {
                    take_view(&mut map, &mut around, seen, &cloud, model, &v.q, params.loop_params());
                }
                None => map.update(seen, &params.step_map),
            }
            out.push(replayed);
            continue;
        };
        if then.q0.len() != model.nq() {
            replayed.plan = Some(PlanVerdict::NoStartConfiguration);
            out.push(replayed);
            continue;
        }
        let ViewInput { next, surfaces } =
            take_view(&mut map, &mut around, seen, &cloud, model, &then.q0, params.loop_params());
        replayed.deferred = next.deferred.as_ref().map(|top| [top.height_m(), top.depth_m()]);
        // As many stances as were planned then (the loop plans a few per scan, a rehearsal all
        // it sees).
        let stances = then.stances.len();
        replayed.plan =
            Some(match plan_next(model, &then.q0, &next, surfaces, stances, start_floor_z_m, &params.plan) {
                Err(e) => PlanVerdict::RefusedNow(e.message),
                Ok((p, closer_look)) => {
                    replayed.closer_look = closer_look.map(|r| r.message);
                    let now = PlanMsg::of(then.start_s, &next.ahead, &p);
                    let same_q = trajectory.as_ref().is_none_or(|t| {
                        t.q.len() == p.trajectory.samples.len()
                            && t.q.iter().zip(&p.trajectory.samples).all(|(a, b)| *a == b.q)
                    });
                    match now.differs_from(then) {
                        None if !same_q => PlanVerdict::OtherTrajectory,
                        None => PlanVerdict::Same {
                            stances: p.stances.len(),
                            duration_s: p.duration_s(),
                            q_recorded: trajectory.is_some(),
                        },
                        Some(k) => PlanVerdict::Different {
                            what: k.to_string(),
                            now_s: now.duration_s,
                            then_s: then.duration_s,
                        },
                    }
                }
            });
        out.push(replayed);
    }
    Ok(out)
}
