//! The paper's sensor (§3): a Hokuyo UTM-30LX-EW 2-D lidar tilted by a Dynamixel MX-64 servo.
//!
//! Every [`Source`] (the MuJoCo simulation, the real drivers, an MCAP replay) produces the
//! same [`Sweep`] of [`ScanRow`]s; [`assemble`] turns a sweep into a gravity-aligned point
//! cloud. Nothing here knows the simulator: the simulated lidar casts its beams through any
//! [`RayCaster`], and the MuJoCo world is one.

pub mod assemble;
pub mod clock;
pub mod dynamixel;
pub mod fuzz;
pub mod hardware;
pub mod lidar;
pub mod link;
pub mod scip;
pub mod servo;
pub mod simulated;

pub use assemble::{assemble, AssembleParams};
pub use lidar::LidarModel;
pub use servo::TiltSweep;
pub use simulated::{RayCaster, RayHit, SimLidar};

use crate::cancel::Cancel;
use nalgebra::Vector3;

/// Where sweeps come from: the simulated lidar in a world, the real lidar and servo, or a
/// recording. The closed loop knows its sensor only through this.
pub trait Source {
    /// One tilt sweep from where the sensor head is now. `on_rows(done, total)` is called as
    /// rows arrive (for progress bars). A cancelled `cancel` ends the sweep early with
    /// [`SensorError::Cancelled`].
    fn sweep(&mut self, cancel: &Cancel, on_rows: &mut dyn FnMut(usize, usize))
        -> Result<Sweep, SensorError>;

    /// Seconds before a sweep ending then would be a whole one: for a head that sweeps as
    /// the robot moves, its servo is on its way back from the last pass or the pass under
    /// way began less than a sweep ago (the loop stands that long before it looks). 0 for a
    /// source that sweeps when asked, taking the sweep's time in [`Source::sweep`].
    fn whole_in_s(&self) -> f64 {
        0.0
    }

    /// The pass under way is dropped: the next [`Source::sweep`] is taken standing, from
    /// where the head is (the loop looks again standing at a plan a moving pass could not
    /// settle). Returns the seconds the servo needs first, from where its pass ended to
    /// where a standing sweep starts (0 for the paper's sweep: a pass ends level, where a
    /// standing sweep starts). 0 for a source that sweeps standing when asked.
    fn sweep_standing_next(&mut self) -> f64 {
        0.0
    }
}

/// One row of the lidar: one mirror revolution, `beams` ranges in a plane.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanRow {
    /// Time of the row's first beam on the source's clock, seconds.
    pub stamp_s: f64,
    /// Tilt reported by the servo at `stamp_s`, radians (quantized to its encoder ticks).
    pub tilt_rad: f64,
    /// Range of each beam, metres, first beam first; 0 means no return (out of range,
    /// dropout, nothing hit), as the Hokuyo reports errors below its minimum range.
    pub ranges_m: Vec<f32>,
    /// Gravity direction measured by the IMU, unit vector in the servo base (mount) frame.
    pub gravity_mount: Vector3<f64>,
    /// Pose of the servo base in the world at `stamp_s` as the source knew it, when the head
    /// moved during the sweep (a sweep taken while the robot walks: the robot's own estimate
    /// at the row's instant); `None`: the head stood at the sweep's
    /// [`Sweep::mount_to_world`] all along.
    pub mount_to_world: Option<nalgebra::Isometry3<f64>>,
}

impl ScanRow {
    /// Whether beam `i` returned a range.
    pub fn has_return(&self, i: usize) -> bool {
        self.ranges_m.get(i).is_some_and(|r| r.is_finite() && *r > 0.0)
    }
}

/// Why a sensor could not produce or assemble rows.
#[derive(Debug, thiserror::Error)]
pub enum SensorError {
    /// The scenario is invalid.
    #[error(transparent)]
    Scenario(#[from] crate::scenario::ScenarioError),
    /// A row's length differs from the lidar's beam count.
    #[error("row {row} has {got} ranges, the lidar has {expected} beams")]
    RowLength {
        /// Index of the row in the sweep.
        row: usize,
        /// Ranges in the row.
        got: usize,
        /// Beams of the lidar.
        expected: usize,
    },
    /// Stamps or tilts that are not finite numbers.
    #[error("row {row} has a non-finite stamp or tilt")]
    NonFinite {
        /// Index of the row in the sweep.
        row: usize,
    },
    /// The sweep was cancelled (Ctrl-C, a timeout) after `rows` rows.
    #[error("the sweep was cancelled after {rows} rows")]
    Cancelled {
        /// Rows received before the cancellation.
        rows: usize,
    },
    /// The source has no more sweeps (a recording's end).
    #[error("no more sweeps: the source has given its {given}")]
    Exhausted {
        /// Sweeps given before.
        given: usize,
    },
    /// The real lidar failed.
    #[error(transparent)]
    Lidar(#[from] scip::LidarError),
    /// The real servo failed.
    #[error(transparent)]
    Servo(#[from] dynamixel::ServoError),
    /// A sweep was cut short: the rows received before are kept.
    #[error("the sweep was cut after {} rows: {why}", .partial.rows.len())]
    Cut {
        /// The sweep so far.
        partial: Box<Sweep>,
        /// Why.
        why: String,
    },
    /// A hardware configuration file is wrong.
    #[error("{origin}{}: {message}", .line.map(|l| format!(":{l}")).unwrap_or_default())]
    Config {
        /// The file.
        origin: String,
        /// 1-based line, when known.
        line: Option<usize>,
        /// What is wrong.
        message: String,
    },
}

/// A whole tilt sweep: the rows and what is needed to assemble them.
#[derive(Debug, Clone)]
pub struct Sweep {
    /// The rows, in time order.
    pub rows: Vec<ScanRow>,
    /// The lidar that produced them.
    pub lidar: LidarModel,
    /// Pose of the servo base (tilt axis frame) in the world during the sweep, as the source
    /// (or the loop, from the robot's configuration) knows it; the cloud's frame is this
    /// levelled by the rows' measured gravity ([`assemble::mount_in_cloud`]). A row with a
    /// pose of its own ([`ScanRow::mount_to_world`]) is assembled there instead.
    pub mount_to_world: nalgebra::Isometry3<f64>,
}

impl Sweep {
    /// The sweep's point cloud.
    pub fn assemble(&self, params: &AssembleParams) -> Result<crate::cloud::PointCloud, SensorError> {
        assemble(&self.rows, &self.lidar, &self.mount_to_world, params)
    }

    /// The sweep moved by `offset` (a registration's, in the world): its mount and every
    /// row's own pose.
    pub fn moved(&mut self, offset: &nalgebra::Isometry3<f64>) {
        self.mount_to_world = offset * self.mount_to_world;
        for pose in self.rows.iter_mut().filter_map(|r| r.mount_to_world.as_mut()) {
            *pose = offset * *pose;
        }
    }

    /// Whether the head moved during the sweep (its rows carry poses of their own).
    pub fn moving(&self) -> bool {
        self.rows.iter().any(|r| r.mount_to_world.is_some())
    }

    /// How far the head went during the sweep: the farthest any row's origin lies from the
    /// last row's, metres (0 for a sweep taken standing).
    pub fn head_travel_m(&self) -> f64 {
        let origins = || self.rows.iter().filter_map(|r| r.mount_to_world.map(|m| m.translation.vector));
        let Some(last) = origins().next_back() else { return 0.0 };
        origins().map(|o| (o - last).norm()).fold(0.0, f64::max)
    }

    /// Beams cast in the sweep.
    pub fn beam_count(&self) -> usize {
        self.rows.len() * self.lidar.beams()
    }
}
