//! The simulated lidar as a [`Source`]: the scenario's tilting lidar on the robot's head in a
//! MuJoCo [`World`], swept from wherever the robot stands when the loop asks. Each sweep draws
//! its own noise (the scenario's seed plus the sweep's number, from 1).

use super::world::{SimError, World};
use crate::cancel::Cancel;
use crate::scenario::LidarSpec;
use crate::scene::mjcf::HEAD_SITE;
use crate::sensor::{SensorError, SimLidar, Source, Sweep};
use std::cell::RefCell;

/// The head lidar of a shared world.
pub struct SimSource<'a> {
    world: &'a RefCell<World>,
    spec: LidarSpec,
    head_site: usize,
    seed: u64,
    sweeps: u64,
}

impl<'a> SimSource<'a> {
    /// The lidar of `spec` on the head of `world`'s robot; `seed` drives noise and dropouts.
    pub fn new(world: &'a RefCell<World>, spec: &LidarSpec, seed: u64) -> Result<Self, SimError> {
        let head_site = world.borrow().site_id(HEAD_SITE)?;
        Ok(Self { world, spec: spec.clone(), head_site, seed, sweeps: 0 })
    }
}

/// The lidar of `spec` on the head of `world`'s robot, frozen at the world's current state;
/// `seed` drives noise and dropouts.
pub fn head_lidar<'w>(
    world: &'w World,
    spec: &LidarSpec,
    seed: u64,
) -> Result<SimLidar<'w, World>, SimError> {
    let head = world.site_pose(world.site_id(HEAD_SITE)?);
    Ok(SimLidar::new(world, spec, &head, seed))
}

impl Source for SimSource<'_> {
    fn sweep(
        &mut self,
        cancel: &Cancel,
        on_rows: &mut dyn FnMut(usize, usize),
    ) -> Result<Sweep, SensorError> {
        self.sweeps += 1;
        let world = self.world.borrow();
        let head = world.site_pose(self.head_site);
        let lidar = SimLidar::new(&*world, &self.spec, &head, self.seed.wrapping_add(self.sweeps));
        lidar.sweep_rows(cancel, on_rows)
    }
}
