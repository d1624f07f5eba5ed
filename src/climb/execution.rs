//! What one execution of a plan found ([`Execution`]): the touchdowns, the margins, the
//! violations, the control's cost. The loop's reports and events carry it; the executors
//! ([`super::executor`]) return it.

use super::outcome::{CheckKind, SimWarning, Violation};
use crate::planning::Foot;

/// A touchdown: where a foot landed against its target.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Touchdown {
    /// Which foot.
    pub foot: Foot,
    /// Position error, metres.
    pub error_m: f64,
    /// Yaw error, radians.
    pub yaw_error_rad: f64,
}

/// What one execution found.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Execution {
    /// Simulated time, seconds.
    pub sim_s: f64,
    /// Smallest CoM margin in the polygon of the real contacts, metres (`null` in JSON when
    /// no instant had a polygon).
    pub min_margin_m: f64,
    /// Largest torque demand over limit.
    pub max_torque_ratio: f64,
    /// The joint of `max_torque_ratio`.
    pub torque_joint: String,
    /// Largest speed over limit.
    pub max_speed_ratio: f64,
    /// The joint of `max_speed_ratio`.
    pub speed_joint: String,
    /// Every touchdown.
    pub touchdowns: Vec<Touchdown>,
    /// Largest horizontal slide of a sole in contact from where it came down, metres.
    pub max_slip_m: f64,
    /// Largest friction a loaded foot used: tangential over normal force, per sole axis
    /// (the pyramid's measure; the check's limit is the checks' friction coefficient).
    pub max_friction_ratio: f64,
    /// Violations (the first of each kind per second of simulation, to keep reports short).
    pub violations: Vec<Violation>,
    /// The robot fell (the execution stopped).
    pub fell: bool,
    /// MuJoCo warned during a step (the execution stopped): which warning.
    pub unstable: Option<SimWarning>,
    /// The execution was cancelled before its end.
    pub cancelled: bool,
    /// The stabilizer's cost, when it ran.
    pub control: Option<ControlCost>,
    /// Wall time of the physics alone (MuJoCo's steps), seconds: the execution's wall time
    /// less this and the stabilizer's is the checks' and the loop's own.
    pub physics_wall_s: f64,
    /// The base's true speed, m/s, when the robot judged itself still and ended its hold of
    /// the plan's last instant (on its own estimate, `RunParams::still_speed_m_s`): the
    /// bench's measure of that judgement. `None` where the hold ran to its longest, or no
    /// stabilizer held.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub still_true_speed_m_s: Option<f64>,
}

/// What the stabilizer cost over an execution.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ControlCost {
    /// Its ticks.
    pub ticks: usize,
    /// Their wall time, seconds.
    pub wall_s: f64,
}

impl Execution {
    /// An execution that has not run yet: no time, nothing measured.
    pub fn empty() -> Self {
        Self {
            sim_s: 0.0,
            min_margin_m: f64::INFINITY,
            max_torque_ratio: 0.0,
            torque_joint: String::new(),
            max_speed_ratio: 0.0,
            speed_joint: String::new(),
            touchdowns: Vec::new(),
            max_slip_m: 0.0,
            max_friction_ratio: 0.0,
            violations: Vec::new(),
            fell: false,
            unstable: None,
            cancelled: false,
            control: None,
            physics_wall_s: 0.0,
            still_true_speed_m_s: None,
        }
    }

    /// No check violated.
    pub fn pass(&self) -> bool {
        self.violations.is_empty() && !self.fell && self.unstable.is_none()
    }

    /// The largest touchdown position error, metres (0 without touchdowns).
    pub fn max_touchdown_error_m(&self) -> f64 {
        self.touchdowns.iter().map(|t| t.error_m).fold(0.0, f64::max)
    }

    /// The first violation of `kind`, if any.
    pub fn first(&self, kind: CheckKind) -> Option<&Violation> {
        self.violations.iter().find(|v| v.check.kind() == kind)
    }
}
