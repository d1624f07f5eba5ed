//! Assembly of a sweep of [`ScanRow`]s into a point cloud in a gravity-aligned frame.
//!
//! The servo reports one quantized tilt per row, while the scanner keeps turning during the
//! row. The tilt of each beam is estimated from a local straight-line fit of the readings of
//! the neighbouring rows (the servo moves at constant speed), evaluated at the beam's own time:
//! this removes most of the encoder's quantization and the in-row motion.

use super::{LidarModel, ScanRow, SensorError};
use crate::cloud::{PointCloud, ScanGrid};
use nalgebra::{Isometry3, Point3, Unit, Vector3};

/// Parameters of the assembly.
#[derive(Debug, Clone, PartialEq)]
pub struct AssembleParams {
    /// Rows on each side of a row used to fit its tilt and tilt rate; 0 uses the raw reading
    /// and holds it for the whole row (what a naive assembler does).
    pub tilt_fit_half_window_rows: usize,
}

impl Default for AssembleParams {
    fn default() -> Self {
        Self { tilt_fit_half_window_rows: 8 }
    }
}

/// Estimated tilt (at the row's stamp) and tilt rate of each row.
pub fn estimate_tilts(rows: &[ScanRow], half_window: usize) -> Vec<(f64, f64)> {
    (0..rows.len())
        .map(|k| {
            if half_window == 0 || rows.len() < 2 {
                return (rows[k].tilt_rad, 0.0);
            }
            let lo = k.saturating_sub(half_window);
            let hi = (k + half_window + 1).min(rows.len());
            let n = (hi - lo) as f64;
            let t0 = rows[k].stamp_s;
            let (mut st, mut sa, mut stt, mut sta) = (0.0, 0.0, 0.0, 0.0);
            for r in &rows[lo..hi] {
                let t = r.stamp_s - t0;
                st += t;
                sa += r.tilt_rad;
                stt += t * t;
                sta += t * r.tilt_rad;
            }
            let det = n * stt - st * st;
            if det.abs() < 1e-18 {
                return (rows[k].tilt_rad, 0.0);
            }
            let rate = (n * sta - st * sa) / det;
            let at_stamp = (sa - rate * st) / n;
            (at_stamp, rate)
        })
        .collect()
}

/// The point cloud of a sweep in the world frame given by `mount_to_world` (the servo base's
/// pose; in simulation the true one, on the robot the one from kinematics and the IMU).
pub fn assemble(
    rows: &[ScanRow],
    lidar: &LidarModel,
    mount_to_world: &Isometry3<f64>,
    params: &AssembleParams,
) -> Result<PointCloud, SensorError> {
    let beams = lidar.beams();
    for (k, r) in rows.iter().enumerate() {
        if r.ranges_m.len() != beams {
            return Err(SensorError::RowLength { row: k, got: r.ranges_m.len(), expected: beams });
        }
        if !r.stamp_s.is_finite() || !r.tilt_rad.is_finite() {
            return Err(SensorError::NonFinite { row: k });
        }
    }
    let tilts = estimate_tilts(rows, params.tilt_fit_half_window_rows);
    let mut points = Vec::new();
    let mut cell_to_point = vec![u32::MAX; rows.len() * beams];
    let mut viewpoint_sum = Vector3::zeros();
    let dirs: Vec<Vector3<f64>> = (0..beams).map(|i| lidar.beam_direction(i)).collect();
    for (k, row) in rows.iter().enumerate() {
        let (tilt0, rate) = tilts[k];
        let mid = mount_to_world * lidar.scanner_in_mount(tilt0 + rate * lidar.beam_time_offset_s(beams / 2));
        viewpoint_sum += mid.translation.vector;
        for (i, &r) in row.ranges_m.iter().enumerate() {
            if !(r.is_finite() && r > 0.0) {
                continue;
            }
            let tilt = tilt0 + rate * lidar.beam_time_offset_s(i);
            let scanner = mount_to_world * lidar.scanner_in_mount(tilt);
            let p = scanner * Point3::from(dirs[i] * r as f64);
            cell_to_point[k * beams + i] = points.len() as u32;
            points.push(p.cast::<f32>());
        }
    }
    let viewpoint = if rows.is_empty() {
        Point3::from(mount_to_world.translation.vector)
    } else {
        Point3::from(viewpoint_sum / rows.len() as f64)
    };
    let g_mount: Vector3<f64> = rows.iter().map(|r| r.gravity_mount).sum();
    let g_world = mount_to_world.rotation * g_mount;
    let gravity = Unit::try_new(g_world, 1e-9).unwrap_or(-Vector3::z_axis());
    let grid = ScanGrid::new(rows.len(), beams, cell_to_point);
    Ok(PointCloud::new(points, viewpoint, gravity, grid))
}
