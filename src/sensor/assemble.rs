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
    turned(mount_to_world, &level_turn(&(mount_to_world.rotation * gravity_mount.into_inner())))
}

/// The least rotation that takes `g_world` (gravity as the poses put it in the world) to the
/// world's -z; gravity pointing up turns about the world's x axis.
fn level_turn(g_world: &Vector3<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::rotation_between(g_world, &-Vector3::z())
        .unwrap_or_else(|| UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI))
}

/// `pose` turned by `turn` about its own position.
fn turned(pose: &Isometry3<f64>, turn: &UnitQuaternion<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(pose.translation, turn * pose.rotation)
}

/// The servo base's pose at each row of a sweep whose head moved (rows with poses of their
/// own, [`ScanRow::mount_to_world`]; `mount_to_world` for a row without), levelled together:
/// each turned about its own position by the one least rotation that takes the rows' mean
/// measured gravity, each reading carried into the world by its row's pose, to -z. As for a
/// head that stood ([`mount_in_cloud`]), the turn mends what the poses get wrong about the
/// head's tilt, the same all along the sweep (a mount not where the model says, a base
/// estimate's tilt); the motion between rows is the poses'.
pub fn rows_in_cloud(rows: &[ScanRow], mount_to_world: &Isometry3<f64>) -> Vec<Isometry3<f64>> {
    let pose = |r: &ScanRow| r.mount_to_world.unwrap_or(*mount_to_world);
    let g_world: Vector3<f64> = rows
        .iter()
        .filter(|r| r.gravity_mount.iter().all(|v| v.is_finite()))
        .map(|r| pose(r).rotation * r.gravity_mount)
        .sum();
    let turn = Unit::try_new(g_world, 1e-9).map_or_else(UnitQuaternion::identity, |g| level_turn(&g));
    rows.iter().map(|r| turned(&pose(r), &turn)).collect()
}

/// The pose of the servo base in the cloud's frame: `mount_to_world` levelled by the rows'
/// measured gravity (unchanged without a reading).
pub fn mount_in_cloud(rows: &[ScanRow], mount_to_world: &Isometry3<f64>) -> Isometry3<f64> {
    measured_gravity(rows).map_or(*mount_to_world, |g| levelled(mount_to_world, &g))
}

/// The point cloud of a sweep in a gravity-aligned frame: `mount_to_world` (the servo base's
/// pose; in simulation the true one, on the robot the one from kinematics) levelled by the
/// rows' measured gravity ([`mount_in_cloud`]); gravity is the cloud's -z. A sweep whose rows
/// carry poses of their own (the head moved) is assembled row by row from those, levelled
/// together ([`rows_in_cloud`]); the head's motion within a row's few milliseconds is not
/// undone.
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
    // A head that moved: each row from its own pose, levelled together.
    let moved = rows.iter().any(|r| r.mount_to_world.is_some()).then(|| rows_in_cloud(rows, mount_to_world));
    let mount_to_world = &mount_in_cloud(rows, mount_to_world);
    let tilts = estimate_tilts(rows, params.tilt_fit_half_window_rows);
    let mut points = Vec::new();
    let mut cell_to_point = vec![u32::MAX; rows.len() * beams];
    let mut viewpoint_sum = Vector3::zeros();
    let mut row_origins = Vec::with_capacity(if moved.is_some() { rows.len() } else { 0 });
    let dirs: Vec<Vector3<f64>> = (0..beams).map(|i| lidar.beam_direction(i)).collect();
    for (k, row) in rows.iter().enumerate() {
        let (tilt0, rate) = tilts[k];
        let mount_to_world = moved.as_ref().map_or(mount_to_world, |poses| &poses[k]);
        let mid = mount_to_world * lidar.scanner_in_mount(tilt0 + rate * lidar.beam_time_offset_s(beams / 2));
        viewpoint_sum += mid.translation.vector;
        if moved.is_some() {
            row_origins.push(Point3::from(mid.translation.vector));
        }
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
    // A head that moved saw each row from its own place.
    let grid = ScanGrid::new(rows.len(), beams, cell_to_point).and_then(|g| {
        if moved.is_some() {
            g.with_row_origins(row_origins)
        } else {
            Some(g)
        }
    });
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

    /// A head walking 0.3 m forward and rising 0.2 m over a sweep while it pitches by 4
    /// deg and back, its belief of itself off by a constant 3 deg tilt: each row assembled
    /// where the robot believed the head was at its instant, levelled together, gives the
    /// floor flat at its height; the same rows assembled from the head's last pose (what a
    /// sweep taken as if standing makes of them) give a floor centimetres off.
    #[test]
    fn a_sweep_taken_as_the_head_moves_is_assembled_row_by_row() {
        let spec = LidarSpec { noise_sigma_m: 0.0, dropout_probability: 0.0, ..LidarSpec::default() };
        let rows = crate::sensor::TiltSweep::from_spec(&spec).rows();
        let tilt_error = UnitQuaternion::from_euler_angles(3f64.to_radians(), 0.0, 0.0);
        let heads: Vec<(Isometry3<f64>, Isometry3<f64>)> = (0..rows)
            .map(|k| {
                let s = k as f64 / (rows - 1) as f64;
                let pitch_deg = 4.0 * (std::f64::consts::PI * s).sin();
                let truth = head([0.3 * s, 0.0, 1.3 + 0.2 * s], [0.0, pitch_deg, 0.0]);
                (truth, Isometry3::from_parts(truth.translation, tilt_error * truth.rotation))
            })
            .collect();
        let lidar = SimLidar::moving(&Floor, &spec, &heads, 1).expect("a head per row");
        let sweep = lidar.sweep_rows(&crate::cancel::Cancel::never(), &mut |_, _| {}).expect("a sweep");
        assert!(sweep.moving());
        let cloud = sweep.assemble(&AssembleParams::default()).expect("cloud");
        let worst_m = cloud.points().iter().map(|p| f64::from(p.z).abs()).fold(0.0, f64::max);
        assert!(cloud.points().len() > 100_000 && worst_m < 0.002, "the floor within {worst_m} m of z = 0");
        assert!(floor_slope_deg(&cloud) < 0.05, "{} deg", floor_slope_deg(&cloud));
        let mut standing = sweep.clone();
        standing.mount_to_world = heads[rows - 1].1 * lidar.lidar().mount_in_head;
        standing.rows.iter_mut().for_each(|r| r.mount_to_world = None);
        let cloud = standing.assemble(&AssembleParams::default()).expect("cloud");
        let worst_m = cloud.points().iter().map(|p| f64::from(p.z).abs()).fold(0.0, f64::max);
        assert!(worst_m > 0.05, "assembled from one pose, the floor is {worst_m} m off at most");
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
