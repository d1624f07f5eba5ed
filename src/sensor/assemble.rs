//! Assembly of a sweep of [`ScanRow`]s into a point cloud in a gravity-aligned frame.
//!
//! The frame is levelled by the rows' measured gravity (the IMU's reading in the servo base
//! frame): the mount's given pose keeps its position and heading, and its orientation is
//! turned by the least rotation that puts the measured gravity on the cloud's -z. A head
//! whose pose is known only roughly (a tripod, a chest pitched otherwise than the model
//! says) gives a level cloud all the same.
//!
//! The servo reports one quantized tilt per row, while the scanner keeps turning during the
//! row. The tilt of each beam is estimated from a local straight-line fit of the readings of
//! the neighbouring rows (the servo moves at constant speed), evaluated at the beam's own time:
//! this removes most of the encoder's quantization and the in-row motion.

use super::{LidarModel, ScanRow, SensorError};
use crate::cloud::{PointCloud, ScanGrid};
use nalgebra::{Isometry3, Point3, Unit, UnitQuaternion, Vector3};

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

/// The mean of the rows' measured gravity, unit, in the servo base frame (`None` without rows
/// or with readings that cancel out).
pub fn measured_gravity(rows: &[ScanRow]) -> Option<Unit<Vector3<f64>>> {
    let sum: Vector3<f64> =
        rows.iter().map(|r| r.gravity_mount).filter(|g| g.iter().all(|v| v.is_finite())).sum();
    Unit::try_new(sum, 1e-9)
}

/// `mount_to_world` levelled by `gravity_mount` (gravity measured in the servo base frame):
/// the same position, the orientation turned by the least rotation that takes the measured
/// gravity to the world's -z (so the heading is kept). Gravity pointing up (a head upside
/// down) turns about the world's x axis.
pub fn levelled(mount_to_world: &Isometry3<f64>, gravity_mount: &Unit<Vector3<f64>>) -> Isometry3<f64> {
    let g_world = mount_to_world.rotation * gravity_mount.into_inner();
    let turn = UnitQuaternion::rotation_between(&g_world, &-Vector3::z())
        .unwrap_or_else(|| UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI));
    Isometry3::from_parts(mount_to_world.translation, turn * mount_to_world.rotation)
}

/// The pose of the servo base in the cloud's frame: `mount_to_world` levelled by the rows'
/// measured gravity (unchanged without a reading).
pub fn mount_in_cloud(rows: &[ScanRow], mount_to_world: &Isometry3<f64>) -> Isometry3<f64> {
    measured_gravity(rows).map_or(*mount_to_world, |g| levelled(mount_to_world, &g))
}

/// The point cloud of a sweep in a gravity-aligned frame: `mount_to_world` (the servo base's
/// pose; in simulation the true one, on the robot the one from kinematics) levelled by the
/// rows' measured gravity ([`mount_in_cloud`]); gravity is the cloud's -z.
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
    let mount_to_world = &mount_in_cloud(rows, mount_to_world);
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
    let gravity = -Vector3::z_axis();
    let grid = ScanGrid::new(rows.len(), beams, cell_to_point);
    Ok(PointCloud::new(points, viewpoint, gravity, grid))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::LidarSpec;
    use crate::sensor::{RayCaster, RayHit, SimLidar};
    use nalgebra::Translation3;

    /// The floor z = 0, and nothing else.
    struct Floor;

    impl RayCaster for Floor {
        fn ray(&self, origin: &Point3<f64>, dir: &Vector3<f64>) -> Option<RayHit> {
            (dir.z < -1e-9).then(|| RayHit { distance_m: -origin.z / dir.z, geom: 0 })
        }
    }

    fn head(xyz_m: [f64; 3], rpy_deg: [f64; 3]) -> Isometry3<f64> {
        let [r, p, y] = rpy_deg.map(f64::to_radians);
        Isometry3::from_parts(
            Translation3::new(xyz_m[0], xyz_m[1], xyz_m[2]),
            UnitQuaternion::from_euler_angles(r, p, y),
        )
    }

    /// The floor's slope in the cloud (least-squares plane z = a x + b y + c), degrees.
    fn floor_slope_deg(cloud: &crate::cloud::PointCloud) -> f64 {
        let (mut m, mut v) = (nalgebra::Matrix3::<f64>::zeros(), Vector3::<f64>::zeros());
        for p in cloud.points() {
            let row = Vector3::new(f64::from(p.x), f64::from(p.y), 1.0);
            m += row * row.transpose();
            v += row * f64::from(p.z);
        }
        let abc = m.lu().solve(&v).expect("a plane");
        abc.x.hypot(abc.y).atan().to_degrees()
    }

    #[test]
    fn a_head_not_where_its_pose_says_still_gives_a_level_floor() {
        let spec = LidarSpec { noise_sigma_m: 0.0, dropout_probability: 0.0, ..LidarSpec::default() };
        // The head level on a tripod at 1.4 m, turned 20 deg and rolled 3 deg; the sweep
        // believes it pitched 7.5 deg at 1.5 m, facing +x (a robot's half-sitting head).
        let truth = head([0.0, 0.0, 1.4], [3.0, 0.0, 20.0]);
        let believed = head([0.0, 0.0, 1.5], [0.0, 7.5, 0.0]);
        let lidar = SimLidar::new(&Floor, &spec, &truth, 1);
        let mut sweep = lidar.sweep_rows(&crate::cancel::Cancel::never(), &mut |_, _| {}).expect("a sweep");
        let level = floor_slope_deg(&sweep.assemble(&AssembleParams::default()).expect("cloud"));
        sweep.mount_to_world = believed * lidar.lidar().mount_in_head;
        let cloud = sweep.assemble(&AssembleParams::default()).expect("cloud");
        let slope = floor_slope_deg(&cloud);
        assert!(
            level < 0.01 && slope < 0.01,
            "the floor is level: {level} deg, {slope} deg believed elsewhere"
        );
        assert_eq!(cloud.gravity(), -Vector3::z_axis());
        // The heading kept: the believed head faces +x, so the floor seen ahead is at +x.
        let ahead = cloud.points().iter().filter(|p| p.x > 0.0).count();
        assert!(ahead * 10 > cloud.points().len() * 9, "{ahead} of {} points ahead", cloud.points().len());
    }

    #[test]
    fn levelling_keeps_the_position_and_the_heading() {
        let pose = head([0.3, -0.2, 1.2], [4.0, -12.0, 35.0]);
        let g_mount = Unit::new_normalize(pose.rotation.inverse() * -Vector3::z());
        let same = levelled(&pose, &g_mount);
        assert!((same.rotation.angle_to(&pose.rotation)) < 1e-9 && same.translation == pose.translation);
        // Measured level: the pose loses its roll and pitch, keeps its yaw.
        let flat = levelled(&pose, &-Vector3::z_axis());
        let (r, p, y) = flat.rotation.euler_angles();
        assert!(r.abs() < 1e-6 && p.abs() < 1e-6, "roll {r}, pitch {p}");
        assert!((y.to_degrees() - 35.0).abs() < 0.5, "yaw {} deg", y.to_degrees());
        let upside = levelled(&Isometry3::identity(), &Vector3::z_axis());
        assert!((upside.rotation * Vector3::z()).z < -0.999);
    }
}
