//! The Hokuyo UTM-30LX-EW's geometry, timing, range limits and noise model.

use crate::scenario::LidarSpec;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

/// Mirror steps in one revolution of a UTM-30LX-EW (0.25 degrees each; 1081 of them fall in
/// the 270 degree field of view, so a row's beams span 1080/1440 of the row period).
fn steps_per_rev(resolution_rad: f64) -> f64 {
    (std::f64::consts::TAU / resolution_rad).round()
}

/// The lidar as the simulator and the assembler see it. Built from a validated [`LidarSpec`].
#[derive(Debug, Clone, PartialEq)]
pub struct LidarModel {
    beams: usize,
    first_beam_rad: f64,
    resolution_rad: f64,
    row_period_s: f64,
    range_min_m: f64,
    range_max_m: f64,
    /// Gaussian range noise, metres (0 for none).
    pub noise_sigma_m: f64,
    /// Probability that a beam returns nothing.
    pub dropout_probability: f64,
    /// Servo base (tilt axis) pose in the robot's head frame.
    pub mount_in_head: Isometry3<f64>,
    /// Optical centre from the tilt axis, in the tilted frame, metres.
    pub axis_to_optical_m: Vector3<f64>,
    spec: LidarSpec,
}

impl LidarModel {
    /// The model of a (validated) lidar spec.
    pub fn from_spec(s: &LidarSpec) -> Self {
        let resolution_rad = s.resolution_deg.to_radians();
        let beams = (s.fov_deg / s.resolution_deg).round() as usize + 1;
        let [r, p, y] = s.mount_rpy_deg.map(f64::to_radians);
        Self {
            beams,
            first_beam_rad: -resolution_rad * (beams - 1) as f64 / 2.0,
            resolution_rad,
            row_period_s: s.row_period_s,
            range_min_m: s.range_min_m,
            range_max_m: s.range_max_m,
            noise_sigma_m: s.noise_sigma_m,
            dropout_probability: s.dropout_probability,
            mount_in_head: Isometry3::from_parts(
                Translation3::from(Vector3::from(s.mount_xyz_m)),
                UnitQuaternion::from_euler_angles(r, p, y),
            ),
            axis_to_optical_m: Vector3::from(s.axis_to_optical_m),
            spec: s.clone(),
        }
    }

    /// The spec the model was built from (recorded with a sweep, so a replay rebuilds it).
    pub fn spec(&self) -> &LidarSpec {
        &self.spec
    }

    /// Beams in a row (1081 for the UTM-30LX-EW).
    pub fn beams(&self) -> usize {
        self.beams
    }

    /// Time of one row, seconds.
    pub fn row_period_s(&self) -> f64 {
        self.row_period_s
    }

    /// Shortest range reported, metres.
    pub fn range_min_m(&self) -> f64 {
        self.range_min_m
    }

    /// Longest range reported, metres.
    pub fn range_max_m(&self) -> f64 {
        self.range_max_m
    }

    /// Angle of beam `i` in the scan plane, radians (0 looks along the scanner's +x, positive
    /// toward +y).
    pub fn beam_angle_rad(&self, i: usize) -> f64 {
        self.first_beam_rad + self.resolution_rad * i as f64
    }

    /// Time of beam `i` after the row's stamp, seconds (the mirror turns at a constant rate).
    pub fn beam_time_offset_s(&self, i: usize) -> f64 {
        self.row_period_s * i as f64 / steps_per_rev(self.resolution_rad)
    }

    /// Unit direction of beam `i` in the scanner frame (the scan plane is its x-y plane).
    pub fn beam_direction(&self, i: usize) -> Vector3<f64> {
        let a = self.beam_angle_rad(i);
        Vector3::new(a.cos(), a.sin(), 0.0)
    }

    /// Pose of the scanner (optical centre, scan plane = x-y) in the mount frame at `tilt_rad`:
    /// a rotation about the mount's +y axis (positive pitches the scan plane down), then the
    /// offset from the axis to the optical centre.
    pub fn scanner_in_mount(&self, tilt_rad: f64) -> Isometry3<f64> {
        let r = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), tilt_rad);
        Isometry3::from_parts(Translation3::from(r * self.axis_to_optical_m), r)
    }

    /// Whether a measured range counts as a return.
    pub fn in_range(&self, range_m: f64) -> bool {
        range_m >= self.range_min_m && range_m <= self.range_max_m
    }
}
