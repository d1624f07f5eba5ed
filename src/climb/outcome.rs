//! Outcomes as data: every check the execution makes, with what it measured and the limit it
//! held it to ([`Check`]), a violation's instant and cycle ([`Violation`]), and why a climb
//! stopped ([`StopReason`]). The terminal table, the JSON report, the MCAP `/checks` topic and
//! `regress`'s tables are rendered from these; nothing reads a message back.

use crate::perception::NoStaircase;
use crate::planning::{Foot, Refusal};
use serde::{Deserialize, Serialize};
use std::fmt;

/// A warning MuJoCo counts in `mjData.warning` (its `mjtWarning`): the physics was asked
/// something it could not do, and what followed is not to be trusted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SimWarning {
    /// A body's inertia is too small or violates the triangle inequality.
    Inertia,
    /// Too many contacts for the preallocated buffer: some were dropped.
    ContactFull,
    /// Too many constraints for the preallocated buffer.
    ConstraintFull,
    /// A position is not finite or too large; MuJoCo reset the state.
    BadQpos,
    /// A velocity is not finite or too large; MuJoCo reset the state.
    BadQvel,
    /// An acceleration is not finite or too large; MuJoCo reset the state.
    BadQacc,
    /// A control is not finite or too large.
    BadCtrl,
}

impl SimWarning {
    /// Every warning, in `mjtWarning`'s order (index = MuJoCo's number).
    pub const ALL: [SimWarning; 7] = [
        SimWarning::Inertia,
        SimWarning::ContactFull,
        SimWarning::ConstraintFull,
        SimWarning::BadQpos,
        SimWarning::BadQvel,
        SimWarning::BadQacc,
        SimWarning::BadCtrl,
    ];
}

/// Which check (the `check` key of a violation in JSON).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CheckKind {
    /// The CoM inside the static-stability polygon of the feet in contact.
    Margin,
    /// A loaded foot's resultant inside its friction pyramid.
    Friction,
    /// A foot's centre of pressure inside its sole.
    Cop,
    /// Joint torque demand within the limit.
    Torque,
    /// Joint speed within the limit.
    Speed,
    /// A swing foot lands at its target.
    Touchdown,
    /// A sole in contact stays where it came down.
    Slip,
    /// A landed sole stays on its step's tread.
    OffStep,
    /// A swinging foot touches nothing before its descent.
    Strike,
    /// No part but the soles touches the world.
    Collision,
    /// The robot stays up.
    Fall,
    /// The physics stays sound (MuJoCo's warnings).
    Unstable,
}

impl CheckKind {
    /// The name used in JSON and tables.
    pub fn name(self) -> &'static str {
        match self {
            CheckKind::Margin => "margin",
            CheckKind::Friction => "friction",
            CheckKind::Cop => "cop",
            CheckKind::Torque => "torque",
            CheckKind::Speed => "speed",
            CheckKind::Touchdown => "touchdown",
            CheckKind::Slip => "slip",
            CheckKind::OffStep => "off_step",
            CheckKind::Strike => "strike",
            CheckKind::Collision => "collision",
            CheckKind::Fall => "fall",
            CheckKind::Unstable => "unstable",
        }
    }
}

impl fmt::Display for CheckKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A violated check with what it measured. Lengths in metres, forces in newtons, torques in
/// newton metres, angles in radians.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "check", rename_all = "snake_case")]
pub enum Check {
    /// The CoM's margin inside the polygon of the feet in contact below the least allowed.
    Margin {
        /// The margin (negative outside; `None` when the feet in contact give no polygon).
        margin_m: Option<f64>,
        /// The least margin allowed.
        limit_m: f64,
        /// Which feet carried load (right, left).
        feet_down: [bool; 2],
    },
    /// A loaded foot's tangential force beyond the friction pyramid.
    Friction {
        /// Which foot.
        foot: Foot,
        /// Tangential force along the sole's x and y axes.
        tangential_n: [f64; 2],
        /// Normal force.
        normal_n: f64,
        /// The friction coefficient judged against: the surface's true one.
        limit: f64,
        /// The coefficient the plan assumed (`plan.step.friction`, its pyramids): above
        /// `limit`, the plan asked for friction the surface does not have. `None` in reports
        /// written before it was recorded.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        planned_mu: Option<f64>,
    },
    /// A foot's centre of pressure outside its sole.
    Cop {
        /// Which foot.
        foot: Foot,
        /// The centre of pressure in the sole frame (x, y).
        cop_m: [f64; 2],
        /// The sole's half length and half width.
        half_m: [f64; 2],
        /// How far outside it may lie (numerical slack).
        tolerance_m: f64,
    },
    /// A joint's torque demand beyond its allowed share of the limit.
    Torque {
        /// The joint.
        joint: String,
        /// The servo's unclamped demand (absolute).
        demand_nm: f64,
        /// The joint's torque limit.
        limit_nm: f64,
        /// The allowed fraction of the limit.
        max_ratio: f64,
    },
    /// A joint's speed beyond its allowed share of the limit.
    Speed {
        /// The joint.
        joint: String,
        /// The speed (absolute), rad/s.
        speed_rad_s: f64,
        /// The joint's speed limit, rad/s.
        limit_rad_s: f64,
        /// The allowed fraction of the limit.
        max_ratio: f64,
    },
    /// A swing foot landed away from its target.
    Touchdown {
        /// Which foot.
        foot: Foot,
        /// Position error.
        error_m: f64,
        /// Yaw error.
        yaw_error_rad: f64,
        /// Largest position error allowed.
        limit_m: f64,
        /// Largest yaw error allowed.
        limit_yaw_rad: f64,
    },
    /// A sole in contact slid.
    Slip {
        /// Which foot.
        foot: Foot,
        /// Horizontal distance from where it came down.
        slip_m: f64,
        /// The most allowed.
        limit_m: f64,
    },
    /// A landed sole overhangs its step's tread.
    OffStep {
        /// Which foot.
        foot: Foot,
        /// The overhang.
        overhang_m: f64,
        /// The most allowed.
        limit_m: f64,
    },
    /// A swinging foot hit something other than a level face between its lift-off and its
    /// landing.
    Strike {
        /// Which foot.
        foot: Foot,
        /// What it hit (the world's geom name).
        geom: String,
        /// Where, in its planned sole frame.
        at_m: [f64; 3],
        /// Its planned height above its target at the time (below it, negative, while it
        /// lifts toward a higher tread).
        above_target_m: f64,
        /// Its planned sole's distance from the nearer of its lift-off and its target.
        #[serde(default)]
        from_ends_m: f64,
        /// Contacts within this distance of the lift-off or the target are the lift-off and
        /// the landing, not strikes.
        limit_m: f64,
    },
    /// A part other than the soles touched the world (or the robot touched itself).
    Collision {
        /// The robot's geom.
        geom: String,
        /// What it touched.
        other: String,
    },
    /// The robot fell.
    Fall {
        /// The base's height.
        base_z_m: f64,
        /// The lowest the base may be.
        min_base_z_m: f64,
        /// Tilt from the plan's base orientation.
        tilt_rad: f64,
        /// Largest tilt allowed.
        limit_tilt_rad: f64,
        /// Tilt from upright.
        upright_tilt_rad: f64,
    },
    /// MuJoCo counted a warning during the step: the physics is not to be trusted.
    Unstable {
        /// Which warning.
        warning: SimWarning,
        /// How many times so far.
        count: i32,
        /// MuJoCo's extra information (often the index of the offending coordinate).
        info: i32,
    },
}

/// A measured value against its limit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measure {
    /// What was measured.
    pub value: f64,
    /// The limit it was held to.
    pub limit: f64,
    /// Unit of both (`m`, `rad`, `N m`, `ratio`, `count`).
    pub unit: &'static str,
}

impl Check {
    /// Which check this is.
    pub fn kind(&self) -> CheckKind {
        match self {
            Check::Margin { .. } => CheckKind::Margin,
            Check::Friction { .. } => CheckKind::Friction,
            Check::Cop { .. } => CheckKind::Cop,
            Check::Torque { .. } => CheckKind::Torque,
            Check::Speed { .. } => CheckKind::Speed,
            Check::Touchdown { .. } => CheckKind::Touchdown,
            Check::Slip { .. } => CheckKind::Slip,
            Check::OffStep { .. } => CheckKind::OffStep,
            Check::Strike { .. } => CheckKind::Strike,
            Check::Collision { .. } => CheckKind::Collision,
            Check::Fall { .. } => CheckKind::Fall,
            Check::Unstable { .. } => CheckKind::Unstable,
        }
    }

    /// The main value measured and its limit (`None` for a collision: touching is the fault).
    pub fn measure(&self) -> Option<Measure> {
        let m = |value: f64, limit: f64, unit: &'static str| Some(Measure { value, limit, unit });
        match self {
            Check::Margin { margin_m, limit_m, .. } => {
                m(margin_m.unwrap_or(f64::NEG_INFINITY), *limit_m, "m")
            }
            Check::Friction { tangential_n, normal_n, limit, .. } => {
                m(tangential_n[0].abs().max(tangential_n[1].abs()) / normal_n, *limit, "ratio")
            }
            Check::Cop { cop_m, half_m, tolerance_m, .. } => {
                m((cop_m[0].abs() - half_m[0]).max(cop_m[1].abs() - half_m[1]), *tolerance_m, "m")
            }
            Check::Torque { demand_nm, limit_nm, max_ratio, .. } => {
                m(demand_nm / limit_nm, *max_ratio, "ratio")
            }
            Check::Speed { speed_rad_s, limit_rad_s, max_ratio, .. } => {
                m(speed_rad_s / limit_rad_s, *max_ratio, "ratio")
            }
            Check::Touchdown { error_m, limit_m, .. } => m(*error_m, *limit_m, "m"),
            Check::Slip { slip_m, limit_m, .. } => m(*slip_m, *limit_m, "m"),
            Check::OffStep { overhang_m, limit_m, .. } => m(*overhang_m, *limit_m, "m"),
            Check::Strike { from_ends_m, limit_m, .. } => m(*from_ends_m, *limit_m, "m"),
            Check::Collision { .. } => None,
            Check::Fall { tilt_rad, limit_tilt_rad, .. } => m(*tilt_rad, *limit_tilt_rad, "rad"),
            Check::Unstable { count, .. } => m(f64::from(*count), 0.0, "count"),
        }
    }

    /// The foot the check is about, if one.
    pub fn foot(&self) -> Option<Foot> {
        match self {
            Check::Friction { foot, .. }
            | Check::Cop { foot, .. }
            | Check::Touchdown { foot, .. }
            | Check::Slip { foot, .. }
            | Check::OffStep { foot, .. }
            | Check::Strike { foot, .. } => Some(*foot),
            _ => None,
        }
    }
}

impl fmt::Display for Check {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Check::Margin { margin_m, limit_m: _, feet_down } => {
                let m = margin_m.unwrap_or(f64::NEG_INFINITY);
                let side = if m < 0.0 { "outside" } else { "inside (below the margin)" };
                write!(
                    f,
                    "CoM {:.1} mm {side} the stability polygon of the feet in contact ({feet_down:?})",
                    m.abs() * 1e3
                )
            }
            Check::Friction { foot, tangential_n, normal_n, limit, planned_mu } => {
                write!(
                    f,
                    "{foot:?} foot: tangential ({:.1}, {:.1}) N beyond the surface's {limit:.2} x normal {normal_n:.1} N",
                    tangential_n[0], tangential_n[1]
                )?;
                match planned_mu {
                    Some(mu) if mu > limit => write!(f, " (the plan assumed {mu:.2}: more than the surface has)"),
                    Some(mu) => write!(f, " (beyond the plan's own {mu:.2} pyramid too)"),
                    None => Ok(()),
                }
            }
            Check::Cop { foot, cop_m, .. } => {
                write!(f, "{foot:?} centre of pressure outside the sole at ({:.3}, {:.3})", cop_m[0], cop_m[1])
            }
            Check::Torque { joint, demand_nm, limit_nm, .. } => write!(
                f,
                "{joint} needs {:.0} % of its torque limit ({demand_nm:.1} of {limit_nm:.1} N m)",
                demand_nm / limit_nm * 100.0
            ),
            Check::Speed { joint, speed_rad_s, limit_rad_s, .. } => {
                write!(f, "{joint} at {:.0} % of its speed limit", speed_rad_s / limit_rad_s * 100.0)
            }
            Check::Touchdown { foot, error_m, yaw_error_rad, .. } => write!(
                f,
                "{foot:?} foot lands {:.1} mm and {:.1} deg from its target",
                error_m * 1e3,
                yaw_error_rad.to_degrees()
            ),
            Check::Slip { foot, slip_m, .. } => write!(f, "{foot:?} foot slid {:.1} mm while in contact", slip_m * 1e3),
            Check::OffStep { foot, overhang_m, .. } => {
                write!(f, "{foot:?} foot overhangs its step's edge by {:.1} mm", overhang_m * 1e3)
            }
            Check::Strike { foot, geom, at_m, above_target_m, .. } => write!(
                f,
                "the swinging {foot:?} foot hits {geom} at ({:.3}, {:.3}, {:.3}) m in its planned sole frame, {:.1} mm {} its target",
                at_m[0],
                at_m[1],
                at_m[2],
                above_target_m.abs() * 1e3,
                if *above_target_m < 0.0 { "below" } else { "above" }
            ),
            Check::Collision { geom, other } => write!(f, "{geom} touches {other}"),
            Check::Fall { base_z_m, tilt_rad, upright_tilt_rad, .. } => write!(
                f,
                "the robot fell: base at {base_z_m:.2} m, tilted {:.0} deg from the plan's ({:.0} deg from upright)",
                tilt_rad.to_degrees(),
                upright_tilt_rad.to_degrees()
            ),
            Check::Unstable { warning, count, info } => {
                write!(f, "MuJoCo warned {warning:?} ({count} so far, info {info}): the physics is not to be trusted")
            }
        }
    }
}

/// A violated check at an instant.
#[derive(Debug, Clone, PartialEq)]
pub struct Violation {
    /// Time from the start of the execution (the simulation's clock: past the plan's
    /// duration while a late foot is waited for or the plan's end is held), seconds.
    pub t_s: f64,
    /// The loop's cycle (1-based; 0 for an execution outside the loop).
    pub cycle: usize,
    /// What was violated, with its figures.
    pub check: Check,
}

/// The JSON form of a [`Violation`]: `t_s`, `cycle`, `check` (the kind's name), the check's
/// own fields, and `detail`, its message.
#[derive(Serialize, Deserialize)]
struct ViolationJson {
    t_s: f64,
    #[serde(default)]
    cycle: usize,
    #[serde(flatten)]
    check: Check,
    #[serde(default)]
    detail: String,
}

impl Serialize for Violation {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        ViolationJson {
            t_s: self.t_s,
            cycle: self.cycle,
            check: self.check.clone(),
            detail: self.check.to_string(),
        }
        .serialize(s)
    }
}

impl<'de> Deserialize<'de> for Violation {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let v = ViolationJson::deserialize(d)?;
        Ok(Violation { t_s: v.t_s, cycle: v.cycle, check: v.check })
    }
}

impl fmt::Display for Violation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "cycle {}, t = {:.3} s: {}: {}", self.cycle, self.t_s, self.check.kind(), self.check)
    }
}

/// Why the loop stopped before the top (or why it ended at all).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "reason", rename_all = "snake_case")]
pub enum StopReason {
    /// The planner refused the next stance; nothing of that cycle moved.
    Refused {
        /// The cycle whose plan was refused.
        cycle: usize,
        /// The refusal, as data.
        refusal: Refusal,
    },
    /// Perception found no step ahead, and the robot is not at the top.
    NoStaircaseAhead {
        /// The cycle.
        cycle: usize,
        /// Why perception found nothing in the last view, if it found nothing.
        last_view: Option<NoStaircase>,
    },
    /// Perception could not run (bad parameters).
    PerceptionFailed {
        /// The cycle.
        cycle: usize,
        /// The error.
        error: String,
    },
    /// The sensor failed (a driver error, a recording's end).
    SensorFailed {
        /// The cycle.
        cycle: usize,
        /// The error.
        error: String,
    },
    /// The robot fell during a cycle's execution.
    Fell {
        /// The cycle.
        cycle: usize,
    },
    /// The robot fell while it stood before a cycle's sweep (after the previous cycle's
    /// execution, or at the set-down before the first).
    FellStanding {
        /// The cycle whose sweep it stood for (never run).
        cycle: usize,
        /// What the fall check measured.
        fall: Check,
    },
    /// A sole slid on its tread while the robot stood before a cycle's sweep: a check
    /// violated outside an execution.
    SlidStanding {
        /// The cycle whose sweep it stood for (never run).
        cycle: usize,
        /// What the slip check measured.
        slip: Check,
    },
    /// The physics went wrong (a MuJoCo warning) during a cycle's execution.
    SimulationUnstable {
        /// The cycle.
        cycle: usize,
        /// The warning.
        warning: SimWarning,
    },
    /// Cancelled from outside (Ctrl-C, a timeout).
    StoppedByUser {
        /// The cycle during which it stopped.
        cycle: usize,
    },
    /// The loop ran its most cycles without reaching the top.
    CyclesExhausted {
        /// The cycles run.
        cycles: usize,
    },
}

impl StopReason {
    /// The name of the reason (the `reason` key in JSON).
    pub fn name(&self) -> &'static str {
        match self {
            StopReason::Refused { .. } => "refused",
            StopReason::NoStaircaseAhead { .. } => "no_staircase_ahead",
            StopReason::PerceptionFailed { .. } => "perception_failed",
            StopReason::SensorFailed { .. } => "sensor_failed",
            StopReason::Fell { .. } => "fell",
            StopReason::FellStanding { .. } => "fell_standing",
            StopReason::SlidStanding { .. } => "slid_standing",
            StopReason::SimulationUnstable { .. } => "simulation_unstable",
            StopReason::StoppedByUser { .. } => "stopped_by_user",
            StopReason::CyclesExhausted { .. } => "cycles_exhausted",
        }
    }
}

impl fmt::Display for StopReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StopReason::Refused { refusal, .. } => write!(f, "plan refused: {}", refusal.message),
            StopReason::NoStaircaseAhead { .. } => write!(f, "no staircase found ahead before the top"),
            StopReason::PerceptionFailed { error, .. } => write!(f, "perception failed: {error}"),
            StopReason::SensorFailed { error, .. } => write!(f, "sensor failed: {error}"),
            StopReason::Fell { .. } => write!(f, "the robot fell"),
            StopReason::FellStanding { cycle, fall } => {
                write!(f, "the robot fell while it stood before cycle {cycle}'s sweep: {fall}")
            }
            StopReason::SlidStanding { cycle, slip } => {
                write!(f, "while the robot stood before cycle {cycle}'s sweep: {slip}")
            }
            StopReason::SimulationUnstable { warning, .. } => {
                write!(f, "the simulation became unstable (MuJoCo warned {warning:?})")
            }
            StopReason::StoppedByUser { .. } => write!(f, "stopped by the user"),
            StopReason::CyclesExhausted { cycles } => {
                write!(f, "{cycles} cycles run without reaching the top")
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_violation_round_trips_through_json_with_its_kind_fields_and_message() {
        let v = Violation {
            t_s: 1.25,
            cycle: 3,
            check: Check::Friction {
                foot: Foot::Right,
                tangential_n: [-34.2, 7.9],
                normal_n: 48.9,
                limit: 0.4,
                planned_mu: Some(0.7),
            },
        };
        let json = serde_json::to_value(&v).expect("serializable");
        assert_eq!(json["check"], "friction");
        assert_eq!(json["cycle"], 3);
        assert_eq!(json["normal_n"], 48.9);
        assert_eq!(
            json["detail"],
            "Right foot: tangential (-34.2, 7.9) N beyond the surface's 0.40 x normal 48.9 N \
             (the plan assumed 0.70: more than the surface has)"
        );
        let back: Violation = serde_json::from_value(json).expect("readable");
        assert_eq!(back, v);
        let m = v.check.measure().expect("measured");
        assert!((m.value - 34.2 / 48.9).abs() < 1e-12 && m.limit == 0.4 && m.unit == "ratio");
    }

    #[test]
    fn a_stop_reason_keeps_its_refusal_as_data() {
        let e = crate::planning::PlanError::HighRise { step: 0, rise_m: 0.4, max_m: 0.25 };
        let r = StopReason::Refused { cycle: 1, refusal: e.refusal() };
        assert_eq!(r.to_string(), format!("plan refused: {e}"));
        let json = serde_json::to_value(&r).expect("serializable");
        assert_eq!(json["reason"], "refused");
        assert_eq!(json["refusal"]["kind"], "high_rise");
        assert_eq!(json["refusal"]["step"], 1);
        assert_eq!(json["refusal"]["value"], 0.4);
        assert_eq!(json["refusal"]["limit"], 0.25);
        assert_eq!(serde_json::from_value::<StopReason>(json).expect("readable"), r);
    }
}
