//! The simulated sensor: the tilting lidar's beams cast into a world through a
//! [`RayCaster`] (MuJoCo's in the bench, an analytic one in tests), each beam with the tilt at
//! its own time stamp, with range noise and dropouts.

use super::{LidarModel, ScanRow, SensorError, Sweep, TiltSweep};
use crate::cancel::Cancel;
use crate::scenario::LidarSpec;
use nalgebra::{Isometry3, Point3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;
use std::ops::Range;

/// One ray's hit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayHit {
    /// Distance along the (unit) ray direction, metres.
    pub distance_m: f64,
    /// Id of the surface hit, as the caster numbers them (MuJoCo's geom id).
    pub geom: usize,
}

/// A world rays can be cast into (everything but the robot itself). Shared by the threads
/// that cast a sweep's rows.
pub trait RayCaster: Sync {
    /// The first hit of the ray from `origin` along the unit vector `dir`, if any.
    fn ray(&self, origin: &Point3<f64>, dir: &Vector3<f64>) -> Option<RayHit>;
}

/// A tilting lidar whose servo base sits at `mount_to_world` in a world seen through a
/// [`RayCaster`], frozen at the world's current state (the robot standing still during a
/// sweep), or moving along a head's path ([`SimLidar::moving`]).
pub struct SimLidar<'w, C: RayCaster> {
    world: &'w C,
    lidar: LidarModel,
    /// Each beam's direction in the scanner frame ([`LidarModel::beam_direction`]).
    directions: Vec<Vector3<f64>>,
    sweep: TiltSweep,
    mount_to_world: Isometry3<f64>,
    motion: Option<Motion>,
    seed: u64,
}

/// The servo base's path through a sweep, one pose per row: where it was, and where the
/// robot believed it was.
struct Motion {
    truth: Vec<Isometry3<f64>>,
    believed: Vec<Isometry3<f64>>,
}

impl<'w, C: RayCaster> SimLidar<'w, C> {
    /// The lidar of `spec` mounted on a head at `head_to_world` (the scenario's mount is
    /// relative to the head); `seed` drives noise and dropouts.
    pub fn new(world: &'w C, spec: &LidarSpec, head_to_world: &Isometry3<f64>, seed: u64) -> Self {
        let lidar = LidarModel::from_spec(spec);
        let mount_to_world = head_to_world * lidar.mount_in_head;
        let directions = (0..lidar.beams()).map(|i| lidar.beam_direction(i)).collect();
        Self {
            world,
            sweep: TiltSweep::from_spec(spec),
            lidar,
            directions,
            mount_to_world,
            motion: None,
            seed,
        }
    }

    /// The lidar of `spec` on a head that moves during the sweep (a robot walking): row `k`
    /// is cast from the head at `heads[k].0` (its true pose at the row's stamp, held through
    /// the row) and carries `heads[k].1`, where the robot believed the head was then, for
    /// the assembly ([`ScanRow::mount_to_world`]). The servo runs the sweep level last
    /// ([`TiltSweep::level_last`]), each pass ending when the loop looks, so the rows that
    /// cross the space just ahead of the head are cast from nearest where it stands then.
    /// As many heads as the sweep has rows, else `None`.
    pub fn moving(
        world: &'w C,
        spec: &LidarSpec,
        heads: &[(Isometry3<f64>, Isometry3<f64>)],
        seed: u64,
    ) -> Option<Self> {
        let sweep = TiltSweep::from_spec(spec);
        let (last, _) = heads.last()?;
        if heads.len() != sweep.rows() {
            return None;
        }
        let mut lidar = Self::new(world, spec, last, seed);
        lidar.sweep = sweep.level_last();
        let mount = lidar.lidar.mount_in_head;
        lidar.motion = Some(Motion {
            truth: heads.iter().map(|(t, _)| t * mount).collect(),
            believed: heads.iter().map(|(_, b)| b * mount).collect(),
        });
        Some(lidar)
    }

    /// The same lidar run along `sweep` instead (a test's other pass order).
    #[cfg(test)]
    pub(crate) fn along(mut self, sweep: TiltSweep) -> Self {
        self.sweep = sweep;
        self
    }

    /// The lidar's model (what the assembler needs).
    pub fn lidar(&self) -> &LidarModel {
        &self.lidar
    }

    /// The servo's sweep.
    pub fn sweep(&self) -> &TiltSweep {
        &self.sweep
    }

    /// Pose of the servo base (tilt axis frame) in the world.
    pub fn mount_to_world(&self) -> Isometry3<f64> {
        self.mount_to_world
    }

    /// Rows `range` of the sweep, cast in parallel (rayon). Deterministic for a seed.
    pub fn rows(&self, range: Range<usize>) -> Vec<ScanRow> {
        let end = range.end.min(self.sweep.rows());
        (range.start..end).into_par_iter().map(|k| self.cast_row(k, None)).collect()
    }

    /// Row `k` and, for each beam, the true hit (before noise, dropouts and range limits).
    pub fn row_with_hits(&self, k: usize) -> (ScanRow, Vec<Option<RayHit>>) {
        let mut hits = Vec::with_capacity(self.lidar.beams());
        let row = self.cast_row(k, Some(&mut hits));
        (row, hits)
    }

    /// The true hits of one row whose beam `i` leaves with the servo at `tilt_of(i)` (no
    /// noise, no range limits): for a head whose servo does not follow the configured sweep
    /// (an emulator's, moved by a driver).
    pub fn hits_at(&self, tilt_of: &dyn Fn(usize) -> f64) -> Vec<Option<RayHit>> {
        (0..self.lidar.beams())
            .map(|i| {
                let scanner = self.mount_to_world * self.lidar.scanner_in_mount(tilt_of(i));
                let dir = scanner.rotation * self.directions[i];
                self.world.ray(&scanner.translation.vector.into(), &dir)
            })
            .collect()
    }

    /// Beam `i` of row `k` as it is cast: its origin and unit direction (world), the servo
    /// at the beam's own time stamp, the head where row `k` was cast from.
    pub fn beam_ray(&self, k: usize, i: usize) -> (Point3<f64>, Vector3<f64>) {
        let mount_to_world = self.motion.as_ref().map_or(&self.mount_to_world, |m| &m.truth[k]);
        let tilt = self.sweep.tilt_at(self.sweep.row_stamp_s(k) + self.lidar.beam_time_offset_s(i));
        let scanner = mount_to_world * self.lidar.scanner_in_mount(tilt);
        (scanner.translation.vector.into(), scanner.rotation * self.directions[i])
    }

    /// Casts row `k`, recording each beam's true hit in `hits` when given.
    fn cast_row(&self, k: usize, mut hits: Option<&mut Vec<Option<RayHit>>>) -> ScanRow {
        let stamp_s = self.sweep.row_stamp_s(k);
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed ^ (k as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
        let noise =
            Normal::new(0.0, self.lidar.noise_sigma_m).ok().filter(|_| self.lidar.noise_sigma_m > 0.0);
        let beams = self.lidar.beams();
        let mount_to_world = self.motion.as_ref().map_or(&self.mount_to_world, |m| &m.truth[k]);
        let mut ranges_m = Vec::with_capacity(beams);
        for i in 0..beams {
            let (origin, dir) = self.beam_ray(k, i);
            let hit = self.world.ray(&origin, &dir);
            let mut range = hit.map_or(0.0, |h| h.distance_m);
            if let Some(n) = &noise {
                range += n.sample(&mut rng);
            }
            let dropped =
                self.lidar.dropout_probability > 0.0 && rng.random::<f64>() < self.lidar.dropout_probability;
            let valid = hit.is_some() && !dropped && self.lidar.in_range(range);
            ranges_m.push(if valid { range as f32 } else { 0.0 });
            if let Some(h) = hits.as_deref_mut() {
                h.push(hit);
            }
        }
        let gravity_mount = mount_to_world.rotation.inverse() * -Vector3::z();
        let believed = self.motion.as_ref().map(|m| m.believed[k]);
        let tilt_rad = self.sweep.reading_at(stamp_s);
        ScanRow { stamp_s, tilt_rad, ranges_m, gravity_mount, mount_to_world: believed }
    }

    /// The whole sweep, cast in chunks of rows; `on_rows(done_rows, total_rows)` is called
    /// after each chunk (for progress bars). A cancelled `cancel` stops it between chunks.
    pub fn sweep_rows(
        &self,
        cancel: &Cancel,
        on_rows: &mut dyn FnMut(usize, usize),
    ) -> Result<Sweep, SensorError> {
        let total = self.sweep.rows();
        let chunk = 24;
        let mut rows = Vec::with_capacity(total);
        let mut k = 0;
        while k < total {
            if cancel.is_cancelled() {
                return Err(SensorError::Cancelled { rows: k });
            }
            rows.extend(self.rows(k..k + chunk));
            k = (k + chunk).min(total);
            on_rows(k, total);
        }
        Ok(Sweep { rows, lidar: self.lidar.clone(), mount_to_world: self.mount_to_world })
    }
}
