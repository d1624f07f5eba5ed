//! `bench lidar`: rays per second of the simulated lidar, one thread against all cores.

use super::{machine, median_s};
use anyhow::{Context, Result};
use stairbench::scenario::Scenario;
use stairbench::scene::Scene;
use stairbench::sim::lidar::head_lidar;
use stairbench::sim::World;

/// Measures one sweep of the Exp. 1 world; returns the Markdown table.
pub fn run(repeat: usize) -> Result<String> {
    const REAL_POINTS_PER_S: f64 = 43_240.0;
    let scenario = Scenario::default();
    let scene = Scene::from_scenario(&scenario)?;
    let world = World::for_scene(&scene)?;
    let lidar = head_lidar(&world, &scenario.lidar, scenario.seed)?;
    let rows = lidar.sweep().rows();
    let rays = (rows * lidar.lidar().beams()) as f64;
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().context("thread pool")?;
    let base_s = median_s(repeat, || {
        one.install(|| std::hint::black_box(lidar.rows(0..rows)));
    });
    let par_s = median_s(repeat, || {
        std::hint::black_box(lidar.rows(0..rows));
    });
    let mut t = String::new();
    t += &format!(
        "Simulated lidar, Exp. 1 world with the HRP-4-class robot in it ({} geoms, the robot's excluded from the rays), one sweep of {rows} rows x {} beams = {rays:.0} rays, median of {repeat}; {}.\n\n",
        world.model().ffi().ngeom,
        lidar.lidar().beams(),
        machine()
    );
    t += "| variant | wall per sweep | rays/s | x real sensor (43 240 points/s) | ratio to baseline |\n|---|---|---|---|---|\n";
    for (name, s) in [("baseline: 1 thread, mj_ray per beam", base_s), ("rayon over rows, all cores", par_s)]
    {
        t += &format!(
            "| {name} | {:.1} ms | {:.2} M | {:.0} x | {:.2} |\n",
            s * 1e3,
            rays / s / 1e6,
            rays / s / REAL_POINTS_PER_S,
            base_s / s
        );
    }
    Ok(t)
}
