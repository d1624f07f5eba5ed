//! The simulated sensor: the tilting lidar's beams cast into the MuJoCo world, each beam with
//! the tilt at its own time stamp, with range noise and dropouts.

use super::{LidarModel, ScanRow, SensorError, TiltSweep};
use crate::scenario::LidarSpec;
use crate::scene::mjcf::HEAD_SITE;
use crate::sim::{RayHit, World};
use nalgebra::{Isometry3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;
use std::ops::Range;

/// A tilting lidar mounted on the robot's head in a [`World`], frozen at the world's current
/// state (the robot stands still during a sweep, as on the real robot).
pub struct SimLidar<'w> {
    world: &'w World,
    lidar: LidarModel,
    sweep: TiltSweep,
    mount_to_world: Isometry3<f64>,
    seed: u64,
}

impl<'w> SimLidar<'w> {
    /// The lidar of `spec` on the `head` site of `world`; `seed` drives noise and dropouts.
    pub fn new(world: &'w World, spec: &LidarSpec, seed: u64) -> Result<Self, SensorError> {
        let lidar = LidarModel::from_spec(spec);
        let head = world.site_pose(world.site_id(HEAD_SITE)?);
        let mount_to_world = head * lidar.mount_in_head;
        Ok(Self { world, sweep: TiltSweep::from_spec(spec), lidar, mount_to_world, seed })
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

    /// Casts row `k`, recording each beam's true hit in `hits` when given.
    fn cast_row(&self, k: usize, mut hits: Option<&mut Vec<Option<RayHit>>>) -> ScanRow {
        let stamp_s = self.sweep.row_stamp_s(k);
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed ^ (k as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
        let noise =
            Normal::new(0.0, self.lidar.noise_sigma_m).ok().filter(|_| self.lidar.noise_sigma_m > 0.0);
        let beams = self.lidar.beams();
        let mut ranges_m = Vec::with_capacity(beams);
        for i in 0..beams {
            let tilt = self.sweep.tilt_at(stamp_s + self.lidar.beam_time_offset_s(i));
            let scanner = self.mount_to_world * self.lidar.scanner_in_mount(tilt);
            let origin = scanner.translation.vector.into();
            let dir = scanner.rotation * self.lidar.beam_direction(i);
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
        let gravity_mount = self.mount_to_world.rotation.inverse() * -Vector3::z();
        ScanRow { stamp_s, tilt_rad: self.sweep.reading_at(stamp_s), ranges_m, gravity_mount }
    }
}

impl SimLidar<'_> {
    /// The whole sweep, cast in chunks of rows; `progress(done_rows, total_rows)` is called
    /// after each chunk (for progress bars).
    pub fn sweep_with_progress(&self, progress: &mut dyn FnMut(usize, usize)) -> super::Sweep {
        let total = self.sweep.rows();
        let chunk = 24;
        let mut rows = Vec::with_capacity(total);
        let mut k = 0;
        while k < total {
            rows.extend(self.rows(k..k + chunk));
            k = (k + chunk).min(total);
            progress(k, total);
        }
        super::Sweep { rows, lidar: self.lidar.clone(), mount_to_world: self.mount_to_world }
    }
}

/// A scenario's world, scanned once by its lidar from the robot's start.
pub struct ScenarioScan {
    /// The scenario's scene (ground truth included).
    pub scene: crate::scene::Scene,
    /// The sweep.
    pub sweep: super::Sweep,
}

/// Builds the world of `scenario` (with the bench's robot, see [`World::for_scene`]) and
/// sweeps its lidar once; `progress(done_rows, total_rows)` is called along the way.
pub fn scan_scenario(
    scenario: &crate::scenario::Scenario,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<ScenarioScan, SensorError> {
    let scene = crate::scene::Scene::from_scenario(scenario)?;
    let world = World::for_scene(&scene)?;
    let sweep = SimLidar::new(&world, &scenario.lidar, scenario.seed)?.sweep_with_progress(progress);
    Ok(ScenarioScan { scene, sweep })
}
