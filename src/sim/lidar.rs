//! The simulated lidar as a [`Source`]: the scenario's tilting lidar on the robot's head in a
//! MuJoCo [`World`], swept from wherever the robot stands when the loop asks, or, given the
//! head's track ([`HeadTrack`]), along the path the head took over the servo's last pass
//! (the robot sweeping as it moves). Each sweep draws its own noise (the scenario's seed plus
//! the sweep's number, from 1).

use super::head_track::HeadTrack;
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
    track: Option<&'a RefCell<HeadTrack>>,
}

impl<'a> SimSource<'a> {
    /// The lidar of `spec` on the head of `world`'s robot; `seed` drives noise and dropouts.
    pub fn new(world: &'a RefCell<World>, spec: &LidarSpec, seed: u64) -> Result<Self, SimError> {
        let head_site = world.borrow().site_id(HEAD_SITE)?;
        Ok(Self { world, spec: spec.clone(), head_site, seed, sweeps: 0, track: None })
    }

    /// The lidar sweeping as the head moves: a sweep is cast along the pass `track` holds
    /// (the rows' true poses, the robot's beliefs carried by the rows; the servo then swings
    /// back, [`HeadTrack::take`]), or, while the track holds less than a pass (a look that
    /// did not wait [`Source::whole_in_s`], a look again standing after
    /// [`Source::sweep_standing_next`]), from where the head stands.
    pub fn with_track(mut self, track: &'a RefCell<HeadTrack>) -> Self {
        self.track = Some(track);
        self
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
        let seed = self.seed.wrapping_add(self.sweeps);
        // The pass ends here either way (a sweep cancelled below has used it up).
        let heads = self.track.and_then(|t| t.borrow_mut().take(world.data().time()));
        if let Some(lidar) = heads.and_then(|heads| SimLidar::moving(&*world, &self.spec, &heads, seed)) {
            return lidar.sweep_rows(cancel, on_rows);
        }
        let head = world.site_pose(self.head_site);
        if let Some(track) = self.track {
            track.borrow_mut().swept_standing(world.data().time());
        }
        SimLidar::new(&*world, &self.spec, &head, seed).sweep_rows(cancel, on_rows)
    }

    fn sweep_standing_next(&mut self) -> f64 {
        self.track.map_or(0.0, |track| track.borrow_mut().drop_pass())
    }

    fn whole_in_s(&self) -> f64 {
        let Some(track) = self.track else { return 0.0 };
        let now_s = self.world.borrow().data().time();
        track.borrow().whole_at_s(now_s) - now_s
    }
}
