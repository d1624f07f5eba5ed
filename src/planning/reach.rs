//! The leading leg's reach at its touchdown, measured on the tracked trajectory. The gait
//! places the CoM waypoint of each step's first touchdown from a model of the legs (the hip
//! over the trailing ankle, the distance to the leading ankle taken along the ascent); the
//! IK, holding the CoM over the trailing ankle while the leading leg reaches forward, puts
//! the hip 6-7 cm behind it and 11-13 cm to the side of the leading ankle, so the leading
//! leg lands all but straight, farther from its hip than the model allows, on low rises
//! with deep treads (regression `leading-leg-landed-straight`). A straight leg is a strut:
//! the touchdown's impact runs along it and the sole slides at the first tick.
//! [`touchdown_drops_m`] measures how far each touchdown's waypoint must come down for the
//! leg to land within its reach; the planner lowers it and tracks again (a round to be
//! tracked again stops once its touchdowns are measured, [`touchdown_drop_m`] each as the
//! tracking reaches it).

use super::gait::{Phase, Segment};
use super::motion::JointTrajectory;
use super::PlanError;
use crate::robot::{Kinematics, RobotModel};

/// How far each stance's touchdown waypoint must come down for the leading (right) leg to
/// land no farther from its hip than `reach_m`, metres (0 where it already does), in the
/// configuration `trajectory` reaches at the end of each stance's [`Phase::SwingRight`]
/// (hip pitch axis to ankle pitch axis, in three dimensions). Stances without that segment
/// get 0. Refuses a stance whose hip is farther from the ankle than `reach_m` horizontally
/// alone (no height reaches it).
pub fn touchdown_drops_m(
    model: &RobotModel,
    segments: &[Segment],
    trajectory: &JointTrajectory,
    reach_m: f64,
) -> Result<Vec<f64>, PlanError> {
    let stances = segments.iter().map(|s| s.stance + 1).max().unwrap_or(0);
    let mut drops = vec![0.0; stances];
    let mut kin = Kinematics::new(model);
    for (i, seg) in segments.iter().enumerate().filter(|(_, s)| s.phase == Phase::SwingRight) {
        let Some(landed) = trajectory.samples.iter().rev().find(|s| s.segment == i) else { continue };
        drops[seg.stance] = touchdown_drop_m(model, &mut kin, seg, &landed.q, reach_m)?;
    }
    Ok(drops)
}

/// How far the touchdown waypoint of `seg` (a [`Phase::SwingRight`]) must come down for the
/// leading leg, landed at configuration `landed_q` (`kin` computes it), to be within
/// `reach_m` of its hip ([`touchdown_drops_m`] for one segment).
pub fn touchdown_drop_m(
    model: &RobotModel,
    kin: &mut Kinematics,
    seg: &Segment,
    landed_q: &[f64],
    reach_m: f64,
) -> Result<f64, PlanError> {
    let (hip, ankle) = (model.joint_link("R_HIP_P")?, model.joint_link("R_ANKLE_P")?);
    kin.update(landed_q)?;
    let d = kin.link_pose(hip).translation.vector - kin.link_pose(ankle).translation.vector;
    let across_m = d.xy().norm();
    if across_m >= reach_m {
        return Err(PlanError::TouchdownReach { stance: seg.stance, across_m, reach_m });
    }
    Ok((d.z - (reach_m * reach_m - across_m * across_m).sqrt()).max(0.0))
}
