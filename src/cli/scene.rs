//! `stairbench scene`: a scenario's world, its ground truth and (optionally) its MJCF.

use anyhow::{Context, Result};
use clap::Args;
use stairbench::scene::mjcf::HEAD_SITE;
use stairbench::scene::Scene;
use stairbench::sim::World;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `stairbench scene`.
#[derive(Debug, Args)]
pub struct SceneArgs {
    /// Scenario file or name in scenarios/ (default: the paper's Exp. 1).
    scenario: Option<PathBuf>,
    /// Write the generated MJCF world here.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Print the scenario with every default filled in, as TOML.
    #[arg(long)]
    resolved: bool,
}

/// Runs `stairbench scene`.
pub fn run(a: SceneArgs) -> Result<ExitCode> {
    let mut scenario = super::load_scenario(a.scenario.as_deref())?;
    if a.resolved {
        scenario.plant = scenario.plant.resolved();
        print!("{}", scenario.to_toml_string()?);
        return Ok(ExitCode::SUCCESS);
    }
    let scene = Scene::from_scenario(&scenario)?;
    let world = World::for_scene(&scene)?;
    println!(
        "scenario {}: {} boxes, {} bodies, {} geoms in MuJoCo",
        scene.name(),
        scene.boxes().len(),
        world.model().ffi().nbody,
        world.model().ffi().ngeom
    );
    let mount = world.site_pose(world.site_id(HEAD_SITE)?).translation.vector;
    println!(
        "robot: HRP-4-class model in half-sitting, lidar mount (`{HEAD_SITE}` site) at ({:.3}, {:.3}, {:.3}) m",
        mount.x, mount.y, mount.z
    );
    println!("ground truth, step tops (world frame, metres):");
    println!("  step  height   depth   width   centre (x, y)");
    for s in scene.steps() {
        let c = s.center();
        println!(
            "  {:>4}  {:>6.3}  {:>6.3}  {:>6.3}   ({:.3}, {:.3})",
            s.index + 1,
            s.height_m,
            s.depth_m,
            s.width_m,
            c.x,
            c.y
        );
    }
    if let Some(out) = a.output {
        super::ensure_parent(&out)?;
        std::fs::write(&out, world.xml()).with_context(|| format!("cannot write {}", out.display()))?;
        println!("MJCF written to {}", out.display());
    }
    Ok(ExitCode::SUCCESS)
}
