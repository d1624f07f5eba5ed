//! `bench lidar`: rays per second of the simulated lidar, `mj_ray` against the world's box
//! caster, one thread against all cores; and the casting alone, each caster on the sweep's
//! rays computed beforehand.

use super::{machine, median_s};
use anyhow::{Context, Result};
use nalgebra::{Point3, Vector3};
use stairbench::scenario::Scenario;
use stairbench::scene::mjcf::HEAD_SITE;
use stairbench::scene::Scene;
use stairbench::sensor::{RayCaster, RayHit, SimLidar};
use stairbench::sim::lidar::head_lidar;
use stairbench::sim::World;

/// The world's rays all cast by `mj_ray` (the baseline).
struct ByMujoco<'w>(&'w World);

impl RayCaster for ByMujoco<'_> {
    fn ray(&self, origin: &Point3<f64>, dir: &Vector3<f64>) -> Option<RayHit> {
        self.0.ray_by_mujoco(origin, dir)
    }
}

/// Measures one sweep of the Exp. 1 world; returns the Markdown table.
pub fn run(repeat: usize) -> Result<String> {
    const REAL_POINTS_PER_S: f64 = 43_240.0;
    let scenario = Scenario::default();
    let scene = Scene::from_scenario(&scenario)?;
    let world = World::for_scene(&scene)?;
    let lidar = head_lidar(&world, &scenario.lidar, scenario.seed)?;
    let by_mujoco = ByMujoco(&world);
    let head = world.site_pose(world.site_id(HEAD_SITE)?);
    let baseline = SimLidar::new(&by_mujoco, &scenario.lidar, &head, scenario.seed);
    let rows = lidar.sweep().rows();
    let rays = (rows * lidar.lidar().beams()) as f64;
    anyhow::ensure!(
        baseline.rows(0..rows) == lidar.rows(0..rows),
        "the box caster's sweep differs from mj_ray's"
    );
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().context("thread pool")?;
    let time = |rows_of: &(dyn Fn() -> Vec<stairbench::sensor::ScanRow> + Sync),
                threads: Option<&rayon::ThreadPool>| {
        median_s(repeat, || {
            match threads {
                Some(pool) => pool.install(|| std::hint::black_box(rows_of())),
                None => std::hint::black_box(rows_of()),
            };
        })
    };
    let base_s = time(&|| baseline.rows(0..rows), Some(&one));
    let par_s = time(&|| baseline.rows(0..rows), None);
    let boxes_s = time(&|| lidar.rows(0..rows), Some(&one));
    let boxes_par_s = time(&|| lidar.rows(0..rows), None);
    // The casting alone: the sweep's rays, each beam at its own tilt, computed once.
    let beams: Vec<(Point3<f64>, Vector3<f64>)> = (0..rows)
        .flat_map(|k| (0..lidar.lidar().beams()).map(move |i| (k, i)))
        .map(|(k, i)| lidar.beam_ray(k, i))
        .collect();
    let cast = |caster: &dyn RayCaster| {
        median_s(repeat, || {
            for (o, d) in &beams {
                std::hint::black_box(caster.ray(o, d));
            }
        })
    };
    let (cast_mujoco_s, cast_boxes_s) = (cast(&by_mujoco), cast(&world));
    let mut t = String::new();
    t += &format!(
        "Simulated lidar, Exp. 1 world with the HRP-4-class robot in it ({} geoms, the robot's excluded from the rays), one sweep of {rows} rows x {} beams = {rays:.0} rays, median of {repeat}; {}.\n\n",
        world.model().ffi().ngeom,
        lidar.lidar().beams(),
        machine()
    );
    t += "The world's box caster (`sim::box_rays`, used wherever the world is static boxes, as every scenario's is) gives `mj_ray`'s sweep exactly (checked here, and by tests/lidar.rs on the beams and on rays at every box's corners and edges).\n\n";
    t += "| variant | wall per sweep | rays/s | x real sensor (43 240 points/s) | ratio to baseline |\n|---|---|---|---|---|\n";
    for (name, s) in [
        ("baseline: 1 thread, mj_ray per beam", base_s),
        ("mj_ray, rayon over rows, all cores", par_s),
        ("the world's box caster (the default), 1 thread", boxes_s),
        ("the world's box caster, all cores", boxes_par_s),
    ] {
        t += &format!(
            "| {name} | {:.1} ms | {:.2} M | {:.0} x | {:.2} |\n",
            s * 1e3,
            rays / s / 1e6,
            rays / s / REAL_POINTS_PER_S,
            base_s / s
        );
    }
    t += &format!(
        "\nThe casting alone (the sweep's {rays:.0} rays computed beforehand, 1 thread, no noise): `mj_ray` {:.1} ms, the box caster {:.1} ms, **x {:.2}**.\n",
        cast_mujoco_s * 1e3,
        cast_boxes_s * 1e3,
        cast_mujoco_s / cast_boxes_s
    );
    Ok(t)
}
